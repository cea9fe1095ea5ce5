"""Recognition: register the touch data on every model and rank them (Section 2.4)."""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.checks import check_choice, check_instance
from meshrec.io.touch import RepeatedSamplesWarning, TouchData
from meshrec.model.index import ModelIndex
from meshrec.model.probe import probe_model
from meshrec.model.resolution import ResolutionWarning, coarse_message
from meshrec.recognition.bestfirst import fit_best_first
from meshrec.recognition.cascade import cascade_register
from meshrec.recognition.edges import patches_crossed, warn_sharp_edges
from meshrec.recognition.flatness import flat_prior
from meshrec.recognition.freedom import (
    PoseFreedom,
    pose_freedom,
    pose_sigma,
    with_alternatives,
    with_symmetries,
)
from meshrec.recognition.joint import (
    check_touch_sizes,
    explore_weak_motions,
    first_touch_fit,
    joint_poses,
    log_likelihood_bound,
    pooled_noise,
    register_touches,
    rms_out_of_reach,
    search_pairs,
    transfer_poses,
    transferred_poses,
)
from meshrec.recognition.phases import PhaseTimes, phase_clock, timed
from meshrec.recognition.probing import (
    ProbeOffset,
    check_tip_fits,
    touch_probe_radius,
    warn_probe_offset,
)
from meshrec.recognition.scoring import (
    ModelScore,
    Verdict,
    WeightedPose,
    decide,
    fit_p_value,
    log_likelihoods,
    noise_estimate,
    pose_weights,
    posterior,
)
from meshrec.recognition.units import check_units
from meshrec.recognition.weak import weak_motion_starts
from meshrec.recognition.workers import ModelWorkers
from meshrec.registration.objective import residuals
from meshrec.registration.poses import distinct_poses
from meshrec.registration.register import Registration, touch_geometry
from meshrec.registration.search import SEARCH_METHODS
from meshrec.registration.transform import apply_transform

__all__ = ["Recognition", "recognize"]


@dataclass(frozen=True, eq=False)
class Recognition(ValueEquality):
    """The models ranked by how well the touch data superpose onto them.

    Attributes
    ----------
    touch : TouchData
        The touch data recognised.
    geometry : LocalGeometry
        The local geometry estimated at the contact (touch frame), shared by all models.
    ranking : tuple of Registration
        Every model, most probable first (then least error, then name); models rejected
        by the table lookup last. Each model is registered independently of the others, so
        the ranking does not depend on the order of the models.
    seconds : float
        Wall time of the whole recognition.
    verdict : str
        "recognised", "ambiguous" or "unknown" (see
        :func:`meshrec.recognition.scoring.decide`).
    plausible : tuple of str
        The models the data cannot rule out, best first: one when recognised, two or
        more when ambiguous (or one, when only it fits but its pose is free: see
        ``pose_freedom``; or when one touch, too noisy for its length
        (``defaults.SCORE_MAX_NOISE_FRACTION``) or across a sharp edge of that model,
        names none: see ``reason``), none when unknown.
    noise : float
        The noise the scores take (standard deviation, data units): the level estimated
        from the touches, with the error of the competing models' meshes added in
        quadrature where they scatter (:mod:`meshrec.model.roughness`).
    reason : str
        One sentence explaining the verdict.
    warnings : tuple of str
        Every warning raised while recognising, and the verdict's own cautions.
    scores : tuple of ModelScore
        The calibrated probability and weighted poses of each model, in ranking order.
    scoring_seconds : float
        Of ``seconds``, the time spent on the scores and the verdict (without a widened
        second lookup, which is counted in ``widened_seconds``).
    widened_seconds : float
        Time of the later passes: the widened lookup (when the first pass fit no model to
        the noise), the dense one after it, and the confirmation of a one-touch answer's
        search before it is ``recognised``; 0 when none ran.
    touches : tuple of TouchData
        Every touch recognised, in the order given (``touch`` is the first); all in one
        frame, the frame of every ``T_model_touch``.
    geometries : tuple of LocalGeometry
        The local geometry of each touch (``geometry`` is the first's).
    touch_rms : tuple of float or None
        RMS point-to-surface distance of each touch at the best model's reported pose,
        model units (None when no model was registered).
    probe_radius : float
        The probe's ball-tip radius the data were compared with the models for (0: a
        point probe): the contacts and poses are those of the surface, the distances
        those to the surface offset by it.
    pose_freedom : PoseFreedom or None
        The rigid motions the data leave free at the best model's reported pose
        (:func:`meshrec.recognition.freedom.pose_freedom`): a flat face leaves two slides
        and a turn, a cylinder's side a slide and a turn. None when no model was
        registered. When any motion is free that is not a symmetry of the model (a turn
        about a cylinder's axis is; a slide along it is not) the verdict is never
        ``recognised``: with one plausible model it is ``ambiguous`` with that model alone,
        and the reason says the model is named but the pose is not fixed. Distinct poses
        that fit about equally well (``pose_freedom.alternatives``) leave the verdict as
        it is, but ``pose_freedom.fixed`` is False and the reason says the pose is one of
        them: check ``fixed`` before acting on ``T_model_touch``.
    probe_offset : ProbeOffset or None
        The probe-offset check's evidence (:func:`meshrec.recognition.probing.probe_offset`
        at the best model's pose: the tip radius that best explains the data, the RMS
        without and with it, the linearised drop), whether it warned or not. None when
        the check did not run (a probe radius given or read from the touches, no model
        registered).
    phase_times : PhaseTimes
        CPU seconds of each phase of the recognition (``time.process_time``; see
        :class:`~meshrec.recognition.phases.PhaseTimes`). Not part of the equality of two
        recognitions (nor is anything about the answers in it).
    """

    touch: TouchData
    geometry: LocalGeometry
    ranking: tuple[Registration, ...]
    seconds: float = dataclasses.field(compare=False)
    verdict: str = "unknown"
    plausible: tuple[str, ...] = ()
    noise: float = float("nan")
    reason: str = ""
    warnings: tuple[str, ...] = ()
    scores: tuple[ModelScore, ...] = ()
    scoring_seconds: float = dataclasses.field(default=0.0, compare=False)
    widened_seconds: float = dataclasses.field(default=0.0, compare=False)
    touches: tuple[TouchData, ...] = ()
    geometries: tuple[LocalGeometry, ...] = ()
    touch_rms: tuple[float | None, ...] = ()
    probe_radius: float = 0.0
    pose_freedom: PoseFreedom | None = None
    probe_offset: ProbeOffset | None = None
    phase_times: PhaseTimes = dataclasses.field(default_factory=PhaseTimes, compare=False)

    @property
    def best(self) -> Registration | None:
        """The recognised model's registration, or None if every model was rejected."""
        if not self.ranking or self.ranking[0].rejected:
            return None
        return self.ranking[0]

    @property
    def probabilities(self) -> dict[str, float]:
        """Posterior probability of each model, by name (ranking order)."""
        return {s.model: s.probability for s in self.scores}

    def __repr__(self) -> str:
        best = self.best.model if self.best is not None else None
        return (
            f"Recognition(verdict={self.verdict!r}, best={best!r}, "
            f"plausible={list(self.plausible)}, models={len(self.ranking)}, "
            f"touches={max(len(self.touches), 1)}, "
            f"noise={self.noise:.3g}, K={self.geometry.K:.4g}, H={self.geometry.H:.4g}, "
            f"seconds={self.seconds:.3f})"
        )


