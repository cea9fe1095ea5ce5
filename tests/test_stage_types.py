"""Every public registration stage, and the indexers, refuse a wrong-typed argument with
a TypeError naming it (issue 15 item 10), rather than an AttributeError from deep inside.

Each case passes the right objects (from one traced registration) but for one argument,
given a string, a number or None.
"""

import re
from pathlib import Path

import numpy as np
import pytest

import meshrec
from meshrec.registration.brackets import phi_brackets, refine_phis
from meshrec.registration.candidates import curvature_tolerance
from meshrec.registration.lookup import lookup_candidates
from meshrec.registration.poses import (
    distinct_poses,
    pose_hypotheses,
    refine_searches,
    refined_pose,
)
from meshrec.registration.register import register
from meshrec.registration.screening import screen_candidates
from meshrec.registration.searching import search_candidates

MODELS = Path(__file__).resolve().parents[1] / "models"


@pytest.fixture(scope="module")
def parts(surfaces):
    """Right arguments for every stage, from one traced registration."""
    model = surfaces["ellipsoid"]
    touch = meshrec.simulate_touch(model, rng=3).touch
    reg = register(touch, model, trace=True)
    t = reg.trace
    refined = refine_searches(model, t.candidates, t.searches, best=1)
    return {
        "touch": touch,
        "model": model,
        "geometry": t.candidates.geometry,
        "candidates": t.candidates,
        "brackets": t.brackets,
        "searches": t.searches,
        "refined": refined,
        "refinement": refined[0].refinement,
        "poses": reg.poses,
    }


# (stage, its arguments by name, the argument to spoil, the wrong value)
CASES = [
    (lookup_candidates, ("touch", "model", "geometry"), "touch", "touch.csv"),
    (lookup_candidates, ("touch", "model", "geometry"), "model", "ellipsoid"),
    (lookup_candidates, ("touch", "model", "geometry"), "geometry", None),
    (phi_brackets, ("model", "candidates"), "model", "ellipsoid"),
    (phi_brackets, ("model", "candidates"), "candidates", "candidates"),
    (refine_phis, ("model", "candidates", "brackets", "indices"), "model", 3),
    (refine_phis, ("model", "candidates", "brackets", "indices"), "candidates", "c"),
    (refine_phis, ("model", "candidates", "brackets", "indices"), "brackets", "b"),
    (refine_phis, ("model", "candidates", "brackets", "indices"), "indices[0]", 0.5),
    (screen_candidates, ("model", "candidates", "brackets"), "model", None),
    (screen_candidates, ("model", "candidates", "brackets"), "candidates", "c"),
    (screen_candidates, ("model", "candidates", "brackets"), "brackets", "b"),
    (search_candidates, ("model", "candidates", "starts"), "model", "ellipsoid"),
    (search_candidates, ("model", "candidates", "starts"), "candidates", "c"),
    (search_candidates, ("model", "candidates", "starts"), "starts", 3),
    (search_candidates, ("model", "candidates", "starts"), "starts[0]", "ab"),
    (search_candidates, ("model", "candidates", "starts"), r"starts[0][0]", ("a", 0.0)),
    (search_candidates, ("model", "candidates", "starts"), r"starts[0][1]", (0, 1j)),
    (search_candidates, ("model", "candidates", "starts", "method"), "method", 3),
    (refine_searches, ("model", "candidates", "searches"), "model", "ellipsoid"),
    (refine_searches, ("model", "candidates", "searches"), "candidates", "c"),
    (refine_searches, ("model", "candidates", "searches"), "searches", "s"),
    (pose_hypotheses, ("model", "candidates", "searches", "refined"), "model", 1.0),
    (pose_hypotheses, ("model", "candidates", "searches", "refined"), "candidates", "c"),
    (pose_hypotheses, ("model", "candidates", "searches", "refined"), "searches", "s"),
    (pose_hypotheses, ("model", "candidates", "searches", "refined"), "refined", 3),
    (pose_hypotheses, ("model", "candidates", "searches", "refined"), "refined[0]", "r"),
    (refined_pose, ("model", "refinement", "point"), "model", "ellipsoid"),
    (refined_pose, ("model", "refinement", "point"), "refinement", "r"),
    (refined_pose, ("model", "refinement", "point"), "point", [1j, 0, 0]),
    (distinct_poses, ("hypotheses", "half_length"), "hypotheses", 3),
    (distinct_poses, ("hypotheses", "half_length"), "hypotheses[0]", "p"),
    (distinct_poses, ("hypotheses", "half_length"), "half_length", "1"),
    (distinct_poses, ("hypotheses", "half_length", "angle_deg"), "angle_deg", 1j),
    (distinct_poses, ("hypotheses", "half_length", "distance_fraction"), "distance_fraction", None),
]


