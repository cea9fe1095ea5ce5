"""The probe-offset check on seeded touches with and without a ball tip: warned or not, and why.

Touches recognised without a radius (warm cache, in-process), as in the ball-tip tests:

1. the 12 seeded touches of the four paper surfaces (``bench.paper_touch``, seeds 0-2) and
   one touch per surface with each tip of ``--tips`` (``simulate_touch``, seeds 100+);
2. the tests' sphere (radius 1) and tube (radius 1, side only): one touch per tip in
   ``0`` and ``--tips`` and seed in 1-3 (noise 1e-3, curves 0.6 long), against both.

For each: the best model, whether a ``ProbeOffsetWarning`` was raised, ``probe_offset``'s
radius, rms0 and rms, the drop of the sum of squares in noise variances that the warning's
chi-squared test reads, and the drop that the residuals linearised at the rigid optimum
predict (``meshrec.registration.refine``'s ``_linear_gain``, which decides the skip), and
the CPU seconds of the check. Prints a Markdown table (and writes it with ``--out``)::

    python tools/probe_offset_cases.py --out reports/probe_offset.md
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

from _report import finish  # tools/_report.py

import meshrec
import meshrec.recognition.probing as probing
import meshrec.recognition.recognize as recognize_module
import meshrec.registration.refine as refine_module
from meshrec import bench
from meshrec.contact.probe import ProbeOffsetWarning

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from analytic_meshes import index_of, sphere, tube  # noqa: E402 (the tests' meshes)

_SEEN: dict = {}


def _spy() -> None:
    """Record probe_offset's answers, the linearised drop and the check's CPU time."""
    # A spy on the module's own functions (as tools/cost_profile.py's stage clocks): the
    # private _linear_gain is read, not re-implemented.
    offset, warn = probing.probe_offset, recognize_module.warn_probe_offset
    gain = refine_module._linear_gain

    def probe_offset(points, model, T, noise, **kwargs):
        _SEEN["offset"] = offset(points, model, T, noise, **kwargs)
        _SEEN["n"], _SEEN["noise"] = len(points), noise
        return _SEEN["offset"]

    def linear_gain(*args):
        _SEEN["linear"] = gain(*args)
        return _SEEN["linear"]

    def warn_probe_offset(*args, **kwargs):
        c0 = time.process_time()
        try:
            return warn(*args, **kwargs)
        finally:
            _SEEN["cpu"] = time.process_time() - c0

    probing.probe_offset = probe_offset
    refine_module._linear_gain = linear_gain
    recognize_module.warn_probe_offset = warn_probe_offset


def _row(label: str, touch, library) -> str:
    _SEEN.clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = meshrec.recognize(touch, library)
    warned = sum(issubclass(w.category, ProbeOffsetWarning) for w in caught)
    if "offset" not in _SEEN:
        return f"| {label} | {rec.best.model if rec.best else '-'} | {warned} | | | | | | |"
    radius, rms0, rms = _SEEN["offset"]
    var = _SEEN["noise"] ** 2
    drop = _SEEN["n"] * (rms0**2 - rms**2) / var
    linear = _SEEN.get("linear", float("nan")) / var
    return (f"| {label} | {rec.best.model} | {warned} | {radius:.4g} | {rms0:.4g} | {rms:.4g} | "
            f"{drop:.3g} | {linear:.3g} | {_SEEN['cpu']:.4f} |")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tips", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.2],
                   help="tip radii of the tipped touches")
    p.add_argument("--out", type=Path, default=None, help="Markdown report (default: stdout)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    _spy()
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    out = ["# The probe-offset check, case by case", "",
           f"Command: `python tools/probe_offset_cases.py {shown}`", "",
           "Drops in noise variances: n (rms0^2 - rms^2) / noise^2 refined, and the one the "
           "residuals linearised at the rigid optimum predict (the skip's test: below "
           f"{meshrec.defaults.PROBE_OFFSET_CHI2 / meshrec.defaults.PROBE_OFFSET_LINEAR_MARGIN:g}"
           " the joint refinement is skipped).", "",
           "| touch | best | warned | R | rms0 | rms | drop | linearised | CPU s |",
           "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    surfaces = meshrec.ModelLibrary.from_folder(ROOT / "models" / "surfaces")
    meshrec.recognize(bench.paper_touch(surfaces["ellipsoid"], 0).touch, surfaces)  # warm
    for s in meshrec.PAPER_SURFACES:
        for seed in range(3):
            out.append(_row(f"{s} seed {seed}", bench.paper_touch(surfaces[s], seed).touch,
                            surfaces))
        for k, tip in enumerate(args.tips):
            sim = meshrec.simulate_touch(surfaces[s], rng=100 + k, probe_radius=tip)
            out.append(_row(f"{s} tip {tip:g}", sim.touch, surfaces))
    with tempfile.TemporaryDirectory(prefix="meshrec-tips-") as tmp:
        models = {"sphere": index_of(sphere(1.0, 5), Path(tmp), "sphere"),
                  "tube": index_of(tube(1.0, 4.0), Path(tmp), "tube")}
        library = list(models.values())
        for shape, model in models.items():
            for tip in [0.0, *args.tips]:
                for seed in (1, 2, 3):
                    sim = meshrec.simulate_touch(model, rng=seed, probe_radius=tip, noise=1e-3,
                                                 length=0.6, name=shape)
                    out.append(_row(f"{shape} tip {tip:g} seed {seed}", sim.touch, library))
    return finish(out, args.out)


if __name__ == "__main__":
    sys.exit(main())
