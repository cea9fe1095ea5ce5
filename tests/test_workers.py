"""Tests for meshrec.recognition.workers: local processes and a Dask cluster give exactly
the serial result."""

import json
import os
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.recognition.workers import ModelWorkers, available_cores

pytestmark = pytest.mark.filterwarnings("ignore::meshrec.model.resolution.ResolutionWarning")


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """Three ellipsoids of 1,280 faces (distinct axes) in a folder, indexed."""
    root = tmp_path_factory.mktemp("workers")
    folder = root / "models"
    folder.mkdir()
    for name, axes in (("a", (1.0, 0.8, 0.6)), ("b", (1.2, 1.0, 0.5)), ("c", (0.9, 0.9, 0.7))):
        m = trimesh.creation.icosphere(subdivisions=3)
        m.apply_scale(axes)
        m.export(folder / f"{name}.stl")
    cache = root / "cache"
    return meshrec.ModelLibrary.from_folder(folder, cache_dir=cache), cache


@pytest.fixture
def parallel_small(monkeypatch):
    """Let three models run in parallel (the threshold is for speed, not correctness)."""
    monkeypatch.setattr(defaults, "PARALLEL_MIN_MODELS", 2)


def _touches(lib):
    sims = [meshrec.simulate_touch(lib["b"], rng=s) for s in (3, 4)]
    return [s.touch for s in sims]


@pytest.fixture(scope="module")
def serial_plain(library):
    """Touches on b (one; one and two; a small sphere no model fits) and their serial
    recognitions without the cascade, made once for the module's tests."""
    lib, _ = library
    one, two = _touches(lib)
    far = meshrec.simulate_touch(
        trimesh.creation.icosphere(subdivisions=4, radius=0.1), length=0.2, rng=5
    ).touch  # no model fits: the widened pass runs too
    touches = (one, [one, two], far)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        serial = [meshrec.recognize(t, lib, cascade=False) for t in touches]
    return touches, serial


def _same(a, b):
    """Two recognitions agree in everything but their timings."""
    assert a.verdict == b.verdict
    assert a.plausible == b.plausible
    assert a.reason == b.reason
    assert a.warnings == b.warnings
    assert a.probabilities == b.probabilities
    assert a.touch_rms == b.touch_rms
    for x, y in zip(a.ranking, b.ranking, strict=True):
        assert x.model == y.model
        assert x.error == y.error
        assert x.rms == y.rms
        assert x.candidates == y.candidates
        assert x.reason == y.reason
        if x.T_model_touch is not None:
            np.testing.assert_array_equal(x.T_model_touch, y.T_model_touch)
        assert len(x.poses) == len(y.poses)
        for p, q in zip(x.poses, y.poses, strict=True):
            np.testing.assert_array_equal(p.T_model_touch, q.T_model_touch)


@pytest.mark.slow
def test_local_processes_give_the_serial_result(library, serial_plain, parallel_small):
    lib, cache = library
    touches, serial = serial_plain
    one = touches[0]
    with ModelWorkers(lib, workers=2, cache_dir=cache) as workers:
        assert workers.mode == "processes"
        assert workers.workers == 2
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            parallel = [
                meshrec.recognize(t, lib, workers=workers, cascade=False) for t in touches
            ]
    assert serial[2].widened_seconds > 0
    for s, p in zip(serial, parallel, strict=True):
        _same(s, p)
    assert serial[0].best.model == "b"
    with pytest.raises(RuntimeError, match="closed"):
        workers.register_each(one, list(lib), serial[0].geometry, "lm")


@pytest.mark.slow
def test_workers_given_as_a_number_load_from_the_librarys_cache(
    library, serial_plain, parallel_small, monkeypatch, tmp_path
):
    # recognize(..., workers=2) makes its own processes: they load the library from the
    # cache it was loaded from (lib.cache_dir), not from the default cache (which they
    # used to fill with a new index of every model)
    lib, cache = library
    assert lib.cache_dir == cache
    default = tmp_path / "default_cache"
    monkeypatch.setenv("MESHREC_CACHE_DIR", str(default))
    touches, serial = serial_plain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parallel = meshrec.recognize(touches[0], lib, workers=2, cascade=False)
    _same(serial[0], parallel)
    assert not default.exists() or list(default.iterdir()) == []


