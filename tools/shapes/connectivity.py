"""Connectivity of triangle lists: directed and unique edges, boundaries, planar winding."""

from __future__ import annotations

import numpy as np

__all__ = [
    "boundary_vertices",
    "corner_angle",
    "directed_edges",
    "faces_valid",
    "reverse_index",
    "signed_area",
    "unique_edges",
    "wind_counterclockwise",
]


def directed_edges(faces):
    """Directed edges of a triangle list with the opposite corner and owning face.

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    u, v, opposite, face : (3m,) int ndarray
        Edge ``u -> v`` of triangle ``face``, whose third corner is ``opposite``.
    """
    u = faces.ravel()
    v = np.roll(faces, -1, axis=1).ravel()
    opposite = np.roll(faces, -2, axis=1).ravel()
    face = np.repeat(np.arange(len(faces)), 3)
    return u, v, opposite, face


def reverse_index(u, v, n_vertices):
    """Index of the reverse of every directed edge, or -1 where it has none.

    Parameters
    ----------
    u, v : (k,) int ndarray
        Directed edges ``u -> v``.
    n_vertices : int
        Number of vertices (to build integer edge keys).

    Returns
    -------
    (k,) int ndarray
        ``j`` with ``(u[j], v[j]) == (v[i], u[i])``, or -1.
    """
    key = u.astype(np.int64) * n_vertices + v
    reverse = v.astype(np.int64) * n_vertices + u
    order = np.argsort(key, kind="stable")
    pos = np.clip(np.searchsorted(key[order], reverse), 0, len(key) - 1)
    found = key[order][pos] == reverse
    return np.where(found, order[pos], -1)


def boundary_vertices(faces, n_vertices):
    """Mask of the vertices on the boundary (edges used by one face only).

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.
    n_vertices : int
        Number of vertices.

    Returns
    -------
    (n_vertices,) bool ndarray
    """
    u, v, _, _ = directed_edges(faces)
    lonely = reverse_index(u, v, n_vertices) < 0
    mask = np.zeros(n_vertices, dtype=bool)
    mask[u[lonely]] = True
    mask[v[lonely]] = True
    return mask


def unique_edges(faces):
    """Undirected edges of a triangle list, each once.

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    (k, 2) int ndarray
    """
    u, v, _, _ = directed_edges(faces)
    lo = np.minimum(u, v).astype(np.int64)
    hi = np.maximum(u, v).astype(np.int64)
    n = int(hi.max()) + 1
    key = np.unique(lo * n + hi)
    return np.column_stack([key // n, key % n])


def signed_area(xy, faces):
    """Twice the signed areas of planar triangles, positive when counter-clockwise."""
    tri = xy[faces]
    d1 = tri[:, 1] - tri[:, 0]
    d2 = tri[:, 2] - tri[:, 0]
    return d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]


def wind_counterclockwise(xy, faces):
    """Reorder triangles of a planar triangulation to counter-clockwise winding."""
    clockwise = signed_area(xy, faces) < 0
    faces = faces.copy()
    faces[clockwise] = faces[clockwise][:, ::-1]
    return faces


def corner_angle(p, q, r):
    """Angle at ``p`` of the triangles ``(p, q, r)``, row by row, in radians."""
    a = q - p
    b = r - p
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def faces_valid(xyz, faces):
    """Whether the triangles of a graph patch are counter-clockwise seen from above.

    For a patch ``z = g(x, y)`` this is exactly "not folded over" (normal towards +z).

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices.
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    (m,) bool ndarray
    """
    return signed_area(xyz[:, :2], faces) > 0.0

