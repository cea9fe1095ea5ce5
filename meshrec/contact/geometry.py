"""Local differential geometry at the common point of concurrent curves (step 1 of the method).

The paper (Section 2, after its reference [11]) estimates, at the point p where three data
curves sampled on a surface meet, the surface normal N and the principal, Gaussian and mean
curvatures from the curves alone:

1. each curve is fitted near p for its unit tangent t_i and curvature vector kappa_i;
2. N is the direction most nearly perpendicular to all tangents;
3. by Meusnier's theorem the normal curvature of the surface in direction t_i is
   kn_i = -kappa_i . N (whatever the tilt of the curve's plane), and Euler's formula
   kn(theta) = L cos^2 theta + 2 M cos theta sin theta + N sin^2 theta is solved for the
   second fundamental form (L, M, N), from which K = L N - M^2 and H = (L + N) / 2.

Sign convention (that of libigl's ``principal_curvature`` on the mesh side): a curvature is
positive where the surface bends away from the normal, so a sphere of radius r with its
outward normal has k1 = k2 = H = 1/r.

Curve fit. Each curve is fitted whole, as a space curve r(s) = p + polynomial of degree
``degree`` in a parameter s that approximates arc length: s is the cumulative chord length
of a lightly smoothed copy of the samples (centred moving average over
2 ``defaults.CURVE_PARAM_SMOOTHING`` + 1 samples), zero at p's position along the curve.
Smoothing makes the parameter noise-free enough (raw chord lengths are ~15% noisy at noise
0.001 and spacing 0.01), and only the parameter is smoothed: the fitted coordinates are the
raw samples. Where the samples crowd the noise (thousands along a curve), the average
widens and its chords are taken as far apart (``defaults.CURVE_PARAM_MAX_NOISE_CHORD``).
The tangent is t = r'(0)/|r'(0)| and the curvature vector
kappa = (r'' - (r''.t) t)/|r'|^2 at s = 0. The fit stops on each side where the curve turns
more than ``defaults.CURVE_FIT_MAX_TURN_DEG`` from its direction at p, so that a polynomial
still describes it. The samples of each curve must therefore be ordered along the curve
(as a probe traces it); a shuffled curve is rejected.

Measured on exact plane sections of analytic surfaces (``tests/test_geometry.py``; 61 points
0.01 apart, p the middle one), this beats the graph fit over the chord/tangent direction
(same noise, but the graph's truncation bias grows like (half-length * curvature)^4: K off by
2.2% on a sphere of radius 0.5 and 21% at radius 0.3, against 0.1% and 0.8% here, and a
graph cannot follow a curve turning by 90 degrees or more), and fits of short windows
(+-10 samples gave K, H errors of 5-17% at noise 0.001 in a prototype).
Fitting the curves jointly with a shared common point lowered the error of K only on
non-umbilic surfaces and not that of H, and biases curves that do not quite meet: not used.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npoly
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_curves, check_int, check_vector, one_line

__all__ = [
    "CommonPoint",
    "LocalGeometry",
    "RoughFitWarning",
    "estimate_local_geometry",
    "find_common_point",
]


class RoughFitWarning(UserWarning):
    """The curves fit no smooth surface patch well: they may cross an edge or a rim."""


# --------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CommonPoint(ValueEquality):
    """Where concurrent curves (nearly) meet.

    Attributes
    ----------
    point : (3,) float64
        The estimated common point p: the least-squares point closest to the tangent lines
        of the curves' fitted polynomials where they pass p.
    spread : float
        Largest distance between two curves' fitted passages at p (each fitted curve's
        point at p's position along it), i.e. how far apart the curves' copies of p are:
        a fraction of the noise level for curves that truly meet.
    indices : (c,) int64
        Index on each curve of the sample nearest to ``point``.
    """

    point: np.ndarray
    spread: float
    indices: np.ndarray


@dataclass(frozen=True, eq=False)
class LocalGeometry(ValueEquality):
    """Normal and curvatures of the surface at the common point of the curves.

    Attributes
    ----------
    point : (3,) float64
        The point p at which the geometry is estimated.
    normal : (3,) float64
        Unit surface normal N.
    frame : (3, 3) float64
        Columns t1, t2, N: orthonormal and right-handed (t1 x t2 = N), t1 the principal
        direction of k1 and t2 that of k2.
    k1, k2 : float
        Principal curvatures, k1 >= k2, positive where the surface bends away from N.
    K : float
        Gaussian curvature k1 k2.
    H : float
        Mean curvature (k1 + k2) / 2.
    tangents : (c, 3) float64
        Unit tangent of each curve at p, in the order of the input curves, each pointing
        the way the curve's samples run (increasing index).
    normal_curvatures : (c,) float64
        Normal curvature kn_i = -kappa_i . N of each curve at p.
    fit_rms : float
        Root-mean-square residual of the curve fits along the surface normal, data units:
        over all fitted samples, the residual across the fitted curve projected on the
        surface normal there (the direction perpendicular to the curve closest to N), with
        the degrees of freedom of the fits taken off. It estimates the standard deviation
        of the data noise along the normal, the part that a point-to-surface distance
        sees: for isotropic noise the deviation per coordinate (uniform noise of
        half-width e gives about e / sqrt(3)); for a probe whose error lies along the
        normal, that error's whole deviation. Where the component across the curve in the
        tangent plane agrees with it (``defaults.NOISE_ISOTROPY_MAX_RATIO``), both are
        pooled.
    half_length : float
        Median over the curves of the arc length from p to the curve's farther end, data
        units (measured along the smoothed samples, so that noise does not lengthen it).
    condition : float
        2-norm condition number of the Euler least-squares system, rows
        (cos^2, 2 cos sin, sin^2) of each tangent's angle: sqrt(2) for three tangents 60
        degrees apart, 68 for 0, 10, 20 degrees; large means nearly parallel tangents.
    curvature_sd : float
        The standard error of the principal curvatures, 1 / data units: each curve's
        curvature at p has its least-squares fit's deviation (``fit_rms`` times the fit's
        own gain: larger where the curve's samples lie on one side of p), carried through
        Euler's formula to the shape operator, whose error bounds the principal
        curvatures' (the root of its squared entries' summed variances). The (K, H)
        lookup's window is at least ``defaults.CANDIDATE_SD_FACTOR`` of it (see
        :func:`meshrec.registration.candidates.curvature_tolerance`); 0 when not computed.
    noise_rms : float
        The data noise along the surface normal estimated without any model of the shape,
        from the third differences d of consecutive samples along each curve, each taken
        along the surface normal at its samples: sqrt(mean(d^2) / 20) (independent noise
        of deviation s gives E[d^2] = 20 s^2; a smooth curve sampled finely adds little);
        pooled with the other two components where they agree, as for ``fit_rms``.
        Compare ``fit_rms``: see :attr:`fit_to_noise`.
    """

    point: np.ndarray
    normal: np.ndarray
    frame: np.ndarray
    k1: float
    k2: float
    K: float
    H: float
    tangents: np.ndarray
    normal_curvatures: np.ndarray
    fit_rms: float
    half_length: float
    condition: float
    noise_rms: float
    curvature_sd: float = 0.0

    @property
    def fit_to_noise(self) -> float:
        """``fit_rms / noise_rms``: about 1 where the curves lie on one smooth patch.

        Well above 1 (``defaults.ROUGH_FIT_RATIO``), the curve fits leave more than the
        noise: the curves cross an edge, a rim or a bump smaller than their length, and
        the curvature estimate describes no single surface. ``inf`` for noiseless data
        whose fits leave a residual.
        """
        if self.noise_rms > 0.0:
            return self.fit_rms / self.noise_rms
        return math.inf if self.fit_rms > 0.0 else 1.0

    def flipped(self) -> LocalGeometry:
        """The same geometry seen from the other side of the surface.

        N becomes -N, the principal curvatures become (-k2, -k1), H becomes -H and K is
        unchanged; the frame becomes (t2, t1, -N), still right-handed with its first column
        the direction of the new k1. The normal curvatures are negated; ``flipped()``
        applied twice gives back the original exactly.

        Returns
        -------
        LocalGeometry
        """
        frame = np.column_stack([self.frame[:, 1], self.frame[:, 0], -self.frame[:, 2]])
        return LocalGeometry(
            point=self.point.copy(),
            normal=-self.normal,
            frame=frame,
            k1=-self.k2,
            k2=-self.k1,
            K=self.K,
            H=-self.H,
            tangents=self.tangents.copy(),
            normal_curvatures=-self.normal_curvatures,
            fit_rms=self.fit_rms,
            half_length=self.half_length,
            condition=self.condition,
            noise_rms=self.noise_rms,
            curvature_sd=self.curvature_sd,
        )


# --------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------
def _order_ratio(points: np.ndarray) -> float:
    """Median distance between consecutive samples over median nearest-neighbour distance."""
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    near, _ = cKDTree(points).query(points, k=2)
    step, near = step[step > 0], near[:, 1][near[:, 1] > 0]
    if len(step) == 0 or len(near) == 0:
        return 1.0
    return float(np.median(step) / np.median(near))


def _across_normals(tangents: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The surface normal along a curve, from the curve's tangents and the normal at p.

    The surface normal at a sample is perpendicular to the curve's tangent there; of those
    directions the one closest to ``n`` is taken: ``n - (n . t) t``, normalised. It is exact
    where the surface normal stays in the plane of ``n`` and the curve (a great circle
    of a sphere, a cylinder's circle or ruling) and close wherever the normal turns
    little over the curve. Samples where the curve runs within
    ``defaults.NOISE_MIN_TANGENT_NORMAL_ANGLE_DEG`` of ``n`` (around a rim) have no such
    direction to speak of and are left out (``keep`` is False there).

    Returns
    -------
    normals : (m, 3) float64
        Unit normals (rows where ``keep`` is False are arbitrary).
    keep : (m,) bool
    """
    v = n[None, :] - (tangents @ n)[:, None] * tangents
    size = np.linalg.norm(v, axis=1)
    keep = size > np.sin(np.radians(defaults.NOISE_MIN_TANGENT_NORMAL_ANGLE_DEG))
    return v / np.maximum(size, 1e-300)[:, None], keep


