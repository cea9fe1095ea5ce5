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
#: Directions of the simulated noise: "isotropic" (every coordinate, the paper's) or
#: "normal" (along the smooth surface normal at each sample only, as most probes err).
SIM_NOISE_DIRECTIONS = ("isotropic", "normal")
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
#: A curve's tangent at the common point more than this many degrees out of the plane
#: that fits all the tangents best: the curves do not lie on one smooth surface (three
#: straight lines along x, y and z are 90 degrees out). Generous: a touch whose curves
#: cross an edge near p still gets a geometry (and its warnings); only tangents nearly
#: along the fitted normal, where Euler's formula has no plane to be written in, stop.
MAX_TANGENT_TILT_DEG = 75.0
#: The noise estimates (LocalGeometry.fit_rms, noise_rms) are of the noise along the
#: surface normal, the part a point-to-surface distance sees. Where the other components
#: (across the curve in the tangent plane, and along it for third differences) show a
#: variance within this factor of the normal one's, the noise is taken as isotropic and
#: all components are pooled (the same expectation, with two to three times the data);
#: otherwise the normal component alone is used. 1.7 is about the two-sided 99% range of
#: the ratio of two such variance estimates from three 61-point curves (third
#: differences are correlated: about n / 2.3 effective degrees of freedom); noise along
#: the normal alone gives ratios of 100 and more.
NOISE_ISOTROPY_MAX_RATIO = 1.7
#: ... the normal at a sample is taken perpendicular to the curve there, closest to the
#: normal at p; samples where the curve runs within this angle of the normal at p
#: (around a rim) have none to speak of and are left out of both estimates, degrees.
NOISE_MIN_TANGENT_NORMAL_ANGLE_DEG = 30.0
#: Samples on each side of the moving average whose chord lengths parametrise a curve fit.
CURVE_PARAM_SMOOTHING = 3
#: ... at least; more on densely sampled curves: the moving average widens until the noise
#: left in a chord across it is at most this fraction of the chord (3 coordinates of noise
#: sigma, estimated from the third differences, over 2k + 1 samples: sigma sqrt(6 / (2k + 1))
#: against 2k sample spacings). Otherwise, with samples much closer together than the noise
#: (a probe logging 5,000 points along 0.3 at noise 0.002), the chords are noise, the fit
#: window collapses and the curvature is nonsense (K = -1.7e7 on the ellipsoid, measured).
#: At 0.25 every protocol of 61 points per curve keeps 3 (the worst, curves 0.2 long at
#: noise 0.004, has 0.11).
CURVE_PARAM_MAX_NOISE_CHORD = 0.25
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
#: The tolerance on each principal curvature is at least this many times the estimate's
#: own standard error (LocalGeometry.curvature_sd: each curve's least-squares deviation at
#: p, carried through Euler's formula). On default and short noisy touches of the paper
#: surfaces (160 touches, stop 34) the error was 0.43 of the tolerance above (median), 0.99
#: at most, so this leaves them as they were; a touch whose second curve was cut short on
#: one side of p read K -0.68 on a convex ellipsoid (an error 5 times that tolerance) and
#: the lookup left the ellipsoid out, naming the elliptic paraboloid at p 1.000.
CANDIDATE_SD_FACTOR = 1.0
#: A refined pose of a touch whose side is known (its normal given, on a closed model) is
#: dropped where the touch's normal, placed, meets the surface's normal at the contact at
#: a cosine below this: the data were carried through a thin wall (about -1 there). Not
#: 0: across a sharp edge the contact's closest point can lie on a face whose normal is
#: up to 90 degrees from the curves' (a knife edge), and noise tips it over.
POSE_SIDE_MIN_COS = -0.5
#: Candidates closer than this fraction of the curves' half-length are merged (one basin).
#: On the analytic surfaces 0.5 and 24 candidates lost no basin, but on scanned meshes
#: (YCB mustard bottle, banana, power drill; 12 seeded touches each, noise 1e-4 m) the
#: local search's basins are smaller: 20 of 36 registrations ended above the oracle's
#: error (started at the true pose) with 0.5 and 24, 12 of 36 with 0.25 and 64, for about
#: 30% more time.
CANDIDATE_SPACING_FRACTION = 0.25
#: Most candidates kept per model and side after spreading them over the surface.
MAX_CANDIDATES = 64

# --- initial phi (Section 2.2.1) -----------------------------------------------------------
#: Steps of the discretisation of [0, 2 pi) in which every local minimum is bracketed.
PHI_STEPS = 36
#: Data points (evenly subsampled) used while searching phi; all points are used later.
PHI_POINTS = 36
#: A bracket is refined only if its grid error is within this factor of the best one.
PHI_REFINE_RATIO = 1.5
#: Absolute tolerance of the bracket refinement, radians.
PHI_XTOL = 2e-3
#: The phi grid by bounds (:mod:`meshrec.registration.bounded`): points evaluated
#: (cumulative, farthest from the contact first) before each check of which samples can
#: still matter; the rest of the PHI_POINTS follow for the samples left. The registrations
#: are the same bits as with the whole grid; only the work changes. Measured on the
#: candidates of 8 touches of the paper surfaces and 3 YCB touches against the 10 scans
#: (as phi_brackets calls it), twice: (6, 12, 24) took 0.47 and 0.68 to 0.72 of the
#: whole grid's CPU time (0.32 and 0.55 of its point distances); (3, 6, 12, 24),
#: (4, 8, 16, 24, 30), (9, 18, 27) and (12, 24) took 0.47 to 0.59 and 0.67 to 0.79.
PHI_BOUND_ROUNDS = (6, 12, 24)
#: How the phi grid's distances are computed: "fields" (local height-fields at the
#: candidates, :mod:`meshrec.registration.fields`, exact by bounds where a field may not
#: hold) or "exact" (closest-point queries by bounds, PHI_BOUND_ROUNDS, as until stop 26).
#: The grid only ranks the candidates and gives their starting angles; every later stage
#: is exact. See docs/performance.md, "The phi grid from height-fields".
PHI_GRID_DISTANCES = "fields"
#: Sites fitted per field (the nearest, thinned so that about FIELD_FILL * FIELD_NEIGHBOURS
#: lie within the field's reach).
FIELD_NEIGHBOURS = 40
FIELD_FILL = 0.8
#: A field reaches this factor times the data's largest distance from the contact across
#: the normal.
FIELD_REACH = 1.1
#: Degree of the fields' polynomials, and the weight of a slope equation in their fits.
FIELD_DEGREE = 4
FIELD_SLOPE_WEIGHT = 1.0
#: A field is trusted only if its farthest neighbour is at least this fraction of the reach
#: away (the sites cover it) ...
FIELD_MIN_COVER = 0.75
#: ... the neighbours' mean offset across the normal is at most this fraction of the
#: farthest's distance (no rim of an open surface beside it) ...
FIELD_MAX_OFFCENTRE = 0.3
#: ... and the fit's RMS height residual is at most this fraction of the reach (no fold,
#: no curvature too high for the polynomial); no crease site may be among the neighbours.
FIELD_MAX_RESIDUAL = 0.02
#: A height-field row's local minima within this factor of its least estimate, and their
#: two neighbours, are computed exactly: the ranking, the pruning and the screening's
#: starts then read exact values (on a YCB banana touch the field's least sample was one
#: step beside the exact one, and the screening from it missed the best basin).
FIELD_VERIFY_RATIO = 1.1
#: ... on the FIELD_VERIFY_FIRST rows of least estimate (the least exact error among them
#: and the exact rows sets the pruning threshold) ...
FIELD_VERIFY_FIRST = 8
#: ... and on the rows whose least estimate is within this factor of the pruning threshold
#: (SEARCH_PRUNE_RATIO times that least error): the others are pruned on their estimates.
#: A row's least estimate over its least exact error (1st, 5th, 50th, 95th and 99th
#: percentiles; every field that holds at the candidates of 8 paper-surface touches, 4
#: touches of shape_set(20) and 6 YCB touches, all models): 0.16, 0.44, 1.00, 1.21, 1.48
#: on the surfaces, 0.29, 0.92, 1.00, 1.09, 1.21 on the shapes, 0.75, 0.83, 0.99, 1.07,
#: 1.14 on the scans. Estimates too low are verified; only one too high by this factor
#: is pruned wrongly.
FIELD_PRUNE_MARGIN = 2.0

