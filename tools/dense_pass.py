"""The dense pass of one touch, paired: YCB curved objects recognised with and without it.

    PYTHONPATH=. .venv/bin/python tools/dense_pass.py --seeds 0 6 --out reports/dense_pass.md

The touches are those of ``tools/families.py`` (family ``ycb curved``: three touches per
object and seed, the first recognised alone). Each is recognised as shipped; where the
dense pass ran (its caution in ``warnings``), it is recognised again with
``defaults.LOOKUP_DENSE_CANDIDATES`` set to ``defaults.MAX_CANDIDATES``: the dense pass
then repeats the widened pass exactly and each model keeps the same fit, so that answer is
the one before the dense pass existed. Prints per seed range: right (best model is the
touched one), the verdicts, right and recognised, the truth plausible, confident wrong,
and CPU time (``time.process_time``) per touch; then every touch whose answer changed.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import meshrec
from meshrec import defaults

sys.path.insert(0, str(Path(__file__).resolve().parent))
import families  # the families' touches (tools/families.py)
from _report import finish  # tools/_report.py

_CAUTION = "candidates"  # the dense pass's words in the widened caution


def _answer(rec):
    return (rec.best.model if rec.best is not None else None, rec.verdict, tuple(rec.plausible))


def _run(library, names, seeds):
    rows = []
    for seed in seeds:
        for name in names:
            touch = families.family_touches(
                lambda n: families.YCB / f"{n}.obj", name, 1e-4, seed
            )[0]
            t0 = time.process_time()
            new = meshrec.recognize(touch, library)
            t_new = time.process_time() - t0
            dense = any(f"{defaults.LOOKUP_DENSE_CANDIDATES} {_CAUTION}" in w for w in new.warnings)
            old, t_old = new, t_new
            if dense:
                keep = defaults.LOOKUP_DENSE_CANDIDATES
                defaults.LOOKUP_DENSE_CANDIDATES = defaults.MAX_CANDIDATES
                try:
                    t0 = time.process_time()
                    old = meshrec.recognize(touch, library)
                    t_old = time.process_time() - t0
                finally:
                    defaults.LOOKUP_DENSE_CANDIDATES = keep
            rows.append((name, seed, dense, _answer(old), _answer(new), t_old, t_new))
            print(rows[-1][:5], file=sys.stderr, flush=True)
    return rows


def _table(rows, label):
    out = []
    for k, which in ((3, "without"), (4, "with")):
        right = sum(r[k][0] == r[0] for r in rows)
        verdicts = [sum(r[k][1] == v for r in rows) for v in ("recognised", "ambiguous", "unknown")]
        rec_right = sum(r[k][0] == r[0] and r[k][1] == "recognised" for r in rows)
        plausible = sum(r[0] in r[k][2] for r in rows)
        wrong = sum(r[k][1] == "recognised" and r[k][0] != r[0] for r in rows)
        t = [r[5 if k == 3 else 6] for r in rows]
        out.append(
            f"| {label} | {which} | {len(rows)} | {right} ({100 * right / len(rows):.0f}%) "
            f"| {' / '.join(map(str, verdicts))} | {rec_right} | {plausible} | {wrong} "
            f"| {statistics.median(t):.1f} / {statistics.fmean(t):.1f} |"
        )
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="first seed of each range")
    p.add_argument("--trials", type=int, default=6, help="seeds per range (default 6)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    library = meshrec.ModelLibrary.from_folder(families.YCB)
    names = [n for n in library.names if n not in families.YCB_BOXES]
    lines = [
        "# The dense pass of one touch, paired (YCB curved)\n",
        f"Command: `python tools/dense_pass.py {' '.join(sys.argv[1:] if argv is None else argv)}`"
        f"; meshrec {meshrec.__version__}. CPU seconds per touch (median / mean).\n",
        "| seeds | dense pass | touches | right | recognised / ambiguous / unknown "
        "| right and recognised | truth plausible | confident wrong | CPU s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    changed = []
    for first in args.seeds:
        rows = _run(library, names, range(first, first + args.trials))
        lines += _table(rows, f"{first} to {first + args.trials - 1}")
        ran = sum(r[2] for r in rows)
        lines.append(f"| | (ran on {ran} of {len(rows)}) | | | | | | | |")
        changed += [r for r in rows if r[3][:2] != r[4][:2]]
    lines += ["", "Changed answers (object, seed: without -> with):", ""]
    lines += [f"- {r[0]}, {r[1]}: {r[3][0]} ({r[3][1]}) -> {r[4][0]} ({r[4][1]})" for r in changed]
    return finish(lines, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
