"""The recognition's cascade: first stages everywhere, the full search on the survivors.

Known answers: the full search run on every model (the brute-force twin) gives the same
verdicts, best models, best errors and plausible sets on seeded touches; the survivors'
rule worked by hand from the scores' log-likelihood; the stages split in two give
register()'s result.
"""

from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.bench.protocols import paper_touch
from meshrec.recognition.cascade import (
    cascade_register,
    cascade_survivors,
    pruned_registration,
)
from meshrec.recognition.jobs import run_stage, run_stages_here
from meshrec.recognition.scoring import effective_points, noise_estimate
from meshrec.registration.register import register, register_coarse, register_full

MODELS = Path(__file__).resolve().parents[1] / "models"


# ------------------------------------------------------------------ the rule
def test_survivors_follow_the_log_likelihood_rule_worked_by_hand():
    n, noise = 100, 0.01
    half_n = 0.5 * effective_points(n)
    leader = 0.01
    # The threshold error: best conceivable log-likelihood exactly log_ratio below the
    # leaders' worst.
    worst = half_n * (leader * defaults.CASCADE_LEADER_GAIN / noise) ** 2
    edge = (
        defaults.CASCADE_SCREEN_GAIN
        * noise
        * np.sqrt((worst - defaults.JOINT_PRUNE_LOG_RATIO) / half_n)
    )
    keep = cascade_survivors([leader, 0.99 * edge, 1.01 * edge, None], n, noise)
    assert keep.tolist() == [True, True, False, False]


def test_a_reached_rms_tightens_the_leaders_bound_worked_by_hand():
    n, noise = 100, 0.01
    half_n = 0.5 * effective_points(n)
    leader, reached = 0.01, 0.012  # the leader's rms below its screened error x the gain
    worst = half_n * (reached / noise) ** 2
    edge = (
        defaults.CASCADE_SCREEN_GAIN
        * noise
        * np.sqrt((worst - defaults.JOINT_PRUNE_LOG_RATIO) / half_n)
    )
    errors = [leader, 0.99 * edge, 1.01 * edge]
    keep = cascade_survivors(errors, n, noise, leader_rms=reached)
    assert keep.tolist() == [True, True, False]
    # without it, the bound from the screened error alone keeps the model beyond the edge
    assert cascade_survivors(errors, n, noise).tolist() == [True, True, True]
    # a reached rms above the screened bound changes nothing: the bound is the smaller one
    loose = cascade_survivors(errors, n, noise, leader_rms=1.0)
    assert loose.tolist() == [True, True, True]


def test_survivors_do_not_depend_on_the_order():
    rng = np.random.default_rng(4)
    errors = [*list(rng.uniform(0.001, 0.05, 12)), None, None]
    keep = cascade_survivors(errors, 61, 0.001)
    assert keep.any()
    assert not keep.all()
    perm = rng.permutation(len(errors))
    again = cascade_survivors([errors[i] for i in perm], 61, 0.001)
    assert again.tolist() == keep[perm].tolist()


def test_no_known_error_keeps_nothing():
    assert cascade_survivors([None, None], 10, 0.1).tolist() == [False, False]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(n_points=0), "n_points"),
        (dict(n_points=2.5), "n_points"),
        (dict(noise=0.0), "noise"),
        (dict(noise=float("nan")), "noise"),
        (dict(screen_gain=0.5), "screen_gain"),
        (dict(leader_gain=float("inf")), "leader_gain"),
        (dict(log_ratio=1.0), "log_ratio"),
        (dict(screened_errors=[0.1, -1.0]), "screened_errors"),
        (dict(screened_errors=[float("nan")]), "screened_errors"),
        (dict(leader_rms=-0.1), "leader_rms"),
        (dict(leader_rms=float("inf")), "leader_rms"),
    ],
)
def test_bad_survivor_inputs_are_refused(kwargs, match):
    args = dict(screened_errors=[0.1, 0.2], n_points=10, noise=0.1) | kwargs
    with pytest.raises(ValueError, match=match):
        cascade_survivors(**args)


# ------------------------------------------------------------------ the split stages
def test_coarse_then_full_is_register(surfaces):
    model = surfaces["ellipsoid"]
    touch = meshrec.simulate_touch(model, rng=3).touch
    whole = register(touch, model)
    split = register_full(model, register_coarse(touch, model))
    assert split.error == whole.error
    np.testing.assert_array_equal(split.T_model_touch, whole.T_model_touch)
    assert not split.pruned


