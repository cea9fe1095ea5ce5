"""``meshrec index`` and ``meshrec simulate``."""

from __future__ import annotations

from pathlib import Path

__all__ = ["run_index", "run_simulate"]


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
    from meshrec.model.library import bundled_models_dir

    path = Path(text)
    if path.exists():
        return path
    for lib in ("surfaces", "objects"):
        folder = bundled_models_dir(lib)
        for candidate in sorted(folder.glob(f"{text}.*")):
            return candidate
    from meshrec.io.checks import one_line

    raise ValueError(f"model_file {one_line(text)}: no such file, nor a bundled model of that name")


def run_index(args, out, err) -> int:
    """``meshrec index``: build or refresh the indexes, a progress line per stage on
    ``err``, a line per model on ``out``, a ResolutionWarning per model too coarse for
    reliable answers (:mod:`meshrec.model.resolution`); 0. A read-only cache folder is
    checked instead: 0 when it holds every model's index, else a ValueError."""
    import warnings

    from meshrec.app import inputs
    from meshrec.io.checks import one_line
    from meshrec.model.cache import CacheWarning, default_cache_dir

    folder = inputs.model_folder(args.models)
    writable = _check_cache_folder(args.cache_dir, force=getattr(args, "force", False))
    tty = err.isatty()
    try:
        if writable:
            library = inputs.library(args, folder, progress=_progress_printer(err))
        else:
            # A read-only cache: index may only check it. The models are loaded (nothing
            # can be written, so the cache's own "continuing without caching" warnings
            # are expected); any that had to be built means the cache is not complete.
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", CacheWarning)
                library = inputs.library(args, folder, progress=_progress_printer(err))
    finally:
        if tty:
            err.write("\n")  # end the progress line, also when interrupted
    if not writable:
        missing = [m.name for m in library.models if not m.from_cache]
        where = args.cache_dir if args.cache_dir is not None else default_cache_dir()
        if missing:
            raise ValueError(
                f"{_cache_name(args.cache_dir)} {one_line(str(where))}: not writable, and "
                f"{len(missing)} of {len(library.models)} models are not in it "
                f"({', '.join(missing[:3])}{', ...' if len(missing) > 3 else ''}); index "
                "only fills the cache"
            )
        err.write(
            f"{_cache_name(args.cache_dir)} {one_line(str(where))}: read-only, and every "
            "model's index is in it: nothing to write\n"
        )
    for m in library.models:
        how = "cached" if m.from_cache else f"built in {m.build_seconds:.2f} s"
        out.write(
            f"{m.name:<24} {len(m.mesh.faces):>8} faces  "
            f"{int(m.curvature.valid.sum()):>8} table entries  {how}\n"
        )
    _warn_coarse(library.models)
    return 0


def _cache_name(cache_dir) -> str:
    return "--cache-dir" if cache_dir is not None else "the cache folder"


def _check_cache_folder(cache_dir, force: bool = False) -> bool:
    """``index`` is for the cache: refuse one that cannot be a folder at once (a
    recognition goes on without caching, with a warning; an index that caches nothing
    would exit 0 having done nothing lasting), and a read-only one when ``force`` would
    rebuild every index. Returns whether the folder is writable: a read-only one may
    still be complete (:func:`run_index` checks it)."""
    import os

    from meshrec.io.checks import one_line
    from meshrec.model.cache import default_cache_dir

    where = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    name = _cache_name(cache_dir)
    try:
        where.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(
            f"{name} {one_line(str(where))}: cannot be created ({exc.strerror or exc}); "
            "index only fills the cache"
        ) from exc
    writable = os.access(where, os.W_OK | os.X_OK)
    if not writable and force:
        raise ValueError(
            f"{name} {one_line(str(where))}: not writable, and --force rebuilds every index; "
            "index only fills the cache"
        )
    return writable


def _warn_coarse(models) -> None:
    """One ResolutionWarning per model too coarse for reliable answers."""
    import warnings

    from meshrec.model.resolution import ResolutionWarning, coarse_message

    for m in models:
        if m.resolution.too_coarse:
            warnings.warn(coarse_message(m.name, m.resolution), ResolutionWarning, stacklevel=2)


#: simulate_touch's arguments and the options of ``meshrec simulate`` that give them.
_SIMULATE_OPTIONS = {
    "n_points": "--points",
    "noise": "--noise",
    "length": "--length",
    "contact": "--contact",
    "probe_radius": "--probe-radius",
}


def run_simulate(args, out) -> int:
    """``meshrec simulate``: write a simulated touch (and its truth); 0."""
    import numpy as np

    from meshrec.sim.simulate import simulate_touch

    model_file = _resolve_model_file(args.model_file)
    try:
        sim = simulate_touch(
            model_file,
            contact=args.contact,
            rng=args.seed,
            n_points=args.points,
            noise=args.noise,
            length=args.length,
            probe_radius=args.probe_radius,
            noise_direction=args.noise_direction,
        )
    except ValueError as exc:
        # The message names the API's argument: name the option instead.
        text = str(exc)
        for name, option in _SIMULATE_OPTIONS.items():
            if text.startswith(f"{name} "):
                raise ValueError(option + text[len(name) :]) from None
        raise
    from meshrec.io.checks import one_line

    sim.write(args.output, args.truth)  # the truth file only with --truth
    c = np.array2string(sim.contact, precision=5)
    truth = f"truth in {one_line(args.truth)}" if args.truth else "no truth file (use --truth)"
    out.write(
        f"wrote {one_line(args.output)}: {len(sim.touch.curves)} curves x {args.points} "
        f"points on {one_line(sim.model)}, true contact {c}"
        + (f", ball centres of a tip of radius {sim.probe_radius:g}" if sim.probe_radius else "")
        + (", noise along the normal" if sim.noise_direction == "normal" else "")
        + f"; {truth}\n"
    )
    return 0
