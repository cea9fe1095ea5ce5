"""Tests for meshrec.registration.refine: the final rigid refinement of all six DOF.

The data are vertices of a finely meshed ellipsoid (they lie on the analytic surface and on
the smooth surface the residuals measure, whose height is zero at the vertices) in a patch
around a contact, moved into a touch frame by a known rigid transform: the true pose is
known exactly and the residuals vanish there. The ellipsoid's three different semi-axes
leave no continuous symmetry, so the patch fixes all six degrees of freedom.
"""

import numpy as np
import pytest
from analytic_meshes import ellipsoid, index_of
from scipy.spatial.transform import Rotation

from meshrec.registration.objective import residuals
from meshrec.registration.refine import Refinement, refine_rigid
from meshrec.registration.transform import apply_transform, invert_transform


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return index_of(ellipsoid(subdivisions=5), tmp_path_factory.mktemp("ellipsoid"), "ellipsoid")


def _rigid(rotvec, translation):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = translation
    return T


def _pose_error(T, T_true):
    """Rotation angle (rad) and translation distance between two rigid transforms."""
    D = T @ invert_transform(T_true)
    angle = Rotation.from_matrix(D[:3, :3]).magnitude()
    return angle, float(np.linalg.norm(D[:3, 3]))


def _touch(model, seed, radius=0.6, count=300):
    """Vertices of the model near a random one, in a random touch frame; the true pose."""
    rng = np.random.default_rng(seed)
    centre = model.mesh.vertices[rng.integers(len(model.mesh.vertices))]
    near = np.flatnonzero(np.linalg.norm(model.mesh.vertices - centre, axis=1) < radius)
    chosen = model.mesh.vertices[rng.choice(near, size=min(count, len(near)), replace=False)]
    T_model_touch = _rigid(Rotation.random(random_state=seed).as_rotvec(), rng.normal(size=3))
    return apply_transform(invert_transform(T_model_touch), chosen), T_model_touch


def _brute_force(model, points, T):
    """Mean and RMS of the residuals of the points placed by T, recomputed from scratch."""
    values = residuals(model, apply_transform(T, points)).values
    return np.abs(values).mean(), np.sqrt(np.mean(values**2))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_refinement_returns_to_the_true_pose(model, seed):
    points, T_true = _touch(model, seed)
    rng = np.random.default_rng(50 + seed)
    axis = rng.normal(size=3)
    # A small perturbation: 3 degrees about a random axis and 0.02 (2% of the size).
    nudge = _rigid(np.radians(3.0) * axis / np.linalg.norm(axis), 0.02 * rng.normal(size=3))
    T0 = nudge @ T_true
    angle0, shift0 = _pose_error(T0, T_true)
    assert angle0 > np.radians(2.9)
    assert shift0 > 0.005
    start_error = _brute_force(model, points, T0)[0]

    result = refine_rigid(model, points, T0)
    assert isinstance(result, Refinement)
    angle, shift = _pose_error(result.T_model_touch, T_true)
    # The points are the model's vertices: at the true pose every residual is zero, and the
    # refinement gets there to rounding (measured: 1e-15 rad and 1e-15 after 6 to 9 steps).
    assert angle < 1e-8
    assert shift < 1e-8
    assert result.error < 1e-10
    assert start_error > 1e-3
    assert 1 <= result.iterations <= 30


@pytest.mark.parametrize("seed", [0, 1])
def test_reported_error_and_rms_are_those_of_the_returned_transform(model, seed):
    points, T_true = _touch(model, seed)
    rng = np.random.default_rng(seed)
    # Stopped after one iteration, so that the residuals are far from zero.
    T0 = _rigid(0.1 * rng.normal(size=3), 0.05 * rng.normal(size=3)) @ T_true
    result = refine_rigid(model, points, T0, max_iter=1)
    mean, rms = _brute_force(model, points, result.T_model_touch)
    assert mean > 1e-3
    assert result.error == pytest.approx(mean, rel=1e-12)
    assert result.rms == pytest.approx(rms, rel=1e-12)
    assert result.rms >= result.error  # RMS bounds the mean from above
    assert result.iterations == 1
    # A rigid transform: a rotation block and the homogeneous row.
    R = result.T_model_touch[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_array_equal(result.T_model_touch[3], [0.0, 0.0, 0.0, 1.0])


def test_refinement_at_the_true_pose_stays_there(model):
    points, T_true = _touch(model, 4)
    result = refine_rigid(model, points, T_true)
    angle, shift = _pose_error(result.T_model_touch, T_true)
    assert angle < 1e-10
    assert shift < 1e-10
    assert result.error < 1e-10
