"""The resolution check (meshrec.model.resolution): analytic answers, the flags, the
``meshrec index`` / ``meshrec models`` output and the recognition's warning."""

from __future__ import annotations

import itertools
import json
import math
import warnings

import numpy as np
import pytest
import trimesh

from meshrec import defaults, simulate_touch
from meshrec.app.cli import main
from meshrec.model.curvature import CurvatureTable
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.mesh import MeshData
from meshrec.model.resolution import (
    Resolution,
    ResolutionWarning,
    coarse_message,
    mesh_resolution,
)
from meshrec.model.surface import AabbSurface
from meshrec.recognition.recognize import recognize


def _mesh(tm: trimesh.Trimesh) -> MeshData:
    return MeshData.from_arrays(tm.vertices, tm.faces)


def _tube(r: float, k: int, rings: int = 40, height: float = 4.0) -> MeshData:
    """An open cylinder of radius r in k sections with many rings (radial normals)."""
    phi = 2 * np.pi * np.arange(k) / k
    z = np.linspace(0.0, height, rings)
    V = np.array([[r * math.cos(p), r * math.sin(p), zz] for zz in z for p in phi])
    F = []
    for j in range(rings - 1):
        for i in range(k):
            a, b = j * k + i, j * k + (i + 1) % k
            F += [[a, b, b + k], [a, b + k, a + k]]
    return MeshData.from_arrays(V, np.array(F))


def test_icosphere_edges_and_chord_error_shrink_with_subdivision():
    res = [mesh_resolution(_mesh(trimesh.creation.icosphere(k))) for k in range(1, 6)]
    medians = [r.edge_median for r in res]
    assert all(a > b for a, b in itertools.pairwise(medians))
    assert all(r.edge_p90 >= r.edge_median for r in res)
    # Subdivision 1 has every edge beyond the crease angle (its normals differ by about
    # 36 degrees): no smooth surface is implied there, so its chord error is 0.
    chords = [r.chord_error for r in res[1:]]
    assert all(a > b > 0 for a, b in itertools.pairwise(chords))
    # the sagitta of a chord L on a unit sphere is about L^2 / 8
    assert res[-1].chord_error == pytest.approx(res[-1].edge_p90 ** 2 / 8, rel=0.3)


@pytest.mark.parametrize("k", [24, 48, 96])
def test_chord_error_of_a_cylinder_is_its_sagitta(k):
    r = 3.0
    res = mesh_resolution(_tube(r, k))
    assert res.chord_error == pytest.approx(r * (1 - math.cos(math.pi / k)), rel=0.02)
    assert res.chord_fraction == pytest.approx(res.chord_error / res.curve_length)


def test_default_curve_length_and_vertices_per_curve():
    mesh = _mesh(trimesh.creation.icosphere(4))
    res = mesh_resolution(mesh)
    assert res.curve_length == pytest.approx(defaults.SIM_LENGTH_FRACTION * mesh.scale)
    assert res.vertices_per_curve == pytest.approx(res.curve_length / res.edge_median)
    assert math.isnan(res.curvature_min)
    assert math.isnan(res.curvature_max)
    longer = mesh_resolution(mesh, curve_length=2 * res.curve_length)
    assert longer.vertices_per_curve == pytest.approx(2 * res.vertices_per_curve)


def _table(mesh):
    spacing, radius, range_radius = IndexParams().lengths(mesh.scale)
    surface = AabbSurface.from_mesh(mesh, defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG)
    return CurvatureTable.from_mesh(
        mesh, surface, spacing=spacing, curvature_radius=radius, range_radius=range_radius
    )


def test_curvature_range_from_the_table():
    mesh = _mesh(trimesh.creation.icosphere(4, radius=2.0))
    res = mesh_resolution(mesh, curvature=_table(mesh))
    assert res.curvature_min == pytest.approx(0.5, rel=0.08)
    assert res.curvature_max == pytest.approx(0.5, rel=0.08)


