"""The probe's ball tip in a recognition: its radius, its checks, and a tip not declared.

A ball-tipped probe records the ball's centres, on the surface offset outwards by the tip
radius (see :mod:`meshrec.contact.probe`). :func:`touch_probe_radius` settles the radius
of a recognition (the argument, or the touches' own), :func:`check_tip_fits` refuses a
radius that the data's curvature rules out, and :func:`warn_probe_offset` warns when data
recognised without a radius fit the best model's offset surface clearly better than the
surface itself (a tip nobody declared).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.contact.probe import ProbeOffsetWarning, check_probe_radius
from meshrec.io.checks import check_number
from meshrec.model.probe import probe_model
from meshrec.recognition.scoring import fit_p_value
from meshrec.registration.refine import refine_offset, refine_rigid

__all__ = [
    "ProbeOffset",
    "check_tip_fits",
    "probe_offset",
    "touch_probe_radius",
    "warn_probe_offset",
]


@dataclass(frozen=True)
class ProbeOffset:
    """The evidence of :func:`probe_offset`: the tip radius that best explains a fit.

    Attributes
    ----------
    radius : float
        The best R, data units (0 when no R > 0 fits better than the surface itself).
    rms0 : float
        RMS distance at R = 0, after rigid refinement.
    rms : float
        RMS distance at ``radius``, after refinement (``rms0`` when ``radius`` is 0).
    linear_drop : float
        The drop of the sum of squares that the residuals linearised at the rigid optimum
        predict with any pose and any R
        (:attr:`~meshrec.registration.refine.OffsetRefinement.linear_drop`), squared data
        units: below ``min_gain * noise**2`` the joint refinement was skipped.
    radius_max : float
        The largest R tried (``R_max`` of :func:`probe_offset`), data units.
    """

    radius: float
    rms0: float
    rms: float
    linear_drop: float
    radius_max: float = float("nan")


def touch_probe_radius(touches, probe_radius) -> float:
    """The tip radius of a recognition: ``probe_radius``, else the touches' own, else 0.

    Parameters
    ----------
    touches : sequence of TouchData
    probe_radius : float or None

    Returns
    -------
    float

    Raises
    ------
    TypeError
        If ``probe_radius`` is not a real number (or None).
    ValueError
        If ``probe_radius`` is negative or not finite, or a touch records a different
        radius (from ``probe_radius``, or from another touch).
    """
    given = {t.probe_radius for t in touches if t.probe_radius is not None}
    if probe_radius is not None:
        radius = check_probe_radius(probe_radius)
        if given - {radius}:
            raise ValueError(
                f"probe_radius={radius!r} differs from the touches' own probe_radius "
                f"{sorted(given)}"
            )
        return radius
    if len(given) > 1:
        raise ValueError(f"the touches give different probe_radius values: {sorted(given)}")
    return given.pop() if given else 0.0


def check_tip_fits(touches, geometries, radius: float) -> None:
    """Refuse a tip radius that data with a given outward normal rule out.

    Where a touch gives its outward ``normal``, the side of the data is known, and a ball
    of radius R traces radii of curvature of at least R where the surface is convex: a
    largest principal curvature k1 with ``R k1 >= 1`` cannot come from that tip. (Without
    a normal either side may be the outside, and the registration tries only the side
    the tip could have traced.)

    Parameters
    ----------
    touches : sequence of TouchData
    geometries : sequence of LocalGeometry
        The local geometry of each touch (its normal oriented by the touch's normal).
    radius : float
        The tip radius, data units.

    Raises
    ------
    ValueError
        If a touch with a normal has ``radius * k1 >= 1``.
    """
    for k, (touch, g) in enumerate(zip(touches, geometries, strict=True)):
        if touch.normal is None or radius * g.k1 < 1.0:
            continue
        which = f"touch {k + 1}" if len(touches) > 1 else "the touch"
        raise ValueError(
            f"probe_radius must be less than the radius of curvature of {which} where it is "
            f"convex ({1.0 / g.k1:.6g} data units: a ball of radius R traces radii of at "
            f"least R there), got {radius!r}"
        )


def probe_offset(
    points, model, T_model_touch, noise: float, min_gain: float = 0.0
) -> ProbeOffset:
    """The tip radius that best explains the fit of touch data to a model, and its evidence.

    The data are refined rigidly onto the model's surface (from ``T_model_touch``), then
    the pose and R together onto the surface offset by R, R in ``[0, R_max]``, ``R_max``
    the smaller of ``defaults.PROBE_OFFSET_MAX_FRACTION`` of the touch's size and of the
    model's (:func:`~meshrec.registration.refine.refine_offset`); where that refinement
    realises less than ``1 / defaults.PROBE_OFFSET_LINEAR_MARGIN`` of the drop its own
    linearisation predicts, R is also searched by rigid refinements at several R (a
    parabola's vertex), and the better answer kept.
    One touch cannot show the offset itself (a translation along the normal absorbs
    it), only through curvature: the offset surface's principal radii are larger by R on
    convex parts and smaller on concave ones, the same R everywhere, which no rigid
    motion of the surface reproduces where the curvature is not flat.

    With several touches at different places on the object the offset shows directly
    (no one translation moves them all in), with one only through curvature, as above.

    Parameters
    ----------
    points : (n, 3) float
        The data points (every touch's, in their common frame).
    model : ModelIndex
        A plain model (no probe radius).
    T_model_touch : (4, 4) float
        The pose found without a radius.
    noise : float
        Noise standard deviation per point, data units (> 0).
    min_gain : float
        With ``min_gain`` > 0, the joint refinement is skipped (the answer is then R of
        about 0, ``rms`` of about ``rms0``) when the residuals linearised at the rigid
        optimum could not lower their sum of squares by ``min_gain * noise**2`` with any
        pose and R (see ``refine_offset``'s ``skip_below``).

    Returns
    -------
    ProbeOffset
        The best R (``radius``, data units), the RMS distances at R = 0 and at it
        (``rms0``, ``rms``, both after refinement) and the linearised drop.

    Raises
    ------
    ValueError
        If ``noise`` is not a positive finite number or ``min_gain`` not a non-negative
        finite one.
    """
    noise = check_number(noise, "noise", positive=True)
    min_gain = check_number(min_gain, "min_gain", minimum=0.0)
    points = np.asarray(points, dtype=np.float64)
    r_max = defaults.PROBE_OFFSET_MAX_FRACTION * min(_half_length(points), model.mesh.scale)
    rigid = refine_rigid(model, points, T_model_touch)
    # The pose and R refined together (R eliminated: the residuals are linear in it),
    # from the rigid optimum, so that rms <= rms0: one refinement where a search over R
    # (a parabola's vertex through three, then the three nearest it) took five rigid
    # ones, 52 distance queries per recognition of the paper surfaces.
    joint = refine_offset(
        model,
        points,
        rigid.T_model_touch,
        r_max,
        rel_tol=defaults.PROBE_OFFSET_REL_TOL,
        skip_below=min_gain * noise**2,
    )
    drop = len(points) * (rigid.rms**2 - joint.rms**2)
    if joint.iterations > 0 and drop < joint.linear_drop / defaults.PROBE_OFFSET_LINEAR_MARGIN:
        # The joint loop did not follow its own linearisation (measured: it realised 95%
        # to 120% of it wherever either was above 2 noise variances, but from a rigid
        # optimum far from the offset one, a 0.2 tip on the crossed trough, the undamped
        # step overshot and the damped ones, cut short in R's near-null direction, did
        # not descend: 0.001 of 45 noise variances). Then the former search over R too,
        # and the better answer.
        radius, rms = _parabola_search(points, model, T_model_touch, r_max, rigid.rms)
        if not rms < joint.rms:
            radius, rms = joint.radius, joint.rms
    else:
        radius, rms = joint.radius, joint.rms
    if not rms < rigid.rms:
        return ProbeOffset(0.0, rigid.rms, rigid.rms, joint.linear_drop, r_max)
    return ProbeOffset(radius, rigid.rms, rms, joint.linear_drop, r_max)


def _parabola_search(points, model, T_model_touch, r_max: float, rms0: float):
    """The R in ``[0, r_max]`` of least RMS by rigid refinements onto the surface offset by
    R from ``T_model_touch`` (``rms0`` the one at R = 0): (R, its RMS)."""
    cache: dict[float, float] = {0.0: rms0}

    def rms_at(r: float) -> float:
        r = float(min(max(r, 0.0), r_max))
        if r not in cache:
            cache[r] = refine_rigid(probe_model(model, r), points, T_model_touch).rms
        return cache[r]

    # The summed squares are nearly a parabola in R: its vertex through three samples,
    # then once more through the three samples nearest it (four rigid refinements more).
    h = 0.25 * r_max
    for r in (h, 2.0 * h):
        rms_at(r)
    for _ in range(2):
        best = min(cache, key=cache.get)
        near = sorted(cache, key=lambda r: abs(r - best))[:3]
        rms_at(_vertex({r: cache[r] for r in near}))
    radius = min(cache, key=cache.get)
    return radius, cache[radius]


def _vertex(samples: dict[float, float]) -> float:
    """The R of least summed squares on the parabola through three samples ``R -> rms``
    (the best sample where the parabola opens downwards)."""
    r = np.array(sorted(samples))
    ss = np.array([samples[x] ** 2 for x in r])
    a, b, _ = np.polyfit(r, ss, 2)
    if not a > 0:
        return float(r[np.argmin(ss)])
    return float(-b / (2.0 * a))


def _half_length(points: np.ndarray) -> float:
    """Half the largest distance of the data from their centroid, a size of the touch."""
    centred = points - points.mean(axis=0)
    return float(np.linalg.norm(centred, axis=1).max())


def warn_probe_offset(rec, models) -> ProbeOffset | None:
    """Warn when touches recognised without a radius look taken with a ball tip.

    For the best model (every touch's points at its pose), :func:`probe_offset` finds the tip
    radius R that best explains the data; when the fit improves by more than the noise
    allows (``n (rms0^2 - rms^2) / max(noise, rms)^2 > defaults.PROBE_OFFSET_CHI2``, a
    test of one added parameter against the residual variance left, or the noise if
    larger), R is more than ``defaults.PROBE_OFFSET_MIN_NOISE`` noise deviations, and the
    offset removes at least ``defaults.PROBE_OFFSET_EXPLAINED`` of the summed squares
    beyond the noise (``rms0^2 - noise^2``; otherwise a tip is not what is wrong), a
    :class:`~meshrec.contact.probe.ProbeOffsetWarning` says so.

    Parameters
    ----------
    rec : Recognition
    models : list of ModelIndex

    Returns
    -------
    ProbeOffset or None
        The evidence weighed (:func:`probe_offset` at the best model's pose, every
        touch's points, ``min_gain`` as below), warned or not; None when there is no
        best pose or no positive noise estimate (nothing was checked).
    """
    best = rec.best
    if best is None or best.T_model_touch is None or not rec.noise > 0:
        return None
    model = {m.name: m for m in models}[best.model]
    points = np.vstack([t.points for t in rec.touches or (rec.touch,)])
    # The test below needs n (rms0^2 - rms^2) > PROBE_OFFSET_CHI2 max(noise, rms)^2, so
    # a drop of the sum of squares by more than PROBE_OFFSET_CHI2 noise^2. The drop that
    # the residuals linearised at the rigid optimum allow (any pose, any R) is the score
    # statistic of the added parameter, which the likelihood-ratio one (the refined drop)
    # equals to first order; where it is below PROBE_OFFSET_CHI2 / PROBE_OFFSET_LINEAR_MARGIN
    # noise^2 the joint refinement is skipped. Measured on 55 touches (no tip and tips of
    # 0.02 to 0.2 on the paper surfaces, a sphere and a tube; one and three touches): the
    # refined drop was within 2% of the linearised one wherever either was above 2 noise
    # variances (to 16% for three touches at 8e5), and at most 0.42 above it below that.
    found = probe_offset(
        points,
        model,
        best.T_model_touch,
        rec.noise,
        min_gain=defaults.PROBE_OFFSET_CHI2 / defaults.PROBE_OFFSET_LINEAR_MARGIN,
    )
    radius, rms0, rms = found.radius, found.rms0, found.rms
    n = len(points)
    # The improvement is measured against the residual variance left with the offset, or
    # the noise if larger (an F-test of one added parameter): where the surface itself
    # misfits the data (a scan's chord error, a coarse mesh), any extra parameter trims a
    # little of that misfit, many times the noise alone in chi-squared terms (a tomato
    # soup can scan, simulated touches with no tip: RMS 0.155 mm to 0.149 mm at a 1.2 mm
    # "offset", 62 times the noise variance but 10 times the residual one).
    gain = n * (rms0**2 - rms**2) / max(rec.noise, rms) ** 2
    if gain <= defaults.PROBE_OFFSET_CHI2 or radius <= defaults.PROBE_OFFSET_MIN_NOISE * rec.noise:
        return found
    excess = rms0**2 - rec.noise**2
    if excess > 0 and (rms0**2 - rms**2) < defaults.PROBE_OFFSET_EXPLAINED * excess:
        # The offset explains little of the misfit beyond the noise: a tip is not what is
        # wrong (a torus touched against a library of bumped spheres and ellipsoids, RMS
        # 27 times the noise, was trimmed by 5% at an "offset" of 0.08), and suggesting
        # one would mislead.
        return found
    if radius >= defaults.PROBE_OFFSET_BOUND_FRACTION * found.radius_max and (
        fit_p_value(rms, n, rec.noise) < defaults.WIDEN_P_VALUE
    ):
        # R at the end of its range is a bound, not an estimate, and the offset surface
        # still misfits: any added parameter trims a misfit that has another cause (an
        # ellipsoid touched against the other paper surfaces: R at R_max, 11.7 times the
        # noise left; suggesting the tip would invite a wrong model to fit).
        return found
    warnings.warn(
        f"the data lie about {radius:.3g} outside the surface of {best.model!r} (they fit "
        f"the surface offset by {radius:.3g} with RMS {rms:.3g} against {rms0:.3g} for the "
        f"surface itself, beyond the noise {rec.noise:.3g}): a ball tip? use "
        f"--probe-radius (probe_radius=) with the tip's radius, which this fit puts at about "
        f"{_round(radius)} (less than a tip wider than the surface's curvature radii: the "
        "fit at the plain surface's pose flattens such an offset); or the part is a little "
        "larger than its model (a scale or unit error: on a curved patch a 1% larger part "
        "looks like a tip of 1% of its radius of curvature)",
        ProbeOffsetWarning,
        stacklevel=4,
    )
    return found


def _round(x: float) -> str:
    """``x`` to two significant digits, for a suggested option value."""
    if x <= 0 or not math.isfinite(x):
        return f"{x:g}"
    return f"{x:.2g}"
