"""The initial rotation phi about the normal: discretise, bracket every minimum, refine.

Section 2.2.1 of the paper: with the contact fixed at a candidate point, the error depends
on phi alone. [0, 2 pi) is discretised, every local minimum of the sampled error is
bracketed by its two neighbours, and each bracket is refined (the paper bisects; we use
scipy's bounded Brent method, a bracketing refinement that needs fewer evaluations, run
on every bracket at once by :mod:`meshrec.registration.brent`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.registration.brent import minimize_bounded

__all__ = ["PhiSearch", "bracket_minima", "search_phi", "search_phis"]


@dataclass(frozen=True, eq=False)
class PhiSearch(ValueEquality):
    """Result of the phi search at one candidate.

    Attributes
    ----------
    phi : float
        The angle with the smallest refined error, radians in [0, 2 pi).
    error : float
        The error at ``phi``.
    grid : (s,) float
        The sampled angles.
    grid_errors : (s,) float
        The error at each sampled angle (from :func:`search_phis`, an estimate on a row
        it was told is estimated).
    minima : (m, 2) float
        Every refined local minimum as rows (phi, error), best first.
    """

    phi: float
    error: float
    grid: np.ndarray
    grid_errors: np.ndarray
    minima: np.ndarray


def bracket_minima(values: np.ndarray) -> np.ndarray:
    """Indices of the local minima of samples on a circle.

    A plateau counts once (its first index). A constant sequence has one minimum, index 0.

    Parameters
    ----------
    values : (s,) float
        Samples at equally spaced angles around the circle.

    Returns
    -------
    (m,) int
        Indices i with values[i] <= both circular neighbours (strictly below the left
        one, so that a plateau is not reported twice).

    Raises
    ------
    ValueError
        If ``values`` has fewer than 3 samples or a non-finite value.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 1 or len(values) < 3:
        raise ValueError(f"values must be (s,) with s >= 3, got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("values must be finite")
    left, right = np.roll(values, 1), np.roll(values, -1)
    idx = np.flatnonzero((values < left) & (values <= right))
    if len(idx) == 0:
        idx = np.array([int(np.argmin(values))])
    return idx


def search_phi(
    error: Callable[[np.ndarray], np.ndarray],
    steps: int = defaults.PHI_STEPS,
    refine_ratio: float = defaults.PHI_REFINE_RATIO,
    xtol: float = defaults.PHI_XTOL,
    grid_errors: np.ndarray | None = None,
) -> PhiSearch:
    """Find the phi minimising ``error`` by discretising, bracketing and refining.

    Parameters
    ----------
    error : callable
        ``error(phis)`` maps a (k,) array of angles to their (k,) errors. The refinement
        calls it with one angle at a time.
    steps : int
        Number of samples of [0, 2 pi).
    refine_ratio : float
        Brackets whose sampled error exceeds ``refine_ratio`` times the best sampled error
        are not refined (they cannot become the best minimum in practice).
    xtol : float
        Absolute tolerance of the refinement, radians.
    grid_errors : (steps,) float, optional
        The errors at the ``steps`` sampled angles ``2 pi i / steps``, if already computed
        (for example for many candidates in one batched query).

    Returns
    -------
    PhiSearch

    Raises
    ------
    ValueError
        If ``steps`` < 3, ``refine_ratio`` < 1, or ``grid_errors`` is not (steps,).
    """
    if int(steps) != steps or steps < 3:
        raise ValueError(f"steps must be an integer >= 3, got {steps!r}")
    if grid_errors is None:
        values = np.asarray(error(np.arange(steps) * (2.0 * np.pi / steps)), dtype=np.float64)
    else:
        values = np.asarray(grid_errors, dtype=np.float64)
        if values.shape != (steps,):
            raise ValueError(f"grid_errors must be ({steps},), got {values.shape}")

    def errors(rows, phis):
        return np.array([error(np.array([phi]))[0] for phi in phis], dtype=np.float64)

    return search_phis(errors, values[None, :], refine_ratio=refine_ratio, xtol=xtol)[0]


def search_phis(
    error: Callable[[np.ndarray, np.ndarray], np.ndarray],
    grid_errors: np.ndarray,
    *,
    refine_ratio: float = defaults.PHI_REFINE_RATIO,
    xtol: float = defaults.PHI_XTOL,
    estimated: np.ndarray | None = None,
) -> tuple[PhiSearch, ...]:
    """:func:`search_phi` for many candidates, every bracket refined in lockstep.

    Each bracket is refined by scipy's bounded Brent method (as ``minimize_scalar`` with
    ``method="bounded"`` would, to the bit), all of them at once by
    :func:`meshrec.registration.brent.minimize_bounded`: ``error`` is called once per
    step with every bracket still being refined.

    Parameters
    ----------
    error : callable
        ``error(rows, phis)``: (k,) candidate indices (rows of ``grid_errors``) and (k,)
        angles to the (k,) errors of those candidates at those angles.
    grid_errors : (c, steps) float
        Each candidate's errors at the angles ``2 pi i / steps``.
    refine_ratio : float
        As in :func:`search_phi`, per candidate.
    xtol : float
        Absolute tolerance of the refinement, radians.
    estimated : (c, steps) bool, optional
        The samples of ``grid_errors`` that are estimates (height-fields): the brackets
        are chosen from them, but a bracket whose own sample is an estimate has it
        computed by ``error`` (one more call for all of them) before it is compared with
        its refinement, so that every reported error is ``error``'s. None: none is.

    Returns
    -------
    tuple of PhiSearch
        One per candidate, in order.

    Raises
    ------
    ValueError
        If ``grid_errors`` is not (c, steps) with steps >= 3 or has a non-finite value,
        ``refine_ratio`` < 1, or ``estimated`` is not of the shape of ``grid_errors``.
    """
    values = np.asarray(grid_errors, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] < 3:
        raise ValueError(f"grid_errors must be (c, steps) with steps >= 3, got {values.shape}")
    if not refine_ratio >= 1.0:
        raise ValueError(f"refine_ratio must be >= 1, got {refine_ratio!r}")
    steps = values.shape[1]
    step = 2.0 * np.pi / steps
    grid = np.arange(steps) * step
    rows, samples = [], []
    for row, row_values in enumerate(values):
        best_sample = float(row_values.min())
        for i in bracket_minima(row_values):
            if row_values[i] <= refine_ratio * best_sample + 1e-300:
                rows.append(row)
                samples.append(i)
    rows, samples = np.array(rows, dtype=np.int64), np.array(samples, dtype=np.int64)
    centre = values[rows, samples]
    if estimated is not None:
        estimated = np.asarray(estimated, dtype=bool)
        if estimated.shape != values.shape:
            raise ValueError(f"estimated must be {values.shape}, got {estimated.shape}")
        guess = np.flatnonzero(estimated[rows, samples])
        if len(guess):
            centre = centre.copy()
            centre[guess] = error(rows[guess], grid[samples[guess]])
    res = minimize_bounded(
        lambda problems, phis: error(rows[problems], phis),
        grid[samples] - step,
        grid[samples] + step,
        xatol=xtol,
    )
    minima = [[] for _ in range(len(values))]
    for k, (row, i) in enumerate(zip(rows, samples, strict=True)):
        phi, val = float(res.x[k]), float(res.fun[k])
        if centre[k] < val:  # the refinement cannot be worse than its bracket's sample
            phi, val = float(grid[i]), float(centre[k])
        minima[row].append((phi % (2.0 * np.pi), val))
    out = []
    for row, found in enumerate(minima):
        found.sort(key=lambda m: m[1])
        table = np.array(found, dtype=np.float64).reshape(-1, 2)
        out.append(
            PhiSearch(
                phi=float(table[0, 0]),
                error=float(table[0, 1]),
                grid=grid,
                grid_errors=values[row],
                minima=table,
            )
        )
    return tuple(out)
