"""Several touches of one object: one rigid pose per model that fits them all.

A robot touches an object that does not move several times, and every touch is given in
one world frame, so a model's pose ``T_model_touch`` is the same for all of them. Per
model, the touches are first registered alone (:func:`meshrec.register`, the paper's
method); each registration's distinct pose hypotheses are poses of the whole object. The
hypotheses that fit all the touches best are refined jointly, on every touch's points
(:func:`meshrec.registration.refine.refine_rigid`), and the distinct results are the
model's joint pose hypotheses.

Not every touch has to be registered alone: the poses of the first touch, refined on all
the points, usually already fit every touch to the noise, and the further registrations
are only needed when they do not. :func:`register_touches` registers the first ``upto``
touches; the recognition decides, per model and after every model's first pass, which
models need the rest (see :func:`log_likelihood_bound`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.recognition.pairs import pair_seeds
from meshrec.recognition.phases import timed
from meshrec.recognition.scoring import (
    effective_points,
    fit_p_value,
    log_likelihoods,
    noise_estimate,
)
from meshrec.recognition.weak import exploration_starts
from meshrec.registration.batch import refine_rigid_batch
from meshrec.registration.objective import Residuals, residuals
from meshrec.registration.phi import bracket_minima
from meshrec.registration.poses import PoseHypothesis, distinct_poses, keeps_side, refined_pose
from meshrec.registration.register import Registration, StageTimes, register
from meshrec.registration.transform import apply_transform, superposition

__all__ = [
    "JointFit",
    "candidate_seeds",
    "check_touch_sizes",
    "explore_weak_motions",
    "first_touch_fit",
    "joint_poses",
    "log_likelihood_bound",
    "pooled_noise",
    "register_touches",
    "rms_out_of_reach",
    "search_pairs",
    "touch_rms",
    "transfer_poses",
    "transferred_poses",
]


@dataclass(frozen=True, eq=False)
class JointFit(ValueEquality):
    """One model's registration of several touches at one rigid pose.

    Attributes
    ----------
    registration : Registration
        The joint registration: ``error``, ``rms`` and ``n_points`` over every touch's
        points, ``T_model_touch`` the best joint pose (touch frame = the world frame all
        touches share), ``contact`` on the model where the first touch's common point
        lies, ``poses`` the distinct joint poses (least RMS first); ``candidates``,
        ``searches``, ``seconds`` and ``times`` add up the single-touch registrations and
        the joint refinement. Rejected (``error`` None) when no touch registered alone
        found a candidate.
    single : tuple of Registration
        The single-touch registrations run, in touch order (the first ``len(single)``
        touches).
    touch_rms : tuple of float
        RMS point-to-surface distance of each touch at the best joint pose (empty when
        rejected).
    """

    registration: Registration
    single: tuple[Registration, ...] = field(repr=False)
    touch_rms: tuple[float, ...] = ()

    @property
    def registered(self) -> int:
        """How many touches were registered alone."""
        return len(self.single)


def check_touch_sizes(touches: Sequence[TouchData]) -> None:
    """Refuse touches whose sizes cannot be those of one probe on one object.

    Parameters
    ----------
    touches : sequence of TouchData
        Two or more.

    Raises
    ------
    ValueError
        If one touch's bounding-box diagonal is more than
        ``defaults.JOINT_MAX_SIZE_RATIO`` times another's (touches in different units).
    """
    sizes = [float(np.linalg.norm(np.ptp(t.points, axis=0))) for t in touches]
    big, small = int(np.argmax(sizes)), int(np.argmin(sizes))
    if sizes[small] > 0 and sizes[big] / sizes[small] > defaults.JOINT_MAX_SIZE_RATIO:
        raise ValueError(
            f"{_named(touches, big)} is {sizes[big] / sizes[small]:.3g} times the size of "
            f"{_named(touches, small)} ({sizes[big]:.4g} against {sizes[small]:.4g}): "
            "touches of one object in different units? Give every touch in the same unit"
        )


def _named(touches: Sequence[TouchData], k: int) -> str:
    """``touches[k]``, with its file where it was read from one (the command line's
    touches are counted from 1, the list from 0)."""
    source = touches[k].source
    return f"touches[{k}]" if source is None else f"touches[{k}] ({source})"


def pooled_noise(noises: Sequence[float], n_points: Sequence[int]) -> float:
    """The noise level of several touches together: their variances averaged by points.

    Parameters
    ----------
    noises : sequence of float
        Each touch's noise estimate (standard deviation), > 0.
    n_points : sequence of int
        Each touch's number of points.

    Returns
    -------
    float
        ``sqrt(sum n_t sigma_t^2 / sum n_t)``; with one touch, its own noise.

    Raises
    ------
    ValueError
        If the lengths differ or are zero, a noise is not positive and finite, or a count
        is not positive.
    """
    s = np.asarray(noises, dtype=np.float64)
    n = np.asarray(n_points, dtype=np.float64)
    if s.ndim != 1 or s.shape != n.shape or len(s) == 0:
        raise ValueError(
            f"noises and n_points must be 1-D of the same non-zero length, got {s.shape} "
            f"and {n.shape}"
        )
    if np.any(~np.isfinite(s)) or np.any(s <= 0) or np.any(n < 1):
        raise ValueError("noises must be positive and finite and n_points at least 1")
    return float(np.sqrt((n * s**2).sum() / n.sum()))


def touch_rms(model, touches: Sequence[TouchData], T_model_touch: np.ndarray) -> tuple:
    """RMS point-to-surface distance of each touch at one pose.

    Parameters
    ----------
    model : ModelIndex
    touches : sequence of TouchData
    T_model_touch : (4, 4) float

    Returns
    -------
    tuple of float
        One per touch, model units.
    """
    points = np.vstack([t.points for t in touches])
    values = residuals(model, apply_transform(T_model_touch, points)).values
    ends = np.cumsum([t.n_points for t in touches])[:-1]
    return tuple(float(np.sqrt(np.mean(v**2))) for v in np.split(values, ends))


def joint_poses(
    model,
    touches: Sequence[TouchData],
    seeds: Sequence[np.ndarray],
    geometry: LocalGeometry,
    *,
    best: int = defaults.JOINT_REFINE_SEEDS,
    start_ratio: float = defaults.JOINT_KEEP_RATIO,
    hopeless_rms: float = np.inf,
) -> tuple[PoseHypothesis, ...]:
    """Refine poses of the object jointly on every touch's points; the distinct results.

    Parameters
    ----------
    model : ModelIndex
    touches : sequence of TouchData
        All in one frame.
    seeds : sequence of (4, 4) float
        Starting poses ``T_model_touch`` (for instance the single-touch registrations'
        pose hypotheses).
    geometry : LocalGeometry
        The first touch's local geometry: its common point locates each pose's
        ``contact`` on the model, and its half-length the tolerance of
        :func:`~meshrec.registration.poses.distinct_poses`.
    best : int
        Seeds refined at most: those with the least joint RMS at their starting pose and
        within ``defaults.JOINT_KEEP_RATIO`` of the least, first on about
        ``defaults.JOINT_COARSE_POINTS`` of the points, then (those that come within
        ``defaults.JOINT_KEEP_RATIO`` of the best coarse RMS) on all of them. Seeds that
        reach the same pose as a better one on the way (within
        ``defaults.JOINT_SAME_POSE_FRACTION`` of the half-length) are refined once.
    start_ratio : float
        Seeds whose starting RMS is more than this factor above the least are not refined
        (``inf``: every one of the ``best``; for seeds that all start a little off the
        pose, such as :func:`~meshrec.recognition.pairs.pair_seeds`).
    hopeless_rms : float
        A joint RMS above which the model cannot compete (``inf``: none): when every
        coarse result kept, scored on all the points, is more than
        ``defaults.JOINT_FINE_GAIN`` times above it, they are returned as they are (no
        fine refinement).

    Returns
    -------
    tuple of PoseHypothesis
        Distinct, least RMS first (``phi`` and ``run`` None: no chart is involved); empty
        when there is no seed.

    Raises
    ------
    ValueError
        If ``best`` is not a positive integer, ``start_ratio`` is not at least 1 or
        ``hopeless_rms`` is not positive.
    """
    if not isinstance(best, (int, np.integer)) or isinstance(best, bool) or best < 1:
        raise ValueError(f"best must be a positive integer, got {best!r}")
    if not start_ratio >= 1:
        raise ValueError(f"start_ratio must be at least 1, got {start_ratio!r}")
    if not hopeless_rms > 0:
        raise ValueError(f"hopeless_rms must be positive, got {hopeless_rms!r}")
    if len(seeds) == 0:
        return ()
    points = np.vstack([t.points for t in touches])
    n = len(points)
    stride = max(1, n // defaults.JOINT_COARSE_POINTS)
    sub = points[::stride]
    # Coarse to fine: each seed refined on every k-th point (most seeds are far off and
    # take many steps), then the coarse results that come near the best one refined on
    # all the points (a few steps).
    # Only seeds that start near the best one: the others are far off (a wrong touch
    # placement) and would take many steps to reach what the best reaches in a few.
    order, start_rms, start_res = _least_start_rms(model, sub, seeds, best)
    # In lockstep, one closest-point query per round for all the seeds (the same results
    # as refine_rigid from each: meshrec.registration.batch), from the residuals the
    # ranking above computed at the starts (not queried again).
    chosen = [k for k in order if start_rms[k] <= start_ratio * start_rms[order[0]]]
    starts = np.array([seeds[k] for k in chosen])
    tol = defaults.JOINT_SAME_POSE_FRACTION * float(geometry.half_length)
    coarse = sorted(
        _coarse(model, sub, starts, tol, [start_res[k] for k in chosen]), key=lambda c: c.rms
    )
    # A refinement that went astray (not a finite fit) is no pose: left out, and with
    # none left there is no pose (an empty batch was refused with a ValueError).
    coarse = [c for c in coarse if np.isfinite(c.rms)]
    if not coarse:
        return ()
    least = min(c.rms for c in coarse)
    kept = [c.T_model_touch for c in coarse if c.rms <= defaults.JOINT_KEEP_RATIO * least]
    kept = _merged(kept, sub, tol)
    initial = None
    if np.isfinite(hopeless_rms):
        # the residuals at the kept poses, for this test and as the fine stage's start
        initial = _rms_on(model, points, kept, keep=True)[1]
        scored = refine_rigid_batch(model, points, np.array(kept), max_iter=0, initial=initial)
        if min(r.rms for r in scored) > defaults.JOINT_FINE_GAIN * hopeless_rms:
            out = sorted((refined_pose(model, r, geometry.point) for r in scored), key=_rms)
            return distinct_poses(out, float(geometry.half_length))
    refs = refine_rigid_batch(model, points, np.array(kept), initial=initial)
    # Along a nearly free motion (a turn of a bumped sphere about its centre) the
    # point-to-plane steps crawl, a few per cent of the way per iteration, and the
    # iteration limit stopped them short of the minimum (0.28 from the truth where the
    # minimum is 0.015 from it): the best pose goes on if it used every iteration (only
    # the best: on look-alikes most poses of every model crawl, and polishing them all
    # cost more than the rest of the joint refinement).
    k = int(np.argmin([r.rms for r in refs]))
    if refs[k].iterations >= defaults.REFINE_MAX_ITER:
        more = refine_rigid_batch(
            model, points, refs[k].T_model_touch[None], max_iter=defaults.JOINT_POLISH_ITER
        )[0]
        refs[k] = dataclasses.replace(more, iterations=refs[k].iterations + more.iterations)
    out = sorted((refined_pose(model, ref, geometry.point) for ref in refs), key=_rms)
    return distinct_poses(out, float(geometry.half_length))


def _rms(pose: PoseHypothesis) -> float:
    """A pose's RMS, the sort key of pose lists."""
    return pose.rms


