"""Checks and measurements of a written mesh: topology, winding, size, shape, deviation."""

from __future__ import annotations

import numpy as np
import trimesh

from shapes.params import N_SAMPLES, SEED

__all__ = ["check_mesh", "measure_mesh"]


def check_mesh(mesh, closed, name):
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


def measure_mesh(mesh, distance):
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
        ``dev_rms`` (over ``N_SAMPLES`` points sampled uniformly on the faces).
    """
    points, _ = trimesh.sample.sample_surface(mesh, N_SAMPLES, seed=SEED)
    dev = distance(points)
    return {
        "faces": len(mesh.faces),
        "vertices": len(mesh.vertices),
        "mean_edge": float(mesh.edges_unique_length.mean()),
        "min_angle": float(np.degrees(mesh.face_angles.min())),
        "dev_max": float(dev.max()),
        "dev_rms": float(np.sqrt(np.mean(dev**2))),
    }

