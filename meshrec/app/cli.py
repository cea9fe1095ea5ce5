"""The ``meshrec`` command line: parses arguments and calls the public API, nothing more."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec._version import __version__
from meshrec.io.touch import TouchData
from meshrec.model.library import ModelLibrary, bundled_models_dir
from meshrec.recognition.recognize import Recognition, recognize
from meshrec.registration.register import touch_geometry
from meshrec.sim.simulate import simulate_touch

__all__ = ["main", "recognition_to_json"]

_VECTOR_OPTIONS = ("--contact", "--normal")


def _vector(text: str) -> np.ndarray:
    parts = text.replace(" ", "").split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z numbers, got {text!r}") from None
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z, got {text!r}")
    return np.array(values)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr and exit status 2."""

    def error(self, message):
        self.exit(2, f"meshrec: error: {message} (see '{self.prog} --help')\n")


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
            type=Path,
            default=None,
            help="folder of model meshes (default: the bundled paper surfaces)",
        )
        sp.add_argument(
            "--cache-dir",
            type=Path,
            default=None,
            help="index cache folder (default: $MESHREC_CACHE_DIR or the user cache)",
        )

    r = sub.add_parser("recognize", help="rank the models by how well the touch fits them")
    r.add_argument("touch_file", type=Path, help="touch file (.csv curve,x,y,z or .json)")
    models_arg(r)
    r.add_argument("--contact", type=_vector, help="the curves' common point X,Y,Z")
    r.add_argument("--normal", type=_vector, help="approximate outward normal X,Y,Z")
    r.add_argument("--top", type=int, default=None, help="show only the N best models")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.add_argument(
        "--method",
        choices=("lm", "steepest"),
        default=defaults.SEARCH_METHOD,
        help="local search: least squares on charts (lm) or the paper's steepest descent",
    )

    i = sub.add_parser("index", help="build or refresh the cached model indexes")
    models_arg(i)
    i.add_argument("--force", action="store_true", help="rebuild even if cached")

    s = sub.add_parser("simulate", help="simulate a touch on a model (three plane sections)")
    s.add_argument("model_file", help="model mesh file, or the name of a bundled model")
    s.add_argument("-o", "--output", type=Path, required=True, help="touch file to write")
    s.add_argument("--truth", type=Path, help="JSON file for the true contact and transform")
    s.add_argument("--seed", type=int, default=None, help="random seed")
    s.add_argument("--noise", type=float, default=defaults.SIM_NOISE, help="uniform noise +-A")
    s.add_argument("--points", type=int, default=defaults.SIM_POINTS, help="points per curve")
    s.add_argument("--length", type=float, default=None, help="curve length (model units)")
    s.add_argument("--contact", type=_vector, help="contact X,Y,Z on the model")
    _add_viz_parsers(sub, models_arg)
    return p


def _progress_printer(stream):
    tty = stream.isatty()

    def progress(i: int, n: int, name: str) -> None:
        if tty:  # one line, redrawn; the caller ends it (after the library is built)
            width = 30
            done = int(width * i / max(n, 1))
            stream.write(f"\r[{'#' * done}{'.' * (width - done)}] {i + 1}/{n} {name[:40]:<40}")
        else:
            stream.write(f"indexing {i + 1}/{n}: {name}\n")
        stream.flush()

    return progress


def _resolve_model_file(text: str) -> Path:
    path = Path(text)
    if path.exists():
        return path
    for lib in ("surfaces", "objects"):
        folder = bundled_models_dir(lib)
        for candidate in sorted(folder.glob(f"{text}.*")):
            return candidate
    raise ValueError(f"model_file {text}: no such file, nor a bundled model of that name")


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
        Keys ``verdict``, ``best``, ``plausible``, ``noise``, ``reason``, ``warnings``,
        ``touch`` and ``ranking`` (each entry with ``probability`` and ``poses``, a list
        of ``{"transform": T_model_touch, "weight": w}``).
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
        "warnings": list(dict.fromkeys([*warnings, *rec.warnings])),
        "touch": {
            "file": rec.touch.source,
            "points": rec.touch.n_points,
            "curves": len(rec.touch.curves),
            "contact": g.point.tolist(),
            "normal": g.normal.tolist(),
            "K": float(g.K),
            "H": float(g.H),
        },
        "ranking": [entry(r) for r in ranking],
    }


