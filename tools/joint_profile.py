"""Where a three-touch recognition's CPU time goes, against one touch (issue 12).

The objects of ``tools/touches.py`` (the same shape set, seeded poses and touches: its
generator is drawn from in the same order), each recognised from its first touch alone
and from its three touches. Each phase's CPU time (``time.process_time``) is read from
``Recognition.phase_times`` (:class:`meshrec.PhaseTimes`: each phase's exclusive time,
the parts of a joint phase within it), the whole call's measured around it:

- ``first touch``: the first touch registered alone on every model (the cascade), and
  its poses scored on every touch;
- ``best-first: ...``: the best-first joint fits (``meshrec.recognition.bestfirst``):
  touches 2 and 3 registered alone, the joint refinements (with the harder search's
  seeds), and its own work (the bounds);
- ``adequacy: ...``: the search adequacy step (its single-touch registrations, the pair
  seeds, their joint refinements, its own work);
- ``near-symmetries``, ``widened pass``, ``dense pass``, ``scoring``, ``pose freedom``,
  ``warnings`` (coarse models, sharp edges), ``probe-offset check``, ``curve fits``,
  ``checks``, ``other`` (the rest of the call as measured around it).

Prints a Markdown table (medians over the objects, and the sum) and each object's line.
Public API only: it measures the recognition as any caller runs it (in this process,
serially).

    PYTHONPATH=. .venv/bin/python tools/joint_profile.py --sets 7 \
        --families ellipsoid bumped_sphere [--objects 0 3] [--cprofile FILE]
"""

from __future__ import annotations

import argparse
import cProfile
import os
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

LENGTH, NOISE = 0.3, 0.002  # tools/touches.py's three touches

#: (label, the CPU seconds of a PhaseTimes p); "other" is added from the measured total.
_PHASES = [
    ("first touch", lambda p: p.first),
    ("best-first: touches registered alone", lambda p: p.best_first_alone),
    ("best-first: joint refinements", lambda p: p.best_first_joint),
    ("best-first: own work", lambda p: p.best_first - p.best_first_alone - p.best_first_joint),
    ("adequacy: touches registered alone", lambda p: p.adequacy_alone),
    ("adequacy: pair seeds", lambda p: p.adequacy_pairs),
    ("adequacy: joint refinements", lambda p: p.adequacy_joint),
    (
        "adequacy: own work",
        lambda p: p.adequacy - p.adequacy_alone - p.adequacy_pairs - p.adequacy_joint,
    ),
    ("near-symmetries", lambda p: p.symmetries),
    ("widened pass", lambda p: p.widened),
    ("dense pass", lambda p: p.dense),
    ("poses tried on other models", lambda p: p.transfer),
    ("scoring", lambda p: p.scoring),
    ("pose freedom", lambda p: p.freedom),
    ("warnings", lambda p: p.cautions),
    ("probe-offset check", lambda p: p.probe_offset),
    ("curve fits", lambda p: p.geometry),
    ("checks", lambda p: p.checks),
]
#: The registrations alone: what three touches would cost with every joint step free.
_ALONE = ("first touch", "best-first: touches registered alone",
          "adequacy: touches registered alone")


def _world(rng) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


def _objects(seed, families, folder, cache_dir):
    """The library and tools/touches.py's objects: (name, three touches), in its order."""
    bench.write_shapes(bench.shape_set(9, seed=seed, families=families), folder)
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache_dir)
    rng = np.random.default_rng(500 + seed)
    out = []
    for name in library.names:
        model = library[name]
        T = _world(rng)
        three = [
            meshrec.simulate_touch(
                model, length=LENGTH, noise=NOISE, rng=rng, transform=False
            ).touch.transformed(T)
            for _ in range(3)
        ]
        rng.integers(2**32)  # tools/touches.py's draw for its loops' generator
        out.append((name, three))
    return library, out


def _timed(touches, library, prof=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if prof is not None:
            prof.enable()
        c0 = time.process_time()
        rec = meshrec.recognize(touches, library)
        total = time.process_time() - c0
        if prof is not None:
            prof.disable()
    spent = {label: get(rec.phase_times) for label, get in _PHASES}
    spent["other"] = total - sum(rec.phase_times.phases().values())
    return rec, total, spent


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, nargs="+", default=[7], help="shape-set seeds")
    p.add_argument("--families", nargs="+", default=None, help="shape families of the sets")
    p.add_argument("--objects", type=int, nargs="+", default=None, help="object indices")
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--cprofile", type=Path, default=None, help="cProfile of the 3-touch runs")
    args = p.parse_args(argv)
    prof = cProfile.Profile() if args.cprofile else None
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.sets:
            library, objects = _objects(
                seed, args.families, Path(tmp) / f"set{seed}", args.cache_dir
            )
            for i, (name, three) in enumerate(objects):
                if args.objects is not None and i not in args.objects:
                    continue
                _, t1, s1 = _timed(three[0], library)
                rec, t3, s3 = _timed(three, library, prof)
                rows.append((seed, name, t1, t3, s1, s3, rec))
                print(
                    f"set {seed} {name:<20} one {t1:6.2f} s three {t3:6.2f} s "
                    f"x{t3 / t1:.2f} {rec.best.model if rec.best else None} {rec.verdict} | "
                    + " ".join(f"{k}={v:.2f}" for k, v in sorted(s3.items()) if v >= 0.01),
                    flush=True,
                )
    if prof is not None:
        prof.dump_stats(args.cprofile)
    labels = sorted(
        {k for r in rows for k in (*r[4], *r[5])},
        key=lambda k: -sum(r[5].get(k, 0.0) for r in rows),
    )
    print(f"\n{len(rows)} objects, load average {os.getloadavg()[0]:.2f} at the end\n")
    print("| phase | one touch: median s | three touches: median s | three: sum s | share |")
    print("|---|---|---|---|---|")
    whole = sum(r[3] for r in rows)
    for k in labels:
        a = statistics.median(r[4].get(k, 0.0) for r in rows)
        b = [r[5].get(k, 0.0) for r in rows]
        print(
            f"| {k} | {a:.2f} | {statistics.median(b):.2f} | {sum(b):.1f} | "
            f"{100 * sum(b) / whole:.0f}% |"
        )
    t1 = [r[2] for r in rows]
    t3 = [r[3] for r in rows]
    print(
        f"| **total** | {statistics.median(t1):.2f} | {statistics.median(t3):.2f} | "
        f"{sum(t3):.1f} | 100% |"
    )
    ratios = [r[3] / r[2] for r in rows]
    print(f"\nthree over one: median {statistics.median(ratios):.2f}, max {max(ratios):.2f}")
    # The registrations alone (the first touch's, and touches 2 and 3's on the models that
    # registered them): what three touches would cost with every joint step free.
    alone = [sum(r[5][k] for k in _ALONE) / r[2] for r in rows]
    print(
        f"three over one with only the registrations alone (every joint step free): median "
        f"{statistics.median(alone):.2f}, min {min(alone):.2f}, max {max(alone):.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
