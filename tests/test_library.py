"""Tests for meshrec.model.library: folders of models and the bundled libraries."""

import warnings

import pytest
import trimesh

from meshrec.model import library as library_mod
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.library import LibraryWarning, ModelLibrary, bundled_models_dir


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "models"
    d.mkdir()
    trimesh.creation.icosphere(subdivisions=2).export(d / "ball.stl")
    trimesh.creation.box().subdivide().export(d / "Box.obj")
    cyl = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=24)
    cyl.export(d / "can.ply")
    (d / "README.txt").write_text("not a model")  # skipped with a warning: no mesh ending
    (d / ".DS_Store").write_bytes(b"\x00\x01")  # hidden: ignored silently
    (d / "sub").mkdir()  # not recursive: skipped with a warning, as it holds a mesh
    trimesh.creation.icosphere(subdivisions=1).export(d / "sub" / "hidden.stl")
    (d / "empty").mkdir()  # no mesh in it: ignored silently
    (d / "gone.stl").symlink_to(d / "nowhere.stl")  # a broken link: skipped with a warning
    return d


def test_from_folder(folder, tmp_path, recwarn):
    calls = []
    lib = ModelLibrary.from_folder(
        folder, cache_dir=tmp_path / "cache", progress=lambda i, n, name: calls.append((i, n, name))
    )
    assert [str(w.message) for w in recwarn] == [
        f"skipping {str(folder / 'README.txt')!r}: not a mesh file (ending '.txt', expected "
        ".stl, .obj, .ply, .off)",
        f"skipping {str(folder / 'gone.stl')!r}: a link to a file that does not exist",
        f"skipping {str(folder / 'sub')!r}: a sub-folder holding 1 mesh file(s); sub-folders "
        "are not searched (give it as a model folder of its own)",
    ]
    assert recwarn[0].category is LibraryWarning
    assert lib.folder == folder
    assert lib.names == ("Box", "ball", "can")
    assert [m.name for m in lib] == list(lib.names)
    assert len(lib) == 3
    assert lib["ball"].path == folder / "ball.stl"
    assert isinstance(lib["can"], ModelIndex)
    assert "can" in lib
    assert "nope" not in lib
    assert [(p.name, why.split(" (")[0].split(";")[0]) for p, why in lib.skipped] == [
        ("README.txt", "not a mesh file"),
        ("gone.stl", "a link to a file that does not exist"),
        ("sub", "a sub-folder holding 1 mesh file(s)"),
    ]
    stages = ["loading the mesh", "curvature", "writing the cache", "trees"]
    assert calls == [
        (i, 3, label)
        for i, name in enumerate(["Box", "ball", "can"])
        for label in [name, *(f"{name} ({s})" for s in stages)]
    ]
    assert "ball" in repr(lib)
    with pytest.raises(TypeError, match=r"looked up by its name \(a str\), got int"):
        lib[0]
    with pytest.raises(KeyError, match="no model named 'nope'"):
        lib["nope"]
    # everything cached now, and loading from the cache reports no stages; the model
    # folder is untouched
    calls.clear()
    again = ModelLibrary.from_folder(
        folder, cache_dir=tmp_path / "cache", progress=lambda i, n, name: calls.append((i, n, name))
    )
    assert all(m.from_cache for m in again)
    assert calls == [(0, 3, "Box"), (1, 3, "ball"), (2, 3, "can")]
    assert sorted(p.name for p in folder.iterdir()) == [
        ".DS_Store",
        "Box.obj",
        "README.txt",
        "ball.stl",
        "can.ply",
        "empty",
        "gone.stl",
        "sub",
    ]
    forced = ModelLibrary.from_folder(
        folder,
        params=IndexParams(curvature_fraction=0.05),
        cache_dir=tmp_path / "cache",
        force=True,
    )
    assert not any(m.from_cache for m in forced)
    assert all(m.params.curvature_fraction == 0.05 for m in forced)


def test_bad_and_duplicate_files_are_skipped_with_warnings(folder, tmp_path):
    (folder / "broken.stl").write_bytes(b"\x00garbage" * 5)
    trimesh.creation.icosphere(subdivisions=1).export(folder / "ball.off")  # same name
    with pytest.warns(LibraryWarning) as record:
        lib = ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    messages = [str(w.message) for w in record]
    assert any("broken.stl" in m for m in messages)
    assert any("ball.stl" in m and "duplicate model name 'ball'" in m for m in messages)
    assert lib.names == ("Box", "ball", "can")
    assert lib["ball"].path.name == "ball.off"  # sorted: ball.off comes first
    skipped = {p.name: why for p, why in lib.skipped}
    assert set(skipped) == {"README.txt", "broken.stl", "ball.stl", "gone.stl", "sub"}
    assert "could not be read" in skipped["broken.stl"] or "no faces" in skipped["broken.stl"]


def test_from_files(folder, tmp_path):
    lib = ModelLibrary.from_files(
        [folder / "can.ply", str(folder / "ball.stl")], cache_dir=tmp_path / "cache"
    )
    assert lib.folder is None
    assert lib.names == ("ball", "can")
    with pytest.warns(LibraryWarning, match=r"missing\.stl.*does not exist"):
        lib = ModelLibrary.from_files(
            [folder / "missing.stl", folder / "ball.stl"], cache_dir=tmp_path / "cache"
        )
    assert lib.names == ("ball",)
    assert lib.skipped[0][0].name == "missing.stl"


