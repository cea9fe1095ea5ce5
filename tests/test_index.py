"""Tests for meshrec.model.index: curvature table, lookup, distance queries, caching."""

import dataclasses
import itertools
import pickle
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.model.cache import CacheWarning
from meshrec.model.curvature import CurvatureTable
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.mesh import MeshData
from meshrec.model.record import IndexRecord
from meshrec.model.surface import AabbSurface, SurfaceQuery

sys.path.insert(0, str(Path(__file__).parent))
from surface_backends import DelegatingSurface


# ----------------------------------------------------------------------------- meshes
def _cylinder(r=1.0, h=4.0, sections=128, rings=80, cap_rings=20) -> trimesh.Trimesh:
    """A closed cylinder about z: a fine side grid and caps of concentric rings."""
    th = np.linspace(0.0, 2.0 * np.pi, sections, endpoint=False)
    ring = np.column_stack([np.cos(th), np.sin(th), np.zeros(sections)])
    z = np.linspace(-h / 2, h / 2, rings + 1)
    verts = [ring * [r, r, 0] + [0, 0, zz] for zz in z]
    faces = []
    j = np.arange(sections)
    jn = (j + 1) % sections
    for i in range(rings):
        a, b = i * sections + j, i * sections + jn
        c, d = (i + 1) * sections + jn, (i + 1) * sections + j
        faces += [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    n = (rings + 1) * sections
    for top in (False, True):
        zz = h / 2 if top else -h / 2
        rim = j + (rings * sections if top else 0)
        rims = [rim]
        for k in range(1, cap_rings):
            verts.append(ring * (r * (1 - k / cap_rings)) + [0, 0, zz])
            rims.append(n + j)
            n += sections
        verts.append(np.array([[0.0, 0.0, zz]]))
        centre = n
        n += 1
        tris = []
        for o, i_ in itertools.pairwise(rims):
            tris += [np.column_stack([o, o[jn], i_[jn]]), np.column_stack([o, i_[jn], i_])]
        tris.append(np.column_stack([rims[-1], rims[-1][jn], np.full(sections, centre)]))
        tris = np.vstack(tris)
        faces.append(tris if top else tris[:, ::-1])
    return trimesh.Trimesh(np.vstack(verts), np.vstack(faces), process=True)


def _ellipsoid_KH(p, a, b, c):
    """Closed-form Gaussian and mean curvature (outward normals) at points on the ellipsoid."""
    x, y, z = p.T
    w = x**2 / a**4 + y**2 / b**4 + z**2 / c**4
    K = 1.0 / ((a * b * c) ** 2 * w**2)
    H = (a * a + b * b + c * c - (x * x + y * y + z * z)) / (2.0 * (a * b * c) ** 2 * w**1.5)
    return K, H


def _index(tmp_path, mesh, name="m", suffix=".stl", **kw):
    path = tmp_path / f"{name}{suffix}"
    mesh.export(path)
    kw.setdefault("cache_dir", tmp_path / "cache")
    return ModelIndex.from_file(path, **kw)


@pytest.fixture(scope="module")
def sphere_index(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sphere")
    return _index(tmp, trimesh.creation.icosphere(subdivisions=4, radius=2.0), "sphere")


@pytest.fixture(scope="module")
def ellipsoid_index(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ellipsoid")
    mesh = trimesh.creation.icosphere(subdivisions=5)
    mesh.apply_scale([1.0, 0.8, 0.5])
    return _index(tmp, mesh, "ellipsoid")


# ----------------------------------------------------------------------------- params
def test_params_defaults_and_lengths():
    p = IndexParams()
    assert p.curvature_fraction == defaults.CURVATURE_SCALE_FRACTION
    assert p.spacing_fraction == defaults.SITE_SPACING_FRACTION
    assert p.range_fraction == defaults.SITE_RANGE_FRACTION
    assert p.sharp_angle_deg == defaults.SITE_CREASE_ANGLE_DEG
    spacing, radius, range_radius = p.lengths(10.0)
    assert np.isclose(spacing, 10.0 * defaults.SITE_SPACING_FRACTION)
    assert np.isclose(radius, 10.0 * defaults.CURVATURE_SCALE_FRACTION)
    assert np.isclose(range_radius, 10.0 * defaults.SITE_RANGE_FRACTION)
    assert IndexParams(range_fraction=0).range_fraction == 0.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"curvature_fraction": 0.0}, "curvature_fraction must be a finite number > 0, got 0.0"),
        ({"curvature_fraction": float("nan")}, "curvature_fraction"),
        ({"curvature_fraction": "big"}, "curvature_fraction"),
        ({"spacing_fraction": -1.0}, "spacing_fraction must be a finite number > 0, got -1.0"),
        ({"spacing_fraction": True}, "spacing_fraction"),
        ({"range_fraction": -0.1}, "range_fraction must be a finite number >= 0, got -0.1"),
        ({"sharp_angle_deg": 0.0}, r"sharp_angle_deg must be in \(0, 180\] degrees, got 0.0"),
        ({"crease_angle_deg": 0.0}, r"crease_angle_deg must be in \(0, 180\] degrees, got 0.0"),
        ({"crease_angle_deg": 181}, "crease_angle_deg"),
        ({"crease_angle_deg": float("inf")}, "crease_angle_deg"),
    ],
)
def test_params_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        IndexParams(**kwargs)


