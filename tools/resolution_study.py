"""How coarse may a model be? Recognition against libraries decimated to fewer faces.

    python tools/resolution_study.py --shapes 9 --trials 2 --out reports/resolution_study.md

Evidence for the thresholds of the resolution check (``defaults.RESOLUTION_*``,
:mod:`meshrec.model.resolution`). The shapes are ``meshrec.bench.shape_set(n, seed)``
(unit-size smooth shapes, about 20k faces each). For each level, every shape is decimated
with Open3D's quadric decimation to the level's face count (irregular triangles, as a
scan or a CAD tool's mesh simplification writes them), and the library of the decimated
shapes is indexed; the touches are simulated on the *fine* shapes (the real objects) with
the default protocol (61 points per curve, curves 0.22 sqrt(area) long) and recognised
against the decimated library. Per level: the models' median vertices per curve and
chord error (as ``meshrec models`` reports them), how many of them the check flags, and
the answers: right (best model is the touched one), recognised, recognised wrong, truth
among the plausible, and the touched model's fit (its rms over the noise's, 1 for a
perfect model). Needs open3d (the ``viz`` extra) for the decimation. Uses only meshrec's
public API.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import trimesh

import meshrec
import meshrec.bench


def decimated(mesh: trimesh.Trimesh, faces: int) -> trimesh.Trimesh:
    """``mesh`` simplified to about ``faces`` triangles (Open3D's quadric decimation)."""
    import open3d as o3d

    if faces >= len(mesh.faces):
        return mesh
    m = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(mesh.vertices, dtype=np.float64)),
        o3d.utility.Vector3iVector(np.asarray(mesh.faces, dtype=np.int32)),
    )
    m = m.simplify_quadric_decimation(target_number_of_triangles=int(faces))
    return trimesh.Trimesh(np.asarray(m.vertices), np.asarray(m.triangles), process=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--shapes", type=int, default=9, help="shapes in the library")
    p.add_argument("--seed", type=int, default=11, help="seed of the shapes and touches")
    p.add_argument("--trials", type=int, default=2, help="touches per shape and level")
    p.add_argument("--noise", type=float, default=1e-3, help="uniform noise +-A")
    p.add_argument(
        "--faces",
        type=int,
        nargs="+",
        default=[250, 500, 1000, 2000, 5000, 0],
        help="face counts of the levels (0: the fine shapes themselves)",
    )
    p.add_argument("--out", type=Path, default=None, help="also write the report here")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore", meshrec.ResolutionWarning)  # the table counts them
    lines: list[str] = []

    def emit(text=""):
        print(text)
        sys.stdout.flush()
        lines.append(text)

    shapes = meshrec.bench.shape_set(args.shapes, seed=args.seed)
    cmd = " ".join(
        ["python tools/resolution_study.py", *(argv if argv is not None else sys.argv[1:])]
    )
    emit("# Resolution study: recognition against decimated libraries\n")
    emit(f"Command: `{cmd}`; meshrec {meshrec.__version__}.\n")
    emit(
        f"{len(shapes)} shapes ({', '.join(s.name for s in shapes)}); {args.trials} touches "
        f"per shape and level on the fine shape, noise +-{args.noise:g}; each recognised "
        "against the library at that level. Vertices per curve and chord error: medians over "
        "the library's models; fit: the touched model's rms over the noise's rms (median, "
        "max).\n"
    )
    emit(
        "| faces | vertices per curve | chord error (% of curve) | flagged too coarse "
        "| right | recognised | recognised wrong | truth plausible | fit / noise (median, max) "
        "| s per touch |"
    )
    emit("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    noise_rms = args.noise / np.sqrt(3.0)
    for level in args.faces:
        with tempfile.TemporaryDirectory(prefix="resolution-study-") as tmp:
            folder = Path(tmp) / "models"
            folder.mkdir()
            for s in shapes:
                m = s.mesh if level == 0 else decimated(s.mesh, level)
                m.export(folder / f"{s.name}.stl")
            library = meshrec.ModelLibrary.from_folder(folder, cache_dir=Path(tmp) / "cache")
            res = [m.resolution for m in library.models]
            per_curve = float(np.median([r.vertices_per_curve for r in res]))
            chord = float(np.median([r.chord_fraction for r in res]))
            flagged = sum(r.too_coarse for r in res)
            counts = np.zeros(4, dtype=int)  # right, recognised, recognised wrong, plausible
            fits, secs, n = [], [], 0
            for k, s in enumerate(shapes):
                for t in range(args.trials):
                    seed = args.seed * 10_000 + 100 * k + t
                    sim = meshrec.simulate_touch(s.mesh, rng=seed, noise=args.noise, name=s.name)
                    t0 = time.process_time()
                    rec = meshrec.recognize(sim.touch, library)
                    secs.append(time.process_time() - t0)
                    n += 1
                    best = rec.best.model if rec.best is not None else None
                    right = best == s.name
                    counts += (
                        right,
                        rec.verdict == "recognised",
                        rec.verdict == "recognised" and not right,
                        s.name in rec.plausible,
                    )
                    mine = [r for r in rec.ranking if r.model == s.name]
                    if mine and np.isfinite(mine[0].rms):
                        fits.append(mine[0].rms / noise_rms)
        label = "fine" if level == 0 else f"{level}"
        emit(
            f"| {label} | {per_curve:.3g} | {100 * chord:.3g} | {flagged}/{len(res)} "
            f"| {counts[0]}/{n} | {counts[1]} | {counts[2]} | {counts[3]} "
            f"| {np.median(fits):.2f}, {np.max(fits):.2f} | {np.median(secs):.2f} |"
        )
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