def test_from_files_errors(folder, tmp_path):
    with pytest.raises(ValueError, match="paths must name at least one mesh file, got none"):
        ModelLibrary.from_files([], cache_dir=tmp_path / "cache")
    with pytest.raises(ValueError, match="paths must be an iterable of paths, got a single path"):
        ModelLibrary.from_files(str(folder / "ball.stl"), cache_dir=tmp_path / "cache")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"no loadable mesh in the given files: nope\.stl"):
            ModelLibrary.from_files([folder / "nope.stl"], cache_dir=tmp_path / "cache")
    with pytest.raises(ValueError, match="params must be an IndexParams or None, got 3"):
        ModelLibrary.from_files([folder / "ball.stl"], params=3, cache_dir=tmp_path / "cache")


def test_folder_errors(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"model folder '.*empty' holds no mesh file"):
        ModelLibrary.from_folder(empty, cache_dir=tmp_path / "cache")
    (empty / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="holds no mesh file"):
        ModelLibrary.from_folder(empty, cache_dir=tmp_path / "cache")
    with pytest.raises(ValueError, match=r"model folder '.*missing' does not exist"):
        ModelLibrary.from_folder(tmp_path / "missing", cache_dir=tmp_path / "cache")
    a_file = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=1).export(a_file)
    with pytest.raises(ValueError, match=r"model folder '.*ball\.stl' is not a directory"):
        ModelLibrary.from_folder(a_file, cache_dir=tmp_path / "cache")


def test_folder_with_no_loadable_mesh(tmp_path):
    d = tmp_path / "junk"
    d.mkdir()
    (d / "a.stl").write_bytes(b"")
    (d / "b.ply").write_text("nope")
    # one error naming every file and its problem, and no warning per file before it
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"no loadable mesh in .*junk: a\.stl: .*; b\.ply: "):
            ModelLibrary.from_folder(d, cache_dir=tmp_path / "cache")


def test_bundled_models_dir_prefers_the_installed_copy(tmp_path, monkeypatch):
    installed = tmp_path / "pkg" / "_bundled_models"
    repo = tmp_path / "repo" / "models"
    (repo / "surfaces").mkdir(parents=True)
    (repo / "objects").mkdir(parents=True)
    monkeypatch.setattr(library_mod, "_bundled_roots", lambda: (installed, repo))
    assert bundled_models_dir() == repo / "surfaces"
    assert bundled_models_dir("objects") == repo / "objects"
    (installed / "surfaces").mkdir(parents=True)
    assert bundled_models_dir("surfaces") == installed / "surfaces"
    with pytest.raises(
        ValueError, match="no bundled model library named 'cars'; available: objects, surfaces"
    ):
        bundled_models_dir("cars")


def test_bundled_models_dir_errors(tmp_path, monkeypatch):
    monkeypatch.setattr(library_mod, "_bundled_roots", lambda: (tmp_path / "a", tmp_path / "b"))
    with pytest.raises(ValueError, match="available: none"):
        bundled_models_dir("surfaces")
    for bad in ["", "..", "a/b", None]:
        with pytest.raises(ValueError, match="name must be a plain library name"):
            bundled_models_dir(bad)


def test_bundled_roots_point_at_the_package_and_the_repo():
    installed, repo = library_mod._bundled_roots()
    assert installed.name == "_bundled_models"
    assert installed.parent.name == "meshrec"
    assert repo == installed.parents[1] / "models"


def test_a_folder_whose_models_are_one_level_down_says_so(tmp_path):
    # no mesh in the folder itself, two in a sub-folder: the error names the sub-folder
    # and that it is not searched
    top = tmp_path / "models"
    (top / "parts").mkdir(parents=True)
    for name in ("a", "b"):
        trimesh.creation.icosphere(subdivisions=1).export(top / "parts" / f"{name}.stl")
    with pytest.raises(
        ValueError,
        match=r"holds no mesh file .*parts/ \(2 mesh files\); "
        r"sub-folders are not searched: give one as the folder",
    ):
        ModelLibrary.from_folder(top, cache_dir=tmp_path / "cache")


def test_size_outliers_flag_a_model_in_other_units():
    from meshrec.model.library import size_outliers

    # YCB-like scans in m and one in mm (the probe's case): only it, 1,110 times larger
    (k, ratio), *rest = size_outliers([0.2, 0.25, 0.15, 0.28, 222.0])
    assert (k, rest) == (4, [])
    assert ratio == pytest.approx(222.0 / 0.25)
    # two models 1,000 times apart: each is flagged against the other
    assert size_outliers([1.0, 1000.0]) == [(0, 0.001), (1, 1000.0)]
    # a 10 mm screw beside a 1.5 m frame (150 times) is left alone, as is a lone model
    assert size_outliers([0.01, 1.5, 0.4]) == []
    assert size_outliers([5.0]) == []
    for bad in ([1.0, 0.0], [1.0, float("nan")], [-1.0, 2.0]):
        with pytest.raises(ValueError, match="sizes must be positive finite numbers"):
            size_outliers(bad)


def test_a_model_in_other_units_is_warned_about_on_loading(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    for k, scale in enumerate([1.0, 1.3, 0.8]):
        egg = trimesh.creation.icosphere(subdivisions=3)
        egg.apply_scale([scale, 0.8, 0.6])
        egg.export(folder / f"egg{k}.stl")
    big = trimesh.creation.icosphere(subdivisions=3)
    big.apply_scale(1000.0)
    big.export(folder / "ball_mm.stl")
    with pytest.warns(
        LibraryWarning,
        match=r"'ball_mm' \(size 3\d{3}, the square root of its area\) is 1\.\d+e\+03 times",
    ):
        ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    (folder / "ball_mm.stl").unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
