"""The open patches z = g(x, y) of the paper's surfaces: their parametrisation and domains."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from shapes.params import PARABOLOID_AB

__all__ = [
    "GraphPatch",
    "crossed_trough_patch",
    "monkey_saddle_patch",
    "paraboloid_patch",
    "square_outline",
    "square_patch",
]


@dataclass(frozen=True)
class GraphPatch:
    """An open surface patch ``z = g(x, y)`` over a convex domain of the xy-plane.

    Attributes
    ----------
    height : callable
        ``g(x, y)``.
    slope : callable
        ``(dg/dx, dg/dy)`` at ``(x, y)``.
    outline : callable
        ``() -> list of (k, 2) float ndarray``: densely sampled polylines that together go
        once counter-clockwise around the domain, each starting where the previous one ends
        (the end points, e.g. the corners of a square, are kept as mesh vertices).
    inside : callable
        ``(k, 2) -> (k,) bool``, strictly inside the domain.
    snap : callable
        Moves ``(k, 2)`` points near the outline onto it.
    box : tuple of float
        ``(xmin, xmax, ymin, ymax)`` of the domain.
    """

    height: Callable
    slope: Callable
    outline: Callable
    inside: Callable
    snap: Callable
    box: tuple

    def lift(self, xy):
        """Points ``(x, y, g(x, y))`` of the surface above ``(k, 2)`` points ``xy``."""
        return np.column_stack([xy[:, 0], xy[:, 1], self.height(xy[:, 0], xy[:, 1])])

    def project(self, xyz):
        """Vertical projection of ``(k, 3)`` points onto the surface."""
        return self.lift(xyz[:, :2])

    def normal(self, xyz):
        """Upward unit normals at the surface points above ``(k, 3)`` points."""
        gx, gy = self.slope(xyz[:, 0], xyz[:, 1])
        n = np.column_stack([-gx, -gy, np.ones_like(gx)])
        return n / np.linalg.norm(n, axis=1)[:, None]

    def area_element(self, xy):
        """Surface area per unit area of the xy-plane, ``sqrt(1 + |grad g|^2)``."""
        gx, gy = self.slope(xy[:, 0], xy[:, 1])
        return np.sqrt(1.0 + gx**2 + gy**2)


def square_outline():
    """Counter-clockwise sides of the square [-1, 1]^2, densely sampled, corners included."""
    s = np.linspace(-1.0, 1.0, 4001)
    one = np.ones_like(s)
    return [
        np.column_stack([s, -one]),
        np.column_stack([one, s]),
        np.column_stack([-s, one]),
        np.column_stack([-one, -s]),
    ]


def square_patch(height, slope):
    """A ``GraphPatch`` over the square [-1, 1]^2."""
    return GraphPatch(
        height=height,
        slope=slope,
        outline=square_outline,
        inside=lambda xy: np.abs(xy).max(axis=1) < 1.0,
        snap=lambda xy: np.clip(xy, -1.0, 1.0),
        box=(-1.0, 1.0, -1.0, 1.0),
    )


def paraboloid_patch():
    """The elliptic paraboloid over the elliptic disc x^2/a^2 + y^2/b^2 <= 1."""
    a, b = PARABOLOID_AB

    def snap(xy):
        r = np.sqrt((xy[:, 0] / a) ** 2 + (xy[:, 1] / b) ** 2)
        return xy / r[:, None]

    def outline():
        t = np.linspace(0.0, 2.0 * np.pi, 20_001)
        return [np.column_stack([a * np.cos(t), b * np.sin(t)])]

    return GraphPatch(
        height=lambda x, y: (x / a) ** 2 + (y / b) ** 2,
        slope=lambda x, y: (2.0 * x / a**2, 2.0 * y / b**2),
        outline=outline,
        inside=lambda xy: (xy[:, 0] / a) ** 2 + (xy[:, 1] / b) ** 2 < 1.0,
        snap=snap,
        box=(-a, a, -b, b),
    )


def monkey_saddle_patch():
    """The monkey saddle z = x^3 - 3 x y^2 over [-1, 1]^2."""
    return square_patch(
        lambda x, y: x**3 - 3.0 * x * y**2,
        lambda x, y: (3.0 * x**2 - 3.0 * y**2, -6.0 * x * y),
    )


def crossed_trough_patch():
    """The crossed trough z = x^2 y^2 over [-1, 1]^2."""
    return square_patch(
        lambda x, y: x**2 * y**2,
        lambda x, y: (2.0 * x * y**2, 2.0 * x**2 * y),
    )

