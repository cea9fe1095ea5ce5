"""Which free motions of a pose are symmetries of the whole model.

:func:`~meshrec.recognition.freedom.pose_freedom` finds the rigid motions that leave the
touch data's residuals unchanged. Some of them move the data along a flat face or a
cylinder's side that ends somewhere: the object's pose is then truly not fixed. Others
map the whole model onto itself (a turn about a body of revolution's axis, any turn about
a sphere's centre): every pose along such a motion is the same placement of the object,
and the pose is fixed up to the model's symmetry, as every pose of a symmetric object is.

The test moves points spread over the whole model's surface by a finite amount of the
motion and measures how far they land from the surface. No library routine tests a mesh
for a given continuous symmetry (trimesh's ``symmetry`` property names only the radial
and spherical symmetries of the inertia tensor, not whether the surface has them about a
given axis, and nothing for slides), so it is written here.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.recognition.freedom import PoseFreedom
from meshrec.registration.objective import residuals

__all__ = ["without_symmetries"]


def _surface_points(model) -> np.ndarray:
    """Vertices and face centroids of the model's mesh, at most SYMMETRY_POINTS of them."""
    mesh = model.mesh
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    pts = np.vstack([mesh.vertices, centres])
    stride = max(1, len(pts) // defaults.SYMMETRY_POINTS)
    return np.asarray(pts[::stride], dtype=np.float64)


def _lands_on_surface(model, moved: np.ndarray, start: np.ndarray, tol: float) -> bool:
    # Against the residuals before the motion: a probe model's surface is offset from
    # its mesh by the tip radius.
    d = residuals(model, moved).values - start
    return bool(np.sqrt(np.mean(d**2)) <= tol)


def without_symmetries(model, freedom: PoseFreedom, noise: float) -> PoseFreedom:
    """The free motions that are not symmetries of the model, and those that are.

    A slide is moved by ``defaults.SYMMETRY_SLIDE`` times the model's bounding-box
    diagonal, a turn by ``defaults.SYMMETRY_TURN_RAD`` about its axis; the motion is a
    symmetry when the model's surface points land back on its surface within an RMS of
    ``max(defaults.SYMMETRY_NOISE x noise, defaults.SYMMETRY_TOL x diagonal)`` (the turn's
    axis is estimated from noisy data, and a faceted mesh turned off its facets lands
    within its chord error).

    Parameters
    ----------
    model : ModelIndex
        The model the pose belongs to.
    freedom : PoseFreedom
        The free motions at the pose, model frame.
    noise : float
        The touches' noise (model units), at least 0.

    Returns
    -------
    PoseFreedom
        ``freedom`` with the symmetric motions moved from ``slides``/``turns`` (and
        ``free``) to ``symmetries`` (phrases such as ``"turn about (0, 0, 1)"``).

    Raises
    ------
    ValueError
        If ``noise`` is negative or not finite.
    """
    if not (np.isfinite(noise) and noise >= 0.0):
        raise ValueError(f"noise must be a finite number >= 0, got {noise!r}")
    if freedom.free == 0:
        return freedom
    pts = _surface_points(model)
    diag = float(np.linalg.norm(np.ptp(model.mesh.vertices, axis=0)))
    start = residuals(model, pts).values
    tol = max(defaults.SYMMETRY_NOISE * float(noise), defaults.SYMMETRY_TOL * diag)
    keep_slides, symmetries = [], []
    for d in freedom.slide_directions:
        if _lands_on_surface(model, pts + defaults.SYMMETRY_SLIDE * diag * d, start, tol):
            symmetries.append(f"slide along {np.array2string(d, precision=3)}")
        else:
            keep_slides.append(d)
    keep_turns = []
    for axis, point in zip(freedom.turn_axes, freedom.turn_points, strict=True):
        R = Rotation.from_rotvec(defaults.SYMMETRY_TURN_RAD * axis).as_matrix()
        moved = (pts - point) @ R.T + point
        if _lands_on_surface(model, moved, start, tol):
            symmetries.append(f"turn about {np.array2string(axis, precision=3)}")
        else:
            keep_turns.append((axis, point))
    if not symmetries:
        return freedom
    return dataclasses.replace(
        freedom,
        free=len(keep_slides) + len(keep_turns),
        slides=len(keep_slides),
        turns=len(keep_turns),
        slide_directions=np.array(keep_slides, dtype=np.float64).reshape(-1, 3),
        turn_axes=np.array([a for a, _ in keep_turns], dtype=np.float64).reshape(-1, 3),
        turn_points=np.array([p for _, p in keep_turns], dtype=np.float64).reshape(-1, 3),
        symmetries=tuple(symmetries),
    )
