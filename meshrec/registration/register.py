"""Registration of touch data onto one model: the paper's Section 2.3 on a mesh.

:func:`register` composes the stages, each a public function of its own module: the
(K, H) lookup for candidate contacts (:mod:`~meshrec.registration.lookup`), the error
against phi and its brackets (:mod:`~meshrec.registration.brackets`), the screening
(:mod:`~meshrec.registration.screening`), the local searches on surface charts
(:mod:`~meshrec.registration.searching`) and the rigid refinement into pose hypotheses
(:mod:`~meshrec.registration.poses`). With ``trace=True`` it keeps every stage's output.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry, RoughFitWarning, estimate_local_geometry
from meshrec.io.checks import (
    check_choice,
    check_instance,
    check_int,
    check_number,
    check_transform,
)
from meshrec.io.touch import TouchData
from meshrec.model.index import ModelIndex
from meshrec.registration.brackets import PhiBrackets, phi_brackets, refine_phis
from meshrec.registration.lookup import ContactCandidates, lookup_candidates
from meshrec.registration.poses import (
    PoseHypothesis,
    distinct_poses,
    pose_hypotheses,
    refine_searches,
    refined_pose,
)
from meshrec.registration.refine import refine_rigid
from meshrec.registration.screening import Screening, screen_candidates
from meshrec.registration.search import SEARCH_METHODS
from meshrec.registration.searching import search_candidates
from meshrec.registration.trace import RegistrationTrace

__all__ = [
    "CoarseRegistration",
    "Registration",
    "StageTimes",
    "refine_pose",
    "register",
    "register_coarse",
    "register_full",
    "touch_geometry",
]


@dataclass(frozen=True)
class StageTimes:
    """Seconds spent in each stage of one registration."""

    lookup: float = 0.0
    phi: float = 0.0
    screen: float = 0.0
    search: float = 0.0
    refine: float = 0.0

    def __add__(self, other: StageTimes) -> StageTimes:
        return StageTimes(
            self.lookup + other.lookup,
            self.phi + other.phi,
            self.screen + other.screen,
            self.search + other.search,
            self.refine + other.refine,
        )


@dataclass(frozen=True, eq=False)
class Registration(ValueEquality):
    """The best superposition of the touch data on one model.

    Attributes
    ----------
    model : str
        Model name (file stem).
    path : str
        Model file.
    error : float or None
        Mean unsigned point-to-surface distance per data point, model units (the paper's
        Table 4 measure); None when the model had no candidates. The surface is the
        model's smooth surface: its flat faces bulged by the heights their corner normals
        imply (:mod:`meshrec.registration.objective`), within the mesh's chord error of
        its faces (on a coarse export, points lying on the flat faces are that far off).
    contact : (3,) float or None
        The estimated contact p* on the model, model coordinates.
    normal : (3,) float or None
        The model's outward (face-winding) unit normal at ``contact``.
    phi : float or None
        Rotation of ``T_model_touch`` about ``normal``, radians in [0, 2 pi): the angle
        from the first axis of the chart frame at ``contact`` (the local search's frame
        carried there) to the data frame's first axis placed by ``T_model_touch``
        (see :class:`~meshrec.registration.poses.PoseHypothesis`); None when no chart
        was used.
    T_model_touch : (4, 4) float or None
        Maps touch-frame points to model coordinates.
    candidates : int
        Candidate points tried (after spreading), both sides together.
    raw_hits : int
        Vertices matching the curvature lookup before spreading.
    searches : int
        Local searches run.
    seconds : float
        Wall time of this registration.
    times : StageTimes
        Wall time per stage.
    reason : str
        Why the model was rejected ("" when it was not).
    candidate_points : (c, 3) float
        The candidate points, model coordinates.
    search_paths : tuple of (k, 3) float
        The contact's path in each local search, model coordinates.
    rms : float or None
        Root-mean-square point-to-surface distance at ``T_model_touch`` (the objective
        the refinement minimises, by which the pose was chosen), model units; to the
        smooth surface, as ``error``.
    n_points : int
        Data points in ``error`` and ``rms`` (0 when rejected).
    poses : tuple of PoseHypothesis
        The distinct refined poses, least ``rms`` first; the first is the one reported.
    trace : RegistrationTrace or None
        Every stage's output, with ``register(..., trace=True)``; None otherwise.
    pruned : bool
        The recognition's cascade stopped this model after the screening (its best
        conceivable fit was far worse than the leaders'): the pose is the best screened
        candidate's, refined on all the points, not a local search's
        (:mod:`meshrec.registration.cascade`).
    """

    model: str
    path: str
    error: float | None
    contact: np.ndarray | None
    normal: np.ndarray | None
    phi: float | None
    T_model_touch: np.ndarray | None
    candidates: int
    raw_hits: int
    searches: int
    seconds: float = field(compare=False)
    times: StageTimes = field(default_factory=StageTimes, compare=False)
    reason: str = ""
    candidate_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)), repr=False)
    search_paths: tuple[np.ndarray, ...] = field(default=(), repr=False)
    rms: float | None = None
    n_points: int = 0
    poses: tuple[PoseHypothesis, ...] = field(default=(), repr=False)
    trace: RegistrationTrace | None = field(default=None, repr=False)
    pruned: bool = False

    @property
    def rejected(self) -> bool:
        """True when the table lookup found no candidate on this model (or every pose
        found put the touch through the surface, against its given normal: ``reason``)."""
        return self.error is None

    def __repr__(self) -> str:
        if self.rejected:
            return f"Registration({self.model!r}, rejected: {self.reason})"
        c = np.round(self.contact, 6).tolist()
        return (
            f"Registration({self.model!r}, error={self.error:.6g}, rms={self.rms:.6g}, "
            f"contact={c}, "
            f"candidates={self.candidates}, searches={self.searches}, "
            f"seconds={self.seconds:.3f})"
        )


def touch_geometry(touch: TouchData) -> LocalGeometry:
    """Estimate the local geometry at the touch's contact (given or found).

    Parameters
    ----------
    touch : TouchData

    Returns
    -------
    LocalGeometry

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData.
    ValueError
        If the curves do not allow an estimate (see
        :func:`meshrec.contact.geometry.estimate_local_geometry`).

    Warns
    -----
    RoughFitWarning
        If the curve fits leave more than ``defaults.ROUGH_FIT_RATIO`` times the noise
        that the samples show (and more than ``defaults.ROUGH_FIT_MIN_FRACTION`` of the
        half-length): the curves may cross an edge or a rim, where the recognition is
        less reliable; where they turn by more than ``defaults.ROUGH_FIT_LONG_TURN``
        radians over their half-length at the estimated curvature, it also says they may
        be long for the surface's bend.
    """
    check_instance(touch, TouchData, "touch")
    g = estimate_local_geometry(touch.curves, point=touch.contact, normal=touch.normal)
    ratio = g.fit_to_noise
    if ratio > defaults.ROUGH_FIT_RATIO and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * (
        g.half_length
    ):
        turn = max(abs(float(g.k1)), abs(float(g.k2))) * float(g.half_length)
        long = (
            f", or they are long for the surface's bend (at the curvature estimated they "
            f"turn by {turn:.3g} radians over their half-length: shorter curves fit better)"
            if turn > defaults.ROUGH_FIT_LONG_TURN
            else ""
        )
        warnings.warn(
            f"the curves fit no smooth surface patch: the curve fits leave {g.fit_rms:.3g}, "
            f"{ratio:.3g} times the noise the samples show ({g.noise_rms:.3g}; "
            f"defaults.ROUGH_FIT_RATIO = {defaults.ROUGH_FIT_RATIO:g}): they may cross an "
            f"edge or a rim{long}, where the curvature estimate and the recognition are less "
            "reliable; touch again away from edges",
            RoughFitWarning,
            stacklevel=3,
        )
    return g


def _stage_inputs(method, max_candidates, searches, lookup_scale) -> None:
    check_choice(method, SEARCH_METHODS, "method")
    check_int(max_candidates, "max_candidates", minimum=1)
    check_int(searches, "searches", minimum=1)
    check_number(lookup_scale, "lookup_scale", positive=True)


class _Clock:
    """Seconds per stage, accumulated."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._t
        self._t = now


