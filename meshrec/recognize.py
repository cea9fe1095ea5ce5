"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from . import defaults
from .geometry import LocalGeometry
from .register import Registration, register, touch_geometry
from .touch import TouchData

__all__ = ["Recognition", "recognize"]


@dataclass(frozen=True)
class Recognition:
    """The models ranked by how well the touch data superpose onto them.

    Attributes
    ----------
    touch : TouchData
        The touch data recognised.
    geometry : LocalGeometry
        The local geometry estimated at the contact (touch frame), shared by all models.
    ranking : tuple of Registration
        Every model, least error first; models rejected by the table lookup last.
    seconds : float
        Wall time of the whole recognition.
    """

    touch: TouchData
    geometry: LocalGeometry
    ranking: tuple[Registration, ...]
    seconds: float

    @property
    def best(self) -> Registration | None:
        """The recognised model's registration, or None if every model was rejected."""
        if not self.ranking or self.ranking[0].rejected:
            return None
        return self.ranking[0]

    def __repr__(self) -> str:
        best = self.best.model if self.best is not None else None
        return (
            f"Recognition(best={best!r}, models={len(self.ranking)}, "
            f"K={self.geometry.K:.4g}, H={self.geometry.H:.4g}, seconds={self.seconds:.3f})"
        )


def recognize(
    touch: TouchData,
    library,
    method: str = defaults.SEARCH_METHOD,
    progress: Callable[[int, int, str], None] | None = None,
) -> Recognition:
    """Recognise which model of ``library`` the touch data came from, and where.

    Parameters
    ----------
    touch : TouchData
        The curves, in the touch frame.
    library : ModelLibrary or iterable of ModelIndex
        The candidate models.
    method : {"lm", "steepest"}
        The local-search optimiser.
    progress : callable, optional
        Called as ``progress(i, n, name)`` before each model is registered.

    Returns
    -------
    Recognition

    Raises
    ------
    ValueError
        If the library is empty, ``method`` is unknown, or the curves do not allow an
        estimate of the local geometry.
    """
    t0 = time.perf_counter()
    models = list(library)
    if not models:
        raise ValueError("library must hold at least one model, got none")
    geometry = touch_geometry(touch)
    results = []
    for i, model in enumerate(models):
        if progress is not None:
            progress(i, len(models), model.name)
        results.append(register(touch, model, geometry=geometry, method=method))
    results.sort(key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model))
    return Recognition(
        touch=touch, geometry=geometry, ranking=tuple(results), seconds=time.perf_counter() - t0
    )
