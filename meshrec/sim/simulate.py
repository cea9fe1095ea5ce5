"""Simulated touches: three noisy curves cut from a mesh through one contact point.

This follows the simulation protocol of the paper (Section 3.1): pick a point ``p`` on the
surface, intersect the surface with three planes through ``p``, sample 61 points along each
intersection curve and add uniform noise within +-0.001 to every coordinate. The curves
are then moved by a random rigid motion, as if a robot had touched the object somewhere in
its own frame, so that recognition has to find the pose as well as the contact.

The curves are sections of the *mesh* (not of an analytic surface): each is the connected
piece through the contact of the polyline where a cutting plane meets the mesh faces,
resampled at equal arc length along that polyline and centred on the contact, so that the
middle sample of every noiseless curve is exactly the contact.

With a ball-tipped probe (``probe_radius`` R > 0) the data are the ball's centres: every
curve sample is moved outwards by R along the smooth surface normal there (the vertex
normals blended over its face), onto the true offset surface; a sample the ball could not
reach without cutting into the mesh elsewhere (a concavity tighter than the tip) makes
the contact unusable.
"""

from __future__ import annotations

import math
import os
import secrets
from dataclasses import dataclass
from pathlib import Path

import igl
import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.io.checks import (
    check_choice,
    check_int,
    check_number,
    check_points,
    check_rng,
    check_vector,
    one_line,
)
from meshrec.io.touch import TouchData
from meshrec.io.truth import Truth, write_truth
from meshrec.model.index import ModelIndex

__all__ = ["SimulatedTouch", "simulate_touch"]


