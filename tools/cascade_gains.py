"""The cascade's gains, measured against the full search.

    nice -n 10 .venv/bin/python tools/cascade_gains.py --blobs 30 --touches 8 --shapes 20 \
        --surfaces 3 --objects 3 --data /tmp/library/data --out reports/cascade_gains.md

``--folder DIR`` adds a library of your own (touched with ``simulate_touch``, seeds from
30, ``--folder-touches`` of them spread over its models).

The cascade (:func:`meshrec.cascade_register`) runs every model's first stages
(:func:`meshrec.register_coarse`) and then the full search only on the models whose best
conceivable fit can still compete (:func:`meshrec.cascade_survivors`): a model's rms is
taken to be at least its least screened error over ``CASCADE_SCREEN_GAIN``, and the
leaders' rms at most the rms that the model of least screened error reaches in its full
search (and at most the least screened error times ``CASCADE_LEADER_GAIN``).

For seeded touches on generated and bundled libraries, this compares every model's least
screened error with the rms of its full search (``recognize(..., cascade=False)``: every
model's own registration, the brute-force reference). Per touch: the largest screened
error / rms over the models whose full-search log-likelihood is within
``JOINT_PRUNE_LOG_RATIO`` (e^-14) of the leader's ("close": the ones the cascade must never
prune) and over all models; how many models the rule keeps for the full search with the
leaders' bound from the screened error alone (the rule before stop 23) and with the rms
reached (the rule now), and how many close ones it would prune (must be 0), at the gain in
use and at smaller ones. Uses only meshrec's public API.
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

GAINS = (defaults.CASCADE_SCREEN_GAIN, 1.5, 1.3)


def _touches(library, n_touches, kind, seed0=0):
    names = library.names
    out = []
    step = max(1, len(names) // max(1, n_touches))
    for k in range(n_touches):
        name = names[(k * step + k) % len(names)]
        if kind == "paper":
            sim = bench.paper_touch(library[name], seed=seed0 + k)
        else:
            sim = meshrec.simulate_touch(library[name], rng=seed0 + k)
        out.append((name, sim.touch))
    return out


def _measure(library, touches, label, rows):
    models = list(library)
    for name, touch in touches:
        c0 = time.process_time()
        rec = meshrec.recognize(touch, models, cascade=False)
        t_full = time.process_time() - c0
        rms = {r.model: r.rms for r in rec.ranking if not r.rejected}
        ll = {s.model: s.log_likelihood for s in rec.scores}
        lead_ll = max(ll.values())
        c0 = time.process_time()
        screened = [meshrec.register_coarse(touch, m, rec.geometry).screened_error for m in models]
        t_coarse = time.process_time() - c0
        known = [(e, m.name) for e, m in zip(screened, models, strict=True) if e is not None]
        if not known:
            continue
        leader = min(known)[1]  # least screened error, ties by name: searched in full first
        close = [
            m.name in rms and ll[m.name] - lead_ll >= defaults.JOINT_PRUNE_LOG_RATIO for m in models
        ]
        ratios = [
            (e / rms[m.name], c)
            for e, m, c in zip(screened, models, close, strict=True)
            if e is not None and m.name in rms and rms[m.name] > 0
        ]
        row = {
            "library": label,
            "model": name,
            "models": len(models),
            "judged": len(known),
            "close": sum(close),
            "close_max": max((r for r, c in ratios if c), default=float("nan")),
            "all_max": max((r for r, _ in ratios), default=float("nan")),
            "right": rec.best is not None and rec.best.model == name,
            "full_cpu": t_full,
            "coarse_cpu": t_coarse,
        }
        n, noise = int(touch.n_points), rec.noise
        for g in GAINS:
            before = meshrec.cascade_survivors(screened, n, noise, screen_gain=g)
            now = meshrec.cascade_survivors(
                screened, n, noise, screen_gain=g, leader_rms=rms[leader]
            )
            row[f"kept_before_{g}"] = int(before.sum())
            row[f"kept_{g}"] = int(now.sum())
            row[f"close_pruned_{g}"] = int(
                sum(c and not k for c, k in zip(close, now, strict=True))
            )
        rows.append(row)
        print(row, file=sys.stderr, flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blobs", type=int, default=30, help="blob library size (0: none)")
    p.add_argument("--shapes", type=int, default=0, help="shape_set library size (0: none)")
    p.add_argument("--surfaces", type=int, default=0, help="touches per paper surface (0: none)")
    p.add_argument("--objects", type=int, default=0, help="touches per bundled object (0: none)")
    p.add_argument("--touches", type=int, default=8, help="touches per generated library")
    p.add_argument("--folder", type=Path, default=None, help="also a folder of your own models")
    p.add_argument(
        "--folder-touches", type=int, default=10, help="touches on --folder (simulate_touch)"
    )
    p.add_argument("--data", type=Path, default=None, help="blobs and cache folder")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="meshrec-cascade-gains-") as tmp:
        data = args.data or Path(tmp)
        if args.blobs:
            folder = blob_folder(data, args.blobs, f"gains_blobs_{args.blobs}")
            library = meshrec.ModelLibrary.from_folder(folder, cache_dir=data / "cache")
            _measure(
                library, _touches(library, args.touches, "paper"), f"blobs ({args.blobs})", rows
            )
        for kind, count in (("surfaces", args.surfaces), ("objects", args.objects)):
            if not count:
                continue
            library = meshrec.ModelLibrary.from_folder(
                meshrec.bundled_models_dir(kind), cache_dir=data / "cache"
            )
            touches = [
                (name, bench.paper_touch(library[name], seed=10 + k).touch)
                for name in library.names
                for k in range(count)
            ]
            _measure(library, touches, f"bundled {kind}", rows)
        if args.shapes:
            bench.write_shapes(bench.shape_set(args.shapes, seed=0), Path(tmp) / "shapes")
            library = meshrec.ModelLibrary.from_folder(
                Path(tmp) / "shapes", cache_dir=Path(tmp) / "cache"
            )
            touches = _touches(library, args.touches, "shape", seed0=20)
            _measure(library, touches, f"shape_set({args.shapes})", rows)
        if args.folder is not None:
            library = meshrec.ModelLibrary.from_folder(args.folder, cache_dir=data / "cache")
            touches = _touches(library, args.folder_touches, "shape", seed0=30)
            _measure(library, touches, args.folder.name, rows)
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    g0 = GAINS[0]
    out = [
        "## Cascade gains: the first stages' screened errors against the full search\n",
        f"Command: `nice -n 10 python tools/cascade_gains.py {shown}`; meshrec "
        f"{meshrec.__version__}. Gains in use: CASCADE_SCREEN_GAIN {g0}, "
        f"CASCADE_LEADER_GAIN {defaults.CASCADE_LEADER_GAIN}. CPU seconds "
        '(time.process_time). "kept": models the rule sends to the full search; '
        '"before": the leaders\' bound from the least screened error x the leader gain '
        'alone; "now": also the rms the model of least screened error reaches.\n',
        "| library | touched | models | judged | close | max screened/rms (close) "
        "| max screened/rms (all) | kept before | kept now | close pruned "
        "| kept now, gain 1.5 | close pruned, 1.5 | kept now, gain 1.3 | close pruned, 1.3 "
        "| right | full CPU s | first stages CPU s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for r in rows:
        out.append(
            f"| {r['library']} | {r['model']} | {r['models']} | {r['judged']} | {r['close']} "
            f"| {r['close_max']:.2f} | {r['all_max']:.2f} | {r[f'kept_before_{g0}']} "
            f"| {r[f'kept_{g0}']} | {r[f'close_pruned_{g0}']} | {r['kept_1.5']} "
            f"| {r['close_pruned_1.5']} | {r['kept_1.3']} | {r['close_pruned_1.3']} "
            f"| {r['right']} | {r['full_cpu']:.2f} | {r['coarse_cpu']:.2f} |"
        )
    if rows:
        libs = sorted({r["library"] for r in rows}, key=[r["library"] for r in rows].index)
        out += [
            "",
            "| library | touches | max screened/rms (close) | kept before | kept now "
            "| kept now, gain 1.5 | kept now, gain 1.3 | close pruned (gain in use, 1.5, 1.3) |",
            "|---|---:|---:|---:|---:|---:|---:|---|",
        ]
        for lib in [*libs, "all"]:
            sel = [r for r in rows if lib in ("all", r["library"])]
            out.append(
                f"| {lib} | {len(sel)} | {np.nanmax([r['close_max'] for r in sel]):.2f} "
                f"| {sum(r[f'kept_before_{g0}'] for r in sel)} "
                f"| {sum(r[f'kept_{g0}'] for r in sel)} | {sum(r['kept_1.5'] for r in sel)} "
                f"| {sum(r['kept_1.3'] for r in sel)} "
                f"| {sum(r[f'close_pruned_{g0}'] for r in sel)}, "
                f"{sum(r['close_pruned_1.5'] for r in sel)}, "
                f"{sum(r['close_pruned_1.3'] for r in sel)} |"
            )
        out.append("")
    return finish(out, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
