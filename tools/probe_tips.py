"""Ball-tipped probes (issue 13, item 6): recognition with and without the tip radius.

A probe with a ball tip records the ball's centre, on the surface offset outwards by the
tip radius. For tip radii 0, 0.5, 1 and 2 mm, seeded touches are simulated with that tip
(``simulate_touch(..., probe_radius=R)``) and recognised twice: told the radius
(``recognize(..., probe_radius=R)``, as ``--probe-radius R``) and not told. Per radius:
right answers (best model is the touched one), recognised and right, the median contact
error (on the surface, modulo the shape's symmetries), how often the undeclared-tip
warning (ProbeOffsetWarning) fired, and the median time.

Two libraries:

* ``objects``: the paper's experiment objects (``models/objects``, mm: cylinders of radius
  25.2 and 47 mm, an elliptic cylinder 50.8 x 31.75 mm, a sphere), its protocol (41 points
  per curve, noise +-0.1 mm, contacts on the curved sides 30 mm from the rims);
* ``surfaces``: the paper's four unit-size surfaces (``models/surfaces``), read at the
  scale 1 unit = ``--unit-mm`` mm (default 20: the ellipsoid is 40 x 32 x 20 mm, its
  tightest radius of curvature 5 mm), the paper's simulation protocol (61 points, noise
  +-0.001 units = +-0.02 mm at that scale).

    .venv/bin/python tools/probe_tips.py --trials 3 --out reports/probe_tips.md

Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench, defaults

TIPS_MM = (0.0, 0.5, 1.0, 2.0)


def _contact(model, rng):
    """The paper's objects: a contact on the curved side away from the rims; else None."""
    if model.name not in bench.OBJECT_SIDES:
        return None
    a, b, half = bench.OBJECT_SIDES[model.name]
    theta = rng.uniform(0, 2 * np.pi)
    z = rng.uniform(-(half - defaults.BENCH_RIM_MARGIN), half - defaults.BENCH_RIM_MARGIN)
    return np.array([a * np.cos(theta), b * np.sin(theta), z])


def _loc(name, true_contact, found_contact) -> float:
    if name in meshrec.PAPER_SURFACES:
        return meshrec.localisation_error(name, true_contact, found_contact)
    return bench.object_localisation_error(name, true_contact, found_contact)


def _recognise(touch, library, radius):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        rec = meshrec.recognize(touch, library, probe_radius=radius)
        seconds = time.perf_counter() - t0
    fired = [w for w in caught if issubclass(w.category, meshrec.ProbeOffsetWarning)]
    return rec, bool(fired), seconds


def run(library, tips, trials, n_points, noise, log):
    """Rows ``(tip, told, shape, seed, right, recognised, loc, warned, seconds)``."""
    rows = []
    for model in library:
        length = defaults.SIM_LENGTH_FRACTION * model.mesh.scale
        for seed in range(trials):
            for tip in tips:
                rng = np.random.default_rng(seed)
                contact = _contact(model, rng)
                sim = meshrec.simulate_touch(
                    model,
                    contact=contact,
                    rng=rng,
                    n_points=n_points,
                    noise=noise,
                    length=length,
                    probe_radius=tip,
                    name=model.name,
                )
                for told in (False, True) if tip > 0 else (False,):
                    rec, warned, seconds = _recognise(sim.touch, library, tip if told else 0.0)
                    best = rec.best.model if rec.best is not None else None
                    right = best == model.name
                    found = {r.model: r for r in rec.ranking}[model.name]
                    loc = (
                        _loc(model.name, sim.contact, found.contact)
                        if not found.rejected
                        else float("inf")
                    )
                    rows.append(
                        (tip, told, model.name, seed, right, right and rec.verdict == "recognised",
                         loc, warned, seconds)
                    )
                    log(
                        f"  {model.name} seed {seed} tip {tip:g} told={told}: {best} "
                        f"{rec.verdict} loc {loc:.3g} warned={warned} {seconds:.1f} s"
                    )
    return rows