def _print_table(rec: Recognition, top: int | None, out) -> None:
    g = rec.geometry
    out.write(
        f"touch: {rec.touch.n_points} points on {len(rec.touch.curves)} curves; "
        f"contact {np.array2string(g.point, precision=5)}, "
        f"K = {g.K:.5g}, |H| = {abs(g.H):.5g}; noise {rec.noise:.3g}\n"
    )
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
    if rec.verdict == "recognised":
        what = rec.plausible[0]
    elif rec.verdict == "ambiguous":
        what = " or ".join(rec.plausible)
    else:
        best = rec.best.model if rec.best is not None else "none"
        what = f"not in the library (best fit: {best})"
    out.write(f"{rec.verdict}: {what}  ({rec.seconds:.2f} s)\n")


def _library(args, progress=None) -> ModelLibrary:
    folder = args.models if args.models is not None else bundled_models_dir("surfaces")
    return ModelLibrary.from_folder(
        folder, cache_dir=args.cache_dir, force=getattr(args, "force", False), progress=progress
    )


def _run(args) -> int:
    if args.command in ("show", "plot"):
        return _run_viz(args)
    if args.command == "recognize":
        if args.top is not None and args.top < 1:
            raise ValueError(f"--top must be at least 1, got {args.top}")
        # Every warning is printed as before and also kept for the JSON.
        caught: list = []
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                touch, geometry = _read_touch(args)
                library = _library(args)
                rec = recognize(touch, library, method=args.method, geometry=geometry)
        finally:
            shown = {}
            for w in caught:  # each text once, as the default filter would
                shown.setdefault(str(w.message), w)
            for w in shown.values():
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        texts = list(shown)
        if args.json:
            doc = recognition_to_json(rec, args.top, warnings=texts)
            sys.stdout.write(json.dumps(doc) + "\n")
        else:
            _print_table(rec, args.top, sys.stdout)
        return 1 if rec.verdict == "unknown" else 0
    if args.command == "index":
        library = _library(args, progress=_progress_printer(sys.stderr))
        if sys.stderr.isatty():
            sys.stderr.write("\n")  # end the progress line
        for m in library.models:
            how = "cached" if m.from_cache else f"built in {m.build_seconds:.2f} s"
            sys.stdout.write(
                f"{m.name:<24} {len(m.faces):>8} faces  {int(m.valid.sum()):>8} table entries  "
                f"{how}\n"
            )
        return 0
    # simulate
    model_file = _resolve_model_file(args.model_file)
    sim = simulate_touch(
        model_file,
        contact=args.contact,
        rng=args.seed,
        n_points=args.points,
        noise=args.noise,
        length=args.length,
    )
    sim.write(args.output, args.truth)
    c = np.array2string(sim.contact, precision=5)
    sys.stdout.write(
        f"wrote {args.output}: {len(sim.touch.curves)} curves x {args.points} points on "
        f"{sim.model}, true contact {c}" + (f"; truth in {args.truth}" if args.truth else "") + "\n"
    )
    return 0


def _size_arg(text: str) -> tuple[int, int]:
    """Parse ``WxH`` (pixels) for ``--size``."""
    parts = text.lower().split("x")
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"expected positive WIDTHxHEIGHT, got {text!r}")
    return w, h


def _add_viz_parsers(sub, models_arg) -> None:
    """The ``show`` and ``plot`` subcommands (pictures; need the ``viz`` extra)."""
    v = sub.add_parser(
        "show", help="view the registration in 3D (open3d window, or a PNG with --screenshot)"
    )
    v.add_argument("touch_file", type=Path, help="touch file (.csv curve,x,y,z or .json)")
    models_arg(v)
    v.add_argument("--model", help="model to show (default: the recognised one)")
    v.add_argument("--truth", type=Path, help="truth JSON (meshrec simulate --truth)")
    v.add_argument("--screenshot", type=Path, help="render off-screen to this PNG, no window")
    v.add_argument("--size", type=_size_arg, default=(1024, 768), help="WxH pixels (1024x768)")
    v.add_argument(
        "--view",
        choices=("contact", "model"),
        default="contact",
        help="frame the contact region (default) or the whole model",
    )

    pl = sub.add_parser("plot", help="the paper's figures as PNG plots (matplotlib)")
    kinds = pl.add_subparsers(dest="plot", required=True)
    ph = kinds.add_parser("phi", help="error against phi at a candidate (Figure 2)")
    se = kinds.add_parser("search", help="candidates and local-search paths (Figure 3)")
    for q in (ph, se):
        q.add_argument("touch_file", type=Path, help="touch file (.csv curve,x,y,z or .json)")
        models_arg(q)
        q.add_argument("--model", help="model (default: the recognised one)")
        q.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
        q.add_argument("--size", type=_size_arg, default=None, help="WxH pixels")
    ph.add_argument(
        "--candidate",
        type=int,
        default=None,
        help="candidate index (default: the one with the least sampled error)",
    )
    se.add_argument("--truth", type=Path, help="truth JSON: mark the true contact")