def _least_start_rms(model, sub: np.ndarray, seeds: Sequence[np.ndarray], best: int):
    """The ``best`` seeds of least RMS on ``sub`` (least first, ties by index), the RMS
    of each seed as a dict (only the seeds whose RMS was needed), and their residuals on
    ``sub`` (a dict of the same seeds: the refinement starts from them).

    The same seeds, in the same order and with the same values, as the RMS of every seed
    sorted (each point's residual is its own, whatever else is queried with it). With many
    seeds (the harder search's every candidate contact), the sum of squares on every k-th
    point of ``sub`` (about ``defaults.JOINT_START_PROBE_POINTS``), a lower bound of the
    sum on all of ``sub``, ranks them first, and the exact RMS is computed only in that
    order until the next bound is above the ``best``-th least sum found: evaluating every
    seed on every point of ``sub`` was a third of a look-alike's three-touch recognition.
    """
    k, m = len(seeds), len(sub)
    probe_stride = max(1, m // defaults.JOINT_START_PROBE_POINTS)
    if k <= 4 * best or probe_stride == 1:
        rms, res = _rms_on(model, sub, seeds, keep=True)
        return np.argsort(rms, kind="stable")[:best], dict(enumerate(rms)), dict(enumerate(res))
    probe = sub[::probe_stride]
    bound = (_rms_on(model, probe, seeds) ** 2) * len(probe)  # sums of squares on probe
    ranked = np.argsort(bound, kind="stable")
    exact: dict[int, float] = {}
    placed: dict[int, Residuals] = {}
    chunk = max(best, 16)
    at = 0
    while at < k:
        ids = ranked[at : at + chunk].tolist()
        rms, res = _rms_on(model, sub, [seeds[i] for i in ids], keep=True)
        exact.update(zip(ids, rms.tolist(), strict=True))
        placed.update(zip(ids, res, strict=True))
        at += len(ids)
        if len(exact) >= best and at < k:
            kth = sorted(exact.values())[best - 1] ** 2 * m  # the best-th least sum
            if kth * (1.0 + 1e-9) < bound[ranked[at]]:
                break  # every seed left sums more than the best-th on the probe alone
    order = sorted(exact, key=lambda i: (exact[i], i))[:best]
    return np.array(order, dtype=np.int64), exact, placed


def _rms_on(model, points: np.ndarray, poses: Sequence[np.ndarray], keep: bool = False):
    """(k,) RMS distance of ``points`` placed by each of the ``k`` poses, one query; with
    ``keep``, also each pose's residuals (a list of k Residuals, as
    :func:`~meshrec.registration.objective.residuals` gives them for that pose alone:
    each point's answer is its own)."""
    stacked = np.vstack([apply_transform(T, points) for T in poses])
    res = residuals(model, stacked)
    rms = np.sqrt((res.values.reshape(len(poses), len(points)) ** 2).mean(1))
    if not keep:
        return rms
    n = len(points)
    return rms, [
        Residuals(
            values=res.values[i * n : (i + 1) * n],
            closest=res.closest[i * n : (i + 1) * n],
            gradient=res.gradient[i * n : (i + 1) * n],
        )
        for i in range(len(poses))
    ]


def _coarse(model, sub: np.ndarray, starts: np.ndarray, tol: float, initial=None) -> list:
    """The coarse stage of :func:`joint_poses`: every start refined on ``sub`` (from the
    residuals ``initial`` at the starts, when given: see
    :func:`~meshrec.registration.batch.refine_rigid_batch`).

    With more starts than ``defaults.JOINT_REFINE_SEEDS``, the refinement stops after
    ``defaults.JOINT_MERGE_ITER`` iterations, the starts that have reached the same pose
    as a better one are dropped (:func:`_merged`), and the others go on to
    ``defaults.JOINT_COARSE_ITER`` in all (those that had converged are kept as they are).
    """
    total = defaults.JOINT_COARSE_ITER
    first = defaults.JOINT_MERGE_ITER
    if len(starts) <= defaults.JOINT_REFINE_SEEDS or first >= total:
        return refine_rigid_batch(model, sub, starts, max_iter=total, initial=initial)
    early = sorted(
        refine_rigid_batch(model, sub, starts, max_iter=first, initial=initial),
        key=lambda c: c.rms,
    )
    unique = _merged([c.T_model_touch for c in early], sub, tol)
    kept_ids = {id(T) for T in unique}
    early = [c for c in early if id(c.T_model_touch) in kept_ids]
    going = [c for c in early if c.iterations >= first]  # the others have converged
    later = (
        refine_rigid_batch(
            model, sub, np.array([c.T_model_touch for c in going]), max_iter=total - first
        )
        if going
        else []
    )
    return [c for c in early if c.iterations < first] + list(later)


def _merged(poses: Sequence[np.ndarray], sub: np.ndarray, tol: float) -> list[np.ndarray]:
    """``poses`` (best first) without those that place ``sub`` within ``tol`` (everywhere)
    of a better one's placement: the same basin, which refining again would only repeat.
    """
    kept: list[np.ndarray] = []
    placed: list[np.ndarray] = []
    for T in poses:
        y = apply_transform(T, sub)
        if any(float(np.linalg.norm(y - z, axis=1).max()) < tol for z in placed):
            continue
        kept.append(T)
        placed.append(y)
    return kept


def register_touches(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    *,
    upto: int = 1,
    previous: JointFit | None = None,
    method: str = defaults.SEARCH_METHOD,
    lookup_scale: float = 1.0,
    noise: float | None = None,
    hopeless_rms: float = np.inf,
) -> JointFit:
    """Register several touches of one object on one model at one rigid pose.

    The first ``upto`` touches are registered alone (those already in ``previous`` are
    not registered again; touches after the first with ``defaults.JOINT_EXTRA_SEARCHES``
    local searches); every distinct pose they give seeds :func:`joint_poses` on all
    the touches. The result depends on this model and the touches only.

    Parameters
    ----------
    touches : sequence of TouchData
        Two or more, in one frame.
    model : ModelIndex
    geometries : sequence of LocalGeometry
        The local geometry of each touch.
    upto : int
        Touches registered alone, 1 to ``len(touches)``.
    previous : JointFit, optional
        An earlier pass on the same touches and model, with the same ``lookup_scale``:
        its single-touch registrations are reused.
    method : {"lm", "steepest"}
        The local-search optimiser.
    lookup_scale : float
        Factor widening the (K, H) lookup window.
    noise : float, optional
        The touches' pooled noise (:func:`pooled_noise`). When given and every touch is
        registered alone, a joint fit still worse than the noise allows
        (``defaults.WIDEN_P_VALUE``) is searched harder: every candidate contact of every
        touch at its best bracketed angles (:func:`candidate_seeds`) seeds the joint
        refinement too (the touches' distinct poses may all be slid along a nearly
        flat or symmetric patch, off the one pose that fits them all).
    hopeless_rms : float
        A joint RMS above which this model cannot compete with the best fit so far
        (:func:`joint_poses`; ``inf``: none).

    Returns
    -------
    JointFit

    Raises
    ------
    ValueError
        If ``upto`` is outside 1 to ``len(touches)``, ``geometries`` does not match
        ``touches`` or ``hopeless_rms`` is not positive (:func:`joint_poses`).
    """
    if len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    if not isinstance(upto, (int, np.integer)) or not 1 <= upto <= len(touches):
        raise ValueError(f"upto must be an integer in [1, {len(touches)}], got {upto!r}")
    t0 = time.perf_counter()
    single = list(previous.single) if previous is not None else []
    with timed("alone"):
        for k in range(len(single), upto):
            # The first touch is registered as one touch alone would be; the others only
            # seed the joint refinement, where the touches registered before constrain the
            # pose.
            searches = defaults.LOCAL_SEARCHES if k == 0 else defaults.JOINT_EXTRA_SEARCHES
            single.append(
                register(
                    touches[k],
                    model,
                    geometry=geometries[k],
                    method=method,
                    lookup_scale=lookup_scale,
                    searches=searches,
                    trace=True,
                )
            )
    # Seeds: the joint poses already found (refined ones converge at once) and the poses
    # of the touches newly registered alone.
    done = len(previous.single) if previous is not None else 0
    seeds = [p.T_model_touch for p in previous.registration.poses] if previous else []
    seeds += [p.T_model_touch for reg in single[done:] for p in reg.poses]
    t1 = time.perf_counter()
    with timed("joint"):
        poses = joint_poses(model, touches, seeds, geometries[0], hopeless_rms=hopeless_rms)
        n = int(sum(t.n_points for t in touches))
        if (
            noise is not None
            and upto == len(touches)
            and (not poses or fit_p_value(poses[0].rms, n, noise) < defaults.WIDEN_P_VALUE)
        ):
            more = [T for reg in single for T in candidate_seeds(reg)]
            found = (
                joint_poses(model, touches, more, geometries[0], hopeless_rms=hopeless_rms)
                if more
                else ()
            )
            poses = distinct_poses(
                sorted((*poses, *found), key=lambda p: p.rms), float(geometries[0].half_length)
            )
    return _fit(model, touches, single, poses, time.perf_counter() - t1, t0, geometries)


def search_pairs(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    previous: JointFit,
    *,
    lookup_scale: float = 1.0,
    hopeless_rms: float = np.inf,
) -> JointFit:
    """Search a model's joint pose again from pairs of touches (:func:`pair_seeds`).

    For a model whose joint fit may have been missed: each touch alone fits it at many
    places, none of them where all the touches fit. The poses that pairs of touches give
    (two oriented contacts fix a rigid pose) are refined on every touch
    (:func:`joint_poses`, every one of the ``defaults.PAIR_REFINE_SEEDS`` best, however far
    off they start) and join the poses of
    ``previous``.

    Parameters
    ----------
    touches : sequence of TouchData
        Two or more, in one frame.
    model : ModelIndex
    geometries : sequence of LocalGeometry
        The local geometry of each touch.
    previous : JointFit
        The model's joint fit so far (:func:`register_touches`); its single-touch
        registrations are kept.
    lookup_scale : float
        Factor widening the (K, H) lookup window.
    hopeless_rms : float
        A joint RMS above which the model cannot compete (:func:`joint_poses`; ``inf``:
        none).

    Returns
    -------
    JointFit
        ``previous`` with the pair poses among its poses (least RMS first).

    Raises
    ------
    ValueError
        As :func:`pair_seeds` and :func:`joint_poses`.
    """
    t0 = time.perf_counter()
    with timed("pairs"):
        seeds = pair_seeds(touches, model, geometries, lookup_scale=lookup_scale)
    with timed("joint"):
        found = joint_poses(
            model,
            touches,
            seeds,
            geometries[0],
            best=defaults.PAIR_REFINE_SEEDS,
            start_ratio=np.inf,
            hopeless_rms=hopeless_rms,
        )
    return _with_poses(model, touches, geometries, previous, found, t0)


def explore_weak_motions(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    previous: JointFit,
) -> JointFit:
    """Refine again from poses a long way along the best pose's weakest motions.

    On a nearly symmetric object the joint search can end in a basin a large turn away
    from a better one (see :mod:`meshrec.recognition.weak`). The starts
    (:func:`~meshrec.recognition.weak.weak_motion_starts`) are all refined jointly, coarse
    to fine as :func:`joint_poses` does (the start nearest the better basin is often the
    worst at its start: the bumps are then misplaced by the long turn), and the poses
    found join the previous ones: the best pose only improves.

    Parameters
    ----------
    touches : sequence of TouchData
        All in one frame.
    model : ModelIndex
    geometries : sequence of LocalGeometry
        One per touch.
    previous : JointFit
        The model's joint fit so far.

    Returns
    -------
    JointFit
        ``previous`` itself when it is rejected or its best pose has no weak motion.

    Raises
    ------
    ValueError
        If ``geometries`` does not match ``touches``.
    """
    if len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    reg = previous.registration
    if reg.rejected or reg.T_model_touch is None:
        return previous
    t0 = time.perf_counter()
    points = np.vstack([t.points for t in touches])
    # (the touches' normals are not turned about: several touches pin phi far better
    # than one, and each turn costs a joint refinement)
    starts = exploration_starts(model, points, reg.T_model_touch)
    if not starts:
        return previous
    found = joint_poses(
        model,
        touches,
        starts,
        geometries[0],
        best=len(starts),
        start_ratio=float("inf"),
    )
    return _with_poses(model, touches, geometries, previous, found, t0)


def transfer_poses(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    previous: JointFit,
    seeds: Sequence[np.ndarray],
    reach: float,
) -> JointFit:
    """Another model's poses refined on this one (:func:`transferred_poses`), kept among
    its poses.

    Parameters
    ----------
    touches, model, geometries, seeds, reach
        As for :func:`transferred_poses`.
    previous : JointFit
        The model's fit so far.

    Returns
    -------
    JointFit
        ``previous`` itself when no seed is within reach.

    Raises
    ------
    ValueError
        As :func:`transferred_poses`.
    """
    t0 = time.perf_counter()
    found = transferred_poses(touches, model, geometries, seeds, reach)
    if not found:
        return previous
    return _with_poses(model, touches, geometries, previous, found, t0)


def transferred_poses(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    seeds: Sequence[np.ndarray],
    reach: float,
) -> tuple[PoseHypothesis, ...]:
    """Another model's poses refined on this one, where they start within reach.

    Variants of one part exported in one frame (with and without a hole, a chamfer, a
    boss) fit touches away from their difference at the same pose; each model's own
    search can still end elsewhere, and the variant whose search found the pose was then
    named alone (a black-box probe, stop 33: 21 of 204 several-touch recognitions of CAD
    variants). A seed whose RMS at its start, on a subsample of the points, is within
    ``reach`` is refined on every touch (:func:`joint_poses`); the others cost one query.

    Parameters
    ----------
    touches : sequence of TouchData
        One or more, in one frame.
    model : ModelIndex
    geometries : sequence of LocalGeometry
        One per touch.
    seeds : sequence of (4, 4) float
        Poses ``T_model_touch`` of another model.
    reach : float
        Largest starting RMS refined, model units (> 0).

    Returns
    -------
    tuple of PoseHypothesis
        Distinct, least RMS first; empty when no seed is within reach.

    Raises
    ------
    ValueError
        If ``geometries`` does not match ``touches`` or ``reach`` is not positive.
    """
    if len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    if not reach > 0:
        raise ValueError(f"reach must be positive, got {reach!r}")
    if len(seeds) == 0:
        return ()
    points = np.vstack([t.points for t in touches])
    sub = points[:: max(1, len(points) // defaults.JOINT_COARSE_POINTS)]
    start = _rms_on(model, sub, list(seeds))
    near = [T for T, r in zip(seeds, start, strict=True) if r <= reach]
    if not near:
        return ()
    return joint_poses(model, touches, near, geometries[0], best=len(near), start_ratio=np.inf)


def candidate_seeds(
    registration: Registration, per_candidate: int = defaults.JOINT_PHI_MINIMA
) -> list[np.ndarray]:
    """Every candidate contact's pose at its best bracketed angles, from a traced registration.

    Parameters
    ----------
    registration : Registration
        From ``register(..., trace=True)``.
    per_candidate : int
        Bracketed minima of the error against phi kept per candidate, least first.

    Returns
    -------
    list of (4, 4) float
        ``T_model_touch`` of each (candidate, angle) kept by the phi stage; empty when the
        registration has no trace or no candidate.
    """
    trace = registration.trace
    if trace is None or trace.brackets is None:
        return []
    cands, brackets = trace.candidates, trace.brackets
    out = []
    for i in brackets.order:
        side = cands.sides[cands.side[i]]
        row = brackets.errors[i]
        minima = sorted(bracket_minima(row), key=lambda j: row[j])[:per_candidate]
        out.extend(
            superposition(side.point, side.frame, cands.origins[i], brackets.grid[j])
            for j in minima
        )
    return out


def first_touch_fit(touches: Sequence[TouchData], model, first: Registration) -> JointFit:
    """The first touch's registration alone, its poses taken as they are for every touch.

    No refinement: each pose of ``first`` is scored on all the touches' points. It is the
    starting point of :func:`register_touches` (``previous=``), and the final fit of a
    model that cannot become plausible (see :func:`log_likelihood_bound`).

    Parameters
    ----------
    touches : sequence of TouchData
    model : ModelIndex
    first : Registration
        ``register(touches[0], model)``.

    Returns
    -------
    JointFit
    """
    t0 = time.perf_counter()
    poses = []
    if first.poses:
        points = np.vstack([t.points for t in touches])
        n = len(points)
        stacked = np.vstack([apply_transform(p.T_model_touch, points) for p in first.poses])
        values = residuals(model, stacked).values.reshape(len(first.poses), n)
        rms = np.sqrt((values**2).mean(axis=1))
        error = np.abs(values).mean(axis=1)
        poses = sorted(
            (
                dataclasses.replace(p, rms=float(r), error=float(e))
                for p, r, e in zip(first.poses, rms, error, strict=True)
            ),
            key=lambda p: p.rms,
        )
    return _fit(model, touches, [first], tuple(poses), time.perf_counter() - t0, t0)


def _with_poses(model, touches, geometries, previous: JointFit, found, t0: float) -> JointFit:
    """``previous`` with the poses ``found`` since ``t0`` among its own (distinct, least RMS
    first), its time included."""
    poses = distinct_poses(
        sorted((*previous.registration.poses, *found), key=lambda p: p.rms),
        float(geometries[0].half_length),
    )
    fit = _fit(
        model, touches, list(previous.single), poses, time.perf_counter() - t0, t0, geometries
    )
    reg = dataclasses.replace(
        fit.registration, seconds=previous.registration.seconds + fit.registration.seconds
    )
    return dataclasses.replace(fit, registration=reg)


def _fit(model, touches, single, poses, t_joint: float, t0: float, geometries=None) -> JointFit:
    """The JointFit the single registrations and the joint poses make; given the touches'
    ``geometries``, a pose that carries a touch through the surface where its side is
    known (:func:`~meshrec.registration.poses.keeps_side`) is left out."""
    if geometries is not None:
        poses = tuple(
            p
            for p in poses
            if all(
                keeps_side(model, t, g, p.T_model_touch)
                for t, g in zip(touches, geometries, strict=True)
            )
        )
    times = StageTimes(refine=t_joint)
    for reg in single:
        times = times + reg.times
    common = dict(
        model=model.name,
        path=str(model.path),
        candidates=sum(r.candidates for r in single),
        raw_hits=sum(r.raw_hits for r in single),
        searches=sum(r.searches for r in single),
        times=times,
    )
    if not poses:
        reason = "; ".join(f"touch {k + 1}: {r.reason}" for k, r in enumerate(single))
        reg = Registration(
            error=None,
            contact=None,
            normal=None,
            phi=None,
            T_model_touch=None,
            seconds=time.perf_counter() - t0,
            reason=reason,
            **common,
        )
        return JointFit(registration=reg, single=tuple(single))
    best = poses[0]
    reg = Registration(
        error=best.error,
        contact=best.contact,
        normal=best.normal,
        phi=None,
        T_model_touch=best.T_model_touch,
        seconds=time.perf_counter() - t0,
        rms=best.rms,
        n_points=int(sum(t.n_points for t in touches)),
        poses=tuple(poses),
        candidate_points=np.vstack([r.candidate_points for r in single]),
        search_paths=tuple(p for r in single for p in r.search_paths),
        **common,
    )
    return JointFit(
        registration=reg,
        single=tuple(single),
        touch_rms=touch_rms(model, touches, best.T_model_touch),
    )


def rms_out_of_reach(leader: float, n_points: int, noise: float) -> float:
    """The joint RMS at which a model is ``defaults.JOINT_PRUNE_LOG_RATIO`` below a leader.

    Parameters
    ----------
    leader : float
        The best joint log-likelihood so far (see
        :func:`~meshrec.recognition.scoring.log_likelihoods`); ``-inf`` while none.
    n_points : int
        The touches' points, >= 1.
    noise : float
        The pooled noise (:func:`pooled_noise`), > 0.

    Returns
    -------
    float
        The RMS whose log-likelihood is ``leader + defaults.JOINT_PRUNE_LOG_RATIO``
        (``inf`` without a leader): a fit worse than that cannot compete.

    Raises
    ------
    ValueError
        If ``leader`` is NaN or positive, or as
        :func:`~meshrec.recognition.scoring.log_likelihoods`.
    """
    if not leader <= 0:
        raise ValueError(f"leader must be a log-likelihood (<= 0), got {leader!r}")
    if leader == -np.inf:
        return float(np.inf)
    unit = -float(log_likelihoods([1.0], n_points, noise)[0])  # -ll of an RMS of 1
    return float(np.sqrt(-(leader + defaults.JOINT_PRUNE_LOG_RATIO) / unit))


def log_likelihood_bound(
    fit: JointFit,
    touches: Sequence[TouchData],
    noise: float,
    geometries: Sequence[LocalGeometry] | None = None,
) -> float:
    """The most log-likelihood a model could still reach on all the touches.

    The joint fit's squared residuals add up over the touches, and no pose fits a touch
    better than that touch's own best registration, so the joint log-likelihood is at
    most the sum of the registered touches' own. A touch not registered alone yet counts
    0 without ``geometries``; with them, it is taken to fit no better than
    ``defaults.JOINT_UNREGISTERED_FLOOR`` times its own noise level (the smaller of its
    curves' fit RMS and its noise estimate): no rigid placement of a model fits the
    touch's points much closer than its own smooth local fit does. A model whose
    bound is already far below the best model's joint log-likelihood cannot become
    plausible by registering its remaining touches. A touch whose (K, H) lookup found no
    candidate on the model rules it out here, as for one touch; when then no model fits
    the touches, the recognition widens the lookup and registers every touch again.

    Parameters
    ----------
    fit : JointFit
    touches : sequence of TouchData
    noise : float
        The pooled noise estimate (:func:`pooled_noise`), > 0.
    geometries : sequence of LocalGeometry, optional
        The local geometry of each touch (for the touches not registered alone).

    Returns
    -------
    float
        At most 0; ``-inf`` when a registered touch found no candidate.

    Raises
    ------
    ValueError
        If ``geometries`` is given and does not match ``touches``.
    """
    if geometries is not None and len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    total = 0.0
    for k, touch in enumerate(touches):
        n_eff = effective_points(touch.n_points)
        if k < len(fit.single):
            reg = fit.single[k]
            if reg.rejected:
                return float("-inf")
            rms = reg.rms
        elif geometries is not None:
            g = geometries[k]
            own = min(g.fit_rms, noise_estimate(g.fit_rms, g.noise_rms, g.half_length))
            rms = defaults.JOINT_UNREGISTERED_FLOOR * own
        else:
            rms = 0.0
        total -= 0.5 * n_eff * (rms / noise) ** 2
    return total