# --- local search on surface charts (Section 2.2.1) and final refinement --------------------
#: Candidates (best by their phi error) that get a full local search.
LOCAL_SEARCHES = 8
#: Data points (evenly subsampled) used by the chart search; the refinement uses all.
SEARCH_POINTS = 64
#: The local searches stop after this many in a row that did not improve the best error
#: by at least SEARCH_IMPROVEMENT (a fraction): later candidates rank worse after the
#: screening and mostly find the same minima again.
SEARCH_PATIENCE = 3
SEARCH_IMPROVEMENT = 0.01
#: ... but only once the best mean distance is within this factor of the noise RMS that
#: the curve fits estimate (a right superposition leaves 0.80 to 0.87 of it: Gaussian to
#: uniform noise; a near miss on the crossed trough, seed 4, left 1.07). The rule looks at
#: one model's searches only, so that no model's result depends on another's.
SEARCH_GOOD_FIT = 1.0
#: The local-search results (best by their subsample error) given the final rigid
#: refinement on all the points. All of them: at the noise floor the 64-point subsample
#: misranks basins whose errors differ by a few percent (100 seeded touches per paper
#: surface: with 3, the right basin was searched but not refined on the monkey saddle,
#: seed 33, 0.34 off, and on the crossed trough, seeds 67 and 93), and the refinement
#: costs a few milliseconds.
REFINE_BEST = 8
#: Candidates whose best sampled phi error exceeds this factor times the best candidate's
#: are not searched (the paper's example: right-basin starts within a factor of 2).
SEARCH_PRUNE_RATIO = 3.0
#: Candidates (best by their sampled phi error) screened by a few rigid-refinement steps;
#: the best screened ones get the full phi refinement and local search.
SCREEN_CANDIDATES = 48
#: Rigid-refinement iterations of the screening.
SCREEN_ITERATIONS = 3
#: Step of the chart's one-sided difference in (u, v) for the local search's Jacobian, as
#: a fraction of the curves' half-length.
CHART_FD_STEP = 1e-3
#: Chart re-centrings at most per local search.
MAX_RECENTRES = 6
#: A re-centring smaller than this fraction of the half-length ends the local search.
RECENTRE_TOL_FRACTION = 1e-3
#: Function evaluations allowed for one chart's least-squares solve.
CHART_MAX_EVALS = 30
#: Relative tolerance (ftol and xtol) of one chart's least-squares solve; the rigid
#: refinement that follows polishes the result, so the search only has to reach the
#: basin. 1e-3 instead of 1e-5 halves the solves' evaluations (5.6 instead of 11.6 per
#: solve) and cuts the search stage by a third, with the same verdicts, best models and
#: plausible sets on 32 seeded touches (tools/tolerances.py, reports/chart_tol.md).
CHART_TOL = 1e-3
#: Iterations of the paper's steepest descent (reference method) at most.
STEEPEST_MAX_ITER = 300
#: The steepest descent works in (u / half-length, v / half-length, phi): its first step
#: is this long in those units (5% of the half-length, or 0.05 rad) ...
STEEPEST_STEP = 0.05
#: ... its gradient is a central difference with this step (in the same units) ...
STEEPEST_FD_STEP = 1e-5
#: ... its backtracking line search halves the step (STEEPEST_SHRINK) until the Armijo
#: condition E1 < E0 - STEEPEST_ARMIJO * step * |grad| holds (the usual 1e-4), giving up
#: below STEEPEST_MIN_STEP; after an accepted step the next starts STEEPEST_GROW times
#: longer. It stops when E improves by less than STEEPEST_REL_TOL (a fraction). These are
#: the values the reference method was written with; the default method is "lm".
STEEPEST_MIN_STEP = 1e-7
STEEPEST_ARMIJO = 1e-4
STEEPEST_SHRINK = 0.5
STEEPEST_GROW = 1.5
STEEPEST_REL_TOL = 1e-7
#: Iterations of the final rigid (6-DOF) refinement at most.
REFINE_MAX_ITER = 30
#: A rigid refinement (the final one of each search, the joint ones of several touches)
#: stops at the first step that improves the sum of squares by less than this fraction.
#: 1e-5 instead of 1e-6: on poor fits (wrong models, a large residual) Gauss-Newton
#: converges linearly and crawled on to the 30-iteration limit; the same verdicts, best
#: models and plausible sets on 38 seeded touches, the best error within 2.5e-4 of
#: itself, 0.86 to 0.96 of the CPU time (tools/tolerances.py, reports/refine_tol.md).
REFINE_REL_TOL = 1e-5
#: Levenberg-Marquardt damping of the rigid refinement (relative to diag(J^T J)): the
#: first iteration's, the factor of the "tenfold" schedule (it grows by it after a
#: rejected step and shrinks by it after an accepted one), the largest tried before giving
#: up (no step reduces the error), and the least it shrinks to. The start and factor are
#: Numerical Recipes' (mrqmin: 1e-3, times or divided by 10); the bounds only stop the loop.
REFINE_DAMPING = 1e-3
REFINE_DAMPING_FACTOR = 10.0
#: How the damping moves between steps (meshrec.registration.damping, read at call time):
#: "gain" (Nielsen's: by the ratio of the actual to the predicted drop) or "tenfold" (by
#: REFINE_DAMPING_FACTOR either way, Numerical Recipes', the default until stop 25). The
#: tenfold swings had about half the trial steps rejected on poor fits. With "gain", on
#: 38 seeded touches: the same verdicts, best models and plausible sets, the best errors
#: within -2.1% and +0.64% (medians within 1e-4), the refinement stage 0.63 to 0.96 of
#: its time and the recognition 0.84 to 0.94 of its CPU time (1.04 on the YCB scans,
#: whose time is mostly the phi grid) (tools/tolerances.py, reports/damping.md).
REFINE_DAMPING_SCHEDULE = "gain"
REFINE_MAX_DAMPING = 1e8
REFINE_MIN_DAMPING = 1e-9
#: Two refined poses whose contacts are closer than this fraction of the curves'
#: half-length ... (Registration.poses keeps one of them, the better)
POSE_DUPLICATE_FRACTION = 0.05
#: ... and whose rotations differ by at most this angle, degrees, are the same minimum.
POSE_DUPLICATE_ANGLE_DEG = 1.0
#: The default local-search method: "lm" (least squares on charts) or "steepest" (the paper's).
SEARCH_METHOD = "lm"

# --- model index: the curvature table at sites on the smooth surface (Section 2.1, issue 13)
#: Radius of the neighbourhood the curvature at a site is fitted over, as a fraction of
#: sqrt(surface area) of the model (the touch curves are SIM_LENGTH_FRACTION of it long,
#: so this is about 0.36 of their half-length), whatever the mesh resolution.
CURVATURE_SCALE_FRACTION = 0.04
#: Distance asked between curvature sites (Poisson-disk sampling of the surface), as a
#: fraction of sqrt(surface area): about 4,000-5,000 sites per model (the sampling keeps
#: about 0.27 / spacing^2 per unit area). Crease sites are this far apart along an edge.
SITE_SPACING_FRACTION = 0.008
#: Uniform candidate samples per spacing^2 of surface area that the smooth sites are
#: thinned from (meshrec.model.thinning, dart throwing in a random order) ...
SITE_CANDIDATES_PER_SPACING2 = 1.5
#: ... to at least this many spacings apart. With 1.5 candidates per spacing^2, 1.35
#: keeps 0.27 sites per spacing^2 (the density trimesh's remove_close kept from 6
#: candidates per spacing^2, which left holes 2.65 spacings wide; these leave at most
#: about 2.3 on a blob).
SITE_THINNING_FACTOR = 1.35
#: Radius of the neighbourhood whose (K, H) make a site's range (what a touch straddling a
#: change of curvature may report), as a fraction of sqrt(surface area): about half the
#: touch curves' half-length.
SITE_RANGE_FRACTION = 0.05
#: Adjacent faces whose normals differ by more than this (degrees) meet at a sharp edge:
#: normals are not blended across it, curvature is fitted on each side separately, and
#: sites along it are crease sites. Above the 22.5 degrees between the faces of an
#: 80-face icosphere, below the 90 degrees of a box or a cylinder's rim.
SITE_CREASE_ANGLE_DEG = 40.0
#: A touch crosses a sharp edge (a warning) when at least this many of its points, placed
#: by the best pose, lie on each of two or more smooth patches of the model.
EDGE_MIN_POINTS = 3
#: Adjacent vertex normals further apart than this (degrees) mark a crease: no smooth
#: surface is implied across that edge, and the distance there is to the flat faces.
SMOOTH_MAX_NORMAL_ANGLE_DEG = 25.0
#: The lookup scales the K axis by 1 / (2 median |H|); below this fraction of 1 / scale
#: the median |H| counts as zero (a flat model) and 1 / scale is used instead.
LOOKUP_MIN_H_FRACTION = 1e-6

