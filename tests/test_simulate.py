"""Tests of meshrec.sim.simulate: simulated touches cut from meshes."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.io.touch import TouchData
from meshrec.io.truth import Truth, read_truth
from meshrec.sim.simulate import SimulatedTouch, simulate_touch

RADIUS = 2.0


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=5, radius=RADIUS)


@pytest.fixture(scope="module")
def coarse_sphere():
    return trimesh.creation.icosphere(subdivisions=2, radius=1.0)


def _sphere_depth(mesh: trimesh.Trimesh) -> float:
    """How far inside the sphere the mesh reaches (deepest at face centroids)."""
    return RADIUS - float(np.linalg.norm(mesh.triangles_center, axis=1).min())


def _grid_patch(height, n: int = 41, half: float = 1.0) -> trimesh.Trimesh:
    """An open patch z = height(x, y) over [-half, half]^2, faces wound with +z normals."""
    xs = np.linspace(-half, half, n)
    X, Y = np.meshgrid(xs, xs)
    vertices = np.column_stack([X.ravel(), Y.ravel(), height(X, Y).ravel()])
    idx = np.arange(n * n).reshape(n, n)
    v00, v01 = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    v10, v11 = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.vstack([np.column_stack([v00, v01, v11]), np.column_stack([v00, v11, v10])])
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def _paraboloid(x, y):
    return x**2 + y**2


@pytest.fixture(scope="module")
def paraboloid():
    return _grid_patch(_paraboloid)


def _mesh_distance(mesh: trimesh.Trimesh, point) -> float:
    """Distance from ``point`` to the mesh, brute force over every face by barycentric
    coordinates (trimesh's), independent of the simulator's closest-point query: the
    distance to a face's plane where the projection falls inside the face, else to the
    nearest vertex or edge (an upper bound that is exact for points on the mesh)."""
    p = np.asarray(point, dtype=np.float64)
    tri = mesh.triangles
    normals = mesh.face_normals
    height = np.einsum("ij,ij->i", p - tri[:, 0], normals)
    foot = p - height[:, None] * normals
    bary = trimesh.triangles.points_to_barycentric(tri, foot)
    inside = np.all(bary >= -1e-9, axis=1)
    best = np.abs(height[inside]).min() if inside.any() else np.inf
    return float(min(best, np.linalg.norm(mesh.vertices - p, axis=1).min()))


def _chord_error(mesh: trimesh.Trimesh, radius: float) -> float:
    """The most a mesh inscribed in a sphere or cylinder of ``radius`` falls inside it:
    the sagitta of its longest edge, r - sqrt(r^2 - (e/2)^2) (an edge's midpoint lies
    deeper than any face's points... up to the face's circumradius, bounded by e / sqrt(3))."""
    e = float(mesh.edges_unique_length.max())
    half = e / math.sqrt(3.0)  # the circumradius of a face with longest edge e, at most
    return radius - math.sqrt(radius * radius - half * half)


def _steps(curve: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(curve, axis=0), axis=1)


def _tangent_at_middle(curve: np.ndarray) -> np.ndarray:
    mid = len(curve) // 2
    d = curve[mid + 1] - curve[mid - 1]
    return d / np.linalg.norm(d)


# ------------------------------------------------------------------ geometry on a sphere
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_sphere_curves_lie_on_the_sphere_equally_spaced(sphere, seed):
    sim = simulate_touch(sphere, rng=seed, noise=0.0, transform=False)
    depth = _sphere_depth(sphere)
    assert sim.length == pytest.approx(defaults.SIM_LENGTH_FRACTION * math.sqrt(sphere.area))
    assert len(sim.clean_curves) == 3
    step = sim.length / (defaults.SIM_POINTS - 1)
    for curve in sim.clean_curves:
        assert curve.shape == (defaults.SIM_POINTS, 3)
        r = np.linalg.norm(curve, axis=1)
        assert np.all(r <= RADIUS + 1e-9)
        assert np.all(r >= RADIUS - depth - 1e-9)
        steps = _steps(curve)
        # equal arc length along the section polyline: chords are at most the step and
        # shorter only where a step straddles a (slight) polyline corner
        assert np.all(steps <= step * (1 + 1e-9))
        assert np.all(steps >= step * (1 - 1e-3))
        assert steps.sum() == pytest.approx(sim.length, rel=1e-3)
    # with no noise and no motion the touch is the clean curves
    for a, b in zip(sim.touch.curves, sim.clean_curves, strict=True):
        np.testing.assert_array_equal(a, b)
    assert sim.touch.contact is None
    assert sim.touch.normal is None


@pytest.mark.parametrize("seed", [0, 5, 11])
def test_sphere_curves_meet_at_the_contact_not_parallel(sphere, seed):
    sim = simulate_touch(sphere, rng=seed, noise=0.0, transform=False)
    # the contact is on the mesh and the normal is the outward face normal there
    assert _mesh_distance(sphere, sim.contact) < 1e-12
    assert np.linalg.norm(sim.normal) == pytest.approx(1.0)
    assert sim.normal @ (sim.contact / np.linalg.norm(sim.contact)) > 0.99
    mid = defaults.SIM_POINTS // 2
    for curve in sim.clean_curves:
        np.testing.assert_array_equal(curve[mid], sim.contact)
    tangents = [_tangent_at_middle(c) for c in sim.clean_curves]
    for t in tangents:
        assert abs(t @ sim.normal) < math.sin(math.radians(2.0))
    for a, b in itertools.combinations(tangents, 2):
        angle = math.degrees(math.acos(min(1.0, abs(float(a @ b)))))
        assert angle >= defaults.SIM_MIN_PLANE_ANGLE_DEG - 2.0


def test_curves_are_planar_and_tilted_at_most_the_maximum(sphere):
    max_sin = math.sin(math.radians(defaults.SIM_MAX_TILT_DEG))
    for seed in range(6):
        sim = simulate_touch(sphere, rng=seed, noise=0.0, transform=False)
        for curve in sim.clean_curves:
            centred = curve - sim.contact
            _, sv, vt = np.linalg.svd(centred)
            assert sv[2] < 1e-9 * sv[0]
            plane_normal = vt[2]
            assert abs(plane_normal @ sim.normal) <= max_sin + 1e-3


def test_closed_loop_wraps_around_the_contact(coarse_sphere):
    # every cut of a unit sphere is a circle of perimeter >= 2 pi cos(max tilt) > 5
    sim = simulate_touch(coarse_sphere, rng=3, noise=0.0, transform=False, length=5.0)
    step = 5.0 / (defaults.SIM_POINTS - 1)
    mid = defaults.SIM_POINTS // 2
    for curve in sim.clean_curves:
        np.testing.assert_array_equal(curve[mid], sim.contact)
        arc = _steps(curve)
        assert np.all(arc <= step * (1 + 1e-9))
        assert arc.sum() == pytest.approx(5.0, rel=0.02)


def test_closed_loop_shorter_than_length(coarse_sphere):
    contact = coarse_sphere.vertices[0]
    with pytest.raises(ValueError, match="closed loop"):
        simulate_touch(coarse_sphere, contact=contact, rng=0, length=7.0)
    with pytest.raises(ValueError, match="length=7"):
        simulate_touch(coarse_sphere, rng=0, length=7.0)


def test_n_points_is_honoured(sphere):
    sim = simulate_touch(sphere, rng=4, n_points=7, noise=0.0, transform=False)
    for curve in sim.clean_curves:
        assert curve.shape == (7, 3)
        np.testing.assert_array_equal(curve[3], sim.contact)
    assert sim.truth_dict()["points"] == 7


# ------------------------------------------------------------------ noise and motion
def test_noise_is_uniform_within_bounds(sphere):
    noise = 0.01
    sim = simulate_touch(sphere, rng=7, noise=noise, transform=False)
    deltas = [t - c for t, c in zip(sim.touch.curves, sim.clean_curves, strict=True)]
    stacked = np.vstack(deltas)
    assert np.all(np.abs(stacked) <= noise)
    assert np.abs(stacked).max() > 0.9 * noise
    assert abs(stacked.mean()) < 0.1 * noise
    # each curve has its own noise: the three noisy copies of the contact differ
    mid = defaults.SIM_POINTS // 2
    copies = np.array([c[mid] for c in sim.touch.curves])
    assert np.ptp(copies, axis=0).max() > 0


def test_noise_along_the_normal_is_radial_on_a_sphere(sphere, tmp_path):
    # The smooth normal of a fine icosphere is radial: each sample moves along its own
    # radius, by at most the noise, and by (nearly) nothing across it.
    noise = 0.01
    sim = simulate_touch(sphere, rng=7, noise=noise, transform=False, noise_direction="normal")
    assert sim.noise_direction == "normal"
    clean = np.vstack(sim.clean_curves)
    delta = np.vstack(sim.touch.curves) - clean
    radial = clean / np.linalg.norm(clean, axis=1)[:, None]
    along = np.sum(delta * radial, axis=1)
    across = delta - along[:, None] * radial
    assert np.all(np.abs(along) <= noise)
    assert np.abs(along).max() > 0.9 * noise
    assert np.linalg.norm(across, axis=1).max() < 0.01 * noise
    # recorded in the truth file, and read back
    sim.write(tmp_path / "t.csv", tmp_path / "truth.json")
    assert read_truth(tmp_path / "truth.json").noise_direction == "normal"
    assert "noise along the normal" in repr(sim)


def test_isotropic_noise_is_the_default_and_not_recorded(sphere):
    default = simulate_touch(sphere, rng=7, noise=0.01)
    isotropic = simulate_touch(sphere, rng=7, noise=0.01, noise_direction="isotropic")
    for a, b in zip(default.touch.curves, isotropic.touch.curves, strict=True):
        np.testing.assert_array_equal(a, b)
    assert "noise_direction" not in default.truth_dict()
    assert default.truth.noise_direction is None


def test_noise_direction_is_checked(sphere):
    with pytest.raises(ValueError, match="noise_direction must be one of"):
        simulate_touch(sphere, rng=7, noise_direction="sideways")
    with pytest.raises(TypeError, match="noise_direction"):
        simulate_touch(sphere, rng=7, noise_direction=3)
    truth = simulate_touch(sphere, rng=7).truth_dict()
    with pytest.raises(ValueError, match=r"truth\['noise_direction'\]"):
        Truth.from_dict({**truth, "noise_direction": "sideways"})


def test_transform_maps_back_to_the_clean_curves(sphere):
    noise = 1e-3
    sim = simulate_touch(sphere, rng=8, noise=noise)
    T, T_inv = sim.T_touch_model, sim.T_model_touch
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(T_inv @ T, np.eye(4), atol=1e-12)
    assert np.all(np.abs(T[:3, 3]) <= math.sqrt(sphere.area))
    assert not np.allclose(T, np.eye(4))
    back = sim.touch.transformed(T_inv)
    for b, c in zip(back.curves, sim.clean_curves, strict=True):
        assert np.all(np.abs(b - c) <= noise + 1e-9)
    np.testing.assert_allclose(sim.contact_touch, R @ sim.contact + T[:3, 3])
    np.testing.assert_allclose(T_inv[:3, :3] @ sim.contact_touch + T_inv[:3, 3], sim.contact)


def test_identity_without_transform(sphere):
    sim = simulate_touch(sphere, rng=9, transform=False)
    np.testing.assert_array_equal(sim.T_touch_model, np.eye(4))
    np.testing.assert_array_equal(sim.T_model_touch, np.eye(4))


# ------------------------------------------------------------------ reproducibility
def test_same_seed_same_touch_different_seed_different(sphere):
    a = simulate_touch(sphere, rng=42)
    b = simulate_touch(sphere, rng=42)
    c = simulate_touch(sphere, rng=43)
    assert a.seed == 42
    for x, y in zip(a.touch.curves, b.touch.curves, strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.T_touch_model, b.T_touch_model)
    np.testing.assert_array_equal(a.contact, b.contact)
    assert not np.allclose(a.contact, c.contact)
    assert not np.allclose(a.touch.points, c.touch.points)
    # a generator gives the same stream as its seed
    d = simulate_touch(sphere, rng=np.random.default_rng(42))
    assert d.seed is None
    np.testing.assert_array_equal(a.touch.points, d.touch.points)


def test_no_rng_records_a_seed_that_reproduces(sphere):
    a = simulate_touch(sphere)
    assert isinstance(a.seed, int)
    b = simulate_touch(sphere, rng=a.seed)
    np.testing.assert_array_equal(a.touch.points, b.touch.points)


def test_noise_level_does_not_change_contact_or_pose(sphere):
    a = simulate_touch(sphere, rng=5, noise=0.0)
    b = simulate_touch(sphere, rng=5, noise=0.01)
    np.testing.assert_array_equal(a.contact, b.contact)
    np.testing.assert_array_equal(a.T_touch_model, b.T_touch_model)


# ------------------------------------------------------------------ a given contact
def test_given_contact_is_honoured(sphere):
    direction = np.array([0.3, -0.5, 0.8])
    given = RADIUS * direction / np.linalg.norm(direction)  # on the sphere, near the mesh
    sim = simulate_touch(sphere, contact=given, rng=1, noise=0.0, transform=False)
    assert np.linalg.norm(sim.contact - given) <= _sphere_depth(sphere) + 1e-9
    assert _mesh_distance(sphere, sim.contact) < 1e-12
    mid = defaults.SIM_POINTS // 2
    for curve in sim.clean_curves:
        np.testing.assert_array_equal(curve[mid], sim.contact)
    # a contact exactly at a mesh vertex works too
    vertex = sphere.vertices[17]
    sim = simulate_touch(sphere, contact=vertex, rng=2, noise=0.0, transform=False)
    np.testing.assert_allclose(sim.contact, vertex, atol=1e-12)
    for curve in sim.clean_curves:
        steps = _steps(curve)
        assert np.all(steps >= sim.length / (defaults.SIM_POINTS - 1) * (1 - 1e-3))


def test_given_contact_far_from_the_mesh(sphere):
    with pytest.raises(ValueError, match=r"contact .* is 0\.5 from the mesh"):
        simulate_touch(sphere, contact=[0.0, 0.0, RADIUS + 0.5], rng=0)


# ------------------------------------------------------------------ open patches
def test_open_patch_contact_near_the_boundary(paraboloid):
    x = 0.95
    with pytest.raises(ValueError, match="too short"):
        simulate_touch(paraboloid, contact=[x, 0.0, _paraboloid(x, 0.0)], rng=0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_open_patch_random_contacts_succeed(paraboloid, seed):
    sim = simulate_touch(paraboloid, rng=seed, noise=0.0, transform=False)
    step = sim.length / (defaults.SIM_POINTS - 1)
    for curve in sim.clean_curves:
        assert np.all(np.abs(curve[:, :2]) <= 1.0 + 1e-12)
        # on the mesh: above the paraboloid by at most the chord error of a grid cell
        gap = curve[:, 2] - _paraboloid(curve[:, 0], curve[:, 1])
        assert np.all(gap >= -1e-12)
        assert np.all(gap <= 2 * (2.0 / 40) ** 2)
        steps = _steps(curve)
        assert np.all(steps <= step * (1 + 1e-9))
        assert np.all(steps >= step * 0.98)
    assert sim.normal[2] > 0  # the face winding points up


def test_open_patch_near_centre_given_contact(paraboloid):
    sim = simulate_touch(paraboloid, contact=[0.1, -0.2, 0.05], rng=3, transform=False)
    assert sim.contact[:2] == pytest.approx([0.1, -0.2], abs=1e-12)


def test_flat_patch_gives_straight_curves():
    flat = _grid_patch(lambda x, y: np.zeros_like(x), n=21)
    sim = simulate_touch(flat, rng=6, noise=0.0, transform=False)
    np.testing.assert_allclose(sim.normal, [0.0, 0.0, 1.0])
    for curve in sim.clean_curves:
        np.testing.assert_allclose(curve[:, 2], 0.0, atol=1e-12)
        _, sv, _ = np.linalg.svd(curve - curve.mean(axis=0))
        assert sv[1] < 1e-9 * sv[0]
        np.testing.assert_allclose(_steps(curve), sim.length / (defaults.SIM_POINTS - 1))


# ------------------------------------------------------------------ mesh inputs
def test_mesh_from_file_and_duck_typed_object(tmp_path, coarse_sphere):
    path = tmp_path / "ball.ply"
    coarse_sphere.export(path)
    from_file = simulate_touch(path, rng=1)
    assert from_file.model == "ball"
    from_str = simulate_touch(str(path), rng=1, name="renamed")
    assert from_str.model == "renamed"

    class Model:
        name = "duck"
        vertices = coarse_sphere.vertices
        faces = coarse_sphere.faces

    duck = simulate_touch(Model(), rng=1)
    assert duck.model == "duck"
    bare = simulate_touch(coarse_sphere, rng=1)
    assert bare.model == ""
    # a ModelIndex gives its name (its MeshData has none: the truth said model '')
    index = meshrec.ModelIndex.from_file(path, cache_dir=tmp_path / "cache")
    assert simulate_touch(index, rng=1).model == "ball"
    np.testing.assert_allclose(duck.touch.points, bare.touch.points)
    np.testing.assert_allclose(from_file.contact, bare.contact, atol=1e-9)


# ------------------------------------------------------------------ files
def test_write_csv_and_truth(tmp_path, sphere):
    sim = simulate_touch(sphere, rng=10, name="ball")
    touch_path = tmp_path / "out" / "touch.csv"
    truth_path = tmp_path / "truth.json"
    sim.write(touch_path, truth_path)
    back = TouchData.from_csv(touch_path)
    assert len(back.curves) == 3
    for a, b in zip(back.curves, sim.touch.curves, strict=True):
        np.testing.assert_array_equal(a, b)
    assert back.contact is None
    truth = json.loads(truth_path.read_text())
    assert set(truth) == {
        "model", "contact", "normal", "T_touch_model", "T_model_touch", "contact_touch",
        "noise", "length", "points", "seed",
    }  # fmt: skip
    assert truth["model"] == "ball"
    assert truth["seed"] == 10
    assert truth["points"] == defaults.SIM_POINTS
    assert truth["noise"] == defaults.SIM_NOISE
    assert truth["length"] == sim.length
    np.testing.assert_array_equal(truth["contact"], sim.contact)
    np.testing.assert_array_equal(truth["normal"], sim.normal)
    np.testing.assert_array_equal(truth["T_touch_model"], sim.T_touch_model)
    np.testing.assert_array_equal(truth["T_model_touch"], sim.T_model_touch)
    np.testing.assert_array_equal(truth["contact_touch"], sim.contact_touch)
    assert truth == sim.truth_dict()


def test_write_json_without_truth_writes_only_the_touch(tmp_path, sphere):
    sim = simulate_touch(sphere, rng=11)
    sim.write(tmp_path / "t.json")
    back = TouchData.from_json(tmp_path / "t.json")
    np.testing.assert_array_equal(back.points, sim.touch.points)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def test_truth_file_maps_the_touch_file_onto_the_sphere(tmp_path, sphere):
    # the files alone (read back through the public readers) carry the truth: the touch
    # mapped by T_model_touch lies on the analytic sphere within the chord error and noise
    noise = 2e-3
    sim = simulate_touch(sphere, rng=12, noise=noise)
    sim.write(tmp_path / "t.csv", tmp_path / "truth.json")
    touch = TouchData.from_file(tmp_path / "t.csv")
    truth = read_truth(tmp_path / "truth.json")
    assert isinstance(truth, Truth)
    assert (truth.points, truth.seed, truth.noise) == (defaults.SIM_POINTS, 12, noise)
    back = touch.transformed(truth.T_model_touch).points
    r = np.linalg.norm(back, axis=1)
    slack = noise * math.sqrt(3.0)
    assert np.all(r <= RADIUS + slack)
    assert np.all(r >= RADIUS - _chord_error(sphere, RADIUS) - slack)
    assert abs(np.linalg.norm(truth.contact) - RADIUS) <= _chord_error(sphere, RADIUS)
    np.testing.assert_allclose(
        truth.normal, truth.contact / np.linalg.norm(truth.contact), atol=0.02
    )


def test_write_rejects_unknown_suffix_and_same_path(tmp_path, coarse_sphere):
    sim = simulate_touch(coarse_sphere, rng=0)
    with pytest.raises(ValueError, match=r"\.csv or \.json"):
        sim.write(tmp_path / "t.txt")
    with pytest.raises(ValueError, match="truth_path"):
        sim.write(tmp_path / "t.json", tmp_path / "t.json")


def test_result_is_immutable(coarse_sphere):
    sim = simulate_touch(coarse_sphere, rng=0)
    assert isinstance(sim, SimulatedTouch)
    with pytest.raises(ValueError, match="read-only"):
        sim.contact[0] = 1.0
    with pytest.raises(AttributeError):
        sim.noise = 0.5  # type: ignore[misc]


# ------------------------------------------------------------------ argument checks
@pytest.mark.parametrize(
    ("kwargs", "error", "pattern"),
    [
        ({"n_points": 4}, ValueError, "n_points .* got 4"),
        ({"n_points": 3}, ValueError, "n_points .* got 3"),
        ({"n_points": 10**6 + 1}, ValueError, "n_points must be <= 9999, got 1000001"),
        ({"n_points": 61.0}, TypeError, r"n_points must be an integer, got float 61\.0"),
        ({"n_points": True}, TypeError, "n_points .* got bool True"),
        ({"noise": -0.1}, ValueError, r"noise .* got -0\.1"),
        ({"noise": float("nan")}, ValueError, "noise .* got nan"),
        ({"noise": float("inf")}, ValueError, "noise .* got inf"),
        ({"noise": 1e308}, ValueError, r"noise must be at most 1\.0 \* sqrt\(area\)"),
        ({"noise": 10**400}, ValueError, "noise must be finite"),
        ({"noise": "a"}, TypeError, "noise must be a real number, got str a"),
        ({"noise": 1e-3j}, TypeError, "noise must be a real number, got complex"),
        ({"length": 0.0}, ValueError, r"length .* got 0\.0"),
        ({"length": -1}, ValueError, r"length .* got -1\.0"),
        ({"length": float("inf")}, ValueError, "length .* got inf"),
        ({"length": None, "name": 3}, TypeError, "name must be a str, got int"),
        ({"contact": [0.0, 1.0]}, ValueError, r"contact must be \(3,\), got \(2,\)"),
        ({"contact": [0.0, float("nan"), 1.0]}, ValueError, "contact must be finite, got .*nan"),
        ({"contact": "abc"}, TypeError, "contact must be an array of real numbers, got str"),
        ({"contact": [1j, 0, 0]}, TypeError, "contact must hold real numbers, got a complex"),
        ({"rng": -1}, ValueError, "rng must be a non-negative int seed, got -1"),
        ({"rng": "seed"}, TypeError, "rng must be .* got str seed"),
        ({"rng": 1.5}, TypeError, "rng must be .* got float 1.5"),
        ({"transform": "yes"}, TypeError, "transform must be True or False, got yes"),
    ],
)
def test_invalid_arguments(coarse_sphere, kwargs, error, pattern):
    with pytest.raises(error, match=pattern):
        simulate_touch(coarse_sphere, **kwargs)


def test_invalid_meshes(tmp_path):
    with pytest.raises(ValueError, match=r"missing\.stl: no such file"):
        simulate_touch(tmp_path / "missing.stl")
    text = tmp_path / "notes.txt"
    text.write_text("not a mesh\n")
    with pytest.raises(ValueError, match=r"notes\.txt: not a readable mesh"):
        simulate_touch(text)
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(b"solid x\nfacet normal 0 0 1\n")
    with pytest.raises(ValueError, match=r"garbage\.stl: (not a readable mesh|holds no triangle)"):
        simulate_touch(garbage)

    class Complex:
        vertices = np.zeros((3, 3), dtype=complex)
        faces = np.array([[0, 1, 2]])

    with pytest.raises(TypeError, match=r"mesh\.vertices must hold real numbers"):
        simulate_touch(Complex())

    class OutOfRange:
        vertices = np.eye(3)
        faces = np.array([[0, 1, 3]])

    with pytest.raises(ValueError, match=r"mesh\.faces must index the 3 vertices"):
        simulate_touch(OutOfRange())
    with pytest.raises(TypeError, match="got int"):
        simulate_touch(42)
    flat = trimesh.Trimesh(vertices=np.zeros((3, 3)), faces=[[0, 1, 2]], process=False)
    with pytest.raises(ValueError, match="positive surface area"):
        simulate_touch(flat)


# ------------------------------------------------------------------ independent truths
def _cylinder_distance(points: np.ndarray, radius: float, height: float) -> np.ndarray:
    """Distance to the surface of the closed cylinder x^2 + y^2 = r^2, |z| <= h / 2."""
    rho = np.hypot(points[:, 0], points[:, 1])
    z = np.abs(points[:, 2]) - height / 2
    outside = np.hypot(np.maximum(rho - radius, 0.0), np.maximum(z, 0.0))
    inside = np.minimum(radius - rho, -z)
    return np.where((rho <= radius) & (z <= 0), inside, outside)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_touch_on_a_cylinder_maps_onto_the_analytic_cylinder(seed):
    radius, height, noise = 1.0, 4.0, 1e-3
    mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=256)
    sim = simulate_touch(mesh, rng=seed, noise=noise, length=0.8)
    back = sim.touch.transformed(sim.T_model_touch)
    slack = noise * math.sqrt(3.0) + 1e-12
    chord = radius * (1.0 - math.cos(math.pi / 256))  # the side's sagitta; caps are flat
    for curve in back.curves:
        assert np.all(_cylinder_distance(curve, radius, height) <= chord + slack)
    # the noiseless curves are on the mesh (the chord error is the only gap) and each one
    # is a plane curve through the contact
    for curve in sim.clean_curves:
        assert np.all(_cylinder_distance(curve, radius, height) <= chord + 1e-12)
        _, sv, _ = np.linalg.svd(curve - sim.contact)
        assert sv[2] < 1e-9 * sv[0]
    assert _mesh_distance(mesh, sim.contact) < 1e-12


def test_rotation_is_uniform_and_proper(coarse_sphere):
    # Rotation.random: proper rotations whose columns average to zero over many seeds
    # (a uniform rotation's expected matrix is 0), translations within +-sqrt(area)
    Rs = []
    for seed in range(60):
        T = simulate_touch(coarse_sphere, rng=seed, n_points=5, length=0.3).T_touch_model
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert np.all(np.abs(T[:3, 3]) <= math.sqrt(coarse_sphere.area))
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
        Rs.append(R)
    assert np.abs(np.mean(Rs, axis=0)).max() < 0.3  # 60 draws: sd of an entry ~ 0.075
