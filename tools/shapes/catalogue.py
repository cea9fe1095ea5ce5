"""The bundled models: where each goes, how it is built and measured, and what it is."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from shapes.distances import (
    ellipsoid_distance,
    patch_distance,
    prism_distance,
    sphere_distance,
)
from shapes.params import (
    CYLINDER_DIAMETERS,
    CYLINDER_HEIGHT,
    ELLIPSOID_ABC,
    ELLIPTIC_CYLINDER_AB,
    PARABOLOID_AB,
    SEED,
    SPHERE_RADIUS,
    TARGET_FACES,
)
from shapes.patch_mesh import mesh_patch
from shapes.patches import crossed_trough_patch, monkey_saddle_patch, paraboloid_patch
from shapes.solids import ellipsoid_mesh, elliptic_prism, sphere_mesh

__all__ = ["Model", "all_models"]


@dataclass(frozen=True)
class Model:
    """One bundled mesh: where it goes, how it is made and measured, and what it is.

    Attributes
    ----------
    library : str
        Subfolder of the output folder (``surfaces`` or ``objects``).
    name : str
        File stem.
    build : callable
        ``() -> trimesh.Trimesh``.
    distance : callable
        First-order distance of ``(k, 3)`` points to the analytic surface.
    closed : bool
        Closed solid (watertight, outward normals) or open patch (normals towards +z).
    shape : str
        One-line description for the README.
    """

    library: str
    name: str
    build: Callable
    distance: Callable
    closed: bool
    shape: str


def all_models():
    """All bundled models, in the order they are written and listed.

    Returns
    -------
    list of Model
    """
    a, b, c = ELLIPSOID_ABC
    pa, pb = PARABOLOID_AB
    ea, eb = ELLIPTIC_CYLINDER_AB
    height = CYLINDER_HEIGHT
    paraboloid = paraboloid_patch()
    saddle = monkey_saddle_patch()
    trough = crossed_trough_patch()
    models = [
        Model(
            "surfaces",
            "ellipsoid",
            ellipsoid_mesh,
            lambda p: ellipsoid_distance(p, ELLIPSOID_ABC),
            True,
            f"x²/a² + y²/b² + z²/c² = 1, a = {a:g}, b = {b:g}, c = {c:g}; closed",
        ),
        Model(
            "surfaces",
            "elliptic_paraboloid",
            lambda: mesh_patch(paraboloid, TARGET_FACES, SEED),
            lambda p: patch_distance(p, paraboloid),
            False,
            f"z = x²/a² + y²/b², a = {pa:g}, b = {pb:g}, over the disc x²/a² + y²/b² ≤ 1 "
            "(v in [-1, 1] of the parametric form (a v cos u, b v sin u, v²)); open",
        ),
        Model(
            "surfaces",
            "monkey_saddle",
            lambda: mesh_patch(saddle, TARGET_FACES, SEED + 1),
            lambda p: patch_distance(p, saddle),
            False,
            "z = x³ - 3xy² over [-1, 1]²; open",
        ),
        Model(
            "surfaces",
            "crossed_trough",
            lambda: mesh_patch(trough, TARGET_FACES, SEED + 2),
            lambda p: patch_distance(p, trough),
            False,
            "z = x²y² over [-1, 1]²; open",
        ),
    ]
    for k, diameter in enumerate(CYLINDER_DIAMETERS, start=1):
        r = diameter / 2.0
        models.append(
            Model(
                "objects",
                f"cylinder_{k}",
                lambda r=r: elliptic_prism(r, r, height, TARGET_FACES),
                lambda p, r=r: prism_distance(p, r, r, height),
                True,
                f"circular cylinder, diameter {diameter:g} mm, height {height:g} mm, flat caps",
            )
        )
    models += [
        Model(
            "objects",
            "elliptic_cylinder",
            lambda: elliptic_prism(ea, eb, height, TARGET_FACES),
            lambda p: prism_distance(p, ea, eb, height),
            True,
            f"elliptic cylinder, semi-axes {ea:g} mm (x) and {eb:g} mm (y), "
            f"height {height:g} mm, flat caps",
        ),
        Model(
            "objects",
            "sphere",
            sphere_mesh,
            lambda p: sphere_distance(p, SPHERE_RADIUS),
            True,
            f"sphere, radius {SPHERE_RADIUS:g} mm",
        ),
    ]
    return models

