"""Joint fits most promising model first: against every model registered on every touch."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from seeded_touches import touches_at, world_pose

from meshrec import defaults
from meshrec.recognition import joint
from meshrec.recognition.bestfirst import fit_best_first
from meshrec.recognition.scoring import fit_p_value, log_likelihoods, noise_estimate
from meshrec.registration.objective import residuals
from meshrec.registration.register import register, touch_geometry
from meshrec.registration.transform import apply_transform


@pytest.fixture(scope="module")
def library(ellipsoid_capsule_torus):
    """The shared ellipsoid, capsule and torus library (``conftest.py``)."""
    return ellipsoid_capsule_torus


@pytest.fixture(scope="module")
def on_torus(library):
    """Three seeded touches of the torus at a random pose, their geometries and noise, and
    every model's first touch registered alone."""
    rng = np.random.default_rng(11)
    touches, _ = touches_at(library["torus"], world_pose(rng), rng)
    geometries = [touch_geometry(t) for t in touches]
    noises = [noise_estimate(g.fit_rms, g.noise_rms, g.half_length) for g in geometries]
    noise = joint.pooled_noise(noises, [t.n_points for t in touches])
    models = [library[name] for name in library.names]
    firsts = {
        m.name: joint.first_touch_fit(
            touches, m, register(touches[0], m, geometry=geometries[0], trace=True)
        )
        for m in models
    }
    return touches, geometries, noise, models, firsts


def test_best_first_keeps_every_model_that_could_compete(on_torus):
    """Brute-force twin: every model registered on every touch. A model the best-first
    search stopped early either fits to the noise or is far below its leader, and even
    registered on everything it would not come within the prune ratio of it."""
    touches, geometries, noise, models, firsts = on_torus
    n = sum(t.n_points for t in touches)
    fits = fit_best_first(touches, models, geometries, firsts, noise)
    assert list(fits) == [m.name for m in models]
    ll = {k: float(log_likelihoods([f.registration.rms], n, noise)[0]) for k, f in fits.items()}
    leader = max(ll.values())
    assert max(ll, key=ll.get) == "torus"
    assert fit_p_value(fits["torus"].registration.rms, n, noise) >= defaults.WIDEN_P_VALUE
    stopped = 0
    for m in models:
        fit = fits[m.name]
        full = joint.register_touches(
            touches, m, geometries, upto=len(touches), previous=firsts[m.name], noise=noise
        )
        full_ll = float(log_likelihoods([full.registration.rms], n, noise)[0])
        if fit.registered < len(touches) and m.name != "torus":
            stopped += 1
            assert joint.log_likelihood_bound(fit, touches, noise) < (
                leader + defaults.JOINT_PRUNE_LOG_RATIO
            )
            assert full_ll < leader + defaults.JOINT_PRUNE_LOG_RATIO
        # the leader found first is the one the exhaustive search finds
        assert full_ll <= leader + 1e-6 or m.name == "torus"
    assert stopped >= 1  # the premise: some model was pruned before all its touches


def test_the_order_of_the_models_changes_nothing(on_torus):
    touches, geometries, noise, models, firsts = on_torus
    a = fit_best_first(touches, models, geometries, firsts, noise)
    b = fit_best_first(touches, models[::-1], geometries, firsts, noise)
    assert {k: f.registration.rms for k, f in a.items()} == {
        k: f.registration.rms for k, f in b.items()
    }
    assert {k: f.registered for k, f in a.items()} == {k: f.registered for k, f in b.items()}


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ("geometries", "geometries must hold one LocalGeometry per touch"),
        ("firsts", "firsts must hold every model's first fit, missing"),
        ("noise", "noise must be positive and finite, got"),
    ],
)
def test_bad_input_raises(on_torus, change, match):
    touches, geometries, noise, models, firsts = on_torus
    args = {"geometries": geometries, "firsts": firsts, "noise": noise}
    args[change] = {"geometries": geometries[:2], "firsts": {}, "noise": 0.0}[change]
    with pytest.raises(ValueError, match=match):
        fit_best_first(touches, models, args["geometries"], args["firsts"], args["noise"])


def test_a_hopeless_model_keeps_its_coarse_poses_an_upper_bound(on_torus):
    """With a tiny ``hopeless_rms`` the fine stage is skipped: the poses are each scored
    where the coarse stage left them, no better than the refined ones; with a huge one,
    the fine stage runs as without it."""
    touches, geometries, _noise, models, firsts = on_torus
    model = next(m for m in models if m.name == "torus")
    seeds = [p.T_model_touch for p in firsts["torus"].registration.poses]
    assert seeds
    refined = joint.joint_poses(model, touches, seeds, geometries[0])
    same = joint.joint_poses(model, touches, seeds, geometries[0], hopeless_rms=1e3)
    coarse = joint.joint_poses(model, touches, seeds, geometries[0], hopeless_rms=1e-9)
    assert [p.rms for p in same] == [p.rms for p in refined]
    assert coarse[0].rms >= refined[0].rms
    assert coarse[0].rms != refined[0].rms  # the premise: refining did change the fit
    points = np.vstack([t.points for t in touches])
    for pose in coarse:  # each RMS is that of its own pose on all the points
        y = points @ pose.T_model_touch[:3, :3].T + pose.T_model_touch[:3, 3]
        d = model.surface.closest_points(y)[0]
        assert pose.rms == pytest.approx(np.sqrt(np.mean(d**2)), rel=0.25)