# ---------------------------------------------------------------------------- result type
@dataclass(frozen=True, eq=False)
class SimulatedTouch:
    """A simulated touch together with the ground truth it was made from.

    Attributes
    ----------
    touch : TouchData
        The noisy curves in the touch frame (after the rigid motion); ``touch.contact``
        and ``touch.normal`` are None, as in a file recorded by a real probe.
    model : str
        The model name (file stem, the object's ``name``, or the ``name`` argument), or
        ``""`` for a bare mesh.
    contact : (3,) float
        The true contact, in model coordinates, on the mesh.
    normal : (3,) float
        The outward (face-winding) unit normal of the mesh face at the contact, model
        coordinates.
    T_touch_model : (4, 4) float
        The rigid motion applied: touch-frame point = ``T_touch_model @ model point``.
    T_model_touch : (4, 4) float
        Its inverse.
    clean_curves : tuple of (n, 3) float
        The noiseless curves in model coordinates, each ordered along the curve; the
        middle row of each is ``contact``.
    noise : float
        Half-width of the uniform noise that was added to every coordinate (or, with
        ``noise_direction`` "normal", along the normal).
    length : float
        Arc length of each curve, model units.
    seed : int or None
        The integer seed that reproduces this touch (``rng=seed``), or None when a
        generator was passed in.
    probe_radius : float
        Radius of the probe's ball tip, model units (0: a point probe). With a tip the
        curves are the ball's centres: ``clean_curves`` lie on the surface offset
        outwards by it, and their middle rows are ``contact + probe_radius * normal``
        (``normal`` there the smooth normal).
    noise_direction : str
        "isotropic" (the noise on every coordinate) or "normal" (along the smooth normal
        at each sample only).
    """

    touch: TouchData
    model: str
    contact: np.ndarray
    normal: np.ndarray
    T_touch_model: np.ndarray
    T_model_touch: np.ndarray
    clean_curves: tuple[np.ndarray, ...]
    noise: float
    length: float
    seed: int | None
    probe_radius: float = 0.0
    noise_direction: str = "isotropic"

    @property
    def n_points(self) -> int:
        """Points per curve."""
        return len(self.clean_curves[0])

    @property
    def contact_touch(self) -> np.ndarray:
        """(3,) float: the true contact in the touch frame."""
        return self.T_touch_model[:3, :3] @ self.contact + self.T_touch_model[:3, 3]

    @property
    def normal_touch(self) -> np.ndarray:
        """(3,) float: the true normal in the touch frame."""
        return self.T_touch_model[:3, :3] @ self.normal

    @property
    def truth(self) -> Truth:
        """The ground truth (:class:`meshrec.io.truth.Truth`), as written to a truth file."""
        return Truth(
            model=self.model,
            contact=self.contact,
            T_model_touch=self.T_model_touch,
            T_touch_model=self.T_touch_model,
            normal=self.normal,
            noise=float(self.noise),
            length=float(self.length),
            points=int(self.n_points),
            seed=self.seed,
            probe_radius=self.probe_radius or None,
            noise_direction=None if self.noise_direction == "isotropic" else self.noise_direction,
        )

    def truth_dict(self) -> dict:
        """Return the ground truth as a JSON-ready dictionary.

        Returns
        -------
        dict
            Keys ``model`` (str), ``contact``, ``normal`` (model frame, lists of 3 floats),
            ``T_touch_model``, ``T_model_touch`` (4x4 nested lists), ``contact_touch``
            (list of 3 floats), ``noise``, ``length`` (float), ``points`` (int, points
            per curve), ``seed`` (int or None), with a ball tip ``probe_radius`` (float)
            and with noise along the normal ``noise_direction`` ("normal"):
            :meth:`Truth.to_dict` of :attr:`truth`.
        """
        return self.truth.to_dict()

    def write(self, touch_path, truth_path=None) -> None:
        """Write the touch file and, where asked, the ground-truth JSON; both atomically.

        Parameters
        ----------
        touch_path : str or os.PathLike
            The touch file, ``.csv`` or ``.json`` (format by suffix, see
            :meth:`TouchData.to_file`).
        truth_path : str or os.PathLike, optional
            The truth JSON (:func:`meshrec.io.truth.write_truth`). Without it no truth
            file is written.

        Raises
        ------
        TypeError
            If a path is not a str or os.PathLike.
        ValueError
            If ``touch_path`` does not end in ``.csv`` or ``.json``, or ``truth_path`` is
            the same file as ``touch_path``.
        OSError
            If a file cannot be written.
        """
        for value, label in ((touch_path, "touch_path"), (truth_path, "truth_path")):
            if value is not None and not isinstance(value, (str, os.PathLike)):
                raise TypeError(f"{label} must be a str or os.PathLike, got {type(value).__name__}")
        touch_path = Path(touch_path)
        if truth_path is not None:
            truth_path = Path(truth_path)
            if truth_path.resolve() == touch_path.resolve():
                raise ValueError(
                    f"truth_path must differ from touch_path, got {one_line(truth_path)!r}"
                )
        self.touch.to_file(touch_path)
        if truth_path is not None:
            write_truth(truth_path, self.truth)

    def __repr__(self) -> str:
        return (
            f"SimulatedTouch(model={self.model!r}, {len(self.clean_curves)} curves x "
            f"{self.n_points} points, contact={np.round(self.contact, 6).tolist()}, "
            f"length={self.length:.6g}, noise={self.noise:g}, seed={self.seed}"
            + (f", probe_radius={self.probe_radius:g}" if self.probe_radius else "")
            + (", noise along the normal)" if self.noise_direction == "normal" else ")")
        )


