"""The scores of a ranking as it stands, and what they decide.

Every stage of a recognition that registers models (again) scores the ranking afresh
(:func:`rescored`) and asks the same questions of it: does it name one model
(:func:`would_recognise`), does even the best model fit worse than the noise allows
(:func:`fits_worse_than_noise`)? The noise the scores take is the touches' own and the
model meshes' own error, added in quadrature (:func:`model_error`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from meshrec import defaults
from meshrec.recognition.joint import pooled_noise
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import (
    ModelScore,
    Verdict,
    WeightedPose,
    decide,
    fit_p_value,
    log_likelihoods,
    noise_estimate,
    pose_weights,
    posterior,
)

__all__ = [
    "decided",
    "fits_below",
    "fits_worse",
    "fits_worse_than_noise",
    "model_error",
    "noise_and_points",
    "rescored",
    "would_recognise",
]


def noise_and_points(rec: Recognition) -> tuple[float, int]:
    """The noise estimated from the touches (pooled over several) and their points."""
    touches = rec.touches or (rec.touch,)
    geometries = rec.geometries or (rec.geometry,)
    noises = [noise_estimate(g.fit_rms, g.noise_rms, g.half_length) for g in geometries]
    counts = [int(t.n_points) for t in touches]
    noise = noises[0] if len(noises) == 1 else pooled_noise(noises, counts)
    return noise, int(sum(counts))


def _scores(
    rec: Recognition, prior: dict | None, models: list
) -> tuple[tuple[ModelScore, ...], float]:
    """Per-model calibrated scores (ranking order) and the noise they take; ``prior``: the
    models' prior weights by name (None: uniform).

    The noise is the touches' own (:func:`noise_and_points`) and the model meshes' own
    error (:func:`model_error`) added in quadrature: a residual holds both."""
    noise, n = noise_and_points(rec)
    noise = float(np.hypot(noise, model_error(rec, models)))
    rms, poses = [], []
    for reg in rec.ranking:
        if reg.rejected:
            rms.append(None)
            poses.append(())
            continue
        pose_rms = [pose.rms for pose in reg.poses]
        w = pose_weights(pose_rms, n, noise)
        rms.append(reg.rms)
        poses.append(
            tuple(
                WeightedPose(pose.T_model_touch, pose.rms, float(wi))
                for pose, wi in zip(reg.poses, w, strict=True)
            )
        )
    ll = log_likelihoods(rms, n, noise)
    prob = posterior(ll, None if prior is None else [prior[r.model] for r in rec.ranking])
    scores = tuple(
        ModelScore(reg.model, float(p), r, n, float(li), ps)
        for reg, p, r, li, ps in zip(rec.ranking, prob, rms, ll, poses, strict=True)
    )
    return scores, noise


def model_error(rec: Recognition, models: list) -> float:
    """The largest error of the meshes of the models that compete: the RMS distance of
    the true surface from the mesh of a model whose vertices scatter by ``s`` about it
    (:attr:`~meshrec.model.index.ModelIndex.vertex_scatter`), ``s / sqrt(2)`` (a point of
    a face sees its corners' offsets blended by its barycentric weights, whose squares
    average 1/2). Every model whose best fit comes within
    ``defaults.MODEL_ERROR_REACH`` times the best RMS competes; 0 when none is registered.

    A raw scan's mesh scatters by the scanner's noise: where that is comparable to the
    probe's, the right model's residuals exceed the touch's noise and a look-alike's mesh
    can fit as well by chance (:mod:`meshrec.model.roughness`); an exact mesh adds
    nothing."""
    fitted = [r for r in rec.ranking if not r.rejected and r.rms is not None]
    if not fitted:
        return 0.0
    best = min(r.rms for r in fitted)
    by_name = {m.name: m for m in models}
    reach = [r.model for r in fitted if r.rms <= defaults.MODEL_ERROR_REACH * best]
    scatter = max(float(getattr(by_name[name], "vertex_scatter", 0.0)) for name in reach)
    return scatter / np.sqrt(2.0)


def _ordered(rec: Recognition, scores: tuple[ModelScore, ...]) -> Recognition:
    """The ranking and its scores re-ordered: most probable first, then least error."""
    key = {
        s.model: (r.rejected, -s.probability, r.error if r.error is not None else 0.0, r.model)
        for r, s in zip(rec.ranking, scores, strict=True)
    }
    pairs = sorted(zip(rec.ranking, scores, strict=True), key=lambda rs: key[rs[0].model])
    return dataclasses.replace(
        rec, ranking=tuple(r for r, _ in pairs), scores=tuple(s for _, s in pairs)
    )


def decided(rec: Recognition, prior, n: int, noise: float) -> Verdict:
    """The verdict of the scores as they stand (a flat touch's prior never decides alone)."""
    names = [s.model for s in rec.scores]
    probs = [s.probability for s in rec.scores]
    top = rec.scores[0] if rec.scores else None
    v = decide(names, probs, None if top is None else top.rms, n, noise)
    if prior is not None:
        v = _with_data_plausible(v, rec.scores, n, noise)
    return v


def would_recognise(rec: Recognition, prior, n: int, noise: float) -> bool:
    """Whether the scores as they stand name one model (``recognised``)."""
    return decided(rec, prior, n, noise).verdict == "recognised"


def fits_worse_than_noise(rec: Recognition, n: int, noise: float) -> bool:
    """Whether even the best-scored model (or none at all) fits worse than the noise allows."""
    return fits_below(rec, n, noise, defaults.WIDEN_P_VALUE)


def fits_below(rec: Recognition, n: int, noise: float, p_value: float) -> bool:
    """Whether even the best-scored model (or none at all) fits with a chi-square tail
    below ``p_value``."""
    best = rec.scores[0] if rec.scores else None
    return best is None or best.rms is None or fit_p_value(best.rms, n, noise) < p_value


def fits_worse(rms: float, n: int, noise: float) -> bool:
    """Whether a fit's RMS is worse than the noise allows (``defaults.WIDEN_P_VALUE``)."""
    return fit_p_value(rms, n, noise) < defaults.WIDEN_P_VALUE


def _with_data_plausible(v: Verdict, scores, n: int, noise: float) -> Verdict:
    """The verdict of a flat touch: the prior orders the models but removes none that the
    data alone leave plausible, and it never makes one ``recognised`` alone."""
    if v.verdict == "unknown":
        return v
    names = [s.model for s in scores]
    data = decide(names, posterior([s.log_likelihood for s in scores]), scores[0].rms, n, noise)
    if data.verdict == "unknown":
        return v
    keep = set(v.plausible) | set(data.plausible)
    plausible = tuple(s.model for s in scores if s.model in keep)  # most probable first
    if len(plausible) == len(v.plausible) and v.verdict == data.verdict:
        return v
    reason = (
        f"the data cannot separate {len(plausible)} models ({', '.join(plausible)}) on this "
        "flat touch: they fit about equally well, and how often each one's surface is flat "
        "over the curves' reach orders them; touch again elsewhere to decide"
    )
    return Verdict("ambiguous", plausible, reason, v.fit_ratio)


def rescored(rec: Recognition, prior: dict | None, models: list) -> tuple[Recognition, float]:
    """``rec`` with its models scored afresh and ordered most probable first, and the
    noise the scores take.

    Parameters
    ----------
    rec : Recognition
        A ranking (its registrations).
    prior : dict of str to float or None
        The models' prior weights by name (None: uniform).
    models : list of ModelIndex
        The library (for the meshes' own error).

    Returns
    -------
    recognition : Recognition
        With ``scores`` and ``ranking`` re-ordered.
    noise : float
    """
    scores, noise = _scores(rec, prior, models)
    return _ordered(rec, scores), noise
