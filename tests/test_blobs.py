"""Tests for meshrec.bench.blobs: the scale benchmark's generated library."""

import numpy as np
import pytest

from meshrec import defaults
from meshrec.bench import blob_set, make_blob, write_blobs


def test_blobs_are_closed_smooth_star_shaped_and_distinct():
    blobs = blob_set(6, seed=3)
    assert [b.name for b in blobs] == [f"blob_3_{i:04d}" for i in range(6)]
    for b in blobs:
        m = b.mesh
        assert len(m.faces) == 20 * 4**defaults.BLOB_SUBDIVISIONS
        assert m.is_watertight
        assert m.is_winding_consistent
        assert m.volume > 0  # outward normals
        # star-shaped about the origin: every face faces away from it
        centres = m.triangles_center
        assert np.all(np.einsum("ij,ij->i", m.face_normals, centres) > 0)
        # smooth: adjacent faces turn by a few degrees at most
        assert np.degrees(m.face_adjacency_angles.max()) < 25.0
        lo, hi = defaults.BLOB_AMPLITUDE
        assert lo <= b.params["amplitude"] <= hi
    # distinct shapes: their volumes and principal inertias differ
    vols = [b.mesh.volume for b in blobs]
    assert len({round(v, 6) for v in vols}) == len(blobs)


def test_blob_set_is_deterministic_and_prefix_stable():
    a = blob_set(3, seed=1)
    b = blob_set(5, seed=1)
    for x, y in zip(a, b[:3], strict=True):
        assert x.name == y.name
        np.testing.assert_array_equal(x.mesh.vertices, y.mesh.vertices)
    c = blob_set(3, seed=2)
    assert not np.allclose(a[0].mesh.vertices, c[0].mesh.vertices)


def test_write_blobs_writes_once(tmp_path):
    paths = write_blobs(2, tmp_path / "lib")
    assert [p.name for p in paths] == ["blob_0_0000.stl", "blob_0_0001.stl"]
    stamp = paths[0].stat().st_mtime_ns
    more = write_blobs(3, tmp_path / "lib")
    assert more[:2] == paths
    assert more[0].stat().st_mtime_ns == stamp
    assert not list((tmp_path / "lib").glob(".*"))  # no temporary file left


@pytest.mark.parametrize("n", [0, -1, 1.5, True, "3"])
def test_blob_set_refuses_a_bad_n(n):
    with pytest.raises(ValueError, match="n must be a positive integer"):
        blob_set(n)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        write_blobs(n, "unused")


@pytest.mark.parametrize("seed", [-1, 0.5, None])
def test_blob_set_refuses_a_bad_seed(seed):
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        blob_set(1, seed=seed)
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        write_blobs(1, "unused", seed=seed)


def test_make_blob_refuses_a_bad_name():
    with pytest.raises(ValueError, match="name must be a non-empty string"):
        make_blob(0, name="")
