"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from meshrec import defaults
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_choice, check_instance
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.recognition.units import check_units
from meshrec.registration.register import Registration, register, touch_geometry
from meshrec.registration.search import SEARCH_METHODS

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
        Every model, least error first (ties: by name); models rejected by the table
        lookup last. Each model is registered independently of the others, so the
        ranking does not depend on the order of the models.
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
    TypeError
        If ``touch`` is not a TouchData, ``library`` not an iterable of ModelIndex,
        ``method`` not a
        string, ``geometry`` not a LocalGeometry or ``progress`` not callable (the shared
        checks of :mod:`meshrec.io.checks`).
    ValueError
        If the library is empty, ``method`` is unknown, the touch's size is out of all
        proportion to every model's (a likely unit mismatch, see
        :func:`meshrec.recognition.units.check_units`), or
        the curves do not allow an estimate of the local geometry.
    """
    t0 = time.perf_counter()
    check_instance(touch, TouchData, "touch")
    check_choice(method, SEARCH_METHODS, "method")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be callable or None, got {type(progress).__name__}")
    if isinstance(library, (str, bytes)) or not hasattr(library, "__iter__"):
        raise TypeError(
            f"library must be a ModelLibrary or an iterable of ModelIndex, got "
            f"{type(library).__name__}"
        )
    models = list(library)
    for i, model in enumerate(models):
        check_instance(model, ModelIndex, f"library[{i}]")
    if not models:
        raise ValueError("library must hold at least one model, got none")
    check_units(touch, models)
    if geometry is None:
        geometry = touch_geometry(touch)
    # Every model is registered on its own (the result of one never depends on another),
    # so the order of the models, or running them apart, changes nothing.
    results = []
    for i, model in enumerate(models):
        if progress is not None:
            progress(i, len(models), model.name)
        results.append(register(touch, model, geometry=geometry, method=method))
    results.sort(key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model))
    return Recognition(
        touch=touch, geometry=geometry, ranking=tuple(results), seconds=time.perf_counter() - t0
    )
