"""Recognition: register the touch data on every model and rank them (Section 2.4).

The stages, each in its own module: the first pass (:mod:`meshrec.recognition.passes`),
the scores (:mod:`meshrec.recognition.rescore`), the passes before a model is named
(:mod:`meshrec.recognition.naming`), the holds on the verdict
(:mod:`meshrec.recognition.holds`) and the pose given with the answer
(:mod:`meshrec.recognition.best_pose`). This module checks the input, runs them in turn
and writes the verdict's reason and cautions.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_choice, check_instance
from meshrec.io.touch import RepeatedSamplesWarning, TouchData
from meshrec.model.index import ModelIndex
from meshrec.model.probe import probe_model
from meshrec.model.resolution import ResolutionWarning, coarse_message
from meshrec.recognition.best_pose import with_pose_freedom
from meshrec.recognition.edges import warn_sharp_edges
from meshrec.recognition.flatness import flat_prior, flat_tolerance
from meshrec.recognition.holds import (
    across_an_edge,
    every_touch_hold,
    rough_hold,
    within_calibration,
)
from meshrec.recognition.naming import before_naming
from meshrec.recognition.passes import looked_harder, rank, rank_joint
from meshrec.recognition.phases import phase_clock, timed
from meshrec.recognition.probing import (
    check_tip_fits,
    touch_probe_radius,
    warn_probe_offset,
)
from meshrec.recognition.rescore import (
    decided,
    fits_worse_than_noise,
    model_error,
    noise_and_points,
    rescored,
)
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import fit_p_value, noise_estimate
from meshrec.recognition.workers import ModelWorkers
from meshrec.registration.register import touch_geometry
from meshrec.registration.search import SEARCH_METHODS

__all__ = ["Recognition", "recognize"]


def recognize(
    touch: TouchData | Sequence[TouchData],
    library,
    method: str = defaults.SEARCH_METHOD,
    progress: Callable[[int, int, str], None] | None = None,
    geometry: LocalGeometry | Sequence[LocalGeometry] | None = None,
    probe_radius: float | None = None,
    workers=None,
    scheduler: str | None = None,
    cascade: bool | None = None,
) -> Recognition:
    """Recognise which model of ``library`` the touch data came from, and where.

    Parameters
    ----------
    touch : TouchData or sequence of TouchData
        One touch, or several touches of one object that did not move between them, all
        in one frame (the robot's world frame, say). With several, each model is fitted
        at one rigid pose to all of them (:mod:`meshrec.recognition.joint`) and scored on
        all the data.
    library : ModelLibrary or iterable of ModelIndex
        The candidate models.
    method : {"lm", "steepest"}
        The local-search optimiser.
    progress : callable, optional
        Called as ``progress(i, n, name)`` before each model is registered.
    geometry : LocalGeometry or sequence of LocalGeometry, optional
        The local geometry at each touch's contact, if already estimated (by
        :func:`meshrec.registration.register.touch_geometry`); estimated here otherwise,
        and also for a touch whose exactly repeated samples are removed (see
        :class:`RepeatedSamplesWarning`): a geometry given for it was estimated on the
        copies, which read the noise low.
    probe_radius : float, optional
        Radius of the probe's ball tip, data units (the data are the ball's centres, on
        the surface offset outwards by it): the models are compared with their offset
        surfaces (:func:`meshrec.model.probe.probe_model`) and the curvatures at the
        touch corrected (:func:`meshrec.contact.probe.surface_geometry`). Default: the
        touches' own ``probe_radius`` (from the touch JSON), else 0 (a point probe).
        Without a radius, data that fit a model's offset surface clearly better than
        the surface itself raise a :class:`~meshrec.contact.probe.ProbeOffsetWarning`.
    workers : int or ModelWorkers or None
        Where the per-model registrations run (:mod:`meshrec.recognition.workers`): None,
        in this process; an int, that many local processes (for this call); a
        :class:`~meshrec.recognition.workers.ModelWorkers` of this library, its workers.
        The result is the same as a serial run's.
    scheduler : str or None
        The address of a Dask ``distributed`` scheduler to run them on (for this call).
    cascade : bool, optional
        With one touch (and for the first of several), run the local searches only on
        the models whose best conceivable fit after the first stages is within reach of
        the leaders'
        (:mod:`meshrec.recognition.cascade`); the others keep their best screened pose,
        refined. False: the full search on every model. Default ``defaults.CASCADE``.
        With ``workers`` or ``scheduler`` the cascade's decisions are taken here and its
        per-model batches run on the workers: the result is that of a serial run with
        the same ``cascade``.

    Returns
    -------
    Recognition
        The ranking (most probable first) with the calibrated scores and the verdict
        (recognised, ambiguous or unknown; see :mod:`meshrec.recognition.scoring`). When
        even the best fit is worse than the noise allows, every model is registered again
        with the (K, H) lookup widened (``defaults.LOOKUP_WIDEN_SCALE``) before the verdict
        (with several touches: each touch alone, then the search from pairs of touches);
        one touch that still fits nothing, once more with up to
        ``defaults.LOOKUP_DENSE_CANDIDATES`` candidates per model (each model keeps its best
        fit of all). Every warning raised inside is passed on as usual and its text kept in
        ``Recognition.warnings``, with a ResolutionWarning for each plausible (or best)
        model too coarse for reliable answers. With several touches, ``T_model_touch`` maps their
        common frame to the model, and touches that no model fits at one pose (the object
        moved, or it is not in the library) give ``unknown`` with that reason.

    Raises
    ------
    TypeError
        If ``touch`` is neither a TouchData nor a sequence of them, ``library`` not an
        iterable of ModelIndex, ``method`` not a string, ``geometry`` not a LocalGeometry
        (or a sequence of them) or ``progress`` not callable (the shared checks of
        :mod:`meshrec.io.checks`).
    ValueError
        If there is no touch, two touches hold the same data, the library is empty,
        ``method`` is unknown, ``geometry``
        does not hold one LocalGeometry per touch, a touch's size is out of all
        proportion to every model's (a likely unit mismatch, see
        :func:`meshrec.recognition.units.check_units`) or to another touch's
        (:func:`meshrec.recognition.joint.check_touch_sizes`), the curves do not allow
        an estimate of the local geometry, ``probe_radius`` is negative or not finite,
        the touches give different radii (or one other than ``probe_radius``), or a
        touch with a ``normal`` is curved more tightly than the tip where it is convex
        (``probe_radius`` at least its smallest radius of curvature: no ball of that
        radius traces such data); or as :class:`~meshrec.recognition.workers.ModelWorkers`
        for ``workers`` and ``scheduler``.
    TypeError
        If ``cascade`` is not a bool or None.
    """
    # The clock in this frame, not in a wrapper: the warnings' stack levels count from here.
    with phase_clock() as clock:
        t0 = time.perf_counter()
        touches = _touches(touch)
        geometries = _geometries(geometry, len(touches))
        touches, repeats, thinned = _without_repeats(touches)
        # a geometry estimated on the copies read their noise (a CLI's early estimate,
        # made to refuse bad data before any model is indexed): estimated again
        geometries = tuple(None if cut else g for g, cut in zip(geometries, thinned, strict=True))
        check_choice(method, SEARCH_METHODS, "method")
        if progress is not None and not callable(progress):
            raise TypeError(f"progress must be callable or None, got {type(progress).__name__}")
        if cascade is None:
            cascade = defaults.CASCADE
        if not isinstance(cascade, (bool, np.bool_)):
            raise TypeError(f"cascade must be a bool or None, got {type(cascade).__name__}")
        if isinstance(library, (str, bytes)) or not hasattr(library, "__iter__"):
            raise TypeError(
                f"library must be a ModelLibrary or an iterable of ModelIndex, got "
                f"{type(library).__name__}"
            )
        models = list(library)
        for i, model in enumerate(models):
            check_instance(model, ModelIndex, f"library[{i}]")
        radius = touch_probe_radius(touches, probe_radius)
        # the models as the ball's centres see them (themselves for a point probe); the
        # resolution warnings are the plain models' own (their cached resolution)
        seen = [probe_model(m, radius) for m in models]
        caught: list = []
        run, own = _runner(seen, workers, scheduler, getattr(library, "cache_dir", None))
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                for text in repeats:
                    warnings.warn(text, RepeatedSamplesWarning, stacklevel=2)
                if radius > 0.0:
                    with timed("geometry"):
                        geometries = tuple(
                            g if g is not None else touch_geometry(t)
                            for t, g in zip(touches, geometries, strict=True)
                        )
                    with timed("checks"):
                        check_tip_fits(touches, geometries, radius)
                # the pose freedom at a pose, asked before naming and for the answer
                memo: dict = {}
                if len(touches) == 1:
                    rec = rank(
                        touches[0], seen, method, progress, geometries[0], run, bool(cascade)
                    )
                    rec = _with_verdict(rec, {}, seen, method, run, memo)
                else:
                    rec, fits = rank_joint(
                        touches, seen, method, progress, geometries, run, bool(cascade)
                    )
                    rec = _with_verdict(rec, fits, seen, method, run, memo)
                with timed("freedom"):
                    rec = with_pose_freedom(rec, seen, memo)
                with timed("cautions"):
                    _warn_coarse(rec, models)
                    crossed = warn_sharp_edges(rec, seen)
                    held = across_an_edge(rec, crossed)
                    # held back across the edge (its reason says why), or a caveat
                    rec = held if held is not rec else _edge_caveat(rec, crossed)
                if radius == 0.0:
                    with timed("probe_offset"):
                        rec = dataclasses.replace(rec, probe_offset=warn_probe_offset(rec, models))
        finally:
            if own:
                run.close()
            # Pass every warning on as before (the caller's filters decide what is shown),
            # also when the recognition fails; the result keeps their text.
            raised = list(caught)
            for w in raised:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
        texts = tuple(dict.fromkeys([str(w.message) for w in raised] + list(rec.warnings)))
        return dataclasses.replace(
            rec,
            warnings=texts,
            seconds=time.perf_counter() - t0,
            probe_radius=radius,
            phase_times=clock.times(),
        )


def _runner(models: list, workers, scheduler, cache_dir=None) -> tuple[ModelWorkers, bool]:
    """The workers to register the models with, and whether they are made (and closed)
    here; processes made here load the library from ``cache_dir`` (the library's own)."""
    if isinstance(workers, ModelWorkers):
        if scheduler is not None:
            raise ValueError(
                f"scheduler must be None when workers is a ModelWorkers, got {scheduler!r}"
            )
        return workers, False
    if workers is None and scheduler is None:
        workers = 1
    return ModelWorkers(models, workers=workers, scheduler=scheduler, cache_dir=cache_dir), True


def _warn_coarse(rec: Recognition, models: list) -> None:
    """One ResolutionWarning when models too coarse for reliable answers are among the
    plausible ones and the best (see :mod:`meshrec.model.resolution`): the model's own
    message, or for several their names and the first one's reasons (a probe, stop 34,
    got ten such lines on one flat touch of a library of brackets)."""
    names = list(rec.plausible)
    if rec.best is not None:
        names.append(rec.best.model)
    by_name = {m.name: m for m in models}
    coarse = [
        (name, by_name[name].resolution)
        for name in dict.fromkeys(names)
        if by_name[name].resolution.too_coarse
    ]
    if not coarse:
        return
    text = coarse_message(*coarse[0])
    if len(coarse) > 1:
        listed = ", ".join(name for name, _ in coarse[1:])
        text = f"{text} (also too coarse: {listed}; `meshrec models DIR` gives each one's reasons)"
    warnings.warn(text, ResolutionWarning, stacklevel=3)


def _touches(touch) -> tuple[TouchData, ...]:
    """One touch or a sequence of them, checked, as a tuple."""
    if isinstance(touch, TouchData):
        return (touch,)
    if isinstance(touch, (str, bytes)) or not isinstance(touch, Sequence):
        raise TypeError(
            f"touch must be a TouchData or a sequence of TouchData, got {type(touch).__name__}"
        )
    if len(touch) == 0:
        raise ValueError("touch must hold at least one TouchData, got an empty sequence")
    for i, t in enumerate(touch):
        check_instance(t, TouchData, f"touch[{i}]")
    # The same data twice (a file given twice) would count its evidence twice: its
    # likelihood ratios squared, an ambiguous answer made "recognised" by repetition.
    # (Two touches of the same place carry independent noise and are welcome.)
    # Copies that differ only far below the probe's noise (re-saved with rounding, a
    # jitter added) are the same data: every point within defaults.TOUCH_COPY_FRACTION of
    # their extent, or within defaults.TOUCH_COPY_NOISE_FRACTION of the samples' scatter
    # about their curves (a touch in mm and its copy rounded to 1 um, against 20 um of
    # noise, counted as two touches and moved every probability: a black-box probe, stop
    # 33). A second touch of the same place scatters by its own noise.
    for j, b in enumerate(touch):
        for i in range(j):
            a = touch[i]
            if len(a.curves) != len(b.curves) or any(
                x.shape != y.shape for x, y in zip(a.curves, b.curves, strict=True)
            ):
                continue
            extent = float(np.linalg.norm(np.ptp(a.points, axis=0)))
            apart = max(
                float(np.max(np.abs(x - y))) for x, y in zip(a.curves, b.curves, strict=True)
            )
            if apart > defaults.TOUCH_COPY_FRACTION * extent:
                scatter = min(_sample_scatter(a), _sample_scatter(b))
                if not apart <= defaults.TOUCH_COPY_NOISE_FRACTION * scatter:
                    continue
                same = (
                    f"nearly the same data (every point within {apart:.3g}, "
                    f"{apart / scatter:.2g} times the scatter of its samples about their "
                    "curves)"
                )
            else:
                same = (
                    "the same data"
                    if apart == 0.0
                    else (
                        f"nearly the same data (every point within {apart:.3g}, "
                        f"{apart / extent:.2g} of its extent)"
                    )
                )
            raise ValueError(
                f"touch[{j}] holds {same} as touch[{i}]: give each touch once "
                "(a repeated touch would count its evidence again)"
            )
    return tuple(touch)


def _sample_scatter(touch: TouchData) -> float:
    """The samples' scatter about their curves: the RMS, over every curve's inner samples,
    of the second difference across the chord (``p[i-1] - 2 p[i] + p[i+1]`` less its
    part along ``p[i+1] - p[i-1]``, which uneven spacing makes), over sqrt(12): the noise
    per coordinate for isotropic noise (the part across a chord has two of the three
    coordinates, each of variance 6 sigma^2); the curves' own bend adds to it. 0 without
    inner samples.

    Hand-written: a noise measure needing no fit (this runs before the touches' curve fits,
    :func:`~meshrec.contact.geometry.estimate_local_geometry`)."""
    parts = []
    for c in touch.curves:
        if len(c) < 3:
            continue
        d2 = c[:-2] - 2.0 * c[1:-1] + c[2:]
        chord = c[2:] - c[:-2]
        norm = np.linalg.norm(chord, axis=1)
        unit = chord / np.maximum(norm, 1e-300)[:, None]
        parts.append(d2 - np.einsum("ij,ij->i", d2, unit)[:, None] * unit)
    if not parts:
        return 0.0
    across = np.vstack(parts)
    return float(np.sqrt((across**2).sum(axis=1).mean() / 12.0))


def _without_repeats(touches: tuple) -> tuple[tuple, list[str], tuple[bool, ...]]:
    """The touches without samples that repeat the one before them exactly
    (:meth:`TouchData.without_repeats`), a note for each touch that had some, and
    whether each had some."""
    out, notes, thinned = [], [], []
    for k, t in enumerate(touches):
        kept, removed = t.without_repeats()
        out.append(kept)
        thinned.append(bool(removed))
        if removed:
            which = "the touch" if len(touches) == 1 else f"touch {k + 1}"
            notes.append(
                f"{which}: {removed} of its {t.n_points} samples repeat the one before them "
                "exactly (a logger faster than its sensor, or a probe resting) and were "
                "counted once: copies carry no new measurement"
            )
    return tuple(out), notes, tuple(thinned)


def _geometries(geometry, n: int) -> tuple:
    """The given local geometries, one per touch (None where to be estimated)."""
    if geometry is None:
        return (None,) * n
    if isinstance(geometry, LocalGeometry):
        geometry = (geometry,)
    elif isinstance(geometry, (str, bytes)) or not isinstance(geometry, Sequence):
        raise TypeError(
            "geometry must be a LocalGeometry, a sequence of LocalGeometry or None, got "
            f"{type(geometry).__name__}"
        )
    if len(geometry) != n:
        raise ValueError(
            f"geometry must hold one LocalGeometry per touch ({n}), got {len(geometry)}"
        )
    for i, g in enumerate(geometry):
        check_instance(g, LocalGeometry, f"geometry[{i}]")
    return tuple(geometry)


def _with_verdict(
    rec: Recognition, fits: dict, models: list, method: str, run=None, memo: dict | None = None
) -> Recognition:
    """Add the calibrated scores, the verdict and its cautions to a ranking.

    When even the best model fits far worse than the noise (or no model was registered),
    the (K, H) lookup may have kept the right contact out (curves straddling a seam
    between two patches of different curvature): the lookup is then widened by
    ``defaults.LOOKUP_WIDEN_SCALE`` and every model registered again before concluding;
    the same passes run where one touch would name a model whose fit is only marginal
    (chi-square tail below ``defaults.NAME_P_VALUE``). ``fits`` holds the joint fits of
    several touches by model (empty for one touch).
    """
    by_name = {m.name: m for m in models}
    if memo is None:
        memo = {}
    with timed("scoring"):
        noise, n = noise_and_points(rec)
        t0 = time.perf_counter()
        prior = None
        if len(rec.touches) == 1:
            # the shares of the registered models only (a KD-tree each): a model the lookup
            # rejected has no flat site within the tolerance, its share 0, its weight the
            # floor
            fitted = [by_name[r.model] for r in rec.ranking if not r.rejected]
            weights = flat_prior(rec.touch, rec.geometry, fitted) if fitted else None
            if weights is not None:
                floor = float(weights.max()) / defaults.FLAT_PRIOR_MAX_RATIO
                prior = {m.name: floor for m in models}
                prior.update({m.name: float(w) for m, w in zip(fitted, weights, strict=True)})
        rec, noise = rescored(rec, prior, models)
        t_score = time.perf_counter() - t0
    t_wide = 0.0
    cautions = []
    looked = False
    # Whether to look harder is judged on the touches' own noise: the meshes' error that
    # the scores add (model_error) must not hide a search that ended short (a YCB touch
    # of the gelatin box was named the foam brick again when it did).
    own = noise_and_points(rec)[0]
    if fits_worse_than_noise(rec, n, own):
        # Even the best fit is worse than the noise allows: look harder before
        # concluding. The lookup is a prior, not a gate: curves straddling a seam between
        # patches of different curvature may mismatch every vertex's (K, H) of the right
        # model, so every model is registered again with the window widened.
        t1 = time.perf_counter()
        rec, noise, run, how = looked_harder(
            rec, prior, fits, models, method, run, n, defaults.WIDEN_P_VALUE
        )
        t_wide = time.perf_counter() - t1
        looked = True
        cautions.append(
            "the first pass fitted no model to within the noise (or registered none): the "
            f"curvature lookup was widened {defaults.LOOKUP_WIDEN_SCALE:g} times and {how}"
        )
    # Before a model is named: every other pose and model that might fit as well
    # (meshrec.recognition.naming), looked for only while the scores name one.
    passes = before_naming(rec, prior, fits, models, method, run, noise, own, looked, memo)
    rec, noise = passes.recognition, passes.noise
    cautions.extend(passes.cautions)
    t_wide += passes.widened_seconds
    with timed("scoring"):
        t1 = time.perf_counter()
        mesh_error = model_error(rec, models)
        if mesh_error > defaults.MODEL_ERROR_NOTE * own:
            cautions.append(
                f"the meshes of the models that fit best scatter about their surfaces by up "
                f"to {mesh_error * np.sqrt(2.0):.3g} (a raw scan's roughness, or detail a "
                "coarse mesh does not follow): "
                f"their error, {mesh_error:.3g} on the surface, is added to the touch's noise "
                f"{own:.3g} (the scores take {noise:.3g}), and the answer can tell models "
                "apart only above it"
            )
        v = decided(rec, prior, n, noise)
        if prior is not None:
            cautions.append(_flat_caution(rec.scores, prior))
        v = within_calibration(v, rec)
        reason = v.reason
        rough = False
        for k, g in enumerate(rec.geometries):
            if _rough(g):
                rough = True
                which = (
                    f"touch {k + 1}'s curve fits" if len(rec.geometries) > 1 else "the curve fits"
                )
                cautions.append(
                    f"{which} leave {g.fit_to_noise:.3g} times the noise the samples show: "
                    "the curves may cross an edge, and the probabilities are less reliable"
                )
        if len(rec.geometries) == 1:
            v = rough_hold(v, rec.geometries[0])
            reason = v.reason
        elif rec.best is not None and rec.best.model in fits:
            v = every_touch_hold(v, rec, fits[rec.best.model], noise)
            reason = v.reason
        doubt = rough and v.verdict == "unknown"
        if rough and v.verdict == "unknown" and rec.best is not None:
            # A misfit from curves that fit no smooth patch: the search, started from the
            # curvature at p, may have missed the right pose across the edge.
            reason = (
                f"{reason}, or its pose was missed: the curves fit no smooth surface patch "
                "(they may cross an edge or a rim), where the search is less reliable; touch "
                "again away from edges"
            )
        if rough and v.verdict == "unknown" and rec.best is None:
            # Nothing registered from a touch whose curves fit no smooth patch: the
            # curvature at p, which the lookup matches, is not defined there (a rim, an
            # edge); that, not the library, is the likely cause.
            reason = (
                "no model could be registered: the curves fit no smooth surface patch, so the "
                "curvature at their common point, which the lookup matches, is not defined "
                "(they may cross an edge or a rim); the object may still be in the library: "
                "touch again away from edges"
            )
        if v.verdict == "unknown":
            reason = _inward_hint(rec, reason)
        best_reg = rec.best
        if best_reg is None:
            per_touch = (None,) * len(rec.touches)
        elif len(rec.touches) == 1:
            per_touch = (best_reg.rms,)
        else:
            per_touch = fits[best_reg.model].touch_rms
            if v.verdict == "unknown":
                reason = _joint_unknown_reason(rec, fits, by_name, noise) or reason
        t_score += time.perf_counter() - t1
    return dataclasses.replace(
        rec,
        verdict=v.verdict,
        plausible=v.plausible,
        noise=float(noise),
        reason=reason,
        warnings=tuple(cautions),
        search_doubt=doubt,
        scoring_seconds=t_score,
        widened_seconds=t_wide,
        touch_rms=per_touch,
    )


def _rough(g: LocalGeometry) -> bool:
    """Whether a touch's curve fits leave far more than its noise (``defaults.
    ROUGH_FIT_RATIO``, and a residual not negligible against the curves): across an
    edge or a rim."""
    return (
        g.fit_to_noise > defaults.ROUGH_FIT_RATIO
        and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * g.half_length
    )


def _edge_caveat(rec: Recognition, crossed: int) -> Recognition:
    """One touch across a sharp edge of the best model that names none (``ambiguous`` or
    ``unknown``): the reason says that there a model's search can miss its pose, so the
    touched model may be missing from ``plausible`` (or from the library's fits).

    A black-box probe (stop 34) touched a cup's inner corner and a tray's 1.5 mm rim: the
    answers were `ambiguous` among other parts, the touched one left out although its
    true pose fitted as well or better; a washer's top, the curves wrapping both its
    edges, was `unknown`. (A touch ``recognised`` across an edge is held back by
    :func:`~meshrec.recognition.holds.across_an_edge` instead, whose reason says so; an
    ``unknown`` one whose curves fit no smooth patch already doubts its pose.)
    """
    if (
        len(rec.touches) != 1
        or crossed < 2
        or rec.best is None
        or rec.verdict == "recognised"
        or (rec.verdict == "unknown" and _rough(rec.geometries[0]))
    ):
        return rec
    where = (
        f"the touch crosses a sharp edge (at the best pose its points lie on {crossed} faces "
        f"or smooth patches of {rec.best.model}), where a model's search can miss its pose"
    )
    if rec.verdict == "ambiguous":
        tail = f"{where}: the touched model may be missing from these; touch again away from edges"
    else:
        tail = f"{where}: the object may still be in the library; touch again away from edges"
    return dataclasses.replace(rec, reason=f"{rec.reason}; {tail}", search_doubt=True)


def _inward_hint(rec: Recognition, reason: str) -> str:
    """An ``unknown`` reason, with a word on the touches whose given normal makes the
    surface concave at the contact (mean curvature below zero with it, convex against it):
    an outward normal given with the wrong sign turns a convex patch into a concave one,
    which no closed convex part of a model matches. Only a hint; the verdict stands."""
    inward = [
        k
        for k, (t, g) in enumerate(zip(rec.touches, rec.geometries, strict=True))
        if t.normal is not None and float(g.H) < 0.0
    ]
    if not inward:
        return reason
    if len(rec.touches) == 1:
        which = "the normal given with the touch makes"
    elif len(inward) == 1:
        which = f"the normal given with touch {inward[0] + 1} makes"
    else:
        which = "the normals given with touches " + ", ".join(str(k + 1) for k in inward)
        which += " make"
    return (
        f"{reason}; {which} the surface concave at the contact (mean curvature "
        f"{float(rec.geometries[inward[0]].H):.3g}): if it points into the object rather "
        "than out of it (an outward normal is minus the probe's approach direction), "
        "nothing convex can match; check its sign, or leave it out"
    )


def _flat_caution(scores, prior: dict) -> str:
    """The caution of a flat touch: the models weighed by their flat share."""
    top = max(prior.values())
    fitted = [s for s in scores if s.rms is not None][:4]
    shown = ", ".join(f"{s.model} {prior[s.model] / top:.2g}" for s in fitted)
    return (
        "a flat touch: the models it fits equally are weighed by the share of their surface "
        f"flat over the curves' reach (relative: {shown}); touch a curved part or an edge "
        "to decide"
    )


def _joint_unknown_reason(rec: Recognition, fits: dict, models: dict, noise: float) -> str:
    """Why several touches fit no model, when it is more than "not in the library"."""
    points = np.array([g.point for g in rec.geometries])
    span = float(np.max(np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)))
    largest = max(float(np.linalg.norm(np.ptp(m.mesh.vertices, axis=0))) for m in models.values())
    if span > largest:
        return (
            f"the touches' contacts lie up to {span:.4g} apart, farther than the largest "
            f"model is long ({largest:.4g}): they cannot all be on one object of the library "
            "(touches given in different frames, or the object moved)"
        )
    for reg in rec.ranking:  # most probable first
        fit = fits.get(reg.model)
        if reg.rejected or fit is None or fit.registered < len(rec.touches):
            continue
        if all(
            _fits_alone(r, t, g)
            for r, t, g in zip(fit.single, rec.touches, rec.geometries, strict=True)
        ):
            best = rec.best
            lead = (
                f"the best joint fit, {best.model}'s, leaves {best.rms / noise:.3g} times the "
                f"noise; "
                if best is not None and best.model != reg.model and best.rms is not None
                else ""
            )
            return (
                f"{lead}each touch alone fits {reg.model} to the noise, but no one rigid pose "
                f"fits them all (its joint RMS residual {reg.rms:.3g}, {reg.rms / noise:.3g} "
                f"times the noise {noise:.3g}): the object is not in the library (a part "
                f"like {reg.model}, not it), or it moved between touches, or the touches' "
                "frames disagree (a hand-eye calibration or kinematic error that differs "
                "between the arm's poses)"
            )
    # Each touch alone fits some model, but not the same one: touches of different objects.
    fitting = []
    for k, (touch, geometry) in enumerate(zip(rec.touches, rec.geometries, strict=True)):
        names = [
            reg.model
            for reg in rec.ranking
            if not reg.rejected
            and (fit := fits.get(reg.model)) is not None
            and fit.registered > k
            and _fits_alone(fit.single[k], touch, geometry)
        ]
        fitting.append(names)
    if all(fitting):
        which = "; ".join(
            f"touch {k + 1}: {', '.join(names[:3])}" for k, names in enumerate(fitting)
        )
        return (
            f"each touch alone fits a model of the library ({which}), but no model fits "
            "them all at one pose: the touches may be of different objects, or the object "
            "moved between them"
        )
    if not any(fitting):
        return ""
    # Some touches alone fit a model, the others none (a black-box probe, stop 33: an
    # object turned before its third touch, which crossed a rim, was blamed on the rim
    # and the library alone).
    groups: dict[tuple, list[int]] = {}
    for k, names in enumerate(fitting):
        if names:
            groups.setdefault(tuple(names[:3]), []).append(k + 1)
    fit_part = "; ".join(
        f"touch {ks[0]} fits {', '.join(names)}"
        if len(ks) == 1
        else f"touches {', '.join(map(str, ks[:-1]))} and {ks[-1]} each fit {', '.join(names)}"
        for names, ks in groups.items()
    )
    misfits = [k for k, names in enumerate(fitting) if not names]
    listed = " and ".join(str(k + 1) for k in misfits)
    which = f"touch {listed} fits" if len(misfits) == 1 else f"touches {listed} fit"
    rough = [k for k in misfits if rec.geometries[k].fit_to_noise > defaults.ROUGH_FIT_RATIO]
    edge = (
        ", or cross an edge or a rim (its curves fit no smooth surface patch), where the "
        "search is less reliable"
        if rough
        else ""
    )
    best = rec.best
    lead = (
        f"the best joint fit, {best.model}'s, leaves {best.rms / noise:.3g} times the noise; "
        if best is not None and best.rms is not None
        else ""
    )
    # A flat touch fits any flat patch (a table, a fixture): that it fits alone says
    # little, and the touches that fit nothing may be the object's (a probe, stop 34: the
    # gelatin box's top and side, then the table; touches 1 and 2 alone are `ambiguous`
    # with the gelatin box best once their search is widened, but were blamed).
    flat = [
        k + 1
        for k, names in enumerate(fitting)
        if names and flat_tolerance(rec.geometries[k]) is not None
    ]
    caveat = ""
    if flat:
        listed_flat = " and ".join(map(str, flat))
        caveat = (
            f"; touch {listed_flat} {'is' if len(flat) == 1 else 'are'} flat, and a flat "
            "touch fits any flat patch (a table or a fixture as well)"
        )
    them = "that touch" if len(misfits) == 1 else "those"
    return (
        f"{lead}alone, {fit_part} to the noise, but {which} no model alone (in the first "
        f"pass, without the widened search one touch gets){caveat}: the object may not be "
        f"in the library, or it moved between the touches, or {them} may be of another "
        f"object{edge}, or the touches that fit may be; recognise each touch alone to see "
        "which"
    )


def _fits_alone(reg, touch: TouchData, geometry: LocalGeometry) -> bool:
    """Whether a single-touch registration fits its touch to that touch's own noise."""
    if reg.rejected:
        return False
    noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
    return fit_p_value(reg.rms, int(touch.n_points), noise) >= defaults.UNKNOWN_P_VALUE
