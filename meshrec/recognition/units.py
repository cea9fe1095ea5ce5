"""Units: a touch's length unit converted to the models', and a size check both ways.

A touch and the models must be in the same length unit. When both units are known (the
touch's given by the user, the models' by a note in their folder, see
:func:`read_units_note`), :func:`convert_touch` rescales the touch. Whether the units are
known or not, :func:`check_units` compares the sizes and refuses a touch that cannot lie
on any of the models: larger than every model, or far smaller than every model.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.io.touch import TouchData
from meshrec.model.library import UNITS_NOTE

__all__ = [
    "UNITS",
    "UNITS_NOTE",
    "UNIT_MISMATCH",
    "check_units",
    "convert_touch",
    "read_units_note",
    "unit_factor",
]

#: The length units understood, in metres.
UNITS: dict[str, float] = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254}


#: The words every message of :func:`check_units` holds (the command line adds a hint).
UNIT_MISMATCH = "likely a unit mismatch"


def _unit(value, name: str) -> str:
    """``value`` if it is a known unit name, else ValueError naming ``name``."""
    if not isinstance(value, str) or value not in UNITS:
        raise ValueError(f"{name} must be one of {', '.join(UNITS)}, got {value!r}")
    return value


def unit_factor(from_units: str, to_units: str) -> float:
    """The factor that turns lengths in ``from_units`` into lengths in ``to_units``.

    Parameters
    ----------
    from_units, to_units : {"mm", "cm", "m", "in"}

    Returns
    -------
    float
        For example 0.001 from ``"mm"`` to ``"m"``.

    Raises
    ------
    ValueError
        If either is not a unit of :data:`UNITS`.
    """
    return UNITS[_unit(from_units, "from_units")] / UNITS[_unit(to_units, "to_units")]


def convert_touch(touch: TouchData, from_units: str, to_units: str) -> TouchData:
    """The touch with its curves, contact and probe radius rescaled from one unit to another.

    The normal is a direction and is kept; the source is kept.

    Parameters
    ----------
    touch : TouchData
    from_units, to_units : {"mm", "cm", "m", "in"}

    Returns
    -------
    TouchData
        ``touch`` itself when the units are the same.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData.
    ValueError
        If either unit is not one of :data:`UNITS`.
    """
    if not isinstance(touch, TouchData):
        raise TypeError(f"touch must be a TouchData, got {type(touch).__name__}")
    f = unit_factor(from_units, to_units)
    if f == 1.0:
        return touch
    return TouchData(
        curves=[c * f for c in touch.curves],
        contact=None if touch.contact is None else touch.contact * f,
        normal=touch.normal,
        source=touch.source,
        probe_radius=None if touch.probe_radius is None else touch.probe_radius * f,
    )


def read_units_note(folder: str | os.PathLike) -> str | None:
    """The length unit of a model folder, from its note file, if it has one.

    The note is a JSON file :data:`UNITS_NOTE` (``meshrec.json``) directly inside the
    folder: ``{"units": "mm"}``, with ``"mm"``, ``"cm"``, ``"m"``, ``"in"`` or ``null``
    (unitless, like the paper's surfaces). Model libraries ignore the file.

    Parameters
    ----------
    folder : str or path-like
        A model folder.

    Returns
    -------
    str or None
        The unit, or None when there is no note or it says ``null``.

    Raises
    ------
    ValueError
        If the note cannot be read or parsed, is not an object with exactly the key
        ``"units"``, or names an unknown unit (the message names the file).
    """
    path = Path(folder) / UNITS_NOTE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"units note {path}: cannot be read as JSON ({exc})") from exc
    if not isinstance(data, dict) or set(data) != {"units"}:
        raise ValueError(
            f'units note {path}: expected {{"units": "mm"}} (one key), got {data!r:.80}'
        )
    if data["units"] is None:
        return None
    try:
        return _unit(data["units"], "units")
    except ValueError as exc:
        raise ValueError(f"units note {path}: {exc}") from exc


def _diagonal(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def _mesh_diagonal(mesh) -> float:
    """A mesh's bounding-box diagonal, computed once per mesh (kept in its ``__dict__``
    as :func:`meshrec.model.surface.corner_normals` keeps its table: every recognition
    asks it of every model, 1% of a recognition of the paper surfaces)."""
    d = mesh.__dict__.get("_bbox_diagonal")
    if d is None:
        d = mesh.__dict__["_bbox_diagonal"] = _diagonal(np.asarray(mesh.vertices))
    return d


def check_units(touch: TouchData, models) -> None:
    """Refuse a touch whose size cannot be that of a touch on any of the models.

    The touch's size is the bounding-box diagonal of all its points, a model's the
    bounding-box diagonal of its vertices. The curves lie on the surface, so a touch
    fits inside the model's box: one more than ``defaults.UNIT_MAX_TOUCH_DIAGONALS``
    times larger than every model is in other units (millimetres against metres), as is
    one more than ``defaults.UNIT_MISMATCH_RATIO`` times smaller than every model
    (metres against millimetres).

    The two limits are not symmetric because a real touch is a fraction of its model:
    simulated touches measure about 0.3 of the model, a probe's often less. A single
    limit of 100 both ways (the earlier check, on sqrt(surface area)) put a touch in
    millimetres on a model in metres at 300 times or less, and missed it whenever the
    touch covered less than a third of the largest model (a touch on the YCB scissors,
    in millimetres, is 94 times the cracker box).

    Parameters
    ----------
    touch : TouchData
    models : iterable of ModelIndex
        At least one.

    Raises
    ------
    ValueError
        If the touch is larger than ``defaults.UNIT_MAX_TOUCH_DIAGONALS`` times every
        model's diagonal, or smaller than ``1 / defaults.UNIT_MISMATCH_RATIO`` of it (the
        message holds :data:`UNIT_MISMATCH`, "likely a unit mismatch"), or ``models`` is
        empty.
    """
    models = list(models)
    if not models:
        raise ValueError("models must hold at least one model, got none")
    size = _diagonal(touch.points)
    if not size > 0.0:
        return  # a point-like touch: the geometry estimate says what is wrong with it
    diagonals = np.array([_mesh_diagonal(m.mesh) for m in models])
    ratio = size / diagonals
    upper, lower = defaults.UNIT_MAX_TOUCH_DIAGONALS, 1.0 / defaults.UNIT_MISMATCH_RATIO
    if np.all(ratio > upper):
        k = int(np.argmin(ratio))
        limit = f"defaults.UNIT_MAX_TOUCH_DIAGONALS = {upper:g}"
        way, factor = "larger", ratio[k]
    elif np.all(ratio < lower):
        k = int(np.argmax(ratio))
        limit = f"1 / defaults.UNIT_MISMATCH_RATIO = {lower:g}"
        way, factor = "smaller", 1.0 / ratio[k]
    else:
        return
    raise ValueError(
        f"the touch data ({size:.4g} across) is {factor:.3g} times {way} than the "
        f"nearest-sized model {models[k].name!r} (bounding-box diagonal {diagonals[k]:.4g}), "
        f"beyond {limit} for every model: {UNIT_MISMATCH} (mm vs m?); touch data "
        "and models must be in the same units"
    )
