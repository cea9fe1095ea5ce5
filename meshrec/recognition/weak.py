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
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.io.checks import check_points
from meshrec.registration.objective import residuals
from meshrec.registration.transform import apply_transform

__all__ = ["weak_motion_starts"]


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
    T = np.asarray(T_model_touch, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"T_model_touch must be a finite (4, 4) array, got shape {T.shape}")
    if not (isinstance(ratio, (int, float)) and 0.0 < float(ratio) < 1.0):
        raise ValueError(f"ratio must be a number in (0, 1), got {ratio!r}")
    if not isinstance(most, (int, np.integer)) or isinstance(most, bool) or most < 1:
        raise ValueError(f"most must be a positive integer, got {most!r}")
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
            for deg in defaults.WEAK_TURN_ANGLES_DEG:
                R = Rotation.from_rotvec(np.radians(deg) * axis).as_matrix()
                out.append(_about(R, through) @ T)
        else:
            d = t / np.linalg.norm(t)
            for step in defaults.WEAK_SLIDE_STEPS:
                for sign in (1.0, -1.0):
                    M = np.eye(4)
                    M[:3, 3] = sign * step * spread * d
                    out.append(M @ T)
    return out


def _about(R: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The (4, 4) rotation ``R`` about an axis through ``point``."""
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = point - R @ point
    return M
