"""Registration of touch data onto one model: the paper's Section 2.3 on a mesh.

Steps: the local geometry at the contact (from the curves), the (K, H) table lookup for
candidate points, the initial phi at each candidate, the local search over the contact's
position and phi on surface charts, and a final rigid refinement of the best searches.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry, RoughFitWarning, estimate_local_geometry
from meshrec.io.touch import TouchData
from meshrec.registration.candidates import find_candidates
from meshrec.registration.chart import SurfacePoint, rotation_z, tangent_frame
from meshrec.registration.objective import mean_distances
from meshrec.registration.phi import search_phi
from meshrec.registration.refine import refine_rigid
from meshrec.registration.search import SEARCH_METHODS, local_search
from meshrec.registration.transform import apply_transform, superposition

__all__ = ["Registration", "StageTimes", "refine_pose", "register", "touch_geometry"]


@dataclass(frozen=True)
class StageTimes:
    """Seconds spent in each stage of one registration."""

    lookup: float = 0.0
    phi: float = 0.0
    screen: float = 0.0
    search: float = 0.0
    refine: float = 0.0

    def __add__(self, other: StageTimes) -> StageTimes:
        return StageTimes(
            self.lookup + other.lookup,
            self.phi + other.phi,
            self.screen + other.screen,
            self.search + other.search,
            self.refine + other.refine,
        )


@dataclass(frozen=True)
class Registration:
    """The best superposition of the touch data on one model.

    Attributes
    ----------
    model : str
        Model name (file stem).
    path : str
        Model file.
    error : float or None
        Mean unsigned point-to-surface distance per data point, model units (the paper's
        Table 4 measure); None when the model had no candidates.
    contact : (3,) float or None
        The estimated contact p* on the model, model coordinates.
    normal : (3,) float or None
        The model's outward (face-winding) unit normal at ``contact``.
    phi : float or None
        Rotation about the normal from the chart frame found by the local search, radians.
    T_model_touch : (4, 4) float or None
        Maps touch-frame points to model coordinates.
    candidates : int
        Candidate points tried (after spreading), both sides together.
    raw_hits : int
        Vertices matching the curvature lookup before spreading.
    searches : int
        Local searches run.
    seconds : float
        Wall time of this registration.
    times : StageTimes
        Wall time per stage.
    reason : str
        Why the model was rejected ("" when it was not).
    candidate_points : (c, 3) float
        The candidate points, model coordinates.
    search_paths : tuple of (k, 3) float
        The contact's path in each local search, model coordinates.
    """

    model: str
    path: str
    error: float | None
    contact: np.ndarray | None
    normal: np.ndarray | None
    phi: float | None
    T_model_touch: np.ndarray | None
    candidates: int
    raw_hits: int
    searches: int
    seconds: float
    times: StageTimes = field(default_factory=StageTimes)
    reason: str = ""
    candidate_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)), repr=False)
    search_paths: tuple[np.ndarray, ...] = field(default=(), repr=False)

    @property
    def rejected(self) -> bool:
        """True when the table lookup found no candidate on this model."""
        return self.error is None

    def __repr__(self) -> str:
        if self.rejected:
            return f"Registration({self.model!r}, rejected: {self.reason})"
        c = np.round(self.contact, 6).tolist()
        return (
            f"Registration({self.model!r}, error={self.error:.6g}, contact={c}, "
            f"candidates={self.candidates}, searches={self.searches}, "
            f"seconds={self.seconds:.3f})"
        )


def touch_geometry(touch: TouchData) -> LocalGeometry:
    """Estimate the local geometry at the touch's contact (given or found).

    Parameters
    ----------
    touch : TouchData

    Returns
    -------
    LocalGeometry

    Raises
    ------
    ValueError
        If the curves do not allow an estimate (see
        :func:`meshrec.contact.geometry.estimate_local_geometry`).

    Warns
    -----
    RoughFitWarning
        If the curve fits leave more than ``defaults.ROUGH_FIT_RATIO`` times the noise
        that the samples show (and more than ``defaults.ROUGH_FIT_MIN_FRACTION`` of the
        half-length): the curves may cross an edge or a rim, where the recognition is
        less reliable.
    """
    g = estimate_local_geometry(touch.curves, point=touch.contact, normal=touch.normal)
    ratio = g.fit_to_noise
    if ratio > defaults.ROUGH_FIT_RATIO and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * (
        g.half_length
    ):
        warnings.warn(
            f"the curves fit no smooth surface patch: the curve fits leave {g.fit_rms:.3g}, "
            f"{ratio:.3g} times the noise the samples show ({g.noise_rms:.3g}; "
            f"defaults.ROUGH_FIT_RATIO = {defaults.ROUGH_FIT_RATIO:g}): they may cross an "
            "edge or a rim, where the curvature estimate and the recognition are less "
            "reliable; touch again away from edges",
            RoughFitWarning,
            stacklevel=3,
        )
    return g


def _sides(geometry: LocalGeometry, touch: TouchData, model) -> list[LocalGeometry]:
    """The sides of the surface to try: one when a normal is given and the mesh is closed."""
    if touch.normal is not None and model.closed:
        return [geometry]
    return [geometry, geometry.flipped()]


def _subsample(n: int, k: int) -> np.ndarray:
    if n <= k:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))


def _phi_grid_errors(model, origins, locals_sub) -> np.ndarray:
    """The error at every sampled phi for every candidate, (candidates, steps)."""
    steps = defaults.PHI_STEPS
    Rz = rotation_z(np.arange(steps) * (2.0 * np.pi / steps))  # (s, 3, 3)
    frames = np.array([o.frame for o in origins])  # (c, 3, 3)
    R = np.einsum("cij,sjk->csik", frames, Rz)  # (c, s, 3, 3)
    pts = np.array(locals_sub)  # (c, n, 3)
    placed = np.einsum("csij,cnj->csni", R, pts)
    placed += np.array([o.point for o in origins])[:, None, None, :]
    c, s, n, _ = placed.shape
    return mean_distances(model, placed.reshape(c * s, n, 3)).reshape(c, s)


def register(
    touch: TouchData,
    model,
    geometry: LocalGeometry | None = None,
    method: str = defaults.SEARCH_METHOD,
    max_candidates: int = defaults.MAX_CANDIDATES,
    searches: int = defaults.LOCAL_SEARCHES,
    rival_error: float | None = None,
    lookup_scale: float = 1.0,
) -> Registration:
    """Register touch data onto one model.

    Parameters
    ----------
    touch : TouchData
        The curves (touch frame) with optional contact and normal hints.
    model : ModelIndex
        The model, with its curvature table and distance tree.
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (``recognize`` shares
        one estimate across models).
    method : {"lm", "steepest"}
        The local-search optimiser (see :func:`meshrec.registration.search.local_search`).
    max_candidates : int
        Most candidates per side after spreading.
    searches : int
        Local searches run at most, on the candidates with the least error after the
        screening.
    rival_error : float, optional
        The least error of another model (``recognize`` passes the best so far): the
        searches stop early once this model's best is far worse
        (``defaults.RIVAL_RATIO``), since it cannot win.
    lookup_scale : float
        Factor on the (K, H) lookup's tolerances (> 1 widens the window).

    Returns
    -------
    Registration

    Raises
    ------
    ValueError
        If ``method`` is unknown, ``max_candidates`` or ``searches`` is not a positive
        integer, ``lookup_scale`` is not positive, or the local geometry cannot be
        estimated from the curves.
    """
    if method not in SEARCH_METHODS:
        raise ValueError(f"method must be one of {SEARCH_METHODS}, got {method!r}")
    for name, value in (("max_candidates", max_candidates), ("searches", searches)):
        if not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if not (np.isfinite(lookup_scale) and lookup_scale > 0):
        raise ValueError(f"lookup_scale must be a positive number, got {lookup_scale!r}")
    t_start = time.perf_counter()
    if geometry is None:
        geometry = touch_geometry(touch)
    points = touch.points
    scale = float(geometry.half_length)

    # Table lookup on each side of the surface.
    t0 = time.perf_counter()
    starts = []  # (side geometry, local points, vertex)
    raw_hits = 0
    for side in _sides(geometry, touch, model):
        cand = find_candidates(
            model,
            side.k1,
            side.k2,
            scale,
            side.fit_rms,
            max_candidates=max_candidates,
            scale=lookup_scale,
        )
        raw_hits += cand.raw_hits
        local = (points - side.point) @ side.frame
        starts.extend((side, local, int(v)) for v in cand.vertices)
    t_lookup = time.perf_counter() - t0
    if not starts:
        return Registration(
            model=model.name,
            path=str(model.path),
            error=None,
            contact=None,
            normal=None,
            phi=None,
            T_model_touch=None,
            candidates=0,
            raw_hits=0,
            searches=0,
            seconds=time.perf_counter() - t_start,
            times=StageTimes(lookup=t_lookup),
            reason=(
                f"no vertex with K={geometry.K:.4g}, |H|={abs(geometry.H):.4g} "
                "within the lookup tolerance"
            ),
        )

    # Initial phi at every candidate: the discretised error of all candidates in one
    # batched distance query (on a subsample of the points), then every bracket refined
    # for the candidates that go on to a local search.
    t0 = time.perf_counter()
    sub = _subsample(len(points), defaults.PHI_POINTS)
    origins = [
        SurfacePoint(
            point=model.vertices[v],
            frame=tangent_frame(model.vertex_normals[v], hint=model.dir1[v]),
        )
        for _, _, v in starts
    ]
    grid_errors = _phi_grid_errors(model, origins, [local[sub] for _, local, _ in starts])
    best_grid = grid_errors.min(axis=1)
    order = np.argsort(best_grid, kind="stable")
    order = order[best_grid[order] <= defaults.SEARCH_PRUNE_RATIO * best_grid[order[0]]]
    t_phi = time.perf_counter() - t0

    # Screening: a few rigid-refinement steps on the subsample from each candidate's best
    # sampled phi rank the candidates better than the sampled error alone (a candidate is
    # up to the spreading spacing away from its basin's minimum).
    t0 = time.perf_counter()
    step = 2.0 * np.pi / defaults.PHI_STEPS
    screened = []
    for i in order[: defaults.SCREEN_CANDIDATES]:
        side, _, _ = starts[i]
        phi_i = float(np.argmin(grid_errors[i])) * step
        T0 = superposition(side.point, side.frame, origins[i], phi_i)
        quick = refine_rigid(model, points[sub], T0, max_iter=defaults.SCREEN_ITERATIONS)
        screened.append((quick.error, int(i)))
    screened.sort()
    t_screen = time.perf_counter() - t0

    t0 = time.perf_counter()
    seeds = []
    for _, i in screened[:searches]:
        side, local, _ = starts[i]
        origin, local_sub = origins[i], local[sub]

        def error(phis, origin=origin, local_sub=local_sub):
            R = origin.frame @ rotation_z(phis)  # (k, 3, 3)
            placed = np.einsum("kij,nj->kni", R, local_sub) + origin.point
            return mean_distances(model, placed)

        ps = search_phi(error, grid_errors=grid_errors[i])
        seeds.append((side, local, origin, ps.phi))
    t_phi += time.perf_counter() - t0

    # Local search from the best candidates on a subsample of the points, then a rigid
    # refinement on all of them of the best results (defaults.REFINE_BEST). The searches
    # stop early once several in a row have not improved on a best that already fits the
    # data to the noise level (the distance residuals of a right superposition are the
    # noise, whose RMS the curve fits estimate), or that is far worse than a rival
    # model's error.
    t_search = t_refine = 0.0
    found_all = []
    paths = []
    search_sub = _subsample(len(points), defaults.SEARCH_POINTS)
    fit_rms = float(geometry.fit_rms)
    stale = 0
    t0 = time.perf_counter()
    for side, local, origin, phi in seeds:
        found = local_search(model, local[search_sub], origin, phi, scale, method=method)
        paths.append(found.path)
        best_so_far = min((f.error for _, f in found_all), default=np.inf)
        better = found.error < (1.0 - defaults.SEARCH_IMPROVEMENT) * best_so_far
        stale = 0 if better else stale + 1
        found_all.append((side, found))
        best = min(best_so_far, found.error)
        settled = best <= defaults.SEARCH_GOOD_FIT * fit_rms or (
            rival_error is not None and best > defaults.RIVAL_RATIO * rival_error
        )
        if stale >= defaults.SEARCH_PATIENCE and settled:
            break
    t_search = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = []
    for side, found in sorted(found_all, key=lambda sf: sf[1].error)[: defaults.REFINE_BEST]:
        T = superposition(side.point, side.frame, found.surface, found.phi)
        ref = refine_rigid(model, points, T)
        results.append((ref.rms, ref.error, ref.T_model_touch, found.phi))
    t_refine = time.perf_counter() - t0
    # The best result by the optimisers' own objective (the RMS distance); the error
    # reported is the paper's mean distance at that result.
    _, error, T, phi = min(results, key=lambda r: r[0])
    contact_guess = apply_transform(T, geometry.point[None, :])
    _, closest, face = model.closest_points(contact_guess)
    normal = model.interpolated_normals(closest, face)[0]
    cand_points = np.array([model.vertices[v] for _, _, v in starts])
    return Registration(
        model=model.name,
        path=str(model.path),
        error=float(error),
        contact=closest[0],
        normal=normal,
        phi=float(phi),
        T_model_touch=T,
        candidates=len(starts),
        raw_hits=raw_hits,
        searches=len(results),
        seconds=time.perf_counter() - t_start,
        times=StageTimes(
            lookup=t_lookup, phi=t_phi, screen=t_screen, search=t_search, refine=t_refine
        ),
        candidate_points=cand_points,
        search_paths=tuple(paths),
    )


def refine_pose(
    touch: TouchData,
    model,
    T_model_touch: np.ndarray,
    geometry: LocalGeometry | None = None,
) -> Registration:
    """Register touch data onto one model starting from a known pose.

    Runs only the final rigid refinement of :func:`register` (all six degrees of freedom)
    from ``T_model_touch``: the nearest minimum of the same error. Use it when a pose is
    already approximately known (tracking a touched object between touches), and as the
    benchmarks' oracle: started at the true pose, its error is the floor the noise leaves.

    Parameters
    ----------
    touch : TouchData
        The curves, in the touch frame.
    model : ModelIndex
        The model.
    T_model_touch : (4, 4) float
        The starting pose, mapping touch-frame points to model coordinates.
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (its point locates the
        contact on the model).

    Returns
    -------
    Registration
        With ``candidates`` and ``searches`` zero; ``phi`` is None (no chart was used).

    Raises
    ------
    ValueError
        If ``T_model_touch`` is not a finite (4, 4) rigid transform, or the local geometry
        cannot be estimated from the curves.
    """
    T0 = np.asarray(T_model_touch, dtype=np.float64)
    if T0.shape != (4, 4) or not np.all(np.isfinite(T0)):
        raise ValueError(f"T_model_touch must be a finite (4, 4) array, got shape {T0.shape}")
    R = T0[:3, :3]
    if not (
        np.allclose(R.T @ R, np.eye(3), atol=1e-6)
        and np.linalg.det(R) > 0
        and np.allclose(T0[3], [0, 0, 0, 1])
    ):
        raise ValueError("T_model_touch must be a rigid transform (rotation and translation)")
    t_start = time.perf_counter()
    if geometry is None:
        geometry = touch_geometry(touch)
    t0 = time.perf_counter()
    ref = refine_rigid(model, touch.points, T0)
    t_refine = time.perf_counter() - t0
    contact_guess = apply_transform(ref.T_model_touch, geometry.point[None, :])
    _, closest, face = model.closest_points(contact_guess)
    return Registration(
        model=model.name,
        path=str(model.path),
        error=float(ref.error),
        contact=closest[0],
        normal=model.interpolated_normals(closest, face)[0],
        phi=None,
        T_model_touch=ref.T_model_touch,
        candidates=0,
        raw_hits=0,
        searches=0,
        seconds=time.perf_counter() - t_start,
        times=StageTimes(refine=t_refine),
    )
