"""The index cache: concurrent writers, corrupt entries, changed meshes, and a model folder
that is never written to (it may be read-only).

The command-line runs use the real ``meshrec`` console script.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import warnings
from pathlib import Path

import pytest
import trimesh
from test_bad_touch import cli_command, run_cli

from meshrec import IndexParams, ModelLibrary, simulate_touch

NAMES = ("ball", "can", "pill")


def _models(folder: Path) -> Path:
    """Three small meshes (a few tenths of a second to index each)."""
    folder.mkdir()
    trimesh.creation.icosphere(subdivisions=5).export(folder / "ball.stl")
    trimesh.creation.cylinder(radius=0.5, height=2.0, sections=96).subdivide().export(
        folder / "can.obj"
    )
    trimesh.creation.capsule(height=2.0, radius=0.5, count=[64, 64]).export(folder / "pill.ply")
    return folder


def _snapshot(folder: Path) -> dict:
    """Every entry below ``folder`` (and the folder) with its size, mtime and mode."""
    out = {".": (folder.stat().st_mtime_ns, folder.stat().st_mode)}
    for p in sorted(folder.rglob("*")):
        st = p.stat()
        out[str(p.relative_to(folder))] = (st.st_size, st.st_mtime_ns, st.st_mode)
    return out


def _env(cache: Path | None = None, **extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("MESHREC_CACHE_DIR", "XDG_CACHE_HOME")}
    if cache is not None:
        env["MESHREC_CACHE_DIR"] = str(cache)
    env.update(extra)
    return env


def _how(stdout: str) -> dict:
    """``meshrec index`` output: model name -> "cached" or "built"."""
    out = {}
    for line in stdout.splitlines():
        name = line.split()[0]
        out[name] = "cached" if line.rstrip().endswith("cached") else "built"
    return out


def _index_entries(folder: Path) -> list[Path]:
    """The index entries of a cache folder, without the models' derived quantities
    (:mod:`meshrec.model.derived`: entries of their own, ``NAME.KIND-KEY.npz``)."""
    return [p for p in folder.glob("*.npz") if "." not in p.name.rsplit("-", 1)[0]]


@pytest.mark.slow
def test_two_concurrent_index_runs_leave_a_cache_a_third_run_accepts(tmp_path):
    models = _models(tmp_path / "models")
    before = _snapshot(models)
    cache = tmp_path / "cache"
    # MESHREC_CACHE_DIR points elsewhere: --cache-dir must win
    env = _env(tmp_path / "other_cache")
    args = [*cli_command(), "index", "--models", str(models), "--cache-dir", str(cache)]
    procs = [
        subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
        assert "Traceback" not in err
        assert "warning" not in _without_resolution(err)
        assert set(_how(out)) == set(NAMES)
    # at least one of them built every model (both, when they ran at the same time)
    assert all("built" in (_how(outs[0][0])[n], _how(outs[1][0])[n]) for n in NAMES)
    entries = sorted(p.name for p in cache.iterdir() if p.name != "packs")  # (library packs)
    assert len(_index_entries(cache)) == 3
    assert all(name.endswith(".npz") and not name.startswith(".") for name in entries)
    assert not (tmp_path / "other_cache").exists()

    third = run_cli(["index", "--models", str(models), "--cache-dir", str(cache)], env, tmp_path)
    assert third.returncode == 0, third.stderr
    assert _how(third.stdout) == dict.fromkeys(NAMES, "cached")
    assert "warning" not in _without_resolution(third.stderr)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lib = ModelLibrary.from_folder(models, cache_dir=cache)
    assert all(lib[name].from_cache for name in NAMES)
    assert sorted(p.name for p in cache.iterdir() if p.name != "packs") == entries
    assert _snapshot(models) == before


@pytest.mark.slow
def test_the_model_folder_is_never_written(tmp_path):
    # What a read-only model folder needs: nothing is created, changed or removed in it,
    # whatever the command (root ignores the mode bits, so this checks the folder itself).
    models = _models(tmp_path / "models")
    xdg = tmp_path / "xdg"
    env = _env(XDG_CACHE_HOME=str(xdg))
    before = _snapshot(models)
    touch = tmp_path / "touch.csv"
    simulate_touch(models / "ball.stl", rng=1).touch.to_file(touch)
    for args in (
        ["index", "--models", str(models)],
        ["index", "--models", str(models), "--force"],
        ["recognize", str(touch), "--models", str(models), "--top", "1"],
    ):
        proc = run_cli(args, env, models)  # even run from inside the folder
        assert proc.returncode == 0, proc.stderr
    assert "recognised: ball" in proc.stdout
    assert _snapshot(models) == before
    # the default cache: $XDG_CACHE_HOME/meshrec
    assert len(_index_entries(xdg / "meshrec")) == 3


def test_default_cache_is_in_the_user_cache_directory(tmp_path, monkeypatch):
    models = _models(tmp_path / "models")
    monkeypatch.delenv("MESHREC_CACHE_DIR", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    before = _snapshot(models)
    ModelLibrary.from_folder(models)
    assert len(list((tmp_path / "home" / ".cache" / "meshrec").glob("*.npz"))) == 3
    assert _snapshot(models) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores permissions")
def test_read_only_model_folder(tmp_path):
    models = _models(tmp_path / "models")
    for p in [*models.iterdir(), models]:
        p.chmod(0o555)
    try:
        proc = run_cli(["index", "--models", str(models)], _env(tmp_path / "cache"), tmp_path)
        assert proc.returncode == 0, proc.stderr
        assert _how(proc.stdout) == dict.fromkeys(NAMES, "built")
    finally:
        for p in [models, *models.iterdir()]:
            p.chmod(0o755)


@pytest.mark.slow
def test_corrupt_or_truncated_cache_is_rebuilt_with_a_warning(tmp_path):
    models = _models(tmp_path / "models")
    cache = tmp_path / "cache"
    env = _env(cache)
    first = run_cli(["index", "--models", str(models)], env, tmp_path)
    assert first.returncode == 0, first.stderr
    entries = {p.name.split("-")[0]: p for p in cache.iterdir()}
    data = entries["ball"].read_bytes()
    entries["ball"].write_bytes(data[: len(data) // 3])  # truncated
    raw = bytearray(entries["can"].read_bytes())
    raw[len(raw) // 2] ^= 0xFF  # one flipped byte inside the arrays
    entries["can"].write_bytes(bytes(raw))
    # the library's consolidated pack (still valid: the meshes did not change) would be
    # read instead of the entries; without it the entries are read and found corrupt
    # (a corrupt pack: tests/test_pack.py)
    shutil.rmtree(cache / "packs")
    second = run_cli(["index", "--models", str(models)], env, tmp_path)
    assert second.returncode == 0, second.stderr
    assert "Traceback" not in second.stderr
    warned = [
        ln
        for ln in _without_resolution(second.stderr).splitlines()
        if ln.startswith("meshrec: warning:")
    ]
    assert len(warned) == 2
    assert any("ball-" in w and "unreadable" in w for w in warned)
    assert any("can-" in w and ("unreadable" in w or "checksum" in w) for w in warned)
    assert _how(second.stdout) == {"ball": "built", "can": "built", "pill": "cached"}
    third = run_cli(["index", "--models", str(models)], env, tmp_path)
    assert _how(third.stdout) == dict.fromkeys(NAMES, "cached")
    assert "warning" not in _without_resolution(third.stderr)


def test_a_changed_mesh_or_parameter_is_rebuilt(tmp_path):
    models = _models(tmp_path / "models")
    cache = tmp_path / "cache"
    ModelLibrary.from_folder(models, cache_dir=cache)
    trimesh.creation.icosphere(subdivisions=4).export(models / "ball.stl")  # new content
    lib = ModelLibrary.from_folder(models, cache_dir=cache)
    assert {m.name: m.from_cache for m in lib} == {"ball": False, "can": True, "pill": True}
    assert len(lib["ball"].mesh.vertices) == len(
        trimesh.creation.icosphere(subdivisions=4).vertices
    )
    other = ModelLibrary.from_folder(
        models, params=IndexParams(curvature_fraction=0.05), cache_dir=cache
    )
    assert not any(m.from_cache for m in other)
    assert len(list(cache.glob("*.npz"))) == 3 + 1 + 3  # every version kept side by side


def _without_resolution(stderr: str) -> str:
    """stderr without the resolution check's warnings (these test meshes are coarse on
    purpose: small and fast; test_resolution.py tests those warnings)."""
    return "\n".join(
        ln for ln in stderr.splitlines() if "too coarse for reliable answers" not in ln
    )
