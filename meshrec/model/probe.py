"""A model seen through a ball-tipped probe: its surface offset outwards by the tip radius.

:func:`probe_model` gives a :class:`~meshrec.model.index.ModelIndex` whose ``surface`` is a
:class:`ProbeSurface`: the same queries of the same mesh (the registration's charts and
contacts stay on the real surface), carrying the tip radius R, which the registration's
residuals subtract from the signed distance (:mod:`meshrec.registration.objective`), so
that ball-centre data are compared with the offset surface. The signed distance is
positive outside (on the side of the faces' outward normals).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from meshrec.io.checks import check_instance, check_number
from meshrec.model.index import ModelIndex
from meshrec.model.surface import SurfaceQuery

__all__ = ["ProbeSurface", "probe_model", "probe_radius_of"]


@dataclass(frozen=True, eq=False)
class ProbeSurface:
    """A :class:`~meshrec.model.surface.SurfaceQuery` with a probe's ball-tip radius.

    Every query is the base surface's own; ``probe_radius`` tells the residuals to
    measure from the offset surface.

    Attributes
    ----------
    base : SurfaceQuery
        The model's surface queries.
    probe_radius : float
        The tip radius R, model units, >= 0.

    Raises
    ------
    TypeError
        If ``base`` is not a SurfaceQuery or ``probe_radius`` not a real number.
    ValueError
        If ``probe_radius`` is negative or not finite.
    """

    base: SurfaceQuery
    probe_radius: float

    def __post_init__(self) -> None:
        if not isinstance(self.base, SurfaceQuery):
            raise TypeError(f"base must be a SurfaceQuery, got {type(self.base).__name__}")
        r = check_number(self.probe_radius, "probe_radius", minimum=0.0)
        object.__setattr__(self, "probe_radius", r)

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The base surface's closest points (see ``SurfaceQuery.closest_points``)."""
        return self.base.closest_points(points)

    def interpolated_normals(self, closest: np.ndarray, face: np.ndarray) -> np.ndarray:
        """The base surface's smooth normals (see ``SurfaceQuery.interpolated_normals``)."""
        return self.base.interpolated_normals(closest, face)

    def smooth_offsets(self, closest: np.ndarray, face: np.ndarray) -> np.ndarray:
        """The base surface's smooth heights (see ``SurfaceQuery.smooth_offsets``)."""
        return self.base.smooth_offsets(closest, face)

    def smooth_offsets_and_gradients(
        self, closest: np.ndarray, face: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The base surface's heights and gradients (see the SurfaceQuery method)."""
        return self.base.smooth_offsets_and_gradients(closest, face)

    def __repr__(self) -> str:
        return f"ProbeSurface({self.base!r}, probe_radius={self.probe_radius:g})"


def probe_radius_of(model) -> float:
    """The probe radius a model's residuals subtract (0 for a plain model).

    Parameters
    ----------
    model : ModelIndex

    Returns
    -------
    float
    """
    return float(getattr(model.surface, "probe_radius", 0.0))


def probe_model(model: ModelIndex, probe_radius: float) -> ModelIndex:
    """The model as ball-centre data of a tip of radius ``probe_radius`` see it.

    Parameters
    ----------
    model : ModelIndex
    probe_radius : float
        The tip radius, model units, >= 0.

    Returns
    -------
    ModelIndex
        ``model`` itself when the radius is what it already carries; otherwise a copy whose
        ``surface`` is a :class:`ProbeSurface` over the model's own (its cached resolution
        kept).

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex or ``probe_radius`` not a real number.
    ValueError
        If ``probe_radius`` is negative or not finite.
    """
    check_instance(model, ModelIndex, "model")
    r = check_number(probe_radius, "probe_radius", minimum=0.0)
    if r == probe_radius_of(model):
        return model
    base = model.surface.base if isinstance(model.surface, ProbeSurface) else model.surface
    surface = base if r == 0.0 else ProbeSurface(base=base, probe_radius=r)
    out = dataclasses.replace(model, surface=surface)
    if "resolution" in model.__dict__:  # a cached_property computed already
        out.__dict__["resolution"] = model.__dict__["resolution"]
    return out
