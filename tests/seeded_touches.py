"""Seeded touches of one object at a random pose, for the tests of several touches.

Not a test module: test_bestfirst.py, test_phases.py, test_joint.py and
test_joint_adequacy.py import it. The draws come in one order (the pose's rotation, its
translation, then each touch), so a test's seed gives the same touches wherever it is used.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import meshrec


def world_pose(rng: np.random.Generator, spread: float = 1.0) -> np.ndarray:
    """A seeded rigid motion T_world_model: a uniform rotation, a translation uniform in
    [-spread, spread]^3."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def touches_at(model, T_world_model, rng, n=3, length=0.3, noise=0.002):
    """``n`` simulated touches of ``model`` (a ModelIndex or a mesh) at one pose, in the
    world frame, and their simulations (model frame)."""
    sims = [
        meshrec.simulate_touch(model, length=length, noise=noise, rng=rng, transform=False)
        for _ in range(n)
    ]
    return [s.touch.transformed(T_world_model) for s in sims], sims
