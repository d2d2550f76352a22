"""Every shared tolerance, limit and default, in one place (like trimesh's ``tol``).

Modules read these as ``config.NAME`` at call time (numba kernels freeze them when they
compile). Change them here, not in the modules that use them; each says why it has its value.
Constants that belong to one algorithm's arithmetic (exact-predicate error bounds, status
codes) stay beside their kernels.
"""

from __future__ import annotations

from typing import Final

# ---------------------------------------------------------------------------------- defaults
#: Unit cell, cell size (mm), strut radius (mm) and polygon segments per strut when the
#: user gives none (Lattice.fill, Workplane.lattice and ``lattice-cad fill``).
DEFAULT_CELL = "bcc"
DEFAULT_CELL_SIZE = 5.0
DEFAULT_RADIUS = 0.4
DEFAULT_SEGMENTS = 6
#: A mesh part file (no unit stored) smaller than this (mm, largest extent) read as
#: millimetres gets a warning: it is likely in metres or inches (conformal.load_part).
SMALL_MESH_MM = 1.0
#: ... and one larger than this, a hint that it may be in micrometres (a 5 mm part written in
#: um reads as 5 m, and was filled with 332 mm cells without a word).
LARGE_MESH_MM = 1000.0
#: Holes of a mesh part are closed (``close_holes=True``) up to this many rim edges each:
#: the minimal-area patch is O(n^3) in time (1000 edges: about 1.5 s) and O(n^2) in memory.
CLOSE_HOLES_MAX_EDGES = 1000
#: A mesh part file whose open edges' end points lie this close to one another (as
#: fractions of its bounding-box diagonal, tried in order) has them welded at load: a
#: triangle soup, or coordinates an exporter rounded per triangle. A step is taken only
#: below half the mesh's shortest edge, and kept only if it makes no edge non-manifold.
#: (1e-4: a crack of 0.004 mm across a 215 mm prosthetic keel, its two sides exported
#: apart, made outside shared/data: closed by patches instead, it was two bodies.)
WELD_OPEN_RTOLS = (1e-9, 1e-7, 1e-6, 1e-5, 1e-4)


# --------------------------------------------------------- Printability (conformal.printability)

#: Build direction (the direction layers grow in) when the user gives none: +Z.
BUILD_DIRECTION = (0.0, 0.0, 1.0)

#: Struts whose angle to the build plate is below this (degrees) are overhangs. 35 degrees
#: is a common lower limit for unsupported struts in laser powder-bed fusion (45 is common
#: for FDM); BCC struts along +Z stand at asin(1/sqrt(3)) = 35.26 degrees, so they pass.
OVERHANG_ANGLE_DEG = 35.0

#: Smallest strut diameter (mm) a printer can make: one line of a 0.4 mm FDM nozzle, also
#: about the smallest reliable strut of desktop resin printers (LPBF reaches ~0.2 mm).
MIN_STRUT_DIAMETER = 0.4

#: A strut counts as overhanging only when below the critical angle by more than this
#: (degrees), so that a strut built at exactly the critical angle is not flagged by rounding.
ANGLE_EPS_DEG = 1e-9

#: Nodes within this distance (relative to the lattice's extent along the build direction)
#: of the lattice's lowest point stand on the build plate.
PLATE_RTOL = 1e-9


# ------------------------------------------------------------------------------- File limits

#: Files estimated above this size raise an :class:`ExportWarning`.
WARN_BYTES = 2 * 1024**3

#: Binary STL stores the triangle count as uint32.
STL_MAX_TRIANGLES = 2**32 - 1

#: lib3mf indexes vertices, triangles and beams with signed 32-bit integers.
THREEMF_MAX = 2**31 - 1


# ------------------------------------------------------------ Precision contract (graphs)

#: Check every :class:`LatticeGraph` against the precision limits below (switch off only to
#: measure them, as ``benchmarks/precision_sweep.py`` does).
PRECISION_CONTRACT = True

