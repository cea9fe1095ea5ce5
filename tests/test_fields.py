"""The phi grid from height-fields: its estimates against the closed form on a sphere, its
judgement of where a field holds (edges, rims, ball tips), and its exact rows against the
phi grid by bounds (the brute-force path)."""

import numpy as np
import pytest
import trimesh
from analytic_meshes import index_of, sphere, tube

from meshrec import defaults
from meshrec.model.probe import probe_model
from meshrec.registration.bounded import bounded_grid_errors
from meshrec.registration.chart import SurfacePoint, rotation_z, tangent_frame
from meshrec.registration.fields import candidate_fields, field_grid_errors

STEPS = defaults.PHI_STEPS


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return index_of(sphere(1.0, 5), tmp_path_factory.mktemp("ball"), "ball")


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    mesh = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    mesh = mesh.subdivide_to_size(0.05)
    return index_of(mesh, tmp_path_factory.mktemp("box"), "box")


@pytest.fixture(scope="module")
def pipe(tmp_path_factory):
    return index_of(tube(1.0, 4.0), tmp_path_factory.mktemp("pipe"), "pipe")


def _origin(point, normal):
    point = np.asarray(point, dtype=np.float64)
    return SurfacePoint(point=point, frame=tangent_frame(np.asarray(normal, dtype=np.float64)))


def _sphere_data(rng, n=36, reach=0.3, noise=1e-3):
    """Points on the unit sphere within ``reach`` of its north pole, in the pole's frame
    (z along the outward normal, origin at the pole), with noise along the radius."""
    a = rng.uniform(0, 2 * np.pi, n)
    t = reach * np.sqrt(rng.uniform(0.05, 1, n))
    dirs = np.column_stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
    pts = dirs * (1.0 + rng.uniform(-noise, noise, n))[:, None]
    return pts - [0.0, 0.0, 1.0]


def test_sphere_estimates_match_the_closed_form(ball):
    rng = np.random.default_rng(0)
    local = _sphere_data(rng)
    # A tilted copy of the data: off the surface at every angle but one band.
    tilt = np.array([[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]])
    wrong = local @ tilt.T
    v = rng.normal(size=(6, 3))
    normals = v / np.linalg.norm(v, axis=1, keepdims=True)
    origins = [_origin(n, n) for n in normals]
    for data in (local, wrong):
        grid = field_grid_errors(
            ball,
            origins,
            [data] * len(origins),
            STEPS,
            prune_ratio=3.0,
            refine_ratio=1.0,
            ranked=None,
        )
        # Every field holds on the sphere; each row's least sample is computed exactly
        # (its low minima and their neighbours), the others are estimates.
        assert grid.estimated.all()
        assert grid.settled.all()
        assert grid.exact[np.arange(len(origins)), grid.errors.argmin(axis=1)].all()
        assert not grid.exact.all()
        for o, row in zip(origins, grid.errors, strict=True):
            placed = (
                np.einsum(
                    "ij,sjk,nk->sni",
                    o.frame,
                    rotation_z(np.arange(STEPS) * 2 * np.pi / STEPS),
                    data,
                )
                + o.point
            )
            truth = np.abs(np.linalg.norm(placed, axis=2) - 1.0).mean(axis=1)
            # The tangent-plane distance to the fitted graph: within 3% of the sphere's
            # (its error grows with the gap times the curvature) plus the facets' sag.
            assert np.all(np.abs(row - truth) <= 0.03 * truth + 2e-4)


