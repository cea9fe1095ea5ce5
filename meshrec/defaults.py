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
#: A given contact farther than this fraction of sqrt(surface area) from the mesh is refused
#: (closer ones are snapped onto the mesh).
SIM_CONTACT_TOLERANCE = 2e-3
#: Random plane triples tried through a given contact before simulate reports that the
#: curves through it are too short (some orientations may fit near an open boundary).
SIM_CONTACT_PLANE_TRIES = 20
#: Section end points closer than this fraction of the mesh's bounding-box diagonal are the
#: same vertex of the section polyline.
SIM_MERGE_FRACTION = 1e-9

# --- local geometry from the curves (the paper's reference [11]) ---------------------------
#: Degree of the polynomial fitted to each curve (in a smoothed arc-length parameter).
CURVE_FIT_DEGREE = 4
#: Smallest points per curve accepted.
MIN_POINTS_PER_CURVE = 5
#: Smallest number of curves accepted.
MIN_CURVES = 3
#: Two curve tangents closer than this angle (degrees, modulo 180) count as parallel.
MIN_TANGENT_ANGLE_DEG = 10.0
#: Largest condition number of the Euler least-squares system (tangents 60 degrees apart
#: give 1.41; three tangents within 20 degrees, 68): above it the curves count as parallel.
MAX_EULER_CONDITION = 50.0
#: Samples on each side of the moving average whose chord lengths parametrise a curve fit.
CURVE_PARAM_SMOOTHING = 3
#: A curve fit stops where the curve turns more than this from its direction at p, degrees.
CURVE_FIT_MAX_TURN_DEG = 75.0
#: A curve whose consecutive samples are (median) more than this many times farther apart
#: than nearest neighbours is not ordered along the curve, and is refused (ordered curves
#: stay under 3.5 while the noise is under 10 times the sample spacing; shuffled ones of 61
#: samples give 6.6 or more).
MAX_STEP_TO_NEIGHBOUR_RATIO = 6.0
#: Refinements of the common point (fit the curves around p, meet their tangent lines).
COMMON_POINT_ITERATIONS = 5

# --- candidate lookup (Section 2.1) --------------------------------------------------------
#: Tolerance on each principal curvature:
#: |k_mesh - k_data| <= REL_TOL * max|k| + NOISE_FACTOR * fit_rms / half_length^2.
CANDIDATE_REL_TOL = 0.05
CANDIDATE_NOISE_FACTOR = 12.0
#: Candidates closer than this fraction of the curves' half-length are merged (one basin).
CANDIDATE_SPACING_FRACTION = 0.5
#: Most candidates kept per model and side after spreading them over the surface.
MAX_CANDIDATES = 24

# --- initial phi (Section 2.2.1) -----------------------------------------------------------
#: Steps of the discretisation of [0, 2 pi) in which every local minimum is bracketed.
PHI_STEPS = 36
#: Data points (evenly subsampled) used while searching phi; all points are used later.
PHI_POINTS = 36
#: A bracket is refined only if its grid error is within this factor of the best one.
PHI_REFINE_RATIO = 1.5
#: Absolute tolerance of the bracket refinement, radians.
PHI_XTOL = 2e-3

# --- local search on surface charts (Section 2.2.1) and final refinement --------------------
#: Candidates (best by their phi error) that get a full local search.
LOCAL_SEARCHES = 8
#: Candidates whose best sampled phi error exceeds this factor times the best candidate's
#: are not searched (the paper's example: right-basin starts within a factor of 2).
SEARCH_PRUNE_RATIO = 3.0
#: Candidates (best by their sampled phi error) screened by a few rigid-refinement steps;
#: the best screened ones get the full phi refinement and local search.
SCREEN_CANDIDATES = 48
#: Rigid-refinement iterations of the screening.
SCREEN_ITERATIONS = 3
#: Chart re-centrings at most per local search.
MAX_RECENTRES = 6
#: A re-centring smaller than this fraction of the half-length ends the local search.
RECENTRE_TOL_FRACTION = 1e-3
#: Function evaluations allowed for one chart's least-squares solve.
CHART_MAX_EVALS = 30
#: Relative tolerance (ftol and xtol) of one chart's least-squares solve; the rigid
#: refinement that follows polishes the result.
CHART_TOL = 1e-5
#: Iterations of the paper's steepest descent (reference method) at most.
STEEPEST_MAX_ITER = 300
#: Iterations of the final rigid (6-DOF) refinement at most.
REFINE_MAX_ITER = 30
#: The final refinement stops when the error improves by less than this fraction.
REFINE_REL_TOL = 1e-6
#: Local-search results closer than this fraction of the half-length are the same minimum.
DUPLICATE_FRACTION = 0.05
#: The default local-search method: "lm" (least squares on charts) or "steepest" (the paper's).
SEARCH_METHOD = "lm"

# --- model index: the per-vertex curvature table (Section 2.1) -----------------------------
#: Radius of libigl's curvature ball as a fraction of sqrt(surface area) of the model, so
#: that curvature is measured at a fixed fraction of the model's size (the touch curves are
#: SIM_LENGTH_FRACTION of it long), whatever the mesh resolution.
CURVATURE_SCALE_FRACTION = 0.02
#: Smallest curvature ball radius, in mean edge lengths (fewer fails on coarse meshes).
CURVATURE_MIN_RADIUS = 2
#: Largest curvature ball radius, in mean edge lengths (the cost grows with its square).
CURVATURE_MAX_RADIUS = 8
#: The lookup scales the K axis by 1 / (2 median |H|); below this fraction of 1 / scale
#: the median |H| counts as zero (a flat model) and 1 / scale is used instead.
LOOKUP_MIN_H_FRACTION = 1e-6
