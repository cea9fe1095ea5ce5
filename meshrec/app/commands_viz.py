"""``meshrec show`` and ``meshrec plot``: pictures of a registration (the viz extra).

Only the standard library is imported at module level: the parser is built before
anything heavy is loaded (see :mod:`meshrec.app.cli`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["add_viz_parsers", "run_viz"]


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


def add_viz_parsers(sub, models_arg, touch_arg) -> None:
    """The ``show`` and ``plot`` subcommands (pictures; need the ``viz`` extra).

    ``models_arg(parser)`` and ``touch_arg(parser)`` add the options every command that
    reads a touch and a model folder shares.
    """
    v = sub.add_parser(
        "show", help="view the registration in 3D (open3d window, or a PNG with --screenshot)"
    )
    touch_arg(v)
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
        touch_arg(q)
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


def _model_arg(args, library):
    """The model named by ``--model``, or None when it is not given."""
    if args.model is None:
        return None
    if args.model not in library:
        raise ValueError(f"--model must be one of {list(library.names)}, got {args.model!r}")
    return library[args.model]


def _viz_registration(args, touch, geometry, library):
    """(model index, registration) for ``--model`` or the recognised model."""
    from meshrec.recognition.recognize import recognize
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


def run_viz(args) -> int:
    """Run ``show`` or ``plot``; 0, or ValueError for bad input and missing extras."""
    import numpy as np

    from meshrec.app import inputs
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
        folder = inputs.model_folder(args.models)
        units = inputs.model_units(folder, args.model_units)
        touch, geometry = inputs.touch_and_geometry(args, folder, units)
        library = inputs.library(args, folder)
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
            from meshrec.registration.register import register

            model = _model_arg(args, library)
            if model is None:
                model, _ = _viz_registration(args, touch, geometry, library)
            reg = register(touch, model, geometry=geometry, trace=True)
            profile = plots.phi_profile(reg, model, candidate=args.candidate)
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
