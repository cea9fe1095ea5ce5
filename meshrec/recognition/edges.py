"""Touches across sharp edges (issue 13, item 3): registered, with a warning.

A touch whose curves cross a sharp feature edge of the model (a box's edge, a cylinder's
rim: faces meeting at more than ``defaults.SITE_CREASE_ANGLE_DEG``) has no single (K, H)
at its contact; the table's crease sites let such a touch still find its pose (see
:mod:`meshrec.model.sites`), and the answer says that the touch crossed an edge: the data
at the best pose lie on two or more smooth patches of the model
(:attr:`meshrec.model.curvature.CurvatureTable.face_patch`).
"""

from __future__ import annotations

import warnings

import numpy as np

from meshrec import defaults
from meshrec.registration.transform import apply_transform

__all__ = ["SharpEdgeWarning", "patches_crossed", "patches_touched", "warn_sharp_edges"]


class SharpEdgeWarning(UserWarning):
    """The touch crossed a sharp edge of the model it was registered on."""


def patches_touched(model, points: np.ndarray) -> np.ndarray:
    """The smooth patches of ``model`` the points lie on, with the points on each.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        Points in model coordinates (e.g. the touch placed by its pose).

    Returns
    -------
    (k, 2) int64
        Rows ``(patch, count)``: each patch holding at least one point's closest surface
        point, and how many; most points first.

    Raises
    ------
    ValueError
        If ``points`` is not an (n, 3) array of finite numbers.
    """
    _, _, face = model.surface.closest_points(points)
    patch, count = np.unique(model.curvature.face_patch[face], return_counts=True)
    order = np.argsort(-count, kind="stable")
    return np.column_stack([patch[order], count[order]]).astype(np.int64)


def patches_crossed(model, points: np.ndarray) -> int:
    """How many smooth patches of ``model`` hold at least ``defaults.EDGE_MIN_POINTS`` of
    the points (a point or two pushed over an edge by the noise do not count): more than
    1 when the points cross a sharp edge.

    Parameters
    ----------
    model : ModelIndex
    points : (n, 3) float
        Points in model coordinates.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        If ``points`` is not an (n, 3) array of finite numbers.
    """
    rows = patches_touched(model, points)
    return int(np.sum(rows[:, 1] >= defaults.EDGE_MIN_POINTS))


def warn_sharp_edges(rec, models) -> int:
    """A SharpEdgeWarning when the data at the best model's pose cross a sharp edge.

    A patch counts when at least ``defaults.EDGE_MIN_POINTS`` points lie on it (a point
    or two pushed over an edge by the noise do not).

    Parameters
    ----------
    rec : Recognition
    models : list of ModelIndex
        The models recognised against (``rec.best.model`` among them).

    Returns
    -------
    int
        The faces or smooth patches the data lie on (0 when no model was registered); the
        warning is raised when it is more than 1.
    """
    best = rec.best
    if best is None or best.T_model_touch is None:
        return 0
    model = next((m for m in models if m.name == best.model), None)
    if model is None:
        return 0
    touches = rec.touches or (rec.touch,)
    points = apply_transform(best.T_model_touch, np.vstack([t.points for t in touches]))
    crossed = patches_crossed(model, points)
    if crossed > 1:
        warnings.warn(
            f"the touch crosses a sharp edge of {best.model!r} (its points lie on {crossed} "
            "faces or smooth patches that meet at sharp edges): the curvature at the contact "
            "is not defined there, and the pose rests on the fit across the edge",
            SharpEdgeWarning,
            stacklevel=3,
        )
    return crossed
