"""Property-based: malformed touch files of every kind give a clear ValueError or a valid
result, never another exception (hypothesis, derandomised so that runs repeat)."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from test_bad_touch import write_csv

from meshrec import (
    ModelLibrary,
    TouchData,
    estimate_local_geometry,
    find_common_point,
    recognize,
    simulate_touch,
)

_counter = itertools.count()


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """A one-model library, a valid touch on it, and a folder for the generated files."""
    root = tmp_path_factory.mktemp("property")
    models = root / "models"
    models.mkdir()
    trimesh.creation.icosphere(subdivisions=3).export(models / "ball.stl")
    library = ModelLibrary.from_folder(models, cache_dir=root / "cache")
    sim = simulate_touch(library["ball"], rng=11, n_points=21)
    files = root / "files"
    files.mkdir()
    return {"library": library, "touch": sim.touch, "files": files}


def _path(world, suffix):
    return world["files"] / f"t{next(_counter)}{suffix}"


def _attempt(func, *args):
    """``(result, None)``, or ``(None, message)`` if ``func`` raised a ValueError."""
    try:
        return func(*args), None
    except ValueError as exc:
        return None, str(exc)


def _check(path, library=None) -> str:
    """Read ``path`` and estimate (and, given a library, recognise): "error" or "ok".

    A ValueError must carry a message naming the problem; anything that is returned must
    be valid. Any other exception fails the test.
    """
    touch, message = _attempt(TouchData.from_file, path)
    if message is not None:
        assert message.startswith(f"touch file {path}: ")
        assert len(message) > len(f"touch file {path}: ") + 5
        return "error"
    assert len(touch.curves) >= 3
    assert all(np.isfinite(c).all() and c.shape[1] == 3 for c in touch.curves)
    g, message = _attempt(estimate_local_geometry, touch.curves, touch.contact, touch.normal)
    if message is not None:
        assert len(message) > 10
        return "error"
    for value in (g.K, g.H, g.k1, g.k2, g.fit_rms, g.half_length, g.condition):
        assert math.isfinite(value)
    assert g.k1 >= g.k2
    assert np.isfinite(g.point).all()
    assert abs(np.linalg.norm(g.normal) - 1.0) < 1e-9
    np.testing.assert_allclose(g.frame.T @ g.frame, np.eye(3), atol=1e-9)
    if library is None:
        return "ok"
    rec, message = _attempt(recognize, touch, library)
    if message is not None:
        assert "likely a unit mismatch" in message
        return "error"
    assert len(rec.ranking) == len(library)
    for r in rec.ranking:
        if not r.rejected:
            assert math.isfinite(r.error)
            assert r.error >= 0
            assert np.isfinite(r.T_model_touch).all()
    return "ok"


# ----------------------------------------------------------------------------- raw content
@settings(derandomize=True, database=None, max_examples=60, deadline=None)
@given(data=st.binary(max_size=400), suffix=st.sampled_from([".csv", ".json"]))
def test_random_bytes(world, data, suffix):
    path = _path(world, suffix)
    path.write_bytes(data)
    assert _check(path) == "error"  # random bytes are never three good curves


_CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-2, 2).map(repr),
    st.integers(-3, 3).map(str),
    st.sampled_from(["", " ", "nan", "-inf", "1e999", "abc", "0x10", '"1"', "1,5", "\t"]),
    st.text(max_size=4),
)
_ROWS = st.lists(st.lists(_CELLS, min_size=0, max_size=6).map(",".join), max_size=40)
_HEADERS = st.sampled_from(["curve,x,y,z", " Curve , X , Y , Z ", "", "curve,x,y", "x,y,z,curve"])


#: Rows that are mostly right: a label 0..2 and three numbers, now and then a bad cell.
_GOOD_ROWS = st.lists(
    st.tuples(
        st.integers(0, 2).map(str),
        st.floats(-1, 1).map(repr),
        st.floats(-1, 1).map(repr),
        st.one_of(st.floats(-1, 1).map(repr), _CELLS),
    ).map(",".join),
    min_size=10,
    max_size=40,
)


@settings(derandomize=True, database=None, max_examples=80, deadline=None)
@given(
    header=_HEADERS,
    rows=st.one_of(_ROWS, _GOOD_ROWS),
    newline=st.sampled_from(["\n", "\r\n", "\r"]),
)
def test_random_csv_text(world, header, rows, newline):
    path = _path(world, ".csv")
    path.write_text(newline.join([header, *rows]), encoding="utf-8", newline="")
    _check(path)


_JSON = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=3),
    lambda inner: st.lists(inner, max_size=5)
    | st.dictionaries(st.sampled_from(["curves", "contact", "normal", "x"]), inner, max_size=3),
    max_leaves=30,
)


@settings(derandomize=True, database=None, max_examples=80, deadline=None)
@given(doc=_JSON)
def test_random_json(world, doc):
    path = _path(world, ".json")
    path.write_text(json.dumps(doc))
    _check(path)


# ----------------------------------------------------------------------------- shaped curves
_COORD = st.one_of(
    st.floats(-1, 1),
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, 1e-300, -1e-12, 1e12, 1e300]),
)
_CURVE = st.lists(st.tuples(_COORD, _COORD, _COORD), min_size=0, max_size=12)


@settings(derandomize=True, database=None, max_examples=40, deadline=None)
@given(curves=st.lists(_CURVE, min_size=2, max_size=4))
def test_random_curves(world, curves):
    path = _path(world, ".csv")
    write_csv(path, [np.array(c, dtype=float).reshape(-1, 3) for c in curves])
    _check(path)


#: One smooth curve: direction angle (degrees), bend, miss distance, points, noise, size.
_SMOOTH = st.tuples(
    st.floats(0, 180),
    st.floats(-3, 3),
    st.sampled_from([0.0, 0.0, 0.0, 0.01, 0.3]),
    st.sampled_from([21, 11, 5, 4]),
    st.sampled_from([0.0, 1e-4, 1e-2, 0.3]),
)


@settings(derandomize=True, database=None, max_examples=60, deadline=None)
@given(
    shapes=st.lists(_SMOOTH, min_size=3, max_size=4),
    size=st.sampled_from([1.0, 1e-3, 1e3, 1e-10, 1e13]),
    seed=st.integers(0, 2**16),
)
def test_random_smooth_curves(world, shapes, size, seed):
    # near-valid touches: curves that may miss each other, be parallel, short or noisy
    rng = np.random.default_rng(seed)
    curves = []
    for angle, bend, miss, n, noise in shapes:
        t = np.linspace(-0.3, 0.3, n)[:, None]
        d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle)), 0.0])
        c = t * d + 0.5 * bend * t**2 * np.array([0.0, 0.0, 1.0]) + [0.0, 0.0, miss]
        curves.append(size * (c + noise * rng.uniform(-1, 1, c.shape)))
    path = _path(world, ".csv")
    write_csv(path, curves)
    _check(path)


# ----------------------------------------------------------------------------- spoiled touches
def _mutate(curves, op, i, j, k, amount):
    """Apply one spoiling operation to curve ``i`` (rows ``j``, ``k``)."""
    curves = [c.copy() for c in curves]
    c = curves[i % len(curves)]
    j, k = j % len(c), k % len(c)
    if op == "drop_points":
        curves[i % len(curves)] = c[: max(j, 1)]
    elif op == "duplicate_row":
        curves[i % len(curves)] = np.insert(c, k, c[j], axis=0)
    elif op == "swap_rows":
        c[[j, k]] = c[[k, j]]
    elif op == "shift_curve":
        curves[i % len(curves)] = c + amount * np.array([0.3, -0.5, 0.8])
    elif op == "scale_all":
        curves = [d * 10.0 ** (3 * amount) for d in curves]
    elif op == "outlier":
        c[j] = c[j] + 10.0 ** (3 * amount)
    elif op == "nan":
        c[j, k % 3] = np.nan
    elif op == "reverse":
        curves[i % len(curves)] = c[::-1]
    elif op == "drop_curve":
        del curves[i % len(curves)]
    elif op == "copy_curve":
        curves[(i + 1) % len(curves)] = c.copy()
    elif op == "collapse":
        curves[i % len(curves)] = np.repeat(c[j : j + 1], len(c), axis=0)
    elif op == "flatten":
        curves = [d * [1.0, 1.0, 0.0] for d in curves]
    return curves


_OPS = st.tuples(
    st.sampled_from(
        [
            "drop_points",
            "duplicate_row",
            "swap_rows",
            "shift_curve",
            "scale_all",
            "outlier",
            "nan",
            "reverse",
            "drop_curve",
            "copy_curve",
            "collapse",
            "flatten",
        ]
    ),
    st.integers(0, 3),
    st.integers(0, 30),
    st.integers(0, 30),
    st.floats(-2, 2),
)


@pytest.mark.slow
@settings(derandomize=True, database=None, max_examples=20, deadline=None)
@given(ops=st.lists(_OPS, min_size=1, max_size=3))
def test_spoiled_good_touch_then_recognised(world, ops):
    curves = list(world["touch"].curves)
    for op in ops:
        if len(curves) == 0:
            break
        curves = _mutate(curves, *op)
    path = _path(world, ".csv")
    write_csv(path, curves)
    _check(path, world["library"])


def test_the_unspoiled_touch_is_recognised(world):
    # the baseline of the spoiled ones: the good touch passes every check
    path = _path(world, ".csv")
    write_csv(path, world["touch"].curves)
    assert _check(path, world["library"]) == "ok"


# ----------------------------------------------------------------------------- the Python API
_SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.integers(10**300, 10**400),
    st.floats(),
    st.complex_numbers(),
    st.text(max_size=4),
    st.binary(max_size=4),
)
_ARRAYS = hnp.arrays(
    dtype=st.sampled_from([np.float64, np.float32, np.int64, np.complex128, np.bool_, "U2"]),
    shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=8),
)
#: Anything an argument could be: scalars, nested lists, arrays of any dtype, mappings.
_ANYTHING = st.recursive(
    st.one_of(_SCALARS, _ARRAYS),
    lambda inner: st.lists(inner, max_size=6)
    | st.tuples(inner, inner, inner)
    | st.dictionaries(st.text(max_size=2), inner, max_size=2),
    max_leaves=40,
)


def _good_curves(world):
    return [np.array(c) for c in world["touch"].curves]


def _assert_names_an_argument(exc: Exception, names) -> None:
    """A TypeError or ValueError whose one-line message names one of ``names``."""
    assert isinstance(exc, (TypeError, ValueError)), repr(exc)
    message = str(exc)
    assert "\n" not in message
    assert any(name in message for name in names), (names, message)


@settings(derandomize=True, database=None, max_examples=80, deadline=None)
@given(
    which=st.sampled_from(["curves", "curve", "contact", "normal", "all"]),
    value=_ANYTHING,
    value2=_ANYTHING,
)
def test_touch_data_refuses_malformed_arguments(world, which, value, value2):
    curves = _good_curves(world)
    kwargs = {"curves": curves}
    if which == "curves":
        kwargs["curves"] = value
    elif which == "curve":
        kwargs["curves"] = [curves[0], value, curves[2]]
    elif which == "all":
        kwargs = {"curves": value, "contact": value2, "normal": value}
    else:
        kwargs[which] = value
    try:
        touch = TouchData(**kwargs)
    except Exception as exc:  # which exception, and its message, is the test
        _assert_names_an_argument(exc, ["curves", "contact", "normal"])
        return
    for c in touch.curves:
        assert c.dtype == np.float64
        assert c.ndim == 2
        assert c.shape[1] == 3
        assert np.isfinite(c).all()
    if touch.normal is not None:
        assert abs(np.linalg.norm(touch.normal) - 1.0) < 1e-12


@settings(derandomize=True, database=None, max_examples=80, deadline=None)
@given(
    which=st.sampled_from(["curves", "curve", "point", "normal", "degree"]),
    value=_ANYTHING,
)
def test_geometry_refuses_malformed_arguments(world, which, value):
    curves = _good_curves(world)
    kwargs = {"curves": curves}
    if which == "curve":
        kwargs["curves"] = [curves[0], value, curves[2]]
    else:
        kwargs[which] = value
    for func in (estimate_local_geometry, find_common_point):
        if func is find_common_point:
            kwargs = {"curves": kwargs["curves"]}
        try:
            result = func(**kwargs)
        except Exception as exc:  # which exception, and its message, is the test
            _assert_names_an_argument(exc, ["curves", "point", "normal", "degree"])
            continue
        assert np.isfinite(result.point).all()


@pytest.fixture(scope="module")
def small_ball():
    return trimesh.creation.icosphere(subdivisions=2)


@settings(derandomize=True, database=None, max_examples=60, deadline=None)
@given(
    which=st.sampled_from(
        ["contact", "rng", "n_points", "noise", "length", "transform", "name", "mesh"]
    ),
    value=_ANYTHING,
)
def test_simulate_refuses_malformed_arguments(small_ball, which, value):
    kwargs = {"mesh": small_ball, "rng": 0, "n_points": 7}
    kwargs[which] = value
    if which == "mesh" and isinstance(value, (str, bytes)):
        return  # a string names a file: relative to the working directory, not here
    try:
        sim = simulate_touch(**kwargs)
    except Exception as exc:  # which exception, and its message, is the test
        _assert_names_an_argument(exc, [which])
        return
    assert len(sim.touch.curves) == 3


@settings(derandomize=True, database=None, max_examples=40, deadline=None)
@given(
    which=st.sampled_from(["touch", "library", "method", "geometry", "progress"]),
    value=_ANYTHING,
)
def test_recognize_refuses_malformed_arguments(world, which, value):
    if value is None and which in ("geometry", "progress"):
        return  # their default
    kwargs = {"touch": world["touch"], "library": world["library"]}
    kwargs[which] = value
    try:
        recognize(**kwargs)
    except Exception as exc:  # which exception, and its message, is the test
        _assert_names_an_argument(exc, [which])
        return
    raise AssertionError(f"{which}={value!r} was accepted")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"touch": "t.csv"}, TypeError, "touch must be a TouchData, got str"),
        ({"geometry": 3}, TypeError, "geometry must be a LocalGeometry or None, got int"),
        ({"method": 1}, TypeError, r"method must be one of \('lm', 'steepest'\), got int"),
        ({"method": "x"}, ValueError, r"method must be one of \('lm', 'steepest'\), got 'x'"),
        ({"max_candidates": 1.5}, TypeError, "max_candidates must be an integer, got float"),
        ({"max_candidates": 0}, ValueError, "max_candidates must be >= 1, got 0"),
        ({"searches": True}, TypeError, "searches must be an integer, got bool"),
        ({"lookup_scale": "1"}, TypeError, "lookup_scale must be a real number, got str"),
        ({"lookup_scale": float("nan")}, ValueError, "lookup_scale must be finite"),
        ({"lookup_scale": 0.0}, ValueError, "lookup_scale must be > 0"),
    ],
)
def test_register_argument_checks(world, kwargs, error, match):
    from meshrec.registration.register import register

    args = {"touch": world["touch"], "model": world["library"]["ball"], **kwargs}
    with pytest.raises(error, match=match):
        register(**args)


def test_recognize_argument_checks(world):
    with pytest.raises(TypeError, match=r"library\[1\] must be a ModelIndex, got str"):
        recognize(world["touch"], [world["library"]["ball"], "ball.stl"])
    with pytest.raises(TypeError, match="library must be a ModelLibrary or an iterable"):
        recognize(world["touch"], "models/")
    with pytest.raises(TypeError, match="progress must be callable or None, got int"):
        recognize(world["touch"], world["library"], progress=1)
