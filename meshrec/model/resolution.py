"""A model's resolution against the touch curves it must answer: is the mesh fine enough?

A touch is recognised from curves about ``defaults.SIM_LENGTH_FRACTION * sqrt(area)``
long. :func:`mesh_resolution` measures a mesh against such a curve: how many vertices it
crosses (between them the surface is a guess from their normals), the chord error
(how far the flat faces lie from the smooth surface their vertex normals imply, the
surface :mod:`meshrec.model.surface` registers on), the curvature range, and how much of
the surface is long thin slivers (CAD exports write a cylinder's side as full-height
triangles with no vertex inside). Flat faces are left out of the vertex count and the
slivers: any triangulation of a plane is exact (a 12-triangle box is not coarse). A model
failing one of the thresholds of ``defaults.RESOLUTION_*`` is
:attr:`Resolution.too_coarse`, with the reasons.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import igl
import numpy as np

from meshrec import defaults
from meshrec.model.curvature import CurvatureTable
from meshrec.model.mesh import MeshData
from meshrec.model.surface import corner_normals

__all__ = ["Resolution", "ResolutionWarning", "coarse_message", "mesh_resolution"]


class ResolutionWarning(UserWarning):
    """A model is too coarse for reliable answers."""


@dataclass(frozen=True)
class Resolution:
    """A mesh's resolution measured against a touch curve's length.

    Attributes
    ----------
    curve_length : float
        The expected touch curve length, model units.
    edge_median, edge_p90 : float
        Median and 90th percentile of the lengths of the curved faces' edges (of all edges
        when no face is curved), model units.
    vertices_per_curve : float
        ``curve_length / edge_median``: about how many vertices a curve crosses on the
        curved part of the surface.
    curved_fraction : float
        The fraction of the surface area in curved faces: faces with a corner normal more
        than ``defaults.RESOLUTION_FLAT_ANGLE_DEG`` from the face's normal (the smooth
        surface bends there). With none (a mesh of flat faces) the vertex count is not
        checked.
    chord_error : float
        The largest chord error, model units: over the faces' edges that are not creases
        (corner normals within ``defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG``), the sagitta
        ``(p_j - p_i) . (n_j - n_i) / 8`` that the smooth surface's corner normals imply
        at the edge's middle (``r (1 - cos(pi / k))`` on a circle of radius r in k
        sections; 0 next to an exact part's sharp edges).
    chord_fraction : float
        ``chord_error / curve_length``.
    curvature_min, curvature_max : float
        The smallest ``k2`` and largest ``k1`` over the valid vertices of the curvature
        table, 1 / model units; NaN without a table (or without a valid vertex).
    sliver_fraction : float
        The fraction of the surface area in curved faces whose aspect (``sqrt(3) L^2 / (4 A)``,
        L the longest edge, A the area; 1 for an equilateral triangle) exceeds
        ``defaults.RESOLUTION_SLIVER_ASPECT``.
    too_coarse : bool
        Whether a threshold is crossed (``reasons`` says which).
    reasons : tuple of str
        One sentence per threshold crossed, with the numbers.
    """

    curve_length: float
    edge_median: float
    edge_p90: float
    vertices_per_curve: float
    curved_fraction: float
    chord_error: float
    chord_fraction: float
    curvature_min: float
    curvature_max: float
    sliver_fraction: float
    too_coarse: bool
    reasons: tuple[str, ...]


def mesh_resolution(
    mesh: MeshData,
    curve_length: float | None = None,
    curvature: CurvatureTable | None = None,
) -> Resolution:
    """Measure a mesh's resolution against a touch curve's length.

    Parameters
    ----------
    mesh : MeshData
        The model's cleaned mesh with ``m`` faces.
    curve_length : float or None
        The expected touch curve length, model units; ``None``:
        ``defaults.SIM_LENGTH_FRACTION * mesh.scale`` (``scale = sqrt(area)``).
    curvature : CurvatureTable or None
        The mesh's curvature table (one patch label per face), for the curvature range;
        ``None``: the range is NaN.

    Returns
    -------
    Resolution
        Too coarse when fewer than ``defaults.RESOLUTION_MIN_VERTICES_PER_CURVE``
        vertices lie along a curve on the curved faces, the chord error exceeds
        ``defaults.RESOLUTION_MAX_CHORD_FRACTION`` of the curve length, or more than
        ``defaults.RESOLUTION_MAX_SLIVER_FRACTION`` of the area is curved slivers. Measured
        0.04 to 0.08 s on the bundled 80,000-face models.

    Raises
    ------
    TypeError
        If ``mesh`` is not a MeshData, or ``curvature`` neither a CurvatureTable nor None.
    ValueError
        If ``curve_length`` is not a finite number > 0, or ``curvature`` does not have
        one patch label per mesh face.
    """
    if not isinstance(mesh, MeshData):
        raise TypeError(f"mesh must be a MeshData, got {type(mesh).__name__}")
    if curvature is not None and not isinstance(curvature, CurvatureTable):
        raise TypeError(
            f"curvature must be a CurvatureTable or None, got {type(curvature).__name__}"
        )
    if curve_length is None:
        curve_length = defaults.SIM_LENGTH_FRACTION * mesh.scale
    if (
        isinstance(curve_length, bool)
        or not isinstance(curve_length, numbers.Real)
        or not (math.isfinite(curve_length) and curve_length > 0)
    ):
        raise ValueError(f"curve_length must be a finite number > 0, got {curve_length!r}")
    curve_length = float(curve_length)
    V, F = mesh.vertices, mesh.faces
    if curvature is not None and len(curvature.face_patch) != len(F):
        raise ValueError(
            f"curvature must have one patch label per mesh face ({len(F)}), "
            f"got {len(curvature.face_patch)}"
        )

    # Curved faces: a corner normal of the smooth surface (creases kept sharp) bends away
    # from the face's own normal; on flat faces the triangles are the surface itself.
    bend = np.einsum("fkj,fj->fk", corner_normals(mesh), mesh.face_normals).min(axis=1)
    curved = bend < math.cos(math.radians(defaults.RESOLUTION_FLAT_ANGLE_DEG))
    E = igl.edges(F)
    dp = V[E[:, 1]] - V[E[:, 0]]
    length = np.linalg.norm(dp, axis=1)
    counted = length
    if curved.any():
        # an edge counts when a curved face has it (libigl's edges of the curved faces)
        ce = igl.edges(F[curved])
        counted = np.linalg.norm(V[ce[:, 1]] - V[ce[:, 0]], axis=1)
    edge_median = float(np.median(counted))
    edge_p90 = float(np.percentile(counted, 90))
    per_curve = curve_length / edge_median if edge_median > 0 else 0.0

    # The sagitta the smooth surface implies at each face edge's middle (that of
    # meshrec.model.surface: a quarter of its edge bulge, from the faces' corner normals,
    # which keep sharp edges sharp), creases left out. The vertex normals, averaged
    # across a sharp edge, read a bulge next to every crease of an exact CAD part that
    # the smooth surface does not have (two probes, stops 33 and 34: brackets, bolts and
    # a stepped shaft "too coarse", 8.5% of the curve on the bundled l_bracket against
    # 0.16% from the corner normals).
    corners = corner_normals(mesh)
    cos_max = math.cos(math.radians(defaults.SMOOTH_MAX_NORMAL_ANGLE_DEG))
    chord = 0.0
    for i, j in ((0, 1), (1, 2), (2, 0)):
        ni, nj = corners[:, i], corners[:, j]
        smooth = np.einsum("ij,ij->i", ni, nj) >= cos_max
        if smooth.any():
            step = V[F[smooth, j]] - V[F[smooth, i]]
            sag = np.abs(np.einsum("ij,ij->i", step, nj[smooth] - ni[smooth])) / 8.0
            chord = max(chord, float(sag.max()))

    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * igl.doublearea(V, F)
    longest = np.max([np.einsum("ij,ij->i", u, u) for u in (b - a, c - b, a - c)], axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = math.sqrt(3.0) * longest / (4.0 * area)
    sliver = curved & ~(aspect <= defaults.RESOLUTION_SLIVER_ASPECT)  # degenerate count
    total = float(area.sum())
    sliver_fraction = float(area[sliver].sum()) / total if total > 0 else 0.0
    curved_fraction = float(area[curved].sum()) / total if total > 0 else 0.0

    k_min = k_max = math.nan
    t = [] if curvature is None else curvature.table_sites[~curvature.crease[curvature.table_sites]]
    if len(t):
        k_min = float(np.min(curvature.k2[t]))
        k_max = float(np.max(curvature.k1[t]))

    reasons = []
    if curved.any() and per_curve < defaults.RESOLUTION_MIN_VERTICES_PER_CURVE:
        reasons.append(
            f"a touch curve {curve_length:.4g} long crosses about {per_curve:.3g} vertices "
            f"on its curved faces (median edge {edge_median:.4g}), fewer than "
            f"{defaults.RESOLUTION_MIN_VERTICES_PER_CURVE:g}"
        )
    if chord > defaults.RESOLUTION_MAX_CHORD_FRACTION * curve_length:
        reasons.append(
            f"the flat faces lie up to {chord:.3g} from the smooth surface, "
            f"{chord / curve_length:.2%} of the curve length (at most "
            f"{defaults.RESOLUTION_MAX_CHORD_FRACTION:.1%})"
        )
    if sliver_fraction > defaults.RESOLUTION_MAX_SLIVER_FRACTION:
        reasons.append(
            f"{sliver_fraction:.0%} of the surface is long thin triangles (aspect over "
            f"{defaults.RESOLUTION_SLIVER_ASPECT:g}) on a curved part, with no vertex inside "
            "(at most "
            f"{defaults.RESOLUTION_MAX_SLIVER_FRACTION:.0%})"
        )
    return Resolution(
        curve_length=curve_length,
        edge_median=edge_median,
        edge_p90=edge_p90,
        vertices_per_curve=float(per_curve),
        curved_fraction=curved_fraction,
        chord_error=chord,
        chord_fraction=chord / curve_length,
        curvature_min=k_min,
        curvature_max=k_max,
        sliver_fraction=sliver_fraction,
        too_coarse=bool(reasons),
        reasons=tuple(reasons),
    )


def coarse_message(name: str, resolution: Resolution) -> str:
    """The warning text for a model too coarse for reliable answers.

    Parameters
    ----------
    name : str
        The model's name.
    resolution : Resolution
        Its resolution, with ``too_coarse`` True.

    Returns
    -------
    str
        ``"<name>: too coarse for reliable answers: <reasons>; ..."`` with the remedy.

    Raises
    ------
    TypeError
        If ``resolution`` is not a Resolution.
    ValueError
        If ``resolution`` is not too coarse.
    """
    if not isinstance(resolution, Resolution):
        raise TypeError(f"resolution must be a Resolution, got {type(resolution).__name__}")
    if not resolution.too_coarse:
        raise ValueError(f"resolution must be too coarse, got one of model {name!r} that is not")
    return (
        f"{name}: too coarse for reliable answers: {'; '.join(resolution.reasons)}; export "
        "it finer or subdivide it (e.g. trimesh's subdivide_to_size)"
    )
