"""Local search over the contact's position on the surface and the rotation phi.

From a candidate point and its initial phi, minimise the registration error
E(u, v, phi) over a surface chart (see :mod:`meshrec.registration.chart`), re-centring the
chart at the current point until the contact stops moving. Two methods:

* ``"lm"`` (default): Levenberg-Marquardt least squares (scipy) on the signed
  point-to-surface residuals, with a semi-analytic Jacobian over (u, v, phi).
* ``"steepest"``: the paper's steepest descent on E = mean |distance|, with a backtracking
  line search, kept as the reference method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.registration.chart import SurfaceChart, SurfacePoint, rotation_z
from meshrec.registration.objective import residuals

__all__ = ["SEARCH_METHODS", "LocalSearch", "chart_residuals", "local_search"]

SEARCH_METHODS = ("lm", "steepest")


@dataclass(frozen=True, eq=False)
class LocalSearch(ValueEquality):
    """Result of one local search.

    Attributes
    ----------
    surface : SurfacePoint
        The contact q* found on the model and its frame.
    phi : float
        The rotation about the normal at q*, radians.
    error : float
        Mean unsigned point-to-surface distance of the data points at the result.
    path : (k, 3) float
        The contact's positions along the search, start first, model coordinates.
    evaluations : int
        Error evaluations used.
    """

    surface: SurfacePoint
    phi: float
    error: float
    path: np.ndarray
    evaluations: int


def _placed(local_points: np.ndarray, surface: SurfacePoint, phi: float) -> np.ndarray:
    R = surface.frame @ rotation_z(phi)
    return local_points @ R.T + surface.point


def local_search(
    model,
    local_points: np.ndarray,
    start: SurfacePoint,
    phi0: float,
    scale: float,
    method: str = defaults.SEARCH_METHOD,
) -> LocalSearch:
    """Search locally for the contact and phi with the least registration error.

    Parameters
    ----------
    model : ModelIndex
        The model searched.
    local_points : (n, 3) float
        The data points in the data frame (origin at the contact, z along the normal).
    start : SurfacePoint
        The candidate point and its frame.
    phi0 : float
        The initial rotation about the normal, radians.
    scale : float
        A length that sets the step scale of (u, v): the curves' half-length.
    method : {"lm", "steepest"}
        The optimiser.

    Returns
    -------
    LocalSearch

    Raises
    ------
    ValueError
        If ``method`` is unknown or ``scale`` is not positive.
    """
    if method not in SEARCH_METHODS:
        raise ValueError(f"method must be one of {SEARCH_METHODS}, got {method!r}")
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be positive, got {scale!r}")
    if method == "lm":
        return _search_lm(model, local_points, start, phi0, scale)
    return _search_steepest(model, local_points, start, phi0, scale)


class _ChartResiduals:
    """Residuals of the placed data over a chart's (u, v, phi), and their Jacobian.

    The Jacobian is semi-analytic: phi rotates the data about the normal at the chart
    point, so its column is g . (n x (y - q)) exactly; u and v move the chart point and
    turn its frame, whose derivative is a one-sided difference of the chart (a one-point
    closest-point query each), chained with each residual's gradient g. A finite-difference
    Jacobian of the residuals instead costs a full n-point distance query per column.
    """

    def __init__(self, model, local_points, chart, step):
        self.model, self.local, self.chart, self.step = model, local_points, chart, step
        self._states = {}

    def _at(self, x):
        # Every evaluated point is kept (a few tens per chart): the search's answer is one
        # of them, and its contact and error are then read here, not queried again.
        key = x.tobytes()
        state = self._states.get(key)
        if state is None:
            surface = self.chart.at(x[0], x[1])
            y = _placed(self.local, surface, x[2])
            state = self._states[key] = (surface, y, residuals(self.model, y))
        return state

    def evaluated(self, x):
        """The (surface point, placed data, residuals) at ``x`` if evaluated, else None."""
        return self._states.get(np.asarray(x, dtype=np.float64).tobytes())

    def fun(self, x):
        return self._at(x)[2].values

    def jac(self, x):
        surface, y, res = self._at(x)
        g = res.gradient
        J = np.empty((len(y), 3))
        # Both one-sided differences in one chart query (the same points as two).
        uv = np.array([[x[0] + self.step, x[1] + 0.0], [x[0] + 0.0, x[1] + self.step]])
        for j, moved in enumerate(self.chart.at_many(uv)):
            dy = (_placed(self.local, moved, x[2]) - y) / self.step
            J[:, j] = np.einsum("ij,ij->i", g, dy)
        J[:, 2] = np.einsum("ij,ij->i", g, _cross_rows(surface.normal, y - surface.point))
        return J


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross(a, b)`` of a (3,) vector with (n, 3) rows, written out (the same
    products, without np.cross's axis handling: measured 8% of a recognition's time)."""
    a0, a1, a2 = a.tolist()
    out = np.empty_like(b)
    out[:, 0] = a1 * b[:, 2] - a2 * b[:, 1]
    out[:, 1] = a2 * b[:, 0] - a0 * b[:, 2]
    out[:, 2] = a0 * b[:, 1] - a1 * b[:, 0]
    return out


