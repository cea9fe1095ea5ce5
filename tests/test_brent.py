"""Bounded minimisations in lockstep against scipy's one-at-a-time ``minimize_scalar``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from meshrec import defaults
from meshrec.registration.brent import minimize_bounded
from meshrec.registration.phi import bracket_minima, search_phi, search_phis


def _functions(seed: int, count: int):
    """Smooth, wavy, flat and kinked scalar functions with their intervals."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        a, w, c = rng.uniform(0.5, 3.0), rng.uniform(0.5, 8.0), rng.uniform(-2.0, 2.0)
        kind = k % 4
        if kind == 0:
            f = lambda x, a=a, c=c: a * (x - c) ** 2  # noqa: E731
        elif kind == 1:
            f = lambda x, a=a, w=w, c=c: np.sin(w * x + c) + a * 0.1 * x  # noqa: E731
        elif kind == 2:
            f = lambda x, c=c: np.abs(x - c)  # noqa: E731
        else:
            f = lambda x: np.full_like(np.asarray(x, dtype=float), 0.25)  # noqa: E731
        lo = rng.uniform(-3.0, 1.0)
        out.append((f, lo, lo + rng.uniform(0.01, 4.0)))
    return out


def _scipy(f, lo, hi, xatol, maxiter=500):
    return minimize_scalar(
        lambda x: float(f(np.array([x]))[0]),
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": xatol, "maxiter": maxiter},
    )


@pytest.mark.parametrize("xatol", [1e-5, defaults.PHI_XTOL, 0.3])
def test_lockstep_is_scipy_to_the_bit(xatol):
    problems = _functions(0, 24)
    calls = []

    def func(which, x):
        calls.append(len(which))
        return np.array([problems[j][0](np.array([xj]))[0] for j, xj in zip(which, x, strict=True)])

    got = minimize_bounded(func, [p[1] for p in problems], [p[2] for p in problems], xatol=xatol)
    for k, (f, lo, hi) in enumerate(problems):
        want = _scipy(f, lo, hi, xatol)
        assert got.x[k] == want.x
        assert got.fun[k] == want.fun
        assert got.nfev[k] == want.nfev
    # One call per step, with every problem still running.
    assert got.rounds == len(calls) == got.nfev.max()
    assert calls[0] == len(problems)


@settings(max_examples=60, deadline=None)
@given(
    c=st.floats(-5, 5),
    w=st.floats(0.1, 20),
    lo=st.floats(-5, 5),
    width=st.floats(1e-6, 10),
    maxiter=st.integers(1, 40),
)
def test_lockstep_is_scipy_on_any_wave(c, w, lo, width, maxiter):
    def f(x):
        return np.cos(w * (x - c)) + 0.01 * (x - c) ** 2

    got = minimize_bounded(lambda which, x: f(x), [lo], [lo + width], xatol=1e-4, maxiter=maxiter)
    want = _scipy(f, lo, lo + width, 1e-4, maxiter)
    assert got.x[0] == want.x
    assert got.fun[0] == want.fun
    assert got.nfev[0] == want.nfev


def test_no_problems():
    got = minimize_bounded(lambda which, x: x, [], [], xatol=1e-3)
    assert got.x.shape == (0,)
    assert got.rounds == 0


@pytest.mark.parametrize(
    ("lower", "upper", "kwargs", "match"),
    [
        ([[0.0]], [[1.0]], {}, "lower and upper must be"),
        ([0.0, 1.0], [1.0], {}, "lower and upper must be"),
        ([np.nan], [1.0], {}, "must be finite"),
        ([2.0], [1.0], {}, "must not exceed"),
        ([0.0], [1.0], {"xatol": 0.0}, "xatol must be positive"),
        ([0.0], [1.0], {"maxiter": 0}, "maxiter must be"),
    ],
)
def test_minimize_bounded_errors(lower, upper, kwargs, match):
    kwargs = {"xatol": 1e-3, **kwargs}
    with pytest.raises(ValueError, match=match):
        minimize_bounded(lambda which, x: x, lower, upper, **kwargs)


def test_minimize_bounded_refuses_a_wrong_shaped_answer():
    with pytest.raises(ValueError, match=r"func must return \(1,\) values"):
        minimize_bounded(lambda which, x: np.zeros(3), [0.0], [1.0], xatol=1e-3)