#: Largest ``|x| / r`` for float64 (``|x|``: the largest absolute coordinate of a strut's two
#: nodes, ``r``: its smaller end radius). Measured with the contract off
#: (``benchmarks/precision_sweep.py``: stars and jittered bcc blocks, 30 per half decade;
#: and the fuzzer's families: 40 chains, random graphs and stars at P = 3 and 8): every
#: star and block is valid up to 1e14 (first invalid 10**14.5), but random graphs (struts
#: crossing near nodes) fail from 1e11 (4/51; 9/50 at 10**11.5) and chains with shallow
#: bends from 10**11.5 (2/67). Invalid means zero-area or self-intersecting faces, never
#: an error. Two decades of margin below the first failure.
PRECISION_RATIO_F64 = 1e9

#: Largest ``|x| / r`` for single-precision output (STL, 3MF, beam-lattice 3MF store
#: float32 coordinates). Measured as above on the printable mesh (``Lattice.mesh()``:
#: rounded to float32 as the writers do, flat triangles collapsed) checked in full: every
#: family valid up to 10**5.5; first failures at 1e6 (1/30 blocks), 10**6.5 (11/30 bcc),
#: all from 1e8. One and a half decades of margin.
PRECISION_RATIO_F32 = 3e4

#: Largest absolute coordinate: the exact predicates multiply three coordinate
#: differences and the clearance check squares squared distances, which must not overflow
#: (a length's square overflows above 1.3e154: the campaign's "parallel" struts of length
#: 1e155). Measured: stars scaled by 10**k at the origin (``precision_sweep.py
#: --absolute``, radius 0.01..0.02 x scale) are valid up to 10**100 and all invalid at
#: 10**110; but a random graph whose crossing struts are refused at every scale up to
#: 10**70 came out self-intersecting at 10**77 (found by the fuzzer: the clearance test
#: overflows). Ten decades of margin below that.
MAX_COORDINATE = 1e60

#: Smallest radius: products of radius-sized differences (areas' squares: r**4) must stay
#: normal floating-point numbers. Measured as above: valid down to scale 10**-70 (radii
#: ~1e-72), every one invalid at 10**-80 (zero-area faces, no error). Ten decades of
#: margin.
MIN_RADIUS = 1e-60

#: Largest coordinate and smallest radius of single-precision files: readers compute
#: normals and lengths in float32 from products of two coordinate differences, which must
#: neither overflow (3.4e38) nor underflow (1.2e-38).
MAX_COORDINATE_F32 = 1e18
MIN_RADIUS_F32 = 1e-18


# ----------------------------------------------------------------- Memory (core.resources)

#: Cap on the memory lattice-cad plans to use, in bytes (None: what the system reports).
#: The environment variable ``LATTICE_CAD_MEMORY_LIMIT`` (e.g. ``8G``) caps it too.
MEMORY_LIMIT: int | None = None

#: Fraction of the available memory one operation may plan to use (estimates are not
#: exact, and the interpreter, numba and the caller hold memory too).
MEMORY_FRACTION = 0.85


# ------------------------------------------------------------------- Stitching (fast_stitch)

#: Relative safety margin on profile offsets (keeps hull triangles away from slivers).
OFFSET_MARGIN = 1e-2

#: Profiles are never closer to their node than ``r * tan(FLOOR_ANGLE)``.
FLOOR_ANGLE_DEG = 10.0

#: Struts must keep at least this fraction of their length as open cylinder.
MIN_CYLINDER_FRACTION = 1e-6

#: Relative margin of :func:`clashes`: elements must be ``(1 + margin) (r_a + r_b)`` apart.
CLEARANCE_MARGIN = 0.02


# ------------------------------------------------------------------- LSLT (fast_stitch.lslt)

#: Coplanarity tolerance of the node structure (unit directions).
COPLANAR_EPS = 1e-9

#: Tolerances tried in turn when a node's structure has slivers (near-degenerate nodes).
COPLANAR_EPS_RETRY = (COPLANAR_EPS, 1e-7, 1e-5, 1e-3)

#: Smallest distance between consecutive section vertices, relative to the radius.
MIN_STEP = 1e-5

#: Struts within this (radians) of one plane through their node are projected onto it.
FLAT_EPS = 1e-5

#: Tube vertices must lie this far (relative) inside their cone at each node.
CONE_MARGIN = 1e-7

#: Largest supported node degree (bit masks of 64 points incl. the origin).
MAX_DEGREE = 62

#: Largest polygon size ``segments_for_chord_error`` may return.
MAX_SEGMENTS = 100_000


