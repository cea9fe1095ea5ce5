"""Benchmark protocols: seeded simulated touches, recognised and scored against the truth.

The paper's protocols (its Tables 2 to 4) are runs of :func:`run_trials` on the bundled
libraries; the same function serves a user's own folder. Every trial records the
recognition, the localisation error against the true contact (modulo the shape's
symmetries where they are known), the oracle (the final refinement started at the true
pose: the floor the noise leaves) and the time per stage. ``tools/bench.py`` prints the
report from these rows.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.recognition.recognize import recognize
from meshrec.registration.register import StageTimes, refine_pose
from meshrec.sim.paper import PAPER_SURFACES, localisation_error
from meshrec.sim.simulate import simulate_touch

__all__ = [
    "OBJECT_SIDES",
    "Trial",
    "object_localisation_error",
    "paper_touch",
    "run_trials",
]

#: The paper's Figure 7 objects' curved sides: (semi-axis x, semi-axis y, half-height) mm.
OBJECT_SIDES = {
    "cylinder_1": (25.2, 25.2, 50.0),
    "cylinder_2": (47.0, 47.0, 50.0),
    "elliptic_cylinder": (50.8, 31.75, 50.0),
}


@dataclass(frozen=True, eq=False)
class Trial:
    """One simulated touch recognised against a library.

    Attributes
    ----------
    shape : str
        The model the touch was simulated on.
    seed : int
    best : str or None
        The recognised model.
    lookup_only : bool
        Every wrong model was rejected by the table lookup (no candidates).
    right_error, wrong_error : float or None
        Mean per-point error on the right model, and the least on a wrong one (None if
        every wrong model was rejected).
    errors : dict
        Every model's error (None when rejected), by name.
    true_contact, found_contact : (3,) float
        The true contact and the one found on the right model, model coordinates.
    loc_error : float
        ``||p - p*||`` on the right model, modulo the shape's symmetries where known.
    oracle_error, oracle_loc : float
        The same two measures for the refinement started at the true pose.
    seconds : float
        Wall time of the recognition against the whole library.
    geometry_seconds : float
        Of which the curvature estimate from the curves.
    times : StageTimes
        The other stages, summed over the models.
    """

    shape: str
    seed: int
    best: str | None
    lookup_only: bool
    right_error: float | None
    wrong_error: float | None
    errors: dict
    true_contact: np.ndarray
    found_contact: np.ndarray | None
    loc_error: float
    oracle_error: float
    oracle_loc: float
    seconds: float
    geometry_seconds: float
    times: StageTimes

    @property
    def recognised(self) -> bool:
        """Whether the right model won."""
        return self.best == self.shape


def object_localisation_error(name: str, true_contact, found_contact) -> float:
    """``||p - p*||`` on an experiment object, modulo what a side touch cannot see.

    Away from the caps a touch cannot tell where along the axis it is, so the axial
    coordinate is free; the elliptic cylinder keeps the four symmetries of its ellipse
    (sign flips of x and y); on a circular cylinder every side point is equivalent, and
    on the sphere every point, so only the radial distance remains. Other names: the
    plain Euclidean distance.

    Parameters
    ----------
    name : str
    true_contact, found_contact : (3,) float

    Returns
    -------
    float
    """
    p, q = np.asarray(true_contact, float), np.asarray(found_contact, float)
    if name == "sphere":
        return float(abs(np.linalg.norm(p) - np.linalg.norm(q)))
    if name == "elliptic_cylinder":
        flips = np.array([[1, 1], [-1, 1], [1, -1], [-1, -1]])
        return float(np.min(np.linalg.norm(p[:2] - flips * q[:2], axis=1)))
    if name in OBJECT_SIDES:
        return float(abs(np.linalg.norm(p[:2]) - np.linalg.norm(q[:2])))
    return float(np.linalg.norm(p - q))


def _loc(name: str, p, q) -> float:
    if name in PAPER_SURFACES:
        return localisation_error(name, p, q)
    return object_localisation_error(name, p, q)


def paper_touch(model, seed: int, n_points: int | None = None, noise: float | None = None,
                length_fraction: float = defaults.SIM_LENGTH_FRACTION):
    """A seeded touch by the paper's protocols.

    On the experiment objects (names in :data:`OBJECT_SIDES`) the contact is drawn on the
    curved side, at least 30 mm from the rims (the 41-point curves stay on the side: a flat
    cap cannot tell the objects apart, and a curve across a sharp rim has no curvature to
    estimate); elsewhere uniformly by area.

    Parameters
    ----------
    model : ModelIndex
    seed : int
    n_points, noise : int, float, optional
        Default: the paper's simulation (61, 0.001) on the surfaces, its experiment's
        (41, 0.1 mm) on the objects.
    length_fraction : float
        Curve length as a fraction of sqrt(surface area) of the model.

    Returns
    -------
    SimulatedTouch
    """
    rng = np.random.default_rng(seed)
    length = length_fraction * model.mesh.scale
    is_object = model.name in OBJECT_SIDES or model.name == "sphere"
    if n_points is None:
        n_points = defaults.BENCH_OBJECT_POINTS if is_object else defaults.SIM_POINTS
    if noise is None:
        noise = defaults.BENCH_OBJECT_NOISE if is_object else defaults.SIM_NOISE
    contact = None
    if model.name in OBJECT_SIDES:
        a, b, half = OBJECT_SIDES[model.name]
        theta = rng.uniform(0, 2 * np.pi)
        z = rng.uniform(-(half - defaults.BENCH_RIM_MARGIN), half - defaults.BENCH_RIM_MARGIN)
        contact = np.array([a * np.cos(theta), b * np.sin(theta), z])
    return simulate_touch(
        model, contact=contact, rng=rng, n_points=n_points, noise=noise, length=length
    )


def run_trials(library, shapes, trials: int, first_seed: int = 0, *,
               length_fraction: float = defaults.SIM_LENGTH_FRACTION,
               n_points: int | None = None, noise: float | None = None,
               progress=None) -> list[Trial]:
    """Simulate seeded touches on ``shapes`` and recognise each against ``library``.

    Parameters
    ----------
    library : ModelLibrary
    shapes : sequence of str
        Names of the models touched (each in ``library``).
    trials : int
        Touches per shape, seeds ``first_seed`` to ``first_seed + trials - 1``.
    first_seed : int
    length_fraction : float
        Curve length as a fraction of sqrt(surface area) of the touched model.
    n_points, noise : int, float, optional
        See :func:`paper_touch`.
    progress : callable, optional
        ``progress(done, total)`` after each trial.

    Returns
    -------
    list of Trial

    Raises
    ------
    ValueError
        If a shape is not in the library or ``trials`` is not a positive integer.
    """
    if not isinstance(trials, (int, np.integer)) or trials < 1:
        raise ValueError(f"trials must be a positive integer, got {trials!r}")
    for s in shapes:
        if s not in library.names:
            raise ValueError(f"shape {s!r} is not in the library {list(library.names)}")
    out = []
    total = len(shapes) * trials
    for shape in shapes:
        model = library[shape]
        for seed in range(first_seed, first_seed + trials):
            sim = paper_touch(model, seed, n_points, noise, length_fraction)
            t0 = time.perf_counter()
            rec = recognize(sim.touch, library)
            seconds = time.perf_counter() - t0
            by_name = {r.model: r for r in rec.ranking}
            right = by_name[shape]
            wrong = [r for r in rec.ranking if r.model != shape]
            wrong_errors = [r.error for r in wrong if not r.rejected]
            oracle = refine_pose(sim.touch, model, sim.T_model_touch, geometry=rec.geometry)
            times = StageTimes()
            for r in rec.ranking:
                times = times + r.times
            out.append(Trial(
                shape=shape,
                seed=seed,
                best=rec.best.model if rec.best is not None else None,
                lookup_only=all(r.rejected for r in wrong),
                right_error=right.error,
                wrong_error=min(wrong_errors) if wrong_errors else None,
                errors={r.model: r.error for r in rec.ranking},
                true_contact=sim.contact,
                found_contact=right.contact,
                loc_error=(_loc(shape, sim.contact, right.contact)
                           if not right.rejected else float("inf")),
                oracle_error=oracle.error,
                oracle_loc=_loc(shape, sim.contact, oracle.contact),
                seconds=seconds,
                geometry_seconds=max(rec.seconds - sum(r.seconds for r in rec.ranking), 0.0),
                times=times,
            ))
            if progress is not None:
                progress(len(out), total)
    return out