def test_cad_cylinder_is_flagged_and_a_fine_sphere_is_not():
    cad = mesh_resolution(_mesh(trimesh.creation.cylinder(radius=10, height=40, sections=32)))
    assert cad.too_coarse
    assert cad.vertices_per_curve < defaults.RESOLUTION_MIN_VERTICES_PER_CURVE
    assert cad.sliver_fraction > defaults.RESOLUTION_MAX_SLIVER_FRACTION
    assert any("crosses about" in s for s in cad.reasons)
    assert any("long thin triangles" in s for s in cad.reasons)
    fine = mesh_resolution(_mesh(trimesh.creation.icosphere(5)))
    assert not fine.too_coarse
    assert fine.reasons == ()
    assert fine.sliver_fraction == 0.0
    assert fine.chord_fraction < defaults.RESOLUTION_MAX_CHORD_FRACTION


def test_chord_error_alone_can_flag():
    # a coarse 16-section tube next to a fine sphere: short edges on the curved faces, and
    # the tube's large chord error
    tube = _tube(1.0, 16, rings=3, height=2.0)
    grid = trimesh.creation.icosphere(5, radius=1.0)
    V = np.vstack([tube.vertices, np.asarray(grid.vertices) + np.array((5.0, 0.0, 0.0))])
    F = np.vstack([tube.faces, np.asarray(grid.faces) + len(tube.vertices)])
    res = mesh_resolution(MeshData.from_arrays(V, F), curve_length=1.0)
    assert res.vertices_per_curve >= defaults.RESOLUTION_MIN_VERTICES_PER_CURVE
    assert res.chord_fraction > defaults.RESOLUTION_MAX_CHORD_FRACTION
    assert res.too_coarse
    assert len(res.reasons) == 1
    assert "smooth surface" in res.reasons[0]


def test_raises():
    mesh = _mesh(trimesh.creation.icosphere(2))
    with pytest.raises(TypeError, match="mesh must be a MeshData"):
        mesh_resolution("mesh.stl")
    with pytest.raises(TypeError, match="curvature must be a CurvatureTable"):
        mesh_resolution(mesh, curvature=np.zeros(3))
    for bad in (0.0, -1.0, math.nan, math.inf, True, "1"):
        with pytest.raises(ValueError, match="curve_length must be a finite number > 0"):
            mesh_resolution(mesh, curve_length=bad)
    other = _mesh(trimesh.creation.icosphere(3))
    with pytest.raises(ValueError, match="curvature must have one patch label per mesh face"):
        mesh_resolution(mesh, curvature=_table(other))
    fine = mesh_resolution(_mesh(trimesh.creation.icosphere(5)))
    with pytest.raises(ValueError, match="resolution must be too coarse"):
        coarse_message("ico", fine)
    with pytest.raises(TypeError, match="resolution must be a Resolution"):
        coarse_message("ico", {"too_coarse": True})


def test_flat_faces_are_exact_however_few():
    # a 12-triangle box is its own surface: no vertex count, no sliver, no chord error
    box = mesh_resolution(_mesh(trimesh.creation.box(extents=(40.0, 30.0, 20.0))))
    assert box.curved_fraction == 0.0
    assert box.vertices_per_curve < defaults.RESOLUTION_MIN_VERTICES_PER_CURVE
    assert box.sliver_fraction == 0.0
    assert box.chord_error == 0.0
    assert not box.too_coarse
    # a long thin flat plate (every face a sliver) with a coarse 16-section tube beside it:
    # only the tube's faces are curved and counted
    plate = trimesh.creation.box(extents=(40.0, 1.0, 0.1))
    tube = _tube(1.0, 16, rings=2, height=40.0)
    V = np.vstack([tube.vertices, np.asarray(plate.vertices) + np.array((5.0, 0.0, 0.0))])
    F = np.vstack([tube.faces, np.asarray(plate.faces) + len(tube.vertices)])
    res = mesh_resolution(MeshData.from_arrays(V, F), curve_length=1.0)
    tube_area = 2 * np.pi * 40.0 * np.sin(np.pi / 16) * 16 / np.pi  # 16 flat strips
    plate_area = plate.area
    assert res.curved_fraction == pytest.approx(tube_area / (tube_area + plate_area), rel=1e-6)
    # the tube's strips run its full height: slivers; the plate's are not counted
    assert res.sliver_fraction == pytest.approx(res.curved_fraction, rel=1e-9)