def register(
    touch: TouchData,
    model,
    geometry: LocalGeometry | None = None,
    method: str = defaults.SEARCH_METHOD,
    max_candidates: int = defaults.MAX_CANDIDATES,
    searches: int = defaults.LOCAL_SEARCHES,
    trace: bool = False,
    lookup_scale: float = 1.0,
) -> Registration:
    """Register touch data onto one model: the stages of the paper's Section 2, in turn.

    1. :func:`~meshrec.registration.lookup.lookup_candidates`: candidate contacts from
       the (K, H) lookup, on each side of the surface;
    2. :func:`~meshrec.registration.brackets.phi_brackets`: the error against phi at every
       candidate, its brackets, the candidates ranked;
    3. :func:`~meshrec.registration.screening.screen_candidates`: a few rigid steps rank
       the best of them better;
    4. :func:`~meshrec.registration.brackets.refine_phis`: the brackets of the best
       ``searches`` screened candidates refined;
    5. :func:`~meshrec.registration.searching.search_candidates`: local searches on
       surface charts from them;
    6. :func:`~meshrec.registration.poses.refine_searches`: rigid refinement of the best
       searches on all points, and the distinct pose hypotheses, least RMS first.

    The result depends on this model and the touch only (not on any other model).

    Parameters
    ----------
    touch : TouchData
        The curves (touch frame) with optional contact and normal hints.
    model : ModelIndex
        The model, with its curvature table and distance tree.
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (``recognize`` shares
        one estimate across models).
    method : {"lm", "steepest"}
        The local-search optimiser (see :func:`meshrec.registration.search.local_search`).
    max_candidates : int
        Most candidates per side after spreading.
    searches : int
        Local searches run at most, on the candidates with the least error after the
        screening.
    trace : bool
        Keep every stage's output in ``Registration.trace``.
    lookup_scale : float
        Factor widening the (K, H) lookup window (1: as calibrated).

    Returns
    -------
    Registration
        With ``trace`` a :class:`~meshrec.registration.trace.RegistrationTrace` when
        ``trace`` is true, None otherwise.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``model`` not a ModelIndex, ``geometry`` not a
        LocalGeometry, ``method`` not a string, ``max_candidates`` or ``searches`` not an
        integer, ``lookup_scale`` not a real number (the shared checks of
        :mod:`meshrec.io.checks`), or ``trace`` not a bool.
    ValueError
        If ``method`` is unknown, ``max_candidates`` or ``searches`` is less than 1,
        ``lookup_scale`` is not a positive finite number, or the local geometry cannot be
        estimated from the curves.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    _stage_inputs(method, max_candidates, searches, lookup_scale)
    if not isinstance(trace, (bool, np.bool_)):
        raise TypeError(f"trace must be a bool, got {type(trace).__name__}")
    coarse = register_coarse(
        touch, model, geometry, max_candidates=max_candidates, lookup_scale=lookup_scale
    )
    return register_full(model, coarse, method=method, searches=searches, trace=trace)


@dataclass(frozen=True, eq=False)
class CoarseRegistration(ValueEquality):
    """The first stages of a registration (lookup, phi, screening) on one model.

    Attributes
    ----------
    model : str
        Model name.
    candidates : ContactCandidates
    brackets : PhiBrackets or None
        None when the lookup found no candidate.
    screening : Screening or None
        None when the lookup found no candidate.
    seconds : float
        Wall time of these stages (with the local geometry when it was estimated here).
    times : dict
        Seconds per stage so far (``lookup``, ``phi``, ``screen``).
    """

    model: str
    candidates: ContactCandidates = field(repr=False)
    brackets: PhiBrackets | None = field(default=None, repr=False)
    screening: Screening | None = field(default=None, repr=False)
    seconds: float = field(default=0.0, compare=False)
    times: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def rejected(self) -> bool:
        """True when the table lookup found no candidate on this model."""
        return self.screening is None

    @property
    def screened_error(self) -> float | None:
        """The least screened error (mean distance of the phi subsample after the
        screening steps, model units); None when rejected."""
        return None if self.screening is None else float(self.screening.errors[0])


def register_coarse(
    touch: TouchData,
    model,
    geometry: LocalGeometry | None = None,
    max_candidates: int = defaults.MAX_CANDIDATES,
    lookup_scale: float = 1.0,
) -> CoarseRegistration:
    """Stages 1 to 3 of :func:`register`: lookup, phi brackets, screening.

    Parameters
    ----------
    touch, model, geometry, max_candidates, lookup_scale
        As for :func:`register`.

    Returns
    -------
    CoarseRegistration
        Continue it with :func:`register_full`.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``model`` not a ModelIndex or ``geometry`` not a
        LocalGeometry.
    ValueError
        If ``max_candidates`` is less than 1, ``lookup_scale`` is not a positive finite
        number, or the local geometry cannot be estimated from the curves.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    check_int(max_candidates, "max_candidates", minimum=1)
    check_number(lookup_scale, "lookup_scale", positive=True)
    t_start = time.perf_counter()
    if geometry is None:
        geometry = touch_geometry(touch)
    clock = _Clock()
    cands = lookup_candidates(
        touch, model, geometry, max_candidates=max_candidates, lookup_scale=lookup_scale
    )
    clock.lap("lookup")
    if len(cands) == 0:
        return CoarseRegistration(
            model.name, cands, seconds=time.perf_counter() - t_start, times=clock.seconds
        )
    brackets = phi_brackets(model, cands)
    clock.lap("phi")
    screening = screen_candidates(model, cands, brackets)
    clock.lap("screen")
    return CoarseRegistration(
        model.name,
        cands,
        brackets,
        screening,
        seconds=time.perf_counter() - t_start,
        times=clock.seconds,
    )


