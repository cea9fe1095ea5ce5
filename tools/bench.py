"""Benchmark report: the paper's Tables 2 to 4, an oracle, the Open3D baseline, and speed.

    .venv/bin/python tools/bench.py --trials 100 --out reports/benchmark.md

runs, on the bundled libraries, seeded simulated touches by the paper's protocols and
writes a Markdown report beside the paper's figures:

* Table 2: localisation error ||p - p*|| per paper surface (modulo its symmetries), with
  the oracle (the final refinement started at the true pose) and their ratio;
* Table 3: recognition among the four surfaces: successes by table lookup alone, by local
  search, failures, and the ratio of the best wrong model's error to the right one's;
* Table 4: the four experiment objects (41 points per curve, noise +-0.1 mm), the matrix
  of mean per-point errors of each object's touches on each model;
* the Open3D baseline (FPFH + RANSAC + ICP, and multi-start ICP) on the first
  ``--baseline-trials`` touches of each shape, with the same metrics and times;
* speed: time per recognition and per stage, index build and cached load per model.

The figures at ``--paper-size`` trials (default 10, the paper's) are the first seeds of
the same run. ``--folder DIR`` runs the recognition protocol on a folder of your own models
instead (uniform random contacts, plain Euclidean localisation error). Uses only
meshrec's public API (``meshrec`` and its modules ``bench``, ``baseline``, ``plots``).
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench, defaults
from meshrec.bench import baseline

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"

PAPER_TABLE2 = {  # min, max, avg over 10 trials per surface
    "ellipsoid": (0.0169, 0.0408, 0.0288),
    "elliptic_paraboloid": (0.0148, 0.0448, 0.0297),
    "monkey_saddle": (0.0053, 0.0433, 0.0234),
    "crossed_trough": (0.0171, 0.0396, 0.0265),
}
PAPER_TABLE3 = {  # successes by table lookup, by local search (10 trials each)
    "ellipsoid": (2, 8),
    "elliptic_paraboloid": (1, 9),
    "monkey_saddle": (9, 1),
    "crossed_trough": (0, 10),
}
OBJECTS = ("cylinder_1", "cylinder_2", "elliptic_cylinder", "sphere")
PAPER_TABLE4 = {  # object -> errors on (cylinder_1, cylinder_2, elliptic_cylinder, sphere)
    "cylinder_1": (0.033, 0.155, 0.446, 0.296),
    "cylinder_2": (0.182, 0.072, 0.195, 1.056),
    "elliptic_cylinder": (0.230, 0.224, 0.156, 0.254),
    "sphere": (0.271, 0.306, 0.929, 0.055),
}
TARGET_LOC, TARGET_ORACLE_RATIO, TARGET_OBJECT_RATE, TARGET_OBJECT_ERROR = 0.015, 1.5, 0.98, 0.06
TARGET_SECONDS, TARGET_BUILD, TARGET_LOAD = 1.0, 2.0, 0.1


def _versions() -> str:
    from importlib.metadata import PackageNotFoundError, version

    import scipy
    import trimesh

    parts = [
        f"meshrec {meshrec.__version__}",
        f"Python {platform.python_version()}",
        f"numpy {np.__version__}",
        f"scipy {scipy.__version__}",
        f"trimesh {trimesh.__version__}",
    ]
    try:  # igl itself has no __version__
        parts.append(f"libigl {version('libigl')}")
    except PackageNotFoundError:
        parts.append("libigl ?")
    try:
        o3d = baseline.load_open3d()
        parts.append(f"open3d {o3d.__version__}")
    except ImportError:
        parts.append("open3d not installed (no baseline)")
    return ", ".join(parts)


def _machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os

    return f"{platform.system()} {platform.machine()}, {cpu}, {os.cpu_count()} logical CPUs"


def _ok(flag: bool) -> str:
    return "met" if flag else "**missed**"


def _progress(label):
    def report(done, total):
        print(f"\r{label}: {done}/{total}", end="", file=sys.stderr, flush=True)
        if done == total:
            print(file=sys.stderr)

    return report


def _table2(rows, n, out):
    out.append(f"### Table 2: localisation error ||p - p*||, {n} trials per surface\n")
    out.append("| surface | min | max | avg | oracle avg | avg / oracle | paper min | max | avg "
               "| target (avg <= 0.015, <= 1.5x oracle) |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for name in meshrec.PAPER_SURFACES:
        r = [t for t in rows if t.shape == name][:n]
        loc = np.array([t.loc_error for t in r])
        orc = np.array([t.oracle_loc for t in r])
        ratio = loc.mean() / orc.mean()
        pmin, pmax, pavg = PAPER_TABLE2[name]
        ok = loc.mean() <= TARGET_LOC and ratio <= TARGET_ORACLE_RATIO
        out.append(f"| {name} | {loc.min():.4f} | {loc.max():.4f} | {loc.mean():.4f} "
                   f"| {orc.mean():.4f} | {ratio:.2f} | {pmin} | {pmax} | {pavg} | {_ok(ok)} |")
    out.append("")


def _table3(rows, n, out):
    out.append(f"### Table 3: recognition among the four surfaces, {n} trials per surface\n")
    out.append("| surface | table lookup | local search | failed | wrong / right error: mean "
               "| min | paper: lookup | local search |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|")
    total = 0
    for name in meshrec.PAPER_SURFACES:
        r = [t for t in rows if t.shape == name][:n]
        lookup = sum(t.recognised and t.lookup_only for t in r)
        search = sum(t.recognised and not t.lookup_only for t in r)
        total += lookup + search
        ratios = [t.wrong_error / t.right_error for t in r if t.wrong_error is not None]
        mean = f"{np.mean(ratios):.2f}" if ratios else "-"
        low = f"{np.min(ratios):.2f}" if ratios else "-"
        pl, ps = PAPER_TABLE3[name]
        out.append(f"| {name} | {lookup} | {search} | {len(r) - lookup - search} | {mean} "
                   f"| {low} | {pl} | {ps} |")
    out.append(f"\nRecognised: {total}/{4 * n} (target {4 * n}/{4 * n}: "
               f"{_ok(total == 4 * n)}; the paper: 40/40 on 10 trials each, wrong models' "
               "errors 180% higher on average where a local search was needed).\n")


def _table4(rows, n, out):
    out.append(f"### Table 4: experiment objects, {n} trials per object (mm)\n")
    out.append("Mean per-point error of each object's touches on each model (mean over the "
               "trials; '-' where the lookup rejected the model on every trial, with how "
               "often it was rejected), the paper's single touch in brackets.\n")
    out.append("| object \\ model | " + " | ".join(OBJECTS) + " | recognised |")
    out.append("|---|" + "---:|" * (len(OBJECTS) + 1))
    ok_all = n_all = 0
    right_errors = []
    for obj in OBJECTS:
        r = [t for t in rows if t.shape == obj][:n]
        cells = []
        for j, m in enumerate(OBJECTS):
            errs = [t.errors[m] for t in r if t.errors[m] is not None]
            rejected = len(r) - len(errs)
            cell = f"{np.mean(errs):.3f}" if errs else "-"
            if rejected and errs:
                cell += f" ({rejected} rej.)"
            cells.append(f"{cell} [{PAPER_TABLE4[obj][j]}]")
        ok = sum(t.recognised for t in r)
        ok_all += ok
        n_all += len(r)
        right_errors += [t.right_error for t in r if t.right_error is not None]
        out.append(f"| {obj} | " + " | ".join(cells) + f" | {ok}/{len(r)} |")
    rate = ok_all / n_all
    mean_right = float(np.mean(right_errors))
    out.append(f"\nRecognised {ok_all}/{n_all} ({100 * rate:.1f}%; target >= 98%: "
               f"{_ok(rate >= TARGET_OBJECT_RATE)}); right-model error mean {mean_right:.4f} mm, "
               f"max {np.max(right_errors):.4f} mm (target <= 0.06 mm per point: "
               f"{_ok(mean_right <= TARGET_OBJECT_ERROR)}).\n")


def _speed(rows_by_lib, out):
    out.append("### Speed: one recognition against a library (warm cache)\n")
    out.append("Wall time per touch; stages summed over the library's models, median over the "
               "touches.\n")
    out.append("| library | touches | median (s) | worst (s) | curvature estimate | lookup | "
               "phi | screen | local search | refinement | target median <= 1.0 s |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for lib, rows in rows_by_lib.items():
        s = np.array([t.seconds for t in rows])
        st = {k: np.median([getattr(t.times, k) for t in rows])
              for k in ("lookup", "phi", "screen", "search", "refine")}
        geo = np.median([t.geometry_seconds for t in rows])
        out.append(f"| {lib} | {len(rows)} | {np.median(s):.3f} | {s.max():.3f} | {geo:.4f} "
                   f"| {st['lookup']:.4f} | {st['phi']:.3f} | {st['screen']:.3f} "
                   f"| {st['search']:.3f} | {st['refine']:.3f} "
                   f"| {_ok(np.median(s) <= TARGET_SECONDS)} |")
    out.append("")


def _index_times(out):
    out.append("### Index build and cached load per model\n")
    out.append("Built into an empty temporary cache, then loaded from it (median of 3 loads).\n")
    out.append("| model | faces | vertices | curvature sites | build (s) "
               "| cached load (s) | targets (build <= 2 s, load <= 0.1 s) |")
    out.append("|---|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as cache:
        for lib in ("surfaces", "objects"):
            for path in sorted((MODELS / lib).glob("*.stl")):
                t0 = time.perf_counter()
                m = meshrec.ModelIndex.from_file(path, cache_dir=cache)
                build = time.perf_counter() - t0
                loads = []
                for _ in range(3):
                    t0 = time.perf_counter()
                    meshrec.ModelIndex.from_file(path, cache_dir=cache)
                    loads.append(time.perf_counter() - t0)
                load = float(np.median(loads))
                ok = build <= TARGET_BUILD and load <= TARGET_LOAD
                faces, vertices = len(m.mesh.faces), len(m.mesh.vertices)
                out.append(f"| {lib}/{path.name} | {faces:,} | {vertices:,} "
                           f"| {len(m.curvature.points):,} | {build:.2f} | {load:.3f} "
                           f"| {_ok(ok)} |")
    out.append("")


def _baseline(library, rows, n, label, out, length_fraction):
    try:
        baseline.load_open3d()
    except ImportError as exc:
        out.append(f"### Baseline on {label}: not run ({exc})\n")
        return
    prepared = {m.name: baseline.BaselineModel.from_index(m, rng=0) for m in library}
    shapes = sorted({t.shape for t in rows}, key=[t.shape for t in rows].index)
    stats = {"meshrec": [], "fpfh": [], "multistart": []}
    done, total = 0, len(shapes) * n
    for shape in shapes:
        for t in [t for t in rows if t.shape == shape][:n]:
            sim = bench.paper_touch(library[shape], t.seed, length_fraction=length_fraction)
            stats["meshrec"].append((t.recognised, t.loc_error, t.seconds))
            for method in ("fpfh", "multistart"):
                res = [
                    baseline.baseline_register(sim.touch, prepared[name], method=method,
                                               rng=t.seed)
                    for name in library.names
                ]
                best = min(res, key=lambda r: r.error)
                right = next(r for r in res if r.model == shape)
                T = right.T_model_touch
                found = T[:3, :3] @ sim.contact_touch + T[:3, 3]
                if shape in meshrec.PAPER_SURFACES:
                    loc = meshrec.localisation_error(shape, sim.contact, found)
                else:
                    loc = bench.object_localisation_error(shape, sim.contact, found)
                stats[method].append((best.model == shape, loc, sum(r.seconds for r in res)))
            done += 1
            print(f"\rbaseline {label}: {done}/{total}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    out.append(f"### Baseline on {label}: {n} touches per shape, the same touches\n")
    out.append("| method | recognised | localisation avg | median | time per recognition: "
               "median (s) | worst (s) |")
    out.append("|---|---:|---:|---:|---:|---:|")
    names = {"meshrec": "meshrec", "fpfh": "Open3D FPFH + RANSAC + ICP",
             "multistart": f"Open3D multi-start ICP ({defaults.BASELINE_STARTS} starts)"}
    for key, rows_k in stats.items():
        ok = sum(r[0] for r in rows_k)
        loc = np.array([r[1] for r in rows_k])
        sec = np.array([r[2] for r in rows_k])
        out.append(f"| {names[key]} | {ok}/{len(rows_k)} | {loc.mean():.4f} | "
                   f"{np.median(loc):.4f} | {np.median(sec):.3f} | {sec.max():.3f} |")
    out.append("")


def _figure6(library, rows, n, path):
    """The paper's Figure 6 (meshrec.figures.plots): true contacts as dots, the found as crosses."""
    from meshrec.figures import plots

    groups = {}
    for name in meshrec.PAPER_SURFACES:
        sym = meshrec.symmetry_rotations(name)
        pairs = []
        for t in [t for t in rows if t.shape == name][:n]:
            p = t.true_contact
            q = t.found_contact
            if q is not None:  # its symmetric twin nearest the truth (the same answer)
                q = min((S @ q for S in sym), key=lambda v: np.linalg.norm(v - p))
            pairs.append((p, q))
        groups[name] = pairs
    plots.contacts_figure(groups, path, meshes={m.name: m for m in library})


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=100, help="touches per shape")
    p.add_argument("--paper-size", type=int, default=10, help="also report the first N trials")
    p.add_argument("--baseline-trials", type=int, default=10,
                   help="touches per shape for the Open3D baseline (0: none)")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--length-fraction", type=float, default=defaults.SIM_LENGTH_FRACTION,
                   help="curve length as a fraction of sqrt(surface area) of the model")
    p.add_argument("--folder", type=Path, default=None,
                   help="benchmark a folder of your own models instead of the bundled ones")
    p.add_argument("--out", type=Path, default=None, help="Markdown report (default: stdout)")
    p.add_argument("--figure", type=Path, default=None,
                   help="Figure 6 style PNG of the true and found contacts on the surfaces")
    p.add_argument("--no-index-times", action="store_true", help="skip the index timings")
    args = p.parse_args(argv)

    t_start = time.perf_counter()
    out = ["# meshrec benchmark", ""]
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out.append(f"Command: `python tools/bench.py {shown}`")
    out.append("")
    out.append(f"Machine: {_machine()}. Versions: {_versions()}.")
    out.append("")
    out.append(f"Curves: length {args.length_fraction:g} x sqrt(surface area) of the touched "
               "model (about 0.6 on the unit surfaces, the paper's figures; 31 to 45 mm on the "
               "objects); paper surfaces 61 points per curve, uniform noise +-0.001; objects "
               "41 points, +-0.1 mm, contacts on the curved sides at least "
               f"{defaults.BENCH_RIM_MARGIN:g} mm from the rims. Seeds {args.seed} to "
               f"{args.seed + args.trials - 1} per shape. Times are wall-clock on a shared "
               "machine: read medians and ratios.")
    out.append("")
    ok = True
    if args.folder is not None:
        library = meshrec.ModelLibrary.from_folder(args.folder)
        rows = bench.run_trials(library, library.names, args.trials, args.seed,
                                length_fraction=args.length_fraction,
                                progress=_progress(str(args.folder)))
        out.append(f"## Folder {args.folder}\n")
        out.append("| model | recognised | localisation avg | max | time median (s) |")
        out.append("|---|---:|---:|---:|---:|")
        for name in library.names:
            r = [t for t in rows if t.shape == name]
            loc = np.array([t.loc_error for t in r])
            out.append(f"| {name} | {sum(t.recognised for t in r)}/{len(r)} | {loc.mean():.4g} "
                       f"| {loc.max():.4g} | {np.median([t.seconds for t in r]):.3f} |")
        _speed({str(args.folder): rows}, out)
    else:
        surfaces = meshrec.ModelLibrary.from_folder(MODELS / "surfaces")
        objects = meshrec.ModelLibrary.from_folder(MODELS / "objects")
        s_rows = bench.run_trials(surfaces, meshrec.PAPER_SURFACES, args.trials, args.seed,
                                  length_fraction=args.length_fraction,
                                  progress=_progress("surfaces"))
        o_rows = bench.run_trials(objects, OBJECTS, args.trials, args.seed,
                                  length_fraction=args.length_fraction,
                                  progress=_progress("objects"))
        for n in sorted({min(args.paper_size, args.trials), args.trials}):
            out.append(f"## {n} trials per shape\n")
            _table2(s_rows, n, out)
            _table3(s_rows, n, out)
            _table4(o_rows, n, out)
        out.append("## Speed\n")
        _speed({"four paper surfaces": s_rows, "four experiment objects": o_rows}, out)
        if not args.no_index_times:
            _index_times(out)
        if args.baseline_trials:
            out.append("## Baseline: Open3D\n")
            _baseline(surfaces, s_rows, min(args.baseline_trials, args.trials),
                      "the paper surfaces", out, args.length_fraction)
            _baseline(objects, o_rows, min(args.baseline_trials, args.trials),
                      "the experiment objects", out, args.length_fraction)
        if args.figure is not None:
            _figure6(surfaces, s_rows, min(args.paper_size, args.trials), args.figure)
            out.append(f"Figure 6 (the first {min(args.paper_size, args.trials)} trials per "
                       f"surface): `{args.figure}`.\n")
        ok = all(t.recognised for t in s_rows)
    out.append(f"Report made in {time.perf_counter() - t_start:.0f} s.")
    text = "\n".join(out) + "\n"
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        print(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
