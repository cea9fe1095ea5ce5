"""Pose freedom: which rigid motions the touch data leave unconstrained at a fitted pose.

A touch on a flat face fixes the pose only up to two slides on the face and a turn about its
normal; on a cylinder's side, up to a slide along and a turn about its axis; on a sphere, up
to three turns about its centre. The point-to-surface residuals then do not change (to first
order) along those motions, whatever the optimiser reports as "the" pose.

The test is the rank of the rigid Jacobian of the residuals at the pose: one row
``[n_i, (x_i - c) / L x n_i]`` per data point ``x_i`` (model frame) with the surface normal
``n_i`` at its closest point, ``c`` the points' centroid and ``L`` their RMS distance from
it (so slides and turns are measured alike: a turn of one radian moves the points by about
``L``). A right singular vector whose singular value is below
``defaults.POSE_FREE_RATIO`` times the largest is a free motion. The free subspace is then
split into turns (the rank of its rotational part) and slides (the motions in it with no
rotation); a slide's direction and a turn's axis are reported in the model frame.

A pose can also be one of a few distinct ones that fit equally well: touches near a box's
corner fit it as well after a third of a turn about the corner's diagonal, where no motion
is free. :func:`with_alternatives` counts the poses among the model's weighted hypotheses
that are not symmetries of the model of the reported one and that the data cannot rule
out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import check_points

__all__ = ["PoseFreedom", "pose_freedom", "pose_sigma", "with_alternatives", "with_symmetries"]


@dataclass(frozen=True, eq=False)
class PoseFreedom(ValueEquality):
    """The rigid motions the data leave free at a pose.

    Attributes
    ----------
    free : int
        Number of free rigid degrees of freedom (0 to 6): ``slides + turns``.
    slides : int
        Free translations.
    turns : int
        Free rotations (possibly with a translation along or across their axis).
    slide_directions : (slides, 3) float64
        Unit directions of the free translations, model frame (orthonormal).
    turn_axes : (turns, 3) float64
        Unit axes of the free rotations, model frame.
    turn_points : (turns, 3) float64
        A point on each turn's axis, model frame (the closest to the data's centroid).
    singular_values : (6,) float64
        The Jacobian's singular values relative to the largest, descending.
    ratio : float
        The threshold below which a singular value counted as free.
    slide_symmetric, turn_symmetric : tuple of bool
        Per slide and per turn, whether it is a symmetry of the whole model (a turn about
        a cylinder's or a sphere's axis: no touch anywhere can fix it, and the contact is
        known all the same), when checked (:func:`with_symmetries`); empty otherwise.
    sigma : float
        How precisely the data fix the pose: the largest one-sigma displacement of a data
        point along the least-constrained motion (:func:`pose_sigma`), model units; NaN
        when not computed, ``inf`` when a motion is free.
    alternatives : int
        Distinct poses besides the reported one, none a symmetry of the model of another,
        that the data cannot rule out (:func:`with_alternatives`); 0 when not checked.
    pose_weight : float
        The weight of the reported pose and the poses grouped with it (a symmetry of the
        model, or a motion within the tolerance: :func:`with_alternatives`) among the
        model's pose hypotheses; NaN when not checked.
    twin_apart : float
        How far apart, at most, the poses grouped with the reported one because they move
        the model (almost) onto itself place the data points: a symmetry's or a
        near-symmetry's twins (a slightly oval cylinder turned), which fit as well and
        leave the object where it was, but not the touch; 0 when there are none or when
        not checked. The description then says so.
    """

    free: int
    slides: int
    turns: int
    slide_directions: np.ndarray
    turn_axes: np.ndarray
    turn_points: np.ndarray
    singular_values: np.ndarray
    ratio: float
    slide_symmetric: tuple[bool, ...] = ()
    turn_symmetric: tuple[bool, ...] = ()
    sigma: float = float("nan")
    alternatives: int = 0
    pose_weight: float = float("nan")
    twin_apart: float = 0.0

    @property
    def unresolved(self) -> int:
        """Free motions that are not symmetries of the model: another touch can fix them."""
        return self.free - sum(self.slide_symmetric) - sum(self.turn_symmetric)

    @property
    def fixed(self) -> bool:
        """Whether the data fix the pose: no free motion that is not a symmetry of the
        model, and no distinct pose that fits about as well (``alternatives``)."""
        return self.unresolved == 0 and self.alternatives == 0

    @property
    def names(self) -> tuple[str, ...]:
        """``("slide", ..., "turn", ...)``: one name per free degree of freedom."""
        return ("slide",) * self.slides + ("turn",) * self.turns

    @property
    def description(self) -> str:
        """A short phrase: "fixed", "fixed up to the model's symmetry (1 turn)", e.g.
        "free: 2 slides and 1 turn", or "one of 2 poses that fit about equally well (this
        one's weight 0.50)"."""
        if self.alternatives:
            text = (
                f"one of {self.alternatives + 1} poses that fit about equally well (this "
                f"one's weight {self.pose_weight:.2f})"
            )
            return text if self.free == 0 else f"{text}; {self._free_phrase()}"
        if self.free == 0:
            if self.twin_apart > 0.0:
                return (
                    "fixed up to a symmetry or near-symmetry of the model (poses that place "
                    f"the data up to {self.twin_apart:.3g} apart fit as well and leave the "
                    "model where it is)"
                )
            return "fixed"
        if self.unresolved == 0:
            # every free motion a symmetry of the model: the pose is fixed (a probe read
            # "free: 1 turn (1 of them a symmetry of the model)" beside fixed = True as
            # contradicting it)
            return f"fixed up to the model's symmetry ({self._motions()})"
        return self._free_phrase()

    def _motions(self) -> str:
        """E.g. "2 slides and 1 turn"."""
        words = []
        if self.slides:
            words.append(f"{self.slides} slide{'s' if self.slides > 1 else ''}")
        if self.turns:
            words.append(f"{self.turns} turn{'s' if self.turns > 1 else ''}")
        return " and ".join(words)

    def _free_phrase(self) -> str:
        """E.g. "free: 2 slides and 1 turn (1 of them a symmetry of the model)"."""
        text = "free: " + self._motions()
        symmetric = sum(self.slide_symmetric) + sum(self.turn_symmetric)
        if symmetric:
            text += f" ({symmetric} of them a symmetry of the model)"
        return text

    def to_dict(self) -> dict:
        """JSON-ready: ``free``, ``slides``, ``turns``, ``names``, ``description``,
        ``slide_directions``, ``turn_axes``, ``turn_points``, ``singular_values``, the
        symmetry flags, ``unresolved``, ``sigma`` (None when NaN or infinite),
        ``alternatives``, ``pose_weight`` (None when NaN), ``twin_apart`` and ``fixed``."""
        return {
            "free": int(self.free),
            "slides": int(self.slides),
            "turns": int(self.turns),
            "names": list(self.names),
            "description": self.description,
            "slide_directions": self.slide_directions.tolist(),
            "turn_axes": self.turn_axes.tolist(),
            "turn_points": self.turn_points.tolist(),
            "singular_values": self.singular_values.tolist(),
            "slide_symmetric": list(self.slide_symmetric),
            "turn_symmetric": list(self.turn_symmetric),
            "unresolved": int(self.unresolved),
            "sigma": float(self.sigma) if np.isfinite(self.sigma) else None,
            "alternatives": int(self.alternatives),
            "pose_weight": float(self.pose_weight) if np.isfinite(self.pose_weight) else None,
            "twin_apart": float(self.twin_apart),
            "fixed": bool(self.fixed),
        }

    def __repr__(self) -> str:
        return f"PoseFreedom({self.description}, smallest={self.singular_values[-1]:.2g})"


