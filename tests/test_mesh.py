"""Tests for meshrec.model.mesh: loading and cleaning mesh files."""

import os

import numpy as np
import pytest
import trimesh

from meshrec.model import mesh as mesh_mod
from meshrec.model.mesh import MESH_SUFFIXES, check_mesh_path, is_mesh_file, load_mesh


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=2)


@pytest.mark.parametrize("suffix", MESH_SUFFIXES)
def test_load_every_format(tmp_path, sphere, suffix):
    path = tmp_path / f"ball{suffix}"
    sphere.export(path)
    V, F = load_mesh(path)
    assert V.dtype == np.float64
    assert F.dtype == np.int64
    assert V.flags["C_CONTIGUOUS"]
    assert F.flags["C_CONTIGUOUS"]
    # STL stores three vertices per face: they must have been merged back.
    assert V.shape == sphere.vertices.shape
    assert F.shape == sphere.faces.shape
    assert np.allclose(np.linalg.norm(V, axis=1), 1.0)


def test_load_uppercase_suffix_and_str_path(tmp_path, sphere):
    path = tmp_path / "BALL.STL"
    sphere.export(path, file_type="stl")
    _, F = load_mesh(str(path))
    assert len(F) == len(sphere.faces)


def test_load_cleans_degenerate_duplicate_and_unreferenced(tmp_path):
    text = "\n".join(
        [
            "v 0 0 0",
            "v 1 0 0",
            "v 0 1 0",
            "v 0 0 1",
            "v 2 0 0",  # collinear with vertices 1 and 2 along x: degenerate face
            "v 9 9 9",  # unreferenced
            "f 1 3 2",
            "f 1 2 4",
            "f 1 4 3",
            "f 2 3 4",
            "f 2 4 3",  # same face, other winding: a duplicate
            "f 1 2 5",  # zero area
            "f 1 3 2",  # exact duplicate
        ]
    )
    path = tmp_path / "dirty.obj"
    path.write_text(text + "\n")
    V, F = load_mesh(path)
    assert F.shape == (4, 3)
    assert V.shape == (4, 3)
    assert set(np.unique(F)) == {0, 1, 2, 3}
    assert not np.any(np.all(V == 9.0, axis=1))


def test_suffixes_and_is_mesh_file():
    assert set(MESH_SUFFIXES) == {".stl", ".obj", ".ply", ".off"}
    assert is_mesh_file("a/b.OBJ")
    assert not is_mesh_file("notes.txt")
    assert not is_mesh_file("stl")


def test_error_missing_file(tmp_path):
    path = tmp_path / "nothing.stl"
    with pytest.raises(ValueError, match=r"nothing\.stl.*does not exist"):
        load_mesh(path)


def test_error_directory(tmp_path):
    path = tmp_path / "folder.stl"
    path.mkdir()
    with pytest.raises(ValueError, match=r"folder\.stl.*is a directory"):
        load_mesh(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_error_not_a_regular_file(tmp_path):
    path = tmp_path / "pipe.stl"
    os.mkfifo(path)
    with pytest.raises(ValueError, match=r"pipe\.stl.*not a regular file"):
        check_mesh_path(path)


def test_error_unsupported_suffix(tmp_path, sphere):
    path = tmp_path / "ball.glb"
    sphere.export(path)
    with pytest.raises(ValueError, match=r"ball\.glb.*unsupported ending '\.glb'"):
        load_mesh(path)


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("junk.stl", b"\x00\x01garbage" * 10),
        ("junk.obj", b"hello world\nthis is not an obj\n"),
        ("junk.ply", b"hello"),
        ("junk.off", b"hello"),
        ("empty.stl", b""),
        ("empty.obj", b""),
    ],
)
def test_error_garbage_content(tmp_path, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    pattern = rf"{name.replace('.', '[.]')}.*(could not be read|no faces|is empty)"
    with pytest.raises(ValueError, match=pattern):
        load_mesh(path)


def test_error_point_cloud(tmp_path):
    path = tmp_path / "cloud.ply"
    rng = np.random.default_rng(0)
    trimesh.PointCloud(rng.random((20, 3))).export(path)
    with pytest.raises(ValueError, match=r"cloud\.ply.*no faces"):
        load_mesh(path)


def test_error_vertices_only(tmp_path):
    path = tmp_path / "verts.off"
    path.write_text("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n")
    with pytest.raises(ValueError, match=r"verts\.off.*no faces"):
        load_mesh(path)


def test_error_only_degenerate_faces(tmp_path):
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n")
    with pytest.raises(ValueError, match=r"flat\.obj.*(degenerate|no faces)"):
        load_mesh(path)


def test_error_not_a_trimesh(tmp_path, monkeypatch):
    path = tmp_path / "thing.obj"
    path.write_text("v 0 0 0\n")
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: trimesh.PointCloud(np.eye(3)))
    with pytest.raises(ValueError, match=r"thing\.obj.*no triangle mesh \(got PointCloud\)"):
        load_mesh(path)


def test_error_non_finite_vertices(tmp_path, monkeypatch):
    # trimesh itself drops non-finite vertices; the check guards other loaders.
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\n")
    bad = trimesh.Trimesh(
        vertices=[[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], faces=[[0, 1, 2]], process=False
    )
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: bad)
    with pytest.raises(ValueError, match=r"nan\.obj.*non-finite"):
        load_mesh(path)


def test_parse_mesh_parses_the_bytes_it_is_given(tmp_path, sphere):
    path = tmp_path / "ball.ply"
    sphere.export(path)
    data = path.read_bytes()
    path.unlink()  # the name only gives the format: the file is not opened
    V, F = mesh_mod.parse_mesh(data, path)
    assert len(F) == len(sphere.faces)
    assert np.allclose(np.sort(V, axis=0), np.sort(sphere.vertices, axis=0))


def test_parse_mesh_errors(tmp_path):
    with pytest.raises(TypeError, match="data must be bytes, got str"):
        mesh_mod.parse_mesh("v 0 0 0", tmp_path / "x.obj")
    with pytest.raises(ValueError, match=r"x\.glb' has unsupported ending '\.glb'"):
        mesh_mod.parse_mesh(b"glTF", tmp_path / "x.glb")
    with pytest.raises(ValueError, match=r"x\.stl' is empty \(0 bytes\)"):
        mesh_mod.parse_mesh(b"", tmp_path / "x.stl")


@pytest.mark.parametrize("func", [load_mesh, check_mesh_path])
def test_a_path_that_is_not_a_path_names_the_argument(func):
    # it raised pathlib's own "expected str, bytes or os.PathLike object, not int"
    with pytest.raises(TypeError, match=r"path must be a str or os\.PathLike, got int"):
        func(5)
