"""Generate the bundled model meshes of meshrec and measure how well they fit their shapes.

Two model libraries are written as binary STL files:

``models/surfaces/``
    The four surfaces of the paper's Table 1 (unit-sized): an ellipsoid (closed) and three
    open patches over the paper's parameter domains (elliptic paraboloid, monkey saddle,
    crossed trough).
``models/objects/``
    The four experiment objects of the paper's Figure 7, in millimetres, as closed solids:
    two circular cylinders, an elliptic cylinder (all 100 mm tall, flat caps) and a sphere.

Every mesh is then measured: face and vertex counts, mean edge length, smallest triangle
angle, and the deviation of the mesh from its analytic surface (maximum and RMS of the
first-order implicit distance ``|f| / |grad f|`` at points sampled uniformly on the mesh
faces). The table is printed and written into ``models/README.md``.

The script is deterministic: running it twice writes byte-identical files.

Usage::

    .venv/bin/python tools/make_models.py [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import Delaunay, cKDTree

_REPO = Path(__file__).resolve().parent.parent
_DEFAULT_OUT = _REPO / "models"

#: Seed of every random draw (initial points of the relaxed patches, deviation samples).
_SEED = 20240607
#: Points sampled on each mesh to measure its deviation from the analytic surface.
_N_SAMPLES = 200_000
#: Faces aimed at for the meshes whose face count is free (icospheres have 81,920).
_TARGET_FACES = 80_000

# --- the paper's shapes ---------------------------------------------------------------------
#: Ellipsoid semi-axes (Table 1, Figure 5a).
_ELLIPSOID_ABC = (1.0, 0.8, 0.5)
#: Elliptic paraboloid z = x^2/a^2 + y^2/b^2 (Figure 4), over v in [-1, 1] of the
#: parametric form (a v cos u, b v sin u, v^2), i.e. the elliptic disc x^2/a^2 + y^2/b^2 <= 1.
_PARABOLOID_AB = (1.5, 1.1)
#: Cylinder diameters (Figure 7), mm.
_CYLINDER_DIAMETERS = (50.4, 94.0)
#: Elliptic cylinder semi-axes (Figure 7), mm.
_ELLIPTIC_CYLINDER_AB = (50.8, 31.75)
#: Height of the three cylinders, mm (the paper does not give it; 100 mm is our choice).
_CYLINDER_HEIGHT = 100.0
#: Sphere radius (Figure 7), mm.
_SPHERE_RADIUS = 33.0

# --- relaxation of the open patches -----------------------------------------------------------
#: Midpoint subdivisions applied after relaxing the coarse mesh (faces grow 4x each).
_SUBDIVISIONS = 3
#: Relaxation steps on the coarse mesh, and after every subdivision.
_COARSE_STEPS = 300
_FINE_STEPS = 5
#: Step size and internal-pressure factor of the DistMesh-style edge springs.
_SPRING_STEP = 0.2
_SPRING_PRESSURE = 1.2


# =============================================================================================
# Mesh connectivity helpers
# =============================================================================================


def _directed_edges(faces):
    """Directed edges of a triangle list with the opposite corner and owning face.

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    u, v, opposite, face : (3m,) int ndarray
        Edge ``u -> v`` of triangle ``face``, whose third corner is ``opposite``.
    """
    u = faces.ravel()
    v = np.roll(faces, -1, axis=1).ravel()
    opposite = np.roll(faces, -2, axis=1).ravel()
    face = np.repeat(np.arange(len(faces)), 3)
    return u, v, opposite, face


def _reverse_index(u, v, n_vertices):
    """Index of the reverse of every directed edge, or -1 where it has none.

    Parameters
    ----------
    u, v : (k,) int ndarray
        Directed edges ``u -> v``.
    n_vertices : int
        Number of vertices (to build integer edge keys).

    Returns
    -------
    (k,) int ndarray
        ``j`` with ``(u[j], v[j]) == (v[i], u[i])``, or -1.
    """
    key = u.astype(np.int64) * n_vertices + v
    reverse = v.astype(np.int64) * n_vertices + u
    order = np.argsort(key, kind="stable")
    pos = np.clip(np.searchsorted(key[order], reverse), 0, len(key) - 1)
    found = key[order][pos] == reverse
    return np.where(found, order[pos], -1)


def _boundary_vertices(faces, n_vertices):
    """Mask of the vertices on the boundary (edges used by one face only).

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.
    n_vertices : int
        Number of vertices.

    Returns
    -------
    (n_vertices,) bool ndarray
    """
    u, v, _, _ = _directed_edges(faces)
    lonely = _reverse_index(u, v, n_vertices) < 0
    mask = np.zeros(n_vertices, dtype=bool)
    mask[u[lonely]] = True
    mask[v[lonely]] = True
    return mask


def _unique_edges(faces):
    """Undirected edges of a triangle list, each once.

    Parameters
    ----------
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    (k, 2) int ndarray
    """
    u, v, _, _ = _directed_edges(faces)
    lo = np.minimum(u, v).astype(np.int64)
    hi = np.maximum(u, v).astype(np.int64)
    n = int(hi.max()) + 1
    key = np.unique(lo * n + hi)
    return np.column_stack([key // n, key % n])


def _signed_area(xy, faces):
    """Twice the signed areas of planar triangles, positive when counter-clockwise."""
    tri = xy[faces]
    d1 = tri[:, 1] - tri[:, 0]
    d2 = tri[:, 2] - tri[:, 0]
    return d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]


def _wind_counterclockwise(xy, faces):
    """Reorder triangles of a planar triangulation to counter-clockwise winding."""
    clockwise = _signed_area(xy, faces) < 0
    faces = faces.copy()
    faces[clockwise] = faces[clockwise][:, ::-1]
    return faces


def _corner_angle(p, q, r):
    """Angle at ``p`` of the triangles ``(p, q, r)``, row by row, in radians."""
    a = q - p
    b = r - p
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def _faces_valid(xyz, faces):
    """Whether the triangles of a graph patch are counter-clockwise seen from above.

    For a patch ``z = g(x, y)`` this is exactly "not folded over" (normal towards +z).

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices.
    faces : (m, 3) int ndarray
        Triangles.

    Returns
    -------
    (m,) bool ndarray
    """
    return _signed_area(xyz[:, :2], faces) > 0.0


# =============================================================================================
# Relaxation on a smooth surface (edge flips + DistMesh-style springs)
# =============================================================================================
# trimesh has no isotropic remesher (only subdivision), so the open patches z = g(x, y) are
# relaxed here: Delaunay edge flips measured in 3D keep the triangles fat, and the repulsive
# edge springs of DistMesh (Persson & Strang 2004), moved in the tangent plane and projected
# back onto the surface, make the edges even in 3D, also where the monkey saddle is steep.
# Flips and moves that would turn a triangle clockwise in the xy-plane are refused.


def _flip_to_delaunay(xyz, faces, max_passes=50):
    """Flip interior edges until the two angles facing each edge sum to at most pi (in 3D).

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above); not modified.
    max_passes : int
        Largest number of rounds of independent flips.

    Returns
    -------
    (m, 3) int ndarray
        Flipped triangles, same winding.
    """
    faces = faces.copy()
    for _ in range(max_passes):
        u, v, opp, face = _directed_edges(faces)
        rev = _reverse_index(u, v, len(xyz))
        first = np.nonzero((rev >= 0) & (u < v))[0]
        second = rev[first]
        u, v = u[first], v[first]
        a, b = opp[first], opp[second]
        excess = (
            _corner_angle(xyz[a], xyz[u], xyz[v]) + _corner_angle(xyz[b], xyz[v], xyz[u]) - np.pi
        )
        cand = np.nonzero(excess > 1e-9)[0]
        new1 = np.column_stack([u[cand], b[cand], a[cand]])
        new2 = np.column_stack([b[cand], v[cand], a[cand]])
        ok = _faces_valid(xyz, new1) & _faces_valid(xyz, new2)
        cand, new1, new2 = cand[ok], new1[ok], new2[ok]
        if len(cand) == 0:
            break
        f1, f2 = face[first][cand], face[second][cand]
        used = np.zeros(len(faces), dtype=bool)
        for k in np.argsort(-excess[cand], kind="stable"):
            if used[f1[k]] or used[f2[k]]:
                continue
            used[f1[k]] = used[f2[k]] = True
            faces[f1[k]] = new1[k]
            faces[f2[k]] = new2[k]
    return faces


def _spring_step(xyz, faces, fixed, patch):
    """Move the free vertices one DistMesh step along the surface.

    Edges shorter than ``_SPRING_PRESSURE`` times the RMS edge length push their ends apart.
    The corner opposite a boundary edge is also pushed away from its mirror image across that
    edge, as if the mesh went on beyond the fixed boundary; otherwise the pressure flattens
    the triangles along the boundary. The push is projected on the tangent plane and the
    vertex projected back onto the surface. A vertex whose move would fold a triangle over
    stays where it is.

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices on the surface.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above).
    fixed : (n,) bool ndarray
        Vertices that must not move (the boundary).
    patch : _GraphPatch
        The surface.

    Returns
    -------
    (n, 3) float ndarray
        New vertices.
    """
    edges = _unique_edges(faces)
    vec = xyz[edges[:, 0]] - xyz[edges[:, 1]]
    length = np.linalg.norm(vec, axis=1)
    rest = _SPRING_PRESSURE * np.sqrt(np.mean(length**2))
    force = (np.maximum(rest - length, 0.0) / length)[:, None] * vec
    # boundary edges u -> v (counter-clockwise, so the mesh is on their left) and their apex w
    u, v, w, _ = _directed_edges(faces)
    lonely = _reverse_index(u, v, len(xyz)) < 0
    u, v, w = u[lonely], v[lonely], w[lonely]
    inward = np.cross(patch.normal(0.5 * (xyz[u] + xyz[v])), xyz[v] - xyz[u])
    inward /= np.linalg.norm(inward, axis=1)[:, None]
    height = np.einsum("ij,ij->i", xyz[w] - xyz[u], inward)
    wall = np.maximum(rest - 2.0 * height, 0.0)[:, None] * inward
    move = np.zeros_like(xyz)
    for k in range(3):
        move[:, k] = (
            np.bincount(edges[:, 0], force[:, k], minlength=len(xyz))
            - np.bincount(edges[:, 1], force[:, k], minlength=len(xyz))
            + np.bincount(w, wall[:, k], minlength=len(xyz))
        )
    n = patch.normal(xyz)
    move -= np.einsum("ij,ij->i", move, n)[:, None] * n
    move[fixed] = 0.0
    new = patch.project(xyz + _SPRING_STEP * move)
    was_valid = _faces_valid(xyz, faces)
    for _ in range(100):
        bad = was_valid & ~_faces_valid(new, faces)
        if not bad.any():
            break
        back = np.unique(faces[bad])
        new[back] = xyz[back]
    return new


def _relax(xyz, faces, fixed, patch, steps):
    """Alternate Delaunay flips and spring steps, ending with flips.

    Parameters
    ----------
    xyz : (n, 3) float ndarray
        Vertices on the surface.
    faces : (m, 3) int ndarray
        Counter-clockwise triangles (seen from above).
    fixed : (n,) bool ndarray
        Vertices that must not move.
    patch : _GraphPatch
        The surface.
    steps : int
        Number of spring steps.

    Returns
    -------
    xyz : (n, 3) float ndarray
    faces : (m, 3) int ndarray
    """
    for _ in range(steps):
        faces = _flip_to_delaunay(xyz, faces)
        xyz = _spring_step(xyz, faces, fixed, patch)
    return xyz, _flip_to_delaunay(xyz, faces)


# =============================================================================================
# Open patches z = g(x, y)
# =============================================================================================


@dataclass(frozen=True)
class _GraphPatch:
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


def _resample_outline(patch, spacing):
    """Points along the closed outline of a patch, evenly spaced in 3D arc length.

    Parameters
    ----------
    patch : _GraphPatch
        The patch.
    spacing : float
        Wanted 3D distance between consecutive points.

    Returns
    -------
    (k, 2) float ndarray
        Counter-clockwise xy points on the domain boundary, not repeating the first.
    """
    pieces = []
    for piece in patch.outline():
        xyz = patch.lift(piece)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
        count = max(round(s[-1] / spacing), 3)
        t = np.linspace(0.0, s[-1], count + 1)[:-1]
        pieces.append(np.column_stack([np.interp(t, s, piece[:, 0]), np.interp(t, s, piece[:, 1])]))
    return patch.snap(np.concatenate(pieces))


def _area_elements(patch, n=1001):
    """Area element of a patch at the cell centres of an ``n x n`` grid over its box.

    Parameters
    ----------
    patch : _GraphPatch
        The patch.
    n : int
        Cells per side.

    Returns
    -------
    values : (n * n,) float ndarray
        ``sqrt(1 + |grad g|^2)`` inside the domain, 0 outside.
    cell : float
        Area of a grid cell in the xy-plane.
    """
    xmin, xmax, ymin, ymax = patch.box
    x = xmin + (np.arange(n) + 0.5) * (xmax - xmin) / n
    y = ymin + (np.arange(n) + 0.5) * (ymax - ymin) / n
    xy = np.column_stack([np.repeat(x, n), np.tile(y, n)])
    cell = (xmax - xmin) * (ymax - ymin) / n**2
    return patch.area_element(xy) * patch.inside(xy), cell


def _sample_patch(patch, count, rng, batch=20_000):
    """Random points of the domain whose lift is uniform in surface area (rejection sampling).

    Parameters
    ----------
    patch : _GraphPatch
        The patch.
    count : int
        Number of points wanted.
    rng : numpy.random.Generator
        Random source.
    batch : int
        Candidates drawn per round.

    Returns
    -------
    (count, 2) float ndarray
    """
    xmin, xmax, ymin, ymax = patch.box
    top = 1.05 * float(_area_elements(patch)[0].max())  # bound of the acceptance ratio
    kept = []
    total = 0
    while total < count:
        xy = rng.uniform([xmin, ymin], [xmax, ymax], size=(batch, 2))
        take = patch.inside(xy) & (rng.uniform(0.0, top, size=batch) < patch.area_element(xy))
        kept.append(xy[take])
        total += int(take.sum())
    return np.concatenate(kept)[:count]


def _mesh_patch(patch, faces_wanted, seed):
    """Evenly sized, well-shaped triangulation of an open patch, normals pointing to +z.

    A coarse mesh (``faces_wanted / 4**_SUBDIVISIONS`` faces) of random interior points and
    evenly spaced outline points is relaxed, then subdivided at the midpoints, snapped back
    onto the outline and the surface, and relaxed a little after each subdivision.

    Parameters
    ----------
    patch : _GraphPatch
        The patch.
    faces_wanted : int
        Aimed-at number of faces.
    seed : int
        Seed of the random initial points.

    Returns
    -------
    trimesh.Trimesh
    """
    coarse_faces = faces_wanted / 4**_SUBDIVISIONS
    values, cell = _area_elements(patch)
    # edge of the equilateral triangle of mean area
    spacing = np.sqrt(4.0 * float(values.sum()) * cell / (np.sqrt(3.0) * coarse_faces))
    outline = _resample_outline(patch, spacing)
    # a triangulated disc has faces = 2 * vertices - boundary vertices - 2
    n_inner = round((coarse_faces - len(outline) + 2) / 2)
    rng = np.random.default_rng(seed)
    inner = _sample_patch(patch, 4 * n_inner, rng)
    near, _ = cKDTree(patch.lift(outline)).query(patch.lift(inner))
    inner = inner[near > 0.5 * spacing][:n_inner]
    xy = np.concatenate([outline, inner])
    faces = _wind_counterclockwise(xy, Delaunay(xy).simplices)
    # Qhull may return zero-area triangles on collinear hull points (the sides of the
    # square); without them, each side is the chain of its outline points
    faces = faces[_signed_area(xy, faces) > 1e-12 * spacing**2]
    xyz = patch.lift(xy)
    fixed = np.arange(len(xyz)) < len(outline)
    xyz, faces = _relax(xyz, faces, fixed, patch, _COARSE_STEPS)
    for _ in range(_SUBDIVISIONS):
        xyz, faces = trimesh.remesh.subdivide(xyz, faces)
        fixed = _boundary_vertices(faces, len(xyz))
        xyz[fixed, :2] = patch.snap(xyz[fixed, :2])
        xyz = patch.project(xyz)
        xyz, faces = _relax(xyz, faces, fixed, patch, _FINE_STEPS)
    return trimesh.Trimesh(xyz, faces, process=True)


def _square_outline():
    """Counter-clockwise sides of the square [-1, 1]^2, densely sampled, corners included."""
    s = np.linspace(-1.0, 1.0, 4001)
    one = np.ones_like(s)
    return [
        np.column_stack([s, -one]),
        np.column_stack([one, s]),
        np.column_stack([-s, one]),
        np.column_stack([-one, -s]),
    ]


def _square_patch(height, slope):
    """A ``_GraphPatch`` over the square [-1, 1]^2."""
    return _GraphPatch(
        height=height,
        slope=slope,
        outline=_square_outline,
        inside=lambda xy: np.abs(xy).max(axis=1) < 1.0,
        snap=lambda xy: np.clip(xy, -1.0, 1.0),
        box=(-1.0, 1.0, -1.0, 1.0),
    )


def _paraboloid_patch():
    """The elliptic paraboloid over the elliptic disc x^2/a^2 + y^2/b^2 <= 1."""
    a, b = _PARABOLOID_AB

    def snap(xy):
        r = np.sqrt((xy[:, 0] / a) ** 2 + (xy[:, 1] / b) ** 2)
        return xy / r[:, None]

    def outline():
        t = np.linspace(0.0, 2.0 * np.pi, 20_001)
        return [np.column_stack([a * np.cos(t), b * np.sin(t)])]

    return _GraphPatch(
        height=lambda x, y: (x / a) ** 2 + (y / b) ** 2,
        slope=lambda x, y: (2.0 * x / a**2, 2.0 * y / b**2),
        outline=outline,
        inside=lambda xy: (xy[:, 0] / a) ** 2 + (xy[:, 1] / b) ** 2 < 1.0,
        snap=snap,
        box=(-a, a, -b, b),
    )


def _monkey_saddle_patch():
    """The monkey saddle z = x^3 - 3 x y^2 over [-1, 1]^2."""
    return _square_patch(
        lambda x, y: x**3 - 3.0 * x * y**2,
        lambda x, y: (3.0 * x**2 - 3.0 * y**2, -6.0 * x * y),
    )


def _crossed_trough_patch():
    """The crossed trough z = x^2 y^2 over [-1, 1]^2."""
    return _square_patch(
        lambda x, y: x**2 * y**2,
        lambda x, y: (2.0 * x * y**2, 2.0 * x**2 * y),
    )


# =============================================================================================
# Closed shapes
# =============================================================================================


def _ellipsoid():
    """The ellipsoid of the paper, a subdivided icosphere scaled by its semi-axes.

    Scaling keeps every vertex exactly on the ellipsoid, avoids the slivers a (u, v) grid has
    at its poles, and leaves the triangles smallest near the ends of the long axis, where the
    ellipsoid is most curved.

    Returns
    -------
    trimesh.Trimesh
    """
    mesh = trimesh.creation.icosphere(subdivisions=6)
    mesh.apply_scale(_ELLIPSOID_ABC)
    return mesh


def _sphere():
    """The sphere of the experiment, a subdivided icosphere (radius in mm)."""
    return trimesh.creation.icosphere(subdivisions=6, radius=_SPHERE_RADIUS)


def _ellipse_ring(a, b, count, phase):
    """Points on an ellipse, evenly spaced in arc length, counter-clockwise.

    Parameters
    ----------
    a, b : float
        Semi-axes along x and y.
    count : int
        Number of points.
    phase : float
        Offset of the first point from ``(a, 0)``, in units of the spacing.

    Returns
    -------
    (count, 2) float ndarray
        Points exactly on the ellipse.
    """
    t = np.linspace(0.0, 2.0 * np.pi, 20_001)
    dense = np.column_stack([a * np.cos(t), b * np.sin(t)])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    tt = np.interp((np.arange(count) + phase) * s[-1] / count, s, t)
    return np.column_stack([a * np.cos(tt), b * np.sin(tt)])


def _ellipse_perimeter(a, b):
    """Perimeter of an ellipse (Ramanujan's second approximation, exact for a circle)."""
    h = ((a - b) / (a + b)) ** 2
    return np.pi * (a + b) * (1.0 + 3.0 * h / (10.0 + np.sqrt(4.0 - 3.0 * h)))


def _cap(rim, a, b, rings, top):
    """Flat cap of a cylinder: concentric rings inside its rim, Delaunay-triangulated.

    Parameters
    ----------
    rim : (n, 2) float ndarray
        Rim points (a row of the side), counter-clockwise.
    a, b : float
        Semi-axes of the rim ellipse.
    rings : int
        Number of ring intervals from the centre to the rim.
    top : bool
        Wind for an upward normal (top cap) or a downward one (bottom cap).

    Returns
    -------
    inner : (k, 2) float ndarray
        The cap's own points (rings and centre).
    faces : (m, 3) int ndarray
        Triangles indexing ``rim`` (indices below ``n``) then ``inner``.
    """
    inner = [np.zeros((1, 2))]
    for k in range(1, rings):
        scale = k / rings
        count = max(round(len(rim) * scale), 3)
        inner.append(_ellipse_ring(a * scale, b * scale, count, 0.5 * (k % 2)))
    inner = np.concatenate(inner[::-1])
    points = np.concatenate([rim, inner])
    tri = Delaunay(points)
    if len(tri.coplanar):
        raise RuntimeError("cap triangulation dropped points")
    faces = _wind_counterclockwise(points, tri.simplices)
    return inner, faces if top else faces[:, ::-1]


def _elliptic_prism(a, b, height, faces_wanted):
    """Closed elliptic (or circular) cylinder along z, centred at the origin, flat caps.

    The side is a lattice of rings whose points are offset by half a step on every other
    ring, so that its triangles are nearly equilateral; the caps are rings inside the rim.
    Written here because ``trimesh.creation.cylinder`` makes one band of side triangles as
    tall as the cylinder and fan caps, and has no elliptic section.

    Parameters
    ----------
    a, b : float
        Semi-axes of the section along x and y.
    height : float
        Length along z.
    faces_wanted : int
        Aimed-at number of faces.

    Returns
    -------
    trimesh.Trimesh
    """
    perimeter = _ellipse_perimeter(a, b)
    area = perimeter * height + 2.0 * np.pi * a * b
    edge = np.sqrt(4.0 * area / (np.sqrt(3.0) * faces_wanted))
    row_step = edge * np.sqrt(3.0) / 2.0
    n = round(perimeter / edge)
    rows = round(height / row_step)
    rings = max(round(np.sqrt(a * b) / row_step), 1)

    side = []
    for j in range(rows + 1):
        ring = _ellipse_ring(a, b, n, 0.5 * (j % 2))
        side.append(np.column_stack([ring, np.full(n, -height / 2.0 + j * height / rows)]))
    vertices = [np.concatenate(side)]

    i = np.arange(n)
    nxt = (i + 1) % n
    faces = []
    for j in range(rows):
        lo, up = j * n, (j + 1) * n
        if j % 2 == 0:  # the upper ring is shifted half a step ahead of the lower one
            faces += [np.column_stack([lo + i, lo + nxt, up + i])]
            faces += [np.column_stack([lo + nxt, up + nxt, up + i])]
        else:  # the lower ring is shifted half a step ahead of the upper one
            faces += [np.column_stack([lo + i, lo + nxt, up + nxt])]
            faces += [np.column_stack([lo + i, up + nxt, up + i])]

    offset = len(vertices[0])
    for first, z, top in ((0, -height / 2.0, False), (rows * n, height / 2.0, True)):
        rim = vertices[0][first : first + n, :2]
        inner, cap = _cap(rim, a, b, rings, top)
        index = np.concatenate([first + i, offset + np.arange(len(inner))])
        vertices.append(np.column_stack([inner, np.full(len(inner), z)]))
        faces.append(index[cap])
        offset += len(inner)
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=True)


