"""Tests of meshrec.io.checks: the input checks every entry point shares."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from meshrec import defaults
from meshrec.io.checks import (
    check_curves,
    check_int,
    check_number,
    check_points,
    check_rng,
    check_transform,
    check_vector,
    one_line,
)


# ----------------------------------------------------------------------------- one_line
@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("plain.csv", "plain.csv"),
        ("two\nlines.csv", "two\\nlines.csv"),
        ("tab\there\r", "tab\\there\\r"),
        (Path("/tmp") / "a\nb.stl", "/tmp/a\\nb.stl"),
        (Path(os.fsdecode(b"caf\xe9.stl")), "caf\\xe9.stl"),  # not UTF-8: a surrogate escape
        (b"raw\xff\n", "raw\\xff\\n"),
        ("\x1b[31mred", "\\x1b[31mred"),
        ("ünïcode ok", "ünïcode ok"),
        (3.5, "3.5"),
        (["a\nb"], "['a\\nb']"),  # repr escapes already
    ],
)
def test_one_line_renders_on_one_printable_line(value, expected):
    text = one_line(value)
    assert text == expected
    assert text.isprintable()
    text.encode("utf-8")  # no lone surrogate left: it encodes


def test_one_line_limits_the_length():
    assert one_line("x" * 500, 20) == "x" * 17 + "..."
    assert len(one_line("x" * 500)) == 200
    assert one_line("x" * 500, None) == "x" * 500


def test_one_line_survives_a_broken_repr():
    class Broken:
        def __repr__(self):
            raise RuntimeError("no")

    assert one_line(Broken()).startswith("<Broken")


# ----------------------------------------------------------------------------- numbers
def test_check_number_accepts_real_numbers():
    assert check_number(3, "x") == 3.0
    assert isinstance(check_number(np.float32(0.5), "x"), float)
    assert check_number(np.int64(-2), "x", minimum=-2) == -2.0
    assert check_number(10**300, "x") == 1e300


@pytest.mark.parametrize(
    ("value", "kwargs", "error", "match"),
    [
        (True, {}, TypeError, "x must be a real number, got bool True"),
        (1j, {}, TypeError, "x must be a real number, got complex 1j"),
        ("1", {}, TypeError, "x must be a real number, got str 1"),
        (None, {}, TypeError, "x must be a real number, got NoneType"),
        (np.array([1.0]), {}, TypeError, "x must be a real number, got float64 array"),
        (float("nan"), {}, ValueError, "x must be finite, got nan"),
        (-float("inf"), {}, ValueError, "x must be finite, got -inf"),
        (10**400, {}, ValueError, "x must be finite, got 1000"),
        (0.0, {"positive": True}, ValueError, r"x must be > 0, got 0\.0"),
        (-1, {"minimum": 0.0}, ValueError, r"x must be >= 0, got -1\.0"),
        (2, {"maximum": 1.0}, ValueError, r"x must be <= 1, got 2\.0"),
    ],
)
def test_check_number_refuses(value, kwargs, error, match):
    with pytest.raises(error, match=match):
        check_number(value, "x", **kwargs)


def test_check_int():
    assert check_int(np.int32(7), "n") == 7
    with pytest.raises(TypeError, match=r"n must be an integer, got float 7\.0"):
        check_int(7.0, "n")
    with pytest.raises(TypeError, match="n must be an integer, got bool False"):
        check_int(False, "n")
    with pytest.raises(ValueError, match="n must be >= 5, got 4"):
        check_int(4, "n", minimum=5)
    with pytest.raises(ValueError, match="n must be <= 9, got 10"):
        check_int(10, "n", maximum=9)


# ----------------------------------------------------------------------------- arrays
def test_check_vector():
    v = check_vector([1, 2, 3], "v")
    assert v.dtype == np.float64
    assert v.shape == (3,)
    np.testing.assert_array_equal(check_vector((0, 0, 5), "v", unit=True), [0, 0, 1])
    # no overflow nor underflow in the length
    np.testing.assert_array_equal(check_vector([1e308, 0, 0], "v", unit=True), [1, 0, 0])
    np.testing.assert_allclose(check_vector([1e308, 1e308, 0], "v", unit=True)[0], 2**-0.5)
    np.testing.assert_array_equal(check_vector([0, 5e-324, 0], "v", unit=True), [0, 1, 0])
    given = np.array([1.0, 2.0, 3.0])
    assert check_vector(given, "v") is not given  # a copy


@pytest.mark.parametrize(
    ("value", "kwargs", "error", "match"),
    [
        ([1, 2], {}, ValueError, r"v must be \(3,\), got \(2,\)"),
        ([[1, 2, 3]], {}, ValueError, r"v must be \(3,\), got \(1, 3\)"),
        ([1, np.nan, 3], {}, ValueError, "v must be finite"),
        ([1, 2, 10**400], {}, ValueError, "v holds a number too large for a float"),
        ([0, 0, 0], {"nonzero": True}, ValueError, "v must be non-zero"),
        ([0, 0, 0], {"unit": True}, ValueError, "v must be non-zero"),
        ("abc", {}, TypeError, "v must be an array of real numbers, got str"),
        (None, {}, TypeError, "v must be an array of real numbers, got NoneType"),
        ({"x": 1}, {}, TypeError, "got dict"),
        ([1j, 0, 0], {}, TypeError, "v must hold real numbers, got a complex128 array"),
        ([True, False, True], {}, TypeError, "v must hold real numbers, got a bool array"),
        (["1", "2", "3"], {}, TypeError, "v must hold real numbers, got a <U1 array"),
        ([object(), 1, 2], {}, TypeError, "v must hold real numbers only, got objects"),
        ([[1, 2], [3]], {}, ValueError, "v must be a regular array of numbers"),
    ],
)
def test_check_vector_refuses(value, kwargs, error, match):
    with pytest.raises(error, match=match):
        check_vector(value, "v", **kwargs)


def test_check_points():
    pts = check_points([[0, 0, 0], [1, 2, 3]], "p")
    assert pts.shape == (2, 3)
    assert pts.dtype == np.float64
    with pytest.raises(ValueError, match=r"p must be \(n, 3\), got \(3,\)"):
        check_points([1, 2, 3], "p")
    with pytest.raises(ValueError, match="p must have at least 3 points, got 2"):
        check_points(np.zeros((2, 3)), "p", min_rows=3)
    with pytest.raises(ValueError, match="p must have at most 1 points, got 2"):
        check_points(np.zeros((2, 3)), "p", max_rows=1)
    with pytest.raises(ValueError, match=r"p has a non-finite point at row 1: \[1\.0, inf, 0\.0\]"):
        check_points([[0, 0, 0], [1, np.inf, 0]], "p")
    with pytest.raises(TypeError, match="p must hold real numbers, got a complex"):
        check_points(np.zeros((2, 3), dtype=complex), "p")


def test_check_transform():
    T = np.eye(4)
    T[:3, 3] = [1, 2, 3]
    np.testing.assert_array_equal(check_transform(T, "T", rigid=True), T)
    with pytest.raises(ValueError, match=r"T must be a finite \(4, 4\) array, got shape \(3, 3\)"):
        check_transform(np.eye(3), "T")
    with pytest.raises(ValueError, match="T must be a rigid transform"):
        check_transform(np.diag([2.0, 1.0, 1.0, 1.0]), "T", rigid=True)
    with pytest.raises(ValueError, match="T must be a rigid transform"):
        check_transform(np.diag([-1.0, 1.0, 1.0, 1.0]), "T", rigid=True)  # a reflection
    check_transform(np.diag([2.0, 1.0, 1.0, 1.0]), "T")  # any finite matrix without rigid
    with pytest.raises(TypeError, match="T must be an array of real numbers, got str"):
        check_transform("eye", "T")


# ----------------------------------------------------------------------------- curves
def _curves(n=7):
    return [np.random.default_rng(i).normal(size=(n, 3)) for i in range(3)]


def test_check_curves_accepts_any_sequence():
    for value in (_curves(), tuple(_curves()), np.stack(_curves()), iter(_curves())):
        out = check_curves(value)
        assert len(out) == 3
        assert all(c.dtype == np.float64 and c.shape == (7, 3) for c in out)


@pytest.mark.parametrize(
    ("value", "error", "match"),
    [
        (5, TypeError, r"curves must be a sequence of \(n, 3\) arrays, got int"),
        ("abc", TypeError, "got str"),
        ({"a": 1}, TypeError, "got dict"),
        (np.zeros((7, 3)), ValueError, r"got an array of shape \(7, 3\)"),
        (_curves()[:2], ValueError, "at least 3 curves, got 2"),
        (_curves() * 6, ValueError, f"at most {defaults.MAX_CURVES} curves"),
        (
            [np.zeros((defaults.MIN_POINTS_PER_CURVE - 1, 3))] * 3,
            ValueError,
            r"curves\[0\] must have at least",
        ),
        ([*_curves()[:2], _curves()[2].astype(complex)], TypeError, r"curves\[2\] must hold real"),
    ],
)
def test_check_curves_refuses(value, error, match):
    with pytest.raises(error, match=match):
        check_curves(value)


# ----------------------------------------------------------------------------- rng
def test_check_rng():
    a = check_rng(3).uniform(size=4)
    np.testing.assert_array_equal(a, np.random.default_rng(3).uniform(size=4))
    g = np.random.default_rng(1)
    assert check_rng(g) is g
    assert isinstance(check_rng(None), np.random.Generator)
    with pytest.raises(ValueError, match="rng must be a non-negative int seed, got -1"):
        check_rng(-1)
    for bad in (1.5, "seed", True, [1, 2]):
        with pytest.raises(TypeError, match="rng must be a numpy Generator, an int seed or None"):
            check_rng(bad)
