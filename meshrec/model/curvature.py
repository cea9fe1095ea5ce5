"""The per-vertex curvature table of a model and its (K, H) lookup (the paper's Section 2.1).

At every vertex: the principal curvatures ``k1 >= k2`` and their directions, from libigl's
quadric fitting over a ball of ``radius_edges`` mean edge lengths, ``K = k1 k2`` and
``H = (k1 + k2) / 2``. Sign convention (libigl's): curvature is positive where the surface
bends away from its normal, the normal following the face winding, so a sphere with
outward normals has ``k1 = k2 = +1/r``.

A KD tree over the valid vertices' ``(K * s, H)`` answers :meth:`CurvatureTable.lookup`,
with ``s = 1 / (2 median |H|)`` so that both axes count about equally (for a sphere-like
region ``d(K s) ~ dH``). The tree is built when a table is created or unpickled; it is
never cached or pickled.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, fields

import igl
import numpy as np
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.model._arrays import readonly
from meshrec.model.mesh import MeshData

__all__ = ["CurvatureTable"]


@dataclass(frozen=True, eq=False)
class CurvatureTable:
    """Principal curvatures at a mesh's vertices, and the (K, H) lookup over them.

    Build it from a mesh with :meth:`from_mesh`; the constructor takes every field (e.g.
    from the cache). The arrays are read-only.

    Attributes
    ----------
    k1, k2 : (n,) float64
        Principal curvatures, ``k1 >= k2``; NaN where ``valid`` is False.
    dir1, dir2 : (n, 3) float64
        Principal directions of ``k1`` and ``k2``; zero where ``valid`` is False.
    valid : (n,) bool
        False where libigl's curvature failed (its bad vertices, non-finite values) or the
        normal is undefined; invalid vertices never enter the lookup table.
    radius_edges : int
        Curvature ball radius in mean edge lengths.
    curvature_radius : float
        The same radius in model units.
    scale : float
        The model's size, ``sqrt(surface area)``: on a model without curvature the K axis
        of the lookup is scaled by it.
    K, H : (n,) float64
        Gaussian ``k1 * k2`` and mean ``(k1 + k2) / 2`` curvature (derived).
    table_vertices : (t,) int64
        The vertices in the lookup table: valid, with finite K and H (derived).
    kh_scale : float
        ``s``, the factor of K in the lookup's scaled coordinates ``(K s, H)`` (derived).

    Raises
    ------
    ValueError
        If the arrays' shapes do not agree, or ``scale`` is not finite and positive.
    """

    k1: np.ndarray = field(repr=False)
    k2: np.ndarray = field(repr=False)
    dir1: np.ndarray = field(repr=False)
    dir2: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    radius_edges: int
    curvature_radius: float
    scale: float
    K: np.ndarray = field(init=False, repr=False)
    H: np.ndarray = field(init=False, repr=False)
    table_vertices: np.ndarray = field(init=False, repr=False)
    kh_scale: float = field(init=False, repr=False)
    _kdtree: cKDTree = field(init=False, repr=False)

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        k1 = readonly(self.k1, np.float64, (None,), "k1")
        n = len(k1)
        put("k1", k1)
        put("k2", readonly(self.k2, np.float64, (n,), "k2"))
        for name in ("dir1", "dir2"):
            put(name, readonly(getattr(self, name), np.float64, (n, 3), name))
        valid = readonly(self.valid, bool, (n,), "valid")
        put("valid", valid)
        put("radius_edges", int(self.radius_edges))
        put("curvature_radius", float(self.curvature_radius))
        scale = float(self.scale)
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be finite and > 0, got {self.scale!r}")
        put("scale", scale)
        K = self.k1 * self.k2
        H = 0.5 * (self.k1 + self.k2)
        K.setflags(write=False)
        H.setflags(write=False)
        put("K", K)
        put("H", H)

        # The lookup table: valid vertices with finite (K, H) only.
        table = np.flatnonzero(valid & np.isfinite(K) & np.isfinite(H))
        table.setflags(write=False)
        put("table_vertices", table)
        h_ref = float(np.median(np.abs(H[table]))) if len(table) else 0.0
        if not (math.isfinite(h_ref) and h_ref > defaults.LOOKUP_MIN_H_FRACTION / scale):
            # A flat (or curvature-less) model: use the curvature of the model's size.
            h_ref = 1.0 / scale
        s = 1.0 / (2.0 * h_ref)
        put("kh_scale", s)
        put(
            "_kdtree",
            cKDTree(
                np.column_stack([K[table] * s, H[table]]),
                balanced_tree=False,
                compact_nodes=False,
            ),
        )

    @classmethod
    def from_mesh(cls, mesh: MeshData, radius_edges: int) -> CurvatureTable:
        """Estimate the curvatures of a mesh with libigl.

        Parameters
        ----------
        mesh : MeshData
        radius_edges : int
            Ball radius in mean edge lengths (``>= 1``), e.g.
            :meth:`meshrec.model.index.IndexParams.radius_edges`.

        Returns
        -------
        CurvatureTable

        Raises
        ------
        TypeError
            If ``mesh`` is not a :class:`MeshData`.
        ValueError
            If ``radius_edges`` is not an integer >= 1.
        """
        if not isinstance(mesh, MeshData):
            raise TypeError(f"mesh must be a MeshData, got {type(mesh).__name__}")
        if (
            isinstance(radius_edges, bool)
            or not isinstance(radius_edges, (int, np.integer))
            or radius_edges < 1
        ):
            raise ValueError(f"radius_edges must be an integer >= 1, got {radius_edges!r}")
        k1, k2, dir1, dir2, valid = _curvatures(mesh.vertices, mesh.faces, int(radius_edges))
        valid &= mesh.normal_ok
        return cls(
            k1=k1,
            k2=k2,
            dir1=dir1,
            dir2=dir2,
            valid=valid,
            radius_edges=int(radius_edges),
            curvature_radius=int(radius_edges) * mesh.avg_edge,
            scale=mesh.scale,
        )

    def __reduce__(self):
        # The KD tree is rebuilt, not pickled.
        args = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        return (functools.partial(type(self), **args), ())

    def __repr__(self) -> str:
        return (
            f"CurvatureTable(vertices={len(self.k1)}, table={len(self.table_vertices)}, "
            f"radius_edges={self.radius_edges}, curvature_radius={self.curvature_radius:.6g})"
        )

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
        s = self.kh_scale
        x = np.array([K * s, H])
        r = math.hypot(tol_K * s, tol_H)
        if math.isfinite(r):
            # A ball covering the box, widened for rounding in the scaled coordinates.
            r = r * (1.0 + 1e-9) + 1e-9 * (abs(x[0]) + abs(H)) + 1e-300
            rows = np.asarray(self._kdtree.query_ball_point(x, r), dtype=np.int64)
            cand = self.table_vertices[rows]
        else:
            cand = self.table_vertices
        keep = (np.abs(self.K[cand] - K) <= tol_K) & (np.abs(self.H[cand] - H) <= tol_H)
        return np.sort(cand[keep])


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
