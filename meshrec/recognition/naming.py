"""Before a model is named: every other pose and model that might fit as well.

The scores trust each model's best fit. Where they would name one model (the verdict
``recognised``), a search that ended short of the right pose, on the named model or on
another, would make the answer wrong and confident, the worst outcome a robot can act
on. So before naming, this stage looks again where the black-box probes found such
searches end short, and the scores are taken afresh after each look:

- **several touches** (:func:`before_naming`): the leading model is searched again from
  pairs of touches (:func:`~meshrec.recognition.passes.search_lone_leader`), unless the
  data leave its pose free anyway or every turn is a symmetry of the model; then its best
  poses are refined on every other model (:func:`_transferred`);
- **one touch**: a marginal best fit (chi-square tail below ``defaults.NAME_P_VALUE``)
  has every model registered again with the window widened
  (:func:`~meshrec.recognition.passes.looked_harder`); a curvature estimate out of its
  range has the models that the lookup alone rejected registered on every site; the
  named model's own search is run again with more candidates (:func:`_confirmed`); its
  poses along its weakest motions, across its near-symmetries and turned about the
  touch's normal are refined (:func:`_explore_weak_motions_one`); and
  its best poses are refined on every other model (:func:`_transferred`).

Each look runs only while the scores still name a model, so an answer that is already
``ambiguous`` or ``unknown`` costs nothing here. Every look can only add poses (each
model keeps its best fit of all), never remove one.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.io.touch import TouchData
from meshrec.recognition.best_pose import free_motions
from meshrec.recognition.edges import patches_crossed
from meshrec.recognition.holds import would_be_named
from meshrec.recognition.joint import joint_poses, transfer_poses, transferred_poses
from meshrec.recognition.passes import (
    curvature_turn,
    looked_again,
    looked_harder,
    search_lone_leader,
)
from meshrec.recognition.phases import timed
from meshrec.recognition.rescore import noise_and_points, rescored, would_recognise
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import fit_p_value
from meshrec.recognition.weak import exploration_starts
from meshrec.registration.poses import distinct_poses, keeps_side
from meshrec.registration.register import Registration
from meshrec.registration.transform import apply_transform

__all__ = ["NamingPasses", "before_naming"]


@dataclass(frozen=True)
class NamingPasses:
    """What the stage before naming did.

    Attributes
    ----------
    recognition : Recognition
        The ranking and scores after the passes (the input's when none ran).
    noise : float
        The noise the scores take.
    run : ModelWorkers or None
        The workers the passes registered with (started here when given None and a pass
        needed them; the caller closes them).
    cautions : tuple of str
        The cautions the passes add to the answer.
    widened_seconds : float
        Wall time of the one-touch passes (counted in ``Recognition.widened_seconds``).
    passes : tuple of str
        The passes that ran, in order ("lone_leader", "transfer", "marginal",
        "rejected", "confirm", "weak_motions").
    """

    recognition: Recognition
    noise: float
    run: object
    cautions: tuple[str, ...]
    widened_seconds: float
    passes: tuple[str, ...]


def before_naming(
    rec: Recognition,
    prior: dict | None,
    fits: dict,
    models: list,
    method: str,
    run,
    noise: float,
    own: float,
    looked: bool,
    memo: dict,
) -> NamingPasses:
    """Look again for every pose and model that might fit as well, where the scores would
    name a model.

    Parameters
    ----------
    rec : Recognition
        Ranked and scored (:func:`~meshrec.recognition.rescore.rescored`).
    prior : dict of str to float or None
        The models' prior weights (a flat touch's), None: uniform.
    fits : dict
        Several touches' joint fits by model (updated in place); empty for one touch.
    models : list of ModelIndex
    method : str
        The local-search optimiser.
    run : ModelWorkers or None
        Where registrations run (None: started here if needed).
    noise : float
        The noise the scores take.
    own : float
        The touches' own noise (without the meshes' error): whether a fit is marginal is
        judged on it.
    looked : bool
        Whether the models were already registered again because nothing fitted (the
        marginal pass is then not run again).
    memo : dict
        Shared with the answer's pose test
        (:func:`~meshrec.recognition.best_pose.free_motions`).

    Returns
    -------
    NamingPasses
    """
    if len(rec.touches) > 1:
        return _before_naming_several(rec, prior, fits, models, run, noise, memo)
    return _before_naming_one(rec, prior, fits, models, method, run, noise, own, looked, memo)


def _before_naming_several(rec, prior, fits, models, run, noise, memo) -> NamingPasses:
    """Several touches: the lone leader's pairs, then its poses on the other models."""
    by_name = {m.name: m for m in models}
    n = noise_and_points(rec)[1]
    done = []
    if would_recognise(rec, prior, n, noise):
        # Every pose its touches allow, before its pose is given. Not where the data leave
        # the pose free anyway, nor where every turn is a symmetry of the model (a sphere):
        # as for one touch's confirmation (it cost a second on the bundled sphere's 80k
        # faces).
        with timed("freedom"):
            freedom = free_motions(rec, by_name[rec.ranking[0].model], memo)[0]
        if not (freedom.unresolved or freedom.turns >= 3):
            done.append("lone_leader")
            with timed("adequacy"):
                search_lone_leader(rec.touches, models, rec.geometries, fits, noise, n)
                ranking = [
                    fits[r.model].registration if r.model in fits else r for r in rec.ranking
                ]
                rec = dataclasses.replace(rec, ranking=tuple(ranking))
                rec, noise = rescored(rec, prior, models)
    if would_recognise(rec, prior, n, noise):
        done.append("transfer")
        with timed("transfer"):
            rec = _transferred(rec, models, fits, noise)
            rec, noise = rescored(rec, prior, models)
    return NamingPasses(rec, noise, run, (), 0.0, tuple(done))


