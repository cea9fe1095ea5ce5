"""Per-shape report: recognition, localisation error and time of seeded simulated touches.

For every bundled shape, simulate seeded touches, recognise each against the shape's own
library, and print a Markdown table: successes, the localisation error ||p - p*|| (modulo
the shape's symmetries; on the objects' curved sides, modulo their symmetries and the
position along the axis, see ``_object_loc_error``) and the wall time of one recognition.

    .venv/bin/python tools/shape_report.py --trials 10

The paper surfaces use the paper's simulation protocol (61 points per curve, noise
+-0.001); the experiment objects use its experiment's (41 points per curve, +-0.1 mm),
with contacts on their curved sides, away from the rims (a flat cap cannot tell the
objects apart, and a curve across a sharp rim has no curvature to estimate). Uses only
meshrec's public API.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

import meshrec

MODELS = Path(__file__).resolve().parents[1] / "models"


def _touch(model, library_name, seed):
    if library_name == "surfaces":
        return meshrec.simulate_touch(model, rng=seed)
    # Objects: redraw (deterministically) until the contact is on a curved side, far
    # enough from the rims (|z| < 20 mm of the 50 mm half-height) that no curve crosses
    # a sharp edge onto a flat cap.
    for k in range(1000):
        sim = meshrec.simulate_touch(model, rng=seed * 1000 + k, n_points=41, noise=0.1)
        if model.name == "sphere" or (abs(sim.normal[2]) < 0.1 and abs(sim.contact[2]) < 20):
            return sim
    raise RuntimeError(f"no side contact found on {model.name}")


def _object_loc_error(name, true_contact, found_contact):
    """||p - p*|| modulo the object's symmetries, on its curved side.

    Away from the caps a touch cannot see where along the axis it is, so the axial
    coordinate is free. The elliptic cylinder keeps its four symmetries of the ellipse
    (sign flips of x and y); on a circular cylinder every side point is equivalent, and on
    the sphere every point, so what remains there is the radial distance.
    """
    p, q = np.asarray(true_contact), np.asarray(found_contact)
    if name == "sphere":
        return abs(np.linalg.norm(p) - np.linalg.norm(q))
    if name == "elliptic_cylinder":
        flips = np.array([[1, 1], [-1, 1], [1, -1], [-1, -1]])
        return float(np.min(np.linalg.norm(p[:2] - flips * q[:2], axis=1)))
    return abs(np.linalg.norm(p[:2]) - np.linalg.norm(q[:2]))


def _row(library, library_name, name, trials, first_seed):
    ok, errs, times, ratios = 0, [], [], []
    for seed in range(first_seed, first_seed + trials):
        sim = _touch(library[name], library_name, seed)
        t0 = time.perf_counter()
        rec = meshrec.recognize(sim.touch, library)
        times.append(time.perf_counter() - t0)
        best = rec.best
        if best is not None and best.model == name:
            ok += 1
            if name in meshrec.PAPER_SURFACES:
                errs.append(meshrec.localisation_error(name, sim.contact, best.contact))
            else:
                errs.append(_object_loc_error(name, sim.contact, best.contact))
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
