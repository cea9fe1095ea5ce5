"""Local height-fields: fits checked on analytic surfaces (a cubic graph it holds exactly,
a sphere to its sixth-order term), the batched products against one-at-a-time twins."""

import numpy as np
import pytest

from meshrec.model.heightfield import (
    fit_heightfields,
    heightfield_distances,
    heightfield_gaps,
    monomial_exponents,
    monomials,
)


def _disk(rng, n, r):
    a = rng.uniform(0, 2 * np.pi, n)
    s = r * np.sqrt(rng.uniform(0, 1, n))
    return np.column_stack([s * np.cos(a), s * np.sin(a)])


def _graph_samples(f, grad, xy):
    z = f(xy[:, 0], xy[:, 1])
    gx, gy = grad(xy[:, 0], xy[:, 1])
    n = np.column_stack([-gx, -gy, np.ones_like(gx)])
    return np.column_stack([xy, z]), n / np.linalg.norm(n, axis=1, keepdims=True)


def test_exponents_by_total_degree():
    assert monomial_exponents(2).tolist() == [[0, 0], [1, 0], [0, 1], [2, 0], [1, 1], [0, 2]]
    assert len(monomial_exponents(4)) == 15


def test_monomial_derivatives_match_central_differences():
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1, 1, (20, 2))
    h = 1e-6
    for d in (0, 1):
        step = np.zeros(2)
        step[d] = h
        fd = (monomials(xy + step, 4) - monomials(xy - step, 4)) / (2 * h)
        np.testing.assert_allclose(monomials(xy, 4, d), fd, atol=1e-8)


def test_a_cubic_graph_is_fitted_exactly_and_translated_frames_agree():
    rng = np.random.default_rng(1)

    def f(x, y):
        return 0.3 * x * x - 0.2 * x * y + 0.5 * y**3 + 0.1 * x**3

    def grad(x, y):
        return 0.6 * x - 0.2 * y + 0.3 * x * x, -0.2 * x + 1.5 * y * y

    pts, nrm = _graph_samples(f, grad, _disk(rng, 40, 0.5))
    center = np.array([[2.0, -1.0, 0.5]])  # the same graph, moved
    coef = fit_heightfields(center, np.eye(3)[None], (pts + center)[None], nrm[None], 0.5)
    data = np.column_stack([_disk(rng, 30, 0.5), np.zeros(30)])
    data[:, 2] = f(data[:, 0], data[:, 1]) + 0.01
    gaps = heightfield_gaps(coef, data, 0.5)
    np.testing.assert_allclose(gaps[:, 0], 0.01, atol=1e-6)  # the ridge: 1e-8 of the trace


def test_a_sphere_is_held_to_its_sixth_order_term():
    # Unit sphere seen from its north pole, outward normals: z = sqrt(1 - r^2) - 1 below
    # the tangent plane, frame (x, y, n = +z); the degree-4 fit misses r^6 / 16 at most.
    rng = np.random.default_rng(2)
    xy = _disk(rng, 60, 0.35)
    z = np.sqrt(1 - (xy**2).sum(axis=1)) - 1.0
    pts = np.column_stack([xy, z])
    nrm = pts + np.array([0, 0, 1.0])
    coef = fit_heightfields(np.zeros((1, 3)), np.eye(3)[None], pts[None], nrm[None], 0.35)
    test_xy = _disk(rng, 200, 0.3)
    above = np.column_stack([test_xy, np.sqrt(1 - (test_xy**2).sum(axis=1)) - 1 + 0.002])
    gaps = heightfield_gaps(coef, above, 0.35)[:, 0]
    assert np.max(np.abs(gaps - 0.002)) < 0.3**6 / 16 * 2
    # The distance (slope-corrected) against the exact distance to the sphere.
    exact = np.linalg.norm(above - np.array([0, 0, -1.0]), axis=1) - 1.0
    d = heightfield_distances(coef, above, 0.35)[:, 0]
    np.testing.assert_allclose(d, exact, atol=1e-4)