def _before_naming_one(
    rec, prior, fits, models, method, run, noise, own, looked, memo
) -> NamingPasses:
    """One touch: the marginal and out-of-range looks, the confirmation, the weak motions
    and the transfer."""
    by_name = {m.name: m for m in models}
    n = noise_and_points(rec)[1]
    done, cautions = [], []
    t_wide = 0.0
    if not looked and would_be_named(rec, prior, n, noise):
        p_best = fit_p_value(rec.scores[0].rms, n, own)
        if p_best < defaults.NAME_P_VALUE:
            # One touch about to name a model that fits only marginally (the right model
            # fits better than this on all but a few touches): the touched model's own
            # search may have ended short of its pose while another model fits about as
            # well (a YCB touch of the gelatin box named the foam brick, tail 0.016; the
            # gelatin box's pose, found by these passes, fits better). Look harder first.
            done.append("marginal")
            t1 = time.perf_counter()
            rec, noise, run, how = looked_harder(
                rec, prior, fits, models, method, run, n, defaults.NAME_P_VALUE
            )
            t_wide += time.perf_counter() - t1
            cautions.append(
                f"the best fit was marginal for naming a model from one touch (its chi-square "
                f"tail {p_best:.2g}, below defaults.NAME_P_VALUE = {defaults.NAME_P_VALUE:g}): "
                f"the curvature lookup was widened {defaults.LOOKUP_WIDEN_SCALE:g} times and "
                f"{how}"
            )
    turn = curvature_turn(rec.geometry)
    if turn > defaults.CURVATURE_MAX_TURN:
        rejected = frozenset(r.model for r in rec.ranking if r.rejected)
        if rejected and would_recognise(rec, prior, n, noise):
            # The curvature estimate is out of its range (the curves would turn by more
            # than CURVATURE_MAX_TURN radians over their half-length: curves long against
            # the radius of curvature, or noise large against their length), and the
            # lookup window built on it may have left the right model out. Before one model
            # is named, the models the lookup alone rejected are registered with the
            # window open (every site a candidate, spread as usual).
            done.append("rejected")
            t1 = time.perf_counter()
            opened = {"only": rejected, "lookup_scale": defaults.LOOKUP_OPEN_SCALE}
            rec, noise, run = looked_again(rec, prior, models, method, run, "widened", **opened)
            t_wide += time.perf_counter() - t1
            found = [r.model for r in rec.ranking if r.model in rejected and not r.rejected]
            cautions.append(
                f"the curvature estimate at the contact is out of its range (the curves would "
                f"turn by {turn:.3g} radians over their half-length, more than "
                f"defaults.CURVATURE_MAX_TURN = {defaults.CURVATURE_MAX_TURN:g}): the "
                f"{len(rejected)} model(s) that the curvature lookup rejected were registered "
                f"again on every site ({len(found)} registered)"
            )
    if would_be_named(rec, prior, n, noise):
        confirmed, t_confirm = _confirmed(rec, prior, method, run, models, memo)
        t_wide += t_confirm
        if confirmed is not None:
            done.append("confirm")
            rec, noise, caution = confirmed
            if caution:
                cautions.append(caution)
        if would_be_named(rec, prior, n, noise):
            t1 = time.perf_counter()
            with timed("freedom"):
                explored = _explore_weak_motions_one(rec, by_name[rec.ranking[0].model], memo)
            if explored is not rec:
                done.append("weak_motions")
                rec, noise = rescored(explored, prior, models)
            t_wide += time.perf_counter() - t1
        if would_be_named(rec, prior, n, noise):
            done.append("transfer")
            t1 = time.perf_counter()
            with timed("transfer"):
                rec = _transferred(rec, models, fits, noise)
                rec, noise = rescored(rec, prior, models)
            t_wide += time.perf_counter() - t1
    return NamingPasses(rec, noise, run, tuple(cautions), t_wide, tuple(done))


