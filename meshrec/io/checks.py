"""Input checks shared by every entry point: the Python API, the touch readers, the command
line and the simulator.

Each check takes the value and the argument's name, returns the value in its canonical
form (a Python ``float``/``int``, a ``float64`` array of the right shape) and otherwise
raises ``TypeError`` (a value of the wrong kind: a string, a complex or boolean array, an
object that is not a number) or ``ValueError`` (the right kind, but a wrong shape or
value), with a one-line message that names the argument and what it got.
"""

from __future__ import annotations

import math
import os
import reprlib
from collections.abc import Iterable, Mapping

import numpy as np

from meshrec import defaults

__all__ = [
    "check_choice",
    "check_curves",
    "check_instance",
    "check_int",
    "check_number",
    "check_points",
    "check_rng",
    "check_transform",
    "check_vector",
    "one_line",
]

#: Longest rendering of a value in a message (the rest is elided with "...").
_MESSAGE_LIMIT = 200
_SHORT = reprlib.Repr()
_SHORT.maxstring = 60
_SHORT.maxother = 60
_SHORT.maxlist = 6
_SHORT.maxtuple = 6


def one_line(value, limit: int | None = _MESSAGE_LIMIT) -> str:
    """Render a path, a string or any value on one printable line, for messages.

    Paths and bytes are decoded like the file system names them (bytes that are not
    UTF-8 become ``\\xNN``); line breaks, control characters and lone surrogates are
    written as Python escapes, so the text never spans two lines nor fails to encode.

    Parameters
    ----------
    value : str or bytes or os.PathLike or object
        What to render: text and paths as they are, anything else by a short ``repr``.
    limit : int or None
        Longest result in characters (longer ones end in ``...``); None for no limit.

    Returns
    -------
    str
    """
    if isinstance(value, (bytes, os.PathLike)):
        try:
            text = os.fsdecode(value)
        except (TypeError, ValueError):
            text = repr(value)
    elif isinstance(value, str):
        text = value
    else:
        try:
            text = _SHORT.repr(value)
        except Exception:  # a broken __repr__ must not hide the real error
            text = f"<{type(value).__name__}>"
    if not text.isprintable():
        text = "".join(
            ch if ch.isprintable() and not 0xD800 <= ord(ch) <= 0xDFFF else _escape(ch)
            for ch in text
        )
    if limit is not None and len(text) > limit:
        text = text[: max(limit - 3, 0)] + "..."
    return text


def _escape(ch: str) -> str:
    """A character as its Python escape; surrogates from undecodable bytes as ``\\xNN``."""
    code = ord(ch)
    if 0xDC80 <= code <= 0xDCFF:  # os.fsdecode's surrogateescape of byte code - 0xDC00
        return f"\\x{code - 0xDC00:02x}"
    return ch.encode("unicode_escape").decode("ascii")


def _kind(value) -> str:
    """The type of ``value`` for a message: ``str``, ``complex128 array``, ..."""
    if isinstance(value, np.ndarray):
        return f"{value.dtype} array"
    return type(value).__name__


def check_instance(value, types, name: str, *, optional: bool = False):
    """Return ``value`` if it is an instance of ``types`` (or None when ``optional``).

    Parameters
    ----------
    value : object
    types : type or tuple of type
    name : str
        The argument's name, for messages.
    optional : bool
        Accept None.

    Returns
    -------
    object
        ``value``.

    Raises
    ------
    TypeError
        Naming the argument, the expected and the actual type.
    """
    if (optional and value is None) or isinstance(value, types):
        return value
    expected = types if isinstance(types, tuple) else (types,)
    wanted = " or ".join(t.__name__ for t in expected) + (" or None" if optional else "")
    raise TypeError(f"{name} must be a {wanted}, got {_kind(value)}")


def check_choice(value, choices, name: str) -> str:
    """Return ``value`` if it is one of the strings ``choices``.

    Parameters
    ----------
    value : str
    choices : sequence of str
    name : str
        The argument's name, for messages.

    Returns
    -------
    str

    Raises
    ------
    TypeError
        If ``value`` is not a string.
    ValueError
        If it is not one of ``choices``.
    """
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {tuple(choices)}, got {_kind(value)}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {tuple(choices)}, got {one_line(value)!r}")
    return value


