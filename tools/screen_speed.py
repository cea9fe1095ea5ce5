"""The library-wide screen's speed: recognitions with and without it, the same touches.

    nice -n 10 .venv/bin/python tools/screen_speed.py --models 100 --touches 3 \
        --data /tmp/library/data --out reports/screen_speed.md

On a library of ``--models`` blobs (``meshrec.bench.blobs``, as ``tools/scale.py`` makes
them; warm cache), seeded touches (``bench.paper_touch`` on the model ``seed * 7919 mod
n``, as ``tools/scale.py``) are recognised in one process with the screen (the default)
and without it (``defaults.SCREEN_MIN_MODELS`` set above the library's size: the cascade
alone, as before the screen): CPU time per recognition (``time.process_time``), the
models searched in full, and whether the verdict, plausible set, best model and best
error are the same. Prints a Markdown table (and writes it with ``--out``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import meshrec
from meshrec import bench, defaults

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import finish  # tools/_report.py


def _answer(rec) -> tuple:
    best = rec.best
    return (
        rec.verdict,
        tuple(rec.plausible),
        None if best is None else best.model,
        None if best is None else best.error,
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", type=int, default=100)
    p.add_argument("--touches", type=int, default=3)
    p.add_argument("--data", type=Path, default=None, help="blobs and cache folder")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory(prefix="meshrec-screen-") as tmp:
        data = args.data or Path(tmp)
        folder = data / f"library_{args.models}"
        folder.mkdir(parents=True, exist_ok=True)
        for f in bench.write_blobs(args.models, data / "blobs"):
            if not (folder / f.name).exists():
                (folder / f.name).hardlink_to(f)
        library = meshrec.ModelLibrary.from_folder(folder, cache_dir=data / "cache")
        names = library.names
        n = len(names)
        screen_min = defaults.SCREEN_MIN_MODELS
        rows = []
        for seed in range(args.touches):
            true = names[(seed * 7919) % n]
            touch = bench.paper_touch(library[true], seed=seed).touch
            row = {"seed": seed, "model": true}
            for label, threshold in (("screen", screen_min), ("cascade", n + 1)):
                defaults.SCREEN_MIN_MODELS = threshold
                c0 = time.process_time()
                rec = meshrec.recognize(touch, library)
                row[label] = {
                    "cpu": time.process_time() - c0,
                    "searched": sum(r.searches > 0 for r in rec.ranking),
                    "pruned": sum(r.pruned for r in rec.ranking),
                    "answer": _answer(rec),
                }
            defaults.SCREEN_MIN_MODELS = screen_min
            row["same"] = row["screen"]["answer"] == row["cascade"]["answer"]
            rows.append(row)
            print(row, file=sys.stderr, flush=True)
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out = [
        "## The library-wide screen: recognitions with and without it\n",
        f"Command: `nice -n 10 python tools/screen_speed.py {shown}` ({os.cpu_count()} "
        f"logical CPUs shared with other work; load average {os.getloadavg()[0]:.1f} at the "
        "end). CPU seconds per recognition (time.process_time).\n",
        "| touch (model) | verdict | CPU s, cascade alone | CPU s, screen + cascade "
        "| ratio | searched in full (alone; screen) | same answer |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        a, b = r["cascade"], r["screen"]
        out.append(
            f"| {r['seed']} ({r['model']}) | {b['answer'][0]} | {a['cpu']:.1f} | {b['cpu']:.1f} "
            f"| {b['cpu'] / a['cpu']:.2f} | {a['searched']}; {b['searched']} | {r['same']} |"
        )
    if rows:
        med_a = statistics.median(r["cascade"]["cpu"] for r in rows)
        med_b = statistics.median(r["screen"]["cpu"] for r in rows)
        out.append("")
        out.append(
            f"Median CPU per recognition: {med_a:.1f} s alone ({med_a / n:.3f} s per model), "
            f"{med_b:.1f} s with the screen ({med_b / n:.3f} s per model); same answers "
            f"{sum(r['same'] for r in rows)}/{len(rows)}.\n"
        )
    return finish(out, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
