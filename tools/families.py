"""Recognition per family of models: mechanical parts, coarse primitives, YCB scans, surfaces.

    PYTHONPATH=. .venv/bin/python tools/families.py [--quick] [--trials N] [--leave-out]
        [--out FILE]

Each family is a model folder recognised as a library of its own:

* ``parts``: ``models/parts/`` (twelve mechanical parts at CAD export resolution, mm);
  the touches are simulated on the real parts (the same constructive geometry with
  2-degree circles, ``tools/make_parts.py``), noise +-0.05 mm;
* ``primitives``: ``models/primitives/`` (trimesh primitives at trimesh's default
  resolution, unit-sized); the touches on the real shapes (360 sections, a finer
  icosphere), noise +-0.001;
* ``ycb curved`` and ``ycb boxes``: the YCB scans of ``../shared/data/ycb`` (metres, 15,728
  triangles), the touches on the scans themselves, noise +-1e-4 m (a probe's accuracy);
  the boxes are the cracker box, the gelatin box, the potted meat can and the foam brick,
  as that folder's README names them;
* ``surfaces``: the paper's surfaces ``models/surfaces/``, noise +-0.001 (the paper's).

Per object and trial (seeded), three touches at random contacts (uniform by area, curves
``0.22 sqrt(area)`` long, 61 points each) on the object at one random pose; the first touch
is recognised alone, then all three together (``recognize`` takes a list of touches).
Reported per family, for one touch and for three: right (the best model is the touched
one), the verdicts (recognised, ambiguous, unknown), named with a free pose (ambiguous with
the touched model alone: a flat face), the truth among the plausible models, and confident
wrong answers (``recognised`` and wrong). ``--leave-out`` recognises each object against
its family's folder without it: an object not in the library, where every answer should
be ``unknown`` (or ``ambiguous``), none ``recognised``. ``--quick`` takes one trial of at
most four objects per family (a few minutes on a shared 2-core machine). Uses only
meshrec's public API and the builders of ``tools/make_parts.py``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import meshrec

sys.path.insert(0, str(Path(__file__).resolve().parent))
import make_parts  # the builders of the real shapes (tools/make_parts.py)

_REPO = Path(__file__).resolve().parent.parent
YCB = _REPO.parent / "shared" / "data" / "ycb"
YCB_BOXES = ("cracker_box", "foam_brick", "gelatin_box", "potted_meat_can")
POINTS = 61
TOUCHES = 3


@dataclass(frozen=True)
class Family:
    """A model folder, the objects to touch, how to make each real object, and the noise."""

    name: str
    folder: Path
    objects: tuple[str, ...] | None  # None: every model of the folder
    real: object  # callable(name) -> mesh or path of the real object touched
    noise: float


def _families(ycb: Path) -> list[Family]:
    """The benchmark's families (the YCB ones only if ``ycb`` exists)."""
    out = [
        Family("parts", _REPO / "models" / "parts", None,
               lambda n: make_parts.build_part(n, fine=True), 0.05),
        Family("primitives", _REPO / "models" / "primitives", None,
               lambda n: make_parts.build_primitive(n, fine=True), 1e-3),
    ]
    if ycb.is_dir():
        names = sorted(p.stem for p in ycb.glob("*.obj"))
        curved = tuple(n for n in names if n not in YCB_BOXES)
        boxes = tuple(n for n in names if n in YCB_BOXES)
        out += [
            Family("ycb curved", ycb, curved, lambda n: ycb / f"{n}.obj", 1e-4),
            Family("ycb boxes", ycb, boxes, lambda n: ycb / f"{n}.obj", 1e-4),
        ]
    surfaces = _REPO / "models" / "surfaces"
    out.append(Family("surfaces", surfaces, None, lambda n: surfaces / f"{n}.stl", 1e-3))
    return out


@dataclass(frozen=True)
class Outcome:
    """One recognition: the truth, the answer and its verdict."""

    truth: str
    best: str | None
    verdict: str
    plausible: tuple[str, ...]
    free: int | None
    seconds: float

    @property
    def right(self) -> bool:
        return self.best == self.truth

    @property
    def named_pose_free(self) -> bool:
        return self.verdict == "ambiguous" and self.plausible == (self.truth,)

    @property
    def confident_wrong(self) -> bool:
        return self.verdict == "recognised" and self.best != self.truth


def family_touches(real, name: str, noise: float, seed: int):
    """Three touches of one object at one random pose (a common world frame)."""
    rng = np.random.default_rng(seed)
    mesh = real(name)
    sims = [
        meshrec.simulate_touch(mesh, rng=rng, noise=noise, n_points=POINTS, transform=False,
                               name=name)
        for _ in range(TOUCHES)
    ]
    size = float(np.linalg.norm(np.ptp(sims[0].touch.points, axis=0)))
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-10 * size, 10 * size, 3)
    return [s.touch.transformed(T) for s in sims]


