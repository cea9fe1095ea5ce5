"""The ``meshrec`` command line: parses arguments and calls the public API, nothing more.

Exit status: 0 success (for recognize: recognised or ambiguous), 1 recognize found the
object unknown (its output is still printed), 2 bad input (one line on stderr), 130
interrupted (Ctrl-C), 141 standard output closed by its reader (a broken pipe).

Only the standard library is imported at module level, and ``meshrec/__init__`` imports
its public names lazily: everything heavy (numpy, scipy, trimesh, libigl) is loaded inside
:func:`main`, so that Ctrl-C at any moment after the interpreter starts ends the program
quietly with status 130 rather than with a traceback from the middle of an import.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from meshrec import defaults
from meshrec._version import __version__
from meshrec.app.commands_advice import add_advice_parser
from meshrec.app.commands_serve import add_serve_parser
from meshrec.app.commands_viz import add_viz_parsers
from meshrec.app.parallel import add_workers_args, model_workers

if TYPE_CHECKING:
    from collections.abc import Sequence

    from meshrec.recognition.result import Recognition

__all__ = ["main", "recognition_to_json"]

_VECTOR_OPTIONS = ("--contact", "--normal", "--approach")
#: The environment variables that set how many threads OpenBLAS (numpy's BLAS) starts.
_BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def _vector(text: str):
    """Parse ``X,Y,Z`` for ``--contact`` and ``--normal`` (checked by check_vector)."""
    from meshrec.io.checks import check_vector, one_line  # numpy: only once an option is used

    try:
        values = [float(p) for p in text.replace(" ", "").split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected X,Y,Z numbers, got {one_line(text, 60)!r}"
        ) from None
    try:
        return check_vector(values, "vector")
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected three finite numbers X,Y,Z, got {one_line(text, 60)!r}"
        ) from None


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr and exit status 2."""

    def error(self, message):
        self.exit(2, f"meshrec: error: {message} (see '{self.prog} --help')\n")