# =============================================================================================
# Analytic distances (first order: |f| / |grad f|)
# =============================================================================================


def _ellipsoid_distance(points, abc):
    """First-order distance of ``(k, 3)`` points to the ellipsoid with semi-axes ``abc``."""
    abc = np.asarray(abc, dtype=float)
    f = np.sum((points / abc) ** 2, axis=1) - 1.0
    return np.abs(f) / np.linalg.norm(2.0 * points / abc**2, axis=1)


def _patch_distance(points, patch):
    """First-order distance of ``(k, 3)`` points to the graph ``z = g(x, y)`` of a patch."""
    f = points[:, 2] - patch.height(points[:, 0], points[:, 1])
    return np.abs(f) / patch.area_element(points[:, :2])


def _prism_distance(points, a, b, height):
    """First-order distance of ``(k, 3)`` points to an elliptic cylinder with flat caps.

    The smaller of the distance to the side ``x^2/a^2 + y^2/b^2 = 1`` and to the cap planes
    ``z = +-height/2``.
    """
    x, y = points[:, 0], points[:, 1]
    f = (x / a) ** 2 + (y / b) ** 2 - 1.0
    side = np.abs(f) / np.hypot(2.0 * x / a**2, 2.0 * y / b**2)
    return np.minimum(side, np.abs(np.abs(points[:, 2]) - height / 2.0))


