"""Every number that defines the bundled models: the paper's shapes, sizes, seeds, meshing."""

from __future__ import annotations

__all__ = [
    "COARSE_STEPS",
    "CYLINDER_DIAMETERS",
    "CYLINDER_HEIGHT",
    "ELLIPSOID_ABC",
    "ELLIPTIC_CYLINDER_AB",
    "FINE_STEPS",
    "N_SAMPLES",
    "PARABOLOID_AB",
    "SEED",
    "SPHERE_RADIUS",
    "SPRING_PRESSURE",
    "SPRING_STEP",
    "SUBDIVISIONS",
    "TARGET_FACES",
]

#: Seed of every random draw (initial points of the relaxed patches, deviation samples).
SEED = 20240607
#: Points sampled on each mesh to measure its deviation from the analytic surface.
N_SAMPLES = 200_000
#: Faces aimed at for the meshes whose face count is free (icospheres have 81,920).
TARGET_FACES = 80_000

# --- the paper's shapes ---------------------------------------------------------------------
#: Ellipsoid semi-axes (Table 1, Figure 5a).
ELLIPSOID_ABC = (1.0, 0.8, 0.5)
#: Elliptic paraboloid z = x^2/a^2 + y^2/b^2 (Figure 4), over v in [-1, 1] of the
#: parametric form (a v cos u, b v sin u, v^2), i.e. the elliptic disc x^2/a^2 + y^2/b^2 <= 1.
PARABOLOID_AB = (1.5, 1.1)
#: Cylinder diameters (Figure 7), mm.
CYLINDER_DIAMETERS = (50.4, 94.0)
#: Elliptic cylinder semi-axes (Figure 7), mm.
ELLIPTIC_CYLINDER_AB = (50.8, 31.75)
#: Height of the three cylinders, mm (the paper does not give it; 100 mm is our choice).
CYLINDER_HEIGHT = 100.0
#: Sphere radius (Figure 7), mm.
SPHERE_RADIUS = 33.0

# --- relaxation of the open patches -----------------------------------------------------------
#: Midpoint subdivisions applied after relaxing the coarse mesh (faces grow 4x each).
SUBDIVISIONS = 3
#: Relaxation steps on the coarse mesh, and after every subdivision.
COARSE_STEPS = 300
FINE_STEPS = 5
#: Step size and internal-pressure factor of the DistMesh-style edge springs.
SPRING_STEP = 0.2
SPRING_PRESSURE = 1.2
