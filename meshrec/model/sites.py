"""Curvature sites: the smooth surface a mesh approximates, sampled independently of its
triangles (issue 13, items 1 and 3).

A per-vertex curvature table describes where a mesh's vertices happen to lie: a cylinder
exported with 32 sections has every vertex on its two rims, none on the side wall. The
sites are instead spread evenly over the surface (uniform samples thinned by Poisson-disk
dart throwing, :mod:`meshrec.model.thinning`) at a spacing tied to the model's size,
lifted onto the smooth surface the vertex normals imply
(:meth:`meshrec.model.surface.AabbSurface.smooth_offsets`),
and their curvature is that of the smooth normal field: the normals are blended from
per-corner normals that average only faces within the crease angle (libigl's
``per_corner_normals``), so a box keeps its faces flat and a cylinder's side keeps its
radial normals.

Sharp feature edges (adjacent faces' normals further apart than the crease angle) split
the surface into smooth *patches*; each face carries its patch label. Curvature and its
neighbourhood range are measured within one patch. Points along the sharp edges become
*crease sites*, holding both faces' normals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import igl
import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from meshrec import defaults
from meshrec._lazy import trimesh_module
from meshrec.model.mesh import MeshData
from meshrec.model.surface import corner_normals
from meshrec.model.thinning import poisson_disk_thin

if TYPE_CHECKING:  # for the annotations only: trimesh is imported on first use
    import trimesh

__all__ = ["SiteSample", "sample_sites"]


@dataclass(frozen=True)
class SiteSample:
    """The sites of one mesh and their curvature (the raw arrays of a curvature table).

    Attributes
    ----------
    points : (n, 3) float64
        Sites on the smooth surface, model coordinates.
    normals : (n, 3) float64
        Unit normals (for a crease site: the bisector of its two faces' normals).
    normals2 : (n, 3) float64
        A crease site's two face normals are ``normals2`` and its mirror about
        ``normals``; equal to ``normals`` for a smooth site.
    k1, k2 : (n,) float64
        Principal curvatures, ``k1 >= k2``; NaN where ``valid`` is False.
    dir1, dir2 : (n, 3) float64
        Principal directions (for a crease site: across the edge and along it).
    valid : (n,) bool
    K_range, H_range : (n, 2) float64
        Lowest and highest K and H over the site's neighbourhood in its patch.
    crease : (n,) bool
        Crease sites.
    face_patch : (m,) int64
        The smooth patch of each mesh face.
    """

    points: np.ndarray
    normals: np.ndarray
    normals2: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    dir1: np.ndarray
    dir2: np.ndarray
    valid: np.ndarray
    K_range: np.ndarray
    H_range: np.ndarray
    crease: np.ndarray
    face_patch: np.ndarray


def sample_sites(
    mesh: MeshData,
    surface,
    spacing: float,
    radius: float,
    range_radius: float,
    crease_angle_deg: float,
    rng: np.random.Generator | int | None = 0,
) -> SiteSample:
    """Sample a mesh's smooth surface and estimate the curvature at the samples.

    Parameters
    ----------
    mesh : MeshData
    surface : AabbSurface
        The mesh's surface queries (its smooth offsets lift the sites off the faces).
    spacing : float
        Distance between sites, model units (> 0).
    radius : float
        Radius of the neighbourhood the curvature is fitted over, model units (> 0).
    range_radius : float
        Radius of the neighbourhood whose curvatures make a site's range (>= 0).
    crease_angle_deg : float
        Adjacent faces whose normals differ by more than this are a sharp edge.
    rng : numpy.random.Generator or int or None
        Randomness of the sampling (default: seed 0, so an index is reproducible).

    Returns
    -------
    SiteSample

    Raises
    ------
    ValueError
        If a length is not finite and positive (``range_radius``: non-negative) or the
        crease angle is not in (0, 180].
    """
    for name, value, low in (("spacing", spacing, 0.0), ("radius", radius, 0.0)):
        if not (math.isfinite(value) and value > low):
            raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    if not (math.isfinite(range_radius) and range_radius >= 0):
        raise ValueError(f"range_radius must be finite and >= 0, got {range_radius!r}")
    if not 0 < crease_angle_deg <= 180:
        raise ValueError(f"crease_angle_deg must be in (0, 180] degrees, got {crease_angle_deg!r}")
    rng = np.random.default_rng(rng)
    # Everything in units of the model's size (trimesh's and libigl's tolerances are
    # absolute), back to model units at the end.
    unit = mesh.scale
    V, F = mesh.vertices / unit, mesh.faces
    spacing, radius, range_radius = spacing / unit, radius / unit, range_radius / unit
    trimesh = trimesh_module()
    tm = trimesh.Trimesh(V, F, process=False, validate=False)
    face_patch, sharp = _patches(tm, crease_angle_deg)

    # Smooth sites: Poisson-disk samples, lifted onto the smooth surface.
    area = float(tm.area)
    # Uniform samples, thinned by dart throwing to SITE_THINNING_FACTOR spacings apart
    # (about 0.27 sites per spacing^2, as trimesh's sample_surface_even kept before).
    count = max(math.ceil(defaults.SITE_CANDIDATES_PER_SPACING2 * area / spacing**2), 48)
    seed = int(rng.integers(2**31))
    pts, face = trimesh.sample.sample_surface(tm, count, seed=seed)
    pts = np.asarray(pts, dtype=np.float64)
    keep = poisson_disk_thin(pts, defaults.SITE_THINNING_FACTOR * spacing, rng)
    pts, face = pts[keep], np.asarray(face, dtype=np.int64)[keep]
    ok = mesh.face_normals[face].any(axis=1) if len(face) else np.zeros(0, bool)
    pts, face = pts[ok], face[ok]
    if crease_angle_deg == defaults.SITE_CREASE_ANGLE_DEG:
        corner = corner_normals(mesh)  # the same, computed once per mesh
    else:
        corner = igl.per_corner_normals(V, F, float(crease_angle_deg)).reshape(-1, 3, 3)
    w = _barycentric(V, F, pts, face)
    blended = np.einsum("ni,nij->nj", w, corner[face])
    # corner normals that cancel (a fold) leave no normal: no site there
    ok = np.linalg.norm(blended, axis=1) > _FOLD
    pts, face, normals = pts[ok], face[ok], _unit(blended[ok])
    lift = surface.smooth_offsets(pts * unit, face) / unit
    pts = pts + lift[:, None] * mesh.face_normals[face]
    patch = face_patch[face]
    # One KD-tree query serves the curvature fits and the ranges (the larger radius).
    pairs, dist = _close_pairs(pts, patch, max(radius, range_radius))
    near = dist <= radius
    k1, k2, dir1, dir2, valid = _shape_operator(pts, normals, pairs[near], dist[near], radius)

    # Crease sites along the sharp edges.
    cp, cn, cn2, cd1, cd2, ck1 = _crease_sites(tm, sharp, spacing, radius)

    points = np.vstack([pts, cp])
    n_smooth = len(pts)
    crease = np.zeros(len(points), dtype=bool)
    crease[n_smooth:] = True
    # Curvatures in model units from here on (the ranges hold the table's own K and H).
    k1_all = np.concatenate([k1, np.maximum(ck1, 0.0)]) / unit
    k2_all = np.concatenate([k2, np.minimum(ck1, 0.0)]) / unit
    K = k1_all * k2_all
    H = 0.5 * (k1_all + k2_all)
    valid_all = np.concatenate([valid, np.ones(len(cp), dtype=bool)])
    in_range = dist <= range_radius
    K_range, H_range = _ranges(K, H, pairs[in_range], valid_all & ~crease, range_radius)
    # A crease's curvature, as curves across it report it, depends on where they cross
    # it and how long they are: any curvature bending its way, with K about 0.
    sign = np.sign(ck1)
    K_range[n_smooth:] = 0.0
    H_range[n_smooth:] = np.column_stack(
        [np.where(sign > 0, 0.0, -np.inf), np.where(sign > 0, np.inf, 0.0)]
    )
    return SiteSample(
        points=points * unit,
        normals=np.vstack([normals, cn]),
        normals2=np.vstack([normals, cn2]),
        k1=k1_all,
        k2=k2_all,
        dir1=np.vstack([dir1, cd1]),
        dir2=np.vstack([dir2, cd2]),
        valid=valid_all,
        K_range=K_range,
        H_range=H_range,
        crease=crease,
        face_patch=face_patch,
    )


#: Normals that sum (or blend, with weights summing to 1) to less than this length cancel:
#: a fold of the mesh, its faces back to back (within 2e-4 degrees), where a site has no
#: normal.
_FOLD = 1e-6


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.nan_to_num(v / n, nan=0.0)


def _barycentric(V, F, pts, face) -> np.ndarray:
    """Barycentric coordinates (n, 3) of points in their faces, clipped and normalised."""
    if len(face) == 0:
        return np.zeros((0, 3))
    tri = F[face]
    w = igl.barycentric_coordinates(
        np.ascontiguousarray(pts),
        np.ascontiguousarray(V[tri[:, 0]]),
        np.ascontiguousarray(V[tri[:, 1]]),
        np.ascontiguousarray(V[tri[:, 2]]),
    )
    w = np.nan_to_num(np.clip(w, 0.0, None), nan=1.0 / 3.0)
    s = w.sum(axis=1, keepdims=True)
    return np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / 3.0)


def _patches(tm: trimesh.Trimesh, crease_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Patch label per face (faces joined across smooth edges) and the sharp edges' rows
    of ``tm.face_adjacency``."""
    adj = tm.face_adjacency
    angles = tm.face_adjacency_angles
    sharp = angles > math.radians(crease_deg)
    m = len(tm.faces)
    smooth = adj[~sharp]
    graph = coo_matrix((np.ones(len(smooth)), (smooth[:, 0], smooth[:, 1])), shape=(m, m))
    _, labels = connected_components(graph, directed=False)
    return labels.astype(np.int64), np.flatnonzero(sharp)


def _close_pairs(points, patch, radius):
    """The pairs of sites (i < j) within ``radius`` of each other in the same patch, and
    their distances."""
    if len(points) < 2 or radius <= 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    tree = cKDTree(points, balanced_tree=False, compact_nodes=False)
    pairs = tree.query_pairs(radius, output_type="ndarray")
    pairs = pairs[patch[pairs[:, 0]] == patch[pairs[:, 1]]]
    dist = np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1)
    return pairs, dist


