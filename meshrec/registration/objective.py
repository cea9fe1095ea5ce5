"""The registration error: distances from transformed data points to a model's surface.

The paper's error (1) is the summed first-order distance |f| / |grad f| to an implicit
surface. On a mesh we use the exact Euclidean distance to the closest point, from libigl's
AABB tree (built once per model). The distance carries a sign only to keep residuals smooth
where a point crosses the surface: the side is read from the normal of the closest point's
face, never from a winding number (unreliable on open meshes), and the
magnitude is always the Euclidean distance, so a point beyond an open mesh's boundary is
charged its true distance to that boundary.

Data taken with a ball-tipped probe lie on the surface offset outwards by the tip radius
R: for a model seen through such a probe (:func:`meshrec.model.probe.probe_model`) the
residual is the signed distance (positive outside) minus R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meshrec._values import ValueEquality
from meshrec.model.probe import probe_radius_of

__all__ = ["Residuals", "mean_distances", "point_distances", "residuals"]


@dataclass(frozen=True, eq=False)
class Residuals(ValueEquality):
    """Signed point-to-surface residuals of a set of points.

    Attributes
    ----------
    values : (n,) float
        Distance to the surface, signed by the side of the closest face's normal: the
        Euclidean distance to the closest point of the mesh, less the height there of the
        smooth surface that the vertex normals imply (see
        :meth:`meshrec.ModelIndex.smooth_offsets`), less the model's probe radius
        (:func:`meshrec.model.probe.probe_radius_of`; 0 for a plain model).
    closest : (n, 3) float
        Closest points on the surface.
    gradient : (n, 3) float
        Gradient of each residual with respect to its point (unit, up to the slope of the
        smooth surface over the face).
    """

    values: np.ndarray
    closest: np.ndarray
    gradient: np.ndarray


def residuals(model, points: np.ndarray) -> Residuals:
    """Signed distances from ``points`` to the model's surface, with their gradients.

    Parameters
    ----------
    model : ModelIndex
        The model (its AABB tree answers the closest-point queries).
    points : (n, 3) float
        Query points in model coordinates.

    Returns
    -------
    Residuals
    """
    dist, closest, face = model.surface.closest_points(points)
    normals = model.mesh.face_normals[face]
    diff = points - closest
    side = np.einsum("ij,ij->i", diff, normals)
    sign = np.where(side < 0.0, -1.0, 1.0)
    tiny = dist <= 1e-12 * max(1.0, float(np.abs(points).max(initial=0.0)))
    if tiny.any():
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = diff / dist[:, None]
        unit[tiny] = normals[tiny]
        unit[~tiny] *= sign[~tiny, None]
    else:
        # The common case without the masks (the same values: this runs at every
        # evaluation of every search and refinement).
        unit = diff / dist[:, None]
        unit *= sign[:, None]
    # Distance to the smooth surface the vertex normals imply, not to the flat faces: the
    # height of that surface above the face is subtracted, and its slope along the face
    # (the closest point moves with the point) from the gradient.
    heights, slopes = model.surface.smooth_offsets_and_gradients(closest, face)
    values = sign * dist - heights - probe_radius_of(model)
    return Residuals(values=values, closest=closest, gradient=unit - slopes)


def point_distances(model, points: np.ndarray) -> np.ndarray:
    """Unsigned distance of each point to the model's surface.

    Parameters
    ----------
    model : ModelIndex
    points : (m, 3) float
        Points, model coordinates.

    Returns
    -------
    (m,) float
        The Euclidean distance to the closest point of the mesh; for a model seen through
        a ball-tipped probe, the distance to the offset surface (``|signed distance - R|``,
        signed by the closest face's normal). Each point's distance is its own (the same
        bits whatever the other points).
    """
    flat = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    dist, closest, face = model.surface.closest_points(flat)
    radius = probe_radius_of(model)
    if radius > 0.0:
        side = np.einsum("ij,ij->i", flat - closest, model.mesh.face_normals[face])
        dist = np.abs(np.where(side < 0.0, -dist, dist) - radius)
    return dist


def mean_distances(model, points: np.ndarray) -> np.ndarray:
    """Mean unsigned distance of each batch of points to the model's surface.

    Parameters
    ----------
    model : ModelIndex
    points : (k, n, 3) float
        ``k`` batches of ``n`` points, model coordinates.

    Returns
    -------
    (k,) float
        The mean distance of each batch (the paper's error (1) divided by ``n``); for a
        model seen through a ball-tipped probe, the distance to the offset surface
        (``|signed distance - R|``, signed by the closest face's normal).
    """
    k, n, _ = points.shape
    return point_distances(model, points.reshape(-1, 3)).reshape(k, n).mean(axis=1)
