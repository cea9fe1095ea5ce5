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

This script is the entry point; the work is done by the modules of ``tools/shapes/`` (one
per job: parameters, parametrisation, meshing, measuring, the README table).

The script is deterministic: running it twice writes byte-identical files.

Usage::

    .venv/bin/python tools/make_models.py [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from shapes.catalogue import all_models
from shapes.export import write_model
from shapes.measure import measure_mesh
from shapes.readme import measurement_table, readme_text

_REPO = Path(__file__).resolve().parent.parent
_DEFAULT_OUT = _REPO / "models"
_PARTS_MARKER = "<!-- make_parts.py -->"


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

    models = all_models()
    rows = []
    for model in models:
        path, mesh = write_model(model, out)
        measured = measure_mesh(mesh, model.distance)
        units = "mm" if model.library == "objects" else "unit"
        relative = path.relative_to(out).as_posix()
        rows.append((relative, units, measured, path.stat().st_size))
        print(f"wrote {path}", flush=True)
    table = measurement_table(rows)
    print(table, end="")
    readme = out / "README.md"
    # Keep the section that tools/make_parts.py writes after its marker line.
    old = readme.read_text(encoding="utf-8") if readme.exists() else ""
    tail = old[old.index(_PARTS_MARKER) :] if _PARTS_MARKER in old else ""
    text = readme_text(models, table)
    readme.write_text(text + ("\n" + tail if tail else ""), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
