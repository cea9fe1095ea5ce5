"""``meshrec next-touch``: where to touch next, after one or more touches.

Only the standard library is imported at module level: the parser is built before
anything heavy is loaded (see :mod:`meshrec.app.cli`).
"""

from __future__ import annotations

import json

from meshrec import defaults

__all__ = ["add_advice_parser", "advice_to_json", "run_advice"]


def add_advice_parser(sub, models_arg, touch_arg) -> None:
    """The ``next-touch`` subcommand.

    ``models_arg(parser)`` and ``touch_arg(parser, nargs)`` add the options every command
    that reads touches and a model folder shares.
    """
    a = sub.add_parser(
        "next-touch",
        help="where to touch next: the contact and approach that best separate the "
        "models and poses the touches left open",
    )
    touch_arg(a, nargs="+")
    models_arg(a)
    a.add_argument(
        "--approach",
        default=None,
        metavar="X,Y,Z",
        help="the direction the probe can move in, into the object (touches' frame): "
        f"only contacts approached within {defaults.ADVICE_MAX_APPROACH_DEG:g} degrees of "
        "it are proposed",
    )
    a.add_argument("--seed", type=int, default=None, help="random seed of the candidates")
    a.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _approach(text: str | None):
    """``--approach X,Y,Z`` as a unit vector, or None.

    Raises
    ------
    ValueError
        If it is not three finite numbers, or is zero.
    """
    if text is None:
        return None
    from meshrec.io.checks import check_vector, one_line

    try:
        values = [float(p) for p in text.replace(" ", "").split(",")]
        return check_vector(values, "--approach", unit=True)
    except ValueError:
        raise ValueError(
            f"--approach must be three finite numbers X,Y,Z, not all zero, got "
            f"{one_line(text, 60)!r}"
        ) from None


def advice_to_json(
    advice, verdict: str, units: str | None = None, models_units: str | None = None
) -> dict:
    """The JSON document of ``meshrec next-touch --json``.

    Parameters
    ----------
    advice : TouchAdvice
    verdict : str
        The recognition's verdict.
    units, models_units : str or None
        The touches' unit and the models' (as ``--units`` and ``--model-units`` gave
        them): when both are known the point is given back in the touches' unit, in which
        the robot gave its touches (the advice is computed in the models').

    Returns
    -------
    dict
        Keys ``point`` and ``direction`` (lists of three numbers, or null), ``units`` (the
        point's unit, or null when no unit is known), ``expected_gain`` (nats),
        ``models``, ``reason``, ``criterion`` and ``verdict``.
    """
    return {
        "point": None
        if advice.point is None
        else _in_touch_units(advice.point, units, models_units).tolist(),
        "units": _point_unit(units, models_units),
        "direction": None if advice.direction is None else advice.direction.tolist(),
        "expected_gain": float(advice.expected_gain),
        "models": list(advice.models),
        "reason": _reason_in_touch_units(advice, units, models_units),
        "criterion": advice.criterion,
        "verdict": verdict,
    }


def _point_unit(units: str | None, models_units: str | None) -> str | None:
    """The unit the proposed point is given in: the touches' when both units are known
    (:func:`_in_touch_units` converts it), else the models' (or None)."""
    return units if units is not None and models_units is not None else models_units


def _in_touch_units(point, units: str | None, models_units: str | None):
    """A point of the models' unit in the touches' unit (as it is when either is None)."""
    if units is None or models_units is None:
        return point
    from meshrec.recognition.units import unit_factor

    return point * unit_factor(models_units, units)


def _reason_in_touch_units(advice, units: str | None, models_units: str | None) -> str:
    """The advice's reason with its point in the touches' unit, labelled, and its model
    units named, where :func:`_in_touch_units` converts the point (the reason is written
    in the models' unit, in which the advice is computed)."""
    if advice.point is None or units is None or models_units is None:
        return advice.reason
    from meshrec.recognition.advice import point_text

    shown = point_text(_in_touch_units(advice.point, units, models_units))
    reason = advice.reason.replace(point_text(advice.point), f"{shown} {units}")
    return reason.replace("model units", models_units)


def run_advice(args, out) -> int:
    """Recognise the touches, then print where to touch next.

    Parameters
    ----------
    args : argparse.Namespace
        ``touch_file`` (one or more), ``models``, ``model_units``, ``units``,
        ``cache_dir``, ``approach``, ``seed``, ``json``.
    out : text stream

    Returns
    -------
    int
        0 with a proposed touch, 1 when no candidate contact is reachable (the advice,
        with its reason, is still printed).

    Raises
    ------
    ValueError
        For bad input: a touch file named twice as ``-``, a bad ``--approach`` or
        ``--seed``, an unreadable touch or model folder, or touches the recognition
        refuses (units, sizes).
    """
    import numpy as np

    from meshrec.app import inputs
    from meshrec.recognition.advice import next_touch
    from meshrec.recognition.recognize import recognize
    from meshrec.registration.register import touch_geometry

    names = args.touch_file
    if names.count(inputs.STDIN) > 1:
        raise ValueError("touch file - (standard input) can be given only once")
    approach = _approach(args.approach)
    if args.seed is not None and args.seed < 0:
        raise ValueError(f"--seed must be a non-negative integer, got {args.seed}")
    folder = inputs.model_folder(args.models)
    units = inputs.model_units(folder, args.model_units)
    touch_units = inputs.touch_units(args.units, units)
    touches, geometries = [], []
    for name in names:  # bad data fail here, before any model is indexed
        touch = inputs.touch_in_units(inputs.read_touch(name), touch_units, units)
        try:
            geometries.append(touch_geometry(touch))
        except ValueError as exc:
            shown = inputs.STDIN_NAME if str(name) == inputs.STDIN else name
            raise ValueError(f"touch file {shown}: {exc}") from exc
        touches.append(touch)
    library = inputs.library(args, folder)
    rec = recognize(touches, library, geometry=geometries)
    advice = next_touch(rec, library, approach=approach, rng=args.seed)
    if args.json:
        out.write(json.dumps(advice_to_json(advice, rec.verdict, touch_units, units)) + "\n")
    else:
        plausible = " or ".join(rec.plausible) if rec.plausible else "none"
        what = "1 touch" if len(touches) == 1 else f"{len(touches)} touches"
        out.write(f"{what}: {rec.verdict} ({plausible})\n")
        if advice.point is None:
            out.write("next touch: none reachable\n")
        else:
            p = np.array2string(_in_touch_units(advice.point, touch_units, units), precision=5)
            d = np.array2string(advice.direction, precision=4)
            unit = _point_unit(touch_units, units)
            at = f"{p} {unit}" if unit is not None else p
            out.write(
                f"next touch: at {at}, approaching along {d} "
                f"({advice.criterion}, expected gain {advice.expected_gain:.3g} nats)\n"
            )
        reason = _reason_in_touch_units(advice, touch_units, units)
        out.write(f"{reason}  ({rec.seconds + advice.seconds:.2f} s)\n")
    return 0 if advice.point is not None else 1