def _search_lm(model, local_points, start, phi0, scale) -> LocalSearch:
    origin, phi = start, float(phi0)
    path = [origin.point]
    evaluations = 0
    state = None
    for _ in range(defaults.MAX_RECENTRES):
        chart = SurfaceChart(model, origin)
        problem = _ChartResiduals(model, local_points, chart, defaults.CHART_FD_STEP * scale)
        sol = least_squares(
            problem.fun,
            np.array([0.0, 0.0, phi]),
            jac=problem.jac,
            method="lm",
            x_scale=np.array([scale, scale, 1.0]),
            max_nfev=defaults.CHART_MAX_EVALS,
            ftol=defaults.CHART_TOL,
            xtol=defaults.CHART_TOL,
        )
        evaluations += int(sol.nfev)
        u, v, phi = (float(t) for t in sol.x)
        state = problem.evaluated(sol.x)
        origin = chart.at(u, v) if state is None else state[0]
        path.append(origin.point)
        if np.hypot(u, v) < defaults.RECENTRE_TOL_FRACTION * scale:
            break
    if state is None:
        state = (origin, None, residuals(model, _placed(local_points, origin, phi)))
    err = float(np.abs(state[2].values).mean())
    return LocalSearch(
        surface=origin,
        phi=phi % (2 * np.pi),
        error=err,
        path=np.array(path),
        evaluations=evaluations + 1,
    )


def _search_steepest(model, local_points, start, phi0, scale) -> LocalSearch:
    """The paper's steepest descent on E(u, v, phi), re-centring the chart every step."""

    def energy(chart, x):
        y = _placed(local_points, chart.at(x[0] * scale, x[1] * scale), x[2])
        return float(np.abs(residuals(model, y).values).mean())

    origin, phi = start, float(phi0)
    chart = SurfaceChart(model, origin)
    e0 = energy(chart, np.array([0.0, 0.0, phi]))
    evaluations = 1
    path = [origin.point]
    alpha, h = defaults.STEEPEST_STEP, defaults.STEEPEST_FD_STEP
    for _ in range(defaults.STEEPEST_MAX_ITER):
        x0 = np.array([0.0, 0.0, phi])
        grad = np.empty(3)
        for j in range(3):
            dx = np.zeros(3)
            dx[j] = h
            grad[j] = (energy(chart, x0 + dx) - energy(chart, x0 - dx)) / (2 * h)
        evaluations += 6
        gnorm = float(np.linalg.norm(grad))
        if gnorm == 0.0:
            break
        direction = -grad / gnorm
        improved = False
        while alpha > defaults.STEEPEST_MIN_STEP:
            x1 = x0 + alpha * direction
            e1 = energy(chart, x1)
            evaluations += 1
            if e1 < e0 - defaults.STEEPEST_ARMIJO * alpha * gnorm:
                improved = True
                break
            alpha *= defaults.STEEPEST_SHRINK
        if not improved:
            break
        origin = chart.at(x1[0] * scale, x1[1] * scale)
        phi = float(x1[2])
        chart = SurfaceChart(model, origin)
        path.append(origin.point)
        rel = (e0 - e1) / max(e0, 1e-300)
        e0 = e1
        alpha *= defaults.STEEPEST_GROW
        if rel < defaults.STEEPEST_REL_TOL:
            break
    return LocalSearch(
        surface=origin,
        phi=phi % (2 * np.pi),
        error=e0,
        path=np.array(path),
        evaluations=evaluations,
    )


def chart_residuals(
    model, local_points: np.ndarray, start: SurfacePoint, x, scale: float
) -> tuple[np.ndarray, np.ndarray]:
    """The local search's residuals at chart coordinates (u, v, phi), and their Jacobian.

    The residuals and the semi-analytic Jacobian that the ``"lm"`` search hands to
    Levenberg-Marquardt, on the chart centred at ``start`` (for tests and diagnostics).

    Parameters
    ----------
    model : ModelIndex
        The model searched.
    local_points : (n, 3) float
        The data points in the data frame (origin at the contact, z along the normal).
    start : SurfacePoint
        The chart's centre and frame.
    x : (3,) float
        Chart coordinates u, v (model units) and the rotation phi about the normal
        (radians).
    scale : float
        The length that sets the chart's difference step (the curves' half-length), as in
        :func:`local_search`.

    Returns
    -------
    values : (n,) float
        Signed point-to-surface residuals of the placed points.
    jacobian : (n, 3) float
        Their derivatives with respect to (u, v, phi).

    Raises
    ------
    ValueError
        If ``local_points`` is not (n, 3), ``x`` is not three finite numbers, or ``scale``
        is not positive.
    """
    pts = np.asarray(local_points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"local_points must be (n, 3), got {pts.shape}")
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (3,) or not np.isfinite(x).all():
        raise ValueError(f"x must be three finite numbers (u, v, phi), got {x!r}")
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be positive, got {scale!r}")
    problem = _ChartResiduals(
        model, pts, SurfaceChart(model, start), defaults.CHART_FD_STEP * scale
    )
    return problem.fun(x).copy(), problem.jac(x)
