"""The paper's figures for your own data, drawn with matplotlib into PNG files.

* :func:`phi_figure` (Figure 2): the registration error against the rotation phi about the
  normal with the contact held at one candidate point, the brackets of its local minima
  and the chosen minimum (from :func:`phi_profile`, drawn from a registration's trace).
* :func:`search_figure` (Figure 3): the candidate points on the model, the paths the
  local searches took from them to their minima, and the winner.
* :func:`contacts_figure` (Figure 6): true contacts as dots and estimated ones as crosses,
  one panel per surface, for a benchmark's results.

matplotlib is an optional dependency (``pip install 'meshrec[viz]'``) imported only inside
these functions; figures are drawn on an Agg canvas (no display, no pyplot state).
"""

from __future__ import annotations

import importlib
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.figures._pixels import check_size, write_png_atomic
from meshrec.figures.viz import COLORS, VizDependencyError
from meshrec.model.index import ModelIndex
from meshrec.model.mesh import load_mesh
from meshrec.registration.brackets import phi_error, refine_phis
from meshrec.registration.chart import tangent_frame
from meshrec.registration.phi import bracket_minima
from meshrec.registration.register import Registration

__all__ = [
    "PhiProfile",
    "check_matplotlib",
    "contacts_figure",
    "phi_figure",
    "phi_profile",
    "search_figure",
]

_DPI = 100
_CELLS = 48  # drawn meshes are decimated on a grid of this many cells along their extent
_MIN_SIZE, _MAX_SIZE = 64, 8192
_TRUE_KEYS = ("true", "true_contact", "truth")
_ESTIMATE_KEYS = ("estimate", "estimated", "estimated_contact", "contact", "found")
_SURFACE_KEYS = ("surface", "model", "name")


# ------------------------------------------------------------------------------ helpers
def _matplotlib():
    """(Figure, FigureCanvasAgg), or raise VizDependencyError naming what to install."""
    try:
        figure = importlib.import_module("matplotlib.figure")
        agg = importlib.import_module("matplotlib.backends.backend_agg")
        importlib.import_module("mpl_toolkits.mplot3d")
    except ImportError as exc:
        hint = "pip install 'meshrec[viz]' (or pip install 'matplotlib>=3.7')"
        if isinstance(exc, ModuleNotFoundError) and (exc.name or "").split(".")[0] in (
            "matplotlib",
            "mpl_toolkits",
        ):
            raise VizDependencyError(f"matplotlib is not installed: {hint}") from None
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise VizDependencyError(f"matplotlib cannot be imported ({first}): {hint}") from None
    return figure.Figure, agg.FigureCanvasAgg


def check_matplotlib() -> None:
    """Check that matplotlib can be imported.

    Raises
    ------
    VizDependencyError
        If it cannot; the message names what to install.
    """
    _matplotlib()


def _check_size(size, name: str = "size") -> tuple[int, int]:
    return check_size(size, _MIN_SIZE, _MAX_SIZE, name)


def _check_png(path) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path ending in .png, got {path!r}")
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(p)!r}")
    return p


def _new_figure(size: tuple[int, int]):
    Figure, Canvas = _matplotlib()
    fig = Figure(figsize=(size[0] / _DPI, size[1] / _DPI), dpi=_DPI)
    Canvas(fig)
    return fig


def _save(fig, path: Path) -> Path:
    return write_png_atomic(
        path, lambda tmp: fig.savefig(tmp, dpi=_DPI, format="png", facecolor="white")
    )