# ---------------------------------------------------------------------------- public entry
def simulate_touch(
    mesh,
    *,
    contact=None,
    rng=None,
    n_points: int = defaults.SIM_POINTS,
    noise: float = defaults.SIM_NOISE,
    length: float | None = None,
    transform: bool = True,
    name: str | None = None,
    probe_radius: float = 0.0,
    noise_direction: str = "isotropic",
) -> SimulatedTouch:
    """Simulate a touch: three noisy curves on a mesh through one contact point.

    The mesh is cut by three planes through the contact ``c``. Each plane contains a
    direction of the tangent plane at ``c`` and is tilted away from containing the normal
    by a random angle up to ``defaults.SIM_MAX_TILT_DEG``; the three tangent directions
    are a random base angle plus steps of 60 degrees with jitter, at least
    ``defaults.SIM_MIN_PLANE_ANGLE_DEG`` apart. The connected piece of each section
    through ``c`` is resampled at ``n_points`` equal arc-length steps over ``length``,
    centred on ``c`` (the middle sample is ``c``). Uniform noise in ``[-noise, noise]`` is
    added to every coordinate (in the model frame, independently per curve), or only along
    the smooth normal at each sample, and the curves are then moved by a random rigid
    motion. The sections are those of the mesh's flat faces: on a coarse export they lie
    up to its chord error from the smooth surface that recognition compares with (see
    ``Registration.error``), so simulate on a fine mesh of the object.

    Parameters
    ----------
    mesh : trimesh.Trimesh or str or os.PathLike or object
        The model: a mesh, a mesh file (loaded with ``trimesh.load(path, force="mesh")``),
        or any object with ``vertices`` (V, 3), ``faces`` (F, 3) and ``name`` attributes.
    contact : (3,) float, optional
        The contact in model coordinates; it is snapped to the closest point of the mesh.
        Default: a random point, uniform by area (redrawn, up to
        ``defaults.SIM_MAX_TRIES`` times, while a curve through it is too short).
    rng : numpy.random.Generator or int or None
        Randomness, through :func:`numpy.random.default_rng`. With None a fresh seed is
        drawn and recorded in the result, so every touch can be reproduced.
    n_points : int
        Points per curve, odd, at least 5 and at most ``defaults.SIM_MAX_POINTS``.
    noise : float
        Half-width of the uniform noise per coordinate, model units, >= 0 and at most
        ``defaults.SIM_MAX_NOISE_FRACTION * sqrt(mesh area)``.
    length : float, optional
        Arc length of each curve, model units. Default
        ``defaults.SIM_LENGTH_FRACTION * sqrt(mesh area)``.
    transform : bool
        Apply a random rigid motion (uniform rotation, translation uniform in
        ``[-s, s]^3`` with ``s = sqrt(mesh area)``). If False the touch frame is the model
        frame.
    name : str, optional
        The model name to record; overrides the name taken from the file or object.
    probe_radius : float
        Radius of the probe's ball tip, model units, >= 0 (default 0: a point probe).
        With a tip the curves are the ball's centres: each sample of a section curve is
        moved outwards by it along the smooth normal (vertex normals blended over the
        face), onto the offset surface, before the noise. Random contacts where the ball
        could not touch the curves (it would cut into the mesh: a concavity tighter
        than the tip) are redrawn.
    noise_direction : {"isotropic", "normal"}
        "isotropic" (default, the paper's): the noise on every coordinate. "normal": one
        uniform value in ``[-noise, noise]`` per sample, along the smooth normal there
        (as above), as a probe that errs along its approach measures.

    Returns
    -------
    SimulatedTouch

    Raises
    ------
    TypeError
        If ``mesh`` is neither a mesh, a path nor an object with vertices and faces (real
        (V, 3) vertices, integer faces), or ``n_points`` is not an integer, ``noise`` or
        ``length`` not a real number, ``contact`` not real numbers, ``rng`` neither a
        Generator, an integer nor None, ``transform`` not a bool, ``name`` or
        ``noise_direction`` not a str (the shared checks of :mod:`meshrec.io.checks`).
    ValueError
        If ``n_points`` is not odd or not in 5..``defaults.SIM_MAX_POINTS``, ``noise`` is
        negative, not finite or more than ``defaults.SIM_MAX_NOISE_FRACTION *
        sqrt(area)``, ``length`` is not positive and finite, ``contact`` is not a finite
        (3,) vector or lies farther than ``defaults.SIM_CONTACT_TOLERANCE * sqrt(area)``
        from the mesh, ``rng`` is a negative integer, the mesh file does not exist or is
        not a readable triangle mesh, the faces index missing vertices, the mesh has no
        area, the curves through a given contact are too short for ``length`` (near an
        open boundary, or a closed section shorter than ``length``) for every one of
        ``defaults.SIM_CONTACT_PLANE_TRIES`` plane triples, or no random contact out of
        ``defaults.SIM_MAX_TRIES`` admits curves of that length; ``probe_radius`` is
        negative or not finite, or the ball cannot trace the curves through a given
        contact (or any random one): it would cut into the mesh (the tip is larger than
        the radius of a concave part there); ``noise_direction`` is not one of
        ``defaults.SIM_NOISE_DIRECTIONS``.
    """
    n_points = _check_n_points(n_points)
    noise = check_number(noise, "noise", minimum=0.0)
    if length is not None:
        length = check_number(length, "length", positive=True)
    if contact is not None:
        contact = check_vector(contact, "contact")
    if not isinstance(transform, (bool, np.bool_)):
        raise TypeError(f"transform must be True or False, got {one_line(transform)}")
    if name is not None and not isinstance(name, str):
        raise TypeError(f"name must be a str, got {type(name).__name__}")
    probe_radius = check_number(probe_radius, "probe_radius", minimum=0.0)
    noise_direction = check_choice(
        noise_direction, defaults.SIM_NOISE_DIRECTIONS, "noise_direction"
    )
    generator, seed = _make_rng(rng)

    tm, model_name = _resolve_mesh(mesh)
    if name is not None:
        model_name = name
    surface = _Surface(tm)
    scale = math.sqrt(surface.area)
    if noise > defaults.SIM_MAX_NOISE_FRACTION * scale:
        raise ValueError(
            f"noise must be at most {defaults.SIM_MAX_NOISE_FRACTION} * sqrt(area) = "
            f"{defaults.SIM_MAX_NOISE_FRACTION * scale:.6g} (defaults.SIM_MAX_NOISE_FRACTION), "
            f"got {noise!r}"
        )
    if length is None:
        length = defaults.SIM_LENGTH_FRACTION * scale

    if contact is not None:
        c, face, dist = _closest_point(surface, contact)
        tol = defaults.SIM_CONTACT_TOLERANCE * scale
        if dist > tol:
            raise ValueError(
                f"contact {contact.tolist()} is {dist:.6g} from the mesh, farther than the "
                f"tolerance {tol:.3g} (defaults.SIM_CONTACT_TOLERANCE * sqrt(area))"
            )
        normal = surface.face_normals[face]
        curves, failure = None, None
        for _ in range(defaults.SIM_CONTACT_PLANE_TRIES):
            curves, failure = _cut_curves(surface, c, normal, generator, n_points, length)
            if curves is not None:
                curves, failure = _ball_centres(surface, curves, probe_radius)
            if curves is not None:
                break
        if curves is None:
            raise ValueError(
                f"contact {contact.tolist()} (snapped to {c.tolist()}): the curve through it "
                f"is too short for length={length:.6g}: {failure} "
                f"(tried {defaults.SIM_CONTACT_PLANE_TRIES} plane orientations)"
            )
    else:
        curves = None
        for _ in range(defaults.SIM_MAX_TRIES):
            points, faces = trimesh.sample.sample_surface(tm, 1, seed=generator)
            c = np.asarray(points[0], dtype=np.float64)
            normal = surface.face_normals[int(faces[0])]
            curves, failure = _cut_curves(surface, c, normal, generator, n_points, length)
            if curves is not None:
                curves, failure = _ball_centres(surface, curves, probe_radius)
            if curves is not None:
                break
        if curves is None:
            tip = f", probe_radius={probe_radius:g}" if probe_radius else ""
            raise ValueError(
                f"length={length:.6g}{tip}: none of {defaults.SIM_MAX_TRIES} random contacts on "
                f"the mesh{f' {model_name!r}' if model_name else ''} has three section curves "
                f"that long (last: {failure}); give a smaller length"
            )

    if noise_direction == "normal":
        stacked = np.vstack(curves)
        normals = _smooth_normals(surface, stacked)
        offsets = generator.uniform(-noise, noise, size=(len(normals), 1)) * normals
        noisy = _split_like(stacked + offsets, curves)
    else:
        noisy = [cv + generator.uniform(-noise, noise, size=cv.shape) for cv in curves]

    T = _random_rigid(generator, scale) if transform else np.eye(4)
    T_inv = np.eye(4)
    T_inv[:3, :3] = T[:3, :3].T
    T_inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    R, t = T[:3, :3], T[:3, 3]
    touch = TouchData(curves=[cv @ R.T + t for cv in noisy])

    clean = tuple(_frozen(cv) for cv in curves)
    return SimulatedTouch(
        touch=touch,
        model=model_name,
        contact=_frozen(c),
        normal=_frozen(normal),
        T_touch_model=_frozen(T),
        T_model_touch=_frozen(T_inv),
        clean_curves=clean,
        noise=noise,
        length=float(length),
        seed=seed,
        probe_radius=probe_radius,
        noise_direction=noise_direction,
    )