def _shape_operator(points, normals, pairs, dist, radius):
    """Principal curvatures and directions of the normal field at each site.

    Hand-written because it fits the *normal field* (dn = S dp, least squares over the
    sites within ``radius`` in the same patch, S symmetrised), not positions: libigl's
    quadric fit of vertex positions sees the flat facets of a coarse mesh, while the
    blended normals carry the smooth surface (a 32-section cylinder's side included).
    ``pairs`` (i < j) and ``dist`` are the sites within ``radius`` in the same patch.
    Sign: libigl's (a sphere with outward normals has +1/r).
    """
    n = len(points)
    k1 = np.full(n, np.nan)
    k2 = np.full(n, np.nan)
    d1 = np.zeros((n, 3))
    d2 = np.zeros((n, 3))
    valid = np.zeros(n, dtype=bool)
    if n < 3:
        return k1, k2, d1, d2, valid
    # Tangent basis at every site.
    t1 = np.cross(normals, np.where(np.abs(normals[:, [0]]) < 0.9, [1.0, 0, 0], [0, 1.0, 0]))
    t1 = _unit(t1)
    t2 = np.cross(normals, t1)
    # The normal equations per site, A = sum w x x^T and B = sum w y x^T with x and y the
    # neighbours' dp and dn in the site's tangent basis T (3 x 2): A = T^T (sum w dp dp^T) T
    # and B = T^T (sum w dn dp^T) T. Both 3 x 3 sums are the same seen from either end of
    # a pair (dp and dn both change sign), so they are summed once per pair.
    a, b = pairs[:, 0], pairs[:, 1]
    dp = points[b] - points[a]
    dn = normals[b] - normals[a]
    # Weights: closer neighbours count more (a smooth fall-off to the ball's edge).
    wgt = 1.0 - (dist / radius) ** 2
    ends = np.concatenate([a, b])
    wdp = wgt[:, None] * dp
    M = np.empty((len(pairs), 3, 6))
    M[:, :, :3] = wdp[:, :, None] * dp[:, None, :]
    M[:, :, 3:] = wdp[:, :, None] * dn[:, None, :]
    # Summed onto both ends of every pair: the (site x pair) incidence matrix times M.
    m = len(pairs)
    incidence = csr_matrix((np.ones(2 * m), (ends, np.tile(np.arange(m), 2))), shape=(n, m))
    S3 = np.asarray(incidence @ M.reshape(m, 18)).reshape(n, 3, 6)
    T = np.stack([t1, t2], axis=2)  # (n, 3, 2)
    Tt = np.swapaxes(T, 1, 2)
    A = Tt @ S3[:, :, :3] @ T
    # sum w y x^T = T^T (sum w dn dp^T) T, and S3[:, :, 3:] holds sum w dp dn^T.
    B = Tt @ np.swapaxes(S3[:, :, 3:], 1, 2) @ T
    a00, a01, a11 = A[:, 0, 0], A[:, 0, 1], A[:, 1, 1]
    count = np.bincount(ends, minlength=n)
    det = a00 * a11 - a01**2
    tr = a00 + a11
    good = (count >= 3) & (det > 1e-3 * tr**2) & (normals.any(axis=1))
    S = np.zeros((n, 2, 2))
    S[good] = B[good] @ np.linalg.inv(A[good])
    S = 0.5 * (S + np.swapaxes(S, 1, 2))
    evals, evecs = np.linalg.eigh(S)  # ascending
    k1[good] = evals[good, 1]
    k2[good] = evals[good, 0]
    e1, e2 = evecs[:, :, 1], evecs[:, :, 0]
    d1[good] = (e1[:, [0]] * t1 + e1[:, [1]] * t2)[good]
    d2[good] = (e2[:, [0]] * t1 + e2[:, [1]] * t2)[good]
    good &= np.isfinite(k1) & np.isfinite(k2)
    valid[:] = good
    k1[~good] = np.nan
    k2[~good] = np.nan
    d1[~good] = 0.0
    d2[~good] = 0.0
    return k1, k2, d1, d2, valid