def check_number(
    value,
    name: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
) -> float:
    """Return a finite real number as a ``float``.

    Parameters
    ----------
    value : int or float
        A Python or numpy real number (not a bool, not complex, not a string).
    name : str
        The argument's name, for messages.
    minimum, maximum : float, optional
        Inclusive bounds.
    positive : bool
        Require ``value > 0``.

    Returns
    -------
    float

    Raises
    ------
    TypeError
        If ``value`` is not a real number (a bool, a complex number, a string, None).
    ValueError
        If it is not finite (NaN, inf, an integer too large for a float) or out of bounds.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be a real number, got {_kind(value)} {one_line(value)}")
    try:
        x = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be finite, got {one_line(value, 40)}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x!r}")
    if positive and not x > 0.0:
        raise ValueError(f"{name} must be > 0, got {x!r}")
    if minimum is not None and x < minimum:
        raise ValueError(f"{name} must be >= {minimum:g}, got {x!r}")
    if maximum is not None and x > maximum:
        raise ValueError(f"{name} must be <= {maximum:g}, got {x!r}")
    return x


def check_int(value, name: str, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """Return an integer (Python or numpy, not a bool or a float) as an ``int``.

    Parameters
    ----------
    value : int
    name : str
        The argument's name, for messages.
    minimum, maximum : int, optional
        Inclusive bounds.

    Returns
    -------
    int

    Raises
    ------
    TypeError
        If ``value`` is not an integer (a bool, a float such as ``61.0``, a string).
    ValueError
        If it is out of bounds.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {_kind(value)} {one_line(value)}")
    n = int(value)
    if minimum is not None and n < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {n}")
    if maximum is not None and n > maximum:
        raise ValueError(f"{name} must be <= {maximum}, got {one_line(n, 40)}")
    return n


