"""Where a probe moving along a ray first meets a mesh: the simulated robot's next touch."""

from __future__ import annotations

import igl
import numpy as np

from meshrec.io.checks import check_vector

__all__ = ["first_hit"]


def first_hit(vertices, faces, origin, direction) -> np.ndarray | None:
    """The first point where the ray ``origin + t direction`` (t >= 0) meets the mesh.

    libigl's ``ray_mesh_intersect`` (one ray, every face: about 0.13 ms on 5k faces, fine
    for a simulated robot's few touches; a batch of rays would want an acceleration
    structure such as Open3D's RaycastingScene).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (F, 3) int
    origin : (3,) float
        Where the probe starts, outside the object.
    direction : (3,) float
        The direction it moves in (any length but zero).

    Returns
    -------
    (3,) float or None
        The first hit, or None when the ray misses the mesh.

    Raises
    ------
    ValueError
        If ``origin`` or ``direction`` is not a finite 3-vector, or ``direction`` is zero.
    """
    o = check_vector(origin, "origin")
    d = check_vector(direction, "direction", unit=True)
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    # every hit along the line (libigl also reports those behind the origin): the nearest
    # one ahead
    hits = igl.ray_mesh_intersect(o, d, V, F, first=False) or []
    ahead = [float(h[1]) for h in hits if h[1] >= 0.0]
    if not ahead:
        return None
    return o + min(ahead) * d
