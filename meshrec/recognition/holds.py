"""The holds on a verdict: where the scores would name a model but the data are not
what the probabilities were measured on, ``recognised`` becomes ``ambiguous``.

One touch too noisy for its length (:func:`within_calibration`), one touch whose curves
fit no smooth patch (:func:`rough_hold`), one touch across a sharp edge of the named model
(:func:`across_an_edge`), and several touches whose named pose leaves one touch
unexplained (:func:`every_touch_hold`). Each keeps the model alone in ``plausible`` and
says why in the reason.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.recognition.rescore import decided
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import Verdict, fit_p_value

__all__ = [
    "across_an_edge",
    "every_touch_hold",
    "rough_hold",
    "within_calibration",
    "would_be_named",
]


def would_be_named(rec: Recognition, prior, n: int, noise: float) -> bool:
    """One touch: whether the scores name one model and the touch's own holds (its noise
    against its length, curve fits far rougher than the noise) leave it named."""
    v = within_calibration(decided(rec, prior, n, noise), rec)
    return rough_hold(v, rec.geometries[0]).verdict == "recognised"


def within_calibration(v: Verdict, rec: Recognition) -> Verdict:
    """One touch whose noise is too large against its curves' length
    (``defaults.SCORE_MAX_NOISE_FRACTION``) names no model: ``recognised`` becomes
    ``ambiguous``, the model alone in ``plausible``, and the reason says why."""
    if len(rec.touches) != 1 or v.verdict != "recognised":
        return v
    g = rec.geometry
    fraction = float(g.noise_rms) / float(g.half_length)
    if not fraction > defaults.SCORE_MAX_NOISE_FRACTION:
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but the touch's noise ({float(g.noise_rms):.3g}) is "
        f"{100 * fraction:.2g}% of the curves' half-length, beyond the "
        f"{100 * defaults.SCORE_MAX_NOISE_FRACTION:g}% up to which the probabilities were "
        "measured to hold: at that noise the curvature estimate and the search may miss "
        "the right model's pose; touch again with longer curves or a finer probe, or add "
        "touches",
        v.fit_ratio,
    )


def rough_hold(v: Verdict, g: LocalGeometry) -> Verdict:
    """One touch whose curve fits leave more than ``defaults.ROUGH_HOLD_RATIO`` times the
    noise (beyond any touch the scores were measured on) names no model: ``recognised``
    becomes ``ambiguous``, the model alone in ``plausible``, and the reason says why."""
    if v.verdict != "recognised" or not (
        g.fit_to_noise > defaults.ROUGH_HOLD_RATIO
        and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * g.half_length
    ):
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but the curves fit no smooth surface patch: their fits leave "
        f"{g.fit_to_noise:.3g} times the noise the samples show (more than "
        f"defaults.ROUGH_HOLD_RATIO = {defaults.ROUGH_HOLD_RATIO:g}), so they cross an edge "
        "or a rim, where the curvature the search starts from is not defined and the right "
        "model's pose may be missed while another model fits; touch again away from edges, "
        "or add touches",
        v.fit_ratio,
    )


def every_touch_hold(v: Verdict, rec: Recognition, fit, noise: float) -> Verdict:
    """Several touches: a model is named only if its pose fits every touch.

    The joint fit test pools the touches, so one touch that the named pose does not
    explain can hide among the others (a black-box probe, stop 33: a lever's mirror twin
    named at p 1.000, fitting two touches at 0.65 times the noise and the third at 1.3
    times, chi-square tail 5e-5; the lever's own search had missed its pose). Where a
    touch's own tail at the named pose is below ``defaults.UNKNOWN_P_VALUE``,
    ``recognised`` becomes ``ambiguous`` and the reason says which touch."""
    if v.verdict != "recognised":
        return v
    tails = [
        fit_p_value(r, int(t.n_points), noise, dof=0)
        for r, t in zip(fit.touch_rms, rec.touches, strict=True)
    ]
    k = int(np.argmin(tails))
    if tails[k] >= defaults.UNKNOWN_P_VALUE:
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but its pose fits touch {k + 1} at {fit.touch_rms[k] / noise:.3g} times "
        f"the noise (chi-square tail {tails[k]:.2g}, below defaults.UNKNOWN_P_VALUE = "
        f"{defaults.UNKNOWN_P_VALUE:g}): one rigid pose of it does not explain every touch; "
        "another model's pose may have been missed, or the object moved: touch again",
        v.fit_ratio,
    )


def across_an_edge(rec: Recognition, crossed: int) -> Recognition:
    """One touch whose data lie on more than one face or smooth patch of the named model
    (across a sharp edge) names no model: ``recognised`` becomes ``ambiguous``, the model
    alone in ``plausible``, and the reason says why."""
    if len(rec.touches) != 1 or rec.verdict != "recognised" or crossed < 2:
        return rec
    return dataclasses.replace(
        rec,
        verdict="ambiguous",
        reason=(
            f"{rec.reason}; the touch crosses a sharp edge of {rec.best.model} (its points "
            f"lie on {crossed} faces or smooth patches), and one touch across an edge is not "
            "enough to name a model: there the search may miss the right model's pose while "
            "another model fits; touch again away from the edge, or add touches"
        ),
    )
