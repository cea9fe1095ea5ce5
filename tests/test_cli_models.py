"""``meshrec models``, ``--models SET`` (a bundled set by name), and ``--units`` /
``--model-units`` on the command line, through the real console script."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from meshrec import TouchData, simulate_touch

MODELS = Path(__file__).resolve().parents[1] / "models"
SCRIPT = Path(sys.executable).with_name("meshrec")


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return {**os.environ, "MESHREC_CACHE_DIR": str(tmp_path_factory.mktemp("cache"))}


def _run(args, env, cwd):
    return subprocess.run(
        [str(SCRIPT), *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600
    )


def _one_error_line(proc, pattern: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("meshrec: error: ")
    assert pattern in lines[0], lines[0]


def test_models_lists_the_bundled_sets(env, tmp_path):
    proc = _run(["models", "--json"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    sets = {s["name"]: s for s in json.loads(proc.stdout)["sets"]}
    assert set(sets) == {"objects", "parts", "primitives", "surfaces"}
    for name, s in sets.items():
        assert sorted(s["models"]) == sorted(p.stem for p in (MODELS / name).glob("*.stl"))
    assert sets["objects"]["units"] == "mm"  # millimetres (models/README.md)
    assert sets["surfaces"]["units"] is None  # unitless
    assert sets["parts"]["units"] == "mm"
    assert sets["primitives"]["units"] is None
    text = _run(["models"], env, tmp_path)
    assert text.returncode == 0
    assert any(ln.split()[:2] == ["objects", "mm"] for ln in text.stdout.splitlines())


def test_models_lists_a_bundled_set_by_name(env, tmp_path):
    proc = _run(["models", "objects", "--json"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["units"] == "mm"
    models = {m["name"]: m for m in doc["models"]}
    assert set(models) == {"cylinder_1", "cylinder_2", "elliptic_cylinder", "sphere"}
    sphere = models["sphere"]
    # radius 33 mm: the bounding box's diagonal is 66 sqrt(3); an icosphere's counts
    assert sphere["size"] == pytest.approx(66 * math.sqrt(3), rel=1e-4)
    assert (sphere["faces"], sphere["vertices"]) == (81920, 40962)
    # the mean edge of an icosphere subdivided 6 times (20 * 4^6 faces) on radius 33:
    # about the edge of a regular triangle of area 4 pi r^2 / faces
    edge = math.sqrt(4 * 4 * math.pi * 33**2 / 81920 / math.sqrt(3))
    assert sphere["mean_edge"] == pytest.approx(edge, rel=0.05)
    assert doc["skipped"] == []


def test_models_lists_a_folder_with_its_note_and_skipped_files(env, tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    trimesh.creation.box(extents=[3.0, 4.0, 12.0]).export(folder / "brick.stl")
    (folder / "notes.txt").write_text("hello")
    (folder / "meshrec.json").write_text('{"units": "cm"}')
    proc = _run(["models", str(folder), "--json"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["units"] == "cm"
    (brick,) = doc["models"]
    assert (brick["name"], brick["faces"], brick["vertices"]) == ("brick", 12, 8)
    assert brick["size"] == pytest.approx(13.0)  # sqrt(3^2 + 4^2 + 12^2)
    assert [s["file"] for s in doc["skipped"]] == ["notes.txt"]
    over = _run(["models", str(folder), "--model-units", "in"], env, tmp_path)
    assert over.returncode == 0, over.stderr
    assert "units in" in over.stdout.splitlines()[0]
    assert "brick" in over.stdout
    assert "skipped notes.txt: not a mesh file" in over.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["models", "nowhere"], "--models nowhere: no such folder, nor a bundled set "),
        (["models", "bad_note"], "units note "),
        (
            ["recognize", "t.csv", "--models", "no_set"],
            "(bundled: objects, parts, primitives, surfaces)",
        ),
        (["recognize", "t.csv", "--models", "bad_note"], "units must be one of mm, cm, m, in"),
        (["recognize", "t.csv", "--units", "ft"], "argument --units: invalid choice: 'ft'"),
    ],
)
def test_bad_models_or_units_one_line_exit_2(env, tmp_path, args, message):
    (tmp_path / "bad_note").mkdir()
    shutil.copy(MODELS / "objects" / "sphere.stl", tmp_path / "bad_note")
    (tmp_path / "bad_note" / "meshrec.json").write_text('{"units": "furlong"}')
    simulate_touch(MODELS / "objects" / "sphere.stl", rng=1).write(tmp_path / "t.csv")
    _one_error_line(_run(args, env, tmp_path), message)


@pytest.fixture(scope="module")
def metres(tmp_path_factory):
    """A touch on the bundled sphere (radius 33 mm), written in metres."""
    folder = tmp_path_factory.mktemp("units")
    sim = simulate_touch(MODELS / "objects" / "sphere.stl", rng=1)
    touch = sim.touch
    TouchData(curves=[c / 1000.0 for c in touch.curves]).to_file(folder / "touch_m.csv")
    return folder, sim


def test_touch_in_metres_against_the_objects_in_millimetres(env, metres):
    folder, sim = metres
    # the objects' note says mm: without --units the size check refuses the touch
    _one_error_line(
        _run(["recognize", "touch_m.csv", "--models", "objects"], env, folder),
        "likely a unit mismatch (mm vs m?); touch data and models must be in the same units "
        "(give the touch's unit with --units, and the models' with --model-units",
    )
    # a wrong --units (cm: the touch, in metres, then 100 times too small) is named as the
    # unit to check, not asked for
    _one_error_line(
        _run(["recognize", "touch_m.csv", "--models", "objects", "--units", "cm"], env, folder),
        "touch data and models must be in the same units "
        "(the touch was read in cm as --units says: check that unit",
    )
    # with --units m it is converted to millimetres and recognised
    proc = _run(
        ["recognize", "touch_m.csv", "--models", "objects", "--units", "m", "--json"], env, folder
    )
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["best"] == "sphere"
    # the contact found is on the sphere of radius 33 (mm), the touch's in mm too
    assert np.linalg.norm(doc["ranking"][0]["contact"]) == pytest.approx(33.0, abs=0.1)
    assert np.linalg.norm(np.array(doc["touch"]["contact"]) - sim.contact_touch) < 1.0


def test_model_units_given_for_a_folder_without_a_note(env, metres, tmp_path):
    folder, _ = metres
    models = tmp_path / "objects_copy"  # no meshrec.json: units unknown
    models.mkdir()
    shutil.copy(MODELS / "objects" / "sphere.stl", models)
    # --units alone cannot convert: one warning, and the size check still refuses
    proc = _run(["recognize", "touch_m.csv", "--models", str(models), "--units", "m"], env, folder)
    assert proc.returncode == 2
    warning, error = proc.stderr.strip().splitlines()
    assert warning.startswith("meshrec: warning: --units m is not used: the models' units")
    assert "likely a unit mismatch" in error
    proc = _run(
        [
            "recognize",
            "touch_m.csv",
            "--models",
            str(models),
            "--units",
            "m",
            "--model-units",
            "mm",
        ],
        env,
        folder,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1].startswith("recognised: sphere")


def test_models_lists_what_a_library_would_skip(env, tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    trimesh.creation.box(extents=[1.0, 2.0, 2.0]).export(folder / "a.stl")
    trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(folder / "a.obj")  # same name
    (folder / "broken.stl").write_text("solid nothing\nendsolid\n")  # no triangle
    proc = _run(["models", str(folder), "--json"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["units"] is None
    assert [m["name"] for m in doc["models"]] == ["a"]
    assert doc["models"][0]["size"] == pytest.approx(math.sqrt(3.0))  # a.obj comes first
    reasons = {s["file"]: s["reason"] for s in doc["skipped"]}
    assert set(reasons) == {"a.stl", "broken.stl"}
    assert reasons["a.stl"] == "duplicate model name 'a'"


def test_models_flags_a_model_in_other_units(env, tmp_path):
    folder = tmp_path / "mixed_units"
    folder.mkdir()
    trimesh.creation.box(extents=[0.2, 0.1, 0.3]).export(folder / "block_m.stl")
    trimesh.creation.box(extents=[0.1, 0.1, 0.1]).export(folder / "cube_m.stl")
    trimesh.creation.box(extents=[200.0, 100.0, 300.0]).export(folder / "block_mm.stl")
    proc = _run(["models", str(folder), "--json"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    ratios = {m["name"]: m["size_ratio"] for m in json.loads(proc.stdout)["models"]}
    assert ratios["block_m"] is None
    assert ratios["cube_m"] is None
    assert ratios["block_mm"] == pytest.approx(1000.0)  # against block_m, the median
    text = _run(["models", str(folder)], env, tmp_path).stdout
    (line,) = [ln for ln in text.splitlines() if ln.startswith("block_mm")]
    assert line.endswith("x the median: other units?")


def test_models_flags_an_open_mesh(env, tmp_path):
    # A black-box probe (stop 36) cut a hole where its touch landed: the touch then fit
    # a near-twin place elsewhere, and nothing had said the model was open.
    folder = tmp_path / "open"
    folder.mkdir()
    ball = trimesh.creation.icosphere(subdivisions=2)  # 320 faces, 480 edges
    ball.export(folder / "closed.stl")
    cut = trimesh.Trimesh(ball.vertices, ball.faces[1:], process=False)  # one face removed
    cut.export(folder / "holed.stl")
    doc = json.loads(_run(["models", str(folder), "--json"], env, tmp_path).stdout)
    edges = {m["name"]: m["boundary_edges"] for m in doc["models"]}
    assert edges == {"closed": 0, "holed": 3}
    text = _run(["models", str(folder)], env, tmp_path).stdout
    (line,) = [ln for ln in text.splitlines() if ln.startswith("holed")]
    assert line.endswith("open (3 boundary edges)")
    (line,) = [ln for ln in text.splitlines() if ln.startswith("closed")]
    assert "open" not in line
