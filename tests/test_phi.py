"""Tests for meshrec.registration.phi: bracketing and refining the minima of E(phi)."""

import numpy as np
import pytest

from meshrec import defaults
from meshrec.registration.phi import bracket_minima, search_phi


def test_bracket_minima_finds_every_circular_minimum():
    phis = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    values = np.cos(3 * (phis - 0.1))  # three minima, one near the wrap-around
    idx = bracket_minima(values)
    assert len(idx) == 3
    expected = (0.1 + np.pi / 3 + 2 * np.pi / 3 * np.arange(3)) % (2 * np.pi)
    got = np.sort(phis[idx])
    step = 2 * np.pi / 36
    assert np.all(np.abs(got - np.sort(expected)) <= step)


def test_bracket_minima_plateau_and_constant():
    assert bracket_minima(np.array([1.0, 0.0, 0.0, 1.0, 2.0])).tolist() == [1]
    assert bracket_minima(np.ones(5)).tolist() == [0]


@pytest.mark.parametrize(
    ("values", "match"),
    [(np.ones(2), r"s >= 3, got \(2,\)"), (np.array([1, np.nan, 2.0]), "finite")],
)
def test_bracket_minima_errors(values, match):
    with pytest.raises(ValueError, match=match):
        bracket_minima(values)


def test_search_phi_refines_to_the_true_minimum():
    true = 4.0321
    calls = []

    def error(phis):
        calls.append(len(phis))
        return 1.2 - np.cos(phis - true) + 0.3 * (1 - np.cos(2 * (phis - true)))

    res = search_phi(error)
    assert abs(res.phi - true) < 5 * defaults.PHI_XTOL
    assert res.error == pytest.approx(0.2, abs=1e-5)
    np.testing.assert_allclose(res.grid, np.linspace(0, 2 * np.pi, defaults.PHI_STEPS, False))
    np.testing.assert_allclose(res.grid_errors, error(res.grid))
    assert calls[0] == defaults.PHI_STEPS
    # The other local minimum, at true + pi (error 2.2, curvature cos + 1.2 cos 2 = 0.2 > 0),
    # is more than PHI_REFINE_RATIO times the best: only the true one is refined.
    assert res.minima.shape == (1, 2)
    # With a wide ratio both are, best first, each row (phi, error(phi)).
    both = search_phi(error, refine_ratio=20.0)
    np.testing.assert_allclose(both.minima[:, 0], [true, true + np.pi - 2 * np.pi], atol=5e-3)
    np.testing.assert_allclose(both.minima[:, 1], [0.2, 2.2], atol=1e-5)
    np.testing.assert_allclose(both.minima[:, 1], error(both.minima[:, 0]))


def test_search_phi_keeps_all_competitive_minima_best_first():
    # Two minima of equal depth 180 degrees apart (a cylinder-like symmetry).
    res = search_phi(lambda p: 1.0 - np.cos(2 * (p - 0.5)), refine_ratio=1.5)
    assert res.minima.shape[0] == 2
    assert np.allclose(np.sort(res.minima[:, 0]), [0.5, 0.5 + np.pi], atol=5e-3)


def test_search_phi_wraps_into_range():
    res = search_phi(lambda p: 1.0 - np.cos(p + 0.01))  # minimum at -0.01 = 2 pi - 0.01
    assert 0.0 <= res.phi < 2 * np.pi
    assert abs(res.phi - (2 * np.pi - 0.01)) < 5e-3


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"steps": 2}, "steps must be an integer >= 3"), ({"refine_ratio": 0.5}, "refine_ratio")],
)
def test_search_phi_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        search_phi(np.cos, **kwargs)


def test_search_phi_uses_given_grid_errors():
    steps = 24
    grid = np.arange(steps) * 2 * np.pi / steps
    calls = []

    def error(phis):
        calls.append(len(phis))
        return 1.0 - np.cos(phis - 1.0)

    res = search_phi(error, steps=steps, grid_errors=error(grid))
    assert abs(res.phi - 1.0) < 5 * defaults.PHI_XTOL
    assert calls[0] == steps  # the grid call made above, then only refinement calls of 1
    assert all(c == 1 for c in calls[1:])
    with pytest.raises(ValueError, match=r"grid_errors must be \(24,\), got \(3,\)"):
        search_phi(error, steps=steps, grid_errors=np.ones(3))
