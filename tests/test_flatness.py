"""The prior of a flat touch (meshrec.recognition.flatness): analytic shares of boxes and
cylinders, the clipping, the recognition's use of it and its errors."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import trimesh

from meshrec import defaults, simulate_touch
from meshrec.app.cli import main
from meshrec.model.index import ModelIndex
from meshrec.recognition.flatness import flat_prior, flat_share, flat_tolerance
from meshrec.recognition.recognize import recognize
from meshrec.recognition.scoring import posterior
from meshrec.registration.register import touch_geometry

BOX = (2.0, 1.5, 1.0)


def _model(tmp_path, name: str, mesh: trimesh.Trimesh) -> ModelIndex:
    path = tmp_path / f"{name}.stl"
    mesh.export(path)
    return ModelIndex.from_file(path, cache_dir=tmp_path / "cache")


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("flat")
    return {
        "box": _model(tmp, "box", trimesh.creation.box(extents=BOX)),
        "cylinder": _model(
            tmp, "cylinder", trimesh.creation.cylinder(radius=1.0, height=3.0, sections=64)
        ),
        "ball": _model(tmp, "ball", trimesh.creation.icosphere(4, radius=1.0)),
    }


def _box_share(reach: float) -> float:
    """Where a disc of radius ``reach`` fits on the box's faces, over its whole area."""
    a, b, c = BOX
    faces = ((a, b), (a, c), (b, c))
    inner = 2 * sum(max(x - 2 * reach, 0) * max(y - 2 * reach, 0) for x, y in faces)
    return inner / (2 * (a * b + a * c + b * c))


def _cylinder_share(reach: float) -> float:
    """Where such a disc fits on the unit cylinder's caps (height 3), over its area."""
    return 2 * math.pi * (1.0 - reach) ** 2 / (2 * math.pi + 2 * math.pi * 3.0)


@pytest.mark.parametrize("reach", [0.3, 0.4, 0.6])
def test_share_of_a_box_is_its_faces_shrunk_by_the_reach(models, reach):
    # the sites next to an edge are not flat (their curvature fit reaches over it): the
    # share erodes by up to two site spacings more than the reach
    delta = 2 * models["box"].curvature.spacing
    share = flat_share(models["box"], 0.05, reach)
    assert _box_share(reach + delta) <= share <= _box_share(reach) * 1.02


@pytest.mark.parametrize("reach", [0.3, 0.4, 0.6])
def test_share_of_a_cylinder_is_its_caps_shrunk_by_the_reach(models, reach):
    delta = 2 * models["cylinder"].curvature.spacing
    share = flat_share(models["cylinder"], 0.05, reach)
    assert _cylinder_share(reach + delta) <= share <= _cylinder_share(reach) * 1.02


def test_a_curved_model_has_no_flat_share_and_a_plane_is_all_flat(models, tmp_path):
    assert flat_share(models["ball"], 0.05, 0.3) == 0.0
    grid = trimesh.creation.box(extents=(2.0, 2.0, 1.0))
    top = grid.faces[grid.face_normals[:, 2] > 0.5]
    plane = _model(tmp_path, "plane", trimesh.Trimesh(grid.vertices, top))
    assert flat_share(plane, 0.05, 0.3) == 1.0


def test_touch_is_flat_on_a_plane_and_not_on_a_small_sphere(models):
    box = trimesh.creation.box(extents=(4.0, 4.0, 4.0)).subdivide_to_size(0.05)
    flat = simulate_touch(box, rng=2, noise=1e-3, length=0.6, contact=(0.1, 0.2, 2.0))
    assert flat_tolerance(touch_geometry(flat.touch)) is not None
    ball = simulate_touch(trimesh.creation.icosphere(5, radius=1.0), rng=2, noise=1e-3)
    assert flat_tolerance(touch_geometry(ball.touch)) is None
    assert flat_prior(ball.touch, touch_geometry(ball.touch), list(models.values())) is None


