"""AabbSurface.first_hits: batched ray casting against the one-ray simulator's twin."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from meshrec.model.mesh import MeshData
from meshrec.model.surface import AabbSurface
from meshrec.sim.probe import first_hit

sys.path.insert(0, str(Path(__file__).parent))
from analytic_meshes import sphere


@pytest.fixture(scope="module")
def ball():
    mesh = sphere(1.0, 4)
    return AabbSurface.from_mesh(MeshData.from_arrays(mesh.vertices, mesh.faces), 45.0)


def test_first_hits_match_one_ray_at_a_time(ball):
    rng = np.random.default_rng(7)
    origins = rng.normal(size=(60, 3))
    origins *= (3.0 / np.linalg.norm(origins, axis=1))[:, None]
    aim = 0.8 * rng.uniform(-1.0, 1.0, size=(60, 3))  # some rays pass beside the ball
    directions = aim - origins
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    directions[:5] *= -1.0  # pointing away: no hit ahead
    points, hit = ball.first_hits(origins, directions)
    V, F = ball.mesh.vertices, ball.mesh.faces
    for o, d, p, h in zip(origins, directions, points, hit, strict=True):
        want = first_hit(V, F, o, d)
        assert h == (want is not None)
        if h:
            np.testing.assert_allclose(p, want, atol=1e-12)
            assert abs(np.linalg.norm(p) - 1.0) < 0.01  # on the unit sphere's faces
            assert (p - o) @ d > 0.0  # ahead of the start, on the near side
            assert np.linalg.norm(p - o) < 3.0
        else:
            assert np.isnan(p).all()
    assert not hit[:5].any()
    assert hit[5:].sum() > 20


def test_first_hits_of_no_rays(ball):
    points, hit = ball.first_hits(np.zeros((0, 3)), np.zeros((0, 3)))
    assert points.shape == (0, 3)
    assert hit.shape == (0,)


@pytest.mark.parametrize(
    ("origins", "directions", "match"),
    [
        (np.zeros(3), np.zeros((1, 3)), r"origins must have shape \(n, 3\), got \(3,\)"),
        (np.zeros((1, 3)), np.zeros((1, 2)), r"directions must have shape \(n, 3\)"),
        (np.full((1, 3), np.nan), np.ones((1, 3)), "origins must be finite"),
        (np.zeros((2, 3)), np.ones((1, 3)), "the same length, got 2 and 1"),
    ],
)
def test_first_hits_refuses_bad_rays(ball, origins, directions, match):
    with pytest.raises(ValueError, match=match):
        ball.first_hits(origins, directions)
