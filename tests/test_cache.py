"""Tests for meshrec.model.cache: keys, atomic writes, corrupt entries, unwritable folders."""

import os
import stat
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

from meshrec._version import __version__
from meshrec.io import files as files_mod
from meshrec.model import cache as cache_mod
from meshrec.model.cache import ArrayCache, CacheWarning, default_cache_dir, file_sha256, make_key

KEY = make_key("0" * 64, {"a": 1})
OTHER_KEY = make_key("1" * 64, {"a": 1})


def _arrays():
    rng = np.random.default_rng(1)
    return {
        "x": rng.normal(size=(50, 3)),
        "i": np.arange(7, dtype=np.int64),
        "ok": rng.random(9) > 0.5,
        "s": np.array(2.5),
    }


def _assert_same(a, b):
    assert sorted(a) == sorted(b)
    for k in a:
        assert a[k].dtype == b[k].dtype
        assert np.array_equal(a[k], b[k])


def test_default_cache_dir_precedence(monkeypatch, tmp_path):
    monkeypatch.setenv("MESHREC_CACHE_DIR", str(tmp_path / "explicit"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "explicit"
    monkeypatch.setenv("MESHREC_CACHE_DIR", "")
    assert default_cache_dir() == tmp_path / "xdg" / "meshrec"
    monkeypatch.delenv("MESHREC_CACHE_DIR")
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "meshrec"
    assert ArrayCache().directory == tmp_path / "home" / ".cache" / "meshrec"


def test_make_key_depends_on_everything(monkeypatch):
    base = make_key("ab" * 32, {"r": 2, "f": 0.02})
    assert base == make_key("ab" * 32, {"f": 0.02, "r": 2})  # order-independent
    assert base != make_key("cd" * 32, {"r": 2, "f": 0.02})
    assert base != make_key("ab" * 32, {"r": 3, "f": 0.02})
    assert base != make_key("ab" * 32, {"r": 2, "f": 0.02}, kind="other")
    monkeypatch.setattr(cache_mod, "__version__", __version__ + ".post1")
    assert base != make_key("ab" * 32, {"r": 2, "f": 0.02})


def test_make_key_rejects_unserialisable():
    with pytest.raises(ValueError, match="params must be JSON-serialisable"):
        make_key("00", {"x": object()})
    with pytest.raises(ValueError, match="params must be JSON-serialisable"):
        make_key("00", {"x": float("nan")})


def test_file_sha256(tmp_path):
    p = tmp_path / "f.bin"
    p.write_bytes(b"abc")
    assert file_sha256(p) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    with pytest.raises(ValueError, match=r"cannot read file .*missing\.bin"):
        file_sha256(tmp_path / "missing.bin")


def test_path_for_rejects_bad_keys(tmp_path):
    c = ArrayCache(tmp_path)
    for bad in ["", "../x", "ABC", 12]:
        with pytest.raises(ValueError, match="key must be a non-empty lowercase hex string"):
            c.path_for(bad)
    assert c.path_for(KEY, label="my model/1").name == f"my_model_1-{KEY}.npz"


def test_roundtrip_and_silent_miss(tmp_path, recwarn):
    c = ArrayCache(tmp_path / "sub" / "dir")  # created on first write
    assert c.load(KEY, ["x"]) is None
    path = c.save(KEY, _arrays(), label="m")
    assert path == c.path_for(KEY, "m")
    assert path.is_file()
    got = c.load(KEY, ["x", "i", "ok", "s"], label="m")
    _assert_same(got, _arrays())
    assert c.load(KEY, ["x"], label="other") is None  # another label: another file
    assert len(recwarn) == 0
    # no temporary file left behind
    assert sorted(p.name for p in c.directory.iterdir()) == [path.name]


def test_save_rejects_reserved_names(tmp_path):
    with pytest.raises(ValueError, match="reserved names"):
        ArrayCache(tmp_path).save(KEY, {"__cache_key__": np.zeros(1)})


def _write_then(tmp_path, mutate):
    c = ArrayCache(tmp_path)
    path = c.save(KEY, _arrays())
    mutate(path)
    return c


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]), "unreadable"),
        (lambda p: p.write_bytes(b"not a zip file at all"), "unreadable"),
        (lambda p: p.write_bytes(b""), "unreadable"),
        (
            # flip one byte inside the data of the array "x"
            lambda p: p.write_bytes(
                (lambda b: b[:200] + bytes([b[200] ^ 0xFF]) + b[201:])(p.read_bytes())
            ),
            "unreadable|checksum",
        ),
        (lambda p: np.savez(p, x=np.zeros(3)), "lacks its key or checksum"),
    ],
    ids=["truncated", "garbage", "empty", "bitflip", "no-key"],
)
def test_corrupt_entry_warns_and_misses(tmp_path, mutate, match):
    c = _write_then(tmp_path, mutate)
    with pytest.warns(CacheWarning, match=match):
        assert c.load(KEY, ["x"]) is None


def test_entry_of_another_key_is_rejected(tmp_path):
    c = ArrayCache(tmp_path)
    other = c.save(OTHER_KEY, _arrays())
    os.replace(other, c.path_for(KEY))
    with pytest.warns(CacheWarning, match="another key or version"):
        assert c.load(KEY, ["x"]) is None


def test_missing_arrays_are_rejected(tmp_path):
    c = ArrayCache(tmp_path)
    c.save(KEY, _arrays())
    with pytest.warns(CacheWarning, match=r"lacks arrays \['y'\]"):
        assert c.load(KEY, ["x", "y"]) is None