# ----------------------------------------------- Fitting radii to a graph (conformal.radius)

#: Fraction of its length every strut keeps as open cylinder after :func:`fit_radii`.
FIT_SLACK = 0.05


# ------------------------------------------------------------- Skins (voxel distance method)

#: Upper bound on the number of voxels of the distance grid (memory ~ 20 bytes/voxel).
MAX_VOXELS = 8_000_000

#: Edges shorter than this (mm) are collapsed after the booleans (no float32 slivers in STL).
SLIVER = 1e-4

#: Voxels per wall thickness, when the budget allows.
VOXELS_PER_THICKNESS = 3.0

#: Default escape-hole diameter (mm) when only hole positions are given.
ESCAPE_DIAMETER = 2.0

#: Seconds OCCT's offsets of a skin may take, counted from their start (they run in a
#: child beside the lattice build and the voxel surfaces); then the voxel surfaces are used
#: and the report says why. Successful offsets of the shared parts take 2-35 s (the
#: cycloidal gear, split to C1 faces, the longest); a threaded bolt's ran past 120 s.
OFFSET_TIMEOUT = 60.0


# ------------------------------------------------------------ Keep-solid zones (conformal.keep)

#: Grid points per zone thickness of the distance field around the kept faces. Planar faces
#: are exact at any spacing; on curved ones the inner surface is off by about h^2 / (8 R)
#: (R its radius), at most t / 32 where R >= t: well below a B-rep part's chord error (its
#: mesh is 1e-3 of the diagonal off the exact surface), at 2.4 x less time than t / 3.
KEEP_VOXELS_PER_THICKNESS = 2.0

#: Chord error of the kept faces' triangulation, relative to the zone thickness.
KEEP_FACE_DEFLECTION = 0.01

#: The zone's inner surface is simplified (short edges collapsed, moving it by less than
#: this fraction of the grid spacing) before the booleans.
KEEP_SIMPLIFY = 0.02


# ------------------------------------------------------- Exact reference (reference_boolean)

#: Hub sphere radius over the largest incident strut radius (Wang et al.: 0.001 % larger).
SPHERE_FACTOR = 1.00001

#: Default linear deflection, relative to the smallest strut radius.
DEFAULT_TOLERANCE_REL = 0.01

#: Default angular deflection (radians) of the tessellation.
DEFAULT_ANGULAR = 0.25

#: Default time bound (seconds) of one hub build (construction, checks, tessellation).
DEFAULT_HUB_TIMEOUT = 300.0

#: Quantum (relative to the longest strut) of the hub cache keys.
CACHE_QUANTUM = 1e-9

#: Hubs in the manifold3d convergence study of the report (a seeded sample of the unit
#: trusses, each a union of its sphere and half-struts; None: the whole lattice, as before).
DEFAULT_UNION_HUBS = 200

#: Largest number of half-struts (the sum of the sampled hubs' degrees) in that sample: the
#: unions' cost grows with the stumps (GE tet 5 mm, degree ~12: 200 hubs took 114 s at
#: 16-128 segments), so high-degree lattices get fewer hubs (reference_boolean.compare.
#: union_sample). None: only DEFAULT_UNION_HUBS bounds the sample.
UNION_MAX_STUMPS: int | None = 400

#: Hubs equal up to a rotation or reflection (reference_boolean.rotations): rounding quantum
#: of the invariant keys and largest stump mismatch of a verified match, both relative to
#: the longest strut.
ROTATION_KEY_RTOL = 1e-6
ROTATION_RTOL = 1e-8

#: Largest allowed move (relative to the hub size) when snapping circle vertices.
SNAP_RTOL = 1e-7

#: Relative tolerance (of the hub size) for "this point is on that circle / plane".
GEOM_RTOL = 1e-7

#: Relative tolerance for merging the copies of edge nodes of adjacent faces.
MERGE_RTOL = 1e-11

#: Angular tolerance (radians) of the uniform circle discretisation check.
ANGLE_TOL = 1e-6

#: Relative accuracy requested from GProp's adaptive volume integration.
VOLUME_EPS = 1e-10