def _search_phi_with_scipy(error, values):
    """The phi search as it was written with scipy, one bracket after another."""
    steps = len(values)
    step = 2.0 * np.pi / steps
    grid = np.arange(steps) * step
    minima = []
    for i in bracket_minima(values):
        if values[i] > defaults.PHI_REFINE_RATIO * values.min() + 1e-300:
            continue
        res = minimize_scalar(
            lambda x: float(error(np.array([x]))[0]),
            bounds=(grid[i] - step, grid[i] + step),
            method="bounded",
            options={"xatol": defaults.PHI_XTOL},
        )
        phi, val = float(res.x), float(res.fun)
        if values[i] < val:
            phi, val = float(grid[i]), float(values[i])
        minima.append((phi % (2.0 * np.pi), val))
    minima.sort(key=lambda m: m[1])
    return np.array(minima)


def test_search_phis_is_the_scipy_search_of_each_candidate():
    rng = np.random.default_rng(5)
    shifts = rng.uniform(0, 2 * np.pi, size=(6, 3))
    weights = rng.uniform(0.2, 1.0, size=(6, 3))

    def one(row):
        def error(phis):
            phis = np.asarray(phis, dtype=float)
            return 2.0 + sum(
                w * np.cos((m + 1) * (phis - s))
                for m, (w, s) in enumerate(zip(weights[row], shifts[row], strict=True))
            )

        return error

    grid = np.arange(defaults.PHI_STEPS) * (2.0 * np.pi / defaults.PHI_STEPS)
    rows = np.stack([one(r)(grid) for r in range(6)])
    asked = []

    def many(which, phis):
        asked.append(len(which))
        return np.array([one(r)(np.array([p]))[0] for r, p in zip(which, phis, strict=True)])

    got = search_phis(many, rows)
    assert sum(len(g.minima) for g in got) > 6  # some candidates have several brackets
    assert asked[0] == sum(len(g.minima) for g in got)
    for r, g in enumerate(got):
        want = _search_phi_with_scipy(one(r), rows[r])
        assert np.array_equal(g.minima, want)
        assert g.phi == want[0, 0]
        assert g.error == want[0, 1]
        alone = search_phi(one(r), grid_errors=rows[r])
        assert np.array_equal(alone.minima, want)


def test_estimated_rows_keep_their_brackets_but_report_exact_errors():
    # A row of estimates (the exact samples lifted by a constant, as a biased field
    # would give): the same brackets, so the same refinements; every reported error is
    # the function's, not the estimate's, also where a bracket's own sample wins.
    grid = np.arange(defaults.PHI_STEPS) * (2.0 * np.pi / defaults.PHI_STEPS)

    def f(phis):
        return 1.0 + 0.5 * np.cos(3.0 * np.asarray(phis, dtype=float)) ** 2

    exact = f(grid)[None, :]

    def many(which, phis):
        return f(phis)

    want = search_phis(many, exact)[0]
    got = search_phis(many, exact + 0.3, estimated=np.ones_like(exact, dtype=bool))[0]
    assert np.array_equal(got.minima, want.minima)
    assert got.error == want.error
    assert np.array_equal(got.grid_errors, exact[0] + 0.3)  # the row as it was given
    # Told nothing, the lifted samples lose to every refinement: the same answer here,
    # but with estimates *below* the function a sample would replace its refinement.
    low = search_phis(many, exact - 0.3, estimated=np.ones_like(exact, dtype=bool))[0]
    assert np.allclose(low.minima[:, 1], f(low.minima[:, 0]), rtol=0, atol=0)
    with pytest.raises(ValueError, match=r"estimated must be \(1, 36\), got \(2,\)"):
        search_phis(many, exact, estimated=np.array([True, False]))


@pytest.mark.parametrize(
    ("grid", "kwargs", "match"),
    [
        (np.ones(36), {}, r"grid_errors must be \(c, steps\)"),
        (np.ones((2, 2)), {}, r"grid_errors must be \(c, steps\)"),
        (np.ones((2, 36)), {"refine_ratio": 0.5}, "refine_ratio must be >= 1"),
        (np.full((1, 36), np.nan), {}, "values must be finite"),
    ],
)
def test_search_phis_errors(grid, kwargs, match):
    with pytest.raises(ValueError, match=match):
        search_phis(lambda rows, phis: np.zeros(len(phis)), grid, **kwargs)
