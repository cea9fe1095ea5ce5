"""The refinements' damping schedules (meshrec.registration.damping)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import meshrec
from meshrec import defaults
from meshrec.registration.batch import refine_rigid_batch
from meshrec.registration.damping import (
    SCHEDULES,
    after_accept,
    after_reject,
    damped_system,
    predicted_drop,
    schedule,
)
from meshrec.registration.refine import refine_offset, refine_rigid

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_predicted_drop_is_the_linear_models():
    """|r|^2 - |r + J h|^2 for the damped step h, computed directly."""
    rng = np.random.default_rng(3)
    J, r = rng.normal(size=(40, 6)), rng.normal(size=40)
    A, b = J.T @ J, -J.T @ r
    for lam in (0.0, 1e-3, 1.0, 100.0):
        diag = np.diag(A) + 1e-12
        h = np.linalg.solve(A + lam * np.diag(diag), b)
        want = r @ r - (r + J @ h) @ (r + J @ h)
        assert predicted_drop(h, b, lam, diag) == pytest.approx(want, rel=1e-10)
        assert predicted_drop(h, b, lam, diag) > 0.0


def test_gain_schedule_follows_the_ratio():
    # A step as good as predicted (rho = 1): a third of the damping, nu reset.
    assert after_accept("gain", 0.3, 8.0, 1.0, 1.0) == (pytest.approx(0.1), 2.0)
    # Half as good as predicted (rho = 1/2): the damping stays.
    assert after_accept("gain", 0.3, 2.0, 0.5, 1.0)[0] == pytest.approx(0.3)
    # Barely accepted (rho -> 0): the damping doubles, so the next step is not rejected.
    assert after_accept("gain", 0.3, 2.0, 1e-12, 1.0)[0] == pytest.approx(0.6)
    # Rejected: times nu, and nu doubles.
    assert after_reject("gain", 0.3, 4.0) == (pytest.approx(1.2), 8.0)
    # Never below the floor.
    assert after_accept("gain", defaults.REFINE_MIN_DAMPING, 2.0, 1.0, 1.0)[0] == (
        defaults.REFINE_MIN_DAMPING
    )


def test_tenfold_schedule():
    f = defaults.REFINE_DAMPING_FACTOR
    assert after_accept("tenfold", 0.3, 2.0, 0.1, 1.0) == (pytest.approx(0.3 / f), 2.0)
    assert after_reject("tenfold", 0.3, 2.0) == (pytest.approx(0.3 * f), 2.0)


def test_schedule_is_read_and_checked_at_call_time(monkeypatch):
    assert schedule() == defaults.REFINE_DAMPING_SCHEDULE
    assert schedule() in SCHEDULES
    monkeypatch.setattr(defaults, "REFINE_DAMPING_SCHEDULE", "tenfold")
    assert schedule() == "tenfold"
    monkeypatch.setattr(defaults, "REFINE_DAMPING_SCHEDULE", "fast")
    with pytest.raises(ValueError, match="REFINE_DAMPING_SCHEDULE must be one of"):
        schedule()


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    return meshrec.ModelLibrary.from_folder(MODELS / "objects", cache_dir=cache)["sphere"]


@pytest.mark.parametrize("name", SCHEDULES)
def test_both_schedules_find_a_known_pose(sphere, name, monkeypatch):
    """Noiseless curves on the bundled sphere, started 0.1 rad and 2% of the radius off:
    both schedules bring every point back onto the surface (the pose is known up to the
    sphere's rotations), the gain schedule in no more evaluations' worth of iterations."""
    monkeypatch.setattr(defaults, "REFINE_DAMPING_SCHEDULE", name)
    sim = meshrec.simulate_touch(sphere, rng=1, noise=0.0)
    radius = float(np.linalg.norm(sphere.mesh.vertices, axis=1).max())
    D = np.eye(4)
    D[:3, :3] = Rotation.from_rotvec([0.1, -0.05, 0.02]).as_matrix()
    D[:3, 3] = [0.02 * radius, 0.0, -0.01 * radius]
    start = D @ sim.T_model_touch
    got = refine_rigid(sphere, sim.touch.points, start)
    assert got.rms < 1e-4 * radius  # the mesh's own chord error is below this
    off = refine_offset(sphere, sim.touch.points, start, max_offset=0.05 * radius)
    assert off.rms < 1e-4 * radius
    assert off.radius < 1e-4 * radius


def test_refinements_refuse_an_unknown_schedule(sphere, monkeypatch):
    sim = meshrec.simulate_touch(sphere, rng=2, noise=0.0)
    monkeypatch.setattr(defaults, "REFINE_DAMPING_SCHEDULE", "fast")
    T = sim.T_model_touch[None]
    with pytest.raises(ValueError, match="REFINE_DAMPING_SCHEDULE must be one of"):
        refine_rigid(sphere, sim.touch.points, sim.T_model_touch)
    with pytest.raises(ValueError, match="REFINE_DAMPING_SCHEDULE must be one of"):
        refine_offset(sphere, sim.touch.points, sim.T_model_touch, max_offset=0.1)
    with pytest.raises(ValueError, match="REFINE_DAMPING_SCHEDULE must be one of"):
        refine_rigid_batch(sphere, sim.touch.points, T)


def test_damped_system_is_marquardts():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(30, 6))
    J[:, 2] = 0.0  # a vanishing column: the floor keeps the system regular
    A = J.T @ J
    damped, diag = damped_system(A, 0.5)
    np.testing.assert_array_equal(np.diag(damped), np.diag(A) + 0.5 * diag)
    np.testing.assert_array_equal(damped - np.diag(np.diag(damped)), A - np.diag(np.diag(A)))
    assert diag[2] > 0.0
    assert np.isfinite(np.linalg.solve(damped, rng.normal(size=6))).all()
