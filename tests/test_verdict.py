"""The verdict on real recognitions: recognised, ambiguous, unknown; the CLI's keys and exits."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.bench import paper_touch
from meshrec.recognition import jobs as jobs_module
from meshrec.recognition import passes as passes_module
from meshrec.registration.register import touch_geometry

MODELS = Path(__file__).resolve().parents[1] / "models"
SCRIPT = Path(sys.executable).with_name("meshrec")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="module")
def surfaces(cache):
    return meshrec.ModelLibrary.from_folder(MODELS / "surfaces", cache_dir=cache)


@pytest.fixture(scope="module")
def small_sphere_touch():
    """A touch on a sphere of radius 0.1: curvature 10, unlike every paper surface."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.1)
    return meshrec.simulate_touch(sphere, length=0.2, noise=0.001, rng=5).touch


def test_a_paper_touch_is_recognised_with_calibrated_fields(surfaces):
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    rec = meshrec.recognize(sim.touch, surfaces)
    assert rec.verdict == "recognised"
    assert rec.plausible == ("ellipsoid",)
    assert rec.best.model == "ellipsoid"
    assert "ellipsoid" in rec.reason
    # the noise estimate: uniform noise of half-width 0.001 has deviation 0.001 / sqrt(3)
    assert rec.noise == pytest.approx(1e-3 / math.sqrt(3.0), rel=0.2)
    # one score per ranking entry, in ranking order, probabilities summing to 1
    assert [s.model for s in rec.scores] == [r.model for r in rec.ranking]
    assert sum(s.probability for s in rec.scores) == pytest.approx(1.0)
    assert rec.probabilities["ellipsoid"] > 1.0 - defaults.VERDICT_COVERAGE
    top = rec.scores[0]
    assert sum(p.weight for p in top.poses) == pytest.approx(1.0)
    np.testing.assert_array_equal(top.poses[0].T_model_touch, rec.best.T_model_touch)
    # the rms is the RMS of the point-to-surface distances at that pose
    pts = meshrec.registration.transform.apply_transform(rec.best.T_model_touch, sim.touch.points)
    dist, _, _ = surfaces["ellipsoid"].surface.closest_points(pts)
    assert top.rms == pytest.approx(float(np.sqrt(np.mean(dist**2))), rel=0.05)
    assert "verdict='recognised'" in repr(rec)
    assert rec.scoring_seconds < 0.1 * rec.seconds


def test_two_copies_of_a_model_are_ambiguous(tmp_path, cache):
    folder = tmp_path / "twins"
    folder.mkdir()
    shutil.copy(MODELS / "surfaces" / "ellipsoid.stl", folder / "left.stl")
    shutil.copy(MODELS / "surfaces" / "ellipsoid.stl", folder / "right.stl")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    sim = meshrec.simulate_touch(library["left"], rng=24)
    rec = meshrec.recognize(sim.touch, library)
    assert rec.verdict == "ambiguous"
    assert set(rec.plausible) == {"left", "right"}
    p = rec.probabilities
    assert p["left"] == pytest.approx(p["right"], abs=0.1)


def test_a_shape_outside_the_library_is_unknown(surfaces, small_sphere_touch):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(small_sphere_touch, surfaces)
    assert rec.verdict == "unknown"
    assert rec.plausible == ()
    assert "not in the library" in rec.reason
    # it looked harder (a widened lookup) before concluding
    assert rec.widened_seconds > 0
    assert rec.phase_times.widened > 0
    assert rec.phase_times.best_first == 0.0  # one touch: no joint phase
    assert any("widened" in w for w in rec.warnings)
    # no paper surface has a site this curved even in the widened window, so the dense
    # pass skips them all, and the caution does not claim it (a probe, stop 34, read the
    # claim on an answer given in 26 ms): a denser look at the same window rejects them
    assert rec.phase_times.dense == 0.0
    assert not any(f"{defaults.LOOKUP_DENSE_CANDIDATES} candidates" in w for w in rec.warnings)
    assert all(r.rejected for r in rec.ranking)
    for m in surfaces:
        dense = meshrec.register(
            small_sphere_touch,
            m,
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
            max_candidates=defaults.LOOKUP_DENSE_CANDIDATES,
        )
        assert dense.rejected