def _normal_or_pooled(sq_normal, dof_normal, sq_rest, dof_rest, fallback: float) -> float:
    """The noise's deviation along the normal, from squared residual components.

    ``sq_normal`` over ``dof_normal`` estimates the variance along the normal, ``sq_rest``
    over ``dof_rest`` that of the other components. Where the two agree within
    ``defaults.NOISE_ISOTROPY_MAX_RATIO`` (isotropic noise) all are pooled; otherwise the
    normal one alone is used. With no normal data, ``fallback``.
    """
    if not dof_normal > 0:
        return fallback
    normal = sq_normal / dof_normal
    if dof_rest > 0 and sq_rest > 0.0:
        ratio = normal / (sq_rest / dof_rest)
        limit = defaults.NOISE_ISOTROPY_MAX_RATIO
        if 1.0 / limit <= ratio <= limit:
            return float(np.sqrt((sq_normal + sq_rest) / (dof_normal + dof_rest)))
    return float(np.sqrt(normal))


def _normal_fit_rms(fits, n: np.ndarray, fallback: float) -> float:
    """RMS of the curve-fit residuals along the surface normal (see LocalGeometry.fit_rms).

    Each curve's fit takes ``n_coefficients`` degrees of freedom from each component of
    its residuals across the curve (along the normal, and across the curve in the tangent
    plane), prorated over the samples kept (:func:`_across_normals`); the two are pooled
    when they agree (:func:`_normal_or_pooled`). Curves that run along ``n`` everywhere
    leave nothing: then ``fallback`` (the estimate over both components) is returned.
    """
    sq, rest, dof = 0.0, 0.0, 0.0
    for f in fits:
        normals, keep = _across_normals(f.tangents, n)
        m = len(f.residuals)
        if not np.any(keep) or m <= f.n_coefficients:
            continue
        r = f.residuals[keep]
        along = np.sum(r * normals[keep], axis=1)
        sq += float(along @ along)
        rest += float(np.sum(r * r)) - float(along @ along)
        dof += np.count_nonzero(keep) * (m - f.n_coefficients) / m
    return _normal_or_pooled(sq, dof, max(rest, 0.0), dof, fallback)


