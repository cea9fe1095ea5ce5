"""Stage 5 of a registration: local searches on surface charts from the best candidates.

From each screened candidate (best first) with its refined phi, the local search (see
:func:`meshrec.registration.search.local_search`) moves the contact over the surface and
turns phi to the least error, on an even subsample of the data points. The searches stop
early once ``defaults.SEARCH_PATIENCE`` in a row have not improved the best error and that
best already fits the data to the noise level (the distance residuals of a right
superposition are the noise, whose RMS the curve fits estimate). The rule looks at this
model's searches only, so a model's result does not depend on any other model.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_choice, check_instance, check_int, check_number
from meshrec.model.index import ModelIndex
from meshrec.registration.lookup import ContactCandidates
from meshrec.registration.sampling import even_subsample
from meshrec.registration.search import SEARCH_METHODS, LocalSearch, local_search

__all__ = ["SearchRun", "Searches", "search_candidates"]


@dataclass(frozen=True, eq=False)
class SearchRun(ValueEquality):
    """One local search.

    Attributes
    ----------
    candidate : int
        The candidate it started from.
    phi0 : float
        The phi it started from, radians.
    result : LocalSearch
        Its result (contact, phi, error on the subsample, path).
    """

    candidate: int
    phi0: float
    result: LocalSearch = field(repr=False)


@dataclass(frozen=True, eq=False)
class Searches(ValueEquality):
    """The local searches run, in the order run.

    Attributes
    ----------
    runs : tuple of SearchRun
    subset : (m,) int
        The data points used (an even subsample, ``defaults.SEARCH_POINTS``).
    stopped_early : bool
        Whether the stopping rule ended the searches before every start was searched.
    """

    runs: tuple[SearchRun, ...]
    subset: np.ndarray = field(repr=False)
    stopped_early: bool

    def __repr__(self) -> str:
        errs = [round(r.result.error, 6) for r in self.runs]
        return f"Searches(runs={len(self.runs)}, errors={errs}, stopped_early={self.stopped_early})"


def _starts(starts, c: int) -> list[tuple[int, float]]:
    """The (candidate, phi) starts checked, before any search runs.

    Raises
    ------
    TypeError
        If ``starts`` or one of its items is not a sequence, or an index is not an
        integer or a phi not a real number.
    ValueError
        If a start is not a pair, names no candidate in ``0..c-1``, or its phi is not
        finite.
    """
    if isinstance(starts, (str, bytes)) or not isinstance(starts, Iterable):
        raise TypeError(
            f"starts must be a sequence of (int, float) pairs, got {type(starts).__name__}"
        )
    pairs = []
    for k, start in enumerate(starts):
        if isinstance(start, (str, bytes)) or not isinstance(start, Iterable):
            raise TypeError(f"starts[{k}] must be an (int, float) pair, got {type(start).__name__}")
        start = tuple(start)
        if len(start) != 2:
            raise ValueError(f"starts[{k}] must be an (int, float) pair, got {len(start)} items")
        i = check_int(start[0], f"starts[{k}][0]")
        phi0 = check_number(start[1], f"starts[{k}][1]")
        if not 0 <= i < c:
            raise ValueError(f"starts[{k}] must name a candidate in 0..{c - 1}, got {i!r}")
        pairs.append((i, phi0))
    return pairs


def search_candidates(
    model,
    candidates: ContactCandidates,
    starts: Sequence[tuple[int, float]],
    *,
    method: str = defaults.SEARCH_METHOD,
    n_points: int = defaults.SEARCH_POINTS,
) -> Searches:
    """Run the local searches from ``starts`` in order, until the stopping rule holds.

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
    starts : sequence of (int, float)
        (candidate index, initial phi) pairs, best first.
    method : {"lm", "steepest"}
        The local-search optimiser.
    n_points : int
        Data points used (an even subsample).

    Returns
    -------
    Searches

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``candidates`` not a ContactCandidates, or
        ``starts`` not a sequence of (integer, real number) pairs, or ``method`` not a
        string.
    ValueError
        If ``method`` is unknown, a start is not a pair, a candidate index is out of range
        or a phi is not finite.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    check_choice(method, SEARCH_METHODS, "method")
    c = len(candidates)
    pairs = _starts(starts, c)
    geometry = candidates.geometry
    scale = float(geometry.half_length)
    good_fit = defaults.SEARCH_GOOD_FIT * float(geometry.fit_rms)
    subset = even_subsample(len(candidates.points), n_points)
    runs: list[SearchRun] = []
    best = np.inf
    stale = 0
    stopped = False
    for k, (i, phi0) in enumerate(pairs):
        local = candidates.local_points[candidates.side[i]][subset]
        found = local_search(model, local, candidates.origins[i], phi0, scale, method=method)
        runs.append(SearchRun(candidate=int(i), phi0=float(phi0), result=found))
        better = found.error < (1.0 - defaults.SEARCH_IMPROVEMENT) * best
        stale = 0 if better else stale + 1
        best = min(best, found.error)
        if stale >= defaults.SEARCH_PATIENCE and best <= good_fit and k + 1 < len(pairs):
            stopped = True
            break
    return Searches(runs=tuple(runs), subset=subset, stopped_early=stopped)