def _recognise(touches, library, truth: str) -> Outcome:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touches, library)
    return Outcome(
        truth,
        rec.best.model if rec.best is not None else None,
        rec.verdict,
        tuple(rec.plausible),
        None if rec.pose_freedom is None else rec.pose_freedom.free,
        time.perf_counter() - t0,
    )


def _row(family: str, n_touches: int, outs: list[Outcome]) -> str:
    n = len(outs)

    def count(pred):
        return sum(1 for o in outs if pred(o))

    right = count(lambda o: o.right)
    return (
        f"| {family} | {n_touches} | {n} | {right} ({100 * right / max(n, 1):.0f}%) | "
        f"{count(lambda o: o.verdict == 'recognised')} | "
        f"{count(lambda o: o.verdict == 'ambiguous')} | "
        f"{count(lambda o: o.verdict == 'unknown')} | "
        f"{count(lambda o: o.named_pose_free)} | "
        f"{count(lambda o: o.truth in o.plausible)} | "
        f"{count(lambda o: o.confident_wrong)} | "
        f"{statistics.median(o.seconds for o in outs):.2f} |"
    )


def main(argv=None) -> int:
    """Run the benchmark; print the Markdown report and write it to ``--out``.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status, 0 on success.
    """
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="one trial of at most 4 objects each")
    p.add_argument("--trials", type=int, default=2, help="trials per object (default 2)")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--ycb", type=Path, default=YCB, help="folder of the YCB scans")
    p.add_argument("--only", nargs="*", default=None, help="families to run (default all)")
    p.add_argument(
        "--leave-out",
        action="store_true",
        help="recognise each object against its family's folder without it (not in the "
        "library: every answer should be unknown or ambiguous, none recognised)",
    )
    p.add_argument("--out", type=Path, default=_REPO / "reports" / "families.md")
    args = p.parse_args(argv)
    trials = 1 if args.quick else args.trials
    lines: list[str] = []

    def emit(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    cmd = " ".join(["python tools/families.py", *(argv if argv is not None else sys.argv[1:])])
    emit("# Recognition per family of models\n")
    emit(f"Command: `{cmd}`; meshrec {meshrec.__version__}. {trials} trial(s) per object, "
         f"seeds from {args.seed}; each trial: three touches of the object at one random pose, "
         "recognised first alone (1 touch) then together (3 touches), against the family's "
         + ("folder without the touched object (it is not in the library: \"right\" is "
            "always 0 and \"confident wrong\" counts every `recognised`).\n"
            if args.leave_out else "folder.\n"))
    emit("| family | touches | runs | right | recognised | ambiguous | unknown | "
         "named, pose free | truth plausible | confident wrong | time median (s) |")
    emit("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    details: list[str] = []
    t_all = time.perf_counter()
    for fam in _families(args.ycb):
        if args.only and fam.name not in args.only:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            library = meshrec.ModelLibrary.from_folder(fam.folder)
        names = list(fam.objects if fam.objects is not None else library.names)
        if args.quick:
            names = names[:: max(1, len(names) // 4)][:4]
        one, three = [], []
        for name in names:
            for k in range(trials):
                touches = family_touches(fam.real, name, fam.noise, args.seed + k)
                models = (
                    [library[n] for n in library.names if n != name] if args.leave_out else library
                )
                a = _recognise(touches[:1], models, name)
                b = _recognise(touches, models, name)
                one.append(a)
                three.append(b)
                details.append(
                    f"| {fam.name} | {name} | {args.seed + k} | {a.best} ({a.verdict}, "
                    f"free {a.free}) | {b.best} ({b.verdict}, free {b.free}) |"
                )
                print(f"  {details[-1]}", file=sys.stderr, flush=True)
        emit(_row(fam.name, 1, one))
        emit(_row(fam.name, TOUCHES, three))
    emit()
    emit(f"Total time {time.perf_counter() - t_all:.0f} s. \"right\": the best model is the "
         "touched one; \"named, pose free\": ambiguous with the touched model alone (the "
         "touch leaves its pose free: a flat face, a cylinder's side); \"confident wrong\": "
         "recognised and wrong.\n")
    emit("## Every run\n")
    emit("| family | object | seed | 1 touch: best (verdict, free DOF) | 3 touches |")
    emit("|---|---|---:|---|---|")
    for d in details:
        emit(d)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
