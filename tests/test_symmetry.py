"""Free motions that are symmetries of the model (meshrec.recognition.symmetry)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec.recognition.freedom import pose_freedom
from meshrec.recognition.symmetry import without_symmetries


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sym")
    trimesh.creation.icosphere(subdivisions=5, radius=0.5).export(folder / "sphere.stl")
    rod = trimesh.creation.capsule(height=1.0, radius=0.3, count=[96, 48])
    v, f = trimesh.remesh.subdivide_to_size(rod.vertices, rod.faces, 0.05)
    trimesh.Trimesh(v, f).export(folder / "capsule.stl")
    trimesh.creation.box(extents=[1.0, 0.8, 0.6]).export(folder / "box.stl")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path_factory.mktemp("c"))
        return {name: lib[name] for name in lib.names}


def _freedom(points, normals):
    """The free motions of exact data: points on the analytic surface, its normals."""
    return pose_freedom(points, normals)


def _patch(centre, normal, size, n=7):
    """A grid of points on the plane through ``centre`` with ``normal``."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    s = np.linspace(-size, size, n)
    u, v = np.meshgrid(s, s)
    return centre + u.reshape(-1, 1) * a + v.reshape(-1, 1) * b


def test_turns_about_a_sphere_centre_are_symmetries(library):
    sphere = library["sphere"]
    # points on the sphere of radius 0.5 near its north pole
    d = _patch([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 0.15)
    points = 0.5 * d / np.linalg.norm(d, axis=1)[:, None]
    raw = _freedom(points, points)
    assert raw.turns == 3
    out = without_symmetries(sphere, raw, noise=0.0)
    assert out.free == 0
    assert len(out.symmetries) == 3
    assert out.description == "fixed up to the model's symmetry"


def test_a_capsule_side_keeps_its_slide_but_not_its_turn(library):
    capsule = library["capsule"]
    # a patch on the side wall (radius 0.3, axis z), away from the caps
    t = np.linspace(-0.3, 0.3, 9)
    z = np.linspace(-0.15, 0.15, 7)
    tt, zz = np.meshgrid(t, z)
    points = np.column_stack([0.3 * np.cos(tt.ravel()), 0.3 * np.sin(tt.ravel()), zz.ravel()])
    raw = _freedom(points, points * [1.0, 1.0, 0.0])
    assert (raw.slides, raw.turns) == (1, 1)
    out = without_symmetries(capsule, raw, noise=0.001)
    assert (out.slides, out.turns) == (1, 0)  # the slide along the axis hits the caps
    np.testing.assert_allclose(np.abs(out.slide_directions[0]), [0, 0, 1], atol=1e-3)
    assert len(out.symmetries) == 1
    assert out.symmetries[0].startswith("turn")


def test_a_box_face_is_not_a_symmetry(library):
    box = library["box"]
    points = _patch([0.0, 0.0, 0.3], [0.0, 0.0, 1.0], 0.2)
    raw = _freedom(points, np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    assert (raw.slides, raw.turns) == (2, 1)
    out = without_symmetries(box, raw, noise=0.001)
    assert out is raw  # no motion maps the box onto itself


def test_a_fixed_pose_is_returned_as_it_is(library):
    box = library["box"]
    # three faces meeting at a corner fix every motion
    points = np.vstack(
        [
            _patch([0.3, 0.2, 0.3], [0, 0, 1], 0.1, 4),
            _patch([0.5, 0.1, 0.1], [1, 0, 0], 0.1, 4),
            _patch([0.3, 0.4, 0.1], [0, 1, 0], 0.1, 4),
        ]
    )
    normals = np.repeat(np.eye(3)[[2, 0, 1]], 16, axis=0)
    raw = _freedom(points, normals)
    assert raw.free == 0
    assert without_symmetries(box, raw, noise=0.0) is raw


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_a_bad_noise_is_refused(library, bad):
    points = _patch([0.0, 0.0, 0.5], [0.0, 0.0, 1.0], 0.1)
    raw = _freedom(points, points)
    with pytest.raises(ValueError, match="noise must be"):
        without_symmetries(library["sphere"], raw, bad)