@pytest.mark.parametrize("scale", [0.0, -1.0, np.inf, np.nan])
def test_lengths_errors(scale):
    with pytest.raises(ValueError, match="scale must be finite and > 0"):
        IndexParams().lengths(scale)


# ----------------------------------------------------------------------------- curvature
def test_sphere_curvature_and_sign(sphere_index):
    idx = sphere_index
    r = 2.0
    table = idx.curvature
    assert table.valid.all()
    assert not table.crease.any()
    assert idx.mesh.closed
    assert np.all(table.k1 >= table.k2)
    # Measured on this 5120-face sphere: relative errors <= 6.2e-2 (K), 3.1e-2 (H), median
    # 1.4e-2 (K) (the blended normals of the flat faces are not quite those of a sphere).
    assert np.allclose(table.K, 1 / r**2, rtol=0.08)
    assert np.allclose(table.H, 1 / r, rtol=0.04)
    assert np.median(np.abs(table.K * r**2 - 1)) < 0.02
    assert np.all(table.k2 > 0)  # outward normals: positive curvature (libigl's sign)
    # The sites lie on the sphere (lifted off the flat faces), with radial normals.
    assert np.allclose(np.linalg.norm(table.points, axis=1), r, rtol=2e-4)
    radial = table.points / np.linalg.norm(table.points, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", table.normals, radial) > 0.9999)
    assert np.isclose(idx.mesh.scale, np.sqrt(4 * np.pi * r**2), rtol=0.01)
    assert np.isclose(table.curvature_radius, defaults.CURVATURE_SCALE_FRACTION * idx.mesh.scale)
    # Sites about evenly spread: none closer than the spacing asked.
    d = cKDTree(table.points).query(table.points, k=2)[0][:, 1]
    assert d.min() >= table.spacing * (1 - 1e-9)
    assert np.median(d) < 2.5 * table.spacing
    # directions: unit, tangent, orthogonal
    for d in (table.dir1, table.dir2):
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
        assert np.abs(np.einsum("ij,ij->i", d, table.normals)).max() < 1e-6
    assert np.abs(np.einsum("ij,ij->i", table.dir1, table.dir2)).max() < 1e-6


def _table(mesh, **kw):
    data = MeshData.from_arrays(mesh.vertices, mesh.faces)
    spacing, radius, range_radius = IndexParams(**kw).lengths(data.scale)
    surface = AabbSurface.from_mesh(data, defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG)
    return data, CurvatureTable.from_mesh(
        data, surface, spacing=spacing, curvature_radius=radius, range_radius=range_radius
    )


def test_flipped_winding_flips_the_sign():
    # The table follows the winding it is given (load_mesh turns closed meshes outward,
    # see tests/test_bad_models.py, so the inside-out sphere is built from arrays here).
    mesh = trimesh.creation.icosphere(subdivisions=3)
    mesh.invert()
    _, table = _table(mesh)
    assert np.all(table.k1 < 0)
    # Measured: relative errors <= 5.8e-2 (H) and 0.113 (K) on this 1280-face sphere.
    assert np.allclose(table.H, -1.0, rtol=0.08)
    assert np.allclose(table.K, 1.0, rtol=0.15)  # K does not change sign


def test_cylinder_side_curvature(tmp_path):
    r = 1.0
    mesh = _cylinder(r=r)
    assert mesh.is_watertight
    assert mesh.volume > 0
    idx = _index(tmp_path, mesh, "cylinder")
    assert idx.mesh.closed
    t = idx.curvature
    side = ~t.crease & (np.abs(t.points[:, 2]) < 1.5)
    assert side.sum() > 1000
    assert np.allclose(np.hypot(t.points[side, 0], t.points[side, 1]), r, rtol=1e-4)
    # Measured: |K| <= 2e-4 and |H - 1/(2r)| / (1/(2r)) <= 2e-3 away from the rims.
    assert np.abs(t.K[side]).max() < 1e-3
    assert np.allclose(t.H[side], 1 / (2 * r), rtol=5e-3)
    assert np.allclose(t.k1[side], 1 / r, rtol=5e-3)
    # the maximal direction goes round the cylinder, the minimal one along its axis
    assert np.abs(t.dir2[side, 2]).min() > 0.999
    # the rims are sharp: crease sites, on the rims, convex
    rim = t.crease
    assert rim.sum() > 50
    assert np.allclose(np.hypot(t.points[rim, 0], t.points[rim, 1]), r, rtol=2e-3)
    assert np.allclose(np.abs(t.points[rim, 2]), 2.0)
    assert (t.H_range[rim, 0] == 0).all()
    assert np.isinf(t.H_range[rim, 1]).all()


def test_ellipsoid_curvature_against_closed_form(ellipsoid_index):
    idx = ellipsoid_index
    a, b, c = 1.0, 0.8, 0.5
    t = idx.curvature
    K, H = _ellipsoid_KH(t.points, a, b, c)
    # Measured over every site: relative error <= 0.122 (K) and 7.1e-2 (H), medians
    # 1.5e-2 (K) and 8.6e-3 (H).
    assert np.max(np.abs(t.K / K - 1)) < 0.16
    assert np.max(np.abs(t.H / H - 1)) < 0.1
    assert np.median(np.abs(t.K / K - 1)) < 0.02
    assert np.median(np.abs(t.H / H - 1)) < 0.012


def test_table_does_not_depend_on_the_tessellation():
    # One cylinder, exported as trimesh writes it (32 sections: every vertex on the two
    # rims, the side made of long full-height triangles) and finely, in small triangles.
    coarse = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=32)
    fine = _cylinder(r=1.0, h=2.0, sections=128, rings=40, cap_rings=10)
    tables = [_table(m)[1] for m in (coarse, fine)]
    sides = [~t.crease & (np.abs(t.points[:, 2]) < 0.8) for t in tables]
    counts = [len(t.points) for t in tables]
    assert abs(counts[0] / counts[1] - 1) < 0.05
    for t, side in zip(tables, sides, strict=True):
        # the side wall of the 32-gon prism is read as the cylinder it approximates
        assert np.abs(t.K[side]).max() < 2e-3
        assert np.allclose(t.H[side], 0.5, rtol=0.01)
    caps = [~t.crease & (np.abs(t.normals[:, 2]) > 0.999) for t in tables]
    for t, cap in zip(tables, caps, strict=True):
        assert np.abs(t.H[cap]).max() < 1e-6  # the flat caps stay flat
    assert abs(caps[0].sum() / caps[1].sum() - 1) < 0.1


