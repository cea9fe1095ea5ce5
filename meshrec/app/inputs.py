"""What the command line reads: a touch from a file or standard input, the model folder
(a path or the name of a bundled set), and the units on both sides."""

from __future__ import annotations

import copy
import dataclasses
import sys
import tempfile
import warnings
from pathlib import Path

from meshrec.io.touch import TouchData
from meshrec.model.library import bundled_model_sets, bundled_models_dir
from meshrec.recognition.units import UNIT_MISMATCH, convert_touch, read_units_note

__all__ = [
    "STDIN",
    "STDIN_NAME",
    "error_message",
    "library",
    "model_folder",
    "model_units",
    "read_touch",
    "touch_and_geometry",
    "touch_in_units",
    "touch_units",
    "touches_and_geometries",
]

#: The touch-file argument that reads standard input, and the name it is given.
STDIN, STDIN_NAME = "-", "<stdin>"


def read_touch(name: str | Path, stdin=None) -> TouchData:
    """A touch from a file (``.csv`` or ``.json``) or, for ``"-"``, standard input.

    Standard input holds a CSV or JSON touch; JSON if its first character (after blanks)
    is ``{``, CSV otherwise. Its data are checked exactly as a file's are (through a
    temporary file, removed at once); messages and the touch's ``source`` say
    ``<stdin>``.

    Parameters
    ----------
    name : str or Path
    stdin : binary file, optional
        Where ``"-"`` reads (default: ``sys.stdin.buffer``).

    Returns
    -------
    TouchData

    Raises
    ------
    ValueError
        If the file or the input is not a valid touch, or ``"-"`` is given while
        standard input is a terminal.
    """
    if str(name) != STDIN:
        return TouchData.from_file(name)
    if stdin is None:
        if sys.stdin is None or sys.stdin.isatty():
            raise ValueError(
                "touch file -: standard input is a terminal; pipe a CSV or JSON touch into it"
            )
        stdin = sys.stdin.buffer
    raw = stdin.read()
    text = raw.lstrip(b"\xef\xbb\xbf \t\r\n")
    suffix = ".json" if text[:1] in (b"{", b"[") else ".csv"
    with tempfile.TemporaryDirectory(prefix="meshrec-stdin-") as tmp:
        path = Path(tmp) / f"stdin{suffix}"
        path.write_bytes(raw)
        try:
            touch = TouchData.from_file(path)
        except ValueError as exc:
            raise ValueError(str(exc).replace(str(path), STDIN_NAME)) from None
    return TouchData(
        curves=touch.curves, contact=touch.contact, normal=touch.normal, source=STDIN_NAME
    )


def model_folder(text: str | Path | None) -> Path:
    """The model folder named by ``--models``: a path, or the name of a bundled set.

    An existing path wins; a plain name (no ``/``) that is not a path names a bundled set
    (``surfaces``, ``objects``, ``parts``, ``primitives``). None gives the bundled paper
    surfaces.

    Raises
    ------
    ValueError
        If ``text`` is neither an existing path nor a bundled set's name (the message
        lists the bundled sets).
    """
    if text is None:
        return bundled_models_dir("surfaces")
    path = Path(text)
    if path.exists():
        return path
    sets = bundled_model_sets()
    if path.name == str(text) and str(text) in sets:
        return bundled_models_dir(str(text))
    raise ValueError(
        f"--models {text}: no such folder, nor a bundled set "
        f"(bundled: {', '.join(sets) if sets else 'none'})"
    )


def model_units(folder: Path, given: str | None) -> str | None:
    """The models' length unit: ``given`` (``--model-units``), else the folder's note.

    Raises
    ------
    ValueError
        If the folder's units note is malformed.
    """
    return given if given is not None else read_units_note(folder)


def touch_units(
    units: str | None, models_units: str | None, given_as: str = "--units"
) -> str | None:
    """The touch's unit to convert from: ``units`` when the models' units are known too.

    ``given_as`` names where ``units`` came from in the warning (``--units`` on the
    command line; the service passes its request's key).

    Warns
    -----
    UserWarning
        If ``units`` is given but the models' are unknown: nothing to convert to, only
        the size check applies (:func:`meshrec.recognition.units.check_units`).
    """
    if units is not None and models_units is None:
        models = (
            "--model-units, or a meshrec.json note in the model folder"
            if given_as == "--units"
            else "a meshrec.json note in the model folder, or serve's --model-units"
        )
        warnings.warn(
            f"{given_as} {units} is not used: the models' units are unknown (give "
            f"{models}); only the size check applies",
            UserWarning,
            stacklevel=2,
        )
        return None
    return units


