"""Units: conversion of a touch between length units, the folder's units note, and the
size check that refuses a touch in other units than the models, both ways."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import trimesh

from meshrec import ModelLibrary, TouchData, defaults, recognize
from meshrec.recognition.units import (
    UNIT_MISMATCH,
    UNITS,
    check_units,
    convert_touch,
    read_units_note,
    unit_factor,
)


def _star(half: float, centre=(0.0, 0.0, 0.0)) -> TouchData:
    """Three straight curves of length 2 * half through ``centre``, 60 degrees apart, in
    the z = const plane: their bounding-box diagonal is known."""
    t = np.linspace(-half, half, 11)[:, None]
    curves = []
    for a in np.radians([0.0, 60.0, 120.0]):
        curves.append(np.asarray(centre) + t * np.array([np.cos(a), np.sin(a), 0.0]))
    return TouchData(curves=curves, contact=centre, normal=[0.0, 0.0, 1.0])


def _diagonal(touch: TouchData) -> float:
    return float(np.linalg.norm(np.ptp(touch.points, axis=0)))


@pytest.fixture(scope="module")
def boxes(tmp_path_factory):
    """Two boxes the size of YCB objects, in metres: the cracker box and a flat one the
    size of the scissors (the case the earlier check missed)."""
    folder = tmp_path_factory.mktemp("boxes")
    trimesh.creation.box(extents=[0.07173, 0.163977, 0.213487]).export(folder / "cracker.stl")
    trimesh.creation.box(extents=[0.203869, 0.08717, 0.019528]).export(folder / "flat.stl")
    with warnings.catch_warnings():  # flat faces: no usable curvature, a LibraryWarning
        warnings.simplefilter("ignore")
        return ModelLibrary.from_folder(folder, cache_dir=tmp_path_factory.mktemp("cache"))


def test_unit_factors():
    assert unit_factor("mm", "m") == pytest.approx(1e-3)
    assert unit_factor("m", "mm") == pytest.approx(1e3)
    assert unit_factor("in", "mm") == pytest.approx(25.4)
    assert unit_factor("cm", "in") == pytest.approx(1 / 2.54)
    assert unit_factor("m", "m") == 1.0
    assert set(UNITS) == {"mm", "cm", "m", "in"}


@pytest.mark.parametrize(("a", "b", "name"), [("mm", "ft", "to_units"), ("um", "m", "from_units")])
def test_unknown_unit_is_refused(a, b, name):
    with pytest.raises(ValueError, match=f"{name} must be one of mm, cm, m, in, got"):
        unit_factor(a, b)


def test_convert_touch_scales_points_and_contact_not_the_normal():
    touch = _star(15.0, centre=(100.0, -20.0, 5.0))
    m = convert_touch(touch, "mm", "m")
    for a, b in zip(touch.curves, m.curves, strict=True):
        np.testing.assert_allclose(b, a / 1000.0)
    np.testing.assert_allclose(m.contact, [0.1, -0.02, 0.005])
    np.testing.assert_allclose(m.normal, touch.normal)
    assert convert_touch(touch, "cm", "cm") is touch
    with pytest.raises(TypeError, match="touch must be a TouchData, got list"):
        convert_touch([], "mm", "m")


def test_units_note(tmp_path):
    assert read_units_note(tmp_path) is None  # no note
    note = tmp_path / "meshrec.json"
    note.write_text(json.dumps({"units": "mm"}))
    assert read_units_note(tmp_path) == "mm"
    note.write_text(json.dumps({"units": None}))  # unitless
    assert read_units_note(tmp_path) is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{units: mm}", "cannot be read as JSON"),
        ('{"unit": "mm"}', "expected .* \\(one key\\)"),
        ('{"units": "mm", "scale": 2}', "expected .* \\(one key\\)"),
        ('["mm"]', "expected .* \\(one key\\)"),
        ('{"units": "furlong"}', "units must be one of mm, cm, m, in, got 'furlong'"),
    ],
)
def test_bad_units_note_names_the_file(tmp_path, text, message):
    (tmp_path / "meshrec.json").write_text(text)
    with pytest.raises(ValueError, match=f"units note {tmp_path / 'meshrec.json'}: {message}"):
        read_units_note(tmp_path)


def test_library_ignores_the_units_note(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    trimesh.creation.icosphere(subdivisions=3).export(folder / "ball.stl")
    (folder / "meshrec.json").write_text('{"units": "m"}')
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "skipping meshrec.json" warning
        lib = ModelLibrary.from_folder(folder, cache_dir=tmp_path / "cache")
    assert lib.names == ("ball",)
    assert lib.skipped == ()


def test_millimetres_against_metres_is_caught(boxes):
    # a touch 2.6 cm across on the flat box, in metres: fits
    touch_m = _star(0.01)
    check_units(touch_m, boxes)
    # the same touch in millimetres. The earlier check (touch diagonal against
    # 100 x sqrt(area) of the largest model) let it through: 26 mm is 75 of them.
    touch_mm = convert_touch(touch_m, "m", "mm")
    assert _diagonal(touch_mm) / boxes["cracker"].mesh.scale < defaults.UNIT_MISMATCH_RATIO
    with pytest.raises(
        ValueError,
        match=r"is \d+ times larger than the nearest-sized model 'cracker' \(bounding-box "
        r"diagonal 0\.27\d*\).*likely a unit mismatch \(mm vs m\?\)",
    ):
        check_units(touch_mm, boxes)
    with pytest.raises(ValueError, match=UNIT_MISMATCH):
        recognize(touch_mm, boxes)  # recognize checks first
    # and metres against millimetres: 0.00003 "m" on a box 0.27 across
    with pytest.raises(
        ValueError, match=r"times smaller than the nearest-sized model 'flat'.*unit mismatch"
    ):
        check_units(convert_touch(touch_m, "mm", "m"), boxes)


def test_the_model_diagonals_are_kept_and_equal_to_brute_force(boxes):
    # check_units keeps each mesh's bounding-box diagonal (asked at every recognition):
    # the value kept is the diagonal of the vertices' box, and a second check agrees.
    touch = _star(0.01)
    check_units(touch, boxes)
    for m in boxes:
        want = float(np.linalg.norm(np.ptp(np.asarray(m.mesh.vertices), axis=0)))
        assert m.mesh.__dict__["_bbox_diagonal"] == want
    check_units(touch, boxes)
    with pytest.raises(ValueError, match="larger"):
        check_units(convert_touch(touch, "m", "mm"), boxes)


def test_the_limits_are_the_defaults(boxes):
    big = float(np.linalg.norm(np.ptp(boxes["cracker"].mesh.vertices, axis=0)))  # the largest
    small = float(np.linalg.norm(np.ptp(boxes["flat"].mesh.vertices, axis=0)))
    assert small < big
    d = _diagonal(_star(1.0))
    ok = _star(0.95 * defaults.UNIT_MAX_TOUCH_DIAGONALS * big / d)
    check_units(ok, boxes)
    with pytest.raises(ValueError, match="larger"):
        check_units(_star(1.05 * defaults.UNIT_MAX_TOUCH_DIAGONALS * big / d), boxes)
    check_units(_star(1.05 * small / defaults.UNIT_MISMATCH_RATIO / d), boxes)
    with pytest.raises(ValueError, match="smaller"):
        check_units(_star(0.95 * small / defaults.UNIT_MISMATCH_RATIO / d), boxes)
    with pytest.raises(ValueError, match="models must hold at least one model, got none"):
        check_units(ok, [])
