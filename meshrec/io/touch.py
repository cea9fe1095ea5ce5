"""Touch data: the probe's points along three or more concurrent curves, read and written.

Two file formats are accepted:

* CSV with the header ``curve,x,y,z``: one row per point, ``curve`` an integer label.
  Points keep their file order within a curve; curves are ordered by label.
* JSON ``{"curves": [[[x, y, z], ...], ...], "contact": [x, y, z], "normal": [x, y, z],
  "probe_radius": r}`` where ``contact``, ``normal`` and ``probe_radius`` (the radius of
  the probe's ball tip, data units) are optional.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.io.checks import (
    check_curves,
    check_number,
    check_transform,
    check_vector,
    one_line,
)
from meshrec.io.files import read_text, write_atomic

__all__ = ["RepeatedSamplesWarning", "TouchData"]

_CSV_HEADER = ("curve", "x", "y", "z")


class RepeatedSamplesWarning(UserWarning):
    """Samples that repeat the one before them exactly were counted once
    (:meth:`TouchData.without_repeats`)."""


@dataclass(frozen=True, eq=False)
class TouchData:
    """Points sampled by a touch probe along three or more concurrent curves.

    Parameters
    ----------
    curves : sequence of (n_i, 3) float
        The curves, each ordered along the curve, in the touch (sensor) frame. At least
        ``defaults.MIN_CURVES`` curves with at least ``defaults.MIN_POINTS_PER_CURVE``
        points each.
    contact : (3,) float, optional
        The curves' common point, if known; otherwise it is estimated from the curves.
    normal : (3,) float, optional
        An approximate outward surface normal at the contact (for example minus the
        probe's approach direction). Without it both sides of the surface are tried.
    source : str, optional
        Where the touch came from (a file name), for messages.
    probe_radius : float, optional
        Radius of the probe's ball tip, data units, if known: the curves are then the
        ball's centres, on the surface offset outwards by it (see
        :mod:`meshrec.contact.probe`). None: not recorded (recognition assumes 0 unless
        told otherwise).

    Raises
    ------
    TypeError
        If ``curves`` is not a sequence of arrays, a curve, ``contact`` or ``normal`` is
        not real numbers (complex, bool, strings), ``source`` is not a str, or
        ``probe_radius`` is not a real number.
    ValueError
        If there are fewer than ``defaults.MIN_CURVES`` or more than
        ``defaults.MAX_CURVES`` curves, a curve is not (n, 3), has fewer than
        ``defaults.MIN_POINTS_PER_CURVE`` or more than ``defaults.MAX_POINTS_PER_CURVE``
        points or a non-finite value, all curves hold more than
        ``defaults.MAX_TOUCH_POINTS`` points, or ``contact`` / ``normal`` is not a finite
        (3,) vector, ``normal`` is zero (see :mod:`meshrec.io.checks`), or
        ``probe_radius`` is negative or not finite.
    """

    curves: tuple[np.ndarray, ...]
    contact: np.ndarray | None = None
    normal: np.ndarray | None = None
    source: str | None = field(default=None, compare=False)
    probe_radius: float | None = None

    def __post_init__(self):
        curves = check_curves(self.curves, "curves")
        for c in curves:
            c.setflags(write=False)
        object.__setattr__(self, "curves", tuple(curves))
        if self.contact is not None:
            object.__setattr__(self, "contact", check_vector(self.contact, "contact"))
        if self.normal is not None:
            object.__setattr__(self, "normal", check_vector(self.normal, "normal", unit=True))
        if self.source is not None and not isinstance(self.source, str):
            raise TypeError(f"source must be a str or None, got {type(self.source).__name__}")
        if self.probe_radius is not None:
            radius = check_number(self.probe_radius, "probe_radius", minimum=0.0)
            object.__setattr__(self, "probe_radius", radius)

    # ------------------------------------------------------------------ properties
    @property
    def points(self) -> np.ndarray:
        """(N, 3) float: all points of all curves, stacked in curve order."""
        return np.vstack(self.curves)

    @property
    def labels(self) -> np.ndarray:
        """(N,) int: the curve index of each row of :attr:`points`."""
        return np.concatenate([np.full(len(c), i) for i, c in enumerate(self.curves)])

    @property
    def n_points(self) -> int:
        """Total number of points."""
        return int(sum(len(c) for c in self.curves))

    def __repr__(self) -> str:
        sizes = ", ".join(str(len(c)) for c in self.curves)
        extra = ""
        if self.contact is not None:
            extra += f", contact={np.round(self.contact, 6).tolist()}"
        if self.normal is not None:
            extra += f", normal={np.round(self.normal, 4).tolist()}"
        if self.probe_radius is not None:
            extra += f", probe_radius={self.probe_radius:g}"
        return f"TouchData({len(self.curves)} curves of [{sizes}] points{extra})"

    # ------------------------------------------------------------------ transforms
    def transformed(self, T: np.ndarray) -> TouchData:
        """Return the same touch mapped by a rigid transform.

        Parameters
        ----------
        T : (4, 4) float
            Homogeneous transform applied to every point (and to the contact; its
            rotation to the normal).

        Returns
        -------
        TouchData

        Raises
        ------
        TypeError
            If ``T`` is not an array of real numbers.
        ValueError
            If ``T`` is not a finite (4, 4) array or not rigid (a rotation and a
            translation, last row (0, 0, 0, 1), within ``defaults.RIGID_TOLERANCE``): a
            scale, mirror or shear would change the shape the touch measured.
        """
        T = check_transform(T, "T", rigid=True)
        R, t = T[:3, :3], T[:3, 3]
        return TouchData(
            curves=[c @ R.T + t for c in self.curves],
            contact=None if self.contact is None else R @ self.contact + t,
            normal=None if self.normal is None else R @ self.normal,
            source=self.source,
            probe_radius=self.probe_radius,
        )

    def without_repeats(self) -> tuple[TouchData, int]:
        """This touch with every sample that repeats the one before it exactly left out.

        A logger faster than its sensor, or a probe resting, writes the same reading
        again. Such copies carry no new measurement, yet each would count as one: the
        noise estimates (differences and fit residuals between equal samples are zero)
        would read the noise low, and the scores would count the evidence twice. Copies
        are kept when a curve would be left with fewer than
        ``defaults.MIN_POINTS_PER_CURVE`` samples (the geometry then refuses it, naming
        the duplicates).

        Returns
        -------
        touch : TouchData
            ``self`` when nothing repeats, else a copy without the repeats (the same
            hints, source and probe radius).
        removed : int
            How many samples were left out.
        """
        kept = []
        for c in self.curves:
            keep = np.concatenate([[True], np.any(c[1:] != c[:-1], axis=1)])
            kept.append(c[keep])
        removed = self.n_points - sum(len(c) for c in kept)
        if removed == 0 or min(len(c) for c in kept) < defaults.MIN_POINTS_PER_CURVE:
            return self, 0
        touch = TouchData(
            curves=kept,
            contact=self.contact,
            normal=self.normal,
            source=self.source,
            probe_radius=self.probe_radius,
        )
        return touch, int(removed)

    def with_hints(self, contact=None, normal=None) -> TouchData:
        """Return a copy with ``contact`` and/or ``normal`` replaced where given."""
        return TouchData(
            curves=self.curves,
            contact=self.contact if contact is None else contact,
            normal=self.normal if normal is None else normal,
            source=self.source,
            probe_radius=self.probe_radius,
        )

    # ------------------------------------------------------------------ reading
    @classmethod
    def from_file(cls, path) -> TouchData:
        """Read a touch file, CSV or JSON by its suffix (``.csv``, ``.json``).

        Parameters
        ----------
        path : str or os.PathLike

        Returns
        -------
        TouchData

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        ValueError
            If the file is missing, a directory or another non-regular file (a pipe),
            unreadable, larger than ``defaults.TOUCH_MAX_FILE_BYTES``, binary, not UTF-8,
            of an unknown suffix, or its content is malformed (the message names the file,
            on one line, and the problem).
        """
        path = _as_path(path)
        if path.is_dir():
            raise ValueError(f"touch file {one_line(path)}: is a directory, expected a file")
        suffix = path.suffix.lower()
        if suffix == ".csv":
            return cls.from_csv(path)
        if suffix == ".json":
            return cls.from_json(path)
        raise ValueError(
            f"touch file {one_line(path)}: unknown suffix {one_line(path.suffix)!r}, "
            "use .csv or .json"
        )

    @classmethod
    def from_csv(cls, path) -> TouchData:
        """Read a CSV touch file with the header ``curve,x,y,z``.

        Parameters
        ----------
        path : str or os.PathLike

        Returns
        -------
        TouchData

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        ValueError
            If the file cannot be read (see :meth:`from_file`), the header is missing or
            wrong, a row is not four numbers, a label is not an integer, there are more
            rows than ``defaults.MAX_TOUCH_POINTS``, or the curves fail validation.
        """
        path = _as_path(path)
        label = f"touch file {one_line(path)}"
        text = read_text(path, what="touch file", max_bytes=defaults.TOUCH_MAX_FILE_BYTES)
        reader = csv.reader(io.StringIO(text, newline=None))  # any line endings
        rows = []  # (line number in the file, cells), blank lines left out
        try:
            for cells in reader:
                if cells and any(cell.strip() for cell in cells):
                    rows.append((reader.line_num, cells))
                    if len(rows) > defaults.MAX_TOUCH_POINTS + 1:
                        raise ValueError(
                            f"{label}: more than {defaults.MAX_TOUCH_POINTS} points "
                            "(defaults.MAX_TOUCH_POINTS)"
                        )
        except csv.Error as exc:
            raise ValueError(f"{label}: not readable as CSV ({one_line(exc)})") from None
        if not rows:
            raise ValueError(f"{label}: empty, expected a header 'curve,x,y,z'")
        header = tuple(cell.strip().lower() for cell in rows[0][1])
        if header != _CSV_HEADER:
            raise ValueError(
                f"{label}: header must be 'curve,x,y,z', got {one_line(','.join(rows[0][1]), 60)!r}"
            )
        groups: dict[int, list[list[float]]] = {}
        for line_no, row in rows[1:]:
            if len(row) != 4:
                raise ValueError(f"{label}: line {line_no} must have 4 fields, got {len(row)}")
            shown = one_line(",".join(row), 60)
            try:
                label_f = float(row[0])
                xyz = [float(v) for v in row[1:]]
            except ValueError:
                raise ValueError(f"{label}: line {line_no} is not numeric: {shown!r}") from None
            if not math.isfinite(label_f) or label_f != int(label_f):
                raise ValueError(
                    f"{label}: line {line_no} curve label must be an integer, "
                    f"got {one_line(row[0], 40)!r}"
                )
            if not all(math.isfinite(v) for v in xyz):
                raise ValueError(f"{label}: line {line_no} has a non-finite value: {shown!r}")
            groups.setdefault(int(label_f), []).append(xyz)
        return cls._checked(path, [groups[k] for k in sorted(groups)], None, None)

    @classmethod
    def from_json(cls, path) -> TouchData:
        """Read a JSON touch file ``{"curves": [...], "contact"?: [...], "normal"?: [...],
        "probe_radius"?: r}``.

        Parameters
        ----------
        path : str or os.PathLike

        Returns
        -------
        TouchData

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        ValueError
            If the file cannot be read (see :meth:`from_file`) or parsed, ``curves`` is
            missing, a curve is not a list of ``[x, y, z]`` lists of numbers (finite, and
            within the range of a float), ``contact`` or ``normal`` is not three numbers,
            or the content fails validation.
        """
        path = _as_path(path)
        label = f"touch file {one_line(path)}"
        text = read_text(path, what="touch file", max_bytes=defaults.TOUCH_MAX_FILE_BYTES)
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{label}: not valid JSON ({exc})") from None
        except RecursionError:
            raise ValueError(f"{label}: JSON nested too deeply") from None
        return cls.from_dict(data, source=str(path), label=label)

    @classmethod
    def from_dict(cls, obj, source: str | None = None, label: str | None = None) -> TouchData:
        """A touch from a parsed JSON object ``{"curves": [...], "contact"?: [...],
        "normal"?: [...], "probe_radius"?: r}``, checked as :meth:`from_json` checks a
        file's (it reads files through this).

        Parameters
        ----------
        obj : object
            What ``json.loads`` gave: the object must be a dict with exactly those keys.
        source : str, optional
            Where the touch came from (its :attr:`source`).
        label : str, optional
            What the messages call the touch (default: ``"touch <source>"``, or
            ``"touch"``).

        Returns
        -------
        TouchData

        Raises
        ------
        ValueError
            If ``obj`` is not an object with a ``curves`` list, has other keys, a curve is
            not a list of ``[x, y, z]`` lists of numbers (finite, and within the range of
            a float), there are more than ``defaults.MAX_CURVES`` curves or
            ``defaults.MAX_TOUCH_POINTS`` points, ``contact`` or ``normal`` is not three
            numbers, ``probe_radius`` is not a number (or is negative), or the content
            fails validation (the message starts with ``label``).
        """
        if label is None:
            label = "touch" if source is None else f"touch {one_line(source)}"
        data = obj
        if not isinstance(data, dict) or "curves" not in data:
            raise ValueError(f"{label}: expected an object with a 'curves' list")
        unknown = set(data) - {"curves", "contact", "normal", "probe_radius"}
        if unknown:
            raise ValueError(f"{label}: unknown keys {one_line(sorted(map(str, unknown)))}")
        if not isinstance(data["curves"], list):
            raise ValueError(f"{label}: 'curves' must be a list of curves")
        if len(data["curves"]) > defaults.MAX_CURVES:
            raise ValueError(
                f"{label}: more than {defaults.MAX_CURVES} curves (defaults.MAX_CURVES), "
                f"got {len(data['curves'])}"
            )
        total = 0
        for i, curve in enumerate(data["curves"]):
            if not isinstance(curve, list):
                raise ValueError(
                    f"{label}: curves[{i}] must be a list of [x, y, z] points, "
                    f"got {_json_type(curve)}"
                )
            total += len(curve)
            if total > defaults.MAX_TOUCH_POINTS:
                raise ValueError(
                    f"{label}: more than {defaults.MAX_TOUCH_POINTS} points "
                    "(defaults.MAX_TOUCH_POINTS)"
                )
            for j, point in enumerate(curve):
                _check_json_vector(label, point, f"curves[{i}][{j}]")
        for key in ("contact", "normal"):
            if data.get(key) is not None:
                _check_json_vector(label, data[key], key)
        radius = data.get("probe_radius")
        if radius is not None and (
            isinstance(radius, bool) or not isinstance(radius, (int, float))
        ):
            raise ValueError(
                f"{label}: 'probe_radius' must be a number, got {_json_type(radius)}"
            )
        try:
            return cls(
                curves=data["curves"],
                contact=data.get("contact"),
                normal=data.get("normal"),
                source=source,
                probe_radius=radius,
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{label}: {exc}") from None

    @classmethod
    def _checked(cls, path, curves, contact, normal) -> TouchData:
        try:
            return cls(curves=curves, contact=contact, normal=normal, source=str(path))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"touch file {one_line(path)}: {exc}") from None

    # ------------------------------------------------------------------ writing
    def to_file(self, path) -> None:
        """Write a CSV or JSON touch file by the suffix of ``path``, atomically.

        Parameters
        ----------
        path : str or os.PathLike

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        ValueError
            If the suffix is neither ``.csv`` nor ``.json``.
        OSError
            If the file cannot be written.
        """
        path = _as_path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            self.to_csv(path)
        elif suffix == ".json":
            self.to_json(path)
        else:
            raise ValueError(f"path must end in .csv or .json, got {one_line(path.name)!r}")

    def to_csv(self, path) -> None:
        """Write the curves as CSV ``curve,x,y,z`` (contact, normal and probe radius are not
        stored),
        atomically (:func:`meshrec.io.files.write_atomic`).

        Parameters
        ----------
        path : str or os.PathLike

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        OSError
            If the file cannot be written.
        """
        path = _as_path(path)
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(_CSV_HEADER)
        for i, curve in enumerate(self.curves):
            for x, y, z in curve:
                writer.writerow([i, repr(float(x)), repr(float(y)), repr(float(z))])
        write_atomic(path, buf.getvalue())

    def to_json(self, path) -> None:
        """Write the curves, and the contact and normal where known, as JSON, atomically.

        Parameters
        ----------
        path : str or os.PathLike

        Raises
        ------
        TypeError
            If ``path`` is not a str or os.PathLike.
        OSError
            If the file cannot be written.
        """
        path = _as_path(path)
        data: dict = {"curves": [c.tolist() for c in self.curves]}
        if self.contact is not None:
            data["contact"] = self.contact.tolist()
        if self.normal is not None:
            data["normal"] = self.normal.tolist()
        if self.probe_radius is not None:
            data["probe_radius"] = self.probe_radius
        write_atomic(path, json.dumps(data))


def _json_type(value) -> str:
    """The JSON name of a parsed value's type, for messages."""
    names = {dict: "an object", list: "a list", str: "a string", bool: "a boolean"}
    if value is None:
        return "null"
    return names.get(type(value), "a number")