def _real_array(value, name: str) -> np.ndarray:
    """``value`` as a float64 array, refusing what is not real numbers.

    Raises
    ------
    TypeError
        If ``value`` is a string, a mapping, a set, or an array of another kind than real
        numbers (complex, bool, strings, objects that are not numbers).
    ValueError
        If it is ragged, or holds an integer too large for a float.
    """
    if isinstance(value, (str, bytes, Mapping, set, frozenset)) or value is None:
        raise TypeError(f"{name} must be an array of real numbers, got {_kind(value)}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nesting
        raise ValueError(f"{name} must be a regular array of numbers ({exc})") from None
    if arr.dtype == object:
        # lists of Python ints beyond int64 (10**400), or of anything else
        try:
            arr = np.asarray(value, dtype=np.float64)
        except OverflowError:
            raise ValueError(f"{name} holds a number too large for a float") from None
        except (TypeError, ValueError):
            raise TypeError(f"{name} must hold real numbers only, got objects") from None
    elif arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got a {arr.dtype} array")
    return np.asarray(arr, dtype=np.float64)


def check_vector(value, name: str, *, nonzero: bool = False, unit: bool = False) -> np.ndarray:
    """Return a finite real 3-vector as a new (3,) float64 array.

    Parameters
    ----------
    value : (3,) float
    name : str
        The argument's name, for messages.
    nonzero : bool
        Refuse the zero vector.
    unit : bool
        Return the vector scaled to unit length (implies ``nonzero``); the length is
        computed without overflow, so ``(1e308, 0, 0)`` gives ``(1, 0, 0)``.

    Returns
    -------
    (3,) float64

    Raises
    ------
    TypeError
        If ``value`` is not an array of real numbers.
    ValueError
        If it is not (3,), not finite, or zero when ``nonzero`` or ``unit``.
    """
    arr = _real_array(value, name)
    if arr.shape != (3,):
        raise ValueError(f"{name} must be (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    if (nonzero or unit) and not np.any(arr != 0.0):
        raise ValueError(f"{name} must be non-zero, got {arr.tolist()}")
    if unit:
        big = float(np.max(np.abs(arr)))
        arr = arr / big  # scaled first: the squares of 1e308 overflow, those of 1e-300 vanish
        arr = arr / float(np.linalg.norm(arr))
    return np.array(arr, dtype=np.float64)


def check_points(
    value,
    name: str,
    *,
    min_rows: int = 0,
    max_rows: int | None = None,
) -> np.ndarray:
    """Return finite real points as a new (n, 3) float64 array.

    Parameters
    ----------
    value : (n, 3) float
    name : str
        The argument's name, for messages (``curves[1]``).
    min_rows, max_rows : int, optional
        The fewest and most points accepted.

    Returns
    -------
    (n, 3) float64

    Raises
    ------
    TypeError
        If ``value`` is not an array of real numbers.
    ValueError
        If it is not (n, 3), has fewer than ``min_rows`` or more than ``max_rows`` rows,
        or a non-finite value (the message gives the first such row).
    """
    arr = _real_array(value, name)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must be (n, 3), got {arr.shape}")
    if arr.shape[0] < min_rows:
        raise ValueError(f"{name} must have at least {min_rows} points, got {arr.shape[0]}")
    if max_rows is not None and arr.shape[0] > max_rows:
        raise ValueError(f"{name} must have at most {max_rows} points, got {arr.shape[0]}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} has a non-finite point at row {row}: {arr[row].tolist()}")
    return np.array(arr, dtype=np.float64)


def check_transform(value, name: str, *, rigid: bool = False) -> np.ndarray:
    """Return a finite (4, 4) real matrix as a new float64 array.

    Parameters
    ----------
    value : (4, 4) float
        A homogeneous transform.
    name : str
        The argument's name, for messages.
    rigid : bool
        Also require a rigid motion: last row (0, 0, 0, 1) and a rotation block (R^T R the
        identity, det R > 0), within ``defaults.RIGID_TOLERANCE``.

    Returns
    -------
    (4, 4) float64

    Raises
    ------
    TypeError
        If ``value`` is not an array of real numbers.
    ValueError
        If it is not a finite (4, 4) array, or (``rigid``) not a rigid motion.
    """
    T = _real_array(value, name)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{name} must be a finite (4, 4) array, got shape {T.shape}")
    if rigid:
        R = T[:3, :3]
        tol = defaults.RIGID_TOLERANCE
        if (
            not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=tol)
            or not np.allclose(R.T @ R, np.eye(3), rtol=0.0, atol=tol)
            or not np.linalg.det(R) > 0.0
        ):
            raise ValueError(f"{name} must be a rigid transform (a rotation and a translation)")
    return np.array(T, dtype=np.float64)


def check_curves(value, name: str = "curves") -> list[np.ndarray]:
    """Return touch curves as a list of finite (n_i, 3) float64 arrays.

    The one rule set for curves (shared by :class:`~meshrec.io.touch.TouchData` and the
    geometry): a sequence (list, tuple, (c, n, 3) array, or other iterable) of
    ``defaults.MIN_CURVES`` to ``defaults.MAX_CURVES`` curves, each (n, 3) real and finite
    with ``defaults.MIN_POINTS_PER_CURVE`` to ``defaults.MAX_POINTS_PER_CURVE`` points, and
    at most ``defaults.MAX_TOUCH_POINTS`` points in all.

    Parameters
    ----------
    value : sequence of (n_i, 3) float
    name : str
        The argument's name, for messages.

    Returns
    -------
    list of (n_i, 3) float64

    Raises
    ------
    TypeError
        If ``value`` is not a sequence (a number, a string, a mapping), or a curve is not
        real numbers.
    ValueError
        If ``value`` is one (n, 3) array instead of a sequence of them, has too few or too
        many curves or points, or a curve fails :func:`check_points`.
    """
    if isinstance(value, np.ndarray) and value.ndim != 3:
        raise ValueError(
            f"{name} must be a sequence of (n, 3) arrays, got an array of shape {value.shape}"
        )
    if isinstance(value, (str, bytes, Mapping, set, frozenset)) or not isinstance(value, Iterable):
        raise TypeError(f"{name} must be a sequence of (n, 3) arrays, got {_kind(value)}")
    items = []
    for item in value:
        items.append(item)
        if len(items) > defaults.MAX_CURVES:
            raise ValueError(
                f"{name} must hold at most {defaults.MAX_CURVES} curves "
                "(defaults.MAX_CURVES), got more"
            )
    if len(items) < defaults.MIN_CURVES:
        raise ValueError(
            f"{name} must hold at least {defaults.MIN_CURVES} curves, got {len(items)}"
        )
    out = [
        check_points(
            c,
            f"{name}[{i}]",
            min_rows=defaults.MIN_POINTS_PER_CURVE,
            max_rows=defaults.MAX_POINTS_PER_CURVE,
        )
        for i, c in enumerate(items)
    ]
    total = sum(len(c) for c in out)
    if total > defaults.MAX_TOUCH_POINTS:
        raise ValueError(
            f"{name} must have at most {defaults.MAX_TOUCH_POINTS} points in all "
            f"(defaults.MAX_TOUCH_POINTS), got {total}"
        )
    return out


def check_rng(rng, name: str = "rng") -> np.random.Generator:
    """Return a generator for ``rng`` through :func:`numpy.random.default_rng`.

    Parameters
    ----------
    rng : numpy.random.Generator or int or None
        A generator (returned as is), a non-negative integer seed, or None (fresh entropy).
    name : str
        The argument's name, for messages.

    Returns
    -------
    numpy.random.Generator

    Raises
    ------
    TypeError
        If ``rng`` is neither a generator, an integer nor None (a bool, a float, a string).
    ValueError
        If it is a negative integer.
    """
    if rng is None or isinstance(rng, np.random.Generator):
        return np.random.default_rng(rng)
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, (int, np.integer)):
        raise TypeError(
            f"{name} must be a numpy Generator, an int seed or None, got "
            f"{_kind(rng)} {one_line(rng)}"
        )
    if rng < 0:
        raise ValueError(f"{name} must be a non-negative int seed, got {int(rng)}")
    return np.random.default_rng(int(rng))
