"""Scale benchmark: index, load, memory and recognition time against the library's size.

    nice -n 10 .venv/bin/python tools/scale.py --sizes 10 100 1000 --workers 2

generates (once, deterministically) a library of distinct smooth blobs
(:mod:`meshrec.bench.blobs`, 5,120 faces each) and measures, for each library size, in a
fresh process of its own:

* index time per model (the build time recorded in each model's index, cached or not);
* load time of the whole library with a warm cache (two loads, the second timed: the
  first may write the consolidated pack), and the memory it takes (RSS growth);
* time per recognition of seeded simulated touches (``meshrec.bench.paper_touch`` on a
  model of the library), in-process, serial and with ``--workers`` processes (same answer
  checked);
* the Open3D multi-start ICP baseline (``--starts`` random starts per model), on the true
  model and ``--baseline-models - 1`` others per touch; its time per recognition is that
  per model times the library's size (extrapolated, and marked so, when it ran on fewer
  models than the library holds).

Results go to ``--json`` (default ``reports/scale.json``): a size already measured there is
not measured again (``--redo`` to force), so the run can be resumed or grown. The Markdown
table goes to stdout and ``--out``, the plot to ``--plot``. Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _libraries import blob_folder  # noqa: E402  (tools/_libraries.py)


def _rss_mb() -> float:
    """This process's resident memory, MB (from /proc/self/status)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _answer(rec) -> tuple:
    """What a recognition answers: the verdict, the plausible models, the best model and its
    error (with workers the same screen and cascade run: the same answer, exactly)."""
    best = rec.best
    return (
        rec.verdict,
        rec.plausible,
        None if best is None else best.model,
        None if best is None else best.error,
    )


def measure(n: int, args) -> dict:
    """Every measurement at library size ``n`` (run in a process of its own)."""
    rss0 = _rss_mb()
    import meshrec
    from meshrec.bench import paper_touch

    data = Path(args.data)
    folder = blob_folder(data, n, f"library_{n}")
    cache = data / "cache"
    os.environ["MESHREC_CACHE_DIR"] = str(cache)
    rss_imports = _rss_mb()
    t0 = time.perf_counter()
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    first_load = time.perf_counter() - t0
    rss_before = _rss_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    second = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    load, load_cpu = time.perf_counter() - t0, time.process_time() - c0
    rss_loaded = _rss_mb()  # both copies alive: the growth is one library's memory
    del library
    library = second
    build = [m.build_seconds for m in library]
    out = {
        "models": n,
        "faces": int(np.median([len(m.mesh.faces) for m in library])),
        "index_median_s": statistics.median(build),
        "index_total_s": float(sum(build)),
        "first_load_s": first_load,
        "load_s": load,
        "load_cpu_s": load_cpu,
        "rss_imports_mb": rss_imports - rss0,
        "rss_library_mb": rss_loaded - rss_before,
        "rss_total_mb": rss_loaded,
        "touches": [],
    }
    names = library.names
    baseline = None
    if args.starts > 0 and args.baseline_models > 0:
        from meshrec.bench import baseline as baseline

    workers = None
    if args.workers > 1:
        from meshrec.recognition.workers import ModelWorkers

        t0 = time.perf_counter()
        workers = ModelWorkers(library, workers=args.workers, cache_dir=cache)
        out["workers_start_s"] = time.perf_counter() - t0
        out["workers_mode"] = workers.mode
    t_start = time.perf_counter()
    for seed in range(args.touches):
        true = names[(seed * 7919) % n]
        sim = paper_touch(library[true], seed=seed)
        row = {"seed": seed, "model": true}
        t0, c0 = time.perf_counter(), time.process_time()
        rec = meshrec.recognize(sim.touch, library)
        row["serial_s"] = time.perf_counter() - t0
        row["serial_cpu_s"] = time.process_time() - c0
        row["serial_best"] = rec.best.model if rec.best is not None else None
        row["searched"] = sum(r.searches > 0 for r in rec.ranking)  # full searches run
        row["pruned"] = sum(r.pruned for r in rec.ranking)
        row["rejected"] = sum(r.rejected for r in rec.ranking)
        # where the time went: each stage's seconds summed over the models (wall clocks)
        stages = sum((r.times for r in rec.ranking), meshrec.StageTimes())
        row["stages_s"] = dataclasses.asdict(stages)
        row["verdict"] = rec.verdict
        if workers is not None:
            t0 = time.perf_counter()
            par = meshrec.recognize(sim.touch, library, workers=workers)
            row["workers_s"] = time.perf_counter() - t0
            row["workers_same"] = _answer(par) == _answer(rec)
        if baseline is not None:
            others = [m for m in names if m != true][: args.baseline_models - 1]
            times, errors = [], {}
            for name in [true, *others]:
                target = baseline.BaselineModel.from_index(library[name], rng=0)
                res = baseline.baseline_register(
                    sim.touch, target, method="multistart", starts=args.starts, rng=seed
                )
                times.append(res.seconds)
                errors[name] = res.error
            row["baseline_models"] = len(times)
            row["baseline_per_model_s"] = statistics.median(times)
            row["baseline_s"] = statistics.median(times) * n
            row["baseline_measured_s"] = float(sum(times))
            row["baseline_best"] = min(errors, key=errors.get)
        out["touches"].append(row)
        print(f"  n={n} touch {seed}: {row}", file=sys.stderr, flush=True)
        if time.perf_counter() - t_start > args.budget:
            break
    if workers is not None:
        workers.close()
    out["load_average"] = os.getloadavg()[0]
    return out


