"""Where to touch next: the contact and approach that best decide what the touches left open.

After a recognition, the remaining (model, pose) hypotheses are weighed by their
probabilities (model probability x pose weight). Candidate contacts are sampled on their
surfaces (in the touches' world frame), the unreachable ones dropped (the probe needs a cone
of free space around its approach ray; an optional direction hint says where the robot
can come from; a place already touched tells nothing new), and each candidate is scored:

- ``"separate"``: the expected information gain about which hypothesis is true (mutual
  information, nats). If hypothesis ``h`` is the truth, the next touch lands where the
  candidate's approach line first meets ``h``'s surface (nothing is learnt under ``h``
  where it misses); a small patch of points there (three chords of the curves'
  length) lies at RMS distance ``d(h, h')`` from every other hypothesis ``h'``, and the
  posterior after the touch is ``p(h' | h) ~ w_h' exp(-n_eff d(h, h')^2 / (2 noise^2))``
  (the likelihood of :mod:`meshrec.recognition.scoring`). The gain is
  ``H(w) - sum_h w_h H(p(. | h))``.
- ``"pose"``: when one model at one pose is recognised (or no reachable place separates
  the hypotheses: symmetric poses), the D-optimal touch for the pose: the largest increase
  of the log-determinant of the point-to-plane information matrix of the 6 pose
  parameters.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import igl
import numpy as np

from meshrec import defaults
from meshrec._values import ValueEquality
from meshrec.io.checks import (
    check_instance,
    check_int,
    check_number,
    check_rng,
    check_transform,
    check_vector,
)
from meshrec.model.index import ModelIndex
from meshrec.model.library import ModelLibrary
from meshrec.recognition.result import Recognition
from meshrec.recognition.scoring import effective_points

__all__ = ["CRITERIA", "TouchAdvice", "next_touch", "point_text"]

#: The two criteria a touch is chosen by.
CRITERIA = ("separate", "pose")


@dataclass(frozen=True, eq=False)
class TouchAdvice(ValueEquality):
    """Where to touch next, and why.

    Attributes
    ----------
    point : (3,) float64 or None
        The contact to aim at, in the touches' (world) frame, on the surface of the
        hypothesis it was sampled from; None when no candidate is reachable.
    direction : (3,) float64 or None
        Unit approach direction, pointing into the object (minus the outward normal
        there); None with ``point``.
    expected_gain : float
        Expected information gain of the touch, nats: about which hypothesis is true
        (``"separate"``) or about the pose (``"pose"``); 0 when there is no advice.
    criterion : str
        ``"separate"`` (tell models or poses apart) or ``"pose"`` (pin down the pose of
        the recognised model).
    models : tuple of str
        The models whose hypotheses were weighed, most probable first.
    reason : str
        One sentence: where, from where, and why there (or why nowhere).
    seconds : float
        Wall time of :func:`next_touch`.
    """

    point: np.ndarray | None
    direction: np.ndarray | None
    expected_gain: float
    criterion: str
    models: tuple[str, ...]
    reason: str
    seconds: float = dataclasses.field(compare=False)

    def __post_init__(self) -> None:
        for name in ("point", "direction"):
            value = getattr(self, name)
            if value is not None:
                arr = np.array(value, dtype=np.float64)
                arr.setflags(write=False)
                object.__setattr__(self, name, arr)

    def __repr__(self) -> str:
        if self.point is None:
            where = "point=None"
        else:
            where = f"point={point_text(self.point)}, direction={point_text(self.direction)}"
        return (
            f"TouchAdvice({self.criterion!r}, {where}, "
            f"expected_gain={self.expected_gain:.3g}, models={list(self.models)}, "
            f"seconds={self.seconds:.3f})"
        )


@dataclass(frozen=True)
class _Hypothesis:
    """One (model, pose) hypothesis in the world frame, with its renormalised weight."""

    name: str
    model: ModelIndex
    weight: float
    T_world_model: np.ndarray
    T_model_world: np.ndarray
    side: float  # +1, or -1 for an open mesh touched on the side its winding points away


@dataclass(frozen=True)
class _Candidates:
    """Candidate contacts: world points and approach directions, with their source."""

    world: np.ndarray  # (n, 3) contact points, world frame
    approach: np.ndarray  # (n, 3) unit approach directions (into the object), world frame
    source: np.ndarray  # (n,) int: the hypothesis each was sampled on
    sampled: int  # how many were sampled before any was dropped
    blocked: int  # dropped: no free cone around the approach ray
    off_hint: int  # dropped: too far from the approach hint
    touched: int  # dropped: too close to a touch already made


def next_touch(
    recognition: Recognition,
    library: ModelLibrary,
    *,
    approach: Sequence[float] | np.ndarray | None = None,
    rng: np.random.Generator | int | None = None,
    candidates: int = defaults.ADVICE_CANDIDATES,
) -> TouchAdvice:
    """Propose the next touch: a contact point and the direction to approach it from.

    Parameters
    ----------
    recognition : Recognition
        The recognition of the touches so far (:func:`meshrec.recognize`); its touches
        share one world frame, the frame of the advice.
    library : ModelLibrary
        The library the recognition used (the hypotheses' meshes).
    approach : (3,) float, optional
        The direction the robot's probe can move in, into the object (world frame); only
        contacts approached within ``defaults.ADVICE_MAX_APPROACH_DEG`` of it are
        proposed. Any length but zero.
    rng : numpy.random.Generator or int or None
        Seeds the sampling of the candidate contacts.
    candidates : int
        About how many candidate contacts to sample in all (shared among the hypotheses
        by weight, at least ``defaults.ADVICE_MIN_PER_HYPOTHESIS`` on each).

    Returns
    -------
    TouchAdvice
        The point and the approach direction (None when no candidate is reachable), the
        expected information gain, the criterion, the models weighed and the reason.
        ``"separate"`` when the verdict is not ``recognised`` or the recognised model
        still has several poses of weight at least ``defaults.ADVICE_MIN_WEIGHT``;
        ``"pose"`` when one pose is left, or when no reachable place separates the
        hypotheses by ``defaults.ADVICE_MIN_GAIN``.

    Raises
    ------
    TypeError
        If ``recognition`` is not a Recognition, ``library`` not a ModelLibrary,
        ``approach`` not real numbers, ``candidates`` not an integer or ``rng`` neither a
        Generator, an int nor None.
    ValueError
        If ``approach`` is not a finite non-zero 3-vector, ``candidates`` is below 1 or
        above ``defaults.ADVICE_MAX_CANDIDATES``, ``rng`` is a negative seed, a model of
        the recognition is not in ``library``, a pose's ``T_model_touch`` is not a rigid
        transform, a probability or weight is not in [0, 1], the recognition's noise
        is not a positive finite number while it has poses to weigh, or its touches and
        geometries do not pair up.
    """
    t0 = time.perf_counter()
    check_instance(recognition, Recognition, "recognition")
    check_instance(library, ModelLibrary, "library")
    hint = None if approach is None else check_vector(approach, "approach", unit=True)
    n_candidates = check_int(
        candidates, "candidates", minimum=1, maximum=defaults.ADVICE_MAX_CANDIDATES
    )
    gen = check_rng(rng, "rng")
    hyps = _hypotheses(recognition, library)
    if not hyps:
        return TouchAdvice(
            None,
            None,
            0.0,
            "separate",
            (),
            "no advice: no model could be registered on "
            "the touches, so there is no hypothesis to test",
            time.perf_counter() - t0,
        )
    noise = check_number(recognition.noise, "recognition.noise", positive=True)
    # every touch (a hand-made Recognition may leave the tuples empty: its first only)
    touches = recognition.touches or (recognition.touch,)
    geometries = recognition.geometries or (recognition.geometry,)
    if len(geometries) != len(touches):
        raise ValueError(
            f"recognition.geometries must hold one LocalGeometry per touch "
            f"({len(touches)}), got {len(geometries)}"
        )
    hyps = _merge_equivalent([_with_side(h, touches, geometries) for h in hyps], noise)
    half = float(np.mean([g.half_length for g in geometries]))
    contacts = np.array([g.point for g in geometries], dtype=np.float64)
    radii = np.array([g.half_length for g in geometries], dtype=np.float64)
    names = tuple(dict.fromkeys(h.name for h in hyps))
    n_eff = effective_points(max(1, round(float(np.mean([t.n_points for t in touches])))))
    space = (hint, contacts, radii)

    top = names[0]
    several = len(hyps) > 1 and (
        recognition.verdict != "recognised" or sum(h.name == top for h in hyps) > 1
    )
    note = None
    if several:
        cand = _candidates(hyps, n_candidates, gen, space)
        if not len(cand.world):
            return _none(hyps, cand, "separate", names, t0)
        cand, gain, spread, D = _separate(hyps, cand, half, n_eff, noise)
        k = int(_ranked(gain, spread)[0])
        if gain[k] >= defaults.ADVICE_MIN_GAIN:
            reason = _separate_reason(hyps, cand, k, D[k], recognition.verdict)
            return TouchAdvice(
                cand.world[k],
                cand.approach[k],
                float(gain[k]),
                "separate",
                names,
                reason,
                time.perf_counter() - t0,
            )
        note = (
            f"the {_pose_words(hyps, recognition.verdict)} cannot be told apart at any "
            f"reachable point (best gain {gain[k]:.2g} nats)"
        )
        if recognition.verdict == "unknown":
            # a probe (stop 34) read "the 2 plausible poses of ..." beside `unknown`
            note = f"no model fits the touches to the noise (unknown); {note}"
    best = max((h for h in hyps if h.name == top), key=lambda h: h.weight)
    best = dataclasses.replace(best, weight=1.0)
    cand = _candidates([best], n_candidates, gen, space)
    if not len(cand.world):
        return _none([best], cand, "pose", (top,), t0)
    points = np.vstack([np.vstack(t.curves) for t in touches])
    gain = _pose_gain(best, points, cand, half, noise)
    k = int(np.argmax(gain))
    where = f"touch at {point_text(cand.world[k])} approaching along {point_text(cand.approach[k])}"
    if note is None:
        if recognition.verdict == "recognised":
            lead = f"recognised as {top}"
        elif recognition.verdict == "unknown":
            lead = f"no model fits the touches to the noise (unknown; best fit {top})"
        else:
            lead = f"only {top} is left to weigh"
        reason = f"{lead}; a {where} pins down its pose best"
    else:
        reason = f"{note}; a {where} pins down the pose of {top} best"
    return TouchAdvice(
        cand.world[k],
        cand.approach[k],
        float(gain[k]),
        "pose",
        (top,) if note is None else names,
        reason,
        time.perf_counter() - t0,
    )


# ---------------------------------------------------------------------- hypotheses
def _hypotheses(recognition: Recognition, library: ModelLibrary) -> list[_Hypothesis]:
    """The heaviest (model, pose) hypotheses, weights renormalised, heaviest first."""
    items = []
    for i, score in enumerate(recognition.scores):
        p = check_number(
            score.probability,
            f"recognition.scores[{i}].probability",
            minimum=0.0,
            maximum=1.0,
        )
        if p <= 0.0 or not score.poses:
            continue
        for k, pose in enumerate(score.poses):
            what = f"recognition.scores[{i}].poses[{k}]"
            w = p * check_number(pose.weight, f"{what}.weight", minimum=0.0, maximum=1.0)
            if w >= defaults.ADVICE_MIN_WEIGHT:
                items.append((w, i, k, score.model, pose.T_model_touch))
    items.sort(key=lambda t: (-t[0], t[1], t[2]))
    items = items[: defaults.ADVICE_MAX_HYPOTHESES]
    total = sum(t[0] for t in items)
    hyps = []
    for w, i, k, name, T in items:
        if name not in library:
            raise ValueError(
                f"recognition.scores[{i}].model {name!r} is not in library (models: "
                f"{list(library.names)}): pass the library the recognition used"
            )
        T_mw = check_transform(T, f"recognition.scores[{i}].poses[{k}].T_model_touch", rigid=True)
        R, t = T_mw[:3, :3], T_mw[:3, 3]
        T_wm = np.eye(4)
        T_wm[:3, :3] = R.T
        T_wm[:3, 3] = -R.T @ t
        hyps.append(_Hypothesis(name, library[name], w / total, T_wm, T_mw, 1.0))
    return hyps


def _merge_equivalent(hyps: list[_Hypothesis], noise: float) -> list[_Hypothesis]:
    """Merge the poses of one model that put its surface in the same place: a symmetric
    object's equivalent poses (a sphere's, a cylinder's roll) cannot be told apart by any
    touch, and weighing them as different would chase the mesh's facets.

    Two poses are the same when every one of ``defaults.ADVICE_SAME_POSE_POINTS``
    vertices of the model, placed by one, lies within ``defaults.ADVICE_SAME_POSE_NOISE``
    x ``noise`` of the surface placed by the other; the heavier keeps both weights.
    """
    kept: list[_Hypothesis] = []
    for h in hyps:
        V = h.model.mesh.vertices
        step = max(1, len(V) // defaults.ADVICE_SAME_POSE_POINTS)
        world = _apply(h.T_world_model, V[::step])
        for j, g in enumerate(kept):
            if g.name != h.name or g.side != h.side:
                continue
            dist = g.model.surface.closest_points(_apply(g.T_model_world, world))[0]
            if float(dist.max()) <= defaults.ADVICE_SAME_POSE_NOISE * noise:
                kept[j] = dataclasses.replace(g, weight=g.weight + h.weight)
                break
        else:
            kept.append(h)
    return kept


def _with_side(h: _Hypothesis, touches, geometries) -> _Hypothesis:
    """An open mesh's side: its winding's, unless the touches' normal hints say the other.

    Closed meshes are oriented outwards by meshrec; an open one is touched on whichever
    side its pose put the touches, and only a touch's ``normal`` hint tells which.
    """
    if h.model.mesh.closed:
        return h
    vote = 0.0
    for touch, geometry in zip(touches, geometries, strict=True):
        if touch.normal is None:
            continue
        _, _, face = h.model.surface.closest_points(_apply(h.T_model_world, geometry.point[None]))
        vote += float(h.model.mesh.face_normals[face[0]] @ (h.T_model_world[:3, :3] @ touch.normal))
    side = -1.0 if vote < 0.0 else 1.0
    return _Hypothesis(h.name, h.model, h.weight, h.T_world_model, h.T_model_world, side)


# ---------------------------------------------------------------------- candidates
def _candidates(hyps, count: int, rng: np.random.Generator, space) -> _Candidates:
    """Sample contacts on the hypotheses' surfaces by weight; keep the reachable ones."""
    hint, contacts, radii = space
    world, approach, source = [], [], []
    sampled = blocked = off_hint = touched = 0
    counts = [max(defaults.ADVICE_MIN_PER_HYPOTHESIS, round(count * h.weight)) for h in hyps]
    samples = _sample(hyps, counts, rng)
    for i, h in enumerate(hyps):
        n = counts[i]
        points, faces = samples[i]
        normals = _normals(h, points, faces)
        sampled += n
        ok = _free_cone(h.model, points, normals)
        blocked += int((~ok).sum())
        c_w = _apply(h.T_world_model, points)
        d_w = -normals @ h.T_world_model[:3, :3].T
        if hint is not None:
            near = d_w @ hint >= math.cos(math.radians(defaults.ADVICE_MAX_APPROACH_DEG))
            off_hint += int((ok & ~near).sum())
            ok &= near
        far = np.all(
            np.linalg.norm(c_w[:, None, :] - contacts[None], axis=2) >= radii[None], axis=1
        )
        touched += int((ok & ~far).sum())
        ok &= far
        world.append(c_w[ok])
        approach.append(d_w[ok])
        source.append(np.full(int(ok.sum()), i, dtype=np.int64))
    return _Candidates(
        np.vstack(world),
        np.vstack(approach),
        np.concatenate(source),
        sampled,
        blocked,
        off_hint,
        touched,
    )


def _sample_surface(
    V: np.ndarray, F: np.ndarray, weight: np.ndarray, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points on the triangles ``F`` of ``V``, faces drawn by ``weight``.

    The same draws and arithmetic as ``trimesh.sample.sample_surface(mesh, count,
    face_weight=weight, seed=rng)`` (``tests/test_advice.py`` checks them equal), written
    here so that ``meshrec next-touch`` does not import trimesh for it: its import is
    about 0.25 s of CPU time, an eighth of the command's time with a warm cache.
    """
    cum = np.cumsum(weight)
    face = np.searchsorted(cum, rng.random(count) * cum[-1])
    origin = V[F[face, 0]]
    edges = V[F[face, 1:]] - origin[:, None, :]
    lengths = rng.random((count, 2, 1))
    lengths[lengths.sum(axis=1).reshape(-1) > 1.0] -= 1.0
    lengths = np.abs(lengths)
    return (edges * lengths).sum(axis=1) + origin, face.astype(np.int64)


def _sample(hyps, counts, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """Area-uniform points ``(n_i, 3)`` and their faces on each hypothesis's model (model
    frame): one draw per model (:func:`_sample_surface`), shared out among its
    hypotheses."""
    out: list = [None] * len(hyps)
    for name in dict.fromkeys(h.name for h in hyps):
        mine = [i for i, h in enumerate(hyps) if h.name == name]
        mesh = hyps[mine[0]].model.mesh
        # libigl's areas: trimesh's own area_faces takes 20 times as long on 80k faces
        area = igl.doublearea(mesh.vertices, mesh.faces)
        total = sum(counts[i] for i in mine)
        points, faces = _sample_surface(mesh.vertices, mesh.faces, area, total, rng)
        start = 0
        for i in mine:
            out[i] = (points[start : start + counts[i]], faces[start : start + counts[i]])
            start += counts[i]
    return out


def _normals(h: _Hypothesis, points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Outward unit normals (model frame) at points on faces: the smooth field on a closed
    mesh, the face's (on the touched side) on an open one."""
    if h.model.mesh.closed:
        return h.model.surface.interpolated_normals(points, faces)
    return h.side * np.asarray(h.model.mesh.face_normals)[faces]


def _free_cone(model: ModelIndex, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Whether the probe can come in along minus each normal (model frame): every point
    ``x_s = c + n s`` of the ray out to the standoff is at least ``sin(clearance) s`` from
    the surface (one distance query for all)."""
    lo, hi = model.mesh.vertices.min(axis=0), model.mesh.vertices.max(axis=0)
    standoff = defaults.ADVICE_STANDOFF_FRACTION * float(np.linalg.norm(hi - lo))
    steps = defaults.ADVICE_RAY_STEPS
    s = standoff * (np.arange(1, steps + 1) / steps) ** 2
    x = points[:, None, :] + normals[:, None, :] * s[None, :, None]
    dist = model.surface.closest_points(x.reshape(-1, 3))[0].reshape(len(points), steps)
    clearance = math.sin(math.radians(defaults.ADVICE_CLEARANCE_DEG))
    return np.all(dist >= clearance * s[None], axis=1) & np.any(normals != 0.0, axis=1)


# ---------------------------------------------------------------------- patches
def _patch_offsets(half: float, points: int) -> np.ndarray:
    """(P, 2) in-plane offsets: the centre, then three chords 60 degrees apart, each
    ``points`` samples over the curves' length (the centre once)."""
    u = np.linspace(-half, half, points)
    u = u[np.abs(u) > 1e-12 * half]
    angles = np.radians([0.0, 60.0, 120.0])
    chords = [np.column_stack([u * math.cos(a), u * math.sin(a)]) for a in angles]
    return np.vstack([np.zeros((1, 2)), *chords])


def _tangents(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per normal, with ``t1 x t2 = n``."""
    axis = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(normals, axis)
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    return t1, np.cross(normals, t1)


def _patch(h: _Hypothesis, centres: np.ndarray, offsets: np.ndarray):
    """The next touch's points on ``h`` around points near it (model frame).

    Returns ``(points (n, P, 3), normals (n, P, 3))``: each centre's closest point on
    ``h``, the offsets laid in the tangent plane there and projected back onto ``h``.
    """
    _, q, f = h.model.surface.closest_points(centres)
    n, p = len(centres), len(offsets)
    if p == 1:
        return q[:, None, :], _normals(h, q, f)[:, None, :]
    t1, t2 = _tangents(_normals(h, q, f))
    raw = (
        q[:, None, :]
        + offsets[None, :, :1] * t1[:, None, :]
        + offsets[None, :, 1:] * t2[:, None, :]
    )
    _, pts, faces = h.model.surface.closest_points(raw.reshape(-1, 3))
    normals = _normals(h, pts, faces)
    return pts.reshape(n, p, 3), normals.reshape(n, p, 3)


# ---------------------------------------------------------------------- separate
def _landings(h: _Hypothesis, world: np.ndarray, approach: np.ndarray):
    """Where the probe, moving along each candidate's approach line from outside, first
    meets hypothesis ``h``'s surface: ``(points (n, 3), model frame; hit (n,) bool)``.

    The line is followed from a start beyond ``h``'s whole mesh (the distance from the
    candidate to the centre of ``h``'s bounding box plus its whole diagonal: farther than
    any of ``h``'s points) so that ``h``'s first face along it is the one the probe would
    touch; a line that misses ``h`` touches nothing if ``h`` is the truth.
    """
    cast = getattr(h.model.surface, "first_hits", None)
    if cast is None:
        # a surface backend without ray casting (the registration's SurfaceQuery does not
        # ask for it): the candidate's closest point on h, as before stop 31
        _, closest, _ = h.model.surface.closest_points(_apply(h.T_model_world, world))
        return closest, np.ones(len(world), dtype=bool)
    V = h.model.mesh.vertices
    centre = _apply(h.T_world_model, 0.5 * (V.min(axis=0) + V.max(axis=0))[None])[0]
    reach = 0.5 * float(np.linalg.norm(np.ptp(V, axis=0)))
    standoff = np.linalg.norm(world - centre, axis=1) + 2.0 * reach
    origins = _apply(h.T_model_world, world - standoff[:, None] * approach)
    directions = approach @ h.T_model_world[:3, :3].T
    return cast(origins, directions)


def _separations(hyps, world: np.ndarray, approach: np.ndarray, offsets: np.ndarray):
    """(n, H, H) mean squared distance of hypothesis h's patch at each candidate to h'.

    If ``h`` is the truth, the next touch lands where the candidate's approach line first
    meets ``h`` (:func:`_landings`), not at the candidate itself (which lies on the
    hypothesis it was sampled on); where the line misses ``h`` the touch tells nothing
    under ``h``, and its row is 0 (the posterior stays the prior: no gain). Before stop
    31 the patch was laid at the candidate's closest point on ``h``, up to a model's size
    from any line the probe could follow: a probe found advice whose line missed the most
    probable model (0.855) by 0.44.
    """
    n, H, P = len(world), len(hyps), len(offsets)
    patches = np.empty((H, n, P, 3))
    lands = np.zeros((H, n), dtype=bool)
    for i, h in enumerate(hyps):
        points, hit = _landings(h, world, approach)
        centres = np.where(hit[:, None], points, _apply(h.T_model_world, world))
        pts, _ = _patch(h, centres, offsets)
        patches[i] = _apply(h.T_world_model, pts.reshape(-1, 3)).reshape(n, P, 3)
        lands[i] = hit
    D = np.zeros((n, H, H))
    for j, g in enumerate(hyps):
        others = [i for i in range(H) if i != j]
        if not others:
            continue
        q = _apply(g.T_model_world, patches[others].reshape(-1, 3))
        dist = g.model.surface.closest_points(q)[0].reshape(len(others), n, P)
        D[:, others, j] = np.mean(dist**2, axis=2).T
    D[~lands.T] = 0.0
    return D


def _expected_gain(D: np.ndarray, w: np.ndarray, n_eff: float, noise: float) -> np.ndarray:
    """(n,) mutual information (nats) between the truth and the touch's outcome."""
    logits = np.log(w)[None, None, :] - 0.5 * n_eff * D / noise**2
    logits -= logits.max(axis=2, keepdims=True)
    p = np.exp(logits)
    p /= p.sum(axis=2, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        plogp = np.where(p > 0.0, p * np.log(p), 0.0)
    h_after = -plogp.sum(axis=2)  # (n, H)
    h_before = -float(np.sum(w * np.log(w)))
    return np.maximum(h_before - h_after @ w, 0.0)


def _ranked(gain: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Candidate indices, best first: gains within ``defaults.ADVICE_GAIN_TIE`` of the
    best are ties, broken by the larger spread; the rest by gain."""
    tied = gain >= gain.max() - defaults.ADVICE_GAIN_TIE
    first = np.flatnonzero(tied)
    rest = np.flatnonzero(~tied)
    return np.concatenate(
        [
            first[np.argsort(-spread[first], kind="stable")],
            rest[np.argsort(-gain[rest], kind="stable")],
        ]
    )


def _separate(hyps, cand: _Candidates, half: float, n_eff: float, noise: float):
    """Expected gains of the candidates: screened on the contact point alone, the best
    ``defaults.ADVICE_REFINE`` scored again on their whole patch.

    Returns ``(candidates, gain, spread, D)`` for the candidates kept: the gains (nats),
    the probability-weighted mean squared separations and the (n, H, H) separations.
    """
    w = np.array([h.weight for h in hyps])
    D0 = _separations(hyps, cand.world, cand.approach, np.zeros((1, 2)))
    gain0 = _expected_gain(D0, w, n_eff, noise)
    keep = _ranked(gain0, np.einsum("nij,i,j->n", D0, w, w))[: defaults.ADVICE_REFINE]
    cand = dataclasses.replace(
        cand, world=cand.world[keep], approach=cand.approach[keep], source=cand.source[keep]
    )
    offsets = _patch_offsets(half, defaults.ADVICE_PATCH_POINTS)
    D = _separations(hyps, cand.world, cand.approach, offsets)
    gain = _expected_gain(D, w, n_eff, noise)
    return cand, gain, np.einsum("nij,i,j->n", D, w, w), D


def _separate_reason(hyps, cand: _Candidates, k: int, D: np.ndarray, verdict: str) -> str:
    """One sentence for a separating touch (``D``: the candidate's (H, H) separations)."""
    where = f"touch at {point_text(cand.world[k])} approaching along {point_text(cand.approach[k])}"
    lead = "no model fits well (unknown), but " if verdict == "unknown" else ""
    return (
        f"{lead}{where}: the {_pose_words(hyps, verdict)} lie up to "
        f"{math.sqrt(float(D.max())):.3g} apart there (RMS over the next touch's patch, "
        "model units)"
    )


def _pose_words(hyps, verdict: str = "ambiguous") -> str:
    """'plausible models a and b', or 'N plausible poses of a' ('best-fitting' for an
    ``unknown`` answer, where no model is plausible)."""
    kind = "best-fitting" if verdict == "unknown" else "plausible"
    names = list(dict.fromkeys(h.name for h in hyps))
    if len(names) == 1:
        return f"{len(hyps)} {kind} poses of {names[0]}"
    listed = ", ".join(names[:-1]) + f" and {names[-1]}"
    return f"{kind} models {listed}"


# ---------------------------------------------------------------------- pose
def _pose_gain(
    h: _Hypothesis, touched: np.ndarray, cand: _Candidates, half: float, noise: float
) -> np.ndarray:
    """(n,) D-optimal gain (nats) of each candidate's patch for the pose of ``h``."""
    R = h.T_world_model[:3, :3]
    lo, hi = h.model.mesh.vertices.min(axis=0), h.model.mesh.vertices.max(axis=0)
    scale = float(np.linalg.norm(hi - lo))  # rotations in radians x this: a length, as t
    centre = touched.mean(axis=0)

    def rows(points_w, normals_m):
        n_w = normals_m @ R.T
        return np.concatenate([np.cross(points_w - centre, n_w) / scale, n_w], axis=-1)

    _, q, f = h.model.surface.closest_points(_apply(h.T_model_world, touched))
    J0 = rows(touched, _normals(h, q, f))
    A = J0.T @ J0 / noise**2
    pts, normals = _patch(
        h, _apply(h.T_model_world, cand.world), _patch_offsets(half, defaults.ADVICE_PATCH_POINTS)
    )
    Jc = rows(_apply(h.T_world_model, pts.reshape(-1, 3)).reshape(pts.shape), normals)
    Ac = np.einsum("npi,npj->nij", Jc, Jc) / noise**2
    ridge = (
        defaults.ADVICE_RIDGE
        * max(np.trace(A), float(np.mean(np.trace(Ac, axis1=1, axis2=2))))
        / 6.0
    )
    eye = ridge * np.eye(6)
    before = np.linalg.slogdet(A + eye)[1]
    after = np.linalg.slogdet(A[None] + Ac + eye[None])[1]
    return 0.5 * (after - before)


# ---------------------------------------------------------------------- helpers
def _none(hyps, cand: _Candidates, criterion: str, names, t0: float) -> TouchAdvice:
    """The advice when no candidate is reachable, saying why."""
    parts = [f"{cand.blocked} in a concavity or behind another part"]
    if cand.off_hint:
        parts.append(
            f"{cand.off_hint} more than {defaults.ADVICE_MAX_APPROACH_DEG:g} degrees from "
            "the approach direction"
        )
    if cand.touched:
        parts.append(f"{cand.touched} where a touch was already made")
    reason = (
        f"no reachable point: of {cand.sampled} candidate contacts on the "
        f"{_pose_words(hyps)}, " + ", ".join(parts)
    )
    return TouchAdvice(None, None, 0.0, criterion, names, reason, time.perf_counter() - t0)


def _apply(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Rigid transform of (n, 3) points."""
    return points @ T[:3, :3].T + T[:3, 3]


def point_text(v) -> str:
    """A point or direction as the advice's reasons write it: ``(x, y, z)``, 4 digits.

    Parameters
    ----------
    v : (3,) float

    Returns
    -------
    str
    """
    return "(" + ", ".join(f"{x:.4g}" for x in np.asarray(v, dtype=np.float64)) + ")"
