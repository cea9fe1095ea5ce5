"""The paper's surfaces (Table 1) as analytic shapes: implicit forms and symmetry groups.

The bundled model library ``surfaces`` holds meshes of these shapes. A symmetric shape has
several equally good answers: a registration that lands on a symmetric copy of the true
contact is right, so localisation errors are measured modulo the shape's rotations.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec.io.checks import check_choice, check_points, check_vector

__all__ = ["PAPER_SURFACES", "implicit_distance", "localisation_error", "symmetry_rotations"]

#: The four surfaces of the paper's Table 1 with the parameters of its simulation.
PAPER_SURFACES = ("ellipsoid", "elliptic_paraboloid", "monkey_saddle", "crossed_trough")


def _rot(axis: str, degrees: float) -> np.ndarray:
    return Rotation.from_euler(axis, degrees, degrees=True).as_matrix()


def symmetry_rotations(name: str) -> np.ndarray:
    """The rotations that map a paper surface onto itself.

    Parameters
    ----------
    name : str
        One of :data:`PAPER_SURFACES`.

    Returns
    -------
    (g, 3, 3) float
        ellipsoid: the identity and 180 degrees about x, y and z; elliptic paraboloid:
        the identity and 180 degrees about z; monkey saddle: 0, 120 and 240 degrees about
        z, each also composed with 180 degrees about y; crossed trough: multiples of 90
        degrees about z.

    Raises
    ------
    TypeError
        If ``name`` is not a string.
    ValueError
        If ``name`` is not a paper surface.
    """
    check_choice(name, PAPER_SURFACES, "name")
    eye = np.eye(3)
    if name == "ellipsoid":
        group = [eye, _rot("x", 180), _rot("y", 180), _rot("z", 180)]
    elif name == "elliptic_paraboloid":
        group = [eye, _rot("z", 180)]
    elif name == "monkey_saddle":
        turns = [_rot("z", a) for a in (0, 120, 240)]
        group = turns + [t @ _rot("y", 180) for t in turns]
    else:  # crossed_trough
        group = [_rot("z", a) for a in (0, 90, 180, 270)]
    return np.array(group)


def implicit_distance(name: str, points: np.ndarray) -> np.ndarray:
    """First-order distance |f| / |grad f| from points to a paper surface (the paper's (1)).

    Parameters
    ----------
    name : str
        One of :data:`PAPER_SURFACES`.
    points : (n, 3) float

    Returns
    -------
    (n,) float

    Raises
    ------
    TypeError
        If ``name`` is not a string or ``points`` not real numbers.
    ValueError
        If ``name`` is not a paper surface or ``points`` is not finite (n, 3).
    """
    check_choice(name, PAPER_SURFACES, "name")
    x, y, z = check_points(points, "points").T
    if name == "ellipsoid":
        a, b, c = 1.0, 0.8, 0.5
        f = x**2 / a**2 + y**2 / b**2 + z**2 / c**2 - 1
        g = np.stack([2 * x / a**2, 2 * y / b**2, 2 * z / c**2], 1)
    elif name == "elliptic_paraboloid":
        a, b = 1.5, 1.1
        f = x**2 / a**2 + y**2 / b**2 - z
        g = np.stack([2 * x / a**2, 2 * y / b**2, -np.ones_like(z)], 1)
    elif name == "monkey_saddle":
        f = x**3 - 3 * x * y**2 - z
        g = np.stack([3 * x**2 - 3 * y**2, -6 * x * y, -np.ones_like(z)], 1)
    else:  # crossed_trough
        f = x**2 * y**2 - z
        g = np.stack([2 * x * y**2, 2 * x**2 * y, -np.ones_like(z)], 1)
    return np.abs(f) / np.linalg.norm(g, axis=1)


def localisation_error(name: str, true_contact: np.ndarray, found_contact: np.ndarray) -> float:
    """Distance ||p - p*|| between true and found contacts, modulo the shape's symmetries.

    Parameters
    ----------
    name : str
        One of :data:`PAPER_SURFACES`.
    true_contact, found_contact : (3,) float
        Model coordinates.

    Returns
    -------
    float
        The smallest distance from ``found_contact`` to a symmetric copy of
        ``true_contact``.

    Raises
    ------
    TypeError
        If ``name`` is not a string or a contact not real numbers.
    ValueError
        If ``name`` is not a paper surface or a contact is not a finite (3,) vector.
    """
    true_contact = check_vector(true_contact, "true_contact")
    found_contact = check_vector(found_contact, "found_contact")
    copies = symmetry_rotations(name) @ true_contact
    return float(np.linalg.norm(copies - found_contact, axis=1).min())