def _sphere_distance(points, radius):
    """First-order distance of ``(k, 3)`` points to the sphere of the given radius."""
    r = np.linalg.norm(points, axis=1)
    return np.abs(r**2 - radius**2) / (2.0 * r)


# =============================================================================================
# The bundled models
# =============================================================================================


@dataclass(frozen=True)
class _Model:
    """One bundled mesh: where it goes, how it is made and measured, and what it is.

    Attributes
    ----------
    library : str
        Subfolder of the output folder (``surfaces`` or ``objects``).
    name : str
        File stem.
    build : callable
        ``() -> trimesh.Trimesh``.
    distance : callable
        First-order distance of ``(k, 3)`` points to the analytic surface.
    closed : bool
        Closed solid (watertight, outward normals) or open patch (normals towards +z).
    shape : str
        One-line description for the README.
    """

    library: str
    name: str
    build: Callable
    distance: Callable
    closed: bool
    shape: str


def _models():
    """All bundled models, in the order they are written and listed.

    Returns
    -------
    list of _Model
    """
    a, b, c = _ELLIPSOID_ABC
    pa, pb = _PARABOLOID_AB
    ea, eb = _ELLIPTIC_CYLINDER_AB
    height = _CYLINDER_HEIGHT
    paraboloid = _paraboloid_patch()
    saddle = _monkey_saddle_patch()
    trough = _crossed_trough_patch()
    models = [
        _Model(
            "surfaces",
            "ellipsoid",
            _ellipsoid,
            lambda p: _ellipsoid_distance(p, _ELLIPSOID_ABC),
            True,
            f"x²/a² + y²/b² + z²/c² = 1, a = {a:g}, b = {b:g}, c = {c:g}; closed",
        ),
        _Model(
            "surfaces",
            "elliptic_paraboloid",
            lambda: _mesh_patch(paraboloid, _TARGET_FACES, _SEED),
            lambda p: _patch_distance(p, paraboloid),
            False,
            f"z = x²/a² + y²/b², a = {pa:g}, b = {pb:g}, over the disc x²/a² + y²/b² ≤ 1 "
            "(v in [-1, 1] of the parametric form (a v cos u, b v sin u, v²)); open",
        ),
        _Model(
            "surfaces",
            "monkey_saddle",
            lambda: _mesh_patch(saddle, _TARGET_FACES, _SEED + 1),
            lambda p: _patch_distance(p, saddle),
            False,
            "z = x³ - 3xy² over [-1, 1]²; open",
        ),
        _Model(
            "surfaces",
            "crossed_trough",
            lambda: _mesh_patch(trough, _TARGET_FACES, _SEED + 2),
            lambda p: _patch_distance(p, trough),
            False,
            "z = x²y² over [-1, 1]²; open",
        ),
    ]
    for k, diameter in enumerate(_CYLINDER_DIAMETERS, start=1):
        r = diameter / 2.0
        models.append(
            _Model(
                "objects",
                f"cylinder_{k}",
                lambda r=r: _elliptic_prism(r, r, height, _TARGET_FACES),
                lambda p, r=r: _prism_distance(p, r, r, height),
                True,
                f"circular cylinder, diameter {diameter:g} mm, height {height:g} mm, flat caps",
            )
        )
    models += [
        _Model(
            "objects",
            "elliptic_cylinder",
            lambda: _elliptic_prism(ea, eb, height, _TARGET_FACES),
            lambda p: _prism_distance(p, ea, eb, height),
            True,
            f"elliptic cylinder, semi-axes {ea:g} mm (x) and {eb:g} mm (y), "
            f"height {height:g} mm, flat caps",
        ),
        _Model(
            "objects",
            "sphere",
            _sphere,
            lambda p: _sphere_distance(p, _SPHERE_RADIUS),
            True,
            f"sphere, radius {_SPHERE_RADIUS:g} mm",
        ),
    ]
    return models