def _third_difference_noise(curves: list[np.ndarray], n: np.ndarray) -> float:
    """Noise along the surface normal from the third differences of the samples (see
    LocalGeometry.noise_rms).

    Hand-written: neither numpy nor scipy has a noise estimator for sampled curves; this
    is the classic difference-based one (the shape's part of a third difference shrinks
    with the cube of the sample spacing, the noise's does not). Each difference is taken
    along the surface normal at its samples (:func:`_across_normals`, the tangent from the
    moving average of :func:`_smoothing_width` samples), and pooled with its
    other two components when they agree (:func:`_normal_or_pooled`); with no difference
    left, the estimate over all components is returned.
    """
    sq, rest, count = 0.0, 0.0, 0
    for c in curves:
        d = np.diff(c, n=3, axis=0)
        k = _smoothing_width(c)
        q = _smoothed(c, k)
        if k == defaults.CURVE_PARAM_SMOOTHING:
            t = q[3:] - q[:-3]
        else:  # a dense curve: the tangent from a chord across 2k samples
            i = np.arange(len(d))
            t = q[np.minimum(i + 1 + k, len(c) - 1)] - q[np.maximum(i + 2 - k, 0)]
        t /= np.maximum(np.linalg.norm(t, axis=1), 1e-300)[:, None]
        normals, keep = _across_normals(t, n)
        along = np.sum(d[keep] * normals[keep], axis=1)
        sq += float(along @ along)
        rest += float(np.sum(d[keep] ** 2)) - float(along @ along)
        count += int(np.count_nonzero(keep))
    if count == 0:
        d = np.vstack([np.diff(c, n=3, axis=0) for c in curves])
        return float(np.sqrt(np.mean(d * d) / 20.0))
    return _normal_or_pooled(sq / 20.0, count, max(rest, 0.0) / 20.0, 2 * count, 0.0)


def _check_curves(curves) -> list[np.ndarray]:
    """The curves by the shared rules (:func:`meshrec.io.checks.check_curves`), then the
    geometry's own: sizes float64 can handle, no duplicate or shuffled samples, three
    different curves, not all on one line."""
    out = check_curves(curves, "curves")
    for i, a in enumerate(out):
        _check_magnitude(a, f"curves[{i}]")
        _check_duplicates(a, f"curves[{i}]")
        ratio = _order_ratio(a)
        if ratio > defaults.MAX_STEP_TO_NEIGHBOUR_RATIO:
            raise ValueError(
                f"curves[{i}] does not look ordered along the curve: its consecutive samples "
                f"are {ratio:.3g} times farther apart than nearest neighbours (median), more "
                f"than defaults.MAX_STEP_TO_NEIGHBOUR_RATIO = "
                f"{defaults.MAX_STEP_TO_NEIGHBOUR_RATIO}"
            )
    for i, j in itertools.combinations(range(len(out)), 2):
        a, b = out[i], out[j]
        if a.shape == b.shape and (np.array_equal(a, b) or np.array_equal(a, b[::-1])):
            raise ValueError(
                f"curves[{i}] and curves[{j}] are the same curve (duplicate points): three "
                "different curves are needed"
            )
    allp = np.concatenate(out)
    centred = allp - allp.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[1] <= 1e-9 * sv[0]:
        raise ValueError(
            "all points of the curves lie on one straight line: they define no surface"
        )
    return out


def _check_magnitude(a: np.ndarray, name: str) -> None:
    """Refuse a finite (n, 3) curve whose size float64 arithmetic cannot handle.

    Raises
    ------
    ValueError
        If a coordinate exceeds ``defaults.TOUCH_MAX_COORDINATE`` in magnitude, all points
        are equal, or the curve's extent is below ``defaults.TOUCH_MIN_EXTENT`` or
        ``defaults.TOUCH_MIN_RELATIVE_EXTENT`` times its largest coordinate.
    """
    biggest = float(np.max(np.abs(a)))
    if biggest > defaults.TOUCH_MAX_COORDINATE:
        raise ValueError(
            f"{name} has a coordinate of magnitude {biggest:.3g}, more than "
            f"defaults.TOUCH_MAX_COORDINATE = {defaults.TOUCH_MAX_COORDINATE:.3g}: "
            "check the data's units"
        )
    extent = float(np.linalg.norm(a.max(axis=0) - a.min(axis=0)))
    if extent == 0.0:
        raise ValueError(f"{name} has all its points equal: it has no direction")
    floor = max(defaults.TOUCH_MIN_EXTENT, defaults.TOUCH_MIN_RELATIVE_EXTENT * biggest)
    if extent < floor:
        raise ValueError(
            f"{name} spans only {extent:.3g} (bounding-box diagonal), less than {floor:.3g} "
            f"(defaults.TOUCH_MIN_EXTENT = {defaults.TOUCH_MIN_EXTENT:.3g}, or "
            f"defaults.TOUCH_MIN_RELATIVE_EXTENT = {defaults.TOUCH_MIN_RELATIVE_EXTENT:.3g} "
            f"times its largest coordinate {biggest:.3g}): too small to have a shape"
        )


