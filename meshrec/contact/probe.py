"""Ball-tipped probes: the data lie on the surface offset outwards by the tip radius.

A touch probe with a ball tip of radius R records the ball's centre, which lies on the
offset surface x + R n(x) (n the outward normal), not on the surface itself. The offset
surface has the same normals and principal directions as the surface, and principal
radii larger by R where the surface is convex (positive curvature, in the sign convention
of :class:`~meshrec.contact.geometry.LocalGeometry`: positive where the surface bends away
from the outward normal) and smaller by R where it is concave:

    1 / k_centre = 1 / k_surface + R,  so  k_surface = k_centre / (1 - R k_centre).

A sphere of radius r touched with a tip of radius R gives data on a sphere of radius r + R
(k_centre = 1 / (r + R)), corrected to 1 / r. :func:`surface_geometry` applies this to the
local geometry estimated from the data (and moves the contact from the ball's centre onto
the surface, p - R n); the registration compares the data with the offset surface (the
signed distance minus R; :mod:`meshrec.model.probe`).
"""

from __future__ import annotations

import numpy as np

from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_instance, check_number

__all__ = ["ProbeOffsetWarning", "check_probe_radius", "surface_geometry"]


class ProbeOffsetWarning(UserWarning):
    """The data look taken with a ball tip whose radius recognition was not told."""


def check_probe_radius(value, name: str = "probe_radius") -> float:
    """The probe's ball-tip radius as a float: finite and >= 0 (0: a point probe).

    Parameters
    ----------
    value : int or float
    name : str
        The argument's name, for messages.

    Returns
    -------
    float

    Raises
    ------
    TypeError
        If ``value`` is not a real number.
    ValueError
        If it is negative or not finite (NaN, inf).
    """
    return check_number(value, name, minimum=0.0)


def surface_geometry(geometry: LocalGeometry, probe_radius: float) -> LocalGeometry:
    """The local geometry of the surface under ball-centre data, on the side of its normal.

    The contact moves from the ball's centre onto the surface (``point - R normal``); the
    frame is kept; each principal curvature becomes ``k / (1 - R k)``, and the normal
    curvatures of the curves are recomputed from them by Euler's formula.

    Parameters
    ----------
    geometry : LocalGeometry
        The geometry estimated from the ball-centre data, its ``normal`` taken as the
        outward normal (call it on ``geometry.flipped()`` for the other side).
    probe_radius : float
        The tip radius R, data units, >= 0.

    Returns
    -------
    LocalGeometry
        ``geometry`` itself when ``probe_radius`` is 0.

    Raises
    ------
    TypeError
        If ``geometry`` is not a LocalGeometry or ``probe_radius`` not a real number.
    ValueError
        If ``probe_radius`` is negative or not finite, or not less than the data's
        smallest radius of curvature on the convex side (``R k1 >= 1``): a ball of that
        radius cannot have traced them from this side.
    """
    check_instance(geometry, LocalGeometry, "geometry")
    R = check_probe_radius(probe_radius)
    if R == 0.0:
        return geometry
    if R * geometry.k1 >= 1.0:
        raise ValueError(
            f"probe_radius must be less than the radius of curvature of the data where they "
            f"are convex ({1.0 / geometry.k1:.6g} data units: a ball of radius R traces "
            f"radii of at least R there), got {R!r}"
        )
    k1 = geometry.k1 / (1.0 - R * geometry.k1)
    k2 = geometry.k2 / (1.0 - R * geometry.k2)
    t1 = geometry.frame[:, 0]
    t2 = geometry.frame[:, 1]
    tangents = np.asarray(geometry.tangents, dtype=np.float64)
    cos = tangents @ t1
    sin = tangents @ t2
    norm2 = np.maximum(cos * cos + sin * sin, 1e-300)
    normal_curvatures = (k1 * cos * cos + k2 * sin * sin) / norm2
    return LocalGeometry(
        point=geometry.point - R * geometry.normal,
        normal=geometry.normal.copy(),
        frame=geometry.frame.copy(),
        k1=float(k1),
        k2=float(k2),
        K=float(k1 * k2),
        H=float(0.5 * (k1 + k2)),
        tangents=tangents.copy(),
        normal_curvatures=normal_curvatures,
        fit_rms=geometry.fit_rms,
        half_length=geometry.half_length,
        condition=geometry.condition,
        noise_rms=geometry.noise_rms,
        # k / (1 - R k) stretches an error in k by 1 / (1 - R k)^2
        curvature_sd=geometry.curvature_sd
        * max(1.0 / (1.0 - R * geometry.k1) ** 2, 1.0 / (1.0 - R * geometry.k2) ** 2),
    )
