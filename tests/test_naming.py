"""The stage before a model is named, called alone (meshrec.recognition.naming), and the
pose test it shares with the answer (meshrec.recognition.best_pose.free_motions)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import trimesh

import meshrec
from meshrec.recognition.best_pose import free_motions
from meshrec.recognition.naming import NamingPasses, before_naming
from meshrec.recognition.passes import rank, rank_joint
from meshrec.recognition.rescore import noise_and_points, rescored, would_recognise
from meshrec.recognition.workers import ModelWorkers


def _ranked(touches, library):
    """The first pass and its scores, as ``recognize`` runs them before this stage."""
    models = list(library)
    run = ModelWorkers(models, workers=1)
    if len(touches) == 1:
        rec, fits = rank(touches[0], models, "lm", None, None, run), {}
    else:
        rec, fits = rank_joint(touches, models, "lm", None, (None,) * len(touches), run)
    rec, noise = rescored(rec, None, models)
    return rec, fits, noise, run, models


def _staged(touches, library):
    rec, fits, noise, run, models = _ranked(touches, library)
    own = noise_and_points(rec)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = before_naming(rec, None, fits, models, "lm", run, noise, own, False, {})
    run.close()
    return rec, out


def _rms(rec) -> dict:
    return {r.model: r.rms for r in rec.ranking if not r.rejected}


def test_an_answer_that_names_no_model_costs_nothing(tmp_path):
    # Two copies of one ellipsoid: they fit every touch equally, so the scores name
    # neither (probability 1/2 each) and no pass runs: the ranking comes back as it was.
    folder = tmp_path / "models"
    folder.mkdir()
    mesh = trimesh.creation.icosphere(subdivisions=4)
    mesh.apply_scale([1.0, 0.8, 0.5])
    for name in ("a", "b"):
        mesh.export(folder / f"{name}.stl")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    touch = meshrec.simulate_touch(library["a"], rng=5).touch
    rec, out = _staged([touch], library)
    n = noise_and_points(rec)[1]
    assert not would_recognise(rec, None, n, out.noise)
    assert isinstance(out, NamingPasses)
    assert out.passes == ()
    assert out.recognition is rec
    assert out.cautions == ()
    assert out.widened_seconds == 0.0


def test_one_touch_about_to_be_named_is_looked_at_again(ellipsoid_capsule_torus):
    # An ellipsoid (three different axes: no turn is a symmetry) touched once: the
    # scores name it, so its weak motions and its poses on the other models are looked
    # at. Each pass only adds poses: no model's best fit gets worse.
    library = ellipsoid_capsule_torus
    touch = meshrec.simulate_touch(library["ellipsoid"], rng=11).touch
    rec, out = _staged([touch], library)
    assert rec.ranking[0].model == "ellipsoid"
    assert "weak_motions" in out.passes
    assert out.passes[-1] == "transfer"
    assert out.recognition.ranking[0].model == "ellipsoid"
    before, after = _rms(rec), _rms(out.recognition)
    for name, rms in before.items():
        assert after[name] <= rms * (1 + 1e-9)
    assert out.widened_seconds > 0.0


def test_several_touches_about_to_be_named_are_looked_at_again(ellipsoid_capsule_torus):
    library = ellipsoid_capsule_torus
    rng = np.random.default_rng(12)
    model = library["ellipsoid"]
    touches = [meshrec.simulate_touch(model, rng=rng, transform=False).touch for _ in range(3)]
    rec, out = _staged(touches, library)
    assert rec.ranking[0].model == "ellipsoid"
    assert out.passes == ("lone_leader", "transfer")
    assert out.recognition.ranking[0].model == "ellipsoid"
    before, after = _rms(rec), _rms(out.recognition)
    for name, rms in before.items():
        assert after[name] <= rms * (1 + 1e-9)
    # the several-touch passes are timed in their own phases, not as widened passes
    assert out.widened_seconds == 0.0


def test_the_pose_test_is_computed_once_per_pose(ellipsoid_capsule_torus):
    library = ellipsoid_capsule_torus
    touch = meshrec.simulate_touch(library["ellipsoid"], rng=11).touch
    rec, _fits, _noise, run, _models = _ranked([touch], library)
    run.close()
    model = library["ellipsoid"]
    memo = {}
    first = free_motions(rec, model, memo)
    assert len(memo) == 1
    assert free_motions(rec, model, memo) is first
    fresh = free_motions(rec, model)
    assert (fresh[0].slides, fresh[0].turns) == (first[0].slides, first[0].turns)
    np.testing.assert_array_equal(fresh[1], first[1])
    # another pose is another entry
    best = rec.ranking[0]
    T = best.T_model_touch.copy()
    T[:3, 3] += 0.01
    shifted = dataclasses.replace(
        rec, ranking=(dataclasses.replace(best, T_model_touch=T), *rec.ranking[1:])
    )
    assert free_motions(shifted, model, memo) is not first
    assert len(memo) == 2
