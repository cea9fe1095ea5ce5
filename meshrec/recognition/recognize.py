"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_choice, check_instance
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.recognition.scoring import (
    ModelScore,
    WeightedPose,
    decide,
    fit_p_value,
    log_likelihoods,
    noise_estimate,
    pose_weights,
    posterior,
)
from meshrec.recognition.units import check_units
from meshrec.registration.register import Registration, register, touch_geometry
from meshrec.registration.search import SEARCH_METHODS

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
        Every model, most probable first (then least error, then name); models rejected
        by the table lookup last. Each model is registered independently of the others, so
        the ranking does not depend on the order of the models.
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
    TypeError
        If ``touch`` is not a TouchData, ``library`` not an iterable of ModelIndex,
        ``method`` not a
        string, ``geometry`` not a LocalGeometry or ``progress`` not callable (the shared
        checks of :mod:`meshrec.io.checks`).
    ValueError
        If the library is empty, ``method`` is unknown, the touch's size is out of all
        proportion to every model's (a likely unit mismatch, see
        :func:`meshrec.recognition.units.check_units`), or
        the curves do not allow an estimate of the local geometry.
    """
    t0 = time.perf_counter()
    check_instance(touch, TouchData, "touch")
    check_choice(method, SEARCH_METHODS, "method")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be callable or None, got {type(progress).__name__}")
    if isinstance(library, (str, bytes)) or not hasattr(library, "__iter__"):
        raise TypeError(
            f"library must be a ModelLibrary or an iterable of ModelIndex, got "
            f"{type(library).__name__}"
        )
    models = list(library)
    for i, model in enumerate(models):
        check_instance(model, ModelIndex, f"library[{i}]")
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
    check_units(touch, models)
    if geometry is None:
        geometry = touch_geometry(touch)
    # Every model is registered on its own (the result of one never depends on another),
    # so the order of the models, or running them apart, changes nothing.
    results = []
    for i, model in enumerate(models):
        if progress is not None:
            progress(i, len(models), model.name)
        results.append(register(touch, model, geometry=geometry, method=method))
    results.sort(key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model))
    return Recognition(
        touch=touch, geometry=geometry, ranking=tuple(results), seconds=time.perf_counter() - t0
    )


# --------------------------------------------------------------------------- the verdict
def _score(rec: Recognition) -> tuple[tuple[ModelScore, ...], float]:
    """Per-model calibrated scores (ranking order) and the noise estimate."""
    g = rec.geometry
    n = int(rec.touch.n_points)
    noise = noise_estimate(g.fit_rms, g.noise_rms, g.half_length)
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
    scores, noise = _score(rec)
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
        scores, noise = _score(rec)
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
