"""The scoring functions against hand-computed answers (meshrec.recognition.scoring)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from meshrec import defaults
from meshrec.recognition import scoring


def test_noise_estimate_takes_the_smaller_estimate_with_the_floor():
    h = 0.15
    floor = defaults.SCORE_NOISE_FLOOR_FRACTION * h
    assert scoring.noise_estimate(0.002, 0.001, h) == pytest.approx(math.hypot(0.001, floor))
    assert scoring.noise_estimate(0.001, 0.003, h) == pytest.approx(math.hypot(0.001, floor))
    # noiseless data: the floor alone
    assert scoring.noise_estimate(0.0, 0.0, h) == pytest.approx(floor)


@pytest.mark.parametrize(
    ("args", "name"),
    [((-1.0, 0.1, 1.0), "fit_rms"), ((0.1, np.nan, 1.0), "noise_rms"), ((0.1, 0.1, 0.0), "half")],
)
def test_noise_estimate_refuses_bad_numbers(args, name):
    with pytest.raises(ValueError, match=name):
        scoring.noise_estimate(*args)


def test_log_likelihood_is_the_gaussian_one_with_the_effective_points():
    n, sigma = 100, 0.01
    ll = scoring.log_likelihoods([0.01, 0.02, None], n, sigma, ess_fraction=0.5)
    # -n_eff rms^2 / (2 sigma^2) with n_eff = 50
    np.testing.assert_allclose(ll[:2], [-25.0, -100.0])
    assert ll[2] == -np.inf


def test_log_likelihood_checks_its_input():
    with pytest.raises(ValueError, match="noise"):
        scoring.log_likelihoods([0.1], 10, 0.0)
    with pytest.raises(ValueError, match="rms"):
        scoring.log_likelihoods([-0.1], 10, 1.0)
    with pytest.raises(ValueError, match="n_points"):
        scoring.log_likelihoods([0.1], 0, 1.0)
    with pytest.raises(ValueError, match="ess_fraction"):
        scoring.log_likelihoods([0.1], 10, 1.0, ess_fraction=1.5)


def test_equal_residuals_give_equal_probabilities():
    ll = scoring.log_likelihoods([0.001, 0.001, 0.001], 183, 0.001)
    np.testing.assert_allclose(scoring.posterior(ll), [1 / 3] * 3)


def test_posterior_matches_a_hand_computed_ratio():
    # two models whose log-likelihoods differ by log(3): probabilities 3/4 and 1/4
    p = scoring.posterior([0.0, -math.log(3.0), -np.inf])
    np.testing.assert_allclose(p, [0.75, 0.25, 0.0])
    # a prior multiplies in
    p = scoring.posterior([0.0, 0.0], prior=[1.0, 3.0])
    np.testing.assert_allclose(p, [0.25, 0.75])


def test_posterior_of_nothing_is_all_zero():
    np.testing.assert_array_equal(scoring.posterior([-np.inf, -np.inf]), [0.0, 0.0])


@pytest.mark.parametrize(
    ("ll", "prior", "match"),
    [
        ([[0.0]], None, "1-D"),
        ([np.nan], None, "NaN"),
        ([0.0, 0.0], [1.0], "prior must have shape"),
        ([0.0, 0.0], [-1.0, 1.0], "non-negative"),
    ],
)
def test_posterior_refuses_bad_input(ll, prior, match):
    with pytest.raises(ValueError, match=match):
        scoring.posterior(ll, prior=prior)


def test_fit_p_value_is_the_chi_square_tail():
    n, sigma, rms = 200, 0.001, 0.0012
    n_eff = defaults.SCORE_ESS_FRACTION * n
    expected = stats.chi2(n_eff - 6).sf(n_eff * (rms / sigma) ** 2)
    assert scoring.fit_p_value(rms, n, sigma) == pytest.approx(expected)
    # a fit at the noise level is unremarkable, one at ten times the noise impossible
    assert scoring.fit_p_value(sigma, n, sigma) > 0.1
    assert scoring.fit_p_value(10 * sigma, n, sigma) < 1e-12


def test_fit_p_value_refuses_bad_input():
    with pytest.raises(ValueError, match="rms"):
        scoring.fit_p_value(-1.0, 100, 1.0)
    with pytest.raises(ValueError, match="dof"):
        scoring.fit_p_value(1.0, 10, 1.0, dof=100)


def test_plausible_set_is_the_fewest_models_reaching_the_coverage():
    names = ["a", "b", "c", "d"]
    assert scoring.plausible_set(names, [0.1, 0.6, 0.25, 0.05], coverage=0.8) == ("b", "c")
    assert scoring.plausible_set(names, [0.0, 0.97, 0.02, 0.01], coverage=0.95) == ("b",)
    assert scoring.plausible_set(names, [0.0, 0.0, 0.0, 0.0]) == ()
    # ties at the edge: exactly the coverage is enough
    assert scoring.plausible_set(names, [0.5, 0.5, 0.0, 0.0], coverage=0.5) == ("a",)


def test_plausible_set_refuses_bad_input():
    with pytest.raises(ValueError, match="shape"):
        scoring.plausible_set(["a"], [0.5, 0.5])
    with pytest.raises(ValueError, match="coverage"):
        scoring.plausible_set(["a"], [1.0], coverage=0.0)
    with pytest.raises(ValueError, match="non-negative"):
        scoring.plausible_set(["a", "b"], [1.5, -0.5])


def test_decide_recognised_ambiguous_unknown():
    n, sigma = 183, 0.001
    v = scoring.decide(["a", "b"], [0.99, 0.01], 0.001, n, sigma)
    assert (v.verdict, v.plausible) == ("recognised", ("a",))
    assert v.fit_ratio == pytest.approx(1.0)
    v = scoring.decide(["a", "b", "c"], [0.5, 0.45, 0.05], 0.001, n, sigma)
    assert (v.verdict, v.plausible) == ("ambiguous", ("a", "b"))
    assert "a, b" in v.reason
    # ten times the noise: unknown, whatever the probabilities say
    v = scoring.decide(["a", "b"], [1.0, 0.0], 0.01, n, sigma)
    assert (v.verdict, v.plausible) == ("unknown", ())
    assert "not in the library" in v.reason
    # no model registered at all
    v = scoring.decide(["a"], [0.0], None, n, sigma)
    assert (v.verdict, v.plausible) == ("unknown", ())
    assert math.isinf(v.fit_ratio)


def test_decide_refuses_a_bad_noise():
    with pytest.raises(ValueError, match="noise"):
        scoring.decide(["a"], [1.0], 0.1, 10, -1.0)


def test_pose_weights():
    np.testing.assert_allclose(scoring.pose_weights([0.001, 0.001], 100, 0.001), [0.5, 0.5])
    w = scoring.pose_weights([0.001, 0.002], 100, 0.001)
    n_eff = defaults.SCORE_ESS_FRACTION * 100
    ratio = math.exp(-0.5 * n_eff * (1.0 - 4.0))  # w0 / w1
    np.testing.assert_allclose(w, [ratio / (1 + ratio), 1 / (1 + ratio)])
    with pytest.raises(ValueError, match="non-empty"):
        scoring.pose_weights([], 100, 0.001)
    with pytest.raises(ValueError, match="finite"):
        scoring.pose_weights([np.inf], 100, 0.001)


def test_results_have_readable_reprs():
    pose = scoring.WeightedPose(np.eye(4), 0.001, 1.0)
    s = scoring.ModelScore("mug", 0.9, 0.001, 100, -50.0, (pose,))
    assert "mug" in repr(s)
    assert "0.900" in repr(s)
    assert "weight=1.000" in repr(pose)
