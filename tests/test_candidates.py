"""Tests for meshrec.registration.candidates and ModelIndex.lookup: the candidate contacts.

On a sphere of radius r every curvature site has K = 1/r^2 and H = 1/r (outward normals),
on a cylinder's side K = 0 and H = 1/(2r): a lookup with those values must find every such
site, and one with other values none. The lookup itself is compared with a brute-force
scan of the table, the spreading with brute-force distances, and the tolerance window with
touches simulated on surfaces of known curvature.
"""

import types

import numpy as np
import pytest
from analytic_meshes import index_of, sphere, tube
from hypothesis import given, settings
from hypothesis import strategies as st

from meshrec import defaults, estimate_local_geometry, simulate_touch
from meshrec.registration.candidates import (
    CandidateSet,
    curvature_tolerance,
    find_candidates,
    spread_points,
)

RADIUS = 2.0
#: Curve half-length and fit residual of a typical touch on these sizes (the tolerance
#: window they give is about 0.07 on H, several times libigl's error on these meshes).
HALF_LENGTH, FIT_RMS = 0.5, 1e-3


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("candidates")
    return types.SimpleNamespace(
        ball=index_of(sphere(RADIUS, subdivisions=5), folder, "ball"),
        can=index_of(tube(RADIUS, height=8.0, sections=256, rings=128), folder, "can"),
    )


def _brute(model, K, H, tol_K, tol_H):
    """Every valid site whose (K, H) range meets the box: a scan of all of them."""
    t = model.curvature
    keep = [
        v
        for v in range(len(t.points))
        if t.valid[v]
        and t.K_range[v, 0] - tol_K <= K <= t.K_range[v, 1] + tol_K
        and t.H_range[v, 0] - tol_H <= H <= t.H_range[v, 1] + tol_H
    ]
    return np.array(keep, dtype=np.int64)


def _check_spread(model, cand, spacing, limit):
    chosen = model.curvature.points[cand.sites]
    assert len(cand.sites) <= limit
    assert len(np.unique(cand.sites)) == len(cand.sites)
    d = np.linalg.norm(chosen[:, None] - chosen[None], axis=2) + np.eye(len(chosen)) * 1e9
    assert d.min() >= spacing


# ----------------------------------------------------------------------------- sphere
def test_sphere_every_valid_site_matches(meshes):
    model = meshes.ball
    k = 1.0 / RADIUS
    cand = find_candidates(model, k, k, HALF_LENGTH, FIT_RMS)
    assert isinstance(cand, CandidateSet)
    assert model.curvature.valid.all()  # a clean closed mesh: all valid
    assert cand.raw_hits == len(model.curvature.points)
    # 64 candidates at least a quarter of the half-length apart (the sphere has room).
    assert len(cand.sites) == defaults.MAX_CANDIDATES
    _check_spread(model, cand, defaults.CANDIDATE_SPACING_FRACTION * HALF_LENGTH, 64)
    # The window is the one curvature_tolerance gives for these inputs.
    assert (cand.tol_K, cand.tol_H) == curvature_tolerance(k, k, HALF_LENGTH, FIT_RMS)


@pytest.mark.parametrize(
    ("k1", "k2"),
    [(1.5, 1.5), (-0.5, -0.5), (0.5, 0.0), (0.5, -0.5)],
    ids=["tighter sphere", "inside out", "cylinder", "saddle"],
)
def test_sphere_other_curvatures_match_nothing(meshes, k1, k2):
    cand = find_candidates(meshes.ball, k1, k2, HALF_LENGTH, FIT_RMS)
    assert cand.raw_hits == 0
    assert cand.sites.shape == (0,)
    assert cand.sites.dtype == np.int64


def test_max_candidates_and_the_first_candidate(meshes):
    model = meshes.ball
    k = 1.0 / RADIUS
    cand = find_candidates(model, k, k, HALF_LENGTH, FIT_RMS, max_candidates=5)
    assert len(cand.sites) == 5
    # The first is the hit closest to (K, H) in units of the tolerances: brute force.
    K, H = k * k, k
    mismatch = (
        np.abs(model.curvature.K - K) / cand.tol_K + np.abs(model.curvature.H - H) / cand.tol_H
    )
    assert cand.sites[0] == np.argmin(mismatch)
    assert len(find_candidates(model, k, k, HALF_LENGTH, FIT_RMS, max_candidates=0).sites) == 0


# ----------------------------------------------------------------------------- cylinder
def test_cylinder_side_matches_k_zero_h_half_over_r(meshes):
    model = meshes.can
    cand = find_candidates(model, 1.0 / RADIUS, 0.0, HALF_LENGTH, FIT_RMS)
    hits = _brute(model, 0.0, 0.5 / RADIUS, cand.tol_K, cand.tol_H)
    assert cand.raw_hits == len(hits)
    assert np.isin(cand.sites, hits).all()
    # Every side site away from the open ends (where the curvature fit is cut) matches.
    z = model.curvature.points[:, 2]
    middle = np.flatnonzero(np.abs(z) < 2.0)
    assert np.isin(middle, hits).all()
    _check_spread(model, cand, defaults.CANDIDATE_SPACING_FRACTION * HALF_LENGTH, 64)
    # A sphere's (K, H) of the same radius matches nothing on the side.
    k = 1.0 / RADIUS
    assert find_candidates(model, k, k, HALF_LENGTH, FIT_RMS).raw_hits == 0


