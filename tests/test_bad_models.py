"""Bad and awkward models: broken files get a clear error (and are skipped with a warning
inside a library), while real-world meshes with defects index and recognise correctly.

The "works" cases check the curvature table against the known sphere curvature, so a
defect that poisoned the table (flipped faces, libigl failures) would show.
"""

from __future__ import annotations

import os
import re
import subprocess
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_bad_touch import assert_one_line_error, run_cli

from meshrec import (
    IndexParams,
    ModelIndex,
    ModelLibrary,
    lookup_candidates,
    recognize,
    simulate_touch,
)
from meshrec.model.library import LibraryWarning


# ----------------------------------------------------------------------------- makers
def _sphere(subdivisions=3, radius=1.0) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def _export(mesh: trimesh.Trimesh, path: Path) -> Path:
    mesh.export(path)
    return path


def _truncated_binary_stl(path: Path) -> Path:
    data = _sphere(2).export(file_type="stl")  # 320 faces: 84 + 50 * 320 = 16084 bytes
    path.write_bytes(data[: len(data) // 2])
    return path


def _truncated_ascii_stl(path: Path) -> Path:
    text = trimesh.exchange.stl.export_stl_ascii(_sphere(1))
    path.write_text(text[: len(text) // 2])
    return path


def _obj_cut_in_a_vertex(path: Path) -> Path:
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0.5 0.5")
    return path


def _obj_bad_index(path: Path) -> Path:
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    return path


def _obj_nan_vertex(path: Path) -> Path:
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nv 1 1 1\nf 1 2 3\nf 1 2 4\n")
    return path


def _truncated_ply(path: Path) -> Path:
    data = _sphere(2).export(file_type="ply")
    path.write_bytes(data[: len(data) // 2])
    return path


def _point_cloud(path: Path) -> Path:
    trimesh.PointCloud(np.random.default_rng(0).random((50, 3))).export(path)
    return path


def _garbage(path: Path) -> Path:
    path.write_bytes(bytes(range(256)) * 8)
    return path


def _empty(path: Path) -> Path:
    path.write_bytes(b"")
    return path


def _degenerate_only(path: Path) -> Path:
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n")
    return path


def _unreadable(path: Path) -> Path:
    if os.geteuid() != 0:
        _sphere(1).export(path)
        path.chmod(0)
    else:  # root reads any file whatever its mode: a file whose read fails instead
        path.symlink_to("/proc/self/mem")
    return path


#: name -> (file name, maker, message pattern)
BROKEN = {
    "truncated_binary_stl": (
        "half.stl",
        _truncated_binary_stl,
        r"half\.stl' could not be read: a truncated binary STL: its header announces 320 "
        r"triangles \(16084 bytes\), the file has 8042 bytes",
    ),
    "truncated_ascii_stl": (
        "cut.stl",
        _truncated_ascii_stl,
        r"cut\.stl' could not be read: an ASCII STL without its closing 'endsolid' line",
    ),
    "obj_cut_in_a_vertex": (
        "cut.obj",
        _obj_cut_in_a_vertex,
        r"cut\.obj': vertices must be \(n, 3\), got \(3, 2\) \(truncated\?\)",
    ),
    "obj_face_index_out_of_range": (
        "index.obj",
        _obj_bad_index,
        # the file's own terms: its line and 1-based index (trimesh's IndexError was
        # 0-based and named no line)
        r"index\.obj' could not be read: line 5: a face refers to vertex 9, and the file "
        r"has 3 vertices \(OBJ indices count from 1",
    ),
    "obj_nan_vertex": ("nan.obj", _obj_nan_vertex, r"nan\.obj' has non-finite vertex"),
    "truncated_ply": ("half.ply", _truncated_ply, r"half\.ply' could not be read"),
    "point_cloud": (
        "cloud.ply",
        _point_cloud,
        r"cloud\.ply' holds no triangle mesh \(got PointCloud\): 50 points and no faces",
    ),
    "garbage_stl": ("junk.stl", _garbage, r"junk\.stl' could not be read"),
    "garbage_obj": ("junk.obj", _garbage, r"junk\.obj' (could not be read|holds no faces)"),
    "empty_off": ("empty.off", _empty, r"empty\.off' is empty \(0 bytes\)"),
    "degenerate_only": ("flat.obj", _degenerate_only, r"flat\.obj' holds only degenerate faces"),
    "unreadable": ("locked.stl", _unreadable, r"cannot read file '[^']*locked\.stl': "),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_mesh_file_raises_naming_the_file_and_problem(tmp_path, name):
    file_name, make, pattern = BROKEN[name]
    path = make(tmp_path / file_name)
    with pytest.raises(ValueError, match=pattern) as info:
        ModelIndex.from_file(path, cache_dir=tmp_path / "cache")
    assert info.type is ValueError
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def test_broken_files_are_skipped_with_a_warning_in_a_library(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    _export(_sphere(), folder / "ball.stl")
    for name in ("truncated_binary_stl", "point_cloud", "obj_cut_in_a_vertex"):
        file_name, make, _ = BROKEN[name]
        make(folder / file_name)
    (folder / "notes.txt").write_text("not a mesh")
    (folder / "part.step").write_text("ISO-10303-21;")
    with pytest.warns(LibraryWarning) as record:
        lib = ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    assert lib.names == ("ball",)
    skipped = {p.name: why for p, why in lib.skipped}
    assert set(skipped) == {"half.stl", "cloud.ply", "cut.obj", "notes.txt", "part.step"}
    assert "truncated binary STL" in skipped["half.stl"]
    assert "no faces" in skipped["cloud.ply"]
    assert skipped["part.step"].startswith("not a mesh file (ending '.step'")
    assert len(record) == 5
    assert all(str(w.message).startswith("skipping ") for w in record)


def test_empty_folder_and_folder_without_meshes(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    pattern = r"empty' holds no mesh file \(\.stl, \.obj, \.ply, \.off\)$"
    with pytest.raises(ValueError, match=pattern):
        ModelLibrary.from_folder(empty, cache_dir=tmp_path / "cache")
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match=r"docs' holds no mesh file .*; it holds notes\.txt"):
        ModelLibrary.from_folder(docs, cache_dir=tmp_path / "cache")


# ----------------------------------------------------------------------------- CLI
#: The broken models also run through ``meshrec index`` (the interpreter start is slow).
CLI_BROKEN = ["truncated_binary_stl", "obj_cut_in_a_vertex", "point_cloud", "unreadable"]


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory):
    """``meshrec index`` on folders of bad models, all started together."""
    root = tmp_path_factory.mktemp("bad_models")
    env = {**os.environ, "MESHREC_CACHE_DIR": str(root / "cache")}
    folders = {}
    for name in ("empty", "mixed", *CLI_BROKEN):
        folders[name] = root / name
        folders[name].mkdir()
    _export(_sphere(), folders["mixed"] / "ball.stl")
    _truncated_binary_stl(folders["mixed"] / "half.stl")
    (folders["mixed"] / "notes.txt").write_text("x")
    for name in CLI_BROKEN:
        file_name, make, _ = BROKEN[name]
        make(folders[name] / file_name)
    with ThreadPoolExecutor(max_workers=3) as pool:
        futures = {
            name: pool.submit(run_cli, ["index", "--models", str(folder)], env, root)
            for name, folder in folders.items()
        }
        return {name: f.result() for name, f in futures.items()}


def assert_index_error(proc, pattern: str) -> None:
    """Exit status 2, no traceback, one error line; ``index`` also reports its progress."""
    progress = [ln for ln in proc.stderr.splitlines() if ln.startswith("indexing ")]
    assert all(re.fullmatch(r"indexing \d+/\d+: \S+( \([a-z ]+\))?", ln) for ln in progress)
    errors = "".join(ln + "\n" for ln in proc.stderr.splitlines() if ln not in progress)
    rest = subprocess.CompletedProcess(proc.args, proc.returncode, proc.stdout, errors)
    assert_one_line_error(rest, pattern)


@pytest.mark.slow
@pytest.mark.parametrize("name", CLI_BROKEN)
def test_cli_index_of_a_broken_model_exits_2_with_one_line(cli_runs, name):
    assert_index_error(cli_runs[name], "no loadable mesh in .*" + BROKEN[name][2])


@pytest.mark.slow
def test_cli_index_of_an_empty_folder(cli_runs):
    assert_one_line_error(cli_runs["empty"], r"empty' holds no mesh file")


@pytest.mark.slow
def test_cli_index_skips_bad_files_with_warnings(cli_runs):
    proc = cli_runs["mixed"]
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    warned = [ln for ln in proc.stderr.splitlines() if ln.startswith("meshrec: warning: ")]
    # the ball (an icosphere of subdivision 3) is also too coarse: its own line
    coarse = [w for w in warned if "too coarse for reliable answers" in w]
    assert [w.split()[2] for w in coarse] == ["ball:"]
    warned = [w for w in warned if w not in coarse]
    assert len(warned) == 2
    assert any("half.stl" in w and "truncated binary STL" in w for w in warned)
    assert any("notes.txt" in w and "not a mesh file" in w for w in warned)
    assert [ln.split()[0] for ln in proc.stdout.splitlines()] == ["ball"]


# ----------------------------------------------------------------------------- meshes that work
def _index(tmp_path, mesh_or_text, name, suffix=".ply") -> ModelIndex:
    path = tmp_path / f"{name}{suffix}"
    if isinstance(mesh_or_text, str):
        path.write_text(mesh_or_text)
    else:
        mesh_or_text.export(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none of these is worth a warning
        return ModelIndex.from_file(path, cache_dir=tmp_path / "cache")


def _radius_1_curvature_ok(idx: ModelIndex, where=None, rtol=0.08) -> None:
    """On a unit sphere with outward normals, H = 1 and K = 1 at the curvature sites
    (those whose points satisfy ``where``). Measured on the 1280-face sphere: relative
    errors up to 5.8e-2 (H) and 0.113 (K)."""
    t = idx.curvature
    mask = np.ones(len(t.points), bool) if where is None else where(t.points)
    assert mask.sum() > 100
    assert t.valid[mask].all()
    assert np.allclose(t.H[mask], 1.0, rtol=rtol)
    assert np.allclose(t.K[mask], 1.0, rtol=2 * rtol)


def test_degenerate_duplicate_faces_and_unreferenced_vertices(tmp_path):
    clean = _sphere()
    V = np.vstack([clean.vertices, [[5.0, 5.0, 5.0], [6.0, 6.0, 6.0]]])  # unreferenced
    F = np.vstack(
        [
            clean.faces,
            clean.faces[:40],  # exact duplicates
            clean.faces[40:80, ::-1],  # duplicates with the other winding
            [[0, 0, 1], [2, 3, 3]],  # repeated vertex
        ]
    )
    mid = 0.5 * (V[clean.faces[0, 0]] + V[clean.faces[0, 1]])
    V = np.vstack([V, mid])  # a zero-area face on an edge
    F = np.vstack([F, [[clean.faces[0, 0], len(V) - 1, clean.faces[0, 1]]]])
    dirty = trimesh.Trimesh(V, F, process=False)
    idx = _index(tmp_path, dirty, "dirty")
    ref = _index(tmp_path, clean, "clean")
    assert len(idx.mesh.vertices) == len(clean.vertices)
    assert len(idx.mesh.faces) == len(clean.faces)
    assert idx.mesh.closed
    np.testing.assert_allclose(np.sort(idx.curvature.H), np.sort(ref.curvature.H), rtol=1e-9)
    _radius_1_curvature_ok(idx)


def test_several_components(tmp_path):
    small = _sphere(radius=0.5)
    small.apply_translation([3.0, 0.0, 0.0])
    idx = _index(tmp_path, trimesh.util.concatenate([_sphere(), small]), "two")
    assert idx.mesh.closed
    _radius_1_curvature_ok(idx, lambda p: p[:, 0] < 1.5)
    # radius 0.5 (the curvature fit spans twice the angle on the small sphere)
    small_sites = idx.curvature.points[:, 0] > 1.5
    assert small_sites.sum() > 20
    assert np.allclose(idx.curvature.H[small_sites], 2.0, rtol=0.08)


def test_open_boundary(tmp_path):
    sphere = _sphere(4)
    keep = sphere.triangles_center[:, 2] > 0.0
    cap = trimesh.Trimesh(sphere.vertices, sphere.faces[keep])
    idx = _index(tmp_path, cap, "cap")
    assert not idx.mesh.closed
    # away from the rim, where the fit is one-sided
    _radius_1_curvature_ok(idx, lambda p: p[:, 2] > 0.3)
    t = idx.curvature
    assert np.isfinite(t.K[t.table_sites]).all()
    assert np.isfinite(t.H[t.table_sites]).all()


def test_non_manifold_edge(tmp_path):
    sphere = _sphere()
    n = len(sphere.vertices)
    fin_v = [[2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [2.0, 0.0, 1.0], [2.0, -1.0, 0.5], [3.0, 0.5, 0.0]]
    fin_f = [[n, n + 1, n + 2], [n, n + 1, n + 3], [n + 1, n, n + 4]]  # edge (n, n+1) x3
    mesh = trimesh.Trimesh(np.vstack([sphere.vertices, fin_v]), np.vstack([sphere.faces, fin_f]))
    idx = _index(tmp_path, mesh, "fin")
    assert (np.linalg.norm(idx.mesh.vertices, axis=1) < 1.5).sum() == n
    _radius_1_curvature_ok(idx, lambda p: np.linalg.norm(p, axis=1) < 1.5)
    assert not idx.mesh.closed
    table = idx.curvature.lookup(0.0, 0.0, np.inf, np.inf)
    assert np.isfinite(idx.curvature.K[table]).all()


def test_inside_out_closed_mesh_is_turned_outward(tmp_path):
    sphere = _sphere()
    sphere.invert()
    assert sphere.volume < 0
    idx = _index(tmp_path, sphere, "inside_out", suffix=".stl")
    outward = np.einsum("ij,ij->i", idx.mesh.vertex_normals, idx.mesh.vertices)
    assert (outward > 0.99).all()
    _radius_1_curvature_ok(idx)


@pytest.mark.parametrize("closed", [True, False])
def test_randomly_flipped_faces_are_made_consistent(tmp_path, closed):
    sphere = _sphere(4)
    faces = sphere.faces if closed else sphere.faces[sphere.triangles_center[:, 2] > -0.2]
    flip = np.random.default_rng(1).random(len(faces)) < 0.3
    faces = faces.copy()
    faces[flip] = faces[flip, ::-1]
    mesh = trimesh.Trimesh(sphere.vertices, faces, process=False)
    assert not mesh.is_winding_consistent
    idx = _index(tmp_path, mesh, f"flipped_{closed}")
    t = idx.curvature
    inner = t.points[:, 2] > 0.1 if not closed else np.ones(len(t.points), bool)
    sign = 1.0 if closed else np.sign(np.median(t.H[inner]))  # an open one keeps a side
    assert np.allclose(sign * t.H[inner], 1.0, rtol=0.08)
    assert trimesh.Trimesh(idx.mesh.vertices, idx.mesh.faces, process=False).is_winding_consistent


@pytest.mark.parametrize("scale", [1e-12, 1e12])
def test_any_unit_size(tmp_path, scale):
    # an absolute merge tolerance merges a tiny model away, and overflows on a huge one
    sphere = _sphere()
    sphere.apply_scale(scale)
    idx = _index(tmp_path, sphere, "scaled")
    assert len(idx.mesh.vertices) == len(sphere.vertices)
    assert np.allclose(idx.curvature.H, 1.0 / scale, rtol=0.08)
    assert not idx.curvature.crease.any()


def test_flat_and_sharp_models_do_not_poison_the_table(tmp_path):
    # a tetrahedron (flat faces and sharp edges only: flat and crease sites), and a sphere
    # with a loose triangle far away (its sites are too few to fit: invalid)
    folder = tmp_path / "models"
    folder.mkdir()
    tetrahedron = trimesh.Trimesh(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    )
    _export(tetrahedron, folder / "tet.stl")
    island = trimesh.Trimesh([[10, 0, 0], [10.05, 0, 0], [10, 0.05, 0]], [[0, 1, 2]])
    _export(trimesh.util.concatenate([_sphere(), island]), folder / "ball.ply")
    lib = ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    tet = lib["tet"].curvature
    assert tet.valid.mean() > 0.99  # a few sites in the corners have too few neighbours
    flat = tet.valid & ~tet.crease
    assert np.abs(tet.H[flat]).max() < 1e-9
    assert tet.crease.sum() > 6
    ball = lib["ball"].curvature
    far = np.linalg.norm(ball.points, axis=1) > 5
    assert far.any()
    assert not ball.valid[far].any()
    assert np.isfinite(ball.K[ball.table_sites]).all()
    touch = simulate_touch(_sphere(), rng=2).touch
    rec = recognize(touch, lib)
    assert rec.best.model == "ball"
    # The (K, H) lookup itself finds no tet site for a sphere's touch: neither its flat
    # sites (K = H = 0) nor its crease sites reach the sphere's K = H = 1. (The
    # recognition's later passes may widen the window: see test_verdict.)
    assert lookup_candidates(touch, lib["tet"], rec.geometry).raw_hits == 0
    assert lookup_candidates(touch, lib["ball"], rec.geometry).raw_hits > 0


def test_a_model_without_a_usable_curvature_is_reported(tmp_path):
    # A curvature fit radius below the site spacing leaves no site with neighbours to fit:
    # the library says that no touch will match the model.
    folder = tmp_path / "models"
    folder.mkdir()
    _export(_sphere(), folder / "ball.stl")
    params = IndexParams(curvature_fraction=1e-4)
    with pytest.warns(LibraryWarning, match=r"'ball'.*no surface site has a usable curvature"):
        lib = ModelLibrary.from_folder(folder, params=params, cache_dir=tmp_path / "cache")
    assert not lib["ball"].curvature.valid.any()


def test_faces_collapsed_by_single_precision_far_from_the_origin_warn(tmp_path):
    # An STL stores float32: a fine ellipsoid moved to 1e6 has its coordinates in steps
    # of 0.0625, coarser than its 0.03 edges, and most faces collapse to zero area. The
    # loss is said, with its cause; the same mesh near the origin, and duplicated faces
    # (which lose nothing), give no warning.
    from meshrec.model.mesh import MeshWarning, load_mesh

    egg = trimesh.creation.icosphere(subdivisions=5)
    egg.apply_scale([1.0, 0.8, 0.6])
    egg.export(tmp_path / "near.stl")
    twice = trimesh.Trimesh(egg.vertices, np.vstack([egg.faces, egg.faces]), process=False)
    twice.export(tmp_path / "twice.ply")
    egg.apply_translation([1e6, 1e6, 1e6])
    egg.export(tmp_path / "far.stl")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(load_mesh(tmp_path / "near.stl")[1]) == 20480
        assert len(load_mesh(tmp_path / "twice.ply")[1]) == 20480
    with pytest.warns(
        MeshWarning,
        match=r"far\.stl'?: \d+ of its 20480 faces have no area .*single precision .*steps "
        r"are 0\.0625",
    ):
        _, faces = load_mesh(tmp_path / "far.stl")
    assert len(faces) < 10000


def test_single_precision_steps_coarse_against_the_edges_are_warned_about(tmp_path):
    # A black-box probe (stop 36): a YCB scan saved as STL 1e4 m from the origin had
    # coordinate steps of 0.98 mm, 37% of its median edge; only 0.7% of its faces
    # collapsed (under MESH_LOST_FACES_WARN), and wrong answers came without a word. The
    # steps are now said whenever they pass MESH_QUANTUM_WARN of the median edge.
    from meshrec.model.mesh import MeshWarning, load_mesh

    egg = trimesh.creation.icosphere(subdivisions=4)
    egg.apply_scale([1.0, 0.8, 0.6])
    egg.export(tmp_path / "near.stl")
    egg.apply_translation([1.5e5, -1.5e5, 7.5e4])  # steps of 0.0156, edges about 0.06
    egg.export(tmp_path / "far.stl")
    egg.export(tmp_path / "far.obj")  # the same coordinates in double precision
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_mesh(tmp_path / "near.stl")
        load_mesh(tmp_path / "far.obj")
    with pytest.warns(MeshWarning, match=r"far\.stl'?: its coordinates are single precision"):
        load_mesh(tmp_path / "far.stl")
    with pytest.warns(MeshWarning, match=r"steps are 0\.0156, \d+% of its median edge"):
        load_mesh(tmp_path / "far.stl")


def test_mesh_warnings_are_said_again_from_the_cache_and_the_pack(tmp_path):
    # A warning said only when the index is built is easily missed (a setup script built
    # the cache; the robot's process loads it): each cached load says it again.
    from meshrec.model.index import ModelIndex
    from meshrec.model.library import ModelLibrary
    from meshrec.model.mesh import MeshWarning

    folder = tmp_path / "models"
    folder.mkdir()
    egg = trimesh.creation.icosphere(subdivisions=4)
    egg.apply_scale([1.0, 0.8, 0.6])
    egg.apply_translation([1.5e5, -1.5e5, 7.5e4])  # steps of 0.0156 (see above)
    egg.export(folder / "far.stl")
    trimesh.creation.icosphere(subdivisions=3).export(folder / "ball.stl")
    cache = tmp_path / "cache"
    for what in ("built", "cached"):
        with pytest.warns(MeshWarning, match="single precision") as said:
            model = ModelIndex.from_file(folder / "far.stl", cache_dir=cache)
        assert model.from_cache is (what == "cached")
        assert len([w for w in said if issubclass(w.category, MeshWarning)]) == 1
        assert model.mesh_warnings == (str(said[0].message),)
        assert model.to_record().mesh_warnings == model.mesh_warnings
    ModelLibrary.from_folder(folder, cache_dir=cache)  # writes the pack
    with pytest.warns(MeshWarning, match="far.stl.*single precision"):
        packed = ModelLibrary.from_folder(folder, cache_dir=cache)
    assert (cache / "packs").is_dir()
    assert packed["far"].mesh_warnings == model.mesh_warnings
    assert packed["ball"].mesh_warnings == ()
