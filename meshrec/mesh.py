"""Loading and cleaning triangle meshes from STL, OBJ, PLY and OFF files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

#: File endings accepted as mesh files (compared case-insensitively).
MESH_SUFFIXES: tuple[str, ...] = (".stl", ".obj", ".ply", ".off")


def is_mesh_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` has one of the accepted mesh endings (:data:`MESH_SUFFIXES`).

    Parameters
    ----------
    path : str or path-like
        A file name; the file need not exist.

    Returns
    -------
    bool
    """
    return Path(path).suffix.lower() in MESH_SUFFIXES


def check_mesh_path(path: str | os.PathLike) -> Path:
    """Check that ``path`` names an existing file with a mesh ending.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    ValueError
        If ``path`` does not exist, is not a regular file (e.g. a directory), or its
        ending is not in :data:`MESH_SUFFIXES`.
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"mesh file {str(p)!r} does not exist")
    if p.is_dir():
        raise ValueError(f"mesh file {str(p)!r} is a directory, not a file")
    if not p.is_file():
        raise ValueError(f"mesh file {str(p)!r} is not a regular file")
    if not is_mesh_file(p):
        raise ValueError(
            f"mesh file {str(p)!r} has unsupported ending {p.suffix!r}; "
            f"expected one of {', '.join(MESH_SUFFIXES)}"
        )
    return p


def load_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Load a triangle mesh and clean it.

    The file is read with trimesh (duplicate vertices merged); then degenerate faces,
    duplicate faces (whatever their winding) and unreferenced vertices are dropped.

    Parameters
    ----------
    path : str or path-like
        An STL, OBJ, PLY or OFF file (see :data:`MESH_SUFFIXES`).

    Returns
    -------
    vertices : (n, 3) float64
        C-contiguous vertex positions, every one of them used by some face.
    faces : (m, 3) int64
        C-contiguous vertex indices of the triangles, ``m >= 1``.

    Raises
    ------
    ValueError
        If ``path`` does not exist, is a directory, has an unsupported ending, cannot be
        parsed, holds no triangles (e.g. a point cloud), or has non-finite coordinates.
    """
    p = check_mesh_path(path)
    suffix = p.suffix.lower()
    try:
        loaded = trimesh.load(str(p), file_type=suffix[1:], force="mesh", process=True)
    except Exception as exc:  # trimesh raises many types on malformed input
        raise ValueError(
            f"mesh file {str(p)!r} could not be read: {type(exc).__name__}: {exc}"
        ) from exc
    if not isinstance(loaded, trimesh.Trimesh):
        raise ValueError(
            f"mesh file {str(p)!r} holds no triangle mesh (got {type(loaded).__name__})"
        )
    mesh = loaded
    if len(mesh.faces) == 0:
        raise ValueError(
            f"mesh file {str(p)!r} holds no faces ({len(mesh.vertices)} vertices): "
            "a point cloud, an empty file or unreadable content"
        )
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"mesh file {str(p)!r} has non-finite vertex coordinates")
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise ValueError(f"mesh file {str(p)!r} holds only degenerate faces")
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    return vertices, faces
