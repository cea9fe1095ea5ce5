"""The registration residuals: distance to the smooth surface the vertex normals imply.

Checked against an analytic sphere (the true distance is | |x| - r |) and a brute-force
finite-difference twin of the gradient.
"""

import numpy as np
import pytest
import trimesh

from meshrec.model.index import ModelIndex
from meshrec.registration.objective import mean_distances, residuals

RADIUS = 2.0


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sphere")
    path = tmp / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=RADIUS).export(path)
    return ModelIndex.from_file(path, cache_dir=tmp / "cache")


def _points(n, offset, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True) * (RADIUS + offset)


def test_residuals_measure_the_smooth_sphere_not_the_facets(sphere):
    # A coarse sphere (edge ~0.15): the facets lie up to a sagitta inside the sphere.
    pts = _points(2000, 0.0)
    flat, _, _ = sphere.surface.closest_points(pts)
    smooth = np.abs(residuals(sphere, pts).values)
    assert flat.max() > 1e-3
    assert smooth.max() < 0.2 * flat.max()
    assert np.sqrt(np.mean(smooth**2)) < 0.2 * np.sqrt(np.mean(flat**2))


@pytest.mark.parametrize("offset", [0.05, -0.05])
def test_residual_sign_follows_the_outward_normal(sphere, offset):
    res = residuals(sphere, _points(200, offset))
    np.testing.assert_allclose(res.values, offset, atol=2e-3)


def test_residual_gradient_matches_finite_differences(sphere):
    # Exact where the closest point is inside a face; where it is on an edge or a vertex
    # the closest point's motion is not the face's, and the slope is approximate.
    pts = _points(200, 0.03, seed=1)
    res = residuals(sphere, pts)
    h = 1e-6
    fd = np.empty_like(pts)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        fd[:, axis] = (
            residuals(sphere, pts + step).values - residuals(sphere, pts - step).values
        ) / (2 * h)
    err = np.linalg.norm(res.gradient - fd, axis=1)
    assert np.quantile(err, 0.8) < 1e-3
    assert err.max() < 0.1
    # The facets' slope is a real part of the gradient: the unit direction alone is off.
    unit = (pts - res.closest) / np.linalg.norm(pts - res.closest, axis=1, keepdims=True)
    assert np.quantile(np.linalg.norm(unit - fd, axis=1), 0.8) > 3e-3


def test_mean_distances_batches(sphere):
    batch = np.stack([_points(10, 0.1), _points(10, 0.2)])
    np.testing.assert_allclose(mean_distances(sphere, batch), [0.1, 0.2], atol=0.01)
