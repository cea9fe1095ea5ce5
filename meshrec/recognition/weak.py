"""Starting poses along the motions the data constrain least.

Touches on the smooth part of a nearly symmetric object (a sphere with small bumps, a
nearly round bottle) fit it at poses far apart: a turn about the near-symmetry moves the
touches to another place where the surface is almost the same, and the fits there differ
by a few per cent of the noise-level residual. The joint search starts from seeds near
the touches' single registrations and can end in one of those basins while a better one
lies a large turn away; its pose is then precise-looking and wrong. A local test (the
rank of the rigid Jacobian, :mod:`meshrec.recognition.freedom`) sees a constrained
minimum at either place.

So the weakest motions of the Jacobian at the best pose (singular values below
``defaults.WEAK_MOTION_RATIO`` of the largest: the near-symmetries) are followed a long
way: turns of ``defaults.WEAK_TURN_ANGLES_DEG`` about their axis, slides of
``defaults.WEAK_SLIDE_STEPS`` times the points' spread along their direction. The poses
reached are starts for the joint refinement
(:func:`meshrec.recognition.joint.explore_weak_motions`). A well-constrained pose
(an ellipsoid's curved side, an edge) has no weak motion and gets no start.

The data's own weak motions are a local estimate: about a scanned can, whose basins along
the turn are a few degrees wide, their axis is a millimetre off the can's. The model's
near-symmetries (:mod:`meshrec.model.symmetry`) give the rest of the starts: whole turns
about its near-symmetry axes, scanned (:func:`near_symmetry_scan`), and its near-symmetric
half-turns (a can upside down). One touch's pose is also turned about its normal
(:func:`normal_turn_starts`). :func:`exploration_starts` gathers them all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.io.checks import check_int, check_points, check_transform, check_vector
from meshrec.model.symmetry import turn_about
from meshrec.registration.objective import residuals
from meshrec.registration.transform import apply_transform

__all__ = [
    "exploration_starts",
    "near_symmetry_scan",
    "normal_turn_starts",
    "weak_motion_starts",
]


def weak_motion_starts(
    model,
    points: np.ndarray,
    T_model_touch: np.ndarray,
    ratio: float = defaults.WEAK_MOTION_RATIO,
    most: int = defaults.WEAK_MOTION_MOST,
) -> list[np.ndarray]:
    """Poses reached from ``T_model_touch`` by long moves along its weakest motions.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        The data points, touch frame; at least 6.
    T_model_touch : (4, 4) float
        The fitted pose.
    ratio : float
        A motion is weak when its singular value of the rigid Jacobian (rows
        ``[n_i, (x_i - c) / L x n_i]`` at the points' closest points) is below this
        fraction of the largest; in (0, 1).
    most : int
        At most this many weak motions are followed, weakest first; at least 1.

    Returns
    -------
    list of (4, 4) float64
        ``T_model_touch`` composed with each move: per turn-like motion one pose per
        angle of ``defaults.WEAK_TURN_ANGLES_DEG`` about its axis, per slide one per step
        of ``defaults.WEAK_SLIDE_STEPS`` (times the points' RMS spread ``L``) either way.
        Empty when no motion is weak.

    Raises
    ------
    ValueError
        If ``points`` is not (n, 3) finite with n >= 6, ``T_model_touch`` is not a finite
        (4, 4) array, ``ratio`` is not in (0, 1) or ``most`` is not a positive integer.
    """
    x = check_points(points, "points", min_rows=6)
    T = check_transform(T_model_touch, "T_model_touch")
    if not (isinstance(ratio, (int, float)) and 0.0 < float(ratio) < 1.0):
        raise ValueError(f"ratio must be a number in (0, 1), got {ratio!r}")
    if not isinstance(most, (int, np.integer)) or isinstance(most, bool) or most < 1:
        raise ValueError(f"most must be a positive integer, got {most!r}")
    out = []
    for motion in _weak_motions(model, x, T, float(ratio), int(most)):
        if motion.turn:
            for deg in defaults.WEAK_TURN_ANGLES_DEG:
                out.append(motion.moved(np.radians(deg)) @ T)
        else:
            for step in defaults.WEAK_SLIDE_STEPS:
                for sign in (1.0, -1.0):
                    out.append(motion.moved(sign * step * motion.spread) @ T)
    return out


def near_symmetry_scan(
    model,
    points: np.ndarray,
    T_model_touch: np.ndarray,
    keep: int = defaults.WEAK_SCAN_KEEP,
) -> list[np.ndarray]:
    """Poses at the deepest other basins of whole turns about the model's near-symmetry
    axes (``model.near_symmetries.axes``: a scanned can's).

    Each turn goes all round in steps that move the farthest point by
    ``defaults.WEAK_SCAN_STEP`` times the points' RMS spread (at most
    ``defaults.WEAK_SCAN_MOST`` steps). Each step is settled onto the surface
    (``defaults.WEAK_SCAN_SETTLE`` point-to-plane steps) and scored by the mean squared
    distance of up to ``defaults.WEAK_SCAN_POINTS`` of the points to the surface (one
    closest-point query per settling step for the whole turn), and the ``keep`` deepest
    distinct basins, the given pose's own left out, are returned as starts. The fixed
    angles of :func:`weak_motion_starts` about an axis estimated from the data miss such
    basins: they are a few degrees wide, and the data's axis is off the model's.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        The data points, touch frame; at least 6.
    T_model_touch : (4, 4) float
        The fitted pose.
    keep : int
        Basins kept per axis; at least 1.

    Returns
    -------
    list of (4, 4) float64
        Empty when the model has no near-symmetry axis.

    Raises
    ------
    TypeError
        If ``keep`` is not an integer.
    ValueError
        If ``points`` is not (n, 3) finite with n >= 6, ``T_model_touch`` is not a finite
        (4, 4) array, or ``keep`` is below 1.
    """
    x = check_points(points, "points", min_rows=6)
    T = check_transform(T_model_touch, "T_model_touch")
    keep = check_int(keep, "keep", minimum=1)
    axes = model.near_symmetries.axes
    if not axes:
        return []
    y = apply_transform(T, x[:: max(1, len(x) // defaults.WEAK_SCAN_POINTS)])
    spread = float(np.sqrt(((y - y.mean(axis=0)) ** 2).sum(axis=1).mean()))
    if spread <= 0.0:
        return []
    out = []
    for axis, through in axes:
        out += [M @ T for M in _turn_scan(model, y, spread, axis, through, keep)]
    return out


def normal_turn_starts(
    points: np.ndarray, T_model_touch: np.ndarray, point: np.ndarray, normal: np.ndarray
) -> list[np.ndarray]:
    """The pose turned about the touch's normal at its contact by each of
    ``defaults.NORMAL_TURN_ANGLES_DEG``: the rotation phi of the method, looked at again
    from the pose found.

    The search brackets phi from each candidate; on a rough or coarse mesh it can settle
    tens of degrees off in a basin of its own (a black-box probe, stop 34: one touch of a
    4,000-face power drill `recognised`, the pose `fixed` and 26 degrees off; turned back
    by 30 to 60 degrees about the normal, the refinement reaches the true pose, which fits
    1.5 times better). Such turns land the curves off a surface curved unequally both ways
    by far more than the basin's fit, so a scan scored where it lands cannot see the basin
    (as :func:`near_symmetry_scan` can about a near-symmetry axis): each turn is refined.

    Parameters
    ----------
    points : (n, 3) float
        The data points, touch frame; at least 6.
    T_model_touch : (4, 4) float
        The fitted pose.
    point, normal : (3,) float
        The contact and its normal, touch frame.

    Returns
    -------
    list of (4, 4) float64

    Raises
    ------
    ValueError
        If ``points`` is not (n, 3) finite with n >= 6, ``T_model_touch`` is not a finite
        (4, 4) array, ``point`` or ``normal`` is not a finite 3-vector or ``normal`` is
        zero.
    """
    check_points(points, "points", min_rows=6)
    T = check_transform(T_model_touch, "T_model_touch")
    p = check_vector(point, "point")
    axis = T[:3, :3] @ check_vector(normal, "normal", unit=True)
    through = T[:3, :3] @ p + T[:3, 3]
    return [
        turn_about(np.radians(deg), axis, through) @ T for deg in defaults.NORMAL_TURN_ANGLES_DEG
    ]


def _turn_scan(model, y, spread: float, axis, through, keep: int) -> list[np.ndarray]:
    """The settled motions (4, 4) at the ``keep`` deepest other basins of a whole turn of
    the points ``y`` (model frame) about ``axis`` through ``through``."""
    radius = float(np.max(np.linalg.norm(np.cross(y - through, axis), axis=1)))
    if not radius > 0.0:
        return []
    n = int(np.ceil(2.0 * np.pi * radius / (defaults.WEAK_SCAN_STEP * spread)))
    angles = np.linspace(0.0, 2.0 * np.pi, min(max(n, 3), defaults.WEAK_SCAN_MOST), endpoint=False)
    poses, score = _settled(model, y, np.array([turn_about(a, axis, through) for a in angles]))
    apart = defaults.WEAK_SCAN_APART * spread
    return [poses[i] for i in _distinct_deepest(y, poses, score, apart, keep)]


def _settled(model, y: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each of ``poses`` (k, 4, 4) after ``defaults.WEAK_SCAN_SETTLE`` damped
    point-to-plane steps of the points ``y`` (n, 3) onto the surface, and the points' mean
    squared distance there (k,).

    Scored as it lands, a scan step reads the basin it lies in badly: a step about a
    scanned can's axis lands a millimetre off the surface when the model's axis is that
    far from the one turned about, and a turn about a touch's normal on a surface curved
    unequally both ways moves the curves off it by far more than the fit that the basin
    holds. Settled, each step reads its basin. All the poses at once: one closest-point
    query per step, then a 6 x 6 solve per pose."""
    k, n = len(poses), len(y)
    settled = np.array(poses, dtype=np.float64)
    for _ in range(defaults.WEAK_SCAN_SETTLE):
        moved = np.einsum("kij,nj->kni", settled[:, :3, :3], y) + settled[:, None, :3, 3]
        _, closest, face = model.surface.closest_points(moved.reshape(-1, 3))
        normal = model.mesh.face_normals[face].reshape(k, n, 3)
        r = np.einsum("kni,kni->kn", moved - closest.reshape(k, n, 3), normal)
        centre = moved.mean(axis=1)
        J = np.concatenate([normal, np.cross(moved - centre[:, None], normal)], axis=2)
        A = np.einsum("kni,knj->kij", J, J)
        A += 1e-3 * np.trace(A, axis1=1, axis2=2)[:, None, None] / 6.0 * np.eye(6)
        step = -np.linalg.solve(A, np.einsum("kni,kn->ki", J, r)[..., None])[..., 0]
        R = Rotation.from_rotvec(step[:, 3:]).as_matrix()  # (k, 3, 3)
        M = np.tile(np.eye(4), (k, 1, 1))
        M[:, :3, :3] = R
        M[:, :3, 3] = centre - np.einsum("kij,kj->ki", R, centre) + step[:, :3]
        settled = M @ settled
    moved = np.einsum("kij,nj->kni", settled[:, :3, :3], y) + settled[:, None, :3, 3]
    d = model.surface.closest_points(moved.reshape(-1, 3))[0].reshape(k, n)
    return settled, np.mean(d**2, axis=1)


def _distinct_deepest(
    y: np.ndarray, settled: np.ndarray, score: np.ndarray, apart: float, keep: int
) -> list[int]:
    """Up to ``keep`` indices of ``settled`` (k, 4, 4), least ``score`` first, each placing
    the points ``y`` more than ``apart`` from the identity (the pose scanned from) and from
    those already taken: the deepest distinct basins of the scan (settled steps in one
    basin land on one pose)."""
    placed = np.einsum("kij,nj->kni", settled[:, :3, :3], y) + settled[:, None, :3, 3]
    taken: list[int] = []
    for i in np.argsort(score, kind="stable"):
        if np.max(np.linalg.norm(placed[i] - y, axis=1)) <= apart:
            continue
        if any(np.max(np.linalg.norm(placed[i] - placed[j], axis=1)) <= apart for j in taken):
            continue
        taken.append(int(i))
        if len(taken) == keep:
            break
    return taken


def exploration_starts(
    model, points: np.ndarray, T_model_touch: np.ndarray, contacts=()
) -> list[np.ndarray]:
    """Every start from which a pose about to be given is refined again: along its
    weakest motions (:func:`weak_motion_starts`), turned about the touches' normals at
    their contacts (:func:`normal_turn_starts`), all round the model's near-symmetry axes
    (:func:`near_symmetry_scan`), and carried by each of the model's near-symmetric
    half-turns (a can turned upside down), with the turns about the axes from there.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        The data points, touch frame; at least 6.
    T_model_touch : (4, 4) float
        The fitted pose.
    contacts : sequence of ((3,) float, (3,) float)
        Each touch's contact and unit normal, touch frame (its ``LocalGeometry``'s
        ``point`` and ``normal``).

    Returns
    -------
    list of (4, 4) float64

    Raises
    ------
    ValueError
        As :func:`weak_motion_starts` and :func:`normal_turn_starts`.
    """
    T = check_transform(T_model_touch, "T_model_touch")
    starts = weak_motion_starts(model, points, T)
    for point, normal in contacts:
        starts += normal_turn_starts(points, T, point, normal)
    starts += near_symmetry_scan(model, points, T)
    for S in model.near_symmetries.half_turns:
        turned = S @ T
        starts += [turned, *near_symmetry_scan(model, points, turned)]
    return starts


@dataclass(frozen=True)
class _Motion:
    """One weak motion: a turn about ``axis`` through ``through``, or a slide along
    ``axis``; ``spread`` is the points' RMS spread."""

    turn: bool
    axis: np.ndarray
    through: np.ndarray
    spread: float

    def moved(self, amount: float) -> np.ndarray:
        """The (4, 4) motion by ``amount`` (radians for a turn, model units for a slide)."""
        if self.turn:
            return turn_about(amount, self.axis, self.through)
        M = np.eye(4)
        M[:3, 3] = amount * self.axis
        return M


def _weak_motions(model, x: np.ndarray, T: np.ndarray, ratio: float, most: int) -> list[_Motion]:
    """The rigid Jacobian's weak motions at pose ``T``, weakest first."""
    y = apply_transform(T, x)
    grad = residuals(model, y).gradient
    norm = np.linalg.norm(grad, axis=1)
    ok = norm > 0.0
    if np.count_nonzero(ok) < 6:
        return []
    y, n = y[ok], grad[ok] / norm[ok, None]
    c = y.mean(axis=0)
    spread = float(np.sqrt(((y - c) ** 2).sum(axis=1).mean()))
    if spread <= 0.0:
        return []
    J = np.hstack([n, np.cross((y - c) / spread, n)])
    _, s, vt = np.linalg.svd(J, full_matrices=False)
    weak = [v for v, r in zip(vt[::-1], (s / s[0])[::-1], strict=True) if r < ratio][:most]
    out = []
    for v in weak:
        t, w = v[:3], v[3:] / spread  # the rotation in radians per unit twist
        if np.linalg.norm(v[3:]) >= defaults.POSE_TURN_FRACTION:
            axis = w / np.linalg.norm(w)
            through = c + np.cross(w, t) / float(w @ w)  # the point of the axis nearest c
            out.append(_Motion(True, axis, through, spread))
        else:
            out.append(_Motion(False, t / np.linalg.norm(t), c, spread))
    return out
