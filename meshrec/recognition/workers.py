"""Where the per-model work of a recognition runs: here, in local processes, or on a Dask cluster.

Each model's work depends on no other model's, so the models of a library can be spread
over processes and machines and the result is exactly that of a serial run: the same
registrations, in the same order, the same warnings. With the cascade
(:mod:`meshrec.recognition.cascade`) the decisions between its batches (the screen, which
models are searched in full) are taken by the caller on the whole batch's results, and
each batch of per-model jobs (:mod:`meshrec.recognition.jobs`) is spread over the
workers in chunks of even expected cost (:meth:`ModelWorkers.run_stages`).

A :class:`ModelWorkers` holds the library and the workers:

* ``workers=1`` (and no scheduler): every model in this process;
* ``workers=N``: a pool of ``N`` local processes
  (:class:`concurrent.futures.ProcessPoolExecutor`, started with "spawn" when the
  ModelWorkers is made); each process loads the library once, when it starts, from the
  same files and cache (the library's consolidated pack, :mod:`meshrec.model.pack`, makes
  that fast), and keeps it;
* ``scheduler="tcp://host:8786"``: the models' work runs on a Dask ``distributed`` cluster
  (scheduler and workers started with Dask's own ``dask scheduler`` and ``dask worker``);
  each Dask worker process loads the library once, on first use, and keeps it. The workers
  must see the model files and the cache at the same paths (a shared file system) and run
  the same meshrec version.

Every worker checks that the models it loaded are the ones of the caller's library (name,
sizes and a CRC-32 of the vertices, faces and curvatures): a model file changed since the
library was loaded is an error, not a silently different answer. Hold one :class:`ModelWorkers` for
many recognitions (a service does); :func:`meshrec.recognition.recognize.recognize` makes
a short-lived one when given ``workers=`` or ``scheduler=``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import warnings
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.io.checks import check_instance
from meshrec.model.cache import default_cache_dir
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.probe import probe_model, probe_radius_of
from meshrec.recognition.jobs import StageJob, balanced_chunks, run_stage, run_stages_here

__all__ = ["ModelWorkers", "available_cores"]


def available_cores() -> int:
    """The CPU cores this process may run on (``os.sched_getaffinity``, else ``os.cpu_count``).

    Returns
    -------
    int
        At least 1.
    """
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):  # not on Linux
        return max(os.cpu_count() or 1, 1)


@dataclass(frozen=True)
class _Spec:
    """How a worker loads the library: its folder (or files), parameters and cache."""

    folder: str | None
    files: tuple[str, ...]
    params: IndexParams
    cache_dir: str


def _fingerprint(model: ModelIndex) -> tuple:
    """What identifies a model's index: its name, sizes and a CRC-32 of its main arrays
    (the same file indexed with the same parameters gives the same one, in any cache)."""
    crc = 0
    for a in (model.mesh.vertices, model.mesh.faces, model.curvature.k1, model.curvature.k2):
        crc = zlib.crc32(np.ascontiguousarray(a).view(np.uint8).reshape(-1), crc)
    return (model.name, len(model.mesh.vertices), len(model.mesh.faces), crc)


#: The libraries loaded in this (worker) process, by spec: name -> (model, fingerprint).
_LOADED: dict[_Spec, dict[str, tuple[ModelIndex, tuple]]] = {}
_LOADED_LOCK = threading.Lock()


def _load(spec: _Spec) -> dict[str, tuple[ModelIndex, tuple]]:
    """The models of ``spec``, loaded once per process."""
    with _LOADED_LOCK:
        models = _LOADED.get(spec)
        if models is None:
            from meshrec.model.library import ModelLibrary

            with warnings.catch_warnings():  # the caller saw them when it loaded the library
                warnings.simplefilter("ignore")
                if spec.folder is not None:
                    lib = ModelLibrary.from_folder(
                        spec.folder, params=spec.params, cache_dir=spec.cache_dir
                    )
                else:
                    lib = ModelLibrary.from_files(
                        spec.files, params=spec.params, cache_dir=spec.cache_dir
                    )
            models = {m.name: (m, _fingerprint(m)) for m in lib}
            _LOADED[spec] = models
        return models


def _warm(spec: _Spec) -> int:
    """Load the library in this process (a pool's initializer, a Dask ``run``)."""
    return len(_load(spec))


@contextlib.contextmanager
def _sigint_ignored():
    """SIGINT ignored while the pool's processes are started, so that they inherit it
    (an ignored signal stays ignored across exec, and Python then installs no
    KeyboardInterrupt handler); restored at once after. Only from the main thread (the
    only one that may set handlers); elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _stage_chunk(spec: _Spec, items, touch, geometry, method, lookup_scale, trace):
    """Run a chunk of :class:`~meshrec.recognition.jobs.StageJob` (in a worker).

    ``items`` holds per job ``(kind, fingerprint, radius, payload, cost)``: the model by
    its fingerprint, seen through a probe tip of ``radius``
    (:func:`meshrec.model.probe.probe_model`: the worker's models are loaded plain).

    Returns, per job in order, ``(result, [(category, message), ...])``: the warnings are
    returned to be raised again by the caller.
    """
    models = _load(spec)
    out = []
    for kind, fp, radius, payload, cost in items:
        model, have = models.get(fp[0], (None, None))
        if have != tuple(fp):
            raise ValueError(
                f"model {fp[0]!r} differs in the worker (loaded {have}, expected {tuple(fp)}): "
                "its file changed since the library was loaded, or the worker sees other files"
            )
        if radius > 0.0:
            model = probe_model(model, radius)
        job = StageJob(kind, model, payload, cost)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = run_stage(job, touch, geometry, method, trace, lookup_scale)
        out.append((result, [(w.category, str(w.message)) for w in caught]))
    return out


class ModelWorkers:
    """The library and where its per-model work runs (see the module docstring).

    Parameters
    ----------
    library : ModelLibrary or iterable of ModelIndex
        The models (all indexed with the same parameters, from files).
    workers : int or None
        Local processes; ``None``: :func:`available_cores`. With 1, or fewer than
        ``defaults.PARALLEL_MIN_MODELS`` models, the work runs in this process (starting
        processes would cost more than it saves). Ignored with ``scheduler``.
    scheduler : str or None
        The address of a Dask ``distributed`` scheduler (``"tcp://127.0.0.1:8786"``).
    cache_dir : str or path-like or None
        The index cache the workers load from (``None``: a ModelLibrary's own
        ``cache_dir``, else :func:`meshrec.model.cache.default_cache_dir`, resolved here).

    Attributes
    ----------
    mode : str
        ``"serial"``, ``"processes"`` or ``"dask"``.
    workers : int
        Processes used (1 when serial; the Dask cluster's worker count with a scheduler).

    Raises
    ------
    TypeError
        If ``library`` is not an iterable of ModelIndex, ``scheduler`` not a string or
        ``cache_dir`` not a path.
    ValueError
        If ``workers`` is not a positive integer, the library is empty, its models have
        different index parameters (in parallel), or ``scheduler`` is not a Dask address
        (``tcp://host:port``) or cannot be reached.
    ImportError
        If ``scheduler`` is given and ``distributed`` is not installed
        (``pip install meshrec[dask]``).
    """

    def __init__(
        self,
        library,
        workers: int | None = None,
        scheduler: str | None = None,
        cache_dir: str | os.PathLike | None = None,
    ) -> None:
        if isinstance(library, (str, bytes)) or not hasattr(library, "__iter__"):
            raise TypeError(
                "library must be a ModelLibrary or an iterable of ModelIndex, got "
                f"{type(library).__name__}"
            )
        if cache_dir is None:  # a ModelLibrary's own cache (its workers load from it)
            cache_dir = getattr(library, "cache_dir", None)
        models = tuple(library)
        for i, m in enumerate(models):
            check_instance(m, ModelIndex, f"library[{i}]")
        if not models:
            raise ValueError("library must hold at least one model, got none")
        if workers is None:
            workers = available_cores()
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
        check_instance(scheduler, str, "scheduler", optional=True)
        check_instance(cache_dir, (str, os.PathLike), "cache_dir", optional=True)
        params = {m.params for m in models}
        parallel = scheduler is not None or (
            workers > 1 and len(models) >= defaults.PARALLEL_MIN_MODELS
        )
        if parallel and len(params) != 1:
            raise ValueError(
                f"library's models must share one IndexParams, got {len(params)} different"
            )
        self.models = models
        self._by_name = {m.name: m for m in models}
        # computed on first need (a serial run of the library's own models needs none:
        # a CRC-32 of every model's arrays was 1% of a recognition of the paper surfaces)
        self._fingerprints: dict[str, tuple] = {}
        folder = getattr(library, "folder", None)
        self._spec = _Spec(
            folder=str(folder) if folder is not None else None,
            files=tuple(str(m.path) for m in models),
            params=next(iter(params)),
            cache_dir=str(Path(cache_dir) if cache_dir is not None else default_cache_dir()),
        )
        self._pool = None
        self._client = None
        if scheduler is not None:
            self._client = _dask_client(scheduler)
            self._client.run(_warm, self._spec)
            self.mode = "dask"
            self.workers = max(len(self._client.scheduler_info()["workers"]), 1)
        elif parallel:
            self._pool = ProcessPoolExecutor(
                max_workers=workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_warm,
                initargs=(self._spec,),
            )
            self.mode = "processes"
            self.workers = workers
            # Start every process now (each loads the library once): the first
            # recognition then costs what the others do. They start ignoring Ctrl-C (a
            # terminal sends it to the whole process group): the caller handles it and
            # stops them, with no traceback from each of them.
            try:
                with _sigint_ignored():
                    started = [self._pool.submit(_warm, self._spec) for _ in range(workers)]
                for f in started:
                    f.result()
            except BaseException:  # Ctrl-C while they start: none is left behind
                self._stop_now()
                raise
        else:
            self.mode = "serial"
            self.workers = 1

    def _fingerprint_of(self, name: str) -> tuple:
        """The fingerprint of this library's model ``name``, computed once."""
        fp = self._fingerprints.get(name)
        if fp is None:
            fp = self._fingerprints[name] = _fingerprint(self._by_name[name])
        return fp

    def __repr__(self) -> str:
        return (
            f"ModelWorkers(models={len(self.models)}, mode={self.mode!r}, workers={self.workers})"
        )

    def __enter__(self) -> ModelWorkers:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None and not issubclass(exc_type, Exception):
            # Ctrl-C (or an exit): the processes ignore SIGINT, so stop them now rather
            # than wait for the chunks they are running.
            self._stop_now()
        self.close()

    def close(self) -> None:
        """Stop the local processes (or leave the Dask cluster); idempotent."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._client is not None:
            self._client.close()
            self._client = None

    def _stop_now(self) -> None:
        """Terminate the local processes at once (their work is abandoned)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
        if terminate is not None:
            terminate()
            return
        # Before 3.14 the executor keeps its processes in ``_processes`` (pid -> Process).
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)

    def register_each(
        self,
        touch,
        models: Sequence[ModelIndex],
        geometry,
        method: str,
        lookup_scale: float = 1.0,
        trace: bool = False,
        progress: Callable[[int, int, str], None] | None = None,
        max_candidates: int | None = None,
    ) -> list:
        """Register ``touch`` on each of ``models`` (``meshrec.registration.register``).

        Parameters
        ----------
        touch : TouchData
        models : sequence of ModelIndex
            Models of this library.
        geometry : LocalGeometry
            The touch's local geometry (shared by all models).
        method : str
        lookup_scale : float
        trace : bool
        progress : callable, optional
            ``progress(i, n, name)``: before model ``i`` is registered (serial), or as the
            results come in (in parallel).
        max_candidates : int, optional
            The most candidate contacts per model (default ``defaults.MAX_CANDIDATES``).

        Returns
        -------
        list of Registration
            In the order of ``models``; the warnings each registration raised are raised
            again here, in that order.

        Raises
        ------
        ValueError
            If a model is not one of this library's (or differs from it in a worker), or
            as :func:`~meshrec.registration.register.register`.
        RuntimeError
            If the workers were closed.
        """
        jobs = [StageJob("register", m, max_candidates) for m in models]
        n = len(jobs)
        report = None
        if progress is not None:

            def report(k, job):
                progress(k, n, job.model.name)

        return self.run_stages(
            jobs, touch, geometry, method, trace=trace, lookup_scale=lookup_scale, progress=report
        )

    def run_stages(
        self,
        jobs: Sequence[StageJob],
        touch,
        geometry,
        method: str,
        trace: bool = False,
        lookup_scale: float = 1.0,
        progress: Callable[[int, StageJob], None] | None = None,
    ) -> list:
        """Run a batch of per-model jobs (:mod:`meshrec.recognition.jobs`) on the workers.

        In parallel the jobs are split into about ``defaults.PARALLEL_CHUNKS_PER_WORKER``
        chunks per worker of even expected cost (``StageJob.cost``,
        :func:`~meshrec.recognition.jobs.balanced_chunks`), the costliest submitted
        first; the jobs of cost at most ``defaults.PARALLEL_HERE_COST`` run in this
        process meanwhile.

        Parameters
        ----------
        jobs : sequence of StageJob
            On models of this library.
        touch : TouchData
        geometry : LocalGeometry
            The touch's local geometry (shared by all models).
        method : str
        trace : bool
        lookup_scale : float
            As for :func:`~meshrec.recognition.jobs.run_stage`.
        progress : callable, optional
            ``progress(k, job)``: before the ``k``-th job (serial), or as the results come
            in, ``k`` counting them (in parallel).

        Returns
        -------
        list
            :func:`~meshrec.recognition.jobs.run_stage`'s result per job, in the order
            of ``jobs``; the warnings each job raised are raised again here, in that order.

        Raises
        ------
        TypeError
            If a job is not a StageJob.
        ValueError
            If a job's model is not one of this library's (or differs from it in a
            worker), or as the stage's own function.
        RuntimeError
            If the workers were closed.
        """
        jobs = list(jobs)
        for i, job in enumerate(jobs):
            check_instance(job, StageJob, f"jobs[{i}]")
            m = job.model
            known = self._by_name.get(m.name)
            if known is not m and (
                known is None or self._fingerprint_of(m.name) != _fingerprint(m)
            ):
                raise ValueError(f"models must belong to the workers' library, got {m.name!r}")
        n = len(jobs)
        if self.mode == "serial" or n == 0:
            return run_stages_here(jobs, touch, geometry, method, trace, lookup_scale, progress)
        if self._pool is None and self._client is None:
            raise RuntimeError("the workers were closed")
        # The cheapest jobs (a pruned pose: a few refinement steps) run here while the
        # workers run the others: no round trip of their inputs, and this process waits
        # anyway.
        here = [i for i, job in enumerate(jobs) if job.cost <= defaults.PARALLEL_HERE_COST]
        away = [i for i, job in enumerate(jobs) if job.cost > defaults.PARALLEL_HERE_COST]
        chunks = [
            [away[j] for j in c]
            for c in balanced_chunks(
                [jobs[i].cost for i in away], self.workers * defaults.PARALLEL_CHUNKS_PER_WORKER
            )
        ]
        args = (geometry, method, float(lookup_scale), bool(trace))
        # the models may be seen through a probe tip (recognize's probe_radius)
        items = {
            i: (
                jobs[i].kind,
                self._fingerprint_of(jobs[i].model.name),
                probe_radius_of(jobs[i].model),
                jobs[i].payload,
                jobs[i].cost,
            )
            for i in away
        }
        # Dask's submit re-runs nothing by default (pure=False: every call is new work)
        extra = {"pure": False} if self._client is not None else {}
        executor = self._client if self._client is not None else self._pool
        futures = [
            executor.submit(_stage_chunk, self._spec, [items[i] for i in c], touch, *args, **extra)
            for c in chunks
        ]
        out = [None] * n
        done = 0
        for i in here:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                result = run_stage(jobs[i], touch, geometry, method, trace, lookup_scale)
            out[i] = (result, [(w.category, str(w.message)) for w in caught])
            if progress is not None:
                progress(done, jobs[i])
            done += 1
        results = [f.result() for f in futures]
        for c, res in zip(chunks, results, strict=True):
            for i, item in zip(c, res, strict=True):
                out[i] = item
                if progress is not None:
                    progress(done, jobs[i])
                done += 1
        regs = []
        for result, caught in out:
            for category, message in caught:
                warnings.warn(message, category, stacklevel=2)
            regs.append(result)
        return regs


def _dask_client(address: str):
    """A Dask client of the scheduler at ``address``."""
    try:
        from distributed import Client
    except ImportError as exc:
        raise ImportError(
            f"scheduler needs the Dask 'distributed' package (pip install meshrec[dask]): {exc}"
        ) from exc
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        # checked before a Client is made: one that fails on a malformed address inside
        # its constructor is left running, and holds the interpreter's exit for seconds
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except ValueError as exc:
        raise ValueError(
            f"scheduler must be a Dask scheduler address such as 'tcp://127.0.0.1:8786', "
            f"got {address!r} ({exc})"
        ) from None
    try:
        return Client(address, timeout=defaults.DASK_CONNECT_SECONDS, set_as_default=False)
    except OSError as exc:
        raise ValueError(f"scheduler {address!r} cannot be reached: {exc}") from exc
