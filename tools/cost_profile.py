"""Where one recognition's CPU time goes, and what a cheap lower bound could save the phi grid.

Two measurements on the four paper surfaces (``models/surfaces``), in-process with a warm
cache, on the 12 seeded touches of ``tools/speed.py`` (``bench.paper_touch``, seeds 0-2):

1. CPU seconds per stage: each registration's ``StageTimes`` taken with
   ``time.process_time`` instead of the wall clock (lookup, phi grid and its refinement,
   screening, local searches, final refinements), and the phases of ``recognize`` as
   ``Recognition.phase_times`` gives them (CPU: the first touch's registrations as a
   whole, the contact's curve fits, the checks, the scores, the pose freedom, the
   warnings, the probe-offset check after the verdict, the rest).
2. The phi grid by bounds (``meshrec.registration.bounded``) started from a per-point
   lower bound ``max(d - s, 0)`` instead of 0, ``d`` the exact distance and ``s`` a
   slack: what a distance grid with error at most ``s`` would give it (a grid of unsigned
   distances with spacing h bounds d(p) >= d(node) - |p - node|, a slack of up to
   0.87 h). It counts the exact point distances still needed, against the whole grid's.
   The bound is started by running the module's own function with its zero start
   replaced (its source, one line changed): the same algorithm, not a re-implementation.
3. With ``--errors``: how far an approximate distance for the phi grid (stage 2 only) may
   be off. The phi grid's point distances (``meshrec.registration.bounded``) get an
   error uniform in [-e, e] (clipped at 0), a fixed function of the point's coordinates
   (as a distance grid's error is: a hash of their bits, not a random draw); every other
   stage stays exact. Each touch's verdict, best model, best error and contact are
   compared with the exact run's.

4. With ``--grid N``: a prototype of that distance, not used by meshrec: per model a
   dense grid of distances over its bounding box grown by 0.4 (the touches' reach),
   ``N`` nodes along the longest side, each node's distance from libigl (unsigned, or
   signed by the side of the closest face's normal as the residuals are), and the phi
   grids' points looked up by trilinear interpolation (the absolute value of the signed
   one): build time and size per model, lookup time against libigl's on the same
   points, and the lookups' errors.

Prints Markdown tables. Usage::

    python tools/cost_profile.py [--slacks 0 0.002 0.005 0.01 0.02 0.03] [--errors 1e-4 1e-2]
                                 [--grid 64]
"""

from __future__ import annotations

import argparse
import inspect
import itertools
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import meshrec
import meshrec.registration.bounded as bounded
import meshrec.registration.brackets as brackets
import meshrec.registration.register as register_module
from meshrec import bench
from meshrec.registration.objective import point_distances

MODELS = Path(__file__).resolve().parents[1] / "models"
#: The phases of Recognition.phase_times shown (one touch: the joint phases are 0).
PHASES = ("first", "geometry", "checks", "widened", "dense", "scoring", "freedom", "cautions",
          "probe_offset")


class _ProcessClock:
    """Stands for the ``time`` module inside ``register``: its stage clock on CPU time."""

    perf_counter = staticmethod(time.process_time)
    process_time = staticmethod(time.process_time)


def _stage_cpu(library, touches, out: list[str]) -> None:
    register_module.time = _ProcessClock
    try:
        stages = meshrec.StageTimes()
        spent = dict.fromkeys((*PHASES, "other"), 0.0)
        total = 0.0
        for touch in touches:
            c0 = time.process_time()
            rec = meshrec.recognize(touch, library)
            total += time.process_time() - c0
            for r in rec.ranking:
                stages = stages + r.times
            for name in PHASES:
                spent[name] += getattr(rec.phase_times, name)
            spent["other"] += rec.phase_times.other
    finally:
        register_module.time = time
    n = len(touches)
    out.append(f"### CPU per recognition: {total / n:.3f} s (mean of {n} touches)\n")
    out.append("Stages: every registration's ``StageTimes`` on CPU; phases: "
               "``Recognition.phase_times`` (the stages run within ``first``, "
               "``widened`` and ``dense``).\n")
    out.append("| part | CPU s per recognition | share |")
    out.append("|---|---:|---:|")
    for key in ("lookup", "phi", "screen", "search", "refine"):
        v = getattr(stages, key) / n
        out.append(f"| stage {key} | {v:.3f} | {v * n / total:.0%} |")
    for name, v in spent.items():
        out.append(f"| phase {name} | {v / n:.4f} | {v / total:.1%} |")
    out.append("")


