"""Joint pose seeds from pairs of touches: two oriented contacts fix a rigid pose.

A short, noisy touch alone often fits a model at many places equally well (on look-alike
shapes every candidate contact does), so none of its own pose hypotheses need be the one
that fits every touch, and refining them jointly slides into the wrong basins. Two
touches together are far more selective: their contact points ``p_a, p_b`` and normals
``n_a, n_b`` (touch frame) must land on model points ``x_i, x_j`` whose (K, H) match each
touch, whose distance is ``|p_b - p_a|`` and whose normals make the same angles with each
other and with the baseline (the point-pair feature of Drost et al. 2010, "Model globally,
match locally"). Every such model pair gives a whole rigid pose; the poses that fit a few
points of every touch best seed the joint refinement
(:func:`meshrec.recognition.joint.joint_poses`).

The model points are the (K, H) lookup's hits spread over the surface
(:func:`meshrec.registration.candidates.find_candidates`, up to
``defaults.PAIR_CANDIDATES`` per touch and side), so a model pair is within about the
spread's covering radius of the true pair; the distance and angle tests allow for it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.registration.candidates import curvature_tolerance, spread_points
from meshrec.registration.lookup import surface_sides
from meshrec.registration.objective import residuals

__all__ = ["pair_seeds"]


def pair_seeds(
    touches: Sequence[TouchData],
    model,
    geometries: Sequence[LocalGeometry],
    *,
    lookup_scale: float = 1.0,
    keep: int = defaults.PAIR_KEEP,
) -> list[np.ndarray]:
    """Poses ``T_model_touch`` from pairs of touches matched to pairs of model points.

    Parameters
    ----------
    touches : sequence of TouchData
        Two or more touches of one object, in one frame.
    model : ModelIndex
    geometries : sequence of LocalGeometry
        The local geometry of each touch.
    lookup_scale : float
        Factor widening the (K, H) lookup window.
    keep : int
        Most poses returned: those with the least RMS distance of an even subsample of
        every touch's points (``defaults.PAIR_SCORE_POINTS`` per touch).

    Returns
    -------
    list of (4, 4) float
        Least subsample RMS first; empty when no pair of model points matches.

    Raises
    ------
    ValueError
        If fewer than two touches are given, ``geometries`` does not match ``touches``
        or ``keep`` is not a positive integer.
    """
    if len(touches) < 2:
        raise ValueError(f"touches must hold at least two touches, got {len(touches)}")
    if len(geometries) != len(touches):
        raise ValueError(
            f"geometries must hold one LocalGeometry per touch ({len(touches)}), got "
            f"{len(geometries)}"
        )
    if not isinstance(keep, (int, np.integer)) or isinstance(keep, bool) or keep < 1:
        raise ValueError(f"keep must be a positive integer, got {keep!r}")
    points = [g.point for g in geometries]
    spread: dict[int, list[_Side]] = {}

    def matches(k: int) -> bool:
        """Whether touch ``k``'s (K, H) matches some of the model's points (spread once,
        when first needed)."""
        if k not in spread:
            spread[k] = [
                _spread(model, side, lookup_scale)
                for side in surface_sides(geometries[k], touches[k], model)
            ]
        return any(len(side.x) for side in spread[k])

    # The pairs with the longest baselines pin the rotation best; of the touches whose
    # (K, H) matches some of the model's points (one across an edge may match none: with
    # it in the longest pair, a box's pair search found nothing, a black-box probe at
    # stop 32).
    by_length = sorted(
        itertools.combinations(range(len(touches)), 2),
        key=lambda ab: -float(np.linalg.norm(points[ab[1]] - points[ab[0]])),
    )
    pairs = []
    for a, b in by_length:
        if len(pairs) == defaults.PAIR_MAX_PAIRS:
            break
        if matches(a) and matches(b):
            pairs.append((a, b))
    T = np.concatenate(
        [np.zeros((0, 4, 4))]
        + [
            _pair_poses(sa, sb)
            for a, b in pairs
            for sa, sb in itertools.product(spread[a], spread[b])
        ]
    )
    if len(T) == 0:
        return []
    # Screen every pose on a few telling points with the distance to the nearest vertex or
    # curvature site (cheap; off by at most about a site spacing), then score the
    # survivors exactly.
    cap = defaults.PAIR_SCREEN_CAP * max(float(g.half_length) for g in geometries)
    T = _screen(model, touches, geometries, T, cap)
    rms = _subsample_rms(model, touches, T)
    order = np.argsort(rms, kind="stable")[:keep]
    return [T[k] for k in order]


class _Side(NamedTuple):
    """One touch side: its contact and normal, and the model points that may match it."""

    point: np.ndarray  # (3,) touch frame
    normal: np.ndarray  # (3,) touch frame
    x: np.ndarray  # (c, 3) spread model points whose (K, H) match
    m: np.ndarray  # (c, 3) their normals
    gap: float  # covering radius of the spread over all the matching sites
    kappa: float  # largest principal curvature magnitude of the touch side


def _spread(model, side: LocalGeometry, lookup_scale: float) -> _Side:
    """One touch side and its matching model points, spread over the surface."""
    tol_K, tol_H = curvature_tolerance(
        side.k1, side.k2, float(side.half_length), side.fit_rms, curvature_sd=side.curvature_sd
    )
    tol_K, tol_H = tol_K * lookup_scale, tol_H * lookup_scale
    hits = model.curvature.lookup(side.K, side.H, tol_K, tol_H)
    kappa = max(abs(side.k1), abs(side.k2)) + tol_H
    if len(hits) == 0:
        empty = np.zeros((0, 3))
        return _Side(side.point, side.normal, empty, empty, 0.0, kappa)
    table = model.curvature
    x_hits = table.points[hits]
    # Spread (farthest-point sampling) over at most PAIR_SPREAD_POOL of the hits, evenly
    # strided: its cost grows with both counts, and the covering radius below is measured
    # against every hit anyway.
    pool = hits[:: -(-len(hits) // defaults.PAIR_SPREAD_POOL)]
    chosen = pool[
        spread_points(
            table.points[pool],
            defaults.CANDIDATE_SPACING_FRACTION * float(side.half_length),
            defaults.PAIR_CANDIDATES,
        )
    ]
    x = table.points[chosen]
    # How far a matching site (a possible true contact) may lie from the nearest
    # spread point.
    gap = float(cKDTree(x).query(x_hits)[0].max())
    return _Side(side.point, side.normal, x, table.normals[chosen], gap, kappa)


def _pair_poses(a: _Side, b: _Side) -> np.ndarray:
    """(m, 4, 4) poses of every model pair matching one pair of touch sides."""
    d = b.point - a.point
    length = float(np.linalg.norm(d))
    if len(a.x) == 0 or len(b.x) == 0 or length <= 0:
        return np.zeros((0, 4, 4))
    tol = a.gap + b.gap + defaults.PAIR_DISTANCE_TOL * length
    near = cKDTree(b.x).query_ball_point(a.x, length + tol)
    counts = np.array([len(r) for r in near], dtype=np.int64)
    if counts.sum() == 0:
        return np.zeros((0, 4, 4))
    i = np.repeat(np.arange(len(a.x)), counts)
    j = np.concatenate([np.asarray(r, dtype=np.int64) for r in near if len(r)])
    e = b.x[j] - a.x[i]
    e_len = np.linalg.norm(e, axis=1)
    ok = e_len >= max(length - tol, 1e-12 * length)
    i, j, e = i[ok], j[ok], e[ok] / e_len[ok, None]
    # The point-pair feature: the normals' angles with the baseline and with each other.
    # A spread point's normal is off the true contact's by up to its curvature times the
    # gap; the estimated normals add defaults.PAIR_ANGLE_TOL (as cosines).
    d_hat = d / length
    tol_cos = defaults.PAIR_ANGLE_TOL + max(a.gap * a.kappa, b.gap * b.kappa)
    ma, mb = a.m[i], b.m[j]
    ok = (
        (np.abs(np.einsum("ij,ij->i", ma, e) - a.normal @ d_hat) <= tol_cos)
        & (np.abs(np.einsum("ij,ij->i", mb, e) - b.normal @ d_hat) <= tol_cos)
        & (np.abs(np.einsum("ij,ij->i", ma, mb) - a.normal @ b.normal) <= tol_cos)
    )
    i, j, e, ma, mb = i[ok], j[ok], e[ok], ma[ok], mb[ok]
    if len(i) == 0:
        return np.zeros((0, 4, 4))
    # Hand-written rather than scipy's Rotation.align_vectors, which solves one set of
    # vector pairs per call: here there are thousands. Each pair of oriented points gives
    # a frame (the baseline, and the normals' sum or difference across it, whichever the
    # touches define better); the rotation maps the touches' frame onto the model pair's.
    use_sum = (
        _across(d_hat[None], (a.normal + b.normal)[None])[1][0]
        >= _across(d_hat[None], (a.normal - b.normal)[None])[1][0]
    )
    sign = 1.0 if use_sum else -1.0
    # A frame whose second axis is (nearly) along the baseline is undefined: the normals'
    # sum or difference has no part across it (two faces of a box at right angles, the
    # baseline along their bisector). Such pairs are dropped: normalising a vanishing
    # part gave a singular "rotation" that squashed every touch onto a line, fitting any
    # surface to 1e-15 (a black-box probe, stop 32: every kept seed of a box's two
    # touches was such a pose, and the box was left out of `plausible`).
    if _across(d_hat[None], (a.normal + sign * b.normal)[None])[1][0] < _FRAME_MIN:
        return np.zeros((0, 4, 4))
    ok = _across(e, ma + sign * mb)[1] >= _FRAME_MIN
    i, j, e, ma, mb = i[ok], j[ok], e[ok], ma[ok], mb[ok]
    if len(i) == 0:
        return np.zeros((0, 4, 4))
    F_touch = _frame(d_hat[None], (a.normal + sign * b.normal)[None])[0]
    F_model = _frame(e, ma + sign * mb)
    R = F_model @ F_touch.T
    T = np.zeros((len(i), 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = 0.5 * (a.x[i] + b.x[j]) - R @ (0.5 * (a.point + b.point))
    T[:, 3, 3] = 1.0
    return T


def _across(e1: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The part of each row of ``c`` perpendicular to the unit rows ``e1``, and its norm."""
    perp = c - np.einsum("ij,ij->i", c, e1)[:, None] * e1
    return perp, np.linalg.norm(perp, axis=1)