def _fmt(x: float) -> str:
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"


def _cpu(x: float | None) -> str:
    """``"; CPU s"`` when measured (the process's CPU time: the wall time of an idle machine)."""
    return "" if x is None else f"; {_fmt(x)}"


def report(results: list[dict], args) -> str:
    """The Markdown report of all measured sizes."""
    out = [
        "## Scale: library size against index, load, memory and recognition time\n",
        "Commands: "
        + "; ".join(sorted({f"`nice -n 10 python tools/scale.py {r['command']}`" for r in results}))
        + f" ({os.cpu_count()} logical CPUs shared with other work; OMP_NUM_THREADS="
        f"{os.environ.get('OMP_NUM_THREADS', 'unset')}). Blobs of "
        f"{results[0]['faces'] if results else '?'} faces (meshrec.bench.blobs); medians over "
        "the touches measured (column `touches`).\n",
        "| models | index s/model | load s (warm; CPU s) | library RSS MB | MB/model | touches "
        "| recognition s (serial; CPU s) | s/model/touch | recognition s (workers) | right "
        f"| ICP x{args.starts} s/recognition | ratio meshrec/ICP | ICP right "
        "| workers start s | load average |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in sorted(results, key=lambda r: r["models"]):
        n, t = r["models"], r["touches"]
        if not t:  # measured without touches (--touches 0)
            out.append(
                f"| {n} | {r['index_median_s']:.3f} | {r['load_s']:.3f}{_cpu(r.get('load_cpu_s'))} "
                f"| {r['rss_library_mb']:.0f} | {r['rss_library_mb'] / n:.2f} | 0 "
                "| - | - | - | - | - | - | - "
                f"| - | {r.get('load_average', 0):.1f} |"
            )
            continue
        serial = statistics.median(x["serial_s"] for x in t) if t else float("nan")
        cpu = statistics.median(x["serial_cpu_s"] for x in t) if "serial_cpu_s" in t[0] else None
        right = sum(x["serial_best"] == x["model"] for x in t)
        if t and "workers_s" in t[0]:
            w = statistics.median(x["workers_s"] for x in t)
            same = all(x["workers_same"] for x in t)
            workers = f"{_fmt(w)}" + ("" if same else " (**differs**)")
        else:
            workers = "-"
        if t and "baseline_s" in t[0]:
            b = statistics.median(x["baseline_s"] for x in t)
            measured = t[0]["baseline_models"]
            mark = "" if measured >= n else f" (ext. from {measured})"
            base = f"{_fmt(b)}{mark}"
            ratio = f"{serial / b:.3f}"
            bright = f"{sum(x['baseline_best'] == x['model'] for x in t)}/{len(t)}"
            if measured < n:
                bright += f" (of {measured})"
        else:
            base = ratio = bright = "-"
        out.append(
            f"| {n} | {r['index_median_s']:.3f} | {r['load_s']:.3f}{_cpu(r.get('load_cpu_s'))} "
            f"| {r['rss_library_mb']:.0f} | {r['rss_library_mb'] / n:.2f} | {len(t)} "
            f"| {_fmt(serial)}{_cpu(cpu)} | {serial / n:.3f} | {workers} | {right}/{len(t)} "
            f"| {base} | {ratio} | {bright} "
            f"| {r.get('workers_start_s', float('nan')):.2f} | {r.get('load_average', 0):.1f} |"
        )
    staged = [r for r in sorted(results, key=lambda r: r["models"]) if r["touches"]]
    staged = [r for r in staged if "stages_s" in r["touches"][0]]
    if staged:
        names = list(staged[0]["touches"][0]["stages_s"])
        out += [
            "",
            "Where a recognition's time went (medians over the touches; each stage's wall "
            "seconds summed over the models, `Registration.times`), and the models searched "
            "in full, pruned (by the library-wide screen or the cascade) and rejected by the "
            "lookup:",
            "",
            "| models | "
            + " | ".join(f"{k} s" for k in names)
            + " | searched in full | pruned | rejected |",
            "|---:|" + "---:|" * (len(names) + 3),
        ]
        for r in staged:
            t = r["touches"]
            cells = [_fmt(statistics.median(x["stages_s"][k] for x in t)) for k in names]
            counts = [
                f"{statistics.median(x[k] for x in t):.0f}"
                for k in ("searched", "pruned", "rejected")
            ]
            out.append(f"| {r['models']} | " + " | ".join(cells + counts) + " |")
    out.append("")
    return "\n".join(out)


def plot(results: list[dict], path: Path, starts: int) -> None:
    """Time per recognition (and load time) against the library's size, log-log."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = sorted((r for r in results if r["touches"]), key=lambda r: r["models"])

    def med(key):
        """The sizes measured with ``key`` (not every run measures workers or ICP), and
        their medians."""
        have = [r for r in rows if key in r["touches"][0]]
        return [r["models"] for r in have], [
            statistics.median(x[key] for x in r["touches"]) for r in have
        ]

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    ax.plot(*med("serial_s"), "o-", label="meshrec, serial")
    if any("workers_s" in r["touches"][0] for r in rows):
        ax.plot(*med("workers_s"), "s-", label="meshrec, --workers")
    cpu = [r for r in rows if "serial_cpu_s" in r["touches"][0]]
    if cpu:
        ax.plot(
            [r["models"] for r in cpu],
            [statistics.median(x["serial_cpu_s"] for x in r["touches"]) for r in cpu],
            "o",
            mfc="none",
            label="meshrec, serial: CPU time",
        )
    if any("baseline_s" in r["touches"][0] for r in rows):
        ax.plot(
            *med("baseline_s"),
            "^--",
            label=f"Open3D multi-start ICP x{starts} (per model x models)",
        )
    every = sorted(results, key=lambda r: r["models"])
    ax.plot(
        [r["models"] for r in every],
        [r["load_s"] for r in every],
        "d:",
        label="library load (warm cache)",
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("models in the library")
    ax.set_ylabel("seconds")
    ax.set_title("Time per recognition against library size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    p.add_argument("--touches", type=int, default=3, help="touches per size (at most)")
    p.add_argument(
        "--budget",
        type=float,
        default=300.0,
        help="seconds of touches per size: stop after the touch that exceeds it",
    )
    p.add_argument("--workers", type=int, default=2, help="also measure with N processes")
    p.add_argument("--starts", type=int, default=256, help="multi-start ICP starts (0: none)")
    p.add_argument(
        "--baseline-models",
        type=int,
        default=5,
        help="models the baseline runs on per touch (the true one and others)",
    )
    p.add_argument("--data", default="/tmp/meshrec-scale", help="blobs and cache folder")
    p.add_argument("--json", default=str(ROOT / "reports" / "scale.json"))
    p.add_argument("--out", default=str(ROOT / "reports" / "scale.md"))
    p.add_argument("--plot", default=str(ROOT / "docs" / "images" / "scale.png"))
    p.add_argument("--redo", action="store_true", help="measure sizes already in --json")
    p.add_argument("--measure", type=int, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.measure is not None:
        print(json.dumps(measure(args.measure, args)))
        return 0
    store = Path(args.json)
    done = json.loads(store.read_text()) if store.is_file() else {}
    for n in args.sizes:
        if str(n) in done and not args.redo:
            print(f"size {n}: already measured in {store}", file=sys.stderr)
            continue
        print(f"size {n}: measuring", file=sys.stderr, flush=True)
        child = [sys.executable, __file__, "--measure", str(n), *(argv or sys.argv[1:])]
        proc = subprocess.run(child, stdout=subprocess.PIPE, text=True, check=True)
        done[str(n)] = json.loads(proc.stdout.strip().splitlines()[-1])
        done[str(n)]["command"] = " ".join(argv or sys.argv[1:])
        store.parent.mkdir(parents=True, exist_ok=True)
        store.write_text(json.dumps(done, indent=1))
    results = list(done.values())
    text = report(results, args)
    print(text)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)
    plot(results, Path(args.plot), args.starts)
    return 0


if __name__ == "__main__":
    sys.exit(main())
