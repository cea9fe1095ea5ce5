"""A model's curvature sites near given points, thinned so that about ``k`` cover a reach.

A local fit around a point of the surface (a height-field over the touch curves' reach,
:mod:`meshrec.registration.fields`) needs about ``k`` oriented samples spread over that
reach, whatever the model's site density. The sites are thinned by a seeded rank, the
same on every run and independent of any other model (seeded by
``defaults.SCREEN_SEED`` and the site count, as the library-wide screen thins them): at
level ``L`` the sites of rank below ``2^-L`` are kept, the level chosen from how many
sites lie within the reach of the first points. The ``k`` nearest kept sites of every
point are one query of a KD-tree (scipy's ``cKDTree``), built once per level on first use
and kept with the table (not pickled: ``CurvatureTable`` pickles its fields only).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.io.checks import check_instance, check_int, check_number
from meshrec.model.curvature import CurvatureTable

__all__ = ["SiteNeighbours", "site_neighbours", "site_ranks"]

_LOCK = threading.Lock()
#: Points whose site counts within the reach choose the thinning level (evenly spread).
_COUNT_POINTS = 8


@dataclass(frozen=True)
class SiteNeighbours:
    """The nearest thinned sites of some points.

    Attributes
    ----------
    indices : (c, k) int64
        Sites (indices into the table), nearest first.
    distances : (c, k) float64
        Their distances from each point, model units.
    level : int
        The thinning level: the sites of rank below ``2^-level`` were searched.
    """

    indices: np.ndarray = field(repr=False)
    distances: np.ndarray = field(repr=False)
    level: int

    def __repr__(self) -> str:
        c, k = self.indices.shape
        return f"SiteNeighbours(points={c}, k={k}, level={self.level})"


def site_neighbours(
    table: CurvatureTable, points: np.ndarray, radius: float, k: int
) -> SiteNeighbours:
    """The ``k`` nearest sites of each point among the sites thinned to about ``k`` per
    disc of ``radius``.

    Parameters
    ----------
    table : CurvatureTable
        The model's sites.
    points : (c, 3) float
        Model coordinates (at least one).
    radius : float
        The reach the neighbours should cover (> 0).
    k : int
        Neighbours per point (at least 1; at most the table's site count are returned).

    Returns
    -------
    SiteNeighbours
        With ``min(k, n)`` neighbours per point for ``n`` sites kept at the chosen level
        (the level is lowered until at least ``k`` sites are kept).

    Raises
    ------
    TypeError
        If ``table`` is not a CurvatureTable, ``radius`` not a real number or ``k`` not
        an integer.
    ValueError
        If ``points`` is not (c, 3) with c >= 1 or not finite, ``radius`` is not positive
        and finite, or ``k`` is below 1.
    """
    check_instance(table, CurvatureTable, "table")
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise ValueError(f"points must be (c, 3) with c >= 1, got shape {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError("points must be finite")
    radius = check_number(radius, "radius", positive=True)
    k = check_int(k, "k", minimum=1)
    n = len(table.points)
    pick = np.unique(np.linspace(0, len(points) - 1, min(_COUNT_POINTS, len(points))).round())
    counts = _tree(table, 0)[1].query_ball_point(
        points[pick.astype(np.int64)], radius, return_length=True
    )
    # About k within the reach after thinning (defaults.FIELD_FILL of them on average).
    per_disc = max(float(np.median(counts)), 1.0)
    level = max(0, round(math.log2(per_disc / (defaults.FIELD_FILL * k)))) if per_disc > k else 0
    keep, tree = _tree(table, level)
    while len(keep) < min(k, n) and level > 0:
        level -= 1
        keep, tree = _tree(table, level)
    kk = min(k, len(keep))
    dist, nb = tree.query(points, k=kk)
    dist = np.asarray(dist, dtype=np.float64).reshape(len(points), kk)
    nb = np.asarray(nb, dtype=np.int64).reshape(len(points), kk)
    return SiteNeighbours(indices=keep[nb], distances=dist, level=level)


def site_ranks(n: int) -> np.ndarray:
    """A seeded uniform number per site of a table of ``n`` sites: the sites of rank below
    ``f`` are an even random fraction ``f`` of them.

    Seeded by ``defaults.SCREEN_SEED`` and ``n`` only, so a model's ranks do not depend on
    its place in a library (the library-wide screen thins its sites by them as well).

    Parameters
    ----------
    n : int
        The table's site count (>= 0).

    Returns
    -------
    (n,) float64
        In [0, 1).

    Raises
    ------
    TypeError
        If ``n`` is not an integer.
    ValueError
        If ``n`` is negative.
    """
    n = check_int(n, "n", minimum=0)
    return np.random.default_rng([defaults.SCREEN_SEED, n]).random(n)


def _tree(table: CurvatureTable, level: int) -> tuple[np.ndarray, cKDTree]:
    """The sites kept at ``level`` and their KD-tree, built on first use."""
    cache = table.__dict__.get("_neighbour_trees")
    if cache is None or level not in cache:
        with _LOCK:
            cache = table.__dict__.setdefault("_neighbour_trees", {})
            if level not in cache:
                n = len(table.points)
                if level == 0:
                    keep = np.arange(n, dtype=np.int64)
                else:
                    keep = np.flatnonzero(site_ranks(n) < 2.0**-level).astype(np.int64)
                cache[level] = (keep, cKDTree(np.asarray(table.points)[keep]))
    return cache[level]
