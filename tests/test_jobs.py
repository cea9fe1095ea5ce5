"""Tests for meshrec.recognition.jobs: the per-model stage jobs and their even split.

Known answers: the longest-first split worked by hand; a job's result is the stage
function's own, called directly.
"""

import numpy as np
import pytest

import meshrec
from meshrec.recognition.jobs import (
    STAGE_KINDS,
    StageJob,
    balanced_chunks,
    run_stage,
    run_stages_here,
)
from meshrec.recognition.screen import library_sites, screen_library
from meshrec.registration.register import register, register_coarse, touch_geometry


# ------------------------------------------------------------------ the split
def test_equal_costs_are_interleaved():
    assert balanced_chunks([1.0] * 7, 3) == [[0, 3, 6], [1, 4], [2, 5]]
    assert balanced_chunks([0.0] * 4, 2) == [[0, 2], [1, 3]]  # zero costs spread too


def test_the_longest_first_split_worked_by_hand():
    # most costly first: job 1 (5) -> A; job 3 (4) -> B; job 0 (3) -> B (4 < 5);
    # job 4 (3) -> A (5 < 7); job 2 (1) -> B (7 < 8). Loads 8 and 8: A first.
    chunks = balanced_chunks([3.0, 5.0, 1.0, 4.0, 3.0], 2)
    assert chunks == [[1, 4], [0, 2, 3]]
    loads = [sum([3.0, 5.0, 1.0, 4.0, 3.0][i] for i in c) for c in chunks]
    assert loads == [8.0, 8.0]


def test_the_split_covers_every_job_once_with_no_empty_chunk():
    rng = np.random.default_rng(2)
    costs = rng.uniform(0.0, 1.0, 23)
    chunks = balanced_chunks(costs, 5)
    assert sorted(i for c in chunks for i in c) == list(range(23))
    assert all(c for c in chunks)
    loads = [costs[c].sum() for c in chunks]
    assert loads == sorted(loads, reverse=True)  # the most loaded first
    # the greedy bound: no chunk exceeds the mean load by more than the largest job
    assert max(loads) <= costs.sum() / 5 + costs.max()
    assert balanced_chunks([1.0, 2.0], 8) == [[1], [0]]
    assert balanced_chunks([], 3) == []


@pytest.mark.parametrize(
    ("costs", "k", "error", "match"),
    [
        ([1.0], 0, ValueError, "k must be >= 1"),
        ([1.0], 1.5, TypeError, "k must be an integer"),
        ([1.0, -1.0], 2, ValueError, "costs must be finite"),
        ([float("nan")], 2, ValueError, "costs must be finite"),
    ],
)
def test_bad_split_inputs_are_refused(costs, k, error, match):
    with pytest.raises(error, match=match):
        balanced_chunks(costs, k)


# ------------------------------------------------------------------ the jobs
def test_jobs_are_checked(surfaces):
    model = surfaces["ellipsoid"]
    touch = meshrec.simulate_touch(model, rng=3).touch
    coarse = register_coarse(touch, model)
    with pytest.raises(ValueError, match="kind"):
        StageJob("search", model)
    with pytest.raises(TypeError, match="model must be a ModelIndex"):
        StageJob("coarse", "ellipsoid")
    with pytest.raises(ValueError, match="cost must be >= 0"):
        StageJob("coarse", model, cost=-1.0)
    with pytest.raises(ValueError, match="cost must be finite"):
        StageJob("coarse", model, cost=float("inf"))
    with pytest.raises(TypeError, match="cost must be a real number"):
        StageJob("coarse", model, cost="1")
    with pytest.raises(TypeError, match="payload must be a CoarseRegistration"):
        StageJob("full", model)
    with pytest.raises(TypeError, match="payload must be a \\(LibraryScreen, int\\) pair"):
        StageJob("screened", model, coarse)
    with pytest.raises(TypeError, match="payload\\[0\\] must be a LibraryScreen"):
        StageJob("screened", model, (coarse, 0))
    models = list(surfaces)
    screen = screen_library(touch, touch_geometry(touch), library_sites(models))
    with pytest.raises(ValueError, match="payload\\[1\\] must be >= 0"):
        StageJob("screened", model, (screen, -1))
    with pytest.raises(TypeError, match="payload\\[1\\] must be an integer"):
        StageJob("screened", model, (screen, 1.0))
    with pytest.raises(ValueError, match="payload must be None"):
        StageJob("coarse", model, coarse)
    with pytest.raises(ValueError, match="payload must be >= 1"):
        StageJob("register", model, 0)
    with pytest.raises(TypeError, match="payload must be an integer"):
        StageJob("register", model, 64.0)
    with pytest.raises(TypeError, match="job must be a StageJob"):
        run_stage("coarse", touch, touch_geometry(touch), "lm")
    assert set(STAGE_KINDS) == {"register", "coarse", "leader", "full", "pruned", "screened"}


def test_each_kind_gives_its_stage_functions_result(surfaces):
    model = surfaces["ellipsoid"]
    touch = meshrec.simulate_touch(model, rng=3).touch
    g = touch_geometry(touch)
    whole = register(touch, model, geometry=g)
    models = list(surfaces)
    i = models.index(model)
    screen = screen_library(touch, g, library_sites(models))
    jobs = [
        StageJob("register", model),
        StageJob("leader", model),
        StageJob("coarse", model),
    ]
    calls = []
    reg, (c, full), coarse = run_stages_here(
        jobs, touch, g, "lm", progress=lambda k, job: calls.append((k, job.kind))
    )
    assert calls == [(0, "register"), (1, "leader"), (2, "coarse")]
    assert reg.error == whole.error == full.error
    np.testing.assert_array_equal(reg.T_model_touch, whole.T_model_touch)
    assert c.screened_error == coarse.screened_error
    again = run_stage(StageJob("full", model, coarse), touch, g, "lm")
    assert again.error == whole.error
    pruned = run_stage(StageJob("pruned", model, coarse), touch, g, "lm")
    assert pruned.pruned
    assert pruned.error >= whole.error * (1 - 1e-3)  # an upper bound, up to tolerance
    screened = run_stage(StageJob("screened", model, (screen, i)), touch, g, "lm")
    assert screened.pruned
    assert len(screened.candidate_points) == 1
    # a "register" job's payload caps the candidates, as register's max_candidates does
    few = run_stage(StageJob("register", model, 3), touch, g, "lm")
    direct = register(touch, model, geometry=g, max_candidates=3)
    assert few.candidates == direct.candidates == 3 < whole.candidates
    assert few.error == direct.error
    np.testing.assert_array_equal(few.T_model_touch, direct.T_model_touch)
