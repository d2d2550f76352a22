"""Every shared tolerance, limit and default, in one place (like trimesh's ``tol``).

Modules read these as ``config.NAME`` at call time (numba kernels freeze them when they
compile). Change them here, not in the modules that use them; each says why it has its value.
Constants that belong to one algorithm's arithmetic (exact-predicate error bounds, status
codes) stay beside their kernels.
"""

from __future__ import annotations

# ---------------------------------------------------------------------------------- defaults
#: Unit cell, cell size (mm), strut radius (mm) and polygon segments per strut when the
#: user gives none (Lattice.fill, Workplane.lattice and ``lattice-cad fill``).
DEFAULT_CELL = "bcc"
DEFAULT_CELL_SIZE = 5.0
DEFAULT_RADIUS = 0.4
DEFAULT_SEGMENTS = 6


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

#: Default number of surface samples per mesh for the deviation measures.
DEFAULT_SAMPLES = 50_000


# ----------------------------------------------------------------- B-rep output of the front

#: Largest lattice for which :meth:`Lattice.to_workplane` builds B-rep solids by default.
MAX_BREP_STRUTS = 2_000
