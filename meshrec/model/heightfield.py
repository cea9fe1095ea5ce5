"""Local height-fields: a surface near a point as a polynomial z = f(x, y) in its tangent
frame, fitted to oriented surface samples, and evaluated for many fields at once.

A library-wide screen (:mod:`meshrec.recognition.screen`) needs the distance of the same
data points, rotated by the same angles, to the surface near tens of thousands of
candidate contacts. Near a contact a smooth surface is the graph of a function over its
tangent plane; a polynomial of degree 3-4 fitted over the curves' reach holds its shape to
a fraction of the noise, and with every field's coefficients in one matrix the heights of
all data points over all fields are one matrix product (BLAS), instead of one
closest-point query per candidate and angle. This is written here because neither libigl
nor trimesh fits batches of local polynomial patches; the fit is ordinary weighted least
squares (numpy), on the heights of neighbouring samples and on the slopes their normals
give.
"""

from __future__ import annotations

import numpy as np

from meshrec.io.checks import check_int, check_number

__all__ = [
    "fit_heightfields",
    "heightfield_distances",
    "heightfield_gaps",
    "monomial_exponents",
    "monomials",
]


def monomial_exponents(degree: int) -> np.ndarray:
    """The exponents ``(i, j)`` of the monomials ``x^i y^j`` with ``i + j <= degree``.

    Parameters
    ----------
    degree : int
        At least 1.

    Returns
    -------
    (m, 2) int64
        ``m = (degree + 1) (degree + 2) / 2``, by total degree, then by falling ``i``.

    Raises
    ------
    ValueError
        If ``degree`` is not an integer >= 1.
    """
    degree = check_int(degree, "degree", minimum=1)
    return np.array([(d - j, j) for d in range(degree + 1) for j in range(d + 1)], dtype=np.int64)


def monomials(xy: np.ndarray, degree: int, derivative: int | None = None) -> np.ndarray:
    """The monomials (or their derivatives) at points of the plane.

    Parameters
    ----------
    xy : (..., 2) float
    degree : int
    derivative : {None, 0, 1}
        None: ``x^i y^j``; 0: its derivative in x; 1: in y.

    Returns
    -------
    (..., m) float64

    Raises
    ------
    ValueError
        If ``xy``'s last axis is not of length 2, ``degree`` is not an integer >= 1 or
        ``derivative`` not None, 0 or 1.
    """
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim < 1 or xy.shape[-1] != 2:
        raise ValueError(f"xy must have a last axis of length 2, got shape {xy.shape}")
    if derivative not in (None, 0, 1):
        raise ValueError(f"derivative must be None, 0 or 1, got {derivative!r}")
    return np.stack(_columns(xy, degree, derivative), axis=-1)


def _columns(xy: np.ndarray, degree: int, derivative: int | None) -> list[np.ndarray]:
    """The monomials (or derivatives) of :func:`monomials`, one array per monomial."""
    x, y = xy[..., 0], xy[..., 1]
    px, py = [np.ones_like(x)], [np.ones_like(y)]
    for _ in range(degree):
        px.append(px[-1] * x)
        py.append(py[-1] * y)
    zero = np.zeros_like(x)
    out = []
    for i, j in monomial_exponents(degree).tolist():
        if derivative is None:
            out.append(px[i] * py[j])
        elif derivative == 0:
            out.append(i * px[i - 1] * py[j] if i > 0 else zero)
        else:
            out.append(j * px[i] * py[j - 1] if j > 0 else zero)
    return out