# ----------------------------------------------------------------------------- lookup
@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    site=st.integers(min_value=0, max_value=10**6),
    dK=st.floats(-0.2, 0.2),
    dH=st.floats(-0.2, 0.2),
    tol_K=st.one_of(st.floats(0.0, 0.3), st.just(np.inf)),
    tol_H=st.one_of(st.floats(0.0, 0.3), st.just(np.inf)),
)
def test_lookup_matches_a_brute_force_scan(meshes, site, dK, dH, tol_K, tol_H):
    # Boxes around the cylinder's table entries (whose K and H spread near the open ends).
    model = meshes.can
    v = site % len(model.curvature.points)
    K, H = float(model.curvature.K[v]) + dK, float(model.curvature.H[v]) + dH
    got = model.curvature.lookup(K, H, tol_K, tol_H)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, _brute(model, K, H, tol_K, tol_H))


# ----------------------------------------------------------------------------- spreading
def test_spread_points_matches_brute_force_spacing():
    rng = np.random.default_rng(5)
    pts = rng.uniform(size=(500, 3))
    idx = spread_points(pts, spacing=0.3, limit=1000)
    chosen = pts[idx]
    d = np.linalg.norm(chosen[:, None] - chosen[None], axis=2) + np.eye(len(idx)) * 9
    assert d.min() >= 0.3
    # Every point is within the spacing of a chosen one (farthest-point coverage).
    cover = np.linalg.norm(pts[:, None] - chosen[None], axis=2).min(axis=1)
    assert cover.max() < 0.3
    assert idx[0] == 0
    assert spread_points(pts, 0.3, 1000, first=7)[0] == 7
    assert len(spread_points(pts, 0.0, 7)) == 7
    assert len(spread_points(pts[:0], 0.1, 7)) == 0
    assert len(spread_points(pts, 0.1, 0)) == 0


def test_spread_points_takes_the_farthest_point_next():
    pts = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0], [2.0, 0, 0]])
    assert spread_points(pts, 0.5, 10).tolist() == [0, 2, 3, 1]
    assert spread_points(pts, 2.5, 10).tolist() == [0, 2]


# ----------------------------------------------------------------------------- tolerance
@pytest.mark.parametrize("seed", range(5))
def test_the_window_holds_the_true_curvature_of_a_touch(seed):
    # Touches on a sphere (K = 1/r^2, H = 1/r) and on a cylinder's side (K = 0,
    # H = 1/(2r)), simulated with the default noise: the truth lies inside the window
    # around the estimate, and the other shape's values do not.
    r = 1.0
    meshes = {"ball": sphere(r, subdivisions=5), "can": tube(r, 6.0, sections=256, rings=96)}
    truth = {"ball": (1.0 / r**2, 1.0 / r), "can": (0.0, 0.5 / r)}
    for name, mesh in meshes.items():
        contact = None if name == "ball" else [r, 0.0, 0.0]
        sim = simulate_touch(mesh, rng=seed, contact=contact, transform=False)
        g = estimate_local_geometry(sim.touch.curves)
        if g.H < 0:  # the curves cannot tell the sides apart: take the outward one
            k1, k2 = -g.k2, -g.k1
        else:
            k1, k2 = g.k1, g.k2
        tol_K, tol_H = curvature_tolerance(k1, k2, g.half_length, g.fit_rms)
        K, H = k1 * k2, 0.5 * (k1 + k2)
        K_true, H_true = truth[name]
        assert abs(K - K_true) <= tol_K
        assert abs(H - H_true) <= tol_H
        K_other, H_other = truth["can" if name == "ball" else "ball"]
        assert abs(K - K_other) > tol_K or abs(H - H_other) > tol_H


def test_the_window_bounds_k_and_h_for_curvatures_off_by_tau():
    # The window is derived for principal curvatures each within tau of the estimate:
    # tol_H = tau, and tol_K the worst |K' - K| over that square (brute force on a grid).
    for k1, k2, half_length, fit_rms in [(2.0, 1.0, 0.5, 1e-3), (1.0, -3.0, 0.3, 0.0)]:
        tol_K, tol_H = curvature_tolerance(k1, k2, half_length, fit_rms)
        tau = tol_H
        e = np.linspace(-tau, tau, 201)
        e1, e2 = np.meshgrid(e, e)
        dK = np.abs((k1 + e1) * (k2 + e2) - k1 * k2)
        dH = np.abs(0.5 * (e1 + e2))
        assert dH.max() == pytest.approx(tol_H)
        assert dK.max() <= tol_K * (1 + 1e-12)
        assert dK.max() >= 0.99 * tol_K  # and it is the worst case, not a loose bound


def test_the_window_widens_with_noise_and_shrinks_with_length():
    base = curvature_tolerance(1.0, 0.5, 0.5, 1e-3)
    noisier = curvature_tolerance(1.0, 0.5, 0.5, 4e-3)
    longer = curvature_tolerance(1.0, 0.5, 1.0, 1e-3)
    assert np.all(np.array(noisier) > base)
    assert np.all(np.array(longer) < base)
    # With no noise the window is relative: it scales with the curvature.
    a = curvature_tolerance(1.0, 0.5, 0.5, 0.0)
    b = curvature_tolerance(2.0, 1.0, 0.5, 0.0)
    assert b[1] == pytest.approx(2 * a[1])


def test_curvature_tolerance_errors():
    with pytest.raises(ValueError, match=r"half_length must be positive, got 0\.0"):
        curvature_tolerance(1.0, 1.0, 0.0, 0.001)
    with pytest.raises(ValueError, match=r"half_length must be finite, got nan"):
        curvature_tolerance(1.0, 1.0, float("nan"), 0.001)
    with pytest.raises(ValueError, match=r"fit_rms must be non-negative, got -1\.0"):
        curvature_tolerance(1.0, 1.0, 0.3, -1.0)
