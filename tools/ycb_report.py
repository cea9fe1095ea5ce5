"""Real scanned meshes: recognition of simulated touches on the YCB objects.

    .venv/bin/python tools/ycb_report.py --models ../shared/data/ycb --trials 20

Indexes a folder of scanned models (the YCB set: metres, 15,728 triangles each),
simulates seeded touches on each object (61 points per curve, noise +-1e-4 m, the
accuracy of a robot's touch probe; contacts uniform by area, curves 0.22 sqrt(area)
long), recognises each against the whole folder, and prints per object: successes, the
localisation error ||p - p*|| (plain Euclidean: no symmetries are assumed, so a
symmetric object's twin contact counts as an error), how often the registration reached
the oracle's minimum (error within 5% of the refinement started at the true pose: on a
symmetric object a twin contact does), the errors on the right and the best wrong
model, the wall time per recognition, and the CPU time per touch (the whole trial:
simulation, the oracle's refinement and the recognition; steadier than wall time on a
loaded machine). Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", type=Path, required=True, help="folder of model meshes")
    p.add_argument("--trials", type=int, default=20, help="touches per object")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--noise", type=float, default=1e-4, help="uniform noise +-A, model units")
    p.add_argument("--only", nargs="*", default=None, help="objects to touch (default: all)")
    p.add_argument("--out", type=Path, default=None, help="also write the report here")
    args = p.parse_args(argv)
    lines = []

    def emit(text=""):
        print(text)
        sys.stdout.flush()
        lines.append(text)

    t0 = time.perf_counter()
    library = meshrec.ModelLibrary.from_folder(args.models)
    build = time.perf_counter() - t0
    shapes = args.only or list(library.names)
    cmd = " ".join(["python tools/ycb_report.py", *(argv if argv is not None else sys.argv[1:])])
    emit("# YCB report\n")
    emit(f"Command: `{cmd}`; meshrec {meshrec.__version__}.\n")
    emit(f"{len(library.names)} models indexed in {build:.1f} s; {args.trials} touches per "
         f"object, seeds {args.seed}..{args.seed + args.trials - 1}, noise +-{args.noise:g}; "
         "each touch recognised against the whole folder.")
    emit()
    emit("| object | faces | recognised | at the oracle's minimum | loc. error median | max "
         "| right error median | best wrong / right (min) | rejected by lookup (mean of models) "
         "| time median (s) | CPU per touch (s) |")
    emit("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    total = 0
    cpu_all = 0.0
    for name in shapes:
        c0 = time.process_time()
        rows = bench.run_trials(library, [name], args.trials, args.seed, noise=args.noise)
        cpu = (time.process_time() - c0) / max(len(rows), 1)
        cpu_all += cpu * len(rows)
        ok = sum(t.recognised for t in rows)
        total += ok
        loc = np.array([t.loc_error for t in rows])
        right = np.array([t.right_error for t in rows if t.right_error is not None])
        ratios = [t.wrong_error / t.right_error for t in rows
                  if t.wrong_error is not None and t.right_error]
        rejected = np.mean([sum(e is None for e in t.errors.values()) for t in rows])
        at_oracle = sum(
            t.right_error is not None and t.right_error <= 1.05 * t.oracle_error for t in rows
        )
        emit(f"| {name} | {len(library[name].mesh.faces):,} | {ok}/{len(rows)} "
             f"| {at_oracle}/{len(rows)} "
             f"| {np.median(loc):.2e} | {loc.max():.2e} | {np.median(right):.2e} "
             f"| {min(ratios) if ratios else float('nan'):.2f} | {rejected:.1f} "
             f"| {np.median([t.seconds for t in rows]):.2f} | {cpu:.2f} |")
    emit()
    n_touches = len(shapes) * args.trials
    emit(f"recognised {total}/{n_touches}; CPU {cpu_all / max(n_touches, 1):.2f} s per touch, "
         f"{cpu_all / max(n_touches, 1) / len(library.names):.3f} s per model per touch")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
