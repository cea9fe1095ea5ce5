"""The registration of a model pruned before its local searches: one start, a few steps.

The cascade (:mod:`meshrec.recognition.cascade`) and the library-wide screen
(:mod:`meshrec.recognition.screen`) both give a model they prune the pose of its best
screened start, refined on all the points by a few steps of the rigid refinement, and
mark it ``pruned``: its error is an upper bound of what the full search would reach.
"""

from __future__ import annotations

import time

import numpy as np

from meshrec.registration.poses import refined_pose
from meshrec.registration.refine import refine_rigid
from meshrec.registration.register import Registration, StageTimes

__all__ = ["pruned_from_start"]


def pruned_from_start(
    model,
    points: np.ndarray,
    T_start: np.ndarray,
    touch_point: np.ndarray,
    iterations: int,
    *,
    candidates: int,
    raw_hits: int,
    candidate_points: np.ndarray,
    before: StageTimes | None = None,
    seconds_before: float = 0.0,
) -> Registration:
    """A pruned model's Registration from one starting pose.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        The touch's points, touch frame.
    T_start : (4, 4) float
        The starting pose ``T_model_touch``.
    touch_point : (3,) float
        The touch's common point (locates the pose's contact on the model).
    iterations : int
        Refinement steps at most.
    candidates, raw_hits : int
        Reported as the registration's.
    candidate_points : (k, 3) float
        The candidate contacts, model frame.
    before : StageTimes, optional
        Time of the stages already run (the refinement's is added).
    seconds_before : float
        Their total.

    Returns
    -------
    Registration
        With ``pruned`` true, ``searches`` 0 and one pose.
    """
    t0 = time.perf_counter()
    ref = refine_rigid(model, points, T_start, max_iter=iterations)
    pose = refined_pose(model, ref, touch_point)
    t_refine = time.perf_counter() - t0
    times = (before or StageTimes()) + StageTimes(refine=t_refine)
    return Registration(
        model=model.name,
        path=str(model.path),
        error=pose.error,
        contact=pose.contact,
        normal=pose.normal,
        phi=None,
        T_model_touch=pose.T_model_touch,
        candidates=int(candidates),
        raw_hits=int(raw_hits),
        searches=0,
        seconds=seconds_before + t_refine,
        times=times,
        candidate_points=candidate_points,
        rms=pose.rms,
        n_points=len(points),
        poses=(pose,),
        pruned=True,
    )
