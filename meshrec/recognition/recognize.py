"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.recognition.units import check_units
from meshrec.registration.register import Registration, register, touch_geometry

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
    geometry: LocalGeometry | None = None,
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
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (by
        :func:`meshrec.registration.register.touch_geometry`); estimated here otherwise.

    Returns
    -------
    Recognition

    Raises
    ------
    ValueError
        If the library is empty, ``method`` is unknown, the touch's size is out of all
        proportion to every model's (a likely unit mismatch, see
        :func:`meshrec.recognition.units.check_units`), or
        the curves do not allow an estimate of the local geometry.
    """
    t0 = time.perf_counter()
    models = list(library)
    if not models:
        raise ValueError("library must hold at least one model, got none")
    check_units(touch, models)
    if geometry is None:
        geometry = touch_geometry(touch)
    results = []
    for i, model in enumerate(models):
        if progress is not None:
            progress(i, len(models), model.name)
        # The best error so far lets a model that cannot win stop its searches early.
        done = [r.error for r in results if r.error is not None]
        rival = min(done) if done else None
        results.append(
            register(touch, model, geometry=geometry, method=method, rival_error=rival)
        )
    results.sort(key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model))
    return Recognition(
        touch=touch, geometry=geometry, ranking=tuple(results), seconds=time.perf_counter() - t0
    )
