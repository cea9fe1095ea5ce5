"""Relaxation of a mesh on a smooth surface: Delaunay edge flips and DistMesh-style springs.

trimesh has no isotropic remesher (only subdivision), so the open patches z = g(x, y) are
relaxed here: Delaunay edge flips measured in 3D keep the triangles fat, and the repulsive
edge springs of DistMesh (Persson & Strang 2004), moved in the tangent plane and projected
back onto the surface, make the edges even in 3D, also where the monkey saddle is steep.
Flips and moves that would turn a triangle clockwise in the xy-plane are refused.
"""

from __future__ import annotations

import numpy as np

from shapes.connectivity import (
    corner_angle,
    directed_edges,
    faces_valid,
    reverse_index,
    unique_edges,
)
from shapes.params import SPRING_PRESSURE, SPRING_STEP

__all__ = ["flip_to_delaunay", "relax", "spring_step"]


def flip_to_delaunay(xyz, faces, max_passes=50):
    """Flip interior edges until the two angles facing each edge sum to at most pi (in 3D).

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above); not modified.
    max_passes : int
        Largest number of rounds of independent flips.

    Returns
    -------
    (m, 3) int ndarray
        Flipped triangles, same winding.
    """
    faces = faces.copy()
    for _ in range(max_passes):
        u, v, opp, face = directed_edges(faces)
        rev = reverse_index(u, v, len(xyz))
        first = np.nonzero((rev >= 0) & (u < v))[0]
        second = rev[first]
        u, v = u[first], v[first]
        a, b = opp[first], opp[second]
        excess = (
            corner_angle(xyz[a], xyz[u], xyz[v]) + corner_angle(xyz[b], xyz[v], xyz[u]) - np.pi
        )
        cand = np.nonzero(excess > 1e-9)[0]
        new1 = np.column_stack([u[cand], b[cand], a[cand]])
        new2 = np.column_stack([b[cand], v[cand], a[cand]])
        ok = faces_valid(xyz, new1) & faces_valid(xyz, new2)
        cand, new1, new2 = cand[ok], new1[ok], new2[ok]
        if len(cand) == 0:
            break
        f1, f2 = face[first][cand], face[second][cand]
        used = np.zeros(len(faces), dtype=bool)
        for k in np.argsort(-excess[cand], kind="stable"):
            if used[f1[k]] or used[f2[k]]:
                continue
            used[f1[k]] = used[f2[k]] = True
            faces[f1[k]] = new1[k]
            faces[f2[k]] = new2[k]
    return faces


def spring_step(xyz, faces, fixed, patch):
    """Move the free vertices one DistMesh step along the surface.

    Edges shorter than ``SPRING_PRESSURE`` times the RMS edge length push their ends apart.
    The corner opposite a boundary edge is also pushed away from its mirror image across that
    edge, as if the mesh went on beyond the fixed boundary; otherwise the pressure flattens
    the triangles along the boundary. The push is projected on the tangent plane and the
    vertex projected back onto the surface. A vertex whose move would fold a triangle over
    stays where it is.

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices on the surface.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above).
    fixed : (n,) bool ndarray
        Vertices that must not move (the boundary).
    patch : GraphPatch
        The surface.

    Returns
    -------
    (n, 3) float ndarray
        New vertices.
    """
    edges = unique_edges(faces)
    vec = xyz[edges[:, 0]] - xyz[edges[:, 1]]
    length = np.linalg.norm(vec, axis=1)
    rest = SPRING_PRESSURE * np.sqrt(np.mean(length**2))
    force = (np.maximum(rest - length, 0.0) / length)[:, None] * vec
    # boundary edges u -> v (counter-clockwise, so the mesh is on their left) and their apex w
    u, v, w, _ = directed_edges(faces)
    lonely = reverse_index(u, v, len(xyz)) < 0
    u, v, w = u[lonely], v[lonely], w[lonely]
    inward = np.cross(patch.normal(0.5 * (xyz[u] + xyz[v])), xyz[v] - xyz[u])
    inward /= np.linalg.norm(inward, axis=1)[:, None]
    height = np.einsum("ij,ij->i", xyz[w] - xyz[u], inward)
    wall = np.maximum(rest - 2.0 * height, 0.0)[:, None] * inward
    move = np.zeros_like(xyz)
    for k in range(3):
        move[:, k] = (
            np.bincount(edges[:, 0], force[:, k], minlength=len(xyz))
            - np.bincount(edges[:, 1], force[:, k], minlength=len(xyz))
            + np.bincount(w, wall[:, k], minlength=len(xyz))
        )
    n = patch.normal(xyz)
    move -= np.einsum("ij,ij->i", move, n)[:, None] * n
    move[fixed] = 0.0
    new = patch.project(xyz + SPRING_STEP * move)
    was_valid = faces_valid(xyz, faces)
    for _ in range(100):
        bad = was_valid & ~faces_valid(new, faces)
        if not bad.any():
            break
        back = np.unique(faces[bad])
        new[back] = xyz[back]
    return new


def relax(xyz, faces, fixed, patch, steps):
    """Alternate Delaunay flips and spring steps, ending with flips.

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices on the surface.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above).
    fixed : (n,) bool ndarray
        Vertices that must not move.
    patch : GraphPatch
        The surface.
    steps : int
        Number of spring steps.

    Returns
    -------
    xyz : (n, 3) float ndarray
    faces : (m, 3) int ndarray
    """
    for _ in range(steps):
        faces = flip_to_delaunay(xyz, faces)
        xyz = spring_step(xyz, faces, fixed, patch)
    return xyz, flip_to_delaunay(xyz, faces)

