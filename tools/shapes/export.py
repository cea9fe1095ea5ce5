"""Writing a model: build it, export binary STL, load it back and check it."""

from __future__ import annotations

import trimesh

from shapes.measure import check_mesh

__all__ = ["write_model"]


def write_model(model, out):
    """Build one model, write it as binary STL, reload and check it.

    Parameters
    ----------
    model : Model
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
    check_mesh(mesh, model.closed, model.name)
    return path, mesh