# --- model resolution check (meshrec.model.resolution; measured on the bundled models, the
# --- YCB scans in ../shared/data/ycb and trimesh primitives, see the README) ---------------
#: A touch curve should cross at least this many mesh vertices (curve length over the median
#: edge), so that the curvature ball and the lookup see the surface at the curve's scale.
#: The models recognised reliably cross 41 (bundled, 80k faces) and 17 to 18 (YCB scans);
#: trimesh's default icosphere (subdivisions 3) crosses 5.2 and its 32-section cylinder 0.8.
RESOLUTION_MIN_VERTICES_PER_CURVE = 8.0
#: A face is flat, and left out of the vertex count and the slivers, when every corner normal
#: of the smooth surface is within this angle (degrees) of the face's normal: the triangles
#: of a plane are exact however few (a box's 12). A 32-section cylinder's side bends 5.6
#: degrees per face, an icosphere(5)'s faces about 1.
RESOLUTION_FLAT_ANGLE_DEG = 0.25
#: Largest chord error (the sagitta the vertex normals imply at an edge's middle) as a
#: fraction of the curve length. The YCB scans, recognised well, reach at most 5.2e-3 and
#: the bundled models 1.9e-4; trimesh's default torus 1.0e-2 and icosphere(2) 1.6e-2.
RESOLUTION_MAX_CHORD_FRACTION = 8e-3
#: A face is a long thin sliver when its longest edge squared over its area, times
#: sqrt(3) / 4 (1 for an equilateral triangle), exceeds this: the YCB scans have 99% of
#: their faces under 5.5; a CAD cylinder's full-height side faces (radius 10, height 40,
#: 32 sections) reach 18.
RESOLUTION_SLIVER_ASPECT = 10.0
#: Largest fraction of the surface area in slivers: the YCB scans have at most 0.2% of
#: their faces above RESOLUTION_SLIVER_ASPECT; a CAD cylinder is 80% sliver by area (its
#: side has no vertex inside, so its curvature is never seen).
RESOLUTION_MAX_SLIVER_FRACTION = 0.05

# --- the Open3D baseline of the benchmarks (meshrec.bench.baseline) -----------------------
#: Points sampled on each model's mesh for the baseline's target cloud.
BASELINE_MODEL_POINTS = 20000
#: Radius of the touch points' normal estimate, fraction of the touch data's extent.
BASELINE_NORMAL_RADIUS = 0.1
#: Radius of the FPFH features, fraction of the touch data's extent.
BASELINE_FPFH_RADIUS = 0.25
#: RANSAC's inlier distance, fraction of the touch data's extent.
BASELINE_RANSAC_DISTANCE = 0.05
#: RANSAC iterations at most (Open3D's default is 100,000).
BASELINE_RANSAC_ITERATIONS = 100000
#: ICP's correspondence distance, fraction of the touch data's extent.
BASELINE_ICP_DISTANCE = 0.1
#: ICP iterations at most (Open3D's default).
BASELINE_ICP_ITERATIONS = 30
#: Random starts of the multi-start ICP (as measured in the developers' brief: 256).
BASELINE_STARTS = 256
#: The best ICP results (by fitness, then RMS) rescored on the mesh.
BASELINE_RESCORED = 8

# --- benchmark protocols (meshrec.bench.protocols) ----------------------------------------
#: Points per curve and probe noise (mm) of the paper's experiment on its objects (Sec. 4).
BENCH_OBJECT_POINTS = 41
BENCH_OBJECT_NOISE = 0.1
#: Benchmark contacts on the objects' curved sides stay this far from the rims, mm.
BENCH_RIM_MARGIN = 30.0

# --- input checks: touch data, model meshes, units (hardening) -----------------------------
#: The curves must meet at one point: their fitted passages there may be at most this
#: fraction of the curves' half-length apart (and a given contact at most this far from
#: each curve) ... Measured on simulated touches (15 seeds per paper surface, noise up to
#: 0.03; 120 seeds per bundled object, noise 0.1 mm): passages at most 6.8% of the
#: half-length apart (curves across a cylinder's rim), 0.2% on the surfaces at noise 0.001.
MAX_MEET_FRACTION = 0.1
#: ... or this many times the curve fit's rms residual (the noise), if that is larger.
#: With both, the measured passages stay within half the allowance.
MAX_MEET_NOISE_FACTOR = 10.0
#: Largest coordinate magnitude of touch data (beyond it the fits' squares lose all
#: precision; no probe measures that far in any unit).
TOUCH_MAX_COORDINATE = 1e12
#: Smallest extent (bounding-box diagonal) of a curve, as a fraction of its largest
#: coordinate magnitude (below it, float64 cannot resolve the curve's shape) ...
TOUCH_MIN_RELATIVE_EXTENT = 1e-9
#: ... and in absolute terms, data units (a nanometre in metres; squares of smaller
#: lengths underflow).
TOUCH_MIN_EXTENT = 1e-9
#: A touch whose extent (bounding-box diagonal of all its points) is more than this many
#: times larger than the bounding-box diagonal of every model is refused as a likely unit
#: mismatch: curves on a surface lie inside the model's box, so 1 is the most a real touch
#: can measure; 2 leaves room for noise. Simulated touches measure about 0.3 of the
#: diagonal; millimetres against metres make it 300 (a touch of 1 mm in millimetres still
#: exceeds a 0.3 m model's box 3 times).
UNIT_MAX_TOUCH_DIAGONALS = 2.0
#: ... and one more than this many times smaller than every model's diagonal is refused
#: too: metres against millimetres make a simulated touch 0.0003 of it, while a real
#: touch of a few millimetres on a 300 mm object is still 0.01.
UNIT_MISMATCH_RATIO = 100.0
#: Most curves in a touch (a probe traces three; the pairwise checks of the curves cost
#: the square of their number).
MAX_CURVES = 16
#: Most points per curve, and in a whole touch. A probe samples tens to hundreds per
#: curve. Reading, checking and the common-point search are O(n log n); the registration
#: scores every point, so the recognition's time grows with them. Measured at the limit
#: (3 curves of 9,999 points on the bundled ellipsoid, the shared 2-core machine): reading
#: the CSV 0.20 s (JSON 0.05 s), the local geometry 0.09 s, `meshrec recognize` on the
#: bundled surfaces 10.1 s in all (8.4 s recognising); 3 curves of 99,999 points took 60 s.
MAX_POINTS_PER_CURVE = 10_000
MAX_TOUCH_POINTS = 30_000
#: Largest touch file read, bytes: 30,000 points take 1.8 MB as CSV or JSON (full
#: precision); the rest is room for whitespace. A file over it is refused before it is
#: read, and a CSV of more rows than MAX_TOUCH_POINTS as soon as they are counted
#: (8 MB of rows: 0.05 s).
TOUCH_MAX_FILE_BYTES = 8 * 1024 * 1024
#: Largest truth file read, bytes (one is about 1.3 kB).
TRUTH_MAX_BYTES = 1024 * 1024
#: A transform read from a file is rigid if R^T R is the identity and its last row is
#: (0, 0, 0, 1) within this (meshrec writes floats that read back exactly; this leaves
#: room for a rotation written by hand with 7 significant digits).
RIGID_TOLERANCE = 1e-6
#: Largest simulated noise half-width, as a fraction of sqrt(surface area) of the model
#: (beyond it the curves are noise; 1e308 overflows the random draw).
SIM_MAX_NOISE_FRACTION = 1.0
#: Most points per simulated curve (odd, within MAX_POINTS_PER_CURVE: what readers accept).
SIM_MAX_POINTS = 9_999
#: Mesh vertices closer than this fraction of the mesh's bounding-box diagonal are merged
#: (STL stores every face's corners separately; like trimesh's absolute 1e-8 on a unit
#: model); relative, so that meshes in any unit merge alike (an absolute tolerance
#: overflows on coordinates of 1e11 or merges tiny models away).
MESH_MERGE_FRACTION = 1e-8
#: A mesh whose cleaning drops more than this fraction of the faces read as degenerate
#: (duplicates lose nothing: not counted) gets a MeshWarning (meshrec.model.mesh), which
#: names single precision far
#: from the origin when its steps exceed this fraction of the median edge: a float32 STL
#: at 1e6 (steps 0.06) lost 78% of a fine ellipsoid's faces without a word.
MESH_LOST_FACES_WARN = 0.01
#: A mesh whose coordinates are all single precision (an STL stores float32) and whose
#: steps at its largest coordinate exceed this fraction of its median edge gets a
#: MeshWarning even when few faces collapse: the surface is staircased, its faces tilted
#: by up to about that many radians (a black-box probe, stop 36: a YCB scan moved 1e4 m
#: from the origin had steps of 0.98 mm, 37% of its 2.6 mm median edge; 0.7% of its faces
#: collapsed, below MESH_LOST_FACES_WARN, and answers went wrong without a word). At 5%,
#: that scan 1e3 m out (steps 0.061 mm, 2.3%) is not warned about.
MESH_QUANTUM_WARN = 0.05
#: A model whose size (bounding-box diagonal) is more than this many times the median of
#: the other models' in its folder, or less than its inverse, gets a LibraryWarning: in
#: other units, most likely (mm among m: 1,000 times; a black-box probe, stop 36, put a
#: YCB scan in mm among scans in m, and it never fitted, without a word). 200 leaves a
#: 10 mm screw beside a 1.5 m frame alone.
LIBRARY_SIZE_RATIO_WARN = 200.0