def _check_duplicates(a: np.ndarray, name: str) -> None:
    """Refuse duplicate points that make a curve unusable.

    Repeats of a sample right after it (a probe resting at a point) are harmless and
    allowed; a curve must still have ``defaults.MIN_POINTS_PER_CURVE`` distinct points, and
    must not come back to an earlier sample after others (a copied or retraced run).

    Parameters
    ----------
    a : (n, 3) float
        One finite curve.
    name : str
        Its name in messages, e.g. ``"curves[1]"``.

    Raises
    ------
    ValueError
        If the curve has too few distinct points or revisits an earlier sample.
    """
    _, inverse = np.unique(a, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    distinct = int(inverse.max()) + 1
    if distinct < defaults.MIN_POINTS_PER_CURVE:
        raise ValueError(
            f"{name} has only {distinct} distinct points among its {len(a)} (duplicate "
            f"points), it must have at least {defaults.MIN_POINTS_PER_CURVE}"
        )
    starts = np.flatnonzero(np.concatenate([[True], np.any(a[1:] != a[:-1], axis=1)]))
    ids = inverse[starts]
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if len(same):
        first, again = sorted((int(starts[order[same[0]]]), int(starts[order[same[0] + 1]])))
        raise ValueError(
            f"{name} has duplicate points: row {again} repeats row {first} "
            f"{a[first].tolist()} with other points between, a curve must not come back to "
            "a sample"
        )


def _check_degree(degree) -> int:
    try:
        return check_int(degree, "degree", minimum=2)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"degree must be an integer >= 2, got {one_line(degree)}") from None


# --------------------------------------------------------------------------------------------
# curve fit
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _CurveFit:
    origin: np.ndarray  # (3,) r(0): the fitted curve's point at p's position along it
    tangent: np.ndarray  # (3,) unit tangent at r(0)
    curvature: np.ndarray  # (3,) curvature vector at r(0)
    sq_residual: float  # sum of squared residuals across the curve
    dof: int  # number of residual components minus number of coefficients
    half_length: float  # arc length (smoothed samples) from p to the farther end
    residuals: np.ndarray  # (m, 3) residual of each fitted sample, across the fitted curve
    tangents: np.ndarray  # (m, 3) unit tangent of the fitted curve at each fitted sample
    n_coefficients: int  # polynomial coefficients per coordinate
    # standard error of the curvature at p per unit of noise (one coordinate's deviation):
    # from the fit's covariance, large where p lies near an end of the fitted samples
    curvature_gain: float = 0.0


