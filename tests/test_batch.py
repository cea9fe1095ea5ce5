"""Rigid refinements in lockstep and large distance queries: each the same as its
one-at-a-time twin (refine_rigid from each start, small queries), to the last bit."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import meshrec
from meshrec.registration.batch import refine_rigid_batch
from meshrec.registration.objective import Residuals, residuals
from meshrec.registration.refine import refine_rigid
from meshrec.registration.transform import apply_transform

MODELS = Path(__file__).resolve().parents[1] / "models"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    return meshrec.ModelLibrary.from_folder(MODELS / "surfaces", cache_dir=cache)["ellipsoid"]


def _starts(sim, k, rng):
    """``k`` transforms around the true pose: small and large rotations and shifts."""
    out = []
    for j in range(k):
        D = np.eye(4)
        D[:3, :3] = Rotation.from_rotvec(rng.normal(0, 0.05 * (1 + j), 3)).as_matrix()
        D[:3, 3] = rng.normal(0, 0.02 * (1 + j), 3)
        out.append(D @ sim.T_model_touch)
    return np.array(out)


@pytest.mark.parametrize("schedule", ["gain", "tenfold"])
@pytest.mark.parametrize("max_iter", [0, 1, 3, 30])
def test_each_start_is_refine_rigid_from_it(model, max_iter, schedule, monkeypatch):
    monkeypatch.setattr(meshrec.defaults, "REFINE_DAMPING_SCHEDULE", schedule)
    rng = np.random.default_rng(7)
    sim = meshrec.simulate_touch(model, rng=2)
    points = sim.touch.points[::3]
    T0 = _starts(sim, 6, rng)
    batch = refine_rigid_batch(model, points, T0, max_iter=max_iter)
    assert len(batch) == len(T0)
    for T, b in zip(T0, batch, strict=True):
        one = refine_rigid(model, points, T, max_iter=max_iter)
        np.testing.assert_array_equal(b.T_model_touch, one.T_model_touch)
        assert (b.error, b.rms, b.iterations) == (one.error, one.rms, one.iterations)


@pytest.mark.parametrize("max_iter", [0, 3, 30])
def test_given_initial_residuals_change_nothing(model, max_iter):
    # The residuals at the starts, given (as joint_poses passes those its ranking of the
    # seeds computed), instead of queried: the same refinements to the last bit.
    rng = np.random.default_rng(8)
    sim = meshrec.simulate_touch(model, rng=3)
    points = sim.touch.points[::2]
    T0 = _starts(sim, 5, rng)
    stacked = residuals(model, np.vstack([apply_transform(T, points) for T in T0]))
    n = len(points)
    initial = [
        Residuals(
            values=stacked.values[i * n : (i + 1) * n],
            closest=stacked.closest[i * n : (i + 1) * n],
            gradient=stacked.gradient[i * n : (i + 1) * n],
        )
        for i in range(len(T0))
    ]
    given = refine_rigid_batch(model, points, T0, max_iter=max_iter, initial=initial)
    queried = refine_rigid_batch(model, points, T0, max_iter=max_iter)
    for a, b in zip(given, queried, strict=True):
        np.testing.assert_array_equal(a.T_model_touch, b.T_model_touch)
        assert (a.error, a.rms, a.iterations) == (b.error, b.rms, b.iterations)
    with pytest.raises(ValueError, match=r"initial must hold one Residuals of \d+ values per"):
        refine_rigid_batch(model, points, T0, initial=initial[:-1])
    with pytest.raises(ValueError, match="initial must hold one Residuals"):
        refine_rigid_batch(model, points[:-1], T0, initial=initial)


def test_no_start_gives_nothing(model):
    assert refine_rigid_batch(model, np.zeros((4, 3)), np.zeros((0, 4, 4))) == []


@pytest.mark.parametrize(
    ("points", "T", "match"),
    [
        (np.zeros((4, 3)), np.eye(4), "T_model_touch"),
        (np.zeros((4, 2)), np.eye(4)[None], "points"),
        (np.zeros((0, 3)), np.eye(4)[None], "points"),
    ],
)
def test_bad_shapes_are_refused(model, points, T, match):
    with pytest.raises(ValueError, match=match):
        refine_rigid_batch(model, points, T)


def test_a_large_query_answers_each_point_as_small_ones_do(model):
    # Large queries are sorted along a Morton curve inside closest_points: every point's
    # answer must be the one it gets in small (unsorted) queries, to the last bit.
    rng = np.random.default_rng(3)
    V = model.mesh.vertices
    P = V[rng.integers(0, len(V), 3000)] + rng.normal(0, 0.05, (3000, 3))
    d, c, f = model.surface.closest_points(P)
    parts = [model.surface.closest_points(P[i : i + 100]) for i in range(0, len(P), 100)]
    np.testing.assert_array_equal(d, np.concatenate([p[0] for p in parts]))
    np.testing.assert_array_equal(c, np.concatenate([p[1] for p in parts]))
    np.testing.assert_array_equal(f, np.concatenate([p[2] for p in parts]))
    # Coincident points (a degenerate bounding box) are answered too.
    same = np.repeat(P[:1], 600, axis=0)
    assert np.all(model.surface.closest_points(same)[0] == d[0])


@pytest.mark.parametrize(
    ("name", "value", "keyword"),
    [
        ("REFINE_MAX_ITER", 2, "max_iter"),
        ("REFINE_REL_TOL", 0.05, "rel_tol"),
    ],
)
def test_defaults_are_read_at_call_time(model, monkeypatch, name, value, keyword):
    """Without the argument, both refinements take meshrec.defaults' value as it is when
    called (a tool or a user may tune it at run time): the same as passing it."""
    rng = np.random.default_rng(11)
    sim = meshrec.simulate_touch(model, rng=4)
    points = sim.touch.points[::3]
    T0 = _starts(sim, 3, rng)
    want_batch = refine_rigid_batch(model, points, T0, **{keyword: value})
    want_one = refine_rigid(model, points, T0[2], **{keyword: value})
    full = refine_rigid(model, points, T0[2])
    # The tuned value does change this refinement (else the test could not fail).
    assert want_one.iterations < full.iterations
    monkeypatch.setattr(meshrec.defaults, name, value)
    got_batch = refine_rigid_batch(model, points, T0)
    got_one = refine_rigid(model, points, T0[2])
    for g, w in zip(got_batch, want_batch, strict=True):
        np.testing.assert_array_equal(g.T_model_touch, w.T_model_touch)
        assert g.iterations == w.iterations
    np.testing.assert_array_equal(got_one.T_model_touch, want_one.T_model_touch)
    assert got_one.iterations == want_one.iterations
