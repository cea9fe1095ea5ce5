"""Tests for meshrec.model.pack: the consolidated, memory-mapped library cache."""

import warnings

import numpy as np
import pytest
import trimesh

from meshrec.model import pack
from meshrec.model.cache import CacheWarning
from meshrec.model.index import IndexParams
from meshrec.model.library import ModelLibrary

pytestmark = pytest.mark.filterwarnings("ignore::meshrec.model.library.LibraryWarning")

_ARRAYS = ("vertices", "faces", "vertex_normals", "k1", "k2", "dir1", "dir2", "valid")


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "models"
    d.mkdir()
    trimesh.creation.icosphere(subdivisions=2, radius=1.0).export(d / "ball.stl")
    trimesh.creation.capsule(height=1.0, radius=0.4, count=[16, 16]).export(d / "pill.stl")
    e = trimesh.creation.icosphere(subdivisions=2)
    e.apply_scale([1.5, 1.0, 0.7])
    e.export(d / "egg.stl")
    (d / "notes.txt").write_text("not a model")
    return d


def _packs(cache):
    return sorted(p for p in (cache / "packs").iterdir() if not p.name.startswith("."))


def _same(a, b):
    assert a.names == b.names
    for x, y in zip(a, b, strict=True):
        for name in _ARRAYS:
            left = getattr(x.mesh, name, None)
            if left is None:
                left, right = getattr(x.curvature, name), getattr(y.curvature, name)
            else:
                right = getattr(y.mesh, name)
            np.testing.assert_array_equal(left, right)
        np.testing.assert_array_equal(x.surface.edge_bulge, y.surface.edge_bulge)
        assert x.build_seconds == y.build_seconds
        assert x.path == y.path
        assert x.params == y.params
        # the same surface queries
        p = np.random.default_rng(0).normal(size=(20, 3))
        for u, v in zip(x.surface.closest_points(p), y.surface.closest_points(p), strict=True):
            np.testing.assert_array_equal(u, v)


def test_pack_round_trip_equals_the_per_model_load(folder, tmp_path):
    cache = tmp_path / "cache"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        built = ModelLibrary.from_folder(folder, cache_dir=cache)
        (found,) = _packs(cache)
        assert found.name.startswith("models-")
        packed = ModelLibrary.from_folder(folder, cache_dir=cache)
        rebuilt = ModelLibrary.from_folder(folder, cache_dir=cache, force=True)
        repacked = ModelLibrary.from_folder(folder, cache_dir=cache)
    assert not list(folder.glob("*.npy"))
    assert not (folder / "packs").exists()
    _same(built, packed)
    # a forced rebuild replaces the pack (new build records)
    assert [m.build_seconds for m in rebuilt] != [m.build_seconds for m in built]
    _same(rebuilt, repacked)
    assert len(_packs(cache)) == 1
    assert all(m.from_cache for m in packed)
    assert [str(p) for p, _ in packed.skipped] == [str(folder / "notes.txt")]
    # memory-mapped, read-only
    v = packed["ball"].mesh.vertices
    assert not v.flags.writeable
    base = v
    while base.base is not None and not isinstance(base, np.memmap):
        base = base.base
    assert isinstance(base, np.memmap)


def test_a_corrupt_pack_is_rebuilt(folder, tmp_path):
    cache = tmp_path / "cache"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = ModelLibrary.from_folder(folder, cache_dir=cache)
    (found,) = _packs(cache)
    data = bytearray((found / "k1.npy").read_bytes())
    data[-5] ^= 0xFF  # one flipped byte in the data
    (found / "k1.npy").write_bytes(bytes(data))
    with pytest.warns(CacheWarning, match="fails its checksum"):
        again = ModelLibrary.from_folder(folder, cache_dir=cache)
    _same(good, again)
    (rebuilt,) = _packs(cache)
    assert rebuilt.name == found.name
    assert (rebuilt / "k1.npy").read_bytes() != bytes(data)
    # a truncated table of contents
    (rebuilt / "toc.json").write_text('{"format": 1, "key"')
    with pytest.warns(CacheWarning, match="unusable"):
        ModelLibrary.from_folder(folder, cache_dir=cache)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        warnings.simplefilter("error", CacheWarning)  # valid again: no warning
        _same(good, ModelLibrary.from_folder(folder, cache_dir=cache))


def test_a_changed_file_or_parameter_invalidates_the_pack(folder, tmp_path):
    cache = tmp_path / "cache"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ModelLibrary.from_folder(folder, cache_dir=cache)
        (first,) = _packs(cache)
        trimesh.creation.icosphere(subdivisions=3, radius=2.0).export(folder / "ball.stl")
        lib = ModelLibrary.from_folder(folder, cache_dir=cache)
        assert lib["ball"].mesh.scale > 3.0  # the new file's model, not the packed one
        (second,) = _packs(cache)  # the old pack is removed
        assert second != first
        coarse = IndexParams(curvature_fraction=0.2)
        other = ModelLibrary.from_folder(folder, cache_dir=cache, params=coarse)
        assert other["ball"].params == coarse
        assert len(_packs(cache)) == 1  # one pack per library folder


def test_pack_key_depends_on_every_input(folder):
    files = sorted(folder.glob("*.stl"))
    digests = pack.file_digests(files)
    key = pack.pack_key(files, digests, IndexParams())
    assert key == pack.pack_key(files, digests, IndexParams())
    assert key != pack.pack_key(files, (digests[1], digests[0], digests[2]), IndexParams())
    assert key != pack.pack_key(files[::-1], digests[::-1], IndexParams())
    assert key != pack.pack_key(files, digests, IndexParams(curvature_fraction=0.05))


def test_file_digests_of_an_unreadable_file_is_none(folder):
    assert pack.file_digests([folder / "missing.stl"]) is None


def test_pack_key_refuses_mismatched_inputs(folder):
    files = sorted(folder.glob("*.stl"))
    with pytest.raises(ValueError, match="digests must hold one digest per file"):
        pack.pack_key(files, ("0" * 64,), IndexParams())
    with pytest.raises(ValueError, match="params must be an IndexParams"):
        pack.pack_key(files, pack.file_digests(files), {"curvature_fraction": 0.1})


def test_an_unwritable_cache_leaves_the_library_usable(folder, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "packs").write_text("a file where the packs folder would be")
    with pytest.warns(
        CacheWarning,
        match=r"cannot create the cache folder .*packs.*the library loads model by model",
    ):
        lib = ModelLibrary.from_folder(folder, cache_dir=cache)
    assert lib.names == ("ball", "egg", "pill")