def recognize(
    touch: TouchData | Sequence[TouchData],
    library,
    method: str = defaults.SEARCH_METHOD,
    progress: Callable[[int, int, str], None] | None = None,
    geometry: LocalGeometry | Sequence[LocalGeometry] | None = None,
    probe_radius: float | None = None,
    workers=None,
    scheduler: str | None = None,
    cascade: bool | None = None,
) -> Recognition:
    """Recognise which model of ``library`` the touch data came from, and where.

    Parameters
    ----------
    touch : TouchData or sequence of TouchData
        One touch, or several touches of one object that did not move between them, all
        in one frame (the robot's world frame, say). With several, each model is fitted
        at one rigid pose to all of them (:mod:`meshrec.recognition.joint`) and scored on
        all the data.
    library : ModelLibrary or iterable of ModelIndex
        The candidate models.
    method : {"lm", "steepest"}
        The local-search optimiser.
    progress : callable, optional
        Called as ``progress(i, n, name)`` before each model is registered.
    geometry : LocalGeometry or sequence of LocalGeometry, optional
        The local geometry at each touch's contact, if already estimated (by
        :func:`meshrec.registration.register.touch_geometry`); estimated here otherwise,
        and also for a touch whose exactly repeated samples are removed (see
        :class:`RepeatedSamplesWarning`): a geometry given for it was estimated on the
        copies, which read the noise low.
    probe_radius : float, optional
        Radius of the probe's ball tip, data units (the data are the ball's centres, on
        the surface offset outwards by it): the models are compared with their offset
        surfaces (:func:`meshrec.model.probe.probe_model`) and the curvatures at the
        touch corrected (:func:`meshrec.contact.probe.surface_geometry`). Default: the
        touches' own ``probe_radius`` (from the touch JSON), else 0 (a point probe).
        Without a radius, data that fit a model's offset surface clearly better than
        the surface itself raise a :class:`~meshrec.contact.probe.ProbeOffsetWarning`.
    workers : int or ModelWorkers or None
        Where the per-model registrations run (:mod:`meshrec.recognition.workers`): None,
        in this process; an int, that many local processes (for this call); a
        :class:`~meshrec.recognition.workers.ModelWorkers` of this library, its workers.
        The result is the same as a serial run's.
    scheduler : str or None
        The address of a Dask ``distributed`` scheduler to run them on (for this call).
    cascade : bool, optional
        With one touch (and for the first of several), run the local searches only on
        the models whose best conceivable fit after the first stages is within reach of
        the leaders'
        (:mod:`meshrec.recognition.cascade`); the others keep their best screened pose,
        refined. False: the full search on every model. Default ``defaults.CASCADE``.
        With ``workers`` or ``scheduler`` the cascade's decisions are taken here and its
        per-model batches run on the workers: the result is that of a serial run with
        the same ``cascade``.

    Returns
    -------
    Recognition
        The ranking (most probable first) with the calibrated scores and the verdict
        (recognised, ambiguous or unknown; see :mod:`meshrec.recognition.scoring`). When
        even the best fit is worse than the noise allows, every model is registered again
        with the (K, H) lookup widened (``defaults.LOOKUP_WIDEN_SCALE``) before the verdict
        (with several touches: each touch alone, then the search from pairs of touches);
        one touch that still fits nothing, once more with up to
        ``defaults.LOOKUP_DENSE_CANDIDATES`` candidates per model (each model keeps its best
        fit of all). Every warning raised inside is passed on as usual and its text kept in
        ``Recognition.warnings``, with a ResolutionWarning for each plausible (or best)
        model too coarse for reliable answers. With several touches, ``T_model_touch`` maps their
        common frame to the model, and touches that no model fits at one pose (the object
        moved, or it is not in the library) give ``unknown`` with that reason.

    Raises
    ------
    TypeError
        If ``touch`` is neither a TouchData nor a sequence of them, ``library`` not an
        iterable of ModelIndex, ``method`` not a string, ``geometry`` not a LocalGeometry
        (or a sequence of them) or ``progress`` not callable (the shared checks of
        :mod:`meshrec.io.checks`).
    ValueError
        If there is no touch, two touches hold the same data, the library is empty,
        ``method`` is unknown, ``geometry``
        does not hold one LocalGeometry per touch, a touch's size is out of all
        proportion to every model's (a likely unit mismatch, see
        :func:`meshrec.recognition.units.check_units`) or to another touch's
        (:func:`meshrec.recognition.joint.check_touch_sizes`), the curves do not allow
        an estimate of the local geometry, ``probe_radius`` is negative or not finite,
        the touches give different radii (or one other than ``probe_radius``), or a
        touch with a ``normal`` is curved more tightly than the tip where it is convex
        (``probe_radius`` at least its smallest radius of curvature: no ball of that
        radius traces such data); or as :class:`~meshrec.recognition.workers.ModelWorkers`
        for ``workers`` and ``scheduler``.
    TypeError
        If ``cascade`` is not a bool or None.
    """
    # The clock in this frame, not in a wrapper: the warnings' stack levels count from here.
    with phase_clock() as clock:
        t0 = time.perf_counter()
        touches = _touches(touch)
        geometries = _geometries(geometry, len(touches))
        touches, repeats, thinned = _without_repeats(touches)
        # a geometry estimated on the copies read their noise (a CLI's early estimate,
        # made to refuse bad data before any model is indexed): estimated again
        geometries = tuple(None if cut else g for g, cut in zip(geometries, thinned, strict=True))
        check_choice(method, SEARCH_METHODS, "method")
        if progress is not None and not callable(progress):
            raise TypeError(f"progress must be callable or None, got {type(progress).__name__}")
        if cascade is None:
            cascade = defaults.CASCADE
        if not isinstance(cascade, (bool, np.bool_)):
            raise TypeError(f"cascade must be a bool or None, got {type(cascade).__name__}")
        if isinstance(library, (str, bytes)) or not hasattr(library, "__iter__"):
            raise TypeError(
                f"library must be a ModelLibrary or an iterable of ModelIndex, got "
                f"{type(library).__name__}"
            )
        models = list(library)
        for i, model in enumerate(models):
            check_instance(model, ModelIndex, f"library[{i}]")
        radius = touch_probe_radius(touches, probe_radius)
        # the models as the ball's centres see them (themselves for a point probe); the
        # resolution warnings are the plain models' own (their cached resolution)
        seen = [probe_model(m, radius) for m in models]
        caught: list = []
        run, own = _runner(seen, workers, scheduler, getattr(library, "cache_dir", None))
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                for text in repeats:
                    warnings.warn(text, RepeatedSamplesWarning, stacklevel=2)
                if radius > 0.0:
                    with timed("geometry"):
                        geometries = tuple(
                            g if g is not None else touch_geometry(t)
                            for t, g in zip(touches, geometries, strict=True)
                        )
                    with timed("checks"):
                        check_tip_fits(touches, geometries, radius)
                if len(touches) == 1:
                    rec = _rank(
                        touches[0], seen, method, progress, geometries[0], run, bool(cascade)
                    )
                    rec = _with_verdict(rec, {}, seen, method, run)
                else:
                    rec, fits = _rank_joint(
                        touches, seen, method, progress, geometries, run, bool(cascade)
                    )
                    rec = _with_verdict(rec, fits, seen, method, run)
                with timed("freedom"):
                    rec = _with_pose_freedom(rec, seen)
                with timed("cautions"):
                    _warn_coarse(rec, models)
                    rec = _across_an_edge(rec, warn_sharp_edges(rec, seen))
                if radius == 0.0:
                    with timed("probe_offset"):
                        rec = dataclasses.replace(rec, probe_offset=warn_probe_offset(rec, models))
        finally:
            if own:
                run.close()
            # Pass every warning on as before (the caller's filters decide what is shown),
            # also when the recognition fails; the result keeps their text.
            raised = list(caught)
            for w in raised:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
        texts = tuple(dict.fromkeys([str(w.message) for w in raised] + list(rec.warnings)))
        return dataclasses.replace(
            rec,
            warnings=texts,
            seconds=time.perf_counter() - t0,
            probe_radius=radius,
            phase_times=clock.times(),
        )


def _with_pose_freedom(rec: Recognition, models: list) -> Recognition:
    """The pose freedom at the best model's pose; a free pose is never ``recognised``.

    A touch on a flat face fits its model equally well after any slide on the face or turn
    about its normal: the reported pose is then one of a continuum, not a measurement. The
    model may still be the only one that fits; the verdict is then ``ambiguous`` with that
    model alone in ``plausible``, and the reason says so. When instead the model's pose
    hypotheses hold distinct poses, not symmetries of the model of each other, that the
    data cannot rule out (touches near a box's corner, which fit it as well after a third
    of a turn about the corner's diagonal: ``with_alternatives``), each pose has its weight
    and the verdict stays the model's; the reason says the pose is one of them, and
    ``pose_freedom.fixed`` is False.
    """
    best = rec.best
    if best is None or best.T_model_touch is None:
        return rec
    model = {m.name: m for m in models}[best.model]
    freedom, on_surface, normals = _free_motions(rec, model)
    sigma = float("inf")
    if freedom.unresolved == 0 and rec.noise is not None and rec.noise > 0:
        # how precisely the data fix the pose, the symmetries' free motions left out
        sigma = pose_sigma(on_surface, normals, float(rec.noise), leave_out=freedom.free)
    freedom = dataclasses.replace(freedom, sigma=sigma)
    score = next((s for s in rec.scores if s.model == best.model), None)
    if score is not None and score.poses and freedom.unresolved == 0:
        # Distinct poses (a free motion already leaves the pose open). Two poses that move
        # the object by less than a few times the pose's own precision are one.
        vertices, distance, tolerance = _symmetry_test(model)
        weights = np.array([p.weight for p in score.poses])
        within = defaults.POSE_ALTERNATIVE_SIGMAS * sigma if np.isfinite(sigma) else 0.0
        # (the tolerance, whose chord error costs a pass over the mesh, only when a pose
        # is compared: not when the reported one alone reaches the coverage)
        needed = weights[0] < defaults.VERDICT_COVERAGE
        freedom = with_alternatives(
            freedom,
            np.array([p.T_model_touch for p in score.poses]),
            weights,
            vertices,
            distance,
            max(tolerance(), within) if needed else float("inf"),
        )
    rec = dataclasses.replace(rec, pose_freedom=freedom)
    if freedom.fixed:
        return rec
    if freedom.unresolved == 0:
        # No free motion, but distinct poses that fit about equally well: each has its
        # weight (a distribution over poses, as the models' probabilities), so the verdict
        # stays the model's; the reason and pose_freedom.fixed say the pose is open.
        poses = (
            f"{best.model}'s pose is one of {freedom.alternatives + 1} that fit about "
            "equally well and are not symmetries of it (the one reported has weight "
            f"{freedom.pose_weight:.2f})"
        )
        if rec.verdict == "recognised":
            why = f"{rec.reason}; but {poses}: touch again elsewhere on the object to fix it"
        else:
            why = f"{rec.reason}; {poses}"
        return dataclasses.replace(rec, reason=why)
    what = _freedom_phrase(freedom)
    if rec.verdict == "recognised":
        return dataclasses.replace(
            rec,
            verdict="ambiguous",
            reason=(
                f"of the library's models only {best.model} is plausible on the data "
                f"(probability {rec.probabilities.get(best.model, float('nan')):.3f}), but "
                f"{'the touch fixes' if len(rec.touches) <= 1 else 'the touches fix'} its "
                f"pose only up to {what}: the pose reported is one of "
                "many that fit equally well; touch again across an edge or on a curved part "
                "to fix it"
            ),
        )
    return dataclasses.replace(
        rec, reason=f"{rec.reason}; the best model's pose is free too ({what})"
    )


def _free_motions(rec: Recognition, model):
    """The rigid motions the data leave free at the best pose, the model's symmetries
    marked: ``(PoseFreedom, points on the surface (n, 3), their normals (n, 3))``, the
    points the test used."""
    points = np.vstack([t.points for t in (rec.touches or (rec.touch,))])
    y = apply_transform(rec.best.T_model_touch, points)
    # The test is taken at the points' closest points on the surface: the data's noise
    # across the surface would otherwise pin a turn about a cylinder's axis at the noise.
    on_surface, normals, at_crease, leaning = _pose_normals(model, y)
    # Points at a crease are left out (their constraint is one-sided); so are, on a fine
    # mesh, the points on the thin triangles that touch a crease vertex. On a coarse export
    # (a 12-triangle box, a cylinder's cap fanned to its rim) every face touches a crease
    # vertex: then only the points at the crease itself are left out.
    for over in (at_crease | leaning, at_crease):
        if np.count_nonzero(~over) >= 6:
            on_surface, normals = on_surface[~over], normals[~over]
            break
    freedom = pose_freedom(on_surface, normals)
    if freedom.free:
        freedom = _with_model_symmetries(freedom, model)
    return freedom, on_surface, normals


def _with_model_symmetries(freedom: PoseFreedom, model) -> PoseFreedom:
    """Which free motions are symmetries of the whole model (see ``with_symmetries``)."""
    vertices, distance, tolerance = _symmetry_test(model)
    return with_symmetries(freedom, vertices, distance, tolerance())