def fit_heightfields(
    centers: np.ndarray,
    frames: np.ndarray,
    points: np.ndarray,
    normals: np.ndarray,
    radius: float,
    degree: int = 4,
    slope_weight: float = 1.0,
    ridge: float = 1e-8,
) -> np.ndarray:
    """Fit one height-field per center to its neighbouring oriented samples.

    In each center's frame (columns: two tangents and the normal) a neighbour ``q`` at
    local ``(x, y, z)`` gives the equation ``f(x, y) = z`` and its normal ``(a, b, c)``
    (``c > 0``) the two slopes ``df/dx = -a / c``, ``df/dy = -b / c``; samples whose
    normal leans more than 60 degrees from the center's (the other side of a thin part,
    a crease) are left out. ``f`` is fitted in coordinates scaled by ``radius``.

    Parameters
    ----------
    centers : (c, 3) float
        The fields' origins, model coordinates.
    frames : (c, 3, 3) float
        Orthonormal frames, columns (t1, t2, n).
    points : (c, k, 3) float
        Each center's neighbouring samples, model coordinates.
    normals : (c, k, 3) float
        Their unit normals.
    radius : float
        The reach of the fields (> 0): coordinates are scaled by it.
    degree : int
        Degree of the polynomial (>= 1).
    slope_weight : float
        Weight of a slope equation against a height equation (>= 0).
    ridge : float
        Tikhonov regularisation of the normal equations (>= 0), relative to their trace.

    Returns
    -------
    (c, m) float64
        The coefficients of ``g`` with ``f(x, y) = radius * g(x / radius, y / radius)``,
        in the order of :func:`monomial_exponents`.

    Raises
    ------
    ValueError
        If the shapes do not agree, ``radius`` is not positive and finite, or
        ``slope_weight`` or ``ridge`` is negative.
    """
    centers = np.asarray(centers, dtype=np.float64)
    frames = np.asarray(frames, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    c = len(centers)
    if centers.shape != (c, 3):
        raise ValueError(f"centers must be (c, 3), got shape {centers.shape}")
    if frames.shape != (c, 3, 3):
        raise ValueError(f"frames must be ({c}, 3, 3), got shape {frames.shape}")
    if points.ndim != 3 or points.shape[0] != c or points.shape[2] != 3:
        raise ValueError(f"points must be ({c}, k, 3), got shape {points.shape}")
    if normals.shape != points.shape:
        raise ValueError(f"normals must be of shape {points.shape}, got {normals.shape}")
    radius = check_number(radius, "radius")
    if not radius > 0:
        raise ValueError(f"radius must be positive, got {radius!r}")
    slope_weight = check_number(slope_weight, "slope_weight", minimum=0.0)
    ridge = check_number(ridge, "ridge", minimum=0.0)
    local = np.einsum("ckj,cji->cki", points - centers[:, None, :], frames) / radius
    nl = np.einsum("ckj,cji->cki", normals, frames)
    use = nl[..., 2] > 0.5  # within 60 degrees of the center's normal
    nz = np.where(use, nl[..., 2], 1.0)
    w = use.astype(np.float64)
    xy = local[..., :2]
    sw = np.sqrt(w)
    ss = sw * np.sqrt(slope_weight)
    # One weighted design of the heights' and the slopes' equations, (c, m, 3k), filled
    # a monomial at a time (contiguous rows: the products below stay in cache).
    k = xy.shape[1]
    m = len(monomial_exponents(degree))
    D = np.empty((c, m, 3 * k))
    for part, (weight, d) in enumerate(((sw, None), (ss, 0), (ss, 1))):
        for col, values in enumerate(_columns(xy, degree, d)):
            D[:, col, part * k : (part + 1) * k] = weight * values
    rhs = np.concatenate([sw * local[..., 2], ss * -nl[..., 0] / nz, ss * -nl[..., 1] / nz], axis=1)
    A = np.matmul(D, D.transpose(0, 2, 1))
    b = np.einsum("cmk,ck->cm", D, rhs)
    tr = np.trace(A, axis1=1, axis2=2)[:, None, None]
    A += (ridge * tr + 1e-300) * np.eye(m)
    return np.linalg.solve(A, b[..., None])[..., 0]


#: Points per block of the batched products (see heightfield_distances).
_BLOCK = 256


def heightfield_distances(
    coefficients: np.ndarray,
    local_points: np.ndarray,
    radius: float,
    degree: int = 4,
    slopes: bool = True,
) -> np.ndarray:
    """Distances of data points to many height-fields, the fields' heights in one product.

    Each distance is the vertical gap to the graph divided by ``sqrt(1 + |grad f|^2)``:
    the distance to the graph's tangent plane below the point, which is the normal
    distance to first order.

    Parameters
    ----------
    coefficients : (c, m) float
        From :func:`fit_heightfields` (same ``radius`` and ``degree``).
    local_points : (p, 3) float
        Data points in the fields' (common) local frame, e.g. every data point at every
        angle: the same for all fields.
    radius : float
        The fields' reach (> 0).
    degree : int
    slopes : bool
        Divide by ``sqrt(1 + |grad f|^2)`` (False: the vertical gap, an upper bound of
        the distance to the tangent plane, at a third of the cost).

    Returns
    -------
    (p, c) float64
        Distance of each point to each field, model units.

    Raises
    ------
    ValueError
        If the shapes do not agree with ``degree`` or ``radius`` is not positive.
    """
    coefficients, local_points, radius = _checked(coefficients, local_points, radius, degree)
    s = local_points / radius
    G = coefficients.T
    out = np.empty((len(s), G.shape[1]))
    # In blocks of points: each product then stays below OpenBLAS's threshold for
    # threading, whose idle threads spin on the other core after every call (measured on
    # 1,296 points x 100 fields: the same wall time, twice the CPU time; in blocks of 256
    # points, the CPU time equals the wall time).
    for a in range(0, len(s), _BLOCK):
        b = s[a : a + _BLOCK]
        gap = np.abs(b[:, 2:3] - monomials(b[:, :2], degree) @ G)
        if slopes:
            gx = monomials(b[:, :2], degree, 0) @ G
            gy = monomials(b[:, :2], degree, 1) @ G
            gap /= np.sqrt(1.0 + gx * gx + gy * gy)
        out[a : a + _BLOCK] = gap
    out *= radius
    return out


def heightfield_gaps(
    coefficients: np.ndarray, local_points: np.ndarray, radius: float, degree: int = 4
) -> np.ndarray:
    """Signed vertical gaps ``z - f(x, y)`` of data points over many height-fields.

    Parameters
    ----------
    coefficients : (c, m) float
        From :func:`fit_heightfields` (same ``radius`` and ``degree``).
    local_points : (p, 3) float
        Data points in the fields' (common) local frame.
    radius : float
        The fields' reach (> 0).
    degree : int

    Returns
    -------
    (p, c) float64
        Model units.

    Raises
    ------
    ValueError
        If the shapes do not agree with ``degree`` or ``radius`` is not positive.
    """
    coefficients, local_points, radius = _checked(coefficients, local_points, radius, degree)
    s = local_points / radius
    return radius * (s[:, 2:3] - monomials(s[:, :2], degree) @ coefficients.T)


def _checked(coefficients, local_points, radius, degree: int):
    """The arguments of :func:`heightfield_distances` and :func:`heightfield_gaps` as
    float64 arrays and a float, checked against each other."""
    coefficients = np.asarray(coefficients, dtype=np.float64)
    local_points = np.asarray(local_points, dtype=np.float64)
    m = len(monomial_exponents(degree))
    if coefficients.ndim != 2 or coefficients.shape[1] != m:
        raise ValueError(f"coefficients must be (c, {m}), got shape {coefficients.shape}")
    if local_points.ndim != 2 or local_points.shape[1] != 3:
        raise ValueError(f"local_points must be (p, 3), got shape {local_points.shape}")
    radius = check_number(radius, "radius")
    if not radius > 0:
        raise ValueError(f"radius must be positive, got {radius!r}")
    return coefficients, local_points, radius
