"""The Morton order of the closest-point queries against a bit-by-bit interleave."""

import numpy as np

from meshrec.model.surface import _morton_order


def _interleaved(P: np.ndarray, bits: int = 10) -> np.ndarray:
    """Morton codes the slow way: bit b of axis d to bit 3 b + d."""
    lo = P.min(axis=0)
    span = float((P.max(axis=0) - lo).max())
    q = ((P - lo) * ((2**bits - 1) / span)).astype(np.int64)
    code = np.zeros(len(P), dtype=np.int64)
    for b in range(bits):
        for d in range(3):
            code |= ((q[:, d] >> b) & 1) << (3 * b + d)
    return code


def test_morton_order_sorts_by_the_interleaved_codes():
    rng = np.random.default_rng(7)
    P = rng.normal(size=(5000, 3)) * [3.0, 1.0, 0.2]
    order = _morton_order(P)
    assert np.array_equal(order, np.argsort(_interleaved(P), kind="stable"))
    # A permutation, and not the identity (the codes do reorder random points).
    assert np.array_equal(np.sort(order), np.arange(len(P)))
    assert not np.array_equal(order, np.arange(len(P)))


def test_morton_order_of_coincident_points_keeps_their_order():
    P = np.ones((600, 3))
    assert np.array_equal(_morton_order(P), np.arange(600))
