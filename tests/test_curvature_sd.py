"""The curvature estimate's own standard error (LocalGeometry.curvature_sd) and the (K, H)
lookup window it widens (meshrec.registration.candidates.curvature_tolerance)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import meshrec
from meshrec import defaults
from meshrec.contact.geometry import estimate_local_geometry
from meshrec.registration.candidates import curvature_tolerance

DATA = Path(__file__).parent / "data"


def _sphere_curves(rng, noise: float, one_sided: bool = False, n: int = 41, half: float = 0.3):
    """Three great-circle arcs of the unit sphere through p = (0, 0, 1), 60 degrees apart,
    with uniform noise; ``one_sided``: the second arc only on one side of p."""
    curves = []
    for k, angle in enumerate(np.radians([0.0, 60.0, 120.0])):
        d = np.array([np.cos(angle), np.sin(angle), 0.0])
        s = np.linspace(0.0 if (one_sided and k == 1) else -half, half, n)
        arc = np.sin(s)[:, None] * d + np.cos(s)[:, None] * np.array([0.0, 0.0, 1.0])
        curves.append(arc + rng.uniform(-noise, noise, arc.shape))
    return curves


def _estimate(curves):
    return estimate_local_geometry(curves, point=np.array([0.0, 0.0, 1.0]))


def test_a_curve_cut_short_on_one_side_of_p_makes_the_estimate_less_precise():
    rng = np.random.default_rng(3)
    centred = _estimate(_sphere_curves(rng, 1e-3))
    cut = _estimate(_sphere_curves(rng, 1e-3, one_sided=True))
    assert centred.curvature_sd > 0.0
    assert cut.curvature_sd > 2.0 * centred.curvature_sd


@pytest.mark.parametrize("one_sided", [False, True])
def test_the_standard_error_matches_the_scatter_of_the_estimates(one_sided):
    # A Monte-Carlo twin: the principal curvatures of the unit sphere (1, 1) estimated
    # from 150 noise draws scatter by about the standard error given (it bounds the
    # shape operator's error, so each curvature's scatter is at most about it).
    rng = np.random.default_rng(11)
    found = [_estimate(_sphere_curves(rng, 2e-3, one_sided)) for _ in range(150)]
    sd = np.mean([g.curvature_sd for g in found])
    scatter = np.std([[g.k1, g.k2] for g in found], axis=0).max()
    assert 0.3 * sd < scatter < 1.3 * sd
    assert np.mean([g.H for g in found]) == pytest.approx(1.0, abs=2 * sd)


def test_the_lookup_window_is_at_least_the_estimates_error():
    tol_K, tol_H = curvature_tolerance(1.0, 1.0, 0.3, 1e-4)
    wide_K, wide_H = curvature_tolerance(1.0, 1.0, 0.3, 1e-4, curvature_sd=0.5)
    assert wide_H == pytest.approx(defaults.CANDIDATE_SD_FACTOR * 0.5)
    assert wide_H > tol_H
    assert wide_K > tol_K
    # an error below the calibrated window leaves it as it was
    assert curvature_tolerance(1.0, 1.0, 0.3, 1e-4, curvature_sd=1e-6) == (tol_K, tol_H)


def test_a_negative_standard_error_is_refused():
    with pytest.raises(ValueError, match="curvature_sd"):
        curvature_tolerance(1.0, 1.0, 0.3, 1e-4, curvature_sd=-0.1)


def test_a_touch_with_a_curve_cut_short_is_not_named_as_another_surface(surfaces):
    # A black-box probe (stop 34): one touch of the bundled ellipsoid whose curves have
    # 121, 45 and 17 points, the third ending at p, read K -0.68 on the convex ellipsoid
    # (an error 5 times the calibrated window): the lookup left the ellipsoid out and the
    # elliptic paraboloid was `recognised` at p 1.000. Its standard error now widens the
    # window to hold the ellipsoid's contact.
    touch = meshrec.TouchData.from_file(DATA / "ellipsoid_trimmed_curve.csv")
    T_true = np.array(
        [
            [0.215612004709, -0.282973129771, -0.934578873747, 0.963775692149],
            [-0.296596478606, -0.93085082612, 0.213418060132, -1.404292260016],
            [-0.930345093126, 0.231177307147, -0.284631446535, -0.760248882661],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touch, surfaces)
        truth = meshrec.refine_pose(touch, surfaces["ellipsoid"], T_true)
    assert rec.geometry.K < 0.0  # the estimate is still wrong ...
    assert rec.best.model == "ellipsoid"  # ... but the right model is found
    assert rec.verdict != "recognised" or rec.plausible == ("ellipsoid",)
    assert rec.best.rms <= truth.rms * 1.01
