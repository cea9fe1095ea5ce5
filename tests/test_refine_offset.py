"""Tests for meshrec.registration.refine.refine_offset: the pose and an outward offset R.

The data are vertices of a finely meshed sphere of radius 1 scaled to radius 1 + R (the
ball centres of a tip of radius R: closed form), in a patch, moved into a touch frame by
a known rigid transform. The brute-force twin is a search over R of rigid refinements
onto the offset surface (:func:`meshrec.model.probe.probe_model`), the path that
``probe_offset`` took before the joint refinement.
"""

import numpy as np
import pytest
from analytic_meshes import ellipsoid, index_of, sphere
from scipy.spatial.transform import Rotation

from meshrec.model.probe import probe_model
from meshrec.registration.objective import residuals
from meshrec.registration.refine import OffsetRefinement, refine_offset, refine_rigid
from meshrec.registration.transform import apply_transform, invert_transform


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("offset_models")
    return {
        "sphere": index_of(sphere(1.0, 5), folder, "sphere"),
        "ellipsoid": index_of(ellipsoid(5), folder, "ellipsoid"),
    }


def _patch(model, tip, seed, radius=0.5, noise=0.0):
    """Vertices near a random one, pushed out along the sphere's radius by ``tip`` (so on
    the sphere of radius 1 + tip), in a random touch frame; the true pose."""
    rng = np.random.default_rng(seed)
    V = model.mesh.vertices
    centre = V[rng.integers(len(V))]
    chosen = V[np.linalg.norm(V - centre, axis=1) < radius]
    chosen = chosen * (1.0 + tip) + noise * rng.normal(size=chosen.shape)
    T_true = np.eye(4)
    T_true[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T_true[:3, 3] = rng.normal(size=3)
    return apply_transform(invert_transform(T_true), chosen), T_true


@pytest.mark.parametrize("tip", [0.05, 0.1])
def test_the_offset_of_ball_centres_on_a_sphere_is_the_tip(models, tip):
    m = models["sphere"]
    points, T_true = _patch(m, tip, seed=3)
    rigid = refine_rigid(m, points, T_true)
    joint = refine_offset(m, points, rigid.T_model_touch, max_offset=0.2)
    assert isinstance(joint, OffsetRefinement)
    # one touch shows the offset only through curvature: 1 / (1 + R) against 1
    assert joint.radius == pytest.approx(tip, abs=2e-3)
    assert joint.rms < 0.05 * rigid.rms
    # the reported error and RMS are those of the returned pose and offset
    values = residuals(m, apply_transform(joint.T_model_touch, points)).values - joint.radius
    assert joint.rms == pytest.approx(np.sqrt(np.mean(values**2)), rel=1e-9)
    assert joint.error == pytest.approx(np.abs(values).mean(), rel=1e-9)


@pytest.mark.parametrize(("name", "tip", "seed"), [("sphere", 0.08, 1), ("ellipsoid", 0.0, 2)])
def test_the_joint_refinement_matches_a_search_over_rigid_ones(models, name, tip, seed):
    m = models[name]
    points, T_true = _patch(m, tip, seed=seed, noise=2e-3)
    start = refine_rigid(m, points, T_true).T_model_touch
    joint = refine_offset(m, points, start, max_offset=0.2)
    grid = np.linspace(0.0, 0.2, 41)
    brute = np.array([refine_rigid(probe_model(m, r), points, start).rms for r in grid])
    # no R of the grid fits better than the joint optimum (up to the refinements' stops)
    assert joint.rms <= brute.min() * (1.0 + 1e-4)
    assert abs(joint.radius - grid[np.argmin(brute)]) <= 0.01
    assert joint.rms == pytest.approx(brute.min(), rel=2e-3)


def test_the_offset_stays_in_its_bounds(models):
    m = models["sphere"]
    inside, T_in = _patch(m, -0.05, seed=4)  # data inside: the best R >= 0 is 0
    rigid = refine_rigid(m, inside, T_in)
    low = refine_offset(m, inside, rigid.T_model_touch, max_offset=0.2)
    assert low.radius == 0.0
    assert low.rms <= rigid.rms
    outside, T_out = _patch(m, 0.1, seed=4)
    start = refine_rigid(m, outside, T_out).T_model_touch
    high = refine_offset(m, outside, start, max_offset=0.04)
    assert high.radius == 0.04
    free = refine_offset(m, outside, start, max_offset=0.2)
    assert free.rms < high.rms


def test_a_start_that_cannot_gain_enough_is_returned_unrefined(models):
    m = models["sphere"]
    points, T_true = _patch(m, 0.0, seed=5, noise=1e-3)
    start = refine_rigid(m, points, T_true)
    values = residuals(m, apply_transform(start.T_model_touch, points)).values
    skipped = refine_offset(m, points, start.T_model_touch, 0.2, skip_below=1.0)
    assert skipped.iterations == 0
    assert np.array_equal(skipped.T_model_touch, start.T_model_touch)
    assert skipped.radius == min(max(values.mean(), 0.0), 0.2)
    # a tip's drop is far above a threshold of a few noise variances: refined
    tipped, T_tip = _patch(m, 0.1, seed=5, noise=1e-3)
    rigid = refine_rigid(m, tipped, T_tip)
    refined = refine_offset(m, tipped, rigid.T_model_touch, 0.2, skip_below=25e-6)
    assert refined.iterations >= 1
    assert refined.radius == pytest.approx(0.1, abs=5e-3)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_refine_offset_refuses_a_bad_bound(models, bad):
    m = models["sphere"]
    points, T_true = _patch(m, 0.0, seed=6)
    with pytest.raises(ValueError, match="max_offset must be finite and >= 0"):
        refine_offset(m, points, T_true, bad)


def test_probe_offset_searches_over_r_when_the_joint_fit_stalls(models, monkeypatch):
    """A joint refinement that realises less than a quarter of its linearised drop (here
    a stand-in that does not move) sends probe_offset to the search over R of rigid
    refinements: the tip is still found (closed form: the offset sphere's 0.1)."""
    import meshrec.recognition.probing as probing

    m = models["sphere"]
    points, T_true = _patch(m, 0.1, seed=7, noise=1e-3)
    rms0 = refine_rigid(m, points, T_true).rms

    def stalled(model, pts, T0, max_offset, **kwargs):
        return OffsetRefinement(np.array(T0), 0.0, rms0, rms0, 1, linear_drop=1.0)

    monkeypatch.setattr(probing, "refine_offset", stalled)
    found = probing.probe_offset(points, m, T_true, 1e-3)
    radius, rms_zero, rms = found.radius, found.rms0, found.rms
    assert found.linear_drop == 1.0  # the stand-in's, passed on
    assert rms_zero == rms0
    assert radius == pytest.approx(0.1, abs=0.01)
    assert rms < 1.2e-3 < rms0 / 3  # down to the noise (1e-3 per coordinate)
