"""The per-model index: curvature lookup table (the paper's Section 2.1) and distance queries.

A :class:`ModelIndex` holds a cleaned triangle mesh with, at every vertex, the unit normal,
the principal curvatures ``k1 >= k2`` and directions, ``K = k1 k2`` and
``H = (k1 + k2) / 2``. Curvatures come from libigl's quadric fitting over a ball whose
radius is a fixed fraction of the model's size (:class:`IndexParams`). Sign convention
(libigl's): curvature is positive where the surface bends away from its normal, the normal
following the face winding, so a sphere with outward normals has ``k1 = k2 = +1/r``.

Two search structures are built when an index is created or loaded (they are not cached):

* a KD tree over the valid vertices' ``(K * s, H)`` answering :meth:`ModelIndex.lookup`,
  with ``s = 1 / (2 median |H|)`` so that both axes count about equally (for a sphere-like
  region ``d(K s) ~ dH``);
* a libigl AABB tree over the triangles answering :meth:`ModelIndex.closest_points`.

Everything else is cached on disk (:mod:`meshrec.model.cache`), keyed by the mesh file's bytes,
the parameters and the package version.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import numbers
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import igl
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.model.cache import ArrayCache, CacheWarning, make_key, refuse_model_folder
from meshrec.model.mesh import check_mesh_path, parse_mesh, read_mesh_file

_ARRAYS = (
    "vertices", "faces", "vertex_normals", "k1", "k2", "dir1", "dir2", "valid", "edge_bulge"
)
_SCALARS = ("closed", "scale", "avg_edge", "radius_edges", "curvature_radius", "build_seconds")


@dataclass(frozen=True)
class IndexParams:
    """Parameters of the curvature table (part of the cache key).

    Parameters
    ----------
    curvature_fraction : float
        Curvature ball radius as a fraction of ``sqrt(surface area)``.
    min_radius, max_radius : int
        Bounds of the ball radius, in mean edge lengths.
    crease_angle_deg : float
        Adjacent vertex normals further apart than this mark a crease, where the smooth
        distance does not bulge the faces (see :meth:`ModelIndex.smooth_offsets`).

    Raises
    ------
    ValueError
        If ``curvature_fraction`` is not a finite positive number, the radii are not
        integers with ``1 <= min_radius <= max_radius``, or ``crease_angle_deg`` is not
        in (0, 180].
    """

    curvature_fraction: float = defaults.CURVATURE_SCALE_FRACTION
    min_radius: int = defaults.CURVATURE_MIN_RADIUS
    max_radius: int = defaults.CURVATURE_MAX_RADIUS
    crease_angle_deg: float = defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG

    def __post_init__(self) -> None:
        f = self.curvature_fraction
        if (
            isinstance(f, bool)
            or not isinstance(f, numbers.Real)
            or not (math.isfinite(f) and f > 0)
        ):
            raise ValueError(f"curvature_fraction must be a finite number > 0, got {f!r}")
        for name in ("min_radius", "max_radius"):
            r = getattr(self, name)
            if isinstance(r, bool) or not isinstance(r, numbers.Integral) or r < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {r!r}")
        if self.max_radius < self.min_radius:
            raise ValueError(
                f"max_radius must be >= min_radius, got max_radius={self.max_radius!r} "
                f"and min_radius={self.min_radius!r}"
            )
        a = self.crease_angle_deg
        if (
            isinstance(a, bool)
            or not isinstance(a, numbers.Real)
            or not (math.isfinite(a) and 0 < a <= 180)
        ):
            raise ValueError(f"crease_angle_deg must be in (0, 180] degrees, got {a!r}")
        object.__setattr__(self, "crease_angle_deg", float(a))
        object.__setattr__(self, "curvature_fraction", float(f))
        object.__setattr__(self, "min_radius", int(self.min_radius))
        object.__setattr__(self, "max_radius", int(self.max_radius))

    def radius_edges(self, scale: float, avg_edge: float) -> int:
        """The ball radius in mean edge lengths for a model of this size and resolution.

        Parameters
        ----------
        scale : float
            ``sqrt(surface area)`` of the model.
        avg_edge : float
            Mean edge length of the mesh.

        Returns
        -------
        int
            ``clip(round(curvature_fraction * scale / avg_edge), min_radius, max_radius)``.

        Raises
        ------
        ValueError
            If ``scale`` or ``avg_edge`` is not finite and positive.
        """
        for name, value in (("scale", scale), ("avg_edge", avg_edge)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        r = round(self.curvature_fraction * scale / avg_edge)
        return int(min(max(r, self.min_radius), self.max_radius))


def _readonly(a: np.ndarray, dtype, shape: tuple, name: str) -> np.ndarray:
    """A read-only C-contiguous view/copy of ``a`` with ``dtype``, checking its shape."""
    out = np.ascontiguousarray(a, dtype=dtype)
    if out.ndim != len(shape) or any(
        s is not None and s != d for s, d in zip(shape, out.shape, strict=True)
    ):
        dims = ["n" if s is None else str(s) for s in shape]
        want = f"({dims[0]},)" if len(dims) == 1 else "(" + ", ".join(dims) + ")"
        raise ValueError(f"{name} must have shape {want}, got {out.shape}")
    out = out.view()
    out.setflags(write=False)
    return out


def _surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Total area of the triangles."""
    tri = vertices[faces]
    return 0.5 * float(
        np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )


