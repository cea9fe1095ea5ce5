"""Ctrl-C: the real ``meshrec`` console script, sent SIGINT at seeded moments from start-up
(while numpy is being imported) to the middle of indexing, exits with status 130, one
line on stderr and no traceback, and leaves a cache that the next run uses."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

MODELS = Path(__file__).resolve().parents[1] / "models" / "surfaces"
SCRIPT = Path(sys.executable).with_name("meshrec")

pytestmark = pytest.mark.skipif(
    not Path("/proc/self/maps").exists() or not SCRIPT.exists(),
    reason="needs Linux /proc and the installed console script",
)


def _numpy_loaded(pid: int) -> bool:
    """Whether numpy's compiled core is mapped into the process: it is importing numpy,
    which the command line does inside main (the heavy part of start-up)."""
    try:
        return "_multiarray_umath" in Path(f"/proc/{pid}/maps").read_text()
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return False


def _default_sigint() -> None:
    """In the child before it runs: Ctrl-C's default action, also when this test runs in
    a background job (whose shell ignores SIGINT, and a child inherits that: the run then
    ignored the signal and ended with status 0, as it should)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_index(cache: Path, preexec) -> subprocess.Popen:
    """``meshrec index --force`` of the bundled surfaces into ``cache``; ``preexec`` runs in
    the child before it starts (its SIGINT disposition)."""
    return subprocess.Popen(
        [str(SCRIPT), "index", "--models", str(MODELS), "--cache-dir", str(cache), "--force"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MESHREC_CACHE_DIR": str(cache)},
        preexec_fn=preexec,
    )


def _wait_for_numpy(proc: subprocess.Popen, deadline: float) -> None:
    """Wait until the child is importing numpy (or has ended, or the deadline passed)."""
    while not _numpy_loaded(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.0002)


def _entries(cache: Path) -> int:
    """Finished model entries in the cache (written through a rename: whole files only)."""
    return len(list(cache.glob("*.npz"))) if cache.exists() else 0


def _interrupt(cache: Path, after: float, entries: int = 0) -> subprocess.CompletedProcess:
    """Start ``meshrec index --force``, wait until numpy is loading (and, with ``entries``,
    until that many models are indexed), then ``after`` more seconds, and send SIGINT."""
    proc = _start_index(cache, _default_sigint)
    deadline = time.monotonic() + 60
    _wait_for_numpy(proc, deadline)
    while _entries(cache) < entries and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.0002)
    time.sleep(after)
    running = proc.poll() is None
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert running, f"the run ended before the signal ({after} s): {err}"
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


# Seeded moments (models indexed, seconds after): at once (numpy half-imported), later in
# start-up (trimesh's imports, where a KeyboardInterrupt used to be swallowed and the run
# went on), and during the indexing of the four models, after the first and the second
# model's entry is written (about 0.6 s per model here: timing the indexing from start-up
# instead went stale when the index got faster, and the signal came after the end).
_rng = np.random.default_rng(15)
MOMENTS = [
    (0, 0.0),
    (0, round(float(_rng.uniform(0.05, 0.4)), 3)),
    *[(k, round(float(_rng.uniform(0.0, 0.2)), 3)) for k in (1, 2)],
]


@pytest.mark.parametrize(("entries", "after"), MOMENTS)
def test_ctrl_c_exits_130_quietly(tmp_path, entries, after):
    cache = tmp_path / "cache"
    proc = _interrupt(cache, after, entries)
    assert proc.returncode == 130, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    # the progress lines (stderr is not a terminal) and exactly one line more
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("indexing ")]
    assert lines == ["meshrec: interrupted"], proc.stderr
    # nothing half-written: no temporary file left, and the next run completes, reusing
    # whatever entries were finished
    if cache.exists():
        assert [p.name for p in cache.iterdir() if p.name.startswith(".")] == []
    again = subprocess.run(
        [str(SCRIPT), "index", "--models", str(MODELS), "--cache-dir", str(cache)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr
    assert len(again.stdout.strip().splitlines()) == 4


def test_an_ignored_ctrl_c_stays_ignored(tmp_path):
    # started with SIGINT ignored (as a shell starts a background job), a Ctrl-C during
    # start-up (the heavy imports, where meshrec otherwise exits at once) changes nothing
    cache = tmp_path / "cache"
    proc = _start_index(cache, lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    _wait_for_numpy(proc, time.monotonic() + 60)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert len(out.strip().splitlines()) == 4


def test_start_up_imports_nothing_heavy():
    # importing the package and the command line loads no numpy: Ctrl-C during the
    # heavy imports happens inside main, which turns it into status 130
    code = (
        "import sys, meshrec, meshrec.app.cli; "
        "print(sorted(m for m in ('numpy', 'scipy', 'trimesh', 'igl') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


def test_lazy_public_names():
    import meshrec
    from meshrec.recognition.recognize import recognize

    assert meshrec.recognize is recognize
    assert set(meshrec.__all__) - {"__version__"} <= set(dir(meshrec))
    for name in meshrec.__all__:
        assert getattr(meshrec, name) is not None
    with pytest.raises(AttributeError, match="module 'meshrec' has no attribute 'nothing'"):
        _ = meshrec.nothing


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux /proc)."""
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return []
    return [int(c) for c in text.split()]


@pytest.mark.slow
def test_ctrl_c_to_the_process_group_with_worker_processes(tmp_path):
    """A terminal's Ctrl-C reaches the command and its worker processes (one process
    group): one line, status 130, no traceback from the workers (which used to print a
    KeyboardInterrupt each while they imported), and no worker left behind."""
    import trimesh

    import meshrec

    folder = tmp_path / "models"
    folder.mkdir()
    for k in range(8):  # eight models: --workers starts processes from eight up
        blob = trimesh.creation.icosphere(subdivisions=3)
        blob.apply_scale([1.0, 0.8 + 0.05 * k, 0.6])
        blob.export(folder / f"blob_{k}.stl")
    cache = tmp_path / "cache"
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    meshrec.simulate_touch(lib["blob_3"], rng=0).touch.to_file(tmp_path / "touch.csv")
    cmd = [str(SCRIPT), "recognize", str(tmp_path / "touch.csv"), "--models", str(folder)]
    cmd += ["--cache-dir", str(cache), "--workers", "2"]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while len(_children(proc.pid)) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    workers = _children(proc.pid)
    time.sleep(0.3)  # the workers are importing numpy and loading the library
    running = proc.poll() is None
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert running, err
    assert len(workers) >= 2, err
    assert proc.returncode == 130, (proc.returncode, err)
    assert "Traceback" not in err, err
    assert err.strip().splitlines()[-1] == "meshrec: interrupted"
    time.sleep(1.0)
    assert [w for w in workers if _alive(w)] == []


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    state = next((ln for ln in status.splitlines() if ln.startswith("State:")), "")
    return "(zombie)" not in state
