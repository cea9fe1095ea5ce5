"""Tests of meshrec.io.files (the one atomic writer, the bounded reader) and of
meshrec.io.truth (the truth file)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.io.files import read_text, write_atomic
from meshrec.io.truth import Truth, read_truth, write_truth
from meshrec.sim.simulate import simulate_touch


@pytest.fixture
def umask_027():
    previous = os.umask(0o027)
    yield 0o027
    os.umask(previous)


# ----------------------------------------------------------------------------- write_atomic
def test_write_atomic_text_bytes_and_callable(tmp_path):
    assert write_atomic(tmp_path / "a" / "t.txt", "héllo\n") == tmp_path / "a" / "t.txt"
    assert (tmp_path / "a" / "t.txt").read_text(encoding="utf-8") == "héllo\n"
    write_atomic(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    seen = []

    def write(name):
        seen.append(name)
        with open(name, "w") as fh:
            fh.write("made")

    write_atomic(tmp_path / "pic.png", write)
    assert seen[0].endswith(".png")  # picture writers pick the format by the suffix
    assert (tmp_path / "pic.png").read_text() == "made"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b.bin", "pic.png"]


def test_write_atomic_mode_follows_the_umask_like_open(tmp_path, umask_027):
    write_atomic(tmp_path / "atomic.txt", "x")
    with open(tmp_path / "plain.txt", "w") as fh:
        fh.write("x")
    mode = (tmp_path / "atomic.txt").stat().st_mode & 0o777
    assert mode == 0o640
    assert mode == (tmp_path / "plain.txt").stat().st_mode & 0o777


def test_write_atomic_failure_keeps_the_old_file(tmp_path):
    path = tmp_path / "keep.txt"
    path.write_text("old")

    def fail(name):
        with open(name, "w") as fh:
            fh.write("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        write_atomic(path, fail)
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]  # no temporary left


def test_write_atomic_errors(tmp_path):
    with pytest.raises(TypeError, match="content must be str, bytes or callable, got int"):
        write_atomic(tmp_path / "x", 3)
    (tmp_path / "dir").mkdir()
    with pytest.raises(IsADirectoryError, match="Is a directory"):
        write_atomic(tmp_path / "dir", "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir"]


def test_write_atomic_names_its_temporary_file_by_prefix_and_suffix(tmp_path):
    seen = []

    def write(name):
        seen.append(os.path.basename(name))
        with open(name, "wb") as fh:
            fh.write(b"x")

    write_atomic(tmp_path / "entry.npz", write, prefix=".entry.host.42.", suffix=".tmp")
    (name,) = seen
    assert name.startswith(".entry.host.42.")
    assert name.endswith(".tmp")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.npz"]
    with pytest.raises(TypeError, match="prefix must be a str or None, got int"):
        write_atomic(tmp_path / "y", "x", prefix=3)
    with pytest.raises(TypeError, match="suffix must be a str or None, got bytes"):
        write_atomic(tmp_path / "y", "x", suffix=b".tmp")
    assert not (tmp_path / "y").exists()


# ----------------------------------------------------------------------------- read_text
def test_read_text(tmp_path):
    path = tmp_path / "t.txt"
    path.write_bytes(b"\xef\xbb\xbfabc")
    assert read_text(path, what="thing", max_bytes=10) == "abc"  # BOM dropped
    with pytest.raises(ValueError, match=r"thing .*t\.txt: 6 bytes, larger than the limit of 5"):
        read_text(path, what="thing", max_bytes=5)
    with pytest.raises(ValueError, match=r"thing .*none: no such file"):
        read_text(tmp_path / "none", what="thing", max_bytes=5)
    odd = tmp_path / "a\nb.txt"
    odd.write_bytes(b"x\x00y")
    with pytest.raises(ValueError, match=r"thing .*a\\nb\.txt: binary content") as info:
        read_text(odd, what="thing", max_bytes=10)
    assert "\n" not in str(info.value)


# ----------------------------------------------------------------------------- truth
def _truth(**kw) -> Truth:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    T[:3, 3] = [1.0, -2.0, 0.5]
    args = dict(model="ball", contact=[0.0, 0.0, 1.0], T_model_touch=T, normal=[0, 0, 1])
    return Truth(**{**args, **kw})


def test_truth_round_trip_and_inverse(tmp_path):
    truth = _truth(noise=0.001, length=0.6, points=61, seed=4)
    truth.to_file(tmp_path / "t.json")
    back = read_truth(tmp_path / "t.json")
    for key in ("contact", "T_model_touch", "T_touch_model", "normal", "contact_touch"):
        np.testing.assert_array_equal(getattr(back, key), getattr(truth, key))
    assert (back.model, back.noise, back.length, back.points, back.seed) == (
        "ball", 0.001, 0.6, 61, 4
    )  # fmt: skip
    np.testing.assert_allclose(truth.T_touch_model @ truth.T_model_touch, np.eye(4), atol=1e-15)
    # the touch-frame contact maps back onto the model contact
    T = truth.T_model_touch
    np.testing.assert_allclose(
        T[:3, :3] @ truth.contact_touch + T[:3, 3], truth.contact, atol=1e-15
    )
    assert "Truth(model='ball'" in repr(truth)
    data = json.loads((tmp_path / "t.json").read_text())
    assert data == truth.to_dict()


def test_simulated_truth_file_is_the_simulation(tmp_path):
    sim = simulate_touch(trimesh.creation.icosphere(subdivisions=2), rng=2, name="ball")
    sim.write(tmp_path / "t.csv", tmp_path / "truth.json")
    back = read_truth(tmp_path / "truth.json")
    np.testing.assert_array_equal(back.T_model_touch, sim.T_model_touch)
    np.testing.assert_array_equal(back.T_touch_model, sim.T_touch_model)
    np.testing.assert_array_equal(back.contact_touch, sim.contact_touch)
    assert json.loads((tmp_path / "truth.json").read_text()) == sim.truth_dict()


def test_truth_only_needs_contact_and_transform(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps({"contact": [1, 2, 3], "T_model_touch": np.eye(4).tolist()}))
    truth = read_truth(path)
    assert truth.model == ""
    assert truth.normal is None
    assert truth.seed is None
    np.testing.assert_array_equal(truth.contact_touch, [1, 2, 3])


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ([1, 2], "truth must be a mapping"),
        ({"contact": [0, 0, 0]}, "truth must have a 'T_model_touch' entry"),
        ({"T_model_touch": np.eye(4).tolist()}, "truth must have a 'contact' entry"),
        ({"T_model_touch": "eye", "contact": [0, 0, 0]}, r"truth\['T_model_touch'\] must be"),
        (
            {"T_model_touch": (2 * np.eye(4)).tolist(), "contact": [0, 0, 0]},
            r"truth\['T_model_touch'\] must be a rigid 4x4 transform",
        ),
        (
            {"T_model_touch": np.eye(4).tolist(), "contact": [0, 10**400, 0]},
            r"truth\['contact'\] must be 3 finite numbers",
        ),
        (
            {"T_model_touch": np.eye(4).tolist(), "contact": [0, 0, 0], "seed": "x"},
            r"truth\['seed'\] must be an integer",
        ),
        (
            {"T_model_touch": np.eye(4).tolist(), "contact": [0, 0, 0], "model": 3},
            r"truth\['model'\] must be a string",
        ),
        (
            {
                "T_model_touch": np.eye(4).tolist(),
                "T_touch_model": np.diag([1.0, -1.0, -1.0, 1.0]).tolist(),
                "contact": [0, 0, 0],
            },
            "T_touch_model must be the inverse of T_model_touch",
        ),
    ],
)
def test_truth_file_errors(tmp_path, data, match):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=match) as info:
        read_truth(path)
    assert str(info.value).startswith(f"truth file {path}: ")


def test_truth_file_unreadable(tmp_path):
    with pytest.raises(ValueError, match=r"none\.json cannot be read: no such file"):
        read_truth(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(ValueError, match=r"bad\.json is not JSON"):
        read_truth(bad)
    big = tmp_path / "big.json"
    big.write_bytes(b" " * (defaults.TRUTH_MAX_BYTES + 1))
    with pytest.raises(ValueError, match="larger than the limit"):
        read_truth(big)


def test_truth_constructor_and_writer_types(tmp_path):
    with pytest.raises(TypeError, match="model must be a str, got int"):
        _truth(model=3)
    with pytest.raises(TypeError, match="contact must hold real numbers"):
        _truth(contact=[1j, 0, 0])
    with pytest.raises(TypeError, match="truth must be a Truth, got dict"):
        write_truth(tmp_path / "t.json", {"contact": [0, 0, 0]})
    np.testing.assert_allclose(_truth(normal=[0, 0, 1e308]).normal, [0, 0, 1])
