"""Tests for meshrec.registration.search: the local search over (u, v, phi).

The data are three curves on the analytic ellipsoid through a known contact c, expressed in
a known frame turned by a known phi: the true pose is known exactly. The model is the
ellipsoid meshed finely (an icosphere of 81,920 faces scaled by its semi-axes, every vertex
on the surface).
"""

import types

import numpy as np
import pytest
from analytic_meshes import ellipsoid, ellipsoid_normal, index_of, on_ellipsoid

from meshrec.registration.chart import SurfaceChart, SurfacePoint, rotation_z, tangent_frame
from meshrec.registration.search import SEARCH_METHODS, chart_residuals, local_search

#: Half-length of the curves: long enough that the ellipsoid's varying curvature fixes the
#: contact (with 0.3 the error changes by less than the mesh's deviation over 0.04).
HALF_LENGTH = 0.6
#: The start's offset from the truth: chart coordinates (model units) and phi (radians).
START = (0.04, -0.03, 0.1)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return index_of(ellipsoid(subdivisions=6), tmp_path_factory.mktemp("ellipsoid"), "ellipsoid")


def _touch(seed):
    """Curves through a random contact of the analytic ellipsoid, in the data frame."""
    rng = np.random.default_rng(seed)
    c = on_ellipsoid(rng.normal(size=3))[0]
    frame = tangent_frame(ellipsoid_normal(c)[0], hint=rng.normal(size=3))
    s = np.linspace(-HALF_LENGTH, HALF_LENGTH, 21)
    curves = [
        on_ellipsoid(c + s[:, None] * (np.cos(t) * frame[:, 0] + np.sin(t) * frame[:, 1]))
        for t in 0.3 + np.arange(3) * np.pi / 3
    ]
    phi = float(rng.uniform(0.0, 2.0 * np.pi))
    # The registration places x as frame Rz(phi) x + c: the data are the inverse of that.
    local = (np.vstack(curves) - c) @ frame @ rotation_z(phi)
    return types.SimpleNamespace(contact=c, frame=frame, phi=phi, local=local)


def _central_differences(model, local, start, x, scale, h):
    J = np.empty((len(local), 3))
    for j in range(3):
        dx = np.zeros(3)
        dx[j] = h * (scale if j < 2 else 1.0)
        plus = chart_residuals(model, local, start, x + dx, scale)[0]
        minus = chart_residuals(model, local, start, x - dx, scale)[0]
        J[:, j] = (plus - minus) / (2.0 * dx[j])
    return J


def test_jacobian_matches_central_differences(model):
    errors = []
    for seed in range(3):
        touch = _touch(seed)
        start = SurfacePoint(touch.contact, touch.frame)
        rng = np.random.default_rng(100 + seed)
        for du, dv, dphi in rng.uniform(-0.06, 0.06, size=(4, 3)):
            x = np.array([du, dv, touch.phi + 3 * dphi])
            values, J = chart_residuals(model, touch.local, start, x, HALF_LENGTH)
            assert values.shape == (len(touch.local),)
            assert J.shape == (len(touch.local), 3)
            assert np.abs(values).mean() > 1e-4  # away from the minimum: slopes are not ~0
            fd = _central_differences(model, touch.local, start, x, HALF_LENGTH, h=1e-4)
            errors.append(np.linalg.norm(J - fd, axis=0) / np.linalg.norm(fd, axis=0))
    errors = np.array(errors)  # (12, 3): relative error of the u, v and phi columns
    # The residuals are only piecewise smooth (the chart's closest point crosses face
    # edges, where the interpolated normal's slope jumps), and the (u, v) columns are
    # one-sided differences of the chart over defaults.CHART_FD_STEP: where an edge falls
    # within that step they differ from the local slope (measured: up to 7.6%, typically
    # 0.03%). phi's column is exact. A wrong sign or a missing term would be off by ~100%.
    assert np.median(errors[:, :2]) < 1e-2
    assert errors[:, :2].max() < 0.15
    assert np.median(errors[:, 2]) < 1e-3
    assert errors[:, 2].max() < 1e-2


