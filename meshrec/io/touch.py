"""Touch data: the probe's points along three or more concurrent curves, read and written.

Two file formats are accepted:

* CSV with the header ``curve,x,y,z``: one row per point, ``curve`` an integer label.
  Points keep their file order within a curve; curves are ordered by label.
* JSON ``{"curves": [[[x, y, z], ...], ...], "contact": [x, y, z], "normal": [x, y, z]}``
  where ``contact`` and ``normal`` are optional.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from meshrec import defaults

__all__ = ["TouchData"]

_CSV_HEADER = ("curve", "x", "y", "z")


def _as_vector(value, name: str) -> np.ndarray:
    """Return ``value`` as a finite (3,) float64 array or raise ValueError naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be 3 numbers, got {value!r}") from exc
    if arr.shape != (3,):
        raise ValueError(f"{name} must be (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def _as_curve(value, index: int) -> np.ndarray:
    """Return curve ``index`` as a finite (n, 3) float64 array or raise ValueError."""
    name = f"curves[{index}]"
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an (n, 3) array of numbers: {exc}") from exc
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must be (n, 3), got {arr.shape}")
    if arr.shape[0] < defaults.MIN_POINTS_PER_CURVE:
        raise ValueError(
            f"{name} must have at least {defaults.MIN_POINTS_PER_CURVE} points, "
            f"got {arr.shape[0]}"
        )
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} has a non-finite point at row {row}: {arr[row].tolist()}")
    arr.setflags(write=False)
    return arr


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

    Raises
    ------
    ValueError
        If there are fewer than ``defaults.MIN_CURVES`` curves, a curve is not (n, 3),
        has too few points or a non-finite value, or ``contact`` / ``normal`` is not a
        finite (3,) vector, or ``normal`` is zero.
    """

    curves: tuple[np.ndarray, ...]
    contact: np.ndarray | None = None
    normal: np.ndarray | None = None
    source: str | None = field(default=None, compare=False)

    def __post_init__(self):
        if isinstance(self.curves, np.ndarray) and self.curves.ndim == 2:
            raise ValueError(
                f"curves must be a sequence of (n, 3) arrays, got one array {self.curves.shape}"
            )
        try:
            items = list(self.curves)
        except TypeError as exc:
            raise ValueError(
                f"curves must be a sequence of (n, 3) arrays, got {type(self.curves).__name__}"
            ) from exc
        if len(items) < defaults.MIN_CURVES:
            raise ValueError(
                f"curves must hold at least {defaults.MIN_CURVES} curves, got {len(items)}"
            )
        object.__setattr__(self, "curves", tuple(_as_curve(c, i) for i, c in enumerate(items)))
        if self.contact is not None:
            object.__setattr__(self, "contact", _as_vector(self.contact, "contact"))
        if self.normal is not None:
            normal = _as_vector(self.normal, "normal")
            length = float(np.linalg.norm(normal))
            if length == 0.0:
                raise ValueError("normal must be a non-zero vector, got [0, 0, 0]")
            object.__setattr__(self, "normal", normal / length)

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
        ValueError
            If ``T`` is not a finite (4, 4) array.
        """
        T = np.asarray(T, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"T must be a finite (4, 4) array, got shape {T.shape}")
        R, t = T[:3, :3], T[:3, 3]
        return TouchData(
            curves=[c @ R.T + t for c in self.curves],
            contact=None if self.contact is None else R @ self.contact + t,
            normal=None if self.normal is None else R @ self.normal,
            source=self.source,
        )

    def with_hints(self, contact=None, normal=None) -> TouchData:
        """Return a copy with ``contact`` and/or ``normal`` replaced where given."""
        return TouchData(
            curves=self.curves,
            contact=self.contact if contact is None else contact,
            normal=self.normal if normal is None else normal,
            source=self.source,
        )

    # ------------------------------------------------------------------ reading
    @classmethod
    def from_file(cls, path) -> TouchData:
        """Read a touch file, CSV or JSON by its suffix (``.csv``, ``.json``).

        Raises
        ------
        ValueError
            If the file is missing, a directory or another non-regular file (a pipe),
            unreadable, binary, not UTF-8, of an unknown suffix, or its content is
            malformed (the message names the file and the problem).
        """
        path = Path(path)
        if path.is_dir():
            raise ValueError(f"touch file {path}: is a directory, expected a file")
        suffix = path.suffix.lower()
        if suffix == ".csv":
            return cls.from_csv(path)
        if suffix == ".json":
            return cls.from_json(path)
        raise ValueError(f"touch file {path}: unknown suffix {path.suffix!r}, use .csv or .json")

    @classmethod
    def from_csv(cls, path) -> TouchData:
        """Read a CSV touch file with the header ``curve,x,y,z``.

        Raises
        ------
        ValueError
            If the file cannot be read, the header is missing or wrong, a row is not four
            numbers, a label is not an integer, or the curves fail validation.
        """
        text = _read_text(path)
        reader = csv.reader(io.StringIO(text, newline=None))  # any line endings
        rows = []  # (line number in the file, cells), blank lines left out
        try:
            for cells in reader:
                if cells and any(cell.strip() for cell in cells):
                    rows.append((reader.line_num, cells))
        except csv.Error as exc:
            raise ValueError(f"touch file {path}: not readable as CSV ({exc})") from exc
        if not rows:
            raise ValueError(f"touch file {path}: empty, expected a header 'curve,x,y,z'")
        header = tuple(cell.strip().lower() for cell in rows[0][1])
        if header != _CSV_HEADER:
            raise ValueError(
                f"touch file {path}: header must be 'curve,x,y,z', "
                f"got {','.join(rows[0][1])[:60]!r}"
            )
        groups: dict[int, list[list[float]]] = {}
        for line_no, row in rows[1:]:
            if len(row) != 4:
                raise ValueError(
                    f"touch file {path}: line {line_no} must have 4 fields, got {len(row)}"
                )
            try:
                label_f = float(row[0])
                xyz = [float(v) for v in row[1:]]
            except ValueError as exc:
                raise ValueError(
                    f"touch file {path}: line {line_no} is not numeric: {','.join(row)[:60]!r}"
                ) from exc
            if not math.isfinite(label_f) or label_f != int(label_f):
                raise ValueError(
                    f"touch file {path}: line {line_no} curve label must be an integer, "
                    f"got {row[0]!r}"
                )
            if not all(math.isfinite(v) for v in xyz):
                raise ValueError(
                    f"touch file {path}: line {line_no} has a non-finite value: "
                    f"{','.join(row)[:60]!r}"
                )
            groups.setdefault(int(label_f), []).append(xyz)
        return cls._checked(path, [groups[k] for k in sorted(groups)], None, None)

    @classmethod
    def from_json(cls, path) -> TouchData:
        """Read a JSON touch file ``{"curves": [...], "contact"?: [...], "normal"?: [...]}``.

        Raises
        ------
        ValueError
            If the file cannot be read or parsed, ``curves`` is missing, a curve is not a
            list of ``[x, y, z]`` lists of numbers, ``contact`` or ``normal`` is not three
            numbers, or the content fails validation.
        """
        text = _read_text(path)
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"touch file {path}: not valid JSON ({exc})") from exc
        except RecursionError as exc:
            raise ValueError(f"touch file {path}: JSON nested too deeply") from exc
        if not isinstance(data, dict) or "curves" not in data:
            raise ValueError(f"touch file {path}: expected an object with a 'curves' list")
        unknown = set(data) - {"curves", "contact", "normal"}
        if unknown:
            raise ValueError(f"touch file {path}: unknown keys {sorted(unknown)}")
        if not isinstance(data["curves"], list):
            raise ValueError(f"touch file {path}: 'curves' must be a list of curves")
        for i, curve in enumerate(data["curves"]):
            if not isinstance(curve, list):
                raise ValueError(
                    f"touch file {path}: curves[{i}] must be a list of [x, y, z] points, "
                    f"got {_json_type(curve)}"
                )
            for j, point in enumerate(curve):
                _check_json_vector(path, point, f"curves[{i}][{j}]")
        for key in ("contact", "normal"):
            if data.get(key) is not None:
                _check_json_vector(path, data[key], key)
        return cls._checked(path, data["curves"], data.get("contact"), data.get("normal"))

    @classmethod
    def _checked(cls, path, curves, contact, normal) -> TouchData:
        try:
            return cls(curves=curves, contact=contact, normal=normal, source=str(path))
        except ValueError as exc:
            raise ValueError(f"touch file {path}: {exc}") from exc

    # ------------------------------------------------------------------ writing
    def to_file(self, path) -> None:
        """Write a CSV or JSON touch file by the suffix of ``path``.

        Raises
        ------
        ValueError
            If the suffix is neither ``.csv`` nor ``.json``.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            self.to_csv(path)
        elif suffix == ".json":
            self.to_json(path)
        else:
            raise ValueError(f"path must end in .csv or .json, got {path.name!r}")

    def to_csv(self, path) -> None:
        """Write the curves as CSV ``curve,x,y,z`` (contact and normal are not stored)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(_CSV_HEADER)
        for i, curve in enumerate(self.curves):
            for x, y, z in curve:
                writer.writerow([i, repr(float(x)), repr(float(y)), repr(float(z))])
        _write_atomic(Path(path), buf.getvalue())

    def to_json(self, path) -> None:
        """Write the curves, and the contact and normal where known, as JSON."""
        data: dict = {"curves": [c.tolist() for c in self.curves]}
        if self.contact is not None:
            data["contact"] = self.contact.tolist()
        if self.normal is not None:
            data["normal"] = self.normal.tolist()
        _write_atomic(Path(path), json.dumps(data))


