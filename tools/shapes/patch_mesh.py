"""Meshing an open patch: outline, area-uniform samples, Delaunay, relaxation, subdivision."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import Delaunay, cKDTree

from shapes.connectivity import boundary_vertices, signed_area, wind_counterclockwise
from shapes.params import COARSE_STEPS, FINE_STEPS, SUBDIVISIONS
from shapes.relax import relax

__all__ = ["area_elements", "mesh_patch", "resample_outline", "sample_patch"]


def resample_outline(patch, spacing):
    """Points along the closed outline of a patch, evenly spaced in 3D arc length.

    Parameters
    ----------
    patch : GraphPatch
        The patch.
    spacing : float
        Wanted 3D distance between consecutive points.

    Returns
    -------
    (k, 2) float ndarray
        Counter-clockwise xy points on the domain boundary, not repeating the first.
    """
    pieces = []
    for piece in patch.outline():
        xyz = patch.lift(piece)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
        count = max(round(s[-1] / spacing), 3)
        t = np.linspace(0.0, s[-1], count + 1)[:-1]
        pieces.append(np.column_stack([np.interp(t, s, piece[:, 0]), np.interp(t, s, piece[:, 1])]))
    return patch.snap(np.concatenate(pieces))


def area_elements(patch, n=1001):
    """Area element of a patch at the cell centres of an ``n x n`` grid over its box.

    Parameters
    ----------
    patch : GraphPatch
        The patch.
    n : int
        Cells per side.

    Returns
    -------
    values : (n * n,) float ndarray
        ``sqrt(1 + |grad g|^2)`` inside the domain, 0 outside.
    cell : float
        Area of a grid cell in the xy-plane.
    """
    xmin, xmax, ymin, ymax = patch.box
    x = xmin + (np.arange(n) + 0.5) * (xmax - xmin) / n
    y = ymin + (np.arange(n) + 0.5) * (ymax - ymin) / n
    xy = np.column_stack([np.repeat(x, n), np.tile(y, n)])
    cell = (xmax - xmin) * (ymax - ymin) / n**2
    return patch.area_element(xy) * patch.inside(xy), cell


def sample_patch(patch, count, rng, batch=20_000):
    """Random points of the domain whose lift is uniform in surface area (rejection sampling).

    Parameters
    ----------
    patch : GraphPatch
        The patch.
    count : int
        Number of points wanted.
    rng : numpy.random.Generator
        Random source.
    batch : int
        Candidates drawn per round.

    Returns
    -------
    (count, 2) float ndarray
    """
    xmin, xmax, ymin, ymax = patch.box
    top = 1.05 * float(area_elements(patch)[0].max())  # bound of the acceptance ratio
    kept = []
    total = 0
    while total < count:
        xy = rng.uniform([xmin, ymin], [xmax, ymax], size=(batch, 2))
        take = patch.inside(xy) & (rng.uniform(0.0, top, size=batch) < patch.area_element(xy))
        kept.append(xy[take])
        total += int(take.sum())
    return np.concatenate(kept)[:count]


def mesh_patch(patch, faces_wanted, seed):
    """Evenly sized, well-shaped triangulation of an open patch, normals pointing to +z.

    A coarse mesh (``faces_wanted / 4**SUBDIVISIONS`` faces) of random interior points and
    evenly spaced outline points is relaxed, then subdivided at the midpoints, snapped back
    onto the outline and the surface, and relaxed a little after each subdivision.

    Parameters
    ----------
    patch : GraphPatch
        The patch.
    faces_wanted : int
        Aimed-at number of faces.
    seed : int
        Seed of the random initial points.

    Returns
    -------
    trimesh.Trimesh
    """
    coarse_faces = faces_wanted / 4**SUBDIVISIONS
    values, cell = area_elements(patch)
    # edge of the equilateral triangle of mean area
    spacing = np.sqrt(4.0 * float(values.sum()) * cell / (np.sqrt(3.0) * coarse_faces))
    outline = resample_outline(patch, spacing)
    # a triangulated disc has faces = 2 * vertices - boundary vertices - 2
    n_inner = round((coarse_faces - len(outline) + 2) / 2)
    rng = np.random.default_rng(seed)
    inner = sample_patch(patch, 4 * n_inner, rng)
    near, _ = cKDTree(patch.lift(outline)).query(patch.lift(inner))
    inner = inner[near > 0.5 * spacing][:n_inner]
    xy = np.concatenate([outline, inner])
    faces = wind_counterclockwise(xy, Delaunay(xy).simplices)
    # Qhull may return zero-area triangles on collinear hull points (the sides of the
    # square); without them, each side is the chain of its outline points
    faces = faces[signed_area(xy, faces) > 1e-12 * spacing**2]
    xyz = patch.lift(xy)
    fixed = np.arange(len(xyz)) < len(outline)
    xyz, faces = relax(xyz, faces, fixed, patch, COARSE_STEPS)
    for _ in range(SUBDIVISIONS):
        xyz, faces = trimesh.remesh.subdivide(xyz, faces)
        fixed = boundary_vertices(faces, len(xyz))
        xyz[fixed, :2] = patch.snap(xyz[fixed, :2])
        xyz = patch.project(xyz)
        xyz, faces = relax(xyz, faces, fixed, patch, FINE_STEPS)
    return trimesh.Trimesh(xyz, faces, process=True)

