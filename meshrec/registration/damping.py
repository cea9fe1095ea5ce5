"""How the rigid refinements' Levenberg-Marquardt damping moves from step to step.

:func:`meshrec.registration.refine.refine_rigid` (and ``refine_offset``) and their batched
twin :func:`meshrec.registration.batch.refine_rigid_batch` share these rules, so that they
stay the same to the bit. Two schedules, chosen by ``defaults.REFINE_DAMPING_SCHEDULE``
(read at call time):

- ``"gain"`` (Nielsen's, as in Madsen, Nielsen and Tingleff, *Methods for non-linear least
  squares problems*, 2004, eq. 3.15 and Algorithm 3.16): after an accepted step the
  damping is scaled by ``max(1/3, 1 - (2 rho - 1)^3)``, rho being the drop of the sum of
  squares over the drop the linearised model predicted, and the growth factor ``nu`` is
  reset to 2; after a rejected step the damping is multiplied by ``nu`` and ``nu``
  doubles. A step that is accepted but poorly predicted (small rho) raises the damping
  instead of lowering it, so that the next step is not rejected.
- ``"tenfold"`` (Numerical Recipes' ``mrqmin``): divided by
  ``defaults.REFINE_DAMPING_FACTOR`` after an accepted step, multiplied by it after a
  rejected one. On poor fits it swings between too bold and accepted: about one trial
  step in two was rejected on the blobs' refinements.

Why not scipy: ``scipy.optimize.least_squares(method="lm")`` is MINPACK's, one problem at a
time with its own stopping rules; the refinements here run hundreds of starts in lockstep
(one distance query per round for all of them) and stop on the relative drop.
"""

from __future__ import annotations

import numpy as np

from meshrec import defaults

__all__ = [
    "SCHEDULES",
    "after_accept",
    "after_reject",
    "damped_system",
    "predicted_drop",
    "schedule",
]

#: The damping schedules (see the module's description).
SCHEDULES = ("gain", "tenfold")

#: Added to diag(A) before damping: a numerical guard against a singular system (a column
#: of J that vanishes, e.g. all gradients parallel), not a tuning value (far below any
#: squared residual gradient, which are of order 1).
_DIAG_FLOOR = 1e-12


def schedule() -> str:
    """``defaults.REFINE_DAMPING_SCHEDULE``, checked.

    Returns
    -------
    str
        One of :data:`SCHEDULES`.

    Raises
    ------
    ValueError
        If ``defaults.REFINE_DAMPING_SCHEDULE`` is not one of :data:`SCHEDULES`.
    """
    name = defaults.REFINE_DAMPING_SCHEDULE
    if name not in SCHEDULES:
        raise ValueError(
            f"defaults.REFINE_DAMPING_SCHEDULE must be one of {SCHEDULES}, got {name!r}"
        )
    return name


def damped_system(A: np.ndarray, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """The normal matrix damped as Marquardt scales it, and the scaling.

    Parameters
    ----------
    A : (p, p) float
        ``J^T J``.
    lam : float
        The damping.

    Returns
    -------
    damped : (p, p) float
        ``A + lam diag(diag)``.
    diag : (p,) float
        ``diag(A)`` and a floor that keeps the system regular (for
        :func:`predicted_drop`).
    """
    diag = np.diag(A) + _DIAG_FLOOR
    return A + lam * np.diag(diag), diag


def predicted_drop(step: np.ndarray, b: np.ndarray, lam: float, diag: np.ndarray) -> float:
    """The drop of the sum of squares that the linearised residuals predict for ``step``.

    Parameters
    ----------
    step : (p,) float
        The damped step, the solution of ``(A + lam diag(diag)) step = b``.
    b : (p,) float
        ``-J^T r``, the right-hand side of the normal equations.
    lam : float
        The damping the step was solved with.
    diag : (p,) float
        The damping's scaling (``diag(A)`` and its floor).

    Returns
    -------
    float
        ``|r|^2 - |r + J step|^2 = step.b + lam step.(diag step)`` (positive for a
        nonzero ``b``).
    """
    return float(step @ b) + lam * float(step @ (diag * step))


def after_accept(name: str, lam: float, nu: float, drop: float, predicted: float):
    """The damping and growth factor after an accepted step.

    Parameters
    ----------
    name : str
        The schedule, from :func:`schedule`.
    lam, nu : float
        The damping the step was taken with, and the growth factor.
    drop : float
        The drop of the sum of squares the step gave (positive).
    predicted : float
        The drop :func:`predicted_drop` gave for it.

    Returns
    -------
    (lam, nu) : (float, float)
        Not below ``defaults.REFINE_MIN_DAMPING``.
    """
    if name == "tenfold":
        return max(lam / defaults.REFINE_DAMPING_FACTOR, defaults.REFINE_MIN_DAMPING), nu
    rho = drop / predicted if predicted > 0.0 else 1.0
    scale = max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
    return max(lam * scale, defaults.REFINE_MIN_DAMPING), 2.0


def after_reject(name: str, lam: float, nu: float):
    """The damping and growth factor after a rejected step.

    Parameters
    ----------
    name : str
        The schedule, from :func:`schedule`.
    lam, nu : float
        The damping the step was tried with, and the growth factor.

    Returns
    -------
    (lam, nu) : (float, float)
    """
    if name == "tenfold":
        return lam * defaults.REFINE_DAMPING_FACTOR, nu
    return lam * nu, 2.0 * nu
