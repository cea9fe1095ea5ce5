"""The library-wide screen: every model's best fit estimated at once, before any model's
own registration stages, so that only the models that could compete are registered.

For one touch, over all the models' curvature sites together (:class:`LibrarySites`, built
once per library):

1. the (K, H) lookup of every model in one interval test (each side of the surface the
   model's registration would try);
2. the hits spread over each model's surface by a grid of cells of
   ``defaults.SCREEN_CELL_FRACTION`` times the curves' half-length (the best (K, H) match
   in each cell), all models in one ``np.unique``;
3. at every candidate a local height-field z = f(x, y) in its tangent frame
   (:func:`meshrec.model.heightfield.fit_heightfields`: a degree-4 polynomial through the
   heights and slopes of its ``defaults.SCREEN_NEIGHBOURS`` nearest sites, found by one
   KD-tree query over all models' sites, thinned to the curves' reach);
4. a data subsample (``defaults.SCREEN_POINTS``) at ``defaults.SCREEN_PHI_STEPS`` angles
   about the normal and with its contact at ``defaults.SCREEN_SHIFTS`` squared places over
   the candidate's cell, its vertical gaps to every field less their affine part (a small
   tilt and lift of the data), their mean, in one float32 matrix product per chunk; a
   model's estimate is its least.

:func:`screen_leaders` names the few models with the least estimates: their own
registrations run first, and the least rms they reach bounds the best model's.
:func:`screen_survivors` applies the scores' rule, as the cascade does, to the estimates
(a model's rms taken to be at least its estimate over a measured gain) against that rms.
:func:`screened_registration` gives a model the screen prunes the pose of its best
estimate, refined a few steps on all the points with the exact distances, so its error is
an upper bound of what its registration would find and its probability only falls.
Models the screen cannot judge (seen through a ball-tipped probe, or with sharp edges,
whose fields would straddle a crease) always survive it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_instance, check_int
from meshrec.io.touch import TouchData
from meshrec.model.heightfield import fit_heightfields, monomials
from meshrec.model.index import ModelIndex
from meshrec.model.neighbours import site_ranks
from meshrec.model.probe import probe_radius_of
from meshrec.recognition.scoring import effective_points
from meshrec.registration.candidates import curvature_tolerance
from meshrec.registration.chart import SurfacePoint, rotation_z
from meshrec.registration.pruned import pruned_from_start
from meshrec.registration.register import Registration
from meshrec.registration.sampling import even_subsample
from meshrec.registration.transform import superposition

__all__ = [
    "LibraryScreen",
    "LibrarySites",
    "library_sites",
    "screen_leaders",
    "screen_library",
    "screen_survivors",
    "screened_registration",
]


@dataclass(frozen=True, eq=False)
class LibrarySites:
    """Every model's curvature sites, concatenated (the screen's library-wide index).

    Attributes
    ----------
    names : tuple of str
        The models, in order.
    model : (N,) int32
        Each site's model (index into ``names``).
    points, normals, dir1 : (N, 3) float64
        Sites, unit normals, first principal directions.
    lo, hi : (N, 2) float64
        Each site's (K, H) range; ``+inf, -inf`` for sites outside the model's lookup
        table (never matched).
    K, H : (N,) float64
        Each site's own (K, H) (0 outside the table).
    rank : (N,) float64
        A seeded uniform number per site (seeded by ``defaults.SCREEN_SEED`` and the
        model's site count, not its place in the library): the sites with ``rank < f`` are
        an even random fraction ``f`` of them (the thinning of the neighbours).
    area_per_site : (m,) float64
        Each model's surface area over its sites.
    screened : (m,) bool
        Models the screen judges (no probe radius, no crease site).
    closed : (m,) bool
        Models with a closed mesh (one side tried when the touch gives a normal).
    """

    names: tuple[str, ...]
    model: np.ndarray = field(repr=False)
    points: np.ndarray = field(repr=False)
    normals: np.ndarray = field(repr=False)
    dir1: np.ndarray = field(repr=False)
    lo: np.ndarray = field(repr=False)
    hi: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    H: np.ndarray = field(repr=False)
    rank: np.ndarray = field(repr=False)
    area_per_site: np.ndarray = field(repr=False)
    screened: np.ndarray = field(repr=False)
    closed: np.ndarray = field(repr=False)

    @classmethod
    def from_models(cls, models: Sequence) -> LibrarySites:
        """Concatenate the models' curvature tables.

        Parameters
        ----------
        models : sequence of ModelIndex

        Returns
        -------
        LibrarySites

        Raises
        ------
        TypeError
            If a model is not a ModelIndex.
        ValueError
            If ``models`` is empty.
        """
        models = list(models)
        if not models:
            raise ValueError("models must hold at least one model, got none")
        parts = {k: [] for k in ("model", "points", "normals", "dir1", "lo", "hi", "K", "H")}
        area, screened, closed = [], [], []
        for i, m in enumerate(models):
            check_instance(m, ModelIndex, f"models[{i}]")
            t = m.curvature
            n = len(t.points)
            lo = np.full((n, 2), np.inf)
            hi = np.full((n, 2), -np.inf)
            ts = t.table_sites
            lo[ts, 0], lo[ts, 1] = t.K_range[ts, 0], t.H_range[ts, 0]
            hi[ts, 0], hi[ts, 1] = t.K_range[ts, 1], t.H_range[ts, 1]
            K = np.zeros(n)
            H = np.zeros(n)
            K[ts], H[ts] = t.K[ts], t.H[ts]
            parts["model"].append(np.full(n, i, dtype=np.int32))
            parts["points"].append(np.asarray(t.points))
            parts["normals"].append(np.asarray(t.normals))
            parts["dir1"].append(np.asarray(t.dir1))
            parts["lo"].append(lo)
            parts["hi"].append(hi)
            parts["K"].append(K)
            parts["H"].append(H)
            area.append(t.scale**2 / max(n, 1))
            screened.append(probe_radius_of(m) == 0.0 and not bool(np.any(t.crease)))
            closed.append(bool(m.mesh.closed))
        arrays = {k: np.concatenate(v) for k, v in parts.items()}
        # Each model's ranks from its own site count only: the same whatever the order.
        rank = np.concatenate([site_ranks(len(k)) for k in parts["K"]])
        return cls(
            names=tuple(m.name for m in models),
            rank=rank,
            area_per_site=np.array(area),
            screened=np.array(screened, dtype=bool),
            closed=np.array(closed, dtype=bool),
            **arrays,
        )

    def __len__(self) -> int:
        return len(self.model)


_CACHE: list[tuple[tuple, list, LibrarySites]] = []


def library_sites(models: Sequence) -> LibrarySites:
    """The :class:`LibrarySites` of these models, built once and kept for the last two
    model lists (a service or a benchmark recognises many touches on one library).

    Parameters
    ----------
    models : sequence of ModelIndex

    Returns
    -------
    LibrarySites

    Raises
    ------
    TypeError, ValueError
        As :meth:`LibrarySites.from_models`.
    """
    models = list(models)
    key = tuple(id(m) for m in models)
    for k, _, sites in _CACHE:
        if k == key:
            return sites
    sites = LibrarySites.from_models(models)
    _CACHE.insert(0, (key, models, sites))  # the models are held: their ids stay theirs
    del _CACHE[2:]
    return sites


@dataclass(frozen=True, eq=False)
class LibraryScreen(ValueEquality):
    """The screen's result for one touch.

    Attributes
    ----------
    estimates : (m,) float
        Each model's least mean gap of the data subsample to the height-fields of its
        candidates (vertical, less its affine part), model units; NaN for a model with no
        candidate or not screened.
    judged : (m,) bool
        Models the screen judged (screened, with candidates).
    side : (m,) int
        The side (0: the touch's geometry, 1: its flip) of each judged model's best
        candidate.
    site : (m,) int
        Its site (index into the model's curvature table); -1 when not judged.
    phi : (m,) float
        Its best angle, radians.
    shift : (m, 2) float
        Its best placement of the data's contact in the site's tangent plane, model units.
    candidates : (m,) int
        Candidates screened per model.
    raw_hits : (m,) int
        Sites matching the lookup per model (both sides).
    seconds : float
        Wall time of the screen.
    """

    estimates: np.ndarray = field(repr=False)
    judged: np.ndarray = field(repr=False)
    side: np.ndarray = field(repr=False)
    site: np.ndarray = field(repr=False)
    phi: np.ndarray = field(repr=False)
    shift: np.ndarray = field(repr=False)
    candidates: np.ndarray = field(repr=False)
    raw_hits: np.ndarray = field(repr=False)
    seconds: float = field(default=0.0, compare=False)


def _frames(normals: np.ndarray, dir1: np.ndarray) -> np.ndarray:
    """(c, 3, 3) frames (d1, d2, n) as :func:`meshrec.registration.chart.tangent_frame`
    builds them, for many sites at once."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    d1 = dir1 - np.einsum("ij,ij->i", dir1, n)[:, None] * n
    bad = np.linalg.norm(d1, axis=1) < 1e-8 * np.maximum(1.0, np.linalg.norm(dir1, axis=1))
    if bad.any():
        axis = np.eye(3)[np.argmin(np.abs(n[bad]), axis=1)]
        d1[bad] = axis - np.einsum("ij,ij->i", axis, n[bad])[:, None] * n[bad]
    d1 /= np.linalg.norm(d1, axis=1, keepdims=True)
    d2 = np.cross(n, d1)
    return np.stack([d1, d2, n], axis=2)


def _sides(geometry: LocalGeometry) -> tuple[LocalGeometry, LocalGeometry]:
    return geometry, geometry.flipped()


def screen_library(touch: TouchData, geometry: LocalGeometry, sites: LibrarySites) -> LibraryScreen:
    """Estimate every model's best fit of the touch at once (see the module's text).

    Parameters
    ----------
    touch : TouchData
    geometry : LocalGeometry
        The touch's local geometry.
    sites : LibrarySites
        Of the models to screen.

    Returns
    -------
    LibraryScreen

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``geometry`` not a LocalGeometry or ``sites``
        not a LibrarySites.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(geometry, LocalGeometry, "geometry")
    check_instance(sites, LibrarySites, "sites")
    t0 = time.perf_counter()
    m = len(sites.names)
    hl = float(geometry.half_length)
    radius = defaults.SCREEN_REACH * hl
    cell = defaults.SCREEN_CELL_FRACTION * hl
    two_sides = ~sites.closed if touch.normal is not None else np.ones(m, dtype=bool)
    raw_hits = np.zeros(m, dtype=np.int64)
    hit_site, hit_side = [], []
    for s, side in enumerate(_sides(geometry)):
        use_model = sites.screened & (two_sides if s == 1 else True)
        tol_K, tol_H = curvature_tolerance(
            side.k1, side.k2, hl, side.fit_rms, curvature_sd=side.curvature_sd
        )
        K, H = side.k1 * side.k2, 0.5 * (side.k1 + side.k2)
        lo, hi = sites.lo, sites.hi
        match = (lo[:, 0] - tol_K <= K) & (hi[:, 0] + tol_K >= K)
        match &= (lo[:, 1] - tol_H <= H) & (hi[:, 1] + tol_H >= H)
        match &= use_model[sites.model]
        hits = np.flatnonzero(match)
        if len(hits) == 0:
            continue
        raw_hits += np.bincount(sites.model[hits], minlength=m)
        with np.errstate(divide="ignore", invalid="ignore"):
            mis = np.abs(sites.K[hits] - K) / tol_K + np.abs(sites.H[hits] - H) / tol_H
        mis = np.nan_to_num(mis, nan=np.inf)
        # Best (K, H) match first within each model, so that a cell's first hit is its best.
        hits = hits[np.lexsort((mis, sites.model[hits]))]
        hit_site.append(hits)
        hit_side.append(np.full(len(hits), s, dtype=np.int64))
    est = np.full(m, np.nan)
    best_side = np.zeros(m, dtype=np.int64)
    best_site = np.full(m, -1, dtype=np.int64)
    best_phi = np.zeros(m)
    best_shift = np.zeros((m, 2))
    n_cand = np.zeros(m, dtype=np.int64)
    if hit_site:
        hits = np.concatenate(hit_site)
        sides_of_hit = np.concatenate(hit_side)
        # Coarse cells: one candidate each (its best match).
        cell_of = _cells(sites, hits, sides_of_hit, cell)
        first = _first_of_each(cell_of)
        cands, sides_of = hits[first], sides_of_hit[first]
        err, phi, shift = _candidate_errors(touch, geometry, sites, cands, sides_of, radius, cell)
        cm = sites.model[cands]
        n_cand = np.bincount(cm, minlength=m)
        best = _best_per_model(cm, err, 1)
        est[cm[best]] = err[best]
        best_side[cm[best]] = sides_of[best]
        offsets = np.concatenate([[0], np.cumsum(np.bincount(sites.model, minlength=m))])
        best_site[cm[best]] = cands[best] - offsets[cm[best]]
        best_phi[cm[best]] = phi[best]
        best_shift[cm[best]] = shift[best]
    return LibraryScreen(
        estimates=est,
        judged=np.isfinite(est),
        side=best_side,
        site=best_site,
        phi=best_phi,
        shift=best_shift,
        candidates=n_cand,
        raw_hits=raw_hits,
        seconds=time.perf_counter() - t0,
    )


def _cells(sites: LibrarySites, hits: np.ndarray, side: np.ndarray, size: float) -> np.ndarray:
    """One integer per (model, side, cell of the given size) of each hit."""
    cell = np.floor(sites.points[hits] / size).astype(np.int64)
    cell -= cell.min(axis=0)
    dims = cell.max(axis=0) + 1
    key = sites.model[hits].astype(np.int64) * 2 + side
    for d in range(3):
        key = key * int(dims[d]) + cell[:, d]
    return key


def _first_of_each(keys: np.ndarray) -> np.ndarray:
    """Indices of the first occurrence of each distinct key, in their order."""
    return np.sort(np.unique(keys, return_index=True)[1])


def _best_per_model(model: np.ndarray, err: np.ndarray, k: int) -> np.ndarray:
    """Indices of the ``k`` least errors of each model."""
    order = np.lexsort((err, model))
    start = np.unique(model[order], return_index=True)[1]
    rank = np.arange(len(order)) - np.repeat(start, np.diff(np.append(start, len(order))))
    return order[rank < k]


def _candidate_errors(touch, geometry, sites, cands, sides_of, radius, cell):
    """Each candidate's least mean gap over the phi grid and the contact's shifts within
    its cell, its angle and its shift."""
    k = defaults.SCREEN_NEIGHBOURS
    cm = sites.model[cands]
    # The neighbours: the sites thinned so that about k of them fall within the reach,
    # per model (its site density), and models kept apart by a fourth coordinate.
    frac = np.minimum(1.0, k * sites.area_per_site / (math.pi * radius**2))
    keep = np.flatnonzero(sites.rank < frac[sites.model])
    keep = np.union1d(keep, cands)
    span = float(np.ptp(sites.points, axis=0).max() + np.abs(sites.points).max() + radius)
    sep = 4.0 * span
    pts4 = np.column_stack([sites.points[keep], sites.model[keep] * sep])
    tree = cKDTree(pts4)
    q4 = np.column_stack([sites.points[cands], cm * sep])
    _, nb = tree.query(q4, k=min(k, len(keep)), distance_upper_bound=sep / 2)
    nb = np.asarray(nb).reshape(len(cands), -1)
    missing = nb >= len(keep)
    nb = keep[np.minimum(nb, len(keep) - 1)]
    frames = _frames(sites.normals[cands], sites.dir1[cands])
    steps = defaults.SCREEN_PHI_STEPS
    grid = np.arange(steps) * (2.0 * np.pi / steps)
    Rz = rotation_z(grid)  # (s, 3, 3)
    subset = even_subsample(int(touch.n_points), defaults.SCREEN_POINTS)
    n_sub = len(subset)
    # The data's contact placed on a grid over the candidate's cell (one field serves
    # them all; the affine removal absorbs the field's height and slope there).
    g = defaults.SCREEN_SHIFTS
    offs = (np.arange(g) - (g - 1) / 2.0) * (cell / g)
    shifts = np.array([(u, v) for u in offs for v in offs])  # (h, 2)
    designs = []
    for side in _sides(geometry):
        local = (touch.points[subset] - side.point) @ side.frame  # (n, 3)
        placed = np.einsum("sij,nj->sni", Rz, local) / radius  # (s, n, 3), field units
        xy = placed[None, :, :, :2] + shifts[:, None, None, :] / radius  # (h, s, n, 2)
        phi_m = monomials(xy, defaults.SCREEN_DEGREE)  # (h, s, n, m)
        z = np.broadcast_to(placed[None, :, :, 2], xy.shape[:3])
        if defaults.SCREEN_AFFINE:
            # The gaps' part that a small tilt and lift of the data explain (affine in the
            # placed (x, y), the same span at every shift) is removed: P (z - M g) with P
            # the projection off that span, so P z and P M are made once per touch.
            X = np.concatenate([np.ones((*placed.shape[:2], 1)), placed[..., :2]], axis=2)
            P = np.eye(n_sub) - X @ np.linalg.pinv(X)  # (s, n, n)
            z = np.matmul(P[None], z[..., None])[..., 0]
            phi_m = np.matmul(P[None], phi_m)
        designs.append(
            (
                np.ascontiguousarray(z.reshape(-1, 1), dtype=np.float32),
                np.ascontiguousarray(phi_m.reshape(-1, phi_m.shape[-1]), dtype=np.float32),
            )
        )
    err = np.empty(len(cands))
    phi = np.empty(len(cands))
    shift = np.empty((len(cands), 2))
    chunk = defaults.SCREEN_CHUNK
    for a in range(0, len(cands), chunk):
        b = min(a + chunk, len(cands))
        nbp = sites.points[nb[a:b]]
        nbn = sites.normals[nb[a:b]].copy()
        miss = missing[a:b]
        if miss.any():
            nbn[miss] = -frames[a:b, :, 2][np.nonzero(miss)[0]]  # left out of the fit
        coef = fit_heightfields(
            sites.points[cands[a:b]],
            frames[a:b],
            nbp,
            nbn,
            radius,
            degree=defaults.SCREEN_DEGREE,
            slope_weight=defaults.SCREEN_SLOPE_WEIGHT,
        )
        for s in (0, 1):
            sel = np.flatnonzero(sides_of[a:b] == s)
            if len(sel) == 0:
                continue
            z, design = designs[s]
            gaps = z - design @ coef[sel].T.astype(np.float32)  # (h s n, c), field units
            np.abs(gaps, out=gaps)
            mean = gaps.reshape(len(shifts) * steps, n_sub, len(sel)).mean(axis=1)
            mean *= radius
            j = np.argmin(mean, axis=0)
            err[a + sel] = mean[j, np.arange(len(sel))]
            phi[a + sel] = grid[j % steps]
            shift[a + sel] = shifts[j // steps]
    return err, phi, shift


def screen_leaders(screen: LibraryScreen, names: Sequence[str], k: int) -> np.ndarray:
    """The ``k`` judged models with the least estimates (ties by name: order-free).

    Parameters
    ----------
    screen : LibraryScreen
    names : sequence of str
        The screen's models' names, in its order.
    k : int
        How many (>= 1).

    Returns
    -------
    (j,) int
        Their indices, least estimate first (``j = min(k, judged)``).

    Raises
    ------
    TypeError
        If ``screen`` is not a LibraryScreen.
    ValueError
        If ``names`` does not name every model of the screen or ``k`` is below 1.
    """
    check_instance(screen, LibraryScreen, "screen")
    k = check_int(k, "k", minimum=1)
    if len(names) != len(screen.estimates):
        raise ValueError(f"names must name {len(screen.estimates)} models, got {len(names)}")
    judged = np.flatnonzero(screen.judged)
    order = sorted(judged.tolist(), key=lambda i: (screen.estimates[i], names[i]))
    return np.array(order[:k], dtype=np.int64)


def screen_survivors(
    screen: LibraryScreen,
    n_points: int,
    noise: float,
    leader_rms: float | None,
    screen_gain: float = defaults.SCREEN_GAIN,
    log_ratio: float = defaults.JOINT_PRUNE_LOG_RATIO,
) -> np.ndarray:
    """Which models go on to their own registration stages.

    The scores' rule, as the cascade's (:func:`meshrec.recognition.cascade.cascade_survivors`):
    a model's log-likelihood is ``-n_eff rms^2 / (2 noise^2)``; its best conceivable rms is
    its estimate over ``screen_gain``; the best model's rms is at most ``leader_rms``, an
    rms a registration reached (of :func:`screen_leaders`' models: no gain needed). A
    model whose best conceivable log-likelihood is below the leader's worst by more than
    ``-log_ratio`` is pruned. A model the screen did not judge always survives.

    Parameters
    ----------
    screen : LibraryScreen
    n_points : int
        Data points of the touch.
    noise : float
        The touch's noise estimate.
    leader_rms : float or None
        The least rms the registrations of the leaders reached (None: no leader was
        registered, every model survives).
    screen_gain : float
        A model's rms is taken to be at least its estimate over this (>= 1).
    log_ratio : float
        Prune below this log-likelihood ratio to the leader's (< 0).

    Returns
    -------
    (m,) bool

    Raises
    ------
    TypeError
        If ``screen`` is not a LibraryScreen.
    ValueError
        If ``n_points`` is not a positive integer, ``noise`` or ``leader_rms`` not
        positive and finite (``leader_rms`` may be 0), ``screen_gain`` below 1 or
        ``log_ratio`` not negative.
    """
    check_instance(screen, LibraryScreen, "screen")
    n_points = check_int(n_points, "n_points", minimum=1)
    if not (np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be positive and finite, got {noise!r}")
    if not (np.isfinite(screen_gain) and screen_gain >= 1):
        raise ValueError(f"screen_gain must be a finite number >= 1, got {screen_gain!r}")
    if not (np.isfinite(log_ratio) and log_ratio < 0):
        raise ValueError(f"log_ratio must be negative and finite, got {log_ratio!r}")
    if leader_rms is None:
        return np.ones(len(screen.judged), dtype=bool)
    if not (np.isfinite(leader_rms) and leader_rms >= 0):
        raise ValueError(f"leader_rms must be finite and >= 0, got {leader_rms!r}")
    half_n = 0.5 * effective_points(n_points)
    worst_leader = -half_n * (leader_rms / noise) ** 2
    est = np.where(screen.judged, screen.estimates, 0.0)
    best_conceivable = -half_n * (est / screen_gain / noise) ** 2
    return (best_conceivable - worst_leader >= log_ratio) | ~screen.judged


def screened_registration(
    touch: TouchData, model, geometry: LocalGeometry, screen: LibraryScreen, i: int
) -> Registration:
    """The Registration of a model the screen pruned: the pose of its best estimate,
    refined by ``defaults.SCREEN_PRUNED_ITERATIONS`` steps on all the points with the
    exact distances (its error an upper bound of the full search's, up to the optimisers'
    tolerance).

    Parameters
    ----------
    touch : TouchData
    model : ModelIndex
        The ``i``-th model of the screen.
    geometry : LocalGeometry
        The touch's local geometry (the one screened).
    screen : LibraryScreen
    i : int
        The model's index in the screen.

    Returns
    -------
    Registration
        With ``pruned`` true, ``searches`` 0 and one pose.

    Raises
    ------
    TypeError
        If an argument is not of its type.
    ValueError
        If the screen did not judge model ``i``.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(geometry, LocalGeometry, "geometry")
    check_instance(screen, LibraryScreen, "screen")
    if not (0 <= i < len(screen.judged)) or not screen.judged[i]:
        raise ValueError(f"i must be a model the screen judged, got {i!r}")
    side = _sides(geometry)[int(screen.side[i])]
    t = model.curvature
    v = int(screen.site[i])
    frame = _frames(t.normals[v][None, :], t.dir1[v][None, :])[0]
    shift = frame[:, :2] @ screen.shift[i]  # in the tangent plane: the refinement lands it
    origin = SurfacePoint(point=np.array(t.points[v]) + shift, frame=frame)
    T0 = superposition(side.point, side.frame, origin, float(screen.phi[i]))
    return pruned_from_start(
        model,
        touch.points,
        T0,
        geometry.point,
        defaults.SCREEN_PRUNED_ITERATIONS,
        candidates=int(screen.candidates[i]),
        raw_hits=int(screen.raw_hits[i]),
        candidate_points=origin.point[None, :],
    )
