"""Distinct poses that fit equally well (meshrec.recognition.freedom.with_alternatives).

The expected answers are known independently: the half-turns about a box's axes are its
symmetries (the same place for the box), a third of a turn about its corner's diagonal is
not (the box's sides differ), yet three orthogonal faces at a corner fit a touch near the
corner as well after it.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import meshrec
from meshrec import defaults
from meshrec.recognition.freedom import pose_freedom, with_alternatives

EXTENTS = np.array([5.0, 3.0, 2.0])


def _box_distance(p: np.ndarray) -> np.ndarray:
    """Unsigned distance to the surface of the box of EXTENTS about the origin (analytic)."""
    q = np.abs(p) - EXTENTS / 2.0
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return np.abs(outside + np.minimum(q.max(axis=1), 0.0))


def _box_points() -> np.ndarray:
    box = trimesh.creation.box(extents=EXTENTS)
    return trimesh.sample.sample_surface(box, 800, seed=0)[0]


def _pose(R: np.ndarray, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def _freedom():
    # any fixed freedom to extend: points on three faces of a corner
    rng = np.random.default_rng(0)
    x = rng.uniform(-1.0, 1.0, (30, 3))
    n = rng.normal(size=(30, 3))
    return pose_freedom(x, n)


#: A third of a turn about the box's corner diagonal (x -> y -> z -> x): the corner's three
#: faces map onto each other, the box does not.
CORNER_TURN = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: A half-turn about z: a symmetry of the box.
HALF_TURN = np.diag([-1.0, -1.0, 1.0])


def test_poses_related_by_a_symmetry_of_the_model_are_one():
    T0 = _pose(np.eye(3), (0.3, -0.2, 0.1))
    T1 = _pose(HALF_TURN) @ T0  # the model turned onto itself: the same place
    f = with_alternatives(_freedom(), [T0, T1], [0.5, 0.5], _box_points(), _box_distance, 1e-6)
    assert f.alternatives == 0
    assert f.pose_weight == pytest.approx(1.0)
    assert f.fixed == (f.unresolved == 0)


def test_a_turn_about_the_corner_diagonal_is_an_alternative():
    T0 = _pose(np.eye(3), (0.3, -0.2, 0.1))
    T1 = _pose(CORNER_TURN) @ T0
    f = with_alternatives(_freedom(), [T0, T1], [0.5, 0.5], _box_points(), _box_distance, 1e-6)
    assert f.alternatives == 1
    assert f.pose_weight == pytest.approx(0.5)
    assert not f.fixed
    assert "one of 2 poses" in f.description
    assert f.to_dict()["alternatives"] == 1
    assert f.to_dict()["fixed"] is False


def test_the_alternatives_are_those_needed_to_reach_the_coverage():
    T0 = _pose(np.eye(3))
    poses = [T0, _pose(CORNER_TURN), _pose(CORNER_TURN.T), _pose(HALF_TURN)]
    pts = _box_points()
    # 0.6 + 0.05 (its symmetric twin) = 0.65, then 0.25 and 0.1: all three groups needed
    f = with_alternatives(_freedom(), poses, [0.6, 0.25, 0.1, 0.05], pts, _box_distance, 1e-6)
    assert (f.alternatives, f.pose_weight) == (2, pytest.approx(0.65))
    # with coverage 0.85 the second group reaches it: one alternative
    f = with_alternatives(
        _freedom(), poses, [0.6, 0.25, 0.1, 0.05], pts, _box_distance, 1e-6, coverage=0.85
    )
    assert f.alternatives == 1


def test_a_dominant_pose_is_fixed_without_any_test():
    calls = []

    def distance(p):
        calls.append(len(p))
        return _box_distance(p)

    T0 = _pose(np.eye(3))
    f = with_alternatives(
        _freedom(), [T0, _pose(CORNER_TURN)], [0.97, 0.03], _box_points(), distance, 1e-6
    )
    assert (f.alternatives, f.pose_weight, calls) == (0, 0.97, [])


def test_poses_of_negligible_weight_are_not_compared():
    calls = []

    def distance(p):
        calls.append(len(p))
        return _box_distance(p)

    tiny = defaults.POSE_ALTERNATIVE_MIN_WEIGHT / 2
    poses = [_pose(np.eye(3)), _pose(CORNER_TURN), _pose(CORNER_TURN.T)]
    f = with_alternatives(_freedom(), poses, [0.5, 0.5 - tiny, tiny], _box_points(), distance, 1e-6)
    assert f.alternatives == 1
    assert len(calls) == 1  # only the second pose was compared with the first


def test_a_motion_is_tested_on_a_subset_first_with_the_same_decision():
    calls = []

    def distance(p):
        calls.append(len(p))
        return _box_distance(p)

    pts = _box_points()
    stride = defaults.POSE_SYMMETRY_PROBE_STRIDE
    T0 = _pose(np.eye(3))
    # not a symmetry: the subset alone settles it
    f = with_alternatives(_freedom(), [T0, _pose(CORNER_TURN)], [0.5, 0.5], pts, distance, 1e-6)
    assert (f.alternatives, calls) == (1, [len(pts[::stride])])
    # a symmetry: the subset, then every vertex
    calls.clear()
    f = with_alternatives(_freedom(), [T0, _pose(HALF_TURN)], [0.5, 0.5], pts, distance, 1e-6)
    assert (f.alternatives, calls) == (0, [len(pts[::stride]), len(pts)])
    # one vertex off the surface, outside the subset: the subset passes, every vertex
    # does not (the brute-force answer), under a motion that is none
    off = pts.copy()
    off[1] *= 1.2
    low, high = _box_distance(off[::stride]).max(), _box_distance(off).max()
    assert low < 1e-9 < high
    for tolerance, same in ((0.5 * high, False), (2.0 * high, True)):
        f = with_alternatives(_freedom(), [T0, T0], [0.5, 0.5], off, distance, tolerance)
        assert f.alternatives == (0 if same else 1)


@pytest.mark.parametrize(
    ("poses", "weights", "vertices", "tolerance", "coverage", "match"),
    [
        (np.zeros((0, 4, 4)), [], np.ones((3, 3)), 1e-3, 0.95, "poses must be"),
        (np.zeros((2, 3, 3)), [0.5, 0.5], np.ones((3, 3)), 1e-3, 0.95, "poses must be"),
        ([np.full((4, 4), np.nan)], [1.0], np.ones((3, 3)), 1e-3, 0.95, "poses must be"),
        ([np.eye(4)], [0.5, 0.5], np.ones((3, 3)), 1e-3, 0.95, "weights must be"),
        ([np.eye(4)], [-1.0], np.ones((3, 3)), 1e-3, 0.95, "weights must be"),
        ([np.eye(4)], [1.0], np.zeros((0, 3)), 1e-3, 0.95, "vertices"),
        ([np.eye(4)], [1.0], np.ones((3, 3)), 0.0, 0.95, "tolerance"),
        ([np.eye(4)], [1.0], np.ones((3, 3)), 1e-3, 0.0, "coverage"),
        ([np.eye(4)], [1.0], np.ones((3, 3)), 1e-3, 1.5, "coverage"),
    ],
)
def test_with_alternatives_bad_input_raises(poses, weights, vertices, tolerance, coverage, match):
    with pytest.raises(ValueError, match=match):
        with_alternatives(
            _freedom(), poses, weights, vertices, lambda p: np.zeros(len(p)), tolerance, coverage
        )


def test_touch_near_a_box_corner_names_the_box_but_not_one_pose(tmp_path):
    """A 50 x 30 x 20 box (mm, alone in its folder): three curves near a corner, on its three
    faces, fit it as well after a third of a turn about the corner's diagonal. The box
    alone fits, but its pose is one of two (not fixed), and the true pose (up to the box's
    half-turns) is among the poses the data cannot rule out. One touch across the box's
    edges names no model: the verdict is ``ambiguous`` with the box alone plausible."""
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.box(extents=(50.0, 30.0, 20.0)).export(folder / "box.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    sim = meshrec.simulate_touch(folder / "box.stl", rng=1, noise=0.01)
    rec = meshrec.recognize(sim.touch, lib)
    assert rec.best.model == "box"
    assert (rec.verdict, rec.plausible) == ("ambiguous", ("box",))
    assert "crosses a sharp edge of box (its points lie on 3 faces" in rec.reason
    assert rec.pose_freedom.free == 0
    assert rec.pose_freedom.alternatives >= 1
    assert not rec.pose_freedom.fixed
    assert "box's pose is one of" in rec.reason
    pts = sim.touch.points
    true = pts @ sim.T_model_touch[:3, :3].T + sim.T_model_touch[:3, 3]
    halves = [np.diag(d) for d in ([1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1])]
    weights = {}
    for p in rec.scores[0].poses:
        placed = pts @ p.T_model_touch[:3, :3].T + p.T_model_touch[:3, 3]
        err = min(np.abs(placed @ S.T - true).max() for S in halves)
        weights[err < 0.1] = weights.get(err < 0.1, 0.0) + p.weight
    # the true pose is found and holds a real share of the weight; so does another one
    assert weights.get(True, 0.0) > 0.2
    assert weights.get(False, 0.0) > 0.2


def test_two_touches_across_the_box_edges_are_not_held_back_by_the_one_touch_rule(tmp_path):
    """The rule that one touch across a sharp edge names no model is for one touch: two
    touches of the box near two of its corners, in one frame, are judged on their joint
    fit (the box alone in the folder)."""
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.box(extents=(50.0, 30.0, 20.0)).export(folder / "box.stl")
    lib = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    rng = np.random.default_rng(5)
    sims = [
        meshrec.simulate_touch(folder / "box.stl", contact=c, rng=rng, noise=0.01, transform=False)
        for c in ([23.0, 15.0, 8.0], [-23.0, -15.0, 8.0])
    ]
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 3.0]
    with pytest.warns(meshrec.SharpEdgeWarning):
        rec = meshrec.recognize([s.touch.transformed(T) for s in sims], lib)
    assert (rec.verdict, rec.plausible) == ("recognised", ("box",))
    assert "one touch across an edge" not in rec.reason