def _read_touch(args):
    """The touch file with its hints, and its local geometry: bad data fail here, before
    any model is indexed."""
    touch = TouchData.from_file(args.touch_file)
    contact, normal = getattr(args, "contact", None), getattr(args, "normal", None)
    if contact is not None or normal is not None:
        touch = touch.with_hints(contact=contact, normal=normal)
    try:
        geometry = touch_geometry(touch)
    except ValueError as exc:
        raise ValueError(f"touch file {args.touch_file}: {exc}") from exc
    return touch, geometry


def _model_arg(args, library):
    """The model named by ``--model``, or None when it is not given."""
    if args.model is None:
        return None
    if args.model not in library:
        raise ValueError(f"--model must be one of {list(library.names)}, got {args.model!r}")
    return library[args.model]


def _viz_registration(args, touch, geometry, library):
    """(model index, registration) for ``--model`` or the recognised model."""
    from meshrec.registration.register import register

    model = _model_arg(args, library)
    if model is not None:
        reg = register(touch, model, geometry=geometry)
        if reg.rejected:
            raise ValueError(f"--model {args.model}: {reg.reason}")
        return model, reg
    rec = recognize(touch, library, geometry=geometry)
    if rec.best is None:
        raise ValueError("no model recognised: the table lookup rejected every model")
    return library[rec.best.model], rec.best


def _run_viz(args) -> int:
    from meshrec.figures import (
        plots,  # they import open3d and matplotlib only when drawing
        viz,  # they import open3d and matplotlib only when drawing
    )

    try:
        if args.command == "show":  # fail fast, before any work, without the viz extra
            if args.screenshot is None:
                viz.check_display()
            viz.check_offscreen()
        else:
            plots.check_matplotlib()
        out_path = args.screenshot if args.command == "show" else args.output
        if out_path is not None and out_path.suffix.lower() != ".png":
            raise ValueError(f"{out_path} must end in .png")
        touch, geometry = _read_touch(args)
        library = _library(args)
        if args.command == "show":
            model, reg = _viz_registration(args, touch, geometry, library)
            kw = dict(touch=touch, truth=args.truth, mesh=model, size=args.size, view=args.view)
            if args.screenshot is None:
                viz.show(reg, **kw)
                return 0
            snap = viz.render(reg, args.screenshot, **kw)
            c = np.array2string(reg.contact, precision=5)
            sys.stdout.write(
                f"wrote {snap.path} ({snap.size[0]}x{snap.size[1]}): {reg.model}, "
                f"contact {c}, error {reg.error:.4g}\n"
            )
            return 0
        size = {} if args.size is None else {"size": args.size}
        if args.plot == "phi":
            model = _model_arg(args, library)
            if model is None:
                model, _ = _viz_registration(args, touch, geometry, library)
            profile = plots.phi_profile(
                touch, model, candidate=args.candidate, geometry=geometry
            )
            out = plots.phi_figure(profile, args.output, **size)
            detail = f"candidate {profile.candidate}, phi {profile.phi:.4f} rad"
        else:
            model, reg = _viz_registration(args, touch, geometry, library)
            out = plots.search_figure(reg, args.output, mesh=model, truth=args.truth, **size)
            detail = f"{reg.candidates} candidates, {len(reg.search_paths)} searches"
        sys.stdout.write(f"wrote {out}: {model.name}, {detail}\n")
        return 0
    except (viz.VizDependencyError, viz.RenderError) as exc:
        raise ValueError(str(exc)) from None


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
    (file or sys.stderr).write(f"meshrec: warning: {message}\n")


def main(argv: list[str] | None = None) -> int:
    """Run the ``meshrec`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success (for recognize: recognised or ambiguous), 1 when recognize finds the
        object unknown (its output is still printed), 2 on bad input (one line on stderr,
        no traceback).
    """
    parser = _parser()
    argv = _join_vector_options(list(sys.argv[1:] if argv is None else argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    previous = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        return _run(args)
    except ValueError as exc:
        sys.stderr.write(f"meshrec: error: {exc}\n")
        return 2
    except OSError as exc:  # e.g. an output file that cannot be written
        target = exc.filename2 or exc.filename  # a rename's destination, else the file
        where = f" {target}:" if target else ""
        sys.stderr.write(f"meshrec: error:{where} {exc.strerror or exc}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("meshrec: interrupted\n")
        return 130
    finally:
        warnings.showwarning = previous


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
