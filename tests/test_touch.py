"""Tests for meshrec.io.touch: reading, writing and validating touch data."""

import json
import os
import warnings

import numpy as np
import pytest

from meshrec import defaults
from meshrec.io.touch import TouchData


def _curves(seed=0, n=7):
    rng = np.random.default_rng(seed)
    return [rng.normal(size=(n, 3)) for _ in range(3)]


def test_csv_round_trip(tmp_path):
    touch = TouchData(curves=_curves())
    path = tmp_path / "t.csv"
    touch.to_csv(path)
    back = TouchData.from_file(path)
    assert len(back.curves) == 3
    for a, b in zip(touch.curves, back.curves, strict=True):
        np.testing.assert_array_equal(a, b)
    assert back.source == str(path)


def test_json_round_trip_keeps_hints(tmp_path):
    touch = TouchData(curves=_curves(), contact=[1, 2, 3], normal=[0, 0, 2])
    path = tmp_path / "t.json"
    touch.to_file(path)
    back = TouchData.from_file(path)
    np.testing.assert_array_equal(back.contact, [1, 2, 3])
    np.testing.assert_allclose(back.normal, [0, 0, 1])
    for a, b in zip(touch.curves, back.curves, strict=True):
        np.testing.assert_array_equal(a, b)


def test_csv_labels_any_integers_and_order(tmp_path):
    path = tmp_path / "t.csv"
    rows = ["curve,x,y,z"]
    for label in (7, 3, 5):
        for i in range(5):
            rows.append(f"{label},{label},{i},0")
    path.write_text("\n".join(rows) + "\n")
    touch = TouchData.from_csv(path)
    assert [c[0, 0] for c in touch.curves] == [3.0, 5.0, 7.0]
    np.testing.assert_array_equal(touch.curves[0][:, 1], np.arange(5))


def test_points_labels_and_transform():
    touch = TouchData(curves=_curves(), contact=[0, 0, 0], normal=[0, 0, 1])
    assert touch.points.shape == (21, 3)
    assert touch.n_points == 21
    np.testing.assert_array_equal(np.bincount(touch.labels), [7, 7, 7])
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T[:3, 3] = [1, 2, 3]
    moved = touch.transformed(T)
    np.testing.assert_allclose(moved.points, touch.points @ T[:3, :3].T + [1, 2, 3])
    np.testing.assert_allclose(moved.contact, [1, 2, 3])
    np.testing.assert_allclose(moved.normal, [0, 0, 1])
    assert "3 curves" in repr(touch)


def test_with_hints():
    touch = TouchData(curves=_curves()).with_hints(contact=[1, 1, 1])
    np.testing.assert_array_equal(touch.contact, [1, 1, 1])
    assert touch.normal is None