def _curvatures(
    vertices: np.ndarray, faces: np.ndarray, radius_edges: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Principal curvatures and directions with libigl (ball neighbourhood).

    Unreferenced vertices are dropped before calling libigl (it crashes on them) and, like
    the vertices libigl reports as bad or returns non-finite values for, come back invalid
    with NaN curvatures and zero directions. Where ``k1 < k2`` the pair is swapped.

    Returns
    -------
    k1, k2 : (n,) float
    dir1, dir2 : (n, 3) float
    valid : (n,) bool
    """
    n = len(vertices)
    used = np.zeros(n, dtype=bool)
    used[faces.ravel()] = True
    if used.all():
        V, F, back = vertices, faces, None
    else:
        back = np.flatnonzero(used)
        remap = np.full(n, -1, dtype=np.int64)
        remap[back] = np.arange(len(back))
        V = np.ascontiguousarray(vertices[back])
        F = np.ascontiguousarray(remap[faces])
    pd1, pd2, pv1, pv2, bad = igl.principal_curvature(V, F, int(radius_edges), False)
    ok = np.isfinite(pv1) & np.isfinite(pv2)
    ok &= np.isfinite(pd1).all(axis=1) & np.isfinite(pd2).all(axis=1)
    if len(bad):
        ok[np.asarray(bad, dtype=np.int64)] = False
    swap = ok & (pv1 < pv2)
    pv1[swap], pv2[swap] = pv2[swap], pv1[swap].copy()
    pd1[swap], pd2[swap] = pd2[swap], pd1[swap].copy()
    pv1[~ok] = np.nan
    pv2[~ok] = np.nan
    pd1[~ok] = 0.0
    pd2[~ok] = 0.0
    if back is None:
        return pv1, pv2, pd1, pd2, ok
    k1 = np.full(n, np.nan)
    k2 = np.full(n, np.nan)
    d1 = np.zeros((n, 3))
    d2 = np.zeros((n, 3))
    valid = np.zeros(n, dtype=bool)
    k1[back], k2[back], d1[back], d2[back], valid[back] = pv1, pv2, pd1, pd2, ok
    return k1, k2, d1, d2, valid


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vertex normals following the face winding, and where they are defined."""
    normals = igl.per_vertex_normals(vertices, faces)
    norm = np.linalg.norm(normals, axis=1)
    ok = np.isfinite(norm) & (norm > 0)
    normals[ok] /= norm[ok, None]
    normals[~ok] = 0.0
    return normals, ok


def _build_arrays(vertices: np.ndarray, faces: np.ndarray, params: IndexParams) -> dict:
    """Everything :class:`ModelIndex` caches, computed from a cleaned mesh."""
    t0 = time.perf_counter()
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    scale = math.sqrt(_surface_area(vertices, faces))
    avg_edge = float(igl.avg_edge_length(vertices, faces))
    radius_edges = params.radius_edges(scale, avg_edge)
    normals, normal_ok = _vertex_normals(vertices, faces)
    k1, k2, dir1, dir2, valid = _curvatures(vertices, faces, radius_edges)
    valid &= normal_ok
    closed = bool(trimesh.Trimesh(vertices, faces, process=False).is_watertight)
    bulge = _edge_bulges(vertices, faces, normals, params.crease_angle_deg)
    return {
        "vertices": vertices,
        "faces": faces,
        "vertex_normals": normals,
        "k1": k1,
        "k2": k2,
        "dir1": dir1,
        "dir2": dir2,
        "valid": valid,
        "edge_bulge": bulge,
        "closed": closed,
        "scale": scale,
        "avg_edge": avg_edge,
        "radius_edges": radius_edges,
        "curvature_radius": radius_edges * avg_edge,
        "build_seconds": time.perf_counter() - t0,
    }


def _check_finite(name: str, value) -> float:
    """``value`` as a float, or ValueError if it is not a finite real number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return v


def _check_tolerance(name: str, value) -> float:
    """``value`` as a float >= 0 (inf allowed: the axis is not constrained)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number >= 0, got {value!r}") from None
    if not v >= 0:  # also catches NaN
        raise ValueError(f"{name} must be a number >= 0, got {value!r}")
    return v


@dataclass(frozen=True, eq=False)
class ModelIndex:
    """One model: its cleaned mesh, per-vertex curvature table and distance structures.

    Build it with :meth:`from_file`. The arrays are read-only.

    Attributes
    ----------
    name : str
        The file's stem.
    path : Path
        The mesh file.
    vertices : (n, 3) float64
    faces : (m, 3) int64
    vertex_normals : (n, 3) float64
        Unit normals following the face winding (libigl's per-vertex normals); zero where
        undefined.
    k1, k2 : (n,) float64
        Principal curvatures, ``k1 >= k2``; NaN where ``valid`` is False.
    dir1, dir2 : (n, 3) float64
        Principal directions of ``k1`` and ``k2``; zero where ``valid`` is False.
    valid : (n,) bool
        False where libigl's curvature failed (its bad vertices, non-finite values) or the
        normal is undefined; invalid vertices never enter the lookup table.
    closed : bool
        Whether the mesh is watertight.
    scale : float
        ``sqrt(surface area)``, model units.
    avg_edge : float
        Mean edge length, model units.
    radius_edges : int
        Curvature ball radius in mean edge lengths (see :meth:`IndexParams.radius_edges`).
    curvature_radius : float
        The same radius in model units, ``radius_edges * avg_edge``.
    params : IndexParams
    build_seconds : float
        Time the table took to build (when it was built, also for a cached index).
    from_cache : bool
        Whether the arrays came from the on-disk cache.
    load_seconds : float
        Wall time of :meth:`from_file` (hashing, cache load or build, tree building).
    edge_bulge : (m, 3) float64 or None
        Per face and edge, the smooth surface's bulge (see ``_edge_bulges``), cached with
        the curvature table; ``None``: computed from the vertex normals.
    K, H : (n,) float64
        Gaussian ``k1 * k2`` and mean ``(k1 + k2) / 2`` curvature (derived).
    face_normals : (m, 3) float64
        Unit face normals following the winding (derived; zero for degenerate faces).

    Raises
    ------
    ValueError
        If the arrays' shapes do not agree or a face index is out of range.
    """

    name: str
    path: Path
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    vertex_normals: np.ndarray = field(repr=False)
    k1: np.ndarray = field(repr=False)
    k2: np.ndarray = field(repr=False)
    dir1: np.ndarray = field(repr=False)
    dir2: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    closed: bool
    scale: float
    avg_edge: float
    radius_edges: int
    curvature_radius: float
    params: IndexParams = field(default_factory=IndexParams)
    build_seconds: float = 0.0
    from_cache: bool = False
    load_seconds: float = 0.0
    edge_bulge: np.ndarray | None = field(default=None, repr=False)
    K: np.ndarray = field(init=False, repr=False)
    H: np.ndarray = field(init=False, repr=False)
    _kh_scale: float = field(init=False, repr=False)
    _table_vertices: np.ndarray = field(init=False, repr=False)
    _kdtree: cKDTree = field(init=False, repr=False)
    _aabb: igl.AABB = field(init=False, repr=False)
    face_normals: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        V = _readonly(self.vertices, np.float64, (None, 3), "vertices")
        n = len(V)
        F = _readonly(self.faces, np.int64, (None, 3), "faces")
        if len(F) == 0:
            raise ValueError("faces must hold at least one triangle, got shape (0, 3)")
        if F.min() < 0 or F.max() >= n:
            raise ValueError(
                f"faces must index vertices 0..{n - 1}, got range {F.min()}..{F.max()}"
            )
        put("vertices", V)
        put("faces", F)
        put("vertex_normals", _readonly(self.vertex_normals, np.float64, (n, 3), "vertex_normals"))
        for name in ("k1", "k2"):
            put(name, _readonly(getattr(self, name), np.float64, (n,), name))
        for name in ("dir1", "dir2"):
            put(name, _readonly(getattr(self, name), np.float64, (n, 3), name))
        valid = _readonly(self.valid, bool, (n,), "valid")
        put("valid", valid)
        put("path", Path(self.path))
        put("closed", bool(self.closed))
        put("scale", float(self.scale))
        put("avg_edge", float(self.avg_edge))
        put("radius_edges", int(self.radius_edges))
        put("curvature_radius", float(self.curvature_radius))
        K = self.k1 * self.k2
        H = 0.5 * (self.k1 + self.k2)
        K.setflags(write=False)
        H.setflags(write=False)
        put("K", K)
        put("H", H)

        # The lookup table: valid vertices with finite (K, H) only.
        table = np.flatnonzero(valid & np.isfinite(K) & np.isfinite(H))
        table.setflags(write=False)
        put("_table_vertices", table)
        h_ref = float(np.median(np.abs(H[table]))) if len(table) else 0.0
        floor = defaults.LOOKUP_MIN_H_FRACTION / self.scale if self.scale > 0 else 0.0
        if not (math.isfinite(h_ref) and h_ref > floor):
            # A flat (or curvature-less) model: use the curvature of the model's size.
            h_ref = 1.0 / self.scale if self.scale > 0 else 1.0
        s = 1.0 / (2.0 * h_ref)
        put("_kh_scale", s)
        put(
            "_kdtree",
            cKDTree(
                np.column_stack([K[table] * s, H[table]]),
                balanced_tree=False,
                compact_nodes=False,
            ),
        )

        aabb = igl.AABB()
        aabb.init(V, F)
        put("_aabb", aabb)
        face_normals = igl.per_face_normals(V, F, np.zeros(3))
        face_normals.setflags(write=False)
        put("face_normals", face_normals)
        if self.edge_bulge is None:
            bulge = _edge_bulges(V, F, self.vertex_normals, self.params.crease_angle_deg)
        else:
            bulge = _readonly(self.edge_bulge, np.float64, (len(F), 3), "edge_bulge")
        put("edge_bulge", bulge)

    def __reduce__(self):
        # The AABB tree cannot be pickled: pickle the fields and rebuild the trees.
        args = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}
        return (_unpickle_index, (args,))

    def __repr__(self) -> str:
        return (
            f"ModelIndex({self.name!r}, vertices={len(self.vertices)}, "
            f"faces={len(self.faces)}, table={len(self._table_vertices)}, "
            f"closed={self.closed}, scale={self.scale:.6g}, from_cache={self.from_cache})"
        )

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
        ValueError
            If ``params`` is not an :class:`IndexParams`; the file is missing, not a
            regular file, or cannot be loaded as a triangle mesh (see
            :func:`meshrec.model.mesh.parse_mesh`); or the cache directory is the file's
            folder (see :func:`meshrec.model.cache.refuse_model_folder`).

        Warns
        -----
        CacheWarning
            If a cache entry is unusable (it is rebuilt) or cannot be written.
        """
        t0 = time.perf_counter()
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
        key = make_key(digest, dataclasses.asdict(params), kind="model-index")
        index = None
        if not force:
            arrays = cache.load(key, _ARRAYS + _SCALARS, label=p.stem)
            if arrays is not None:
                try:
                    index = cls._from_arrays(p, params, arrays, from_cache=True)
                except ValueError as exc:
                    warnings.warn(
                        f"cache entry for {str(p)!r} is inconsistent ({exc}); rebuilding",
                        CacheWarning,
                        stacklevel=2,
                    )
        if index is None:
            say = stage if stage is not None else (lambda what: None)
            say("loading the mesh")
            vertices, faces = parse_mesh(data, p)
            data = None  # the bytes of a large STL are large: not kept through the build
            say("curvature")
            arrays = _build_arrays(vertices, faces, params)
            say("writing the cache")
            cache.save(key, {k: np.asarray(v) for k, v in arrays.items()}, label=p.stem)
            say("trees")
            index = cls._from_arrays(p, params, arrays, from_cache=False)
        object.__setattr__(index, "load_seconds", time.perf_counter() - t0)
        return index

    @classmethod
    def _from_arrays(cls, path: Path, params: IndexParams, arrays: dict, from_cache: bool):
        """Construct from the cached (or freshly built) arrays."""
        scalars = {name: np.asarray(arrays[name]).item() for name in _SCALARS}
        return cls(
            name=path.stem,
            path=path,
            params=params,
            from_cache=from_cache,
            **{name: arrays[name] for name in _ARRAYS},
            **scalars,
        )

    # ------------------------------------------------------------------ queries
    def lookup(self, K: float, H: float, tol_K: float, tol_H: float) -> np.ndarray:
        """The table entries matching ``(K, H)`` within a box (the paper's table lookup).

        Parameters
        ----------
        K, H : float
            Gaussian and mean curvature to match (finite).
        tol_K, tol_H : float
            Half-widths of the box, ``>= 0``; ``inf`` leaves that axis unconstrained.

        Returns
        -------
        (k,) int64
            Sorted indices of the valid vertices ``v`` with ``|K[v] - K| <= tol_K`` and
            ``|H[v] - H| <= tol_H``.

        Raises
        ------
        ValueError
            If ``K`` or ``H`` is not finite or a tolerance is negative or NaN.
        """
        K = _check_finite("K", K)
        H = _check_finite("H", H)
        tol_K = _check_tolerance("tol_K", tol_K)
        tol_H = _check_tolerance("tol_H", tol_H)
        s = self._kh_scale
        x = np.array([K * s, H])
        r = math.hypot(tol_K * s, tol_H)
        if math.isfinite(r):
            # A ball covering the box, widened for rounding in the scaled coordinates.
            r = r * (1.0 + 1e-9) + 1e-9 * (abs(x[0]) + abs(H)) + 1e-300
            rows = np.asarray(self._kdtree.query_ball_point(x, r), dtype=np.int64)
            cand = self._table_vertices[rows]
        else:
            cand = self._table_vertices
        keep = (np.abs(self.K[cand] - K) <= tol_K) & (np.abs(self.H[cand] - H) <= tol_H)
        return np.sort(cand[keep])

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest points on the mesh (unsigned Euclidean distance), via the AABB tree.

        Parameters
        ----------
        points : (n, 3) float
            Query points, model coordinates.

        Returns
        -------
        dist : (n,) float64
            Unsigned distances to the surface.
        closest : (n, 3) float64
            The closest surface points.
        face : (n,) int64
            The face each closest point lies on.

        Raises
        ------
        ValueError
            If ``points`` is not an (n, 3) array of finite numbers.
        """
        P = np.ascontiguousarray(points, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {P.shape}")
        if not np.isfinite(P).all():
            raise ValueError("points must be finite, got NaN or inf")
        sqr, face, closest = self._aabb.squared_distance(self.vertices, self.faces, P)
        return np.sqrt(np.maximum(sqr, 0.0)), closest, face.astype(np.int64, copy=False)

    def smooth_offsets(self, closest: np.ndarray, face: np.ndarray) -> np.ndarray:
        """Height of the smooth surface implied by the vertex normals above the flat faces.

        The flat triangles of a mesh of a curved surface lie inside or outside it by up to
        a sagitta; the distance to the flat faces therefore ripples with the faces, and
        those ripples make spurious local minima of the registration error. A quadratic
        patch per face (see ``_edge_bulges``), continuous across edges, removes most of
        the deviation: the signed distance to the smooth surface is the signed distance
        to the face minus this height.

        Parameters
        ----------
        closest : (n, 3) float
            Points on the faces, e.g. from :meth:`closest_points`.
        face : (n,) int
            The face of each point.

        Returns
        -------
        (n,) float64
            Heights along the face normals, model units.
        """
        return self.smooth_offsets_and_gradients(closest, face)[0]

    def smooth_offsets_and_gradients(
        self, closest: np.ndarray, face: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`smooth_offsets` and their gradients along the faces.

        Parameters
        ----------
        closest : (n, 3) float
            Points on the faces.
        face : (n,) int
            The face of each point.

        Returns
        -------
        heights : (n,) float64
            As :meth:`smooth_offsets`.
        gradients : (n, 3) float64
            Gradient of the height as the point moves in its face's plane.
        """
        f = np.asarray(face, dtype=np.int64)
        w = self._barycentric(np.asarray(closest, dtype=np.float64), f)
        d = self.edge_bulge[f]
        w0, w1, w2 = w.T
        d0, d1, d2 = d.T
        heights = w0 * w1 * d0 + w1 * w2 * d1 + w2 * w0 * d2
        # dh/dw_i chained with the barycentric gradients in the face plane.
        dh = np.column_stack([d0 * w1 + d2 * w2, d0 * w0 + d1 * w2, d1 * w1 + d2 * w0])
        gradients = np.einsum("ni,nij->nj", dh, self._face_table()["grads"][f])
        return heights, gradients

    def _face_table(self) -> dict:
        """Per-face constants of the barycentric coordinates, computed on first use.

        (Not at load time: the cached load stays fast, and only registrations need them.)
        """
        table = self.__dict__.get("_faces_cache")
        if table is None:
            V, F = self.vertices, self.faces
            a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
            v0, v1 = b - a, c - a
            d00 = np.einsum("ij,ij->i", v0, v0)
            d01 = np.einsum("ij,ij->i", v0, v1)
            d11 = np.einsum("ij,ij->i", v1, v1)
            den = d00 * d11 - d01 * d01
            ok = den > 1e-300 * np.maximum(d00 * d11, 1e-300)
            # grad w_i = n x e_i / |n|^2 with n = v0 x v1 and e_i the edge opposite vertex
            # i, counter-clockwise (zero on degenerate faces).
            n = _cross(v0, v1)
            nn = np.einsum("ij,ij->i", n, n)
            inv = np.where(ok & (nn > 0), 1.0 / np.where(nn > 0, nn, 1.0), 0.0)[:, None]
            grads = np.stack([_cross(n, c - b), _cross(n, a - c), _cross(n, b - a)], axis=1)
            grads *= inv[:, :, None]
            table = {"a": a, "v0": v0, "v1": v1, "d00": d00, "d01": d01, "d11": d11,
                     "den": np.where(ok, den, np.inf), "ok": ok, "grads": grads}
            self.__dict__["_faces_cache"] = table
        return table

    def _barycentric(self, p: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Barycentric coordinates (n, 3) of points ``p`` in faces ``f``, clipped to them.

        Not ``igl.barycentric_coordinates_tri`` or trimesh's ``points_to_barycentric``:
        both recompute each face's dot products on every call, and this runs at every
        residual evaluation of the searches; the per-face constants are tabulated once.
        """
        t = self._face_table()
        v2 = p - t["a"][f]
        d20 = np.einsum("ij,ij->i", v2, t["v0"][f])
        d21 = np.einsum("ij,ij->i", v2, t["v1"][f])
        d00, d01, d11, den = t["d00"][f], t["d01"][f], t["d11"][f], t["den"][f]
        v = (d11 * d20 - d01 * d21) / den
        u = (d00 * d21 - d01 * d20) / den
        w = np.column_stack([1.0 - v - u, v, u])
        w[~t["ok"][f]] = 1.0 / 3.0
        w = np.clip(w, 0.0, None)
        return w / w.sum(axis=1, keepdims=True)

    def interpolated_normals(self, closest: np.ndarray, face: np.ndarray) -> np.ndarray:
        """The smooth normal field at points on faces: barycentric vertex-normal blend.

        Parameters
        ----------
        closest : (n, 3) float
            Points on (or near) the faces, e.g. from :meth:`closest_points`.
        face : (n,) int
            The face of each point.

        Returns
        -------
        (n, 3) float64
            Unit normals. Barycentric weights are clipped to the triangle; where the blend
            vanishes the face's own normal is used.

        Raises
        ------
        ValueError
            If the shapes disagree or a face index is out of range.
        """
        P = np.ascontiguousarray(closest, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"closest must have shape (n, 3), got {P.shape}")
        f = np.asarray(face)
        if f.shape != (len(P),):
            raise ValueError(f"face must have shape ({len(P)},), got {f.shape}")
        if f.size and not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"face must hold integers, got dtype {f.dtype}")
        f = f.astype(np.int64, copy=False)
        m = len(self.faces)
        if f.size and (f.min() < 0 or f.max() >= m):
            raise ValueError(f"face must index faces 0..{m - 1}, got range {f.min()}..{f.max()}")
        tri = self.faces[f]  # (n, 3)
        w = self._barycentric(P, f)
        normals = np.einsum("ni,nij->nj", w, self.vertex_normals[tri])
        norm = np.linalg.norm(normals, axis=1)
        bad = ~(norm > 1e-12)
        if bad.any():
            a, b, c = (self.vertices[tri[bad, i]] for i in range(3))
            fn = np.cross(b - a, c - a)
            normals[bad] = fn
            norm[bad] = np.linalg.norm(fn, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            normals /= norm[:, None]
        return np.nan_to_num(normals, nan=0.0)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (n, 3) arrays (np.cross costs more in overhead)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _edge_bulges(V: np.ndarray, F: np.ndarray, N: np.ndarray, crease_deg: float) -> np.ndarray:
    """Per face and edge (01, 12, 20), the bulge d_ij = (p_j - p_i) . (n_j - n_i) / 2.

    The quadratic patch h(b) = sum b_i b_j d_ij over a face's edges, with b its barycentric
    coordinates, is the height of the smooth surface above the flat face that its vertex
    normals imply (on a circle of radius R through two vertices L apart it gives the
    sagitta L^2 / (8 R) at the middle of the edge), and it agrees across shared edges. An
    edge whose normals differ by more than ``crease_deg`` degrees
    (``defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG`` by default) is a
    crease (a rim between a side and a flat cap), where a smooth surface is not implied:
    its bulge is zero.
    """
    out = np.zeros((len(F), 3))
    cos_max = np.cos(np.radians(crease_deg))
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        pi, pj = V[F[:, i]], V[F[:, j]]
        ni, nj = N[F[:, i]], N[F[:, j]]
        d = 0.5 * np.einsum("ij,ij->i", pj - pi, nj - ni)
        smooth = np.einsum("ij,ij->i", ni, nj) >= cos_max
        out[:, k] = np.where(smooth, d, 0.0)
    out.setflags(write=False)
    return out


def _unpickle_index(args: dict) -> ModelIndex:
    """Rebuild a pickled :class:`ModelIndex` (its trees are rebuilt, not unpickled)."""
    return ModelIndex(**args)
