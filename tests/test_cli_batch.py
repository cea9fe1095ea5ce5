"""``meshrec recognize --batch`` (JSON Lines, one object per touch file) and touches read
from standard input (``-``), through the real console script."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from meshrec import TouchData, simulate_touch
from meshrec.app import cli

MODELS = Path(__file__).resolve().parents[1] / "models" / "surfaces"
SCRIPT = Path(sys.executable).with_name("meshrec")


@pytest.fixture(scope="module")
def touches(tmp_path_factory):
    """Two simulated touches (CSV and JSON) with known models, a bad file, and the env."""
    folder = tmp_path_factory.mktemp("batch")
    simulate_touch(MODELS / "monkey_saddle.stl", rng=3).write(folder / "saddle.csv")
    simulate_touch(MODELS / "ellipsoid.stl", rng=24).write(folder / "ellipsoid.json")
    (folder / "bad.csv").write_text("a,b\n1,2\n")
    env = {**os.environ, "MESHREC_CACHE_DIR": str(tmp_path_factory.mktemp("cache"))}
    return folder, env


def _run(args, env, cwd, stdin=None):
    return subprocess.run(
        [str(SCRIPT), *args],
        env=env,
        cwd=cwd,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=600,
    )


def _one_error_line(proc, pattern: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("meshrec: error: ")
    assert pattern in lines[0], lines[0]


def test_batch_prints_one_json_line_per_file_and_goes_on_after_a_bad_one(touches):
    folder, env = touches
    proc = _run(
        ["recognize", "--batch", "saddle.csv", "bad.csv", "ellipsoid.json", "--top", "1"],
        env,
        folder,
    )
    _one_error_line(proc, '1 of 3 touch files failed (their JSON lines have an "error" key)')
    docs = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [d["file"] for d in docs] == ["saddle.csv", "bad.csv", "ellipsoid.json"]
    assert docs[0]["best"] == "monkey_saddle"
    assert len(docs[0]["ranking"]) == 1
    assert set(docs[1]) == {"file", "error"}
    assert "header must be 'curve,x,y,z'" in docs[1]["error"]
    assert docs[2]["best"] == "ellipsoid"


def test_batch_all_good_exits_0_with_stdin_among_the_files(touches):
    folder, env = touches
    proc = _run(
        ["recognize", "--batch", "saddle.csv", "-"],
        env,
        folder,
        stdin=(folder / "ellipsoid.json").read_text(),
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    docs = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [(d["file"], d["best"]) for d in docs] == [
        ("saddle.csv", "monkey_saddle"),
        ("<stdin>", "ellipsoid"),
    ]
    assert docs[1]["touch"]["file"] == "<stdin>"


@pytest.mark.parametrize("name", ["saddle.csv", "ellipsoid.json"])
def test_a_touch_on_standard_input_csv_or_json(touches, name):
    folder, env = touches
    proc = _run(["recognize", "-", "--json"], env, folder, stdin=(folder / name).read_text())
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["best"] == Path(name).stem.replace("saddle", "monkey_saddle")
    assert doc["touch"]["file"] == "<stdin>"


@pytest.mark.parametrize(
    ("args", "stdin", "message"),
    [
        (["recognize", "-"], "a,b\n1,2\n", "touch file <stdin>: header must be 'curve,x,y,z'"),
        (["recognize", "-"], '{"curves": 3}', "touch file <stdin>: 'curves' must be a list"),
        (["recognize", "-"], "", "touch file <stdin>: empty"),
        (["recognize", "saddle.csv", "saddle.csv", "--normal", "0,0,1"], None, "not with 2"),
        (["recognize", "saddle.csv", "-", "-"], "", "standard input) can be given only once"),
        (["recognize", "--batch", "-", "-"], "", "standard input) can be given only once"),
        (["recognize", "--batch", "saddle.csv", "--normal", "0,0,1"], None, "not with --batch"),
        (["recognize", "--batch", "saddle.csv", "--models", "nowhere"], None, "nowhere"),
    ],
)
def test_bad_input_one_line_exit_2(touches, args, stdin, message):
    folder, env = touches
    proc = _run(args, env, folder, stdin=stdin)
    _one_error_line(proc, message)
    assert proc.stdout == ""


def test_batch_loads_the_library_once(touches, monkeypatch, capsys):
    folder, env = touches
    monkeypatch.setenv("MESHREC_CACHE_DIR", env["MESHREC_CACHE_DIR"])
    from meshrec.model.library import ModelLibrary

    calls = []
    real = ModelLibrary.from_folder.__func__

    def counting(cls, *a, **k):
        calls.append(a[0])
        return real(cls, *a, **k)

    monkeypatch.setattr(ModelLibrary, "from_folder", classmethod(counting))
    files = [str(folder / n) for n in ("saddle.csv", "ellipsoid.json", "saddle.csv")]
    assert cli.main(["recognize", "--batch", *files, "--top", "1"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 3
    assert len(calls) == 1


def test_a_reader_that_stops_early_ends_the_batch_quietly(touches):
    # `meshrec recognize --batch ... | head -1`: status 141 (SIGPIPE's), nothing on stderr
    folder, env = touches
    proc = subprocess.Popen(
        [str(SCRIPT), "recognize", "--batch", "saddle.csv", "saddle.csv", "saddle.csv"],
        env=env,
        cwd=folder,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=600) == 141
    assert json.loads(first)["best"] == "monkey_saddle"
    assert err == ""


def test_a_terminal_on_standard_input_is_refused(monkeypatch, capsys):
    class Terminal:
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stdin", Terminal())
    assert cli.main(["recognize", "-"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "meshrec: error: touch file -: standard input is a terminal; pipe a CSV or JSON "
        "touch into it\n"
    )


def test_batch_exits_0_when_a_touch_is_unknown_and_its_line_says_so(touches, tmp_path):
    """Unlike a single recognition (exit 1 when unknown), --batch exits 0 when every file
    was read and recognised, whatever the verdicts: each line carries its touch's verdict."""
    folder, env = touches
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.1)  # curvature 10: no paper
    touch = simulate_touch(sphere, length=0.2, noise=0.001, rng=5).touch  # surface has it
    # each sample logged twice: a RepeatedSamplesWarning raised beside the recognition's
    # own cautions
    TouchData(curves=[np.repeat(c, 2, axis=0) for c in touch.curves]).to_file(
        tmp_path / "sphere.csv"
    )
    single = _run(["recognize", str(tmp_path / "sphere.csv"), "--json"], env, folder)
    assert single.returncode == 1, single.stderr
    proc = _run(
        ["recognize", "--batch", str(tmp_path / "sphere.csv"), "ellipsoid.json"], env, folder
    )
    assert proc.returncode == 0, proc.stderr
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [d["verdict"] for d in lines] == ["unknown", "recognised"]
    assert "error" not in lines[0]
    assert "not in the library" in lines[0]["reason"]
    # the line carries every warning the single --json run gives, the recognition's own
    # cautions (the widened lookup) too: the batch dropped them when anything else warned
    want = json.loads(single.stdout)["warnings"]
    assert any("widened" in w for w in want)
    assert any("counted once" in w for w in want)
    assert lines[0]["warnings"] == want
