"""Per-phase CPU clocks of a recognition (meshrec.recognition.phases, Recognition.phase_times)."""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np
import pytest
from seeded_touches import touches_at, world_pose

import meshrec
from meshrec import defaults
from meshrec.recognition.phases import PARTS, PHASES, PhaseTimes, phase_clock, timed

#: Float slack of the sums (the phases are disjoint intervals of the same clock).
SLACK = 1e-6


def _spin(seconds: float) -> None:
    """Burn about ``seconds`` of CPU (the clock's test needs time to pass)."""
    c0 = time.process_time()
    while time.process_time() - c0 < seconds:
        sum(range(1000))


def _check_sums(p: PhaseTimes) -> None:
    values = p.as_dict()
    assert all(v >= 0.0 for v in values.values()), values
    assert sum(p.phases().values()) <= p.total + SLACK
    assert p.other >= -SLACK
    assert p.best_first_alone + p.best_first_joint <= p.best_first + SLACK
    assert p.adequacy_alone + p.adequacy_pairs + p.adequacy_joint <= p.adequacy + SLACK


def test_nested_phases_count_exclusively_and_parts_within_their_phase():
    with phase_clock() as clock:
        with timed("best_first"):
            _spin(0.01)
            with timed("alone"):
                _spin(0.01)
            with timed("joint"):
                _spin(0.01)
        # no widened_joint field: counted in widened itself
        with timed("widened"), timed("joint"):
            _spin(0.01)
        # a phase inside another counts for itself only
        with timed("scoring"), timed("freedom"):
            _spin(0.01)
    p = clock.times()
    _check_sums(p)
    assert p.best_first_alone >= 0.01
    assert p.best_first_joint >= 0.01
    assert p.best_first >= p.best_first_alone + p.best_first_joint + 0.01
    assert p.widened >= 0.01
    assert p.freedom >= 0.01
    assert p.scoring < p.freedom  # freedom's time is not scoring's
    assert p.total >= 0.05
    zero = ("geometry", "checks", "first", "adequacy", "adequacy_alone", "dense", "probe_offset")
    assert all(getattr(p, k) == 0.0 for k in zero)


def test_timed_outside_a_clock_counts_nothing_and_clocks_do_not_leak():
    with timed("first"):
        _spin(0.002)
    with phase_clock() as outer:
        with phase_clock() as inner, timed("first"):
            _spin(0.002)
        with timed("geometry"):
            _spin(0.002)
    assert inner.times().first > 0
    assert inner.times().geometry == 0.0
    assert outer.times().first == 0.0
    assert outer.times().geometry > 0


def test_timed_refuses_an_unknown_phase():
    with pytest.raises(ValueError, match=r"name must be one of .* got 'lookup'"):
        timed("lookup")
    assert set(PHASES) | {f"best_first_{k}" for k in ("alone", "joint")} <= {
        f.name for f in dataclasses.fields(PhaseTimes)
    }
    assert set(PARTS) == {"alone", "pairs", "joint"}


def test_phase_times_repr_and_dict():
    p = PhaseTimes(first=1.5, scoring=0.25, best_first=0.5, best_first_joint=0.5, total=3.0)
    assert repr(p) == (
        "PhaseTimes(total=3, first=1.5, best_first=0.5, best_first_joint=0.5, scoring=0.25)"
    )
    assert p.phases()["first"] == 1.5
    assert "best_first_joint" not in p.phases()
    assert p.as_dict()["best_first_joint"] == 0.5
    assert p.other == pytest.approx(0.75)
    assert repr(PhaseTimes()) == "PhaseTimes(total=0)"


def test_phase_times_are_not_part_of_a_recognitions_equality():
    field = {f.name: f for f in dataclasses.fields(meshrec.Recognition)}["phase_times"]
    assert field.compare is False
    assert "PhaseTimes" in meshrec.__all__


def _answers(rec) -> tuple:
    """Everything a recognition answers (not its times), for an exact comparison."""
    regs = tuple(
        (
            r.model,
            r.error,
            r.rms,
            None if r.T_model_touch is None else r.T_model_touch.tobytes(),
            tuple((p.T_model_touch.tobytes(), p.rms) for p in r.poses),
        )
        for r in rec.ranking
    )
    return (
        rec.verdict,
        rec.plausible,
        rec.noise,
        rec.reason,
        rec.warnings,
        tuple(rec.probabilities.items()),
        rec.touch_rms,
        regs,
    )


def _timed_recognition(touch, library, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c0 = time.process_time()
        rec = meshrec.recognize(touch, library, **kwargs)
        return rec, time.process_time() - c0


def test_one_touch_runs_no_joint_phase(touched_ellipsoid):
    t = touched_ellipsoid
    rec, around = _timed_recognition(t.sim.touch, t.library)
    p = rec.phase_times
    _check_sums(p)
    assert p.total <= around + SLACK
    for name in ("geometry", "checks", "first", "scoring", "freedom", "probe_offset"):
        assert getattr(p, name) > 0, name
    joint = ("best_first", "best_first_alone", "best_first_joint", "adequacy", "symmetries")
    assert all(getattr(p, k) == 0.0 for k in joint)
    assert p.widened == 0.0
    # about to be `recognised`: the named model's search confirmed with more candidates
    assert rec.verdict == "recognised"
    assert (p.dense > 0.0) == (t.rec.ranking[0].candidates >= defaults.MAX_CANDIDATES)
    # the clock changes no answer: the session's recognition of the same touch
    assert _answers(rec) == _answers(t.rec)


def test_a_given_probe_radius_skips_the_offset_check(touched_ellipsoid):
    t = touched_ellipsoid
    rec, _ = _timed_recognition(t.sim.touch, t.library, probe_radius=0.01)
    assert rec.phase_times.probe_offset == 0.0
    assert rec.phase_times.first > 0
    assert rec.phase_times.checks > 0


def test_three_touches_time_the_joint_phases(ellipsoid_capsule_torus):
    library = ellipsoid_capsule_torus
    rng = np.random.default_rng(3)
    touches, _ = touches_at(library["ellipsoid"], world_pose(rng), rng)
    rec, around = _timed_recognition(touches, library)
    again, _ = _timed_recognition(touches, library)
    assert rec.best.model == "ellipsoid"
    p = rec.phase_times
    _check_sums(p)
    assert p.total <= around + SLACK
    for name in ("geometry", "first", "best_first", "best_first_joint", "symmetries"):
        assert getattr(p, name) > 0, name
    assert p.widened == 0.0
    assert p.dense == 0.0
    # two runs give the same answers, whatever their clocks say
    assert _answers(rec) == _answers(again)


def test_the_clock_adds_no_frame_to_the_warnings(objects):
    """The recognition's own warnings still point at its caller (their stack levels count
    from ``recognize``'s frame, which holds the clock)."""
    touch = meshrec.simulate_touch(objects["cylinder_2"], rng=0).touch
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        meshrec.recognize(touch, objects)
    edges = [w for w in caught if issubclass(w.category, meshrec.SharpEdgeWarning)]
    assert edges
    assert all(w.filename == __file__ for w in edges)