def test_fields_hold_on_smooth_parts_only(box, pipe, ball):
    # The box: one candidate at a face's centre, one beside an edge (crease sites near).
    fields = candidate_fields(
        box, [_origin([0, 0, 1], [0, 0, 1]), _origin([0.9, 0, 1], [0, 0, 1])], 0.3
    )
    assert fields.reliable.tolist() == [True, False]
    # The open tube: mid-height holds, the rim does not (its neighbours lie to one side).
    fields = candidate_fields(
        pipe, [_origin([1, 0, 0], [1, 0, 0]), _origin([1, 0, 2.0], [1, 0, 0])], 0.3
    )
    assert fields.reliable.tolist() == [True, False]
    assert fields.residual[0] < 1e-4
    # Through a ball-tipped probe the distances are to the offset surface: never a field.
    probed = probe_model(ball, 0.05)
    fields = candidate_fields(probed, [_origin([0, 0, 1], [0, 0, 1])], 0.3)
    assert not fields.reliable.any()
    # A reach beyond the cap within 60 degrees of the normal (the sites the fit uses):
    # they do not cover it.
    fields = candidate_fields(ball, [_origin([0, 0, 1], [0, 0, 1])], 1.5)
    assert not fields.reliable.any()


def test_wrinkles_finer_than_the_reach_fail_the_residual_test(ball, tmp_path):
    mesh = sphere(1.0, 5)
    v = mesh.vertices
    mesh.vertices = v * (1.0 + 0.02 * np.sin(25.0 * v[:, [0]]) * np.sin(25.0 * v[:, [1]]))
    wrinkled = index_of(mesh, tmp_path, "wrinkled")
    o = [_origin([0, 0, 1], [0, 0, 1])]
    smooth, rough = candidate_fields(ball, o, 0.3), candidate_fields(wrinkled, o, 0.3)
    assert smooth.reliable.all()
    assert smooth.residual[0] < 1e-3 * smooth.radius
    assert not rough.reliable.any()
    assert rough.residual[0] > defaults.FIELD_MAX_RESIDUAL * rough.radius


def test_rows_without_a_field_are_the_bounded_grids(box):
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.25, 0.25, (36, 2))
    local = np.column_stack([xy, rng.uniform(-1e-3, 1e-3, 36)])
    origins = [
        _origin([0, 0, 1], [0, 0, 1]),
        _origin([0.9, 0, 1], [0, 0, 1]),
        _origin([0, 0.95, 1], [0, 0, 1]),
    ]
    data = [local] * 3
    got = field_grid_errors(
        box, origins, data, STEPS, prune_ratio=3.0, refine_ratio=1.0, ranked=None
    )
    want = bounded_grid_errors(box, origins[1:], data[1:], STEPS, prune_ratio=3.0, refine_ratio=1.0)
    assert np.array_equal(got.errors[1:], want.errors)
    assert np.array_equal(got.exact[1:], want.exact)
    assert got.estimated.tolist() == [True, False, False]
    # On the flat face the field is the plane: the estimate is the data's mean |z| at
    # every angle, so every sample is a minimum and is computed exactly: the same value.
    assert got.exact[0].all()
    assert np.allclose(got.errors[0], np.abs(local[:, 2]).mean(), rtol=0, atol=1e-9)


def test_bad_arguments_raise(ball):
    o = _origin([0, 0, 1], [0, 0, 1])
    data = np.tile([0.1, 0.0, 0.0], (4, 1))
    kw = {"prune_ratio": 3.0, "refine_ratio": 1.0, "ranked": None}
    with pytest.raises(ValueError, match="origins must hold at least one candidate, got none"):
        field_grid_errors(ball, [], [], STEPS, **kw)
    with pytest.raises(ValueError, match="local_points must hold 1 arrays, got 2"):
        field_grid_errors(ball, [o], [data, data], STEPS, **kw)
    with pytest.raises(
        ValueError, match=r"local_points must be \(n, 3\) arrays, got shape \(4, 2\)"
    ):
        field_grid_errors(ball, [o], [data[:, :2]], STEPS, **kw)
    with pytest.raises(TypeError, match="model must be a ModelIndex, got str"):
        field_grid_errors("ball", [o], [data], STEPS, **kw)
    with pytest.raises(ValueError, match="origins must hold at least one candidate, got none"):
        candidate_fields(ball, [], 0.3)
    with pytest.raises(ValueError, match=r"reach must be > 0, got 0\.0"):
        candidate_fields(ball, [o], 0.0)
    with pytest.raises(TypeError, match="model must be a ModelIndex, got str"):
        candidate_fields("ball", [o], 0.3)