def _right(parts, name):
    """The right value of an argument."""
    return {
        "indices": [0],
        "starts": [(0, 0.0)],
        "point": parts["geometry"].point,
        "hypotheses": parts["poses"],
        "half_length": float(parts["geometry"].half_length),
        "method": "lm",
        "angle_deg": 5.0,
        "distance_fraction": 0.1,
    }.get(name, parts.get(name))


def _spoil(name, value, arg, right):
    """The value to pass for ``arg``: ``value`` itself, or put inside ``right``'s first item."""
    base = arg.split("[")[0]
    if base != name:
        return right
    if arg == name:
        return value
    return [value, *list(right)[1:]]


#: Arguments passed by keyword (the others by position).
KEYWORDS = {"method", "angle_deg", "distance_fraction"}


def _call(stage, names, values):
    args = [v for n, v in zip(names, values, strict=True) if n not in KEYWORDS]
    kwargs = {n: v for n, v in zip(names, values, strict=True) if n in KEYWORDS}
    return stage(*args, **kwargs)


@pytest.mark.parametrize(
    ("stage", "names", "arg", "value"),
    CASES,
    ids=[f"{c[0].__name__}-{c[2]}" for c in CASES],
)
def test_a_stage_refuses_a_wrong_type_naming_the_argument(parts, stage, names, arg, value):
    values = [_spoil(n, value, arg, _right(parts, n)) for n in names]
    with pytest.raises(TypeError, match=r"^" + re.escape(arg) + " must "):
        _call(stage, names, values)


def test_the_right_arguments_pass(parts):
    """The cases spoil one argument each: with none spoiled, every stage runs."""
    for stage, names, _, _ in CASES:
        _call(stage, names, [_right(parts, n) for n in names])


def test_curvature_tolerance_refuses_a_complex_number():
    for k, args in enumerate([(1j, 1.0, 0.5, 0.001), (1.0, 1 + 0j, 0.5, 0.001)]):
        name = ("k1", "k2")[k]
        with pytest.raises(TypeError, match=rf"^{name} must be a real number, got complex"):
            curvature_tolerance(*args)
    with pytest.raises(TypeError, match=r"^half_length must be a real number, got str"):
        curvature_tolerance(1.0, 1.0, "0.5", 0.001)
    with pytest.raises(TypeError, match=r"^fit_rms must be a real number, got complex"):
        curvature_tolerance(1.0, 1.0, 0.5, 0.001j)
    with pytest.raises(ValueError, match=r"^k1 must be finite, got nan"):
        curvature_tolerance(np.nan, 1.0, 0.5, 0.001)
    with pytest.raises(ValueError, match=r"^rel must be >= 0, got -1\.0"):
        curvature_tolerance(1.0, 1.0, 0.5, 0.001, rel=-1.0)
    with pytest.raises(ValueError, match=r"^noise_factor must be >= 0, got -1\.0"):
        curvature_tolerance(1.0, 1.0, 0.5, 0.001, noise_factor=-1.0)


def test_a_point_must_be_a_3_vector(parts):
    with pytest.raises(ValueError, match=r"^point must be \(3,\)"):
        refined_pose(parts["model"], parts["refinement"], [0.0, 0.0])


def test_a_start_must_be_a_pair_with_a_finite_phi(parts):
    model, cands = parts["model"], parts["candidates"]
    with pytest.raises(ValueError, match=r"^starts\[0\] must be an \(int, float\) pair, got 3"):
        search_candidates(model, cands, [(0, 0.0, 1.0)])
    with pytest.raises(ValueError, match=r"^starts\[1\]\[1\] must be finite, got nan"):
        search_candidates(model, cands, [(0, 0.0), (0, np.nan)])


def test_a_tolerance_of_distinct_poses_must_be_finite(parts):
    with pytest.raises(ValueError, match=r"^half_length must be finite, got inf"):
        distinct_poses(parts["poses"], np.inf)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: meshrec.ModelIndex.from_file(3), "path"),
        (
            lambda: meshrec.ModelIndex.from_file(
                MODELS / "surfaces" / "ellipsoid.stl", cache_dir=3
            ),
            "cache_dir",
        ),
        (lambda: meshrec.ModelLibrary.from_folder(3), "folder"),
        (lambda: meshrec.ModelLibrary.from_folder(MODELS / "surfaces", cache_dir=2.5), "cache_dir"),
    ],
    ids=["from_file-path", "from_file-cache_dir", "from_folder-folder", "from_folder-cache_dir"],
)
def test_the_indexers_refuse_a_wrong_type_naming_the_argument(call, name):
    with pytest.raises(TypeError, match=rf"^{name} must be a str or PathLike"):
        call()