#: Least part of a frame's second vector across its baseline (unit vectors): below it
#: the frame's rotation about the baseline is undefined.
_FRAME_MIN = 1e-6


def _frame(e1: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(m, 3, 3) right-handed frames, columns ``e1``, ``c`` across ``e1``, their cross
    (each ``c`` must have a part across ``e1`` of at least ``_FRAME_MIN``)."""
    perp, norm = _across(e1, c)
    e2 = perp / norm[:, None]
    return np.stack([e1, e2, np.cross(e1, e2)], axis=2)


def _probes(touches, geometries) -> tuple[np.ndarray, np.ndarray]:
    """Telling points: each touch's contact and its two points farthest from it.

    Returns the points (3 per touch) and the index of one far point per touch (the quick
    first screen's points together with the contacts)."""
    probe = []
    for t, g in zip(touches, geometries, strict=True):
        far = np.argsort(np.linalg.norm(t.points - g.point, axis=1))[-2:]
        probe.extend([g.point, *t.points[far]])
    first = np.array([k for k in range(len(probe)) if k % 3 != 2], dtype=np.int64)
    return np.array(probe), first


def _moved(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(m, k, 3): ``points`` (k, 3) mapped by each of the poses ``T`` (m, 4, 4)."""
    # One matrix product over all the poses (batched 3x3 products are much slower).
    R = T[:, :3, :3].reshape(-1, 3) @ points.T  # (m * 3, k)
    return R.reshape(len(T), 3, len(points)).transpose(0, 2, 1) + T[:, None, :3, 3]


def _screen(model, touches, geometries, T: np.ndarray, cap: float) -> np.ndarray:
    """The poses that put a few telling points nearest the model's vertices and curvature
    sites (capped; the sites cover the faces of a coarse mesh, whose vertices may all lie
    on a few rims).

    Two rounds: each touch's contact and one far point for every pose, then those and a
    second far point per touch for the best ``defaults.PAIR_SCREEN_FIRST``; the best
    ``defaults.PAIR_SCREEN`` are returned, best first."""
    # Without compact_nodes: the tree's nodes keep their full boxes, so the capped queries
    # (most of a look-alike's pair search) prune more; each distance is still the exact
    # nearest one (the same bits). Measured on the five pair screens of a look-alike's
    # three-touch recognition (set 7, ellipsoid_7_0; 29,000 to 41,000 poses each, 3 rounds):
    # 0.57 s against 0.71 s as the median, load average 2-3.
    tree = cKDTree(np.vstack([model.mesh.vertices, model.curvature.points]), compact_nodes=False)
    probe, first = _probes(touches, geometries)

    def rms(poses, points):
        # Capped: far points cost a KD tree most, and a pose that puts a point that far
        # off is screened out anyway.
        d = tree.query(_moved(poses, points).reshape(-1, 3), distance_upper_bound=cap)[0]
        d = np.minimum(d, cap).reshape(len(poses), len(points))
        return np.sqrt((d**2).mean(axis=1))

    T = T[np.argsort(rms(T, probe[first]), kind="stable")[: defaults.PAIR_SCREEN_FIRST]]
    return T[np.argsort(rms(T, probe), kind="stable")[: defaults.PAIR_SCREEN]]


def _subsample_rms(model, touches: Sequence[TouchData], T: np.ndarray) -> np.ndarray:
    """(m,) RMS distance of an even subsample of every touch's points at each pose."""
    sub = np.vstack(
        [
            t.points[np.linspace(0, t.n_points - 1, defaults.PAIR_SCORE_POINTS).astype(int)]
            for t in touches
        ]
    )
    out = np.empty(len(T))
    chunk = max(1, 200_000 // len(sub))
    for s in range(0, len(T), chunk):
        Tc = T[s : s + chunk]
        moved = _moved(Tc, sub)
        values = residuals(model, moved.reshape(-1, 3)).values.reshape(len(Tc), len(sub))
        out[s : s + chunk] = np.sqrt((values**2).mean(axis=1))
    return out
