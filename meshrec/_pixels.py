"""Picture sizes in pixels, checked alike by :mod:`meshrec.viz` and :mod:`meshrec.plots`."""

from __future__ import annotations


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
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (width, height) in pixels, got {size!r}") from None
    if not ok or not (low <= w <= high and low <= h <= high):
        raise ValueError(
            f"{name} must be (width, height) with each in {low}..{high} pixels, got {size!r}"
        )
    return w, h