# ---------------------------------------------------------------------------- validation
def _check_n_points(n_points) -> int:
    """``n_points`` as an int: odd, at least 5 and at most ``defaults.SIM_MAX_POINTS``.

    Raises
    ------
    TypeError
        If it is not an integer.
    ValueError
        If it is even or out of range.
    """
    n = check_int(n_points, "n_points", minimum=5, maximum=defaults.SIM_MAX_POINTS)
    if n % 2 == 0:
        raise ValueError(f"n_points must be an odd integer >= 5, got {n}")
    return n


def _make_rng(rng) -> tuple[np.random.Generator, int | None]:
    """Return a generator for ``rng`` and the integer seed that reproduces it, if any."""
    if rng is None:
        seed = secrets.randbits(63)
        return np.random.default_rng(seed), seed
    generator = check_rng(rng)
    return generator, None if isinstance(rng, np.random.Generator) else int(rng)


def _frozen(arr) -> np.ndarray:
    """Return a read-only float64 copy of ``arr``."""
    out = np.array(arr, dtype=np.float64)
    out.setflags(write=False)
    return out


# ---------------------------------------------------------------------------- the mesh
def _resolve_mesh(mesh) -> tuple[trimesh.Trimesh, str]:
    """Return ``(trimesh.Trimesh, name)`` for a mesh, a mesh file or a duck-typed model."""
    if isinstance(mesh, trimesh.Trimesh):
        return mesh, ""
    if isinstance(mesh, (str, os.PathLike)):
        path = Path(mesh)
        label = f"mesh file {one_line(path)}"
        if not path.is_file():
            raise ValueError(f"{label}: no such file (or not a regular file)")
        try:
            loaded = trimesh.load(path, force="mesh")
        except Exception as exc:  # trimesh raises many kinds (NotImplementedError, KeyError, ...)
            raise ValueError(
                f"{label}: not a readable mesh ({type(exc).__name__}: {one_line(exc, 120)})"
            ) from None
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise ValueError(f"{label}: holds no triangle mesh")
        return loaded, path.stem
    name = None
    if isinstance(mesh, ModelIndex):
        name = mesh.name  # the model's name: its MeshData has none
        mesh = mesh.mesh
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices = check_points(mesh.vertices, "mesh.vertices")
        faces = np.asarray(mesh.faces)
        if faces.dtype.kind not in "iu":
            raise TypeError(f"mesh.faces must be integers, got a {faces.dtype} array")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"mesh.faces must be (m, 3), got {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError(f"mesh.faces must index the {len(vertices)} vertices")
        tm = trimesh.Trimesh(vertices=vertices, faces=faces.astype(np.int64), process=False)
        label = name if name is not None else getattr(mesh, "name", "")
        return tm, "" if label is None else str(label)
    raise TypeError(
        "mesh must be a trimesh.Trimesh, a path to a mesh file, or an object with "
        f"vertices and faces, got {type(mesh).__name__}"
    )