def _crease_sites(tm: trimesh.Trimesh, sharp: np.ndarray, spacing: float, radius: float):
    """Sites along the sharp edges: points, bisector normals, one face normal, directions
    (across, along) and a signed nominal curvature (+ convex)."""
    empty3 = np.zeros((0, 3))
    if len(sharp) == 0:
        z = np.zeros(0)
        return empty3, empty3, empty3, empty3, empty3, z
    edges = tm.face_adjacency_edges[sharp]
    faces = tm.face_adjacency[sharp]
    convex = tm.face_adjacency_convex[sharp]
    angle = tm.face_adjacency_angles[sharp]
    a, b = tm.vertices[edges[:, 0]], tm.vertices[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    steps = np.maximum(np.ceil(length / spacing).astype(np.int64), 1)
    row = np.repeat(np.arange(len(edges)), steps)
    first = np.cumsum(steps) - steps
    t = (np.arange(len(row)) - first[row] + 0.5) / steps[row]
    points = a[row] + t[:, None] * (b - a)[row]
    fn = tm.face_normals
    n1, n2 = fn[faces[row, 0]], fn[faces[row, 1]]
    normal = _unit(n1 + n2)
    along = _unit((b - a)[row])
    across = _unit(np.cross(along, normal))
    # A fold (two faces back to back, their normals opposite: a mesh whose coordinates
    # were rounded, such as a float32 STL far from the origin) has no bisector (zero, or
    # the rounding's direction), and a zero-length edge no direction: no site there (a
    # zero normal made the lookup's frames NaN, and a black-box probe's recognition
    # raise, stop 36).
    ok = (np.linalg.norm(n1 + n2, axis=1) > _FOLD) & along.any(axis=1) & across.any(axis=1)
    sign = np.where(convex[row], 1.0, -1.0)
    k = sign * angle[row] / radius
    return points[ok], normal[ok], n1[ok], across[ok], along[ok], k[ok]


def _ranges(K, H, pairs, use, radius):
    """Lowest and highest (K, H) over each site's ``radius`` neighbourhood in its patch
    (the site's own values included), from the ``pairs`` (i < j) of sites within
    ``radius`` in the same patch; only sites in ``use`` count."""
    n = len(K)
    K_range = np.column_stack([K, K]).astype(np.float64)
    H_range = np.column_stack([H, H]).astype(np.float64)
    if radius <= 0 or n < 2:
        return K_range, H_range
    pairs = pairs[use[pairs[:, 0]] & use[pairs[:, 1]]]
    if len(pairs) == 0:
        return K_range, H_range
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    # Per site, the extremes of its neighbours' values: sorted by site, reduced per run.
    # (numpy's stable sort is a radix sort on 16-bit keys: 6 times faster here.)
    order = np.argsort(i.astype(np.uint16) if n <= 2**16 else i, kind="stable")
    i, j = i[order], j[order]
    start = np.flatnonzero(np.r_[True, i[1:] != i[:-1]])
    site = i[start]
    for values, out in ((K, K_range), (H, H_range)):
        v = values[j]
        out[site, 0] = np.minimum(out[site, 0], np.minimum.reduceat(v, start))
        out[site, 1] = np.maximum(out[site, 1], np.maximum.reduceat(v, start))
    return K_range, H_range
