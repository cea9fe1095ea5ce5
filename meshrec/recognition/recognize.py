"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.recognition.scoring import (
    ModelScore,
    PoseHypothesis,
    decide,
    fit_p_value,
    log_likelihoods,
    noise_estimate,
    pose_weights,
    posterior,
)
from meshrec.registration.objective import residuals
from meshrec.registration.register import Registration, register, touch_geometry
from meshrec.registration.transform import apply_transform

__all__ = ["Recognition", "recognize"]


@dataclass(frozen=True)
class Recognition:
    """The models ranked by how well the touch data superpose onto them.

    Attributes
    ----------
    touch : TouchData
        The touch data recognised.
    geometry : LocalGeometry
        The local geometry estimated at the contact (touch frame), shared by all models.
    ranking : tuple of Registration
        Every model, most probable first (then least error); models rejected by the table
        lookup last.
    seconds : float
        Wall time of the whole recognition.
    verdict : str
        "recognised", "ambiguous" or "unknown" (see
        :func:`meshrec.recognition.scoring.decide`).
    plausible : tuple of str
        The models the data cannot rule out, best first: one when recognised, two or
        more when ambiguous, none when unknown.
    noise : float
        The noise level estimated from the touch (standard deviation, data units).
    reason : str
        One sentence explaining the verdict.
    warnings : tuple of str
        Every warning raised while recognising, and the verdict's own cautions.
    scores : tuple of ModelScore
        The calibrated probability and weighted poses of each model, in ranking order.
    scoring_seconds : float
        Of ``seconds``, the time spent on the scores and the verdict (without a widened
        second lookup, which is counted in ``widened_seconds``).
    widened_seconds : float
        Time of the second, widened lookup pass (0 when the first pass fit the noise).
    """

    touch: TouchData
    geometry: LocalGeometry
    ranking: tuple[Registration, ...]
    seconds: float
    verdict: str = "unknown"
    plausible: tuple[str, ...] = ()
    noise: float = float("nan")
    reason: str = ""
    warnings: tuple[str, ...] = ()
    scores: tuple[ModelScore, ...] = ()
    scoring_seconds: float = 0.0
    widened_seconds: float = 0.0

    @property
    def best(self) -> Registration | None:
        """The recognised model's registration, or None if every model was rejected."""
        if not self.ranking or self.ranking[0].rejected:
            return None
        return self.ranking[0]

    @property
    def probabilities(self) -> dict[str, float]:
        """Posterior probability of each model, by name (ranking order)."""
        return {s.model: s.probability for s in self.scores}

    def __repr__(self) -> str:
        best = self.best.model if self.best is not None else None
        return (
            f"Recognition(verdict={self.verdict!r}, best={best!r}, "
            f"plausible={list(self.plausible)}, models={len(self.ranking)}, "
            f"noise={self.noise:.3g}, K={self.geometry.K:.4g}, H={self.geometry.H:.4g}, "
            f"seconds={self.seconds:.3f})"
        )


def _check_units(touch: TouchData, models: list) -> None:
    """Refuse a touch whose size is out of all proportion to every model's.

    The touch's size is the bounding-box diagonal of all its points; a model's is
    ``sqrt(surface area)``. The curves lie on the surface, so a touch many times larger
    than every model, or many times smaller (``defaults.UNIT_MISMATCH_RATIO``), is almost
    surely in other units than the models (millimetres against metres: a factor 1000).

    Parameters
    ----------
    touch : TouchData
    models : list of ModelIndex
        At least one.

    Raises
    ------
    ValueError
        If ``size / scale`` exceeds ``defaults.UNIT_MISMATCH_RATIO`` or is below its
        inverse for every model; the message says "likely a unit mismatch".
    """
    pts = touch.points
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if not size > 0.0:
        return  # a point-like touch: the geometry estimate says what is wrong with it
    scales = np.array([float(m.scale) for m in models])
    ratio = size / scales
    limit = defaults.UNIT_MISMATCH_RATIO
    if np.all(ratio > limit) or np.all(ratio < 1.0 / limit):
        k = int(np.argmin(np.abs(np.log(np.maximum(ratio, 1e-300)))))
        way = "larger" if ratio[k] > 1.0 else "smaller"
        factor = ratio[k] if ratio[k] > 1.0 else 1.0 / ratio[k]
        raise ValueError(
            f"the touch data ({size:.4g} across) is {factor:.3g} times {way} than the "
            f"nearest-sized model {models[k].name!r} (sqrt(area) {scales[k]:.4g}), beyond "
            f"defaults.UNIT_MISMATCH_RATIO = {limit:g} for every model: likely a unit "
            "mismatch (mm vs m?); touch data and models must be in the same units"
        )


