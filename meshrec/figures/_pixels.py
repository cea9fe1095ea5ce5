"""Picture files shared by :mod:`meshrec.figures.viz` and :mod:`meshrec.figures.plots`.

Sizes and atomic writes.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from meshrec.io.files import write_atomic


def check_size(size, low: int, high: int, name: str = "size") -> tuple[int, int]:
    """``size`` as ``(width, height)`` whole pixels, each in ``low..high``.

    Parameters
    ----------
    size : (2,) int
        Width and height in pixels.
    low, high : int
        The smallest and largest width or height accepted.
    name : str
        The argument's name, for the message.

    Returns
    -------
    (int, int)

    Raises
    ------
    ValueError
        If ``size`` is not two whole numbers, or one is outside ``low..high``.
    """
    try:
        w, h = (int(v) for v in size)
        ok = all(float(v) == int(v) for v in size)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be (width, height) in pixels, got {size!r}") from None
    if not ok or not (low <= w <= high and low <= h <= high):
        raise ValueError(
            f"{name} must be (width, height) with each in {low}..{high} pixels, got {size!r}"
        )
    return w, h


def write_png_atomic(path, write: Callable[[str], None]) -> Path:
    """Write a PNG through :func:`meshrec.io.files.write_atomic`.

    An interrupted or failed write leaves no half-written picture at ``path``; the file
    gets the mode ``open()`` would give it (following the umask).

    Parameters
    ----------
    path : str or os.PathLike
        The PNG; its folder is created.
    write : callable
        ``write(tmp)`` writes the picture to the file name ``tmp`` (ending in ``.png``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        If the folder or the file cannot be written (the temporary file is removed).
    """
    return write_atomic(path, write)
