"""Every tolerance and default that tunes the method, in one place.

Code and tests import these names; nothing else in the package hard-codes a tuning value.
Lengths marked "model units" are in the units of the mesh files (the bundled paper surfaces
are unit-sized, the bundled experiment objects are in millimetres).
"""

# --- simulated touch (the paper's protocol, Section 3.1) -----------------------------------
#: Points per simulated curve (odd, so that the middle sample is the contact).
SIM_POINTS = 61
#: Half-width of the uniform noise added to every coordinate, model units.
SIM_NOISE = 1e-3
#: Length of each simulated curve as a fraction of sqrt(surface area) of the model.
#: On the bundled paper surfaces this gives curves about 0.6 long, as in the paper's figures.
SIM_LENGTH_FRACTION = 0.22
#: Largest tilt of a cutting plane away from containing the surface normal, degrees.
SIM_MAX_TILT_DEG = 30.0
#: Smallest angle between two cutting planes' traces in the tangent plane, degrees.
SIM_MIN_PLANE_ANGLE_DEG = 35.0
#: Random contacts tried before simulate gives up (a contact is rejected when a curve
#: through it is shorter than the requested length, e.g. near the edge of an open patch).
SIM_MAX_TRIES = 200

# --- local geometry from the curves (the paper's reference [11]) ---------------------------
#: Degree of the polynomial fitted to each curve, as a graph over its chord direction.
CURVE_FIT_DEGREE = 4
#: Smallest points per curve accepted.
MIN_POINTS_PER_CURVE = 5
#: Smallest number of curves accepted.
MIN_CURVES = 3
#: Two curve tangents closer than this angle (degrees, modulo 180) count as parallel.
MIN_TANGENT_ANGLE_DEG = 10.0
