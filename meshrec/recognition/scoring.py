"""Calibrated scores and the verdict: how sure the recognition is, as numbers.

Pure functions over numbers and arrays (no meshes): the noise level of a touch, each
model's log-likelihood from its residual at its best pose, the posterior probabilities,
the goodness of fit of the best model, the plausible set and the verdict, and the weights
of a model's pose hypotheses.

The noise model: the signed point-to-surface residuals of the right model at the right
pose are the data noise along the normal, independent with standard deviation ``noise``.
``n`` points whose RMS residual is ``rms`` then have the log-likelihood
``-n rms^2 / (2 noise^2)`` up to a constant shared by every model. The residuals of a
touch are not independent in practice (the curve fits, the mesh's facets and a slightly
wrong model all leave smooth, correlated residuals along the curves), so ``n`` is replaced
by an effective sample size ``defaults.SCORE_ESS_FRACTION * n`` (measured on simulated
touches, see ``tools/calibration.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from meshrec import defaults
from meshrec._values import ValueEquality

__all__ = [
    "VERDICTS",
    "ModelScore",
    "Verdict",
    "WeightedPose",
    "decide",
    "effective_points",
    "fit_p_value",
    "log_likelihoods",
    "noise_estimate",
    "plausible_set",
    "pose_weights",
    "posterior",
]

#: The three verdicts, from most to least sure.
VERDICTS = ("recognised", "ambiguous", "unknown")


@dataclass(frozen=True, eq=False)
class WeightedPose(ValueEquality):
    """One distinct pose of the touch on a model, with its weight.

    Attributes
    ----------
    T_model_touch : (4, 4) float
        Maps touch-frame points to model coordinates.
    rms : float
        RMS point-to-surface distance at this pose, model units.
    weight : float
        Probability of this pose among the model's poses (they sum to 1).
    """

    T_model_touch: np.ndarray
    rms: float
    weight: float

    def __repr__(self) -> str:
        return f"WeightedPose(rms={self.rms:.4g}, weight={self.weight:.3f})"


@dataclass(frozen=True, eq=False)
class ModelScore(ValueEquality):
    """The calibrated score of one model of the ranking.

    Attributes
    ----------
    model : str
        Model name.
    probability : float
        Posterior probability that the touch came from this model (the ranking's sum to 1;
        0 for a model with no registration).
    rms : float or None
        RMS point-to-surface distance at the best pose, model units; None when the model
        had no registration (no candidate).
    n_points : int
        Data points the residual is taken over.
    log_likelihood : float
        ``-n_eff rms^2 / (2 noise^2)``; ``-inf`` for a model with no registration.
    poses : tuple of WeightedPose
        The distinct poses, best first; empty for a model with no registration.
    """

    model: str
    probability: float
    rms: float | None
    n_points: int
    log_likelihood: float
    poses: tuple[WeightedPose, ...] = ()

    def __repr__(self) -> str:
        rms = "-" if self.rms is None else f"{self.rms:.4g}"
        return (
            f"ModelScore({self.model!r}, probability={self.probability:.3f}, rms={rms}, "
            f"poses={len(self.poses)})"
        )


@dataclass(frozen=True)
class Verdict:
    """What the recognition concludes.

    Attributes
    ----------
    verdict : str
        "recognised" (one model clearly), "ambiguous" (two or more models the data cannot
        separate) or "unknown" (no model fits the data to the noise level).
    plausible : tuple of str
        The models that stay plausible, best first: one when recognised, two or more
        when ambiguous, none when unknown.
    reason : str
        One sentence explaining the verdict.
    fit_ratio : float
        The best model's RMS residual over the noise estimate (about 1 for a right fit;
        ``inf`` when no model was registered).
    """

    verdict: str
    plausible: tuple[str, ...]
    reason: str
    fit_ratio: float


def _positive(value, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _non_negative(value, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be a non-negative finite number, got {value!r}")
    return v


def noise_estimate(fit_rms: float, noise_rms: float, half_length: float) -> float:
    """The touch's noise level along the surface normal, from the touch itself.

    Two estimates come with the local geometry: the curve fits' RMS residual (inflated
    where the curves cross an edge: the polynomial cannot follow it) and the third
    differences of consecutive samples (inflated where the samples are coarse on a
    tightly bent curve). Each errs only upwards, so the smaller one is taken. A floor of
    ``defaults.SCORE_NOISE_FLOOR_FRACTION`` of the half-length is added in quadrature: the
    mesh's facets and the curvature table leave that much misfit even on noiseless data.

    Parameters
    ----------
    fit_rms : float
        :attr:`meshrec.LocalGeometry.fit_rms`, >= 0.
    noise_rms : float
        :attr:`meshrec.LocalGeometry.noise_rms`, >= 0.
    half_length : float
        The curves' half-length, > 0.

    Returns
    -------
    float
        Standard deviation of the noise, data units, > 0.

    Raises
    ------
    ValueError
        If an estimate is negative or not finite, or ``half_length`` is not positive.
    """
    f = _non_negative(fit_rms, "fit_rms")
    t = _non_negative(noise_rms, "noise_rms")
    h = _positive(half_length, "half_length")
    floor = defaults.SCORE_NOISE_FLOOR_FRACTION * h
    return float(np.hypot(min(f, t), floor))


def effective_points(n_points: int, ess_fraction: float = defaults.SCORE_ESS_FRACTION) -> float:
    """Effective number of independent residuals among ``n_points`` correlated ones.

    Parameters
    ----------
    n_points : int
        Data points, >= 1.
    ess_fraction : float
        Independent residuals per data point, in (0, 1].

    Returns
    -------
    float
        ``ess_fraction * n_points``.

    Raises
    ------
    ValueError
        If ``n_points`` is not a positive integer or ``ess_fraction`` is outside (0, 1].
    """
    if not isinstance(n_points, (int, np.integer)) or n_points < 1:
        raise ValueError(f"n_points must be a positive integer, got {n_points!r}")
    if not (0.0 < ess_fraction <= 1.0):
        raise ValueError(f"ess_fraction must be in (0, 1], got {ess_fraction!r}")
    return ess_fraction * float(n_points)


def log_likelihoods(
    rms: Sequence[float | None],
    n_points: int,
    noise: float,
    ess_fraction: float = defaults.SCORE_ESS_FRACTION,
) -> np.ndarray:
    """Each model's log-likelihood from its RMS residual at its best pose.

    Parameters
    ----------
    rms : sequence of float or None, length m
        RMS point-to-surface distance of each model at its best pose; None (or NaN) for
        a model with no registration.
    n_points : int
        Data points the residuals are taken over (the same for every model).
    noise : float
        The noise estimate, > 0 (:func:`noise_estimate`).
    ess_fraction : float
        See :func:`effective_points`.

    Returns
    -------
    (m,) float
        ``-n_eff rms^2 / (2 noise^2)`` (see :func:`effective_points`); ``-inf`` where no
        registration. Every model's pose search has the same six degrees of freedom, so
        they cancel in the comparison; they enter the fit test (:func:`fit_p_value`).

    Raises
    ------
    ValueError
        If ``noise`` is not positive, ``n_points`` not a positive integer, an rms is
        negative or infinite, or ``ess_fraction`` is outside (0, 1].
    """
    sigma = _positive(noise, "noise")
    n_eff = effective_points(n_points, ess_fraction)
    r = np.array([np.nan if v is None else float(v) for v in rms], dtype=np.float64)
    bad = ~np.isnan(r) & ~((r >= 0.0) & np.isfinite(r))
    if np.any(bad):
        raise ValueError(f"rms must be non-negative and finite, got {r[bad][0]!r}")
    out = -0.5 * n_eff * (r / sigma) ** 2
    return np.where(np.isnan(r), -np.inf, out)


def posterior(log_likelihood: Sequence[float], prior: Sequence[float] | None = None) -> np.ndarray:
    """Posterior probabilities from log-likelihoods (uniform prior by default).

    Parameters
    ----------
    log_likelihood : (m,) float
        ``-inf`` for a model that is excluded.
    prior : (m,) float, optional
        Prior probabilities (non-negative, normalised here).

    Returns
    -------
    (m,) float
        Summing to 1; all zero when every log-likelihood is ``-inf``.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of the same length, a log-likelihood is NaN or
        ``+inf``, or the prior is negative or sums to zero.
    """
    ll = np.asarray(log_likelihood, dtype=np.float64)
    if ll.ndim != 1:
        raise ValueError(f"log_likelihood must be 1-D, got shape {ll.shape}")
    if np.any(np.isnan(ll)) or np.any(ll == np.inf):
        raise ValueError("log_likelihood must not hold NaN or +inf")
    if prior is not None:
        pr = np.asarray(prior, dtype=np.float64)
        if pr.shape != ll.shape:
            raise ValueError(f"prior must have shape {ll.shape}, got {pr.shape}")
        if np.any(pr < 0) or not pr.sum() > 0:
            raise ValueError("prior must be non-negative with a positive sum")
        with np.errstate(divide="ignore"):
            ll = ll + np.log(pr / pr.sum())
    if not np.any(np.isfinite(ll)):
        return np.zeros_like(ll)
    return special.softmax(ll)


def fit_p_value(rms: float, n_points: int, noise: float, dof: int = defaults.POSE_DOF) -> float:
    """How likely a residual this large is if the model is right (chi-square tail).

    The sum of squared residuals over ``noise^2`` of the right model, with the effective
    number of points (:func:`effective_points`) and the pose's ``dof`` fitted, follows a
    chi-square distribution with ``n_eff - dof`` degrees of freedom.

    Parameters
    ----------
    rms : float
        RMS residual at the best pose, >= 0.
    n_points : int
        Data points.
    noise : float
        Noise estimate, > 0.
    dof : int
        Degrees of freedom of the pose search (6: a rigid motion).

    Returns
    -------
    float
        The upper tail probability, in [0, 1].

    Raises
    ------
    ValueError
        If ``rms`` is negative, ``noise`` not positive, ``n_points`` not a positive
        integer, or ``dof`` negative or not below the effective number of points.
    """
    r = _non_negative(rms, "rms")
    sigma = _positive(noise, "noise")
    n_eff = effective_points(n_points)
    if not isinstance(dof, (int, np.integer)) or dof < 0 or dof >= n_eff:
        raise ValueError(f"dof must be an integer in [0, {n_eff:g}), got {dof!r}")
    # chdtrc(k, x) is chi2.sf(x, k): scipy.special, not scipy.stats, whose import alone
    # takes 0.25 s of CPU time (a quarter of `meshrec next-touch`'s start-up)
    return float(special.chdtrc(n_eff - dof, n_eff * (r / sigma) ** 2))


def plausible_set(
    names: Sequence[str],
    probabilities: Sequence[float],
    coverage: float = defaults.VERDICT_COVERAGE,
) -> tuple[str, ...]:
    """The fewest models whose probabilities add up to at least ``coverage``, best first.

    Parameters
    ----------
    names : sequence of str, length m
    probabilities : (m,) float
        Summing to 1 (or all zero: then the set is empty).
    coverage : float
        In (0, 1].

    Returns
    -------
    tuple of str

    Raises
    ------
    ValueError
        If the lengths differ, a probability is negative or not finite, or ``coverage``
        is outside (0, 1].
    """
    p = np.asarray(probabilities, dtype=np.float64)
    if p.shape != (len(names),):
        raise ValueError(f"probabilities must have shape ({len(names)},), got {p.shape}")
    if np.any(~np.isfinite(p)) or np.any(p < 0):
        raise ValueError("probabilities must be finite and non-negative")
    if not (0.0 < coverage <= 1.0):
        raise ValueError(f"coverage must be in (0, 1], got {coverage!r}")
    if not p.sum() > 0:
        return ()
    order = np.argsort(-p, kind="stable")
    cum = np.cumsum(p[order])
    # a small slack so that rounding never adds a model of probability ~0
    k = int(np.searchsorted(cum, coverage * p.sum() - 1e-12)) + 1
    return tuple(names[i] for i in order[: min(k, len(order))] if p[i] > 0)


def decide(
    names: Sequence[str],
    probabilities: Sequence[float],
    best_rms: float | None,
    n_points: int,
    noise: float,
) -> Verdict:
    """The verdict: recognised, ambiguous or unknown, with the plausible set and why.

    ``unknown`` when no model was registered, or when the best model's residual is
    inconsistent with the noise: its RMS exceeds ``defaults.UNKNOWN_FIT_RATIO`` times the
    noise estimate and its chi-square tail (:func:`fit_p_value`) is below
    ``defaults.UNKNOWN_P_VALUE``. Otherwise the plausible set (:func:`plausible_set` at
    ``defaults.VERDICT_COVERAGE``) decides: one model is ``recognised``, more are
    ``ambiguous``. One model is not ``recognised`` but ``ambiguous`` (with the runner-up)
    when it fits worse than the noise allows (chi-square tail below
    ``defaults.RECOGNISE_P_VALUE``) and the library holds other models.

    Parameters
    ----------
    names : sequence of str
        Model names, in any order.
    probabilities : (m,) float
        Their posterior probabilities (:func:`posterior`).
    best_rms : float or None
        RMS residual of the most probable model; None when no model was registered.
    n_points : int
        Data points.
    noise : float
        Noise estimate, > 0.

    Returns
    -------
    Verdict

    Raises
    ------
    ValueError
        As :func:`plausible_set` and :func:`fit_p_value`.
    """
    sigma = _positive(noise, "noise")
    p = np.asarray(probabilities, dtype=np.float64)
    plausible = plausible_set(names, p)
    if best_rms is None or not plausible:
        return Verdict(
            "unknown",
            (),
            "no model could be registered (the curvature lookup found no candidate contact "
            "on any model, even with a widened window, or, with a normal given, every pose "
            "found put the touch through the surface): the object is probably not in the "
            "library",
            float("inf"),
        )
    ratio = float(best_rms) / sigma
    pval = fit_p_value(best_rms, n_points, sigma)
    if ratio > defaults.UNKNOWN_FIT_RATIO and pval < defaults.UNKNOWN_P_VALUE:
        return Verdict(
            "unknown",
            (),
            f"even the best model, {plausible[0]}, leaves an RMS residual of "
            f"{best_rms:.3g}, {ratio:.3g} times the noise estimated from the touch "
            f"({sigma:.3g}; chi-square p = {pval:.2g}): the object is probably not in the "
            "library",
            ratio,
        )
    best = int(np.argmax(p))
    if len(plausible) == 1 and pval < defaults.RECOGNISE_P_VALUE and len(names) > 1:
        # One model stands out, but even it fits worse than the noise allows: its rivals'
        # probabilities rest on their best fits found, and a better pose of one of them
        # may have been missed (or the object is none of them). Not confident.
        second = names[int(np.argsort(-p, kind="stable")[1])]
        return Verdict(
            "ambiguous",
            (plausible[0], second),
            f"{plausible[0]} fits best (probability {p[best]:.3f}) but worse than the noise "
            f"allows ({ratio:.3g} times the noise, chi-square p = {pval:.2g}): a better fit "
            f"of another model, such as {second}, may have been missed, or the object is "
            "not in the library; touch again elsewhere to decide",
            ratio,
        )
    if len(plausible) == 1:
        return Verdict(
            "recognised",
            plausible,
            f"{plausible[0]} has probability {p[best]:.3f} (the other models "
            f"{max(1.0 - p[best], 0.0):.2g} together, at the best poses their searches "
            f"found) and fits to {ratio:.3g} times the noise",
            ratio,
        )
    return Verdict(
        "ambiguous",
        plausible,
        f"the data cannot separate {len(plausible)} models ({', '.join(plausible)}): they "
        f"fit about equally well (best probability {p[best]:.3f}); touch again elsewhere to "
        "decide",
        ratio,
    )


def pose_weights(rms: Sequence[float], n_points: int, noise: float) -> np.ndarray:
    """Weights of a model's distinct pose hypotheses from their RMS residuals.

    Parameters
    ----------
    rms : (k,) float
        RMS residual at each pose, k >= 1.
    n_points : int
        Data points.
    noise : float
        Noise estimate, > 0.

    Returns
    -------
    (k,) float
        The posterior of each pose under the same likelihood as the models'
        (:func:`log_likelihoods`), summing to 1: equal residuals give equal weights.

    Raises
    ------
    ValueError
        If ``rms`` is empty, negative or not finite, or as :func:`log_likelihoods`.
    """
    r = np.asarray(rms, dtype=np.float64)
    if r.ndim != 1 or len(r) == 0:
        raise ValueError(f"rms must be a non-empty 1-D array, got shape {r.shape}")
    if np.any(~np.isfinite(r)):
        raise ValueError("rms must be finite")
    return posterior(log_likelihoods(list(r), n_points, noise))
