"""The ``meshrec`` command line, run as the real console script and in-process."""

import json
import os
import subprocess
import sys
from pathlib import Path

import jsonschema
import numpy as np
import pytest
import trimesh

import meshrec
from meshrec.app.cli import main

MODELS = Path(__file__).resolve().parents[1] / "models"
SCRIPT = Path(sys.executable).with_name("meshrec")

VECTOR = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
MATRIX = {
    "type": "array",
    "minItems": 4,
    "maxItems": 4,
    "items": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4},
}
#: The schema of ``meshrec recognize --json`` as the issue specifies it.
SCHEMA = {
    "type": "object",
    "required": [
        "verdict",
        "best",
        "plausible",
        "noise",
        "reason",
        "search_doubt",
        "warnings",
        "touch",
        "touches",
        "ranking",
        "pose_freedom",
    ],
    "additionalProperties": False,
    "properties": {
        "verdict": {"enum": ["recognised", "ambiguous", "unknown"]},
        "pose_freedom": {
            "type": ["object", "null"],
            "required": [
                "free",
                "slides",
                "turns",
                "names",
                "description",
                "alternatives",
                "fixed",
            ],
            "properties": {
                "free": {"type": "integer", "minimum": 0, "maximum": 6},
                "alternatives": {"type": "integer", "minimum": 0},
                "pose_weight": {"type": ["number", "null"], "minimum": 0, "maximum": 1},
                "fixed": {"type": "boolean"},
                "slides": {"type": "integer", "minimum": 0, "maximum": 3},
                "turns": {"type": "integer", "minimum": 0, "maximum": 3},
                "names": {"type": "array", "items": {"enum": ["slide", "turn"]}},
                "description": {"type": "string", "minLength": 1},
            },
        },
        "plausible": {"type": "array", "items": {"type": "string"}},
        "noise": {"type": "number", "exclusiveMinimum": 0},
        "reason": {"type": "string", "minLength": 1},
        "search_doubt": {"type": "boolean"},
        "warnings": {"type": "array", "items": {"type": "string"}},
        "probe_radius": {"type": "number", "minimum": 0},
        "touch": {
            "type": "object",
            "required": ["file", "points", "curves", "contact", "normal", "K", "H"],
            "additionalProperties": False,
            "properties": {
                "file": {"type": ["string", "null"]},
                "points": {"type": "integer", "minimum": 15},
                "curves": {"type": "integer", "minimum": 3},
                "contact": VECTOR,
                "normal": VECTOR,
                "K": {"type": "number"},
                "H": {"type": "number"},
            },
        },
        "touches": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "required": ["file", "points", "curves", "contact", "normal", "K", "H", "rms"],
                "additionalProperties": False,
                "properties": {
                    "file": {"type": ["string", "null"]},
                    "points": {"type": "integer", "minimum": 15},
                    "curves": {"type": "integer", "minimum": 3},
                    "contact": VECTOR,
                    "normal": VECTOR,
                    "K": {"type": "number"},
                    "H": {"type": "number"},
                    "rms": {"type": ["number", "null"], "minimum": 0},
                },
            },
        },
        "best": {"type": ["string", "null"]},
        "ranking": {
            "type": "array",
            "items": {
                "type": "object",
                "required": [
                    "model",
                    "file",
                    "error",
                    "contact",
                    "transform",
                    "candidates",
                    "seconds",
                    "probability",
                    "rms",
                    "poses",
                ],
                "additionalProperties": False,
                "properties": {
                    "model": {"type": "string"},
                    "file": {"type": "string"},
                    "error": {"type": ["number", "null"], "minimum": 0},
                    "contact": {"oneOf": [VECTOR, {"type": "null"}]},
                    "transform": {"oneOf": [MATRIX, {"type": "null"}]},
                    "candidates": {"type": "integer", "minimum": 0},
                    "seconds": {"type": "number", "minimum": 0},
                    "probability": {"type": ["number", "null"], "minimum": 0, "maximum": 1},
                    "rms": {"type": ["number", "null"], "minimum": 0},
                    "poses": {
                        "type": "array",
                        "items": {
                            "type": "object",
                            "required": ["transform", "weight"],
                            "additionalProperties": False,
                            "properties": {
                                "transform": MATRIX,
                                "weight": {"type": "number", "minimum": 0, "maximum": 1},
                            },
                        },
                    },
                    "reason": {"type": "string"},
                },
            },
        },
    },
}


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    return {**os.environ, "MESHREC_CACHE_DIR": str(cache)}


