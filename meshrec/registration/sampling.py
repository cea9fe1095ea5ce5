"""Even subsamples of the data points, for the stages that work on fewer of them."""

from __future__ import annotations

import numpy as np

__all__ = ["even_subsample"]


def even_subsample(n: int, k: int) -> np.ndarray:
    """Indices of ``k`` points spread evenly over ``n`` (all of them when ``n <= k``).

    Parameters
    ----------
    n : int
        Number of points.
    k : int
        Number wanted.

    Returns
    -------
    (m,) int
        Sorted distinct indices in ``0..n-1``; ``m = min(n, k)`` (fewer only if rounding
        merges two, which it cannot for ``k <= n``).

    Raises
    ------
    ValueError
        If ``n`` is negative or ``k`` is not positive.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n!r}")
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k!r}")
    if n <= k:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))
