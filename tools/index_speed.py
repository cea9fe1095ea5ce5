"""Index build time and memory per model, cold cache: generated blobs and large scans.

    nice -n 10 .venv/bin/python tools/index_speed.py --blobs 20 --scan-faces 50000 100000

measures, each set in a fresh process (imports and a warm-up build done before timing):

* ``--blobs`` generated smooth blobs of 5,120 faces (:mod:`meshrec.bench.blobs`), each
  indexed with :meth:`meshrec.ModelIndex.from_file` into an empty cache folder: CPU time
  (``time.process_time``) and wall time per model, and the CPU time of each build stage
  (the ``stage`` callback: loading the mesh, curvature, writing the cache, trees);
* one YCB scan (``--scan``, from ``--ycb``) subdivided with trimesh's
  ``subdivide_to_size`` to about each of ``--scan-faces`` faces (the edge length found
  by bisection; the subdivided triangles add faces, not detail): the same times, the
  peak resident memory growth of the build (``ru_maxrss`` against the resident memory
  before it), the cache entry's size on disk, and from a second, untimed build under
  ``tracemalloc`` (numpy's and Python's allocations, not libigl's) the peak during the
  build and the memory the built index holds.

``--baseline-src DIR`` also runs every measurement with ``PYTHONPATH=DIR`` (for example
``git archive <commit> meshrec | tar -x -C DIR``), interleaved with the current code on
the same inputs, and reports the ratios. Prints a Markdown table and writes it to
``--out`` (default ``reports/index_speed.md``). Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STAGES = ("loading the mesh", "curvature", "writing the cache", "trees")


def _rss_mb() -> float:
    """This process's resident memory, MB (from /proc/self/status)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _build(path: Path, cache: Path) -> dict:
    """Index one file into an empty cache folder; CPU and wall time, per stage too."""
    import meshrec

    cache.mkdir(parents=True)
    stage_cpu = {}
    current = [None, 0.0]

    def stage(what: str) -> None:
        now = time.process_time()
        if current[0] is not None:
            stage_cpu[current[0]] = now - current[1]
        current[:] = [what, now]

    w0, c0 = time.perf_counter(), time.process_time()
    index = meshrec.ModelIndex.from_file(path, cache_dir=cache, stage=stage)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    stage_cpu[current[0]] = time.process_time() - current[1]
    entry = sum(f.stat().st_size for f in cache.rglob("*") if f.is_file())
    return {
        "cpu_s": cpu,
        "wall_s": wall,
        "stages_cpu_s": stage_cpu,
        "faces": len(index.mesh.faces),
        "sites": len(index.curvature.points),
        "cache_mb": entry / 2**20,
        "_index": index,
    }


def _scan_file(args, faces: int) -> Path:
    """The YCB scan subdivided to about ``faces`` faces (written once, deterministic)."""
    import numpy as np
    import trimesh

    out = Path(args.data) / f"{args.scan}_{faces}.obj"
    if out.is_file():
        return out
    mesh = trimesh.load(Path(args.ycb) / f"{args.scan}.obj", force="mesh")
    # Between a quarter of the median edge (at most about 16 times the faces) and the
    # longest edge (no subdivision).
    lo, hi = 0.25 * float(np.median(mesh.edges_unique_length)), mesh.edges_unique_length.max()
    best = (mesh.vertices, mesh.faces)
    for _ in range(30):  # bisection on the longest edge allowed
        mid = float(np.sqrt(lo * hi))
        v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=mid)
        best = (v, f)
        if abs(len(f) - faces) < 0.03 * faces:
            break
        lo, hi = (mid, hi) if len(f) > faces else (lo, mid)
    out.parent.mkdir(parents=True, exist_ok=True)
    trimesh.Trimesh(*best, process=False).export(out)
    return out