#: A stump starts at ``TRIM_FRACTION`` of the largest height at which its start disc is
#: still strictly inside the hub sphere (see :func:`stump_start`).
TRIM_FRACTION = 0.9

#: Stumps whose start could only move by less than this fraction of ``R`` start at the node.
TRIM_MIN_REL = 0.05

#: Slivers of a boolean result (skin, trim) that float32 cannot hold are collapsed by
#: manifold3d's simplify with this many float32 steps (at the largest coordinate) as its
#: tolerance before the result is checked again (lattice_cad.lattice).
SIMPLIFY_ULPS = 4

#: The float32 check of a boolean result lists up to this many problems of each kind, so
#: that each collapse round takes all of them and the next check can be local
#: (fast_stitch.recheck needs a complete list; with the check's default of 100, the GE
#: bracket's tet trim at 5 mm went through two whole checks and 9 rounds).
COLLAPSE_MAX_REPORT = 20_000
#: The collapses of folds stop when a round leaves more than this many times the folds
#: (self-intersecting pairs and zero-area faces) the mesh had at first (counted from
#: ``COLLAPSE_DIVERGES_FROM`` folds): they diverge.
COLLAPSE_DIVERGES = 2.0
COLLAPSE_DIVERGES_FROM = 100

#: Default number of surface samples per mesh for the deviation measures.
DEFAULT_SAMPLES = 50_000

#: Points per query of the deviation measure's distance tree (bounds its memory).
DEVIATION_CHUNK = 200_000

#: Vertices (of both meshes) from which the two sides of the deviation are measured in
#: two processes (``reference_boolean.compare.two_sided_deviation``).
DEVIATION_PARALLEL_MIN = 500_000

#: Default surface tolerance of the accuracy report's verdict, as a fraction of the median
#: strut radius: the mesh passes when 95 % of its two-sided surface deviation from the exact
#: solid is within +-(this x radius) mm (issue 14: p95 under 10 % of the radius).
DEFAULT_DEVIATION_TOLERANCE_REL = 0.1

#: Hub zone of the report's deviation mask, as a multiple of the smallest ball about a node
#: that holds the exact solid's ball and every intersection of the node's struts
#: (reference_boolean.regions): 1.5 holds fast_stitch's convex hubs for every profile at
#: P >= 4 (profile circumradius up to 1.41 r). Beyond the zones both model the same struts.
HUB_ZONE_FACTOR = 1.5

#: The verdict judges the deviation along struts (outside the hub zones) when at least this
#: fraction of each surface's samples lies there; else the whole surface.
MIN_STRUT_FRACTION = 0.05

#: Default volume tolerance of the verdict: |V_mesh - V_exact| / V_exact at most this.
DEFAULT_VOLUME_TOLERANCE = 0.01

#: Worst hubs shown (with a close-up picture each) on the report's first screen.
REPORT_WORST_HUBS = 4


# ---------------------------------------------------------- Beam FE export (lattice_cad.io.fe)

#: Default material of ``.inp`` beam models: PLA, the most common FDM filament, with bulk
#: datasheet values (NatureWorks Ingeo 4043D: tensile modulus 3.6 GPa, density 1.24 g/cm^3;
#: Poisson's ratio 0.36). Printed parts are anisotropic and usually softer (infill, layer
#: bonding): pass the measured values of your printer and material. Units are mm, N, MPa and
#: tonne/mm^3 (1.24 g/cm^3 = 1.24e-9 t/mm^3), the consistent set of CalculiX/Abaqus models
#: in millimetres.
FE_MATERIAL = "PLA"
FE_YOUNGS_MODULUS = 3500.0
FE_POISSON = 0.36
FE_DENSITY = 1.24e-9

#: Strut radii are grouped into beam sections of this relative width: every radius moves by
#: at most half of it (0.05 %), so A and I by at most 0.1 % and 0.2 %.
FE_RADIUS_STEP = 1e-3

#: Quadratic beam elements per strut. One element cannot bend in double curvature (its
#: deflection is a parabola), and the struts of a rigid-jointed lattice do: with one element
#: a BCC cell under compression came out 14-22 % too stiff in CalculiX, with two 0.1-2.1 %,
#: with three 0.1-0.7 % (against the closed form; see lattice_cad.io.fe).
FE_ELEMENTS_PER_STRUT = 3

