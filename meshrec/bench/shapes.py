"""Deterministic smooth shapes for the calibration and scale benchmarks.

Families of unit-size smooth surfaces with random parameters, each a ``trimesh.Trimesh``
of a few thousand to about 20,000 faces: ellipsoids, tori, superellipsoids, capsules,
bumped spheres, and open paraboloid and saddle patches. A seed fixes every parameter, so
a shape set can be regenerated anywhere; ``shape_set(n, seed)`` makes as many distinct
models as asked (the families in turn, each with its own random parameters).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

__all__ = ["EXTRA_FAMILIES", "SHAPE_FAMILIES", "Shape", "make_shape", "shape_set", "write_shapes"]

#: The shape families, in the order ``shape_set`` cycles through them.
SHAPE_FAMILIES = (
    "ellipsoid",
    "torus",
    "superellipsoid",
    "capsule",
    "bumped_sphere",
    "paraboloid",
    "saddle",
)

#: Families that ``shape_set`` uses only when asked by name: ``tipped_rod`` makes
#: look-alikes that differ in one small feature (rods of one radius and length whose
#: tips differ), the case where touching at random rarely decides.
EXTRA_FAMILIES = ("tipped_rod",)


@dataclass(frozen=True, eq=False)
class Shape:
    """One generated shape.

    Attributes
    ----------
    name : str
        Unique name (the file stem when written).
    family : str
        One of :data:`SHAPE_FAMILIES`.
    params : dict
        The parameters drawn for it.
    mesh : trimesh.Trimesh
        The surface (closed for the solids, an open patch for paraboloid and saddle).
    """

    name: str
    family: str
    params: dict
    mesh: trimesh.Trimesh

    def __repr__(self) -> str:
        p = ", ".join(f"{k}={v:.3g}" for k, v in self.params.items())
        return f"Shape({self.name!r}, {self.family}, {p}, faces={len(self.mesh.faces)})"


def _sphere(subdivisions: int = 5) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)


def _ellipsoid(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    a, b, c = np.sort(rng.uniform(0.45, 1.0, 3))[::-1]
    m = _sphere()
    m.vertices = m.vertices * [a, b, c]
    return {"a": a, "b": b, "c": c}, m


def _torus(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    major = rng.uniform(0.6, 0.8)
    minor = rng.uniform(0.22, 0.35)
    m = trimesh.creation.torus(
        major_radius=major, minor_radius=minor, major_sections=160, minor_sections=64
    )
    return {"major": major, "minor": minor}, m


def _superellipsoid(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    # |x/a|^r + |y/b|^r + |z/c|^r = 1 with r in (2, 3.2]: rounded boxes, smooth everywhere
    # (r > 2 keeps the curvature finite). Radial projection of a sphere's vertices.
    a, b, c = rng.uniform(0.55, 1.0, 3)
    r = rng.uniform(2.4, 3.2)
    m = _sphere()
    d = m.vertices
    scale = (np.abs(d[:, 0] / a) ** r + np.abs(d[:, 1] / b) ** r + np.abs(d[:, 2] / c) ** r) ** (
        -1.0 / r
    )
    m.vertices = d * scale[:, None]
    return {"a": a, "b": b, "c": c, "r": r}, m


def _capsule(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    radius = rng.uniform(0.3, 0.5)
    height = rng.uniform(0.6, 1.2)
    # A revolved profile (cap, straight side, cap) sampled about every 0.03: trimesh's
    # own capsule spans its cylinder with one band of long thin triangles whose only
    # vertices sit on the seams, which leaves the curvature table no vertex on the side.
    cap = np.linspace(-0.5 * np.pi, 0.0, 24)
    side = np.linspace(-0.5 * height, 0.5 * height, max(int(height / 0.03), 2) + 1)
    profile = np.vstack(
        [
            np.column_stack([radius * np.cos(cap), -0.5 * height + radius * np.sin(cap)]),
            np.column_stack([np.full(len(side) - 2, radius), side[1:-1]]),
            np.column_stack(
                [radius * np.cos(-cap[::-1]), 0.5 * height + radius * np.sin(-cap[::-1])]
            ),
        ]
    )
    profile[0, 0] = profile[-1, 0] = 0.0
    m = trimesh.creation.revolve(profile, sections=96)
    return {"radius": radius, "height": height}, m


def _bumped_sphere(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    # r(d) = 1 + amp * sum of a few smooth lobes cos(k angle(d, centre)), k up to 3.
    lobes = int(rng.integers(2, 5))
    amp = rng.uniform(0.06, 0.12)
    m = _sphere()
    d = m.vertices
    r = np.ones(len(d))
    for _ in range(lobes):
        centre = rng.normal(size=3)
        centre /= np.linalg.norm(centre)
        k = rng.uniform(1.5, 3.0)
        r += amp * np.cos(k * np.arccos(np.clip(d @ centre, -1.0, 1.0)))
    m.vertices = d * r[:, None] * 0.8
    return {"lobes": float(lobes), "amp": amp}, m


def _tipped_rod(rng: np.random.Generator) -> tuple[dict, trimesh.Trimesh]:
    # A rod of radius 0.3 with a straight side 0.9 long, a hemispherical base and a
    # semi-ellipsoidal tip whose axial half-axis is ``tip`` x the radius: every rod of the
    # family is the same except near its tip (a fifth of its area).
    radius, side_len = 0.3, 0.9
    tip = rng.uniform(0.35, 2.2)
    t = np.linspace(-0.5 * np.pi, 0.0, 24)
    base = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    side = np.linspace(0.0, side_len, int(side_len / 0.03) + 1)[1:-1]
    s = np.linspace(0.0, 0.5 * np.pi, 24 + int(12 * tip))
    top = np.column_stack([radius * np.cos(s), side_len + tip * radius * np.sin(s)])
    profile = np.vstack([base, np.column_stack([np.full(len(side), radius), side]), top])
    profile[0, 0] = profile[-1, 0] = 0.0
    m = trimesh.creation.revolve(profile, sections=96)
    m.apply_translation([0.0, 0.0, -0.5 * side_len])
    return {"radius": radius, "side": side_len, "tip": tip}, m


def _patch(rng: np.random.Generator, sign: float) -> tuple[dict, trimesh.Trimesh]:
    # z = (x^2 / a + sign * y^2 / b) / 2 on a disc of radius 1 (open patch).
    a, b = rng.uniform(0.8, 2.5, 2)
    n = 100
    t = np.linspace(-1.0, 1.0, n)
    x, y = np.meshgrid(t, t, indexing="ij")
    z = 0.5 * (x**2 / a + sign * y**2 / b)
    verts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    idx = np.arange(n * n).reshape(n, n)
    q = np.column_stack(
        [idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()]
    )
    faces = np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    m = trimesh.Trimesh(verts, faces, process=True)
    return {"a": a, "b": b}, m


_MAKERS = {
    "ellipsoid": _ellipsoid,
    "torus": _torus,
    "superellipsoid": _superellipsoid,
    "capsule": _capsule,
    "bumped_sphere": _bumped_sphere,
    "paraboloid": lambda rng: _patch(rng, 1.0),
    "saddle": lambda rng: _patch(rng, -1.0),
    "tipped_rod": _tipped_rod,
}


def make_shape(family: str, rng: np.random.Generator | int | None = None) -> Shape:
    """Make one shape of ``family`` with parameters drawn from ``rng``.

    Parameters
    ----------
    family : str
        One of :data:`SHAPE_FAMILIES` or :data:`EXTRA_FAMILIES`.
    rng : numpy.random.Generator or int or None
        Randomness, through :func:`numpy.random.default_rng`.

    Returns
    -------
    Shape
        Named ``family`` (rename it with :func:`shape_set`), randomly oriented.

    Raises
    ------
    ValueError
        If ``family`` is not one of :data:`SHAPE_FAMILIES` or :data:`EXTRA_FAMILIES`.
    """
    if family not in _MAKERS:
        raise ValueError(
            f"family must be one of {SHAPE_FAMILIES + EXTRA_FAMILIES}, got {family!r}"
        )
    gen = np.random.default_rng(rng)
    params, mesh = _MAKERS[family](gen)
    mesh.apply_transform(trimesh.transformations.random_rotation_matrix(gen.random(3)))
    params = {k: float(v) for k, v in params.items()}
    return Shape(name=family, family=family, params=params, mesh=mesh)


def shape_set(
    n: int, seed: int = 0, families: tuple[str, ...] | list[str] | None = None
) -> list[Shape]:
    """``n`` distinct shapes, the families in turn, all fixed by ``seed``.

    Parameters
    ----------
    n : int
        How many shapes, at least 1.
    seed : int
        Seed of every parameter; the same ``(n, seed, families)`` gives the same shapes.
    families : sequence of str, optional
        The families to cycle through (default :data:`SHAPE_FAMILIES`; those of
        :data:`EXTRA_FAMILIES` only when named).

    Returns
    -------
    list of Shape
        Named ``f"{family}_{seed}_{i}"``.

    Raises
    ------
    ValueError
        If ``n`` is not a positive integer or a family is unknown.
    """
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    fams = tuple(SHAPE_FAMILIES if families is None else families)
    if not fams:
        raise ValueError("families must name at least one family, got none")
    for f in fams:
        if f not in _MAKERS:
            raise ValueError(
                f"families must be among {SHAPE_FAMILIES + EXTRA_FAMILIES}, got {f!r}"
            )
    seeds = np.random.SeedSequence(seed).spawn(int(n))
    out = []
    for i in range(int(n)):
        s = make_shape(fams[i % len(fams)], np.random.default_rng(seeds[i]))
        out.append(Shape(f"{s.family}_{seed}_{i}", s.family, s.params, s.mesh))
    return out


def write_shapes(shapes: list[Shape], folder: str | os.PathLike) -> list[Path]:
    """Write each shape as ``folder/<name>.stl`` (the folder is created).

    Parameters
    ----------
    shapes : list of Shape
    folder : str or path

    Returns
    -------
    list of Path
        The files written, in the order of ``shapes``.
    """
    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    paths = []
    for s in shapes:
        path = root / f"{s.name}.stl"
        s.mesh.export(path)
        paths.append(path)
    return paths