def test_each_model_keeps_its_best_fit_of_the_harder_looks(objects):
    """A touch on a torus (tube radius 10) fits no model of the objects: every model is
    registered again with the widened lookup, then with more candidates, and keeps the best
    of its fits (checked against those registrations made directly: the brute-force twin).
    """
    torus = trimesh.creation.torus(30, 10, major_sections=96, minor_sections=48)
    touch = meshrec.simulate_touch(torus, length=25, noise=0.05, rng=11).touch
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touch, objects)
        wide = {
            m.name: meshrec.register(touch, m, lookup_scale=defaults.LOOKUP_WIDEN_SCALE)
            for m in objects
        }
        dense = {
            m.name: meshrec.register(
                touch,
                m,
                lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
                max_candidates=defaults.LOOKUP_DENSE_CANDIDATES,
            )
            for m in objects
        }
    assert any(f"{defaults.LOOKUP_DENSE_CANDIDATES} candidates" in w for w in rec.warnings)
    assert rec.verdict == "unknown"
    assert all(not r.rejected for r in rec.ranking)
    for reg in rec.ranking:
        assert reg.error <= min(wide[reg.model].error, dense[reg.model].error)
    # the denser look found a better fit somewhere (else this test would not tell)
    assert any(dense[m].error < wide[m].error for m in objects.names)


def test_a_denser_look_where_the_window_held_fewer_sites_than_the_cap_changes_nothing(surfaces):
    """The premise of the dense pass's skip: a model whose widened lookup chose fewer
    candidates than ``defaults.MAX_CANDIDATES`` gets the same candidates, and the same
    fit, with the dense cap (the spreading stops by its spacing, not by the cap)."""
    touch = paper_touch(surfaces["ellipsoid"], 1).touch
    model = surfaces["crossed_trough"]
    wide = meshrec.register(touch, model, lookup_scale=defaults.LOOKUP_WIDEN_SCALE)
    dense = meshrec.register(
        touch,
        model,
        lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        max_candidates=defaults.LOOKUP_DENSE_CANDIDATES,
    )
    assert 0 < wide.candidates < defaults.MAX_CANDIDATES  # else this test would not tell
    assert dense.candidates == wide.candidates
    assert dense.error == wide.error
    np.testing.assert_array_equal(dense.T_model_touch, wide.T_model_touch)


@pytest.mark.parametrize(
    ("cascade", "module", "name"),
    [(False, jobs_module, "register"), (True, passes_module, "cascade_register")],
)
def test_warnings_raised_inside_are_kept_and_passed_on(
    surfaces, monkeypatch, cascade, module, name
):
    real = getattr(module, name)

    def noisy(*args, **kwargs):
        warnings.warn("a test warning from register", UserWarning, stacklevel=2)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, noisy)
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    with pytest.warns(UserWarning, match="a test warning from register"):
        rec = meshrec.recognize(sim.touch, surfaces, cascade=cascade)
    assert rec.warnings.count("a test warning from register") == 1


def test_register_refuses_a_bad_lookup_scale(surfaces):
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    with pytest.raises(ValueError, match="lookup_scale"):
        meshrec.register(sim.touch, surfaces["ellipsoid"], lookup_scale=0.0)
    # a flag given as a string was taken as true
    with pytest.raises(TypeError, match="trace must be a bool, got str"):
        meshrec.register(sim.touch, surfaces["ellipsoid"], trace="yes")


def test_a_wider_lookup_finds_at_least_as_many_candidates(surfaces):
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    narrow = meshrec.register(sim.touch, surfaces["elliptic_paraboloid"], lookup_scale=0.25)
    wide = meshrec.register(sim.touch, surfaces["elliptic_paraboloid"], lookup_scale=4.0)
    assert wide.raw_hits >= narrow.raw_hits
    assert wide.raw_hits > 0