#: A tapered strut is split into stepped elements until the estimated bending-stiffness
#: error of the steps (midpoint rule on 1/r^4) is below this fraction.
FE_TAPER_TOL = 0.01

#: Most elements one tapered strut is split into.
FE_MAX_TAPER_ELEMENTS = 32


# ----------------------------------------------------------------- B-rep output of the front

#: Largest lattice for which :meth:`Lattice.to_workplane` and ``Lattice.save("x.step")``
#: build B-rep solids by default (about 5-7 min at the measured rates below); larger ones
#: are refused before any work, with the estimate (``max_struts=``/``--max-brep-struts``).
MAX_BREP_STRUTS = 2_000

#: A lattice trimmed to its part lies outside the part's surface by at most this fraction of
#: the largest strut radius (``conformal.trim``; checked on every vertex and reported).
TRIM_RTOL = 0.01

#: When a cut by the part's cutting tessellation cannot be written in float32 (its facets
#: meet the lattice in surfaces a float32 step apart, even with the part moved), it is
#: cut again by a tessellation of the B-rep with this fraction of that chord error
#: (``Lattice._retrim``).
RETRIM_FINER = 0.8

#: Before a lattice is cut by a B-rep part (trim, skin), the part is tessellated again with
#: a chord error of this fraction of the largest strut radius (``conformal.trim.cutting_part``):
#: the default tessellation (1e-3 of the diagonal) lies outside concave faces (holes, inner
#: fillets) by up to its deflection, several % of r on real parts; half of TRIM_RTOL leaves
#: the other half for BRepMesh's own deviation from its target.
CUT_DEFLECTION_RTOL = 0.005
#: Angular deflection (rad) of that tessellation (the default part's).
CUT_ANGULAR_DEFLECTION = 0.3
#: Budget for that tessellation: its chord error is kept at least ``d0 * n0 /
#: CUT_MAX_TRIANGLES`` (``n0`` triangles at the default chord error ``d0``; triangles grow
#: at most as 1 / chord error), so parts whose default mesh is already dense (threads,
#: gear teeth: 340k-410k triangles and minutes of BRepMesh at 0.5 % r) stay affordable;
#: there the cut may stand out of the exact surface by somewhat more than TRIM_RTOL.
#: 700k (was 300k): the Ventilator's cut reaches 0.5 % r (clip 3.14 -> 0.50 % r exact; fill
#: 24 -> 60 s, 2.5x; the cycloidal gear 34 -> 43 CPU s, 1.3x; benchmarks/results/
#: bench_protrusion_exact.txt).
CUT_MAX_TRIANGLES = 700_000
#: A refined tessellation (``conformal.Part.refined``) first splits each B-rep face that a
#: coarse pass predicts would hold more than MESH_SPLIT_MIN triangles into patches of about
#: MESH_FACE_TRIANGLES (``occ_impl.chord.split_dense_faces``: ShapeUpgrade_FaceDivideArea,
#: the same surfaces): BRepMesh's time per face grows faster than its triangles, and the
#: patches are meshed in parallel. M6 screw's thread face: 70 K triangles in 8.3 s as one
#: face (8.5 K a second, 36-42 K for faces of 11-55 K elsewhere); cutting tessellations of
#: the M6 100 -> 17 s, the cycloidal gear 35 -> 6 s. Below 30 K the split costs more than it
#: saves (NIST CTC-02's four 24-28 K B-spline faces: 1.2 s to split one; 7.3 s whole, 10.4 s
#: split).
MESH_FACE_TRIANGLES = 3000
MESH_SPLIT_MIN = 30_000
#: The coarse pass of that prediction meshes at this many times the chord error asked, and
#: predicts the fine count as this many times its own (triangles grow at most as 1 / chord
#: error: exact for doubly curved faces, pessimistic for cylinders and planes).
MESH_SPLIT_COARSE = 16.0
#: The split runs in a child process (ShapeUpgrade_FaceDivideArea dies of a segmentation
#: fault on some B-spline faces); one that takes longer than this many seconds is killed and
#: the faces are meshed whole (the M6 screw's thread: about 1 s, plus the child's start).
MESH_SPLIT_SECONDS = 120.0
#: A refined tessellation (``conformal.Part.refined``, so the cutting one) is checked face by
#: face against the exact surface (``occ_impl.chord``): B-spline faces whose triangles
#: deviate by more than this factor times the chord error asked get knots inserted where
#: they deviate and are meshed again (BRepMesh places no interior node along the straight
#: direction of a twisted ruled face: 25x the chord error on trimesh_featuretype.STEP).
CHORD_CONTROL = 1.5

