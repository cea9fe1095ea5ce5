"""Candidate contacts: the table lookup over (K, H) and the spreading of its hits.

Section 2.1 of the paper: the curvature sites (points on the model's smooth surface, see
:mod:`meshrec.model.curvature`) whose Gaussian and mean curvatures are close to the
estimate at p are candidate locations of p. On a sphere or cylinder every site matches,
and thousands of neighbouring hits would start the same local search in the same basin,
so the hits are thinned by spreading them over the surface (farthest-point sampling with
a minimum spacing), not by the best curvature match, which would cluster them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_number

__all__ = ["CandidateSet", "curvature_tolerance", "find_candidates", "spread_points"]


@dataclass(frozen=True, eq=False)
class CandidateSet(ValueEquality):
    """The candidates found on one model for one side of the surface.

    Attributes
    ----------
    sites : (c,) int
        Curvature-site indices (into ``model.curvature``) of the spread candidates.
    raw_hits : int
        Sites that matched the curvature lookup before spreading.
    tol_K, tol_H : float
        The lookup's tolerances on K and H.
    """

    sites: np.ndarray
    raw_hits: int
    tol_K: float
    tol_H: float


def curvature_tolerance(
    k1: float,
    k2: float,
    half_length: float,
    fit_rms: float,
    rel: float = defaults.CANDIDATE_REL_TOL,
    noise_factor: float = defaults.CANDIDATE_NOISE_FACTOR,
    curvature_sd: float = 0.0,
) -> tuple[float, float]:
    """Tolerances on (K, H) derived from the expected error of the principal curvatures.

    The error of a curvature estimated from noisy curves grows like noise / length^2
    (a second derivative of a least-squares fit), and the mesh's own curvature and the
    fit's bias add a part proportional to the curvature. Each principal curvature is taken
    to be within ``tau = rel * max(|k1|, |k2|) + noise_factor * fit_rms / half_length^2``;
    propagated to K = k1 k2 and H = (k1 + k2) / 2 this gives ``tol_H = tau`` and
    ``tol_K = tau (|k1| + |k2|) + tau^2``. The defaults hold the true contact's table
    entry for every one of 160 simulated touches on the paper's surfaces (noise +-0.001,
    seeds 0-39 per surface), the tolerance at least 3.2 times the actual mismatch
    (measured with ``tools/tolerance_study.py``). ``tau`` is at least
    ``defaults.CANDIDATE_SD_FACTOR`` times the estimate's own standard error
    (:attr:`~meshrec.contact.geometry.LocalGeometry.curvature_sd`), which the curves'
    length and noise alone understate where a curve's samples lie on one side of p.

    Parameters
    ----------
    k1, k2 : float
        Estimated principal curvatures.
    half_length : float
        Half-length of the data curves.
    fit_rms : float
        RMS residual of the curve fits, an estimate of the data's noise.
    rel, noise_factor : float
        The relative and the noise-driven parts of the tolerance.
    curvature_sd : float
        The principal curvatures' standard error (0: not known).

    Returns
    -------
    tol_K, tol_H : float

    Raises
    ------
    TypeError
        If an argument is not a real number (a complex number, a string, a bool).
    ValueError
        If an argument is not finite, ``half_length`` is not positive, or ``fit_rms``,
        ``rel`` or ``noise_factor`` is negative.
    """
    k1 = check_number(k1, "k1")
    k2 = check_number(k2, "k2")
    half_length = check_number(half_length, "half_length")
    fit_rms = check_number(fit_rms, "fit_rms")
    rel = check_number(rel, "rel", minimum=0.0)
    noise_factor = check_number(noise_factor, "noise_factor", minimum=0.0)
    curvature_sd = check_number(curvature_sd, "curvature_sd", minimum=0.0)
    if not half_length > 0:
        raise ValueError(f"half_length must be positive, got {half_length!r}")
    if not fit_rms >= 0:
        raise ValueError(f"fit_rms must be non-negative, got {fit_rms!r}")
    tau = rel * max(abs(k1), abs(k2)) + noise_factor * fit_rms / half_length**2
    tau = max(tau, defaults.CANDIDATE_SD_FACTOR * curvature_sd)
    return tau * (abs(k1) + abs(k2)) + tau * tau, tau


def spread_points(points: np.ndarray, spacing: float, limit: int, first: int = 0) -> np.ndarray:
    """Farthest-point sampling: indices of points spread at least ``spacing`` apart.

    Parameters
    ----------
    points : (n, 3) float
    spacing : float
        Stop once the farthest remaining point is closer than this to the chosen ones.
    limit : int
        Most points chosen.
    first : int
        Index of the first point chosen.

    Returns
    -------
    (c,) int
        Chosen indices, in the order chosen.
    """
    n = len(points)
    if n == 0 or limit <= 0:
        return np.zeros(0, dtype=np.int64)
    chosen = [int(first)]
    dist = np.linalg.norm(points - points[first], axis=1)
    while len(chosen) < limit:
        j = int(np.argmax(dist))
        if dist[j] < spacing:
            break
        chosen.append(j)
        dist = np.minimum(dist, np.linalg.norm(points - points[j], axis=1))
    return np.array(chosen, dtype=np.int64)


def find_candidates(
    model,
    k1: float,
    k2: float,
    half_length: float,
    fit_rms: float,
    max_candidates: int = defaults.MAX_CANDIDATES,
    lookup_scale: float = 1.0,
    curvature_sd: float = 0.0,
) -> CandidateSet:
    """Look up the curvature sites of ``model`` whose (K, H) match, then spread them.

    Parameters
    ----------
    model : ModelIndex
    k1, k2 : float
        Principal curvatures estimated at the contact, for the side being matched (the
        sign convention of :func:`meshrec.contact.geometry.estimate_local_geometry`).
    half_length : float
        Half-length of the data curves; sets the tolerance and the candidates' spacing.
    fit_rms : float
        RMS residual of the curve fits (the data's noise); sets the tolerance.
    max_candidates : int
        Most candidates returned.
    lookup_scale : float
        Factor widening both tolerances of :func:`curvature_tolerance` (1: as
        calibrated; larger looks harder, for more candidates).
    curvature_sd : float
        The principal curvatures' standard error (see :func:`curvature_tolerance`).

    Returns
    -------
    CandidateSet

    Raises
    ------
    ValueError
        If ``lookup_scale`` is not a positive finite number, or (see
        :func:`curvature_tolerance`) ``half_length`` is not positive or ``fit_rms`` is
        negative.
    """
    if isinstance(lookup_scale, bool) or not (
        isinstance(lookup_scale, (int, float, np.integer, np.floating))
        and np.isfinite(lookup_scale)
        and lookup_scale > 0
    ):
        raise ValueError(f"lookup_scale must be a positive finite number, got {lookup_scale!r}")
    K, H = k1 * k2, 0.5 * (k1 + k2)
    tol_K, tol_H = curvature_tolerance(k1, k2, half_length, fit_rms, curvature_sd=curvature_sd)
    if lookup_scale != 1.0:
        tol_K, tol_H = tol_K * lookup_scale, tol_H * lookup_scale
    hits = model.curvature.lookup(K, H, tol_K, tol_H)
    if len(hits) == 0:
        return CandidateSet(np.zeros(0, dtype=np.int64), 0, tol_K, tol_H)
    # Start from the closest match in (K, H) so that the best one is always tried.
    table = model.curvature
    with np.errstate(divide="ignore", invalid="ignore"):
        mismatch = table.mismatch(hits, K, H, tol_K, tol_H)
    first = int(np.argmin(np.nan_to_num(mismatch, nan=np.inf)))
    spacing = defaults.CANDIDATE_SPACING_FRACTION * half_length
    chosen = spread_points(table.points[hits], spacing, max_candidates, first=first)
    return CandidateSet(hits[chosen], len(hits), tol_K, tol_H)