def _json_type(value) -> str:
    """The JSON name of a parsed value's type, for messages."""
    names = {dict: "an object", list: "a list", str: "a string", bool: "a boolean"}
    if value is None:
        return "null"
    return names.get(type(value), "a number")


def _check_json_vector(path, value, name: str) -> None:
    """Check that a parsed JSON value is a list of three numbers (not booleans or strings).

    Raises
    ------
    ValueError
        Naming the file, ``name`` and what was found instead.
    """
    if not isinstance(value, list):
        raise ValueError(f"touch file {path}: {name} must be [x, y, z], got {_json_type(value)}")
    if len(value) != 3:
        raise ValueError(f"touch file {path}: {name} must have 3 numbers, got {len(value)}")
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(
                f"touch file {path}: {name} must hold numbers, got {_json_type(v)} {v!r:.40}"
            )


def _read_text(path) -> str:
    """Read a UTF-8 text file, turning every failure into a ValueError naming the file."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"touch file {path}: no such file")
    if path.is_dir():
        raise ValueError(f"touch file {path}: is a directory, expected a file")
    if not path.is_file():
        raise ValueError(f"touch file {path}: not a regular file (a pipe or device?)")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"touch file {path}: cannot be read ({exc.strerror})") from exc
    if b"\x00" in raw:
        raise ValueError(f"touch file {path}: binary content, expected CSV or JSON text")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"touch file {path}: not UTF-8 text ({exc.reason})") from exc


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