#: ``fill="auto"`` (the voxel method's default) keeps whole cells only ("inside") when they
#: fill at least this share of the part's volume; else it conforms the cut cells to the
#: surface. Whole cells filled 4 % of the rocker arm (16 struts), 12 % of the dragon and
#: 10 % of the face-recognition part at the benchmark's size (largest extent / 15), 25-60 %
#: of the other parts where any fits (session 23).
AUTO_INSIDE_SHARE = 0.2
#: A trim of a part whose surface crosses itself is given up at once (the lattice written
#: uncut, and said) when more than this share of the cut's triangles cross another before
#: any rounding: the folded pipe elbow 4.9 % (9,139 pairs), never repaired; a noisy scan's
#: cut 0.03 % (32 pairs) or a noisy bunny's 0.003 % (4), repaired by the fold collapses.
TRIM_HOPELESS_SHARE = 0.01
#: ``conformal.Part.self_crossings`` tells crossing pairs of the part's triangles from
#: touching ones (solids sharing an edge) up to this many pairs; past it all count (a
#: surface folded that much is folded, whatever a few of its pairs do).
CROSSING_PAIRS_CLASSIFIED = 1_000_000
#: ``conformal.Part.folds``: a B-rep part whose tessellation crosses itself in more than
#: TRIM_HOPELESS_SHARE of its triangles is tessellated this many times finer (unchecked)
#: to tell a fold of its surface (it stays) from chords meeting across a thin feature.
FOLD_REFINE = 4.0
#: ``conformal.Part.folds`` first asks OCCT whether the B-rep's faces intersect one
#: another (``BRepAlgoAPI_Check``), for at most this many seconds (0.5-1.8 s on the folds
#: measured, 1.7-2.9 s with the child's start; minutes on NIST CTC-02, which never gets here).
FOLD_CHECK_SECONDS = 15.0
#: When most of a voxel fill falls apart into loose pieces, the warning says what keeps it
#: joined, tried: the conform fill at the same size (for inside and clip), then cells of
#: JOINED_SHRINK, JOINED_SHRINK^2, ... of the size (JOINED_TRIALS sizes at most), each
#: built as a graph while it is expected to have at most JOINED_TRIAL_STRUTS struts; the
#: first that keeps at least JOINED_KEPT of its struts in the main pieces ends the trials.
JOINED_SHRINK = 0.75
JOINED_TRIALS = 4
JOINED_TRIAL_STRUTS = 200_000
JOINED_KEPT = 0.9

#: A strut fitted thinner than this fraction of the radius asked is counted apart
#: (``BuildReport.thinned_beyond_tolerance``, the CLI's "N below 0.7 x the radius asked"):
#: the tet lattice's graph repair aims to keep every strut above it (issue 11: thinning a
#: strut to a tenth is not a fix), and the voxel fills count theirs the same way.
THIN_TOLERANCE = 0.7
#: Seconds one gmsh attempt of a tet lattice may take (conformal.tet_mesh), plus one second
#: per TET_ATTEMPT_RATE tetrahedra expected (twice the part's volume over a regular tet's
#: of the size asked): the shared parts' attempts that succeed take 1-23 s; a lofted fan's
#: B-rep hung in all three 3-D algorithms (600 s each, before).
TET_ATTEMPT_SECONDS = 120.0
TET_ATTEMPT_RATE = 2000.0
#: All of a tet mesh's gmsh attempts together stop after this many times one attempt's
#: time (conformal.tet_mesh): a 945 K-triangle gyroid network (genus 486) timed out or
#: failed in every strategy, 12 minutes before its refusal.
TET_TOTAL_ATTEMPTS = 2.5
#: A mesh part's surface is not re-parametrised with feature edges at an angle when those
#: edges cut it into more patches than this share of its area in squares of the size: a
#: scan's noise, not its features, at that size (a noisy capsule: 11,007 patches at 40 deg
#: against 320 squares; gmsh failed on it after 37 s; CAD meshes: at most 0.02, the
#: smooth scans 0.04-0.12; the dragon 0.73 and the hammer 0.81, which gmsh fails on too).
TET_FEATURE_PATCH_SHARE = 0.5
#: A mesh part's surface of more than ``TET_DENSE_TRIANGLES`` triangles and more than
#: ``TET_DENSE_PER_SQUARE`` per square of the tet size is resampled before gmsh is given
#: it as it is (conformal.tet_mesh): a 20 mm knob of 986,904 triangles (1,237 per square
#: at 1.33 mm; made outside shared/data) took gmsh 70-83 s per failed re-parametrisation,
#: and the budget ran out before its resampled surface (1.1 s) was tried. The shared
#: meshes: at most 60,160 triangles (the hammer, 777 per square).
TET_DENSE_TRIANGLES = 200_000
TET_DENSE_PER_SQUARE = 200.0