# --- touch quality -------------------------------------------------------------------------
#: Warn (RoughFitWarning) when the curve fits leave more than this many times the noise the
#: samples themselves show (LocalGeometry.fit_to_noise) ... On the analytic surfaces the
#: ratio is about 1. On 80 touches on four scanned YCB objects (noise 1e-4 m), 27 were
#: above 3: 6 of them were not recognised and 9 reached the oracle's minimum, against 2
#: and 33 of the 53 below it; touches across a box's edge gave 3 to 10.
ROUGH_FIT_RATIO = 3.0
#: ... and the fit residual is more than this fraction of the curves' half-length (so that
#: near-noiseless data, whose two estimates are both rounding-level, never warn).
ROUGH_FIT_MIN_FRACTION = 1e-3
#: One touch whose curve fits leave more than this many times the noise (a rough fit far
#: beyond the measured range) names no model: ``recognised`` becomes ``ambiguous``. The
#: curvature at p, which the lookup matches, is not defined there, and the search can miss
#: the right model's pose while another fits: a knob's knurled rim touched with +-1e-3 on
#: the bundled parts (19.7 times) was `recognised` as the flange, the knob's true pose
#: fitting 9 times better than the flange's. The largest ratio over the touches of
#: ``tools/calibration.py`` (its 414 generated-shape touches, 1.24) and of
#: ``tools/families.py --trials 2`` (192: parts, primitives, YCB scans, surfaces; 8.8, on a
#: part) is below it: none of their answers changes (regenerated and measured, stop 30).
ROUGH_HOLD_RATIO = 10.0
#: Two touches whose points all agree within this fraction of their extent are one touch
#: given twice (re-saved with rounding, or a jitter added), refused like an exact copy: a
#: second touch of the same place carries the probe's own noise, which no probe has below
#: 1e-7 of the touch's size (10 nm on a 0.1 m touch).
TOUCH_COPY_FRACTION = 1e-7
#: ... or within this fraction of the samples' scatter about their curves (the noise per
#: coordinate, estimated from second differences: ``recognize._sample_scatter``): a copy
#: rounded or jittered far below the probe's noise is not a new measurement (a touch in mm
#: rounded to 1 um against 20 um of noise is 0.1 of it at most); a second touch of the same
#: place differs by its own noise, several times the scatter at some point.
TOUCH_COPY_NOISE_FRACTION = 0.25

# --- before a model is named: its poses tried on the others (naming._transferred) -------
#: The named model's best poses (least RMS first) refined on every other model ...
TRANSFER_POSES = 4
#: ... where one starts within this factor of the named model's RMS (or of the noise, if
#: larger): variants of one part in one frame fit there (a pose at 3 times the noise is
#: within a few refinement steps); a model in another frame starts far off and costs one
#: query.
TRANSFER_REACH = 3.0

# --- calibrated scores and the verdict (meshrec.recognition.scoring) -----------------------
#: The model meshes' own error joins the noise the scores take (rescore.model_error):
#: that of every model whose best fit comes within this factor of the best RMS (a rough
#: mesh's right model fits worse than the touch's noise alone explains).
MODEL_ERROR_REACH = 2.0
#: ... and the answer says so (a caution) where that error is more than this fraction of
#: the touch's own noise.
MODEL_ERROR_NOTE = 0.3
#: Degrees of freedom of the pose search (a rigid motion), taken off in the fit test.
POSE_DOF = 6
#: Effective number of independent residuals per data point (the temperature of the
#: likelihood). Fitted by tools/calibration.py on its training group only (shape set 1,
#: nine generated shapes, curves 0.3 long, noise 0.002, 108 touches): mean -log p(truth)
#: 0.420 at 0.2, 0.376 at 0.3, 0.355 at 0.4, 0.347 at 0.5, 0.352 at 0.7, 0.384 at 1.0.
#: Below 1 because the residuals of a search-found pose on a mesh are not independent
#: and the search's own imperfection adds to them. Held-out reliability:
#: reports/calibration.md.
SCORE_ESS_FRACTION = 0.5
#: Floor of the noise estimate, fraction of the curves' half-length (added in quadrature):
#: the facets and the smoothing of the mesh leave some misfit even on noiseless data
#: (1.5e-4 on curves 0.3 long, an eighth of the issue's noise of 0.002 / sqrt(3)).
SCORE_NOISE_FLOOR_FRACTION = 1e-3
#: The plausible set holds the most probable models up to this total probability, so
#: that the truth is inside at least 95% of the time when the probabilities are
#: calibrated (measured: 99.3% on the issue's condition, held out).
VERDICT_COVERAGE = 0.95
#: A flat touch weighs each model by the share of its surface that is flat over the
#: curves' reach (meshrec.recognition.flatness): a random touch on a box is flat far more
#: often than one on a cylinder, whose caps fit it as well. The weights are clipped to at
#: most this ratio between models, so that the prior orders the models the data cannot
#: separate but never decides alone (at 4, two tied models get at most 0.8 and 0.2: both
#: stay plausible at VERDICT_COVERAGE); the recognition also keeps every model plausible
#: on the data alone.
FLAT_PRIOR_MAX_RATIO = 4.0
#: A curvature site counts as flat for that prior when its normal turns less than this
#: (radians) over the curves' reach, besides being within the touch's lookup tolerance:
#: the planes of CAD models and trimesh primitives (0 to 1e-6), not a gently curved
#: shape that short noisy curves cannot tell from a plane (the calibration's curves 0.2
#: long on unit-size shapes turn 0.05 to 0.1 over theirs).
FLAT_SITE_BEND = 0.01
#: "unknown" when the best model's RMS residual exceeds this many times the noise ...
#: (in-library simulated touches: best RMS / noise at most 1.23 over 90 touches of
#: the issue's condition, most between 0.92 and 1.11; shapes of clearly different
#: curvature give 10 or more; real scans leave more misfit than simulations, hence 2,
#: not 1.3)
UNKNOWN_FIT_RATIO = 2.0
#: ... and its chi-square tail probability (meshrec.recognition.scoring.fit_p_value) is
#: below this.
UNKNOWN_P_VALUE = 1e-3
#: A second, widened lookup pass registers every model again when the best model's
#: chi-square tail probability is below this (a fit worse than the noise allows: 18 of
#: 494 calibration touches, 4.7% of the total time) ...
WIDEN_P_VALUE = 0.01
#: One touch is named (`recognised`) only after that widened pass (and the denser one)
#: whenever its best fit's chi-square tail is below this, though above WIDEN_P_VALUE: a
#: marginal fit is where the touched model's own search may have ended short of its pose
#: while another model fits about as well (a YCB touch of the gelatin box, normal noise
#: 0.1 mm, seed 3003, named the foam brick at p 1.000 with a tail of 0.016; the passes
#: find the gelatin box's pose, which fits better). In reports/calibration_raw.json 5 of
#: 215 `recognised` answers had a tail below 0.1 (4 right, 1 an object not in the
#: library), so the extra passes run on about 2% of named touches.
NAME_P_VALUE = 0.1
#: A model is only `recognised` when it fits to the noise: its chi-square tail is at
#: least this; below it (and above UNKNOWN_P_VALUE) the answer is `ambiguous`. In
#: reports/calibration_raw.json (494 touches) no right `recognised` answer had a tail
#: below 0.01, and 4 of 13 wrong `recognised` answers (objects not in the library) did.
RECOGNISE_P_VALUE = 0.01
#: ... with the (K, H) lookup window this many times wider (a capsule whose trimesh mesh
#: had no vertex on its cylinder, 42 of 60 touches rejected at 1x: 8 were found at 3x,
#: every one at 4x).
LOOKUP_WIDEN_SCALE = 4.0
#: ... and, for one touch that even then fits no model to the noise, once more with up to
#: this many candidates per model (MAX_CANDIDATES otherwise); every model keeps its best
#: fit of the passes. The widened window can match most of a rough scan's sites (5,474 of
#: the YCB scissors' 6,068 for a touch across its edge) and 64 spread candidates then left
#: the true contact 6 mm from the nearest.
LOOKUP_DENSE_CANDIDATES = 256
#: One touch about to be `recognised`: the named model is registered again with up to this
#: many candidates (where its window held more sites than MAX_CANDIDATES) and keeps the
#: better fit, before its pose is given (naming._confirmed). Measured (stop 31): six
#: short touches of a superellipsoid and a cone that a probe found `recognised` with the
#: pose `fixed` 8 to 34 mm off; the five re-run all found the true pose with 256 (with the
#: window widened 4 times instead, four of five), in 0.3 to 0.5 s each.
CONFIRM_CANDIDATES = 256
#: ... and a caution says so when the better pose moves the data by more than this
#: fraction of the curves' half-length (a step within the same basin says nothing).
CONFIRM_MOVED_FRACTION = 0.05
#: The curvature estimate at the contact is out of its range when the curves would turn by
#: more than this many radians over their half-length at it (the larger principal
#: curvature's magnitude times the half-length). Then, before one model is named, the
#: models the lookup alone rejected are registered again with the window open
#: (LOOKUP_OPEN_SCALE). Measured (stop 28): the bundled surfaces and objects 0.08 to 0.85;
#: 120 touches each on 30 generated shapes 1.17 at most (default touches), 0.67 (curves
#: 0.3, noise 0.002), 0.54 (curves 0.2, noise 0.004); 10 mm objects in metres touched with
#: the default noise of 1 mm (noise 6% of the half-length) 0.7 to 431, where the lookup
#: left the touched model out and another was named with probability 1; the YCB scans
#: (default touches) up to 5.3 across rims and box edges.
CURVATURE_MAX_TURN = 2.0
#: A RoughFitWarning also names the curves' length as a possible cause when they turn by
#: more than this (radians over their half-length at the estimated curvature): curves 1.6
#: long on the bundled ellipsoid (1.95) were told only that they might cross an edge.
ROUGH_FIT_LONG_TURN = 1.0
#: A lookup window this many times the calibrated one holds every site of any model.
LOOKUP_OPEN_SCALE = 1e6
#: One touch whose noise (LocalGeometry.noise_rms, the noise its samples show) is more
#: than this fraction of its curves' half-length is never `recognised`: the probabilities
#: were measured on touches up to about half of it (curves 0.2 long with noise +-0.004 on
#: unit-size shapes: 0.023; the YCB scans' default touches 0.039 at most). Measured
#: (stop 28): 10 mm objects in metres touched with the default noise of 1 mm, 0.057 to
#: 0.076, gave 5 `recognised` answers naming the wrong model with probability 1 in 35
#: touches (the curvature estimate 10 to 400 times too large, the search missing the
#: touched model's pose).
SCORE_MAX_NOISE_FRACTION = 0.045

