"""The thinned nearest sites against a brute-force twin (a sort of every kept site)."""

import numpy as np
import pytest
from analytic_meshes import index_of, sphere

from meshrec import defaults
from meshrec.model.neighbours import site_neighbours, site_ranks


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return index_of(sphere(1.0, 5), tmp_path_factory.mktemp("ball"), "ball")


def _kept(table, level):
    n = len(table.points)
    if level == 0:
        return np.arange(n)
    rank = np.random.default_rng([defaults.SCREEN_SEED, n]).random(n)
    return np.flatnonzero(rank < 2.0**-level)


@pytest.mark.parametrize("radius", [0.05, 0.2, 0.6])
def test_neighbours_are_the_nearest_kept_sites(ball, radius):
    table = ball.curvature
    rng = np.random.default_rng(3)
    v = rng.normal(size=(12, 3))
    points = v / np.linalg.norm(v, axis=1, keepdims=True)
    k = 24
    nb = site_neighbours(table, points, radius, k)
    kept = _kept(table, nb.level)
    sites = np.asarray(table.points)[kept]
    for p, idx, dist in zip(points, nb.indices, nb.distances, strict=True):
        d = np.linalg.norm(sites - p, axis=1)
        want = np.sort(d)[:k]
        assert np.allclose(dist, want, rtol=0, atol=1e-12)
        assert np.allclose(np.linalg.norm(np.asarray(table.points)[idx] - p, axis=1), dist)
        assert set(idx.tolist()) <= set(kept.tolist())
    # Thinned to about FIELD_FILL * k per disc of the radius (within the level's factor
    # of 2 either way), unless the whole table is needed.
    inside = (nb.distances <= radius).sum(axis=1)
    if nb.level > 0:
        assert 0.25 * k <= np.median(inside) <= k
    else:
        assert radius <= 0.2  # the small discs need every site


def test_more_neighbours_than_sites_gives_all_of_them(ball):
    table = ball.curvature
    n = len(table.points)
    nb = site_neighbours(table, np.array([[0.0, 0.0, 1.0]]), 10.0, n + 5)
    assert nb.indices.shape == (1, n)
    assert nb.level == 0
    assert sorted(nb.indices[0].tolist()) == list(range(n))


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"table": "nope"}, TypeError, "table must be a CurvatureTable, got str"),
        (
            {"points": np.zeros((2, 2))},
            ValueError,
            r"points must be \(c, 3\) with c >= 1, got shape \(2, 2\)",
        ),
        (
            {"points": np.zeros((0, 3))},
            ValueError,
            r"points must be \(c, 3\) with c >= 1, got shape \(0, 3\)",
        ),
        ({"points": np.full((1, 3), np.nan)}, ValueError, "points must be finite"),
        ({"radius": 0.0}, ValueError, "radius must be > 0, got 0.0"),
        ({"radius": "a"}, TypeError, "radius must be a real number"),
        ({"k": 0}, ValueError, "k must be >= 1, got 0"),
        ({"k": 2.5}, TypeError, "k must be an integer"),
    ],
)
def test_bad_arguments_raise(ball, kwargs, error, message):
    args = {"table": ball.curvature, "points": np.array([[0.0, 0.0, 1.0]]), "radius": 0.1, "k": 4}
    args.update(kwargs)
    with pytest.raises(error, match=message):
        site_neighbours(**args)


def test_site_ranks_are_seeded_by_the_count_alone():
    a, b = site_ranks(500), site_ranks(500)
    assert np.array_equal(a, b)
    assert np.array_equal(a, np.random.default_rng([defaults.SCREEN_SEED, 500]).random(500))
    assert not np.array_equal(site_ranks(501)[:500], a)
    assert site_ranks(0).shape == (0,)
    with pytest.raises(ValueError, match="n must be >= 0, got -1"):
        site_ranks(-1)
    with pytest.raises(TypeError, match="n must be an integer"):
        site_ranks(2.5)
