"""Recognitions serially and with ``--workers`` processes, the same touches, back to back.

    PYTHONPATH=. nice -n 10 .venv/bin/python tools/workers_speed.py --models 100 \
        --touches 2 --workers 2 --data /tmp/workers/data --out reports/workers_speed.md

On a library of ``--models`` blobs (``meshrec.bench.blobs``, as ``tools/scale.py`` makes
them; the cache is warmed first), seeded touches (``bench.paper_touch`` on the model
``seed * 7919 mod n``, as ``tools/scale.py``) are recognised in one process (the
default: screen and cascade), then with ``--workers`` local processes started for the
touch and closed after it (their start not timed), and, unless ``--no-full``, by a held
``ModelWorkers`` with ``cascade=False`` (every model searched in full: what the workers
ran before they ran the cascade). Wall time per recognition (``time.perf_counter``) and
CPU time: the serial process's (``time.process_time``), the parent's and the workers'
(``getrusage`` of the ended children, less that of a start and close of as many workers
measured once); the ratio of the wall times measured back to back; whether the workers'
result is the serial one exactly (verdict, plausible set, every registration's model,
error, rms, pose, pruned flag and searches). Beside each touch, the attainable ratio:
pure CPU work on ``--workers`` spawned processes against the same in this process,
measured right after (the best the machine's load allows). Prints a Markdown table (and
writes it with ``--out``). Run it with this checkout first on ``PYTHONPATH`` (a
script's folder, not the current one, is on ``sys.path``).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import statistics
import sys
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench
from meshrec.recognition.workers import ModelWorkers


def _identical(a, b) -> bool:
    """Whether two recognitions agree in everything but their timings."""
    if (a.verdict, a.plausible, a.probabilities) != (b.verdict, b.plausible, b.probabilities):
        return False
    for x, y in zip(a.ranking, b.ranking, strict=True):
        if (x.model, x.error, x.rms, x.pruned, x.searches) != (
            y.model,
            y.error,
            y.rms,
            y.pruned,
            y.searches,
        ):
            return False
        if (x.T_model_touch is None) != (y.T_model_touch is None):
            return False
        if x.T_model_touch is not None and not np.array_equal(x.T_model_touch, y.T_model_touch):
            return False
    return True


def _spin(n: int) -> int:
    """Pure CPU work (the calibration's unit)."""
    s = 0
    for i in range(n):
        s += i * i
    return s


def _attainable(k: int, n: int = 4_000_000, jobs: int = 4) -> float:
    """The wall-time ratio of ``jobs`` units of pure CPU work on ``k`` spawned processes to
    the same in this process, now: the best ratio the machine's load leaves for ``k``
    workers (1/k on an idle machine)."""
    t0 = time.perf_counter()
    for _ in range(jobs):
        _spin(n)
    serial = time.perf_counter() - t0
    with ProcessPoolExecutor(k, mp_context=multiprocessing.get_context("spawn")) as pool:
        list(pool.map(_spin, [10] * k))
        t0 = time.perf_counter()
        list(pool.map(_spin, [n] * jobs))
        return (time.perf_counter() - t0) / serial


def _children_cpu() -> float:
    """CPU seconds of this process's children that have ended (and were waited for)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _started(library, k: int, cache: Path) -> dict:
    """Wall time and children's CPU of starting ``k`` workers and closing them."""
    k0, t0 = _children_cpu(), time.perf_counter()
    ModelWorkers(library, workers=k, cache_dir=cache).close()
    return {"wall": time.perf_counter() - t0, "children_cpu": _children_cpu() - k0}


def _timed(touch, library, **kwargs):
    t0, c0 = time.perf_counter(), time.process_time()
    rec = meshrec.recognize(touch, library, **kwargs)
    return rec, time.perf_counter() - t0, time.process_time() - c0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", type=int, default=100)
    p.add_argument("--touches", type=int, default=2)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--no-full", action="store_true", help="skip the cascade=False runs")
    p.add_argument("--data", type=Path, default=None, help="blobs and cache folder")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory(prefix="meshrec-workers-") as tmp:
        data = args.data or Path(tmp)
        folder = data / f"library_{args.models}"
        folder.mkdir(parents=True, exist_ok=True)
        for f in bench.write_blobs(args.models, data / "blobs"):
            if not (folder / f.name).exists():
                (folder / f.name).hardlink_to(f)
        cache = data / "cache"
        library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
        names = library.names
        n = len(names)
        start = _started(library, args.workers, cache)  # once, as a baseline
        workers = ModelWorkers(library, workers=args.workers, cache_dir=cache)
        rows = []
        try:
            for seed in range(args.touches):
                true = names[(seed * 7919) % n]
                touch = bench.paper_touch(library[true], seed=seed).touch
                row = {"seed": seed, "model": true}
                serial, row["serial_s"], row["serial_cpu"] = _timed(touch, library)
                # fresh workers, closed after the touch: their CPU less the start's
                k0 = _children_cpu()
                fresh = ModelWorkers(library, workers=args.workers, cache_dir=cache)
                par, row["workers_s"], row["workers_cpu"] = _timed(touch, library, workers=fresh)
                fresh.close()
                row["children_cpu"] = _children_cpu() - k0 - start["children_cpu"]
                row["same"] = _identical(serial, par)
                row["attainable"] = _attainable(args.workers)
                row["verdict"] = serial.verdict
                row["best"] = None if serial.best is None else serial.best.model
                row["searched"] = sum(r.searches > 0 for r in serial.ranking)
                if not args.no_full:
                    _, row["full_s"], _ = _timed(touch, library, workers=workers, cascade=False)
                rows.append(row)
                print(row, file=sys.stderr, flush=True)
        finally:
            workers.close()
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    k = args.workers
    out = [
        "## Recognitions serially and with workers\n",
        f"Command: `PYTHONPATH=. nice -n 10 python tools/workers_speed.py {shown}` "
        f"({os.cpu_count()} logical CPUs shared with other work; load average "
        f"{os.getloadavg()[0]:.1f} at the end). {n} blobs, warm cache; {workers.mode} mode, "
        f"{k} workers (their start: {start['wall']:.1f} s wall, "
        f"{start['children_cpu']:.1f} s CPU, not counted). Wall seconds per recognition "
        "(CPU seconds: serial, of the process; with workers, of the parent + the workers).\n",
        f"| touch (model) | verdict (best) | searched in full | serial | {k} workers "
        f"| ratio | attainable ratio | {k} workers, no cascade | same result |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        full = f"{r['full_s']:.1f}" if "full_s" in r else "-"
        out.append(
            f"| {r['seed']} ({r['model']}) | {r['verdict']} ({r['best']}) | {r['searched']} "
            f"| {r['serial_s']:.1f} ({r['serial_cpu']:.1f}) "
            f"| {r['workers_s']:.1f} ({r['workers_cpu']:.2f} + {r['children_cpu']:.1f}) "
            f"| {r['workers_s'] / r['serial_s']:.2f} | {r['attainable']:.2f} | {full} "
            f"| {r['same']} |"
        )
    if rows:
        med_s = statistics.median(r["serial_s"] for r in rows)
        med_w = statistics.median(r["workers_s"] for r in rows)
        med_c = statistics.median(r["serial_cpu"] for r in rows)
        med_wc = statistics.median(r["workers_cpu"] + r["children_cpu"] for r in rows)
        out.append("")
        out.append(
            f"Median wall per recognition: {med_s:.1f} s serial ({med_c:.1f} s CPU, "
            f"{med_c / n:.3f} s CPU per model), {med_w:.1f} s with {k} workers (ratio "
            f"{med_w / med_s:.2f}; {med_wc:.1f} s CPU, parent + workers); identical results "
            f"{sum(r['same'] for r in rows)}/{len(rows)}; attainable ratio (pure CPU work) "
            f"{statistics.median(r['attainable'] for r in rows):.2f}.\n"
        )
    text = "\n".join(out) + "\n"
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