def _symmetry_test(model):
    """The vertices (at most ``defaults.POSE_SYMMETRY_VERTICES``), the distance to the
    surface, and a function giving the tolerance (its chord error is only computed when
    asked), with which a motion is tested for a symmetry of the model."""
    V = model.mesh.vertices
    step = max(1, len(V) // defaults.POSE_SYMMETRY_VERTICES)
    diagonal = float(np.linalg.norm(np.ptp(V, axis=0)))

    def tolerance() -> float:
        return max(
            defaults.POSE_SYMMETRY_TOLERANCE * diagonal,
            2.0 * float(model.resolution.chord_error),
        )

    return V[::step], lambda p: model.surface.closest_points(p)[0], tolerance


def _pose_normals(
    model, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each point's closest point on the surface, the normal there, which points lie at a
    crease, and which lie on a face touching a crease vertex.

    The normal is the smooth normal field of the vertex normals (exactly horizontal on a
    finely meshed cylinder's side, where the residual's gradient, that of the quadratic
    patches, wobbles along the axis by the sagitta's slope). On a face with a vertex
    normal more than ``defaults.POSE_EDGE_DEG`` off the face's own normal (a face
    touching a crease vertex, whose normal averages the faces on both sides) the field
    leans towards the crease: the face's normal is taken, and the point is flagged: it
    lies within a triangle of a crease. A point at a crease, such as a flat touch that
    reaches a box's edge within the noise, has a normal that jumps as it moves: a
    one-sided constraint (the touch may slide off the edge inwards, not outwards) that the
    first-order test would count as a full one.
    Such points (the residual's gradient turns by more than ``defaults.POSE_EDGE_DEG``
    when the point moves by ``defaults.POSE_EDGE_STEP`` times the points' spread along
    either tangent) are flagged, to be left out of the test.
    """
    cos_limit = np.cos(np.radians(defaults.POSE_EDGE_DEG))
    _, closest, face = model.surface.closest_points(points)
    smooth = model.surface.interpolated_normals(closest, face)
    flat = model.mesh.face_normals[face]
    corners = model.mesh.vertex_normals[model.mesh.faces[face]]  # (n, 3, 3)
    leaning = np.einsum("ikj,ij->ik", corners, flat).min(axis=1) < cos_limit
    normals = np.where(leaning[:, None], flat, smooth)
    grad = residuals(model, points).gradient
    unit = grad / np.maximum(np.linalg.norm(grad, axis=1), 1e-300)[:, None]
    spread = float(np.sqrt(((points - points.mean(axis=0)) ** 2).sum(axis=1).mean()))
    step = defaults.POSE_EDGE_STEP * spread
    # Two tangents per point, orthogonal to its normal.
    helper = np.where(np.abs(unit[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(unit, helper)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(unit, t1)
    at_crease = np.zeros(len(points), dtype=bool)
    for t in (t1, -t1, t2, -t2):
        g = residuals(model, points + step * t).gradient
        g /= np.maximum(np.linalg.norm(g, axis=1), 1e-300)[:, None]
        at_crease |= np.einsum("ij,ij->i", g, unit) < cos_limit
    return closest, normals, at_crease, leaning


def _freedom_phrase(freedom: PoseFreedom) -> str:
    """E.g. "2 slides and 1 turn (axis [0. 0. 1.] through [1. 2. 3.])"."""
    parts = []
    sym_s = freedom.slide_symmetric or (False,) * freedom.slides
    sym_t = freedom.turn_symmetric or (False,) * freedom.turns
    if freedom.slides:
        n_sym = sum(sym_s)
        extra = f" ({n_sym} a symmetry of the model)" if n_sym else ""
        parts.append(f"{freedom.slides} slide{'s' if freedom.slides > 1 else ''}{extra}")
    if freedom.turns:
        axes = "; ".join(
            f"axis {np.array2string(a, precision=3)} through {np.array2string(p, precision=4)}"
            + (", a symmetry of the model" if sym else "")
            for a, p, sym in zip(freedom.turn_axes, freedom.turn_points, sym_t, strict=True)
        )
        parts.append(f"{freedom.turns} turn{'s' if freedom.turns > 1 else ''} ({axes})")
    return " and ".join(parts)


def _runner(models: list, workers, scheduler, cache_dir=None) -> tuple[ModelWorkers, bool]:
    """The workers to register the models with, and whether they are made (and closed)
    here; processes made here load the library from ``cache_dir`` (the library's own)."""
    if isinstance(workers, ModelWorkers):
        if scheduler is not None:
            raise ValueError(
                f"scheduler must be None when workers is a ModelWorkers, got {scheduler!r}"
            )
        return workers, False
    if workers is None and scheduler is None:
        workers = 1
    return ModelWorkers(models, workers=workers, scheduler=scheduler, cache_dir=cache_dir), True


def _warn_coarse(rec: Recognition, models: list) -> None:
    """A ResolutionWarning per model too coarse for reliable answers among the plausible
    ones and the best (see :mod:`meshrec.model.resolution`)."""
    names = list(rec.plausible)
    if rec.best is not None:
        names.append(rec.best.model)
    by_name = {m.name: m for m in models}
    for name in dict.fromkeys(names):
        res = by_name[name].resolution
        if res.too_coarse:
            warnings.warn(coarse_message(name, res), ResolutionWarning, stacklevel=3)


def _touches(touch) -> tuple[TouchData, ...]:
    """One touch or a sequence of them, checked, as a tuple."""
    if isinstance(touch, TouchData):
        return (touch,)
    if isinstance(touch, (str, bytes)) or not isinstance(touch, Sequence):
        raise TypeError(
            f"touch must be a TouchData or a sequence of TouchData, got {type(touch).__name__}"
        )
    if len(touch) == 0:
        raise ValueError("touch must hold at least one TouchData, got an empty sequence")
    for i, t in enumerate(touch):
        check_instance(t, TouchData, f"touch[{i}]")
    # The same data twice (a file given twice) would count its evidence twice: its
    # likelihood ratios squared, an ambiguous answer made "recognised" by repetition.
    # (Two touches of the same place carry independent noise and are welcome.)
    # Copies that differ only far below the probe's noise (re-saved with rounding, a
    # jitter added) are the same data: every point within defaults.TOUCH_COPY_FRACTION of
    # their extent, or within defaults.TOUCH_COPY_NOISE_FRACTION of the samples' scatter
    # about their curves (a touch in mm and its copy rounded to 1 um, against 20 um of
    # noise, counted as two touches and moved every probability: a black-box probe, stop
    # 33). A second touch of the same place scatters by its own noise.
    for j, b in enumerate(touch):
        for i in range(j):
            a = touch[i]
            if len(a.curves) != len(b.curves) or any(
                x.shape != y.shape for x, y in zip(a.curves, b.curves, strict=True)
            ):
                continue
            extent = float(np.linalg.norm(np.ptp(a.points, axis=0)))
            apart = max(
                float(np.max(np.abs(x - y))) for x, y in zip(a.curves, b.curves, strict=True)
            )
            if apart > defaults.TOUCH_COPY_FRACTION * extent:
                scatter = min(_sample_scatter(a), _sample_scatter(b))
                if not apart <= defaults.TOUCH_COPY_NOISE_FRACTION * scatter:
                    continue
                same = (
                    f"nearly the same data (every point within {apart:.3g}, "
                    f"{apart / scatter:.2g} times the scatter of its samples about their "
                    "curves)"
                )
            else:
                same = (
                    "the same data"
                    if apart == 0.0
                    else (
                        f"nearly the same data (every point within {apart:.3g}, "
                        f"{apart / extent:.2g} of its extent)"
                    )
                )
            raise ValueError(
                f"touch[{j}] holds {same} as touch[{i}]: give each touch once "
                "(a repeated touch would count its evidence again)"
            )
    return tuple(touch)


def _sample_scatter(touch: TouchData) -> float:
    """The samples' scatter about their curves: the RMS, over every curve's inner samples,
    of the second difference across the chord (``p[i-1] - 2 p[i] + p[i+1]`` less its
    part along ``p[i+1] - p[i-1]``, which uneven spacing makes), over sqrt(12): the noise
    per coordinate for isotropic noise (the part across a chord has two of the three
    coordinates, each of variance 6 sigma^2); the curves' own bend adds to it. 0 without
    inner samples.

    Hand-written: a noise measure needing no fit (this runs before the touches' curve fits,
    :func:`~meshrec.contact.geometry.estimate_local_geometry`)."""
    parts = []
    for c in touch.curves:
        if len(c) < 3:
            continue
        d2 = c[:-2] - 2.0 * c[1:-1] + c[2:]
        chord = c[2:] - c[:-2]
        norm = np.linalg.norm(chord, axis=1)
        unit = chord / np.maximum(norm, 1e-300)[:, None]
        parts.append(d2 - np.einsum("ij,ij->i", d2, unit)[:, None] * unit)
    if not parts:
        return 0.0
    across = np.vstack(parts)
    return float(np.sqrt((across**2).sum(axis=1).mean() / 12.0))


def _without_repeats(touches: tuple) -> tuple[tuple, list[str], tuple[bool, ...]]:
    """The touches without samples that repeat the one before them exactly
    (:meth:`TouchData.without_repeats`), a note for each touch that had some, and
    whether each had some."""
    out, notes, thinned = [], [], []
    for k, t in enumerate(touches):
        kept, removed = t.without_repeats()
        out.append(kept)
        thinned.append(bool(removed))
        if removed:
            which = "the touch" if len(touches) == 1 else f"touch {k + 1}"
            notes.append(
                f"{which}: {removed} of its {t.n_points} samples repeat the one before them "
                "exactly (a logger faster than its sensor, or a probe resting) and were "
                "counted once: copies carry no new measurement"
            )
    return tuple(out), notes, tuple(thinned)


def _geometries(geometry, n: int) -> tuple:
    """The given local geometries, one per touch (None where to be estimated)."""
    if geometry is None:
        return (None,) * n
    if isinstance(geometry, LocalGeometry):
        geometry = (geometry,)
    elif isinstance(geometry, (str, bytes)) or not isinstance(geometry, Sequence):
        raise TypeError(
            "geometry must be a LocalGeometry, a sequence of LocalGeometry or None, got "
            f"{type(geometry).__name__}"
        )
    if len(geometry) != n:
        raise ValueError(
            f"geometry must hold one LocalGeometry per touch ({n}), got {len(geometry)}"
        )
    for i, g in enumerate(geometry):
        check_instance(g, LocalGeometry, f"geometry[{i}]")
    return tuple(geometry)


def _rank(touch, library, method, progress, geometry, run, cascade=False) -> Recognition:
    """Register the touch on every model and rank them (the recognition proper)."""
    t0 = time.perf_counter()
    models = list(library)
    if not models:
        raise ValueError("library must hold at least one model, got none")
    with timed("checks"):
        check_units(touch, models)
    if geometry is None:
        with timed("geometry"):
            geometry = touch_geometry(touch)
    # Every model is registered on its own (the result of one never depends on another),
    # so the order of the models, or running them apart, changes nothing.
    with timed("first"):
        if cascade:
            # the cascade's decisions here, its per-model batches on the workers
            noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
            results = cascade_register(touch, models, geometry, noise, method, progress, run=run)
        else:
            results = run.register_each(touch, models, geometry, method, progress=progress)
    return _ranked(
        Recognition(
            touch=touch,
            geometry=geometry,
            ranking=(),
            seconds=time.perf_counter() - t0,
            touches=(touch,),
            geometries=(geometry,),
        ),
        results,
    )


def _ranked(rec: Recognition, results) -> Recognition:
    """``rec`` with ``results`` as its ranking, least error first (rejected last)."""
    results = sorted(
        results, key=lambda r: (r.rejected, r.error if r.error is not None else 0.0, r.model)
    )
    return dataclasses.replace(rec, ranking=tuple(results))


def _rank_joint(touches, models, method, progress, geometries, run, cascade=False):
    """Several touches: every model fitted at one pose to all, the needed touches alone.

    Per model (independently of the others) the first touch is registered alone. Then,
    most promising model first (:func:`~meshrec.recognition.bestfirst.fit_best_first`),
    its poses are refined on every touch and, while the joint fit is worse than the noise
    allows, the next touch is registered alone too, unless even the model's best
    conceivable fit (:func:`~meshrec.recognition.joint.log_likelihood_bound`) is already
    far below the best joint fit so far (``defaults.JOINT_PRUNE_LOG_RATIO``).
    """
    t0 = time.perf_counter()
    if not models:
        raise ValueError("library must hold at least one model, got none")
    with timed("checks"):
        check_touch_sizes(touches)
        for touch in touches:
            check_units(touch, models)
    with timed("geometry"):
        geometries = tuple(
            g if g is not None else touch_geometry(t)
            for t, g in zip(touches, geometries, strict=True)
        )
    rec = Recognition(
        touch=touches[0],
        geometry=geometries[0],
        ranking=(),
        seconds=0.0,
        touches=touches,
        geometries=geometries,
    )
    noise, n = _noise_and_points(rec)
    with timed("first"):
        if cascade:
            # The first touch through the cascade: a model it prunes fits the first touch
            # alone far worse than the leaders, and a joint fit is worse still.
            regs = cascade_register(
                touches[0], models, geometries[0], None, method, progress, trace=True, run=run
            )
        else:
            regs = run.register_each(
                touches[0], models, geometries[0], method, trace=True, progress=progress
            )
        firsts = {
            model.name: first_touch_fit(touches, model, first)
            for model, first in zip(models, regs, strict=True)
        }
    # Most promising model first, each model a step (one more touch) at a time, until
    # it fits every touch to the noise or cannot become plausible (branch and bound:
    # meshrec.recognition.bestfirst).
    with timed("best_first"):
        fits = fit_best_first(touches, models, geometries, firsts, noise, method)
    with timed("adequacy"):
        _search_adequately(touches, models, geometries, fits, noise, n, method)
    with timed("symmetries"):
        _explore_near_symmetries(touches, models, geometries, fits, noise, n)
    rec = dataclasses.replace(rec, seconds=time.perf_counter() - t0)
    return _ranked(rec, [f.registration for f in fits.values()]), fits


def _search_adequately(
    touches,
    models,
    geometries,
    fits: dict,
    noise: float,
    n: int,
    method,
    lookup_scale=1.0,
    below=True,
):
    """Search again, from pairs of touches, every model whose joint pose may have been missed.

    The scores trust each model's best joint fit. On look-alike shapes touched with short
    noisy curves each touch alone fits every model at many places, and the right model's
    joint search can end in a wrong basin while a wrong model's happens to fit: a wrong
    and confident answer. The right model's search can also end in a wrong basin
    while it still leads (touches across a scan's rims, where each touch alone is placed
    badly): then even the best joint fit is worse than the noise allows, and the answer
    would be ``unknown`` for an object in the library. So, in rounds until none qualifies
    (each model searched once; an order-free step over all the fits): a model more than
    ``defaults.PAIR_SEARCH_GAP`` below the best log-likelihood, or whose joint fit is worse
    than the noise allows (p-value under ``defaults.WIDEN_P_VALUE``), is registered on
    every touch alone; if its best conceivable fit
    (:func:`~meshrec.recognition.joint.log_likelihood_bound`) still comes within that gap
    of the best, it is searched again from pairs of touches
    (:func:`~meshrec.recognition.joint.search_pairs`), both with the (K, H) window widened
    by ``lookup_scale``. With ``below`` False only the models within the gap of the best
    that fit worse than the noise qualify (the widened pass: the leaders, where a missed
    pose turns the answer to ``unknown``). ``fits`` is updated in place.
    """
    searched = set()
    gap = defaults.PAIR_SEARCH_GAP
    while True:
        names = list(fits)
        ll = log_likelihoods([fits[k].registration.rms for k in names], n, noise)
        leader = float(np.max(ll))
        ll_of = dict(zip(names, ll, strict=True))
        todo = [
            m
            for m in models
            if m.name not in searched
            and not fits[m.name].registration.rejected
            and (
                (below and ll_of[m.name] < leader - gap)
                or (
                    ll_of[m.name] >= leader - gap
                    and _fits_worse(fits[m.name].registration.rms, n, noise)
                )
            )
            and log_likelihood_bound(fits[m.name], touches, noise, geometries) >= leader - gap
        ]
        if not todo:
            return
        for model in todo:
            searched.add(model.name)
            fit = fits[model.name]
            if fit.registered < len(touches):
                fit = register_touches(
                    touches,
                    model,
                    geometries,
                    upto=len(touches),
                    previous=fit,
                    method=method,
                    lookup_scale=lookup_scale,
                    noise=noise,
                )
            if log_likelihood_bound(fit, touches, noise, geometries) >= leader - gap:
                far = rms_out_of_reach(leader, n, noise)
                fit = search_pairs(
                    touches, model, geometries, fit, lookup_scale=lookup_scale, hopeless_rms=far
                )
            fits[model.name] = fit


def _search_lone_leader(touches, models, geometries, fits: dict, noise: float, n: int):
    """Several touches: the one model that leads alone (no other within
    ``defaults.PAIR_SEARCH_GAP`` of its log-likelihood) is searched from pairs of touches
    again, so that every pose its touches allow is among its poses before its pose is
    given.

    On a part that is nearly symmetric where it was touched (a plate's two faces, a box's
    faces on either side of an edge) the joint search can end at one of two poses a
    half-turn apart that fit equally well; the other was then never found and the pose
    was given as fixed (a black-box probe, stop 32: three of fifteen `recognised`
    three-touch answers 31 to 43 mm off, about 5,000 sigma). The pairs of touches match
    pairs of the model's points with the same features whichever of the two it is. The
    poses found join the model's (its best fit only improves); their weights then say
    whether the pose is one of several. The (K, H) window is widened
    (``defaults.LOOKUP_WIDEN_SCALE``). ``fits`` is updated in place.
    """
    names = list(fits)
    ll = log_likelihoods([fits[k].registration.rms for k in names], n, noise)
    order = np.argsort(ll)[::-1]
    leader = names[int(order[0])]
    if fits[leader].registration.rejected:
        return
    if len(order) > 1 and ll[int(order[1])] >= ll[int(order[0])] - defaults.PAIR_SEARCH_GAP:
        return  # not named alone: its pose is not given as the answer's
    model = {m.name: m for m in models}[leader]
    # the window widened: on a coarse export a touch's (K, H) can miss the sites around
    # its true contact (a plate's face touched with H 0.012 where the model's is 0: 8 of
    # 400 spread points matched, none near the truth)
    fits[leader] = search_pairs(
        touches, model, geometries, fits[leader], lookup_scale=defaults.LOOKUP_WIDEN_SCALE
    )


def _explore_near_symmetries(touches, models, geometries, fits: dict, noise: float, n: int):
    """Follow the weakest motions of the leading models' joint poses for better basins.

    Every model within ``defaults.PAIR_SEARCH_GAP`` of the best log-likelihood (an
    order-free set, taken before any is explored) is refined again from poses a long way
    along its best pose's near-symmetries
    (:func:`~meshrec.recognition.joint.explore_weak_motions`): on a nearly symmetric
    object the joint search can end at a precise-looking pose a large turn away from the
    right one. ``fits`` is updated in place.
    """
    names = list(fits)
    ll = log_likelihoods([fits[k].registration.rms for k in names], n, noise)
    leader = float(np.max(ll))
    ll_of = dict(zip(names, ll, strict=True))
    near = [
        m
        for m in models
        if not fits[m.name].registration.rejected
        and ll_of[m.name] >= leader - defaults.PAIR_SEARCH_GAP
    ]
    for model in near:
        fits[model.name] = explore_weak_motions(touches, model, geometries, fits[model.name])


# --------------------------------------------------------------------------- the verdict
def _noise_and_points(rec: Recognition) -> tuple[float, int]:
    """The noise estimated from the touches (pooled over several) and their points."""
    touches = rec.touches or (rec.touch,)
    geometries = rec.geometries or (rec.geometry,)
    noises = [noise_estimate(g.fit_rms, g.noise_rms, g.half_length) for g in geometries]
    counts = [int(t.n_points) for t in touches]
    noise = noises[0] if len(noises) == 1 else pooled_noise(noises, counts)
    return noise, int(sum(counts))


def _score(
    rec: Recognition, prior: dict | None, models: list
) -> tuple[tuple[ModelScore, ...], float]:
    """Per-model calibrated scores (ranking order) and the noise they take; ``prior``: the
    models' prior weights by name (None: uniform).

    The noise is the touches' own (:func:`_noise_and_points`) and the model meshes' own
    error (:func:`_model_error`) added in quadrature: a residual holds both."""
    noise, n = _noise_and_points(rec)
    noise = float(np.hypot(noise, _model_error(rec, models)))
    rms, poses = [], []
    for reg in rec.ranking:
        if reg.rejected:
            rms.append(None)
            poses.append(())
            continue
        pose_rms = [pose.rms for pose in reg.poses]
        w = pose_weights(pose_rms, n, noise)
        rms.append(reg.rms)
        poses.append(
            tuple(
                WeightedPose(pose.T_model_touch, pose.rms, float(wi))
                for pose, wi in zip(reg.poses, w, strict=True)
            )
        )
    ll = log_likelihoods(rms, n, noise)
    prob = posterior(ll, None if prior is None else [prior[r.model] for r in rec.ranking])
    scores = tuple(
        ModelScore(reg.model, float(p), r, n, float(li), ps)
        for reg, p, r, li, ps in zip(rec.ranking, prob, rms, ll, poses, strict=True)
    )
    return scores, noise


def _model_error(rec: Recognition, models: list) -> float:
    """The largest error of the meshes of the models that compete: the RMS distance of
    the true surface from the mesh of a model whose vertices scatter by ``s`` about it
    (:attr:`~meshrec.model.index.ModelIndex.vertex_scatter`), ``s / sqrt(2)`` (a point of
    a face sees its corners' offsets blended by its barycentric weights, whose squares
    average 1/2). Every model whose best fit comes within
    ``defaults.MODEL_ERROR_REACH`` times the best RMS competes; 0 when none is registered.

    A raw scan's mesh scatters by the scanner's noise: where that is comparable to the
    probe's, the right model's residuals exceed the touch's noise and a look-alike's mesh
    can fit as well by chance (:mod:`meshrec.model.roughness`); an exact mesh adds
    nothing."""
    fitted = [r for r in rec.ranking if not r.rejected and r.rms is not None]
    if not fitted:
        return 0.0
    best = min(r.rms for r in fitted)
    by_name = {m.name: m for m in models}
    reach = [r.model for r in fitted if r.rms <= defaults.MODEL_ERROR_REACH * best]
    scatter = max(float(getattr(by_name[name], "vertex_scatter", 0.0)) for name in reach)
    return scatter / np.sqrt(2.0)


def _ordered(rec: Recognition, scores: tuple[ModelScore, ...]) -> Recognition:
    """The ranking and its scores re-ordered: most probable first, then least error."""
    key = {
        s.model: (r.rejected, -s.probability, r.error if r.error is not None else 0.0, r.model)
        for r, s in zip(rec.ranking, scores, strict=True)
    }
    pairs = sorted(zip(rec.ranking, scores, strict=True), key=lambda rs: key[rs[0].model])
    return dataclasses.replace(
        rec, ranking=tuple(r for r, _ in pairs), scores=tuple(s for _, s in pairs)
    )


def _widened(
    rec: Recognition,
    models: dict,
    method: str,
    run,
    max_candidates=None,
    only=None,
    lookup_scale: float = defaults.LOOKUP_WIDEN_SCALE,
) -> tuple[Recognition, frozenset]:
    """One touch: register every model again with the (K, H) window widened; keep each
    one's better fit.

    Each model may look at up to ``max_candidates`` candidates (None: the default number),
    and only the models named in ``only`` (None: all) are registered; the others are kept
    as they are. ``lookup_scale`` widens the window (``defaults.LOOKUP_OPEN_SCALE`` opens
    it to every site).

    Returns the merged recognition and the names of the models whose widened lookup
    filled the cap (``defaults.MAX_CANDIDATES`` candidates): only for them can a denser
    look choose other candidates (the spreading stops short of the cap by the same rule
    whatever the cap, so a model under it would get the same candidates and the same fit;
    a model with none, rejected, gets none again).
    """
    todo = [reg for reg in rec.ranking if only is None or reg.model in only]
    regs = run.register_each(
        rec.touch,
        [models[reg.model] for reg in todo],
        rec.geometry,
        method,
        lookup_scale=lookup_scale,
        max_candidates=max_candidates,
    )
    wides = {reg.model: wide for reg, wide in zip(todo, regs, strict=True)}
    capped = frozenset(
        name for name, wide in wides.items() if wide.candidates >= defaults.MAX_CANDIDATES
    )
    merged = []
    for reg in rec.ranking:
        wide = wides.get(reg.model, reg)
        better = reg.rejected or (not wide.rejected and wide.error < reg.error)
        merged.append(wide if better else reg)
    return dataclasses.replace(rec, ranking=tuple(merged)), capped


def _looked_again(rec: Recognition, prior, models: list, method: str, run, phase: str, **kw):
    """One touch: :func:`_widened` (``kw`` its options), timed as ``phase``, and the scores
    again: ``(recognition, noise, run)`` (``run`` started here when None)."""
    if run is None:
        run = ModelWorkers(models, workers=1)
    with timed(phase):
        rec, _ = _widened(rec, {m.name: m for m in models}, method, run, **kw)
        scores, noise = _score(rec, prior, models)
        rec = _ordered(rec, scores)
    return rec, noise, run


def _looked_harder(
    rec: Recognition, prior, fits: dict, models: list, method: str, run, n: int, p_value: float
):
    """Every model registered again with the (K, H) window widened
    (``defaults.LOOKUP_WIDEN_SCALE``), and the scores again; for one touch whose best fit
    still has a chi-square tail below ``p_value``, once more with up to
    ``defaults.LOOKUP_DENSE_CANDIDATES`` candidates on the models whose widened window
    held more than the cap. Each model keeps its best fit of all.

    Returns ``(recognition, noise, run, how)``: ``run`` is started here when None, and
    ``how`` says what was done (for the caution).
    """
    by_name = {m.name: m for m in models}
    if run is None:
        run = ModelWorkers(models, workers=1)
    with timed("widened"):
        if len(rec.touches) == 1:
            rec, capped = _widened(rec, by_name, method, run)
        else:
            rec = _widened_joint(rec, fits, by_name, method)
        scores, noise = _score(rec, prior, models)
        rec = _ordered(rec, scores)
    how = "every model registered again"
    # the touch's own noise (not the meshes' error the scores add): a marginal fit to the
    # touch is a reason to look harder on any mesh
    if len(rec.touches) == 1 and _fits_below(rec, n, _noise_and_points(rec)[0], p_value):
        # Still no good fit: where the widened window matches most of a model's sites (a
        # thin, rough scan; a box's flat faces), the spread candidates lie too far apart to
        # start from; look once more among more of them (on the models where the window
        # held more than the cap: the others would get the same candidates).
        dense = {"max_candidates": defaults.LOOKUP_DENSE_CANDIDATES, "only": capped}
        rec, noise, run = _looked_again(rec, prior, models, method, run, "dense", **dense)
        how = (
            f"every model registered again, then once more with up to "
            f"{defaults.LOOKUP_DENSE_CANDIDATES} candidates where the window held more "
            f"than {defaults.MAX_CANDIDATES} sites"
        )
    return rec, noise, run, how


def _widened_joint(rec: Recognition, fits: dict, models: dict, method: str) -> Recognition:
    """Several touches: every model's touches registered alone again with the (K, H)
    window widened, jointly refined; each model keeps its better fit.

    Then the leading models whose joint fit may still have been missed are searched from
    pairs of touches with the wider window (:func:`_search_adequately`). ``fits`` (the
    joint fits, by model) is updated in place where the wider pass fits better.
    """
    noise, n = _noise_and_points(rec)
    merged = []
    for reg in rec.ranking:
        fit = register_touches(
            rec.touches,
            models[reg.model],
            rec.geometries,
            upto=len(rec.touches),
            method=method,
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
            noise=noise,
        )
        wide = fit.registration
        if reg.rejected or (not wide.rejected and wide.error < reg.error):
            merged.append(wide)
            fits[reg.model] = fit
        else:
            merged.append(reg)
    # Every touch registered alone with the wider window, but a leader's joint pose
    # missed still: its pairs of touches again, with the wider window too (the leaders
    # only: the models well below them were searched from pairs already, and searching
    # them all again costs an out-of-library answer a third more time).
    present = [models[reg.model] for reg in merged if reg.model in fits]
    _search_adequately(
        rec.touches,
        present,
        rec.geometries,
        fits,
        noise,
        n,
        method,
        lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        below=False,
    )
    _search_rough_touches(rec, present, fits, noise, n)
    merged = [fits[reg.model].registration if reg.model in fits else reg for reg in merged]
    return dataclasses.replace(rec, ranking=tuple(merged))


def _search_rough_touches(rec: Recognition, models: list, fits: dict, noise: float, n: int):
    """Several touches that no model fits, some of them rough (curve fits far worse than
    the noise: across an edge): the best ``defaults.ROUGH_PAIR_MODELS`` models by joint
    fit are searched from pairs of touches with the (K, H) window widened, whatever their
    bound.

    A rough touch's curvature is not defined, so each touch registered alone can miss its
    place, and the bound built on those registrations then rules the right model out of
    the pair search (a black-box probe, stop 32: three touches across a coarse plate's
    edges were `unknown` with the plate fourth at 28 times the noise, where its true pose
    fits to it; the widened pair search finds that pose). ``fits`` is updated in place.
    """
    rough = any(g.fit_to_noise > defaults.ROUGH_FIT_RATIO for g in rec.geometries)
    ranked = sorted(
        (m for m in models if not fits[m.name].registration.rejected),
        key=lambda m: (fits[m.name].registration.rms, m.name),
    )
    if not rough or not ranked or not _fits_worse(fits[ranked[0].name].registration.rms, n, noise):
        return
    for model in ranked[: defaults.ROUGH_PAIR_MODELS]:
        fits[model.name] = search_pairs(
            rec.touches,
            model,
            rec.geometries,
            fits[model.name],
            lookup_scale=defaults.LOOKUP_WIDEN_SCALE,
        )


def _with_verdict(rec: Recognition, fits: dict, models: list, method: str, run=None) -> Recognition:
    """Add the calibrated scores, the verdict and its cautions to a ranking.

    When even the best model fits far worse than the noise (or no model was registered),
    the (K, H) lookup may have kept the right contact out (curves straddling a seam
    between two patches of different curvature): the lookup is then widened by
    ``defaults.LOOKUP_WIDEN_SCALE`` and every model registered again before concluding;
    the same passes run where one touch would name a model whose fit is only marginal
    (chi-square tail below ``defaults.NAME_P_VALUE``). ``fits`` holds the joint fits of
    several touches by model (empty for one touch).
    """
    by_name = {m.name: m for m in models}
    with timed("scoring"):
        noise, n = _noise_and_points(rec)
        t0 = time.perf_counter()
        prior = None
        if len(rec.touches) == 1:
            # the shares of the registered models only (a KD-tree each): a model the lookup
            # rejected has no flat site within the tolerance, its share 0, its weight the
            # floor
            fitted = [by_name[r.model] for r in rec.ranking if not r.rejected]
            weights = flat_prior(rec.touch, rec.geometry, fitted) if fitted else None
            if weights is not None:
                floor = float(weights.max()) / defaults.FLAT_PRIOR_MAX_RATIO
                prior = {m.name: floor for m in models}
                prior.update({m.name: float(w) for m, w in zip(fitted, weights, strict=True)})
        scores, noise = _score(rec, prior, models)
        rec = _ordered(rec, scores)
        t_score = time.perf_counter() - t0
    t_wide = 0.0
    cautions = []
    looked = False
    # Whether to look harder is judged on the touches' own noise: the meshes' error that
    # the scores add (_model_error) must not hide a search that ended short (a YCB touch
    # of the gelatin box was named the foam brick again when it did).
    own = _noise_and_points(rec)[0]
    if _fits_worse_than_noise(rec, n, own):
        # Even the best fit is worse than the noise allows: look harder before
        # concluding. The lookup is a prior, not a gate: curves straddling a seam between
        # patches of different curvature may mismatch every vertex's (K, H) of the right
        # model, so every model is registered again with the window widened.
        t1 = time.perf_counter()
        rec, noise, run, how = _looked_harder(
            rec, prior, fits, models, method, run, n, defaults.WIDEN_P_VALUE
        )
        t_wide = time.perf_counter() - t1
        looked = True
        cautions.append(
            "the first pass fitted no model to within the noise (or registered none): the "
            f"curvature lookup was widened {defaults.LOOKUP_WIDEN_SCALE:g} times and {how}"
        )
    if len(rec.touches) > 1 and _would_recognise(rec, prior, n, noise):
        # Several touches about to name a model: every pose its touches allow, before its
        # pose is given (_search_lone_leader). Not where the data leave the pose free
        # anyway, nor where every turn is a symmetry of the model (a sphere): as for one
        # touch's confirmation (it cost a second on the bundled sphere's 80k faces).
        with timed("freedom"):
            freedom = _free_motions(rec, by_name[rec.ranking[0].model])[0]
        search = not (freedom.unresolved or freedom.turns >= 3)
    else:
        search = False
    if search:
        with timed("adequacy"):
            _search_lone_leader(rec.touches, models, rec.geometries, fits, noise, n)
            ranking = [fits[r.model].registration if r.model in fits else r for r in rec.ranking]
            rec = dataclasses.replace(rec, ranking=tuple(ranking))
            scores, noise = _score(rec, prior, models)
            rec = _ordered(rec, scores)
    if len(rec.touches) > 1 and _would_recognise(rec, prior, n, noise):
        with timed("transfer"):
            rec = _transferred(rec, models, fits, noise)
            scores, noise = _score(rec, prior, models)
            rec = _ordered(rec, scores)
    if len(rec.touches) == 1 and not looked and _would_be_named(rec, prior, n, noise):
        p_best = fit_p_value(rec.scores[0].rms, n, own)
        if p_best < defaults.NAME_P_VALUE:
            # One touch about to name a model that fits only marginally (the right model
            # fits better than this on all but a few touches): the touched model's own
            # search may have ended short of its pose while another model fits about as
            # well (a YCB touch of the gelatin box named the foam brick, tail 0.016; the
            # gelatin box's pose, found by these passes, fits better). Look harder first.
            t1 = time.perf_counter()
            rec, noise, run, how = _looked_harder(
                rec, prior, fits, models, method, run, n, defaults.NAME_P_VALUE
            )
            t_wide += time.perf_counter() - t1
            cautions.append(
                f"the best fit was marginal for naming a model from one touch (its chi-square "
                f"tail {p_best:.2g}, below defaults.NAME_P_VALUE = {defaults.NAME_P_VALUE:g}): "
                f"the curvature lookup was widened {defaults.LOOKUP_WIDEN_SCALE:g} times and "
                f"{how}"
            )
    turn = _curvature_turn(rec.geometry)
    if len(rec.touches) == 1 and turn > defaults.CURVATURE_MAX_TURN:
        rejected = frozenset(r.model for r in rec.ranking if r.rejected)
        if rejected and _would_recognise(rec, prior, n, noise):
            # The curvature estimate is out of its range (the curves would turn by more
            # than CURVATURE_MAX_TURN radians over their half-length: curves long against
            # the radius of curvature, or noise large against their length), and the
            # lookup window built on it may have left the right model out. Before one model
            # is named, the models the lookup alone rejected are registered with the
            # window open (every site a candidate, spread as usual).
            t1 = time.perf_counter()
            opened = {"only": rejected, "lookup_scale": defaults.LOOKUP_OPEN_SCALE}
            rec, noise, run = _looked_again(rec, prior, models, method, run, "widened", **opened)
            t_wide += time.perf_counter() - t1
            found = [r.model for r in rec.ranking if r.model in rejected and not r.rejected]
            cautions.append(
                f"the curvature estimate at the contact is out of its range (the curves would "
                f"turn by {turn:.3g} radians over their half-length, more than "
                f"defaults.CURVATURE_MAX_TURN = {defaults.CURVATURE_MAX_TURN:g}): the "
                f"{len(rejected)} model(s) that the curvature lookup rejected were registered "
                f"again on every site ({len(found)} registered)"
            )
    if len(rec.touches) == 1 and _would_be_named(rec, prior, n, noise):
        confirmed, t_confirm = _confirmed(rec, prior, method, run, models)
        t_wide += t_confirm
        if confirmed is not None:
            rec, noise, caution = confirmed
            if caution:
                cautions.append(caution)
        if _would_be_named(rec, prior, n, noise):
            t1 = time.perf_counter()
            with timed("freedom"):
                explored = _explore_weak_motions_one(rec, by_name[rec.ranking[0].model])
            if explored is not rec:
                scores, noise = _score(explored, prior, models)
                rec = _ordered(explored, scores)
            t_wide += time.perf_counter() - t1
        if _would_be_named(rec, prior, n, noise):
            t1 = time.perf_counter()
            with timed("transfer"):
                rec = _transferred(rec, models, fits, noise)
                scores, noise = _score(rec, prior, models)
                rec = _ordered(rec, scores)
            t_wide += time.perf_counter() - t1
    with timed("scoring"):
        t1 = time.perf_counter()
        mesh_error = _model_error(rec, models)
        if mesh_error > defaults.MODEL_ERROR_NOTE * own:
            cautions.append(
                f"the meshes of the models that fit best scatter about their surfaces by up "
                f"to {mesh_error * np.sqrt(2.0):.3g} (vertex roughness, as a raw scan's): "
                f"their error, {mesh_error:.3g} on the surface, is added to the touch's noise "
                f"{own:.3g} (the scores take {noise:.3g}), and the answer can tell models "
                "apart only above it"
            )
        v = _decided(rec, prior, n, noise)
        if prior is not None:
            cautions.append(_flat_caution(rec.scores, prior))
        v = _within_calibration(v, rec)
        reason = v.reason
        rough = False
        for k, g in enumerate(rec.geometries):
            if (
                g.fit_to_noise > defaults.ROUGH_FIT_RATIO
                and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * g.half_length
            ):
                rough = True
                which = (
                    f"touch {k + 1}'s curve fits" if len(rec.geometries) > 1 else "the curve fits"
                )
                cautions.append(
                    f"{which} leave {g.fit_to_noise:.3g} times the noise the samples show: "
                    "the curves may cross an edge, and the probabilities are less reliable"
                )
        if len(rec.geometries) == 1:
            v = _rough_hold(v, rec.geometries[0])
            reason = v.reason
        elif rec.best is not None and rec.best.model in fits:
            v = _every_touch_hold(v, rec, fits[rec.best.model], noise)
            reason = v.reason
        if rough and v.verdict == "unknown" and rec.best is not None:
            # A misfit from curves that fit no smooth patch: the search, started from the
            # curvature at p, may have missed the right pose across the edge.
            reason = (
                f"{reason}, or its pose was missed: the curves fit no smooth surface patch "
                "(they may cross an edge or a rim), where the search is less reliable; touch "
                "again away from edges"
            )
        if rough and v.verdict == "unknown" and rec.best is None:
            # Nothing registered from a touch whose curves fit no smooth patch: the
            # curvature at p, which the lookup matches, is not defined there (a rim, an
            # edge); that, not the library, is the likely cause.
            reason = (
                "no model could be registered: the curves fit no smooth surface patch, so the "
                "curvature at their common point, which the lookup matches, is not defined "
                "(they may cross an edge or a rim); the object may still be in the library: "
                "touch again away from edges"
            )
        if v.verdict == "unknown":
            reason = _inward_hint(rec, reason)
        best_reg = rec.best
        if best_reg is None:
            per_touch = (None,) * len(rec.touches)
        elif len(rec.touches) == 1:
            per_touch = (best_reg.rms,)
        else:
            per_touch = fits[best_reg.model].touch_rms
            if v.verdict == "unknown":
                reason = _joint_unknown_reason(rec, fits, by_name, noise) or reason
        t_score += time.perf_counter() - t1
    return dataclasses.replace(
        rec,
        verdict=v.verdict,
        plausible=v.plausible,
        noise=float(noise),
        reason=reason,
        warnings=tuple(cautions),
        scoring_seconds=t_score,
        widened_seconds=t_wide,
        touch_rms=per_touch,
    )


def _confirmed(rec: Recognition, prior, method: str, run, models: list):
    """One touch about to be ``recognised``: the named model's own search again, with
    ``defaults.CONFIRM_CANDIDATES`` candidates, before its pose is given.

    The first pass spreads at most ``defaults.MAX_CANDIDATES`` candidates over the sites
    the (K, H) window holds; on a short touch of a smooth, nearly symmetric shape the
    window holds many, and the search can end in a wrong basin that fits almost as well
    (a black-box probe, stop 31: five of six such touches of a superellipsoid and a cone
    were `recognised` with the pose `fixed` and 8 to 34 mm off, the true pose fitting
    better; with 256 candidates the search found it in all five). The model keeps the
    better of its two fits. Skipped where the window held no more sites than the cap (the
    same candidates again), where the data leave the pose free (a motion that is not a
    symmetry of the model) and where the touch crosses a sharp edge of the model (the
    answer is then ``ambiguous`` anyway), and where every turn is a symmetry of the model
    (a sphere: every basin is the same pose).

    Returns ``(None, seconds)`` when skipped, else ``((recognition, noise, caution),
    seconds)``; ``caution`` is "" unless the better pose moves the data by more
    than ``defaults.CONFIRM_MOVED_FRACTION`` of the curves' half-length.
    """
    best = rec.ranking[0]
    if best.rejected or best.candidates < defaults.MAX_CANDIDATES:
        return None, 0.0
    t0 = time.perf_counter()
    with timed("freedom"):
        # A pose the data leave free (a slide along a cylinder's side) is never
        # `recognised` (_with_pose_freedom), nor is one touch across a sharp edge of the
        # model (_across_an_edge): nothing to confirm, and such touches of the bundled
        # cylinders paid a second registration for it (0.3 to 0.6 s).
        model = {m.name: m for m in models}[best.model]
        freedom = _free_motions(rec, model)[0]
        # every turn a symmetry (a sphere): every basin is the same pose, none to miss
        free = freedom.unresolved or freedom.turns >= 3
        points = apply_transform(best.T_model_touch, rec.touch.points)
        crossed = patches_crossed(model, points)
    if free or crossed > 1:
        return None, time.perf_counter() - t0
    # the first pass's window (not widened), more candidates in it
    looks = {"max_candidates": defaults.CONFIRM_CANDIDATES, "lookup_scale": 1.0}
    looks["only"] = frozenset({best.model})
    rec, noise, _ = _looked_again(rec, prior, models, method, run, "dense", **looks)
    after = next(r for r in rec.ranking if r.model == best.model)
    caution = ""
    points = np.c_[rec.touch.points, np.ones(rec.touch.n_points)]
    moved = (
        float(np.max(np.linalg.norm(points @ (after.T_model_touch - best.T_model_touch).T, axis=1)))
        if after is not best
        else 0.0
    )
    if moved > defaults.CONFIRM_MOVED_FRACTION * rec.geometry.half_length:
        caution = (
            f"the search of {best.model}, looked at again with up to "
            f"{defaults.CONFIRM_CANDIDATES} candidates before naming it, found a better pose "
            f"(RMS {after.rms:.3g} against {best.rms:.3g}; the data moved up to {moved:.3g})"
        )
    return (rec, noise, caution), time.perf_counter() - t0


def _explore_weak_motions_one(rec: Recognition, model) -> Recognition:
    """One touch about to name ``model``: its poses a long way along the best pose's
    weakest motions refined too, and kept among its poses.

    As for several touches (:func:`_explore_near_symmetries`): on a nearly symmetric
    stretch of the surface (the rounded edge of a boxy superquadric, nearly a cylinder
    there) a slide or turn of the touch fits almost as well, and the search, started
    from the candidates, can end in one such basin while the true pose lies in another.
    The local test then saw a fixed pose (a black-box probe, stop 33: `recognised`, the
    pose `fixed` and 0.355 off, 7 times its sigma, on an exact mesh; the true pose fits
    within 1% of its RMS). The poses found
    (:func:`~meshrec.recognition.weak.weak_motion_starts`, refined on all the points)
    join the model's; their weights then say whether the pose is one of several. Skipped
    where the data leave the pose free or every turn is a symmetry of the model (a
    sphere), as the confirmation is. Returns ``rec`` itself when nothing was explored.
    """
    best = rec.ranking[0]
    if best.rejected or best.T_model_touch is None:
        return rec
    freedom = _free_motions(rec, model)[0]
    if freedom.unresolved or freedom.turns >= 3:
        return rec
    starts = weak_motion_starts(model, rec.touch.points, best.T_model_touch)
    if not starts:
        return rec
    # refined coarse to fine, as for several touches (every start: the one nearest the
    # better basin is often the worst at its start)
    found = joint_poses(
        model,
        [rec.touch],
        starts,
        rec.geometry,
        best=len(starts),
        start_ratio=float("inf"),
    )
    reg = _with_more_poses(best, found, rec.touch, rec.geometry)
    return dataclasses.replace(rec, ranking=(reg, *rec.ranking[1:]))


def _with_more_poses(reg: Registration, found, touch: TouchData, geometry) -> Registration:
    """One touch's registration with the poses ``found`` among its own (distinct, least
    RMS first; a rejected one registered by them)."""
    if not found:
        return reg
    poses = distinct_poses(
        sorted((*reg.poses, *found), key=lambda p: p.rms), float(geometry.half_length)
    )
    top = poses[0]
    return dataclasses.replace(
        reg,
        poses=poses,
        T_model_touch=top.T_model_touch,
        error=top.error,
        rms=top.rms,
        contact=top.contact,
        normal=top.normal,
        phi=top.phi,
        n_points=int(touch.n_points),
    )


def _transferred(rec: Recognition, models: list, fits: dict, noise: float) -> Recognition:
    """About to name a model: its best poses refined on every other model, kept where they
    fit (:func:`~meshrec.recognition.joint.transfer_poses`).

    Variants of one part exported in one frame fit touches away from their difference at
    the same pose, and a variant's own search can end elsewhere: the variant whose search
    found the pose was named alone, at p 1.000 (a black-box probe, stop 33: brackets and
    levers with and without a hole, a chamfer or a boss; 21 of 204 several-touch answers).
    The named model's ``defaults.TRANSFER_POSES`` best poses are the seeds; a model where a
    seed starts within ``defaults.TRANSFER_REACH`` times the named model's RMS (or the
    noise, if larger) is refined from it. Models in other frames cost one query each.
    ``fits`` (several touches) is updated in place.
    """
    leader = rec.ranking[0]
    if leader.rejected or leader.T_model_touch is None:
        return rec
    seeds = [p.T_model_touch for p in leader.poses[: defaults.TRANSFER_POSES]]
    reach = defaults.TRANSFER_REACH * max(float(leader.rms), float(noise))
    by_name = {m.name: m for m in models}
    ranking = [leader]
    for reg in rec.ranking[1:]:
        model = by_name[reg.model]
        if len(rec.touches) > 1:
            fit = transfer_poses(rec.touches, model, rec.geometries, fits[reg.model], seeds, reach)
            fits[reg.model] = fit
            ranking.append(fit.registration)
        else:
            found = transferred_poses(rec.touches, model, rec.geometries, seeds, reach)
            ranking.append(_with_more_poses(reg, found, rec.touch, rec.geometry))
    return dataclasses.replace(rec, ranking=tuple(ranking))


def _inward_hint(rec: Recognition, reason: str) -> str:
    """An ``unknown`` reason, with a word on the touches whose given normal makes the
    surface concave at the contact (mean curvature below zero with it, convex against it):
    an outward normal given with the wrong sign turns a convex patch into a concave one,
    which no closed convex part of a model matches. Only a hint; the verdict stands."""
    inward = [
        k
        for k, (t, g) in enumerate(zip(rec.touches, rec.geometries, strict=True))
        if t.normal is not None and float(g.H) < 0.0
    ]
    if not inward:
        return reason
    if len(rec.touches) == 1:
        which = "the normal given with the touch makes"
    elif len(inward) == 1:
        which = f"the normal given with touch {inward[0] + 1} makes"
    else:
        which = "the normals given with touches " + ", ".join(str(k + 1) for k in inward)
        which += " make"
    return (
        f"{reason}; {which} the surface concave at the contact (mean curvature "
        f"{float(rec.geometries[inward[0]].H):.3g}): if it points into the object rather "
        "than out of it (an outward normal is minus the probe's approach direction), "
        "nothing convex can match; check its sign, or leave it out"
    )


def _across_an_edge(rec: Recognition, crossed: int) -> Recognition:
    """One touch whose data lie on more than one face or smooth patch of the named model
    (across a sharp edge) names no model: ``recognised`` becomes ``ambiguous``, the model
    alone in ``plausible``, and the reason says why."""
    if len(rec.touches) != 1 or rec.verdict != "recognised" or crossed < 2:
        return rec
    return dataclasses.replace(
        rec,
        verdict="ambiguous",
        reason=(
            f"{rec.reason}; the touch crosses a sharp edge of {rec.best.model} (its points "
            f"lie on {crossed} faces or smooth patches), and one touch across an edge is not "
            "enough to name a model: there the search may miss the right model's pose while "
            "another model fits; touch again away from the edge, or add touches"
        ),
    )


def _would_be_named(rec: Recognition, prior, n: int, noise: float) -> bool:
    """One touch: whether the scores name one model and the touch's own holds (its noise
    against its length, curve fits far rougher than the noise) leave it named."""
    v = _within_calibration(_decided(rec, prior, n, noise), rec)
    return _rough_hold(v, rec.geometries[0]).verdict == "recognised"


def _within_calibration(v: Verdict, rec: Recognition) -> Verdict:
    """One touch whose noise is too large against its curves' length
    (``defaults.SCORE_MAX_NOISE_FRACTION``) names no model: ``recognised`` becomes
    ``ambiguous``, the model alone in ``plausible``, and the reason says why."""
    if len(rec.touches) != 1 or v.verdict != "recognised":
        return v
    g = rec.geometry
    fraction = float(g.noise_rms) / float(g.half_length)
    if not fraction > defaults.SCORE_MAX_NOISE_FRACTION:
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but the touch's noise ({float(g.noise_rms):.3g}) is "
        f"{100 * fraction:.2g}% of the curves' half-length, beyond the "
        f"{100 * defaults.SCORE_MAX_NOISE_FRACTION:g}% up to which the probabilities were "
        "measured to hold: at that noise the curvature estimate and the search may miss "
        "the right model's pose; touch again with longer curves or a finer probe, or add "
        "touches",
        v.fit_ratio,
    )


def _rough_hold(v: Verdict, g: LocalGeometry) -> Verdict:
    """One touch whose curve fits leave more than ``defaults.ROUGH_HOLD_RATIO`` times the
    noise (beyond any touch the scores were measured on) names no model: ``recognised``
    becomes ``ambiguous``, the model alone in ``plausible``, and the reason says why."""
    if v.verdict != "recognised" or not (
        g.fit_to_noise > defaults.ROUGH_HOLD_RATIO
        and g.fit_rms > defaults.ROUGH_FIT_MIN_FRACTION * g.half_length
    ):
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but the curves fit no smooth surface patch: their fits leave "
        f"{g.fit_to_noise:.3g} times the noise the samples show (more than "
        f"defaults.ROUGH_HOLD_RATIO = {defaults.ROUGH_HOLD_RATIO:g}), so they cross an edge "
        "or a rim, where the curvature the search starts from is not defined and the right "
        "model's pose may be missed while another model fits; touch again away from edges, "
        "or add touches",
        v.fit_ratio,
    )


def _every_touch_hold(v: Verdict, rec: Recognition, fit, noise: float) -> Verdict:
    """Several touches: a model is named only if its pose fits every touch.

    The joint fit test pools the touches, so one touch that the named pose does not
    explain can hide among the others (a black-box probe, stop 33: a lever's mirror twin
    named at p 1.000, fitting two touches at 0.65 times the noise and the third at 1.3
    times, chi-square tail 5e-5; the lever's own search had missed its pose). Where a
    touch's own tail at the named pose is below ``defaults.UNKNOWN_P_VALUE``,
    ``recognised`` becomes ``ambiguous`` and the reason says which touch."""
    if v.verdict != "recognised":
        return v
    tails = [
        fit_p_value(r, int(t.n_points), noise, dof=0)
        for r, t in zip(fit.touch_rms, rec.touches, strict=True)
    ]
    k = int(np.argmin(tails))
    if tails[k] >= defaults.UNKNOWN_P_VALUE:
        return v
    return Verdict(
        "ambiguous",
        v.plausible,
        f"{v.reason}; but its pose fits touch {k + 1} at {fit.touch_rms[k] / noise:.3g} times "
        f"the noise (chi-square tail {tails[k]:.2g}, below defaults.UNKNOWN_P_VALUE = "
        f"{defaults.UNKNOWN_P_VALUE:g}): one rigid pose of it does not explain every touch; "
        "another model's pose may have been missed, or the object moved: touch again",
        v.fit_ratio,
    )


def _curvature_turn(geometry: LocalGeometry) -> float:
    """How far the curves would turn, in radians, over their half-length at the estimated
    curvature (the larger principal curvature's magnitude times the half-length)."""
    return max(abs(float(geometry.k1)), abs(float(geometry.k2))) * float(geometry.half_length)


def _decided(rec: Recognition, prior, n: int, noise: float) -> Verdict:
    """The verdict of the scores as they stand (a flat touch's prior never decides alone)."""
    names = [s.model for s in rec.scores]
    probs = [s.probability for s in rec.scores]
    top = rec.scores[0] if rec.scores else None
    v = decide(names, probs, None if top is None else top.rms, n, noise)
    if prior is not None:
        v = _with_data_plausible(v, rec.scores, n, noise)
    return v


def _would_recognise(rec: Recognition, prior, n: int, noise: float) -> bool:
    """Whether the scores as they stand name one model (``recognised``)."""
    return _decided(rec, prior, n, noise).verdict == "recognised"


def _fits_worse_than_noise(rec: Recognition, n: int, noise: float) -> bool:
    """Whether even the best-scored model (or none at all) fits worse than the noise allows."""
    return _fits_below(rec, n, noise, defaults.WIDEN_P_VALUE)


def _fits_below(rec: Recognition, n: int, noise: float, p_value: float) -> bool:
    """Whether even the best-scored model (or none at all) fits with a chi-square tail
    below ``p_value``."""
    best = rec.scores[0] if rec.scores else None
    return best is None or best.rms is None or fit_p_value(best.rms, n, noise) < p_value


def _fits_worse(rms: float, n: int, noise: float) -> bool:
    """Whether a fit's RMS is worse than the noise allows (``defaults.WIDEN_P_VALUE``)."""
    return fit_p_value(rms, n, noise) < defaults.WIDEN_P_VALUE


def _with_data_plausible(v: Verdict, scores, n: int, noise: float) -> Verdict:
    """The verdict of a flat touch: the prior orders the models but removes none that the
    data alone leave plausible, and it never makes one ``recognised`` alone."""
    if v.verdict == "unknown":
        return v
    names = [s.model for s in scores]
    data = decide(names, posterior([s.log_likelihood for s in scores]), scores[0].rms, n, noise)
    if data.verdict == "unknown":
        return v
    keep = set(v.plausible) | set(data.plausible)
    plausible = tuple(s.model for s in scores if s.model in keep)  # most probable first
    if len(plausible) == len(v.plausible) and v.verdict == data.verdict:
        return v
    reason = (
        f"the data cannot separate {len(plausible)} models ({', '.join(plausible)}) on this "
        "flat touch: they fit about equally well, and how often each one's surface is flat "
        "over the curves' reach orders them; touch again elsewhere to decide"
    )
    return Verdict("ambiguous", plausible, reason, v.fit_ratio)


def _flat_caution(scores, prior: dict) -> str:
    """The caution of a flat touch: the models weighed by their flat share."""
    top = max(prior.values())
    fitted = [s for s in scores if s.rms is not None][:4]
    shown = ", ".join(f"{s.model} {prior[s.model] / top:.2g}" for s in fitted)
    return (
        "a flat touch: the models it fits equally are weighed by the share of their surface "
        f"flat over the curves' reach (relative: {shown}); touch a curved part or an edge "
        "to decide"
    )


def _joint_unknown_reason(rec: Recognition, fits: dict, models: dict, noise: float) -> str:
    """Why several touches fit no model, when it is more than "not in the library"."""
    points = np.array([g.point for g in rec.geometries])
    span = float(np.max(np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)))
    largest = max(float(np.linalg.norm(np.ptp(m.mesh.vertices, axis=0))) for m in models.values())
    if span > largest:
        return (
            f"the touches' contacts lie up to {span:.4g} apart, farther than the largest "
            f"model is long ({largest:.4g}): they cannot all be on one object of the library "
            "(touches given in different frames, or the object moved)"
        )
    for reg in rec.ranking:  # most probable first
        fit = fits.get(reg.model)
        if reg.rejected or fit is None or fit.registered < len(rec.touches):
            continue
        if all(
            _fits_alone(r, t, g)
            for r, t, g in zip(fit.single, rec.touches, rec.geometries, strict=True)
        ):
            best = rec.best
            lead = (
                f"the best joint fit, {best.model}'s, leaves {best.rms / noise:.3g} times the "
                f"noise; "
                if best is not None and best.model != reg.model and best.rms is not None
                else ""
            )
            return (
                f"{lead}each touch alone fits {reg.model} to the noise, but no one rigid pose "
                f"fits them all (its joint RMS residual {reg.rms:.3g}, {reg.rms / noise:.3g} "
                f"times the noise {noise:.3g}): the object moved between touches, or it is not "
                "in the library"
            )
    # Each touch alone fits some model, but not the same one: touches of different objects.
    fitting = []
    for k, (touch, geometry) in enumerate(zip(rec.touches, rec.geometries, strict=True)):
        names = [
            reg.model
            for reg in rec.ranking
            if not reg.rejected
            and (fit := fits.get(reg.model)) is not None
            and fit.registered > k
            and _fits_alone(fit.single[k], touch, geometry)
        ]
        fitting.append(names)
    if all(fitting):
        which = "; ".join(
            f"touch {k + 1}: {', '.join(names[:3])}" for k, names in enumerate(fitting)
        )
        return (
            f"each touch alone fits a model of the library ({which}), but no model fits "
            "them all at one pose: the touches may be of different objects, or the object "
            "moved between them"
        )
    if not any(fitting):
        return ""
    # Some touches alone fit a model, the others none (a black-box probe, stop 33: an
    # object turned before its third touch, which crossed a rim, was blamed on the rim
    # and the library alone).
    groups: dict[tuple, list[int]] = {}
    for k, names in enumerate(fitting):
        if names:
            groups.setdefault(tuple(names[:3]), []).append(k + 1)
    fit_part = "; ".join(
        f"touch {ks[0]} fits {', '.join(names)}"
        if len(ks) == 1
        else f"touches {', '.join(map(str, ks[:-1]))} and {ks[-1]} each fit {', '.join(names)}"
        for names, ks in groups.items()
    )
    misfits = [k for k, names in enumerate(fitting) if not names]
    listed = " and ".join(str(k + 1) for k in misfits)
    which = f"touch {listed} fits" if len(misfits) == 1 else f"touches {listed} fit"
    rough = [k for k in misfits if rec.geometries[k].fit_to_noise > defaults.ROUGH_FIT_RATIO]
    edge = (
        ", or cross an edge or a rim (its curves fit no smooth surface patch), where the "
        "search is less reliable"
        if rough
        else ""
    )
    best = rec.best
    lead = (
        f"the best joint fit, {best.model}'s, leaves {best.rms / noise:.3g} times the noise; "
        if best is not None and best.rms is not None
        else ""
    )
    return (
        f"{lead}alone, {fit_part} to the noise, but {which} no model alone: the object may "
        f"have moved between the touches, or {'that touch' if len(misfits) == 1 else 'those'} "
        f"may be of another object{edge}; or the object is not in the library"
    )


def _fits_alone(reg, touch: TouchData, geometry: LocalGeometry) -> bool:
    """Whether a single-touch registration fits its touch to that touch's own noise."""
    if reg.rejected:
        return False
    noise = noise_estimate(geometry.fit_rms, geometry.noise_rms, geometry.half_length)
    return fit_p_value(reg.rms, int(touch.n_points), noise) >= defaults.UNKNOWN_P_VALUE
