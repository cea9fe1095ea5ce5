"""Per-phase CPU clocks of one recognition (:attr:`Recognition.phase_times`).

:func:`recognize` runs its phases (the curve fits, the checks, the first touch's
registrations, the joint phases of several touches, the widened and dense passes, the
scores, the pose freedom, the probe-offset check) each inside :func:`timed`, within a
:func:`phase_clock`; the clock keeps each phase's exclusive CPU time
(``time.process_time``: a phase nested in another counts for itself only) and gives a
:class:`PhaseTimes`. Outside a clock :func:`timed` does nothing: the joint functions
time their parts (registrations alone, pair seeds, joint refinements) only when a
recognition runs them. A few ``process_time`` calls per phase, nothing else: the answers
do not depend on the clock.
"""

from __future__ import annotations

import time
from contextvars import ContextVar
from dataclasses import dataclass, fields

__all__ = ["PARTS", "PHASES", "PhaseClock", "PhaseTimes", "phase_clock", "timed"]

#: The top-level phases of a recognition, in the order they run (disjoint).
PHASES = (
    "geometry",
    "checks",
    "first",
    "best_first",
    "adequacy",
    "symmetries",
    "widened",
    "dense",
    "transfer",
    "scoring",
    "freedom",
    "cautions",
    "probe_offset",
)
#: The parts timed inside the joint phases: ``<phase>_<part>`` where PhaseTimes has that
#: field (``best_first_alone``, ...), otherwise counted in the enclosing phase itself.
PARTS = ("alone", "pairs", "joint")


