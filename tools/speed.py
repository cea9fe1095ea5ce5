"""Speed of one recognition: the cascade against the full search on every model.

Two measurements, in-process with a warm cache (each library loaded and one recognition
run before timing):

1. The four paper surfaces (``models/surfaces``): seeded touches by the paper's protocol
   (``meshrec.bench.paper_touch``), each recognised with the full search on every model
   (``cascade=False``, the path before the cascade) and with the cascade; wall and CPU
   time per recognition, whether the right model is the best, and whether both give the
   same verdict, best model, best error and plausible set.
2. A generated library of ``--models`` smooth shapes (``meshrec.bench.shape_set``): the
   same on touches of a few of its models, reported per model per touch.

Prints a Markdown table (and writes it with ``--out``). Usage::

    python tools/speed.py --trials 3 --models 20 --out reports/speed.md
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import meshrec
from meshrec import bench

MODELS = Path(__file__).resolve().parents[1] / "models"


def _timed(touch, library, cascade: bool):
    w0, c0 = time.perf_counter(), time.process_time()
    rec = meshrec.recognize(touch, library, cascade=cascade)
    return rec, time.perf_counter() - w0, time.process_time() - c0


def _run(library, touches) -> dict:
    """Both paths on every (shape, touch): times, right answers, agreement."""
    rows = {"full": [], "cascade": []}
    same = 0
    pruned = 0
    for shape, touch in touches:
        full, wf, cf = _timed(touch, library, False)
        fast, wc, cc = _timed(touch, library, True)
        rows["full"].append((wf, cf, full.best is not None and full.best.model == shape))
        rows["cascade"].append((wc, cc, fast.best is not None and fast.best.model == shape))
        same += (
            full.verdict == fast.verdict
            and (full.best is None) == (fast.best is None)
            and (full.best is None or (full.best.model, full.best.error)
                 == (fast.best.model, fast.best.error))
            and tuple(full.plausible) == tuple(fast.plausible)
        )
        pruned += sum(r.pruned for r in fast.ranking)
    return {"rows": rows, "same": same, "pruned": pruned, "n": len(touches)}


def _table(name: str, n_models: int, res: dict, out: list[str]) -> None:
    full = np.array([r[:2] for r in res["rows"]["full"]])
    fast = np.array([r[:2] for r in res["rows"]["cascade"]])
    n = res["n"]
    out.append(f"### {name}: {n_models} models, {n} touches\n")
    out.append("| path | wall median (s) | CPU median (s) | wall per model (s) | right best |")
    out.append("|---|---:|---:|---:|---:|")
    for label, arr, key in (("full search", full, "full"), ("cascade", fast, "cascade")):
        right = sum(r[2] for r in res["rows"][key])
        med = np.median(arr, axis=0)
        out.append(f"| {label} | {med[0]:.3f} | {med[1]:.3f} | {med[0] / n_models:.4f} | "
                   f"{right}/{n} |")
    ratio = np.median(fast[:, 1] / full[:, 1])
    out.append("")
    out.append(f"Cascade / full, median of the per-touch CPU-time ratios: {ratio:.2f}. "
               f"Same verdict, best model, best error and plausible set: {res['same']}/{n}. "
               f"Models pruned: {res['pruned']} of {n * n_models} (model, touch) pairs.\n")


def _surfaces(trials: int, out: list[str]) -> None:
    library = meshrec.ModelLibrary.from_folder(MODELS / "surfaces")
    touches = [(s, bench.paper_touch(library[s], seed).touch)
               for s in meshrec.PAPER_SURFACES for seed in range(trials)]
    meshrec.recognize(touches[0][1], library)  # warm: lazy tables, imports
    _table("The four paper surfaces", len(library), _run(library, touches), out)


def _generated(n_models: int, touched: int, seed: int, out: list[str]) -> None:
    with tempfile.TemporaryDirectory(prefix="meshrec-speed-") as tmp:
        shapes = bench.shape_set(n_models, seed=seed)
        bench.write_shapes(shapes, Path(tmp) / "models")
        t0 = time.perf_counter()
        library = meshrec.ModelLibrary.from_folder(Path(tmp) / "models",
                                                   cache_dir=Path(tmp) / "cache")
        t_index = time.perf_counter() - t0
        step = max(1, n_models // touched)
        names = [shapes[i].name for i in range(0, n_models, step)][:touched]
        touches = [(name, meshrec.simulate_touch(library[name], rng=k).touch)
                   for k, name in enumerate(names)]
        meshrec.recognize(touches[0][1], library)
        res = _run(library, touches)
    faces = [len(s.mesh.faces) for s in shapes]
    _table(f"Generated shapes (bench.shape_set({n_models}, seed={seed}))", n_models, res, out)
    out.append(f"Faces per model: median {int(np.median(faces))} ({min(faces)} to "
               f"{max(faces)}); index build (cold cache) {t_index:.1f} s for all.\n")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=3, help="touches per paper surface")
    p.add_argument("--models", type=int, default=20, help="generated library size (0: none)")
    p.add_argument("--touched", type=int, default=4, help="touches on the generated library")
    p.add_argument("--seed", type=int, default=0, help="seed of the generated library")
    p.add_argument("--out", type=Path, default=None, help="Markdown report (default: stdout)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    t_start = time.perf_counter()
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out = ["# meshrec speed", "", f"Command: `python tools/speed.py {shown}`", "",
           f"Machine: {platform.machine()}, {platform.python_implementation()} "
           f"{platform.python_version()}, meshrec {meshrec.__version__}; shared 2-core "
           "machine (wall times depend on its load: CPU times and ratios are steadier).", ""]
    _surfaces(args.trials, out)
    if args.models:
        _generated(args.models, args.touched, args.seed, out)
    out.append(f"Report made in {time.perf_counter() - t_start:.0f} s.")
    text = "\n".join(out) + "\n"
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(f"wrote {args.out}", file=sys.stderr)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
