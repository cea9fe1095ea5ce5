"""Tests for meshrec.model.derived: a model's resolution, vertex scatter and
near-symmetries kept on disk beside its index."""

import dataclasses
import os
import warnings

import numpy as np
import pytest
import trimesh

from meshrec import defaults
from meshrec.model import index as index_module
from meshrec.model.cache import ArrayCache, CacheWarning
from meshrec.model.derived import KINDS, DerivedStore
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.library import ModelLibrary
from meshrec.model.resolution import Resolution
from meshrec.model.symmetry import NearSymmetries, turn_about

pytestmark = pytest.mark.filterwarnings("ignore::meshrec.model.library.LibraryWarning")

_PARAMS = dataclasses.asdict(IndexParams())


def _store(tmp_path, label="m"):
    return DerivedStore(tmp_path / "cache", "ab" * 32, _PARAMS, label)


def _never():
    raise AssertionError("computed again: the entry was not read")


def _resolution():
    return Resolution(
        curve_length=0.6,
        edge_median=0.01,
        edge_p90=0.013,
        vertices_per_curve=60.0,
        curved_fraction=0.9,
        chord_error=1.5e-5,
        chord_fraction=2.5e-5,
        curvature_min=float("nan"),
        curvature_max=3.25,
        sliver_fraction=0.0,
        too_coarse=True,
        reasons=("one reason, with a comma", "another: 'quoted'"),
    )


def _near():
    axis = np.array([0.0, 0.6, 0.8])
    through = np.array([0.1, -0.2, 0.3])
    half = turn_about(np.pi, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.01, 0.0]))
    return NearSymmetries(half_turns=(half,), axes=((axis, through),))


def _same_near(a, b):
    assert len(a.half_turns) == len(b.half_turns)
    assert len(a.axes) == len(b.axes)
    for x, y in zip(a.half_turns, b.half_turns, strict=True):
        np.testing.assert_array_equal(x, y)
    for (u, p), (v, q) in zip(a.axes, b.axes, strict=True):
        np.testing.assert_array_equal(u, v)
        np.testing.assert_array_equal(p, q)


def test_each_kind_round_trips_bit_for_bit(tmp_path):
    store = _store(tmp_path)
    res = _resolution()
    assert store.kept("resolution", lambda: res) is res  # computed and written
    back = store.kept("resolution", _never)
    np.testing.assert_equal(dataclasses.astuple(back), dataclasses.astuple(res))  # NaN too
    assert back.reasons == res.reasons
    assert back.too_coarse is True

    assert store.kept("vertex_scatter", lambda: 1.2345678901234567e-4) == 1.2345678901234567e-4
    assert store.kept("vertex_scatter", _never) == 1.2345678901234567e-4

    near = _near()
    store.kept("near_symmetries", lambda: near)
    _same_near(store.kept("near_symmetries", _never), near)
    empty = DerivedStore(tmp_path / "cache", "cd" * 32, _PARAMS, "m")
    empty.kept("near_symmetries", NearSymmetries)
    assert empty.kept("near_symmetries", _never) == NearSymmetries()


def test_the_key_follows_the_file_the_parameters_and_the_defaults(tmp_path, monkeypatch):
    store = _store(tmp_path)
    keys = {store.key(what) for what in KINDS}
    assert len(keys) == 3
    other_file = DerivedStore(store.directory, "cd" * 32, _PARAMS, "m")
    other_params = DerivedStore(store.directory, "ab" * 32, {**_PARAMS, "sharp_angle_deg": 30}, "m")
    assert other_file.key("resolution") != store.key("resolution")
    assert other_params.key("resolution") != store.key("resolution")
    before = store.key("near_symmetries")
    store.kept("near_symmetries", _near)
    monkeypatch.setattr(defaults, "NEAR_SYMMETRY_FRACTION", defaults.NEAR_SYMMETRY_FRACTION * 2)
    assert store.key("near_symmetries") != before
    # computed again under the other defaults, not read
    assert store.kept("near_symmetries", NearSymmetries) == NearSymmetries()


