"""Where a three-touch recognition's CPU time goes, against one touch (issue 12).

The objects of ``tools/touches.py`` (the same shape set, seeded poses and touches: its
generator is drawn from in the same order), each recognised from its first touch alone
and from its three touches. Each phase's CPU time (``time.process_time``) is taken by
wrapping the function that runs it where the recognition calls it (its exclusive time:
a phase nested in another, such as the joint refinement inside the pair search, counts
only for itself):

- ``first touch``: the first touch registered alone on every model (the cascade);
- ``best-first: ...``: the best-first joint fits (``meshrec.recognition.bestfirst``):
  the stages of touches 2 and 3 registered alone (lookup, phi grid, screening, phi
  refinement, local searches, search refinement) and the joint refinements (with the
  harder search's seeds);
- ``adequacy: ...``: the search adequacy step (its single-touch registrations, the pair
  seeds, their joint refinements);
- ``near-symmetries``, ``widened pass``, ``scoring``, ``probe-offset check``,
  ``pose freedom``, ``other`` (the rest: curve fits, unit checks, warnings).

Prints a Markdown table (medians over the objects, and the sum) and each object's line.
It wraps meshrec's internal functions (as ``tools/cost_profile.py`` does), so it
measures this checkout's code path, not only its public API; the answers are not
changed by the wrapping.

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
import meshrec.recognition.bestfirst as bestfirst_module
import meshrec.recognition.joint as joint_module
import meshrec.recognition.recognize as recognize_module
import meshrec.registration.register as register_module
from meshrec import bench

LENGTH, NOISE = 0.3, 0.002  # tools/touches.py's three touches

# (module, function name, phase label); a label starting with "/" is a sub-phase: it
# takes the enclosing phase's label as its prefix.
_WRAPPED = [
    (recognize_module, "cascade_register", "first touch"),
    (recognize_module, "_rank", "first touch"),
    (recognize_module, "first_touch_fit", "first touch"),
    (recognize_module, "fit_best_first", "best-first"),
    (bestfirst_module, "register_touches", "best-first"),
    (recognize_module, "_search_adequately", "adequacy"),
    (recognize_module, "_explore_near_symmetries", "near-symmetries"),
    (recognize_module, "_widened", "widened pass"),
    (recognize_module, "_score", "scoring"),
    (recognize_module, "flat_prior", "scoring"),
    (recognize_module, "warn_probe_offset", "probe-offset check"),
    (recognize_module, "_with_pose_freedom", "pose freedom"),
    (joint_module, "pair_seeds", "/pair seeds"),
    (joint_module, "joint_poses", "/joint refinement"),
    # the stages of every registration alone (the first touch's, touches 2 and 3's)
    (register_module, "lookup_candidates", "/lookup"),
    (register_module, "phi_brackets", "/phi grid"),
    (register_module, "screen_candidates", "/screening"),
    (register_module, "refine_phis", "/phi refinement"),
    (register_module, "search_candidates", "/local searches"),
    (register_module, "refine_searches", "/search refinement"),
]


class _Clock:
    """Exclusive CPU time per label, with a stack of the labels running."""

    def __init__(self):
        self.spent: dict[str, float] = {}
        self.stack: list[list] = []  # [label, start, time of the wrapped calls inside]

    def wrap(self, fn, label):
        def call(*args, **kwargs):
            parent = self.stack[-1][0] if self.stack else None
            if label.startswith("/"):
                full = (parent.split("/")[0] if parent else "other") + ":" + label[1:]
            else:
                full = label if parent is None else parent
            frame = [full, time.process_time(), 0.0]
            self.stack.append(frame)
            try:
                return fn(*args, **kwargs)
            finally:
                self.stack.pop()
                took = time.process_time() - frame[1]
                self.spent[full] = self.spent.get(full, 0.0) + took - frame[2]
                if self.stack:
                    self.stack[-1][2] += took

        return call


def _stage(label: str) -> bool:
    """Whether a label is a stage of a registration alone (touches 2 and 3)."""
    stages = {label[1:] for _, _, label in _WRAPPED[-6:]}
    return ":" in label and label.split(":", 1)[1] in stages


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


def _timed(clock, touches, library, prof=None):
    clock.spent = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if prof is not None:
            prof.enable()
        c0 = time.process_time()
        rec = meshrec.recognize(touches, library)
        total = time.process_time() - c0
        if prof is not None:
            prof.disable()
    spent = dict(clock.spent)
    spent["other"] = spent.get("other", 0.0) + total - sum(spent.values())
    return rec, total, spent


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, nargs="+", default=[7], help="shape-set seeds")
    p.add_argument("--families", nargs="+", default=None, help="shape families of the sets")
    p.add_argument("--objects", type=int, nargs="+", default=None, help="object indices")
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--cprofile", type=Path, default=None, help="cProfile of the 3-touch runs")
    args = p.parse_args(argv)
    clock = _Clock()
    for module, name, label in _WRAPPED:
        setattr(module, name, clock.wrap(getattr(module, name), label))
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
                _, t1, s1 = _timed(clock, three[0], library)
                rec, t3, s3 = _timed(clock, three, library, prof)
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
    alone = [
        sum(v for k, v in r[5].items() if k.startswith("first touch") or _stage(k)) / r[2]
        for r in rows
    ]
    print(
        f"three over one with only the registrations alone (every joint step free): median "
        f"{statistics.median(alone):.2f}, min {min(alone):.2f}, max {max(alone):.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
