"""Benchmark protocols (small versions) and the oracle and baseline they compare against.

The slow-marked protocol tests run a few seeded trials of each of the paper's protocols
and assert the issue's recognition and localisation targets (not timing).
"""

import numpy as np
import pytest

import meshrec
from meshrec import bench, defaults

OBJECTS = ("cylinder_1", "cylinder_2", "elliptic_cylinder", "sphere")


@pytest.mark.slow
def test_table2_and_table3_protocols_small(surfaces):
    rows = bench.run_trials(surfaces, meshrec.PAPER_SURFACES, trials=2)
    assert len(rows) == 8
    assert all(t.recognised for t in rows)
    loc = np.array([t.loc_error for t in rows])
    oracle = np.array([t.oracle_loc for t in rows])
    assert loc.mean() <= 0.015
    assert loc.mean() <= 1.5 * oracle.mean()
    # The right model's error is that of the truth's own refinement (the noise floor).
    for t in rows:
        assert t.right_error <= 1.05 * t.oracle_error
        assert t.right_error < 1e-3


@pytest.mark.slow
def test_table4_protocol_small(objects):
    rows = bench.run_trials(objects, OBJECTS, trials=2)
    assert all(t.recognised for t in rows)
    assert np.mean([t.right_error for t in rows]) <= 0.06


def test_paper_touch_follows_the_protocols(surfaces, objects):
    s = bench.paper_touch(surfaces["ellipsoid"], 1)
    assert [len(c) for c in s.touch.curves] == [defaults.SIM_POINTS] * 3
    o = bench.paper_touch(objects["cylinder_2"], 1)
    assert [len(c) for c in o.touch.curves] == [defaults.BENCH_OBJECT_POINTS] * 3
    assert o.noise == defaults.BENCH_OBJECT_NOISE
    # On the curved side, away from the rims.
    assert np.hypot(*o.contact[:2]) == pytest.approx(47.0, abs=0.05)
    assert abs(o.contact[2]) <= 50.0 - defaults.BENCH_RIM_MARGIN


@pytest.mark.parametrize(
    ("name", "p", "q", "expected"),
    [
        ("sphere", [33, 0, 0], [0, 0, -33], 0.0),
        ("cylinder_1", [25.2, 0, 10], [0, 25.2, -30], 0.0),
        ("elliptic_cylinder", [50.8, 0, 0], [-50.8, 0, 40], 0.0),
        ("elliptic_cylinder", [50.8, 0, 0], [0, 31.75, 0], np.hypot(50.8, 31.75)),
        ("something_else", [0, 0, 0], [3, 4, 0], 5.0),
    ],
)
def test_object_localisation_error(name, p, q, expected):
    assert bench.object_localisation_error(name, p, q) == pytest.approx(expected, abs=1e-9)


def test_run_trials_errors(surfaces):
    with pytest.raises(ValueError, match="trials must be a positive integer"):
        bench.run_trials(surfaces, ["ellipsoid"], trials=0)
    with pytest.raises(ValueError, match="shape 'teapot' is not in the library"):
        bench.run_trials(surfaces, ["teapot"], trials=1)


def test_refine_pose_from_the_truth_stays_at_the_truth(surfaces):
    model = surfaces["monkey_saddle"]
    sim = meshrec.simulate_touch(model, rng=4)
    reg = meshrec.refine_pose(sim.touch, model, sim.T_model_touch)
    assert reg.error < 1e-3
    assert np.linalg.norm(reg.contact - sim.contact) < 0.02
    assert reg.candidates == 0
    assert reg.phi is None


def test_refine_pose_errors(surfaces):
    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=0)
    with pytest.raises(ValueError, match=r"finite \(4, 4\)"):
        meshrec.refine_pose(sim.touch, surfaces["ellipsoid"], np.eye(3))
    scaled = np.diag([2.0, 2.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="rigid transform"):
        meshrec.refine_pose(sim.touch, surfaces["ellipsoid"], scaled)


@pytest.mark.slow
def test_baseline_multistart_registers_a_touch(surfaces):
    pytest.importorskip("open3d")
    from meshrec.bench import baseline

    model = surfaces["ellipsoid"]
    sim = meshrec.simulate_touch(model, rng=2)
    target = baseline.BaselineModel.from_index(model, rng=0)
    res = baseline.baseline_register(sim.touch, target, method="multistart", starts=64, rng=0)
    assert res.model == "ellipsoid"
    assert res.error < 5e-3
    moved = sim.touch.points @ res.T_model_touch[:3, :3].T + res.T_model_touch[:3, 3]
    assert np.abs(meshrec.sim.paper.implicit_distance("ellipsoid", moved)).mean() < 5e-3


def test_baseline_errors(surfaces):
    from meshrec.bench import baseline

    sim = meshrec.simulate_touch(surfaces["ellipsoid"], rng=0)
    with pytest.raises(ValueError, match="method must be one of"):
        baseline.baseline_register(sim.touch, None, method="teleport")
    with pytest.raises(ValueError, match="starts must be a positive integer"):
        baseline.baseline_register(sim.touch, None, starts=0)