#: A B-rep part's tetrahedra come from its triangulated surface (re-meshed at the size)
#: before its B-rep when the edges of its faces would carry more than this many times the
#: nodes of a surface meshed at the size (conformal.tet._brep_crowding): a helical gear
#: whose flanks are 744 narrow faces (made outside shared/data), 4.6 x at size 3.47, gave
#: 29,438 of 35,070 struts beyond the thin tolerance in 129 s from its B-rep, 2,072 of
#: 7,492 in 7 s from its surface. The shared STEP parts at the benchmark's size: 0.25-2.5.
TET_BREP_CROWDING = 3.0
#: When more than this share of a tet lattice's struts from a B-rep are thinned beyond the
#: tolerance where the part is thick for the size, the lattice of its triangulated surface
#: is made too, and the one with the smaller share kept (conformal.tet.tet_lattice).
TET_RETRY_THIN_SHARE = 0.1

#: Fewest nodes gmsh puts on a B-rep circle (on an arc in proportion to its angle), and
#: on any other curve, for the tet method (gmsh's defaults: 7 and 3). At gmsh's defaults
#: a small fillet's or hole's edges carry nodes a fraction of the size asked apart, and
#: the struts between them must be thinned far below the radius asked.
TET_MIN_CIRCLE_POINTS = 3
TET_MIN_CURVE_POINTS = 2

#: Before several solids of a part are united, their tessellations are rounded to a common
#: grid of this fraction of the largest coordinate (a power of two, so the rounding is exact):
#: solids that touch come out of their separate tessellations a float64 ulp or two apart, and
#: the exact union keeps a zero-thickness slit between such faces (a self-intersecting part
#: surface that every cut by the part inherits; ``conformal.part``).
UNION_SNAP = 1e-9

#: Vertices of a written mesh closer than this (mm) are merged before the final check:
#: trimesh (and tools built on it) merge them on reading, so the file must be closed then.
NEAR_VERTEX = 1e-8

#: Measured rates of the B-rep path (``lattice_cad.brep.estimate``), on the development
#: machine (2 cores shared with other jobs, load 10-14; benchmarks/brep_rates.md): a fixed
#: start (imports, process pool), seconds per stump of a distinct hub (its sphere-and-
#: stumps fuse, divided among the worker processes), per strut for sewing clean hubs or
#: fusing overlapping ones (BRepCheck included), per strut for trimming to the part, per
#: strut for writing STEP; and STEP bytes per strut. Measured on the GE bracket, BCC 10 mm
#: (1,647 struts, 46 distinct hubs, sewn, trimmed: 316 s, 46 MB) and the example
#: bracket, BCC 5 mm clipped (1,884 struts, 126 distinct hubs, fused, trimmed: 421 s).
BREP_START_SECONDS = 5.0
BREP_HUB_SECONDS = 0.85
BREP_SEW_SECONDS = 0.07
BREP_FUSE_SECONDS = 0.06
BREP_TRIM_SECONDS = 0.045
BREP_WRITE_SECONDS = 0.03
BREP_STEP_BYTES = 27_000

#: Sewing tolerance of the hubs' shared midpoint circles, relative to the smallest strut
#: radius (the circles agree to rounding: both hubs build them on the same frame).
BREP_SEW_RTOL = 1e-5

