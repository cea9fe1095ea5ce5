"""Deterministic smooth blobs: large libraries of distinct closed models for the scale benchmark.

A blob is a unit icosphere (:func:`trimesh.creation.icosphere`, ``defaults.BLOB_SUBDIVISIONS``
subdivisions: 5,120 faces) whose vertices are moved radially by a seeded smooth field
``r(d) = 1 + amplitude * f(d) / max|f|``, where ``f`` is a random polynomial of degree
``defaults.BLOB_DEGREE`` in the unit direction ``d`` (on the sphere, a combination of
spherical harmonics of order at most that degree: low-order, smooth), then scaled
anisotropically and rotated at random. ``r`` stays positive, so the radial map is one to
one and the surface is closed, manifold and free of self-intersections. Model ``i`` of seed
``s`` depends only on ``(s, i)``: ``blob_set(1000)`` starts with ``blob_set(10)``.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from meshrec import defaults

__all__ = ["Blob", "blob_set", "make_blob", "write_blobs"]


@dataclass(frozen=True, eq=False)
class Blob:
    """One generated blob.

    Attributes
    ----------
    name : str
        Unique name (the file stem when written), ``blob_<seed>_<i:04d>``.
    params : dict
        ``amplitude`` and the three anisotropic ``scale_x/y/z`` drawn for it.
    mesh : trimesh.Trimesh
        The closed surface.
    """

    name: str
    params: dict
    mesh: trimesh.Trimesh

    def __repr__(self) -> str:
        p = ", ".join(f"{k}={v:.3g}" for k, v in self.params.items())
        return f"Blob({self.name!r}, {p}, faces={len(self.mesh.faces)})"


def _exponents(degree: int) -> np.ndarray:
    """(k, 3) int: the exponents (a, b, c) of the monomials x^a y^b z^c, 1 <= a+b+c <= degree."""
    return np.array(
        [e for e in itertools.product(range(degree + 1), repeat=3) if 1 <= sum(e) <= degree]
    )


def make_blob(rng: np.random.Generator | int | None = None, name: str = "blob") -> Blob:
    """Make one blob with its shape drawn from ``rng``.

    Parameters
    ----------
    rng : numpy.random.Generator or int or None
        Randomness, through :func:`numpy.random.default_rng`.
    name : str
        The blob's name.

    Returns
    -------
    Blob
        ``(20 * 4**defaults.BLOB_SUBDIVISIONS)`` faces, about unit size.

    Raises
    ------
    ValueError
        If ``name`` is not a non-empty string.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string, got {name!r}")
    gen = np.random.default_rng(rng)
    mesh = trimesh.creation.icosphere(subdivisions=defaults.BLOB_SUBDIVISIONS, radius=1.0)
    d = np.asarray(mesh.vertices, dtype=np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    exps = _exponents(defaults.BLOB_DEGREE)
    # Coefficients fall off with the degree: the low orders set the overall form.
    coef = gen.normal(size=len(exps)) / exps.sum(axis=1)
    f = np.prod(d[:, None, :] ** exps[None, :, :], axis=2) @ coef
    amplitude = float(gen.uniform(*defaults.BLOB_AMPLITUDE))
    r = 1.0 + amplitude * f / np.max(np.abs(f))
    scale = gen.uniform(*defaults.BLOB_ANISOTROPY, size=3)
    rotation = trimesh.transformations.random_rotation_matrix(gen.random(3))[:3, :3]
    vertices = (d * r[:, None] * scale) @ rotation.T
    out = trimesh.Trimesh(vertices, np.asarray(mesh.faces), process=False)
    params = {"amplitude": amplitude}
    params.update({f"scale_{a}": float(s) for a, s in zip("xyz", scale, strict=True)})
    return Blob(name=name, params=params, mesh=out)


def blob_set(n: int, seed: int = 0) -> list[Blob]:
    """``n`` distinct blobs, fixed by ``seed``; blob ``i`` depends only on ``(seed, i)``.

    Parameters
    ----------
    n : int
        How many, at least 1.
    seed : int
        Seed of every shape.

    Returns
    -------
    list of Blob
        Named ``f"blob_{seed}_{i:04d}"`` (sorted by name in the order made).

    Raises
    ------
    ValueError
        If ``n`` is not a positive integer or ``seed`` not a non-negative integer.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return [
        make_blob(np.random.default_rng([int(seed), i]), name=f"blob_{seed}_{i:04d}")
        for i in range(int(n))
    ]


def write_blobs(n: int, folder: str | os.PathLike, seed: int = 0) -> list[Path]:
    """Write ``blob_set(n, seed)`` as binary STL files into ``folder`` (created).

    Files already there with the right name are kept as they are (a blob depends only on
    ``(seed, i)``, so growing a library from 100 to 1,000 writes only the 900 new ones).

    Parameters
    ----------
    n : int
    folder : str or path-like
    seed : int

    Returns
    -------
    list of Path
        The ``n`` files, in order.

    Raises
    ------
    ValueError
        As :func:`blob_set`.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(int(n)):
        path = root / f"blob_{seed}_{i:04d}.stl"
        if not path.is_file():
            blob = make_blob(np.random.default_rng([int(seed), i]), name=path.stem)
            tmp = path.with_name(f".{path.name}.tmp")
            blob.mesh.export(tmp, file_type="stl")
            os.replace(tmp, path)
        paths.append(path)
    return paths
