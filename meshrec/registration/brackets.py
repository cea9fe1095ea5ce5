"""Stage 2 of a registration: the error against phi at every candidate, and its brackets.

With the data's common point on a candidate and their normal along the model's, the
error depends on the rotation phi about the normal alone (the paper's Section 2.2.1).
It is sampled at ``defaults.PHI_STEPS`` angles for every candidate in one batched distance
query, on an even subsample of the data points; every local minimum of the samples is a
bracket. The candidates are ranked by their best sample, and those far worse than the
best are pruned. :func:`refine_phis` refines the brackets of the candidates that go on to
a local search (stage 4, after the screening).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_choice, check_instance, check_int
from meshrec.model.index import ModelIndex
from meshrec.registration.bounded import bounded_grid_errors, exact_samples, placed_grid
from meshrec.registration.chart import SurfacePoint, rotation_z
from meshrec.registration.fields import field_grid_errors
from meshrec.registration.lookup import ContactCandidates
from meshrec.registration.objective import mean_distances
from meshrec.registration.phi import PhiSearch, bracket_minima, search_phis
from meshrec.registration.sampling import even_subsample

__all__ = [
    "PHI_GRID_DISTANCES",
    "PhiBrackets",
    "grid_errors",
    "phi_brackets",
    "phi_error",
    "refine_phis",
]

#: The ways :func:`phi_brackets` computes its samples.
PHI_GRID_DISTANCES = ("fields", "exact")


@dataclass(frozen=True, eq=False)
class PhiBrackets(ValueEquality):
    """The sampled error against phi of every candidate, and their ranking.

    Attributes
    ----------
    subset : (m,) int
        The data points used (an even subsample, ``defaults.PHI_POINTS``).
    grid : (s,) float
        The sampled angles, ``2 pi i / s``, radians.
    errors : (c, s) float
        Mean point-to-surface distance of the subsample at each candidate and angle where
        ``exact``. Elsewhere, on a candidate's row whose height-field holds, its estimate
        from the field (:mod:`meshrec.registration.fields`); on the other rows a lower
        bound of it (see :mod:`meshrec.registration.bounded`: such samples are above
        every threshold the later stages apply).
    order : (k,) int
        The candidates kept, best sampled error first (stable); those whose best sample
        exceeds ``defaults.SEARCH_PRUNE_RATIO`` times the least one are pruned. Exact in
        its first ``ranked`` entries (``phi_brackets``; on a height-field row the least
        sample is computed exactly); after them, the candidates whose best is only
        bounded, or estimated far above the threshold and not checked, follow, least
        first.
    exact : (c, s) bool or None
        Which samples of ``errors`` are exact (None: all of them).
    estimated : (c,) bool or None
        The rows that are height-field estimates (None: none).
    """

    subset: np.ndarray = field(repr=False)
    grid: np.ndarray = field(repr=False)
    errors: np.ndarray = field(repr=False)
    order: np.ndarray = field(repr=False)
    exact: np.ndarray | None = field(default=None, repr=False)
    estimated: np.ndarray | None = field(default=None, repr=False)

    @property
    def best(self) -> np.ndarray:
        """(c,) float: each candidate's least sampled error."""
        return self.errors.min(axis=1)

    @property
    def minima(self) -> tuple[np.ndarray, ...]:
        """Per candidate, the grid indices of its bracketed local minima (see
        :func:`meshrec.registration.phi.bracket_minima`)."""
        return tuple(bracket_minima(row) for row in self.errors)

    def __repr__(self) -> str:
        c, s = self.errors.shape
        return f"PhiBrackets(candidates={c}, steps={s}, kept={len(self.order)})"


def grid_errors(
    model, origins: Sequence[SurfacePoint], local_points: Sequence[np.ndarray], steps: int
) -> np.ndarray:
    """The error at ``steps`` equally spaced phi for every candidate, in one query.

    Parameters
    ----------
    model : ModelIndex
    origins : sequence of SurfacePoint
        The candidates' points and frames on the model (``c`` of them).
    local_points : sequence of (n, 3) float
        Each candidate's data points in its side's frame.
    steps : int
        Angles sampled over [0, 2 pi).

    Returns
    -------
    (c, steps) float
        Mean unsigned point-to-surface distance at each candidate and angle.
    """
    placed = placed_grid(origins, local_points, steps)
    c, s, n, _ = placed.shape
    return mean_distances(model, placed.reshape(c * s, n, 3)).reshape(c, s)