def test_a_corrupt_entry_is_computed_again_and_rewritten(tmp_path):
    store = _store(tmp_path)
    store.kept("vertex_scatter", lambda: 0.5)
    path = ArrayCache(store.directory).path_for(store.key("vertex_scatter"), "m.vertex_scatter")
    path.write_bytes(path.read_bytes()[:-40])
    with pytest.warns(CacheWarning):
        assert store.kept("vertex_scatter", lambda: 0.5) == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert store.kept("vertex_scatter", _never) == 0.5


def test_an_entry_that_does_not_decode_is_computed_again(tmp_path):
    store = _store(tmp_path)
    key = store.key("near_symmetries")
    bad = {"half_turns": np.zeros((1, 3, 3)), "axes": np.zeros((0, 2, 3))}
    ArrayCache(store.directory).save(key, bad, label="m.near_symmetries")
    with pytest.warns(CacheWarning, match="does not decode"):
        _same_near(store.kept("near_symmetries", _near), _near())
    _same_near(store.kept("near_symmetries", _never), _near())


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root ignores modes")
def test_a_read_only_cache_is_not_warned_about(tmp_path):
    store = _store(tmp_path)
    store.directory.mkdir()
    store.directory.chmod(0o555)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert store.kept("vertex_scatter", lambda: 0.25) == 0.25
    finally:
        store.directory.chmod(0o755)
    assert not list(store.directory.iterdir())


def test_bad_arguments_raise(tmp_path):
    store = _store(tmp_path)
    with pytest.raises(ValueError, match="what must be one of"):
        store.key("curvature")
    with pytest.raises(ValueError, match="what must be one of"):
        store.kept("curvature", lambda: 0.0)


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "models"
    d.mkdir()
    bumped = trimesh.creation.capsule(height=1.0, radius=0.4, count=[24, 24])
    v = bumped.vertices.copy()
    v[:, 0] += 0.01 * np.exp(-((v[:, 1] - 0.4) ** 2 + v[:, 2] ** 2) / 0.02)
    trimesh.Trimesh(v, bumped.faces).export(d / "pill.stl")
    e = trimesh.creation.icosphere(subdivisions=3)
    e.apply_scale([1.5, 1.0, 0.7])
    e.export(d / "egg.stl")
    return d


def _values(model):
    return model.resolution, model.vertex_scatter, model.near_symmetries


def _no_compute(monkeypatch):
    for name in ("mesh_resolution", "vertex_scatter", "near_symmetries"):
        monkeypatch.setattr(index_module, name, lambda *a, **k: _never())


def _same_values(a, b):
    np.testing.assert_equal(dataclasses.astuple(a[0]), dataclasses.astuple(b[0]))
    assert a[1] == b[1]
    _same_near(a[2], b[2])


def test_an_index_keeps_its_values_for_the_next_process(folder, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    first = ModelIndex.from_file(folder / "pill.stl", cache_dir=cache)
    computed = _values(first)
    entries = sorted(p.name.split("-")[0] for p in cache.glob("pill.*.npz"))
    assert entries == ["pill.near_symmetries", "pill.resolution", "pill.vertex_scatter"]
    _no_compute(monkeypatch)
    again = ModelIndex.from_file(folder / "pill.stl", cache_dir=cache)  # a new index
    _same_values(_values(again), computed)
    # another file has entries of its own
    other = ModelIndex.from_file(folder / "egg.stl", cache_dir=cache)
    with pytest.raises(AssertionError, match="computed again"):
        _ = other.resolution


def test_a_library_pack_gives_its_models_their_entries(folder, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    built = ModelLibrary.from_folder(folder, cache_dir=cache)
    computed = {m.name: _values(m) for m in built}
    _no_compute(monkeypatch)
    packed = ModelLibrary.from_folder(folder, cache_dir=cache)
    assert (cache / "packs").is_dir()
    assert all(m.from_cache for m in packed)
    for m in packed:
        _same_values(_values(m), computed[m.name])


def test_from_record_checks_its_store(folder, tmp_path):
    model = ModelIndex.from_file(folder / "egg.stl", cache_dir=tmp_path / "cache")
    with pytest.raises(TypeError, match="derived"):
        ModelIndex.from_record(model.path, model.params, model.to_record(), derived="here")
    plain = ModelIndex.from_record(model.path, model.params, model.to_record())
    np.testing.assert_equal(
        dataclasses.astuple(plain.resolution), dataclasses.astuple(model.resolution)
    )