def test_pruned_registration_is_the_best_screened_pose_refined(surfaces):
    model = surfaces["ellipsoid"]
    touch = meshrec.simulate_touch(model, rng=3).touch
    coarse = register_coarse(touch, model)
    pruned = pruned_registration(touch, model, coarse)
    full = register_full(model, coarse)
    assert pruned.pruned
    assert pruned.searches == 0
    assert len(pruned.poses) == 1
    # The distances at the reported pose are its error (recomputed independently).
    y = touch.points @ pruned.T_model_touch[:3, :3].T + pruned.T_model_touch[:3, 3]
    d = model.surface.closest_points(y)[0]
    assert abs(d.mean() - pruned.error) < 0.1 * pruned.error
    # The full search, from the same screening, fits as well up to the optimisers'
    # tolerance (here both reach the noise floor, on twin contacts of the ellipsoid).
    assert full.rms <= pruned.rms * (1 + 1e-3)


def test_split_stages_refuse_another_models_coarse(surfaces):
    touch = meshrec.simulate_touch(surfaces["ellipsoid"], rng=3).touch
    coarse = register_coarse(touch, surfaces["ellipsoid"])
    with pytest.raises(ValueError, match="coarse must be of model"):
        register_full(surfaces["monkey_saddle"], coarse)
    with pytest.raises(ValueError, match="coarse must be of model"):
        pruned_registration(touch, surfaces["monkey_saddle"], coarse)


def test_pruned_registration_refuses_a_rejected_model(surfaces):
    # a touch on a small, tightly curved sphere: no site of the ellipsoid has (K, H) in
    # reach (the site table's (K, H) ranges keep sites in a vanishing window)
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.02)
    touch = meshrec.simulate_touch(ball, length=0.02, noise=1e-5, rng=3).touch
    model = surfaces["ellipsoid"]
    coarse = register_coarse(touch, model)
    if not coarse.rejected:
        pytest.fail("a touch curved 50 times more than the model should find no candidate")
    with pytest.raises(ValueError, match="coarse must have candidates"):
        pruned_registration(touch, model, coarse)


def test_recognize_refuses_a_non_bool_cascade(surfaces):
    touch = meshrec.simulate_touch(surfaces["ellipsoid"], rng=3).touch
    with pytest.raises(TypeError, match="cascade"):
        meshrec.recognize(touch, surfaces, cascade="yes")


# ------------------------------------------------------------------ the brute-force twin
def _same_answer(touch, library):
    full = meshrec.recognize(touch, library, cascade=False)
    fast = meshrec.recognize(touch, library, cascade=True)
    assert fast.verdict == full.verdict
    assert fast.best.model == full.best.model
    assert fast.best.error == full.best.error
    assert tuple(fast.plausible) == tuple(full.plausible)
    assert not any(r.pruned for r in full.ranking)
    for a, b in zip(full.ranking, fast.ranking, strict=True):
        if not b.pruned:
            assert a.model == b.model
            assert a.error == b.error
    return fast


def test_the_cascade_gives_the_full_searchs_answers(surfaces):
    pruned = 0
    for name, seed in (("ellipsoid", 0), ("crossed_trough", 0)):
        fast = _same_answer(paper_touch(surfaces[name], seed).touch, surfaces)
        pruned += sum(r.pruned for r in fast.ranking)
    assert pruned >= 1  # the cascade did prune (it does on each of these)


def test_cascade_register_is_order_free(surfaces):
    touch = paper_touch(surfaces["ellipsoid"], 0).touch
    models = list(surfaces)
    a = cascade_register(touch, models)
    b = cascade_register(touch, models[::-1])[::-1]
    assert [(r.model, r.error, r.pruned) for r in a] == [(r.model, r.error, r.pruned) for r in b]


class _Spy:
    """A ModelWorkers stand-in that runs the batches here and records their jobs."""

    def __init__(self):
        self.batches = []

    def run_stages(self, jobs, touch, geometry, method, trace=False, progress=None):
        self.batches.append([(job.kind, job.model.name) for job in jobs])
        return run_stages_here(jobs, touch, geometry, method, trace, progress=progress)