def register_full(
    model,
    coarse: CoarseRegistration,
    method: str = defaults.SEARCH_METHOD,
    searches: int = defaults.LOCAL_SEARCHES,
    trace: bool = False,
) -> Registration:
    """Stages 4 to 6 of :func:`register` from its first stages: the same Registration.

    Parameters
    ----------
    model : ModelIndex
        The model ``coarse`` was computed on.
    coarse : CoarseRegistration
        From :func:`register_coarse`.
    method, searches, trace
        As for :func:`register`.

    Returns
    -------
    Registration

    Raises
    ------
    TypeError
        If ``model`` is not a ModelIndex or ``coarse`` not a CoarseRegistration.
    ValueError
        If ``coarse`` is of another model, ``method`` is unknown or ``searches`` is less
        than 1.
    """
    check_instance(model, ModelIndex, "model")
    check_instance(coarse, CoarseRegistration, "coarse")
    if coarse.model != model.name:
        raise ValueError(f"coarse must be of model {model.name!r}, got {coarse.model!r}")
    check_choice(method, SEARCH_METHODS, "method")
    check_int(searches, "searches", minimum=1)
    t_start = time.perf_counter()
    clock = _Clock()
    clock.seconds = dict(coarse.times)
    cands = coarse.candidates
    if coarse.rejected:
        stages = RegistrationTrace(candidates=cands)
        return _registration(model, stages, trace, coarse.seconds, clock)
    brackets, screening = coarse.brackets, coarse.screening
    chosen = screening.candidates[:searches]
    # Exact rows only in a trace (pictures); the angles are the same either way.
    phis = refine_phis(model, cands, brackets, chosen, complete=trace)
    clock.lap("phi")
    starts = [(i, p.phi) for i, p in zip(chosen, phis, strict=True)]
    runs = search_candidates(model, cands, starts, method=method)
    clock.lap("search")
    refined = refine_searches(model, cands, runs)
    hypotheses = pose_hypotheses(model, cands, runs, refined)
    clock.lap("refine")
    stages = RegistrationTrace(cands, brackets, screening, phis, runs, refined, hypotheses)
    seconds = coarse.seconds + time.perf_counter() - t_start
    return _registration(model, stages, trace, seconds, clock)


