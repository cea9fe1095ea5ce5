"""Checks of the bundled model meshes in ``models/`` against the analytic shapes they stand for.

The expected shapes are written out here from the paper (Table 1 and Figure 7), independently
of ``tools/make_models.py``. Regenerating the files is not tested here: the script takes
longer than this suite may (about 20 s).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

MODELS = Path(__file__).resolve().parent.parent / "models"

A, B, C = 1.0, 0.8, 0.5  # ellipsoid semi-axes
PA, PB = 1.5, 1.1  # elliptic paraboloid z = x^2/PA^2 + y^2/PB^2
HEIGHT = 100.0  # cylinder height, mm


def _ellipsoid(p):
    """Implicit function and gradient of the ellipsoid."""
    x, y, z = p.T
    f = (x / A) ** 2 + (y / B) ** 2 + (z / C) ** 2 - 1.0
    return f, np.column_stack([2 * x / A**2, 2 * y / B**2, 2 * z / C**2])


def _graph(g, gx, gy):
    """Implicit function ``z - g(x, y)`` and its gradient, from ``g`` and its slopes."""

    def implicit(p):
        x, y, z = p.T
        return z - g(x, y), np.column_stack([-gx(x, y), -gy(x, y), np.ones_like(x)])

    return implicit


_paraboloid = _graph(
    lambda x, y: (x / PA) ** 2 + (y / PB) ** 2,
    lambda x, y: 2 * x / PA**2,
    lambda x, y: 2 * y / PB**2,
)
_monkey_saddle = _graph(
    lambda x, y: x**3 - 3 * x * y**2,
    lambda x, y: 3 * x**2 - 3 * y**2,
    lambda x, y: -6 * x * y,
)
_crossed_trough = _graph(
    lambda x, y: x**2 * y**2,
    lambda x, y: 2 * x * y**2,
    lambda x, y: 2 * x**2 * y,
)


def _sphere(radius):
    """Implicit function and gradient of a sphere."""

    def implicit(p):
        return np.sum(p**2, axis=1) - radius**2, 2 * p

    return implicit


def _prism(a, b):
    """Implicit function and gradient of the side of an elliptic cylinder along z."""

    def implicit(p):
        x, y, _ = p.T
        f = (x / a) ** 2 + (y / b) ** 2 - 1.0
        return f, np.column_stack([2 * x / a**2, 2 * y / b**2, np.zeros_like(x)])

    return implicit


# file, closed, implicit function, bounding box (min, max), volume of the solid (closed only)
SURFACES = {
    "surfaces/ellipsoid.stl": (
        True,
        _ellipsoid,
        (-A, -B, -C),
        (A, B, C),
        4 / 3 * np.pi * A * B * C,
    ),
    "surfaces/elliptic_paraboloid.stl": (False, _paraboloid, (-PA, -PB, 0), (PA, PB, 1), None),
    "surfaces/monkey_saddle.stl": (False, _monkey_saddle, (-1, -1, -2), (1, 1, 2), None),
    "surfaces/crossed_trough.stl": (False, _crossed_trough, (-1, -1, 0), (1, 1, 1), None),
}
# file, semi-axes of the section (cylinders) or radius (sphere)
OBJECTS = {
    "objects/cylinder_1.stl": (25.2, 25.2),
    "objects/cylinder_2.stl": (47.0, 47.0),
    "objects/elliptic_cylinder.stl": (50.8, 31.75),
    "objects/sphere.stl": (33.0,),
}
ALL = sorted(SURFACES) + sorted(OBJECTS)
OPEN = sorted(name for name, spec in SURFACES.items() if not spec[0])


@functools.cache
def _load(name):
    """The bundled mesh ``name`` (path relative to ``models/``), loaded once."""
    return trimesh.load(MODELS / name, file_type="stl", force="mesh")


def _distance(implicit, points):
    """First-order distance ``|f| / |grad f|`` of points to an implicit surface."""
    f, grad = implicit(points)
    return np.abs(f) / np.linalg.norm(grad, axis=1)


def _boundary_vertices(mesh):
    """Vertices on edges used by one face only."""
    edges = mesh.edges_sorted[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    return mesh.vertices[np.unique(edges)]


def test_no_other_files():
    # parts/ and primitives/ are checked by test_parts_models.py
    found = sorted(
        p.relative_to(MODELS).as_posix()
        for folder in ("surfaces", "objects")
        for p in (MODELS / folder).rglob("*.stl")
    )
    assert found == sorted(ALL)


@pytest.mark.parametrize("name", ALL)
def test_loads_as_fine_mesh(name):
    mesh = _load(name)
    assert 40_000 <= len(mesh.faces) <= 100_000
    assert mesh.is_winding_consistent
    assert mesh.area_faces.min() > 0.01 * mesh.area_faces.mean()
    assert np.degrees(mesh.face_angles.min()) > 25.0


@pytest.mark.parametrize("name", [n for n in ALL if n not in OPEN])
def test_closed_solid_has_outward_normals(name):
    mesh = _load(name)
    assert mesh.is_watertight
    assert mesh.euler_number == 2
    assert mesh.volume > 0.0


@pytest.mark.parametrize("name", OPEN)
def test_open_patch_faces_up(name):
    mesh = _load(name)
    assert mesh.euler_number == 1  # one disc
    assert (mesh.face_normals[:, 2] > 0.0).all()


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_surface_vertices_on_shape_and_bounds(name):
    closed, implicit, lo, hi, volume = SURFACES[name]
    mesh = _load(name)
    assert _distance(implicit, mesh.vertices).max() < 1e-6
    np.testing.assert_allclose(mesh.bounds, [lo, hi], atol=1e-3)
    if closed:
        assert mesh.volume == pytest.approx(volume, rel=1e-3)


def test_paraboloid_boundary_is_the_elliptic_rim():
    rim = _boundary_vertices(_load("surfaces/elliptic_paraboloid.stl"))
    np.testing.assert_allclose((rim[:, 0] / PA) ** 2 + (rim[:, 1] / PB) ** 2, 1.0, atol=1e-6)
    np.testing.assert_allclose(rim[:, 2], 1.0, atol=1e-6)


@pytest.mark.parametrize("name", ["surfaces/monkey_saddle.stl", "surfaces/crossed_trough.stl"])
def test_square_patch_boundary_is_the_square(name):
    rim = _boundary_vertices(_load(name))
    np.testing.assert_allclose(np.abs(rim[:, :2]).max(axis=1), 1.0, atol=1e-6)
    # the four corners are vertices
    for corner in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
        assert np.linalg.norm(rim[:, :2] - corner, axis=1).min() < 1e-6


@pytest.mark.parametrize("name", sorted(OBJECTS))
def test_object_vertices_on_shape_and_bounds(name):
    mesh = _load(name)
    p = mesh.vertices
    if name.endswith("sphere.stl"):
        (r,) = OBJECTS[name]
        assert _distance(_sphere(r), p).max() < 1e-4
        np.testing.assert_allclose(mesh.bounds, [(-r, -r, -r), (r, r, r)], atol=0.01)
        assert mesh.volume == pytest.approx(4 / 3 * np.pi * r**3, rel=1e-3)
        return
    a, b = OBJECTS[name]
    # each vertex is on a cap or on the side
    on_cap = np.abs(np.abs(p[:, 2]) - HEIGHT / 2) < 1e-4
    assert _distance(_prism(a, b), p[~on_cap]).max() < 1e-4
    assert ((p[:, 0] / a) ** 2 + (p[:, 1] / b) ** 2).max() < 1.0 + 1e-6
    np.testing.assert_allclose(mesh.bounds, [(-a, -b, -HEIGHT / 2), (a, b, HEIGHT / 2)], atol=0.01)
    assert mesh.volume == pytest.approx(np.pi * a * b * HEIGHT, rel=1e-3)
    # the caps are flat and face along the axis
    on_cap = np.abs(np.abs(mesh.triangles_center[:, 2]) - HEIGHT / 2) < 1e-4
    normals = mesh.face_normals[on_cap]
    np.testing.assert_allclose(normals[:, 2], np.sign(mesh.triangles_center[on_cap, 2]), atol=1e-6)


def test_readme_lists_every_file_with_its_counts():
    text = (MODELS / "README.md").read_text(encoding="utf-8")
    for name in ALL:
        row = re.search(rf"\| `{re.escape(name)}` \| \w+ \| ([\d,]+) \| ([\d,]+) \|", text)
        assert row is not None, name
        mesh = _load(name)
        assert int(row.group(1).replace(",", "")) == len(mesh.faces)
        assert int(row.group(2).replace(",", "")) == len(mesh.vertices)
