"""A model's near-symmetries (meshrec.model.symmetry) and the starts they give before a
pose is named (meshrec.recognition.weak.near_symmetry_scan, exploration_starts).

The shape is a "can": a cylinder of radius 1 and height 2 whose side is rippled by a few
waves of 0.2% of its radius, so that a turn about its axis or a half-turn upside down
carries it nearly, not exactly, onto itself, as a scanned can's label relief and dents
do; a touch fits it well only at its true place.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec.model.symmetry import near_symmetries, turn_about
from meshrec.recognition.freedom import pose_freedom, with_alternatives
from meshrec.recognition.joint import joint_poses
from meshrec.recognition.weak import exploration_starts, near_symmetry_scan

#: (waves round the axis, half-waves along it, phase) of each ripple, amplitude 0.002.
RIPPLES = ((3, 2, 0.4), (5, 3, 1.9), (7, 5, 4.1), (4, 7, 2.8), (9, 4, 5.5), (6, 6, 0.9))


def _can(hole: bool = False) -> trimesh.Trimesh:
    """The rippled can (see the module docstring): a 192 x 64 grid on its side, its caps
    fanned, 24,960 faces; ``hole``: with a round hole of radius 0.3 cut in its side at
    angle pi, height -0.5."""
    nt, nz = 192, 64
    th, z = np.meshgrid(np.linspace(0, 2 * np.pi, nt, endpoint=False), np.linspace(-1, 1, nz))
    r = np.ones_like(th)
    for m, n, phase in RIPPLES:
        r += 0.002 * np.sin(m * th + n * np.pi * z / 2 + phase)
    V = np.c_[(r * np.cos(th)).ravel(), (r * np.sin(th)).ravel(), z.ravel()]
    i, j = np.meshgrid(np.arange(nz - 1), np.arange(nt), indexing="ij")
    a, b = i * nt + j, i * nt + (j + 1) % nt
    c, d = a + nt, b + nt
    F = [np.c_[a.ravel(), b.ravel(), d.ravel()], np.c_[a.ravel(), d.ravel(), c.ravel()]]
    bottom, top = len(V), len(V) + 1
    V = np.vstack([V, [0, 0, -1], [0, 0, 1]])
    ring = np.arange(nt)
    F.append(np.c_[np.full(nt, bottom), (ring + 1) % nt, ring])
    F.append(np.c_[np.full(nt, top), (nz - 1) * nt + ring, (nz - 1) * nt + (ring + 1) % nt])
    out = trimesh.Trimesh(V, np.vstack(F), process=False)
    if hole:
        c = out.triangles_center
        far = np.hypot(np.angle(np.exp(1j * (np.arctan2(c[:, 1], c[:, 0]) - np.pi))), c[:, 2] + 0.5)
        out = out.submesh([np.flatnonzero(~((far < 0.3) & (np.hypot(c[:, 0], c[:, 1]) > 0.9)))])[0]
    return out


@pytest.fixture(scope="module")
def can_model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("can")
    _can().export(folder / "can.stl")
    cache = tmp_path_factory.mktemp("cache")
    return meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)["can"]


def test_a_rippled_can_has_its_axis_and_its_upside_down_turns(can_model):
    found = can_model.near_symmetries
    assert len(found.axes) == 1
    axis, through = found.axes[0]
    assert abs(axis[2]) > np.cos(np.radians(1.0))
    # the axis passes within 1% of the radius of the can's axis
    assert np.hypot(*(through - axis * through[2] / axis[2])[:2]) < 0.01
    # one half-turn about a horizontal axis (upside down): the other follows from it by a
    # turn about the can's axis, and the one about the can's axis is on that turn
    assert len(found.half_turns) == 1
    assert found.half_turns[0][2, 2] == pytest.approx(-1.0, abs=1e-2)


def test_an_exact_cylinder_and_an_asymmetric_part_have_no_near_symmetry(tmp_path):
    folder = tmp_path / "m"
    folder.mkdir()
    trimesh.creation.cylinder(radius=1.0, height=2.0, sections=64).export(folder / "cyl.stl")
    # an L of two boxes: no turn carries it near itself
    ell = trimesh.util.concatenate(
        [
            trimesh.creation.box((2.0, 0.4, 0.4)),
            trimesh.creation.box(
                (0.4, 1.2, 0.4), trimesh.transformations.translation_matrix((-0.8, 0.8, 0))
            ),
        ]
    )
    ell.export(folder / "ell.stl")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    for name in ("cyl", "ell"):
        found = library[name].near_symmetries
        assert found.half_turns == (), name
        assert found.axes == (), name


def test_the_axis_is_fitted_where_a_hole_tilts_the_principal_axes(tmp_path):
    # A hole in the side moves the area's centroid and tilts its principal axes off the
    # can's; the fitted axis is the can's.
    folder = tmp_path / "m"
    folder.mkdir()
    _can(hole=True).export(folder / "holed.stl")
    model = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")["holed"]
    V, F = model.mesh.vertices, model.mesh.faces
    c = V[F].mean(axis=1)
    assert abs(c.mean(axis=0)[0]) > 0.005  # the hole moved the centroid (unweighted check)
    axis, through = model.near_symmetries.axes[0]
    # (the principal axis leans 2.7 degrees and passes 0.015 off the can's)
    assert abs(axis[2]) > np.cos(np.radians(1.0))
    assert np.hypot(*(through - axis * through[2] / axis[2])[:2]) < 0.01


def test_a_box_with_one_corner_chamfered_has_its_half_turns(tmp_path):
    # A black-box probe (stop 35): one touch near a plain corner of a 60 x 40 x 30 box with
    # one corner chamfered, exported with 10 vertices, gave the pose `fixed` and 28 mm off,
    # the true pose (a half-turn of the box away) fitting as well. The chamfer leans the
    # principal axes 12 degrees off the box's; the box's own axes give the half-turns.
    m3d = pytest.importorskip("manifold3d")
    n = -np.ones(3) / np.sqrt(3.0)
    box = m3d.Manifold.cube([60.0, 40.0, 30.0], True)
    cut = box.trim_by_plane(n.tolist(), float(n @ np.array([30.0, 20.0, 15.0]) + 6.0))
    mesh = cut.to_mesh()
    folder = tmp_path / "m"
    folder.mkdir()
    trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts)).export(
        folder / "box_chamfer.stl"
    )
    model = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")["box_chamfer"]
    found = model.near_symmetries
    assert len(found.half_turns) == 3
    for S in found.half_turns:
        # a half-turn about one of the box's axes, through its centre
        assert np.allclose(np.abs(np.diag(S[:3, :3])), 1.0, atol=1e-2)
        assert np.trace(S[:3, :3]) == pytest.approx(-1.0, abs=1e-2)
        assert np.abs(S[:3, 3]).max() < 0.5
    assert found.axes == ()


def test_near_symmetries_bad_input_raises(can_model):
    with pytest.raises(ValueError, match="exact_tolerance"):
        near_symmetries(can_model.mesh, can_model.surface, -1.0)
    with pytest.raises(ValueError, match="exact_tolerance"):
        near_symmetries(can_model.mesh, can_model.surface, float("nan"))
    with pytest.raises(ValueError, match="fraction"):
        near_symmetries(can_model.mesh, can_model.surface, 0.0, fraction=1.5)


@pytest.mark.parametrize(("wrong_deg", "flip"), [(90.0, False), (-75.0, True), (40.0, True)])
def test_the_true_pose_is_reached_from_a_turn_or_a_flip_away(can_model, wrong_deg, flip):
    # A touch of the can's side, whose search ended a turn about the axis (and upside
    # down) from the truth (the touch frame is the model's: the identity). The starts,
    # refined, reach the true pose. The weak motions' fixed angles alone
    # (weak_motion_starts, stop 34's starts) reached it from none of these three poses.
    near = np.array([[np.cos(2.3), np.sin(2.3), 0.35]])
    contact = can_model.surface.closest_points(near)[1][0]
    sim = meshrec.simulate_touch(
        can_model, contact=contact, rng=5, noise=0.0005, length=0.5, transform=False
    )
    touch = sim.touch
    wrong = turn_about(np.radians(wrong_deg), np.array([0.0, 0.0, 1.0]), np.zeros(3))
    if flip:
        wrong = turn_about(np.pi, np.array([1.0, 0.0, 0.0]), np.zeros(3)) @ wrong
    starts = exploration_starts(can_model, touch.points, wrong)
    geometry = meshrec.estimate_local_geometry(touch.curves)
    found = joint_poses(can_model, [touch], starts, geometry, best=len(starts), start_ratio=np.inf)
    best = found[0].T_model_touch
    error = np.linalg.norm(touch.points @ best[:3, :3].T + best[:3, 3] - touch.points, axis=1)
    assert error.max() < 0.02


def test_near_symmetry_scan_gives_nothing_without_an_axis(tmp_path):
    folder = tmp_path / "m"
    folder.mkdir()
    trimesh.creation.box((2.0, 1.0, 0.5)).export(folder / "box.stl")
    model = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")["box"]
    pts = np.c_[np.linspace(-0.5, 0.5, 10), np.zeros(10), np.full(10, 0.25)]
    assert near_symmetry_scan(model, pts, np.eye(4)) == []


def test_near_symmetry_scan_bad_input_raises(can_model):
    pts = np.c_[np.linspace(-0.2, 0.2, 10), np.ones(10), np.zeros(10)]
    with pytest.raises(ValueError, match="keep"):
        near_symmetry_scan(can_model, pts, np.eye(4), keep=0)
    with pytest.raises(TypeError, match="keep"):
        near_symmetry_scan(can_model, pts, np.eye(4), keep=1.5)
    with pytest.raises(ValueError, match="T_model_touch"):
        near_symmetry_scan(can_model, pts, np.eye(3))
    with pytest.raises(ValueError, match="points"):
        near_symmetry_scan(can_model, pts[:3], np.eye(4))
    with pytest.raises(ValueError, match="T_model_touch"):
        exploration_starts(can_model, pts, np.full((4, 4), np.nan))


def _fixed_freedom():
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(20, 3))
    return pose_freedom(
        rng.normal(size=(20, 3)), normals / np.linalg.norm(normals, axis=1)[:, None]
    )


def _flat_freedom():
    pts = np.c_[np.linspace(-1, 1, 20), np.linspace(0, 0.5, 20) ** 2, np.zeros(20)]
    normals = np.tile([0.0, 0.0, 1.0], (20, 1))
    return pose_freedom(pts, normals)


def test_poses_a_near_symmetry_apart_are_two_answers_not_one():
    # Two poses whose relative motion moves the model within the tolerance (a near-
    # symmetry) but the data by far more than `within`: distinct. The same two poses with
    # `within` above the data's displacement: one.
    T0 = np.eye(4)
    T1 = turn_about(np.pi, np.array([1.0, 0.0, 0.0]), np.zeros(3))
    vertices = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    points = np.array([[0.0, 1.0, 0.5], [0.0, 1.0, 0.7]])
    on_itself = lambda p: np.zeros(len(p))  # noqa: E731 - every motion is a "symmetry"
    f = with_alternatives(_flat_freedom(), [T0, T1], [0.5, 0.5], vertices, on_itself, 1e-6)
    assert f.alternatives == 0  # the symmetry test alone merges them
    assert f.twin_apart == 0.0  # (no points given)
    f = with_alternatives(
        _fixed_freedom(), [T0, T1], [0.5, 0.5], vertices, on_itself, 1e-6, points=points, within=0.1
    )
    assert f.alternatives == 0
    # the half-turn about x moves (0, 1, z) to (0, -1, -z): 2.2 and 2.44 apart
    assert f.twin_apart == pytest.approx(np.hypot(2.0, 1.4))
    assert f.fixed
    assert "near-symmetry" in f.description
    assert f.to_dict()["twin_apart"] == pytest.approx(np.hypot(2.0, 1.4))
    never = lambda p: np.ones(len(p))  # noqa: E731 - no motion is a symmetry
    f = with_alternatives(
        _flat_freedom(), [T0, T1], [0.5, 0.5], vertices, never, 1e-6, points=points, within=0.1
    )
    assert f.alternatives == 1
    f = with_alternatives(
        _flat_freedom(), [T0, T1], [0.5, 0.5], vertices, never, 1e-6, points=points, within=3.0
    )
    assert f.alternatives == 0


@pytest.mark.parametrize(
    ("points", "within", "match"),
    [
        (np.zeros((2, 2)), 0.1, "points"),
        (np.full((2, 3), np.nan), 0.1, "points"),
        (np.zeros((2, 3)), -1.0, "within"),
        (np.zeros((2, 3)), float("inf"), "within"),
    ],
)
def test_with_alternatives_bad_points_or_within_raises(points, within, match):
    with pytest.raises(ValueError, match=match):
        with_alternatives(
            _flat_freedom(),
            [np.eye(4)],
            [1.0],
            np.zeros((1, 3)),
            lambda p: np.zeros(len(p)),
            1e-6,
            points=points,
            within=within,
        )
