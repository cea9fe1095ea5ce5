"""The benchmark's shape generator (meshrec.bench.shapes)."""

from __future__ import annotations

import numpy as np
import pytest

from meshrec import bench


def test_every_family_is_a_clean_unit_size_surface():
    for i, family in enumerate(bench.SHAPE_FAMILIES):
        s = bench.make_shape(family, rng=i)
        m = s.mesh
        assert 2_000 <= len(m.faces) <= 25_000, (family, len(m.faces))
        assert 0.5 < float(np.max(m.extents)) < 3.0, (family, m.extents)
        if family in ("paraboloid", "saddle"):
            assert not m.is_watertight
        else:
            assert m.is_watertight, family
            assert m.volume > 0, family


def test_capsule_volume_is_the_analytic_one():
    s = bench.make_shape("capsule", rng=3)
    r, h = s.params["radius"], s.params["height"]
    expected = np.pi * r**2 * (h + 4.0 / 3.0 * r)
    assert s.mesh.volume == pytest.approx(expected, rel=5e-3)


def test_tipped_rod_volume_is_the_analytic_one_and_only_the_tip_varies():
    a = bench.make_shape("tipped_rod", rng=1)
    b = bench.make_shape("tipped_rod", rng=2)
    r, side = a.params["radius"], a.params["side"]
    for s in (a, b):
        c = s.params["tip"] * r
        # cylinder + hemisphere + half an ellipsoid of revolution (semi-axes r, r, c)
        expected = np.pi * r**2 * side + 2.0 / 3.0 * np.pi * r**3 + 2.0 / 3.0 * np.pi * r**2 * c
        assert s.mesh.is_watertight
        assert s.mesh.volume == pytest.approx(expected, rel=5e-3)
    assert (b.params["radius"], b.params["side"]) == (r, side)
    assert a.params["tip"] != b.params["tip"]
    assert "tipped_rod" in bench.EXTRA_FAMILIES
    assert "tipped_rod" not in bench.SHAPE_FAMILIES
    assert {s.family for s in bench.shape_set(3, seed=0, families=["tipped_rod"])} == {
        "tipped_rod"
    }


def test_ellipsoid_axes_are_the_drawn_ones():
    s = bench.make_shape("ellipsoid", rng=5)
    axes = sorted(2.0 * np.array([s.params["a"], s.params["b"], s.params["c"]]))
    # the oriented bounding box of a rotated ellipsoid has its axes as half-extents
    obb = sorted(s.mesh.bounding_box_oriented.primitive.extents)
    np.testing.assert_allclose(obb, axes, rtol=2e-2)


def test_shape_set_is_deterministic_and_distinct():
    a = bench.shape_set(9, seed=4)
    b = bench.shape_set(9, seed=4)
    c = bench.shape_set(9, seed=5)
    assert [s.name for s in a] == [s.name for s in b]
    assert len({s.name for s in a}) == 9
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.mesh.vertices, y.mesh.vertices)
    assert not np.array_equal(a[0].mesh.vertices, c[0].mesh.vertices)
    assert [s.family for s in a[:7]] == list(bench.SHAPE_FAMILIES)
    assert "faces=" in repr(a[0])


def test_write_shapes(tmp_path):
    shapes = bench.shape_set(2, seed=1, families=["ellipsoid"])
    paths = bench.write_shapes(shapes, tmp_path / "lib")
    assert [p.name for p in paths] == ["ellipsoid_1_0.stl", "ellipsoid_1_1.stl"]
    assert all(p.stat().st_size > 0 for p in paths)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: bench.make_shape("cube"), "family"),
        (lambda: bench.shape_set(0), "n must be"),
        (lambda: bench.shape_set(2, families=[]), "families"),
        (lambda: bench.shape_set(2, families=["cube"]), "families"),
    ],
)
def test_bad_arguments_are_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call()