def test_resolution_is_frozen():
    res = mesh_resolution(_mesh(trimesh.creation.icosphere(2)))
    assert isinstance(res, Resolution)
    with pytest.raises(AttributeError):
        res.too_coarse = False


@pytest.fixture
def coarse_folder(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.cylinder(radius=10, height=40, sections=32).export(folder / "cad_cyl.stl")
    trimesh.creation.icosphere(5, radius=10).export(folder / "fine_ball.stl")
    return folder


def test_index_warns_once_per_coarse_model(coarse_folder, tmp_path, capsys):
    cache = tmp_path / "cache"
    assert main(["index", "--models", str(coarse_folder), "--cache-dir", str(cache)]) == 0
    err = capsys.readouterr().err.splitlines()
    lines = [ln for ln in err if "too coarse" in ln]
    assert len(lines) == 1, err
    assert lines[0].startswith(
        "meshrec: warning: cad_cyl: too coarse for reliable answers: a touch curve"
    )
    assert "subdivide_to_size" in lines[0]


def test_models_shows_the_resolution(coarse_folder, capsys):
    assert main(["models", str(coarse_folder), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    by = {m["name"]: m for m in doc["models"]}
    assert by["cad_cyl"]["too_coarse"]
    assert by["cad_cyl"]["coarse_reasons"]
    assert not by["fine_ball"]["too_coarse"]
    assert by["fine_ball"]["coarse_reasons"] == []
    assert by["fine_ball"]["vertices_per_curve"] > defaults.RESOLUTION_MIN_VERTICES_PER_CURVE
    for key in ("chord_error", "sliver_fraction"):
        assert isinstance(by["cad_cyl"][key], float)
    assert main(["models", str(coarse_folder)]) == 0
    rows = {ln.split()[0]: ln for ln in capsys.readouterr().out.splitlines()}
    assert rows["cad_cyl"].endswith("too coarse")
    assert not rows["fine_ball"].endswith("too coarse")
    assert "per curve" in rows["model"]


def test_recognition_warns_when_the_plausible_model_is_coarse(tmp_path):
    coarse = trimesh.creation.icosphere(3, radius=10.0)  # 5.2 vertices per curve
    path = tmp_path / "ball.stl"
    coarse.export(path)
    model = ModelIndex.from_file(path, cache_dir=tmp_path / "cache")
    assert model.resolution.too_coarse
    assert model.resolution is model.resolution  # computed once
    sim = simulate_touch(coarse, rng=3, noise=1e-3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = recognize(sim.touch, [model])
    assert rec.best is not None
    assert rec.best.model == "ball"
    texts = [t for t in rec.warnings if "too coarse for reliable answers" in t]
    assert texts == [coarse_message("ball", model.resolution)]
    assert any(issubclass(w.category, ResolutionWarning) for w in caught)


def test_several_coarse_plausible_models_give_one_warning(tmp_path):
    # two copies of a coarse ball: both plausible, one warning naming both (a probe,
    # stop 34, got a line per plausible bracket, ten on one flat touch)
    coarse = trimesh.creation.icosphere(3, radius=10.0)
    models = []
    for name in ("ball", "ball_copy"):
        coarse.export(tmp_path / f"{name}.stl")
        models.append(ModelIndex.from_file(tmp_path / f"{name}.stl", cache_dir=tmp_path / "c"))
    sim = simulate_touch(coarse, rng=3, noise=1e-3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = recognize(sim.touch, models)
    assert set(rec.plausible) == {"ball", "ball_copy"}
    texts = [t for t in rec.warnings if "too coarse for reliable answers" in t]
    assert len(texts) == 1
    first, other = rec.plausible
    assert texts[0].startswith(coarse_message(first, models[0].resolution).split(":")[0])
    assert f"also too coarse: {other}" in texts[0]
    assert sum(issubclass(w.category, ResolutionWarning) for w in caught) == 1
