"""Rigid transforms: building ``T_model_touch`` from a superposition, and applying it."""

from __future__ import annotations

import numpy as np

from meshrec.registration.chart import SurfacePoint, rotation_z

__all__ = ["apply_transform", "invert_transform", "superposition"]


def superposition(
    data_point: np.ndarray, data_frame: np.ndarray, surface: SurfacePoint, phi: float
) -> np.ndarray:
    """The transform that lays the data frame onto a surface point, rotated by ``phi``.

    Implements the paper's Section 2.2: a data point x is taken to the data frame,
    x' = F^T (x - p), rotated by ``phi`` about the frame's z axis (the normal), and placed
    in the model's tangent frame at q: x'' = D Rz(phi) x' + q.

    Parameters
    ----------
    data_point : (3,) float
        The curves' common point p, touch coordinates.
    data_frame : (3, 3) float
        Columns t1, t2, N at p, touch coordinates.
    surface : SurfacePoint
        The point q on the model and its frame D = (d1, d2, n).
    phi : float
        Rotation about the common normal, radians.

    Returns
    -------
    (4, 4) float
        ``T_model_touch``: maps touch-frame points to model coordinates.
    """
    R = surface.frame @ rotation_z(phi) @ data_frame.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = surface.point - R @ data_point
    return T


def apply_transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a (4, 4) rigid transform to (n, 3) points."""
    return points @ T[:3, :3].T + T[:3, 3]


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Invert a (4, 4) rigid transform."""
    R, t = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out
