"""``meshrec models``: the bundled model sets, or what a model folder holds."""

from __future__ import annotations

import json
from pathlib import Path

import igl
import numpy as np

from meshrec.app.inputs import model_folder, model_units
from meshrec.model.library import (
    bundled_model_sets,
    bundled_models_dir,
    folder_mesh_files,
    size_outliers,
)
from meshrec.model.mesh import MeshData, load_mesh
from meshrec.model.resolution import mesh_resolution
from meshrec.recognition.units import read_units_note

__all__ = ["list_bundled", "list_folder", "run_models"]


def list_bundled() -> dict:
    """The bundled sets: ``{"sets": [{"name", "folder", "models", "units"}]}``."""
    sets = []
    for name in bundled_model_sets():
        folder = bundled_models_dir(name)
        files, _ = folder_mesh_files(folder)
        sets.append(
            {
                "name": name,
                "folder": str(folder),
                "models": [p.stem for p in files],
                "units": read_units_note(folder),
            }
        )
    return {"sets": sets}


def list_folder(folder: Path, units: str | None) -> dict:
    """What a model folder holds, each mesh loaded and cleaned as the index loads it.

    Returns
    -------
    dict
        ``{"folder", "units", "models": [{"name", "file", "faces", "vertices", "size",
        "mean_edge", "vertices_per_curve", "curved_fraction", "chord_error",
        "sliver_fraction", "too_coarse", "coarse_reasons", "size_ratio",
        "boundary_edges"}], "skipped": [{"file", "reason"}]}``; ``size`` is the
        bounding-box diagonal and ``mean_edge`` the mean edge length, in the models'
        units; ``size_ratio`` the size over the folder's median where
        :func:`meshrec.model.library.size_outliers` flags it (other units?), else None;
        ``boundary_edges`` the edges of one face only (0: closed; else holes, or parts the
        mesh lacks, where a touch can fit elsewhere as well); the resolution fields are
        those of
        :func:`meshrec.model.resolution.mesh_resolution` (default curve length).

    Raises
    ------
    ValueError
        If the folder cannot be listed or holds no mesh file.
    """
    files, skipped = folder_mesh_files(folder)
    models, bad = [], [{"file": p.name, "reason": r} for p, r in skipped]
    seen: set[str] = set()
    for path in files:
        if path.stem in seen:
            bad.append({"file": path.name, "reason": f"duplicate model name {path.stem!r}"})
            continue
        try:
            V, F = load_mesh(path)
        except ValueError as exc:
            bad.append({"file": path.name, "reason": str(exc)})
            continue
        seen.add(path.stem)
        res = mesh_resolution(MeshData.from_arrays(V, F))
        # edges of one face only: holes, or parts the scan or export lacks
        edges = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, uses = np.unique(edges, axis=0, return_counts=True)
        models.append(
            {
                "name": path.stem,
                "file": path.name,
                "faces": len(F),
                "vertices": len(V),
                "size": float(np.linalg.norm(np.ptp(V, axis=0))),
                "mean_edge": float(igl.avg_edge_length(V, F)),
                "vertices_per_curve": res.vertices_per_curve,
                "curved_fraction": res.curved_fraction,
                "chord_error": res.chord_error,
                "sliver_fraction": res.sliver_fraction,
                "too_coarse": res.too_coarse,
                "coarse_reasons": list(res.reasons),
                "boundary_edges": int(np.count_nonzero(uses == 1)),
            }
        )
    ratios = dict(size_outliers([m["size"] for m in models]))
    for k, m in enumerate(models):
        m["size_ratio"] = ratios.get(k)
    return {"folder": str(folder), "units": units, "models": models, "skipped": bad}


def run_models(args, out) -> int:
    """Print the listing of ``meshrec models [DIR|SET] [--json]``; 0."""
    if args.folder is None:
        doc = list_bundled()
        if args.json:
            out.write(json.dumps(doc) + "\n")
            return 0
        out.write(f"{'set':<12} {'units':<6} {'models':>6}  folder\n")
        for s in doc["sets"]:
            units = s["units"] or "-"
            out.write(f"{s['name']:<12} {units:<6} {len(s['models']):>6}  {s['folder']}\n")
        return 0
    folder = model_folder(args.folder)
    doc = list_folder(folder, model_units(folder, args.model_units))
    if args.json:
        out.write(json.dumps(doc) + "\n")
        return 0
    units = doc["units"] or "unknown"
    out.write(f"{doc['folder']}: {len(doc['models'])} models, units {units}\n")
    out.write(
        f"{'model':<24} {'faces':>8} {'vertices':>9} {'size':>10} {'mean edge':>10} "
        f"{'per curve':>9}\n"
    )
    for m in doc["models"]:
        flag = "  too coarse" if m["too_coarse"] else ""
        if m["boundary_edges"]:
            flag += f"  open ({m['boundary_edges']} boundary edges)"
        if m["size_ratio"] is not None:
            flag += f"  size {m['size_ratio']:.3g} x the median: other units?"
        out.write(
            f"{m['name']:<24} {m['faces']:>8} {m['vertices']:>9} {m['size']:>10.4g} "
            f"{m['mean_edge']:>10.4g} {m['vertices_per_curve']:>9.3g}{flag}\n"
        )
    if any(m["too_coarse"] for m in doc["models"]):
        out.write(
            "per curve: vertices a touch curve crosses on the curved faces; too coarse: see "
            "`meshrec index` or --json for why\n"
        )
    for s in doc["skipped"]:
        out.write(f"skipped {s['file']}: {s['reason']}\n")
    return 0
