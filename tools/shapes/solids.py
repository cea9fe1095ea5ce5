"""The closed shapes: the ellipsoid and the sphere (icospheres), and elliptic cylinders."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import Delaunay

from shapes.connectivity import wind_counterclockwise
from shapes.params import ELLIPSOID_ABC, SPHERE_RADIUS

__all__ = [
    "cap_faces",
    "ellipse_perimeter",
    "ellipse_ring",
    "ellipsoid_mesh",
    "elliptic_prism",
    "sphere_mesh",
]


def ellipsoid_mesh():
    """The ellipsoid of the paper, a subdivided icosphere scaled by its semi-axes.

    Scaling keeps every vertex exactly on the ellipsoid, avoids the slivers a (u, v) grid has
    at its poles, and leaves the triangles smallest near the ends of the long axis, where the
    ellipsoid is most curved.

    Returns
    -------
    trimesh.Trimesh
    """
    mesh = trimesh.creation.icosphere(subdivisions=6)
    mesh.apply_scale(ELLIPSOID_ABC)
    return mesh


def sphere_mesh():
    """The sphere of the experiment, a subdivided icosphere (radius in mm)."""
    return trimesh.creation.icosphere(subdivisions=6, radius=SPHERE_RADIUS)


def ellipse_ring(a, b, count, phase):
    """Points on an ellipse, evenly spaced in arc length, counter-clockwise.

    Parameters
    ----------
    a, b : float
        Semi-axes along x and y.
    count : int
        Number of points.
    phase : float
        Offset of the first point from ``(a, 0)``, in units of the spacing.

    Returns
    -------
    (count, 2) float ndarray
        Points exactly on the ellipse.
    """
    t = np.linspace(0.0, 2.0 * np.pi, 20_001)
    dense = np.column_stack([a * np.cos(t), b * np.sin(t)])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    tt = np.interp((np.arange(count) + phase) * s[-1] / count, s, t)
    return np.column_stack([a * np.cos(tt), b * np.sin(tt)])


def ellipse_perimeter(a, b):
    """Perimeter of an ellipse (Ramanujan's second approximation, exact for a circle)."""
    h = ((a - b) / (a + b)) ** 2
    return np.pi * (a + b) * (1.0 + 3.0 * h / (10.0 + np.sqrt(4.0 - 3.0 * h)))


def cap_faces(rim, a, b, rings, top):
    """Flat cap of a cylinder: concentric rings inside its rim, Delaunay-triangulated.

    Parameters
    ----------
    rim : (n, 2) float ndarray
        Rim points (a row of the side), counter-clockwise.
    a, b : float
        Semi-axes of the rim ellipse.
    rings : int
        Number of ring intervals from the centre to the rim.
    top : bool
        Wind for an upward normal (top cap) or a downward one (bottom cap).

    Returns
    -------
    inner : (k, 2) float ndarray
        The cap's own points (rings and centre).
    faces : (m, 3) int ndarray
        Triangles indexing ``rim`` (indices below ``n``) then ``inner``.
    """
    inner = [np.zeros((1, 2))]
    for k in range(1, rings):
        scale = k / rings
        count = max(round(len(rim) * scale), 3)
        inner.append(ellipse_ring(a * scale, b * scale, count, 0.5 * (k % 2)))
    inner = np.concatenate(inner[::-1])
    points = np.concatenate([rim, inner])
    tri = Delaunay(points)
    if len(tri.coplanar):
        raise RuntimeError("cap triangulation dropped points")
    faces = wind_counterclockwise(points, tri.simplices)
    return inner, faces if top else faces[:, ::-1]


def elliptic_prism(a, b, height, faces_wanted):
    """Closed elliptic (or circular) cylinder along z, centred at the origin, flat caps.

    The side is a lattice of rings whose points are offset by half a step on every other
    ring, so that its triangles are nearly equilateral; the caps are rings inside the rim.
    Written here because ``trimesh.creation.cylinder`` makes one band of side triangles as
    tall as the cylinder and fan caps, and has no elliptic section.

    Parameters
    ----------
    a, b : float
        Semi-axes of the section along x and y.
    height : float
        Length along z.
    faces_wanted : int
        Aimed-at number of faces.

    Returns
    -------
    trimesh.Trimesh
    """
    perimeter = ellipse_perimeter(a, b)
    area = perimeter * height + 2.0 * np.pi * a * b
    edge = np.sqrt(4.0 * area / (np.sqrt(3.0) * faces_wanted))
    row_step = edge * np.sqrt(3.0) / 2.0
    n = round(perimeter / edge)
    rows = round(height / row_step)
    rings = max(round(np.sqrt(a * b) / row_step), 1)

    side = []
    for j in range(rows + 1):
        ring = ellipse_ring(a, b, n, 0.5 * (j % 2))
        side.append(np.column_stack([ring, np.full(n, -height / 2.0 + j * height / rows)]))
    vertices = [np.concatenate(side)]

    i = np.arange(n)
    nxt = (i + 1) % n
    faces = []
    for j in range(rows):
        lo, up = j * n, (j + 1) * n
        if j % 2 == 0:  # the upper ring is shifted half a step ahead of the lower one
            faces += [np.column_stack([lo + i, lo + nxt, up + i])]
            faces += [np.column_stack([lo + nxt, up + nxt, up + i])]
        else:  # the lower ring is shifted half a step ahead of the upper one
            faces += [np.column_stack([lo + i, lo + nxt, up + nxt])]
            faces += [np.column_stack([lo + i, up + nxt, up + i])]

    offset = len(vertices[0])
    for first, z, top in ((0, -height / 2.0, False), (rows * n, height / 2.0, True)):
        rim = vertices[0][first : first + n, :2]
        inner, cap = cap_faces(rim, a, b, rings, top)
        index = np.concatenate([first + i, offset + np.arange(len(inner))])
        vertices.append(np.column_stack([inner, np.full(len(inner), z)]))
        faces.append(index[cap])
        offset += len(inner)
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=True)