# =============================================================================================
# Checks, measurements and the README
# =============================================================================================


def _check(mesh, closed, name):
    """Raise ``RuntimeError`` unless the mesh is clean and consistently wound.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The mesh as loaded back from its file.
    closed : bool
        Closed solid (watertight, positive volume) or open patch (every normal has z > 0).
    name : str
        For the message.
    """
    problems = []
    if not mesh.is_winding_consistent:
        problems.append("inconsistent winding")
    if mesh.area_faces.min() <= 1e-3 * mesh.area_faces.mean():
        problems.append("degenerate faces")
    if mesh.euler_number != (2 if closed else 1):
        problems.append(f"Euler number {mesh.euler_number}: not one sphere or disc")
    if closed and not (mesh.is_watertight and mesh.volume > 0.0):
        problems.append("not a watertight solid with outward normals")
    if not closed and mesh.face_normals[:, 2].min() <= 0.0:
        problems.append("a face normal does not point to +z")
    if problems:
        raise RuntimeError(f"{name}: " + ", ".join(problems))


def _measure(mesh, distance):
    """Size, shape and deviation from the analytic surface of a mesh.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The mesh.
    distance : callable
        First-order distance of ``(k, 3)`` points to the analytic surface.

    Returns
    -------
    dict
        ``faces``, ``vertices``, ``mean_edge``, ``min_angle`` (degrees), ``dev_max`` and
        ``dev_rms`` (over ``_N_SAMPLES`` points sampled uniformly on the faces).
    """
    points, _ = trimesh.sample.sample_surface(mesh, _N_SAMPLES, seed=_SEED)
    dev = distance(points)
    return {
        "faces": len(mesh.faces),
        "vertices": len(mesh.vertices),
        "mean_edge": float(mesh.edges_unique_length.mean()),
        "min_angle": float(np.degrees(mesh.face_angles.min())),
        "dev_max": float(dev.max()),
        "dev_rms": float(np.sqrt(np.mean(dev**2))),
    }