def _check_json_vector(label: str, value, name: str) -> None:
    """Check that a parsed JSON value is a list of three finite numbers (not booleans or
    strings, nor integers beyond the range of a float such as 10**400).

    Raises
    ------
    ValueError
        Naming the file (``label``), ``name`` and what was found instead.
    """
    if not isinstance(value, list):
        raise ValueError(f"{label}: {name} must be [x, y, z], got {_json_type(value)}")
    if len(value) != 3:
        raise ValueError(f"{label}: {name} must have 3 numbers, got {len(value)}")
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(
                f"{label}: {name} must hold numbers, got {_json_type(v)} {one_line(v, 40)}"
            )
        if isinstance(v, int) and not -_FLOAT_MAX_INT <= v <= _FLOAT_MAX_INT:
            raise ValueError(
                f"{label}: {name} holds an integer too large for a float "
                f"({len(str(abs(v)))} digits)"
            )


#: Integers beyond this magnitude do not fit a float64 (float(int) raises OverflowError).
_FLOAT_MAX_INT = int(np.finfo(np.float64).max)


def _as_path(path) -> Path:
    """``path`` as a Path, or TypeError naming the argument."""
    if not isinstance(path, (str, bytes)) and not hasattr(path, "__fspath__"):
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    return Path(os.fsdecode(path) if isinstance(path, bytes) else path)