def test_the_least_screened_model_is_searched_first_and_bounds_the_leaders(surfaces):
    touch = paper_touch(surfaces["ellipsoid"], 0).touch
    models = list(surfaces)  # 4 models: no library-wide screen
    spy = _Spy()
    regs = cascade_register(touch, models, run=spy)
    first, lead, last = spy.batches
    assert {kind for kind, _ in first} == {"coarse"}
    # the model of least screened error, computed independently
    geometry = meshrec.estimate_local_geometry(touch.curves)
    coarse = {m.name: register_coarse(touch, m, geometry) for m in models}
    errors = {k: c.screened_error for k, c in coarse.items() if not c.rejected}
    least = min(errors, key=lambda k: (errors[k], k))
    assert lead == [("full", least)]
    assert least not in [name for _, name in last]
    by_name = {r.model: r for r in regs}
    assert not by_name[least].pruned
    # the decision is cascade_survivors' with the rms that model reached
    noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
    names = [m.name for m in models]
    keep = cascade_survivors(
        [coarse[k].screened_error for k in names],
        int(touch.n_points),
        noise,
        leader_rms=by_name[least].rms,
    )
    for name, k in zip(names, keep, strict=True):
        if not coarse[name].rejected:
            assert by_name[name].pruned == (not k)


@pytest.mark.slow
@pytest.mark.parametrize("folder", ["surfaces", "objects"])
def test_the_cascade_gives_the_full_searchs_answers_on_many_touches(folder, request):
    library = request.getfixturevalue(folder)  # the session's (conftest.py)
    for name in library.names:
        for seed in (1, 2):  # seed 0: test_the_cascade_gives_the_full_searchs_answers
            _same_answer(paper_touch(library[name], seed).touch, library)


def test_the_cascade_on_the_first_of_several_touches_gives_the_full_searchs_answer(surfaces):
    model = surfaces["ellipsoid"]
    touches = [meshrec.simulate_touch(model, rng=s, transform=False).touch for s in (11, 12, 13)]
    full = meshrec.recognize(touches, surfaces, cascade=False)
    fast = meshrec.recognize(touches, surfaces, cascade=True)
    assert fast.verdict == full.verdict
    assert fast.best.model == full.best.model == "ellipsoid"
    assert tuple(fast.plausible) == tuple(full.plausible)
    assert fast.best.rms == pytest.approx(full.best.rms, rel=1e-3)
    np.testing.assert_allclose(fast.touch_rms, full.touch_rms, rtol=1e-3)


# ------------------------------------------------------------------ batches run anywhere
class _Shuffled:
    """Runs each batch of jobs here in a seeded random order: a twin of workers that
    finish in any order (the cascade must only see each batch's results, in its order)."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)
        self.kinds = []

    def run_stages(self, jobs, touch, geometry, method, trace=False, progress=None):
        jobs = list(jobs)
        out = [None] * len(jobs)
        for k, j in enumerate(self.rng.permutation(len(jobs))):
            out[j] = run_stage(jobs[j], touch, geometry, method, trace)
            if progress is not None:
                progress(k, jobs[j])
        self.kinds.append(sorted({job.kind for job in jobs}))
        return out


def test_the_cascades_batches_give_its_result_in_any_order(surfaces, monkeypatch):
    # the screen on the four surfaces, one leader: on these touches it prunes the
    # elliptic paraboloid (ellipsoid 0), the cascade the monkey saddle (crossed trough 0)
    monkeypatch.setattr(defaults, "SCREEN_MIN_MODELS", 2)
    monkeypatch.setattr(defaults, "SCREEN_LEADERS", 1)
    models = list(surfaces)
    seen = {"screen": 0, "cascade": 0, "rejected": 0}
    for name, seed in (("crossed_trough", 0), ("ellipsoid", 0)):
        touch = paper_touch(surfaces[name], seed).touch
        calls = []
        here = cascade_register(touch, models, progress=lambda *a, calls=calls: calls.append(a))
        run = _Shuffled(seed)
        there = cascade_register(touch, models, run=run)
        assert run.kinds[0] == ["leader"]
        assert [c[0] for c in calls] == list(range(len(calls)))
        # the first stages ran on every model but those the screen pruned
        screened = {r.model for r in here if r.pruned and len(r.candidate_points) == 1}
        assert {c[2] for c in calls} == {r.model for r in here} - screened
        for a, b in zip(here, there, strict=True):
            assert (a.model, a.error, a.rms, a.pruned, a.searches) == (
                b.model,
                b.error,
                b.rms,
                b.pruned,
                b.searches,
            )
            if a.T_model_touch is not None:
                np.testing.assert_array_equal(a.T_model_touch, b.T_model_touch)
            seen["rejected"] += a.rejected
            seen["screen"] += a.pruned and len(a.candidate_points) == 1
            seen["cascade"] += a.pruned and len(a.candidate_points) > 1
    assert all(v >= 1 for v in seen.values()), seen


def test_cascade_register_refuses_a_runner_without_run_stages(surfaces):
    touch = meshrec.simulate_touch(surfaces["ellipsoid"], rng=3).touch
    with pytest.raises(TypeError, match="run must be a ModelWorkers"):
        cascade_register(touch, list(surfaces), run=object())
