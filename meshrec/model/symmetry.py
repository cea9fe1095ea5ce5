"""A model's near-symmetries: the turns that carry its surface almost onto itself.

A can's top and bottom, a box's faces, a bottle's two sides: a touch on such a surface
fits the model almost as well after a half-turn that swaps them, and the local search,
which only follows continuous motions, never crosses from one to the other. The
recognition (:mod:`meshrec.recognition.weak`) refines the touches from the best pose
carried by each half-turn found here.

A scanned can is also nearly round: a touch on its side fits after any turn about its
axis, up to the scan's small features, and the basins along that turn are a few degrees
wide. An axis estimated from the touch alone (the data's weakest motion) is a millimetre
or more off the can's at this scale, and a long turn about it moves the touch off the
surface; the model's own axis is needed.

The candidates are the half-turns and the turns about the principal axes of the
surface's area (through its area centroid): a symmetric body's symmetry axes are
principal axes. One is near when the model's vertices, so turned, lie within
``defaults.NEAR_SYMMETRY_FRACTION`` of its diagonal of its surface (at the
``defaults.NEAR_SYMMETRY_QUANTILE`` quantile of points drawn by area), and not all
within the exact-symmetry tolerance (a half-turn that is a symmetry moves no data: a
box's or a cylinder's poses so related are the same answer, as the pose test of
:mod:`meshrec.recognition.freedom` takes them).

Hand-written: trimesh's ``Trimesh.symmetry`` reads equal principal moments of a closed
volume (radial or spherical), not which half-turns carry a surface, open or closed, near
itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.model.mesh import MeshData
from meshrec.model.surface import SurfaceQuery

__all__ = ["NearSymmetries", "near_symmetries"]


@dataclass(frozen=True)
class NearSymmetries:
    """A model's near-symmetries.

    Attributes
    ----------
    half_turns : tuple of (4, 4) float64
        Half-turns that carry the model near itself, motions in model coordinates
        (``S @ T_model_touch`` is the pose so turned), the nearest first. With an axis
        (below), only the nearest half-turn about another axis: the others follow from it
        by a turn about the axis.
    axes : tuple of ((3,) float64, (3,) float64)
        Axes ``(direction, through)`` about which every turn carries the model near
        itself (a scanned can's, a bottle's): the model turned by
        ``defaults.POSE_SYMMETRY_TURN_DEG`` about them stays near itself.
    """

    half_turns: tuple = ()
    axes: tuple = ()


def near_symmetries(
    mesh: MeshData,
    surface: SurfaceQuery,
    exact_tolerance: float,
    fraction: float = defaults.NEAR_SYMMETRY_FRACTION,
) -> NearSymmetries:
    """The half-turns and the axes of turns about the surface's principal axes that carry
    it near itself.

    Parameters
    ----------
    mesh : MeshData
    surface : SurfaceQuery
        The mesh's closest-point query.
    exact_tolerance : float
        A motion that leaves every vertex within this of the surface (model units) is a
        symmetry of the model, not a near one, and is left out; at least 0.
    fraction : float
        A motion is near when it moves the vertices by at most this fraction of the
        diagonal (distance to the surface at ``defaults.NEAR_SYMMETRY_QUANTILE``); in
        (0, 1).

    Returns
    -------
    NearSymmetries

    Raises
    ------
    ValueError
        If ``exact_tolerance`` is negative or not finite, or ``fraction`` is not in
        (0, 1).
    """
    if not (np.isfinite(exact_tolerance) and exact_tolerance >= 0.0):
        raise ValueError(f"exact_tolerance must be finite and >= 0, got {exact_tolerance!r}")
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must be in (0, 1), got {fraction!r}")
    V, F = mesh.vertices, mesh.faces
    tri = V[F]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 0.0:
        return NearSymmetries()
    w = area / area.sum()
    centres = tri.mean(axis=1)
    centroid = w @ centres
    d = centres - centroid
    _, axes = np.linalg.eigh((d * w[:, None]).T @ d)
    diagonal = float(np.linalg.norm(np.ptp(V, axis=0)))
    # Points spread over the surface by area (a coarse CAD export's few vertices sit at its
    # corners, where a chamfer's change hides), the same points on every call.
    probe = _area_samples(V, F, area, defaults.NEAR_SYMMETRY_VERTICES)

    def moved_distance(angle: float, axis: np.ndarray, through: np.ndarray, points) -> np.ndarray:
        M = turn_about(angle, axis, through)
        return surface.closest_points(points @ M[:3, :3].T + M[:3, 3])[0]

    # The candidate axes: the principal axes through the area centroid, and the model's
    # own coordinate axes through its bounding box's centre (a CAD export's frame: a box
    # with one corner chamfered has its principal axes 12 degrees off the box's, and its
    # centroid beside the box's centre).
    box_centre = 0.5 * (V.min(axis=0) + V.max(axis=0))
    candidates = [(a, centroid) for a in axes.T]
    for a in np.eye(3):
        if not any(abs(a @ b) > np.cos(np.radians(5.0)) for b, _ in candidates[:3]):
            candidates.append((a, box_centre))
    half_turns, turns = [], []
    for axis, through in candidates:
        for angle, found in (
            (np.pi, half_turns),
            (np.radians(defaults.POSE_SYMMETRY_TURN_DEG), turns),
        ):
            # a tenth of the points first: most turns tested are far from a symmetry, and
            # the tree's queries far from the surface are the slow ones
            few = moved_distance(angle, axis, through, probe[::10])
            if _spread(few) > 2.0 * fraction * diagonal:
                continue
            dist = moved_distance(angle, axis, through, probe)
            if float(dist.max()) <= exact_tolerance:
                continue  # a symmetry (a cylinder's axis): its poses are one answer
            # the axis of a part with a hole or a handle leans off the principal one
            fitted = _fitted_axis(angle, axis, through, probe[::2], surface, fraction * diagonal)
            dist_fit = moved_distance(angle, *fitted, probe)
            (a, p), spread = (axis, through), _spread(dist)
            if _spread(dist_fit) < spread:  # the fit kept only where it helps
                (a, p), dist, spread = fitted, dist_fit, _spread(dist_fit)
            near = float(dist.max()) > exact_tolerance and spread <= fraction * diagonal
            if near and not any(abs(a @ b) > np.cos(np.radians(5.0)) for _, (b, _) in found):
                found.append((spread, (a, p)))
    if turns:
        # A half-turn about a near-symmetry axis is on the turns' scan, and two upside-down
        # half-turns differ by one about it: the nearest upside-down one is enough.
        ups = [(r, (a, p)) for r, (a, p) in half_turns if abs(a @ turns[0][1][0]) < 0.5]
        half_turns = sorted(ups, key=lambda x: x[0])[:1]
    half_turns = [(rms, turn_about(np.pi, a, p)) for rms, (a, p) in half_turns]
    return NearSymmetries(
        half_turns=tuple(S for _, S in sorted(half_turns, key=lambda x: x[0])),
        axes=tuple(a for _, a in sorted(turns, key=lambda x: x[0])),
    )


def turn_about(angle: float, axis: np.ndarray, through: np.ndarray) -> np.ndarray:
    """The (4, 4) turn by ``angle`` radians about the unit ``axis`` through ``through``."""
    R = Rotation.from_rotvec(angle * np.asarray(axis, dtype=np.float64)).as_matrix()
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = through - R @ through
    return M


def _spread(distance: np.ndarray) -> float:
    """How far the points moved by a turn lie from the surface: the
    ``defaults.NEAR_SYMMETRY_QUANTILE`` quantile of their distances."""
    return float(np.quantile(distance, defaults.NEAR_SYMMETRY_QUANTILE))


def _fitted_axis(
    angle: float,
    axis: np.ndarray,
    through: np.ndarray,
    probe: np.ndarray,
    surface,
    outlier: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The axis near ``(axis, through)`` about which a turn by ``angle`` carries the
    ``probe`` points nearest the surface: robust least squares (scipy's ``least_squares``,
    soft-L1 loss beyond ``outlier``, so that a handle or a hole does not pull the axis)
    over the axis's two tilts and two shifts, on the points' offsets to their closest
    points."""
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    scale = float(np.sqrt(((probe - through) ** 2).sum(axis=1).mean()))

    def axis_of(q):
        a = axis + q[0] * u + q[1] * v
        return a / np.linalg.norm(a), through + scale * (q[2] * u + q[3] * v)

    def offsets(q):
        a, p = axis_of(q)
        M = turn_about(angle, a, p)
        moved = probe @ M[:3, :3].T + M[:3, 3]
        return (moved - surface.closest_points(moved)[1]).ravel()

    fit = least_squares(
        offsets, np.zeros(4), x_scale=0.01, max_nfev=30, loss="soft_l1", f_scale=outlier
    )
    return axis_of(fit.x) if np.all(np.isfinite(fit.x)) else (axis.copy(), through.copy())


def _area_samples(V: np.ndarray, F: np.ndarray, area: np.ndarray, count: int) -> np.ndarray:
    """``count`` points on the surface, faces drawn by area (seeded: the same points for the
    same mesh)."""
    rng = np.random.default_rng(0)
    face = rng.choice(len(F), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    a, b, c = V[F[face, 0]], V[F[face, 1]], V[F[face, 2]]
    return a + u[:, None] * (b - a) + v[:, None] * (c - a)
