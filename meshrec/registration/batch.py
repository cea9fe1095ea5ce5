"""Rigid refinements of many starting poses of the same points, in lockstep.

:func:`refine_rigid_batch` runs :func:`~meshrec.registration.refine.refine_rigid` from
each of ``k`` starting transforms, with the same arithmetic per start (so the same
results), but evaluates the residuals of every start's trial step in one closest-point
query per round instead of one per step: the screening refines up to 48 candidates a few
steps each, and the Python around those small queries was most of its time.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.registration.damping import (
    after_accept,
    after_reject,
    damped_system,
    predicted_drop,
    schedule,
)
from meshrec.registration.objective import Residuals, residuals
from meshrec.registration.refine import Refinement
from meshrec.registration.transform import apply_transform

__all__ = ["refine_rigid_batch"]


class _Start:
    """The state of one start's Levenberg-Marquardt loop (refine_rigid's locals)."""

    def __init__(self, T: np.ndarray):
        self.T = T
        self.res: Residuals | None = None
        self.cost = 0.0
        self.lam = defaults.REFINE_DAMPING
        self.nu = 2.0
        self.predicted = 0.0
        self.it = 0
        self.system = None  # (A, b, m, spread) of the current linearisation
        self.trial = None
        self.done = False


def _batch_residuals(model, Y: list[np.ndarray]) -> list[Residuals]:
    """Residuals of several point sets in one query, split back per set."""
    n = len(Y[0])
    res = residuals(model, np.concatenate(Y, axis=0))
    return [
        Residuals(
            values=res.values[i * n : (i + 1) * n],
            closest=res.closest[i * n : (i + 1) * n],
            gradient=res.gradient[i * n : (i + 1) * n],
        )
        for i in range(len(Y))
    ]


def refine_rigid_batch(
    model,
    points: np.ndarray,
    T_model_touch: np.ndarray,
    max_iter: int | None = None,
    rel_tol: float | None = None,
    initial: list[Residuals] | None = None,
) -> list[Refinement]:
    """:func:`~meshrec.registration.refine.refine_rigid` from each of several starts.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        Data points in the touch frame (the same for every start).
    T_model_touch : (k, 4, 4) float
        The starting transforms.
    max_iter : int, optional
        Iterations at most, per start (default ``defaults.REFINE_MAX_ITER``, read at call
        time).
    rel_tol : float, optional
        Stop a start when its sum of squares improves by less than this fraction (default
        ``defaults.REFINE_REL_TOL``, read at call time).
    initial : list of Residuals, optional
        The residuals of ``points`` placed by each start
        (:func:`~meshrec.registration.objective.residuals` of
        ``apply_transform(T_model_touch[i], points)``), when the caller has them already:
        they are used instead of a first query (the same results, one query less).

    Returns
    -------
    list of Refinement
        One per start, in order; each as ``refine_rigid`` from that start gives it.

    Raises
    ------
    ValueError
        If ``T_model_touch`` is not ``(k, 4, 4)``, ``points`` not ``(n, 3)`` with n >= 1,
        ``initial`` does not hold one Residuals of ``n`` values per start, or
        ``defaults.REFINE_DAMPING_SCHEDULE`` is not one of
        :data:`meshrec.registration.damping.SCHEDULES`.
    """
    max_iter = defaults.REFINE_MAX_ITER if max_iter is None else max_iter
    rel_tol = defaults.REFINE_REL_TOL if rel_tol is None else rel_tol
    T0 = np.asarray(T_model_touch, dtype=np.float64)
    if T0.ndim != 3 or T0.shape[1:] != (4, 4):
        raise ValueError(f"T_model_touch must have shape (k, 4, 4), got {T0.shape}")
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) == 0:
        raise ValueError(f"points must have shape (n, 3) with n >= 1, got {P.shape}")
    if initial is not None and (
        len(initial) != len(T0) or any(np.shape(r.values) != (len(P),) for r in initial)
    ):
        raise ValueError(
            f"initial must hold one Residuals of {len(P)} values per start ({len(T0)}), got "
            f"{[np.shape(r.values) for r in initial]}"
        )
    name = schedule()
    starts = [_Start(np.array(T)) for T in T0]
    if not starts:
        return []
    if initial is None:
        initial = _batch_residuals(model, [apply_transform(s.T, P) for s in starts])
    for s, r in zip(starts, initial, strict=True):
        s.res, s.cost = r, float(r.values @ r.values)
    if max_iter < 1:
        for s in starts:
            s.done = True
    while True:
        active = [s for s in starts if not s.done]
        if not active:
            break
        trials = []
        for s in active:
            if s.system is None:
                s.it += 1
                s.system = _linearise(s, P)
            if s.lam >= defaults.REFINE_MAX_DAMPING:
                s.done = True  # not accepted: stop, as refine_rigid's loop does
                continue
            trials.append(s)
        if not trials:
            continue
        # Every trial's damped step solved and turned into a rotation in one call each:
        # the same bits as one start at a time (LAPACK solves each system alone, scipy
        # converts each rotation vector alone), without a Python call per start (a
        # look-alike's three-touch recognition made about 13,000 of each).
        damped, diags = zip(*(damped_system(s.system[0], s.lam) for s in trials), strict=True)
        steps = np.linalg.solve(
            np.array(damped),
            np.array([s.system[1] for s in trials])[:, :, None],
        )[:, :, 0]
        turns = Rotation.from_rotvec(
            steps[:, :3] * np.array([s.system[3] for s in trials])[:, None]
        ).as_matrix()
        for s, step, turn, diag in zip(trials, steps, turns, diags, strict=True):
            s.predicted = predicted_drop(step, s.system[1], s.lam, diag)
            m = s.system[2]
            D = np.eye(4)
            D[:3, :3] = turn
            D[:3, 3] = m + step[3:] - D[:3, :3] @ m
            s.trial = D @ s.T
        results = _batch_residuals(model, [apply_transform(s.trial, P) for s in trials])
        for s, r in zip(trials, results, strict=True):
            cost_new = float(r.values @ r.values)
            if cost_new < s.cost:
                improvement = (s.cost - cost_new) / max(s.cost, 1e-300)
                s.lam, s.nu = after_accept(name, s.lam, s.nu, s.cost - cost_new, s.predicted)
                s.T, s.res, s.cost = s.trial, r, cost_new
                s.system = None
                if improvement < rel_tol or s.it >= max_iter:
                    s.done = True
            else:
                s.lam, s.nu = after_reject(name, s.lam, s.nu)
    out = []
    for s in starts:
        absval = np.abs(s.res.values)
        out.append(
            Refinement(
                T_model_touch=s.T,
                error=float(absval.mean()),
                rms=float(np.sqrt(s.cost / len(absval))),
                iterations=s.it,
            )
        )
    return out


def _linearise(s: _Start, P: np.ndarray):
    """refine_rigid's normal equations at the start's current transform."""
    y = apply_transform(s.T, P)
    m = y.mean(axis=0)
    g = s.res.gradient
    a = y - m
    J = np.empty((len(y), 6))
    J[:, 0] = a[:, 1] * g[:, 2] - a[:, 2] * g[:, 1]
    J[:, 1] = a[:, 2] * g[:, 0] - a[:, 0] * g[:, 2]
    J[:, 2] = a[:, 0] * g[:, 1] - a[:, 1] * g[:, 0]
    J[:, 3:] = g
    spread = float(np.sqrt(((y - m) ** 2).sum(axis=1).mean())) or 1.0
    J[:, :3] *= spread
    return J.T @ J, -J.T @ s.res.values, m, spread
