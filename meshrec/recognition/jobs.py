"""One model's share of a recognition's work, as a job that runs wherever the workers are.

The cascade (:mod:`meshrec.recognition.cascade`) splits a recognition into per-model
pieces between its order-free decisions: the screen's leaders registered in full, every
surviving model's first stages, the full searches of the models the cascade keeps, the
pruned registrations. Each piece is a :class:`StageJob`; :func:`run_stage` runs one on a
model, the same code in this process, in a local worker process or on a Dask worker
(:mod:`meshrec.recognition.workers`), so the result does not depend on where it ran.
:func:`balanced_chunks` splits a batch of jobs into chunks of about equal expected cost.

The kinds of job (``StageJob.kind``) and what :func:`run_stage` returns for each:

* ``"register"``: :func:`~meshrec.registration.register.register` (all the stages), with
  at most ``payload`` candidates per model (None: ``defaults.MAX_CANDIDATES``): a
  Registration;
* ``"coarse"``: :func:`~meshrec.registration.register.register_coarse`: a
  CoarseRegistration;
* ``"leader"``: both, the full search only when the lookup found a candidate: a pair
  ``(CoarseRegistration, Registration or None)``;
* ``"full"``: :func:`~meshrec.registration.register.register_full` from the
  CoarseRegistration in ``payload``: a Registration;
* ``"pruned"``: :func:`~meshrec.recognition.cascade.pruned_registration` from the
  CoarseRegistration in ``payload``: a Registration;
* ``"screened"``: :func:`~meshrec.recognition.screen.screened_registration` of the
  ``(LibraryScreen, index)`` in ``payload``: a Registration.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_choice, check_instance, check_int, check_number
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.recognition.screen import LibraryScreen, screened_registration
from meshrec.registration.register import (
    CoarseRegistration,
    register,
    register_coarse,
    register_full,
)

__all__ = ["STAGE_KINDS", "StageJob", "balanced_chunks", "run_stage", "run_stages_here"]

#: The kinds of :class:`StageJob` (see the module docstring).
STAGE_KINDS = ("register", "coarse", "leader", "full", "pruned", "screened")


@dataclass(frozen=True, eq=False)
class StageJob:
    """One piece of per-model work of a recognition.

    Attributes
    ----------
    kind : str
        One of :data:`STAGE_KINDS`.
    model : ModelIndex
        The model it runs on (a worker runs it on its own copy, checked equal).
    payload : object
        The CoarseRegistration (``"full"``, ``"pruned"``), the ``(LibraryScreen, i)``
        pair (``"screened"``), or the most candidates to look up (``"register"``: a
        positive int, or None for ``defaults.MAX_CANDIDATES``); None otherwise.
    cost : float
        Its expected cost, in any unit shared by a batch (for :func:`balanced_chunks`).

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``cost`` not a real number, or the payload not
        of its kind's type.
    ValueError
        If ``kind`` is not one of :data:`STAGE_KINDS`, ``cost`` is negative or not
        finite, or a payload is given to a kind that takes none.
    """

    kind: str
    model: ModelIndex
    payload: object = None
    cost: float = 1.0

    def __post_init__(self) -> None:
        check_choice(self.kind, STAGE_KINDS, "kind")
        check_instance(self.model, ModelIndex, "model")
        check_number(self.cost, "cost", minimum=0.0)
        if self.kind in ("full", "pruned"):
            check_instance(self.payload, CoarseRegistration, "payload")
        elif self.kind == "screened":
            if not (isinstance(self.payload, tuple) and len(self.payload) == 2):
                raise TypeError(
                    "payload must be a (LibraryScreen, int) pair, got "
                    f"{type(self.payload).__name__}"
                )
            check_instance(self.payload[0], LibraryScreen, "payload[0]")
            check_int(self.payload[1], "payload[1]", minimum=0)
        elif self.kind == "register":
            if self.payload is not None:
                check_int(self.payload, "payload", minimum=1)
        elif self.payload is not None:
            raise ValueError(f"payload must be None for a {self.kind!r} job, got a payload")


def run_stage(
    job: StageJob,
    touch: TouchData,
    geometry: LocalGeometry,
    method: str,
    trace: bool = False,
    lookup_scale: float = 1.0,
    model: ModelIndex | None = None,
):
    """Run one job (see the module docstring for what each kind returns).

    Parameters
    ----------
    job : StageJob
    touch : TouchData
    geometry : LocalGeometry
        The touch's local geometry (shared by all models).
    method : str
        The local-search optimiser.
    trace : bool
        Keep the full searches' stage traces.
    lookup_scale : float
        The (K, H) window's scale (``"register"`` jobs only; the cascade's use 1).
    model : ModelIndex, optional
        The model to run on (a worker's copy of ``job.model``); default ``job.model``.

    Returns
    -------
    Registration or CoarseRegistration or tuple
        As the module docstring says.

    Raises
    ------
    TypeError
        If ``job`` is not a StageJob.
    ValueError
        As the stage's own function.
    """
    check_instance(job, StageJob, "job")
    model = job.model if model is None else model
    if job.kind == "register":
        most = defaults.MAX_CANDIDATES if job.payload is None else int(job.payload)
        return register(
            touch,
            model,
            geometry=geometry,
            method=method,
            trace=trace,
            lookup_scale=lookup_scale,
            max_candidates=most,
        )
    if job.kind == "coarse":
        return register_coarse(touch, model, geometry)
    if job.kind == "leader":
        coarse = register_coarse(touch, model, geometry)
        if coarse.rejected:
            return coarse, None
        return coarse, register_full(model, coarse, method=method, trace=trace)
    if job.kind == "full":
        return register_full(model, job.payload, method=method, trace=trace)
    if job.kind == "pruned":
        # imported here: the cascade builds these jobs (and imports this module)
        from meshrec.recognition.cascade import pruned_registration

        return pruned_registration(touch, model, job.payload)
    screen, i = job.payload
    return screened_registration(touch, model, geometry, screen, int(i))


def run_stages_here(
    jobs: Sequence[StageJob],
    touch: TouchData,
    geometry: LocalGeometry,
    method: str,
    trace: bool = False,
    lookup_scale: float = 1.0,
    progress: Callable[[int, StageJob], None] | None = None,
) -> list:
    """Run the jobs in this process, in order.

    Parameters
    ----------
    jobs : sequence of StageJob
    touch, geometry, method, trace, lookup_scale
        As for :func:`run_stage`.
    progress : callable, optional
        ``progress(k, job)`` before the ``k``-th job.

    Returns
    -------
    list
        :func:`run_stage`'s result per job, in order.

    Raises
    ------
    TypeError, ValueError
        As :func:`run_stage`.
    """
    out = []
    for k, job in enumerate(jobs):
        if progress is not None:
            progress(k, job)
        out.append(run_stage(job, touch, geometry, method, trace, lookup_scale))
    return out


def balanced_chunks(costs: Sequence[float], k: int) -> list[list[int]]:
    """Split jobs into ``k`` chunks of about equal total cost (the longest-first greedy rule).

    The jobs are taken most costly first (ties: in order) and each is given to the chunk
    with the least cost so far (ties: the fewest jobs, then the first). With equal costs that is the
    interleaved split ``[0, k, 2k, ...], [1, k+1, ...]``. Written here rather than taken
    from a library: it is a dozen lines, and scheduling libraries bring no such helper.

    Parameters
    ----------
    costs : sequence of float
        Each job's expected cost (>= 0).
    k : int
        Chunks wanted (>= 1); fewer come back when there are fewer jobs.

    Returns
    -------
    list of list of int
        The jobs' indices per chunk, each in increasing order; the most loaded chunk
        first (submit in this order: the longest work starts first). No chunk is empty.

    Raises
    ------
    TypeError
        If ``k`` is not an integer.
    ValueError
        If ``k`` is below 1 or a cost is negative or not finite.
    """
    k = check_int(k, "k", minimum=1)
    costs = np.asarray(costs, dtype=float).reshape(-1)
    if not np.all(np.isfinite(costs) & (costs >= 0)):
        raise ValueError(f"costs must be finite and >= 0, got {costs.tolist()!r}")
    n = len(costs)
    k = min(k, n)
    if n == 0:
        return []
    heap = [(0.0, 0, c) for c in range(k)]  # (cost so far, jobs so far, chunk)
    chunks: list[list[int]] = [[] for _ in range(k)]
    loads = [0.0] * k
    for j in sorted(range(n), key=lambda j: (-costs[j], j)):
        load, count, c = heapq.heappop(heap)
        chunks[c].append(j)
        loads[c] = load + float(costs[j])
        heapq.heappush(heap, (loads[c], count + 1, c))
    order = sorted(range(k), key=lambda c: (-loads[c], c))
    return [sorted(chunks[c]) for c in order]
