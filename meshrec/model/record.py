"""The cache record of a model index: the arrays and numbers stored on disk, and back.

An :class:`IndexRecord` is what :class:`meshrec.model.index.ModelIndex` writes to and reads
from :class:`meshrec.model.cache.ArrayCache`: the cleaned mesh, its curvature table, the
smooth surface's bulges and a few numbers, every one checked when it comes back (a cache
entry is data entering the program). The search structures (KD tree, AABB tree) are not
part of it: they are rebuilt from it.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from meshrec.model._arrays import readonly
from meshrec.model.curvature import CurvatureTable
from meshrec.model.mesh import MeshData
from meshrec.model.surface import AabbSurface

__all__ = ["RECORD_VERSION", "IndexRecord"]

#: Part of the cache key: bumped when the record's arrays, or how they are computed,
#: change (1: the record of the split index, same arrays as cache format 3; 2: the
#: curvature table at sites on the smooth surface, issue 13; 3: no site where the normals
#: cancel, on a fold or a zero-length edge, stop 36).
RECORD_VERSION = 3

_MESH = ("vertices", "faces", "vertex_normals", "edge_bulge")
_SITES = (
    "points",
    "normals",
    "normals2",
    "k1",
    "k2",
    "dir1",
    "dir2",
    "valid",
    "K_range",
    "H_range",
    "crease",
    "face_patch",
)
_ARRAYS = _MESH + _SITES
#: The array holding the mesh warnings, one JSON string.
_SAID = "mesh_warnings"
_SCALARS = (
    "closed",
    "scale",
    "avg_edge",
    "spacing",
    "curvature_radius",
    "range_radius",
    "build_seconds",
)


@dataclass(frozen=True, eq=False)
class IndexRecord:
    """Everything a model index caches. The arrays are read-only.

    Attributes
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    vertex_normals : (n, 3) float64
    edge_bulge : (m, 3) float64
    points, normals, normals2, k1, k2, dir1, dir2, valid, K_range, H_range, crease
        The curvature sites' arrays (see :class:`meshrec.model.curvature.CurvatureTable`),
        ``s`` sites each.
    face_patch : (m,) int64
    closed : bool
    scale, avg_edge : float
    spacing, curvature_radius, range_radius : float
    build_seconds : float
        Time the index took to build.
    mesh_warnings : tuple of str
        The :class:`~meshrec.model.mesh.MeshWarning` texts that loading the mesh gave
        when the index was built (said again whenever the index is loaded from the cache).

    Raises
    ------
    ValueError
        If an array's shape disagrees with the others, there is no face, or a face index
        is out of range.
    """

    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    vertex_normals: np.ndarray = field(repr=False)
    edge_bulge: np.ndarray = field(repr=False)
    points: np.ndarray = field(repr=False)
    normals: np.ndarray = field(repr=False)
    normals2: np.ndarray = field(repr=False)
    k1: np.ndarray = field(repr=False)
    k2: np.ndarray = field(repr=False)
    dir1: np.ndarray = field(repr=False)
    dir2: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    K_range: np.ndarray = field(repr=False)
    H_range: np.ndarray = field(repr=False)
    crease: np.ndarray = field(repr=False)
    face_patch: np.ndarray = field(repr=False)
    closed: bool
    scale: float
    avg_edge: float
    spacing: float
    curvature_radius: float
    range_radius: float
    build_seconds: float
    mesh_warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        V = readonly(self.vertices, np.float64, (None, 3), "vertices")
        n = len(V)
        F = readonly(self.faces, np.int64, (None, 3), "faces")
        if len(F) == 0:
            raise ValueError("faces must hold at least one triangle, got shape (0, 3)")
        if F.min() < 0 or F.max() >= n:
            raise ValueError(
                f"faces must index vertices 0..{n - 1}, got range {F.min()}..{F.max()}"
            )
        put("vertices", V)
        put("faces", F)
        put("vertex_normals", readonly(self.vertex_normals, np.float64, (n, 3), "vertex_normals"))
        put("edge_bulge", readonly(self.edge_bulge, np.float64, (len(F), 3), "edge_bulge"))
        P = readonly(self.points, np.float64, (None, 3), "points")
        put("points", P)
        s = len(P)
        for name in ("normals", "normals2", "dir1", "dir2"):
            put(name, readonly(getattr(self, name), np.float64, (s, 3), name))
        for name in ("k1", "k2"):
            put(name, readonly(getattr(self, name), np.float64, (s,), name))
        for name in ("K_range", "H_range"):
            put(name, readonly(getattr(self, name), np.float64, (s, 2), name))
        for name in ("valid", "crease"):
            put(name, readonly(getattr(self, name), bool, (s,), name))
        put("face_patch", readonly(self.face_patch, np.int64, (len(F),), "face_patch"))
        put("closed", bool(self.closed))
        for name in (
            "scale",
            "avg_edge",
            "spacing",
            "curvature_radius",
            "range_radius",
            "build_seconds",
        ):
            put(name, float(getattr(self, name)))
        said = self.mesh_warnings
        if isinstance(said, str) or not all(isinstance(w, str) for w in said):
            raise ValueError(f"mesh_warnings must be a sequence of str, got {said!r}")
        put("mesh_warnings", tuple(said))

    # ------------------------------------------------------------------ cache arrays
    @staticmethod
    def names() -> tuple[str, ...]:
        """The names of the arrays :meth:`to_arrays` writes and :meth:`from_arrays` needs."""
        return _ARRAYS + _SCALARS + (_SAID,)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The record as named arrays (scalars as 0-d arrays, the mesh warnings as one
        JSON string) for the cache.

        Returns
        -------
        dict of str to ndarray
        """
        out = {name: np.asarray(getattr(self, name)) for name in _ARRAYS + _SCALARS}
        out[_SAID] = np.array(json.dumps(list(self.mesh_warnings)))
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> IndexRecord:
        """The record of named arrays from the cache (see :meth:`to_arrays`).

        Parameters
        ----------
        arrays : mapping of str to ndarray
            Holding at least :meth:`names`.

        Returns
        -------
        IndexRecord

        Raises
        ------
        ValueError
            If a name is missing, a scalar is not a single number, or the arrays do not
            fit together.
        """
        missing = [name for name in cls.names() if name not in arrays]
        if missing:
            raise ValueError(f"arrays must hold {missing}, got {sorted(arrays)}")
        scalars = {}
        for name in _SCALARS:
            a = np.asarray(arrays[name])
            if a.size != 1 or a.dtype.kind not in "biuf":
                raise ValueError(f"{name} must be a single number, got {a.dtype} {a.shape}")
            scalars[name] = a.item()
        try:
            said = json.loads(str(np.asarray(arrays[_SAID])))
        except ValueError as exc:
            raise ValueError(f"{_SAID} must be a JSON list of str: {exc}") from None
        if not isinstance(said, list):
            raise ValueError(f"{_SAID} must be a JSON list of str, got {said!r}")
        return cls(**{name: arrays[name] for name in _ARRAYS}, **scalars, mesh_warnings=said)

    # ------------------------------------------------------------------ parts
    @classmethod
    def from_parts(
        cls,
        mesh: MeshData,
        curvature: CurvatureTable,
        edge_bulge: np.ndarray,
        build_seconds: float,
        mesh_warnings=(),
    ) -> IndexRecord:
        """The record of an index's parts.

        Parameters
        ----------
        mesh : MeshData
        curvature : CurvatureTable
        edge_bulge : (m, 3) float
            The smooth surface's bulges (:func:`meshrec.model.surface.edge_bulges`).
        build_seconds : float
        mesh_warnings : sequence of str
            The mesh warnings loading the mesh gave.

        Returns
        -------
        IndexRecord

        Raises
        ------
        ValueError
            If the parts do not belong to one mesh (their sizes differ), or
            ``mesh_warnings`` is not a sequence of str.
        """
        return cls(
            vertices=mesh.vertices,
            faces=mesh.faces,
            vertex_normals=mesh.vertex_normals,
            edge_bulge=edge_bulge,
            **{name: getattr(curvature, name) for name in _SITES},
            closed=mesh.closed,
            scale=mesh.scale,
            avg_edge=mesh.avg_edge,
            spacing=curvature.spacing,
            curvature_radius=curvature.curvature_radius,
            range_radius=curvature.range_radius,
            build_seconds=build_seconds,
            mesh_warnings=tuple(mesh_warnings),
        )

    def parts(self) -> tuple[MeshData, CurvatureTable, AabbSurface]:
        """The mesh, curvature table and surface queries of this record (trees built).

        Returns
        -------
        mesh : MeshData
        curvature : CurvatureTable
        surface : AabbSurface
        """
        mesh = MeshData(
            vertices=self.vertices,
            faces=self.faces,
            vertex_normals=self.vertex_normals,
            closed=self.closed,
            scale=self.scale,
            avg_edge=self.avg_edge,
        )
        curvature = CurvatureTable(
            **{name: getattr(self, name) for name in _SITES},
            spacing=self.spacing,
            curvature_radius=self.curvature_radius,
            range_radius=self.range_radius,
            scale=self.scale,
        )
        return mesh, curvature, AabbSurface(mesh=mesh, edge_bulge=self.edge_bulge)

    def __repr__(self) -> str:
        return (
            f"IndexRecord(vertices={len(self.vertices)}, faces={len(self.faces)}, "
            f"sites={len(self.points)}, build_seconds={self.build_seconds:.3g})"
        )