# --- pose freedom (meshrec.recognition.freedom) ----------------------------------------------
#: A rigid motion is free at the fitted pose when the singular value of the rigid Jacobian
#: of the point-to-surface residuals along it is below this fraction of the largest (rows
#: [n, (x - c) / L x n] at the points' closest points, L their RMS spread). Measured on
#: default simulated touches recognised against the model alone (6 seeds each): a side
#: touch of the bundled 80,000-face cylinder 2e-19 to 4e-7 (a slide along and a turn about
#: the axis), the bundled sphere 3.5e-5 to 2.7e-4 (three turns about its centre); the most
#: nearly free motion of the bundled ellipsoid 8.1e-4 to 9e-3, of the elliptic paraboloid
#: 1.4e-3 to 4.3e-3 (fixed). A 32-section trimesh cylinder's facets pin the turn about its
#: axis at about 0.03 (not reported free: the mesh, not the object, fixes it).
POSE_FREE_RATIO = 5e-4
#: Near-symmetries (meshrec.recognition.weak): at the best joint pose of several touches,
#: the rigid Jacobian's motions with a singular value below this fraction of the largest
#: are followed a long way for other basins. Three touches on the smooth part of a bumped
#: sphere (bench.shape_set(9, seed=7), bumped_sphere_7_1) gave 0.016, 0.0073 and 0.0026:
#: the joint search had ended 0.99 from the truth at an RMS 1.5% above the true basin's,
#: which a turn of about 60 degrees along the weakest motion reaches.
WEAK_MOTION_RATIO = 0.03
#: At most this many weak motions are followed, weakest first.
WEAK_MOTION_MOST = 2
#: Turn angles (degrees) tried about a weak turn's axis (60 degrees apart: on that bumped
#: sphere the better basin was reached from -90 and from 180 degrees alike, and from 60
#: degrees apart in 0.23 s of CPU against 0.31 s from 45 degrees apart).
WEAK_TURN_ANGLES_DEG = (-120.0, -60.0, 60.0, 120.0, 180.0)
#: Slides tried along a weak slide, in multiples of the points' RMS spread, either way.
WEAK_SLIDE_STEPS = (1.0, 2.0, 4.0)
#: A model's near-symmetry axes (meshrec.model.symmetry) are scanned whole
#: (meshrec.recognition.weak.near_symmetry_scan), in steps that move the farthest data
#: point by this fraction of the points' RMS spread. Fixed angles about the data's own
#: weak turn missed the better basin on a scanned can: a touch of the YCB master chef can
#: (seed 503) was `recognised` with its pose `fixed` 133 degrees about the can's axis from
#: the truth, the true pose fitting 2.4 times better; its basins along the turn are a few
#: degrees wide, and the data's axis was 1.5 mm off the can's.
WEAK_SCAN_STEP = 0.25
#: ... at most this many steps per turn (the step grows beyond) ...
WEAK_SCAN_MOST = 180
#: ... on at most this many of the points, evenly spread ...
WEAK_SCAN_POINTS = 48
#: ... each step settled onto the surface by this many damped point-to-plane steps (the
#: model's axis, fitted to its surface on average, lies a little off the one the touch
#: turns about: a step lands a millimetre or so off the surface, and scored as it lands
#: the better basin reads worse than its neighbours) ...
WEAK_SCAN_SETTLE = 3
#: ... and the deepest this-many distinct basins of each scan (settled poses that place
#: the points more than WEAK_SCAN_APART times their RMS spread from the pose scanned from
#: and from each other) are refined.
WEAK_SCAN_KEEP = 3
WEAK_SCAN_APART = 0.25
#: Before one touch names a model, its pose is also refined from turns by these angles
#: (degrees) about the touch's normal at the contact (meshrec.recognition.weak.
#: normal_turn_starts): the method's rotation phi looked at again. On the 4,000-face
#: drill of a stop-34 probe the pose was 26 degrees off; turns of -30 to -60 degrees
#: reach the truth, -20 and +10 to +60 do not. (Scanned and settled instead, the turns
#: about the normal of a surface curved unequally both ways land 4 times the pose's RMS off
#: it and show no basin there.)
NORMAL_TURN_ANGLES_DEG = (-135.0, -90.0, -45.0, 45.0, 90.0, 135.0, 180.0)
#: A half-turn, or a turn by POSE_SYMMETRY_TURN_DEG, about a principal axis of a model's
#: surface or one of its coordinate axes is a near-symmetry (meshrec.model.symmetry) when
#: it moves the model's surface within this fraction of its diagonal of itself (RMS over
#: points drawn by area), the axis fitted. The YCB scans (in metres) read 0.0015 for the
#: master chef can's turns about its axis and 0.0066 for the tomato soup can's, 0.003 to
#: 0.008 for the cans' and the boxes' half-turns; the bundled ellipsoid (semi-axes 1, 0.8,
#: 0.6) 0.020 about its long axis, which is no near-symmetry; the power drill 0.04 to 0.09.
NEAR_SYMMETRY_FRACTION = 0.01
#: ... the distance taken at this quantile of the points (not their RMS: most of a can with
#: holes, or of a mug with a handle, turns onto itself, the holes and the handle do not).
NEAR_SYMMETRY_QUANTILE = 0.8
#: ... measured at this many points on its surface (drawn by area, seeded; the axis fitted
#: on half of them) ...
NEAR_SYMMETRY_VERTICES = 500
#: A free twist counts as a turn when its rotational part is at least this (unit twists,
#: rotation scaled by L); the rest are slides.
POSE_TURN_FRACTION = 0.1
#: A data point whose surface normal turns by more than this many degrees when it moves
#: by POSE_EDGE_STEP times the points' spread along a tangent lies at a crease (a flat
#: touch reaching a box's edge within the noise): the pose-freedom test leaves it out, as
#: its constraint is one-sided. Above the facet angles of the bundled curved models.
POSE_EDGE_DEG = 20.0
#: ... the step of that probe, as a fraction of the points' RMS spread.
POSE_EDGE_STEP = 0.02
#: A free turn is a symmetry of the model (a cylinder's or a sphere's axis) when the model
#: turned by this many degrees about it stays on itself (not a divisor of 360, so that
#: discrete symmetries such as a 12-fluted knob's do not pass) ...
POSE_SYMMETRY_TURN_DEG = 37.0
#: ... a free slide when the model slid by this fraction of its diagonal does ...
POSE_SYMMETRY_SLIDE = 0.1
#: ... to within this fraction of its diagonal, or twice the mesh's own chord error
#: (its resolution check), whichever is larger; at most 2000 vertices are checked.
POSE_SYMMETRY_TOLERANCE = 2e-3
POSE_SYMMETRY_VERTICES = 2000
#: Pose hypotheses of less weight than this are not compared with the reported pose when
#: counting the distinct poses the data cannot rule out (meshrec.recognition.freedom.
#: with_alternatives): each comparison is a closest-point query of up to
#: POSE_SYMMETRY_VERTICES vertices, and the up to REFINE_BEST poses left out weigh less
#: than 1% together.
POSE_ALTERNATIVE_MIN_WEIGHT = 1e-3
#: A motion is tested for a symmetry on every this-many-th of the vertices first, and on
#: all of them only when those stay on the surface: the same decision, and a motion that
#: is not a symmetry (most of those tested) costs a sixteenth of the closest-point queries.
POSE_SYMMETRY_PROBE_STRIDE = 16
#: Two pose hypotheses are one pose when the object moved from one to the other stays
#: within this many times the pose's precision (PoseFreedom.sigma, the one-sigma
#: displacement of a data point) of itself, or within the symmetry tolerance above: a
#: second basin inside the pose's own uncertainty is not another answer. Measured on 40
#: paper-surface and 40 shape_set(20) touches (seeds 0-9 and 0-1): such near twins lie
#: within 1.4 sigma (a crossed trough's, an ellipsoid's, a capsule's), the distinct poses
#: that remain 3.5 to 430 sigma away (a superellipsoid's, a bumped sphere's second basin,
#: a monkey saddle's third of a turn).
POSE_ALTERNATIVE_SIGMAS = 3.0
#: ... or when the motion from one to the other moves the whole model within this many
#: times that precision of itself (no touch could tell them apart: the bundled crossed
#: trough's quarter-turns, symmetries of the surface that its grid mesh follows to 0.007,
#: 0.1 sigma). A near-symmetry that moves the model by about its precision, such as a
#: decimated scan of a can turned upside down (3 to 6 mm at a sigma of 3 mm), moves the
#: touch by centimetres: those poses are two answers. (Stop 34 took 3 sigma here, and gave
#: such a pose as `fixed`.)
POSE_SYMMETRY_SIGMAS = 0.5