@dataclass(frozen=True)
class PhaseTimes:
    """CPU seconds of each phase of one :func:`~meshrec.recognition.recognize.recognize` call.

    Every figure is ``time.process_time`` (the CPU of this whole process, all its threads)
    over the phase, exclusive of the phases nested in it; 0 for a phase that did not run.
    The top-level phases (those of :data:`PHASES`) are disjoint, so their sum is at most
    ``total``; the ``<phase>_<part>`` fields split a joint phase and are included in it.
    In a serial run (``workers`` None or 1) that is the recognition's CPU. With
    ``workers`` > 1 or a Dask scheduler the per-model registrations of ``first``,
    ``widened`` and ``dense`` run in other processes, not counted: those phases then
    hold this process's share only (dispatching, waiting, merging). In a process doing
    other work at the same time (a server's other threads) that work is counted too.

    Attributes
    ----------
    geometry : float
        The touches' curve fits (the local geometry at each contact).
    checks : float
        The unit check, the touches' sizes and the tip radius against the curvature.
    first : float
        The first touch registered alone on every model (through the cascade or not)
        and, with several touches, its poses scored on all of them.
    best_first : float
        Several touches: the best-first joint fits
        (:func:`~meshrec.recognition.bestfirst.fit_best_first`), including
        ``best_first_alone`` and ``best_first_joint``.
    best_first_alone : float
        Of ``best_first``: the touches after the first registered alone.
    best_first_joint : float
        Of ``best_first``: the joint refinements (with the harder search's seeds).
    adequacy : float
        Several touches: the search-adequacy step (the models searched again from pairs
        of touches), including the three ``adequacy_*`` parts.
    adequacy_alone : float
        Of ``adequacy``: touches registered alone.
    adequacy_pairs : float
        Of ``adequacy``: the pair seeds (:func:`~meshrec.recognition.pairs.pair_seeds`).
    adequacy_joint : float
        Of ``adequacy``: the joint refinements.
    symmetries : float
        Several touches: the near-symmetry exploration of the leading models.
    widened : float
        The widened lookup pass and its scores (0 when the first pass fit the noise).
    dense : float
        One touch: the dense passes and their scores: after a widened pass that still fit
        nothing, and the confirmation of the named model's search before a ``recognised``
        answer (0 when neither ran).
    transfer : float
        Before a model is named (one touch or several): its best poses refined on the
        other models, and the scores again (``naming._transferred``).
    scoring : float
        The scores, the flat prior, the verdict and its cautions.
    freedom : float
        The pose freedom at the best model's pose; for one touch about to be named, also
        its poses along the best pose's weak motions (``recognize``).
    cautions : float
        The coarse-resolution and sharp-edge warnings.
    probe_offset : float
        The probe-offset check (0 with a probe radius).
    total : float
        The whole call, from its first line to its return; ``total`` less the phases'
        sum (:attr:`other`) is the rest (argument checks, the offset models, starting
        and closing the workers, passing the warnings on).
    """

    geometry: float = 0.0
    checks: float = 0.0
    first: float = 0.0
    best_first: float = 0.0
    best_first_alone: float = 0.0
    best_first_joint: float = 0.0
    adequacy: float = 0.0
    adequacy_alone: float = 0.0
    adequacy_pairs: float = 0.0
    adequacy_joint: float = 0.0
    symmetries: float = 0.0
    widened: float = 0.0
    dense: float = 0.0
    transfer: float = 0.0
    scoring: float = 0.0
    freedom: float = 0.0
    cautions: float = 0.0
    probe_offset: float = 0.0
    total: float = 0.0

    @property
    def other(self) -> float:
        """``total`` less the sum of the top-level phases (:data:`PHASES`)."""
        return self.total - sum(getattr(self, name) for name in PHASES)

    def phases(self) -> dict[str, float]:
        """The top-level phases (:data:`PHASES`, disjoint), by name, in running order."""
        return {name: getattr(self, name) for name in PHASES}

    def as_dict(self) -> dict[str, float]:
        """Every field by name, the parts too (not disjoint: see the class docstring)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def __repr__(self) -> str:
        shown = ", ".join(
            f"{k}={v:.3g}" for k, v in self.as_dict().items() if v != 0.0 and k != "total"
        )
        return f"PhaseTimes(total={self.total:.3g}{', ' if shown else ''}{shown})"


_FIELDS = frozenset(f.name for f in fields(PhaseTimes))
_CURRENT: ContextVar[PhaseClock | None] = ContextVar("meshrec_phase_clock", default=None)


class PhaseClock:
    """Exclusive CPU seconds by phase, for one recognition (see :func:`phase_clock`)."""

    def __init__(self) -> None:
        self.start = time.process_time()
        self.spent: dict[str, float] = {}
        self.stack: list[list] = []  # [field, its phase, start, time of the phases inside]

    def enter(self, name: str) -> None:
        """Start phase (or part) ``name`` (see :func:`timed`)."""
        if name in PARTS:
            phase = next((f[1] for f in reversed(self.stack)), None)
            key = f"{phase}_{name}" if f"{phase}_{name}" in _FIELDS else phase
        else:
            phase = key = name
        self.stack.append([key, phase, time.process_time(), 0.0])

    def leave(self) -> None:
        """End the phase entered last; its exclusive time is added to its field."""
        key, _, start, inner = self.stack.pop()
        took = time.process_time() - start
        if key is not None:
            self.spent[key] = self.spent.get(key, 0.0) + took - inner
        if self.stack:
            self.stack[-1][3] += took

    def times(self) -> PhaseTimes:
        """The phases so far, ``total`` from the clock's start to now."""
        spent = dict(self.spent)
        for phase in ("best_first", "adequacy"):
            spent[phase] = spent.get(phase, 0.0) + sum(
                v for k, v in self.spent.items() if k.startswith(phase + "_")
            )
        return PhaseTimes(total=time.process_time() - self.start, **spent)


class phase_clock:
    """``with phase_clock() as clock:`` the :func:`timed` phases inside count on ``clock``.

    The clock holds for this thread's (or task's) context and is restored on exit; a
    clock started inside another replaces it for its duration.
    """

    def __enter__(self) -> PhaseClock:
        self._clock = PhaseClock()
        self._token = _CURRENT.set(self._clock)
        return self._clock

    def __exit__(self, *exc) -> None:
        _CURRENT.reset(self._token)


class timed:
    """``with timed(name):`` the block counts as phase ``name`` on the current clock.

    Parameters
    ----------
    name : str
        A field of :class:`PhaseTimes` among :data:`PHASES`, or a part of :data:`PARTS`
        (it counts as ``<enclosing phase>_<part>`` where that field exists, else as the
        enclosing phase). Outside a :func:`phase_clock`, nothing is timed.

    Raises
    ------
    ValueError
        If ``name`` is neither a phase nor a part.
    """

    __slots__ = ("_clock", "_name")

    def __init__(self, name: str) -> None:
        if name not in PHASES and name not in PARTS:
            raise ValueError(f"name must be one of {PHASES + PARTS}, got {name!r}")
        self._name = name
        self._clock = None

    def __enter__(self) -> None:
        self._clock = _CURRENT.get()
        if self._clock is not None:
            self._clock.enter(self._name)

    def __exit__(self, *exc) -> None:
        if self._clock is not None:
            self._clock.leave()
