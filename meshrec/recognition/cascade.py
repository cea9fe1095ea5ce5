"""The recognition's cascade: every model's first stages, then the full search on the
models that can still compete.

A registration's first stages (lookup, phi, screening: :func:`register_coarse`) already
place every candidate near its basin; the local searches and refinements after them
(:func:`register_full`) cost about two thirds of the time and, on a model far worse than
the best, only lower an error that loses anyway. The cascade runs the first stages on every
model, keeps the models whose best conceivable fit is within reach of the leaders'
(:func:`cascade_survivors`), runs the full search on those, and gives every other model the
pose of its best screened candidate, a few refinement steps on all the points
(:func:`pruned_registration`: the full search starts from that candidate too and keeps its
best, so the pruned error is the full search's or larger, up to the optimisers' tolerance,
and its probability only falls).

The rule is the scores' own (:mod:`meshrec.recognition.scoring`): a model's
log-likelihood is ``-n_eff rms^2 / (2 noise^2)``. Its best conceivable rms is its screened
error divided by ``defaults.CASCADE_SCREEN_GAIN`` (the most the searches were measured to
improve a screened error, with a margin); the leaders' rms is at most the rms that a model
already reached in a full search (the screen's leaders, or else the model of least screened
error, searched in full first), and at most the least screened error times
``defaults.CASCADE_LEADER_GAIN``. A model whose best conceivable
log-likelihood is below the leaders' worst by more than ``-defaults.JOINT_PRUNE_LOG_RATIO``
(e^-14: far below any plausible set) is pruned. The rule looks at the set of screened
errors only, so it does not depend on the order of the models.

With ``defaults.SCREEN_MIN_MODELS`` models or more, :func:`cascade_register` first runs the
library-wide screen (:mod:`meshrec.recognition.screen`): its leaders are registered in
full, the models it prunes get its own pruned registration, and only the others enter the
stages above.

The decisions (the screen, its survivors, the cascade's survivors) are taken in the
caller's process on whole sets of results; the per-model work between them runs in
batches of :class:`~meshrec.recognition.jobs.StageJob` (the screen's leaders; the
screen's pruned registrations and the others' first stages; without the screen, the full
search of the model of least screened error; the full searches and the cascade's pruned
registrations), here or on the workers of a
:class:`~meshrec.recognition.workers.ModelWorkers` (local processes, a Dask cluster):
the result is the same wherever they ran.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_instance
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.recognition.jobs import StageJob, run_stages_here
from meshrec.recognition.scoring import effective_points, noise_estimate
from meshrec.recognition.screen import (
    library_sites,
    screen_leaders,
    screen_library,
    screen_survivors,
)
from meshrec.registration.pruned import pruned_from_start
from meshrec.registration.register import (
    CoarseRegistration,
    Registration,
    StageTimes,
    touch_geometry,
)
from meshrec.registration.transform import superposition

__all__ = ["cascade_register", "cascade_survivors", "pruned_registration"]


def cascade_survivors(
    screened_errors: Sequence[float | None],
    n_points: int,
    noise: float,
    screen_gain: float = defaults.CASCADE_SCREEN_GAIN,
    leader_gain: float = defaults.CASCADE_LEADER_GAIN,
    log_ratio: float = defaults.JOINT_PRUNE_LOG_RATIO,
    leader_rms: float | None = None,
) -> np.ndarray:
    """Which models the full search must still run on.

    Parameters
    ----------
    screened_errors : sequence of float or None
        Each model's least screened error (:attr:`CoarseRegistration.screened_error`);
        None for a model the lookup rejected.
    n_points : int
        Data points of the touch.
    noise : float
        The touch's noise estimate (:func:`meshrec.recognition.scoring.noise_estimate`).
    screen_gain : float
        A model's rms is taken to be at least its screened error over this (>= 1).
    leader_gain : float
        The leaders' rms is taken to be at most the least screened error times this (>= 1).
    log_ratio : float
        Prune below this log-likelihood ratio to the leaders' (< 0).
    leader_rms : float, optional
        The least rms a model already reached in a full search: the best model's rms is
        at most that, so the leaders' rms is taken to be at most the smaller of it and the
        least screened error times ``leader_gain`` (None: the latter alone).

    Returns
    -------
    (m,) bool
        True for the models to search fully (always the leaders); False for the pruned
        and the rejected ones.

    Raises
    ------
    ValueError
        If ``n_points`` is not a positive integer, ``noise`` not positive and finite, a
        gain below 1, ``log_ratio`` not negative, an error negative or not finite, or
        ``leader_rms`` negative or not finite.
    """
    if not isinstance(n_points, (int, np.integer)) or isinstance(n_points, bool) or n_points < 1:
        raise ValueError(f"n_points must be a positive integer, got {n_points!r}")
    if not (np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be positive and finite, got {noise!r}")
    for name, gain in (("screen_gain", screen_gain), ("leader_gain", leader_gain)):
        if not (np.isfinite(gain) and gain >= 1):
            raise ValueError(f"{name} must be a finite number >= 1, got {gain!r}")
    if not (np.isfinite(log_ratio) and log_ratio < 0):
        raise ValueError(f"log_ratio must be negative and finite, got {log_ratio!r}")
    if leader_rms is not None and not (np.isfinite(leader_rms) and leader_rms >= 0):
        raise ValueError(f"leader_rms must be finite and >= 0, got {leader_rms!r}")
    known = [e for e in screened_errors if e is not None]
    for e in known:
        if not (np.isfinite(e) and e >= 0):
            raise ValueError(f"screened_errors must be finite and >= 0, got {e!r}")
    keep = np.zeros(len(screened_errors), dtype=bool)
    if not known:
        return keep
    half_n = 0.5 * effective_points(int(n_points))
    bound = min(known) * leader_gain
    if leader_rms is not None:
        bound = min(bound, float(leader_rms))
    worst_leader = -half_n * (bound / noise) ** 2
    for i, e in enumerate(screened_errors):
        if e is None:
            continue
        best_conceivable = -half_n * (e / screen_gain / noise) ** 2
        keep[i] = best_conceivable - worst_leader >= log_ratio
    return keep


def pruned_registration(touch: TouchData, model, coarse: CoarseRegistration) -> Registration:
    """The Registration of a model the cascade pruned: its best screened candidate's pose
    refined on all the points by ``defaults.CASCADE_PRUNED_ITERATIONS`` steps of the
    final rigid refinement of :func:`register_full`.

    Parameters
    ----------
    touch : TouchData
    model : ModelIndex
        The model ``coarse`` was computed on.
    coarse : CoarseRegistration
        Not rejected.

    Returns
    -------
    Registration
        With ``pruned`` true, ``searches`` 0 and one pose.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``model`` not a ModelIndex or ``coarse`` not a
        CoarseRegistration.
    ValueError
        If ``coarse`` is of another model or was rejected by the lookup.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(coarse, CoarseRegistration, "coarse")
    if coarse.model != model.name:
        raise ValueError(f"coarse must be of model {model.name!r}, got {coarse.model!r}")
    if coarse.rejected:
        raise ValueError(f"coarse must have candidates, got none on model {model.name!r}")
    cands = coarse.candidates
    i = int(coarse.screening.candidates[0])
    side = cands.sides[cands.side[i]]
    T0 = superposition(side.point, side.frame, cands.origins[i], float(coarse.screening.phis[0]))
    times = dict(coarse.times)
    # A few steps only (the screening's count): the pose of a model far worse than the
    # leaders needs no polish, and a full refinement there took up to 30 iterations.
    return pruned_from_start(
        model,
        cands.points,
        T0,
        cands.geometry.point,
        defaults.CASCADE_PRUNED_ITERATIONS,
        candidates=len(cands),
        raw_hits=cands.raw_hits,
        candidate_points=cands.model_points,
        before=StageTimes(
            lookup=times.get("lookup", 0.0),
            phi=times.get("phi", 0.0),
            screen=times.get("screen", 0.0),
        ),
        seconds_before=coarse.seconds,
    )


