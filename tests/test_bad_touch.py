"""Bad touch data: a ValueError naming the problem from the API, and from the command line
one line on stderr, exit status 2 and no traceback.

Every case is a touch file written from a valid simulated touch (or from scratch), read
and recognised through the public API, and run through the real ``meshrec`` console
script. The command-line runs of all cases are started together (module fixture) so that
the interpreter start-up is paid in parallel.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import trimesh

from meshrec import (
    ModelLibrary,
    TouchData,
    defaults,
    estimate_local_geometry,
    recognize,
    simulate_touch,
)


def cli_command() -> list[str]:
    """The installed ``meshrec`` console script, else ``python -m meshrec.app.cli``."""
    script = Path(sys.executable).with_name("meshrec")
    return [str(script)] if script.exists() else [sys.executable, "-m", "meshrec.app.cli"]


def run_cli(args, env, cwd, timeout=300) -> subprocess.CompletedProcess:
    """Run the command line with ``args``."""
    return subprocess.run(
        [*cli_command(), *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


def assert_one_line_error(proc: subprocess.CompletedProcess, pattern: str) -> None:
    """Exit status 2, no traceback, exactly one stderr line matching ``pattern``."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("meshrec: error: "), lines[0]
    assert re.search(pattern, lines[0]), (pattern, lines[0])
    assert proc.stdout == ""


# ----------------------------------------------------------------------------- writers
def write_csv(path: Path, curves, header: str = "curve,x,y,z") -> Path:
    """Write curves as CSV rows without any validation (to make bad files)."""
    rows = [header] if header is not None else []
    for i, c in enumerate(curves):
        rows += [f"{i},{x!r},{y!r},{z!r}" for x, y, z in np.asarray(c, dtype=float).tolist()]
    path.write_text("\n".join(rows) + "\n")
    return path


def synthetic_curves(angles_deg, k=1.0, n=21, half=0.3):
    """Three or more plane curves through the origin of z = k (x^2 + y^2) / 2.

    Curve i runs along the direction at ``angles_deg[i]`` in the xy plane; all of them pass
    exactly through the origin, where the normal is z.
    """
    t = np.linspace(-half, half, n)[:, None]
    out = []
    for a in np.radians(angles_deg):
        d = np.array([np.cos(a), np.sin(a), 0.0])
        out.append(t * d + 0.5 * k * t**2 * np.array([0.0, 0.0, 1.0]))
    return out


@dataclass
class Case:
    """One bad touch: how to make it, the extra command-line options, the message."""

    make: object  # (folder, good touch, sim) -> path
    pattern: str
    args: list = field(default_factory=list)  # (folder, sim) -> list, or a list
    cli: bool = True  # also run through the command line (the cases)


def _contact_args(folder, sim):
    far = sim.contact_touch + 1.0 * sim.normal_touch
    return ["--contact", ",".join(repr(float(v)) for v in far)]


def _unreadable(folder, good, sim):
    path = folder / "unreadable.csv"
    if os.geteuid() != 0:
        write_csv(path, good.curves)
        path.chmod(0)
    else:  # root reads any file whatever its mode: a file whose read fails instead
        path.symlink_to("/proc/self/mem")
    return path


def _shifted(good, sim, i, d):
    curves = [c.copy() for c in good.curves]
    curves[i] = curves[i] + d * sim.normal_touch
    return curves