def table(rows, tips, scale_mm, unit) -> list[str]:
    """The Markdown table of one library's rows."""
    both = unit != "mm"
    out = [
        "| tip (mm) | " + (f"tip ({unit}) | " if both else "") + "radius given | right | "
        f"recognised & right | median contact error ({unit}) | undeclared-tip warnings | "
        "median s |",
        "|---:|" + ("---:|" if both else "") + ":---|---:|---:|---:|---:|---:|",
    ]
    for tip in tips:
        for told in (False, True) if tip > 0 else (False,):
            sel = [r for r in rows if r[0] == tip and r[1] == told]
            n = len(sel)
            right = sum(r[4] for r in sel)
            rec = sum(r[5] for r in sel)
            loc = statistics.median(r[6] for r in sel)
            warned = sum(r[7] for r in sel)
            secs = statistics.median(r[8] for r in sel)
            out.append(
                f"| {tip * scale_mm:g} | " + (f"{tip:g} | " if both else "")
                + f"{'yes' if told else 'no'} | "
                f"{right}/{n} ({100 * right / n:.0f}%) | {rec}/{n} | {loc:.3g} | "
                f"{warned}/{n} | {secs:.2f} |"
            )
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trials", type=int, default=3, help="touches per shape and tip")
    p.add_argument("--unit-mm", type=float, default=20.0, help="mm per unit of the surfaces")
    p.add_argument("--libraries", nargs="+", default=["objects", "surfaces"])
    p.add_argument("--cache-dir", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="also write the report here")
    args = p.parse_args(argv)

    def log(text):
        print(text, file=sys.stderr, flush=True)

    root = meshrec.bundled_models_dir().parent
    lines = [
        "# Probe tips: recognition with and without the tip radius",
        "",
        "Touches simulated with a ball tip (the data are the ball's centres, on the surface "
        "offset outwards by the radius), recognised told the radius (`--probe-radius`) "
        "and not told. *right*: the best model is the touched one; *recognised & right*: "
        "and the verdict is `recognised`; contact error on the surface, modulo the shape's "
        "symmetries (the objects: what a side touch cannot see, see "
        "`meshrec.bench.object_localisation_error`); *undeclared-tip warnings*: "
        "`ProbeOffsetWarning` raised.",
        "",
        f"Command: `python tools/probe_tips.py --trials {args.trials} --unit-mm "
        f"{args.unit_mm:g}`; {platform.machine()}, {os.cpu_count()} cores shared with other "
        "jobs, run with `nice -n 10`, OMP_NUM_THREADS=1.",
        "",
    ]
    t0 = time.perf_counter()
    for name in args.libraries:
        folder = root / name
        library = meshrec.ModelLibrary.from_folder(folder, cache_dir=args.cache_dir)
        if name == "objects":
            scale, unit, tips = 1.0, "mm", TIPS_MM
            n_points, noise = defaults.BENCH_OBJECT_POINTS, defaults.BENCH_OBJECT_NOISE
            what = (
                f"## Objects (models/objects, mm): {args.trials} touches per object and tip, "
                f"{n_points} points per curve, noise +-{noise:g} mm"
            )
        else:
            scale, unit = args.unit_mm, "units"
            tips = tuple(t / scale for t in TIPS_MM)
            n_points, noise = defaults.SIM_POINTS, defaults.SIM_NOISE
            what = (
                f"## Surfaces (models/surfaces, unit size, read as 1 unit = {scale:g} mm): "
                f"{args.trials} touches per surface and tip, {n_points} points per curve, "
                f"noise +-{noise:g} units (+-{noise * scale:g} mm)"
            )
        log(what)
        rows = run(library, tips, args.trials, n_points, noise, log)
        lines += [what, "", *table(rows, tips, scale, unit), ""]
    lines.append(f"Total time {time.perf_counter() - t0:.0f} s.")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