#: Default strut profile of :func:`fast_stitch.stitch` (see its ``profile`` option):
#: "volume" keeps the exact solid's volume (cross-section area and hub volume).
DEFAULT_PROFILE: Final = "volume"  # Final: its type is Literal["volume"]
#: Directions of the spherical quadrature of the exact hub volume (profile="volume").
HUB_QUADRATURE = 1024
#: Smallest per-node scale of the hub correction (profile="volume").
MIN_HUB_SCALE = 0.5
#: Largest per-node scale of the hub correction (profile="volume"; boundary hubs grow).
MAX_HUB_SCALE = 1.25
#: Smallest length of the band between a scaled hub ring and its strut's unscaled band ring
#: (profile="volume"), relative to the profile radius: the band is a frustum from the hub
#: ring (offset ``s d``) to the band ring at ``s d + sqrt(((1 - s) d)^2 + g^2)``, so it is
#: never flat where ``s_n`` is 1 (leaves) and nearly the hub's cone where ``s_n < 1``.
HUB_BAND_GAP = 0.05

#: Mesh files: a closed shell smaller than DEBRIS_SIZE of the part's diagonal with less than
#: DEBRIS_VOLUME of the largest shell's volume is debris (a 0.05 mm speck beside a 70 mm
#: bracket: 6e-4 of its size, 1e-9 of its volume), left out with a warning.
DEBRIS_SIZE = 0.01
DEBRIS_VOLUME = 1e-6
#: ... and so is a closed shell whose mean thickness (2 V / A) is below DEBRIS_THICKNESS of
#: the part's diagonal (a 30 x 20 mm face an exporter thickened to 0.1 um beside a 60 mm
#: bracket: 1.3e-6 of its diagonal; a 0.2 mm fin on a 300 mm part is 6.7e-4).
DEBRIS_THICKNESS = 1e-4

#: Mesh files: a vertex within this fraction of the bounding-box diagonal of an edge, strictly
#: between its ends, lies on it (a T-junction, or a zero-area sliver's middle vertex;
#: ``conformal.seams``): 0.1 um on a 100 mm part.
SEAM_RTOL = 1e-6

#: A skin's outer wall (the part's cutting tessellation) whose triangles cross in at least
#: this many pairs folds over itself (the folded pipe elbow: 2,378 pairs), and a skin of it
#: is refused before manifold3d's booleans on the whole lattice, which ran for more than 10
#: minutes there (``conformal.skin.build_skin``). Fewer pairs are faces grazing within the
#: tessellation, which the booleans resolve: 3 on the cycloidal gear's and the wingnut's.
SKIN_FOLD_PAIRS = 100

#: numba's threading layers in the order the engines ask for them (unless the user set
#: ``NUMBA_THREADING_LAYER`` or ``NUMBA_THREADING_LAYER_PRIORITY``): OpenMP first. numba's
#: own order puts TBB first, which it finds wherever a system libtbb is installed (Debian's
#: PrusaSlicer and CuraEngine packages bring one); with it, a CLI run that ended in an error
#: after numba's parallel kernels had run (``--close-holes`` on a triangle soup) spun in
#: TBB's finalize at interpreter exit for minutes (over 300 s, twice), and exits in 3.4 s
#: with OpenMP, which numba uses anyway on machines without libtbb.
NUMBA_THREADING_PRIORITY = ("omp", "tbb", "workqueue")


def prefer_numba_threading() -> None:
    """Apply :data:`NUMBA_THREADING_PRIORITY` (the engines call this when imported; it must
    come before numba's first parallel kernel runs, which fixes the layer for the process).
    An environment that names a layer or an order keeps it."""
    import os
    import sys

    env = os.environ
    if "NUMBA_THREADING_LAYER" in env or "NUMBA_THREADING_LAYER_PRIORITY" in env:
        return
    env["NUMBA_THREADING_LAYER_PRIORITY"] = " ".join(NUMBA_THREADING_PRIORITY)  # children
    numba = sys.modules.get("numba")  # (not imported here: the core floor is numpy only)
    if numba is not None:
        numba.config.THREADING_LAYER_PRIORITY = list(NUMBA_THREADING_PRIORITY)
