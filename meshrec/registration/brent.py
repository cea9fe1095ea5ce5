"""Many bounded scalar minimisations in lockstep, one batched evaluation per step.

The phi refinement (:func:`meshrec.registration.phi.search_phis`) refines every bracket
of every candidate that goes on to a local search: about a hundred one-dimensional
minimisations of ten evaluations each per recognition, each evaluation a closest-point
query of a few dozen points. Run one after the other, as with
:func:`scipy.optimize.minimize_scalar`, that is a thousand small queries whose fixed cost
exceeds their work. :func:`minimize_bounded` runs the same method (scipy's bounded Brent
method, ``method="bounded"``, its code ported line for line and vectorised over the
problems) on all of them at once, and asks for each step's new points in one call.

Why not scipy itself: ``minimize_scalar`` takes one scalar function and calls it once per
point; scipy has no vectorised bounded minimiser. Each problem here follows exactly the
path scipy's would (the same arithmetic, element by element): the same evaluated points,
the same answer, to the bit (``tests/test_brent.py`` checks it against scipy).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from math import sqrt

import numpy as np

from meshrec._values import ValueEquality

__all__ = ["BoundedMinima", "minimize_bounded"]

#: scipy's constants of the method (``_minimize_scalar_bounded``).
_SQRT_EPS = sqrt(2.2e-16)
_GOLDEN_MEAN = 0.5 * (3.0 - sqrt(5.0))


@dataclass(frozen=True, eq=False)
class BoundedMinima(ValueEquality):
    """The minima of many bounded scalar problems.

    Attributes
    ----------
    x : (p,) float
        Each problem's minimiser (scipy's ``res.x``).
    fun : (p,) float
        The function's value there (``res.fun``).
    nfev : (p,) int
        Evaluations each problem took (``res.nfev``).
    rounds : int
        Batched calls of the function (the largest ``nfev``).
    """

    x: np.ndarray = field(repr=False)
    fun: np.ndarray = field(repr=False)
    nfev: np.ndarray = field(repr=False)
    rounds: int

    def __repr__(self) -> str:
        return (
            f"BoundedMinima(problems={len(self.x)}, evaluations={int(self.nfev.sum())}, "
            f"rounds={self.rounds})"
        )


def minimize_bounded(
    func: Callable[[np.ndarray, np.ndarray], np.ndarray],
    lower,
    upper,
    *,
    xatol: float,
    maxiter: int = 500,
) -> BoundedMinima:
    """Minimise ``p`` scalar functions on their intervals by Brent's bounded method, at once.

    Parameters
    ----------
    func : callable
        ``func(problems, x)``: (k,) problem indices and (k,) points to the (k,) values of
        those problems' functions there. Called once per step with every problem still
        running (each at most once per call).
    lower, upper : (p,) float
        Each problem's interval.
    xatol : float
        Absolute tolerance on the minimiser (scipy's ``xatol``).
    maxiter : int
        Most evaluations per problem (scipy's ``maxiter``).

    Returns
    -------
    BoundedMinima

    Raises
    ------
    ValueError
        If ``lower`` and ``upper`` are not finite (p,) arrays of one length with
        ``lower <= upper``, ``xatol`` is not positive, ``maxiter`` is below 1, or ``func``
        returns other than (k,) values.
    """
    a = np.array(lower, dtype=np.float64)
    b = np.array(upper, dtype=np.float64)
    if a.ndim != 1 or b.shape != a.shape:
        raise ValueError(
            f"lower and upper must be (p,) arrays of one length, got {a.shape} and {b.shape}"
        )
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("lower and upper must be finite")
    if np.any(a > b):
        raise ValueError(f"lower must not exceed upper, got {a[a > b][0]!r} > {b[a > b][0]!r}")
    if not xatol > 0.0:
        raise ValueError(f"xatol must be positive, got {xatol!r}")
    if not isinstance(maxiter, (int, np.integer)) or maxiter < 1:
        raise ValueError(f"maxiter must be an integer >= 1, got {maxiter!r}")
    p = len(a)

    def call(problems: np.ndarray, x: np.ndarray) -> np.ndarray:
        values = np.asarray(func(problems, x), dtype=np.float64)
        if values.shape != x.shape:
            raise ValueError(f"func must return ({len(x)},) values, got {values.shape}")
        return values

    fulc = a + _GOLDEN_MEAN * (b - a)
    nfc = fulc.copy()
    xf = fulc.copy()
    rat = np.zeros(p)
    e = np.zeros(p)
    fx = call(np.arange(p), xf) if p else np.zeros(0)
    num = np.ones(p, dtype=np.int64)
    ffulc = fx.copy()
    fnfc = fx.copy()
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * np.abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    rounds = 1 if p else 0
    # (scipy checks the evaluations only after a step: it takes at least two.)
    running = np.abs(xf - xm) > (tol2 - 0.5 * (b - a))
    with np.errstate(divide="ignore", invalid="ignore"):
        while running.any():
            i = np.flatnonzero(running)
            ai, bi, xfi, fxi = a[i], b[i], xf[i], fx[i]
            nfci, fnfci, fulci, ffulci = nfc[i], fnfc[i], fulc[i], ffulc[i]
            ei, rati, xmi, t1, t2 = e[i], rat[i], xm[i], tol1[i], tol2[i]
            # The parabola through the three best points, where the last steps were long.
            parab = np.abs(ei) > t1
            r = (xfi - nfci) * (fxi - ffulci)
            q = (xfi - fulci) * (fxi - fnfci)
            pp = (xfi - fulci) * q - (xfi - nfci) * r
            q = 2.0 * (q - r)
            pp = np.where(q > 0.0, -pp, pp)
            q = np.abs(q)
            accept = (
                parab
                & (np.abs(pp) < np.abs(0.5 * q * ei))
                & (pp > q * (ai - xfi))
                & (pp < q * (bi - xfi))
            )
            rat_par = (pp + 0.0) / q
            x_par = xfi + rat_par
            near = ((x_par - ai) < t2) | ((bi - x_par) < t2)
            si = np.sign(xmi - xfi) + ((xmi - xfi) == 0)
            rat_par = np.where(near, t1 * si, rat_par)
            # Elsewhere a golden-section step into the larger part.
            e_gold = np.where(xfi >= xmi, ai - xfi, bi - xfi)
            new_e = np.where(accept, rati, e_gold)
            new_rat = np.where(accept, rat_par, _GOLDEN_MEAN * e_gold)
            si = np.sign(new_rat) + (new_rat == 0)
            x = xfi + si * np.maximum(np.abs(new_rat), t1)
            fu = call(i, x)
            rounds += 1
            num[i] += 1
            better = fu <= fxi
            right = x >= xfi
            new_a = np.where(better, np.where(right, xfi, ai), np.where(~right, x, ai))
            new_b = np.where(better, np.where(~right, xfi, bi), np.where(right, x, bi))
            c1 = ~better & ((fu <= fnfci) | (nfci == xfi))
            c2 = ~better & ~c1 & ((fu <= ffulci) | (fulci == xfi) | (fulci == nfci))
            shift = better | c1
            fulc[i] = np.where(shift, nfci, np.where(c2, x, fulci))
            ffulc[i] = np.where(shift, fnfci, np.where(c2, fu, ffulci))
            nfc[i] = np.where(better, xfi, np.where(c1, x, nfci))
            fnfc[i] = np.where(better, fxi, np.where(c1, fu, fnfci))
            xf[i] = np.where(better, x, xfi)
            fx[i] = np.where(better, fu, fxi)
            a[i], b[i], e[i], rat[i] = new_a, new_b, new_e, new_rat
            xm[i] = 0.5 * (new_a + new_b)
            tol1[i] = _SQRT_EPS * np.abs(xf[i]) + xatol / 3.0
            tol2[i] = 2.0 * tol1[i]
            running[i] = (np.abs(xf[i] - xm[i]) > (tol2[i] - 0.5 * (b[i] - a[i]))) & (
                num[i] < maxiter
            )
    return BoundedMinima(x=xf, fun=fx, nfev=num, rounds=rounds)