_UNIT_CHOICES = ("mm", "cm", "m", "in")  # meshrec.recognition.units.UNITS (not imported here)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="meshrec",
        description="Recognise a touched object, and where it was touched, from three "
        "probe curves against a folder of STL/OBJ models.",
    )
    p.add_argument("--version", action="version", version=f"meshrec {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    def models_arg(sp):
        sp.add_argument(
            "--models",
            default=None,
            metavar="DIR|SET",
            help="folder of model meshes, or the name of a bundled set (surfaces, objects, "
            "parts, primitives; see 'meshrec models'); default: the bundled paper surfaces",
        )
        sp.add_argument(
            "--model-units",
            choices=_UNIT_CHOICES,
            default=None,
            help="the models' length unit (default: the folder's meshrec.json note, if any)",
        )
        sp.add_argument(
            "--cache-dir",
            type=Path,
            default=None,
            help="index cache folder (default: $MESHREC_CACHE_DIR or the user cache)",
        )

    def touch_arg(sp, nargs=None):
        sp.add_argument(
            "touch_file",
            nargs=nargs,
            help="touch file (.csv curve,x,y,z or .json), or - for standard input",
        )
        sp.add_argument(
            "--units",
            choices=_UNIT_CHOICES,
            default=None,
            help="the touch's length unit: converted to the models' when theirs are known",
        )

    r = sub.add_parser("recognize", help="rank the models by how well the touch fits them")
    touch_arg(r, nargs="+")
    models_arg(r)
    r.add_argument(
        "--batch",
        action="store_true",
        help="many touch files, one touch each: one JSON line per file (JSON Lines)",
    )
    r.add_argument("--contact", type=_vector, help="the curves' common point X,Y,Z")
    r.add_argument("--normal", type=_vector, help="approximate outward normal X,Y,Z")
    r.add_argument(
        "--probe-radius",
        type=float,
        default=None,
        metavar="R",
        help="the probe's ball-tip radius (touch units): the curves are the ball's centres",
    )
    r.add_argument("--top", type=int, default=None, help="show only the N best models")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.add_argument(
        "--method",
        choices=("lm", "steepest"),
        default=defaults.SEARCH_METHOD,
        help="local search: least squares on charts (lm) or the paper's steepest descent",
    )
    add_workers_args(r)

    i = sub.add_parser("index", help="build or refresh the cached model indexes")
    i.add_argument(
        "folder", nargs="?", default=None, metavar="DIR|SET", help="the same as --models"
    )
    models_arg(i)
    i.add_argument("--force", action="store_true", help="rebuild even if cached")

    m = sub.add_parser("models", help="list the bundled model sets, or what a model folder holds")
    m.add_argument(
        "folder", nargs="?", default=None, metavar="DIR|SET", help="a model folder or set"
    )
    m.add_argument("--model-units", choices=_UNIT_CHOICES, default=None, help="the models' unit")
    m.add_argument("--json", action="store_true", help="print one JSON object on stdout")

    s = sub.add_parser("simulate", help="simulate a touch on a model (three plane sections)")
    s.add_argument("model_file", help="model mesh file, or the name of a bundled model")
    s.add_argument("-o", "--output", type=Path, required=True, help="touch file to write")
    s.add_argument("--truth", type=Path, help="JSON file for the true contact and transform")
    s.add_argument("--seed", type=int, default=None, help="random seed")
    s.add_argument("--noise", type=float, default=defaults.SIM_NOISE, help="uniform noise +-A")
    s.add_argument("--points", type=int, default=defaults.SIM_POINTS, help="points per curve")
    s.add_argument("--length", type=float, default=None, help="curve length (model units)")
    s.add_argument("--contact", type=_vector, help="contact X,Y,Z on the model")
    s.add_argument(
        "--probe-radius",
        type=float,
        default=0.0,
        metavar="R",
        help="ball-tip radius (model units): write the ball's centres, not surface points",
    )
    s.add_argument(
        "--noise-direction",
        choices=defaults.SIM_NOISE_DIRECTIONS,
        default="isotropic",
        help="the noise on every coordinate (isotropic, default) or along the normal only",
    )
    add_viz_parsers(sub, models_arg, touch_arg)
    add_advice_parser(sub, models_arg, touch_arg)
    add_serve_parser(sub, models_arg)
    return p


def recognition_to_json(
    rec: Recognition, top: int | None = None, warnings: Sequence[str] = ()
) -> dict:
    """The JSON document printed by ``meshrec recognize --json``.

    Parameters
    ----------
    rec : Recognition
    top : int, optional
        Keep only the ``top`` best models.
    warnings : sequence of str
        Warnings raised outside the recognition (reading the touch, loading the models),
        listed before the recognition's own (duplicates dropped).

    Returns
    -------
    dict
        Keys ``verdict``, ``best``, ``plausible``, ``noise``, ``reason``,
        ``search_doubt`` (:attr:`Recognition.search_doubt`), ``warnings``,
        ``probe_radius`` (the ball-tip radius the data were compared with the models
        for, models' units; 0 for a point probe), ``touch`` (the first touch),
        ``touches`` (one summary per touch, with ``rms``, its RMS residual at the best
        model's pose) and ``ranking`` (each entry with ``probability`` and ``poses``, a
        list of ``{"transform": T_model_touch, "weight": w}``).
    """
    g = rec.geometry
    ranking = rec.ranking if top is None else rec.ranking[:top]
    scores = {s.model: s for s in rec.scores}

    def entry(r):
        s = scores.get(r.model)
        poses = [] if s is None else s.poses
        return {
            "model": r.model,
            "file": r.path,
            "error": r.error,
            "probability": None if s is None else s.probability,
            "rms": None if s is None else s.rms,
            "contact": None if r.contact is None else r.contact.tolist(),
            "transform": None if r.T_model_touch is None else r.T_model_touch.tolist(),
            "poses": [{"transform": p.T_model_touch.tolist(), "weight": p.weight} for p in poses],
            "candidates": r.candidates,
            "seconds": r.seconds,
            **({"reason": r.reason} if r.rejected else {}),
        }

    return {
        "verdict": rec.verdict,
        "best": rec.best.model if rec.best is not None else None,
        "plausible": list(rec.plausible),
        "noise": float(rec.noise),
        "reason": rec.reason,
        "search_doubt": bool(rec.search_doubt),
        "warnings": list(dict.fromkeys([*warnings, *rec.warnings])),
        "probe_radius": float(rec.probe_radius),
        "touch": {
            "file": rec.touch.source,
            "points": rec.touch.n_points,
            "curves": len(rec.touch.curves),
            "contact": g.point.tolist(),
            "normal": g.normal.tolist(),
            "K": float(g.K),
            "H": float(g.H),
        },
        "touches": [
            {
                "file": t.source,
                "points": t.n_points,
                "curves": len(t.curves),
                "contact": tg.point.tolist(),
                "normal": tg.normal.tolist(),
                "K": float(tg.K),
                "H": float(tg.H),
                "rms": None if r is None else float(r),
            }
            for t, tg, r in zip(rec.touches, rec.geometries, rec.touch_rms, strict=True)
        ],
        "ranking": [entry(r) for r in ranking],
        "pose_freedom": None if rec.pose_freedom is None else rec.pose_freedom.to_dict(),
    }


def _print_table(rec: Recognition, top: int | None, out, shown=()) -> None:
    """The text output; ``shown``: the warnings already printed on stderr (the
    recognition's other cautions are printed as ``note:`` lines)."""
    import numpy as np

    several = len(rec.touches) > 1
    for k, (t, g, r) in enumerate(zip(rec.touches, rec.geometries, rec.touch_rms, strict=True)):
        label = f"touch {k + 1}" if several else "touch"
        fit = f"; rms at the best pose {r:.3g}" if several and r is not None else ""
        out.write(
            f"{label}: {t.n_points} points on {len(t.curves)} curves; "
            f"contact {np.array2string(g.point, precision=5)}, "
            f"K = {g.K:.5g}, |H| = {abs(g.H):.5g}"
            + (fit if several else f"; noise {rec.noise:.3g}")
            + "\n"
        )
    if several:
        out.write(f"{len(rec.touches)} touches of one object, noise {rec.noise:.3g}\n")
    ranking = rec.ranking if top is None else rec.ranking[:top]
    prob = rec.probabilities
    out.write(
        f"{'rank':>4}  {'model':<24} {'prob.':>6} {'error/point':>12} {'cand.':>6} {'s':>6}"
        "  contact\n"
    )
    for k, r in enumerate(ranking, start=1):
        p = f"{prob[r.model]:.3f}" if r.model in prob else "-"
        if r.rejected:
            out.write(
                f"{k:>4}  {r.model:<24} {p:>6} {'-':>12} {0:>6} {r.seconds:>6.2f}  {r.reason}\n"
            )
        else:
            c = np.array2string(r.contact, precision=5)
            out.write(
                f"{k:>4}  {r.model:<24} {p:>6} {r.error:>12.4g} {r.candidates:>6} "
                f"{r.seconds:>6.2f}  {c}\n"
            )
    out.write(f"{rec.reason}\n")
    for caution in rec.warnings:
        if caution not in shown:
            out.write(f"note: {caution}\n")
    if rec.pose_freedom is not None:
        sigma = rec.pose_freedom.sigma
        known = f" (data points within about {sigma:.2g}, one sigma)" if np.isfinite(sigma) else ""
        # an unknown answer's best fit misses the data: its precision says nothing
        if rec.verdict == "unknown":
            whose = "pose of the best fit (it misses the data)"
        elif len(rec.plausible) > 1 and rec.best is not None:
            # an ambiguous answer's pose is its best model's, one of the plausible ones (a
            # probe, stop 34, read "pose: fixed" beside two plausible models as the answer's)
            whose = f"pose of {rec.best.model}, if it is that model"
        else:
            whose = "pose"
        out.write(f"{whose}: {rec.pose_freedom.description}{known}\n")
    if rec.verdict == "recognised":
        what = rec.plausible[0]
        if rec.pose_freedom is not None and not rec.pose_freedom.fixed:
            what += f", its pose {rec.pose_freedom.description}"
    elif (
        rec.verdict == "ambiguous"
        and len(rec.plausible) == 1
        and rec.pose_freedom
        and not rec.pose_freedom.fixed
    ):
        what = f"{rec.plausible[0]}, but its pose is not fixed ({rec.pose_freedom.description})"
    elif rec.verdict == "ambiguous" and len(rec.plausible) == 1:
        # one model stands out, but the touch is one from which none is named (across a
        # sharp edge, or too noisy for its length: the reason says which)
        what = f"{rec.plausible[0]} fits best, but one such touch cannot name it"
    elif rec.verdict == "ambiguous":
        what = " or ".join(rec.plausible)
    else:
        if rec.best is None:
            what = "no model could be registered"
        else:
            # the answer's own doubt (a touch across an edge or a rim, where the search
            # may have missed the pose) is kept in the one line a script reads
            missed = ", or its pose was missed" if rec.search_doubt else ""
            what = f"not in the library{missed} (best fit: {rec.best.model})"
    out.write(f"{rec.verdict}: {what}  ({rec.seconds:.2f} s)\n")


def _run_recognize(args) -> int:
    from meshrec.app import inputs
    from meshrec.recognition.recognize import recognize

    if args.top is not None and args.top < 1:
        raise ValueError(f"--top must be at least 1, got {args.top}")
    names = args.touch_file
    if names.count(inputs.STDIN) > 1:
        raise ValueError("touch file - (standard input) can be given only once")
    folder = inputs.model_folder(args.models)
    units = inputs.model_units(folder, args.model_units)
    if args.batch:
        return _run_batch(args, names, folder, units)
    # Every warning is printed as before and also kept for the JSON.
    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            touches, geometries = inputs.touches_and_geometries(args, names, folder, units)
            library = inputs.library(args, folder)
            with model_workers(args, library) as workers:
                rec = recognize(
                    touches, library, method=args.method, geometry=geometries, workers=workers
                )
    finally:
        shown = {}
        for w in caught:  # each text once, as the default filter would
            shown.setdefault(str(w.message), w)
        for w in shown.values():
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    if args.json:
        doc = recognition_to_json(rec, args.top, warnings=list(shown))
        sys.stdout.write(json.dumps(doc) + "\n")
    else:
        _print_table(rec, args.top, sys.stdout, shown=set(shown))
    return 1 if rec.verdict == "unknown" else 0


def _run_batch(args, names, folder, units) -> int:
    from meshrec.app import inputs
    from meshrec.app.commands_batch import run_batch

    for option in ("contact", "normal"):
        if getattr(args, option) is not None:
            raise ValueError(f"--{option} gives one touch's hint: not with --batch")
    touch_units = inputs.touch_units(args.units, units)
    library = inputs.library(args, folder)
    with model_workers(args, library) as workers:
        failed = run_batch(
            names,
            library,
            sys.stdout,
            lambda rec: recognition_to_json(rec, args.top),
            units=touch_units,
            models_units=units,
            method=args.method,
            probe_radius=args.probe_radius,
            workers=workers,
        )
    if failed:
        raise ValueError(
            f'{failed} of {len(names)} touch files failed (their JSON lines have an "error" key)'
        )
    return 0


def _run(args) -> int:
    if args.command in ("show", "plot"):
        from meshrec.app.commands_viz import run_viz

        return run_viz(args)
    if args.command == "serve":
        from meshrec.app.commands_serve import run_serve

        return run_serve(args)
    if args.command == "next-touch":
        from meshrec.app.commands_advice import run_advice

        return run_advice(args, sys.stdout)
    if args.command == "models":
        from meshrec.app.commands_models import run_models

        return run_models(args, sys.stdout)
    if args.command == "index":
        from meshrec.app.commands_simple import run_index

        return run_index(args, sys.stdout, sys.stderr)
    if args.command == "simulate":
        from meshrec.app.commands_simple import run_simulate

        return run_simulate(args, sys.stdout)
    return _run_recognize(args)


def _join_vector_options(argv: list[str]) -> list[str]:
    """Let ``--contact -1,2,3`` through: argparse takes ``-1,2,3`` for an option."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in _VECTOR_OPTIONS and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    from meshrec.io.checks import one_line

    (file or sys.stderr).write(f"meshrec: warning: {one_line(str(message), None)}\n")


def _interrupted() -> int:
    """Ctrl-C: one line, status 130. A second Ctrl-C is ignored from here on (in the
    program's main thread), so that the exit itself is not interrupted."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        sys.stderr.write("meshrec: interrupted\n")
        sys.stderr.flush()
    except (OSError, ValueError):  # stderr closed
        pass
    return 130


def main(argv: list[str] | None = None) -> int:
    """Run the ``meshrec`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success (for recognize: recognised or ambiguous), 1 when recognize finds
        the object unknown (its output is still printed), 2 on bad input (one line on
        stderr, no traceback), 130 when
        interrupted by Ctrl-C (SIGINT), at any moment: one line, no traceback; 141,
        silently, when standard output is a pipe closed by its reader.
    """
    try:
        return _main(argv)
    except KeyboardInterrupt:
        return _interrupted()


def _exit_on_sigint(signum, frame):  # pragma: no cover - runs in the killed process
    import os

    os.write(2, b"meshrec: interrupted\n")
    os._exit(130)


def _load_core(command: str | None = None) -> None:
    """Import numpy, scipy and libigl (and trimesh for the commands that read or cut
    meshes: ``simulate``, ``index``, ``show``, ``plot``) with Ctrl-C ending the process at
    once. A warm ``recognize``, ``next-touch`` or ``serve`` never needs trimesh; where a
    cold cache does, :func:`meshrec._lazy.trimesh_module` imports it, holding a Ctrl-C
    until the import is done.

    A KeyboardInterrupt cannot be relied on here: trimesh imports its optional
    dependencies under ``except BaseException`` and swallows it (measured: SIGINT 0.3 s
    into start-up was ignored and the run went on to the end). Nothing has been written
    yet, so exiting at once with status 130 leaves nothing half-done.
    """
    import os
    import signal
    import threading

    if "numpy" not in sys.modules and not any(os.environ.get(k) for k in _BLAS_THREAD_VARIABLES):
        # One BLAS thread unless the user chose, for every command: meshrec's products are
        # of (n, 3) arrays and small systems, where OpenBLAS's thread pool only costs its
        # start (about 0.07 s of CPU time at import, measured on next-touch; the same
        # answers, compared on the bundled objects) and, with --workers or a service's
        # concurrent requests, competes with the processes and threads for the cores.
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
    if threading.current_thread() is not threading.main_thread():
        previous = None
    elif signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        previous = None  # started ignoring Ctrl-C (a background job): keep ignoring it
    else:
        previous = signal.signal(signal.SIGINT, _exit_on_sigint)
    try:
        import meshrec.model.library
        import meshrec.recognition.recognize

        if command in ("simulate", "index", "show", "plot"):
            import trimesh  # noqa: F401

            import meshrec.sim.simulate  # noqa: F401
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _main(argv: list[str] | None) -> int:
    parser = _parser()
    argv = _join_vector_options(list(sys.argv[1:] if argv is None else argv))
    try:
        args = parser.parse_args(argv)
        if getattr(args, "folder", None) is not None and args.command == "index":
            if args.models is not None and args.models != args.folder:
                parser.error(
                    f"index: give the folder once, got {args.folder!r} and --models {args.models!r}"
                )
            args.models = args.folder
    except SystemExit as exc:
        return int(exc.code or 0)
    _load_core(args.command)
    previous = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        return _run(args)
    except ValueError as exc:
        from meshrec.app.inputs import error_message

        sys.stderr.write(f"meshrec: error: {error_message(exc, getattr(args, 'units', None))}\n")
        return 2
    except BrokenPipeError:  # the reader of stdout went away (``| head -1``): stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error
        return 141  # what the shell shows for a process killed by SIGPIPE
    except OSError as exc:  # e.g. an output file that cannot be written
        from meshrec.io.checks import one_line

        target = exc.filename2 or exc.filename  # a rename's destination, else the file
        where = f" {one_line(target)}:" if target else ""
        sys.stderr.write(f"meshrec: error:{where} {one_line(str(exc.strerror or exc), None)}\n")
        return 2
    finally:
        warnings.showwarning = previous


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
