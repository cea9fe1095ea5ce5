"""Tests for meshrec.registration.transform and the frame helpers of meshrec.registration.chart."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from meshrec.registration.candidates import curvature_tolerance, spread_points
from meshrec.registration.chart import SurfacePoint, rotation_z, tangent_frame
from meshrec.registration.transform import apply_transform, invert_transform, superposition


def test_tangent_frame_is_orthonormal_right_handed():
    rng = np.random.default_rng(1)
    for _ in range(20):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        F = tangent_frame(n, hint=rng.normal(size=3))
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(F[:, 2], n)
        assert np.linalg.det(F) > 0
    # A hint parallel to the normal falls back to a world axis.
    F = tangent_frame(np.array([0.0, 0, 1]), hint=np.array([0.0, 0, 2]))
    np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)


def test_rotation_z_batch_matches_scipy():
    phis = np.array([0.0, 0.3, -2.0])
    R = rotation_z(phis)
    for p, r in zip(phis, R, strict=True):
        np.testing.assert_allclose(r, Rotation.from_euler("z", p).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rotation_z(0.3), R[1])


def test_superposition_puts_the_contact_on_q_and_the_normal_on_n():
    rng = np.random.default_rng(2)
    p = rng.normal(size=3)
    F = Rotation.random(random_state=3).as_matrix()
    D = Rotation.random(random_state=4).as_matrix()
    q = rng.normal(size=3)
    T = superposition(p, F, SurfacePoint(q, D), 0.7)
    np.testing.assert_allclose(apply_transform(T, p[None])[0], q, atol=1e-12)
    np.testing.assert_allclose(T[:3, :3] @ F[:, 2], D[:, 2], atol=1e-12)
    # phi turns the data's first tangent by phi from d1 towards d2.
    t1 = T[:3, :3] @ F[:, 0]
    np.testing.assert_allclose(t1, np.cos(0.7) * D[:, 0] + np.sin(0.7) * D[:, 1], atol=1e-12)
    np.testing.assert_allclose(invert_transform(T) @ T, np.eye(4), atol=1e-12)


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
    assert len(spread_points(pts, 0.0, 7)) == 7
    assert len(spread_points(pts[:0], 0.1, 7)) == 0


def test_curvature_tolerance_propagates_to_k_and_h():
    tol_K, tol_H = curvature_tolerance(2.0, 1.0, 0.5, 0.001, rel=0.1, noise_factor=10.0)
    tau = 0.1 * 2.0 + 10.0 * 0.001 / 0.5**2
    assert tol_H == tau
    # The worst case of K = k1 k2 with both curvatures off by tau.
    assert tol_K >= (2 + tau) * (1 + tau) - 2.0 - 1e-12


def test_curvature_tolerance_errors():
    with pytest.raises(ValueError, match=r"half_length must be positive, got 0\.0"):
        curvature_tolerance(1.0, 1.0, 0.0, 0.001)
    with pytest.raises(ValueError, match="fit_rms must be non-negative"):
        curvature_tolerance(1.0, 1.0, 0.3, -1.0)
