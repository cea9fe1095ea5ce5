"""Reliability of indexing (issue 15): a mesh file changing while it is indexed, corrupt
cache entries declaring huge arrays, temporary files of killed runs, a cache directory
among the models, and an OBJ whose material library is a pipe.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_bad_touch import cli_command, run_cli

from meshrec import ModelIndex, ModelLibrary
from meshrec.model import cache as cache_mod
from meshrec.model import mesh as mesh_mod
from meshrec.model.cache import ArrayCache, CacheWarning


def _env(cache: Path | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("MESHREC_CACHE_DIR", "XDG_CACHE_HOME")}
    if cache is not None:
        env["MESHREC_CACHE_DIR"] = str(cache)
    return env


# ------------------------------------------------------------- 1: hash the parsed bytes
def test_a_file_changed_during_indexing_is_cached_under_its_own_content(tmp_path, monkeypatch):
    path = tmp_path / "thing.stl"
    small = trimesh.creation.icosphere(subdivisions=2)  # 162 vertices
    large = trimesh.creation.icosphere(subdivisions=3)  # 642 vertices
    small.export(path)
    real_load = trimesh.load
    swapped = []

    def load_after_the_file_changed(*args, **kwargs):
        # The file is replaced after indexing started (after any hashing) but before it
        # is parsed: what is parsed must still be what was hashed.
        if not swapped:
            large.export(path)
            swapped.append(True)
        return real_load(*args, **kwargs)

    monkeypatch.setattr(trimesh, "load", load_after_the_file_changed)
    cache = tmp_path / "cache"
    first = ModelIndex.from_file(path, cache_dir=cache)
    monkeypatch.undo()
    assert swapped
    assert len(first.mesh.vertices) == 162  # the content that was there when indexing began
    # The file now holds the large sphere: it must not be answered from the entry of the
    # small sphere's content, and the small sphere's entry must hold the small sphere.
    now = ModelIndex.from_file(path, cache_dir=cache)
    assert len(now.mesh.vertices) == 642
    small.export(path)
    again = ModelIndex.from_file(path, cache_dir=cache)
    assert again.from_cache
    assert len(again.mesh.vertices) == 162


# ------------------------------------------------------------- 2: huge declared arrays
def _with_member_replaced(path: Path, name: str, data: bytes) -> None:
    """Rewrite the zip ``path`` with member ``name`` replaced by ``data``."""
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    members[name] = data
    with zipfile.ZipFile(path, "w") as zf:
        for n, d in members.items():
            zf.writestr(n, d)


def _huge_npy() -> bytes:
    """A .npy whose header declares 10**12 float64 (8 TB) followed by a few bytes."""
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**12,)}
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    return buf.getvalue() + b"\0" * 64


def test_a_cache_entry_declaring_a_huge_array_is_rebuilt(tmp_path):
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=2).export(path)
    cache = tmp_path / "cache"
    good = ModelIndex.from_file(path, cache_dir=cache)
    (entry,) = cache.iterdir()
    _with_member_replaced(entry, "k1.npy", _huge_npy())
    with pytest.warns(CacheWarning, match=r"unreadable \(k1\.npy: its header declares float64"):
        again = ModelIndex.from_file(path, cache_dir=cache)
    assert not again.from_cache
    assert np.array_equal(again.curvature.K, good.curvature.K)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ModelIndex.from_file(path, cache_dir=cache).from_cache  # rewritten


def test_a_cache_load_that_runs_out_of_memory_is_a_miss(tmp_path, monkeypatch):
    c = ArrayCache(tmp_path)
    key = cache_mod.make_key("0" * 64, {})
    c.save(key, {"x": np.zeros(3)})

    def no_memory(*args, **kwargs):
        raise MemoryError("Unable to allocate 7.28 TiB")

    monkeypatch.setattr(cache_mod.np, "load", no_memory)
    with pytest.warns(CacheWarning, match="unreadable.*MemoryError"):
        assert c.load(key, ["x"]) is None


# ------------------------------------------------------------- 6: temporary files
def _dead_pid() -> int:
    """The id of a process that has exited (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _temp(folder: Path, stem: str, pid: int, age: float = 0.0, tag: str = "abcd_123") -> Path:
    """A temporary file as a writer with ``pid`` on this host names it."""
    prefix = cache_mod._temp_prefix(stem).rsplit(".", 2)[0]  # ".<stem>.<host>"
    path = folder / f"{prefix}.{pid}.{tag}.tmp"
    path.write_bytes(b"PK\x03\x04 half an entry")
    if age:
        t = time.time() - age
        os.utime(path, (t, t))
    return path


def test_stale_temporary_files_are_removed_and_live_ones_kept(tmp_path):
    key = cache_mod.make_key("0" * 64, {})
    stem = f"ball-{key}"
    dead = _temp(tmp_path, stem, _dead_pid())
    live = _temp(tmp_path, stem, os.getppid())  # a live process (pytest's parent)
    mine = _temp(tmp_path, stem, os.getpid())
    old = _temp(tmp_path, stem, os.getppid(), age=cache_mod._STALE_TEMP_SECONDS + 60, tag="old")
    legacy_new = tmp_path / f".{stem}.x7_k2abc.tmp"  # an older version's name: no pid
    legacy_new.write_bytes(b"")
    legacy_old = tmp_path / f".{stem}.q9_zzzzz.tmp"
    legacy_old.write_bytes(b"")
    t = time.time() - cache_mod._STALE_TEMP_SECONDS - 60
    os.utime(legacy_old, (t, t))
    other = tmp_path / ".notes.tmp"  # not ours
    other.write_bytes(b"")
    old_other = tmp_path / "x.tmp"
    old_other.write_bytes(b"")
    os.utime(old_other, (t, t))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ArrayCache(tmp_path).load(key, ["x"]) is None  # a miss, and a sweep
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {live.name, mine.name, legacy_new.name, other.name, old_other.name}
    assert not dead.exists()
    assert not old.exists()
    assert not legacy_old.exists()


def test_temporary_files_are_named_after_the_writer(tmp_path, monkeypatch):
    seen = []
    real = cache_mod.os.replace

    def spy(src, dst):
        seen.append(Path(src).name)
        return real(src, dst)

    monkeypatch.setattr(cache_mod.os, "replace", spy)
    key = cache_mod.make_key("0" * 64, {})
    ArrayCache(tmp_path).save(key, {"x": np.zeros(3)}, label="ball")
    (name,) = seen
    m = cache_mod._TEMP_RE.fullmatch(name)
    assert m is not None
    assert m["stem"] == f"ball-{key}"
    assert int(m["pid"]) == os.getpid()


def _models(folder: Path) -> Path:
    folder.mkdir()
    trimesh.creation.icosphere(subdivisions=4).export(folder / "ball.stl")
    trimesh.creation.cylinder(radius=0.5, height=2.0, sections=64).subdivide().export(
        folder / "can.obj"
    )
    trimesh.creation.capsule(height=2.0, radius=0.5, count=[48, 48]).export(folder / "pill.ply")
    return folder


def _same_models(a: ModelLibrary, b: ModelLibrary) -> None:
    assert a.names == b.names
    for x, y in zip(a, b, strict=True):
        for part, name in (
            ("mesh", "vertices"),
            ("mesh", "faces"),
            ("mesh", "vertex_normals"),
            ("curvature", "k1"),
            ("curvature", "k2"),
            ("curvature", "dir1"),
            ("curvature", "dir2"),
            ("curvature", "valid"),
        ):
            a, b = getattr(getattr(x, part), name), getattr(getattr(y, part), name)
            assert np.array_equal(a, b, equal_nan=True), name
        assert (x.mesh.closed, x.mesh.scale, x.mesh.avg_edge, x.curvature.spacing) == (
            y.mesh.closed,
            y.mesh.scale,
            y.mesh.avg_edge,
            y.curvature.spacing,
        )


#: A child that indexes the folder again and again (rebuilding every time), so that a kill
#: at any moment after its imports lands in the middle of some indexing stage.
_INDEX_FOREVER = (
    "import sys, warnings\n"
    "from meshrec import ModelLibrary\n"
    "warnings.simplefilter('ignore')\n"
    "while True:\n"
    "    ModelLibrary.from_folder(sys.argv[1], cache_dir=sys.argv[2], force=True)\n"
)


def _index_entries(folder: Path) -> list[Path]:
    """The index entries of a cache folder, without the models' derived quantities
    (:mod:`meshrec.model.derived`: entries of their own, ``NAME.KIND-KEY.npz``)."""
    return [p for p in folder.glob("*.npz") if "." not in p.name.rsplit("-", 1)[0]]


def _entries_load_cleanly(cache: Path) -> None:
    """Every entry under its final name is complete (writes are atomic)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for entry in cache.glob("*.npz"):
            label, key = entry.stem.rsplit("-", 1)
            assert ArrayCache(cache).load(key, [], label=label) is not None, entry.name


@pytest.mark.slow
def test_indexing_runs_killed_at_random_moments_leave_a_cache_the_next_run_repairs(tmp_path):
    models = _models(tmp_path / "models")
    cache = tmp_path / "cache"
    env = _env()
    rng = np.random.default_rng(15)
    args = [*cli_command(), "index", "--models", str(models), "--cache-dir", str(cache)]
    for i in range(8):
        if i % 2:  # the real command (a first build, or a forced rebuild)
            child = [*args, *(["--force"] if i % 4 == 3 else [])]
            delay = rng.uniform(0.3, 3.0)
        else:  # rebuilding in a loop: killed mid-indexing, sometimes mid-write
            child = [sys.executable, "-c", _INDEX_FOREVER, str(models), str(cache)]
            delay = rng.uniform(0.8, 2.5)
        proc = subprocess.Popen(
            child, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if cache.exists():
            _entries_load_cleanly(cache)
    # Whatever the kills left, plus a temporary file of a writer that certainly died
    # mid-write, the next run must end with a correct cache and no temporary file.
    cache.mkdir(exist_ok=True)
    key = "0" * 64
    _temp(cache, f"ball-{key}", _dead_pid())
    final = run_cli(args[len(cli_command()) :], env, tmp_path)
    assert final.returncode == 0, final.stderr
    assert "Traceback" not in final.stderr
    assert sorted(p.name for p in cache.iterdir() if p.name.endswith(".tmp")) == []
    assert len(_index_entries(cache)) == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cached = ModelLibrary.from_folder(models, cache_dir=cache)
    assert all(m.from_cache for m in cached)
    clean = ModelLibrary.from_folder(models, cache_dir=tmp_path / "clean")
    _same_models(cached, clean)


# ------------------------------------------------------------- 8: cache among the models
def test_a_cache_dir_in_the_model_folder_is_refused(tmp_path):
    models = _models(tmp_path / "models")
    before = sorted(p.name for p in models.iterdir())
    for cache in (models, models / "cache", models / "." / "sub" / ".." / "cache2"):
        with pytest.raises(ValueError, match=r"is (the|inside the) model folder") as info:
            ModelLibrary.from_folder(models, cache_dir=cache)
        assert str(models) in str(info.value)
        assert str(cache) in str(info.value)
    with pytest.raises(ValueError, match=r"cache_dir '.*models' is the model folder '.*models'"):
        ModelIndex.from_file(models / "ball.stl", cache_dir=models)
    with pytest.raises(ValueError, match="is the model folder"):
        ModelLibrary.from_files([models / "ball.stl"], cache_dir=models)
    assert sorted(p.name for p in models.iterdir()) == before


def test_a_cache_dir_in_the_model_folder_from_the_environment_is_refused(tmp_path, monkeypatch):
    models = _models(tmp_path / "models")
    monkeypatch.setenv("MESHREC_CACHE_DIR", str(models))
    with pytest.raises(ValueError, match="is the model folder"):
        ModelLibrary.from_folder(models)
    assert sorted(p.name for p in models.iterdir()) == ["ball.stl", "can.obj", "pill.ply"]


def test_cli_index_refuses_a_cache_dir_in_the_model_folder(tmp_path):
    models = _models(tmp_path / "models")
    proc = run_cli(["index", "--models", str(models), "--cache-dir", str(models)], _env(), tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "is the model folder" in lines[0]
    assert sorted(p.name for p in models.iterdir()) == ["ball.stl", "can.obj", "pill.ply"]


# ------------------------------------------------------------- 9: OBJ material pipes
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_an_obj_whose_material_library_is_a_pipe_indexes_without_hanging(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    os.mkfifo(folder / "pipe.mtl")
    obj = trimesh.exchange.obj.export_obj(trimesh.creation.icosphere(subdivisions=2))
    (folder / "ball.obj").write_text("mtllib pipe.mtl\nusemtl skin\n" + obj)
    script = (
        "import sys; from meshrec.model.mesh import load_mesh; "
        "v, f = load_mesh(sys.argv[1]); print(len(v), len(f))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(folder / "ball.obj")],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=folder,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["162", "320"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_a_pipe_swapped_in_after_the_check_is_refused_without_blocking(tmp_path, monkeypatch):
    path = tmp_path / "ball.stl"
    os.mkfifo(path)
    # check_mesh_path saw a regular file; the pipe is there when the file is opened.
    monkeypatch.setattr(mesh_mod, "check_mesh_path", lambda p: Path(p))
    with pytest.raises(ValueError, match=r"ball\.stl' is not a regular file"):
        mesh_mod.read_mesh_file(path)


def test_a_library_loaded_from_its_pack_sweeps_the_dead_writers_temporary_files(tmp_path):
    models = _models(tmp_path / "models")
    cache = tmp_path / "cache"
    ModelLibrary.from_folder(models, cache_dir=cache)  # the entries and the pack
    dead = _temp(cache, "ball-" + "0" * 64, _dead_pid())
    alive = _temp(cache, "can-" + "0" * 64, os.getpid())  # a writer still running
    lib = ModelLibrary.from_folder(models, cache_dir=cache)
    assert all(m.from_cache for m in lib)
    assert not dead.exists()
    assert alive.exists()