def _rejected(reason: str, common: dict, candidates=0, raw_hits=0, searches=0):
    """A rejected Registration (no pose on this model) and why."""
    return Registration(
        error=None,
        contact=None,
        normal=None,
        phi=None,
        T_model_touch=None,
        candidates=candidates,
        raw_hits=raw_hits,
        searches=searches,
        reason=reason,
        **common,
    )


def _registration(model, stages: RegistrationTrace, trace: bool, seconds: float, clock):
    """The Registration the stages' outputs make (the best distinct pose reported)."""
    cands = stages.candidates
    common = dict(
        model=model.name,
        path=str(model.path),
        seconds=seconds,
        times=StageTimes(**clock.seconds),
        trace=stages if trace else None,
    )
    if len(cands) == 0:
        g = cands.geometry
        return _rejected(
            f"no surface site with K={g.K:.4g}, |H|={abs(g.H):.4g} within the lookup tolerance",
            common,
        )
    poses = distinct_poses(stages.hypotheses, float(cands.geometry.half_length))
    if not poses:
        # every refined pose carried the data through the surface, against the side
        # given (meshrec.registration.poses.pose_hypotheses): no placement on this model
        return _rejected(
            "every pose found put the touch through the surface, against its given normal "
            "(the data fit the far side of a thin wall better)",
            common,
            candidates=len(cands),
            raw_hits=cands.raw_hits,
            searches=len(stages.searches.runs),
        )
    best = poses[0]
    return Registration(
        error=best.error,
        contact=best.contact,
        normal=best.normal,
        phi=best.phi,
        T_model_touch=best.T_model_touch,
        candidates=len(cands),
        raw_hits=cands.raw_hits,
        searches=len(stages.searches.runs),
        candidate_points=cands.model_points,
        search_paths=tuple(r.result.path for r in stages.searches.runs),
        rms=best.rms,
        n_points=len(cands.points),
        poses=poses,
        **common,
    )