def recognize(
    touch: TouchData,
    library,
    method: str = defaults.SEARCH_METHOD,
    progress: Callable[[int, int, str], None] | None = None,
    geometry: LocalGeometry | None = None,
) -> Recognition:
    """Recognise which model of ``library`` the touch data came from, and where.

    Parameters
    ----------
    touch : TouchData
        The curves, in the touch frame.
    library : ModelLibrary or iterable of ModelIndex
        The candidate models.
    method : {"lm", "steepest"}
        The local-search optimiser.
    progress : callable, optional
        Called as ``progress(i, n, name)`` before each model is registered.
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (by
        :func:`meshrec.registration.register.touch_geometry`); estimated here otherwise.

    Returns
    -------
    Recognition
        The ranking (most probable first) with the calibrated scores and the verdict
        (recognised, ambiguous or unknown; see :mod:`meshrec.recognition.scoring`). When
        even the best fit is worse than the noise allows, every model is registered again
        with the (K, H) lookup widened (``defaults.LOOKUP_WIDEN_SCALE``) before the verdict.
        Every warning raised inside is passed on as usual and its text kept in
        ``Recognition.warnings``.

    Raises
    ------
    ValueError
        If the library is empty, ``method`` is unknown, the touch's size is out of all
        proportion to every model's (a likely unit mismatch, see ``_check_units``), or
        the curves do not allow an estimate of the local geometry.
    """
    t0 = time.perf_counter()
    models = list(library)
    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rec = _rank(touch, models, method, progress, geometry)
            rec = _with_verdict(rec, models, method)
    finally:
        # Pass every warning on as before (the caller's filters decide what is shown),
        # also when the recognition fails; the result keeps their text.
        raised = list(caught)
        for w in raised:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    texts = tuple(dict.fromkeys([str(w.message) for w in raised] + list(rec.warnings)))
    return dataclasses.replace(rec, warnings=texts, seconds=time.perf_counter() - t0)


def _rank(touch, library, method, progress, geometry) -> Recognition:
    """Register the touch on every model and rank them (the recognition proper)."""
    t0 = time.perf_counter()
    models = list(library)
    if not models:
        raise ValueError("library must hold at least one model, got none")
    _check_units(touch, models)
    if geometry is None:
        geometry = touch_geometry(touch)
    results = []
    for i, model in enumerate(models):
        if progress is not None:
            progress(i, len(models), model.name)
        # The best error so far lets a model that cannot win stop its searches early.
        done = [r.error for r in results if r.error is not None]
        rival = min(done) if done else None
        results.append(register(touch, model, geometry=geometry, method=method, rival_error=rival))
    results.sort(key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model))
    return Recognition(
        touch=touch, geometry=geometry, ranking=tuple(results), seconds=time.perf_counter() - t0
    )


# --------------------------------------------------------------------------- the verdict
def _fits(model, reg: Registration, points: np.ndarray) -> tuple[float, list[np.ndarray]]:
    """The RMS residual at a registration's pose, and its pose hypotheses.

    Adapter, replaced by ``Registration.rms`` / ``Registration.poses`` after the stages
    merge: until then the only pose is the best one, and its RMS is recomputed here.
    """
    res = residuals(model, apply_transform(reg.T_model_touch, points))
    return float(np.sqrt(np.mean(res.values**2))), [reg.T_model_touch]


