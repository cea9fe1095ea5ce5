"""Tests for meshrec.registration.chart: surface charts and the frame helpers.

Charts are checked on a finely meshed sphere and cylinder, whose closest points and normals
are known in closed form: the chart point q(u, v) is the closest point of the mesh to
q0 + u d1 + v d2, so on a sphere about the origin it is that point scaled onto the sphere,
on a z-axis cylinder that point moved radially onto the cylinder, up to the chord error of
the flat faces.
"""

import types

import numpy as np
import pytest
import trimesh
from analytic_meshes import deepest_chord, index_of, sphere, steepest_tilt, tube
from scipy.spatial.transform import Rotation

from meshrec.registration.chart import SurfaceChart, SurfacePoint, rotation_z, tangent_frame

RADIUS = 1.5


def _angles(a, b):
    """Angles (rad) between the rows of two (n, 3) arrays of unit vectors."""
    return np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))


def _radial(points, axis=False):
    p = np.array(points, dtype=np.float64, ndmin=2)
    if axis:
        p[:, 2] = 0.0
    return p / np.linalg.norm(p, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    mesh = sphere(RADIUS, subdivisions=5)
    ns = types.SimpleNamespace(
        model=index_of(mesh, tmp_path_factory.mktemp("ball"), "ball"),
        mesh=mesh,
        chord=deepest_chord(mesh, radius=RADIUS),
        tilt=steepest_tilt(mesh),
    )
    # The interpolated normal blends the vertex normals, each this far from the analytic
    # normal at its vertex (libigl's weighting at the icosphere's valence-5 vertices: 3e-3).
    ns.normal_tol = (
        1e-4 + _angles(ns.model.mesh.vertex_normals, _radial(ns.model.mesh.vertices)).max()
    )
    return ns


@pytest.fixture(scope="module")
def can(tmp_path_factory):
    mesh = tube(RADIUS, height=4.0, sections=256, rings=64)
    ns = types.SimpleNamespace(
        model=index_of(mesh, tmp_path_factory.mktemp("can"), "can"),
        mesh=mesh,
        chord=deepest_chord(mesh, centre=None, radius=RADIUS),
        tilt=steepest_tilt(mesh, axis=True),
    )
    side = np.abs(ns.model.mesh.vertices[:, 2]) < 1.9  # the rims' normals lean over the ends
    ns.normal_tol = (
        1e-4
        + _angles(
            ns.model.mesh.vertex_normals[side], _radial(ns.model.mesh.vertices[side], axis=True)
        ).max()
    )
    return ns


def _closest_on_mesh(model, x):
    """Brute-force twin of the AABB query: trimesh's closest point on every face, the nearest."""
    triangles = model.mesh.vertices[model.mesh.faces]
    on_faces = trimesh.triangles.closest_point(triangles, np.tile(x, (len(triangles), 1)))
    return on_faces[np.argmin(np.linalg.norm(on_faces - x, axis=1))]


def _check_frame(frame, normal, tol):
    np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-12)
    assert np.linalg.det(frame) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(np.cross(frame[:, 0], frame[:, 1]), frame[:, 2], atol=1e-12)
    assert _angles(frame[None, :, 2], normal)[0] < tol


def _origin(point, normal, hint):
    return SurfacePoint(point=point, frame=tangent_frame(normal, hint=hint))


def test_sphere_chart_points_are_the_radial_projections(ball):
    model, chord, tilt = ball.model, ball.chord, ball.tilt
    # The bounds are those of a fine mesh, not vacuous ones.
    assert 0.0 < chord < 5e-4
    assert 0.0 < tilt < 0.03
    assert ball.normal_tol < 5e-3
    rng = np.random.default_rng(11)
    for _ in range(5):
        n0 = rng.normal(size=3)
        n0 /= np.linalg.norm(n0)
        chart = SurfaceChart(model, _origin(RADIUS * n0, n0, rng.normal(size=3)))
        d1, d2, _ = chart.origin.frame.T
        for u, v in rng.uniform(-0.4, 0.4, size=(8, 2)):
            sp = chart.at(u, v)
            x = chart.origin.point + u * d1 + v * d2
            expected = RADIUS * x / np.linalg.norm(x)
            # On the faces: between the chord depth inside the sphere and the sphere itself
            # (float32 vertices in the STL file).
            r = np.linalg.norm(sp.point)
            assert RADIUS - chord - 1e-9 <= r <= RADIUS + 1e-6
            height = np.linalg.norm(x) - RADIUS + chord
            assert np.linalg.norm(sp.point - expected) <= chord + height * tilt
            np.testing.assert_allclose(sp.point, _closest_on_mesh(model, x), atol=1e-9)
            _check_frame(sp.frame, _radial(sp.point), ball.normal_tol)