def test_invalid_sites_stay_out_of_the_table(tmp_path):
    # A lone triangle far from a sphere: its sites have too few neighbours to fit a
    # curvature (invalid), and never match.
    sphere = trimesh.creation.icosphere(subdivisions=3)
    far = trimesh.Trimesh([[10, 0, 0], [10.02, 0, 0], [10, 0.02, 0]], [[0, 1, 2]])
    mesh = trimesh.util.concatenate([sphere, far])
    idx = _index(tmp_path, mesh, "with_island", suffix=".ply")
    t = idx.curvature
    island = np.linalg.norm(t.points, axis=1) > 5
    assert not t.valid[island].any()
    assert np.isnan(t.K[~t.valid]).all()
    assert t.valid[~island].all()
    assert not idx.mesh.closed
    everything = t.lookup(0.0, 0.0, np.inf, np.inf)
    assert np.array_equal(everything, np.flatnonzero(t.valid))


# ----------------------------------------------------------------------------- lookup
def _brute(idx, K, H, tol_K, tol_H):
    t = idx.curvature
    ok = (
        t.valid
        & (t.K_range[:, 0] - tol_K <= K)
        & (t.K_range[:, 1] + tol_K >= K)
        & (t.H_range[:, 0] - tol_H <= H)
        & (t.H_range[:, 1] + tol_H >= H)
    )
    return np.flatnonzero(ok)


def test_lookup_matches_brute_force(ellipsoid_index):
    idx = ellipsoid_index
    t = idx.curvature
    rng = np.random.default_rng(7)
    for _ in range(200):
        v = rng.integers(len(t.points))
        K = t.K[v] * rng.uniform(0.9, 1.1)
        H = t.H[v] * rng.uniform(0.9, 1.1)
        tol_K = abs(K) * rng.uniform(0.0, 0.3)
        tol_H = abs(H) * rng.uniform(0.0, 0.3)
        got = t.lookup(K, H, tol_K, tol_H)
        assert got.dtype == np.int64
        assert np.array_equal(got, _brute(idx, K, H, tol_K, tol_H))
    # a site's own value always matches it, even with zero tolerance
    v = 123
    assert v in t.lookup(t.K[v], t.H[v], 0.0, 0.0)
    for tk, th in [(np.inf, 0.05), (0.1, np.inf)]:
        assert np.array_equal(t.lookup(2.0, 1.5, tk, th), _brute(idx, 2.0, 1.5, tk, th))
    assert len(t.lookup(-5.0, -3.0, 0.1, 0.1)) == 0


def test_ranges_hold_the_neighbourhood(ellipsoid_index):
    t = ellipsoid_index.curvature
    assert t.valid.all()
    assert np.all(t.K_range[:, 0] <= t.K)
    assert np.all(t.K_range[:, 1] >= t.K)
    assert np.all(t.H_range[:, 0] <= t.H)
    assert np.all(t.H_range[:, 1] >= t.H)
    tree = cKDTree(t.points)
    for v in (0, 77, 1234):
        near = tree.query_ball_point(t.points[v], t.range_radius * 0.999)
        assert t.K_range[v, 0] <= t.K[near].min()
        assert t.K[near].max() <= t.K_range[v, 1]
        assert t.H_range[v, 0] <= t.H[near].min()
        assert t.H[near].max() <= t.H_range[v, 1]


