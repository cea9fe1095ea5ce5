"""``meshrec recognize --batch``: many touch files against one library, JSON Lines out."""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable

from meshrec.app.inputs import (
    STDIN,
    STDIN_NAME,
    error_message,
    read_touch,
    touch_in_units,
    with_probe_radius,
)
from meshrec.recognition.recognize import recognize
from meshrec.recognition.result import Recognition
from meshrec.registration.register import touch_geometry

__all__ = ["run_batch"]


def _one(
    name, library, units, models_units, method, to_json, probe_radius=None, workers=None
) -> dict:
    """The JSON object of one touch file: the recognition, or an ``error``."""
    shown = STDIN_NAME if str(name) == STDIN else str(name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            touch = read_touch(name)
            if probe_radius is not None:
                touch = with_probe_radius(touch, probe_radius)
            touch = touch_in_units(touch, units, models_units)
            try:
                geometry = touch_geometry(touch)
            except ValueError as exc:
                raise ValueError(f"touch file {shown}: {exc}") from exc
            rec = recognize(touch, library, method=method, geometry=geometry, workers=workers)
            doc = {"file": shown, **to_json(rec)}
        except ValueError as exc:
            doc = {"file": shown, "error": error_message(exc, units)}
    if caught:
        # the warnings raised while reading and recognising first, then the recognition's
        # own cautions (as `recognize --json` lists them; they were dropped here)
        raised = [str(w.message) for w in caught]
        doc["warnings"] = list(dict.fromkeys([*raised, *doc.get("warnings", [])]))
    return doc


def run_batch(
    names,
    library,
    out,
    to_json: Callable[[Recognition], dict],
    units: str | None = None,
    models_units: str | None = None,
    method: str = "lm",
    probe_radius: float | None = None,
    workers=None,
) -> int:
    """Recognise every touch file against ``library``; one JSON line each on ``out``.

    A touch that fails (a bad file, a unit mismatch, curves that do not allow a geometry
    estimate) gives a line ``{"file", "error"}`` and the others still run. Warnings about a
    touch go into its line (``"warnings": [...]``), not on stderr. Each line is flushed as
    it is written, so a reader of a pipe sees the results as they come.

    Parameters
    ----------
    names : sequence of str
        Touch files (``"-"``: standard input).
    library : ModelLibrary
        Loaded once, shared by every touch.
    out : text stream
    to_json : callable
        ``to_json(recognition) -> dict``, the single recognition's JSON document.
    units, models_units : str or None
        The touches' and the models' length units (see ``--units``).
    method : {"lm", "steepest"}
    probe_radius : float, optional
        The probe's ball-tip radius, in the touches' units (``--probe-radius``): it
        replaces the touch files' own.
    workers : ModelWorkers or None
        Where the per-model work runs (see :func:`meshrec.recognition.recognize.recognize`).

    Returns
    -------
    int
        How many touches failed.
    """
    failed = 0
    for name in names:
        doc = _one(
            name, library, units, models_units, method, to_json, probe_radius, workers
        )
        failed += "error" in doc
        out.write(json.dumps(doc) + "\n")
        out.flush()
    return failed