class _Surface:
    """Arrays of a mesh used by the simulation, computed once.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The mesh (not modified).

    Raises
    ------
    ValueError
        If the mesh has no faces or no area, or a non-finite vertex.
    """

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        self.vertices = np.asarray(mesh.vertices, dtype=np.float64)
        self.faces = np.asarray(mesh.faces, dtype=np.int64)
        if len(self.faces) == 0:
            raise ValueError("mesh has no faces")
        if not np.all(np.isfinite(self.vertices)):
            raise ValueError("mesh has non-finite vertices")
        tri = self.vertices[self.faces]
        self.triangles = tri
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(cross, axis=1)
        self.face_areas = 0.5 * norm
        self.area = float(self.face_areas.sum())
        if not self.area > 0:
            raise ValueError(f"mesh must have a positive surface area, got {self.area!r}")
        with np.errstate(invalid="ignore", divide="ignore"):
            normals = cross / norm[:, None]
        normals[norm == 0] = 0.0
        self.face_normals = normals
        edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
        self.max_edge = float(edges.max())
        diag = float(np.linalg.norm(np.ptp(self.vertices, axis=0)))
        self.merge_tol = defaults.SIM_MERGE_FRACTION * diag


def _closest_point(surface: _Surface, point: np.ndarray) -> tuple[np.ndarray, int, float]:
    """Return the closest point of the mesh to ``point``, its face and distance.

    libigl's ``point_mesh_squared_distance`` on the faces within reach: the closest point
    is no farther than the nearest vertex (distance d), so it lies on a face with a vertex
    within d + the longest edge. On the bundled models (80,000 faces) this took 1.5 to 5
    ms per query, against 13 to 45 ms for the vectorised brute force it replaces and 70
    ms for libigl on the whole mesh (which builds its tree for every call); the distances
    agreed to 1e-15.

    Parameters
    ----------
    surface : _Surface
    point : (3,) float

    Returns
    -------
    closest : (3,) float
    face : int
    distance : float
    """
    d2 = np.einsum("ij,ij->i", surface.vertices - point, surface.vertices - point)
    reach = math.sqrt(float(d2.min())) + surface.max_edge
    near = d2 <= reach * reach * (1.0 + 1e-9)
    faces = np.flatnonzero(near[surface.faces].any(axis=1) & (surface.face_areas > 0))
    sq, index, closest = igl.point_mesh_squared_distance(
        point[None, :], surface.vertices, surface.faces[faces]
    )
    return np.asarray(closest[0], dtype=np.float64), int(faces[int(index[0])]), math.sqrt(sq[0])