def test_lookup_on_a_flat_model(tmp_path):
    # median |H| is 0 on a box: the K axis falls back to 1 / scale.
    idx = _index(tmp_path, trimesh.creation.box().subdivide().subdivide(), "box")
    t = idx.curvature
    assert np.isclose(t.kh_scale, idx.mesh.scale / 2)
    flat = t.lookup(0.0, 0.0, 1e-9, 1e-9)
    assert np.array_equal(flat, _brute(idx, 0.0, 0.0, 1e-9, 1e-9))
    assert (~t.crease[flat]).sum() > 100
    # the box's 12 edges are convex creases: they match any convex query with K about 0,
    # and no concave one
    assert t.crease[t.lookup(0.0, 3.0, 1e-9, 1e-9)].all()
    assert len(t.lookup(0.0, 3.0, 1e-9, 1e-9)) == t.crease.sum()
    assert len(t.lookup(0.0, -3.0, 1e-9, 1e-9)) == 0


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.nan, 0.0, 1.0, 1.0), "K must be a finite number, got nan"),
        ((0.0, np.inf, 1.0, 1.0), "H must be a finite number, got inf"),
        (("x", 0.0, 1.0, 1.0), "K must be a finite number, got 'x'"),
        ((0.0, 0.0, -1.0, 1.0), "tol_K must be a number >= 0, got -1.0"),
        ((0.0, 0.0, 1.0, np.nan), "tol_H must be a number >= 0, got nan"),
        ((0.0, 0.0, 1.0, None), "tol_H must be a number >= 0, got None"),
    ],
)
def test_lookup_errors(sphere_index, args, match):
    with pytest.raises(ValueError, match=match):
        sphere_index.curvature.lookup(*args)


# ----------------------------------------------------------------------------- distances
def test_closest_points_on_a_cube_exact(tmp_path):
    idx = _index(tmp_path, trimesh.creation.box(extents=(2, 2, 2)), "cube")
    rng = np.random.default_rng(3)
    P = rng.uniform(-3, 3, size=(500, 3))
    dist, closest, face = idx.surface.closest_points(P)
    q = np.abs(P) - 1.0
    outside = np.linalg.norm(np.maximum(q, 0), axis=1)
    inside = -np.minimum(q.max(axis=1), 0)
    assert np.allclose(dist, outside + inside, atol=1e-12)
    assert np.allclose(np.linalg.norm(P - closest, axis=1), dist)
    assert face.dtype == np.int64
    assert np.all((face >= 0) & (face < len(idx.mesh.faces)))