def _confirmed(rec: Recognition, prior, method: str, run, models: list, memo: dict):
    """One touch about to be ``recognised``: the named model's own search again, with
    ``defaults.CONFIRM_CANDIDATES`` candidates, before its pose is given.

    The first pass spreads at most ``defaults.MAX_CANDIDATES`` candidates over the sites
    the (K, H) window holds; on a short touch of a smooth, nearly symmetric shape the
    window holds many, and the search can end in a wrong basin that fits almost as well
    (a black-box probe, stop 31: five of six such touches of a superellipsoid and a cone
    were `recognised` with the pose `fixed` and 8 to 34 mm off, the true pose fitting
    better; with 256 candidates the search found it in all five). The model keeps the
    better of its two fits. Skipped where the window held no more sites than the cap (the
    same candidates again), where the data leave the pose free (a motion that is not a
    symmetry of the model) and where the touch crosses a sharp edge of the model (the
    answer is then ``ambiguous`` anyway), and where every turn is a symmetry of the model
    (a sphere: every basin is the same pose).

    Returns ``(None, seconds)`` when skipped, else ``((recognition, noise, caution),
    seconds)``; ``caution`` is "" unless the better pose moves the data by more
    than ``defaults.CONFIRM_MOVED_FRACTION`` of the curves' half-length.
    """
    best = rec.ranking[0]
    if best.rejected or best.candidates < defaults.MAX_CANDIDATES:
        return None, 0.0
    t0 = time.perf_counter()
    with timed("freedom"):
        # A pose the data leave free (a slide along a cylinder's side) is never
        # `recognised` (with_pose_freedom), nor is one touch across a sharp edge of the
        # model (across_an_edge): nothing to confirm, and such touches of the bundled
        # cylinders paid a second registration for it (0.3 to 0.6 s).
        model = {m.name: m for m in models}[best.model]
        freedom = free_motions(rec, model, memo)[0]
        # every turn a symmetry (a sphere): every basin is the same pose, none to miss
        free = freedom.unresolved or freedom.turns >= 3
        points = apply_transform(best.T_model_touch, rec.touch.points)
        crossed = patches_crossed(model, points)
    if free or crossed > 1:
        return None, time.perf_counter() - t0
    # the first pass's window (not widened), more candidates in it
    looks = {"max_candidates": defaults.CONFIRM_CANDIDATES, "lookup_scale": 1.0}
    looks["only"] = frozenset({best.model})
    rec, noise, _ = looked_again(rec, prior, models, method, run, "dense", **looks)
    after = next(r for r in rec.ranking if r.model == best.model)
    caution = ""
    points = np.c_[rec.touch.points, np.ones(rec.touch.n_points)]
    moved = (
        float(np.max(np.linalg.norm(points @ (after.T_model_touch - best.T_model_touch).T, axis=1)))
        if after is not best
        else 0.0
    )
    if moved > defaults.CONFIRM_MOVED_FRACTION * rec.geometry.half_length:
        caution = (
            f"the search of {best.model}, looked at again with up to "
            f"{defaults.CONFIRM_CANDIDATES} candidates before naming it, found a better pose "
            f"(RMS {after.rms:.3g} against {best.rms:.3g}; the data moved up to {moved:.3g})"
        )
    return (rec, noise, caution), time.perf_counter() - t0


