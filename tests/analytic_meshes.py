"""Finely meshed analytic surfaces for the registration tests, and their closed forms.

Not a test module: test_chart.py, test_search.py, test_refine.py and test_candidates.py
import it. Every vertex of these meshes lies on its analytic surface, so the answers the
tests compare against (normals, closest points, curvatures) are known in closed form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from meshrec import ModelIndex

#: Semi-axes of the test ellipsoid (those of the paper's, so no two are equal).
ABC = np.array([1.0, 0.8, 0.5])


def index_of(mesh: trimesh.Trimesh, folder: Path, name: str) -> ModelIndex:
    """Write ``mesh`` as ``folder/name.stl`` and index it with a cache inside ``folder``."""
    path = Path(folder) / f"{name}.stl"
    mesh.export(path)
    return ModelIndex.from_file(path, cache_dir=Path(folder) / "cache")


def sphere(radius: float = 1.0, subdivisions: int = 5) -> trimesh.Trimesh:
    """An icosphere (20 * 4**subdivisions faces), outward normals."""
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def ellipsoid(subdivisions: int = 5) -> trimesh.Trimesh:
    """The icosphere scaled by :data:`ABC`: every vertex on the ellipsoid."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    mesh.apply_scale(ABC)
    return mesh


def tube(radius: float = 1.0, height: float = 4.0, sections: int = 256, rings: int = 64):
    """The side of a cylinder about z (open at both ends), wound for outward normals.

    ``trimesh.creation.cylinder`` makes side triangles as tall as the cylinder and shares
    their vertices with the caps, whose normals would tilt the side's vertex normals.
    """
    th = np.linspace(0.0, 2.0 * np.pi, sections, endpoint=False)
    z = np.linspace(-height / 2.0, height / 2.0, rings + 1)
    vertices = np.column_stack(
        [
            np.tile(radius * np.cos(th), rings + 1),
            np.tile(radius * np.sin(th), rings + 1),
            np.repeat(z, sections),
        ]
    )
    j = np.arange(sections)
    jn = (j + 1) % sections
    faces = []
    for i in range(rings):
        a, b = i * sections + j, i * sections + jn
        c, d = (i + 1) * sections + jn, (i + 1) * sections + j
        faces += [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    return trimesh.Trimesh(vertices, np.vstack(faces), process=False)


def ellipsoid_normal(points: np.ndarray) -> np.ndarray:
    """Outward unit normals of the ellipsoid :data:`ABC` at ``(n, 3)`` points on it."""
    g = np.atleast_2d(points) / ABC**2
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def on_ellipsoid(points: np.ndarray) -> np.ndarray:
    """Radial projection of ``(n, 3)`` points onto the ellipsoid :data:`ABC`."""
    p = np.atleast_2d(points)
    return p / np.linalg.norm(p / ABC, axis=1, keepdims=True)


def deepest_chord(mesh: trimesh.Trimesh, centre=(0.0, 0.0, 0.0), radius: float = 1.0) -> float:
    """How far inside a sphere (or a cylinder about z, with ``centre`` None) the faces reach.

    For a sphere, the least distance from its centre to a face's plane subtracted from the
    radius bounds the chord error of every point of the faces (a face lies between its
    plane's foot point and its vertices on the sphere); for the z-axis cylinder, likewise in
    the xy-plane.
    """
    normals = mesh.face_normals
    v0 = mesh.vertices[mesh.faces[:, 0]]
    if centre is None:
        normals = normals[:, :2] / np.linalg.norm(normals[:, :2], axis=1, keepdims=True)
        depth = np.abs(np.einsum("ij,ij->i", normals, v0[:, :2]))
    else:
        depth = np.abs(np.einsum("ij,ij->i", normals, v0 - np.asarray(centre)))
    return float(radius - depth.min())


def steepest_tilt(mesh: trimesh.Trimesh, axis: bool = False) -> float:
    """Largest angle (rad) between a face's normal and the radial direction at its corners.

    The radial direction is from the origin (a sphere) or, with ``axis``, from the z axis (a
    cylinder). A point at height h above the surface has its closest point on a face at most
    about h times this angle sideways of its radial projection.
    """
    normals = mesh.face_normals
    corners = mesh.vertices[mesh.faces].copy()
    if axis:
        corners[:, :, 2] = 0.0
    radial = corners / np.linalg.norm(corners, axis=2, keepdims=True)
    cos = np.einsum("fj,fkj->fk", normals, radial)
    return float(np.arccos(np.clip(cos.min(), -1.0, 1.0)))
