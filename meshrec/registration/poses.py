"""Stage 6 of a registration: rigid refinement of the searches, and the pose hypotheses.

The best local-search results (by their subsample error, ``defaults.REFINE_BEST``) are
refined rigidly on all the data points (see :func:`meshrec.registration.refine.refine_rigid`).
Each refined pose is a hypothesis; ranked by the optimiser's own objective (the RMS
point-to-surface distance), the distinct ones are kept: a pose whose contact is within
``defaults.POSE_DUPLICATE_FRACTION`` of the curves' half-length of a better one's and
whose rotation is within ``defaults.POSE_DUPLICATE_ANGLE_DEG`` of it is the same minimum.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_instance, check_number, check_vector
from meshrec.model.index import ModelIndex
from meshrec.registration.batch import refine_rigid_batch
from meshrec.registration.chart import tangent_frame
from meshrec.registration.lookup import ContactCandidates, surface_sides
from meshrec.registration.refine import Refinement
from meshrec.registration.searching import Searches
from meshrec.registration.transform import apply_transform, superposition

__all__ = [
    "PoseHypothesis",
    "RefinedSearch",
    "distinct_poses",
    "keeps_side",
    "pose_hypotheses",
    "refine_searches",
    "refined_pose",
]


def _items(values, cls: type, name: str) -> list:
    """``values`` as a list, each item checked to be a ``cls``.

    Raises
    ------
    TypeError
        If ``values`` is not an iterable (or is a string), or an item is not a ``cls``:
        the message names ``name`` (and the item's index).
    """
    if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
        raise TypeError(f"{name} must be a sequence of {cls.__name__}, got {type(values).__name__}")
    return [check_instance(v, cls, f"{name}[{k}]") for k, v in enumerate(values)]


@dataclass(frozen=True, eq=False)
class RefinedSearch(ValueEquality):
    """The rigid refinement of one local search's result.

    Attributes
    ----------
    run : int
        Index of the search in ``Searches.runs``.
    refinement : Refinement
        The refined pose and its errors on all the data points.
    """

    run: int
    refinement: Refinement = field(repr=False)


@dataclass(frozen=True, eq=False)
class PoseHypothesis(ValueEquality):
    """One refined pose of the touch on the model.

    Attributes
    ----------
    T_model_touch : (4, 4) float
        Maps touch-frame points to model coordinates.
    error : float
        Mean unsigned point-to-surface distance of all the data points, model units.
    rms : float
        Root-mean-square point-to-surface distance (the refinement's objective).
    contact : (3,) float
        The contact on the model: the closest surface point to the data's common point
        placed by ``T_model_touch``, model coordinates.
    normal : (3,) float
        The model's outward (face-winding) unit normal at ``contact``.
    phi : float or None
        Rotation of the pose about ``normal``, radians in [0, 2 pi): the angle from the
        first axis of the contact's chart frame (the search's chart frame carried to
        ``contact``) to the data frame's first axis placed by ``T_model_touch``, in the
        tangent plane; None for a pose refined from a given one (no chart).
    run : int or None
        Index of the local search it came from, in ``Searches.runs`` (None: no search).
    """

    T_model_touch: np.ndarray = field(repr=False)
    error: float
    rms: float
    contact: np.ndarray
    normal: np.ndarray = field(repr=False)
    phi: float | None
    run: int | None


def refined_pose(model, refinement: Refinement, point: np.ndarray) -> PoseHypothesis:
    """A pose refined from a given one (no chart), as a hypothesis.

    Parameters
    ----------
    model : ModelIndex
    refinement : Refinement
        From :func:`meshrec.registration.refine.refine_rigid`.
    point : (3,) float
        The data's common point, touch frame: placed by the pose, its closest surface
        point is the hypothesis's ``contact``.

    Returns
    -------
    PoseHypothesis
        With ``phi`` and ``run`` None.

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``refinement`` not a Refinement, or ``point``
        not real numbers.
    ValueError
        If ``point`` is not a finite (3,) vector.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(refinement, Refinement, "refinement")
    point = check_vector(point, "point")
    guess = apply_transform(refinement.T_model_touch, point[None, :])
    _, closest, face = model.surface.closest_points(guess)
    return PoseHypothesis(
        T_model_touch=refinement.T_model_touch,
        error=float(refinement.error),
        rms=float(refinement.rms),
        contact=closest[0],
        normal=model.surface.interpolated_normals(closest, face)[0],
        phi=None,
        run=None,
    )


def refine_searches(
    model,
    candidates: ContactCandidates,
    searches: Searches,
    *,
    best: int = defaults.REFINE_BEST,
) -> tuple[RefinedSearch, ...]:
    """Refine the best ``best`` local-search results rigidly on all the data points.

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
    searches : Searches
        From :func:`meshrec.registration.searching.search_candidates`.
    best : int
        Results refined, least subsample error first (ties: the earlier search).

    Returns
    -------
    tuple of RefinedSearch
        In the order refined (least search error first).

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``candidates`` not a ContactCandidates or
        ``searches`` not a Searches.
    ValueError
        If ``best`` is not a positive integer.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    check_instance(searches, Searches, "searches")
    if not isinstance(best, (int, np.integer)) or isinstance(best, bool) or best < 1:
        raise ValueError(f"best must be a positive integer, got {best!r}")
    order = sorted(range(len(searches.runs)), key=lambda k: searches.runs[k].result.error)
    chosen, starts = order[:best], []
    for k in chosen:
        run = searches.runs[k]
        side = candidates.sides[candidates.side[run.candidate]]
        starts.append(superposition(side.point, side.frame, run.result.surface, run.result.phi))
    if not starts:
        return ()
    # In lockstep (one distance query per round; the same results as refine_rigid each).
    refined = refine_rigid_batch(model, candidates.points, np.array(starts))
    return tuple(RefinedSearch(run=k, refinement=r) for k, r in zip(chosen, refined, strict=True))


def pose_hypotheses(
    model,
    candidates: ContactCandidates,
    searches: Searches,
    refined: Sequence[RefinedSearch],
) -> tuple[PoseHypothesis, ...]:
    """Every refined pose as a hypothesis, least RMS distance first (stable).

    Parameters
    ----------
    model : ModelIndex
    candidates : ContactCandidates
    searches : Searches
    refined : sequence of RefinedSearch
        From :func:`refine_searches`.

    Returns
    -------
    tuple of PoseHypothesis
        One per refined search (duplicates included; see :func:`distinct_poses`), but
        for those that put the touch on the wrong side of the surface: where the side is
        known (``candidates.sides`` holds one: a normal given with the touch on a closed
        model, or the one side a ball tip can trace), a refinement that carried the data
        through the surface (a thin wall: the touch's normal, placed, then points into
        the material, more than ``defaults.POSE_SIDE_MIN_COS`` against the surface's)
        is no placement of the touch. Empty when every one did.

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex, ``candidates`` not a ContactCandidates,
        ``searches`` not a Searches, or ``refined`` not a sequence of RefinedSearch.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(candidates, ContactCandidates, "candidates")
    check_instance(searches, Searches, "searches")
    refined = _items(refined, RefinedSearch, "refined")
    out = []
    known_side = len(candidates.sides) == 1
    for r in refined:
        run = searches.runs[r.run]
        side = candidates.sides[candidates.side[run.candidate]]
        T = r.refinement.T_model_touch
        closest, normal = _placed_contact(model, T, candidates.geometry.point)
        if known_side and not _keeps_side(T, side, normal):
            # Through the surface: a probe (stop 34) touched a 1 mm-walled tube's inside,
            # normal given, and the refinement carried the data from the inner wall to
            # the outer one, where the tube was then scored (and a ball tip suggested).
            continue
        frame = tangent_frame(normal, hint=run.result.surface.frame[:, 0])
        placed_x = T[:3, :3] @ side.frame[:, 0]
        phi = float(np.arctan2(placed_x @ frame[:, 1], placed_x @ frame[:, 0]) % (2.0 * np.pi))
        out.append(
            PoseHypothesis(
                T_model_touch=T,
                error=float(r.refinement.error),
                rms=float(r.refinement.rms),
                contact=closest[0],
                normal=normal,
                phi=phi,
                run=r.run,
            )
        )
    out.sort(key=lambda p: p.rms)
    return tuple(out)


def _same_pose(a: PoseHypothesis, b: PoseHypothesis, distance: float, angle: float) -> bool:
    if np.linalg.norm(a.contact - b.contact) > distance:
        return False
    R = a.T_model_touch[:3, :3].T @ b.T_model_touch[:3, :3]
    cos = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    return bool(np.arccos(cos) <= angle)


def distinct_poses(
    hypotheses: Sequence[PoseHypothesis],
    half_length: float,
    *,
    distance_fraction: float = defaults.POSE_DUPLICATE_FRACTION,
    angle_deg: float = defaults.POSE_DUPLICATE_ANGLE_DEG,
) -> tuple[PoseHypothesis, ...]:
    """Drop the hypotheses that repeat a better one (the same minimum found twice).

    Parameters
    ----------
    hypotheses : sequence of PoseHypothesis
        Best first.
    half_length : float
        The curves' half-length (sets the contact tolerance).
    distance_fraction : float
        Contacts closer than this fraction of ``half_length`` may be the same minimum ...
    angle_deg : float
        ... if their rotations also differ by at most this angle, degrees.

    Returns
    -------
    tuple of PoseHypothesis
        The first of each group of duplicates, in the given order.

    Raises
    ------
    TypeError
        If ``hypotheses`` is not a sequence of PoseHypothesis, or ``half_length``,
        ``distance_fraction`` or ``angle_deg`` is not a real number.
    ValueError
        If ``half_length`` is not positive and finite, or a tolerance is negative or not
        finite.
    """
    hypotheses = _items(hypotheses, PoseHypothesis, "hypotheses")
    half_length = check_number(half_length, "half_length")
    distance_fraction = check_number(distance_fraction, "distance_fraction")
    angle_deg = check_number(angle_deg, "angle_deg")
    if not half_length > 0:
        raise ValueError(f"half_length must be positive, got {half_length!r}")
    if not (distance_fraction >= 0 and angle_deg >= 0):
        raise ValueError(
            f"distance_fraction and angle_deg must be >= 0, got {distance_fraction!r}, "
            f"{angle_deg!r}"
        )
    distance = distance_fraction * half_length
    angle = np.deg2rad(angle_deg)
    kept: list[PoseHypothesis] = []
    for h in hypotheses:
        if not any(_same_pose(k, h, distance, angle) for k in kept):
            kept.append(h)
    return tuple(kept)


def keeps_side(model, touch, geometry, T_model_touch: np.ndarray) -> bool:
    """Whether the pose leaves the touch on its own side of the surface.

    Where the side is known (:func:`~meshrec.registration.lookup.surface_sides` holds
    one: a normal given with the touch on a closed model, or the one side a ball tip can
    trace), a pose whose placed touch normal meets the surface's normal at the placed
    contact below ``defaults.POSE_SIDE_MIN_COS`` carried the data through the surface (a
    thin wall) and is no placement of the touch. True where the side is not known.
    Every source of poses applies it: the registration's own
    (:func:`pose_hypotheses`), and those refined again before a model is named.

    Parameters
    ----------
    model : ModelIndex
    touch : TouchData
    geometry : LocalGeometry
        The touch's local geometry.
    T_model_touch : (4, 4) float

    Returns
    -------
    bool
    """
    if touch.normal is not None and float(geometry.normal @ touch.normal) < 0.0:
        geometry = geometry.flipped()  # the side the given normal says
    sides = surface_sides(geometry, touch, model)
    if len(sides) != 1:
        return True
    T = np.asarray(T_model_touch, dtype=np.float64)
    _, normal = _placed_contact(model, T, geometry.point)
    return _keeps_side(T, sides[0], normal)


def _placed_contact(model, T: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The surface point nearest the placed contact, and the surface's normal there."""
    guess = apply_transform(T, np.asarray(point, dtype=np.float64)[None, :])
    _, closest, face = model.surface.closest_points(guess)
    return closest, model.surface.interpolated_normals(closest, face)[0]


def _keeps_side(T: np.ndarray, side, normal: np.ndarray) -> bool:
    return float(normal @ (T[:3, :3] @ side.frame[:, 2])) >= defaults.POSE_SIDE_MIN_COS
