"""Pose freedom: the rigid motions a touch leaves free (meshrec.recognition.freedom).

The expected answers are known independently: a plane leaves two slides and a turn about
its normal, a circular cylinder a slide along and a turn about its axis, a sphere three
turns about its centre, an ellipsoid none.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.recognition.freedom import pose_freedom, with_symmetries


def _disc(rng, n=60):
    """Points of a small patch around the origin: parameters (u, v) in [-1, 1]^2."""
    return rng.uniform(-1.0, 1.0, size=(n, 2))


def test_plane_leaves_two_slides_and_a_turn_about_its_normal():
    rng = np.random.default_rng(0)
    uv = _disc(rng)
    x = np.column_stack([uv[:, 0] + 3.0, uv[:, 1] - 1.0, np.full(len(uv), 2.0)])
    f = pose_freedom(x, np.tile([0.0, 0.0, 1.0], (len(x), 1)))
    assert (f.free, f.slides, f.turns) == (3, 2, 1)
    assert f.names == ("slide", "slide", "turn")
    assert np.allclose(np.abs(f.slide_directions[:, 2]), 0.0, atol=1e-9)  # in the plane
    assert np.allclose(np.abs(f.turn_axes[0]), [0, 0, 1], atol=1e-9)  # about the normal
    assert f.description == "free: 2 slides and 1 turn"


def test_cylinder_leaves_a_slide_along_and_a_turn_about_its_axis():
    rng = np.random.default_rng(1)
    uv = _disc(rng)
    theta, z = 0.3 * uv[:, 0], 0.5 * uv[:, 1]
    n = np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
    axis_point = np.array([1.0, -2.0, 0.0])
    x = axis_point + 2.0 * n + np.column_stack([0 * z, 0 * z, z])
    f = pose_freedom(x, n)
    assert (f.free, f.slides, f.turns) == (2, 1, 1)
    assert np.allclose(np.abs(f.slide_directions[0]), [0, 0, 1], atol=1e-9)
    assert np.allclose(np.abs(f.turn_axes[0]), [0, 0, 1], atol=1e-9)
    assert np.allclose(f.turn_points[0][:2], axis_point[:2], atol=1e-9)  # on the axis


def test_sphere_leaves_three_turns_about_its_centre():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(60, 3))
    v[:, 2] = -np.abs(v[:, 2]) - 3.0  # a cap around the south pole
    v /= np.linalg.norm(v, axis=1)[:, None]
    centre = np.array([0.5, 0.0, 3.0])
    f = pose_freedom(centre + 1.5 * v, v)
    assert (f.free, f.slides, f.turns) == (3, 0, 3)
    # Every turn's axis passes through the centre.
    for a, p in zip(f.turn_axes, f.turn_points, strict=True):
        assert np.linalg.norm(np.cross(centre - p, a)) < 1e-9


def test_ellipsoid_patch_leaves_nothing_free():
    rng = np.random.default_rng(3)
    a = np.array([1.0, 0.8, 0.5])
    uv = 0.4 * _disc(rng)
    # The patch around (0, 0, -c): z from the implicit equation, normal its gradient.
    x = np.column_stack([uv[:, 0], uv[:, 1], np.zeros(len(uv))])
    x[:, 2] = -a[2] * np.sqrt(1.0 - (x[:, 0] / a[0]) ** 2 - (x[:, 1] / a[1]) ** 2)
    f = pose_freedom(x, x / a**2)
    assert f.free == 0
    assert f.description == "fixed"
    assert f.singular_values[-1] > defaults.POSE_FREE_RATIO


@pytest.mark.parametrize(
    ("points", "normals", "ratio", "match"),
    [
        (np.zeros((5, 3)), np.ones((5, 3)), 1e-3, "points"),
        (np.zeros((8, 3)), np.ones((8, 3)), 1e-3, "coincide"),
        (np.eye(8, 3), np.ones((7, 3)), 1e-3, "normals"),
        (np.eye(8, 3), np.full((8, 3), np.nan), 1e-3, "normals"),
        (np.eye(8, 3), np.zeros((8, 3)), 1e-3, "zero rows"),
        (np.eye(8, 3), np.ones((8, 3)), 1.5, "ratio"),
        (np.eye(8, 3), np.ones((8, 3)), 0.0, "ratio"),
    ],
)
def test_bad_input_raises(points, normals, ratio, match):
    with pytest.raises(ValueError, match=match):
        pose_freedom(points, normals, ratio)


def test_bad_points_type_raises():
    with pytest.raises(TypeError):
        pose_freedom([["a", "b", "c"]] * 8, np.ones((8, 3)))


@pytest.fixture(scope="module")
def box_and_ellipsoid(tmp_path_factory):
    """A library of a box and an ellipsoid (unit-sized), both with vertices on every face
    (the curvature lookup needs them: a 12-triangle box has none but its corners)."""
    folder = tmp_path_factory.mktemp("freedom")
    box = trimesh.creation.box(extents=(1.0, 0.7, 0.5))
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.05)
    trimesh.Trimesh(v, f).export(folder / "box.stl")
    ellipsoid = trimesh.creation.icosphere(subdivisions=5)
    ellipsoid.apply_scale([0.6, 0.45, 0.3])
    ellipsoid.export(folder / "ellipsoid.stl")
    return folder


def test_touch_on_a_box_face_is_named_but_its_pose_is_ambiguous(box_and_ellipsoid):
    lib = meshrec.ModelLibrary.from_folder(box_and_ellipsoid)
    t = meshrec.simulate_touch(
        box_and_ellipsoid / "box.stl",
        contact=[0.1, 0.05, 0.25],
        rng=1,
        length=0.2,
        noise=0.0005,
    )
    rec = meshrec.recognize(t.touch, lib)
    assert rec.best.model == "box"
    assert (rec.pose_freedom.slides, rec.pose_freedom.turns) == (2, 1)
    assert rec.verdict == "ambiguous"
    assert rec.plausible == ("box",)
    # it said "only box fits the data", which a probe read as "nothing else fits" where
    # another model fitted 7% worse; the probability is over the library's models
    assert "of the library's models only box is plausible on the data" in rec.reason
    assert "2 slides and 1 turn" in rec.reason
    assert "the touch fixes its pose only up to" in rec.reason
    assert rec.pose_freedom.sigma == np.inf  # a free pose has no precision


def test_two_touches_on_one_box_face_leave_the_same_freedom(box_and_ellipsoid):
    # two touches of one face (one frame): still 2 slides and 1 turn, and the reason
    # speaks of the touches (it said "the touch" for any number)
    lib = meshrec.ModelLibrary.from_folder(box_and_ellipsoid)
    touches = [
        meshrec.simulate_touch(
            box_and_ellipsoid / "box.stl",
            contact=c,
            rng=k,
            length=0.2,
            noise=0.0005,
            transform=False,
        ).touch
        for k, c in enumerate(([0.1, 0.05, 0.25], [-0.25, -0.1, 0.25]))
    ]
    rec = meshrec.recognize(touches, lib)
    assert rec.best.model == "box"
    assert (rec.pose_freedom.slides, rec.pose_freedom.turns) == (2, 1)
    assert rec.verdict == "ambiguous"
    assert "the touches fix its pose only up to 2 slides and 1 turn" in rec.reason


def test_touch_on_an_ellipsoid_is_recognised_with_a_fixed_pose(box_and_ellipsoid):
    lib = meshrec.ModelLibrary.from_folder(box_and_ellipsoid)
    t = meshrec.simulate_touch(box_and_ellipsoid / "ellipsoid.stl", rng=2, noise=0.0005)
    rec = meshrec.recognize(t.touch, lib)
    assert rec.best.model == "ellipsoid"
    assert rec.pose_freedom.free == 0
    assert rec.verdict == "recognised"
    # how precisely: finite, and the pose found lies within a few sigma of the truth
    sigma = rec.pose_freedom.sigma
    assert 0.0 < sigma < 0.1
    found = t.touch.points @ rec.best.T_model_touch[:3, :3].T + rec.best.T_model_touch[:3, 3]
    true = t.touch.points @ t.T_model_touch[:3, :3].T + t.T_model_touch[:3, 3]
    # modulo the ellipsoid's symmetries (half-turns about its axes: it is centred and
    # axis-aligned), any of which the search may land on
    turns = [np.diag(d) for d in ([1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1])]
    error = min(np.linalg.norm(found @ S.T - true, axis=1).max() for S in turns)
    assert error < 4.0 * sigma


def _capped_cylinder_distance(radius, half_height):
    """Unsigned distance to the surface of a closed circular cylinder along z (analytic)."""

    def distance(p):
        r = np.hypot(p[:, 0], p[:, 1])
        dr, dz = r - radius, np.abs(p[:, 2]) - half_height
        outside = np.hypot(np.maximum(dr, 0), np.maximum(dz, 0))
        inside = np.minimum(np.maximum(dr, dz), 0)
        return np.abs(outside + inside)

    return distance


def _cylinder_vertices(radius, half_height, rng):
    """Points on the side and the caps of that cylinder."""
    t = rng.uniform(0, 2 * np.pi, 400)
    side = np.column_stack([radius * np.cos(t), radius * np.sin(t), rng.uniform(-1, 1, 400)])
    side[:, 2] *= half_height
    rr = radius * np.sqrt(rng.uniform(0, 1, 200))
    cap = np.column_stack([rr * np.cos(t[:200]), rr * np.sin(t[:200]), np.full(200, half_height)])
    return np.vstack([side, cap, cap * [1, 1, -1]])


def test_turn_about_a_cylinders_axis_is_a_symmetry_and_the_slide_along_it_is_not():
    rng = np.random.default_rng(4)
    theta, z = 0.3 * rng.uniform(-1, 1, 60), 0.5 * rng.uniform(-1, 1, 60)
    n = np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
    x = 2.0 * n + np.column_stack([0 * z, 0 * z, z])
    f = with_symmetries(
        pose_freedom(x, n),
        _cylinder_vertices(2.0, 3.0, rng),
        _capped_cylinder_distance(2.0, 3.0),
        1e-6,
    )
    assert f.slide_symmetric == (False,)
    assert f.turn_symmetric == (True,)
    assert f.unresolved == 1
    assert "1 of them a symmetry" in f.description
    # every free motion a symmetry (the slide pinned): the pose is fixed, and says so
    pinned = dataclasses.replace(
        f, free=1, slides=0, slide_symmetric=(), slide_directions=np.zeros((0, 3))
    )
    assert pinned.fixed
    assert pinned.description == "fixed up to the model's symmetry (1 turn)"


def test_turn_about_a_box_faces_normal_is_no_symmetry():
    rng = np.random.default_rng(5)
    x = np.column_stack([rng.uniform(-0.1, 0.1, (60, 2)), np.full(60, 0.5)])
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))

    def distance(p):  # to the surface of the unit cube (analytic)
        q = np.abs(p) - 0.5
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return np.abs(outside + np.minimum(q.max(axis=1), 0.0))

    f = with_symmetries(
        pose_freedom(x, np.tile([0.0, 0.0, 1.0], (60, 1))),
        trimesh.sample.sample_surface(box, 500, seed=0)[0],
        distance,
        1e-6,
    )
    assert f.slide_symmetric == (False, False)
    assert f.turn_symmetric == (False,)
    assert f.unresolved == 3


@pytest.mark.parametrize(
    ("vertices", "tolerance", "match"),
    [(np.zeros((0, 3)), 1e-3, "vertices"), (np.zeros((5, 3)), 0.0, "tolerance")],
)
def test_with_symmetries_bad_input_raises(vertices, tolerance, match):
    f = pose_freedom(np.eye(8, 3) + np.arange(8)[:, None], np.ones((8, 3)))
    with pytest.raises(ValueError, match=match):
        with_symmetries(f, vertices, lambda p: np.zeros(len(p)), tolerance)


def test_touch_on_a_cylinders_side_is_named_with_a_free_slide(tmp_path):
    """The bundled 80,000-face cylinder (mm): a side touch leaves the slide along the axis
    free (another touch can fix it) and the turn about it (a symmetry)."""
    folder = tmp_path / "lib"
    folder.mkdir()
    models = meshrec.bundled_models_dir("objects")
    (folder / "cylinder_1.stl").write_bytes((models / "cylinder_1.stl").read_bytes())
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    t = meshrec.simulate_touch(
        folder / "cylinder_1.stl", contact=[25.2, 0.0, 5.0], rng=3, length=20.0, noise=0.05
    )
    rec = meshrec.recognize(t.touch, lib)
    f = rec.pose_freedom
    assert rec.best.model == "cylinder_1"
    assert 1 <= f.free <= 2
    assert f.slides == 1
    assert abs(f.slide_directions[0][2]) > 0.99  # along the axis
    assert f.slide_symmetric == (False,)
    assert all(f.turn_symmetric)
    assert rec.verdict == "ambiguous"
    assert rec.plausible == ("cylinder_1",)


def test_touch_on_a_coarse_box_face_leaves_two_slides_and_a_turn(tmp_path):
    # A box exported as 12 triangles: every face touches the crease vertices at its corners,
    # so no point lies on a face away from them; the touch's points that reach an edge
    # within the noise must not pin the pose (their constraint is one-sided).
    box = trimesh.creation.box(extents=(2.0, 1.5, 1.0))
    folder = tmp_path / "models"
    folder.mkdir()
    box.export(folder / "box.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.04)
    fine = trimesh.Trimesh(v, f)
    found = []
    # contacts on the large face, one in its middle and two whose curves reach an edge
    for k, contact in enumerate(([0.1, 0.05, 0.5], [0.6, 0.0, 0.5], [0.0, 0.35, 0.5])):
        t = meshrec.simulate_touch(fine, contact=contact, rng=k, length=0.8, noise=1e-3)
        rec = meshrec.recognize(t.touch, lib)
        found.append((rec.pose_freedom.slides, rec.pose_freedom.turns))
        assert rec.verdict == "ambiguous"
    assert found == [(2, 1)] * 3


def test_flat_touch_decides_only_when_wider_than_the_other_flat_faces(tmp_path):
    # Three curves through one point on a 4 x 4 face, each `length` long: a star of radius
    # length / 2. A cylinder's cap of radius 1 holds the star of radius 0.4 (the touch
    # cannot tell the cap from the face: ambiguous, both plausible) but not the star of
    # radius 1.5, which hangs over the rim (the cylinder is rejected by its fit).
    folder = tmp_path / "models"
    folder.mkdir()
    box = trimesh.creation.box(extents=(4.0, 4.0, 1.0))
    box.export(folder / "box.stl")
    trimesh.creation.cylinder(radius=1.0, height=3.0, sections=32).export(folder / "cylinder.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.05)
    fine = trimesh.Trimesh(v, f)
    small = meshrec.simulate_touch(fine, contact=[0.1, -0.2, 0.5], rng=1, length=0.8)
    rec = meshrec.recognize(small.touch, lib)
    assert rec.verdict == "ambiguous"
    assert set(rec.plausible) == {"box", "cylinder"}
    wide = meshrec.simulate_touch(fine, contact=[0.1, -0.2, 0.5], rng=1, length=3.0)
    rec = meshrec.recognize(wide.touch, lib)
    assert rec.plausible == ("box",)
    rms = {s.model: s.rms for s in rec.scores}
    assert rms["cylinder"] > 50 * rms["box"]
