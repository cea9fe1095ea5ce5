"""The pose given with the answer: which rigid motions the data leave free at the best
pose, which of them are symmetries of the model, and how precisely the rest is fixed.

A free pose is never ``recognised`` (:func:`with_pose_freedom`). The test
(:func:`free_motions`) is also what the passes before naming ask before they look for
other poses (:mod:`meshrec.recognition.naming`): it is computed once per model and pose
when they share a ``memo``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from meshrec import defaults
from meshrec.recognition.freedom import (
    PoseFreedom,
    pose_freedom,
    pose_sigma,
    with_alternatives,
    with_symmetries,
)
from meshrec.recognition.result import Recognition
from meshrec.registration.objective import residuals
from meshrec.registration.transform import apply_transform

__all__ = ["free_motions", "with_pose_freedom"]


def with_pose_freedom(rec: Recognition, models: list, memo: dict | None = None) -> Recognition:
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
    freedom, on_surface, normals = free_motions(rec, model, memo)
    sigma = float("inf")
    if freedom.unresolved == 0 and rec.noise is not None and rec.noise > 0:
        # how precisely the data fix the pose, the symmetries' free motions left out
        sigma = pose_sigma(on_surface, normals, float(rec.noise), leave_out=freedom.free)
    freedom = dataclasses.replace(freedom, sigma=sigma)
    score = next((s for s in rec.scores if s.model == best.model), None)
    if score is not None and score.poses and freedom.unresolved == 0:
        # Distinct poses (a free motion already leaves the pose open). Two poses that move
        # the data by less than a few times the pose's own precision are one, as are two
        # related by a symmetry of the model, or by a motion that moves the whole model by
        # less than half that precision (no touch could tell them apart).
        vertices, distance, tolerance = _symmetry_test(model)
        weights = np.array([p.weight for p in score.poses])
        within = defaults.POSE_ALTERNATIVE_SIGMAS * sigma if np.isfinite(sigma) else 0.0
        symmetric = defaults.POSE_SYMMETRY_SIGMAS * sigma if np.isfinite(sigma) else 0.0
        # (the tolerance, whose chord error costs a pass over the mesh, only when a pose
        # is compared: not when the reported one alone reaches the coverage)
        needed = weights[0] < defaults.VERDICT_COVERAGE
        freedom = with_alternatives(
            freedom,
            np.array([p.T_model_touch for p in score.poses]),
            weights,
            vertices,
            distance,
            max(tolerance(), symmetric) if needed else float("inf"),
            points=np.vstack([t.points for t in (rec.touches or (rec.touch,))]),
            within=within,
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


def free_motions(rec: Recognition, model, memo: dict | None = None):
    """The rigid motions the data leave free at the best pose, the model's symmetries
    marked: ``(PoseFreedom, points on the surface (n, 3), their normals (n, 3))``, the
    points the test used.

    ``memo`` (a dict shared by the calls of one recognition, whose touches do not change)
    keeps each (model, pose)'s answer: the passes before naming and the answer's own test
    ask it of the same pose (about 6 ms each on the bundled 80,000-face objects)."""
    key = (model.name, np.asarray(rec.best.T_model_touch, dtype=np.float64).tobytes())
    if memo is not None and key in memo:
        return memo[key]
    found = _free_motions(rec, model)
    if memo is not None:
        memo[key] = found
    return found


def _free_motions(rec: Recognition, model):
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
    return (
        V[::step],
        lambda p: model.surface.closest_points(p)[0],
        lambda: model.symmetry_tolerance,
    )


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