def _score(rec: Recognition, models: dict) -> tuple[tuple[ModelScore, ...], float]:
    """Per-model calibrated scores (ranking order) and the noise estimate."""
    g = rec.geometry
    points = rec.touch.points
    n = int(rec.touch.n_points)
    noise = noise_estimate(g.fit_rms, g.noise_rms, g.half_length)
    rms, poses = [], []
    for reg in rec.ranking:
        if reg.rejected:
            rms.append(None)
            poses.append(())
            continue
        r, Ts = _fits(models[reg.model], reg, points)
        pose_rms = [r] * len(Ts)  # one pose per model until the stages merge
        w = pose_weights(pose_rms, n, noise)
        rms.append(r)
        poses.append(
            tuple(
                PoseHypothesis(T, pr, float(wi)) for T, pr, wi in zip(Ts, pose_rms, w, strict=True)
            )
        )
    ll = log_likelihoods(rms, n, noise)
    prob = posterior(ll)
    scores = tuple(
        ModelScore(reg.model, float(p), r, n, float(li), ps)
        for reg, p, r, li, ps in zip(rec.ranking, prob, rms, ll, poses, strict=True)
    )
    return scores, noise


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


def _widened(rec: Recognition, models: dict, method: str) -> Recognition:
    """Register every model again with the (K, H) window widened; keep each one's better fit."""
    g = rec.geometry
    merged = []
    for reg in rec.ranking:
        wide = register(
            rec.touch,
            models[reg.model],
            geometry=g,
            method=method,
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        )
        if reg.rejected or (not wide.rejected and wide.error < reg.error):
            merged.append(wide)
        else:
            merged.append(reg)
    return dataclasses.replace(rec, ranking=tuple(merged))


def _with_verdict(rec: Recognition, models: list, method: str) -> Recognition:
    """Add the calibrated scores, the verdict and its cautions to a ranking.

    When even the best model fits far worse than the noise (or no model was registered),
    the (K, H) lookup may have kept the right contact out (curves straddling a seam
    between two patches of different curvature): the lookup is then widened by
    ``defaults.LOOKUP_WIDEN_SCALE`` and every model registered again before concluding.
    """
    by_name = {m.name: m for m in models}
    n = int(rec.touch.n_points)
    t0 = time.perf_counter()
    scores, noise = _score(rec, by_name)
    rec = _ordered(rec, scores)
    t_score = time.perf_counter() - t0
    t_wide = 0.0
    best = rec.scores[0] if rec.scores else None
    cautions = []
    if best is None or best.rms is None or fit_p_value(best.rms, n, noise) < defaults.WIDEN_P_VALUE:
        # Even the best fit is worse than the noise allows: look harder before
        # concluding. The lookup is a prior, not a gate: curves straddling a seam between
        # patches of different curvature may mismatch every vertex's (K, H) of the right
        # model, so every model is registered again with the window widened.
        t1 = time.perf_counter()
        rec = _widened(rec, by_name, method)
        scores, noise = _score(rec, by_name)
        rec = _ordered(rec, scores)
        t_wide = time.perf_counter() - t1
        cautions.append(
            "the best fit was worse than the noise allows: the curvature lookup was widened "
            f"{defaults.LOOKUP_WIDEN_SCALE:g} times and every model registered again"
        )
    t1 = time.perf_counter()
    names = [s.model for s in rec.scores]
    probs = [s.probability for s in rec.scores]
    top = rec.scores[0] if rec.scores else None
    v = decide(names, probs, None if top is None else top.rms, int(rec.touch.n_points), noise)
    g = rec.geometry
    if (
        g.fit_to_noise > defaults.ROUGH_FIT_RATIO
        and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * g.half_length
    ):
        cautions.append(
            f"the curve fits leave {g.fit_to_noise:.3g} times the noise the samples show: "
            "the curves may cross an edge, and the probabilities are less reliable"
        )
    t_score += time.perf_counter() - t1
    return dataclasses.replace(
        rec,
        verdict=v.verdict,
        plausible=v.plausible,
        noise=float(noise),
        reason=v.reason,
        warnings=tuple(cautions),
        scoring_seconds=t_score,
        widened_seconds=t_wide,
    )