def _run(args, env, cwd):
    return subprocess.run(
        [str(SCRIPT), *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def simulated(tmp_path_factory, env):
    folder = tmp_path_factory.mktemp("touch")
    proc = _run(
        [
            "simulate",
            str(MODELS / "surfaces" / "monkey_saddle.stl"),
            "-o",
            "touch.csv",
            "--truth",
            "truth.json",
            "--seed",
            "3",
        ],
        env,
        folder,
    )
    assert proc.returncode == 0, proc.stderr
    return folder


@pytest.mark.slow
def test_recognize_json_matches_the_schema_and_the_truth(simulated, env):
    proc = _run(["recognize", "touch.csv", "--json"], env, simulated)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)  # exactly one JSON object
    jsonschema.validate(doc, SCHEMA)
    assert doc["best"] == "monkey_saddle"
    assert len(doc["ranking"]) == 4
    truth = json.loads((simulated / "truth.json").read_text())
    top = doc["ranking"][0]
    T = np.array(top["transform"])
    contact_touch = np.array(truth["contact_touch"])
    mapped = T[:3, :3] @ contact_touch + T[:3, 3]
    assert np.linalg.norm(mapped - np.array(top["contact"])) < 0.05
    rejected = [r for r in doc["ranking"] if r["error"] is None]
    assert all(r["contact"] is None and r["transform"] is None for r in rejected)


@pytest.mark.slow
def test_recognize_table_with_hints_and_top(simulated, env):
    truth = json.loads((simulated / "truth.json").read_text())
    c = ",".join(str(v) for v in truth["contact_touch"])
    proc = _run(["recognize", "touch.csv", "--contact", c, "--top", "2"], env, simulated)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    # The touch lies inside the square patch, whose surface turned by a third of a turn
    # about its axis fits it as well (z = x^3 - 3 x y^2) but whose square rim does not
    # turn onto itself: the model is recognised, its pose is one of three.
    assert lines[-1].startswith("recognised: monkey_saddle, its pose one of 3 poses")
    assert any(ln.startswith("pose: one of 3 poses") for ln in lines)
    assert len([ln for ln in lines if ln.strip()[:1].isdigit()]) == 2


@pytest.mark.slow
def test_index_reports_progress_and_caches(env, tmp_path):
    first = _run(["index", "--models", str(MODELS / "surfaces")], env, tmp_path)
    assert first.returncode == 0, first.stderr
    assert "indexing 4/4" in first.stderr
    second = _run(["index", "--models", str(MODELS / "surfaces")], env, tmp_path)
    assert second.stdout.count("cached") == 4


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["recognize", "missing.csv"], "no such file"),
        (["recognize", "bad.csv"], "header must be 'curve,x,y,z'"),
        (["recognize", "touch.csv", "--models", "nowhere"], "nowhere"),
        (["recognize", "touch.csv", "--top", "0"], "--top must be at least 1"),
        (["recognize", "touch.csv", "--normal", "1,2"], "expected three finite numbers"),
        (["simulate", "no_such_model", "-o", "x.csv"], "no such file, nor a bundled model"),
        (["simulate", "monkey_saddle", "-o", "x.csv", "--points", "4"], "--points must be"),
        (
            ["simulate", "monkey_saddle", "-o", "x.csv", "--points", "60"],
            "--points must be an odd integer >= 5, got 60",
        ),
        (["simulate", "monkey_saddle", "-o", "x.csv", "--noise", "-1"], "--noise must be >= 0"),
        (["frobnicate"], "invalid choice"),
    ],
)
def test_bad_input_exits_2_with_one_line(simulated, env, args, message):
    (simulated / "bad.csv").write_text("a,b\n1,2\n")
    proc = _run(args, env, simulated)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert message in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_main_in_process(simulated, capsys, monkeypatch, env):
    monkeypatch.setenv("MESHREC_CACHE_DIR", env["MESHREC_CACHE_DIR"])
    assert main(["recognize", str(simulated / "touch.csv"), "--json", "--top", "1"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["ranking"]) == 1
    assert main(["--version"]) == 0
    assert main(["recognize", str(simulated / "missing.csv")]) == 2
    assert "meshrec: error:" in capsys.readouterr().err


def test_index_takes_the_folder_as_an_argument(tmp_path, capsys):
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.icosphere(2, radius=10.0).export(folder / "ball.stl")
    cache = tmp_path / "cache"
    assert main(["index", str(folder), "--cache-dir", str(cache)]) == 0
    assert "ball" in capsys.readouterr().out
    # the same folder twice is fine; two different ones are an error (exit 2, one line)
    assert main(["index", str(folder), "--models", str(folder), "--cache-dir", str(cache)]) == 0
    assert "cached" in capsys.readouterr().out
    assert main(["index", str(folder), "--models", "surfaces", "--cache-dir", str(cache)]) == 2
    err = capsys.readouterr().err
    assert "give the folder once" in err


@pytest.mark.parametrize(
    ("command", "preset", "want"),
    [
        ("next-touch", {}, "1"),
        ("next-touch", {"OMP_NUM_THREADS": "2"}, None),
        ("next-touch", {"OPENBLAS_NUM_THREADS": "2"}, "2"),
        ("recognize", {}, "1"),
        ("serve", {"GOTO_NUM_THREADS": "2"}, None),
    ],
)
def test_commands_start_one_blas_thread_unless_told(command, preset, want):
    # A new interpreter (numpy not yet imported): every command asks OpenBLAS for one
    # thread when no thread variable is set, and leaves the user's choice alone.
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")
    }
    env.update(preset)
    code = (
        "import os; from meshrec.app.cli import _load_core; "
        f"_load_core({command!r}); print(os.environ.get('OPENBLAS_NUM_THREADS'))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == str(want)


def test_simulate_with_noise_along_the_normal(tmp_path, capsys):
    touch, truth = tmp_path / "t.csv", tmp_path / "truth.json"
    args = ["simulate", "ellipsoid", "-o", str(touch), "--truth", str(truth), "--seed", "3"]
    assert main([*args, "--noise-direction", "normal"]) == 0
    assert "noise along the normal" in capsys.readouterr().out
    assert json.loads(truth.read_text())["noise_direction"] == "normal"
    assert main([*args, "--noise-direction", "sideways"]) == 2
    assert "invalid choice: 'sideways'" in capsys.readouterr().err


def test_python_dash_m_runs_the_command_line(tmp_path):
    # ``python -m meshrec`` is the console script's twin: the same help, the same exit
    # status for bad input (a touch file that does not exist: 2, one line on stderr)
    env = dict(os.environ, MESHREC_CACHE_DIR=str(tmp_path / "cache"))
    helped = subprocess.run(
        [sys.executable, "-m", "meshrec", "--help"], capture_output=True, text=True, env=env
    )
    assert helped.returncode == 0
    assert "usage: meshrec" in helped.stdout
    assert "next-touch" in helped.stdout
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "meshrec",
            "recognize",
            str(tmp_path / "missing.csv"),
            "--models",
            "surfaces",
        ],
        capture_output=True,
        text=True,
        env=env,
    )
    assert bad.returncode == 2
    assert "missing.csv" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_index_refuses_a_cache_folder_it_cannot_write(tmp_path, capsys):
    # index only fills the cache: a --cache-dir that is a file (or lies under one) is bad
    # input, exit 2 with one line, before any model is indexed (it warned "continuing
    # without caching", printed "built" lines and exited 0)
    blocker = tmp_path / "afile"
    blocker.write_text("not a folder")
    for where in (blocker, blocker / "sub"):
        assert main(["index", "surfaces", "--cache-dir", str(where)]) == 2
        captured = capsys.readouterr()
        assert captured.out == ""
        assert captured.err.count("\n") == 1
        assert f"--cache-dir {where}: cannot be created" in captured.err
        assert "index only fills the cache" in captured.err


