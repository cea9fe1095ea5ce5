"""Stage 3 of a registration: screen the best candidates by a few rigid-refinement steps.

A candidate is up to the spreading spacing away from its basin's minimum, so its best
sampled phi error ranks it only roughly. A few steps of the rigid refinement on the phi
subsample, from each kept candidate's best sampled phi, rank the candidates better; the
best screened ones get the phi refinement and the local search.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_instance
from meshrec.model.index import ModelIndex
from meshrec.registration.batch import refine_rigid_batch
from meshrec.registration.brackets import PhiBrackets
from meshrec.registration.lookup import ContactCandidates
from meshrec.registration.transform import superposition

__all__ = ["Screening", "screen_candidates"]


@dataclass(frozen=True, eq=False)
class Screening(ValueEquality):
    """The screened candidates, best first.

    Attributes
    ----------
    candidates : (k,) int
        Candidate indices, least screened error first (ties: lower index first).
    phis : (k,) float
        The sampled phi each screening started from, radians.
    errors : (k,) float
        Mean point-to-surface distance of the phi subsample after the screening steps.
    """

    candidates: np.ndarray
    phis: np.ndarray = field(repr=False)
    errors: np.ndarray = field(repr=False)


def screen_candidates(
    model,
    candidates: ContactCandidates,
    brackets: PhiBrackets,
    *,
    limit: int = defaults.SCREEN_CANDIDATES,
    iterations: int = defaults.SCREEN_ITERATIONS,
) -> Screening:
    """Rank the best ``limit`` kept candidates by a short rigid refinement.

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
    brackets : PhiBrackets
        From :func:`meshrec.registration.brackets.phi_brackets` on ``candidates``.
    limit : int
        Candidates screened at most (the first of ``brackets.order``).
    iterations : int
        Rigid-refinement iterations per candidate.

    Returns
    -------
    Screening

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``candidates`` not a ContactCandidates or
        ``brackets`` not a PhiBrackets.
    ValueError
        If ``brackets`` does not belong to ``candidates``, or ``limit`` or
        ``iterations`` is not a positive integer.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    check_instance(brackets, PhiBrackets, "brackets")
    if brackets.errors.shape[0] != len(candidates):
        raise ValueError(
            f"brackets must be of these {len(candidates)} candidates, "
            f"got {brackets.errors.shape[0]}"
        )
    for name, value in (("limit", limit), ("iterations", iterations)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    step = 2.0 * np.pi / len(brackets.grid)
    sub_points = candidates.points[brackets.subset]
    starts, T0s = [], []
    for i in brackets.order[:limit]:
        side = candidates.sides[candidates.side[i]]
        phi = float(np.argmin(brackets.errors[i])) * step
        T0s.append(superposition(side.point, side.frame, candidates.origins[i], phi))
        starts.append((int(i), phi))
    # All the candidates' refinements in lockstep, one distance query per round (the same
    # arithmetic per candidate as refine_rigid, so the same results).
    quick = (
        refine_rigid_batch(model, sub_points, np.array(T0s).reshape(-1, 4, 4), max_iter=iterations)
        if starts
        else []
    )
    screened = [(q.error, i, phi) for q, (i, phi) in zip(quick, starts, strict=True)]
    screened.sort(key=lambda s: (s[0], s[1]))
    return Screening(
        candidates=np.array([s[1] for s in screened], dtype=np.int64),
        phis=np.array([s[2] for s in screened], dtype=np.float64),
        errors=np.array([s[0] for s in screened], dtype=np.float64),
    )
