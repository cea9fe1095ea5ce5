"""Pose freedom: the rigid motions a touch leaves free (meshrec.recognition.freedom).

The expected answers are known independently: a plane leaves two slides and a turn about
its normal, a circular cylinder a slide along and a turn about its axis, a sphere three
turns about its centre, an ellipsoid none.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.recognition.freedom import pose_freedom


def _disc(rng, n=60):
    """Points of a small patch around the origin: parameters (u, v) in [-1, 1]^2."""
    return rng.uniform(-1.0, 1.0, size=(n, 2))


def test_plane_leaves_two_slides_and_a_turn_about_its_normal():
    rng = np.random.default_rng(0)
    uv = _disc(rng)
    x = np.column_stack([uv[:, 0] + 3.0, uv[:, 1] - 1.0, np.full(len(uv), 2.0)])
    f = pose_freedom(x, np.tile([0.0, 0.0, 1.0], (len(x), 1)))
    assert (f.free, f.slides, f.turns) == (3, 2, 1)
    assert f.names == ("slide", "slide", "turn")
    assert np.allclose(np.abs(f.slide_directions[:, 2]), 0.0, atol=1e-9)  # in the plane
    assert np.allclose(np.abs(f.turn_axes[0]), [0, 0, 1], atol=1e-9)  # about the normal
    assert f.description == "free: 2 slides and 1 turn"


def test_cylinder_leaves_a_slide_along_and_a_turn_about_its_axis():
    rng = np.random.default_rng(1)
    uv = _disc(rng)
    theta, z = 0.3 * uv[:, 0], 0.5 * uv[:, 1]
    n = np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
    axis_point = np.array([1.0, -2.0, 0.0])
    x = axis_point + 2.0 * n + np.column_stack([0 * z, 0 * z, z])
    f = pose_freedom(x, n)
    assert (f.free, f.slides, f.turns) == (2, 1, 1)
    assert np.allclose(np.abs(f.slide_directions[0]), [0, 0, 1], atol=1e-9)
    assert np.allclose(np.abs(f.turn_axes[0]), [0, 0, 1], atol=1e-9)
    assert np.allclose(f.turn_points[0][:2], axis_point[:2], atol=1e-9)  # on the axis


def test_sphere_leaves_three_turns_about_its_centre():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(60, 3))
    v[:, 2] = -np.abs(v[:, 2]) - 3.0  # a cap around the south pole
    v /= np.linalg.norm(v, axis=1)[:, None]
    centre = np.array([0.5, 0.0, 3.0])
    f = pose_freedom(centre + 1.5 * v, v)
    assert (f.free, f.slides, f.turns) == (3, 0, 3)
    # Every turn's axis passes through the centre.
    for a, p in zip(f.turn_axes, f.turn_points, strict=True):
        assert np.linalg.norm(np.cross(centre - p, a)) < 1e-9


def test_ellipsoid_patch_leaves_nothing_free():
    rng = np.random.default_rng(3)
    a = np.array([1.0, 0.8, 0.5])
    uv = 0.4 * _disc(rng)
    # The patch around (0, 0, -c): z from the implicit equation, normal its gradient.
    x = np.column_stack([uv[:, 0], uv[:, 1], np.zeros(len(uv))])
    x[:, 2] = -a[2] * np.sqrt(1.0 - (x[:, 0] / a[0]) ** 2 - (x[:, 1] / a[1]) ** 2)
    f = pose_freedom(x, x / a**2)
    assert f.free == 0
    assert f.description == "fixed"
    assert f.singular_values[-1] > defaults.POSE_FREE_RATIO


@pytest.mark.parametrize(
    ("points", "normals", "ratio", "match"),
    [
        (np.zeros((5, 3)), np.ones((5, 3)), 1e-3, "points"),
        (np.zeros((8, 3)), np.ones((8, 3)), 1e-3, "coincide"),
        (np.eye(8, 3), np.ones((7, 3)), 1e-3, "normals"),
        (np.eye(8, 3), np.full((8, 3), np.nan), 1e-3, "normals"),
        (np.eye(8, 3), np.zeros((8, 3)), 1e-3, "zero rows"),
        (np.eye(8, 3), np.ones((8, 3)), 1.5, "ratio"),
        (np.eye(8, 3), np.ones((8, 3)), 0.0, "ratio"),
    ],
)
def test_bad_input_raises(points, normals, ratio, match):
    with pytest.raises(ValueError, match=match):
        pose_freedom(points, normals, ratio)


def test_bad_points_type_raises():
    with pytest.raises(TypeError):
        pose_freedom([["a", "b", "c"]] * 8, np.ones((8, 3)))


@pytest.fixture(scope="module")
def box_and_ellipsoid(tmp_path_factory):
    """A library of a box and an ellipsoid (unit-sized), both with vertices on every face
    (the curvature lookup needs them: a 12-triangle box has none but its corners)."""
    folder = tmp_path_factory.mktemp("freedom")
    box = trimesh.creation.box(extents=(1.0, 0.7, 0.5))
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.05)
    trimesh.Trimesh(v, f).export(folder / "box.stl")
    ellipsoid = trimesh.creation.icosphere(subdivisions=5)
    ellipsoid.apply_scale([0.6, 0.45, 0.3])
    ellipsoid.export(folder / "ellipsoid.stl")
    return folder


def test_touch_on_a_box_face_is_named_but_its_pose_is_ambiguous(box_and_ellipsoid):
    lib = meshrec.ModelLibrary.from_folder(box_and_ellipsoid)
    t = meshrec.simulate_touch(
        box_and_ellipsoid / "box.stl", contact=[0.1, 0.05, 0.25], rng=1, length=0.2,
        noise=0.0005,
    )
    rec = meshrec.recognize(t.touch, lib)
    assert rec.best.model == "box"
    assert (rec.pose_freedom.slides, rec.pose_freedom.turns) == (2, 1)
    assert rec.verdict == "ambiguous"
    assert rec.plausible == ("box",)
    assert "only box fits" in rec.reason
    assert "2 slides and 1 turn" in rec.reason


def test_touch_on_an_ellipsoid_is_recognised_with_a_fixed_pose(box_and_ellipsoid):
    lib = meshrec.ModelLibrary.from_folder(box_and_ellipsoid)
    t = meshrec.simulate_touch(
        box_and_ellipsoid / "ellipsoid.stl", rng=2, noise=0.0005
    )
    rec = meshrec.recognize(t.touch, lib)
    assert rec.best.model == "ellipsoid"
    assert rec.pose_freedom.free == 0
    assert rec.verdict == "recognised"
