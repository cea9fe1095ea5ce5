"""Checks shared by the model records: read-only arrays of a given dtype and shape."""

from __future__ import annotations

import numpy as np

__all__ = ["readonly"]


def readonly(a, dtype, shape: tuple, name: str) -> np.ndarray:
    """A read-only C-contiguous view/copy of ``a`` with ``dtype``, checking its shape.

    Parameters
    ----------
    a : array_like
    dtype : numpy dtype
    shape : tuple of int or None
        The expected shape; ``None`` matches any length on that axis.
    name : str
        The argument's name, for the message.

    Returns
    -------
    ndarray
        Read-only (the caller's array is not changed).

    Raises
    ------
    ValueError
        If the shape differs, naming ``name``, the expected and the actual shape.
    """
    out = np.ascontiguousarray(a, dtype=dtype)
    if out.ndim != len(shape) or any(
        s is not None and s != d for s, d in zip(shape, out.shape, strict=True)
    ):
        dims = ["n" if s is None else str(s) for s in shape]
        want = f"({dims[0]},)" if len(dims) == 1 else "(" + ", ".join(dims) + ")"
        raise ValueError(f"{name} must have shape {want}, got {out.shape}")
    out = out.view()
    out.setflags(write=False)
    return out