def test_batched_gaps_match_one_field_at_a_time():
    rng = np.random.default_rng(3)
    coef = rng.normal(size=(7, 15)) * 0.1
    pts = rng.uniform(-0.4, 0.4, (25, 3))
    out = heightfield_gaps(coef, pts, 0.4)
    dist = heightfield_distances(coef, pts, 0.4, slopes=False)
    for c in range(7):
        for p in range(25):
            x, y, z = pts[p] / 0.4
            g = sum(coef[c, k] * x**i * y**j for k, (i, j) in enumerate(monomial_exponents(4)))
            assert out[p, c] == pytest.approx(0.4 * (z - g), abs=1e-12)
            assert dist[p, c] == pytest.approx(abs(0.4 * (z - g)), abs=1e-12)


@pytest.mark.parametrize("slopes", [False, True])
def test_distances_in_blocks_are_each_points_own(slopes):
    # More points than one block: every row as when the point is evaluated alone.
    rng = np.random.default_rng(4)
    coef = rng.normal(size=(5, 15)) * 0.1
    pts = rng.uniform(-0.4, 0.4, (700, 3))
    whole = heightfield_distances(coef, pts, 0.4, slopes=slopes)
    alone = np.vstack([heightfield_distances(coef, p[None], 0.4, slopes=slopes) for p in pts])
    assert np.allclose(whole, alone, rtol=1e-12, atol=1e-15)
    if slopes:
        gx = monomials(pts[:, :2] / 0.4, 4, 0) @ coef.T
        gy = monomials(pts[:, :2] / 0.4, 4, 1) @ coef.T
        gaps = np.abs(heightfield_gaps(coef, pts, 0.4))
        assert np.allclose(whole, gaps / np.sqrt(1 + gx * gx + gy * gy), rtol=1e-12)


def test_samples_facing_away_are_left_out():
    # Samples of the plane z = 0 plus samples of a far plane facing the other way (the
    # other side of a thin part): the fit is the plane z = 0.
    rng = np.random.default_rng(5)
    xy = _disk(rng, 40, 0.5)
    near = np.column_stack([xy, np.zeros(40)])
    far = np.column_stack([xy, np.full(40, -0.05)])
    pts = np.concatenate([near, far])[None]
    nrm = np.concatenate([np.tile([0, 0, 1.0], (40, 1)), np.tile([0, 0, -1.0], (40, 1))])[None]
    coef = fit_heightfields(np.zeros((1, 3)), np.eye(3)[None], pts, nrm, 0.5)
    np.testing.assert_allclose(heightfield_gaps(coef, near, 0.5), 0.0, atol=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"centers": np.zeros((2, 2))}, "centers"),
        ({"frames": np.zeros((1, 3, 3))}, "frames"),
        ({"points": np.zeros((2, 4, 2))}, "points"),
        ({"normals": np.zeros((2, 3, 3))}, "normals"),
        ({"radius": 0.0}, "radius"),
        ({"slope_weight": -1.0}, "slope_weight"),
        ({"ridge": -1.0}, "ridge"),
    ],
)
def test_fit_rejects_bad_arguments(kwargs, match):
    args = {
        "centers": np.zeros((2, 3)),
        "frames": np.tile(np.eye(3), (2, 1, 1)),
        "points": np.zeros((2, 4, 3)),
        "normals": np.tile([0, 0, 1.0], (2, 4, 1)),
        "radius": 1.0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fit_heightfields(**args)


def test_evaluation_and_monomials_reject_bad_arguments():
    with pytest.raises(ValueError, match="degree"):
        monomial_exponents(0)
    with pytest.raises(ValueError, match="xy"):
        monomials(np.zeros((3, 3)), 2)
    with pytest.raises(ValueError, match="derivative"):
        monomials(np.zeros((3, 2)), 2, derivative=2)
    for fn in (heightfield_gaps, heightfield_distances):
        with pytest.raises(ValueError, match="coefficients"):
            fn(np.zeros((2, 6)), np.zeros((3, 3)), 1.0)
        with pytest.raises(ValueError, match="local_points"):
            fn(np.zeros((2, 15)), np.zeros((3, 2)), 1.0)
        with pytest.raises(ValueError, match="radius"):
            fn(np.zeros((2, 15)), np.zeros((3, 3)), -1.0)