CASES = {
    "empty": Case(lambda f, g, s: _text(f / "empty.csv", ""), r"empty\.csv: empty"),
    "blank_lines": Case(lambda f, g, s: _text(f / "blank.csv", "\n \n,,\n"), r"empty", cli=False),
    "missing_header": Case(
        lambda f, g, s: write_csv(f / "noheader.csv", g.curves, header=None),
        r"header must be 'curve,x,y,z', got '0,",
        cli=False,
    ),
    "wrong_header": Case(
        lambda f, g, s: write_csv(f / "wrong.csv", g.curves, header="id,x,y,z"),
        r"header must be 'curve,x,y,z', got 'id,x,y,z'",
    ),
    "non_numeric": Case(
        lambda f, g, s: _text(f / "text.csv", "curve,x,y,z\n0,1,2,3\n0,1,two,3\n"),
        r"line 3 is not numeric: '0,1,two,3'",
    ),
    "line_numbers_count_blank_lines": Case(
        lambda f, g, s: _text(f / "gaps.csv", "curve,x,y,z\n\n0,1,2,3\n\n0,1,x,3\n"),
        r"gaps\.csv: line 5 is not numeric: '0,1,x,3'",
        cli=False,
    ),
    "nan": Case(
        lambda f, g, s: _text(f / "nan.csv", "curve,x,y,z\n0,1,2,3\n0,nan,2,3\n"),
        r"line 3 has a non-finite value: '0,nan,2,3'",
    ),
    "inf": Case(
        lambda f, g, s: _text(f / "inf.csv", "curve,x,y,z\n0,1,2,-inf\n"),
        r"line 2 has a non-finite value: '0,1,2,-inf'",
        cli=False,
    ),
    "too_many_fields": Case(
        lambda f, g, s: _text(f / "fields.csv", "curve,x,y,z\n0,1,2,3,4\n"),
        r"line 2 must have 4 fields, got 5",
        cli=False,
    ),
    "two_curves": Case(
        lambda f, g, s: write_csv(f / "two.csv", g.curves[:2]),
        r"curves must hold at least 3 curves, got 2",
    ),
    "short_curve": Case(
        lambda f, g, s: write_csv(f / "short.csv", [g.curves[0], g.curves[1][:3], g.curves[2]]),
        r"curves\[1\] must have at least 5 points, got 3",
    ),
    "json_strings": Case(
        lambda f, g, s: _text(f / "strings.json", '{"curves": [[["1", "2", "3"]]]}'),
        r"curves\[0\]\[0\] must hold numbers, got a string",
        cli=False,
    ),
    "json_not_json": Case(
        lambda f, g, s: _text(f / "bad.json", '{"curves": [[1, 2'), r"not valid JSON", cli=False
    ),
    "binary": Case(
        lambda f, g, s: _bytes(f / "binary.csv", bytes(range(256)) * 4), r"binary content"
    ),
    "not_utf8": Case(
        lambda f, g, s: _bytes(f / "latin.csv", b"curve,x,y,z\n0,\xe9,1,2\n"), r"not UTF-8 text",
        cli=False,
    ),
    "directory": Case(lambda f, g, s: _mkdir(f / "folder.csv"), r"folder\.csv: is a directory"),
    "directory_without_suffix": Case(
        lambda f, g, s: _mkdir(f / "folder"), r"folder: is a directory"
    ),
    "pipe": Case(
        lambda f, g, s: _fifo(f / "pipe.csv"), r"pipe\.csv: not a regular file", cli=False
    ),
    "missing": Case(lambda f, g, s: f / "nowhere.csv", r"nowhere\.csv: no such file", cli=False),
    "unreadable": Case(_unreadable, r"unreadable\.csv: cannot be read \("),
    "unknown_suffix": Case(
        lambda f, g, s: write_csv(f / "touch.txt", g.curves), r"unknown suffix '\.txt'", cli=False
    ),
    # geometry of the curves
    "too_few_distinct": Case(
        lambda f, g, s: write_csv(
            f / "distinct.csv",
            [g.curves[0], np.repeat(g.curves[1][:3], 4, axis=0), g.curves[2]],
        ),
        r"curves\[1\] has only 3 distinct points among its 12 \(duplicate points\)",
        cli=False,
    ),
    "revisited_point": Case(
        lambda f, g, s: write_csv(
            f / "revisit.csv", [g.curves[0], np.vstack([g.curves[1], g.curves[1][:4]]), g.curves[2]]
        ),
        rf"curves\[1\] has duplicate points: row {defaults.SIM_POINTS} repeats row 0",
    ),
    "duplicate_curve": Case(
        lambda f, g, s: write_csv(f / "dupcurve.csv", [g.curves[0], g.curves[1], g.curves[0]]),
        r"curves\[0\] and curves\[2\] are the same curve",
        cli=False,
    ),
    "do_not_meet": Case(
        lambda f, g, s: write_csv(f / "apart.csv", _shifted(g, s, 1, 0.2)),
        r"the curves do not meet at a common point: curves\[\d\] and curves\[\d\] pass "
        r"(0\.19\d*|0\.2|0\.20\d*|0\.21\d*) apart",
    ),
    "parallel_pair": Case(
        lambda f, g, s: write_csv(f / "parallel.csv", synthetic_curves([0.0, 4.0, 90.0])),
        r"nearly parallel at p: the tangents of curves\[0\] and curves\[1\] are 4 degrees",
    ),
    "parallel_all": Case(
        lambda f, g, s: write_csv(f / "fan.csv", synthetic_curves([0.0, 11.0, 22.0])),
        r"nearly parallel at p: the Euler system's condition number",
        cli=False,
    ),
    "straight_line": Case(
        lambda f, g, s: write_csv(
            f / "line.csv",
            [np.linspace(a, a + 0.1, 11)[:, None] * [1.0, 2.0, 3.0] for a in (0.0, 0.2, -0.2)],
        ),
        r"all points of the curves lie on one straight line",
    ),
    "contact_far": Case(
        lambda f, g, s: write_csv(f / "contact.csv", g.curves),
        # one unit along the normal from the true contact: the nearest sample is about 1
        # away (it used to say how far the curve fits, carried past their data, passed)
        r"the contact point \[.*\] is (0\.9\d*|1\.0\d*|1) away from the nearest sample "
        r"of curves\[\d\], and the curves are 0\.\d+ long",
        _contact_args,
    ),
    "millimetres": Case(
        lambda f, g, s: write_csv(f / "mm.csv", [c * 1000.0 for c in g.curves]),
        r"is \d+(\.\d+)? times larger than the nearest-sized model 'ball'.*"
        r"likely a unit mismatch \(mm vs m\?\)",
    ),
    # hostile input (issue 15): numbers beyond a float, sizes beyond the limits, file names
    # that would break the one-line message
    "json_huge_integer": Case(
        lambda f, g, s: _text(f / "huge.json", '{"curves": [[[1' + "0" * 400 + ", 0, 0]]]}"),
        r"huge\.json: curves\[0\]\[0\] holds an integer too large for a float \(401 digits\)",
    ),
    "too_many_rows": Case(
        lambda f, g, s: write_csv(
            f / "rows.csv", [np.zeros((defaults.MAX_TOUCH_POINTS // 3 + 1, 3))] * 3
        ),
        rf"rows\.csv: more than {defaults.MAX_TOUCH_POINTS} points \(defaults\.MAX_TOUCH_POINTS\)",
    ),
    "too_many_points_per_curve": Case(
        lambda f, g, s: write_csv(
            f / "long.csv",
            [np.zeros((defaults.MAX_POINTS_PER_CURVE + 1, 3)), g.curves[1], g.curves[2]],
        ),
        rf"curves\[0\] must have at most {defaults.MAX_POINTS_PER_CURVE} points",
        cli=False,
    ),
    "file_too_large": Case(
        lambda f, g, s: _bytes(
            f / "large.json", b" " * defaults.TOUCH_MAX_FILE_BYTES + b'{"curves": []}'
        ),
        rf"large\.json: {defaults.TOUCH_MAX_FILE_BYTES + 14} bytes, larger than the limit",
    ),
    "newline_in_name": Case(
        lambda f, g, s: _text(f / "two\nlines.csv", ""), r"two\\nlines\.csv: empty"
    ),
    "bytes_not_utf8_in_name": Case(
        lambda f, g, s: _text(f / os.fsdecode(b"caf\xe9.csv"), ""), r"caf\\xe9\.csv: empty"
    ),
    "metres": Case(
        lambda f, g, s: write_csv(f / "m.csv", [c / 1000.0 for c in g.curves]),
        r"times smaller than the nearest-sized model 'ball'.*likely a unit mismatch \(mm vs m\?\)",
        cli=False,
    ),
}


def _text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _bytes(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _mkdir(path: Path) -> Path:
    path.mkdir()
    return path


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


# ----------------------------------------------------------------------------- fixtures
@dataclass
class Setup:
    folder: Path
    models: Path
    env: dict
    library: ModelLibrary
    sim: object
    files: dict
    args: dict
    cli: dict


@pytest.fixture(scope="module")
def setup(tmp_path_factory) -> Setup:
    root = tmp_path_factory.mktemp("bad_touch")
    models = root / "models"
    models.mkdir()
    trimesh.creation.icosphere(subdivisions=3).export(models / "ball.stl")
    cache = root / "cache"
    env = {**os.environ, "MESHREC_CACHE_DIR": str(cache)}
    library = ModelLibrary.from_folder(models, cache_dir=cache)
    sim = simulate_touch(library["ball"], rng=5)
    folder = root / "touches"
    folder.mkdir()
    files, args = {}, {}
    for name, case in CASES.items():
        files[name] = case.make(folder, sim.touch, sim)
        args[name] = case.args(folder, sim) if callable(case.args) else list(case.args)
    argv = {
        name: ["recognize", str(files[name]), "--models", str(models), *args[name]]
        for name, case in CASES.items()
        if case.cli
    }
    (folder / "outdir.csv").mkdir()  # an output file that cannot be written
    out = str(folder / "outdir.csv")
    argv["unwritable_output"] = ["simulate", str(models / "ball.stl"), "-o", out]
    # the simulator's hostile input, and a huge normal that is only a direction
    (folder / "notes.txt").write_text("not a mesh\n")
    (folder / "bad\nname.stl").write_text("solid nothing\n")
    sim_out = str(folder / "sim.csv")
    argv["simulate_not_a_mesh"] = ["simulate", str(folder / "notes.txt"), "-o", sim_out]
    argv["simulate_bad_name"] = ["simulate", str(folder / "bad\nname.stl"), "-o", sim_out]
    argv["simulate_missing_name"] = ["simulate", "no\nsuch", "-o", sim_out]
    argv["simulate_huge_noise"] = ["simulate", str(models / "ball.stl"), "-o", sim_out]
    argv["simulate_huge_noise"] += ["--noise", "1e308"]
    argv["simulate_huge_points"] = [*argv["simulate_not_a_mesh"][:1], str(models / "ball.stl")]
    argv["simulate_huge_points"] += ["-o", sim_out, "--points", str(10**9 + 1)]
    sim.write(folder / "good.csv")
    good = str(folder / "good.csv")
    huge = ",".join(repr(float(v)) for v in 1e308 * sim.normal_touch)  # the true side
    argv["normal_huge"] = ["recognize", good, "--models", str(models), "--normal", huge]
    argv["normal_overflow"] = ["recognize", good, "--models", str(models), "--normal", "1e309,0,0"]
    argv["simulate_ok"] = ["simulate", str(models / "ball.stl"), "-o", str(folder / "s" / "t.csv")]
    argv["simulate_ok"] += ["--seed", "3"]
    with ThreadPoolExecutor(max_workers=3) as pool:
        futures = {name: pool.submit(run_cli, a, env, root) for name, a in argv.items()}
        cli = {name: f.result() for name, f in futures.items()}
    return Setup(root, models, env, library, sim, files, args, cli)


def _api(setup: Setup, name: str):
    """What the command line does, through the public API."""
    touch = TouchData.from_file(setup.files[name])
    args = setup.args[name]
    if args:
        contact = np.array([float(v) for v in args[1].split(",")])
        touch = touch.with_hints(contact=contact)
    return recognize(touch, setup.library)


# ----------------------------------------------------------------------------- tests
@pytest.mark.parametrize("name", sorted(CASES))
def test_api_raises_a_value_error_naming_the_problem(setup, name):
    with pytest.raises(ValueError, match=CASES[name].pattern) as info:
        _api(setup, name)
    assert info.type is ValueError


@pytest.mark.parametrize("name", sorted(n for n, c in CASES.items() if c.cli))
def test_cli_one_line_exit_2(setup, name):
    assert_one_line_error(setup.cli[name], CASES[name].pattern)


def test_cli_output_that_cannot_be_written(setup):
    assert_one_line_error(setup.cli["unwritable_output"], r"outdir\.csv: Is a directory$")


@pytest.mark.parametrize(
    ("name", "pattern"),
    [
        ("simulate_not_a_mesh", r"notes\.txt: not a readable mesh \(NotImplementedError: "),
        ("simulate_bad_name", r"bad\\nname\.stl: "),
        ("simulate_missing_name", r"model_file no\\nsuch: no such file"),
        (
            "simulate_huge_noise",
            r"noise must be at most 1\.0 \* sqrt\(area\) = [\d.]+ .*got 1e\+308",
        ),
        ("simulate_huge_points", r"--points must be <= 9999, got 1000000001"),
        (
            "normal_overflow",
            r"argument --normal: expected three finite numbers X,Y,Z, got '1e309,0,0'",
        ),
    ],
)
def test_cli_hostile_input_one_line_exit_2(setup, name, pattern):
    assert_one_line_error(setup.cli[name], pattern)


def test_cli_huge_normal_is_a_direction(setup):
    # (1e308)^2 overflows: it used to print an overflow warning and then an error
    proc = setup.cli["normal_huge"]
    assert proc.returncode == 0, proc.stderr
    # nothing but the resolution check's warning about the small test ball
    assert [
        ln for ln in proc.stderr.splitlines() if "too coarse for reliable answers" not in ln
    ] == []
    assert "recognised: ball" in proc.stdout


def test_cli_simulate_writes_the_truth_only_where_asked_with_the_umask_mode(setup):
    proc = setup.cli["simulate_ok"]
    assert proc.returncode == 0, proc.stderr
    assert "no truth file (use --truth)" in proc.stdout
    folder = setup.folder / "touches" / "s"
    assert sorted(p.name for p in folder.iterdir()) == ["t.csv"]
    umask = os.umask(0o022)
    os.umask(umask)  # the subprocess inherited this umask
    assert (folder / "t.csv").stat().st_mode & 0o777 == 0o666 & ~umask


def test_curves_that_miss_report_how_far_apart(setup):
    # the reported distance tracks the lift of one curve off the others
    for lift in (0.1, 0.4):
        curves = _shifted(setup.sim.touch, setup.sim, 1, lift)
        with pytest.raises(ValueError, match="do not meet") as info:
            recognize(TouchData(curves=curves), setup.library)
        apart = float(re.search(r"pass ([0-9.e+-]+) apart", str(info.value)).group(1))
        assert apart == pytest.approx(lift, rel=0.1)


def test_the_limits_are_the_defaults(setup):
    # just inside the meeting tolerance the touch is accepted, just outside refused
    sim = setup.sim
    g = estimate_local_geometry(sim.touch.curves)
    limit = defaults.MAX_MEET_FRACTION * g.half_length
    assert defaults.MAX_MEET_NOISE_FACTOR * g.fit_rms < limit  # the length term decides
    ok = TouchData(curves=_shifted(sim.touch, sim, 1, 0.5 * limit))
    assert recognize(ok, setup.library).best.model == "ball"  # the unspoiled touch works too
    bad = TouchData(curves=_shifted(sim.touch, sim, 1, 1.5 * limit))
    with pytest.raises(ValueError, match="do not meet"):
        recognize(bad, setup.library)
    # a touch as large as the model (UNIT_MAX_TOUCH_DIAGONALS / 2) is accepted, not a unit error
    size = float(np.linalg.norm(np.ptp(sim.touch.points, axis=0)))
    diagonal = float(np.linalg.norm(np.ptp(setup.library["ball"].mesh.vertices, axis=0)))
    assert 0.1 < size / diagonal < 1.0  # a simulated touch is a fraction of the model's size
    factor = 0.5 * defaults.UNIT_MAX_TOUCH_DIAGONALS * diagonal / size
    big = TouchData(curves=[c * factor for c in sim.touch.curves])
    rec = recognize(big, setup.library)
    assert rec.best is None  # far too big to fit, but not a unit error
