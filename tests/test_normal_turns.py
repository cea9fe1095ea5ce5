"""One touch about to be named: its pose turned about the touch's normal at the contact
and refined again (meshrec.recognition.weak.normal_turn_starts)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import meshrec
from meshrec import defaults
from meshrec.recognition.weak import normal_turn_starts

YCB = Path(__file__).resolve().parents[2] / "shared" / "data" / "ycb"


def test_the_turns_keep_the_contact_and_its_normal_and_turn_by_the_angles():
    rng = np.random.default_rng(3)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=4).as_matrix()
    T[:3, 3] = [0.3, -0.2, 0.1]
    points = rng.normal(size=(20, 3))
    p = np.array([0.1, 0.2, 0.3])
    n = np.array([0.0, 0.6, 0.8])
    starts = normal_turn_starts(points, T, p, 2.0 * n)  # the normal's length does not matter
    assert len(starts) == len(defaults.NORMAL_TURN_ANGLES_DEG)
    for S, deg in zip(starts, defaults.NORMAL_TURN_ANGLES_DEG, strict=True):
        np.testing.assert_allclose(S[:3, :3] @ p + S[:3, 3], T[:3, :3] @ p + T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(S[:3, :3] @ n, T[:3, :3] @ n, atol=1e-12)
        turn = Rotation.from_matrix(S[:3, :3] @ T[:3, :3].T).as_rotvec()
        assert np.degrees(np.linalg.norm(turn)) == pytest.approx(abs(deg), abs=1e-9)


@pytest.mark.parametrize(
    ("point", "normal", "T", "match"),
    [
        ([0.0, 0.0], [0.0, 0.0, 1.0], np.eye(4), "point"),
        ([0.0, 0.0, np.nan], [0.0, 0.0, 1.0], np.eye(4), "point"),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], np.eye(4), "normal"),
        ([0.0, 0.0, 0.0], [0.0, np.inf, 1.0], np.eye(4), "normal"),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], np.eye(3), "T_model_touch"),
    ],
)
def test_normal_turn_starts_bad_input_raises(point, normal, T, match):
    pts = np.c_[np.linspace(-1, 1, 8), np.zeros(8), np.zeros(8)]
    with pytest.raises(ValueError, match=match):
        normal_turn_starts(pts, T, point, normal)
    with pytest.raises(ValueError, match="points"):
        normal_turn_starts(pts[:3], np.eye(4), [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])


@pytest.mark.skipif(not (YCB / "power_drill.obj").is_file(), reason="no YCB scans")
def test_a_decimated_drill_touch_is_not_named_at_a_pose_turned_about_its_normal(tmp_path):
    # A black-box probe (stop 34): one touch of the YCB power drill against its copy
    # decimated by Open3D's quadric decimation to 4,000 faces was `recognised` with the
    # pose `fixed` (sigma 0.7 mm) and 26 degrees about the touch's normal off the truth;
    # the true pose fits 1.5 times better.
    o3d = pytest.importorskip("open3d")
    clean = trimesh.load(YCB / "power_drill.obj", force="mesh")
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(clean.vertices), o3d.utility.Vector3iVector(clean.faces)
    ).simplify_quadric_decimation(4000)
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.triangles), process=False).export(
        folder / "drill_d4k.obj"
    )
    (folder / "meshrec.json").write_text(json.dumps({"units": "m"}))
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    seed = 803
    rng = np.random.default_rng(seed)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = rng.uniform(-0.3, 0.3, 3)
    sim = meshrec.simulate_touch(clean, rng=seed * 10, noise=5e-5, transform=False)
    touch = sim.touch.transformed(T)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touch, library, workers=1)
    T_true = np.linalg.inv(T)
    placed = touch.points @ rec.best.T_model_touch[:3, :3].T + rec.best.T_model_touch[:3, 3]
    truth = touch.points @ T_true[:3, :3].T + T_true[:3, 3]
    error = float(np.linalg.norm(placed - truth, axis=1).mean())
    assert rec.best.model == "drill_d4k"
    assert not rec.pose_freedom.fixed or error < 5 * rec.pose_freedom.sigma, (error, rec.reason)