def test_an_unknown_answer_does_not_call_its_best_fits_pose_precise(tmp_path, capsys):
    # a sphere of radius 1.3 touched, only one of radius 1 in the folder: `unknown`, with a
    # best fit that misses the data; its pose line says so instead of "pose: fixed (data
    # points within about ...)" as if the pose were known that well
    (tmp_path / "m").mkdir()
    trimesh.creation.icosphere(subdivisions=4, radius=1.0).export(tmp_path / "m" / "sphere.stl")
    big = trimesh.creation.icosphere(subdivisions=5, radius=1.3)
    meshrec.simulate_touch(big, length=0.6, noise=0.0005, rng=2).touch.to_file(tmp_path / "t.csv")
    args = ["recognize", str(tmp_path / "t.csv"), "--models", str(tmp_path / "m")]
    assert main([*args, "--cache-dir", str(tmp_path / "c")]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1].startswith("unknown: not in the library (best fit: sphere)")
    assert any(ln.startswith("pose of the best fit (it misses the data): ") for ln in lines)
    assert not any(ln.startswith("pose: ") for ln in lines)


@pytest.mark.parametrize("command", ["recognize", "serve", "next-touch", "index"])
def test_models_help_names_every_bundled_set(command, capsys):
    # `serve --help` named two of the four bundled sets
    from meshrec.model.library import bundled_model_sets

    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "see 'meshrec models'" in text
    for name in bundled_model_sets():
        assert name in text.split("bundled set (")[1].split(";")[0]


