"""Per-shape report: recognition, localisation error and time of seeded simulated touches.

For every bundled shape, simulate seeded touches, recognise each against the shape's own
library, and print a Markdown table: successes, the localisation error ||p - p*|| (modulo
the shape's symmetries; on the objects' curved sides, modulo their symmetries and the
position along the axis, see ``meshrec.bench.object_localisation_error``) and the wall
time of one recognition.

    .venv/bin/python tools/shape_report.py --trials 10

The paper surfaces use the paper's simulation protocol (61 points per curve, noise
+-0.001); the experiment objects use its experiment's (41 points per curve, +-0.1 mm),
with contacts on their curved sides, away from the rims (``meshrec.bench.protocols.paper_touch``: a
flat cap cannot tell the objects apart, and a curve across a sharp rim has no curvature to
estimate). Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench

MODELS = Path(__file__).resolve().parents[1] / "models"


def _row(library, library_name, name, trials, first_seed):
    ok, errs, times, ratios = 0, [], [], []
    for seed in range(first_seed, first_seed + trials):
        sim = bench.paper_touch(library[name], seed)
        t0 = time.perf_counter()
        rec = meshrec.recognize(sim.touch, library)
        times.append(time.perf_counter() - t0)
        best = rec.best
        if best is not None and best.model == name:
            ok += 1
            if name in meshrec.PAPER_SURFACES:
                errs.append(meshrec.localisation_error(name, sim.contact, best.contact))
            else:
                errs.append(bench.object_localisation_error(name, sim.contact, best.contact))
            wrong = [r.error for r in rec.ranking[1:] if r.error is not None]
            if wrong:
                ratios.append(min(wrong) / best.error)
    return ok, errs, times, ratios


def main(argv: list[str] | None = None) -> int:
    """Print the per-shape table.

    Returns
    -------
    int
        0 when every touch was recognised, 1 otherwise.
    """
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=10, help="touches per shape")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument(
        "--libraries", nargs="+", default=["surfaces", "objects"],
        choices=["surfaces", "objects"], help="bundled libraries to report on",
    )
    p.add_argument("--cache-dir", type=Path, default=None, help="index cache folder")
    args = p.parse_args(argv)

    print(f"meshrec {meshrec.__version__}, Python {platform.python_version()}, "
          f"{platform.machine()}, {args.trials} seeded touches per shape from seed {args.seed}")
    print()
    print("| library | shape | recognised | loc. error median | max | "
          "best wrong / right error (min) | time median (s) | max (s) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    all_ok = True
    for library_name in args.libraries:
        library = meshrec.ModelLibrary.from_folder(MODELS / library_name, cache_dir=args.cache_dir)
        for name in library.names:
            ok, errs, times, ratios = _row(library, library_name, name, args.trials, args.seed)
            all_ok &= ok == args.trials
            loc = (f"{np.median(errs):.4f} | {np.max(errs):.4f}" if errs else "n/a | n/a")
            ratio = f"{np.min(ratios):.2f}" if ratios else "no rival"
            print(f"| {library_name} | {name} | {ok}/{args.trials} | {loc} | {ratio} | "
                  f"{np.median(times):.2f} | {np.max(times):.2f} |")
            sys.stdout.flush()
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
