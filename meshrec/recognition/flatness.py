"""The prior of a flat touch: how much of each model's surface could have given it.

A touch on a flat face fits every model with a flat region wider than the curves equally
well: a box's face, a cylinder's cap, a cone's base. The fits cannot tell them apart, but
the models differ in how much of their surface is such a region: a touch at a random
place of a box is flat far more often than one on a cylinder. With the contact uniform
over a model's surface, the chance that a touch lands where the curves fit a plane is the
share of the surface that is flat over the curves' whole reach, and Bayes' rule weighs
each model's likelihood by it. This module estimates that share from the model's curvature
sites (spread evenly over its surface, :mod:`meshrec.model.sites`): the flat sites (both
principal curvatures within the lookup's tolerance of zero, and the normal turning less
than ``defaults.FLAT_SITE_BEND`` over the curves' reach) that lie farther than the
curves' reach from every site that is not flat (curved, a crease, or unfitted).

The prior orders the models and moves their probabilities; it never decides alone:
:func:`flat_prior` clips it to at most ``defaults.FLAT_PRIOR_MAX_RATIO`` between models,
and the recognition keeps every model that is plausible on the data alone
(:mod:`meshrec.recognition.recognize`). A curved touch gets no prior.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_instance
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.registration.candidates import curvature_tolerance

__all__ = ["flat_prior", "flat_share", "flat_tolerance"]


def flat_tolerance(geometry: LocalGeometry) -> float | None:
    """The curvature tolerance within which the touch is flat, or None if it is curved.

    Parameters
    ----------
    geometry : LocalGeometry
        The touch's local geometry at the contact.

    Returns
    -------
    float or None
        The lookup's tolerance on each principal curvature
        (:func:`~meshrec.registration.candidates.curvature_tolerance`, 1 / model units)
        when both of the touch's principal curvatures are within it of zero (a plane is
        inside the lookup's window); None otherwise.

    Raises
    ------
    TypeError
        If ``geometry`` is not a LocalGeometry.
    """
    check_instance(geometry, LocalGeometry, "geometry")
    _, tau = curvature_tolerance(
        geometry.k1,
        geometry.k2,
        geometry.half_length,
        geometry.fit_rms,
        curvature_sd=geometry.curvature_sd,
    )
    if max(abs(geometry.k1), abs(geometry.k2)) <= tau:
        return float(tau)
    return None


def flat_share(model: ModelIndex, tolerance: float, reach: float) -> float:
    """The share of a model's surface where curves of a given reach fit a plane.

    Parameters
    ----------
    model : ModelIndex
        The model, with its curvature sites.
    tolerance : float
        Largest principal curvature of a flat site, >= 0, 1 / model units.
    reach : float
        How far the curves reach from the contact, > 0, model units.

    Returns
    -------
    float
        In [0, 1]: the fraction of the model's sites that are flat (both principal
        curvatures at most ``tolerance`` and ``defaults.FLAT_SITE_BEND / reach``), not on a
        crease, and farther than ``reach`` from every site that is not (the sites are spread evenly,
        so this is about the fraction of the area). On a model that is flat everywhere,
        the fraction of flat sites.

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex.
    ValueError
        If ``tolerance`` is negative or ``reach`` not positive (or either not finite).
    """
    check_instance(model, ModelIndex, "model")
    if not (np.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    if not (np.isfinite(reach) and reach > 0.0):
        raise ValueError(f"reach must be a finite number > 0, got {reach!r}")
    table = model.curvature
    n = len(table.points)
    if n == 0:
        return 0.0
    # a flat site: within the touch's tolerance, and truly flat at the curves' scale (a
    # turn of the normal over the reach under defaults.FLAT_SITE_BEND): at a coarse
    # tolerance (short, noisy curves) every gently curved model would look flat
    k_max = min(tolerance, defaults.FLAT_SITE_BEND / reach)
    with np.errstate(invalid="ignore"):
        flat = (
            table.valid
            & ~table.crease
            & (np.abs(table.k1) <= k_max)
            & (np.abs(table.k2) <= k_max)
        )
    if not flat.any():
        return 0.0
    if flat.all():
        return 1.0
    # scipy's KD-tree gives each flat site's distance to the nearest site that is not flat
    d, _ = cKDTree(table.points[~flat]).query(table.points[flat], k=1)
    return float(np.count_nonzero(d > reach)) / n


def flat_prior(
    touch: TouchData, geometry: LocalGeometry, models: list[ModelIndex]
) -> np.ndarray | None:
    """Prior weights of the models for a flat touch, or None for a curved one.

    Parameters
    ----------
    touch : TouchData
        The touch (its points give the curves' reach from the contact).
    geometry : LocalGeometry
        Its local geometry (:func:`flat_tolerance` decides whether it is flat).
    models : list of ModelIndex
        The models, in the order of the weights returned.

    Returns
    -------
    (m,) float or None
        Each model's :func:`flat_share`, raised to at least the largest share over
        ``defaults.FLAT_PRIOR_MAX_RATIO`` (a model whose flat regions are too small by
        the estimate keeps some weight: the sites are a sample); None when the touch is
        curved or no model has a flat region that holds the curves.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``geometry`` not a LocalGeometry or, for a flat
        touch, a model not a ModelIndex.
    """
    check_instance(touch, TouchData, "touch")
    tolerance = flat_tolerance(geometry)
    if tolerance is None:
        return None
    reach = float(np.max(np.linalg.norm(touch.points - geometry.point, axis=1)))
    if not reach > 0.0:
        return None
    shares = np.array([flat_share(m, tolerance, reach) for m in models], dtype=np.float64)
    top = float(shares.max()) if len(shares) else 0.0
    if not top > 0.0:
        return None
    return np.maximum(shares, top / defaults.FLAT_PRIOR_MAX_RATIO)