def refine_pose(
    touch: TouchData,
    model,
    T_model_touch: np.ndarray,
    geometry: LocalGeometry | None = None,
) -> Registration:
    """Register touch data onto one model starting from a known pose.

    Runs only the final rigid refinement of :func:`register` (all six degrees of freedom)
    from ``T_model_touch``: the nearest minimum of the same error. Use it when a pose is
    already approximately known (tracking a touched object between touches), and as the
    benchmarks' oracle: started at the true pose, its error is the floor the noise leaves.

    Parameters
    ----------
    touch : TouchData
        The curves, in the touch frame.
    model : ModelIndex
        The model.
    T_model_touch : (4, 4) float
        The starting pose, mapping touch-frame points to model coordinates.
    geometry : LocalGeometry, optional
        The local geometry at the contact, if already estimated (its point locates the
        contact on the model).

    Returns
    -------
    Registration
        With ``candidates`` and ``searches`` zero; ``phi`` is None (no chart was used);
        ``poses`` holds the one refined pose.

    Raises
    ------
    TypeError
        If ``touch`` is not a TouchData, ``model`` not a ModelIndex, ``geometry`` not a
        LocalGeometry, or ``T_model_touch`` not real numbers (complex, say).
    ValueError
        If ``T_model_touch`` is not a finite (4, 4) rigid transform, or the local geometry
        cannot be estimated from the curves.
    """
    check_instance(touch, TouchData, "touch")
    check_instance(model, ModelIndex, "model")
    check_instance(geometry, LocalGeometry, "geometry", optional=True)
    T0 = check_transform(T_model_touch, "T_model_touch", rigid=True)
    t_start = time.perf_counter()
    if geometry is None:
        geometry = touch_geometry(touch)
    t0 = time.perf_counter()
    ref = refine_rigid(model, touch.points, T0)
    t_refine = time.perf_counter() - t0
    pose = refined_pose(model, ref, geometry.point)
    return Registration(
        model=model.name,
        path=str(model.path),
        error=pose.error,
        contact=pose.contact,
        normal=pose.normal,
        phi=None,
        T_model_touch=ref.T_model_touch,
        candidates=0,
        raw_hits=0,
        searches=0,
        seconds=time.perf_counter() - t_start,
        times=StageTimes(refine=t_refine),
        rms=pose.rms,
        n_points=len(touch.points),
        poses=(pose,),
    )
