"""A tolerance of the method: what a looser one saves, and what it changes.

    nice -n 5 .venv/bin/python tools/tolerances.py --name CHART_TOL --values 1e-5 1e-3 1e-2 \
        --surfaces 3 --objects 3 --shapes 20 --shape-touches 8 --out reports/chart_tol.md

``--name`` is one of the tolerances below (in ``meshrec.defaults``, read at call time):

* ``CHART_TOL``: each local search (``meshrec.registration.search``) solves a least-squares
  problem over a surface chart's (u, v, phi) to this relative tolerance (ftol and xtol),
  re-centres the chart and solves again until it stops moving; the rigid refinement that
  follows (``refine_searches``) polishes its answer.
* ``REFINE_REL_TOL``: every rigid refinement (the final one of each search, the joint
  ones of several touches, the probe-offset check's) stops at the first step that lowers
  the sum of squares by less than this fraction.
* ``REFINE_DAMPING_SCHEDULE`` (values are names, ``gain`` or ``tenfold``): how those
  refinements' Levenberg-Marquardt damping moves between steps
  (``meshrec.registration.damping``).
* ``PHI_GRID_DISTANCES`` (names, ``exact`` or ``fields``): how the phi grid of stage 2
  computes its distances (``meshrec.registration.fields``).

For seeded touches (``bench.paper_touch`` on the four paper surfaces and the four bundled
objects, ``simulate_touch`` on ``bench.shape_set`` and on ``--folder DIR``, a library of
your own: touch k on its model k modulo their number, seed k), every value recognises
every touch, one after the other touch by touch (so that each touch's runs see about the
same machine load). Per value: verdicts, best models and plausible sets (as sets) equal
to those of the first value given (the reference), the median relative change of the best
error and its largest rise and fall (where the best model is the same), the localisation
error of the best contact on the paper surfaces (modulo their symmetries: the mean, and
the largest change against the reference; the other models' symmetries are not known
here), the phi, screening, search and
refinement stages' times (``Registration.times``, wall clock summed over the models) and the
recognition's CPU time (``time.process_time``), medians per touch and as a ratio to the
reference's. Uses only meshrec's public API, and sets the tolerance in ``meshrec.defaults``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench, defaults

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import finish  # tools/_report.py

MODELS = Path(__file__).resolve().parents[1] / "models"


def _localisation(name: str, true_contact, rec) -> float:
    """Modulo the symmetries on a paper surface; not defined elsewhere (NaN)."""
    if rec.best is None or name not in meshrec.PAPER_SURFACES:
        return float("nan")
    return meshrec.localisation_error(name, true_contact, np.asarray(rec.best.contact))


def _fmt(values: np.ndarray, stat) -> str:
    """``stat`` of the finite values, or '-' when there are none."""
    finite = values[np.isfinite(values)]
    return "-" if len(finite) == 0 else f"{stat(finite):.4f}"


TOLERANCES = ("CHART_TOL", "REFINE_REL_TOL", "REFINE_DAMPING_SCHEDULE", "PHI_GRID_DISTANCES")
#: The settings whose values are names rather than numbers.
NAMED = ("REFINE_DAMPING_SCHEDULE", "PHI_GRID_DISTANCES")


def _show(value) -> str:
    return value if isinstance(value, str) else f"{value:g}"


def _run_one(touch, library, name, value):
    setattr(defaults, name, value)
    c0 = time.process_time()
    rec = meshrec.recognize(touch, library)
    cpu = time.process_time() - c0
    stages = sum((r.times for r in rec.ranking), meshrec.StageTimes())
    return rec, cpu, stages


def _compare(label, library, touches, name, values, out):
    """Every value on every touch; append the library's table to ``out``."""
    meshrec.recognize(touches[0][2], library)  # warm: lazy tables, imports
    rows = {v: [] for v in values}
    for shape, contact, touch in touches:
        for value in values:
            rec, cpu, stages = _run_one(touch, library, name, value)
            rows[value].append(
                {
                    "verdict": rec.verdict,
                    "best": None if rec.best is None else rec.best.model,
                    "plausible": tuple(rec.plausible),
                    "error": np.nan if rec.best is None else rec.best.error,
                    "loc": _localisation(shape, contact, rec),
                    "right": rec.best is not None and rec.best.model == shape,
                    "cpu": cpu,
                    "phi": stages.phi,
                    "screen": stages.screen,
                    "search": stages.search,
                    "refine": stages.refine,
                }
            )
    ref = rows[values[0]]
    n = len(touches)
    out.append(f"### {label}: {len(library)} models, {n} touches\n")
    out.append(
        f"| {name} | same verdict | same best | same plausible | right best | "
        "best error, relative change: median | largest rise | largest fall | localisation "
        "mean | localisation, largest change | phi stage median (s) | screening stage median "
        "(s) | search stage median (s) | refinement stage median (s) | CPU median (s) | "
        "CPU / reference, median |"
    )
    out.append("|" + "---:|" * 16)
    for value in values:
        r = rows[value]
        same_v = sum(a["verdict"] == b["verdict"] for a, b in zip(r, ref, strict=True))
        same_b = sum(a["best"] == b["best"] for a, b in zip(r, ref, strict=True))
        same_p = sum(
            set(a["plausible"]) == set(b["plausible"]) for a, b in zip(r, ref, strict=True)
        )
        right = sum(a["right"] for a in r)
        rel = [
            a["error"] / b["error"] - 1.0
            for a, b in zip(r, ref, strict=True)
            if a["best"] == b["best"] and b["error"] > 0
        ]
        loc = np.array([a["loc"] for a in r])
        dloc = np.array([abs(a["loc"] - b["loc"]) for a, b in zip(r, ref, strict=True)])
        cpu = np.array([a["cpu"] for a in r])
        ratio = np.median(cpu / np.array([b["cpu"] for b in ref]))
        out.append(
            f"| {_show(value)} | {same_v}/{n} | {same_b}/{n} | {same_p}/{n} | {right}/{n} | "
            f"{np.median(rel) if rel else 0.0:+.2e} | "
            f"{max(max(rel, default=0.0), 0.0):.2e} | "
            f"{abs(min(min(rel, default=0.0), 0.0)):.2e} | "
            f"{_fmt(loc, np.mean)} | {_fmt(dloc, np.max)} | "
            f"{np.median([a['phi'] for a in r]):.3f} | "
            f"{np.median([a['screen'] for a in r]):.3f} | "
            f"{np.median([a['search'] for a in r]):.3f} | "
            f"{np.median([a['refine'] for a in r]):.3f} | {np.median(cpu):.3f} | "
            f"{ratio:.2f} |"
        )
    out.append("")