def phi_error(model, origin: SurfacePoint, local_points: np.ndarray):
    """The error as a function of phi with the data's contact held at ``origin``.

    Parameters
    ----------
    model : ModelIndex
    origin : SurfacePoint
        The candidate's point and frame on the model.
    local_points : (n, 3) float
        The data points in the side's frame.

    Returns
    -------
    callable
        ``error(phis)``: (k,) angles to their (k,) mean point-to-surface distances.
    """

    def error(phis):
        return mean_distances(model, _placed_at(origin, local_points, phis))

    return error


def _placed_at(origin: SurfacePoint, local_points: np.ndarray, phis: np.ndarray) -> np.ndarray:
    """(k, n, 3) float: ``local_points`` placed at ``origin`` rotated by each of ``phis``."""
    R = origin.frame @ rotation_z(phis)  # (k, 3, 3)
    return np.einsum("kij,nj->kni", R, local_points) + origin.point


def phi_brackets(
    model,
    candidates: ContactCandidates,
    *,
    steps: int = defaults.PHI_STEPS,
    n_points: int = defaults.PHI_POINTS,
    prune_ratio: float = defaults.SEARCH_PRUNE_RATIO,
    ranked: int | None = defaults.SCREEN_CANDIDATES,
    distances: str | None = None,
) -> PhiBrackets:
    """Sample the error against phi at every candidate, and rank the candidates.

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
        From :func:`meshrec.registration.lookup.lookup_candidates`, not empty.
    steps : int
        Angles sampled over [0, 2 pi).
    n_points : int
        Data points used (an even subsample).
    prune_ratio : float
        Candidates whose best sample exceeds this factor times the least one are dropped
        from ``order``.
    ranked : int, optional
        Only the first ``ranked`` of ``order`` are read (the screening's limit,
        ``defaults.SCREEN_CANDIDATES``): candidates surely behind them are left with
        bounds of their errors. None: ``order`` is exact throughout.
    distances : {"fields", "exact"}, optional
        How the samples are computed: local height-field estimates where the fields hold
        (:func:`meshrec.registration.fields.field_grid_errors`) or closest-point queries
        (:func:`meshrec.registration.bounded.bounded_grid_errors`). None:
        ``defaults.PHI_GRID_DISTANCES``, read at call time.

    Returns
    -------
    PhiBrackets

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex or ``candidates`` not a ContactCandidates.
    ValueError
        If ``candidates`` is empty, ``steps`` is below 3, ``n_points`` below 1 or
        ``distances`` is unknown.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    if len(candidates) == 0:
        raise ValueError("candidates must hold at least one candidate, got none")
    if not isinstance(steps, (int, np.integer)) or steps < 3:
        raise ValueError(f"steps must be an integer >= 3, got {steps!r}")
    if distances is None:
        distances = defaults.PHI_GRID_DISTANCES
    check_choice(distances, PHI_GRID_DISTANCES, "distances")
    subset = even_subsample(len(candidates.points), n_points)
    sides = [candidates.local_points[k][subset] for k in range(len(candidates.local_points))]
    local_sub = [sides[k] for k in candidates.side]  # one array per side, shared
    # "exact": exact wherever the ranking, the pruning and the screening's starts read
    # it, the same as grid_errors there; "fields": estimates where the fields hold.
    # refine_phis completes (exactly) the rows it reads.
    grid_of = field_grid_errors if distances == "fields" else bounded_grid_errors
    grid = grid_of(
        model,
        candidates.origins,
        local_sub,
        steps,
        prune_ratio=max(prune_ratio, 1.0),
        refine_ratio=1.0,
        ranked=ranked,
    )
    errors = grid.errors
    best = errors.min(axis=1)
    order = np.argsort(best, kind="stable")
    settled = order[grid.settled[order]]
    order = settled[best[settled] <= prune_ratio * best[settled[0]]]
    bounded = np.flatnonzero(~grid.settled)
    bounded = bounded[np.argsort(best[bounded], kind="stable")]
    order = np.concatenate([order, bounded[best[bounded] <= prune_ratio * best[settled[0]]]])
    return PhiBrackets(
        subset=subset,
        grid=np.arange(steps) * (2.0 * np.pi / steps),
        errors=errors,
        order=order,
        exact=grid.exact,
        estimated=grid.estimated,
    )


def refine_phis(
    model,
    candidates: ContactCandidates,
    brackets: PhiBrackets,
    indices: Sequence[int],
    *,
    complete: bool = True,
) -> tuple[PhiSearch, ...]:
    """Refine every bracket of the given candidates (stage 4, before their local search).

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
    brackets : PhiBrackets
        From :func:`phi_brackets` on the same candidates.
    indices : sequence of int
        The candidates whose brackets to refine.
    complete : bool
        Give every ``PhiSearch.grid_errors`` of a bounded row exact (for pictures and
        traces). False: exact only where the refinement reads it (within
        ``defaults.PHI_REFINE_RATIO`` of the best), a lower bound elsewhere; the refined
        angles are the same. A row of height-field estimates is given as the search used
        it either way (its refined minima are exact).

    Returns
    -------
    tuple of PhiSearch
        One per index, in order (see :func:`meshrec.registration.phi.search_phi`); all
        their brackets are refined in lockstep (:func:`meshrec.registration.phi.search_phis`).

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``candidates`` not a ContactCandidates,
        ``brackets`` not a PhiBrackets, or an index not an integer.
    ValueError
        If ``brackets`` does not belong to ``candidates`` (another count) or an index is
        out of range.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    check_instance(brackets, PhiBrackets, "brackets")
    c = len(candidates)
    if brackets.errors.shape[0] != c:
        raise ValueError(
            f"brackets must be of these {c} candidates, got {brackets.errors.shape[0]}"
        )
    chosen, local_subs, rows, estimated = [], [], [], []
    for k, i in enumerate(indices):
        i = check_int(i, f"indices[{k}]")
        if not 0 <= i < c:
            raise ValueError(f"indices must be in 0..{c - 1}, got {i!r}")
        local_sub = candidates.local_points[candidates.side[i]][brackets.subset]
        chosen.append(i)
        local_subs.append(local_sub)
        guess = brackets.estimated is not None and bool(brackets.estimated[i])
        estimated.append(~brackets.exact[i] if guess else np.zeros(len(brackets.grid), bool))
        # An estimated row is searched as it is (its brackets' values are computed
        # exactly by search_phis); a bounded one is completed where the search reads it.
        rows.append(
            brackets.errors[i]
            if guess
            else _exact_row(model, candidates.origins[i], local_sub, brackets, i, complete)
        )
    if not chosen:
        return ()
    origins = [candidates.origins[i] for i in chosen]

    def errors(which, phis):
        # Each candidate's points placed as phi_error places them, all of them in one
        # distance query (tests/test_bounded.py: the same bits as one angle at a time).
        placed = np.empty((len(which), len(brackets.subset), 3))
        for j in np.unique(which):
            at = which == j
            placed[at] = _placed_at(origins[j], local_subs[j], phis[at])
        return mean_distances(model, placed)

    return search_phis(errors, np.stack(rows), estimated=np.stack(estimated))


def _exact_row(
    model, origin, local_sub, brackets: PhiBrackets, i: int, complete: bool
) -> np.ndarray:
    """Candidate ``i``'s sampled errors, exact wherever :func:`search_phi` reads them.

    The samples within ``defaults.PHI_REFINE_RATIO`` of the row's (exact) best are
    completed (all of them with ``complete``); the others are lower bounds above that
    threshold, where ``search_phi`` neither refines a bracket nor finds a neighbour below
    one.
    """
    row = brackets.errors[i]
    if brackets.exact is None or brackets.exact[i].all():
        return row
    known = brackets.exact[i]
    best = row[known].min(initial=np.inf)
    if complete or row[~known].min() < best:  # (the best itself only bounded)
        todo = np.flatnonzero(~known)
    else:
        todo = np.flatnonzero(~known & (row <= defaults.PHI_REFINE_RATIO * best))
    if len(todo) == 0:
        return row
    row = row.copy()
    row[todo] = exact_samples(model, origin, local_sub, len(brackets.grid), todo)
    return row
