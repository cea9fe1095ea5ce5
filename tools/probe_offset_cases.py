"""The probe-offset check on seeded touches with and without a ball tip: warned or not, and why.

Touches recognised without a radius (warm cache, in-process), as in the ball-tip tests:

1. the 12 seeded touches of the four paper surfaces (``bench.paper_touch``, seeds 0-2) and
   one touch per surface with each tip of ``--tips`` (``simulate_touch``, seeds 100+);
2. the tests' sphere (radius 1) and tube (radius 1, side only): one touch per tip in
   ``0`` and ``--tips`` and seed in 1-3 (noise 1e-3, curves 0.6 long), against both.

For each: the best model, whether a ``ProbeOffsetWarning`` was raised, and the check's
evidence as the recognition keeps it (``Recognition.probe_offset``, a ``ProbeOffset``):
its radius, rms0 and rms, the drop of the sum of squares in noise variances that the
warning's chi-squared test reads, and the drop that the residuals linearised at the rigid
optimum predict (``ProbeOffset.linear_drop``, which decides the skip), and the CPU seconds
of the check (``Recognition.phase_times.probe_offset``). Public API only. Prints a
Markdown table (and writes it with ``--out``)::

    python tools/probe_offset_cases.py --out reports/probe_offset.md
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

from _report import finish  # tools/_report.py

import meshrec
from meshrec import bench
from meshrec.contact.probe import ProbeOffsetWarning

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from analytic_meshes import index_of, sphere, tube  # noqa: E402 (the tests' meshes)


def _row(label: str, touch, library) -> str:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = meshrec.recognize(touch, library)
    warned = sum(issubclass(w.category, ProbeOffsetWarning) for w in caught)
    found = rec.probe_offset
    if found is None:
        return f"| {label} | {rec.best.model if rec.best else '-'} | {warned} | | | | | | |"
    n = sum(t.n_points for t in rec.touches)
    var = rec.noise**2
    drop = n * (found.rms0**2 - found.rms**2) / var
    linear = found.linear_drop / var
    return (f"| {label} | {rec.best.model} | {warned} | {found.radius:.4g} | {found.rms0:.4g} | "
            f"{found.rms:.4g} | {drop:.3g} | {linear:.3g} | "
            f"{rec.phase_times.probe_offset:.4f} |")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tips", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.2],
                   help="tip radii of the tipped touches")
    p.add_argument("--out", type=Path, default=None, help="Markdown report (default: stdout)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out = ["# The probe-offset check, case by case", "",
           f"Command: `python tools/probe_offset_cases.py {shown}`", "",
           "Drops in noise variances: n (rms0^2 - rms^2) / noise^2 refined, and the one the "
           "residuals linearised at the rigid optimum predict (the skip's test: below "
           f"{meshrec.defaults.PROBE_OFFSET_CHI2 / meshrec.defaults.PROBE_OFFSET_LINEAR_MARGIN:g}"
           " the joint refinement is skipped).", "",
           "| touch | best | warned | R | rms0 | rms | drop | linearised | CPU s |",
           "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    surfaces = meshrec.ModelLibrary.from_folder(ROOT / "models" / "surfaces")
    meshrec.recognize(bench.paper_touch(surfaces["ellipsoid"], 0).touch, surfaces)  # warm
    for s in meshrec.PAPER_SURFACES:
        for seed in range(3):
            out.append(_row(f"{s} seed {seed}", bench.paper_touch(surfaces[s], seed).touch,
                            surfaces))
        for k, tip in enumerate(args.tips):
            sim = meshrec.simulate_touch(surfaces[s], rng=100 + k, probe_radius=tip)
            out.append(_row(f"{s} tip {tip:g}", sim.touch, surfaces))
    with tempfile.TemporaryDirectory(prefix="meshrec-tips-") as tmp:
        models = {"sphere": index_of(sphere(1.0, 5), Path(tmp), "sphere"),
                  "tube": index_of(tube(1.0, 4.0), Path(tmp), "tube")}
        library = list(models.values())
        for shape, model in models.items():
            for tip in [0.0, *args.tips]:
                for seed in (1, 2, 3):
                    sim = meshrec.simulate_touch(model, rng=seed, probe_radius=tip, noise=1e-3,
                                                 length=0.6, name=shape)
                    out.append(_row(f"{shape} tip {tip:g} seed {seed}", sim.touch, library))
    return finish(out, args.out)


if __name__ == "__main__":
    sys.exit(main())
