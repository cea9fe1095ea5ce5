"""The command line's ``--workers`` and ``--scheduler`` options (see
:mod:`meshrec.recognition.workers`)."""

from __future__ import annotations

__all__ = ["add_workers_args", "model_workers"]


def add_workers_args(sp) -> None:
    """Add ``--workers N`` and ``--scheduler ADDRESS`` to a subcommand's parser."""
    sp.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local processes the models are spread over (default: the cores available; "
        "libraries of fewer than 8 models run in one process); same result as one",
    )
    sp.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the per-model work on a Dask distributed cluster, e.g. "
        "tcp://127.0.0.1:8786 (started with 'dask scheduler' and 'dask worker'; the "
        "workers must see the model files and the cache at the same paths)",
    )


def model_workers(args, library):
    """The :class:`~meshrec.recognition.workers.ModelWorkers` of ``--workers``/``--scheduler``.

    Parameters
    ----------
    args : argparse.Namespace
        With ``workers``, ``scheduler`` and ``cache_dir``.
    library : ModelLibrary

    Returns
    -------
    ModelWorkers
        Close it when done (it is a context manager).

    Raises
    ------
    ValueError
        If ``--workers`` is not a positive integer, the scheduler cannot be reached or
        ``distributed`` is not installed (``pip install 'meshrec[dask]'``).
    """
    from meshrec.recognition.workers import ModelWorkers

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    try:
        return ModelWorkers(
            library, workers=args.workers, scheduler=args.scheduler, cache_dir=args.cache_dir
        )
    except ImportError as exc:
        raise ValueError(f"--scheduler: {exc}") from None