def touch_in_units(touch: TouchData, units: str | None, models_units: str | None) -> TouchData:
    """The touch converted from ``units`` to ``models_units`` when both are given; as it
    is when either is None."""
    if units is None or models_units is None:
        return touch
    return convert_touch(touch, units, models_units)


def with_probe_radius(touch: TouchData, radius: float) -> TouchData:
    """The touch with its ``probe_radius`` replaced (``--probe-radius``).

    Raises
    ------
    ValueError
        If ``radius`` is negative or not finite (the message names ``--probe-radius``).
    """
    try:
        return dataclasses.replace(touch, probe_radius=radius)
    except (TypeError, ValueError) as exc:
        raise ValueError(str(exc).replace("probe_radius", "--probe-radius", 1)) from None


def touch_and_geometry(args, folder: Path, models_units: str | None):
    """The touch named by ``args.touch_file`` with its hints, in the models' units, and
    its local geometry: bad data fail here, before any model is indexed.

    Returns
    -------
    touch : TouchData
    geometry : LocalGeometry

    Raises
    ------
    ValueError
        If the touch cannot be read or its curves allow no geometry estimate.
    """
    from meshrec.registration.register import touch_geometry

    name = args.touch_file
    units = touch_units(getattr(args, "units", None), models_units)
    touch = read_touch(name)
    contact, normal = getattr(args, "contact", None), getattr(args, "normal", None)
    if contact is not None or normal is not None:  # in the touch's units, like the file
        touch = touch.with_hints(contact=contact, normal=normal)
    radius = getattr(args, "probe_radius", None)
    if radius is not None:  # in the touch's units too; it replaces the file's own
        touch = with_probe_radius(touch, radius)
    touch = touch_in_units(touch, units, models_units)
    try:
        geometry = touch_geometry(touch)
    except ValueError as exc:
        shown = STDIN_NAME if str(name) == STDIN else name
        raise ValueError(f"touch file {shown}: {exc}") from exc
    return touch, geometry


def touches_and_geometries(args, names, folder: Path, models_units: str | None):
    """Every touch named (``names``: one or more touch files), as
    :func:`touch_and_geometry` reads one; ``--contact`` and ``--normal`` only with one.

    Returns
    -------
    touches : list of TouchData
    geometries : list of LocalGeometry

    Raises
    ------
    ValueError
        If a touch cannot be read or its curves allow no geometry estimate, ``-``
        (standard input) is named more than once, or a hint is given with several touches.
    """
    names = list(names)
    if sum(str(n) == STDIN for n in names) > 1:
        raise ValueError("touch file - (standard input) can be given only once")
    if len(names) > 1:
        for option in ("contact", "normal"):
            if getattr(args, option, None) is not None:
                raise ValueError(
                    f"--{option} gives one touch's hint: not with {len(names)} touch files"
                )
    touches, geometries = [], []
    for name in names:
        one = copy.copy(args)
        one.touch_file = name
        touch, geometry = touch_and_geometry(one, folder, models_units)
        touches.append(touch)
        geometries.append(geometry)
    return touches, geometries


def library(args, folder: Path, progress=None):
    """The model library of ``folder``, with ``args.cache_dir`` and ``args.force``."""
    from meshrec.model.library import ModelLibrary

    return ModelLibrary.from_folder(
        folder, cache_dir=args.cache_dir, force=getattr(args, "force", False), progress=progress
    )


def error_message(exc: ValueError, units: str | None = None) -> str:
    """The one-line message of a bad-input error, with what to do about a unit mismatch
    (``units``: the touch's ``--units``, when given)."""
    from meshrec.io.checks import one_line

    text = one_line(str(exc), None)
    if UNIT_MISMATCH in text:
        if units is not None:
            return (
                f"{text} (the touch was read in {units} as --units says: check that unit, "
                "and the models' with --model-units or a meshrec.json note in their folder)"
            )
        return (
            f"{text} (give the touch's unit with --units, and the models' with --model-units "
            "or a meshrec.json note in their folder)"
        )
    return text
