"""The phi grid of stage 2 by bounds: exact where it can matter, a lower bound elsewhere.

Every candidate's error is sampled at ``steps`` angles on ``n`` data points (stage 2,
:mod:`meshrec.registration.brackets`). The later stages read few of those samples: a
candidate whose best sample exceeds ``prune_ratio`` times the least one is dropped; a kept
candidate's screening starts from its best sample; its phi refinement looks only at the
local minima within ``refine_ratio`` of its best and their two neighbours. A sample far
above those thresholds is not needed exactly, only known to be above them.

The error is a mean of non-negative distances, so the sum over some of the points,
divided by ``n``, is a lower bound of it. The points are evaluated in rounds, those
farthest from the contact first (they swing furthest with phi: the largest distances at
a wrong angle, the tightest bound); after each round a sample is dropped once its bound
exceeds ``refine_ratio`` times its candidate's least exact error so far, or its
candidate's least bound exceeds ``prune_ratio`` times the least exact error of all. The
thresholds only fall and the bounds only rise, so a dropped sample would still be dropped
at the end, and every sample that the later stages read is exact: the same bits as
:func:`meshrec.registration.brackets.grid_errors` (each point's distance is its own, and
the mean of a complete sample is taken as there), so the registrations are the same.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.registration.chart import SurfacePoint, rotation_z
from meshrec.registration.objective import point_distances

__all__ = ["BoundedGrid", "bounded_grid_errors", "exact_samples", "placed_grid"]


@dataclass(frozen=True, eq=False)
class BoundedGrid(ValueEquality):
    """The sampled error against phi: exact where needed, a lower bound elsewhere.

    Attributes
    ----------
    errors : (c, s) float
        Mean point-to-surface distance where ``exact``, else a lower bound of it (the
        distances summed over the points evaluated, divided by all ``n``).
    exact : (c, s) bool
        Which samples are exact.
    settled : (c,) bool
        The candidates whose least sample is exact (its row minimum is its best error);
        the others are either more than ``prune_ratio`` times the least error or behind
        at least ``ranked`` candidates of less error.
    evaluated : int
        Point distances computed (``c * s * n`` for the whole grid).
    estimated : (c,) bool or None
        The rows that are height-field estimates, not bounds
        (:func:`meshrec.registration.fields.field_grid_errors`); None: none.
    """

    errors: np.ndarray = field(repr=False)
    exact: np.ndarray = field(repr=False)
    settled: np.ndarray = field(repr=False)
    evaluated: int
    estimated: np.ndarray | None = field(default=None, repr=False)


def placed_grid(
    origins: Sequence[SurfacePoint], local_points: Sequence[np.ndarray], steps: int
) -> np.ndarray:
    """The data points placed at every candidate and sampled phi.

    Parameters
    ----------
    origins : sequence of SurfacePoint
        The candidates' points and frames on the model (``c`` of them).
    local_points : sequence of (n, 3) float
        Each candidate's data points in its side's frame.
    steps : int
        Angles ``2 pi i / steps``.

    Returns
    -------
    (c, steps, n, 3) float
        Model coordinates: the data rotated by phi about the candidate's normal, their
        contact on the candidate.
    """
    Rz = rotation_z(np.arange(steps) * (2.0 * np.pi / steps))  # (s, 3, 3)
    frames = np.array([o.frame for o in origins]).reshape(-1, 3, 3)  # (c, 3, 3)
    R = np.einsum("cij,sjk->csik", frames, Rz)  # (c, s, 3, 3)
    pts = np.array(local_points, dtype=np.float64).reshape(len(frames), -1, 3)
    placed = np.einsum("csij,cnj->csni", R, pts)
    placed += np.array([o.point for o in origins]).reshape(-1, 3)[:, None, None, :]
    return placed


def exact_samples(
    model, origin: SurfacePoint, local_points: np.ndarray, steps: int, which: np.ndarray
) -> np.ndarray:
    """The exact error of one candidate at some of the sampled phi.

    Parameters
    ----------
    model : ModelIndex
    origin : SurfacePoint
        The candidate's point and frame on the model.
    local_points : (n, 3) float
        The data points in its side's frame.
    steps : int
        Angles ``2 pi i / steps``.
    which : (k,) int
        The angles' indices.

    Returns
    -------
    (k,) float
        Mean point-to-surface distance at each: the same bits as
        :func:`meshrec.registration.brackets.grid_errors`.
    """
    placed = placed_grid([origin], [local_points], steps)[0, np.asarray(which, dtype=np.int64)]
    k, n, _ = placed.shape
    return point_distances(model, placed.reshape(-1, 3)).reshape(k, n).mean(axis=1)


def _check_rounds(rounds) -> tuple[int, ...]:
    try:
        values = tuple(int(r) for r in rounds)
    except (TypeError, ValueError):
        raise ValueError(
            f"rounds must be a sequence of positive integers, got {rounds!r}"
        ) from None
    if any(v != r for v, r in zip(values, rounds, strict=True)) or any(v < 1 for v in values):
        raise ValueError(f"rounds must be a sequence of positive integers, got {rounds!r}")
    if any(b <= a for a, b in itertools.pairwise(values)):
        raise ValueError(f"rounds must be increasing, got {rounds!r}")
    return values


def bounded_grid_errors(
    model,
    origins: Sequence[SurfacePoint],
    local_points: Sequence[np.ndarray],
    steps: int,
    *,
    prune_ratio: float = defaults.SEARCH_PRUNE_RATIO,
    refine_ratio: float = defaults.PHI_REFINE_RATIO,
    ranked: int | None = None,
    rounds: Sequence[int] = defaults.PHI_BOUND_ROUNDS,
) -> BoundedGrid:
    """The error at ``steps`` equally spaced phi for every candidate, exact where needed.

    Parameters
    ----------
    model : ModelIndex
    origins : sequence of SurfacePoint
        The candidates' points and frames on the model (``c`` of them, at least one).
    local_points : sequence of (n, 3) float
        Each candidate's data points in its side's frame (the same ``n`` for all).
    steps : int
        Angles sampled over [0, 2 pi).
    prune_ratio : float
        Candidates whose best sample exceeds this factor times the least one need no
        exact sample (stage 2 drops them); at least 1.
    refine_ratio : float
        Within a kept candidate, samples above this factor times its best need no exact
        value (no later stage reads them); at least 1.
    ranked : int, optional
        Only the best ``ranked`` candidates need their best exactly (the screening's
        limit): a candidate behind at least ``ranked`` others of less exact error is left
        with bounds. None: every candidate within ``prune_ratio``.
    rounds : sequence of int
        Points evaluated (cumulative, farthest from the contact first) before each
        check; the remaining points follow in a last round.

    Returns
    -------
    BoundedGrid
        ``errors`` equal to :func:`meshrec.registration.brackets.grid_errors` wherever
        ``exact``, at most it elsewhere; exact at every candidate's best sample and, for
        every candidate within ``prune_ratio`` of the least, at every sample within
        ``refine_ratio`` of its best; for ``ranked``, only the candidates among the
        best ``ranked`` (ties by index) are sure to be settled.

    Raises
    ------
    ValueError
        If there are no candidates, the point sets differ in shape, a ratio is below 1,
        ``ranked`` is not a positive integer, or ``rounds`` is not an increasing sequence
        of positive integers.
    """
    if len(origins) == 0 or len(origins) != len(local_points):
        raise ValueError(
            f"origins and local_points must be as many and at least one, got "
            f"{len(origins)} and {len(local_points)}"
        )
    for name, ratio in (("prune_ratio", prune_ratio), ("refine_ratio", refine_ratio)):
        if not ratio >= 1.0:
            raise ValueError(f"{name} must be >= 1, got {ratio!r}")
    if ranked is not None and (
        not isinstance(ranked, (int, np.integer)) or isinstance(ranked, bool) or ranked < 1
    ):
        raise ValueError(f"ranked must be a positive integer or None, got {ranked!r}")
    cuts = _check_rounds(rounds)
    pts = np.array(local_points, dtype=np.float64)  # (c, n, 3)
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise ValueError(f"local_points must all be (n, 3), got {pts.shape}")
    c, n, _ = pts.shape
    placed = placed_grid(origins, pts, steps)
    s = placed.shape[1]
    # Farthest from the contact first, per candidate (the two sides' frames differ).
    far = np.argsort(-np.linalg.norm(pts, axis=2), axis=1, kind="stable")  # (c, n)
    dist = np.zeros((c, s, n))
    filled = np.zeros(c * s, dtype=np.int64)  # points evaluated per sample, in `far` order
    evaluated = 0

    def evaluate(rows: np.ndarray, upto: int) -> None:
        """Evaluate samples ``rows`` (flat c*s indices) up to ``upto`` points."""
        nonlocal evaluated
        if len(rows) == 0:
            return
        ci, si = np.divmod(rows, s)
        start = filled[rows]
        counts = upto - start
        # Each sample's points from its `start` to `upto`, flattened.
        rep = np.repeat(np.arange(len(rows)), counts)
        offs = np.arange(len(rep)) - np.repeat(np.cumsum(counts) - counts, counts)
        pk = far[ci[rep], start[rep] + offs]
        d = point_distances(model, placed[ci[rep], si[rep], pk])
        dist[ci[rep], si[rep], pk] = d
        filled[rows] = upto
        evaluated += len(rep)

    everything = np.arange(c * s)
    evaluate(everything, min(cuts[0], n))
    # Each candidate's sample of least bound, completed: an upper bound of its best.
    first = dist.sum(axis=2).argmin(axis=1)
    evaluate(np.arange(c) * s + first, n)

    def needs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The exact samples, the candidates still needed, and each one's threshold."""
        exact = (filled == n).reshape(c, s)
        bound = dist.sum(axis=2) / n
        upper = np.where(exact, bound, np.inf).min(axis=1)  # (c,): at least the best
        least = bound.min(axis=1)  # (c,): at most the best
        needed = least <= prune_ratio * upper.min()
        if ranked is not None and c > ranked:
            # Behind `ranked` candidates whose error is surely less: not screened.
            ahead = np.searchsorted(np.sort(upper), least, side="left")
            needed &= ahead < ranked
        return exact, needed, bound <= refine_ratio * upper[:, None]

    for upto in (*[k for k in cuts[1:] if k < n], n):
        exact, needed, low = needs()
        evaluate(np.flatnonzero((~exact & needed[:, None] & low).ravel()), upto)
    # The thresholds only fell and the bounds only rose: the candidates still needed are
    # exactly those that were needed at every round, their low samples all complete.
    exact, needed, _ = needs()
    errors = dist.sum(axis=2) / n
    # The exact samples as grid_errors takes them (the mean over the points in order).
    errors[exact] = dist[exact].mean(axis=1)
    return BoundedGrid(errors=errors, exact=exact, settled=needed, evaluated=evaluated)
