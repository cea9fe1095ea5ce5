"""The cache record of a model index: the arrays and numbers stored on disk, and back.

An :class:`IndexRecord` is what :class:`meshrec.model.index.ModelIndex` writes to and reads
from :class:`meshrec.model.cache.ArrayCache`: the cleaned mesh, its curvature table, the
smooth surface's bulges and a few numbers, every one checked when it comes back (a cache
entry is data entering the program). The search structures (KD tree, AABB tree) are not
part of it: they are rebuilt from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from meshrec.model._arrays import readonly
from meshrec.model.curvature import CurvatureTable
from meshrec.model.mesh import MeshData
from meshrec.model.surface import AabbSurface

__all__ = ["RECORD_VERSION", "IndexRecord"]

#: Part of the cache key: bumped when the record's arrays, or how they are computed,
#: change (1: the record of the split index, same arrays as cache format 3).
RECORD_VERSION = 1

_ARRAYS = (
    "vertices", "faces", "vertex_normals", "k1", "k2", "dir1", "dir2", "valid", "edge_bulge"
)
_SCALARS = ("closed", "scale", "avg_edge", "radius_edges", "curvature_radius", "build_seconds")


@dataclass(frozen=True, eq=False)
class IndexRecord:
    """Everything a model index caches. The arrays are read-only.

    Attributes
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    vertex_normals : (n, 3) float64
    k1, k2 : (n,) float64
    dir1, dir2 : (n, 3) float64
    valid : (n,) bool
    edge_bulge : (m, 3) float64
    closed : bool
    scale, avg_edge : float
    radius_edges : int
    curvature_radius : float
    build_seconds : float
        Time the index took to build.

    Raises
    ------
    ValueError
        If an array's shape disagrees with the others, there is no face, or a face index
        is out of range.
    """

    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    vertex_normals: np.ndarray = field(repr=False)
    k1: np.ndarray = field(repr=False)
    k2: np.ndarray = field(repr=False)
    dir1: np.ndarray = field(repr=False)
    dir2: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    edge_bulge: np.ndarray = field(repr=False)
    closed: bool
    scale: float
    avg_edge: float
    radius_edges: int
    curvature_radius: float
    build_seconds: float

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
        for name in ("k1", "k2"):
            put(name, readonly(getattr(self, name), np.float64, (n,), name))
        for name in ("dir1", "dir2"):
            put(name, readonly(getattr(self, name), np.float64, (n, 3), name))
        put("valid", readonly(self.valid, bool, (n,), "valid"))
        put("edge_bulge", readonly(self.edge_bulge, np.float64, (len(F), 3), "edge_bulge"))
        put("closed", bool(self.closed))
        for name in ("scale", "avg_edge", "curvature_radius", "build_seconds"):
            put(name, float(getattr(self, name)))
        put("radius_edges", int(self.radius_edges))

    # ------------------------------------------------------------------ cache arrays
    @staticmethod
    def names() -> tuple[str, ...]:
        """The names of the arrays :meth:`to_arrays` writes and :meth:`from_arrays` needs."""
        return _ARRAYS + _SCALARS

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The record as named arrays (scalars as 0-d arrays) for the cache.

        Returns
        -------
        dict of str to ndarray
        """
        return {name: np.asarray(getattr(self, name)) for name in self.names()}

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
        return cls(**{name: arrays[name] for name in _ARRAYS}, **scalars)

    # ------------------------------------------------------------------ parts
    @classmethod
    def from_parts(
        cls,
        mesh: MeshData,
        curvature: CurvatureTable,
        edge_bulge: np.ndarray,
        build_seconds: float,
    ) -> IndexRecord:
        """The record of an index's parts.

        Parameters
        ----------
        mesh : MeshData
        curvature : CurvatureTable
        edge_bulge : (m, 3) float
            The smooth surface's bulges (:func:`meshrec.model.surface.edge_bulges`).
        build_seconds : float

        Returns
        -------
        IndexRecord

        Raises
        ------
        ValueError
            If the parts do not belong to one mesh (their sizes differ).
        """
        return cls(
            vertices=mesh.vertices,
            faces=mesh.faces,
            vertex_normals=mesh.vertex_normals,
            k1=curvature.k1,
            k2=curvature.k2,
            dir1=curvature.dir1,
            dir2=curvature.dir2,
            valid=curvature.valid,
            edge_bulge=edge_bulge,
            closed=mesh.closed,
            scale=mesh.scale,
            avg_edge=mesh.avg_edge,
            radius_edges=curvature.radius_edges,
            curvature_radius=curvature.curvature_radius,
            build_seconds=build_seconds,
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
            k1=self.k1,
            k2=self.k2,
            dir1=self.dir1,
            dir2=self.dir2,
            valid=self.valid,
            radius_edges=self.radius_edges,
            curvature_radius=self.curvature_radius,
            scale=self.scale,
        )
        return mesh, curvature, AabbSurface(mesh=mesh, edge_bulge=self.edge_bulge)

    def __repr__(self) -> str:
        return (
            f"IndexRecord(vertices={len(self.vertices)}, faces={len(self.faces)}, "
            f"radius_edges={self.radius_edges}, build_seconds={self.build_seconds:.3g})"
        )