def test_checksum_mismatch_is_rejected(tmp_path):
    c = ArrayCache(tmp_path)
    arrays = _arrays()
    c.save(KEY, arrays)
    # Same key, valid zip, but the data changed after the checksum was taken.
    with np.load(c.path_for(KEY)) as z:
        stored = {k: z[k] for k in z.files}
    stored["x"] = stored["x"] + 1.0
    np.savez(c.path_for(KEY), **stored)
    with pytest.warns(CacheWarning, match="fails its checksum"):
        assert c.load(KEY, ["x"]) is None


def test_unwritable_directory_warns(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    c = ArrayCache(blocker / "cache")  # cannot create a folder under a file
    with pytest.warns(CacheWarning, match="continuing without caching"):
        assert c.save(KEY, _arrays()) is None
    assert c.load(KEY, ["x"]) is None


def test_a_file_as_the_cache_folder_warns_once_per_folder_not_per_model(tmp_path):
    # a library of three models indexed with a file given as the cache folder: one
    # warning for the cache folder and one for the packs' folder, not one per model
    import trimesh

    import meshrec

    folder = tmp_path / "models"
    folder.mkdir()
    for k in range(3):
        trimesh.creation.icosphere(subdivisions=2, radius=1.0 + k).export(folder / f"s{k}.stl")
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=blocker)
    assert len(lib) == 3
    texts = sorted({str(w.message) for w in caught if issubclass(w.category, CacheWarning)})
    assert len(texts) == 2, texts
    assert texts[0].startswith(f"cannot create the cache folder {str(blocker)!r}")
    assert "packs" in texts[1]
    assert blocker.read_text() == "x"


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root ignores permissions"
)
def test_read_only_directory_warns(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    try:
        with pytest.warns(CacheWarning, match="continuing without caching"):
            assert ArrayCache(d).save(KEY, _arrays()) is None
        assert list(d.iterdir()) == []
    finally:
        d.chmod(0o755)


def test_read_only_directory_simulated(tmp_path, monkeypatch):
    # What a read-only folder does to a non-root user (root ignores the mode bits).
    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path))

    monkeypatch.setattr(files_mod.tempfile, "mkstemp", refuse)
    with pytest.warns(CacheWarning, match="PermissionError.*continuing without caching"):
        assert ArrayCache(tmp_path).save(KEY, _arrays()) is None
    assert list(tmp_path.iterdir()) == []


def test_failed_replace_leaves_no_temp_file(tmp_path, monkeypatch):
    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", str(dst))

    monkeypatch.setattr(cache_mod.os, "replace", refuse)
    c = ArrayCache(tmp_path)
    with pytest.warns(CacheWarning, match="PermissionError"):
        assert c.save(KEY, _arrays()) is None
    assert list(tmp_path.iterdir()) == []


def test_interrupted_write_never_shows_under_final_name(tmp_path, monkeypatch):
    c = ArrayCache(tmp_path)

    def crash(file, **arrays):
        file.write(b"PK\x03\x04 half")
        raise OSError("disk full")

    monkeypatch.setattr(cache_mod.np, "savez", crash)
    with pytest.warns(CacheWarning, match="disk full"):
        assert c.save(KEY, _arrays()) is None
    assert list(tmp_path.iterdir()) == []


def test_an_entry_is_written_by_the_one_atomic_writer(tmp_path, monkeypatch):
    """The cache writes through meshrec.io.files.write_atomic, under the temporary name
    its sweep recognises, and fsyncs the folder after the rename."""
    calls, synced_dirs = [], []
    real_write, real_fsync = cache_mod.write_atomic, os.fsync

    def spy(path, content, **kwargs):
        calls.append((Path(path), kwargs))
        return real_write(path, content, **kwargs)

    def fsync(fd):
        if stat.S_ISDIR(os.fstat(fd).st_mode):
            synced_dirs.append(fd)
        return real_fsync(fd)

    monkeypatch.setattr(cache_mod, "write_atomic", spy)
    monkeypatch.setattr(files_mod.os, "fsync", fsync)
    path = ArrayCache(tmp_path).save(KEY, _arrays(), label="ball")
    ((written, kwargs),) = calls
    assert written == path
    assert cache_mod._TEMP_RE.fullmatch(kwargs["prefix"] + "abc_123" + kwargs["suffix"])
    assert synced_dirs  # the folder, after the rename
    assert ArrayCache(tmp_path).load(KEY, ["x"], label="ball") is not None


def test_an_entry_follows_the_umask(tmp_path):
    previous = os.umask(0o027)
    try:
        path = ArrayCache(tmp_path).save(KEY, _arrays())
    finally:
        os.umask(previous)
    assert path.stat().st_mode & 0o777 == 0o640  # as open() would make it, not mkstemp's 0600


@pytest.mark.slow
def test_concurrent_writers_of_one_key_both_succeed(tmp_path):
    script = textwrap.dedent(
        f"""
        import sys, warnings
        import numpy as np
        from meshrec.model.cache import ArrayCache
        warnings.simplefilter("error")
        c = ArrayCache({str(tmp_path)!r})
        x = np.arange(200000, dtype=np.float64)
        for _ in range(15):
            assert c.save({KEY!r}, {{"x": x}}) is not None
            got = c.load({KEY!r}, ["x"])
            assert got is not None and np.array_equal(got["x"], x)
        """
    )
    env = dict(os.environ, PYTHONPATH=str(Path(cache_mod.__file__).parents[1]))
    procs = [
        subprocess.Popen([sys.executable, "-c", script], env=env, stderr=subprocess.PIPE)
        for _ in range(2)
    ]
    for p in procs:
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err.decode()
    assert [p.name for p in tmp_path.iterdir()] == [f"{KEY}.npz"]
