"""Stage 1 of a registration: candidate contacts from the (K, H) table lookup.

For each side of the surface to try (one when the touch gives a normal and the model is
closed, else both), the model's curvature sites whose curvatures match the estimate at
the curves' common point are looked up and spread (see
:mod:`meshrec.registration.candidates`); each becomes a start for the later stages: its
point and tangent frame on the model, and the data in the frame of its side.

For a model seen through a ball-tipped probe (:func:`meshrec.model.probe.probe_model`)
each side is the surface under the ball's centres
(:func:`meshrec.contact.probe.surface_geometry`: the contact moved in by the tip radius
along that side's normal, the curvatures corrected); a side the tip could not have
traced (its convex curvature tighter than the tip) is not tried.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry
from meshrec.contact.probe import surface_geometry
from meshrec.io.checks import check_instance
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.model.probe import probe_radius_of
from meshrec.registration.candidates import find_candidates
from meshrec.registration.chart import SurfacePoint, tangent_frame

__all__ = ["ContactCandidates", "lookup_candidates", "surface_sides"]


@dataclass(frozen=True, eq=False)
class ContactCandidates(ValueEquality):
    """The candidate contacts on one model, both sides together, in lookup order.

    Attributes
    ----------
    geometry : LocalGeometry
        The local geometry at the contact (touch frame), as estimated.
    points : (n, 3) float
        The touch's data points, touch frame.
    sides : tuple of LocalGeometry
        The data frames tried: ``geometry``, then (when both sides are tried) its flip
        (for a model seen through a ball-tipped probe, the surface under the data on
        each side, see :func:`surface_sides`).
    local_points : tuple of (n, 3) float
        The data points in each side's frame (origin at the contact, z along its normal).
    side : (c,) int
        Index into ``sides`` of each candidate.
    sites : (c,) int
        The model's curvature site of each candidate (index into ``model.curvature``).
    origins : tuple of SurfacePoint
        Each candidate's point and tangent frame on the model (normal: the site's normal;
        first axis: its first principal direction).
    raw_hits : int
        Sites matching the lookup before spreading, both sides together.
    tolerances : (k, 2) float
        The lookup's (tol_K, tol_H) for each side.
    """

    geometry: LocalGeometry = field(repr=False)
    points: np.ndarray = field(repr=False)
    sides: tuple[LocalGeometry, ...] = field(repr=False)
    local_points: tuple[np.ndarray, ...] = field(repr=False)
    side: np.ndarray = field(repr=False)
    sites: np.ndarray = field(repr=False)
    origins: tuple[SurfacePoint, ...] = field(repr=False)
    raw_hits: int
    tolerances: np.ndarray = field(repr=False)

    def __len__(self) -> int:
        return len(self.sites)

    @property
    def model_points(self) -> np.ndarray:
        """(c, 3) float: the candidate points, model coordinates."""
        return np.array([o.point for o in self.origins], dtype=np.float64).reshape(-1, 3)

    def __repr__(self) -> str:
        return (
            f"ContactCandidates(candidates={len(self)}, sides={len(self.sides)}, "
            f"raw_hits={self.raw_hits})"
        )


def surface_sides(geometry: LocalGeometry, touch: TouchData, model) -> tuple[LocalGeometry, ...]:
    """The sides of the surface to try: one when a normal is given and the mesh is closed.

    Three curves cannot tell the outside of a surface from its inside; a given normal
    can, but only on a closed mesh is the model's outward normal defined.

    Parameters
    ----------
    geometry : LocalGeometry
        The local geometry at the contact.
    touch : TouchData
        The touch (its ``normal`` hint, if any).
    model : ModelIndex
        The model (whether it is ``closed``).

    Returns
    -------
    tuple of LocalGeometry
        ``(geometry,)`` or ``(geometry, geometry.flipped())``; for a model seen through
        a ball-tipped probe, the surface under the data on each side that a tip of that
        radius could have traced (possibly none).
    """
    if touch.normal is not None and model.mesh.closed:
        sides = (geometry,)
    else:
        sides = (geometry, geometry.flipped())
    radius = probe_radius_of(model)
    if radius == 0.0:
        return sides
    return tuple(surface_geometry(s, radius) for s in sides if radius * s.k1 < 1.0)


def lookup_candidates(
    touch: TouchData,
    model,
    geometry: LocalGeometry,
    *,
    max_candidates: int = defaults.MAX_CANDIDATES,
    lookup_scale: float = 1.0,
) -> ContactCandidates:
    """Find the candidate contacts of the touch on ``model`` (the paper's Section 2.1).

    Parameters
    ----------
    touch : TouchData
        The curves, touch frame.
    model : ModelIndex
        The model, with its curvature table.
    geometry : LocalGeometry
        The local geometry at the contact (see
        :func:`meshrec.registration.register.touch_geometry`).
    max_candidates : int
        Most candidates per side after spreading.
    lookup_scale : float
        Factor widening the (K, H) tolerances of the lookup (1: the calibrated window).

    Returns
    -------
    ContactCandidates
        Possibly empty (no site matches).

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``model`` not a ModelIndex or ``geometry`` not a
        LocalGeometry.
    ValueError
        If ``max_candidates`` is not a positive integer or ``lookup_scale`` is not a
        positive finite number.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(geometry, LocalGeometry, "geometry")
    if (
        not isinstance(max_candidates, (int, np.integer))
        or isinstance(max_candidates, bool)
        or max_candidates < 1
    ):
        raise ValueError(f"max_candidates must be a positive integer, got {max_candidates!r}")
    points = touch.points
    scale = float(geometry.half_length)
    sides = surface_sides(geometry, touch, model)
    side_of, sites, local_points, tolerances = [], [], [], []
    raw_hits = 0
    for k, side in enumerate(sides):
        cand = find_candidates(
            model,
            side.k1,
            side.k2,
            scale,
            side.fit_rms,
            max_candidates=max_candidates,
            lookup_scale=lookup_scale,
            curvature_sd=side.curvature_sd,
        )
        raw_hits += cand.raw_hits
        local_points.append((points - side.point) @ side.frame)
        tolerances.append((cand.tol_K, cand.tol_H))
        side_of.extend([k] * len(cand.sites))
        sites.extend(int(v) for v in cand.sites)
    table = model.curvature
    origins = tuple(
        SurfacePoint(
            point=table.points[v],
            frame=tangent_frame(table.normals[v], hint=table.dir1[v]),
        )
        for v in sites
    )
    return ContactCandidates(
        geometry=geometry,
        points=points,
        sides=sides,
        local_points=tuple(local_points),
        side=np.array(side_of, dtype=np.int64),
        sites=np.array(sites, dtype=np.int64),
        origins=origins,
        raw_hits=raw_hits,
        tolerances=np.array(tolerances, dtype=np.float64).reshape(-1, 2),
    )