def cascade_register(
    touch: TouchData,
    models: Sequence,
    geometry: LocalGeometry | None = None,
    noise: float | None = None,
    method: str = defaults.SEARCH_METHOD,
    progress=None,
    trace: bool = False,
    run=None,
) -> list[Registration]:
    """Register one touch on every model through the cascade.

    The per-model work runs in batches between the cascade's decisions, each batch on
    ``run`` (a :class:`~meshrec.recognition.workers.ModelWorkers`: in this process, local
    processes or a Dask cluster) or here: the screen's leaders; the screen's pruned
    registrations and the other models' first stages; without the screen, the full
    search of the model of least screened error (its rms bounds the leaders'); the full
    searches of the models the cascade keeps and the pruned registrations of the others.
    The decisions (the
    screen, its survivors, :func:`cascade_survivors`) are taken here on the whole set of
    results, so the result is the same wherever the batches ran.

    Parameters
    ----------
    touch : TouchData
    models : sequence of ModelIndex
    geometry : LocalGeometry, optional
        The touch's local geometry (estimated here otherwise).
    noise : float, optional
        The touch's noise estimate (default: from ``geometry``, as the scores take it).
    method : {"lm", "steepest"}
        The local-search optimiser.
    progress : callable, optional
        ``progress(k, n, name)`` before each model's first stages (``k`` counting them,
        ``n`` the models), or as they come back from the workers.
    trace : bool
        Keep the stage trace of the survivors' full searches (the pruned have none).
    run : ModelWorkers, optional
        Where the per-model batches run (default: here, in order).

    Returns
    -------
    list of Registration
        One per model, in the order of ``models``: the full search's on the survivors,
        :func:`pruned_registration`'s on the pruned.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, a model not a ModelIndex, ``geometry`` not a
        LocalGeometry or ``run`` has no ``run_stages``.
    ValueError
        As :func:`register_coarse` and :func:`register_full`, or as ``run.run_stages``.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    if run is not None and not callable(getattr(run, "run_stages", None)):
        raise TypeError(f"run must be a ModelWorkers or None, got {type(run).__name__}")
    if geometry is None:
        geometry = touch_geometry(touch)
    if noise is None:
        noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
    models = list(models)
    m = len(models)
    started = [0]  # models whose first stages were reported

    def batch(jobs: list[StageJob]) -> list:
        def report(_k, job):
            if progress is not None and job.kind in ("coarse", "leader"):
                progress(started[0], m, job.model.name)
                started[0] += 1

        if run is None:
            return run_stages_here(jobs, touch, geometry, method, trace, progress=report)
        return run.run_stages(jobs, touch, geometry, method, trace=trace, progress=report)

    out: list[Registration | None] = [None] * m
    first: dict[int, CoarseRegistration] = {}
    stay = list(range(m))
    screen = None
    if m >= defaults.SCREEN_MIN_MODELS:
        # The library-wide screen first, here (one vectorised pass over all the models'
        # sites). Its leaders are registered in full; the least rms they reach bounds the
        # best model's, and the models that cannot come near it are pruned.
        screen = screen_library(touch, geometry, library_sites(models))
        names = [mod.name for mod in models]
        leaders = screen_leaders(screen, names, defaults.SCREEN_LEADERS).tolist()
        rms = []
        for i, (c, reg) in zip(
            leaders, batch([StageJob("leader", models[i]) for i in leaders]), strict=True
        ):
            first[i] = c
            if reg is not None:
                out[i] = reg
                rms.append(reg.rms)
        passed = screen_survivors(screen, int(touch.n_points), noise, min(rms) if rms else None)
        stay = [i for i in stay if passed[i] or i in first]
        cut = [int(i) for i in np.flatnonzero(~passed) if int(i) not in first]
    else:
        cut = []
    todo = [i for i in stay if i not in first]
    # The screen's pruned registrations (a few refinement steps each) and the first
    # stages of the others in one batch.
    jobs = [
        StageJob("screened", models[i], (screen, i), defaults.PARALLEL_COST_PRUNED) for i in cut
    ]
    jobs += [StageJob("coarse", models[i], cost=defaults.PARALLEL_COST_COARSE) for i in todo]
    results = batch(jobs)
    for i, reg in zip(cut, results[: len(cut)], strict=True):
        out[i] = reg
    for i, c in zip(todo, results[len(cut) :], strict=True):
        first[i] = c
    coarse = [first[i] for i in stay]
    errors = [c.screened_error for c in coarse]
    reached = [out[i].rms for i in stay if out[i] is not None and not out[i].rejected]
    if not reached and any(e is not None for e in errors):
        # No model registered in full yet (no screen): the one of least screened error
        # first (ties by name), which the rule always keeps. The rms it reaches bounds the
        # best model's, a tighter bound than its screened error times the leader gain.
        lead = min(
            (k for k, e in enumerate(errors) if e is not None),
            key=lambda k: (errors[k], models[stay[k]].name),
        )
        i = stay[lead]
        (out[i],) = batch([_full_job(models[i], coarse[lead])])
        reached = [out[i].rms]
    keep = cascade_survivors(
        errors, int(touch.n_points), noise, leader_rms=min(reached) if reached else None
    )
    # The full searches of the survivors (cost: their local searches) and the pruned poses.
    last, jobs = [], []
    for i, c, k in zip(stay, coarse, keep, strict=True):
        if out[i] is not None:
            continue  # a leader of the screen, registered in full already
        last.append(i)
        if c.rejected or k:
            jobs.append(_full_job(models[i], c))
        else:
            jobs.append(StageJob("pruned", models[i], c, defaults.PARALLEL_COST_PRUNED))
    for i, reg in zip(last, batch(jobs), strict=True):
        out[i] = reg
    return out


def _full_job(model, coarse: CoarseRegistration) -> StageJob:
    """The full search of ``model`` from its first stages, costed by its local searches
    (none for a model the lookup rejected)."""
    if coarse.rejected:
        return StageJob("full", model, coarse, 0.0)
    searches = min(defaults.LOCAL_SEARCHES, len(coarse.screening.candidates))
    return StageJob("full", model, coarse, searches / defaults.LOCAL_SEARCHES)
