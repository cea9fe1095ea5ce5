"""The registration's stages: their composition is register(), they are order-free, and
the new results (rms, n_points, poses, phi, trace) mean what they say.

Known answers: the RMS and mean distances recomputed from the reported transform; a pose
turned by a known angle about its normal changes phi by that angle; a brute-force count
of the widened (K, H) lookup; the composition of the public stages run by hand.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import meshrec
from meshrec import defaults
from meshrec.recognition.cascade import pruned_registration
from meshrec.registration.brackets import phi_brackets, refine_phis
from meshrec.registration.candidates import find_candidates
from meshrec.registration.lookup import lookup_candidates
from meshrec.registration.objective import residuals
from meshrec.registration.poses import (
    PoseHypothesis,
    RefinedSearch,
    distinct_poses,
    pose_hypotheses,
    refine_searches,
)
from meshrec.registration.refine import Refinement
from meshrec.registration.register import register, register_coarse, touch_geometry
from meshrec.registration.sampling import even_subsample
from meshrec.registration.screening import screen_candidates
from meshrec.registration.searching import search_candidates
from meshrec.registration.transform import apply_transform, superposition


@pytest.fixture(scope="module")
def touch(surfaces):
    return meshrec.simulate_touch(surfaces["ellipsoid"], rng=3).touch


@pytest.fixture(scope="module")
def traced(surfaces, touch):
    return register(touch, surfaces["ellipsoid"], trace=True)


# ------------------------------------------------------------------ composition
def test_the_stages_run_by_hand_give_registers_result(surfaces, touch, traced):
    model = surfaces["ellipsoid"]
    g = touch_geometry(touch)
    cands = lookup_candidates(touch, model, g)
    brackets = phi_brackets(model, cands)
    screening = screen_candidates(model, cands, brackets)
    chosen = screening.candidates[: defaults.LOCAL_SEARCHES]
    phis = refine_phis(model, cands, brackets, chosen)
    runs = search_candidates(model, cands, [(i, p.phi) for i, p in zip(chosen, phis, strict=True)])
    refined = refine_searches(model, cands, runs)
    poses = distinct_poses(pose_hypotheses(model, cands, runs, refined), g.half_length)
    assert np.array_equal(poses[0].T_model_touch, traced.T_model_touch)
    assert poses[0].error == traced.error
    assert np.array_equal(cands.model_points, traced.candidate_points)
    assert len(runs.runs) == traced.searches == len(traced.search_paths)


def test_the_trace_changes_nothing_and_holds_every_stage(surfaces, touch, traced):
    plain = register(touch, surfaces["ellipsoid"])
    assert plain.trace is None
    assert plain.error == traced.error
    assert plain.rms == traced.rms
    assert np.array_equal(plain.T_model_touch, traced.T_model_touch)
    t = traced.trace
    assert len(t.candidates) == traced.candidates
    assert t.brackets.errors.shape == (traced.candidates, defaults.PHI_STEPS)
    assert len(t.phis) == min(defaults.LOCAL_SEARCHES, len(t.screening.candidates))
    assert len(t.searches.runs) == traced.searches
    assert len(t.hypotheses) == len(t.refinements) >= len(traced.poses)
    # the brackets are the local minima of each candidate's samples
    row = t.brackets.errors[0]
    for i in t.brackets.minima[0]:
        assert row[i] <= row[i - 1]
        assert row[i] <= row[(i + 1) % len(row)]


def test_a_rejected_registration_traces_its_empty_lookup(surfaces, touch):
    # a window of (almost) zero width matches no vertex
    reg = register(touch, surfaces["crossed_trough"], trace=True, lookup_scale=1e-300)
    assert reg.rejected
    assert reg.rms is None
    assert reg.n_points == 0
    assert reg.poses == ()
    assert len(reg.trace.candidates) == 0
    assert reg.trace.brackets is None


# ------------------------------------------------------------------ order-free
def test_recognition_does_not_depend_on_the_order_of_the_models(surfaces):
    touch = meshrec.simulate_touch(surfaces["crossed_trough"], rng=0).touch
    models = list(surfaces)
    a = meshrec.recognize(touch, models)
    b = meshrec.recognize(touch, models[::-1])
    assert [r.model for r in a.ranking] == [r.model for r in b.ranking]
    for ra, rb in zip(a.ranking, b.ranking, strict=True):
        assert ra.error == rb.error
    # and each entry is the model registered alone (its first stages only, refined, when
    # the cascade pruned it: meshrec.recognition.cascade); the model about to be named may
    # have more poses from the looks before naming (meshrec.recognition.naming), which
    # only add poses: its fit is at least as good
    for k, r in enumerate(a.ranking):
        model = surfaces[r.model]
        if r.pruned:
            coarse = register_coarse(touch, model, geometry=a.geometry)
            alone = pruned_registration(touch, model, coarse)
        else:
            alone = register(touch, model, geometry=a.geometry)
        if k == 0 and a.verdict == "recognised":
            assert r.error <= alone.error
        else:
            assert alone.error == r.error


# ------------------------------------------------------------------ rms, n_points, poses
def test_rms_and_error_are_the_distances_at_the_reported_pose(surfaces, touch, traced):
    model = surfaces["ellipsoid"]
    r = residuals(model, apply_transform(traced.T_model_touch, touch.points)).values
    assert traced.n_points == len(touch.points) == len(r)
    assert traced.rms == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-12)
    assert traced.error == pytest.approx(np.mean(np.abs(r)), rel=1e-12)
    assert traced.rms >= traced.error  # RMS >= mean of |r| (Cauchy-Schwarz)


def test_poses_are_distinct_best_first_and_the_first_is_reported(traced):
    poses = traced.poses
    assert len(poses) >= 1
    assert np.array_equal(poses[0].T_model_touch, traced.T_model_touch)
    assert poses[0].rms == traced.rms
    assert poses[0].error == traced.error
    assert np.array_equal(poses[0].contact, traced.contact)
    assert [p.rms for p in poses] == sorted(p.rms for p in poses)
    tol = defaults.POSE_DUPLICATE_FRACTION * touch_geometry_half_length(traced)
    for i, a in enumerate(poses):
        for b in poses[:i]:
            far = np.linalg.norm(a.contact - b.contact) > tol
            R = a.T_model_touch[:3, :3].T @ b.T_model_touch[:3, :3]
            turned = Rotation.from_matrix(R).magnitude() > np.deg2rad(
                defaults.POSE_DUPLICATE_ANGLE_DEG
            )
            assert far or turned


def touch_geometry_half_length(reg) -> float:
    return float(reg.trace.candidates.geometry.half_length)


def _pose(T, contact, rms=1.0):
    return PoseHypothesis(
        T_model_touch=T,
        error=rms,
        rms=rms,
        contact=np.asarray(contact, float),
        normal=np.array([0.0, 0.0, 1.0]),
        phi=0.0,
        run=0,
    )


def _turn(deg):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", deg, degrees=True).as_matrix()
    return T


def test_distinct_poses_drops_only_the_same_minimum():
    base = _pose(np.eye(4), [0, 0, 0], rms=1.0)
    twin = _pose(_turn(0.5), [0.01, 0, 0], rms=2.0)  # within 0.05 * 1 and 1 degree
    turned = _pose(_turn(2.0), [0.0, 0, 0], rms=3.0)  # same contact, turned 2 degrees
    moved = _pose(np.eye(4), [0.2, 0, 0], rms=4.0)  # same rotation, contact 0.2 away
    kept = distinct_poses([base, twin, turned, moved], half_length=1.0)
    assert kept == (base, turned, moved)
    assert distinct_poses([base, twin], half_length=0.1) == (base, twin)  # tol 0.005


def test_phi_is_the_rotation_of_the_reported_pose_about_the_normal(surfaces, traced):
    model = surfaces["ellipsoid"]
    t = traced.trace
    best = traced.poses[0]
    refined = next(r for r in t.refinements if r.run == best.run)
    # Turning the pose by a known angle about the normal at the contact turns phi by it.
    a = 0.3
    D = np.eye(4)
    D[:3, :3] = Rotation.from_rotvec(a * best.normal).as_matrix()
    D[:3, 3] = best.contact - D[:3, :3] @ best.contact
    ref = refined.refinement
    turned = RefinedSearch(
        run=refined.run,
        refinement=Refinement(D @ ref.T_model_touch, ref.error, ref.rms, ref.iterations),
    )
    (h,) = pose_hypotheses(model, t.candidates, t.searches, [turned])
    assert np.allclose(h.contact, best.contact, atol=1e-6)
    assert (h.phi - best.phi - a + np.pi) % (2 * np.pi) - np.pi == pytest.approx(0, abs=1e-9)
    # An unrefined search's pose has the search's own phi.
    run = t.searches.runs[best.run]
    cands = t.candidates
    side = cands.sides[cands.side[run.candidate]]
    T = superposition(side.point, side.frame, run.result.surface, run.result.phi)
    same = RefinedSearch(run=best.run, refinement=Refinement(T, 0.0, 0.0, 0))
    (u,) = pose_hypotheses(model, cands, t.searches, [same])
    gap = (u.phi - run.result.phi + np.pi) % (2 * np.pi) - np.pi
    assert abs(gap) < 1e-6


def test_refine_pose_reports_one_pose_with_its_rms(surfaces, touch, traced):
    reg = meshrec.refine_pose(touch, surfaces["ellipsoid"], traced.T_model_touch)
    assert reg.n_points == len(touch.points)
    assert len(reg.poses) == 1
    assert reg.poses[0].rms == reg.rms
    assert reg.poses[0].phi is None
    assert reg.rms <= traced.rms * (1 + 1e-9)


# ------------------------------------------------------------------ lookup_scale
def test_lookup_scale_widens_the_window_by_its_factor(surfaces, touch):
    model = surfaces["ellipsoid"]
    g = touch_geometry(touch)
    base = find_candidates(model, g.k1, g.k2, g.half_length, g.fit_rms)
    wide = find_candidates(model, g.k1, g.k2, g.half_length, g.fit_rms, lookup_scale=3.0)
    assert wide.tol_K == pytest.approx(3.0 * base.tol_K, rel=1e-15)
    assert wide.tol_H == pytest.approx(3.0 * base.tol_H, rel=1e-15)
    K, H = g.k1 * g.k2, 0.5 * (g.k1 + g.k2)
    t = model.curvature
    brute = np.sum(
        t.valid
        & (t.K_range[:, 0] - wide.tol_K <= K)
        & (t.K_range[:, 1] + wide.tol_K >= K)
        & (t.H_range[:, 0] - wide.tol_H <= H)
        & (t.H_range[:, 1] + wide.tol_H >= H)
    )
    assert wide.raw_hits == brute >= base.raw_hits
    reg = register(touch, model, lookup_scale=3.0)
    assert reg.raw_hits >= register(touch, model).raw_hits


# ------------------------------------------------------------------ even_subsample
@pytest.mark.parametrize(("n", "k"), [(0, 5), (5, 5), (4, 9), (183, 36), (61, 64), (100, 3)])
def test_even_subsample_spreads_k_of_n(n, k):
    idx = even_subsample(n, k)
    assert len(idx) == min(n, k)
    assert np.all(np.diff(idx) > 0)
    if n:
        assert idx[0] == 0
        assert idx[-1] == n - 1
    if n > k > 1:  # gaps within one of the even spacing
        assert np.diff(idx).max() - np.diff(idx).min() <= 1


# ------------------------------------------------------------------ every raise
def test_stage_inputs_are_checked(surfaces, touch, traced):
    model = surfaces["ellipsoid"]
    t = traced.trace
    cands, brackets = t.candidates, t.brackets
    fewer = lookup_candidates(touch, model, t.candidates.geometry, max_candidates=1)
    cases = [
        (lambda: even_subsample(-1, 3), "n must be >= 0, got -1"),
        (lambda: even_subsample(3, 0), "k must be >= 1, got 0"),
        (
            lambda: lookup_candidates(touch, model, cands.geometry, max_candidates=0),
            "max_candidates must be a positive integer, got 0",
        ),
        (
            lambda: find_candidates(model, 1.0, 1.0, 1.0, 0.0, lookup_scale=0.0),
            "lookup_scale must be a positive finite number, got 0.0",
        ),
        (lambda: register(touch, model, lookup_scale=np.inf), "lookup_scale must be"),
        (lambda: register(touch, model, searches=0), "searches must be >= 1, got 0"),
        (lambda: register(touch, model, method="x"), "method must be one of"),
        (lambda: phi_brackets(model, cands, steps=2), "steps must be an integer >= 3, got 2"),
        (lambda: phi_brackets(model, cands, distances="x"), "distances must be one of"),
        (lambda: refine_phis(model, fewer, brackets, [0]), "brackets must be of these"),
        (lambda: refine_phis(model, cands, brackets, [len(cands)]), "indices must be in 0.."),
        (lambda: screen_candidates(model, fewer, brackets), "brackets must be of these"),
        (
            lambda: screen_candidates(model, cands, brackets, limit=0),
            "limit must be a positive integer, got 0",
        ),
        (
            lambda: screen_candidates(model, cands, brackets, iterations=1.5),
            "iterations must be a positive integer, got 1.5",
        ),
        (lambda: search_candidates(model, cands, [(0, 0.0)], method="x"), "method must be"),
        (
            lambda: search_candidates(model, cands, [(-1, 0.0)]),
            r"starts\[0\] must name a candidate in 0..",
        ),
        (lambda: refine_searches(model, cands, t.searches, best=0), "best must be a positive"),
        (lambda: distinct_poses(traced.poses, 0.0), "half_length must be positive, got 0.0"),
        (
            lambda: distinct_poses(traced.poses, 1.0, angle_deg=-1.0),
            "distance_fraction and angle_deg must be >= 0",
        ),
    ]
    for call, match in cases:
        with pytest.raises(ValueError, match=match):
            call()
    with pytest.raises(TypeError, match="lookup_scale must be a real number, got bool"):
        register(touch, model, lookup_scale=True)


def test_phi_brackets_refuses_no_candidates(surfaces, touch, traced):
    g = traced.trace.candidates.geometry
    trough = surfaces["crossed_trough"]
    cands = lookup_candidates(touch, trough, g, lookup_scale=1e-300)
    assert len(cands) == 0
    with pytest.raises(ValueError, match="candidates must hold at least one candidate"):
        phi_brackets(trough, cands)
