"""The phi grid of stage 2 from local height-fields: estimates where a field holds, exact
(by bounds) elsewhere.

The phi grid ranks the candidates and gives each a starting angle; the later stages
(screening, phi refinement, local searches, refinements) use exact distances. So the grid
need not be exact, only good enough to rank the candidates and find each one's basins.
Near a candidate a smooth surface is the graph of a function over its tangent plane: a
degree-``defaults.FIELD_DEGREE`` polynomial fitted by least squares to the heights and
slopes of the nearest ``defaults.FIELD_NEIGHBOURS`` sites (thinned to the curves' reach,
:func:`meshrec.model.neighbours.site_neighbours`;
:func:`meshrec.model.heightfield.fit_heightfields`). The data's distance to it at every
angle is one matrix product for all the candidates of a side
(:func:`meshrec.model.heightfield.heightfield_distances`), in place of about 1,300
closest-point queries per candidate.

A field is not trusted, and its candidate's row is computed exactly by
:func:`meshrec.registration.bounded.bounded_grid_errors` (the same bits as before), where
the surface may not be one graph over the reach: a crease site among the neighbours
(edges), neighbours within 60 degrees of the candidate's normal (those the fit uses)
that do not reach ``defaults.FIELD_MIN_COVER`` of it or sit to one side (a rim of an open
surface, a fold), a fit whose height residual exceeds
``defaults.FIELD_MAX_RESIDUAL`` of the reach (folds, high curvature), and any model seen
through a ball-tipped probe (its distances are to the offset surface).

Where a field holds, its row is checked where the later stages read it: the row's local
minima within ``defaults.FIELD_VERIFY_RATIO`` of its least estimate, and their
neighbours, are computed exactly and the other samples scaled to them, so that the
ranking, the pruning and the screening's starts read exact values; rows estimated far
above the pruning threshold (``defaults.FIELD_PRUNE_MARGIN``) are not checked.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_instance, check_number
from meshrec.model.heightfield import fit_heightfields, heightfield_distances, monomials
from meshrec.model.index import ModelIndex
from meshrec.model.neighbours import site_neighbours
from meshrec.model.probe import probe_radius_of
from meshrec.registration.bounded import BoundedGrid, bounded_grid_errors
from meshrec.registration.chart import SurfacePoint, rotation_z
from meshrec.registration.objective import mean_distances

__all__ = ["CandidateFields", "candidate_fields", "field_grid_errors"]


@dataclass(frozen=True, eq=False)
class CandidateFields(ValueEquality):
    """Local height-fields at candidate contacts, in each candidate's frame.

    Attributes
    ----------
    coefficients : (c, m) float64
        Each field's polynomial (see :func:`meshrec.model.heightfield.fit_heightfields`).
    radius : float
        The fields' reach, model units.
    reliable : (c,) bool
        The fields that may stand in for the surface (see the module's notes).
    residual : (c,) float64
        Each fit's RMS height residual over the neighbours it used, model units.
    """

    coefficients: np.ndarray = field(repr=False)
    radius: float
    reliable: np.ndarray = field(repr=False)
    residual: np.ndarray = field(repr=False)

    def __repr__(self) -> str:
        return (
            f"CandidateFields(candidates={len(self.reliable)}, "
            f"reliable={int(self.reliable.sum())}, radius={self.radius:.6g})"
        )


def candidate_fields(model, origins: Sequence[SurfacePoint], reach: float) -> CandidateFields:
    """Fit a height-field at every candidate and judge whether it holds over ``reach``.

    Parameters
    ----------
    model : ModelIndex
    origins : sequence of SurfacePoint
        The candidates' points and frames (columns: two tangents and the normal).
    reach : float
        The data's largest distance from the contact across the normal (> 0); the fields
        reach ``defaults.FIELD_REACH`` times it.

    Returns
    -------
    CandidateFields

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex or ``reach`` not a real number.
    ValueError
        If ``origins`` is empty or ``reach`` is not positive and finite.
    """
    check_instance(model, ModelIndex, "model")
    reach = check_number(reach, "reach", positive=True)
    if len(origins) == 0:
        raise ValueError("origins must hold at least one candidate, got none")
    table = model.curvature
    radius = defaults.FIELD_REACH * reach
    centers = np.array([o.point for o in origins], dtype=np.float64).reshape(-1, 3)
    frames = np.array([o.frame for o in origins], dtype=np.float64).reshape(-1, 3, 3)
    nb = site_neighbours(table, centers, radius, defaults.FIELD_NEIGHBOURS)
    points = np.asarray(table.points)[nb.indices]
    normals = np.asarray(table.normals)[nb.indices]
    degree = defaults.FIELD_DEGREE
    coef = fit_heightfields(
        centers,
        frames,
        points,
        normals,
        radius,
        degree=degree,
        slope_weight=defaults.FIELD_SLOPE_WEIGHT,
    )
    local = np.einsum("ckj,cji->cki", points - centers[:, None, :], frames)
    used = np.einsum("ckj,cj->ck", normals, frames[:, :, 2]) > 0.5  # as fit_heightfields
    gaps = local[..., 2] / radius - np.einsum(
        "ckm,cm->ck", monomials(local[..., :2] / radius, degree), coef
    )
    residual = radius * np.sqrt(
        np.where(used, gaps * gaps, 0.0).sum(axis=1) / np.maximum(used.sum(axis=1), 1)
    )
    # Over the neighbours the fit used: the sites of a fold or of the far side of a thin
    # part do not cover the reach.
    farthest = np.where(used, nb.distances, 0.0).max(axis=1)
    count = np.maximum(used.sum(axis=1), 1)[:, None]
    offcentre = np.linalg.norm(
        np.where(used[..., None], local[..., :2], 0.0).sum(axis=1) / count, axis=1
    )
    reliable = (
        ~np.asarray(table.crease)[nb.indices].any(axis=1)
        & (farthest >= defaults.FIELD_MIN_COVER * radius)
        & (offcentre <= defaults.FIELD_MAX_OFFCENTRE * farthest)
        & (residual <= defaults.FIELD_MAX_RESIDUAL * radius)
        & (probe_radius_of(model) == 0.0)
    )
    return CandidateFields(coefficients=coef, radius=radius, reliable=reliable, residual=residual)


def field_grid_errors(
    model,
    origins: Sequence[SurfacePoint],
    local_points: Sequence[np.ndarray],
    steps: int,
    *,
    prune_ratio: float,
    refine_ratio: float,
    ranked: int | None,
) -> BoundedGrid:
    """The phi grid: height-field estimates where the fields hold, exact by bounds elsewhere.

    Parameters
    ----------
    model : ModelIndex
    origins : sequence of SurfacePoint
        The candidates' points and frames on the model (``c`` of them).
    local_points : sequence of (n, 3) float
        Each candidate's data points in its side's frame (candidates of one side share
        one array).
    steps : int
        Angles ``2 pi i / steps``.
    prune_ratio, refine_ratio, ranked
        As for :func:`meshrec.registration.bounded.bounded_grid_errors`, which computes
        the rows of the candidates whose fields are not reliable.

    Returns
    -------
    BoundedGrid
        ``estimated`` marks the rows from the fields. Those whose least estimate is
        within ``defaults.FIELD_PRUNE_MARGIN`` times the pruning threshold are
        ``settled``: their low minima and those minima's neighbours are exact (``exact``),
        the least of them the row's least sample, and the rest are estimates scaled to
        them. The others are unsettled estimates, ranked after the settled rows.
        ``evaluated`` counts the exact point distances.

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex.
    ValueError
        If ``origins`` is empty or ``local_points`` does not hold one (n, 3) array per
        origin.
    """
    check_instance(model, ModelIndex, "model")
    c = len(origins)
    if c == 0:
        raise ValueError("origins must hold at least one candidate, got none")
    if len(local_points) != c:
        raise ValueError(f"local_points must hold {c} arrays, got {len(local_points)}")
    groups: dict[int, list[int]] = {}
    for i, lp in enumerate(local_points):
        groups.setdefault(id(lp), []).append(i)
    arrays = {
        key: np.asarray(local_points[rows[0]], dtype=np.float64) for key, rows in groups.items()
    }
    for lp in arrays.values():
        if lp.ndim != 2 or lp.shape[1] != 3 or len(lp) == 0:
            raise ValueError(f"local_points must be (n, 3) arrays, got shape {lp.shape}")
    reach = max(float(np.sqrt((lp[:, :2] ** 2).sum(axis=1)).max()) for lp in arrays.values())
    errors = np.zeros((c, steps))
    exact = np.zeros((c, steps), dtype=bool)
    settled = np.ones(c, dtype=bool)
    evaluated = 0
    # Through a ball tip no field holds (candidate_fields says so too): no fit at all.
    usable = reach > 0 and probe_radius_of(model) == 0.0
    fields = candidate_fields(model, origins, reach) if usable else None
    reliable = fields.reliable if fields is not None else np.zeros(c, dtype=bool)
    Rz = rotation_z(np.arange(steps) * (2.0 * np.pi / steps))  # (s, 3, 3)
    frames = np.array([o.frame for o in origins], dtype=np.float64).reshape(-1, 3, 3)
    centres = np.array([o.point for o in origins], dtype=np.float64).reshape(-1, 3)

    for key, rows in groups.items():
        rows = np.asarray(rows, dtype=np.int64)
        good = rows[reliable[rows]]
        if len(good) == 0:
            continue
        lp = arrays[key]
        placed = np.einsum("sij,nj->sni", Rz, lp).reshape(-1, 3)  # every angle, field frame
        dist = heightfield_distances(
            fields.coefficients[good], placed, fields.radius, degree=defaults.FIELD_DEGREE
        )  # (s n, g)
        errors[good] = dist.reshape(steps, len(lp), len(good)).mean(axis=1).T
    rest = np.flatnonzero(~reliable)
    least = np.inf
    if len(rest):
        sub = bounded_grid_errors(
            model,
            [origins[i] for i in rest],
            [local_points[i] for i in rest],
            steps,
            prune_ratio=prune_ratio,
            refine_ratio=refine_ratio,
            ranked=ranked,
        )
        errors[rest], exact[rest], settled[rest] = sub.errors, sub.exact, sub.settled
        evaluated = sub.evaluated
        if sub.settled.any():
            least = float(sub.errors[sub.settled].min())
    # Rows estimated far above the least error (by a margin for the estimates' own
    # error) are left as estimates, unsettled (ranked after the settled rows, as bounded
    # rows are); the others have their low minima computed exactly. The least error is
    # an exact one (the least estimates can be far below theirs): the rows of the least
    # estimates are verified first.
    good = np.flatnonzero(reliable)
    if len(good):
        est_best = errors[good].min(axis=1)
        first = good[np.argsort(est_best, kind="stable")[: defaults.FIELD_VERIFY_FIRST]]
        _verify(model, errors, exact, first, groups, arrays, frames, centres, Rz)
        least = min(least, float(errors[first].min()))
        near = good[est_best <= defaults.FIELD_PRUNE_MARGIN * prune_ratio * least]
        near = np.setdiff1d(near, first)
        _verify(model, errors, exact, near, groups, arrays, frames, centres, Rz)
        settled[good] = False
        settled[first] = True
        settled[near] = True
        evaluated += int(exact[good].sum()) * len(next(iter(arrays.values())))
    return BoundedGrid(
        errors=errors, exact=exact, settled=settled, evaluated=evaluated, estimated=reliable.copy()
    )


def _verify(model, errors, exact, rows, groups, arrays, frames, centres, Rz) -> None:
    """:func:`_verified` on ``rows`` of ``errors`` and ``exact``, in place, per side."""
    for key, members in groups.items():
        sel = np.intersect1d(np.asarray(members, dtype=np.int64), rows)
        if len(sel):
            errors[sel], exact[sel] = _verified(
                model, errors[sel], arrays[key], frames[sel], centres[sel], Rz
            )


def _verified(model, est, local, frames, centres, Rz):
    """Estimated rows with their low local minima and those minima's neighbours computed
    exactly; the other samples scaled by the exact-to-estimated ratio at the best of them
    and kept above it, so that each row's least sample is exact and is where the
    screening starts, as on the exact path."""
    best = est.min(axis=1, keepdims=True)
    low = (
        (est <= np.roll(est, 1, axis=1))
        & (est <= np.roll(est, -1, axis=1))
        & (est <= defaults.FIELD_VERIFY_RATIO * best)
    )
    verify = low | np.roll(low, 1, axis=1) | np.roll(low, -1, axis=1)
    rows, cols = np.nonzero(verify)
    R = np.einsum("kij,kjl->kil", frames[rows], Rz[cols])
    pts = np.einsum("kij,nj->kni", R, local) + centres[rows][:, None, :]
    out = est.copy()
    out[rows, cols] = mean_distances(model, pts)
    masked = np.where(verify, out, np.inf)
    at = np.argmin(masked, axis=1)
    g = np.arange(len(est))
    floor = masked[g, at]
    ratio = np.where(est[g, at] > 0.0, floor / np.where(est[g, at] > 0.0, est[g, at], 1.0), 1.0)
    # Strictly above the floor: a row's least sample (the screening's start) is exact.
    scaled = np.maximum(est * ratio[:, None], np.nextafter(floor, np.inf)[:, None])
    return np.where(verify, out, scaled), verify
