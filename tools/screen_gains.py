"""The library-wide screen's gains, measured against the full search.

    nice -n 10 .venv/bin/python tools/screen_gains.py --blobs 30 --touches 8 \
        --data /tmp/library/data --out reports/screen_gains.md

For seeded touches on generated libraries (blobs of ``meshrec.bench.blobs``, touched with
``bench.paper_touch``; optionally ``bench.shape_set`` shapes, touched with
``simulate_touch``) it compares every model's screen estimate
(:func:`meshrec.screen_library`) with the rms of its full search (``recognize(...,
cascade=False)``: every model's own registration, the brute-force reference). The screen's
rule needs one gain: a model's rms is at least its estimate over ``SCREEN_GAIN`` (the best
model's rms is bounded by the rms that the ``SCREEN_LEADERS`` models of least estimate
reach). The table gives, per touch, the largest estimate / rms over the models whose
full-search log-likelihood is within ``JOINT_PRUNE_LOG_RATIO`` (e^-14) of the leader's
("close": the ones the screen must never prune) and over all models, the leaders' least
rms over the best rms (1: the leaders hold the best model), and what the rule prunes.
Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench, defaults

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _libraries import blob_folder  # tools/_libraries.py
from _report import finish  # tools/_report.py


def _touches(library, names, n_touches, kind):
    out = []
    step = max(1, len(names) // max(1, n_touches))
    for k in range(n_touches):
        name = names[(k * step + k) % len(names)]
        if kind == "blob":
            sim = bench.paper_touch(library[name], seed=k)
        else:
            sim = meshrec.simulate_touch(library[name], rng=k)
        out.append((name, sim.touch))
    return out


def _measure(library, touches, label, rows):
    sites = meshrec.library_sites(list(library))
    for name, touch in touches:
        geometry = meshrec.estimate_local_geometry(
            touch.curves, point=touch.contact, normal=touch.normal
        )
        c0 = time.process_time()
        screen = meshrec.screen_library(touch, geometry, sites)
        t_screen = time.process_time() - c0
        c0 = time.process_time()
        rec = meshrec.recognize(touch, library, cascade=False)
        t_full = time.process_time() - c0
        rms = {r.model: r.rms for r in rec.ranking if not r.rejected}
        ll = {s.model: s.log_likelihood for s in rec.scores}
        lead = max(ll.values())
        est = dict(zip(sites.names, screen.estimates, strict=True))
        judged = [m for m in sites.names if np.isfinite(est[m]) and m in rms]
        close = [m for m in judged if ll[m] - lead >= defaults.JOINT_PRUNE_LOG_RATIO]
        leaders = [
            sites.names[i]
            for i in meshrec.screen_leaders(screen, sites.names, defaults.SCREEN_LEADERS)
        ]
        lead_rms = min((rms[m] for m in leaders if m in rms), default=None)
        keep = meshrec.screen_survivors(screen, int(touch.n_points), rec.noise, lead_rms)
        kept = dict(zip(sites.names, keep, strict=True))
        rows.append(
            {
                "library": label,
                "model": name,
                "models": len(sites.names),
                "judged": len(judged),
                "close": len(close),
                "close_max": max((est[m] / rms[m] for m in close), default=float("nan")),
                "all_max": max((est[m] / rms[m] for m in judged), default=float("nan")),
                "leader": (lead_rms / min(rms.values()) if lead_rms is not None else float("nan")),
                "pruned": sum(not kept[m] for m in sites.names),
                "pruned_close": sum(not kept[m] for m in close),
                "right": rec.best is not None and rec.best.model == name,
                "screen_cpu": t_screen,
                "full_cpu": t_full,
            }
        )
        print(rows[-1], file=sys.stderr, flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blobs", type=int, default=30, help="blob library size (0: none)")
    p.add_argument("--shapes", type=int, default=0, help="shape_set library size (0: none)")
    p.add_argument("--surfaces", type=int, default=0, help="touches per paper surface (0: none)")
    p.add_argument("--touches", type=int, default=8, help="touches per library")
    p.add_argument("--data", type=Path, default=None, help="blobs and cache folder")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="meshrec-gains-") as tmp:
        data = args.data or Path(tmp)
        if args.blobs:
            folder = blob_folder(data, args.blobs, f"gains_blobs_{args.blobs}")
            library = meshrec.ModelLibrary.from_folder(folder, cache_dir=data / "cache")
            touches = _touches(library, library.names, args.touches, "blob")
            _measure(library, touches, f"blobs ({args.blobs})", rows)
        if args.surfaces:
            library = meshrec.ModelLibrary.from_folder(
                meshrec.bundled_models_dir("surfaces"), cache_dir=data / "cache"
            )
            touches = [
                (name, bench.paper_touch(library[name], seed=k).touch)
                for name in library.names
                for k in range(args.surfaces)
            ]
            _measure(library, touches, "paper surfaces", rows)
        if args.shapes:
            shapes = bench.shape_set(args.shapes, seed=0)
            bench.write_shapes(shapes, Path(tmp) / "shapes")
            library = meshrec.ModelLibrary.from_folder(
                Path(tmp) / "shapes", cache_dir=Path(tmp) / "cache"
            )
            touches = _touches(library, library.names, args.touches, "shape")
            _measure(library, touches, f"shape_set({args.shapes})", rows)
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out = [
        "## Screen gains: the library-wide screen's estimates against the full search\n",
        f"Command: `nice -n 10 python tools/screen_gains.py {shown}`. Gains in use: "
        f"SCREEN_GAIN {defaults.SCREEN_GAIN}, SCREEN_LEADERS {defaults.SCREEN_LEADERS}. "
        "CPU seconds (time.process_time).\n",
        "| library | touched | models | judged | close | max est/rms (close) "
        "| max est/rms (all) | leaders' rms / best rms | pruned | pruned close | right "
        "| screen CPU s | full CPU s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for r in rows:
        out.append(
            f"| {r['library']} | {r['model']} | {r['models']} | {r['judged']} | {r['close']} "
            f"| {r['close_max']:.2f} | {r['all_max']:.2f} | {r['leader']:.2f} "
            f"| {r['pruned']} | {r['pruned_close']} | {r['right']} "
            f"| {r['screen_cpu']:.3f} | {r['full_cpu']:.2f} |"
        )
    if rows:
        out.append("")
        out.append(
            f"Over all touches: max est/rms on close pairs "
            f"{np.nanmax([r['close_max'] for r in rows]):.2f}, leaders' rms / best rms "
            f"max {np.nanmax([r['leader'] for r in rows]):.2f}; pruned "
            f"{sum(r['pruned'] for r in rows)} of {sum(r['models'] for r in rows)} pairs, "
            f"close ones pruned: {sum(r['pruned_close'] for r in rows)}.\n"
        )
    return finish(out, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
