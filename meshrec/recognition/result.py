"""The result of a recognition: the models ranked, scored and judged."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from meshrec._values import ValueEquality
from meshrec.contact.geometry import LocalGeometry
from meshrec.io.touch import TouchData
from meshrec.recognition.freedom import PoseFreedom
from meshrec.recognition.phases import PhaseTimes
from meshrec.recognition.probing import ProbeOffset
from meshrec.recognition.scoring import ModelScore
from meshrec.registration.register import Registration

__all__ = ["Recognition"]


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
    search_doubt : bool
        Whether the touch is one where a model's search can miss its pose: one touch
        across a sharp edge of the best model, or curves that fit no smooth surface patch
        (across an edge or a rim). Then an ``unknown`` answer's object may still be in
        the library, and an ``ambiguous`` answer's touched model may be missing from
        ``plausible``; ``reason`` says which. Never True for ``recognised``.
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
    search_doubt: bool = False
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