def test_prior_is_the_shares_clipped(models):
    box = trimesh.creation.box(extents=(4.0, 4.0, 4.0)).subdivide_to_size(0.05)
    sim = simulate_touch(box, rng=2, noise=1e-3, length=0.6, contact=(0.1, 0.2, 2.0))
    g = touch_geometry(sim.touch)
    lib = [models["box"], models["cylinder"], models["ball"]]
    prior = flat_prior(sim.touch, g, lib)
    reach = float(np.max(np.linalg.norm(sim.touch.points - g.point, axis=1)))
    tol = flat_tolerance(g)
    shares = [flat_share(m, tol, reach) for m in lib]
    assert shares[2] == 0.0
    assert shares[0] > shares[1] > 0.0
    top = max(shares)
    assert prior == pytest.approx([shares[0], max(shares[1], top / 4), top / 4])
    assert prior.max() / prior.min() <= defaults.FLAT_PRIOR_MAX_RATIO + 1e-12


def test_flat_touch_ranks_the_flattest_model_first_and_keeps_the_rest_plausible(models):
    box = trimesh.creation.box(extents=BOX).subdivide_to_size(0.02)
    # on the largest face, away from its edges: the box's face and the cylinder's caps fit
    sim = simulate_touch(box, rng=5, noise=1e-3, length=0.6, contact=(0.1, 0.05, 0.5))
    lib = [models["cylinder"], models["box"]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = recognize(sim.touch, lib)
    assert rec.best.model == "box"
    assert rec.verdict == "ambiguous"
    assert set(rec.plausible) == {"box", "cylinder"}
    assert any("a flat touch" in w for w in rec.warnings)
    # the probabilities are the likelihoods times the prior (a brute-force twin)
    prior = flat_prior(sim.touch, rec.geometry, [models[s.model] for s in rec.scores])
    expected = posterior([s.log_likelihood for s in rec.scores], prior)
    assert [s.probability for s in rec.scores] == pytest.approx(expected)


def test_curved_touch_gets_no_prior(models):
    sim = simulate_touch(trimesh.creation.icosphere(5, radius=1.0), rng=4, noise=1e-3)
    rec = recognize(sim.touch, list(models.values()))
    assert rec.best.model == "ball"
    assert not any("a flat touch" in w for w in rec.warnings)
    expected = posterior([s.log_likelihood for s in rec.scores])
    assert [s.probability for s in rec.scores] == pytest.approx(expected)


def test_raises(models):
    sim = simulate_touch(trimesh.creation.icosphere(3), rng=1)
    g = touch_geometry(sim.touch)
    with pytest.raises(TypeError, match="geometry must be"):
        flat_tolerance("flat")
    with pytest.raises(TypeError, match="model must be"):
        flat_share("box.stl", 0.1, 0.3)
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="tolerance must be a finite number >= 0"):
            flat_share(models["box"], bad, 0.3)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="reach must be a finite number > 0"):
            flat_share(models["box"], 0.1, bad)
    with pytest.raises(TypeError, match="touch must be"):
        flat_prior(sim.touch.points, g, [models["box"]])
    with pytest.raises(TypeError, match="geometry must be"):
        flat_prior(sim.touch, None, [models["box"]])


def test_cli_prints_the_flat_note(tmp_path, capsys):
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.box(extents=BOX).export(folder / "box.stl")
    trimesh.creation.cylinder(radius=1.0, height=3.0, sections=64).export(folder / "can.stl")
    real = tmp_path / "real_box.stl"
    trimesh.creation.box(extents=BOX).subdivide_to_size(0.02).export(real)
    touch = tmp_path / "touch.json"
    assert main(["simulate", str(real), "-o", str(touch), "--seed", "8"]) == 0
    cache = ["--cache-dir", str(tmp_path / "cache")]
    capsys.readouterr()
    assert main(["recognize", str(touch), "--models", str(folder), *cache]) == 0
    out = capsys.readouterr().out
    notes = [ln for ln in out.splitlines() if ln.startswith("note: a flat touch")]
    assert len(notes) == 1, out
    assert "box 1" in notes[0]
    assert out.strip().splitlines()[-1].startswith("ambiguous: box or can")
    assert main(["recognize", str(touch), "--models", str(folder), "--json", *cache]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert any(w.startswith("a flat touch") for w in doc["warnings"])