_BIG = 10**400  # beyond any float


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"curves": _curves()[:2]}, ValueError, "at least 3 curves"),
        (
            {"curves": [*_curves()[:2], np.zeros(5)]},
            ValueError,
            r"curves\[2\] must be \(n, 3\), got \(5,\)",
        ),
        (
            {"curves": [*_curves()[:2], np.zeros((4, 3))]},
            ValueError,
            r"curves\[2\] must have at least 5",
        ),
        (
            {"curves": [*_curves()[:2], np.full((5, 3), np.nan)]},
            ValueError,
            "non-finite point at row 0",
        ),
        ({"curves": np.zeros((10, 3))}, ValueError, "curves must be a sequence of"),
        ({"curves": 5}, TypeError, "curves must be a sequence of .* got int"),
        ({"curves": "abc"}, TypeError, "curves must be a sequence of .* got str"),
        ({"curves": {"a": 1}}, TypeError, "curves must be a sequence of .* got dict"),
        ({"curves": [*_curves()[:2], [["a", 1, 2]] * 5]}, TypeError, r"curves\[2\] must hold real"),
        ({"curves": [*_curves()[:2], [[object(), 1, 2]] * 5]}, TypeError, r"curves\[2\] must hold"),
        ({"curves": [*_curves()[:2], _curves()[2] + 0j]}, TypeError, r"curves\[2\] .* complex"),
        ({"curves": [*_curves()[:2], _curves()[2] > 0]}, TypeError, r"curves\[2\] .* bool"),
        ({"curves": [*_curves()[:2], [[_BIG, 0, 0]] * 5]}, ValueError, r"curves\[2\] .* too large"),
        ({"curves": [*_curves()[:2], [[1, 2, 3], [1, 2]]]}, ValueError, r"curves\[2\] .* regular"),
        (
            {"curves": [np.zeros((defaults.MAX_POINTS_PER_CURVE + 1, 3))] * 3},
            ValueError,
            r"curves\[0\] must have at most 10000 points",
        ),
        (
            {"curves": [np.zeros((defaults.MAX_TOUCH_POINTS // 4 + 1, 3))] * 4},
            ValueError,
            "at most 30000 points in all",
        ),
        ({"curves": _curves() * 6}, ValueError, "at most 16 curves"),
        (
            {"curves": _curves(), "contact": [1, 2]},
            ValueError,
            r"contact must be \(3,\), got \(2,\)",
        ),
        ({"curves": _curves(), "contact": "abc"}, TypeError, "contact must be an array of real"),
        ({"curves": _curves(), "contact": [1j, 0, 0]}, TypeError, "contact must hold real"),
        ({"curves": _curves(), "contact": [_BIG, 0, 0]}, ValueError, "contact holds a number too"),
        ({"curves": _curves(), "normal": [0, 0, np.inf]}, ValueError, "normal must be finite"),
        ({"curves": _curves(), "normal": [0, 0, 0]}, ValueError, "non-zero"),
        ({"curves": _curves(), "normal": None, "source": 3}, TypeError, "source must be a str"),
    ],
)
def test_validation_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        TouchData(**kwargs)


def test_huge_normal_is_normalised_without_overflow():
    # (1e308)^2 overflows: the length is taken after scaling, with no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        touch = TouchData(curves=_curves(), normal=[1e308, 0, 1e308])
    np.testing.assert_allclose(touch.normal, [2**-0.5, 0, 2**-0.5])
    np.testing.assert_allclose(TouchData(curves=_curves(), normal=[0, 3e-320, 0]).normal, [0, 1, 0])


def test_min_points_constant_is_used():
    curves = [np.zeros((defaults.MIN_POINTS_PER_CURVE, 3))] * defaults.MIN_CURVES
    assert len(TouchData(curves=curves).curves) == defaults.MIN_CURVES


def test_transformed_rejects_bad_matrix():
    with pytest.raises(ValueError, match=r"T must be a finite \(4, 4\)"):
        TouchData(curves=_curves()).transformed(np.eye(3))


@pytest.mark.parametrize(
    "T",
    [
        np.diag([2.0, 2.0, 2.0, 1.0]),  # a scale
        np.diag([-1.0, 1.0, 1.0, 1.0]),  # a mirror
        np.array([[1, 0.3, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]),  # a shear
        np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.1, 0, 0, 1.0]]),  # projective
    ],
)
def test_transformed_rejects_a_motion_that_is_not_rigid(T):
    # each was applied silently (the last row ignored): a touch would change its shape
    with pytest.raises(ValueError, match=r"T must be a rigid transform"):
        TouchData(curves=_curves()).transformed(T)


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("e.csv", "", "empty"),
        ("h.csv", "a,b,c,d\n0,1,2,3\n", "header must be 'curve,x,y,z'"),
        ("f.csv", "curve,x,y,z\n0,1,2\n", "line 2 must have 4 fields"),
        ("n.csv", "curve,x,y,z\n0,1,two,3\n", "line 2 is not numeric"),
        ("i.csv", "curve,x,y,z\n0,1,nan,3\n", "line 2 has a non-finite value"),
        ("l.csv", "curve,x,y,z\n0.5,1,2,3\n", "curve label must be an integer"),
        ("c.csv", "curve,x,y,z\n" + "0,1,2,3\n" * 5, "at least 3 curves"),
        ("j.json", "{not json", "not valid JSON"),
        ("k.json", '{"points": []}', "expected an object with a 'curves' list"),
        ("u.json", '{"curves": [], "extra": 1}', "unknown keys"),
        ("v.json", '{"curves": 3}', "'curves' must be a list"),
        ("x.txt", "curve,x,y,z\n", "unknown suffix"),
    ],
)
def test_file_errors(tmp_path, name, content, match):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(ValueError, match=match):
        TouchData.from_file(path)


def test_missing_directory_binary_and_non_utf8(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        TouchData.from_file(tmp_path / "missing.csv")
    folder = tmp_path / "dir.csv"
    folder.mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        TouchData.from_file(folder)
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"\x00\x01\x02garbage")
    with pytest.raises(ValueError, match="binary content"):
        TouchData.from_file(binary)
    latin = tmp_path / "l.csv"
    latin.write_bytes(b"curve,x,y,z\n0,\xe9,1,2\n")
    with pytest.raises(ValueError, match="not UTF-8"):
        TouchData.from_file(latin)