def _random_rigid(rng: np.random.Generator, scale: float) -> np.ndarray:
    """Return a (4, 4) rigid motion: uniform rotation, translation uniform in [-scale, scale]^3."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-scale, scale, size=3)
    return T


# ---------------------------------------------------------------------------- the curves
def _cutting_planes(
    rng: np.random.Generator, normal: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Draw three cutting planes through a point with surface normal ``normal``.

    Parameters
    ----------
    rng : numpy.random.Generator
    normal : (3,) float
        Unit surface normal.

    Returns
    -------
    list of ((3,) float, (3,) float)
        ``(plane_normal, trace)`` per plane: the unit plane normal and the unit direction
        in which the plane meets the tangent plane.
    """
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    t1 = helper - normal * (helper @ normal)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(normal, t1)
    jitter = math.radians(max(0.0, (60.0 - defaults.SIM_MIN_PLANE_ANGLE_DEG) / 2.0))
    max_tilt = math.radians(defaults.SIM_MAX_TILT_DEG)
    base = rng.uniform(0.0, math.pi)
    angles = base + np.arange(3) * (math.pi / 3.0) + rng.uniform(-jitter, jitter, size=3)
    tilts = rng.uniform(-max_tilt, max_tilt, size=3)
    planes = []
    for angle, tilt in zip(angles, tilts, strict=True):
        trace = math.cos(angle) * t1 + math.sin(angle) * t2
        upright = np.cross(trace, normal)  # normal of the plane spanned by trace and normal
        plane_normal = math.cos(tilt) * upright + math.sin(tilt) * normal
        planes.append((plane_normal / np.linalg.norm(plane_normal), trace))
    return planes


def _cut_curves(
    surface: _Surface,
    c: np.ndarray,
    normal: np.ndarray,
    rng: np.random.Generator,
    n_points: int,
    length: float,
) -> tuple[list[np.ndarray] | None, str | None]:
    """Cut three curves through ``c``; return ``(curves, None)`` or ``(None, why)``."""
    planes = _cutting_planes(rng, normal)
    half = 0.5 * length
    radius = half * (1 + 1e-9) + surface.max_edge + surface.merge_tol
    near = np.einsum("ij,ij->i", surface.vertices - c, surface.vertices - c) <= radius * radius
    local_faces = np.flatnonzero(near[surface.faces].any(axis=1))
    curves = []
    for plane_normal, trace in planes:
        curve, why = _section_curve(surface, c, plane_normal, half, n_points, local_faces)
        if curve is None:
            return None, why
        mid = n_points // 2
        if (curve[mid + 1] - curve[mid - 1]) @ trace < 0:
            curve = curve[::-1].copy()
        curves.append(curve)
    return curves, None


def _merge_labels(points: np.ndarray, tol: float) -> np.ndarray:
    """Label points so that points closer than ``tol`` (transitively) share a label."""
    n = len(points)
    pairs = cKDTree(points).query_pairs(r=tol, output_type="ndarray")
    if len(pairs) == 0:
        return np.arange(n)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return labels


