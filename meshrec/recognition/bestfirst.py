"""Several touches: the models' joint fits, most promising model first (branch and bound).

Per model, the work of a joint fit comes in steps: refine the first touch's poses on every
touch's points, then register the second touch alone and refine again, then the third,
and so on (:func:`meshrec.recognition.joint.register_touches`). A model stops when its
joint fit explains every touch to the noise, or when even its best conceivable fit
(:func:`~meshrec.recognition.joint.log_likelihood_bound`: each touch registered so far
at its own best, the others at a floor below their own noise) is
``defaults.JOINT_PRUNE_LOG_RATIO`` below the best joint fit found so far (the leader):
it cannot become plausible, whatever its remaining touches give. A model whose joint fit
is that far below the leader even before its fine refinement
(:func:`~meshrec.recognition.joint.joint_poses`, ``hopeless_rms``) skips it.

The steps run best bound first (ties by model name: an order of the data, not of the
library), so the leader is found early and prunes the others before their costly steps.
Taken touch by touch over every model instead, every model that fits each touch alone
(the usual case on smooth shapes) registered all its touches before any model had its
joint fit. The bound only falls as touches are registered (a touch fits no better than
its floor) and the leader only rises, so a model pruned here would have been pruned at
the end too: every model that is not is within ``-defaults.JOINT_PRUNE_LOG_RATIO`` of
the final leader or fits to the noise.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.recognition.joint import (
    JointFit,
    log_likelihood_bound,
    register_touches,
    rms_out_of_reach,
)
from meshrec.recognition.scoring import fit_p_value, log_likelihoods

__all__ = ["fit_best_first"]


def fit_best_first(
    touches: Sequence[TouchData],
    models: Sequence,
    geometries: Sequence[LocalGeometry],
    firsts: dict[str, JointFit],
    noise: float,
    method: str = defaults.SEARCH_METHOD,
) -> dict[str, JointFit]:
    """Every model's joint fit of the touches, pruned as soon as it cannot compete.

    Parameters
    ----------
    touches : sequence of TouchData
        Two or more, in one frame.
    models : sequence of ModelIndex
        The library's models (each name once).
    geometries : sequence of LocalGeometry
        The local geometry of each touch.
    firsts : dict of str to JointFit
        Each model's first touch registered alone, its poses unrefined
        (:func:`~meshrec.recognition.joint.first_touch_fit`), by model name.
    noise : float
        The touches' pooled noise (:func:`~meshrec.recognition.joint.pooled_noise`), > 0.
    method : {"lm", "steepest"}
        The local-search optimiser.

    Returns
    -------
    dict of str to JointFit
        By model name, in the order of ``models``: the joint fit as far as it went (a
        pruned or rejected model keeps the fit it had).

    Raises
    ------
    ValueError
        If ``firsts`` lacks a model of ``models``, ``geometries`` does not match
        ``touches`` or ``noise`` is not positive and finite.
    """
    if len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    missing = [m.name for m in models if m.name not in firsts]
    if missing:
        raise ValueError(f"firsts must hold every model's first fit, missing {missing}")
    if not (noise > 0 and noise < float("inf")):
        raise ValueError(f"noise must be positive and finite, got {noise!r}")
    by_name = {m.name: m for m in models}
    fits = {m.name: firsts[m.name] for m in models}
    n = int(sum(t.n_points for t in touches))
    # (-bound, name, refined): the heap pops the best bound first; a model's first step
    # refines its first touch's poses on every touch (refined False), each later step
    # registers one more touch alone.
    heap = [
        (-log_likelihood_bound(fit, touches, noise, geometries), name, False)
        for name, fit in fits.items()
        if not fit.registration.rejected
    ]
    heapq.heapify(heap)
    leader = float("-inf")
    while heap:
        neg_bound, name, refined = heapq.heappop(heap)
        if -neg_bound < leader + defaults.JOINT_PRUNE_LOG_RATIO:
            break  # this one and every one left (their bounds are lower) cannot compete
        fit = fits[name]
        upto = fit.registered if not refined else fit.registered + 1
        fit = register_touches(
            touches,
            by_name[name],
            geometries,
            upto=upto,
            previous=fit,
            method=method,
            noise=noise if refined else None,
            hopeless_rms=rms_out_of_reach(leader, n, noise),
        )
        fits[name] = fit
        reg = fit.registration
        if reg.rejected:
            continue
        leader = max(leader, float(log_likelihoods([reg.rms], n, noise)[0]))
        if fit_p_value(reg.rms, n, noise) >= defaults.WIDEN_P_VALUE:
            continue  # fits every touch to the noise already
        if fit.registered < len(touches):
            bound = log_likelihood_bound(fit, touches, noise, geometries)
            heapq.heappush(heap, (-bound, name, True))
    return fits
