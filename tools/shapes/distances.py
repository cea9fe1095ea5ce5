"""First-order distances |f| / |grad f| of points to the analytic surfaces."""

from __future__ import annotations

import numpy as np

__all__ = ["ellipsoid_distance", "patch_distance", "prism_distance", "sphere_distance"]


def ellipsoid_distance(points, abc):
    """First-order distance of ``(k, 3)`` points to the ellipsoid with semi-axes ``abc``."""
    abc = np.asarray(abc, dtype=float)
    f = np.sum((points / abc) ** 2, axis=1) - 1.0
    return np.abs(f) / np.linalg.norm(2.0 * points / abc**2, axis=1)


def patch_distance(points, patch):
    """First-order distance of ``(k, 3)`` points to the graph ``z = g(x, y)`` of a patch."""
    f = points[:, 2] - patch.height(points[:, 0], points[:, 1])
    return np.abs(f) / patch.area_element(points[:, :2])


def prism_distance(points, a, b, height):
    """First-order distance of ``(k, 3)`` points to an elliptic cylinder with flat caps.

    The smaller of the distance to the side ``x^2/a^2 + y^2/b^2 = 1`` and to the cap planes
    ``z = +-height/2``.
    """
    x, y = points[:, 0], points[:, 1]
    f = (x / a) ** 2 + (y / b) ** 2 - 1.0
    side = np.abs(f) / np.hypot(2.0 * x / a**2, 2.0 * y / b**2)
    return np.minimum(side, np.abs(np.abs(points[:, 2]) - height / 2.0))


def sphere_distance(points, radius):
    """First-order distance of ``(k, 3)`` points to the sphere of the given radius."""
    r = np.linalg.norm(points, axis=1)
    return np.abs(r**2 - radius**2) / (2.0 * r)