def pose_freedom(
    points: np.ndarray, normals: np.ndarray, ratio: float = defaults.POSE_FREE_RATIO
) -> PoseFreedom:
    """The rigid motions that leave the point-to-surface residuals unchanged to first order.

    Parameters
    ----------
    points : (n, 3) float
        The data points at the fitted pose, model frame; at least 6.
    normals : (n, 3) float
        The surface normal at each point's closest point (the residual's gradient); need
        not be unit (it is normalised).
    ratio : float
        A singular value below ``ratio`` times the largest is free; in (0, 1).

    Returns
    -------
    PoseFreedom

    Raises
    ------
    TypeError
        If ``points`` is not an array of real numbers.
    ValueError
        If ``points`` is not (n, 3) finite with n >= 6 or its points all coincide,
        ``normals`` does not have the same shape, is not finite or has a zero row, or
        ``ratio`` is not in (0, 1).
    """
    J, _, c, scale = _rigid_jacobian(points, normals)
    if not (isinstance(ratio, (int, float)) and 0.0 < float(ratio) < 1.0):
        raise ValueError(f"ratio must be a number in (0, 1), got {ratio!r}")
    _, s, vt = np.linalg.svd(J, full_matrices=False)
    rel = s / s[0]
    null = vt[rel < ratio]  # (k, 6) orthonormal free twists
    k = len(null)
    slides_dirs = np.zeros((0, 3))
    axes = np.zeros((0, 3))
    pts = np.zeros((0, 3))
    if k:
        # Split the free subspace: combinations with no rotational part are slides; the
        # rest (the rank of the rotational block) are turns.
        u, sw, _ = np.linalg.svd(null[:, 3:], full_matrices=True)
        sw = np.concatenate([sw, np.zeros(k - len(sw))])
        turning = sw > defaults.POSE_TURN_FRACTION
        twists = u.T @ null  # (k, 6), rotated basis of the free subspace
        slides_dirs = _orthonormal(twists[~turning, :3])
        axes, pts = [], []
        for tw in twists[turning]:
            t, w = tw[:3], tw[3:] / scale  # the rotation in radians per unit twist
            axes.append(w / np.linalg.norm(w))
            pts.append(c + np.cross(w, t) / float(w @ w))
        axes = np.array(axes).reshape(-1, 3)
        pts = np.array(pts).reshape(-1, 3)
    return PoseFreedom(
        free=k,
        slides=len(slides_dirs),
        turns=len(axes),
        slide_directions=slides_dirs,
        turn_axes=axes,
        turn_points=pts,
        singular_values=rel,
        ratio=float(ratio),
    )