def test_closest_points_near_a_sphere(sphere_index):
    idx = sphere_index
    r = 2.0
    rng = np.random.default_rng(4)
    dirs = rng.normal(size=(400, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    P = dirs * rng.uniform(0.5 * r, 1.5 * r, size=(400, 1))
    dist, closest, face = idx.surface.closest_points(P)
    # The mesh lies between the sphere and the planes of its faces.
    tri = idx.mesh.vertices[idx.mesh.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inner = np.abs(np.einsum("ij,ij->i", n / np.linalg.norm(n, axis=1, keepdims=True), tri[:, 0]))
    sag = r - inner.min()
    assert np.all(np.abs(dist - np.abs(np.linalg.norm(P, axis=1) - r)) <= sag + 1e-12)
    # each closest point lies on its face
    fn = n[face] / np.linalg.norm(n[face], axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", closest - tri[face, 0], fn)).max() < 1e-12
    w = idx.surface._barycentric(closest, face)
    assert np.allclose(np.einsum("ni,nij->nj", w, tri[face]), closest, atol=1e-12)
    # no points: empty answers
    d0, c0, f0 = idx.surface.closest_points(np.zeros((0, 3)))
    assert d0.shape == (0,)
    assert c0.shape == (0, 3)
    assert f0.shape == (0,)


@pytest.mark.parametrize(
    ("points", "match"),
    [
        (np.zeros(3), r"points must have shape \(n, 3\), got \(3,\)"),
        (np.zeros((4, 2)), r"points must have shape \(n, 3\), got \(4, 2\)"),
        (np.array([[0.0, np.nan, 0.0]]), "points must be finite"),
    ],
)
def test_closest_points_errors(sphere_index, points, match):
    with pytest.raises(ValueError, match=match):
        sphere_index.surface.closest_points(points)


def test_interpolated_normals(sphere_index):
    idx = sphere_index
    rng = np.random.default_rng(5)
    P = rng.normal(size=(300, 3)) * 3
    _, closest, face = idx.surface.closest_points(P)
    normals = idx.surface.interpolated_normals(closest, face)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    radial = closest / np.linalg.norm(closest, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", normals, radial).min() > 0.9999
    # at a vertex the blend is that vertex's normal
    f = np.arange(10)
    corner = idx.mesh.faces[f, 1]
    got = idx.surface.interpolated_normals(idx.mesh.vertices[corner], f)
    assert np.allclose(got, idx.mesh.vertex_normals[corner], atol=1e-12)
    assert idx.surface.interpolated_normals(np.zeros((0, 3)), np.zeros(0, dtype=int)).shape == (
        0,
        3,
    )


def test_interpolated_normals_fall_back_on_the_face_normal_where_the_blend_vanishes():
    # Corner normals that cancel at the middle of an edge: the blend vanishes there and
    # the face's own normal is used (computed here from its corners); elsewhere the
    # blend, normalised, as np.linalg.norm would (the same bits).
    from meshrec.model.mesh import MeshData
    from meshrec.model.surface import AabbSurface, corner_normals

    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.2]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    mesh = MeshData.from_arrays(V, F)
    surface = AabbSurface.from_mesh(mesh, 30.0)
    cn = corner_normals(mesh).copy()
    cn[0, 0] = [0.0, 0.6, 0.8]
    cn[0, 1] = [0.0, -0.6, -0.8]
    mesh.__dict__["_corner_normals"] = cn  # the cache corner_normals keeps on the mesh
    p = np.array([[0.5, 0.0, 0.0], [0.2, 0.2, 0.0], [0.6, 0.6, 0.05]])
    f = np.array([0, 0, 1])
    got = surface.interpolated_normals(p, f)
    np.testing.assert_allclose(got[0], [0.0, 0.0, 1.0], atol=1e-12)
    w = surface._barycentric(p, f)
    blend = np.einsum("ni,nij->nj", w, cn[f])
    want = blend / np.linalg.norm(blend, axis=1)[:, None]
    np.testing.assert_array_equal(got[1:], want[1:])


@pytest.mark.parametrize(
    ("closest", "face", "match"),
    [
        (np.zeros((2, 2)), np.zeros(2, dtype=int), r"closest must have shape \(n, 3\)"),
        (np.zeros((2, 3)), np.zeros(3, dtype=int), r"face must have shape \(2,\), got \(3,\)"),
        (np.zeros((2, 3)), np.zeros(2), "face must hold integers, got dtype float64"),
        (np.zeros((1, 3)), np.array([10**7]), "face must index faces 0..5119"),
        (np.zeros((1, 3)), np.array([-1]), "face must index faces"),
    ],
)
def test_interpolated_normals_errors(sphere_index, closest, face, match):
    with pytest.raises(ValueError, match=match):
        sphere_index.surface.interpolated_normals(closest, face)


# ----------------------------------------------------------------------------- caching
def test_cached_load_is_equal_and_flagged(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    first = _index(tmp_path, mesh, "ball")
    second = ModelIndex.from_file(tmp_path / "ball.stl", cache_dir=tmp_path / "cache")
    assert not first.from_cache
    assert second.from_cache
    assert second.build_seconds == first.build_seconds
    a_rec, b_rec = first.to_record(), second.to_record()
    for name in IndexRecord.names():
        a, b = getattr(a_rec, name), getattr(b_rec, name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype
            assert np.array_equal(a, b, equal_nan=True), name
        else:
            assert a == b, name
    assert np.array_equal(first.mesh.face_normals, second.mesh.face_normals)
    assert np.array_equal(first.curvature.table_sites, second.curvature.table_sites)
    assert first.curvature.kh_scale == second.curvature.kh_scale
    assert second.name == "ball"
    assert len(list((tmp_path / "cache").iterdir())) == 1
    assert not second.mesh.vertices.flags.writeable
    assert "ball" in repr(second)
    # force rebuilds
    assert not ModelIndex.from_file(
        tmp_path / "ball.stl", cache_dir=tmp_path / "cache", force=True
    ).from_cache


def test_cache_rebuilds_on_changed_bytes_or_params(tmp_path):
    path = tmp_path / "thing.obj"
    trimesh.creation.icosphere(subdivisions=2).export(path)
    cache = tmp_path / "cache"
    assert not ModelIndex.from_file(path, cache_dir=cache).from_cache
    assert ModelIndex.from_file(path, cache_dir=cache).from_cache
    params = IndexParams(curvature_fraction=0.05)
    changed = ModelIndex.from_file(path, params=params, cache_dir=cache)
    assert not changed.from_cache
    assert np.isclose(changed.curvature.curvature_radius, 0.05 * changed.mesh.scale)
    assert ModelIndex.from_file(path, params=params, cache_dir=cache).from_cache
    path.write_text(path.read_text() + "\n# a comment changes the bytes\n")
    assert not ModelIndex.from_file(path, cache_dir=cache).from_cache
    assert not ModelIndex.from_file(
        path, params=IndexParams(crease_angle_deg=10.0), cache_dir=cache
    ).from_cache


def test_cached_edge_bulges_are_those_of_the_vertex_normals(tmp_path):
    # Twin: the cached bulge table equals one computed afresh from the cached normals.
    mesh = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=32)
    _index(tmp_path, mesh, "can")
    idx = ModelIndex.from_file(tmp_path / "can.stl", cache_dir=tmp_path / "cache")
    assert idx.from_cache
    fresh = AabbSurface.from_mesh(idx.mesh, idx.params.crease_angle_deg)
    bulge = idx.surface.edge_bulge
    assert np.array_equal(fresh.edge_bulge, bulge)
    # The rims are creases (90 deg between side and cap normals): no bulge there; the
    # side's edges around the circle bulge outwards by chord^2 / (8 r), up to rounding.
    assert np.count_nonzero(bulge == 0.0) > 0
    assert bulge.max() > 0.0
    with pytest.raises(ValueError, match=r"edge_bulge must have shape \(\d+, 3\), got \(3, 3\)"):
        AabbSurface(mesh=idx.mesh, edge_bulge=np.zeros((3, 3)))


def test_corrupt_cache_file_warns_and_rebuilds(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    good = _index(tmp_path, mesh, "ball")
    (entry,) = (tmp_path / "cache").iterdir()
    entry.write_bytes(entry.read_bytes()[:1000])
    with pytest.warns(CacheWarning, match="unreadable"):
        again = ModelIndex.from_file(tmp_path / "ball.stl", cache_dir=tmp_path / "cache")
    assert not again.from_cache
    assert np.array_equal(again.curvature.K, good.curvature.K)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ModelIndex.from_file(tmp_path / "ball.stl", cache_dir=tmp_path / "cache").from_cache
    assert [p.name for p in (tmp_path / "cache").iterdir()] == [entry.name]


def test_inconsistent_cache_entry_warns_and_rebuilds(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    _index(tmp_path, mesh, "ball")
    (entry,) = (tmp_path / "cache").iterdir()
    # A well-formed entry (right key and checksum) whose arrays do not fit together.
    from meshrec.model.cache import ArrayCache

    with np.load(entry) as z:
        arrays = {k: z[k] for k in z.files if not k.startswith("__")}
        key = str(z["__cache_key__"])
    arrays["k1"] = arrays["k1"][:-1]
    ArrayCache(entry.parent).save(key, arrays, label="ball")
    with pytest.warns(CacheWarning, match=r"inconsistent \(k1 must have shape"):
        idx = ModelIndex.from_file(tmp_path / "ball.stl", cache_dir=tmp_path / "cache")
    assert not idx.from_cache


def test_unwritable_cache_still_works(tmp_path):
    blocker = tmp_path / "blocker"
    blocker.write_text("not a folder")
    with pytest.warns(CacheWarning, match="continuing without caching"):
        idx = _index(
            tmp_path,
            trimesh.creation.icosphere(subdivisions=2),
            "ball",
            cache_dir=blocker / "cache",
        )
    assert not idx.from_cache
    assert idx.curvature.valid.all()


def test_read_only_cache_still_works(tmp_path, monkeypatch):
    from meshrec.io import files as files_mod  # the cache writes through write_atomic

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(files_mod.tempfile, "mkstemp", refuse)
    mesh = trimesh.creation.icosphere(subdivisions=2)
    for _ in range(2):
        with pytest.warns(CacheWarning, match="continuing without caching"):
            idx = _index(tmp_path, mesh, "ball")
        assert not idx.from_cache
        assert idx.curvature.valid.all()


def test_default_cache_dir_comes_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("MESHREC_CACHE_DIR", str(tmp_path / "envcache"))
    path = tmp_path / "models" / "ball.off"
    path.parent.mkdir()
    trimesh.creation.icosphere(subdivisions=2).export(path)
    ModelIndex.from_file(path)
    assert len(list((tmp_path / "envcache").iterdir())) == 1
    assert sorted(p.name for p in path.parent.iterdir()) == ["ball.off"]  # model folder untouched


# ----------------------------------------------------------------------------- errors
def test_from_file_errors(tmp_path):
    with pytest.raises(ValueError, match=r"params must be an IndexParams or None, got \{\}"):
        ModelIndex.from_file(tmp_path / "x.stl", params={}, cache_dir=tmp_path)
    with pytest.raises(ValueError, match=r"x\.stl.*does not exist"):
        ModelIndex.from_file(tmp_path / "x.stl", cache_dir=tmp_path)
    (tmp_path / "bad.stl").write_bytes(b"\x00" * 10)
    with pytest.raises(ValueError, match=r"bad\.stl"):
        ModelIndex.from_file(tmp_path / "bad.stl", cache_dir=tmp_path / "cache")


def test_record_checks_shapes(sphere_index):
    base = {n: getattr(sphere_index.to_record(), n) for n in IndexRecord.names()}
    n = len(base["vertices"])
    s = len(base["points"])
    with pytest.raises(ValueError, match=rf"k2 must have shape \({s},\), got \(3,\)"):
        IndexRecord(**{**base, "k2": np.zeros(3)})
    with pytest.raises(ValueError, match=rf"H_range must have shape \({s}, 2\), got \(3,\)"):
        IndexRecord(**{**base, "H_range": np.zeros(3)})
    m = len(base["faces"])
    with pytest.raises(ValueError, match=rf"face_patch must have shape \({m},\), got \(2,\)"):
        IndexRecord(**{**base, "face_patch": np.zeros(2, dtype=np.int64)})
    with pytest.raises(ValueError, match=r"vertices must have shape \(n, 3\), got \(5,\)"):
        IndexRecord(**{**base, "vertices": np.zeros(5)})
    with pytest.raises(ValueError, match="faces must hold at least one triangle"):
        IndexRecord(**{**base, "faces": np.zeros((0, 3), dtype=np.int64)})
    with pytest.raises(ValueError, match=rf"faces must index vertices 0..{n - 1}, got range"):
        IndexRecord(**{**base, "faces": base["faces"] + 1})
    with pytest.raises(ValueError, match=r"edge_bulge must have shape \(\d+, 3\)"):
        IndexRecord(**{**base, "edge_bulge": np.zeros((2, 3))})
    arrays = IndexRecord(**base).to_arrays()
    with pytest.raises(ValueError, match=r"arrays must hold \['valid'\]"):
        IndexRecord.from_arrays({k: v for k, v in arrays.items() if k != "valid"})
    with pytest.raises(ValueError, match=r"scale must be a single number, got float64 \(2,\)"):
        IndexRecord.from_arrays({**arrays, "scale": np.zeros(2)})
    for bad in ("one text", ["a", 3]):
        with pytest.raises(ValueError, match="mesh_warnings must be a sequence of str"):
            IndexRecord(**{**base, "mesh_warnings": bad})
    for bad in ("not json", '{"a": 1}'):
        with pytest.raises(ValueError, match="mesh_warnings must be a JSON list of str"):
            IndexRecord.from_arrays({**arrays, "mesh_warnings": np.array(bad)})
    said = ("a warning", "another, with 'quotes'")
    back = IndexRecord.from_arrays(IndexRecord(**{**base, "mesh_warnings": said}).to_arrays())
    assert back.mesh_warnings == said
    copy = ModelIndex.from_record(sphere_index.path, sphere_index.params, IndexRecord(**base))
    box = (0.25, 0.5, 0.01, 0.01)
    assert np.array_equal(copy.curvature.lookup(*box), sphere_index.curvature.lookup(*box))


_LENGTHS = {"spacing": 0.1, "curvature_radius": 0.3, "range_radius": 0.4}


def test_parts_check_their_inputs(sphere_index):
    mesh, table = sphere_index.mesh, sphere_index.curvature
    n = len(mesh.vertices)
    with pytest.raises(ValueError, match=rf"vertex_normals must have shape \({n}, 3\), got \(2,"):
        MeshData(mesh.vertices, mesh.faces, np.zeros((2, 3)), True, 1.0, 0.1)
    with pytest.raises(ValueError, match="faces must index vertices"):
        MeshData.from_arrays(mesh.vertices[:3], mesh.faces)
    with pytest.raises(ValueError, match="faces must hold at least one triangle"):
        MeshData.from_arrays(mesh.vertices, np.zeros((0, 3), dtype=np.int64))
    fields = {f.name: getattr(table, f.name) for f in dataclasses.fields(table) if f.init}
    s = len(table.points)
    with pytest.raises(ValueError, match=rf"dir1 must have shape \({s}, 3\), got \(3,\)"):
        CurvatureTable(**{**fields, "dir1": np.zeros(3)})
    with pytest.raises(ValueError, match=r"scale must be finite and > 0, got 0\.0"):
        CurvatureTable(**{**fields, "scale": 0.0})
    with pytest.raises(TypeError, match="mesh must be a MeshData, got Trimesh"):
        CurvatureTable.from_mesh(trimesh.creation.box(), sphere_index.surface, **_LENGTHS)
    with pytest.raises(ValueError, match=r"spacing must be finite and > 0, got 0\.0"):
        CurvatureTable.from_mesh(mesh, sphere_index.surface, **{**_LENGTHS, "spacing": 0.0})
    with pytest.raises(ValueError, match="radius must be finite and > 0, got nan"):
        CurvatureTable.from_mesh(
            mesh, sphere_index.surface, **{**_LENGTHS, "curvature_radius": np.nan}
        )
    with pytest.raises(ValueError, match=r"range_radius must be finite and >= 0, got -1\.0"):
        CurvatureTable.from_mesh(mesh, sphere_index.surface, **{**_LENGTHS, "range_radius": -1.0})
    with pytest.raises(ValueError, match=r"crease_angle_deg must be in \(0, 180\] degrees"):
        CurvatureTable.from_mesh(mesh, sphere_index.surface, **_LENGTHS, crease_angle_deg=200.0)
    with pytest.raises(TypeError, match="mesh must be a MeshData, got str"):
        AabbSurface.from_mesh("ball", 60.0)
    with pytest.raises(ValueError, match=r"crease_angle_deg must be in \(0, 180\]"):
        AabbSurface.from_mesh(mesh, 0.0)
    small = MeshData.from_arrays(*(np.asarray(a) for a in (mesh.vertices[:3], [[0, 1, 2]])))
    small_table = CurvatureTable.from_mesh(small, AabbSurface.from_mesh(small, 25.0), **_LENGTHS)
    m = len(mesh.faces)
    with pytest.raises(
        ValueError, match=rf"curvature must have one patch label per mesh face \({m}\)"
    ):
        dataclasses.replace(sphere_index, curvature=small_table)
    with pytest.raises(TypeError, match="surface must be a SurfaceQuery, got str"):
        dataclasses.replace(sphere_index, surface="fast")
    with pytest.raises(TypeError, match="record must be an IndexRecord, got dict"):
        ModelIndex.from_record(sphere_index.path, sphere_index.params, {})


def test_each_job_has_one_home(sphere_index):
    # the mesh, the curvature table and the surface queries are the index's parts; the
    # index itself holds no copy of their arrays or queries
    idx = sphere_index
    assert isinstance(idx.surface, SurfaceQuery)
    for name in ("vertices", "faces", "k1", "K", "lookup", "closest_points", "smooth_offsets"):
        assert not hasattr(idx, name), name
    assert len(idx.curvature.face_patch) == len(idx.mesh.faces)
    P = np.array([[0.0, 0.0, 3.0], [1.0, 1.0, 0.5]])
    dist, closest, _ = idx.surface.closest_points(P)
    # on the icosphere of radius 2 the distances are the radial ones up to the chord error
    assert np.allclose(dist, np.abs(np.linalg.norm(P, axis=1) - 2.0), atol=0.01)
    assert np.allclose(np.linalg.norm(closest, axis=1), 2.0, atol=0.01)
    with pytest.raises(ValueError, match="read-only"):
        idx.mesh.vertices[0, 0] = 1.0
    assert "sphere" in repr(idx)
    assert "MeshData(" in repr(idx.mesh)
    assert "CurvatureTable(" in repr(idx.curvature)
    assert "AabbSurface(" in repr(idx.surface)


def test_pickle_roundtrip_rebuilds_the_trees(sphere_index):
    copy = pickle.loads(pickle.dumps(sphere_index))
    assert copy.name == sphere_index.name
    assert copy.load_seconds == sphere_index.load_seconds
    assert np.array_equal(copy.curvature.K, sphere_index.curvature.K)
    P = np.array([[0.0, 0.0, 3.0], [1.0, 1.0, 0.5]])
    for a, b in zip(
        copy.surface.closest_points(P), sphere_index.surface.closest_points(P), strict=True
    ):
        assert np.array_equal(a, b)
    box = (0.25, 0.5, 0.01, 0.01)
    assert np.array_equal(copy.curvature.lookup(*box), sphere_index.curvature.lookup(*box))
    assert not copy.mesh.vertices.flags.writeable
    assert not copy.curvature.K.flags.writeable
    h, g = copy.surface.smooth_offsets_and_gradients(*sphere_index.surface.closest_points(P)[1:])
    h0, g0 = sphere_index.surface.smooth_offsets_and_gradients(
        *sphere_index.surface.closest_points(P)[1:]
    )
    assert np.array_equal(h, h0)
    assert np.array_equal(g, g0)


def test_barycentric_matches_a_least_squares_twin_and_clips():
    # Twin: the coordinates solving a + v (b - a) + u (c - a) = p in least squares.
    rng = np.random.default_rng(11)
    V = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.1], [0.3, 1.5, -0.2], [1.0, 0.0, 0.05]])
    F = np.array([[0, 1, 2], [0, 3, 1]])  # the second face is degenerate (collinear)
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    mesh = MeshData(V, F, normals, False, 1.0, 1.0)
    surface = AabbSurface(mesh=mesh, edge_bulge=np.zeros((2, 3)))
    w_in = rng.dirichlet([1.0, 1.0, 1.0], size=50)
    p = w_in @ V[F[0]]
    got = surface._barycentric(p, np.zeros(50, dtype=np.int64))
    M = np.column_stack([V[1] - V[0], V[2] - V[0]])
    vu = np.linalg.lstsq(M, (p - V[0]).T, rcond=None)[0].T
    twin = np.column_stack([1.0 - vu.sum(axis=1), vu])
    assert np.allclose(got, twin, atol=1e-12)
    assert np.allclose(got, w_in, atol=1e-12)
    # outside the triangle: clipped to it, still summing to 1
    out = surface._barycentric(np.array([[-1.0, -1.0, 0.0], [5.0, 5.0, 0.0]]), np.zeros(2, int))
    assert (out >= 0).all()
    assert np.allclose(out.sum(axis=1), 1.0)
    assert np.allclose(out[0], [1.0, 0.0, 0.0])
    # a degenerate face: equal weights
    assert np.allclose(surface._barycentric(V[:1], np.array([1])), 1.0 / 3.0)
    assert surface._barycentric(np.zeros((0, 3)), np.zeros(0, dtype=np.int64)).shape == (0, 3)


def test_another_surface_backend_can_replace_the_default(sphere_index):
    backend = DelegatingSurface(sphere_index.surface)
    assert isinstance(backend, SurfaceQuery)
    other = dataclasses.replace(sphere_index, surface=backend)
    P = np.array([[0.0, 0.0, 3.0]])
    assert np.array_equal(
        other.surface.closest_points(P)[0], sphere_index.surface.closest_points(P)[0]
    )
    assert backend.calls == 1
    with pytest.raises(TypeError, match="surface must be an AabbSurface to be cached"):
        other.to_record()


def test_face_rows_on_demand_are_the_whole_tables_bits():
    # Twin: every face's degeneracy and barycentric gradients computed at once for the
    # whole mesh; the surface computes them face by face as queries reach them, in any
    # order and any company, and must give the same bits (and so the same smooth heights).
    from meshrec.model.surface import _face_gradients

    mesh = trimesh.creation.icosphere(subdivisions=3)
    data = MeshData.from_arrays(mesh.vertices, mesh.faces)
    ok_all, grads_all = _face_gradients(data.vertices, data.faces)
    rng = np.random.default_rng(12)
    surface = AabbSurface.from_mesh(data, defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG)
    twin = AabbSurface.from_mesh(data, defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG)
    m = len(data.faces)
    for size in (1, 5, 200, m):
        f = rng.integers(0, m, size)
        t = surface._face_table(f)
        ok, grads = t["ok"][f], t["grads"][f]
        assert np.array_equal(ok, ok_all[f])
        assert np.array_equal(grads, grads_all[f])
    # every face now asked once at least (the last query had m draws: most of them)
    grads = surface._face_table(np.arange(m))["grads"]
    assert np.array_equal(grads, grads_all)
    # heights and gradients: the same whichever faces a surface saw first
    p = rng.normal(size=(300, 3))
    _, closest, face = surface.closest_points(p)
    got = twin.smooth_offsets_and_gradients(closest[::-1], face[::-1])
    want = surface.smooth_offsets_and_gradients(closest, face)
    assert np.array_equal(got[0][::-1], want[0])
    assert np.array_equal(got[1][::-1], want[1])