def _paper_touches(library, names, trials):
    out = []
    for name in names:
        for seed in range(trials):
            sim = bench.paper_touch(library[name], seed=seed)
            out.append((name, sim.contact, sim.touch))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--name", choices=TOLERANCES, default="CHART_TOL", help="the tolerance")
    p.add_argument(
        "--values",
        nargs="+",
        default=["1e-5", "1e-3", "1e-2"],
        help="its values; the first is the reference",
    )
    p.add_argument("--surfaces", type=int, default=3, help="touches per paper surface")
    p.add_argument("--objects", type=int, default=3, help="touches per bundled object")
    p.add_argument("--shapes", type=int, default=20, help="bench.shape_set size (0: none)")
    p.add_argument("--shape-touches", type=int, default=8, help="touches on the shape set")
    p.add_argument("--folder", type=Path, default=None, help="also a folder of your own models")
    p.add_argument(
        "--folder-touches",
        type=int,
        default=10,
        help="touches on --folder (simulate_touch, spread over its models)",
    )
    p.add_argument("--cache-dir", type=Path, default=None, help="index cache for --folder")
    p.add_argument("--out", type=Path, default=None, help="Markdown report (default: stdout)")
    args = p.parse_args(argv)
    name = args.name
    if name in NAMED:
        values = args.values
    else:
        try:
            values = [float(v) for v in args.values]
        except ValueError:
            p.error(f"--values of {name} must be numbers, got {args.values}")
        if any(not v > 0 for v in values):
            p.error(f"--values must be positive, got {args.values}")
    saved = getattr(defaults, name)
    out = [f"## `defaults.{name}` ({_show(saved)} in use)\n"]
    try:
        if args.surfaces:
            lib = meshrec.ModelLibrary.from_folder(MODELS / "surfaces")
            touches = _paper_touches(lib, meshrec.PAPER_SURFACES, args.surfaces)
            _compare("The four paper surfaces", lib, touches, name, values, out)
        if args.objects:
            lib = meshrec.ModelLibrary.from_folder(MODELS / "objects")
            touches = _paper_touches(lib, lib.names, args.objects)
            _compare("The four bundled objects", lib, touches, name, values, out)
        if args.shapes:
            with tempfile.TemporaryDirectory(prefix="meshrec-tolerances-") as tmp:
                shapes = bench.shape_set(args.shapes, seed=0)
                bench.write_shapes(shapes, Path(tmp) / "models")
                lib = meshrec.ModelLibrary.from_folder(
                    Path(tmp) / "models", cache_dir=Path(tmp) / "cache"
                )
                step = max(1, args.shapes // max(1, args.shape_touches))
                touches = []
                for k in range(args.shape_touches):
                    shape = shapes[(k * step) % args.shapes].name
                    sim = meshrec.simulate_touch(lib[shape], rng=k)
                    touches.append((shape, sim.contact, sim.touch))
                label = f"bench.shape_set({args.shapes}, seed=0)"
                _compare(label, lib, touches, name, values, out)
        if args.folder is not None:
            lib = meshrec.ModelLibrary.from_folder(args.folder, cache_dir=args.cache_dir)
            touches = []
            for k in range(args.folder_touches):
                shape = lib.names[k % len(lib.names)]
                sim = meshrec.simulate_touch(lib[shape], rng=k)
                touches.append((shape, sim.contact, sim.touch))
            _compare(f"{args.folder.name} (`--folder`)", lib, touches, name, values, out)
    finally:
        setattr(defaults, name, saved)
    return finish(out, args.out)


if __name__ == "__main__":
    sys.exit(main())