def _started_bounds():
    """``bounded_grid_errors`` with an ``init`` argument: the starting per-point bounds."""
    src = inspect.getsource(bounded.bounded_grid_errors)
    for old, new in (
        ("rounds: Sequence[int] = defaults.PHI_BOUND_ROUNDS,",
         "rounds: Sequence[int] = defaults.PHI_BOUND_ROUNDS, init=None,"),
        ("dist = np.zeros((c, s, n))",
         "dist = np.zeros((c, s, n)) if init is None else init.copy()"),
    ):
        if old not in src:
            raise RuntimeError(f"bounded_grid_errors changed: {old!r} not found")
        src = src.replace(old, new)
    namespace = dict(vars(bounded))
    exec(src, namespace)  # the module's own source, one line changed
    return namespace["bounded_grid_errors"]


def _bound_slack(library, touches, slacks, out: list[str]) -> None:
    original = brackets.bounded_grid_errors
    calls = _spied_grids(library, touches)
    started = _started_bounds()
    whole = now = 0
    needed = np.zeros(len(slacks))
    for model, origins, local_points, steps, kwargs in calls:
        placed = bounded.placed_grid(origins, np.array(local_points), steps)
        d = point_distances(model, placed.reshape(-1, 3)).reshape(placed.shape[:3])
        whole += d.size
        ref = original(model, origins, local_points, steps, **kwargs)
        now += ref.evaluated
        for i, s in enumerate(slacks):
            g = started(model, origins, local_points, steps, init=np.maximum(d - s, 0.0), **kwargs)
            both = ref.exact & g.exact
            if not np.array_equal(g.errors[both], ref.errors[both]):
                raise RuntimeError("an exact sample differs: the bound was not a bound")
            needed[i] += g.evaluated
    out.append(f"### Phi grid: exact point distances, {len(calls)} grids, "
               f"{whole} point distances in all\n")
    out.append("| start of the bounds | exact distances | fraction of the whole grid |")
    out.append("|---|---:|---:|")
    out.append(f"| 0 (as now) | {now} | {now / whole:.3f} |")
    for s, k in zip(slacks, needed, strict=True):
        out.append(f"| max(d - {s:g}, 0) | {int(k)} | {k / whole:.3f} |")
    out.append("")


def _spied_grids(library, touches) -> list:
    """The phi grids' arguments of the touches' recognitions (keyword arguments last)."""
    calls = []
    original = brackets.bounded_grid_errors

    def spy(model, origins, local_points, steps, **kwargs):
        calls.append((model, origins, local_points, steps, kwargs))
        return original(model, origins, local_points, steps, **kwargs)

    brackets.bounded_grid_errors = spy
    try:
        for touch in touches:
            meshrec.recognize(touch, library)
    finally:
        brackets.bounded_grid_errors = original
    return calls


