"""Tests for meshrec.registration.transform: superposition, applying and inverting transforms.

(The frame helpers of meshrec.registration.chart are tested in test_chart.py, the lookup
window and the spreading of candidates in test_candidates.py.)
"""

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec.registration.chart import SurfacePoint
from meshrec.registration.transform import apply_transform, invert_transform, superposition


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


def test_apply_and_invert_match_homogeneous_matrix_algebra():
    rng = np.random.default_rng(6)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=7).as_matrix()
    T[:3, 3] = rng.normal(size=3)
    points = rng.normal(size=(10, 3))
    homogeneous = np.column_stack([points, np.ones(10)]) @ T.T
    np.testing.assert_allclose(apply_transform(T, points), homogeneous[:, :3], atol=1e-12)
    np.testing.assert_allclose(invert_transform(T), np.linalg.inv(T), atol=1e-12)
    back = apply_transform(invert_transform(T), apply_transform(T, points))
    np.testing.assert_allclose(back, points, atol=1e-12)
