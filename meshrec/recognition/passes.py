"""Registering the models: the first pass, and the passes that look again.

:func:`rank` registers one touch on every model (the paper's method, through the cascade
when asked); :func:`rank_joint` fits several touches at one pose per model, best first,
and searches again from pairs of touches where a joint pose may have been missed.
:func:`looked_harder` and :func:`looked_again` register the models again with the (K, H)
window widened or more candidates, each model keeping its best fit of all: when even
the best fit is worse than the noise allows, and before a model is named
(:mod:`meshrec.recognition.naming`). :func:`search_lone_leader` searches the one leading
model again from pairs of touches, so that every pose its touches allow is among its
poses.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.recognition.bestfirst import fit_best_first
from meshrec.recognition.cascade import cascade_register
from meshrec.recognition.joint import (
    check_touch_sizes,
    explore_weak_motions,
    first_touch_fit,
    log_likelihood_bound,
    register_touches,
    rms_out_of_reach,
    search_pairs,
)
from meshrec.recognition.phases import timed
from meshrec.recognition.rescore import fits_below, fits_worse, noise_and_points, rescored
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import log_likelihoods, noise_estimate
from meshrec.recognition.units import check_units
from meshrec.recognition.workers import ModelWorkers
from meshrec.registration.register import touch_geometry

__all__ = [
    "curvature_turn",
    "looked_again",
    "looked_harder",
    "rank",
    "rank_joint",
    "search_lone_leader",
]


def rank(touch, library, method, progress, geometry, run, cascade=False) -> Recognition:
    """Register the touch on every model and rank them (the recognition proper)."""
    t0 = time.perf_counter()
    models = list(library)
    if not models:
        raise ValueError("library must hold at least one model, got none")
    with timed("checks"):
        check_units(touch, models)
    if geometry is None:
        with timed("geometry"):
            geometry = touch_geometry(touch)
    # Every model is registered on its own (the result of one never depends on another),
    # so the order of the models, or running them apart, changes nothing.
    with timed("first"):
        if cascade:
            # the cascade's decisions here, its per-model batches on the workers
            noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
            results = cascade_register(touch, models, geometry, noise, method, progress, run=run)
        else:
            results = run.register_each(touch, models, geometry, method, progress=progress)
    return _ranked(
        Recognition(
            touch=touch,
            geometry=geometry,
            ranking=(),
            seconds=time.perf_counter() - t0,
            touches=(touch,),
            geometries=(geometry,),
        ),
        results,
    )


def _ranked(rec: Recognition, results) -> Recognition:
    """``rec`` with ``results`` as its ranking, least error first (rejected last)."""
    results = sorted(
        results, key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model)
    )
    return dataclasses.replace(rec, ranking=tuple(results))


def rank_joint(touches, models, method, progress, geometries, run, cascade=False):
    """Several touches: every model fitted at one pose to all, the needed touches alone.

    Per model (independently of the others) the first touch is registered alone. Then,
    most promising model first (:func:`~meshrec.recognition.bestfirst.fit_best_first`),
    its poses are refined on every touch and, while the joint fit is worse than the noise
    allows, the next touch is registered alone too, unless even the model's best
    conceivable fit (:func:`~meshrec.recognition.joint.log_likelihood_bound`) is already
    far below the best joint fit so far (``defaults.JOINT_PRUNE_LOG_RATIO``).
    """
    t0 = time.perf_counter()
    if not models:
        raise ValueError("library must hold at least one model, got none")
    with timed("checks"):
        check_touch_sizes(touches)
        for touch in touches:
            check_units(touch, models)
    with timed("geometry"):
        geometries = tuple(
            g if g is not None else touch_geometry(t)
            for t, g in zip(touches, geometries, strict=True)
        )
    rec = Recognition(
        touch=touches[0],
        geometry=geometries[0],
        ranking=(),
        seconds=0.0,
        touches=touches,
        geometries=geometries,
    )
    noise, n = noise_and_points(rec)
    with timed("first"):
        if cascade:
            # The first touch through the cascade: a model it prunes fits the first touch
            # alone far worse than the leaders, and a joint fit is worse still.
            regs = cascade_register(
                touches[0], models, geometries[0], None, method, progress, trace=True, run=run
            )
        else:
            regs = run.register_each(
                touches[0], models, geometries[0], method, trace=True, progress=progress
            )
        firsts = {
            model.name: first_touch_fit(touches, model, first)
            for model, first in zip(models, regs, strict=True)
        }
    # Most promising model first, each model a step (one more touch) at a time, until
    # it fits every touch to the noise or cannot become plausible (branch and bound:
    # meshrec.recognition.bestfirst).
    with timed("best_first"):
        fits = fit_best_first(touches, models, geometries, firsts, noise, method)
    with timed("adequacy"):
        _search_adequately(touches, models, geometries, fits, noise, n, method)
    with timed("symmetries"):
        _explore_near_symmetries(touches, models, geometries, fits, noise, n)
    rec = dataclasses.replace(rec, seconds=time.perf_counter() - t0)
    return _ranked(rec, [f.registration for f in fits.values()]), fits


def _search_adequately(
    touches,
    models,
    geometries,
    fits: dict,
    noise: float,
    n: int,
    method,
    lookup_scale=1.0,
    below=True,
):
    """Search again, from pairs of touches, every model whose joint pose may have been missed.

    The scores trust each model's best joint fit. On look-alike shapes touched with short
    noisy curves each touch alone fits every model at many places, and the right model's
    joint search can end in a wrong basin while a wrong model's happens to fit: a wrong
    and confident answer. The right model's search can also end in a wrong basin
    while it still leads (touches across a scan's rims, where each touch alone is placed
    badly): then even the best joint fit is worse than the noise allows, and the answer
    would be ``unknown`` for an object in the library. So, in rounds until none qualifies
    (each model searched once; an order-free step over all the fits): a model more than
    ``defaults.PAIR_SEARCH_GAP`` below the best log-likelihood, or whose joint fit is worse
    than the noise allows (p-value under ``defaults.WIDEN_P_VALUE``), is registered on
    every touch alone; if its best conceivable fit
    (:func:`~meshrec.recognition.joint.log_likelihood_bound`) still comes within that gap
    of the best, it is searched again from pairs of touches
    (:func:`~meshrec.recognition.joint.search_pairs`), both with the (K, H) window widened
    by ``lookup_scale``. With ``below`` False only the models within the gap of the best
    that fit worse than the noise qualify (the widened pass: the leaders, where a missed
    pose turns the answer to ``unknown``). ``fits`` is updated in place.
    """
    searched = set()
    gap = defaults.PAIR_SEARCH_GAP
    while True:
        leader, ll_of = _log_likelihoods_of(fits, n, noise)
        todo = [
            m
            for m in models
            if m.name not in searched
            and not fits[m.name].registration.rejected
            and (
                (below and ll_of[m.name] < leader - gap)
                or (
                    ll_of[m.name] >= leader - gap
                    and fits_worse(fits[m.name].registration.rms, n, noise)
                )
            )
            and log_likelihood_bound(fits[m.name], touches, noise, geometries) >= leader - gap
        ]
        if not todo:
            return
        for model in todo:
            searched.add(model.name)
            fit = fits[model.name]
            if fit.registered < len(touches):
                fit = register_touches(
                    touches,
                    model,
                    geometries,
                    upto=len(touches),
                    previous=fit,
                    method=method,
                    lookup_scale=lookup_scale,
                    noise=noise,
                )
            if log_likelihood_bound(fit, touches, noise, geometries) >= leader - gap:
                far = rms_out_of_reach(leader, n, noise)
                fit = search_pairs(
                    touches, model, geometries, fit, lookup_scale=lookup_scale, hopeless_rms=far
                )
            fits[model.name] = fit


def search_lone_leader(touches, models, geometries, fits: dict, noise: float, n: int):
    """Several touches: the one model that leads alone (no other within
    ``defaults.PAIR_SEARCH_GAP`` of its log-likelihood) is searched from pairs of touches
    again, so that every pose its touches allow is among its poses before its pose is
    given.

    On a part that is nearly symmetric where it was touched (a plate's two faces, a box's
    faces on either side of an edge) the joint search can end at one of two poses a
    half-turn apart that fit equally well; the other was then never found and the pose
    was given as fixed (a black-box probe, stop 32: three of fifteen `recognised`
    three-touch answers 31 to 43 mm off, about 5,000 sigma). The pairs of touches match
    pairs of the model's points with the same features whichever of the two it is. The
    poses found join the model's (its best fit only improves); their weights then say
    whether the pose is one of several. The (K, H) window is widened
    (``defaults.LOOKUP_WIDEN_SCALE``). ``fits`` is updated in place.
    """
    names = list(fits)
    ll = log_likelihoods([fits[k].registration.rms for k in names], n, noise)
    order = np.argsort(ll)[::-1]
    leader = names[int(order[0])]
    if fits[leader].registration.rejected:
        return
    if len(order) > 1 and ll[int(order[1])] >= ll[int(order[0])] - defaults.PAIR_SEARCH_GAP:
        return  # not named alone: its pose is not given as the answer's
    model = {m.name: m for m in models}[leader]
    # the window widened: on a coarse export a touch's (K, H) can miss the sites around
    # its true contact (a plate's face touched with H 0.012 where the model's is 0: 8 of
    # 400 spread points matched, none near the truth)
    fits[leader] = search_pairs(
        touches, model, geometries, fits[leader], lookup_scale=defaults.LOOKUP_WIDEN_SCALE
    )


def _explore_near_symmetries(touches, models, geometries, fits: dict, noise: float, n: int):
    """Follow the weakest motions of the leading models' joint poses for better basins.

    Every model within ``defaults.PAIR_SEARCH_GAP`` of the best log-likelihood (an
    order-free set, taken before any is explored) is refined again from poses a long way
    along its best pose's near-symmetries
    (:func:`~meshrec.recognition.joint.explore_weak_motions`): on a nearly symmetric
    object the joint search can end at a precise-looking pose a large turn away from the
    right one. ``fits`` is updated in place.
    """
    leader, ll_of = _log_likelihoods_of(fits, n, noise)
    near = [
        m
        for m in models
        if not fits[m.name].registration.rejected
        and ll_of[m.name] >= leader - defaults.PAIR_SEARCH_GAP
    ]
    for model in near:
        fits[model.name] = explore_weak_motions(touches, model, geometries, fits[model.name])


def _widened(
    rec: Recognition,
    models: dict,
    method: str,
    run,
    max_candidates=None,
    only=None,
    lookup_scale: float = defaults.LOOKUP_WIDEN_SCALE,
) -> tuple[Recognition, frozenset]:
    """One touch: register every model again with the (K, H) window widened; keep each
    one's better fit.

    Each model may look at up to ``max_candidates`` candidates (None: the default number),
    and only the models named in ``only`` (None: all) are registered; the others are kept
    as they are. ``lookup_scale`` widens the window (``defaults.LOOKUP_OPEN_SCALE`` opens
    it to every site).

    Returns the merged recognition and the names of the models whose widened lookup
    filled the cap (``defaults.MAX_CANDIDATES`` candidates): only for them can a denser
    look choose other candidates (the spreading stops short of the cap by the same rule
    whatever the cap, so a model under it would get the same candidates and the same fit;
    a model with none, rejected, gets none again).
    """
    todo = [reg for reg in rec.ranking if only is None or reg.model in only]
    regs = run.register_each(
        rec.touch,
        [models[reg.model] for reg in todo],
        rec.geometry,
        method,
        lookup_scale=lookup_scale,
        max_candidates=max_candidates,
    )
    wides = {reg.model: wide for reg, wide in zip(todo, regs, strict=True)}
    capped = frozenset(
        name for name, wide in wides.items() if wide.candidates >= defaults.MAX_CANDIDATES
    )
    merged = []
    for reg in rec.ranking:
        wide = wides.get(reg.model, reg)
        better = reg.rejected or (not wide.rejected and wide.error < reg.error)
        merged.append(wide if better else reg)
    return dataclasses.replace(rec, ranking=tuple(merged)), capped


def looked_again(rec: Recognition, prior, models: list, method: str, run, phase: str, **kw):
    """One touch: :func:`_widened` (``kw`` its options), timed as ``phase``, and the scores
    again: ``(recognition, noise, run)`` (``run`` started here when None)."""
    if run is None:
        run = ModelWorkers(models, workers=1)
    with timed(phase):
        rec, _ = _widened(rec, {m.name: m for m in models}, method, run, **kw)
        rec, noise = rescored(rec, prior, models)
    return rec, noise, run


def looked_harder(
    rec: Recognition, prior, fits: dict, models: list, method: str, run, n: int, p_value: float
):
    """Every model registered again with the (K, H) window widened
    (``defaults.LOOKUP_WIDEN_SCALE``), and the scores again; for one touch whose best fit
    still has a chi-square tail below ``p_value``, once more with up to
    ``defaults.LOOKUP_DENSE_CANDIDATES`` candidates on the models whose widened window
    held more than the cap. Each model keeps its best fit of all.

    A touch whose curvature estimate is out of its range (:func:`curvature_turn` above
    ``defaults.CURVATURE_MAX_TURN``) and still fits nothing that well has the models the
    widened lookup rejected registered on every site
    (``defaults.LOOKUP_OPEN_SCALE``).

    Returns ``(recognition, noise, run, how)``: ``run`` is started here when None, and
    ``how`` says what was done (for the caution).
    """
    by_name = {m.name: m for m in models}
    if run is None:
        run = ModelWorkers(models, workers=1)
    with timed("widened"):
        if len(rec.touches) == 1:
            rec, capped = _widened(rec, by_name, method, run)
        else:
            rec = _widened_joint(rec, fits, by_name, method)
        rec, noise = rescored(rec, prior, models)
    how = "every model registered again"
    # the touch's own noise (not the meshes' error the scores add): a marginal fit to the
    # touch is a reason to look harder on any mesh
    if len(rec.touches) == 1 and fits_below(rec, n, noise_and_points(rec)[0], p_value):
        # Still no good fit: where the widened window matches most of a model's sites (a
        # thin, rough scan; a box's flat faces), the spread candidates lie too far apart to
        # start from; look once more among more of them (on the models where the window
        # held more than the cap: the others would get the same candidates).
        if capped:
            dense = {"max_candidates": defaults.LOOKUP_DENSE_CANDIDATES, "only": capped}
            rec, noise, run = looked_again(rec, prior, models, method, run, "dense", **dense)
            how += (
                f", then once more with up to {defaults.LOOKUP_DENSE_CANDIDATES} candidates "
                f"on the {len(capped)} model(s) whose window held more than "
                f"{defaults.MAX_CANDIDATES} sites"
            )
        turn = curvature_turn(rec.geometry)
        rejected = frozenset(r.model for r in rec.ranking if r.rejected)
        if (
            turn > defaults.CURVATURE_MAX_TURN
            and rejected
            and fits_below(rec, n, noise_and_points(rec)[0], p_value)
        ):
            # The curvature estimate is out of its range (curves long against the radius
            # of curvature, or across an edge: a probe, stop 34, touched a sheet-metal
            # bracket's bend next to its side edge, K estimated 0.055 where the bend has
            # 0, and every model was rejected, "the object is probably not in the
            # library"): even the widened window, built on that estimate, can miss the
            # right model, so the models it rejected are registered on every site.
            opened = {"only": rejected, "lookup_scale": defaults.LOOKUP_OPEN_SCALE}
            rec, noise, run = looked_again(rec, prior, models, method, run, "widened", **opened)
            found = sum(1 for r in rec.ranking if r.model in rejected and not r.rejected)
            how += (
                f"; the curvature estimate being out of its range (the curves would turn by "
                f"{turn:.3g} radians over their half-length, more than "
                f"defaults.CURVATURE_MAX_TURN = {defaults.CURVATURE_MAX_TURN:g}), the "
                f"{len(rejected)} model(s) the lookup still rejected were registered on every "
                f"site ({found} registered)"
            )
    return rec, noise, run, how


def _widened_joint(rec: Recognition, fits: dict, models: dict, method: str) -> Recognition:
    """Several touches: every model's touches registered alone again with the (K, H)
    window widened, jointly refined; each model keeps its better fit.

    Then the leading models whose joint fit may still have been missed are searched from
    pairs of touches with the wider window (:func:`_search_adequately`). ``fits`` (the
    joint fits, by model) is updated in place where the wider pass fits better.
    """
    noise, n = noise_and_points(rec)
    merged = []
    for reg in rec.ranking:
        fit = register_touches(
            rec.touches,
            models[reg.model],
            rec.geometries,
            upto=len(rec.touches),
            method=method,
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
            noise=noise,
        )
        wide = fit.registration
        if reg.rejected or (not wide.rejected and wide.error < reg.error):
            merged.append(wide)
            fits[reg.model] = fit
        else:
            merged.append(reg)
    # Every touch registered alone with the wider window, but a leader's joint pose
    # missed still: its pairs of touches again, with the wider window too (the leaders
    # only: the models well below them were searched from pairs already, and searching
    # them all again costs an out-of-library answer a third more time).
    present = [models[reg.model] for reg in merged if reg.model in fits]
    _search_adequately(
        rec.touches,
        present,
        rec.geometries,
        fits,
        noise,
        n,
        method,
        lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        below=False,
    )
    _search_rough_touches(rec, present, fits, noise, n)
    merged = [fits[reg.model].registration if reg.model in fits else reg for reg in merged]
    return dataclasses.replace(rec, ranking=tuple(merged))


def _search_rough_touches(rec: Recognition, models: list, fits: dict, noise: float, n: int):
    """Several touches that no model fits, some of them rough (curve fits far worse than
    the noise: across an edge): the best ``defaults.ROUGH_PAIR_MODELS`` models by joint
    fit are searched from pairs of touches with the (K, H) window widened, whatever their
    bound.

    A rough touch's curvature is not defined, so each touch registered alone can miss its
    place, and the bound built on those registrations then rules the right model out of
    the pair search (a black-box probe, stop 32: three touches across a coarse plate's
    edges were `unknown` with the plate fourth at 28 times the noise, where its true pose
    fits to it; the widened pair search finds that pose). ``fits`` is updated in place.
    """
    rough = any(g.fit_to_noise > defaults.ROUGH_FIT_RATIO for g in rec.geometries)
    ranked = sorted(
        (m for m in models if not fits[m.name].registration.rejected),
        key=lambda m: (fits[m.name].registration.rms, m.name),
    )
    if not rough or not ranked or not fits_worse(fits[ranked[0].name].registration.rms, n, noise):
        return
    for model in ranked[: defaults.ROUGH_PAIR_MODELS]:
        fits[model.name] = search_pairs(
            rec.touches,
            model,
            rec.geometries,
            fits[model.name],
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        )


def curvature_turn(geometry: LocalGeometry) -> float:
    """How far the curves would turn, in radians, over their half-length at the estimated
    curvature (the larger principal curvature's magnitude times the half-length): above
    ``defaults.CURVATURE_MAX_TURN`` the estimate is out of the range it was measured on.

    Parameters
    ----------
    geometry : LocalGeometry

    Returns
    -------
    float
    """
    return max(abs(float(geometry.k1)), abs(float(geometry.k2))) * float(geometry.half_length)


def _log_likelihoods_of(fits: dict, n: int, noise: float) -> tuple[float, dict]:
    """The best log-likelihood of the joint fits and each model's, by name."""
    names = list(fits)
    ll = log_likelihoods([fits[k].registration.rms for k in names], n, noise)
    return float(np.max(ll)), dict(zip(names, ll, strict=True))