def _mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh file, a model index, a mesh object, or a pair."""
    if isinstance(mesh, ModelIndex):
        mesh = mesh.mesh
    if isinstance(mesh, (str, os.PathLike)):
        V, F = load_mesh(mesh)
    elif isinstance(mesh, tuple) and len(mesh) == 2:
        V, F = mesh
    elif hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        V, F = mesh.vertices, mesh.faces
    else:
        raise ValueError(
            "mesh must be a mesh file, an object with vertices and faces, or a "
            f"(vertices, faces) pair, got {type(mesh).__name__}"
        )
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise ValueError(
            f"mesh must have (n, 3) vertices and (m, 3) faces, got {V.shape}, {F.shape}"
        )
    return V, F


def _decimate(V: np.ndarray, F: np.ndarray, cells: int = _CELLS) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering decimation for drawing: vertices merged on a ``cells``^3 grid."""
    lo, hi = V.min(axis=0), V.max(axis=0)
    step = float(np.max(hi - lo)) / cells
    if not step > 0:
        return V, F
    keys = np.floor((V - lo) / step).astype(np.int64)
    _, cluster, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cluster = cluster.reshape(-1)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, cluster, V)
    W = sums / counts[:, None]
    G = cluster[F]
    keep = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])
    G = G[keep]
    _, first = np.unique(np.sort(G, axis=1), axis=0, return_index=True)
    return W, G[np.sort(first)]