def pose_sigma(
    points: np.ndarray,
    normals: np.ndarray,
    noise: float,
    ess_fraction: float = defaults.SCORE_ESS_FRACTION,
    leave_out: int = 0,
) -> float:
    """How far the pose's least-squares uncertainty moves the data points, one sigma.

    Linearised at the fitted pose, the residuals change by ``J theta`` for a twist
    ``theta`` (the rows of :func:`pose_freedom`), so the fitted twist has covariance
    ``noise^2 / ess_fraction (J^T J)^-1`` (each point worth ``ess_fraction`` of an
    independent one, as in the scores). Along each principal direction ``v_k`` of ``J``
    (singular value ``s_k``) the twist's standard deviation is
    ``noise / sqrt(ess_fraction) / s_k``; the result is the largest, over the directions,
    of that times the largest displacement of a data point under the unit twist ``v_k``.

    Parameters
    ----------
    points : (n, 3) float
        The data points at the fitted pose, model frame; at least 6.
    normals : (n, 3) float
        The surface normal at each point's closest point (normalised here).
    noise : float
        Noise standard deviation per point, model units (> 0).
    ess_fraction : float
        Effective fraction of independent points, in (0, 1].
    leave_out : int
        The this many least-constrained directions are left out (0 to 5): the free
        motions that are symmetries of the model, which move nothing that matters.

    Returns
    -------
    float
        Model units; ``inf`` when a motion left in is unconstrained (a zero singular
        value).

    Raises
    ------
    TypeError
        If ``points`` is not an array of real numbers.
    ValueError
        If ``points`` or ``normals`` is invalid (as :func:`pose_freedom`), ``noise`` is
        not positive and finite, ``ess_fraction`` is not in (0, 1] or ``leave_out`` is
        not an integer in 0 to 5.
    """
    J, r, _, _ = _rigid_jacobian(points, normals)
    if not (isinstance(noise, (int, float)) and np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be a positive finite number, got {noise!r}")
    if not (isinstance(ess_fraction, (int, float)) and 0.0 < ess_fraction <= 1.0):
        raise ValueError(f"ess_fraction must be a number in (0, 1], got {ess_fraction!r}")
    if (
        not isinstance(leave_out, (int, np.integer))
        or isinstance(leave_out, bool)
        or not (0 <= leave_out <= 5)
    ):
        raise ValueError(f"leave_out must be an integer in 0 to 5, got {leave_out!r}")
    _, s, vt = np.linalg.svd(J, full_matrices=False)
    keep = 6 - int(leave_out)
    s, vt = s[:keep], vt[:keep]
    if s[-1] <= s[0] * 1e-12:
        return float("inf")
    # a unit twist (t, w) moves point i by t + w x r_i
    moves = vt[:, None, :3] + np.cross(vt[:, None, 3:], r[None, :, :])  # (6, n, 3)
    reach = np.linalg.norm(moves, axis=2).max(axis=1)  # (6,)
    return float((noise / np.sqrt(ess_fraction) / s * reach).max())


def _rigid_jacobian(points, normals) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The rigid Jacobian of the residuals, checked: ``(J, r, c, L)``.

    Velocity of a point under the twist (t, w): t + w x (x - c) / L; its normal part is
    n . t + ((x - c) / L x n) . w, one row ``[n, r x n]`` per point, ``r = (x - c) / L``.
    """
    x = check_points(points, "points", min_rows=6)
    n = np.asarray(normals, dtype=np.float64)
    if n.shape != x.shape or not np.all(np.isfinite(n)):
        raise ValueError(
            f"normals must be finite with the shape of points {x.shape}, got shape {n.shape}"
        )
    length = np.linalg.norm(n, axis=1)
    if np.any(length <= 0.0):
        raise ValueError(f"normals must not have zero rows, got {int(np.sum(length <= 0))}")
    n = n / length[:, None]
    c = x.mean(axis=0)
    scale = float(np.sqrt(((x - c) ** 2).sum(axis=1).mean()))
    if scale <= 0.0:
        raise ValueError("points must not all coincide")
    r = (x - c) / scale
    return np.hstack([n, np.cross(r, n)]), r, c, scale


def with_symmetries(
    freedom: PoseFreedom, vertices: np.ndarray, distance, tolerance: float
) -> PoseFreedom:
    """``freedom`` with each free slide and turn checked for a symmetry of the whole model.

    A free motion is a symmetry when the model's vertices, moved by a finite step of it (a
    turn of ``defaults.POSE_SYMMETRY_TURN_DEG`` about the turn's axis, a slide of
    ``defaults.POSE_SYMMETRY_SLIDE`` times the model's diagonal), all stay within
    ``tolerance`` of the model's surface.

    Parameters
    ----------
    freedom : PoseFreedom
    vertices : (V, 3) float
        The model's vertices (a subsample will do).
    distance : callable
        ``distance(points (n, 3)) -> (n,)`` unsigned distances to the model's surface.
    tolerance : float
        The largest distance a symmetric motion may leave, model units (the mesh's own
        facet error and more).

    Returns
    -------
    PoseFreedom

    Raises
    ------
    ValueError
        If ``vertices`` is not (V, 3) finite with V >= 1 or ``tolerance`` is not positive.
    """
    v = check_points(vertices, "vertices", min_rows=1)
    if not (isinstance(tolerance, (int, float)) and float(tolerance) > 0.0):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))

    def stays(moved: np.ndarray) -> bool:
        return _stays(distance, moved, float(tolerance))

    slides = tuple(
        stays(v + defaults.POSE_SYMMETRY_SLIDE * diagonal * d) for d in freedom.slide_directions
    )
    angle = np.radians(defaults.POSE_SYMMETRY_TURN_DEG)
    turns = []
    for a, p in zip(freedom.turn_axes, freedom.turn_points, strict=True):
        # Rodrigues' rotation about the axis (a, p).
        k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        R = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)
        turns.append(stays((v - p) @ R.T + p))
    return replace(freedom, slide_symmetric=slides, turn_symmetric=tuple(turns))


def with_alternatives(
    freedom: PoseFreedom,
    poses: np.ndarray,
    weights: np.ndarray,
    vertices: np.ndarray,
    distance,
    tolerance: float,
    coverage: float = defaults.VERDICT_COVERAGE,
    *,
    points: np.ndarray | None = None,
    within: float = 0.0,
) -> PoseFreedom:
    """``freedom`` with the distinct poses that the data cannot rule out counted.

    Two poses ``T_a`` and ``T_b`` (both ``T_model_touch``) put the object at the same place
    in the touch frame when ``T_a T_b^-1`` is a symmetry of the model: the model's
    vertices, moved by it, all stay within ``tolerance`` of its surface (the test of
    :func:`with_symmetries`); or when they place the data ``points`` within ``within`` of
    each other (a second basin inside the pose's own uncertainty). A near-symmetry of the
    model, such as a scanned can turned upside down, moves the model less than the data's
    precision but the touch by centimetres: two such poses are distinct answers, not one.
    The poses are grouped by that test, in the order given, each into the first group
    whose first pose it equals; the reported pose (the first) leads the first group.
    ``twin_apart`` is how far apart the poses grouped with the reported one by the model
    test (not by the data's ``within``) place the ``points``. ``pose_weight`` is that
    group's weight, and ``alternatives`` the
    number of other groups needed, heaviest first, for the weights to reach ``coverage``:
    the poses of the model the data cannot tell apart (as the plausible set does for
    models, :func:`meshrec.recognition.scoring.plausible_set`).

    When the first pose's own weight reaches ``coverage`` nothing is tested: no
    alternative, and ``pose_weight`` is that weight. Poses of weight below
    ``defaults.POSE_ALTERNATIVE_MIN_WEIGHT`` are not tested either (together they cannot
    tip the coverage by more than their sum).

    Parameters
    ----------
    freedom : PoseFreedom
    poses : (k, 4, 4) float
        The model's distinct pose hypotheses (``T_model_touch``), the reported one first;
        k >= 1.
    weights : (k,) float
        Their weights (summing to 1; :func:`meshrec.recognition.scoring.pose_weights`).
    vertices : (V, 3) float
        The model's vertices (a subsample will do).
    distance : callable
        ``distance(points (n, 3)) -> (n,)`` unsigned distances to the model's surface.
    tolerance : float
        The largest distance a symmetry may leave, model units.
    coverage : float
        In (0, 1].
    points : (n, 3) float or None
        The data points, touch frame (None: only the symmetry test).
    within : float
        How far two poses may place each of ``points`` apart and be one pose; at least 0.

    Returns
    -------
    PoseFreedom

    Raises
    ------
    ValueError
        If ``poses`` is not (k, 4, 4) finite with k >= 1, ``weights`` not (k,) finite and
        non-negative, ``vertices`` not (V, 3) finite with V >= 1, ``tolerance`` not
        positive, ``coverage`` not in (0, 1], ``points`` not (n, 3) finite or ``within``
        negative or not finite.
    """
    T = np.asarray(poses, dtype=np.float64)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) == 0 or not np.isfinite(T).all():
        raise ValueError(f"poses must be (k, 4, 4) finite with k >= 1, got shape {T.shape}")
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(T),) or not np.isfinite(w).all() or (w < 0).any():
        raise ValueError(
            f"weights must be ({len(T)},) finite and non-negative, got {np.asarray(weights)!r}"
        )
    v = check_points(vertices, "vertices", min_rows=1)
    if not (isinstance(tolerance, (int, float)) and float(tolerance) > 0.0):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    if not (isinstance(coverage, (int, float)) and 0.0 < float(coverage) <= 1.0):
        raise ValueError(f"coverage must be a number in (0, 1], got {coverage!r}")
    x = None if points is None else check_points(points, "points", min_rows=1)
    if not (isinstance(within, (int, float)) and np.isfinite(within) and within >= 0.0):
        raise ValueError(f"within must be a finite number >= 0, got {within!r}")
    if w[0] >= coverage:
        return replace(freedom, alternatives=0, pose_weight=float(w[0]))
    leaders: list[int] = [0]
    group_weight = [float(w[0])]
    twin_apart = 0.0
    for i in range(1, len(T)):
        if w[i] < defaults.POSE_ALTERNATIVE_MIN_WEIGHT:
            continue
        for g, j in enumerate(leaders):
            # T_j T_i^-1 maps the model onto itself when the two poses agree.
            D = T[j] @ np.linalg.inv(T[i])
            apart = _apart(T[i], T[j], x) if x is not None else 0.0
            if x is not None and apart <= within:
                group_weight[g] += float(w[i])
                break
            if _stays(distance, v @ D[:3, :3].T + D[:3, 3], float(tolerance)):
                group_weight[g] += float(w[i])
                if g == 0:
                    twin_apart = max(twin_apart, apart)
                break
        else:
            leaders.append(i)
            group_weight.append(float(w[i]))
    total = group_weight[0]
    alternatives = 0
    for gw in sorted(group_weight[1:], reverse=True):
        if total >= coverage:
            break
        total += gw
        alternatives += 1
    return replace(
        freedom, alternatives=alternatives, pose_weight=group_weight[0], twin_apart=twin_apart
    )


def _apart(T_a: np.ndarray, T_b: np.ndarray, x: np.ndarray) -> float:
    """How far apart the two poses place the points ``x`` at most."""
    D = T_a - T_b
    return float(np.max(np.linalg.norm(x @ D[:3, :3].T + D[:3, 3], axis=1)))


def _stays(distance, moved: np.ndarray, tolerance: float) -> bool:
    """Whether every point of ``moved`` is within ``tolerance`` of the surface.

    A spread subset (every ``defaults.POSE_SYMMETRY_PROBE_STRIDE``-th point) is queried
    first: most motions tested are not symmetries, and one point off the surface settles
    it (the decision is the same as on all the points, whose largest distance is at least
    the subset's)."""
    stride = defaults.POSE_SYMMETRY_PROBE_STRIDE
    if len(moved) > stride and float(np.max(np.asarray(distance(moved[::stride])))) > tolerance:
        return False
    return bool(float(np.max(np.asarray(distance(moved)))) <= tolerance)


def _orthonormal(vectors: np.ndarray) -> np.ndarray:
    """An orthonormal basis (rows) of the span of ``vectors`` (k, 3)."""
    if len(vectors) == 0:
        return np.zeros((0, 3))
    _, s, vt = np.linalg.svd(vectors, full_matrices=False)
    return vt[s > 1e-9 * max(float(s[0]), 1e-300)]