def test_joint_poses_refuses_a_hopeless_rms_that_is_not_positive(on_torus):
    touches, geometries, _noise, models, firsts = on_torus
    seeds = [p.T_model_touch for p in firsts["torus"].registration.poses]
    with pytest.raises(ValueError, match=r"hopeless_rms must be positive, got 0\.0"):
        joint.joint_poses(models[0], touches, seeds, geometries[0], hopeless_rms=0.0)


def test_rms_out_of_reach_is_where_the_log_likelihood_falls_by_the_prune_ratio():
    noise, n = 0.0012, 549
    leader = float(log_likelihoods([0.0013], n, noise)[0])
    rms = joint.rms_out_of_reach(leader, n, noise)
    ll = float(log_likelihoods([rms], n, noise)[0])
    assert ll == pytest.approx(leader + defaults.JOINT_PRUNE_LOG_RATIO)
    assert rms > 0.0013
    assert joint.rms_out_of_reach(float("-inf"), n, noise) == float("inf")


@pytest.mark.parametrize("leader", [0.5, float("nan")])
def test_rms_out_of_reach_refuses_a_leader_that_is_no_log_likelihood(leader):
    with pytest.raises(ValueError, match="leader must be a log-likelihood"):
        joint.rms_out_of_reach(leader, 100, 0.001)


def test_the_bound_with_a_floor_is_tighter_and_still_above_the_registered_touches(on_torus):
    """Brute-force twin: every touch registered alone on every model. The bound after the
    first touch, with the unregistered touches at their floor, is below the bound that
    takes them as perfect, and above the bound with every touch registered."""
    touches, geometries, noise, models, firsts = on_torus
    for m in models:
        first = firsts[m.name]
        if first.registration.rejected:
            continue
        loose = joint.log_likelihood_bound(first, touches, noise)
        tight = joint.log_likelihood_bound(first, touches, noise, geometries)
        full = joint.register_touches(touches, m, geometries, upto=3, previous=first)
        registered = joint.log_likelihood_bound(full, touches, noise, geometries)
        assert registered <= tight < loose
        assert joint.log_likelihood_bound(full, touches, noise) == registered


def test_the_bound_refuses_geometries_that_do_not_match(on_torus):
    touches, geometries, noise, _models, firsts = on_torus
    with pytest.raises(ValueError, match=r"geometries must hold one LocalGeometry per touch \(3\)"):
        joint.log_likelihood_bound(firsts["torus"], touches, noise, geometries[:1])


@pytest.mark.parametrize("best", [1, 3, 32])
def test_the_least_start_rms_are_those_of_every_seed_evaluated(on_torus, best):
    """Brute-force twin: the RMS of every seed on every coarse point, sorted. The bounded
    evaluation picks the same seeds in the same order with the same values."""
    from meshrec.recognition.joint import _least_start_rms, _rms_on

    touches, _geometries, _noise, models, firsts = on_torus
    model = next(m for m in models if m.name == "torus")
    rng = np.random.default_rng(5)
    base = [p.T_model_touch for p in firsts["torus"].registration.poses]
    seeds = []
    for _ in range(300):  # poses scattered about the first touch's, near and far
        T = base[int(rng.integers(len(base)))].copy()
        T[:3, :3] = Rotation.from_rotvec(rng.normal(0, 0.3, 3)).as_matrix() @ T[:3, :3]
        T[:3, 3] += rng.normal(0, 0.1, 3)
        seeds.append(T)
    points = np.vstack([t.points for t in touches])
    sub = points[:: max(1, len(points) // defaults.JOINT_COARSE_POINTS)]
    every = _rms_on(model, sub, seeds)
    order, rms, res = _least_start_rms(model, sub, seeds, best)
    assert order.tolist() == np.argsort(every, kind="stable")[:best].tolist()
    assert all(rms[i] == every[i] for i in order)
    assert len(rms) < len(seeds)  # the premise: not every seed was evaluated on all
    # the residuals kept for the refinement's start: each seed's own query's, to the bit
    assert set(res) == set(rms)
    for i in order:
        alone = residuals(model, apply_transform(seeds[i], sub))
        np.testing.assert_array_equal(res[i].values, alone.values)
        np.testing.assert_array_equal(res[i].closest, alone.closest)
        np.testing.assert_array_equal(res[i].gradient, alone.gradient)