def measure(kind: str, args) -> dict:
    """The measurements of one set (``blobs`` or ``scan:<faces>``), in this process."""
    import meshrec
    from meshrec.bench import write_blobs

    data = Path(args.data)
    work = Path(tempfile.mkdtemp(prefix="index-speed-", dir=data))
    # Warm-up: imports and first calls of every library, not timed.
    warm = write_blobs(1, data / "warmup", seed=99)[0]
    _build(warm, work / "warm")
    if kind == "blobs":
        files = write_blobs(args.blobs, data / "blobs")
        rows = []
        for k, f in enumerate(files):
            r = _build(f, work / f"c{k}")
            r.pop("_index")
            rows.append(r)
        return {"kind": kind, "rows": rows, "meshrec": meshrec.__file__}
    faces = int(kind.split(":")[1])
    path = _scan_file(args, faces)
    rss0 = _rss_mb()
    peak0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    r = _build(path, work / "scan")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    # The peak over the process's life: the build's own only if it passed the warm-up's.
    r["peak_rss_growth_mb"] = peak - rss0 if peak > peak0 else float("nan")
    r.pop("_index")
    # Again with tracemalloc (numpy's and Python's allocations; not libigl's), untimed:
    # the peak during the build, and what the built index holds.
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    again = _build(path, work / "traced")
    peak_traced = tracemalloc.get_traced_memory()[1]
    gc.collect()  # trimesh's meshes hold reference cycles: garbage, not the index
    current = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    r["traced_peak_mb"] = (peak_traced - base) / 2**20
    r["traced_kept_mb"] = (current - base) / 2**20
    del again
    return {"kind": kind, "rows": [r], "meshrec": meshrec.__file__}


def _child(kind: str, src: str, args) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = src  # this checkout's meshrec, not an installed one
    cmd = [sys.executable, __file__, "--measure", kind, *sys.argv[1:]]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, check=True, env=env)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["load_average"] = os.getloadavg()[0]
    return out


def _median(rows, key):
    return statistics.median(r[key] for r in rows)


def report(results: dict, args) -> str:
    lines = [
        "## Index build time and memory per model (cold cache)\n",
        f"Command: `python tools/index_speed.py {' '.join(sys.argv[1:])}`; CPU time "
        "(`time.process_time`) per model, medians over the models of a set; one build per "
        "scan. Load average at the end of each set in the last column.\n",
        "| code | set | faces | sites | models | CPU s/model (median) | wall s/model | "
        "CPU s: mesh, curvature, cache, trees | peak RSS growth MB | traced peak MB | "
        "index holds MB | cache MB | load avg |",
        "|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|",
    ]
    for code, sets in results.items():
        for out in sets:
            rows = out["rows"]
            stages = ", ".join(
                f"{statistics.median(r['stages_cpu_s'].get(s, 0.0) for r in rows):.3f}"
                for s in STAGES
            )
            peak = rows[0].get("peak_rss_growth_mb")
            traced = rows[0].get("traced_peak_mb")
            kept = rows[0].get("traced_kept_mb")
            lines.append(
                f"| {code} | {out['kind']} | {int(_median(rows, 'faces'))} "
                f"| {int(_median(rows, 'sites'))} | {len(rows)} "
                f"| {_median(rows, 'cpu_s'):.3f} | {_median(rows, 'wall_s'):.3f} | {stages} "
                f"| {'-' if peak is None else f'{peak:.0f}'} "
                f"| {'-' if traced is None else f'{traced:.0f}'} "
                f"| {'-' if kept is None else f'{kept:.1f}'} "
                f"| {_median(rows, 'cache_mb'):.2f} | {out['load_average']:.1f} |"
            )
    if "before" in results:
        lines.append("")
        lines.append("| set | CPU before / after (median) |")
        lines.append("|---|---:|")
        for b, a in zip(results["before"], results["current"], strict=True):
            ratio = _median(b["rows"], "cpu_s") / _median(a["rows"], "cpu_s")
            lines.append(f"| {a['kind']} | {ratio:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blobs", type=int, default=20, help="blobs of 5,120 faces (0: none)")
    p.add_argument("--scan", default="mustard_bottle", help="YCB object to subdivide")
    p.add_argument("--ycb", default="/work/shared/data/ycb", help="YCB meshes folder")
    p.add_argument("--scan-faces", type=int, nargs="*", default=[50000, 100000])
    p.add_argument("--baseline-src", help="also run with PYTHONPATH=DIR (the 'before' code)")
    p.add_argument("--data", default="/tmp/meshrec-index-speed", help="inputs and caches")
    p.add_argument("--out", default=str(ROOT / "reports" / "index_speed.md"))
    p.add_argument("--measure", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    Path(args.data).mkdir(parents=True, exist_ok=True)
    if args.measure is not None:
        print(json.dumps(measure(args.measure, args)))
        return 0
    kinds = (["blobs"] if args.blobs else []) + [f"scan:{n}" for n in args.scan_faces]
    codes = {"current": str(ROOT)}
    if args.baseline_src:
        codes = {"before": str(Path(args.baseline_src).resolve()), "current": str(ROOT)}
    results = {code: [] for code in codes}
    for kind in kinds:
        for code, src in codes.items():
            print(f"{code} {kind}: measuring", file=sys.stderr, flush=True)
            results[code].append(_child(kind, src, args))
    text = report(results, args)
    print(text)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