@pytest.mark.slow
def test_progress_and_warnings_come_back_from_the_workers(library, parallel_small):
    lib, cache = library
    one = _touches(lib)[0]
    calls = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        serial = meshrec.recognize(one, lib, cascade=False)
    with (
        ModelWorkers(lib, workers=2, cache_dir=cache) as workers,
        warnings.catch_warnings(record=True) as again,
    ):
        warnings.simplefilter("always")
        rec = meshrec.recognize(
            one, lib, workers=workers, cascade=False, progress=lambda *a: calls.append(a)
        )
    _same(serial, rec)
    assert [(w.category, str(w.message)) for w in caught] == [
        (w.category, str(w.message)) for w in again
    ]
    assert sorted(c[2] for c in calls) == ["a", "b", "c"]
    assert [c[0] for c in calls] == [0, 1, 2]
    assert all(c[1] == 3 for c in calls)
    assert rec.best.model == "b"


def test_a_worker_seeing_another_file_is_an_error(tmp_path, parallel_small):
    folder = tmp_path / "models"
    folder.mkdir()
    for i in range(2):
        trimesh.creation.icosphere(subdivisions=2, radius=1.0 + i).export(folder / f"m{i}.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    trimesh.creation.icosphere(subdivisions=3).export(folder / "m0.stl")  # changed since
    sim = meshrec.simulate_touch(lib["m1"], rng=1)
    with (
        ModelWorkers(lib, workers=2, cache_dir=tmp_path / "cache") as workers,
        pytest.raises(ValueError, match="differs in the worker"),
    ):
        meshrec.recognize(sim.touch, lib, workers=workers)


def test_few_models_or_one_worker_run_here(library):
    lib, _ = library
    assert ModelWorkers(lib, workers=1).mode == "serial"
    assert ModelWorkers(lib, workers=4).mode == "serial"  # fewer than PARALLEL_MIN_MODELS
    assert ModelWorkers(lib).workers == 1
    assert available_cores() >= 1


def test_models_of_another_library_are_refused(library):
    lib, _ = library
    one = _touches(lib)[0]
    with pytest.raises(ValueError, match="must belong to the workers' library"):
        meshrec.recognize(one, lib, workers=ModelWorkers([lib["a"], lib["b"]]))


def test_serial_workers_check_a_copy_by_its_fingerprint(library):
    # The fingerprints are computed on first need (a serial run of the library's own
    # models needs none): a copy of a model with the same arrays is accepted and gives
    # the same registration, one with other arrays under the same name is refused.
    import dataclasses

    from meshrec.recognition.jobs import StageJob

    lib, _ = library
    one = _touches(lib)[0]
    workers = ModelWorkers(lib, workers=1)
    copy = dataclasses.replace(lib["a"])
    assert copy is not lib["a"]
    got = workers.run_stages([StageJob("register", copy)], one, None, "lm")[0]
    want = workers.run_stages([StageJob("register", lib["a"])], one, None, "lm")[0]
    assert (got.model, got.error, got.rms) == (want.model, want.error, want.rms)
    impostor = dataclasses.replace(lib["b"], name="a")
    with pytest.raises(ValueError, match="must belong to the workers' library, got 'a'"):
        workers.run_stages([StageJob("register", impostor)], one, None, "lm")


def test_run_stages_refuses_what_is_not_a_job(library):
    lib, _ = library
    one = _touches(lib)[0]
    with pytest.raises(TypeError, match="jobs\\[0\\] must be a StageJob"):
        ModelWorkers(lib, workers=1).run_stages([lib["a"]], one, None, "lm")


@pytest.mark.parametrize("workers", [0, -2, 1.5, True, "2"])
def test_bad_workers_are_refused(library, workers):
    with pytest.raises(ValueError, match="workers must be a positive integer"):
        ModelWorkers(library[0], workers=workers)


def test_bad_arguments_are_refused(library):
    lib, _ = library
    with pytest.raises(TypeError, match="library must be"):
        ModelWorkers("models")
    with pytest.raises(TypeError, match="library\\[0\\]"):
        ModelWorkers([object()])
    with pytest.raises(ValueError, match="at least one model"):
        ModelWorkers([])
    with pytest.raises(TypeError, match="scheduler"):
        ModelWorkers(lib, scheduler=8786)
    with pytest.raises(TypeError, match="cache_dir"):
        ModelWorkers(lib, cache_dir=3)
    one = _touches(lib)[0]
    with pytest.raises(ValueError, match="scheduler must be None"):
        meshrec.recognize(one, lib, workers=ModelWorkers(lib), scheduler="tcp://x:1")


def test_mixed_parameters_cannot_run_in_parallel(library, tmp_path, parallel_small):
    lib, _ = library
    coarse = meshrec.ModelIndex.from_file(
        lib["a"].path,
        params=meshrec.IndexParams(curvature_fraction=0.2),
        cache_dir=tmp_path,
    )
    models = [coarse, lib["b"], lib["c"]]
    assert ModelWorkers(models, workers=1).mode == "serial"  # fine here
    with pytest.raises(ValueError, match="share one IndexParams"):
        ModelWorkers(models, workers=2)


def test_an_unreachable_scheduler_is_an_error(library, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(defaults, "DASK_CONNECT_SECONDS", 1.0)
    lib, _ = library
    with pytest.raises(ValueError, match="cannot be reached"):
        ModelWorkers(lib, scheduler="tcp://127.0.0.1:9")


@pytest.mark.parametrize("address", ["x", "tcp://host-without-port", "tcp://h:port"])
def test_a_malformed_scheduler_address_names_the_argument(library, address):
    # it raised distributed's own "missing port number in address 'x'" from inside a
    # Client, which was left running and held the interpreter's exit for 20 s
    pytest.importorskip("distributed")
    lib, _ = library
    with pytest.raises(ValueError, match=r"scheduler must be a Dask scheduler address .*got"):
        ModelWorkers(lib, scheduler=address)


def test_scheduler_without_distributed_is_an_import_error(library, monkeypatch):
    lib, _ = library
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ImportError, match="meshrec\\[dask\\]"):
        ModelWorkers(lib, scheduler="tcp://127.0.0.1:8786")


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """A Dask scheduler and two worker processes, started with Dask's own commands on
    the loopback interface (once for this module's tests); yields the scheduler's address."""
    pytest.importorskip("distributed")
    tmp_path = tmp_path_factory.mktemp("dask")
    dask = shutil.which("dask", path=str(Path(sys.executable).parent))
    if dask is None:
        pytest.skip("the dask command is not installed")
    info = tmp_path / "scheduler.json"
    common = ["--no-dashboard"]
    # the workers import the meshrec under test (this checkout), as a deployment's would
    env = {**os.environ, "PYTHONPATH": str(Path(meshrec.__file__).resolve().parents[1])}
    procs = [
        subprocess.Popen(
            [
                dask,
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--scheduler-file",
                str(info),
                *common,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    ]
    try:
        deadline = time.monotonic() + 60
        while not info.is_file() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        procs.append(
            subprocess.Popen(
                [
                    dask,
                    "worker",
                    "--scheduler-file",
                    str(info),
                    "--nworkers",
                    "2",
                    "--nthreads",
                    "1",
                    "--host",
                    "127.0.0.1",
                    *common,
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env=env,
            )
        )
        from distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.slow
def test_a_dask_cluster_gives_the_serial_result(library, serial_plain, dask_cluster):
    lib, cache = library
    (one, both, _), serial = serial_plain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ModelWorkers(lib, scheduler=dask_cluster, cache_dir=cache) as workers:
            assert workers.mode == "dask"
            assert workers.workers == 2
            remote = [
                meshrec.recognize(t, lib, workers=workers, cascade=False) for t in (one, both)
            ]
        # and through recognize's own short-lived client
        once = meshrec.recognize(one, lib, scheduler=dask_cluster, cascade=False)
    for s, r in zip(serial[:2], remote, strict=True):
        _same(s, r)
    _same(serial[0], once)


@pytest.mark.slow
def test_local_processes_see_the_models_through_the_probe_tip(library, parallel_small):
    # the workers load the models plain: the tip radius must reach them
    lib, cache = library
    tip = 0.05
    sim = meshrec.simulate_touch(lib["b"], rng=6, probe_radius=tip)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        serial = meshrec.recognize(sim.touch, lib, probe_radius=tip, cascade=False)
        with ModelWorkers(lib, workers=2, cache_dir=cache) as workers:
            parallel = meshrec.recognize(
                sim.touch, lib, probe_radius=tip, workers=workers, cascade=False
            )
    _same(serial, parallel)
    assert parallel.best.model == "b"
    # at the tip's offset: the data fit to about the noise, not the tip radius
    assert parallel.best.rms < 0.2 * tip


# ------------------------------------------------------------------ with the cascade
@pytest.fixture
def screened_small(monkeypatch):
    """The screen and parallel runs on three models, the screen with one leader: then, on
    the touches of :func:`cascade_cases`, the screen prunes, the cascade prunes after
    the first stages and the lookup rejects models (the thresholds are for speed, not
    correctness; all the decisions are taken in the caller's process)."""
    monkeypatch.setattr(defaults, "PARALLEL_MIN_MODELS", 2)
    monkeypatch.setattr(defaults, "SCREEN_MIN_MODELS", 2)
    monkeypatch.setattr(defaults, "SCREEN_LEADERS", 1)


def _by_screen(regs) -> bool:
    return any(r.pruned and len(r.candidate_points) == 1 for r in regs)


def _after_first_stages(regs) -> bool:
    return any(r.pruned and len(r.candidate_points) > 1 for r in regs)


def _rejected(regs) -> bool:
    return any(r.rejected for r in regs)


def _scan(lib, name, branch, first: int):
    """The first seeded touch on model ``name`` (seeds from ``first``) that the serial
    cascade names best and that takes ``branch`` (which seed does depends on the meshes
    trimesh writes and on the numerical libraries' versions, not on what is tested)."""
    for seed in range(first, first + 40):
        touch = meshrec.simulate_touch(lib[name], rng=seed).touch
        rec = meshrec.recognize(touch, lib)
        if rec.best is not None and rec.best.model == name and branch(rec.ranking):
            return touch, rec
    pytest.fail(f"no touch on {name!r} (seeds {first} to {first + 39}) takes {branch.__name__}")


@pytest.fixture(scope="module")
def cascade_cases(library):
    """The touches and their serial recognitions, found once for the module's tests (with
    the settings of :func:`screened_small`): on a, b pruned by the cascade after its first
    stages; on b, a model rejected by the lookup; on b, models pruned by the screen; and
    the last two together."""
    lib, _ = library
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mp.setattr(defaults, "PARALLEL_MIN_MODELS", 2)
        mp.setattr(defaults, "SCREEN_MIN_MODELS", 2)
        mp.setattr(defaults, "SCREEN_LEADERS", 1)
        (a, ra), (b_rejects, rb), (b_screens, rs) = (
            _scan(lib, "a", _after_first_stages, 0),
            _scan(lib, "b", _rejected, 4),
            _scan(lib, "b", _by_screen, 5),
        )
        both = [b_rejects, b_screens]
        touches = [a, b_rejects, b_screens, both]
        serial = [ra, rb, rs, meshrec.recognize(both, lib)]
    return touches, serial


def _same_cascade(a, b):
    """Two recognitions through the cascade agree in everything but their timings."""
    _same(a, b)
    for x, y in zip(a.ranking, b.ranking, strict=True):
        assert (x.pruned, x.searches, x.raw_hits) == (y.pruned, y.searches, y.raw_hits)


def _cascade_exercised(recs):
    """The touches did take every branch of the cascade (else the test proves little)."""
    regs = [r for rec in recs for r in rec.ranking]
    assert _by_screen(regs)
    assert _after_first_stages(regs)
    assert _rejected(regs)


@pytest.mark.slow
def test_local_processes_give_the_serial_cascades_result(
    library, cascade_cases, screened_small
):
    lib, cache = library
    touches, serial = cascade_cases
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ModelWorkers(lib, workers=2, cache_dir=cache) as workers:
            assert workers.mode == "processes"
            calls = []
            parallel = [
                meshrec.recognize(t, lib, workers=workers, progress=lambda *a: calls.append(a))
                for t in touches
            ]
    _cascade_exercised(serial)
    for s, p in zip(serial, parallel, strict=True):
        _same_cascade(s, p)
    assert [s.best.model for s in serial] == ["a", "b", "b", "b"]
    # progress: every model whose first stages ran, as they came back
    assert all(c[1] == 3 for c in calls)
    assert {c[2] for c in calls} == {"a", "b", "c"}


@pytest.mark.slow
def test_a_dask_cluster_gives_the_serial_cascades_result(
    library, dask_cluster, cascade_cases, screened_small
):
    lib, cache = library
    touches, serial = cascade_cases
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ModelWorkers(lib, scheduler=dask_cluster, cache_dir=cache) as workers:
            remote = [meshrec.recognize(t, lib, workers=workers) for t in touches]
    _cascade_exercised(serial)
    for s, r in zip(serial, remote, strict=True):
        _same_cascade(s, r)