def _trilinear(lo: np.ndarray, h: float, d: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Trilinear interpolation of node values ``d`` (grid from ``lo``, spacing ``h``)."""
    x = (P - lo) / h
    i = np.clip(np.floor(x).astype(np.int64), 0, np.array(d.shape) - 2)
    f = x - i
    out = np.zeros(len(P))
    for corner in itertools.product((0, 1), repeat=3):
        w = np.ones(len(P))
        for axis, up in enumerate(corner):
            w *= f[:, axis] if up else 1.0 - f[:, axis]
        out += w * d[i[:, 0] + corner[0], i[:, 1] + corner[1], i[:, 2] + corner[2]]
    return out


def _grid_prototype(library, touches, nodes: int, out: list[str]) -> None:
    calls = _spied_grids(library, touches)
    out.append(f"### Prototype distance grids, {nodes} nodes along the longest side\n")
    out.append("| model | nodes | MB (float32) | spacing | build CPU s (signed) |")
    out.append("|---|---:|---:|---:|---:|")
    grids = {}
    for m in library:
        V = m.mesh.vertices
        lo, hi = V.min(axis=0) - 0.4, V.max(axis=0) + 0.4
        h = float((hi - lo).max()) / (nodes - 1)
        shape = tuple(int(k) for k in np.ceil((hi - lo) / h).astype(int) + 1)
        axes = [lo[i] + h * np.arange(shape[i]) for i in range(3)]
        X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        c0 = time.process_time()
        dist, closest, face = m.surface.closest_points(X)
        side = np.einsum("ij,ij->i", X - closest, m.mesh.face_normals[face])
        signed = np.where(side < 0.0, -dist, dist)
        took = time.process_time() - c0
        grids[m.name] = (lo, h, dist.astype(np.float32).reshape(shape),
                         signed.astype(np.float32).reshape(shape))
        out.append(f"| {m.name} | {'x'.join(map(str, shape))} | {4e-6 * dist.size:.1f} | "
                   f"{h:.4f} | {took:.2f} |")
    out.append("")
    t_exact = t_grid = 0.0
    errors = {"unsigned": [], "signed": []}
    n = 0
    for model, origins, local_points, steps, _ in calls:
        P = bounded.placed_grid(origins, np.array(local_points), steps).reshape(-1, 3)
        c0 = time.process_time()
        exact = point_distances(model, P)
        t_exact += time.process_time() - c0
        lo, h, unsigned, signed = grids[model.name]
        c0 = time.process_time()
        approx = _trilinear(lo, h, unsigned, P)
        t_grid += time.process_time() - c0
        errors["unsigned"].append(np.abs(approx - exact))
        errors["signed"].append(np.abs(np.abs(_trilinear(lo, h, signed, P)) - exact))
        n += len(P)
    out.append(f"The {len(calls)} phi grids' {n} points: libigl {t_exact:.2f} s of CPU "
               f"({1e6 * t_exact / n:.2f} us per point), trilinear lookups {t_grid:.2f} s "
               f"({1e6 * t_grid / n:.2f} us per point).\n")
    out.append("| grid | error mean | median | 99th percentile | largest |")
    out.append("|---|---:|---:|---:|---:|")
    for kind, parts in errors.items():
        e = np.concatenate(parts)
        out.append(f"| {kind} | {e.mean():.2e} | {np.median(e):.2e} | "
                   f"{np.quantile(e, 0.99):.2e} | {e.max():.2e} |")
    out.append("")


def _hashed_error(points: np.ndarray, e: float) -> np.ndarray:
    """An error in [-e, e] per point, a fixed function of its coordinates' bits."""
    bits = np.frombuffer(np.ascontiguousarray(points, dtype=np.float64).tobytes(), np.uint64)
    h = bits.reshape(-1, 3)
    mixed = h[:, 0] ^ (h[:, 1] >> np.uint64(7)) ^ (h[:, 2] >> np.uint64(13))
    u = (mixed % np.uint64(1000003)).astype(np.float64) / 1000003.0
    return e * (2.0 * u - 1.0)


def _perturbed(library, touches, errors, out: list[str]) -> None:
    exact = [meshrec.recognize(t, library) for t in touches]
    out.append("### Phi grid distances off by up to e (other stages exact)\n")
    out.append("| e | same verdict | same best model | best error bit-equal | "
               "best error, largest relative change | contact moved, largest | moved on |")
    out.append("|---:|---:|---:|---:|---:|---:|---|")
    n = len(touches)
    for e in errors:
        def approx(model, points, _e=e):
            d = point_distances(model, points)
            return np.maximum(d + _hashed_error(points, _e), 0.0)

        bounded.point_distances = approx
        try:
            recs = [meshrec.recognize(t, library) for t in touches]
        finally:
            bounded.point_distances = point_distances
        verdict = sum(r.verdict == r0.verdict for r, r0 in zip(recs, exact, strict=True))
        best = sum(r.best.model == r0.best.model for r, r0 in zip(recs, exact, strict=True))
        equal = sum(r.best.error == r0.best.error for r, r0 in zip(recs, exact, strict=True))
        rel = max(abs(r.best.error / r0.best.error - 1) for r, r0 in zip(recs, exact, strict=True))
        moved = max(float(np.linalg.norm(r.best.contact - r0.best.contact))
                    for r, r0 in zip(recs, exact, strict=True))
        where = sorted({r0.best.model for r, r0 in zip(recs, exact, strict=True)
                        if float(np.linalg.norm(r.best.contact - r0.best.contact)) > 1e-6})
        out.append(f"| {e:g} | {verdict}/{n} | {best}/{n} | {equal}/{n} | {rel:.2e} | "
                   f"{moved:.3g} | {', '.join(where) or '-'} |")
    out.append("")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=3, help="touches per paper surface")
    p.add_argument("--slacks", type=float, nargs="*",
                   default=[0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.03])
    p.add_argument("--errors", type=float, nargs="*", default=[],
                   help="errors e of the phi grid's distances to try (none: skip)")
    p.add_argument("--grid", type=int, default=0,
                   help="nodes along the longest side of the prototype grids (0: skip)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    library = meshrec.ModelLibrary.from_folder(MODELS / "surfaces")
    touches = [bench.paper_touch(library[s], seed).touch
               for s in meshrec.PAPER_SURFACES for seed in range(args.trials)]
    for touch in touches[:: max(args.trials, 1)]:
        meshrec.recognize(touch, library)  # warm: every model's lazy tables
    out = ["# Where a recognition's time goes (four paper surfaces)", ""]
    _stage_cpu(library, touches, out)
    _bound_slack(library, touches, args.slacks, out)
    if args.errors:
        _perturbed(library, touches, args.errors, out)
    if args.grid:
        _grid_prototype(library, touches, args.grid, out)
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
