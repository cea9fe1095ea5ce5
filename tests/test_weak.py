"""Starts along the weakest motions (meshrec.recognition.weak).

Known independently: on a sphere every weak motion is a turn about its centre, so every
start keeps each point's distance from the centre; points spread over three faces of a
box corner fix every motion, so they get no start.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.recognition.weak import weak_motion_starts


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("weak") / "models"
    folder.mkdir()
    trimesh.creation.icosphere(subdivisions=5, radius=0.8).export(folder / "sphere.stl")
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.05)
    trimesh.Trimesh(v, f).export(folder / "box.stl")
    return meshrec.ModelLibrary.from_folder(folder, cache_dir=folder.parent / "cache")


def _pose(rng):
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-0.2, 0.2, 3)
    return T


def test_on_a_sphere_every_start_turns_about_its_centre(library):
    rng = np.random.default_rng(3)
    d = rng.normal(size=(80, 3))
    d[:, 2] = np.abs(d[:, 2]) + 3.0  # a cap around +z
    on_model = 0.8 * d / np.linalg.norm(d, axis=1)[:, None]
    T_model_touch = _pose(rng)
    points = (on_model - T_model_touch[:3, 3]) @ T_model_touch[:3, :3]  # touch frame
    starts = weak_motion_starts(library["sphere"], points, T_model_touch)
    # the two weakest of the sphere's three free turns, every angle
    assert len(starts) == defaults.WEAK_MOTION_MOST * len(defaults.WEAK_TURN_ANGLES_DEG)
    moved = [points @ S[:3, :3].T + S[:3, 3] for S in starts]
    for y in moved:
        assert np.allclose(np.linalg.norm(y, axis=1), 0.8, atol=2e-3)  # still on it
    # and they really go somewhere: the largest turn moves the cap by more than its size
    far = max(float(np.linalg.norm(y - on_model, axis=1).max()) for y in moved)
    assert far > 1.0


def test_points_over_a_box_corner_fix_every_motion(library):
    rng = np.random.default_rng(4)
    faces = []
    for axis in range(3):
        p = rng.uniform(0.1, 0.45, size=(30, 3))
        p[:, axis] = 0.5
        faces.append(p)
    points = np.vstack(faces)
    assert weak_motion_starts(library["box"], points, np.eye(4)) == []


@pytest.mark.parametrize(
    ("points", "T", "kwargs", "match"),
    [
        (np.zeros((5, 3)), np.eye(4), {}, "points"),
        (np.zeros((8, 2)), np.eye(4), {}, "points"),
        (None, np.eye(3), {}, "T_model_touch"),
        (None, np.full((4, 4), np.nan), {}, "T_model_touch"),
        (None, np.eye(4), {"ratio": 0.0}, "ratio"),
        (None, np.eye(4), {"ratio": 1.5}, "ratio"),
        (None, np.eye(4), {"most": 0}, "most"),
        (None, np.eye(4), {"most": 1.5}, "most"),
    ],
)
def test_bad_input_raises(library, points, T, kwargs, match):
    if points is None:
        points = np.random.default_rng(0).uniform(-0.1, 0.1, size=(10, 3))
        points[:, 2] += 0.8
    with pytest.raises(ValueError, match=match):
        weak_motion_starts(library["sphere"], points, T, **kwargs)
