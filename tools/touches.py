"""Several touches and the active loop (issue 12): how many touches to a decision?

For each generated shape set (``meshrec.bench.shape_set``, nine unit-size smooth shapes)
and each shape, seeded trials of an object placed at a random pose in the world:

- three touches at random places (curves 0.3 long, noise 0.002): is the joint answer right,
  ``recognised``, and how far is the pose (the touches' points mapped by the found and by
  the true pose; bumped spheres are the asymmetric shapes, the others have symmetries that
  a pose error would count)? Recognition time with three touches over one.
- the active loop: a first touch at random, then touch where ``meshrec.next_touch``
  advises (the simulated probe moves along the advised ray and touches where it first
  meets the true object) until the verdict is ``recognised`` or six touches; against the
  same loop touching at random places. Touches to a decision and the final accuracy.

Writes a Markdown report and a picture of one active run (touches numbered on the model).

    .venv/bin/python tools/touches.py --sets 5 6 --loop-length 0.2 --loop-noise 0.004 \
        --out reports/touches.md --figure docs/images/active_loop.png

Look-alikes that differ in one small feature (rods of one radius and length whose tips
differ, ``meshrec.bench.EXTRA_FAMILIES``), where a touch at random rarely decides:

    .venv/bin/python tools/touches.py --sets 7 --families tipped_rod --loop-length 0.2 \
        --loop-noise 0.004 --out reports/touches_rods.md --figure docs/images/active_rods.png

Three touches only (accuracy, pose against the oracle's, CPU time over one touch), a few
minutes:

    PYTHONPATH=. .venv/bin/python tools/touches.py --sets 5 6 --no-loop

(``PYTHONPATH=.``: a script's own folder, not the working directory, starts ``sys.path``,
so without it an installed meshrec is measured, not this checkout's.)

Uses only meshrec's public API.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import meshrec
from meshrec import bench
from meshrec.sim.probe import first_hit

LENGTH, NOISE, MAX_TOUCHES = 0.3, 0.002, 6


def _world(rng) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


def _touch(model, T_world_model, rng, contact=None, length=LENGTH, noise=NOISE):
    sim = meshrec.simulate_touch(
        model, length=length, noise=noise, rng=rng, transform=False, contact=contact
    )
    return sim.touch.transformed(T_world_model)


def _recognise(touches, library):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()  # CPU time: the machine is shared
        rec = meshrec.recognize(touches if len(touches) > 1 else touches[0], library)
    return rec, time.process_time() - t0


def _pose_error(rec, touches, T_world_model) -> float:
    """Largest distance between the touches' points mapped by the found and the true pose
    (``rec``: a Recognition, or a Registration)."""
    best = getattr(rec, "best", rec)
    if best is None:
        return float("inf")
    points = np.vstack([t.points for t in touches])
    T = best.T_model_touch
    T_true = np.linalg.inv(T_world_model)
    a = points @ T[:3, :3].T + T[:3, 3]
    b = points @ T_true[:3, :3].T + T_true[:3, 3]
    return float(np.linalg.norm(a - b, axis=1).max())


def _oracle_error(rec, touches, model, T_world_model) -> float:
    """The pose error the noise leaves: all the touches refined from the true pose
    (``meshrec.refine_pose``, the benchmarks' oracle), measured as :func:`_pose_error`."""
    if rec.best is None:
        return float("inf")
    together = meshrec.TouchData([c for t in touches for c in t.curves])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = meshrec.refine_pose(
            together, model, np.linalg.inv(T_world_model), geometry=rec.geometries[0]
        )
    return _pose_error(reg, touches, T_world_model)


def _advised_touch(rec, library, model, T_world_model, rng, length, noise):
    """Follow the advice: the probe moves along the advised ray onto the true object."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        advice = meshrec.next_touch(rec, library, rng=rng)
    if advice.point is None:
        return None, advice
    T = np.linalg.inv(T_world_model)
    point = T[:3, :3] @ advice.point + T[:3, 3]
    direction = T[:3, :3] @ advice.direction
    standoff = float(np.linalg.norm(np.ptp(model.mesh.vertices, axis=0)))
    hit = first_hit(model.mesh.vertices, model.mesh.faces, point - standoff * direction, direction)
    if hit is None:  # the ray misses the true object: the robot touches near the point
        hit = point
    try:
        return _touch(model, T_world_model, rng, hit, length, noise), advice
    except ValueError:  # no curve through that contact (an open patch's rim): at random
        return None, advice


def _loop(library, model, T_world_model, rng, first, active: bool, length, noise):
    """Touch (from ``first``) until recognised or MAX_TOUCHES: advised or at random."""
    touches = [first]
    advice_times = []
    while True:
        rec, _ = _recognise(touches, library)
        if rec.verdict == "recognised" or len(touches) >= MAX_TOUCHES:
            return rec, touches, advice_times
        nxt = None
        if active:
            t0 = time.perf_counter()
            nxt, _ = _advised_touch(rec, library, model, T_world_model, rng, length, noise)
            advice_times.append(time.perf_counter() - t0)
        if nxt is None:
            nxt = _touch(model, T_world_model, rng, None, length, noise)
        touches.append(nxt)


def run(set_seeds, trials, cache_dir, log, loop_length, loop_noise, families=None, loop=True):
    rows = []
    picture = None
    with tempfile.TemporaryDirectory() as tmp:
        for seed in set_seeds:
            folder = Path(tmp) / f"set{seed}"
            bench.write_shapes(bench.shape_set(9, seed=seed, families=families), folder)
            library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache_dir)
            rng = np.random.default_rng(500 + seed)
            for _trial in range(trials):
                for name in library.names:
                    model = library[name]
                    T = _world(rng)
                    three = [_touch(model, T, rng) for _ in range(3)]
                    one, t1 = _recognise(three[:1], library)
                    rec3, t3 = _recognise(three, library)
                    # the two loops start from the same first touch (a paired comparison)
                    # the loops draw from their own generator: the three-touch objects are
                    # the same with and without --no-loop
                    lrng = np.random.default_rng(int(rng.integers(2**32)))
                    first = _touch(model, T, lrng, None, loop_length, loop_noise)
                    if loop:
                        act, act_touches, adv_t = _loop(
                            library, model, T, lrng, first, True, loop_length, loop_noise
                        )
                        ran, ran_touches, _ = _loop(
                            library, model, T, lrng, first, False, loop_length, loop_noise
                        )
                    else:  # three touches only: the loops' columns repeat the first touch
                        act = ran = one
                        act_touches = ran_touches = [first]
                        adv_t = []
                    row = {
                        "set": seed,
                        "shape": name,
                        "family": name.split("_")[0],
                        "right3": rec3.best is not None and rec3.best.model == name,
                        "recognised3": rec3.verdict == "recognised",
                        "pose3": _pose_error(rec3, three, T),
                        "oracle3": _oracle_error(rec3, three, model, T),
                        "t1": t1,
                        "t3": t3,
                        "right1": one.best is not None and one.best.model == name,
                        "active_n": len(act_touches),
                        "active_right": act.best is not None and act.best.model == name,
                        "active_decided": act.verdict == "recognised",
                        "random_n": len(ran_touches),
                        "random_right": ran.best is not None and ran.best.model == name,
                        "random_decided": ran.verdict == "recognised",
                        "advice_s": adv_t,
                    }
                    rows.append(row)
                    if row["active_right"] and len(act_touches) > (
                        0 if picture is None else len(picture[1])
                    ):
                        picture = (model, act_touches, T, name)
                    log(
                        f"set {seed} {name:<22} 3: {rec3.verdict[:5]} {row['right3']!s:<5} "
                        f"pose {row['pose3']:.4f} (oracle {row['oracle3']:.4f}) x{t3 / t1:.2f} "
                        f"| active {len(act_touches)} "
                        f"{row['active_right']!s:<5} random {len(ran_touches)} "
                        f"{row['random_right']!s:<5}"
                    )
    return rows, picture


def _pct(k, n) -> str:
    return f"{k}/{n} = {100.0 * k / max(n, 1):.1f}%"


def report(rows, args, seconds) -> str:
    n = len(rows)
    right3 = sum(r["right3"] for r in rows)
    rec3 = sum(r["recognised3"] for r in rows)
    asym = [r["pose3"] for r in rows if r["family"] == "bumped"]
    oracle = [r["oracle3"] for r in rows if r["family"] == "bumped"]
    ratios = [r["t3"] / r["t1"] for r in rows]
    act_n = [r["active_n"] for r in rows]
    ran_n = [r["random_n"] for r in rows]
    adv = [t for r in rows for t in r["advice_s"]]
    lines = [
        "# Several touches and the active loop",
        "",
        f"Command: `python tools/touches.py --sets {' '.join(map(str, args.sets))} "
        f"--trials {args.trials} --loop-length {args.loop_length} --loop-noise "
        f"{args.loop_noise}"
        + (" --no-loop" if args.no_loop else "")
        + (f" --families {' '.join(args.families)}" if args.families else "")
        + "`  ",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; shared 2-core machine; "
        f"{seconds / 60:.1f} min; load average {os.getloadavg()[0]:.2f} at the end.",
        "",
        f"Shape sets {args.sets} (nine generated unit-size shapes each, "
        "`meshrec.bench.shape_set`"
        + (f", families {', '.join(args.families)}" if args.families else "")
        + "), every shape of the set in the library; curves "
        f"{LENGTH} long, noise +-{NOISE} (uniform); {n} objects placed at random poses.",
        "",
        "## Three touches at random places",
        "",
        "| measure | value | target |",
        "|---|---|---|",
        f"| right (top model) | {_pct(right3, n)} | >= 98% |",
        f"| `recognised` | {_pct(rec3, n)} | >= 90% |",
        f"| one touch alone: right | {_pct(sum(r['right1'] for r in rows), n)} | - |",
        "| pose error on the asymmetric shapes (bumped spheres), largest point "
        f"displacement: median / max | {_fmt_med_max(asym)} | <= 0.01 |",
        "| the same, of the oracle (every touch refined from the true pose: the error the "
        f"noise leaves) | {_fmt_med_max(oracle)} | - |",
        f"| CPU time with three touches / one touch: median (max) | "
        f"{statistics.median(ratios):.2f} ({max(ratios):.2f}) | <= 2 |",
        f"| CPU time of one touch / three touches: median | "
        f"{statistics.median([r['t1'] for r in rows]):.2f} s / "
        f"{statistics.median([r['t3'] for r in rows]):.2f} s | - |",
        "",
    ]
    if args.no_loop:
        return "\n".join(lines) + "\n"
    lines += [
        "## Active loop against random touches (until `recognised`, at most "
        f"{MAX_TOUCHES} touches)",
        "",
        f"Curves {args.loop_length} long, noise +-{args.loop_noise}; both loops start from "
        "the same random first touch.",
        "",
        "| strategy | mean touches | median | decided (`recognised`) | final answer right |",
        "|---|---|---|---|---|",
        f"| advised (`next_touch`) | {np.mean(act_n):.2f} | {statistics.median(act_n):g} | "
        f"{_pct(sum(r['active_decided'] for r in rows), n)} | "
        f"{_pct(sum(r['active_right'] for r in rows), n)} |",
        f"| random | {np.mean(ran_n):.2f} | {statistics.median(ran_n):g} | "
        f"{_pct(sum(r['random_decided'] for r in rows), n)} | "
        f"{_pct(sum(r['random_right'] for r in rows), n)} |",
        "",
        f"Touches advised over random: {np.mean(act_n) / np.mean(ran_n):.2f} (target <= 0.75); "
        f"touches after the first: {(np.mean(act_n) - 1) / max(np.mean(ran_n) - 1, 1e-9):.2f}. "
        f"`next_touch` time: median {statistics.median(adv) if adv else float('nan'):.2f} s, "
        f"max {max(adv) if adv else float('nan'):.2f} s over {len(adv)} calls (nine models).",
        "",
        "## Per family",
        "",
        "| family | objects | 3 touches right | recognised | active touches | random touches |",
        "|---|---|---|---|---|---|",
    ]
    for fam in sorted({r["family"] for r in rows}):
        fr = [r for r in rows if r["family"] == fam]
        lines.append(
            f"| {fam} | {len(fr)} | {sum(r['right3'] for r in fr)} | "
            f"{sum(r['recognised3'] for r in fr)} | {np.mean([r['active_n'] for r in fr]):.2f} | "
            f"{np.mean([r['random_n'] for r in fr]):.2f} |"
        )
    return "\n".join(lines) + "\n"


def _fmt_med_max(values) -> str:
    if not values:
        return "-"
    return f"{statistics.median(values):.4f} / {max(values):.4f} ({len(values)} objects)"


def figure(picture, path: Path) -> None:
    """The active run's touches, numbered, on the model (model coordinates)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model, touches, T_world_model, name = picture
    T = np.linalg.inv(T_world_model)
    V = np.asarray(model.mesh.vertices)
    F = np.asarray(model.mesh.faces)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ax.plot_trisurf(V[:, 0], V[:, 1], V[:, 2], triangles=F, color="0.85", alpha=0.35, lw=0)
    for k, touch in enumerate(touches, start=1):
        for c in touch.curves:
            p = c @ T[:3, :3].T + T[:3, 3]
            ax.plot(p[:, 0], p[:, 1], p[:, 2], color=f"C{k}", lw=2)
        mid = touch.curves[0][len(touch.curves[0]) // 2] @ T[:3, :3].T + T[:3, 3]
        ax.text(*mid, f" {k}", color="k", fontsize=13, weight="bold")
    ax.set_title(f"active loop on {name}: touch 1 at random, then as advised")
    ax.set_box_aspect(np.ptp(V, axis=0))
    ax.set_axis_off()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, nargs="+", default=[5], help="shape-set seeds")
    p.add_argument("--trials", type=int, default=1, help="objects per shape per set")
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--out", type=Path, default=None, help="Markdown report")
    p.add_argument("--figure", type=Path, default=None, help="PNG of one active run")
    p.add_argument("--loop-length", type=float, default=LENGTH, help="active loop's curves")
    p.add_argument("--loop-noise", type=float, default=NOISE, help="active loop's noise")
    p.add_argument(
        "--families",
        nargs="+",
        default=None,
        help="shape families of the sets (default: all; e.g. ellipsoid bumped_sphere for a "
        "library of look-alikes)",
    )
    p.add_argument(
        "--no-loop",
        action="store_true",
        help="three touches only (accuracy, pose, CPU time over one touch): no active loop",
    )
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    rows, picture = run(
        args.sets,
        args.trials,
        args.cache_dir,
        lambda s: print(s, flush=True),
        args.loop_length,
        args.loop_noise,
        args.families,
        not args.no_loop,
    )
    text = report(rows, args, time.perf_counter() - t0)
    print(text)
    if args.out is not None:
        args.out.write_text(text)
    if args.figure is not None and picture is not None:
        figure(picture, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