def test_cylinder_chart_points_move_radially_onto_the_side(can):
    model, chord, tilt = can.model, can.chord, can.tilt
    assert 0.0 < chord < 2e-4
    assert 0.0 < tilt < 0.02
    assert can.normal_tol < 1e-3
    rng = np.random.default_rng(12)
    for _ in range(5):
        t = rng.uniform(0, 2 * np.pi)
        n0 = np.array([np.cos(t), np.sin(t), 0.0])
        q0 = RADIUS * n0 + [0.0, 0.0, rng.uniform(-0.5, 0.5)]
        chart = SurfaceChart(model, _origin(q0, n0, rng.normal(size=3)))
        d1, d2, _ = chart.origin.frame.T
        for u, v in rng.uniform(-0.5, 0.5, size=(8, 2)):
            sp = chart.at(u, v)
            x = q0 + u * d1 + v * d2
            radial = np.array([x[0], x[1], 0.0]) / np.hypot(x[0], x[1])
            expected = RADIUS * radial + [0.0, 0.0, x[2]]
            assert RADIUS - chord - 1e-9 <= np.hypot(*sp.point[:2]) <= RADIUS + 1e-6
            height = np.hypot(x[0], x[1]) - RADIUS + chord
            assert np.linalg.norm(sp.point - expected) <= chord + height * tilt
            np.testing.assert_allclose(sp.point, _closest_on_mesh(model, x), atol=1e-9)
            _check_frame(sp.frame, _radial(sp.point, axis=True), can.normal_tol)


def test_chart_centre_is_the_origin_and_the_frame_is_transported(ball):
    model, chord = ball.model, ball.chord
    n0 = np.array([0.3, -0.5, 0.8])
    n0 /= np.linalg.norm(n0)
    hint = np.array([1.0, 0.0, 0.0])
    chart = SurfaceChart(model, _origin(RADIUS * n0, n0, hint))
    centre = chart.at(0.0, 0.0)
    assert np.linalg.norm(centre.point - RADIUS * n0) <= chord + 1e-6
    np.testing.assert_allclose(centre.frame, chart.origin.frame, atol=ball.normal_tol)
    # Away from the centre, d1 is the old d1 projected onto the new tangent plane.
    d1 = chart.origin.frame[:, 0]
    moved = chart.at(0.3, -0.2)
    n = moved.normal
    projected = (d1 - (d1 @ n) * n) / np.linalg.norm(d1 - (d1 @ n) * n)
    np.testing.assert_allclose(moved.frame[:, 0], projected, atol=1e-12)
    np.testing.assert_allclose(moved.normal, moved.frame[:, 2])


def test_chart_keeps_the_side_it_started_on(ball):
    model = ball.model
    n0 = np.array([0.0, 0.0, 1.0])
    # A chart started with the inward normal: its points keep the inward normal.
    chart = SurfaceChart(model, _origin(RADIUS * n0, -n0, None))
    sp = chart.at(0.2, 0.1)
    assert sp.normal @ (sp.point / np.linalg.norm(sp.point)) < -0.99


@pytest.mark.parametrize("inward", [False, True])
def test_chart_points_in_one_query_are_those_one_at_a_time(ball, can, inward):
    """at_many's twin is at(): the same bits, on both sides (the fold test included)."""
    rng = np.random.default_rng(13)
    for ns in (ball, can):
        for _ in range(4):
            n0 = rng.normal(size=3)
            n0[2] = n0[2] if ns is ball else 0.0
            n0 /= np.linalg.norm(n0)
            chart = SurfaceChart(ns.model, _origin(RADIUS * n0, -n0 if inward else n0, None))
            uv = rng.uniform(-0.4, 0.4, size=(5, 2))
            for (u, v), sp in zip(uv, chart.at_many(uv), strict=True):
                one = chart.at(u, v)
                assert np.array_equal(sp.point, one.point)
                assert np.array_equal(sp.frame, one.frame)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.zeros(2), r"uv must have shape \(k, 2\)"),
        (np.zeros((2, 3)), r"uv must have shape \(k, 2\)"),
        (np.array([[0.1, np.nan]]), "points must be finite"),
    ],
)
def test_chart_points_in_one_query_refuse_bad_coordinates(ball, bad, message):
    chart = SurfaceChart(ball.model, _origin(np.array([0.0, 0.0, RADIUS]), np.eye(3)[2], None))
    with pytest.raises(ValueError, match=message):
        chart.at_many(bad)


def test_tangent_frame_respects_its_hint():
    rng = np.random.default_rng(1)
    for _ in range(20):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        hint = rng.normal(size=3)
        F = tangent_frame(n, hint=hint)
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
        assert np.linalg.det(F) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(F[:, 2], n, atol=1e-15)
        # d1 is the hint's tangential part, same direction: d2 has none of the hint.
        assert F[:, 0] @ hint > 0
        assert abs(F[:, 1] @ hint) < 1e-12
    # A normal given unnormalised is normalised.
    np.testing.assert_allclose(tangent_frame(np.array([0.0, 0.0, 5.0]))[:, 2], [0, 0, 1])


@pytest.mark.parametrize("hint", [None, np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, -1e-3])])
def test_tangent_frame_without_a_usable_hint_uses_a_world_axis(hint):
    n = np.array([0.0, 0.0, 1.0])
    F = tangent_frame(n, hint=hint)
    np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(F[:, 2], n)
    assert np.linalg.det(F) == pytest.approx(1.0)
    # The axis least aligned with n is x (the first of the ties), whose projection is x.
    np.testing.assert_allclose(F[:, 0], [1.0, 0.0, 0.0], atol=1e-15)


def test_rotation_z_matches_scipy():
    rng = np.random.default_rng(3)
    phis = rng.uniform(-7.0, 7.0, size=12)
    R = rotation_z(phis)
    assert R.shape == (12, 3, 3)
    for p, r in zip(phis, R, strict=True):
        np.testing.assert_allclose(r, Rotation.from_rotvec([0.0, 0.0, p]).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(rotation_z(p), r, atol=0)
    assert rotation_z(0.4).shape == (3, 3)