def _smoothing_width(points: np.ndarray) -> int:
    """Samples on each side of the moving average that parametrises a curve:
    ``defaults.CURVE_PARAM_SMOOTHING``, or more where the samples lie close together
    against the noise (``defaults.CURVE_PARAM_MAX_NOISE_CHORD``), at most a quarter of the
    curve's samples.

    The noise per coordinate is read from the third differences (the shape's part is
    negligible where the samples are dense, and only there does it matter); the spacing
    from the length of the curve taken at about 60 samples (coarse enough that the noise
    does not lengthen it).
    """
    k = defaults.CURVE_PARAM_SMOOTHING
    n = len(points)
    if n < 8:
        return k
    d3 = np.diff(points, n=3, axis=0)
    sigma = float(np.sqrt(np.mean(d3 * d3) / 20.0))
    h = _coarse_length(points) / (n - 1)
    if not (h > 0.0 and sigma > 0.0):
        return k
    limit = max(k, (n - 1) // 4)
    ratio = defaults.CURVE_PARAM_MAX_NOISE_CHORD
    while k < limit and sigma * np.sqrt(6.0 / (2 * k + 1)) > ratio * 2 * k * h:
        k = min(limit, max(k + 1, int(k * 1.25)))
    return k


def _coarse_length(points: np.ndarray) -> float:
    """A curve's length along about 60 of its samples (every ``(n - 1) // 60``-th and
    the last): on a dense noisy curve, the length through every sample is mostly noise."""
    n = len(points)
    stride = max(1, (n - 1) // 60)
    idx = np.unique(np.concatenate([np.arange(0, n, stride), [n - 1]]))
    return float(np.sum(np.linalg.norm(np.diff(points[idx], axis=0), axis=1)))


def _smoothed(points: np.ndarray, k: int) -> np.ndarray:
    """Centred moving average over 2k + 1 samples (fewer near the ends, keeping them fixed)."""
    n = len(points)
    csum = np.concatenate([np.zeros((1, 3)), np.cumsum(points, axis=0)])
    j = np.arange(n)
    h = np.minimum(np.minimum(j, n - 1 - j), k)
    return (csum[j + h + 1] - csum[j - h]) / (2 * h + 1)[:, None]


def _fit_curve(points: np.ndarray, p: np.ndarray, degree: int, name: str) -> _CurveFit:
    """Fit one curve near p (see the module docstring) and differentiate it at p.

    ``name`` (e.g. ``"curves[1]"``) is used in error messages.
    """
    n = len(points)
    k = _smoothing_width(points)
    q = _smoothed(points, k)
    # the chord lengths of the moving average; on a dense curve (a wider average) taken k
    # samples apart and spread evenly over the samples between: one sample apart, its
    # chords are still noise
    if k == defaults.CURVE_PARAM_SMOOTHING:
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    else:
        knots = np.unique(np.concatenate([np.arange(0, n, k), [n - 1]]))
        chords = np.linalg.norm(np.diff(q[knots], axis=0), axis=1)
        s = np.interp(np.arange(n), knots, np.concatenate([[0.0], np.cumsum(chords)]))
    j0 = int(np.argmin(np.linalg.norm(points - p, axis=1)))
    lo, hi = max(j0 - max(k, 1), 0), min(j0 + max(k, 1), n - 1)
    u = q[hi] - q[lo]
    if not np.linalg.norm(u) > 0.0:  # samples around p repeated: use the curve's main axis
        u = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][0]
    u = u / np.linalg.norm(u)
    s = s - (s[j0] + float((p - q[j0]) @ u))

    # the window: the curve on each side of p until it turns too far from its direction at p
    # (its direction from chords across 2k samples: on a dense curve, across 2 samples
    # they are noise)
    w = 1 if k == defaults.CURVE_PARAM_SMOOTHING else k
    j = np.arange(n)
    d = q[np.minimum(j + w, n - 1)] - q[np.maximum(j - w, 0)]
    dn = np.linalg.norm(d, axis=1)
    ok = d @ u >= np.cos(np.radians(defaults.CURVE_FIT_MAX_TURN_DEG)) * dn
    ok[j0] = True
    bad = np.flatnonzero(~ok)
    first = int(bad[bad < j0].max()) + 1 if np.any(bad < j0) else 0
    last = int(bad[bad > j0].min()) - 1 if np.any(bad > j0) else n - 1
    m = min(max(defaults.MIN_POINTS_PER_CURVE, 2 * w + 1), n)
    if last - first + 1 < m:  # too sharp a turn: keep the m samples around p
        first = int(np.clip(j0 - m // 2, 0, n - m))
        last = first + m - 1
    sw = s[first : last + 1]
    pw = points[first : last + 1] - p
    scale = float(np.max(np.abs(sw)))
    deg = max(2, min(degree, len(sw) - 2))
    speed2 = 0.0
    if np.ptp(sw) > 0.0:
        v = sw / scale
        coef = npoly.polyfit(v, pw, deg)  # (deg + 1, 3)
        r1 = coef[1] / scale
        r2 = 2.0 * coef[2] / scale**2
        speed2 = float(r1 @ r1)
    if not (speed2 > 0.0 and np.isfinite(speed2)):
        raise ValueError(
            f"{name} is degenerate near p: its samples there coincide, so it has no tangent"
        )
    t = r1 / np.sqrt(speed2)
    kappa = (r2 - (r2 @ t) * t) / speed2
    # The second coefficient's variance per unit noise variance ((V^T V)^-1 of the
    # Vandermonde rows in v): a curve whose fitted samples lie on one side of p (trimmed,
    # or its sampling cut short) extrapolates its curvature to p, many times less
    # precisely than one centred on p (numpy's polyfit returns no covariance without a
    # weighted refit; this is the same matrix, from its own design).
    vander = np.vander(v, deg + 1, increasing=True)
    inv = np.linalg.pinv(vander.T @ vander)
    gain = 2.0 * float(np.sqrt(max(inv[2, 2], 0.0))) / scale**2 / speed2

    # residuals across the fitted curve (the along-curve part is absorbed by the parameter)
    resid = pw - npoly.polyval(v, coef).T
    tang = npoly.polyval(v, npoly.polyder(coef, axis=0)).T
    tang /= np.maximum(np.linalg.norm(tang, axis=1), 1e-300)[:, None]
    resid -= np.sum(resid * tang, axis=1)[:, None] * tang
    return _CurveFit(
        origin=p + coef[0],
        tangent=t,
        curvature=kappa,
        sq_residual=float(np.sum(resid**2)),
        dof=int(2 * (len(sw) - deg - 1)),
        half_length=float(max(-s[0], s[-1])),
        residuals=resid,
        tangents=tang,
        n_coefficients=deg + 1,
        curvature_gain=gain,
    )


# --------------------------------------------------------------------------------------------
# common point
# --------------------------------------------------------------------------------------------
def _lines_point(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Least-squares point closest to the lines (origins[i], directions[i])."""
    eye = np.eye(3)
    a = np.zeros((3, 3))
    b = np.zeros(3)
    for o, t in zip(origins, directions, strict=True):
        proj = eye - np.outer(t, t)
        a += proj
        b += proj @ o
    return np.linalg.solve(a, b)


def find_common_point(curves) -> CommonPoint:
    """Find the point where concurrent curves (nearly) meet.

    For each curve the sample closest to all other curves (smallest sum of squared
    distances to their nearest samples, by k-d trees) is taken; p starts as the mean of
    these samples. It is then refined a few times: each curve is fitted as in
    `estimate_local_geometry` around the current p, and p becomes the least-squares point
    closest to the fitted curves' tangent lines at their closest approaches to p. The
    refinement is kept only if it stays near the starting point.

    Parameters
    ----------
    curves : sequence of (n_i, 3) float arrays
        At least ``defaults.MIN_CURVES`` curves, each with at least
        ``defaults.MIN_POINTS_PER_CURVE`` finite samples ordered along the curve.

    Returns
    -------
    CommonPoint

    Raises
    ------
    TypeError
        If ``curves`` is not a sequence of arrays or a curve is not real numbers (complex,
        bool, strings; see :mod:`meshrec.io.checks`).
    ValueError
        If ``curves`` is not a sequence of ``defaults.MIN_CURVES`` to
        ``defaults.MAX_CURVES`` (n, 3) finite arrays with ``defaults.MIN_POINTS_PER_CURVE``
        to ``defaults.MAX_POINTS_PER_CURVE`` points (``defaults.MAX_TOUCH_POINTS`` in all),
        if a curve has all its points equal, coordinates beyond
        ``defaults.TOUCH_MAX_COORDINATE`` or too small an extent, duplicate points (fewer
        than ``defaults.MIN_POINTS_PER_CURVE`` distinct ones, or a return to an earlier
        sample), or does not look ordered along itself, if two curves are the same, or if
        all points lie on one straight line.
    """
    return _common_point(_check_curves(curves))


def _nearest_score(c: np.ndarray, others: list[cKDTree], bound: float = np.inf) -> np.ndarray:
    """Sum over ``others`` of the squared distance of each row of ``c`` to its nearest
    sample there; rows with a distance beyond ``bound`` get inf."""
    score = np.zeros(len(c))
    for tree in others:
        dist, _ = tree.query(c, distance_upper_bound=bound)
        score += dist**2
    return score


def _crossing_samples(cs: list[np.ndarray], trees: list[cKDTree]) -> np.ndarray:
    """(c, 3): on each curve, the sample closest to all other curves (the least sum of
    squared distances to their nearest samples).

    The same samples as querying every sample against every other curve's k-d tree, but
    in O(n log n): a k-d tree's nearest-neighbour query costs in proportion to the samples
    about as near as the nearest one, which for a sample far from a curve of n samples is
    O(n), so that the plain search is O(n^2) (measured on arcs of a sphere: 3 curves of
    20,000 samples took 2.5 s, 0.03 s with this one). Here a coarse search on every
    ``stride``-th sample (``stride`` about sqrt(n) / 8, so O(n) work) gives one sample's
    score S, an upper bound on the least one; the full search then only needs the
    distances up to sqrt(S), and queries with that ``distance_upper_bound`` stop early. A
    sample with a larger distance has a larger score than S and cannot be the least.
    """
    best = []
    for i, c in enumerate(cs):
        others = [tree for k, tree in enumerate(trees) if k != i]
        bound = np.inf
        stride = max(1, math.isqrt(max(len(cd) for cd in cs)) // _COARSE_DIVISOR)
        if stride > 1:
            coarse = [cKDTree(cs[k][::stride]) for k in range(len(cs)) if k != i]
            j = int(np.argmin(_nearest_score(c[::stride], coarse))) * stride
            upper = float(_nearest_score(c[j : j + 1], others)[0])
            bound = math.sqrt(upper) * (1.0 + 1e-9) + 1e-300
        best.append(c[int(np.argmin(_nearest_score(c, others, bound)))])
    return np.array(best)


#: The coarse pass of :func:`_crossing_samples` takes every (sqrt(n) / this)-th sample.
_COARSE_DIVISOR = 8


def _common_point(cs: list[np.ndarray]) -> CommonPoint:
    """:func:`find_common_point` on curves already checked by :func:`_check_curves`."""
    trees = [cKDTree(c) for c in cs]
    best = _crossing_samples(cs, trees)
    p0 = best.mean(axis=0)
    spread0 = max(np.linalg.norm(u - v) for u, v in itertools.combinations(best, 2))
    spacing = float(
        np.median(np.concatenate([np.linalg.norm(np.diff(c, axis=0), axis=1) for c in cs]))
    )
    reach = 2.0 * (spread0 + spacing)

    p = p0
    origins = best
    for _ in range(defaults.COMMON_POINT_ITERATIONS):
        try:
            fits = [
                _fit_curve(c, p, defaults.CURVE_FIT_DEGREE, f"curves[{i}]")
                for i, c in enumerate(cs)
            ]
            origins_new = np.array([f.origin for f in fits])
            tangents = np.array([f.tangent for f in fits])
            p_new = _lines_point(origins_new, tangents)
        except (ValueError, np.linalg.LinAlgError):
            break
        if not np.all(np.isfinite(p_new)) or np.linalg.norm(p_new - p0) > reach:
            break
        step = np.linalg.norm(p_new - p)
        p, origins = p_new, origins_new
        if step <= 1e-12 * (1.0 + spacing):
            break
    spread = max(np.linalg.norm(u - v) for u, v in itertools.combinations(origins, 2))
    indices = np.array([tree.query(p)[1] for tree in trees], dtype=np.int64)
    return CommonPoint(point=np.asarray(p, dtype=np.float64), spread=float(spread), indices=indices)


# --------------------------------------------------------------------------------------------
# local geometry
# --------------------------------------------------------------------------------------------
def _check_meet(
    curves: list[np.ndarray],
    fits: list[_CurveFit],
    p: np.ndarray,
    given: bool,
    half_length: float,
    fit_rms: float,
) -> None:
    """Refuse curves that do not pass through p.

    The curves may miss p by at most ``defaults.MAX_MEET_FRACTION`` of their half-length
    or ``defaults.MAX_MEET_NOISE_FACTOR`` times the fit residual, whichever is larger.
    When p was found from the curves, the test is on how far apart the fitted curves pass
    it; when it was given (a contact), on how far each curve is from it (the fitted curve's
    passage, and the nearest sample less the curve's sample spacing).

    Parameters
    ----------
    curves : list of (n_i, 3) float
        The checked curves.
    fits : list of _CurveFit
        Their fits around p.
    p : (3,) float
        The common point.
    given : bool
        Whether p was given by the caller (a contact) rather than found.
    half_length, fit_rms : float
        As in :class:`LocalGeometry`.

    Raises
    ------
    ValueError
        If a curve misses p (``given``) or two curves pass p too far apart.
    """
    allowed = max(
        defaults.MAX_MEET_FRACTION * half_length, defaults.MAX_MEET_NOISE_FACTOR * fit_rms
    )
    why = (
        f"more than {allowed:.3g} (defaults.MAX_MEET_FRACTION = {defaults.MAX_MEET_FRACTION} "
        f"of the curves' half-length {half_length:.3g}, or defaults.MAX_MEET_NOISE_FACTOR = "
        f"{defaults.MAX_MEET_NOISE_FACTOR} times the fit residual {fit_rms:.3g})"
    )
    origins = np.array([f.origin for f in fits])
    if given:
        miss, off, near = [], [], []
        for c, o in zip(curves, origins, strict=True):
            nearest = float(np.min(np.linalg.norm(c - p, axis=1)))
            step = float(np.median(np.linalg.norm(np.diff(c, axis=0), axis=1)))
            miss.append(max(float(np.linalg.norm(o - p)), nearest - step))
            off.append(nearest - step)
            near.append(nearest)
        i = int(np.argmax(miss))
        k = int(np.argmax(off))
        if not miss[i] <= allowed and off[k] > allowed:
            # Away from the data itself: the fits around it are carried past their data
            # and their half-lengths are measured from the contact, so neither says how
            # far it is: the nearest sample does, and the curves' own extent.
            extent = float(np.median([_coarse_length(c) for c in curves]))
            raise ValueError(
                f"the contact point {np.round(p, 6).tolist()} is {near[k]:.3g} away from "
                f"the nearest sample of curves[{k}], and the curves are {extent:.3g} long: it "
                f"must be where the curves meet (within defaults.MAX_MEET_FRACTION = "
                f"{defaults.MAX_MEET_FRACTION} of their half-length, or "
                f"defaults.MAX_MEET_NOISE_FACTOR = {defaults.MAX_MEET_NOISE_FACTOR} times the "
                "fit residual)"
            )
        if not miss[i] <= allowed:
            raise ValueError(
                f"the contact point {np.round(p, 6).tolist()} is {miss[i]:.3g} away from "
                f"curves[{i}], {why}: it must be where the curves meet"
            )
        return
    worst, wi, wj = -1.0, 0, 1
    for i, j in itertools.combinations(range(len(origins)), 2):
        d = float(np.linalg.norm(origins[i] - origins[j]))
        if d > worst:
            worst, wi, wj = d, i, j
    if not worst <= allowed:
        reach = max(float(np.max(np.linalg.norm(c - p, axis=1))) for c in curves)
        hint = ""
        if worst > reach:
            # Farther apart than any sample lies from p: the fitted curves were carried
            # past their data (a window shrunk to a few samples by noise that turns the
            # curve at every step), not two curves that miss each other.
            hint = (
                f"; that is farther than any sample lies from p ({reach:.3g}): the curve fits "
                "run off their data, and the samples may be too noisy for curves this short"
            )
        raise ValueError(
            f"the curves do not meet at a common point: curves[{wi}] and curves[{wj}] pass "
            f"{worst:.3g} apart where they come closest, {why}{hint}"
        )


def _canonical_sign(v: np.ndarray) -> np.ndarray:
    """v with its largest-magnitude component made positive."""
    return v if v[int(np.argmax(np.abs(v)))] >= 0 else -v


def estimate_local_geometry(
    curves,
    point=None,
    normal=None,
    degree: int = defaults.CURVE_FIT_DEGREE,
) -> LocalGeometry:
    """Estimate the surface normal and curvatures at the common point of the curves.

    Parameters
    ----------
    curves : sequence of (n_i, 3) float arrays
        At least ``defaults.MIN_CURVES`` curves sampled on the surface, each with at least
        ``defaults.MIN_POINTS_PER_CURVE`` finite samples ordered along the curve, all
        passing through (near) one point.
    point : (3,) float, optional
        The common point p. Default: ``find_common_point(curves).point``.
    normal : (3,) float, optional
        An approximate outward normal (e.g. minus the probe's approach direction); the
        estimated N is oriented to have a positive dot product with it. Without it, N is
        oriented so that H >= 0 (the outward normal where the surface is convex), and when
        H == 0 exactly, so that the largest-magnitude component of N is positive; use
        `LocalGeometry.flipped` for the other side.
    degree : int, default ``defaults.CURVE_FIT_DEGREE``
        Degree (>= 2) of the polynomial fitted to each curve (lowered to n - 2 for a curve
        with fewer than degree + 2 fitted samples).

    Returns
    -------
    LocalGeometry

    Raises
    ------
    TypeError
        If ``curves`` is not a sequence of arrays or a curve is not real numbers (complex,
        bool, strings), or ``point``, ``normal`` or ``degree`` has the wrong type (see
        :mod:`meshrec.io.checks`).
    ValueError
        If ``curves`` is not a sequence of ``defaults.MIN_CURVES`` to
        ``defaults.MAX_CURVES`` (n, 3) finite arrays with ``defaults.MIN_POINTS_PER_CURVE``
        to ``defaults.MAX_POINTS_PER_CURVE`` points (``defaults.MAX_TOUCH_POINTS`` in all),
        if a curve has all its points equal, coordinates beyond
        ``defaults.TOUCH_MAX_COORDINATE`` or too small an extent, duplicate points (fewer
        than ``defaults.MIN_POINTS_PER_CURVE`` distinct ones, or a return to an earlier
        sample), or does not look ordered along itself, if two curves are the same, or all
        points lie on one straight line; if a curve's samples near p coincide; if the
        curves do not meet at one point or ``point`` is away from them (more than
        ``defaults.MAX_MEET_FRACTION`` of the half-length or
        ``defaults.MAX_MEET_NOISE_FACTOR`` times the fit residual); if
        ``point`` or ``normal`` is not a finite (3,) vector or ``normal`` is zero; if
        ``degree`` is not an integer >= 2; if two curves' tangents at p are within
        ``defaults.MIN_TANGENT_ANGLE_DEG`` of each other (modulo 180 degrees) or the Euler
        system's condition number exceeds ``defaults.MAX_EULER_CONDITION`` (the curves are
        nearly parallel at p); if a curve's tangent at p is more than
        ``defaults.MAX_TANGENT_TILT_DEG`` out of the plane that fits the tangents best.
    """
    cs = _check_curves(curves)
    degree = _check_degree(degree)
    hint = None if normal is None else check_vector(normal, "normal", unit=True)
    p = _common_point(cs).point if point is None else check_vector(point, "point")

    fits = [_fit_curve(c, p, degree, f"curves[{i}]") for i, c in enumerate(cs)]
    tangents = np.array([f.tangent for f in fits])
    kappas = np.array([f.curvature for f in fits])
    sq = sum(f.sq_residual for f in fits)
    dof = sum(f.dof for f in fits)
    coordinate_rms = float(np.sqrt(sq / dof)) if dof > 0 else 0.0
    half_length = float(np.median([f.half_length for f in fits]))
    _check_meet(
        cs, fits, p, given=point is not None, half_length=half_length, fit_rms=coordinate_rms
    )

    # nearly parallel tangents
    worst = (np.inf, 0, 1)
    for i, j in itertools.combinations(range(len(cs)), 2):
        ang = float(np.degrees(np.arccos(min(1.0, abs(float(tangents[i] @ tangents[j]))))))
        worst = min(worst, (ang, i, j))
    min_angle, wi, wj = worst
    if min_angle < defaults.MIN_TANGENT_ANGLE_DEG:
        raise ValueError(
            f"the curves are nearly parallel at p: the tangents of curves[{wi}] and "
            f"curves[{wj}] are {min_angle:.3g} degrees apart (modulo 180), less than "
            f"defaults.MIN_TANGENT_ANGLE_DEG = {defaults.MIN_TANGENT_ANGLE_DEG} (or p lies on "
            "a sharp edge or rim, where every curve bends and its tangent at p is not "
            "defined: touch away from it)"
        )

    # normal: least-squares direction perpendicular to all tangents
    _, evecs = np.linalg.eigh(tangents.T @ tangents)
    n = _canonical_sign(evecs[:, 0])
    # The tangents must lie about one plane: one nearly along the normal of the others
    # (three straight lines along x, y and z) leaves no tangent plane to write Euler's
    # formula in.
    tilt = np.degrees(np.arcsin(np.minimum(np.abs(tangents @ n), 1.0)))
    k = int(np.argmax(tilt))
    if not tilt[k] <= defaults.MAX_TANGENT_TILT_DEG:
        raise ValueError(
            f"the curves' tangents at p do not lie in one plane: the tangent of curves[{k}] "
            f"is {tilt[k]:.3g} degrees out of the plane that fits them best (more than "
            f"defaults.MAX_TANGENT_TILT_DEG = {defaults.MAX_TANGENT_TILT_DEG}): no smooth "
            "surface holds them; the curves may cross a corner or not lie on one surface"
        )
    e1 = tangents[0] - (tangents[0] @ n) * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)

    # Euler's formula
    cos_t = tangents @ e1
    sin_t = tangents @ e2
    rad = np.hypot(cos_t, sin_t)
    cos_t, sin_t = cos_t / rad, sin_t / rad
    a = np.column_stack([cos_t**2, 2.0 * cos_t * sin_t, sin_t**2])
    condition = float(np.linalg.cond(a))
    if not condition <= defaults.MAX_EULER_CONDITION:
        raise ValueError(
            f"the curves are nearly parallel at p: the Euler system's condition number is "
            f"{condition:.3g} (more than defaults.MAX_EULER_CONDITION = "
            f"{defaults.MAX_EULER_CONDITION}); the closest tangents are {min_angle:.3g} "
            f"degrees apart (modulo 180)"
        )
    kn = -(kappas @ n)
    (ll, mm, nn), *_ = np.linalg.lstsq(a, kn, rcond=None)
    # the normal curvatures' standard errors carried to the shape operator (ll, mm, nn)
    solve = np.linalg.pinv(a)
    sd_kn = coordinate_rms * np.array([f.curvature_gain for f in fits])
    cov = (solve * sd_kn**2) @ solve.T
    curvature_sd = float(np.sqrt(max(cov[0, 0] + 2.0 * cov[1, 1] + cov[2, 2], 0.0)))
    shape = np.array([[ll, mm], [mm, nn]])
    w, v = np.linalg.eigh(shape)
    k2, k1 = float(w[0]), float(w[1])
    t1 = _canonical_sign(v[0, 1] * e1 + v[1, 1] * e2)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    frame = np.column_stack([t1, t2, n])

    geom = LocalGeometry(
        point=np.asarray(p, dtype=np.float64).copy(),
        normal=n,
        frame=frame,
        k1=k1,
        k2=k2,
        K=float(ll * nn - mm * mm),
        H=float(0.5 * (ll + nn)),
        tangents=tangents,
        normal_curvatures=kn,
        fit_rms=_normal_fit_rms(fits, n, coordinate_rms),
        half_length=half_length,
        condition=condition,
        noise_rms=_third_difference_noise(cs, n),
        curvature_sd=curvature_sd,
    )
    # orientation: the pre-flip normal is canonical (largest component positive)
    flip = float(n @ hint) < 0.0 if hint is not None else geom.H < 0.0
    return geom.flipped() if flip else geom
