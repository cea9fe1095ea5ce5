"""Result objects compare by value: arrays element-wise, times left out, never a raise."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import meshrec
from meshrec._values import values_equal


def test_values_equal_arrays_nan_and_shape():
    a = np.array([1.0, np.nan, 3.0])
    assert values_equal(a, a.copy())
    assert not values_equal(a, np.array([1.0, np.nan, 3.5]))
    assert not values_equal(a, a.reshape(3, 1))
    assert not values_equal(a, [1.0, np.nan, 3.0])
    assert values_equal(np.arange(3), np.arange(3))
    assert values_equal(float("nan"), float("nan"))
    assert not values_equal((1, 2), [1, 2])
    assert not values_equal({"a": np.zeros(2)}, {"a": np.ones(2)})
    assert values_equal({"a": (np.zeros(2), None)}, {"a": (np.zeros(2), None)})


def test_registrations_of_one_touch_compare_equal_and_differ_on_an_array(touched_ellipsoid):
    t = touched_ellipsoid
    one = meshrec.register(t.sim.touch, t.model, trace=True)
    two = meshrec.register(t.sim.touch, t.model, trace=True)
    # Registration holds arrays: the generated __eq__ raised here.
    assert one == two
    assert one.trace == two.trace
    assert one == dataclasses.replace(two, seconds=two.seconds + 5.0)  # times take no part
    moved = one.T_model_touch.copy()
    moved[0, 3] += 1e-9
    assert one != dataclasses.replace(one, T_model_touch=moved)
    with pytest.raises(TypeError, match="unhashable"):
        hash(one)


def test_recognitions_of_one_touch_compare_equal(touched_ellipsoid):
    t = touched_ellipsoid
    again = meshrec.recognize(t.sim.touch, t.library)
    assert again == t.rec
    assert again.best == t.rec.best
    assert again.geometry == t.rec.geometry
    assert again != dataclasses.replace(t.rec, verdict="unknown")
    assert again.scores != dataclasses.replace(t.rec, scores=t.rec.scores[::-1]).scores
    advice = meshrec.next_touch(t.rec, t.library, rng=1)
    assert advice == meshrec.next_touch(again, t.library, rng=1)
