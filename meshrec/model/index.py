"""The per-model index: one model's mesh, curvature table and surface queries.

A :class:`ModelIndex` is a small composition, one home per job:

* :attr:`ModelIndex.mesh`, the cleaned mesh and its per-mesh data
  (:class:`meshrec.model.mesh.MeshData`);
* :attr:`ModelIndex.curvature`, the curvature table at sites on the smooth surface and its
  (K, H) lookup
  (:class:`meshrec.model.curvature.CurvatureTable`, the paper's Section 2.1);
* :attr:`ModelIndex.surface`, distance, closest-point, normal and smooth-surface queries
  behind the small :class:`meshrec.model.surface.SurfaceQuery` interface (default
  backend: libigl's AABB tree, :class:`meshrec.model.surface.AabbSurface`);
* the cache record (:class:`meshrec.model.record.IndexRecord`), stored on disk by
  :mod:`meshrec.model.cache`, keyed by the mesh file's bytes, the parameters, the record
  version and the package version.

:meth:`ModelIndex.from_file` is the entry point. The search trees are built when an index
is created or unpickled; they are never cached or pickled.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import numbers
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.io.checks import check_instance
from meshrec.model.cache import ArrayCache, CacheWarning, make_key, refuse_model_folder
from meshrec.model.curvature import CurvatureTable
from meshrec.model.derived import DerivedStore
from meshrec.model.mesh import (
    MeshData,
    MeshWarning,
    check_mesh_path,
    parse_mesh,
    read_mesh_file,
)
from meshrec.model.record import RECORD_VERSION, IndexRecord
from meshrec.model.resolution import Resolution, mesh_resolution
from meshrec.model.roughness import vertex_scatter
from meshrec.model.surface import AabbSurface, SurfaceQuery, edge_bulges
from meshrec.model.symmetry import NearSymmetries, near_symmetries

__all__ = ["IndexParams", "ModelIndex"]


@dataclass(frozen=True)
class IndexParams:
    """Parameters of the curvature table (part of the cache key).

    Lengths are fractions of the model's size ``sqrt(surface area)``, so that a model is
    described at the scale of the touch curves (``defaults.SIM_LENGTH_FRACTION`` of it),
    whatever its triangles.

    Parameters
    ----------
    curvature_fraction : float
        Radius of the curvature fit at each site.
    spacing_fraction : float
        Distance between curvature sites.
    range_fraction : float
        Radius of the neighbourhood of each site's (K, H) range (0: no range).
    sharp_angle_deg : float
        Adjacent faces whose normals differ by more than this meet at a sharp edge (crease
        sites, separate patches).
    crease_angle_deg : float
        Adjacent vertex normals further apart than this mark a crease, where the smooth
        distance does not bulge the faces (see
        :meth:`meshrec.model.surface.AabbSurface.smooth_offsets`).

    Raises
    ------
    ValueError
        If ``curvature_fraction`` or ``spacing_fraction`` is not a finite positive
        number, ``range_fraction`` not a finite number >= 0, or an angle not in (0, 180].
    """

    curvature_fraction: float = defaults.CURVATURE_SCALE_FRACTION
    spacing_fraction: float = defaults.SITE_SPACING_FRACTION
    range_fraction: float = defaults.SITE_RANGE_FRACTION
    sharp_angle_deg: float = defaults.SITE_CREASE_ANGLE_DEG
    crease_angle_deg: float = defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG

    def __post_init__(self) -> None:
        for name in ("curvature_fraction", "spacing_fraction", "range_fraction"):
            f = getattr(self, name)
            low_ok = (lambda v: v >= 0) if name == "range_fraction" else (lambda v: v > 0)
            if (
                isinstance(f, bool)
                or not isinstance(f, numbers.Real)
                or not (math.isfinite(f) and low_ok(f))
            ):
                bound = ">= 0" if name == "range_fraction" else "> 0"
                raise ValueError(f"{name} must be a finite number {bound}, got {f!r}")
            object.__setattr__(self, name, float(f))
        for name in ("sharp_angle_deg", "crease_angle_deg"):
            a = getattr(self, name)
            if (
                isinstance(a, bool)
                or not isinstance(a, numbers.Real)
                or not (math.isfinite(a) and 0 < a <= 180)
            ):
                raise ValueError(f"{name} must be in (0, 180] degrees, got {a!r}")
            object.__setattr__(self, name, float(a))

    def lengths(self, scale: float) -> tuple[float, float, float]:
        """The site spacing, curvature radius and range radius for a model of this size.

        Parameters
        ----------
        scale : float
            ``sqrt(surface area)`` of the model.

        Returns
        -------
        spacing, curvature_radius, range_radius : float
            Model units.

        Raises
        ------
        ValueError
            If ``scale`` is not finite and positive.
        """
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be finite and > 0, got {scale!r}")
        return (
            self.spacing_fraction * scale,
            self.curvature_fraction * scale,
            self.range_fraction * scale,
        )


@dataclass(frozen=True, eq=False)
class ModelIndex:
    """One model: its cleaned mesh, curvature table and surface queries.

    Build it with :meth:`from_file` (or :meth:`from_record`).

    Attributes
    ----------
    name : str
        The file's stem.
    path : Path
        The mesh file.
    params : IndexParams
    mesh : MeshData
        The cleaned mesh with its normals, size and mean edge length.
    curvature : CurvatureTable
        Principal curvatures at sites on the smooth surface and the (K, H) lookup.
    surface : SurfaceQuery
        Closest points, normals and the smooth surface (default :class:`AabbSurface`).
    build_seconds : float
        Time the index took to build (when it was built, also for a cached index).
    from_cache : bool
        Whether it came from the on-disk cache.
    load_seconds : float
        Wall time of :meth:`from_file` (reading, hashing, cache load or build, trees).
    derived : DerivedStore or None
        Where the resolution, vertex scatter and near-symmetries are kept once computed
        (:mod:`meshrec.model.derived`; :meth:`from_file` and the library pack give one);
        None: computed once per process.
    mesh_warnings : tuple of str
        The :class:`~meshrec.model.mesh.MeshWarning` texts that loading the mesh gave when
        the index was built; an index loaded from the cache (or a library pack) warns them
        again, so that they are not said only once.
    resolution : Resolution
        The mesh's resolution against the default touch curve length, computed on first
        use (0.04 to 0.08 s on an 80,000-face model) and, for an index loaded by
        :meth:`from_file` or from a library pack, kept in the cache folder
        (:mod:`meshrec.model.derived`), as are the two below.
    vertex_scatter : float
        How far the vertices scatter along their normals about a smooth surface (the
        mesh's own error, :mod:`meshrec.model.roughness`), computed on first use.
    symmetry_tolerance : float
        How far a symmetry of the model may move its vertices off its surface.
    near_symmetries : NearSymmetries
        Half-turns, and axes of turns, that carry the model near itself
        (:mod:`meshrec.model.symmetry`), computed on first use.

    Raises
    ------
    TypeError
        If a part has the wrong type (``derived`` neither a :class:`DerivedStore` nor
        None, the shared checks' message).
    ValueError
        If the curvature table does not have one patch label per mesh face.
    """

    name: str
    path: Path
    params: IndexParams
    mesh: MeshData
    curvature: CurvatureTable
    surface: SurfaceQuery
    build_seconds: float = 0.0
    from_cache: bool = False
    load_seconds: float = 0.0
    mesh_warnings: tuple[str, ...] = ()
    derived: DerivedStore | None = dataclasses.field(default=None, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(self.path))
        check_instance(self.derived, DerivedStore, "derived", optional=True)
        for name, kind in (
            ("params", IndexParams),
            ("mesh", MeshData),
            ("curvature", CurvatureTable),
            ("surface", SurfaceQuery),
        ):
            value = getattr(self, name)
            if not isinstance(value, kind):
                raise TypeError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
        m = len(self.mesh.faces)
        if len(self.curvature.face_patch) != m:
            raise ValueError(
                f"curvature must have one patch label per mesh face ({m}), "
                f"got {len(self.curvature.face_patch)}"
            )

    def __repr__(self) -> str:
        return (
            f"ModelIndex({self.name!r}, vertices={len(self.mesh.vertices)}, "
            f"faces={len(self.mesh.faces)}, sites={len(self.curvature.table_sites)}, "
            f"closed={self.mesh.closed}, scale={self.mesh.scale:.6g}, "
            f"from_cache={self.from_cache})"
        )

    @functools.cached_property
    def resolution(self) -> Resolution:
        """The mesh's resolution (see :func:`meshrec.model.resolution.mesh_resolution`)."""
        return self._kept(
            "resolution", lambda: mesh_resolution(self.mesh, curvature=self.curvature)
        )

    @functools.cached_property
    def vertex_scatter(self) -> float:
        """How far the mesh's vertices scatter along their normals about a smooth surface,
        model units (:func:`meshrec.model.roughness.vertex_scatter`; about 0 for an exact
        mesh, the scanner's noise for a raw scan), computed on first use."""
        return self._kept(
            "vertex_scatter", lambda: vertex_scatter(self.mesh, self.curvature.face_patch)
        )

    @functools.cached_property
    def symmetry_tolerance(self) -> float:
        """How far a motion may move the model's vertices off its surface and still be a
        symmetry of it, model units: ``defaults.POSE_SYMMETRY_TOLERANCE`` of the diagonal
        or twice the mesh's chord error (:attr:`resolution`), whichever is larger."""
        diagonal = float(np.linalg.norm(np.ptp(self.mesh.vertices, axis=0)))
        return max(
            defaults.POSE_SYMMETRY_TOLERANCE * diagonal,
            2.0 * float(self.resolution.chord_error),
        )

    @functools.cached_property
    def near_symmetries(self) -> NearSymmetries:
        """The turns that carry the model near itself but are not symmetries of it
        (:func:`meshrec.model.symmetry.near_symmetries`), computed on first use."""
        return self._kept(
            "near_symmetries",
            lambda: near_symmetries(self.mesh, self.surface, self.symmetry_tolerance),
        )

    def _kept(self, what: str, compute):
        """``compute()``, or its value kept on disk by the index's :class:`DerivedStore`
        (:mod:`meshrec.model.derived`) when it has one."""
        return compute() if self.derived is None else self.derived.kept(what, compute)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(
        cls,
        path: str | os.PathLike,
        params: IndexParams | None = None,
        cache_dir: str | os.PathLike | None = None,
        force: bool = False,
        stage: Callable[[str], None] | None = None,
    ) -> ModelIndex:
        """Index a mesh file, using the on-disk cache.

        Parameters
        ----------
        path : str or path-like
            An STL, OBJ, PLY or OFF file.
        params : IndexParams or None
            ``None``: the defaults.
        cache_dir : str or path-like or None
            The cache folder; ``None``: :func:`meshrec.model.cache.default_cache_dir`.
        force : bool
            Rebuild (and rewrite the cache entry) even if a valid entry exists.
        stage : callable, optional
            ``stage(what)`` is called as a build starts each of its stages ("loading the
            mesh", "curvature", "writing the cache", "trees"): progress for a large mesh.
            Not called for an index loaded from the cache.

        Returns
        -------
        ModelIndex

        Raises
        ------
        TypeError
            If ``path`` is not a str or path-like, or ``cache_dir`` neither one nor None.
        ValueError
            If ``params`` is not an :class:`IndexParams`; the file is missing, not a
            regular file, or cannot be loaded as a triangle mesh (see
            :func:`meshrec.model.mesh.parse_mesh`); or the cache directory is the file's
            folder (see :func:`meshrec.model.cache.refuse_model_folder`).

        Warns
        -----
        CacheWarning
            If a cache entry is unusable (it is rebuilt) or cannot be written.
        MeshWarning
            What loading the mesh warned of (degenerate faces, single-precision steps),
            when it is built and again whenever it is loaded from the cache.
        """
        t0 = time.perf_counter()
        check_instance(path, (str, os.PathLike), "path")
        check_instance(cache_dir, (str, os.PathLike), "cache_dir", optional=True)
        if params is None:
            params = IndexParams()
        if not isinstance(params, IndexParams):
            raise ValueError(f"params must be an IndexParams or None, got {params!r}")
        p = check_mesh_path(path)
        cache = ArrayCache(cache_dir)
        refuse_model_folder(cache.directory, p.parent, subfolders=False)
        # One read: the key hashes exactly the bytes that are parsed (a file replaced
        # between a hash and a second read would store one content under another's key).
        data = read_mesh_file(p)
        digest = hashlib.sha256(data).hexdigest()
        key = make_key(
            digest, {**dataclasses.asdict(params), "record": RECORD_VERSION}, kind="model-index"
        )
        store = DerivedStore(cache.directory, digest, dataclasses.asdict(params), p.stem)
        index = None
        if not force:
            arrays = cache.load(key, IndexRecord.names(), label=p.stem)
            if arrays is not None:
                try:
                    record = IndexRecord.from_arrays(arrays)
                    index = cls.from_record(p, params, record, from_cache=True, derived=store)
                    for text in record.mesh_warnings:
                        warnings.warn(text, MeshWarning, stacklevel=2)
                except ValueError as exc:
                    warnings.warn(
                        f"cache entry for {str(p)!r} is inconsistent ({exc}); rebuilding",
                        CacheWarning,
                        stacklevel=2,
                    )
        if index is None:
            say = stage if stage is not None else (lambda what: None)
            say("loading the mesh")
            t_build = time.perf_counter()
            # the mesh's own warnings are kept in the record and said again on every
            # cached load (a warning said only on the first build is easily missed)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                vertices, faces = parse_mesh(data, p)
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            said = tuple(str(w.message) for w in caught if issubclass(w.category, MeshWarning))
            data = None  # the bytes of a large STL are large: not kept through the build
            mesh = MeshData.from_arrays(vertices, faces)
            bulge = edge_bulges(mesh, params.crease_angle_deg)
            surface = AabbSurface(mesh=mesh, edge_bulge=bulge)
            say("curvature")
            spacing, radius, range_radius = params.lengths(mesh.scale)
            curvature = CurvatureTable.from_mesh(
                mesh,
                surface,
                spacing=spacing,
                curvature_radius=radius,
                range_radius=range_radius,
                crease_angle_deg=params.sharp_angle_deg,
            )
            build_seconds = time.perf_counter() - t_build
            say("writing the cache")
            record = IndexRecord.from_parts(mesh, curvature, bulge, build_seconds, said)
            cache.save(key, record.to_arrays(), label=p.stem)
            say("trees")
            index = cls(
                name=p.stem,
                path=p,
                params=params,
                mesh=mesh,
                curvature=curvature,
                surface=surface,
                build_seconds=build_seconds,
                mesh_warnings=said,
                derived=store,
            )
        object.__setattr__(index, "load_seconds", time.perf_counter() - t0)
        return index

    @classmethod
    def from_record(
        cls,
        path: str | os.PathLike,
        params: IndexParams,
        record: IndexRecord,
        from_cache: bool = False,
        derived: DerivedStore | None = None,
    ) -> ModelIndex:
        """The index of a cache record (the trees are built here).

        Parameters
        ----------
        path : str or path-like
            The mesh file the record was built from (its stem names the model).
        params : IndexParams
            The parameters it was built with.
        record : IndexRecord
        from_cache : bool
            Whether the record came from the cache.
        derived : DerivedStore or None
            Where the index keeps its resolution, vertex scatter and near-symmetries once
            computed (:mod:`meshrec.model.derived`); None: computed once per process.

        Returns
        -------
        ModelIndex

        Raises
        ------
        TypeError
            If ``record`` is not an :class:`IndexRecord`, ``params`` not an
            :class:`IndexParams` or ``derived`` neither a :class:`DerivedStore` nor None.
        """
        if not isinstance(record, IndexRecord):
            raise TypeError(f"record must be an IndexRecord, got {type(record).__name__}")
        mesh, curvature, surface = record.parts()
        path = Path(path)
        return cls(
            name=path.stem,
            path=path,
            params=params,
            mesh=mesh,
            curvature=curvature,
            surface=surface,
            build_seconds=record.build_seconds,
            from_cache=from_cache,
            mesh_warnings=record.mesh_warnings,
            derived=derived,
        )

    def to_record(self) -> IndexRecord:
        """The cache record of this index.

        Returns
        -------
        IndexRecord

        Raises
        ------
        TypeError
            If the surface backend is not the default :class:`AabbSurface` (only its
            bulge table is cached).
        """
        if not isinstance(self.surface, AabbSurface):
            raise TypeError(
                f"surface must be an AabbSurface to be cached, got {type(self.surface).__name__}"
            )
        return IndexRecord.from_parts(
            self.mesh,
            self.curvature,
            self.surface.edge_bulge,
            self.build_seconds,
            self.mesh_warnings,
        )
