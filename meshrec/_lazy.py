"""trimesh, imported on first use.

trimesh's import takes about 0.25 s of CPU time on top of numpy and scipy, and a warm
recognition never needs it: the models come from the cache. The modules that build
indexes, load mesh files or sample surfaces take it from :func:`trimesh_module` when they
run. trimesh imports its optional dependencies under ``except BaseException``, which
swallows a KeyboardInterrupt (measured: a SIGINT 0.3 s into start-up was ignored and the
run went on); here a Ctrl-C during that import is held and raised as soon as it is done.
"""

from __future__ import annotations

import importlib
import signal
import sys
import threading
from types import ModuleType

__all__ = ["trimesh_module"]


def trimesh_module() -> ModuleType:
    """The ``trimesh`` module, imported now if it was not.

    Returns
    -------
    module
        ``trimesh``.

    Raises
    ------
    KeyboardInterrupt
        If SIGINT came during the import (in the main thread, with Python's default
        handler in place): raised once the import is complete.
    """
    module = sys.modules.get("trimesh")
    if module is not None:
        return module
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        return importlib.import_module("trimesh")
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        module = importlib.import_module("trimesh")
    finally:
        signal.signal(signal.SIGINT, previous)
    if held:
        raise KeyboardInterrupt
    return module