# --- several touches of one object (meshrec.recognition.joint) ------------------------------
#: Pose hypotheses per model refined jointly on every touch's points, the ones with the
#: least joint RMS at their starting pose first (each single-touch registration gives up
#: to ``REFINE_BEST`` distinct poses; most are far off once another touch is added).
JOINT_REFINE_SEEDS = 3
#: ... first on about this many of the points (every k-th) with at most this many
#: iterations, ... (61: one touch of three 61-point curves is refined coarse on every
#: third point, where 150 took them all. Stop 36, 88 recognitions of the bundled sets,
#: one and three touches: the same verdicts, best models and plausible sets, the poses
#: the same up to the models' symmetries, one `fixed` more, 6.5% less CPU in all; the
#: paper surfaces' one-touch median 0.57 s against 0.69 s, paired in one process, the
#: looks before naming that refine jointly 0.12 s against 0.24 s.)
JOINT_COARSE_POINTS = 61
JOINT_COARSE_ITER = 10
#: With many seeds, their starting RMS is first bounded on about this many of the coarse
#: points (a partial sum of squares), and computed on all of them only for the seeds that
#: can still be among the best: the same seeds as computing every one (a cost knob only).
JOINT_START_PROBE_POINTS = 16
#: ... then on all the points those whose coarse RMS is within this factor of the best.
#: (Seeds are refined at all only if their starting RMS is within it of the least.)
JOINT_KEEP_RATIO = 1.5
#: Many seeds (the pair search's 32) converge to a few poses: after this many coarse
#: iterations, a seed whose coarse points lie within JOINT_SAME_POSE_FRACTION x the curves'
#: half-length of a better seed's is dropped (the same basin; refining both on all the
#: points cost half the pair search's joint refinement). Measured on the three pair
#: searches of the first object of tools/touches.py --sets 5: 9-17 of 32 seeds in one
#: basin; seeds 0.02 half-lengths apart after the coarse stage ended at most 0.0057 apart
#: (curves 0.3 long), inside distinct_poses' tolerance (POSE_DUPLICATE_FRACTION, 1 deg).
#: The whole three-touch recognition's time did not change measurably (README).
JOINT_MERGE_ITER = 3
JOINT_SAME_POSE_FRACTION = 0.02
#: The best joint pose, if it used all REFINE_MAX_ITER iterations on all the points, is
#: refined again, this many iterations at most: it is crawling along a nearly free motion
#: (three touches on a bumped sphere, reports/touches_lookalike.md: 0.069 from the truth
#: in the recognition, 0.015 after about 20 more, where a refinement from the true pose
#: ends; tests/test_joint.py).
JOINT_POLISH_ITER = 100
#: The most the fine stage (all the points) was taken to lower the coarse stage's best
#: joint RMS. A model whose coarse poses, scored on all the points, stay above this factor
#: times the RMS at which it can no longer compete with the best joint fit so far
#: (JOINT_PRUNE_LOG_RATIO) keeps them unrefined: an upper bound of what refining gives,
#: and far below the leader either way. Measured on the 226 joint refinements of
#: tools/touches.py --sets 5 6: coarse over fine RMS at most 2.61 (median 1.001), at most
#: 1.73 where the coarse RMS was above 3 x the noise; 3 is a margin over both.
JOINT_FINE_GAIN = 3.0
#: A model whose fit to the touches registered so far already makes it less probable than
#: this, relative to the best joint fit of any model, is not registered on its remaining
#: touches: every further touch can only lower its likelihood (the models' steps run best
#: bound first, meshrec.recognition.bestfirst; e^-14 ~ 1e-6, far below any plausible set).
JOINT_PRUNE_LOG_RATIO = -14.0
#: A touch not yet registered alone on a model is taken, in the model's best conceivable
#: fit, to fit no closer than this times its own noise level (the smaller of its curves'
#: fit RMS and its noise estimate; 0 would take it as fitting perfectly). Measured on the
#: 244 single-touch registrations of tools/touches.py --sets 5 6 (every model, noise
#: +-0.002): the touch's RMS alone over that level was at least 0.924 (median 1.33);
#: 0.75 leaves a margin of 1.5 in the squared residuals.
JOINT_UNREGISTERED_FLOOR = 0.75

