"""Surface charts of a mesh: the (u, v) parametrisation used by the local search.

A mesh has no global parametrisation sigma(u, v) like the paper's surfaces, so the local
search works on charts: around a point q0 on the mesh with tangent frame (d1, d2, n),

    q(u, v) = closest point on the mesh to q0 + u d1 + v d2,

with the normal at q(u, v) interpolated from the vertex normals (continuous across faces)
and the tangent frame transported by projecting d1 onto the new tangent plane. A chart is
valid while (u, v) stays well inside the local radius of curvature; the search re-centres
a new chart at its current point after each solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from meshrec._values import ValueEquality

__all__ = ["SurfaceChart", "SurfacePoint", "rotation_z", "tangent_frame"]


@dataclass(frozen=True, eq=False)
class SurfacePoint(ValueEquality):
    """A point on the model with its tangent frame.

    Attributes
    ----------
    point : (3,) float
        Position on the mesh surface, model coordinates.
    frame : (3, 3) float
        Columns d1, d2, n: an orthonormal right-handed frame, n the surface normal.
    """

    point: np.ndarray
    frame: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        """(3,) float: the unit surface normal."""
        return self.frame[:, 2]


def tangent_frame(normal: np.ndarray, hint: np.ndarray | None = None) -> np.ndarray:
    """Build an orthonormal right-handed frame (d1, d2, n) around a normal.

    Parameters
    ----------
    normal : (3,) float
        Unit normal, the frame's third column.
    hint : (3,) float, optional
        A direction for d1; it is projected onto the tangent plane. When absent or
        (nearly) parallel to the normal, the world axis least aligned with it is used.

    Returns
    -------
    (3, 3) float
    """
    # Written out for 3-vectors (this runs at every chart evaluation of the searches):
    # the same operations as np.linalg.norm and np.cross, so the same bits, at a quarter
    # of the Python overhead (measured: tangent_frame 9% of a recognition's time before).
    n = normal / _norm3(normal)
    d1 = None
    if hint is not None:
        d1 = hint - np.dot(hint, n) * n
        if _norm3(d1) < 1e-8 * max(1.0, _norm3(hint)):
            d1 = None
    if d1 is None:
        axis = np.eye(3)[int(np.argmin(np.abs(n)))]
        d1 = axis - np.dot(axis, n) * n
    d1 = d1 / _norm3(d1)
    n0, n1, n2 = n.tolist()
    e0, e1, e2 = d1.tolist()
    out = np.empty((3, 3))
    out[:, 0] = d1
    out[:, 1] = (n1 * e2 - n2 * e1, n2 * e0 - n0 * e2, n0 * e1 - n1 * e0)
    out[:, 2] = n
    return out


def _norm3(x: np.ndarray) -> float:
    """Euclidean norm of a (3,) vector (np.linalg.norm's own formula for 1-D input)."""
    return math.sqrt(float(x.dot(x)))


def rotation_z(phi) -> np.ndarray:
    """Rotation(s) by ``phi`` about the z axis.

    Parameters
    ----------
    phi : float or (k,) float

    Returns
    -------
    (3, 3) float, or (k, 3, 3) float for an array of angles.
    """
    if isinstance(phi, (float, int, np.floating)) or np.ndim(phi) == 0:
        # One angle (the searches' case): the same ufuncs, without the stacking.
        phi = np.float64(phi)
        c, s = float(np.cos(phi)), float(np.sin(phi))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    phi = np.asarray(phi, dtype=np.float64)
    c, s = np.cos(phi), np.sin(phi)
    zero, one = np.zeros_like(phi), np.ones_like(phi)
    R = np.stack(
        [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )
    return R


class SurfaceChart:
    """A chart of the mesh around ``origin``: (u, v) -> a point with a transported frame.

    Parameters
    ----------
    model : ModelIndex
        The mesh (its closest-point queries and interpolated normals).
    origin : SurfacePoint
        The chart's centre q0 and its frame (d1, d2, n).
    """

    def __init__(self, model, origin: SurfacePoint):
        self.model = model
        self.origin = origin

    def at(self, u: float, v: float) -> SurfacePoint:
        """The surface point at chart coordinates (u, v), model units.

        Returns
        -------
        SurfacePoint
        """
        d1, d2, n0 = self.origin.frame.T
        x = self.origin.point + u * d1 + v * d2
        _, closest, face = self.model.surface.closest_points(x[None, :])
        n = self.model.surface.interpolated_normals(closest, face)[0]
        if np.dot(n, n0) < 0.0:
            # A fold of the mesh within the chart: keep the side we started on.
            n = -n
        return SurfacePoint(point=closest[0], frame=tangent_frame(n, hint=d1))

    def at_many(self, uv: np.ndarray) -> list[SurfacePoint]:
        """:meth:`at` of several chart coordinates, in one closest-point query.

        Each point's answer is :meth:`at`'s, to the bit (the query and the normals are
        row by row; ``tests/test_chart.py`` checks): the search's Jacobian asks two
        points at a time, and a query's Python costs about what its two points do.

        Parameters
        ----------
        uv : (k, 2) float
            Chart coordinates, model units.

        Returns
        -------
        list of SurfacePoint
            One per row of ``uv``.

        Raises
        ------
        ValueError
            If ``uv`` is not a (k, 2) array, or not finite (the query's own check).
        """
        uv = np.asarray(uv, dtype=np.float64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise ValueError(f"uv must have shape (k, 2), got {uv.shape}")
        d1, d2, n0 = self.origin.frame.T
        x = self.origin.point + uv[:, :1] * d1 + uv[:, 1:] * d2
        _, closest, face = self.model.surface.closest_points(x)
        normals = self.model.surface.interpolated_normals(closest, face)
        out = []
        for point, n in zip(closest, normals, strict=True):
            if np.dot(n, n0) < 0.0:
                n = -n  # a fold of the mesh within the chart, as in at()
            out.append(SurfacePoint(point=point, frame=tangent_frame(n, hint=d1)))
        return out