def _hidden(points: np.ndarray, W: np.ndarray, G: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """(n,) bool: whether the surface (W, G) hides each point from a viewer along ``towards``.

    A ray from each point towards the (orthographic) viewer is tested against every
    triangle (Moller-Trumbore); hits closer than three decimation cells are ignored, since
    a point on the surface lies within a cell of the decimated triangles.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    d = towards / np.linalg.norm(towards)
    a, b, c = W[G[:, 0]], W[G[:, 1]], W[G[:, 2]]
    e1, e2 = b - a, c - a
    h = np.cross(d, e2)  # (m, 3)
    det = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    extent = float(np.max(W.max(axis=0) - W.min(axis=0)))
    eps = 3.0 * extent / _CELLS
    hidden = np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        s = p - a
        u = np.einsum("ij,ij->i", s, h) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps)
        hidden[i] = bool(hit.any())
    return hidden


def _scatter(ax, points, hidden, **kw) -> None:
    """Scatter points on a 3D axes, faded where the surface hides them."""
    label = kw.pop("label", None)
    if np.any(~hidden):
        ax.scatter(*points[~hidden].T, depthshade=False, **kw)
    if np.any(hidden):
        ax.scatter(*points[hidden].T, depthshade=False, alpha=0.22, **kw)
    if label is not None:  # a legend entry in full colour
        ax.scatter([], [], [], depthshade=False, label=label, **kw)


def _draw_surface(ax, W, G, light, color=(0.80, 0.80, 0.82), alpha=0.55) -> None:
    """Draw a (decimated) mesh as flat-shaded polygons on a 3D axes."""
    art3d = importlib.import_module("mpl_toolkits.mplot3d.art3d")
    tri = W[G]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    n = n / np.where(norm > 0, norm, 1.0)[:, None]
    shade = 0.45 + 0.55 * np.abs(n @ light)
    rgba = np.column_stack([np.outer(shade, color), np.full(len(G), alpha)])
    coll = art3d.Poly3DCollection(tri, facecolors=rgba, edgecolors="none", linewidths=0)
    coll.set_zorder(0)
    ax.add_collection3d(coll)


def _view_angles(direction: np.ndarray) -> tuple[float, float]:
    """matplotlib (elev, azim) in degrees looking along -direction (from outside)."""
    d = direction / np.linalg.norm(direction)
    elev = float(np.degrees(np.arcsin(np.clip(d[2], -1.0, 1.0))))
    azim = float(np.degrees(np.arctan2(d[1], d[0])))
    return float(np.clip(elev, -60.0, 60.0)), azim


def _camera_direction(elev: float, azim: float) -> np.ndarray:
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _set_equal(ax, points: np.ndarray) -> None:
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) or 1.0
    ax.set_xlim(center[0] - half, center[0] + half)
    ax.set_ylim(center[1] - half, center[1] + half)
    ax.set_zlim(center[2] - half, center[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.3)


def _rgb(key: str) -> tuple[float, float, float]:
    return COLORS[key]


# ------------------------------------------------------------------------ Figure 2: phi
@dataclass(frozen=True)
class PhiProfile:
    """The registration error against phi with the contact held at one candidate.

    Attributes
    ----------
    model : str
        The model's name.
    candidate : int
        Index of the candidate, in the order of ``Registration.candidate_points``.
    point : (3,) float
        The candidate point (a model vertex), model coordinates.
    flipped : bool
        Whether the candidate came from the lookup for the other side of the surface
        (the data frame's normal reversed).
    grid : (s,) float
        The sampled angles, radians (``defaults.PHI_STEPS`` of them over [0, 2 pi)).
    grid_errors : (s,) float
        The error at each sampled angle.
    phis : (k,) float
        A fine sampling of [0, 2 pi), for drawing the curve.
    errors : (k,) float
        The error at each of ``phis``.
    brackets : (m, 2) float
        Every bracketed local minimum of the sampled error as (low, high) angles, radians
        (``low`` may be negative: the bracket wraps around 0).
    refined : (m,) bool
        Whether each bracket was refined (its sample is within
        ``defaults.PHI_REFINE_RATIO`` of the best one).
    minima : (r, 2) float
        The refined minima as rows (phi, error), best first.
    phi : float
        The chosen phi, radians in [0, 2 pi).
    error : float
        The error at ``phi``.

    Notes
    -----
    The error is the mean point-to-surface distance of the same subsample of the data
    points the registration uses for its phi search (``defaults.PHI_POINTS`` points).
    """

    model: str
    candidate: int
    point: np.ndarray = field(repr=False)
    flipped: bool
    grid: np.ndarray = field(repr=False)
    grid_errors: np.ndarray = field(repr=False)
    phis: np.ndarray = field(repr=False)
    errors: np.ndarray = field(repr=False)
    brackets: np.ndarray = field(repr=False)
    refined: np.ndarray = field(repr=False)
    minima: np.ndarray = field(repr=False)
    phi: float
    error: float


def phi_profile(
    registration, model, candidate: int | None = None, *, samples: int = 720
) -> PhiProfile:
    """The registration's phi search at one candidate point, for :func:`phi_figure`.

    Drawn from the registration's trace (``register(..., trace=True)``): the sampled
    errors, brackets and refined minima are the ones the registration computed (for a
    candidate it did not search, its brackets are refined here by the same stage,
    :func:`meshrec.registration.brackets.refine_phis`); only the fine curve is sampled
    anew (exact distances), with the data's common point on the candidate and their
    normal along the model's. Where the registration sampled the error from a local
    height-field (``defaults.PHI_GRID_DISTANCES``), the samples are those estimates, so
    the picture shows how far they are from the curve.

    Parameters
    ----------
    registration : Registration
        A registration with a trace (``register(touch, model, trace=True)``).
    model : ModelIndex
        The model registered (its distance tree evaluates the fine curve).
    candidate : int, optional
        Index of the candidate, as in ``Registration.candidate_points``. Default: the
        candidate whose best sampled error is the least.
    samples : int
        Angles of the fine curve drawn, at least 36.

    Returns
    -------
    PhiProfile

    Raises
    ------
    ValueError
        If ``registration`` is not a Registration or has no trace, ``model`` is not the
        model registered, ``samples`` is not an integer >= 36, the model had no
        candidate for the touch, or ``candidate`` is not an index of its candidates.
    """
    if not isinstance(registration, Registration):
        raise ValueError(f"registration must be a Registration, got {type(registration).__name__}")
    trace = registration.trace
    if trace is None:
        raise ValueError(
            f"registration must carry a trace (register(..., trace=True)), got none for "
            f"{registration.model!r}"
        )
    if getattr(model, "name", None) != registration.model:
        raise ValueError(
            f"model must be {registration.model!r}, the model registered, got "
            f"{getattr(model, 'name', model)!r}"
        )
    if not isinstance(samples, (int, np.integer)) or isinstance(samples, bool) or samples < 36:
        raise ValueError(f"samples must be an integer >= 36, got {samples!r}")
    cands, brackets = trace.candidates, trace.brackets
    if len(cands) == 0:
        g = cands.geometry
        raise ValueError(
            f"model {registration.model!r} has no candidate for this touch (K={g.K:.4g}, "
            f"|H|={abs(g.H):.4g} outside its table's lookup window)"
        )
    if candidate is None:
        candidate = int(np.argmin(brackets.best))
    elif (
        not isinstance(candidate, (int, np.integer))
        or isinstance(candidate, bool)
        or not 0 <= candidate < len(cands)
    ):
        raise ValueError(
            f"candidate must be an index 0..{len(cands) - 1} of the {len(cands)} "
            f"candidates on {registration.model!r}, got {candidate!r}"
        )
    candidate = int(candidate)
    searched = [int(i) for i in trace.screening.candidates[: len(trace.phis)]]
    if candidate in searched:
        ps = trace.phis[searched.index(candidate)]
    else:
        ps = refine_phis(model, cands, brackets, [candidate])[0]
    origin = cands.origins[candidate]
    error = phi_error(model, origin, cands.local_points[cands.side[candidate]][brackets.subset])
    step = 2.0 * np.pi / len(ps.grid)
    idx = bracket_minima(ps.grid_errors)
    best_sample = float(ps.grid_errors.min())
    brackets_ = np.column_stack([ps.grid[idx] - step, ps.grid[idx] + step])
    refined = ps.grid_errors[idx] <= defaults.PHI_REFINE_RATIO * best_sample + 1e-300
    phis = np.linspace(0.0, 2.0 * np.pi, int(samples), endpoint=False)
    return PhiProfile(
        model=registration.model,
        candidate=candidate,
        point=np.array(origin.point, dtype=np.float64),
        flipped=bool(cands.side[candidate] == 1),
        grid=ps.grid,
        grid_errors=ps.grid_errors,
        phis=phis,
        errors=np.asarray(error(phis), dtype=np.float64),
        brackets=brackets_,
        refined=np.asarray(refined, dtype=bool),
        minima=ps.minima,
        phi=ps.phi,
        error=ps.error,
    )


def phi_figure(profile: PhiProfile, path, *, size=(1100, 480)) -> Path:
    """Draw the error against phi (the paper's Figure 2) into a PNG.

    The fine curve, the sampled angles (dots), every bracket (shaded: refined; hatched:
    skipped, its sample too far above the best), every refined minimum (cross) and the
    chosen phi (star).

    Parameters
    ----------
    profile : PhiProfile
        From :func:`phi_profile`.
    path : str or os.PathLike
        The PNG to write; its folder is created.
    size : (2,) int
        (width, height) in pixels, each 64..8192.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``profile`` is not a PhiProfile, ``path`` does not end in ``.png`` or
        ``size`` is invalid.
    VizDependencyError
        If matplotlib cannot be imported.
    """
    if not isinstance(profile, PhiProfile):
        raise ValueError(f"profile must be a PhiProfile, got {type(profile).__name__}")
    path = _check_png(path)
    size = _check_size(size)
    fig = _new_figure(size)
    ax = fig.add_subplot(1, 1, 1)
    two_pi = 2.0 * np.pi
    labels = {True: "bracket, refined", False: "bracket, not refined (too high)"}
    for (lo, hi), refined in zip(profile.brackets, profile.refined, strict=True):
        spans = (
            [(lo, hi)] if lo >= 0 and hi <= two_pi else [(lo % two_pi, two_pi), (0, hi % two_pi)]
        )
        for a, b in spans:
            ax.axvspan(
                a,
                b,
                facecolor=(*_rgb("candidates"), 0.25 if refined else 0.07),
                edgecolor=(*_rgb("candidates"), 0.5),
                hatch=None if refined else "//",
                lw=0,
                label=labels.pop(bool(refined), None),
            )
    ax.plot(profile.phis, profile.errors, color="0.25", lw=1.4, label="error E(phi)")
    ax.plot(
        profile.grid,
        profile.grid_errors,
        "o",
        ms=3.5,
        color="0.25",
        label=f"{len(profile.grid)} sampled angles",
    )
    if len(profile.minima) > 1:
        ax.plot(
            profile.minima[1:, 0],
            profile.minima[1:, 1],
            "x",
            ms=9,
            mew=2,
            color=_rgb("truth"),
            label="refined local minima",
        )
    ax.plot(
        [profile.phi],
        [profile.error],
        "*",
        ms=16,
        color=_rgb("registered"),
        mec="black",
        label=f"chosen: phi = {profile.phi:.3f} rad, E = {profile.error:.3g}",
    )
    ax.set_xlim(0.0, two_pi)
    ax.set_xticks(np.arange(5) * np.pi / 2.0)
    ax.set_xticklabels(["0", "π/2", "π", "3π/2", "2π"])
    ax.set_xlabel("phi: rotation about the normal (rad)")
    ax.set_ylabel("mean point-to-surface distance (model units)")
    p = np.array2string(profile.point, precision=4, suppress_small=True)
    side = ", other side" if profile.flipped else ""
    ax.set_title(
        f"{profile.model}: error against phi at candidate {profile.candidate}, {p}{side}",
        fontsize="medium",
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", framealpha=0.9)
    fig.tight_layout()
    return _save(fig, path)


# --------------------------------------------------------------------- Figure 3: search
def _truth_contact(truth) -> np.ndarray | None:
    if truth is None:
        return None
    from meshrec.io.truth import Truth, read_truth
    from meshrec.sim.simulate import SimulatedTouch

    if isinstance(truth, SimulatedTouch):
        return np.asarray(truth.contact, dtype=np.float64)
    if isinstance(truth, (str, os.PathLike)):
        truth = read_truth(truth)
    elif isinstance(truth, Mapping) and "contact" in truth:
        truth = Truth.from_dict(truth)
    if isinstance(truth, Truth):
        return np.array(truth.contact)
    raise ValueError(
        "truth must be a SimulatedTouch, a Truth, a truth dict or truth JSON file with a "
        f"'contact' of 3 numbers, got {type(truth).__name__}"
    )


def search_figure(registration, path, *, mesh=None, truth=None, size=(1200, 560)) -> Path:
    """Draw the candidates and the local searches' paths (the paper's Figure 3) into a PNG.

    Left, the model in 3D seen from outside at the winner: the candidate points (green),
    the path of each local search from its candidate to its minimum (black lines,
    ending in a dot) and the winner p* (star). Right, the same paths seen from above the
    tangent plane at p*, where they are short.

    Parameters
    ----------
    registration : Registration
        A registration (not rejected), with its ``candidate_points`` and
        ``search_paths``.
    path : str or os.PathLike
        The PNG to write; its folder is created.
    mesh : ModelIndex or trimesh.Trimesh or str or os.PathLike, optional
        The model's mesh; default: loaded from ``registration.path``.
    truth : SimulatedTouch or dict or str or os.PathLike, optional
        The ground truth (or its JSON file): the true contact is marked too.
    size : (2,) int
        (width, height) in pixels, each 64..8192.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``registration`` is not a Registration or was rejected, ``path`` does not end
        in ``.png``, ``size`` is invalid, or ``mesh`` or ``truth`` cannot be read.
    VizDependencyError
        If matplotlib cannot be imported.
    """
    from meshrec.registration.register import Registration

    if not isinstance(registration, Registration):
        raise ValueError(f"registration must be a Registration, got {type(registration).__name__}")
    if registration.rejected:
        raise ValueError(
            f"registration must not be rejected, got {registration.model!r}: {registration.reason}"
        )
    path = _check_png(path)
    size = _check_size(size)
    V, F = _mesh_arrays(registration.path if mesh is None else mesh)
    true_contact = _truth_contact(truth)
    reg = registration
    contact = np.asarray(reg.contact, dtype=np.float64)
    normal = np.asarray(reg.normal, dtype=np.float64)
    cands = np.asarray(reg.candidate_points, dtype=np.float64).reshape(-1, 3)
    paths = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in reg.search_paths]

    fig = _new_figure(size)
    ax = fig.add_subplot(1, 2, 1, projection="3d", computed_zorder=False)
    elev, azim = _view_angles(normal)
    towards = _camera_direction(elev, azim)
    W, G = _decimate(V, F)
    _draw_surface(ax, W, G, _camera_direction(elev + 20.0, azim - 30.0), alpha=0.9)
    if len(cands):
        _scatter(
            ax,
            cands,
            _hidden(cands, W, G, towards),
            s=18,
            color=_rgb("candidates"),
            zorder=3,
            label=f"{len(cands)} candidates (faded: behind)",
        )
    ends = np.array([p[-1] for p in paths]).reshape(-1, 3)
    ends_hidden = _hidden(ends, W, G, towards)
    for k, p in enumerate(paths):
        ax.plot(
            *p.T,
            color="black",
            lw=1.5,
            zorder=4,
            alpha=0.25 if ends_hidden[k] else 1.0,
            label="local searches" if k == 0 else None,
        )
    if len(ends):
        _scatter(ax, ends, ends_hidden, s=10, color="black", zorder=4)
    if true_contact is not None:
        _scatter(
            ax,
            true_contact[None, :],
            _hidden(true_contact[None, :], W, G, towards),
            s=60,
            color=_rgb("true_contact"),
            zorder=5,
            label="true contact",
        )
    ax.scatter(
        *contact,
        s=160,
        marker="*",
        color=_rgb("registered"),
        edgecolors="black",
        depthshade=False,
        zorder=6,
        label="winner p*",
    )
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    _set_equal(ax, V)
    ax.set_axis_off()
    ax.set_title(f"{reg.model}: candidates and local searches", fontsize="medium")
    ax.legend(loc="upper left", fontsize="small", framealpha=0.9)

    # The tangent-plane view at the winner.
    frame = tangent_frame(normal)
    t1, t2 = frame[:, 0], frame[:, 1]

    def uv(p):
        d = np.atleast_2d(p) - contact
        return np.column_stack([d @ t1, d @ t2])

    bx = fig.add_subplot(1, 2, 2)
    shown = [uv(contact)] + [uv(p) for p in paths]
    if true_contact is not None:
        shown.append(uv(true_contact))
    pts = np.vstack(shown)
    half = max(float(np.abs(pts).max()), 1e-9) * 1.25
    near = (
        cands[np.linalg.norm(uv(cands), axis=1) <= 1.5 * half * np.sqrt(2)] if len(cands) else cands
    )
    near = near[np.abs((near - contact) @ normal) < 2 * half] if len(near) else near
    if len(near):
        q = uv(near)
        bx.scatter(q[:, 0], q[:, 1], s=30, color=_rgb("candidates"), zorder=2, label="candidates")
    for k, p in enumerate(paths):
        q = uv(p)
        bx.plot(
            q[:, 0],
            q[:, 1],
            "-",
            color="black",
            lw=1.2,
            zorder=3,
            label="search paths" if k == 0 else None,
        )
        bx.plot(
            q[0, 0],
            q[0, 1],
            "o",
            ms=7,
            mfc="none",
            mec="black",
            zorder=3,
            label="start (candidate)" if k == 0 else None,
        )
        bx.plot(
            q[-1, 0],
            q[-1, 1],
            "o",
            ms=4,
            color="black",
            zorder=3,
            label="end (local minimum)" if k == 0 else None,
        )
    if true_contact is not None:
        q = uv(true_contact)
        bx.plot(
            q[:, 0], q[:, 1], "o", ms=9, color=_rgb("true_contact"), zorder=4, label="true contact"
        )
    bx.plot(
        [0.0],
        [0.0],
        "*",
        ms=16,
        color=_rgb("registered"),
        mec="black",
        zorder=5,
        label=f"winner p*, error {reg.error:.3g}",
    )
    bx.set_xlim(-half, half)
    bx.set_ylim(-half, half)
    bx.set_aspect("equal")
    bx.grid(True, alpha=0.3)
    bx.set_xlabel("along t1 at p* (model units)")
    bx.set_ylabel("along t2 at p*")
    bx.set_title("seen from above the tangent plane at p*", fontsize="medium")
    bx.legend(loc="best", fontsize="small", framealpha=0.9)
    fig.tight_layout()
    return _save(fig, path)


# -------------------------------------------------------------------- Figure 6: contacts
def _first_key(row: Mapping, keys: tuple[str, ...], what: str, where: str):
    for k in keys:
        if k in row:
            return row[k]
    raise ValueError(
        f"{where} must have a {what} entry (one of {list(keys)}), got keys {sorted(row)}"
    )


def _point(value, where: str, allow_none: bool) -> np.ndarray | None:
    if value is None and allow_none:
        return None
    try:
        p = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{where} must be 3 numbers, got {value!r}") from None
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{where} must be 3 finite numbers, got {value!r}")
    return p


def _pair(item, where: str):
    if isinstance(item, Mapping):
        t = _first_key(item, _TRUE_KEYS, "true contact", where)
        e = item.get(next((k for k in _ESTIMATE_KEYS if k in item), ""), None)
    else:
        try:
            t, e = item
        except (TypeError, ValueError):
            raise ValueError(
                f"{where} must be a (true, estimate) pair or a mapping, got {item!r}"
            ) from None
    return _point(t, f"{where} true contact", False), _point(e, f"{where} estimate", True)


def _contact_groups(surfaces) -> dict[str, list]:
    """{surface: [(true (3,), estimate (3,) or None)]} from either accepted form."""
    groups: dict[str, list] = {}
    if isinstance(surfaces, Mapping):
        for name, items in surfaces.items():
            if isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
                raise ValueError(f"surfaces[{name!r}] must be a list of contacts, got {items!r}")
            groups[str(name)] = [
                _pair(it, f"surfaces[{name!r}][{i}]") for i, it in enumerate(items)
            ]
    elif isinstance(surfaces, Iterable) and not isinstance(surfaces, (str, bytes)):
        for i, row in enumerate(surfaces):
            if not isinstance(row, Mapping):
                raise ValueError(f"surfaces[{i}] must be a mapping (a row), got {row!r}")
            name = str(_first_key(row, _SURFACE_KEYS, "surface name", f"surfaces[{i}]"))
            groups.setdefault(name, []).append(_pair(row, f"surfaces[{i}]"))
    else:
        raise ValueError(
            f"surfaces must be a mapping or a list of rows, got {type(surfaces).__name__}"
        )
    if not groups or not any(groups.values()):
        raise ValueError("surfaces must hold at least one contact, got none")
    return groups


def _default_mesh(name: str):
    from meshrec.model.library import bundled_models_dir

    for lib in ("surfaces", "objects"):
        for candidate in sorted(bundled_models_dir(lib).glob(f"{name}.*")):
            return candidate
    return None


def contacts_figure(surfaces, path, *, meshes=None, size=None, columns: int | None = None) -> Path:
    """Draw true contacts (dots) and estimates (crosses) on each surface: the paper's Figure 6.

    For a benchmark: one 3D panel per surface, its mesh drawn lightly, every true contact
    p as a dot and its estimate p* as a cross (an instance without an estimate, a
    rejection, has its dot only).

    Parameters
    ----------
    surfaces : mapping or iterable of mappings
        Either ``{surface name: [instance, ...]}`` where an instance is a
        ``(true, estimate)`` pair of (3,) points or a mapping with a ``"true"`` and an
        ``"estimate"`` entry; or a list of rows (mappings) with ``"surface"``, ``"true"``
        and ``"estimate"`` entries. Accepted aliases: ``"model"``/``"name"`` for the
        surface, ``"true_contact"``/``"truth"`` for the true contact,
        ``"estimated"``/``"estimated_contact"``/``"contact"``/``"found"`` for the
        estimate. An estimate may be None. Points are in model coordinates.
    path : str or os.PathLike
        The PNG to write; its folder is created.
    meshes : mapping, optional
        ``{surface name: mesh}`` (a file, an object with ``vertices`` and ``faces``, or a
        ``(vertices, faces)`` pair). Default: the bundled model of that name, if any;
        else the panel shows the points only.
    size : (2,) int, optional
        (width, height) in pixels; default 520 per column by 470 per row.
    columns : int, optional
        Panels per row (default: 2 up to 4 surfaces, else 3).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``surfaces`` is empty or malformed (the message names the entry), ``path``
        does not end in ``.png``, ``size`` or ``columns`` is invalid, or a mesh cannot be
        read.
    VizDependencyError
        If matplotlib cannot be imported.
    """
    groups = _contact_groups(surfaces)
    path = _check_png(path)
    n = len(groups)
    if columns is None:
        columns = 2 if n <= 4 else 3
    if not isinstance(columns, (int, np.integer)) or isinstance(columns, bool) or columns < 1:
        raise ValueError(f"columns must be a positive integer, got {columns!r}")
    columns = min(int(columns), n)
    rows = math.ceil(n / columns)
    size = _check_size((520 * columns, 470 * rows) if size is None else size)
    if meshes is not None and not isinstance(meshes, Mapping):
        raise ValueError(f"meshes must be a mapping of surface name to mesh, got {meshes!r}")
    fig = _new_figure(size)
    letters = "abcdefghijklmnopqrstuvwxyz"
    for k, (name, pairs) in enumerate(groups.items()):
        ax = fig.add_subplot(rows, columns, k + 1, projection="3d", computed_zorder=False)
        source = (meshes or {}).get(name, None)
        if source is None:
            source = _default_mesh(name)
        true = np.array([t for t, _ in pairs])
        est = np.array([e for _, e in pairs if e is not None]).reshape(-1, 3)
        elev, azim = 30.0, -60.0
        towards = _camera_direction(elev, azim)
        hidden_true = np.zeros(len(true), dtype=bool)
        hidden_est = np.zeros(len(est), dtype=bool)
        if source is not None:
            W, G = _decimate(*_mesh_arrays(source))
            _draw_surface(ax, W, G, _camera_direction(elev + 25.0, azim - 30.0), alpha=0.85)
            _set_equal(ax, np.vstack([W, true, est]))
            hidden_true = _hidden(true, W, G, towards)
            hidden_est = _hidden(est, W, G, towards)
        else:
            _set_equal(ax, np.vstack([true, est]))
        _scatter(
            ax,
            true,
            hidden_true,
            s=28,
            color=_rgb("truth"),
            zorder=3,
            label="true contact p (faded: behind)",
        )
        if len(est):
            _scatter(
                ax,
                est,
                hidden_est,
                s=46,
                marker="x",
                linewidths=1.8,
                color=_rgb("registered"),
                zorder=4,
                label="estimate p*",
            )
        ax.set_proj_type("ortho")
        ax.view_init(elev=elev, azim=azim)
        label = f"({letters[k]}) " if k < len(letters) else ""
        missing = len(pairs) - len(est)
        extra = f", {missing} without estimate" if missing else ""
        ax.set_title(f"{label}{name}: {len(pairs)} instances{extra}", fontsize="medium")
        ax.set_axis_off()
        if k == 0:
            ax.legend(loc="upper left", fontsize="small", framealpha=0.9)
    fig.tight_layout()
    return _save(fig, path)