# ------------------------------------------------------------------ the console script
def _run(args, env, cwd):
    return subprocess.run(
        [str(SCRIPT), *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def env(cache):
    return {**os.environ, "MESHREC_CACHE_DIR": str(cache)}


def test_cli_unknown_exits_1_and_still_prints_the_json(tmp_path, env, small_sphere_touch):
    small_sphere_touch.to_file(tmp_path / "touch.csv")
    proc = _run(["recognize", "touch.csv", "--json"], env, tmp_path)
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["verdict"] == "unknown"
    assert doc["plausible"] == []
    assert "not in the library" in doc["reason"]
    assert any("widened" in w for w in doc["warnings"])
    assert doc["noise"] > 0
    # no model had a candidate contact even in the widened lookup: none is probable
    assert doc["best"] is None
    assert all(e["probability"] == 0.0 for e in doc["ranking"])
    assert all("reason" in e for e in doc["ranking"])
    # the table says the same, with the same exit status
    proc = _run(["recognize", "touch.csv"], env, tmp_path)
    assert proc.returncode == 1
    assert proc.stdout.splitlines()[-1].startswith("unknown: no model could be registered")
    assert any("not in the library" in line for line in proc.stdout.splitlines())


def test_cli_recognised_shows_probabilities_and_exits_0(tmp_path, env, surfaces):
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    sim.touch.to_file(tmp_path / "touch.csv")
    proc = _run(["recognize", "touch.csv"], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert "prob." in lines[1]
    assert lines[2].split()[1:3] == ["ellipsoid", lines[2].split()[2]]
    assert float(lines[2].split()[2]) > 1.0 - defaults.VERDICT_COVERAGE
    assert lines[-1].startswith("recognised: ellipsoid")
    proc = _run(["recognize", "touch.csv", "--json"], env, tmp_path)
    doc = json.loads(proc.stdout)
    assert (doc["verdict"], doc["plausible"], doc["best"]) == (
        "recognised",
        ["ellipsoid"],
        "ellipsoid",
    )
    # the ellipsoid's symmetric twins are distinct poses of (nearly) equal weight; the
    # reported transform is the first, best-fitting one
    poses = doc["ranking"][0]["poses"]
    assert sum(p["weight"] for p in poses) == pytest.approx(1.0)
    assert poses[0]["transform"] == doc["ranking"][0]["transform"]
    assert poses[0]["weight"] == pytest.approx(max(p["weight"] for p in poses))
    assert len(poses) >= 2
    weights = sorted((p["weight"] for p in poses), reverse=True)
    assert weights[0] <= 2.0 * weights[1]  # the two heaviest: nearly equal, not one and zero
    # and they are twins: each pose is the first turned by a symmetry of the ellipsoid
    T0 = np.array(poses[0]["transform"])
    turns = meshrec.symmetry_rotations("ellipsoid")
    for p in poses[1:]:
        D = np.array(p["transform"]) @ np.linalg.inv(T0)
        assert min(np.abs(D[:3, :3] - S).max() for S in turns) < 1e-3
        np.testing.assert_allclose(D[:3, 3], 0.0, atol=1e-3)  # about the model's centre


def test_cli_library_warnings_reach_the_json(tmp_path, env, surfaces):
    folder = tmp_path / "models"
    folder.mkdir()
    shutil.copy(MODELS / "surfaces" / "ellipsoid.stl", folder / "ellipsoid.stl")
    (folder / "broken.stl").write_text("not a mesh")
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=24)
    sim.touch.to_file(tmp_path / "touch.csv")
    proc = _run(["recognize", "touch.csv", "--json", "--models", str(folder)], env, tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert any("broken" in w for w in doc["warnings"]), doc["warnings"]
    assert "broken" in proc.stderr  # and still printed as before


def test_a_misfit_far_above_the_noise_is_unknown(surfaces):
    # a sphere of radius 0.2: candidates exist on the ellipsoid, but no pose fits
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.2)
    touch = meshrec.simulate_touch(sphere, length=0.3, noise=0.001, rng=5).touch
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touch, surfaces)
    assert rec.verdict == "unknown"
    assert rec.best is not None
    assert rec.scores[0].rms > defaults.UNKNOWN_FIT_RATIO * rec.noise
    assert "times the noise" in rec.reason
    assert sum(s.probability for s in rec.scores) == pytest.approx(1.0)


def test_a_touch_across_an_edge_carries_the_rough_fit_caution(tmp_path, cache):
    box = trimesh.creation.box(extents=[2.0, 2.0, 2.0])
    for _ in range(5):
        box = box.subdivide()
    box.export(tmp_path / "box.stl")
    library = meshrec.ModelLibrary.from_folder(tmp_path, cache_dir=cache)
    # 0.1 from the box's top edge: the curves, 0.6 long, run over it onto the side
    sim = meshrec.simulate_touch(library["box"], rng=1, contact=[0.9, 0.0, 1.0], noise=1e-3)
    with pytest.warns(meshrec.RoughFitWarning):
        rec = meshrec.recognize(sim.touch, library)
    assert any("fit no smooth surface patch" in w for w in rec.warnings)  # the warning
    assert any("probabilities are less reliable" in w for w in rec.warnings)  # the caution


def test_an_inward_normal_hint_is_named_in_an_unknown_reason(tmp_path):
    # a unit sphere (convex everywhere, H = 1 with the outward normal): the touch's true
    # outward normal as the hint is recognised; minus it (a sign slip) makes the patch
    # concave (H = -1), which nothing on a sphere matches: `unknown`, and the reason says
    # the normal may point inwards instead of only "not in the library"
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.icosphere(subdivisions=5, radius=1.0).export(folder / "ball.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    sim = meshrec.simulate_touch(lib["ball"], length=0.4, noise=0.001, rng=11)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        right = meshrec.recognize(sim.touch.with_hints(normal=sim.normal_touch), lib)
        wrong = meshrec.recognize(sim.touch.with_hints(normal=-sim.normal_touch), lib)
    assert right.verdict == "recognised"
    assert "check its sign" not in right.reason
    assert abs(wrong.geometry.H + 1.0) < 0.1
    assert wrong.verdict == "unknown"
    assert "the normal given with the touch makes the surface concave" in wrong.reason
    assert "check its sign" in wrong.reason


def test_repeated_samples_are_counted_once(surfaces):
    # every sample logged ten times (a logger ten times faster than its sensor): the
    # third differences and fit residuals between copies are zero, so the noise read about
    # half the plain touch's (0.47 on seed 0) and the touch was `ambiguous` (seeds 0 to 2)
    # or `unknown` (this seed); the copies are now left out, and the answer is the plain
    # touch's, with a warning saying so
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=3)
    logged = meshrec.TouchData(curves=[np.repeat(c, 10, axis=0) for c in sim.touch.curves])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = meshrec.recognize(sim.touch, surfaces)
    with pytest.warns(meshrec.RepeatedSamplesWarning, match=r"the touch: 1647 of its 1830"):
        rec = meshrec.recognize(logged, surfaces)
    assert rec.verdict == plain.verdict == "recognised"
    assert rec.best.model == "ellipsoid"
    assert rec.noise == plain.noise
    assert rec.touch.n_points == sim.touch.n_points
    assert any("counted once" in w for w in rec.warnings)
    # a geometry estimated on the copies (the command line, --batch and the service
    # estimate it early, to refuse bad data before indexing) is estimated again: it read
    # the noise low (0.000392 against 0.000654 on a probe's ellipsoid touch) and gave
    # `ambiguous` there
    early = touch_geometry(logged)
    assert early.noise_rms < 0.8 * plain.geometry.noise_rms
    with pytest.warns(meshrec.RepeatedSamplesWarning):
        given = meshrec.recognize(logged, surfaces, geometry=early)
    assert given.noise == plain.noise
    assert given.verdict == "recognised"
    assert given.geometry == plain.geometry


def test_touches_in_two_frames_name_the_best_joint_fit_in_the_reason(surfaces):
    # two touches of the crossed trough, each in a frame of its own (no one rigid pose):
    # `unknown`; the reason said "each touch alone fits crossed_trough ..." while the
    # answer's best model was another (the best joint fit), which it never named
    name = "crossed_trough"
    a = meshrec.simulate_touch(surfaces[name], rng=1)
    b = meshrec.simulate_touch(surfaces[name], rng=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize([a.touch, b.touch], surfaces)
    assert rec.verdict == "unknown"
    assert f"each touch alone fits {name} to the noise" in rec.reason
    assert rec.best.model in rec.reason
    if rec.best.model != name:
        assert rec.reason.startswith(f"the best joint fit, {rec.best.model}'s, leaves")
