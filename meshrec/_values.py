"""Equality by value for the result dataclasses that hold arrays.

A frozen dataclass's generated ``__eq__`` compares its fields as a tuple, and a numpy
array field makes that raise ("the truth value of an array ... is ambiguous") as soon as
two results are compared that are not the same objects. The results inherit
:class:`ValueEquality` instead (declared with ``eq=False``): two results are equal when
they are of the same class and every field that takes part in comparisons
(``compare=True``, not the times) is equal, arrays element by element with their shapes
and dtypes' kinds, NaN equal to NaN (an answer's "no value" is the same answer), nested
results, tuples and dicts likewise. Results so compared are not hashable.

Why not ``numpy.testing`` or ``dataclasses.astuple``: the first raises instead of
answering, the second deep-copies every array and still compares with ``==``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["ValueEquality", "values_equal"]


def values_equal(a, b) -> bool:
    """Whether two values are equal, arrays element-wise and NaN equal to NaN.

    Parameters
    ----------
    a, b : object
        Values: arrays, dataclasses, tuples, lists, dicts, numbers or anything with ``==``.

    Returns
    -------
    bool
    """
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            return False
        if a.shape != b.shape:
            return False
        nan_ok = a.dtype.kind in "fc" and b.dtype.kind in "fc"
        return bool(np.array_equal(a, b, equal_nan=nan_ok))
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        if type(a) is not type(b):
            return False
        return all(
            values_equal(getattr(a, f.name), getattr(b, f.name))
            for f in dataclasses.fields(a)
            if f.compare
        )
    if isinstance(a, tuple | list):
        if type(a) is not type(b) or len(a) != len(b):
            return False
        return all(values_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        if not isinstance(b, dict) or a.keys() != b.keys():
            return False
        return all(values_equal(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


class ValueEquality:
    """Mixin: ``==`` by :func:`values_equal` over the dataclass's compared fields.

    Declare the dataclass with ``eq=False`` so that its generated ``__eq__`` does not
    replace this one.
    """

    __slots__ = ()

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return values_equal(self, other)

    __hash__ = None  # type: ignore[assignment]