def _section_curve(
    surface: _Surface,
    c: np.ndarray,
    plane_normal: np.ndarray,
    half: float,
    n_points: int,
    local_faces: np.ndarray,
) -> tuple[np.ndarray | None, str | None]:
    """Sample the section curve through ``c`` of the mesh and a plane through ``c``.

    trimesh cuts the faces (``trimesh.intersections.mesh_plane``); the segments are
    chained into the curve through ``c`` here, by hand, because trimesh's own chaining
    (``Trimesh.section``, a Path3D) needs networkx, which meshrec does not depend on, and
    its polylines (``Path3D.discrete``) hold only closed loops: an open section, on an
    open patch, is left as "dangling" entities. Cutting and chaining three curves takes
    12 ms on the bundled ellipsoid (81,920 faces).

    Parameters
    ----------
    surface : _Surface
    c : (3,) float
        A point on the mesh.
    plane_normal : (3,) float
        Unit normal of the cutting plane (which passes through ``c``).
    half : float
        Half the arc length to sample on each side of ``c``.
    n_points : int
        Odd number of samples.
    local_faces : (k,) int
        Faces within reach (every face holding a point within ``half`` of ``c``).

    Returns
    -------
    curve : (n_points, 3) float or None
        Samples at equal arc-length steps over ``[-half, half]``, the middle one ``c``.
    why : str or None
        Why there is no curve (too short), or None.
    """
    segments = trimesh.intersections.mesh_plane(
        surface.mesh, plane_normal, c, local_faces=local_faces
    )
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3)
    if len(segments) == 0:
        return None, "the plane does not cut the mesh near the contact"
    flat = segments.reshape(-1, 3)
    labels = _merge_labels(flat, surface.merge_tol)
    uniq, first = np.unique(labels, return_index=True)
    relabel = np.zeros(labels.max() + 1, dtype=np.int64)
    relabel[uniq] = np.arange(len(uniq))
    nodes = [row for row in flat[first]]
    edges = relabel[labels].reshape(-1, 2)
    edges = edges[edges[:, 0] != edges[:, 1]]
    if len(edges) == 0:
        return None, "the section through the contact is degenerate"
    edges = np.unique(np.sort(edges, axis=1), axis=0)

    # the segment holding c, and c as a node of the section graph
    node_arr = np.asarray(nodes)
    a, b = node_arr[edges[:, 0]], node_arr[edges[:, 1]]
    ab = b - a
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(np.einsum("ij,ij->i", c - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    t = np.nan_to_num(t)
    dist = np.linalg.norm(a + ab * t[:, None] - c, axis=1)
    k = int(np.argmin(dist))
    ia, ib = int(edges[k, 0]), int(edges[k, 1])
    edge_list = [tuple(e) for e in edges.tolist()]
    if np.linalg.norm(node_arr[ia] - c) <= surface.merge_tol:
        start = ia
    elif np.linalg.norm(node_arr[ib] - c) <= surface.merge_tol:
        start = ib
    else:
        start = len(nodes)
        nodes.append(c)
        edge_list[k] = (start, ia)
        edge_list.append((start, ib))
    nodes[start] = c
    adjacency: dict[int, list[int]] = {}
    for u, v in edge_list:
        adjacency.setdefault(u, []).append(v)
        adjacency.setdefault(v, []).append(u)

    first_steps = _opposite_pair(nodes, start, adjacency[start])
    forward, closed = _walk(nodes, adjacency, start, first_steps[0], set())
    if closed:
        loop = np.asarray([nodes[i] for i in [*forward, start]])
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(loop, axis=0), axis=1))])
        perimeter = float(s[-1])
        if perimeter < 2 * half * (1 - 1e-9):
            return None, (
                f"the section through the contact is a closed loop of length {perimeter:.6g} "
                f"< {2 * half:.6g}"
            )
        q = np.mod(np.linspace(-half, half, n_points), perimeter)
        curve = np.column_stack([np.interp(q, s, loop[:, j]) for j in range(3)])
    else:
        if len(first_steps) > 1:
            backward, _ = _walk(nodes, adjacency, start, first_steps[1], set(forward[1:]))
        else:
            backward = [start]
        chain = np.asarray([nodes[i] for i in backward[::-1] + forward[1:]])
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(chain, axis=0), axis=1))])
        s -= s[len(backward) - 1]
        if s[0] > -half * (1 - 1e-9) or s[-1] < half * (1 - 1e-9):
            return None, (
                f"the section curve through the contact ends {-s[0]:.6g} and {s[-1]:.6g} "
                f"from it along the curve, needs {half:.6g} on each side"
            )
        keep = np.concatenate([[True], np.diff(s) > 0])
        s, chain = s[keep], chain[keep]
        q = np.linspace(-half, half, n_points)
        curve = np.column_stack([np.interp(q, s, chain[:, j]) for j in range(3)])
    curve[n_points // 2] = c
    return curve, None


def _split_like(stacked: np.ndarray, curves: list[np.ndarray]) -> list[np.ndarray]:
    """``stacked`` (the curves' rows, one after another) cut back into curves."""
    return np.split(stacked, np.cumsum([len(cv) for cv in curves])[:-1])


def _smooth_normals(surface: _Surface, points: np.ndarray) -> np.ndarray:
    """(n, 3) unit smooth normals at the mesh's closest points to ``points``: the blend of
    the mesh's vertex normals (trimesh's, area-weighted) by the closest point's barycentric
    coordinates in its face (libigl)."""
    V, F = surface.vertices, surface.faces
    _, face, closest = igl.point_mesh_squared_distance(points, V, F)
    tri = V[F[face]]
    w = igl.barycentric_coordinates(
        np.ascontiguousarray(closest), tri[:, 0].copy(), tri[:, 1].copy(), tri[:, 2].copy()
    )
    w = np.clip(np.nan_to_num(w), 0.0, None)
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    normals = np.einsum("ni,nij->nj", w, np.asarray(surface.mesh.vertex_normals)[F[face]])
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def _ball_centres(
    surface: _Surface, curves: list[np.ndarray], radius: float
) -> tuple[list[np.ndarray] | None, str | None]:
    """Move curve samples on the mesh outwards by ``radius`` along the smooth normal.

    The smooth normal is the blend of the mesh's vertex normals (trimesh's, area-weighted)
    by the sample's barycentric coordinates in its closest face (libigl). Each moved
    sample must lie ``radius`` from the mesh (to 1 %): closer, the ball would cut into
    the mesh elsewhere (a concavity tighter than the tip), and the curves are refused.

    Returns
    -------
    curves : list of (n, 3) float or None
    why : str or None
    """
    if radius == 0.0:
        return curves, None
    stacked = np.vstack(curves)
    V, F = surface.vertices, surface.faces
    moved = stacked + radius * _smooth_normals(surface, stacked)
    sq, _, _ = igl.point_mesh_squared_distance(moved, V, F)
    gap = float(np.sqrt(np.maximum(sq, 0.0)).min())
    if gap < 0.99 * radius:
        return None, (
            f"a ball of radius {radius:g} touching the curves comes within {gap:.3g} of the "
            "mesh elsewhere (a concavity tighter than the tip)"
        )
    return _split_like(moved, curves), None


def _opposite_pair(nodes: list[np.ndarray], start: int, neighbours: list[int]) -> list[int]:
    """Return the one or two neighbours of ``start`` to walk to, the most opposite pair."""
    if len(neighbours) <= 2:
        return list(neighbours)
    dirs = np.asarray([nodes[j] - nodes[start] for j in neighbours])
    dirs /= np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-300)
    cos = dirs @ dirs.T
    np.fill_diagonal(cos, np.inf)
    i, j = np.unravel_index(int(np.argmin(cos)), cos.shape)
    return [neighbours[i], neighbours[j]]


def _walk(
    nodes: list[np.ndarray],
    adjacency: dict[int, list[int]],
    start: int,
    first: int,
    forbidden: set[int],
) -> tuple[list[int], bool]:
    """Follow the section graph from ``start`` through ``first`` to an end.

    At a branching node the straightest continuation is taken. Returns the visited nodes
    (starting with ``start``) and whether the walk came back to ``start`` (a closed loop).
    The walk stops before revisiting a node or entering ``forbidden``.
    """
    order = [start, first]
    seen = {start, first}
    prev, cur = start, first
    while True:
        options = [n for n in adjacency[cur] if n != prev]
        if not options:
            return order, False
        if len(options) > 1:
            incoming = nodes[cur] - nodes[prev]
            scores = [
                float(incoming @ (nodes[n] - nodes[cur]))
                / max(float(np.linalg.norm(nodes[n] - nodes[cur])), 1e-300)
                for n in options
            ]
            nxt = options[int(np.argmax(scores))]
        else:
            nxt = options[0]
        if nxt == start:
            return order, True
        if nxt in seen or nxt in forbidden:
            return order, False
        order.append(nxt)
        seen.add(nxt)
        prev, cur = cur, nxt