def _explore_weak_motions_one(rec: Recognition, model, memo: dict) -> Recognition:
    """One touch about to name ``model``: its poses a long way along the best pose's
    weakest motions refined too, and kept among its poses.

    As for several touches (:func:`meshrec.recognition.passes.rank_joint`): on a nearly symmetric
    stretch of the surface (the rounded edge of a boxy superquadric, nearly a cylinder
    there) a slide or turn of the touch fits almost as well, and the search, started
    from the candidates, can end in one such basin while the true pose lies in another.
    The local test then saw a fixed pose (a black-box probe, stop 33: `recognised`, the
    pose `fixed` and 0.355 off, 7 times its sigma, on an exact mesh; the true pose fits
    within 1% of its RMS). The poses found from every start of
    :func:`~meshrec.recognition.weak.exploration_starts` (the weak motions, the model's
    near-symmetries, turns about the touch's normal; refined on all the points, those that
    carry the touch through a thin wall left out) join the model's; their weights then say
    whether the pose is one of several. Skipped
    where the data leave the pose free or every turn is a symmetry of the model (a
    sphere), as the confirmation is. Returns ``rec`` itself when nothing was explored.
    """
    best = rec.ranking[0]
    if best.rejected or best.T_model_touch is None:
        return rec
    freedom = free_motions(rec, model, memo)[0]
    if freedom.unresolved or freedom.turns >= 3:
        return rec
    starts = exploration_starts(
        model,
        rec.touch.points,
        best.T_model_touch,
        [(rec.geometry.point, rec.geometry.normal)],
    )
    if not starts:
        return rec
    # refined coarse to fine, as for several touches (every start: the one nearest the
    # better basin is often the worst at its start)
    found = joint_poses(
        model,
        [rec.touch],
        starts,
        rec.geometry,
        best=len(starts),
        start_ratio=float("inf"),
    )
    reg = _with_more_poses(best, found, model, rec.touch, rec.geometry)
    return dataclasses.replace(rec, ranking=(reg, *rec.ranking[1:]))


def _with_more_poses(reg: Registration, found, model, touch: TouchData, geometry) -> Registration:
    """One touch's registration with the poses ``found`` among its own (distinct, least
    RMS first; a rejected one registered by them), but those that carry the touch through
    the surface where its side is known (:func:`~meshrec.registration.poses.keeps_side`,
    as the registration's own poses are)."""
    found = [p for p in found if keeps_side(model, touch, geometry, p.T_model_touch)]
    if not found:
        return reg
    poses = distinct_poses(
        sorted((*reg.poses, *found), key=lambda p: p.rms), float(geometry.half_length)
    )
    top = poses[0]
    return dataclasses.replace(
        reg,
        poses=poses,
        T_model_touch=top.T_model_touch,
        error=top.error,
        rms=top.rms,
        contact=top.contact,
        normal=top.normal,
        phi=top.phi,
        n_points=int(touch.n_points),
    )


def _transferred(rec: Recognition, models: list, fits: dict, noise: float) -> Recognition:
    """About to name a model: its best poses refined on every other model, kept where they
    fit (:func:`~meshrec.recognition.joint.transfer_poses`).

    Variants of one part exported in one frame fit touches away from their difference at
    the same pose, and a variant's own search can end elsewhere: the variant whose search
    found the pose was named alone, at p 1.000 (a black-box probe, stop 33: brackets and
    levers with and without a hole, a chamfer or a boss; 21 of 204 several-touch answers).
    The named model's ``defaults.TRANSFER_POSES`` best poses are the seeds; a model where a
    seed starts within ``defaults.TRANSFER_REACH`` times the named model's RMS (or the
    noise, if larger) is refined from it. Models in other frames cost one query each.
    ``fits`` (several touches) is updated in place.
    """
    leader = rec.ranking[0]
    if leader.rejected or leader.T_model_touch is None:
        return rec
    seeds = [p.T_model_touch for p in leader.poses[: defaults.TRANSFER_POSES]]
    reach = defaults.TRANSFER_REACH * max(float(leader.rms), float(noise))
    by_name = {m.name: m for m in models}
    ranking = [leader]
    for reg in rec.ranking[1:]:
        model = by_name[reg.model]
        if len(rec.touches) > 1:
            fit = transfer_poses(rec.touches, model, rec.geometries, fits[reg.model], seeds, reach)
            fits[reg.model] = fit
            ranking.append(fit.registration)
        else:
            found = transferred_poses(rec.touches, model, rec.geometries, seeds, reach)
            ranking.append(_with_more_poses(reg, found, model, rec.touch, rec.geometry))
    return dataclasses.replace(rec, ranking=tuple(ranking))