_HEADER = (
    "| file | units | faces | vertices | mean edge | min angle (°) | max deviation "
    "| RMS deviation | size (KiB) |\n"
    "|---|---|---:|---:|---:|---:|---:|---:|---:|\n"
)


def _table(rows):
    """Markdown table of the measurements.

    Parameters
    ----------
    rows : list of (str, str, dict, int)
        Relative file path, units, measurements, file size in bytes.

    Returns
    -------
    str
    """
    lines = [
        f"| `{path}` | {units} | {m['faces']:,} | {m['vertices']:,} | {m['mean_edge']:#.4g} "
        f"| {m['min_angle']:.1f} | {m['dev_max']:.2e} | {m['dev_rms']:.2e} "
        f"| {size / 1024:,.0f} |"
        for path, units, m, size in rows
    ]
    return _HEADER + "\n".join(lines) + "\n"


def _readme(models, table):
    """Text of ``models/README.md``.

    Parameters
    ----------
    models : list of _Model
        The bundled models.
    table : str
        Markdown table of the measurements.

    Returns
    -------
    str
    """

    def shapes(library):
        return "\n".join(f"- `{m.name}.stl`: {m.shape}" for m in models if m.library == library)

    return f"""# Bundled models

Binary STL meshes written by `tools/make_models.py` (run it again to regenerate them; it is
deterministic). Do not edit them by hand.

## `surfaces/`: the paper's simulation surfaces (Table 1), unit-sized

{shapes("surfaces")}

The open patches are the graphs of their equations over the paper's parameter domains, with
normals pointing to +z. They are triangulated with evenly sized triangles in 3D (relaxed with
Delaunay edge flips and DistMesh-style edge springs, then subdivided), so the steep corners
of the monkey saddle are not stretched. The ellipsoid is a subdivided icosphere scaled by
its semi-axes: there are no pole slivers, and the triangles are smallest near the ends of
the long axis, where the ellipsoid is most curved.

## `objects/`: the paper's experiment objects (Figure 7), millimetres

{shapes("objects")}

All are closed, watertight solids with outward normals, centred at the origin, cylinder axes
along z. The paper does not give the height of the cylinders; they are 100 mm tall here. The
cylinder sides are rings of points offset by half a step on every other ring (nearly
equilateral triangles); the caps are concentric rings inside the rim.

## Resolution and accuracy

Every vertex lies on the analytic surface (up to float32 rounding in the STL file). The
deviation is that of the flat triangles from the curved surface: the first-order implicit
distance |f| / |grad f| at {_N_SAMPLES:,} points sampled uniformly on the faces (fixed
seed), its maximum over those points and its RMS; for the cylinders, the smaller of the
distances to the side and to the cap planes. Lengths are in the units of the file; the
paper's simulated touch noise is ±0.001 on the unit surfaces (Section 3.1). "min angle" is
the smallest angle of any triangle. The numbers below are measured by the script on the
files as written.

{table}"""


