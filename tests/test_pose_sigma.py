"""How precisely the data fix a pose (meshrec.recognition.freedom.pose_sigma).

The brute-force twin: many noise draws of the linearised least-squares problem, the
fitted twists' spread along each principal direction measured, not computed.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from meshrec.recognition.freedom import PoseFreedom, pose_freedom, pose_sigma


def _ellipsoid_patch(rng, n=60):
    a = np.array([1.0, 0.8, 0.5])
    uv = 0.4 * rng.uniform(-1.0, 1.0, size=(n, 2))
    x = np.column_stack([uv[:, 0], uv[:, 1], np.zeros(n)])
    x[:, 2] = -a[2] * np.sqrt(1.0 - (x[:, 0] / a[0]) ** 2 - (x[:, 1] / a[1]) ** 2)
    return x, x / a**2


def test_matches_the_spread_of_fitted_twists_over_noise_draws():
    rng = np.random.default_rng(5)
    x, normals = _ellipsoid_patch(rng)
    noise, f = 0.002, 0.5
    n = normals / np.linalg.norm(normals, axis=1)[:, None]
    c = x.mean(axis=0)
    r = (x - c) / np.sqrt(((x - c) ** 2).sum(axis=1).mean())
    J = np.hstack([n, np.cross(r, n)])
    draws = rng.normal(0.0, noise / np.sqrt(f), size=(len(x), 20000))
    theta = np.linalg.lstsq(J, draws, rcond=None)[0]  # (6, draws)
    _, _, vt = np.linalg.svd(J, full_matrices=False)
    twin = 0.0
    for v in vt:
        spread = float(np.std(v @ theta))  # measured along the direction
        reach = float(np.linalg.norm(v[:3] + np.cross(v[3:], r), axis=1).max())
        twin = max(twin, spread * reach)
    assert pose_sigma(x, normals, noise, ess_fraction=f) == pytest.approx(twin, rel=0.03)


def test_scales_with_the_noise_and_the_effective_points():
    x, normals = _ellipsoid_patch(np.random.default_rng(6))
    s = pose_sigma(x, normals, 0.001, ess_fraction=1.0)
    assert np.isfinite(s)
    assert s > 0
    assert pose_sigma(x, normals, 0.003, ess_fraction=1.0) == pytest.approx(3 * s)
    assert pose_sigma(x, normals, 0.001, ess_fraction=0.25) == pytest.approx(2 * s)


def test_a_plane_is_unbounded_until_its_free_motions_are_left_out():
    rng = np.random.default_rng(7)
    uv = rng.uniform(-1.0, 1.0, size=(60, 2))
    x = np.column_stack([uv, np.zeros(60)])
    up = np.tile([0.0, 0.0, 1.0], (60, 1))
    assert pose_freedom(x, up).free == 3
    assert pose_sigma(x, up, 0.001) == np.inf
    # the normal slide and the two tilts are fixed: a finite spread, at most about the
    # noise over the square root of the points times the reach of a tilt
    left = pose_sigma(x, up, 0.001, ess_fraction=1.0, leave_out=3)
    assert 0.001 / np.sqrt(60) < left < 0.001


def test_pose_freedom_reports_sigma_in_its_dict():
    x, normals = _ellipsoid_patch(np.random.default_rng(8))
    f = pose_freedom(x, normals)
    assert f.to_dict()["sigma"] is None  # not computed: NaN
    g = dataclasses.replace(f, sigma=0.004)
    assert isinstance(g, PoseFreedom)
    assert g.to_dict()["sigma"] == pytest.approx(0.004)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise": 0.0}, "noise"),
        ({"noise": float("nan")}, "noise"),
        ({"noise": -1.0}, "noise"),
        ({"ess_fraction": 0.0}, "ess_fraction"),
        ({"ess_fraction": 1.5}, "ess_fraction"),
        ({"leave_out": -1}, "leave_out"),
        ({"leave_out": 6}, "leave_out"),
        ({"leave_out": 1.5}, "leave_out"),
        ({"normals": np.ones((7, 3))}, "normals"),
        ({"normals": np.zeros((8, 3))}, "zero rows"),
        ({"points": np.zeros((8, 3))}, "coincide"),
        ({"points": np.zeros((5, 3)), "normals": np.ones((5, 3))}, "points"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {"points": np.eye(8, 3) + np.arange(8)[:, None], "normals": np.ones((8, 3))}
    args["noise"] = 0.001
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        pose_sigma(**args)