def test_index_checks_a_read_only_cache_instead_of_refusing_it(tmp_path, capsys, monkeypatch):
    # a read-only cache that holds every model's index: exit 0 with the models listed as
    # cached (it exited 2, "not writable", though it had nothing to build); one that lacks
    # a model: exit 2 naming it; --force on it: exit 2 before any work
    cache = tmp_path / "cache"
    assert main(["index", "surfaces", "--cache-dir", str(cache)]) == 0
    capsys.readouterr()
    real_access = os.access

    def read_only(path, mode, *a, **k):
        if Path(path) == cache and mode & os.W_OK:
            return False
        return real_access(path, mode, *a, **k)

    monkeypatch.setattr(os, "access", read_only)
    assert main(["index", "surfaces", "--cache-dir", str(cache)]) == 0
    captured = capsys.readouterr()
    assert captured.out.count("cached") == 4
    assert "read-only, and every model's index is in it" in captured.err
    assert main(["index", "surfaces", "--cache-dir", str(cache), "--force"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "not writable, and --force rebuilds every index" in captured.err
    (tmp_path / "m").mkdir()
    trimesh.creation.icosphere(subdivisions=2).export(tmp_path / "m" / "ball.stl")
    assert main(["index", str(tmp_path / "m"), "--cache-dir", str(cache)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "not writable, and 1 of 1 models are not in it (ball)" in captured.err


def test_an_ambiguous_answers_pose_line_names_whose_pose_it_is(tmp_path, capsys):
    # Two copies of one ellipsoid: `ambiguous` between them, the pose line that of the
    # best one only (a probe, stop 34, read "pose: fixed" as the answer's)
    (tmp_path / "m").mkdir()
    egg = trimesh.creation.icosphere(subdivisions=4)
    egg.apply_scale([1.0, 0.8, 0.5])
    for name in ("a", "b"):
        egg.export(tmp_path / "m" / f"{name}.stl")
    meshrec.simulate_touch(egg, rng=5).touch.to_file(tmp_path / "t.csv")
    args = ["recognize", str(tmp_path / "t.csv"), "--models", str(tmp_path / "m")]
    assert main([*args, "--cache-dir", str(tmp_path / "c")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1].startswith("ambiguous: ")
    assert any(ln.startswith("pose of a, if it is that model: ") for ln in lines)
    assert not any(ln.startswith("pose: ") for ln in lines)