#: The recognition's cascade (meshrec.recognition.cascade): with one touch, every model's
#: first stages (lookup, phi, screening) run first, and the local searches only on the
#: models whose best conceivable fit is within JOINT_PRUNE_LOG_RATIO of the leaders'.
#: False: the full search on every model (the reference the cascade is tested against).
CASCADE = True
#: A model's rms is taken to be at least its least screened error over this. Measured on
#: 135 (touch, model) pairs not rejected by the lookup (10 touches on a generated library
#: of 20 shapes, bench.shape_set(20, seed=0); 12 each on the paper surfaces and objects,
#: seeds 5-7): the least screened error over the full search's rms was at most 1.02 on the
#: 38 pairs whose full-search log-likelihood was within JOINT_PRUNE_LOG_RATIO of the
#: leader's (at most 2.39 on the far ones, which lose either way); 2 is a margin of 2.
CASCADE_SCREEN_GAIN = 2.0
#: The leaders' rms is taken to be at most the least screened error times this (the same
#: pairs: the leader's rms over the least screened error was at most 1.82, median 1.29;
#: the screening's error is a mean on the phi subsample, the rms is at least the mean).
#: With these two gains the rule pruned 59 of the 135 pairs, none of the 38 close ones.
#: Where a model was already searched in full (the screen's leaders, or else the model of
#: least screened error, searched first), the least rms reached bounds the leaders' too,
#: with no gain: the smaller bound is used (reports/cascade_gains.md).
CASCADE_LEADER_GAIN = 2.0
#: Rigid-refinement steps on all the points for a pruned model's reported pose (as the
#: screening's SCREEN_ITERATIONS): its error is an upper bound either way, and the full
#: refinement of a far-off fit was a third of a pruned model's time.
CASCADE_PRUNED_ITERATIONS = 3
#: Local searches of a further touch registered alone (the first has LOCAL_SEARCHES): its
#: poses only seed the joint refinement, where the other touches pin the pose down. Half,
#: for time (three touches cost about twice one: reports/touches.md); not tuned further.
JOINT_EXTRA_SEARCHES = 4
#: When a model's joint fit is still worse than the noise allows after every touch was
#: registered alone, each touch's candidate contacts at this many of their best bracketed
#: angles seed the joint refinement too (superellipsoid and bumped-sphere touches whose
#: distinct poses all lay slid off the common pose: tools/touches.py, reports/touches.md).
JOINT_PHI_MINIMA = 2
#: Touches of one object whose curves' sizes (bounding-box diagonals) differ by more than
#: this factor are refused as given in different units (millimetres and metres differ by
#: 1000; real touches of one probe differ by a few times at most).
JOINT_MAX_SIZE_RATIO = 30.0

# --- where to touch next (meshrec.recognition.advice) ---------------------------------------
#: Candidate contacts sampled on the hypotheses' surfaces, about this many in all (shared
#: by weight): enough that the region where two hypotheses differ (a cylinder's cap, a
#: bump) gets tens of samples; the screen and reachability cost grow linearly with it.
ADVICE_CANDIDATES = 400
#: Most candidate contacts accepted (the time grows about linearly: 400 take 0.1 to 0.5 s
#: on the four bundled objects, so 1e5 would take minutes).
ADVICE_MAX_CANDIDATES = 100_000
#: At least this many candidates on each hypothesis, however light (so that a hypothesis
#: of weight 0.01 still offers the places only it has).
ADVICE_MIN_PER_HYPOTHESIS = 16
#: The heaviest (model, pose) hypotheses weighed, at most: the separation's distance
#: queries grow with its square (measured: 0.48 s for 8 over the four bundled objects,
#: 0.11 s for 4 poses of one), and one model's registration keeps up to REFINE_BEST = 8
#: distinct poses, so a model with all its poses fits.
ADVICE_MAX_HYPOTHESES = 8
#: Hypotheses lighter than this (model probability x pose weight) are left out: one adds
#: at most -w log w = 0.007 nats to the entropy there is to gain, below ADVICE_MIN_GAIN.
ADVICE_MIN_WEIGHT = 1e-3
#: Poses of one model are the same hypothesis when the model's vertices (this many, evenly
#: strided) placed by one lie within ADVICE_SAME_POSE_NOISE x the noise of the surface
#: placed by the other: a symmetric object's equivalent poses. Without the merge the four
#: equivalent poses of the bundled elliptic cylinder, 0.003 apart (a fifth of the noise,
#: the refinement's and the facets' scatter), were "separated" with a gain of 0.08 nats.
ADVICE_SAME_POSE_POINTS = 256
#: ... (3: the equivalent poses above differ by at most a third of the noise; a slide
#: along a cylinder by 3 noise levels is already separable by a cap touch).
ADVICE_SAME_POSE_NOISE = 3.0
#: Half-angle of the cone of free space the probe needs around its approach ray, degrees:
#: a candidate whose ray passes closer than sin(15 deg) x s to the surface at distance s is
#: in a concavity or behind another part (a probe tip and its curves need room besides the
#: ray itself).
ADVICE_CLEARANCE_DEG = 15.0
#: The ray is checked out to this fraction of the model's bounding-box diagonal (half: the
#: whole object lies within it from any surface point's view when it is convex).
ADVICE_STANDOFF_FRACTION = 0.5
#: Points along the ray checked, spaced quadratically (denser near the contact, where a
#: concave corner closes in first).
ADVICE_RAY_STEPS = 12
#: With a direction hint, candidates approached more than this far from it are dropped,
#: degrees (a probe pressed along its motion slips on a surface tilted much further).
ADVICE_MAX_APPROACH_DEG = 30.0
#: Points per chord of the simulated next touch's patch (three chords of the curves'
#: length through the contact, 60 degrees apart: 19 distinct points).
ADVICE_PATCH_POINTS = 7
#: Candidates kept after the screen on the contact point alone, scored again on their whole
#: patch (the whole-patch score of every candidate costs about 20 times as many distance
#: queries).
ADVICE_REFINE = 32
#: Separating gains below this (nats) count as none: the hypotheses cannot be told apart
#: at any reachable point (symmetric poses), and the pose criterion is used instead.
ADVICE_MIN_GAIN = 1e-2
#: Gains within this of the best (nats) are ties, broken by the probability-weighted mean
#: squared distance between the hypotheses' surfaces (separation saturates at the full
#: entropy wherever the surfaces differ by a few noise levels; the larger difference is
#: the more robust to model error).
ADVICE_GAIN_TIE = 1e-2
#: Ridge added to the pose information matrix, relative to its mean eigenvalue (symmetric
#: shapes leave null directions: a cylinder's roll about its axis).
ADVICE_RIDGE = 1e-6

# --- the HTTP service (meshrec serve, meshrec.app.commands_serve) -------------------------
#: Largest request body `meshrec serve` reads, bytes: the largest touch file
#: (TOUCH_MAX_FILE_BYTES). A body over it is refused (HTTP 413) from its Content-Length
#: or, without one, as soon as that many bytes have arrived, before it is parsed.
SERVICE_MAX_BODY_BYTES = TOUCH_MAX_FILE_BYTES
#: An oversized body up to this many bytes is read and dropped before the 413 is sent, so
#: that clients which send the whole body before reading the answer (Python's urllib) see
#: it; a larger one is refused at once and its connection closed.
SERVICE_DRAIN_BYTES = 8 * SERVICE_MAX_BODY_BYTES
#: Most touches in one request (`{"touches": [...]}`): each is registered on every model,
#: so a request's time grows with them; a robot makes a handful before it decides.
SERVICE_MAX_TOUCHES = 16
#: A service error's message is one line of at most this many characters (the longest
#: bad-input messages, a unit mismatch with its advice, run to about 400).
SERVICE_ERROR_CHARS = 1000
#: Requests waiting for the recognition lock beyond this get HTTP 503 at once (with a
#: Retry-After) rather than queueing for minutes: a client that wants the answer now
#: should know the service is busy.
SERVICE_MAX_WAITING = 8
#: A request waiting for its turn checks this often (seconds) whether its client is still
#: connected; one whose client has gone is dropped (and leaves the queue) instead of being
#: answered to nobody: a client that times out and retries would otherwise fill the queue
#: with work whose answers nobody reads (a black-box probe, stop 31).
SERVICE_DISCONNECT_POLL = 0.25