def test_to_file_rejects_unknown_suffix(tmp_path):
    with pytest.raises(ValueError, match=r"must end in \.csv or \.json"):
        TouchData(curves=_curves()).to_file(tmp_path / "t.txt")


def test_json_file_is_plain_json(tmp_path):
    path = tmp_path / "t.json"
    TouchData(curves=_curves()).to_json(path)
    data = json.loads(path.read_text())
    assert set(data) == {"curves"}
    assert len(data["curves"]) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]  # no temporary file left


def test_paths_must_be_paths(tmp_path):
    touch = TouchData(curves=_curves())
    for call in (TouchData.from_file, TouchData.from_csv, TouchData.from_json, touch.to_file):
        with pytest.raises(TypeError, match=r"path must be a str or os\.PathLike, got int"):
            call(3)
    with pytest.raises(TypeError, match=r"T must hold real numbers, got a complex128"):
        touch.transformed(np.eye(4, dtype=complex))


def test_written_files_follow_the_umask(tmp_path):
    previous = os.umask(0o077)
    try:
        TouchData(curves=_curves()).to_file(tmp_path / "private.csv")
    finally:
        os.umask(previous)
    TouchData(curves=_curves()).to_file(tmp_path / "shared.json")
    assert (tmp_path / "private.csv").stat().st_mode & 0o777 == 0o600
    assert (tmp_path / "shared.json").stat().st_mode & 0o777 == 0o666 & ~previous


def test_from_dict_checks_as_the_json_file_reader_does(tmp_path):
    """from_dict is the file reader's check: same touch, same problem in the message."""
    curves = [c.tolist() for c in _curves()]
    obj = {"curves": curves, "normal": [0.0, 0.0, 2.0]}
    touch = TouchData.from_dict(obj, source="<request>")
    assert touch.source == "<request>"
    np.testing.assert_allclose(touch.normal, [0.0, 0.0, 1.0])
    path = tmp_path / "t.json"
    path.write_text(json.dumps(obj))
    from_file = TouchData.from_json(path)
    for a, b in zip(touch.curves, from_file.curves, strict=True):
        np.testing.assert_array_equal(a, b)
    for bad, problem in [
        (3, "expected an object with a 'curves' list"),
        ({"curves": 3}, "'curves' must be a list of curves"),
        ({"curves": curves, "colour": 1}, "unknown keys"),
        ({"curves": [[[0, 0, True]]]}, "must hold numbers"),
        ({"curves": curves, "contact": [0, 0]}, "contact must have 3 numbers"),
    ]:
        with pytest.raises(ValueError, match=r"^request body: .*" + problem):
            TouchData.from_dict(bad, label="request body")
        path.write_text(json.dumps(bad))
        with pytest.raises(ValueError, match=problem):
            TouchData.from_json(path)
    with pytest.raises(ValueError, match=r"^touch: "):
        TouchData.from_dict({"curves": [[[0.0, 0.0, float("nan")]] * 5] * 3})


def test_without_repeats_leaves_out_exact_copies_of_the_sample_before():
    rng = np.random.default_rng(3)
    curves = [rng.normal(size=(9, 3)) for _ in range(3)]
    touch = TouchData(curves=curves, contact=[0.0, 0.0, 0.0], normal=[0.0, 0.0, 1.0])
    same, removed = touch.without_repeats()
    assert same is touch
    assert removed == 0
    # each sample logged three times (a logger three times faster than its sensor) and
    # one sample resting five times: the copies go, the samples and hints stay
    logged = [np.repeat(c, 3, axis=0) for c in curves[:2]]
    logged.append(
        np.concatenate([curves[2][:4], np.repeat(curves[2][4:5], 5, axis=0), curves[2][5:]])
    )
    kept, removed = TouchData(
        curves=logged, normal=[0.0, 0.0, 1.0], source="f.csv"
    ).without_repeats()
    assert removed == 2 * 18 + 4
    for a, b in zip(kept.curves, curves, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(kept.normal, [0.0, 0.0, 1.0])
    assert kept.source == "f.csv"
    # a sample equal to one further back is not a repeat of the one before it: kept
    back = np.vstack([curves[0], curves[0][:1] + 1.0, curves[0][:1]])
    assert TouchData(curves=[back, curves[1], curves[2]]).without_repeats()[1] == 0
    # a curve left with too few samples keeps its copies (the geometry refuses it by name)
    short = np.repeat(curves[0][:4], 3, axis=0)
    same, removed = TouchData(curves=[short, curves[1], curves[2]]).without_repeats()
    assert removed == 0
    assert len(same.curves[0]) == 12