def _write(model, out):
    """Build one model, write it as binary STL, reload and check it.

    Parameters
    ----------
    model : _Model
        The model.
    out : pathlib.Path
        Output folder.

    Returns
    -------
    path : pathlib.Path
        The file written.
    mesh : trimesh.Trimesh
        The mesh as loaded back from the file.
    """
    path = out / model.library / f"{model.name}.stl"
    path.parent.mkdir(parents=True, exist_ok=True)
    model.build().export(path, file_type="stl")
    mesh = trimesh.load(path, file_type="stl", force="mesh")
    _check(mesh, model.closed, model.name)
    return path, mesh


def main(argv=None) -> int:
    """Write the bundled models and ``README.md``; print the measurements.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status, 0 on success.
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out",
        type=Path,
        default=_DEFAULT_OUT,
        help=f"output folder (default: {_DEFAULT_OUT})",
    )
    args = parser.parse_args(argv)
    out = args.out

    models = _models()
    rows = []
    for model in models:
        path, mesh = _write(model, out)
        measured = _measure(mesh, model.distance)
        units = "mm" if model.library == "objects" else "unit"
        relative = path.relative_to(out).as_posix()
        rows.append((relative, units, measured, path.stat().st_size))
        print(f"wrote {path}", flush=True)
    table = _table(rows)
    print(table, end="")
    (out / "README.md").write_text(_readme(models, table), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
