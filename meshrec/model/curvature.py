"""The curvature table of a model, at sites on its smooth surface, and its (K, H) lookup
(the paper's Section 2.1, made independent of the tessellation: issue 13).

The sites (:mod:`meshrec.model.sites`) are spread evenly over the surface the mesh
approximates, whatever its triangles: at each, the principal curvatures ``k1 >= k2`` of
the smooth normal field and their directions, ``K = k1 k2`` and ``H = (k1 + k2) / 2``.
Sign convention (libigl's): curvature is positive where the surface bends away from its
normal, the normal following the face winding, so a sphere with outward normals has
``k1 = k2 = +1/r``.

Each site also holds the range of (K, H) over its neighbourhood at the touch curves' scale
(``range_radius``), so that a touch straddling the junction of two patches (a capsule's
cylinder and cap, a fillet and a flat) still finds the right model: the lookup is an
interval test, a site matching when the query's tolerance box meets its range. Sites on
sharp feature edges (*crease sites*) match any query bending their way with K about 0.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, fields

import numpy as np

from meshrec import defaults
from meshrec.model._arrays import readonly
from meshrec.model.mesh import MeshData
from meshrec.model.sites import sample_sites

__all__ = ["CurvatureTable"]


@dataclass(frozen=True, eq=False)
class CurvatureTable:
    """Principal curvatures at sites on a model's smooth surface, and the (K, H) lookup.

    Build it with :meth:`from_mesh`; the constructor takes every field (e.g. from the
    cache). The arrays are read-only.

    Attributes
    ----------
    points : (n, 3) float64
        The sites, model coordinates.
    normals : (n, 3) float64
        Unit normals at the sites (a crease site: the bisector of its faces' normals).
    normals2 : (n, 3) float64
        A crease site's first face normal (the second is its mirror about ``normals``);
        ``normals`` elsewhere.
    k1, k2 : (n,) float64
        Principal curvatures, ``k1 >= k2``; NaN where ``valid`` is False.
    dir1, dir2 : (n, 3) float64
        Principal directions of ``k1`` and ``k2``; zero where ``valid`` is False.
    valid : (n,) bool
        False where the curvature could not be fitted; invalid sites never match.
    K_range, H_range : (n, 2) float64
        Lowest and highest K and H over each site's neighbourhood.
    crease : (n,) bool
        Sites on sharp feature edges.
    face_patch : (m,) int64
        The smooth patch of each mesh face (faces joined across edges sharper than the
        crease angle belong to different patches).
    spacing : float
        Distance asked between sites, model units.
    curvature_radius : float
        Radius of the neighbourhood the curvatures are fitted over.
    range_radius : float
        Radius of the neighbourhood of the ranges.
    scale : float
        The model's size, ``sqrt(surface area)``: on a model without curvature the K axis
        of the lookup is scaled by it.
    K, H : (n,) float64
        Gaussian ``k1 * k2`` and mean ``(k1 + k2) / 2`` curvature (derived).
    table_sites : (t,) int64
        The sites in the lookup table: valid, with finite K and H (derived).
    kh_scale : float
        ``s = 1 / (2 median |H|)``, weighing K against H when ranking matches (derived).

    Raises
    ------
    ValueError
        If the arrays' shapes do not agree, or ``scale`` is not finite and positive.
    """

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
    spacing: float
    curvature_radius: float
    range_radius: float
    scale: float
    K: np.ndarray = field(init=False, repr=False)
    H: np.ndarray = field(init=False, repr=False)
    table_sites: np.ndarray = field(init=False, repr=False)
    kh_scale: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        points = readonly(self.points, np.float64, (None, 3), "points")
        n = len(points)
        put("points", points)
        for name in ("normals", "normals2", "dir1", "dir2"):
            put(name, readonly(getattr(self, name), np.float64, (n, 3), name))
        for name in ("k1", "k2"):
            put(name, readonly(getattr(self, name), np.float64, (n,), name))
        for name in ("K_range", "H_range"):
            put(name, readonly(getattr(self, name), np.float64, (n, 2), name))
        valid = readonly(self.valid, bool, (n,), "valid")
        put("valid", valid)
        put("crease", readonly(self.crease, bool, (n,), "crease"))
        put("face_patch", readonly(self.face_patch, np.int64, (None,), "face_patch"))
        for name in ("spacing", "curvature_radius", "range_radius"):
            put(name, float(getattr(self, name)))
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
        # The lookup table: valid sites with finite (K, H) and ranges only.
        ok = valid & np.isfinite(K) & np.isfinite(H)
        ok &= ~np.isnan(self.K_range).any(axis=1) & ~np.isnan(self.H_range).any(axis=1)
        table = np.flatnonzero(ok)
        table.setflags(write=False)
        put("table_sites", table)
        smooth = table[~self.crease[table]]
        h_ref = float(np.median(np.abs(H[smooth]))) if len(smooth) else 0.0
        if not (math.isfinite(h_ref) and h_ref > defaults.LOOKUP_MIN_H_FRACTION / scale):
            # A flat (or curvature-less) model: use the curvature of the model's size.
            h_ref = 1.0 / scale
        put("kh_scale", 1.0 / (2.0 * h_ref))
        # The table's columns, contiguous, for the interval test.
        put("_lo", np.column_stack([self.K_range[table, 0], self.H_range[table, 0]]))
        put("_hi", np.column_stack([self.K_range[table, 1], self.H_range[table, 1]]))

    @classmethod
    def from_mesh(
        cls,
        mesh: MeshData,
        surface,
        *,
        spacing: float,
        curvature_radius: float,
        range_radius: float,
        crease_angle_deg: float = defaults.SITE_CREASE_ANGLE_DEG,
    ) -> CurvatureTable:
        """Sample a mesh's smooth surface and estimate the curvatures at the sites.

        Parameters
        ----------
        mesh : MeshData
        surface : AabbSurface
            The mesh's surface queries (their smooth offsets place the sites).
        spacing, curvature_radius : float
            Distance between sites and radius of the curvature fit, model units (> 0),
            e.g. from :meth:`meshrec.model.index.IndexParams.lengths`.
        range_radius : float
            Radius of the neighbourhood of each site's (K, H) range (>= 0).
        crease_angle_deg : float
            Adjacent faces whose normals differ by more than this are a sharp edge.

        Returns
        -------
        CurvatureTable

        Raises
        ------
        TypeError
            If ``mesh`` is not a :class:`MeshData`.
        ValueError
            If a length is not finite and positive (``range_radius``: non-negative) or
            ``crease_angle_deg`` is not in (0, 180].
        """
        if not isinstance(mesh, MeshData):
            raise TypeError(f"mesh must be a MeshData, got {type(mesh).__name__}")
        s = sample_sites(mesh, surface, spacing, curvature_radius, range_radius, crease_angle_deg)
        return cls(
            points=s.points,
            normals=s.normals,
            normals2=s.normals2,
            k1=s.k1,
            k2=s.k2,
            dir1=s.dir1,
            dir2=s.dir2,
            valid=s.valid,
            K_range=s.K_range,
            H_range=s.H_range,
            crease=s.crease,
            face_patch=s.face_patch,
            spacing=spacing,
            curvature_radius=curvature_radius,
            range_radius=range_radius,
            scale=mesh.scale,
        )

    def __reduce__(self):
        # Only the constructor's fields are pickled; the derived ones are rebuilt.
        args = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        return (functools.partial(type(self), **args), ())

    def __repr__(self) -> str:
        return (
            f"CurvatureTable(sites={len(self.points)}, table={len(self.table_sites)}, "
            f"creases={int(self.crease.sum())}, curvature_radius={self.curvature_radius:.6g})"
        )

    def lookup(self, K: float, H: float, tol_K: float, tol_H: float) -> np.ndarray:
        """The sites whose (K, H) range meets a box around ``(K, H)`` (the table lookup).

        A site matches when ``K_range[v, 0] - tol_K <= K <= K_range[v, 1] + tol_K`` and
        the same holds for H: on a smooth patch with no change of curvature nearby this
        is ``|K[v] - K| <= tol_K`` and ``|H[v] - H| <= tol_H``. A vectorised test over
        every table site (not a KD-tree query: ranges are boxes, and a table of a few
        thousand sites is scanned in tens of microseconds).

        Parameters
        ----------
        K, H : float
            Gaussian and mean curvature to match (finite).
        tol_K, tol_H : float
            Half-widths of the box, ``>= 0``; ``inf`` leaves that axis unconstrained.

        Returns
        -------
        (k,) int64
            Sorted indices of the matching sites.

        Raises
        ------
        ValueError
            If ``K`` or ``H`` is not finite or a tolerance is negative or NaN.
        """
        K = _check_finite("K", K)
        H = _check_finite("H", H)
        tol_K = _check_tolerance("tol_K", tol_K)
        tol_H = _check_tolerance("tol_H", tol_H)
        lo, hi = self._lo, self._hi
        keep = (lo[:, 0] - tol_K <= K) & (hi[:, 0] + tol_K >= K)
        keep &= (lo[:, 1] - tol_H <= H) & (hi[:, 1] + tol_H >= H)
        return self.table_sites[keep]

    def mismatch(self, sites: np.ndarray, K: float, H: float, tol_K: float, tol_H: float):
        """How far each site's own (K, H) lies from the query, in tolerances.

        Parameters
        ----------
        sites : (k,) int
            Site indices, e.g. from :meth:`lookup`.
        K, H, tol_K, tol_H : float
            The query and its tolerances (> 0).

        Returns
        -------
        (k,) float64
            ``|K[v] - K| / tol_K + |H[v] - H| / tol_H``; for a crease site, whose own
            value means little, the distance of the query to its range.
        """
        sites = np.asarray(sites, dtype=np.int64)
        own = np.abs(self.K[sites] - K) / tol_K + np.abs(self.H[sites] - H) / tol_H
        c = self.crease[sites]
        if c.any():
            s = sites[c]
            dK = np.maximum(0.0, np.maximum(self.K_range[s, 0] - K, K - self.K_range[s, 1]))
            dH = np.maximum(0.0, np.maximum(self.H_range[s, 0] - H, H - self.H_range[s, 1]))
            own[c] = dK / tol_K + dH / tol_H
        return own


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