def test_residuals_vanish_at_the_true_pose(model):
    touch = _touch(0)
    start = SurfacePoint(touch.contact, touch.frame)
    at_truth = chart_residuals(model, touch.local, start, [0.0, 0.0, touch.phi], HALF_LENGTH)[0]
    away = chart_residuals(model, touch.local, start, [*START[:2], touch.phi], HALF_LENGTH)[0]
    # Only the mesh's deviation from the ellipsoid remains at the truth.
    assert np.abs(at_truth).max() < 2e-4
    assert np.abs(away).mean() > 10 * np.abs(at_truth).mean()


#: Per method: how close to the true contact (model units) and rotation (radians) the
#: search must end, and its error at most this multiple of the true pose's error. The
#: paper's steepest descent stops short of the minimum (measured on seeds 0-7: up to
#: 0.017 and 9 times the true pose's error, where Levenberg-Marquardt ends within 0.004
#: and below the true pose's error, the mesh's own minimum being a little off the truth).
CONVERGED = {"lm": (5e-3, 5e-3, 1.0), "steepest": (0.025, 0.025, 15.0)}


@pytest.mark.parametrize("method", SEARCH_METHODS)
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_search_from_near_the_truth_converges_to_it(model, method, seed):
    touch = _touch(seed)
    truth = SurfacePoint(touch.contact, touch.frame)
    du, dv, dphi = START
    start = SurfaceChart(model, truth).at(du, dv)
    assert np.linalg.norm(start.point - touch.contact) > 0.04
    at_start = chart_residuals(model, touch.local, truth, [du, dv, touch.phi + dphi], HALF_LENGTH)
    at_truth = chart_residuals(model, touch.local, truth, [0.0, 0.0, touch.phi], HALF_LENGTH)
    e_start, e_truth = np.abs(at_start[0]).mean(), np.abs(at_truth[0]).mean()
    assert e_start > 20 * e_truth

    result = local_search(model, touch.local, start, touch.phi + dphi, HALF_LENGTH, method=method)
    max_distance, max_angle, max_ratio = CONVERGED[method]
    assert np.linalg.norm(result.surface.point - touch.contact) < max_distance
    R = result.surface.frame @ rotation_z(result.phi)
    R_true = touch.frame @ rotation_z(touch.phi)
    angle = np.arccos(np.clip((np.trace(R.T @ R_true) - 1.0) / 2.0, -1.0, 1.0))
    assert angle < max_angle
    assert result.error <= max_ratio * e_truth
    assert 0.0 <= result.phi < 2 * np.pi
    np.testing.assert_allclose(result.path[0], start.point)
    np.testing.assert_allclose(result.path[-1], result.surface.point)
    assert result.evaluations > 0


def test_search_errors(model):
    touch = _touch(0)
    start = SurfacePoint(touch.contact, touch.frame)
    with pytest.raises(ValueError, match=r"method must be one of \('lm', 'steepest'\), got 'x'"):
        local_search(model, touch.local, start, 0.0, HALF_LENGTH, method="x")
    with pytest.raises(ValueError, match=r"scale must be positive, got 0\.0"):
        local_search(model, touch.local, start, 0.0, 0.0)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ({"local_points": np.zeros((4, 2))}, r"local_points must be \(n, 3\), got \(4, 2\)"),
        ({"x": [0.0, 0.0]}, "x must be three finite numbers"),
        ({"x": [0.0, np.nan, 0.0]}, "x must be three finite numbers"),
        ({"scale": -1.0}, r"scale must be positive, got -1\.0"),
    ],
)
def test_chart_residuals_errors(model, args, match):
    touch = _touch(0)
    kwargs = {
        "local_points": touch.local,
        "start": SurfacePoint(touch.contact, touch.frame),
        "x": [0.0, 0.0, 0.0],
        "scale": HALF_LENGTH,
        **args,
    }
    with pytest.raises(ValueError, match=match):
        chart_residuals(model, **kwargs)