# --- joint pose seeds from pairs of touches (meshrec.recognition.pairs) --------------------
#: Model points per touch and side: the (K, H) lookup's hits spread over the surface.
PAIR_CANDIDATES = 400
#: ... chosen (farthest-point sampling) from at most this many of the hits, evenly strided.
PAIR_SPREAD_POOL = 2000
#: Pairs of touches used (those with the longest baselines).
PAIR_MAX_PAIRS = 1
#: Extra tolerance on the distance of a model pair, as a fraction of the touches' baseline.
PAIR_DISTANCE_TOL = 0.02
#: Tolerance on the cosines of the point-pair feature's angles for the estimated normals.
PAIR_ANGLE_TOL = 0.15
#: Pair poses kept by the cheap screens (nearest-vertex distances of a few points: the
#: touches' contacts and one far point each, then a second far point each) ...
PAIR_SCREEN_FIRST = 4096
PAIR_SCREEN = 512
#: ... (a distance counts at most this many half-lengths of the curves in the screen) ...
PAIR_SCREEN_CAP = 1.0
#: ... points per touch (evenly spaced) on which those are scored exactly ...
PAIR_SCORE_POINTS = 8
#: ... and the best this many poses seed the joint refinement.
PAIR_KEEP = 32
#: Pair poses refined jointly (coarse to fine, as JOINT_REFINE_SEEDS).
PAIR_REFINE_SEEDS = 32
#: Search adequacy: after the touch-by-touch step, a model whose joint fit is more than
#: PAIR_SEARCH_GAP below the best model's log-likelihood, but whose best conceivable fit
#: (every touch registered alone, ``joint.log_likelihood_bound``) comes within it of the
#: best, is searched again from pairs of touches before the scores are trusted. Its joint
#: pose may have been missed (look-alike shapes, short noisy curves: reports/touches.md).
PAIR_SEARCH_GAP = 3.0
#: Several touches that no model fits, some of them rough (across an edge): this many of
#: the best models by joint fit are searched from pairs of touches with the window
#: widened, whatever their bound (passes._search_rough_touches).
ROUGH_PAIR_MODELS = 8

# --- ball-tipped probes (meshrec.contact.probe, meshrec.recognition.probing) ---------------
#: A touch recognised without a probe radius is tested for an undeclared ball tip: the
#: data are refined onto the best model's surface offset by R for R up to this fraction of
#: the touch's size (half its largest extent from the centroid; and of the model's size).
PROBE_OFFSET_MAX_FRACTION = 0.5
#: The pose and R are refined together (meshrec.registration.refine.refine_offset) until
#: a step improves the sum of squares by less than this fraction: a step's gain below
#: n 1e-4 rms^2 / noise^2 in the chi-squared terms of the test below (0.02 for 183 points
#: at rms = noise, against its threshold of 25). At refine's 1e-6 the refinement crept
#: along a tube's free slide for 10 to 30 steps where the answer had settled.
PROBE_OFFSET_REL_TOL = 1e-4
#: The joint refinement is skipped when the residuals linearised at the rigid optimum
#: predict a drop of the sum of squares below PROBE_OFFSET_CHI2 noise^2 / this (the least
#: drop the warning's chi-squared test needs, with a margin for the residuals'
#: curvature in the pose; measured: see probing.warn_probe_offset).
PROBE_OFFSET_LINEAR_MARGIN = 4.0
#: ... and a ProbeOffsetWarning is raised when the best R improves the fit by more than
#: this chi-squared value (n (rms0^2 - rms^2) / noise^2, one added parameter) ...
PROBE_OFFSET_CHI2 = 25.0
#: ... and R is more than this many noise deviations.
PROBE_OFFSET_MIN_NOISE = 3.0
#: ... and the offset removes at least this fraction of the mean squared misfit beyond the
#: noise (rms0^2 - noise^2). Measured: a 0.1 tip on a unit sphere, three touches, 0.84; on
#: a tube, one touch, above 1 (the fit reaches the noise); a torus against a library of
#: look-alikes it is not in, 0.10; a tomato-can scan with no tip, 0.31.
PROBE_OFFSET_EXPLAINED = 0.5
#: ... and, where the best R lies at the end of the range tried (at least this fraction of
#: R_max: no estimate, only a bound), the offset surface fits the data to the noise (fit
#: p-value at least WIDEN_P_VALUE). Measured (stop 31, one touch of each paper surface
#: against the three others, seeds 0 to 5): 11 of 23 such out-of-folder touches were
#: warned, every one with R at R_max, and all 11 still fit 1.19 to 11.7 times the noise
#: with the offset (p below WIDEN_P_VALUE): none warns now; four touches with a real tip
#: larger than R_max (0.2 and 0.3 on R_max 0.13 to 0.26) ended at R_max too, fitting at
#: 0.95 to 1.11 times it, and still warn.
PROBE_OFFSET_BOUND_FRACTION = 0.98
# --------------------------------------------------------------------------- scale
#: The scale benchmark's blobs (meshrec.bench.blobs): icosphere subdivisions (4: 5,120
#: faces, 2,562 vertices), the degree of the smooth radial field (a polynomial of the unit
#: direction: spherical harmonics up to this order), the range of its amplitude (fraction
#: of the radius) and of the anisotropic scale along each axis.
BLOB_SUBDIVISIONS = 4
BLOB_DEGREE = 3
BLOB_AMPLITUDE = (0.15, 0.35)
BLOB_ANISOTROPY = (0.7, 1.3)
#: Parallel recognition (meshrec.recognition.workers): local processes are used only for
#: libraries of at least this many models (below, starting them costs more than they
#: save); the models are split into this many chunks per worker (even loads, few round
#: trips); seconds to wait for a Dask scheduler to answer.
PARALLEL_MIN_MODELS = 8
PARALLEL_CHUNKS_PER_WORKER = 4
DASK_CONNECT_SECONDS = 10.0

#: The library-wide screen (meshrec.recognition.screen), run before any model's own
#: stages when the cascade is on and the library holds at least this many models (below
#: it the per-model first stages are cheap enough and the screen's fixed cost is not paid).
SCREEN_MIN_MODELS = 8
#: Reach of the screen's local height-fields, times the curves' half-length (the data lie
#: within about one half-length of the contact; a margin for the spread of candidates).
SCREEN_REACH = 1.6
#: The screen spreads each model's lookup hits over cells of this size, times the curves'
#: half-length (the best (K, H) match per cell becomes a candidate).
SCREEN_CELL_FRACTION = 0.8
#: The data's contact is placed on a grid of this many by this many points over each
#: candidate's cell (one height-field serves them all).
SCREEN_SHIFTS = 3
#: Neighbouring sites (their heights and slopes) each height-field is fitted to.
SCREEN_NEIGHBOURS = 32
#: Degree of the height-field polynomials (4: a sphere's quartic term over the reach).
SCREEN_DEGREE = 4
#: Weight of a neighbour's slope equations against its height equation.
SCREEN_SLOPE_WEIGHT = 1.0
#: Data points (an even subsample) and angles about the normal the screen tries.
SCREEN_POINTS = 16
SCREEN_PHI_STEPS = 24
#: Remove from the screen's gaps their affine part in the placed (x, y) (a small tilt and
#: lift of the data, which the registration's refinement makes).
SCREEN_AFFINE = True
#: Candidates per chunk of the screen's fits and products (memory: a few tens of MB).
SCREEN_CHUNK = 1024
#: Seed of the sites' thinning ranks (the screen is deterministic).
SCREEN_SEED = 0
#: A model's rms is taken to be at least its screen estimate over this. Measured with
#: tools/screen_gains.py (reports/screen_gains.md: 28 touches on 30 blobs, the paper
#: surfaces and bench.shape_set(20)): on the pairs whose full-search log-likelihood was
#: within JOINT_PRUNE_LOG_RATIO of the leader's the estimate over the full search's rms was
#: at most 2.05 (a true model whose basin the cells missed, on the ellipsoid; most are
#: 0.5 to 1.3); 2.5 is a margin of 1.2. It pruned 95 of the 448 pairs, none close.
SCREEN_GAIN = 2.5
#: The screen's leaders (least estimates) registered in full before it prunes: the least
#: rms they reach bounds the best model's (no gain needed on that side).
SCREEN_LEADERS = 2
#: Rigid-refinement steps on all the points for a model the screen pruned.
SCREEN_PRUNED_ITERATIONS = 3
#: Expected costs of the cascade's per-model jobs when a batch is split over workers
#: (meshrec.recognition.jobs.balanced_chunks), in units of a full search of
#: LOCAL_SEARCHES local searches (a full search costs its searches over that): a model's
#: first stages, and a pruned registration (the cascade's or the screen's). Measured on
#: 40 blobs of 5,120 faces (CPU medians: first stages 0.11 s, full search 0.21 s, pruned
#: 0.003 s).
PARALLEL_COST_COARSE = 0.5
PARALLEL_COST_PRUNED = 0.015
#: Jobs of at most this cost (the pruned poses, a rejected model's registration) run in
#: the calling process while the workers run the others (their inputs need no round
#: trip, and the caller waits anyway).
PARALLEL_HERE_COST = 0.05
