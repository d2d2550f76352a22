"""The exact unit truss of one lattice node (Wang, Chen & Rosen), in OpenCascade.

:mod:`reference_boolean` describes each hub in plain numpy and calls this module; it is
where the OCCT side of the reference lives.

One function, :func:`build_hub`, turns the plain-numpy description of one unit
truss (:class:`HubSpec`) into a :class:`HubResult`: the exact volume from
``GProp``, a tessellation without the planar midpoint faces, the vertices of
each midpoint circle in canonical order, and the solid as a BREP string.
Nothing OCCT-typed crosses this module's boundary, so hubs can be built in
worker processes (OCP shapes cannot be pickled).

Every OCCT step is checked: ``IsDone()`` of each builder, ``HasErrors()``
where the binding exposes it (OCP 7.9 does not expose it on
``BRepAlgoAPI_Fuse``), ``BRepCheck_Analyzer(shape).IsValid()`` of every
primitive and of the fused hub, a single solid with a positive volume, intact
midpoint discs. A failure is never an exception leaking out of
:func:`build_hub`: it becomes ``HubResult.status`` (the message of the last
attempt) after the retries (:data:`ATTEMPTS`: pairwise fuses in a balanced tree, one
general fuse, a fuzzy value, untrimmed primitives, then fusing one stump at a time).

Hubs whose stumps are cylinders of one radius (most hubs of a lattice) are first built
without a boolean, face by face (:mod:`lattice_cad.occ_impl.hub_direct`, :data:`DIRECT`):
the same solid, checked the same way (BRepCheck, one solid, positive volume, intact
midpoint circles), its volume in closed form; the retries above are its fallback, and
``HubResult.attempts`` says which path built each hub (``"direct: ok"`` or the boolean
construction, after a ``"direct: ..."`` line where the direct path declined). Hubs whose
stumps differ (thinned or tapered struts) build the sphere and their largest group of equal
cylinder stumps face by face and fuse the other stumps onto it in one general fuse
(``"direct+fuse"``, :data:`DIRECT_FUSE`; volume from GProp).

Midpoint circles (how both hubs of a strut get identical vertices)
------------------------------------------------------------------
Each stump is built with ``gp_Ax2(node, axis, xdir)`` where ``xdir`` is the
strut's canonical frame vector (a function of the strut's line only, the same
for both of its hubs). ``BRepMesh_IncrementalMesh`` with an *absolute* linear
and angular deflection discretises a full circle edge uniformly in its
parameter, starting at the seam, i.e. at ``xdir``. Both hubs of a strut
therefore put the same number ``K`` of points at the angles ``2 pi k / K`` of
the shared frame. :func:`build_hub` verifies this (count, uniform angles,
radius) for every circle and returns the vertex of each angle; the caller
then replaces those vertices by one exact canonical polygon per strut and
checks that both ends agree on ``K``. A hub whose circle is not intact (the
disc was split by another stump, or the discretisation is not uniform) fails
with a status instead of producing a mesh with a crack.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
from OCP.BRepPrimAPI import (
    BRepPrimAPI_MakeCone,
    BRepPrimAPI_MakeCylinder,
    BRepPrimAPI_MakeSphere,
)
from OCP.GeomAbs import GeomAbs_Plane
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.TopAbs import TopAbs_SOLID
from OCP.TopoDS import TopoDS_Shape
from OCP.TopTools import TopTools_ListOfShape

from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.shapes import (
    check_done,
    check_valid,
    count,
    face_area,
    face_triangulations,
    fuse,
    merge_close,
    to_bytes,
    volume,
)

__all__ = [
    "HubSpec",
    "HubResult",
    "OCCTFailure",
    "build_hub",
    "make_hub_shape",
    "sphere_axis",
    "make_sphere",
    "build_hub_solid",
    "general_fuse",
    "tree_fuse",
    "StageClock",
    "cap_heights",
    "sphere_is_covered",
    "direct_hub_shape",
    "make_stump",
    "DIRECT",
    "DIRECT_FUSE",
]


@dataclass(frozen=True)
class HubSpec:
    """One unit truss in local coordinates (its node at the origin).

    Attributes
    ----------
    radius : float
        Sphere radius ``R`` (1.00001 x the largest incident radius).
    vecs : (d, 3) float64
        Node -> strut midpoint vector of each stump.
    r_node, r_mid : (d,) float64
        Stump radius at the node and at the midpoint (cone frustum if different).
    xdirs, ydirs : (d, 3) float64
        Canonical orthonormal frame of each strut's midpoint circle; the same
        vectors are used by both hubs of the strut.
    """

    radius: float
    vecs: NDArray[np.float64]
    r_node: NDArray[np.float64]
    r_mid: NDArray[np.float64]
    xdirs: NDArray[np.float64]
    ydirs: NDArray[np.float64]


@dataclass
class HubResult:
    """What :func:`build_hub` returns (plain, picklable data).

    Attributes
    ----------
    status : str
        ``"ok"`` or the reason of the failure (then the arrays are empty).
    attempts : list of str
        One line per construction tried (``"tree: ok"``, ``"tree: <error>"``, ...).
    volume : float
        Exact volume of the hub solid (GProp).
    vertices : (V, 3) float64
        Tessellation vertices, local coordinates; circle vertices come first.
    faces : (F, 3) int64
        Outward triangles without the midpoint discs.
    circles : list of (K_j,) int64
        For stump ``j``, the vertex at angle ``2 pi k / K_j`` of its frame.
    brep : bytes
        The hub solid as binary BREP (``BinTools``) (empty if ``keep_brep`` was false).
    seconds : float
        Build time (construction, checks, tessellation).
    stages : dict[str, float]
        CPU seconds of this process per stage (:class:`StageClock`: ``"primitives"``,
        ``"fuse"``, ``"check"``, ``"volume"``, ``"mesh"``, ``"extract"``, ``"circles"``,
        ``"brep"``), over every attempt; for profiling.
    """

    status: str
    attempts: list[str] = field(default_factory=list)
    volume: float = float("nan")
    vertices: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    faces: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    circles: list[NDArray[np.int64]] = field(default_factory=list)
    brep: bytes = b""
    seconds: float = 0.0
    stages: dict[str, float] = field(default_factory=dict)


class StageClock:
    """CPU seconds (``time.process_time``) per named stage; :meth:`lap` ends the stage."""

    def __init__(self) -> None:
        self.stages: dict[str, float] = {}
        self._t = time.process_time()

    def lap(self, name: str) -> None:
        t = time.process_time()
        self.stages[name] = self.stages.get(name, 0.0) + (t - self._t)
        self._t = t


def _lap(clock: StageClock | None, name: str) -> None:
    if clock is not None:
        clock.lap(name)


# ------------------------------------------------------------ construction
#: Radii of a stump closer than this (mm) make a cylinder, not a cone (see make_primitives).
_SAME_RADIUS = 1e-6


def _pnt(v: NDArray[np.float64]) -> gp_Pnt:
    return gp_Pnt(float(v[0]), float(v[1]), float(v[2]))


def _dir(v: NDArray[np.float64]) -> gp_Dir:
    return gp_Dir(float(v[0]), float(v[1]), float(v[2]))


def stump_start(radius: float, r0: float, r1: float, h: float) -> float:
    """Height along its axis at which a stump may start without changing the hub.

    The part of a stump (radius between ``r0`` and ``r1``) below the height
    ``h0`` lies within distance ``sqrt(h0^2 + max(r0, r1)^2)`` of the node, which
    is less than the sphere radius ``R`` for ``h0 < sqrt(R^2 - max(r0, r1)^2)``:
    that part is inside the sphere, so dropping it leaves the union (the hub)
    unchanged as a point set. It does remove most of the stump/stump
    intersection curves inside the sphere, which the fuse otherwise computes
    and then throws away (about 20 % of the fuse time on jittered degree-6
    hubs). ``h0 = config.TRIM_FRACTION * sqrt(R^2 - rmax^2)`` keeps the start disc's
    rim clear of the sphere; stumps nearly as thick as the sphere (where
    ``h0`` would be tiny) start at the node as before.
    """
    rmax = max(r0, r1)
    room = math.sqrt(max(radius * radius - rmax * rmax, 0.0))
    h0 = config.TRIM_FRACTION * room
    if h0 < config.TRIM_MIN_REL * radius or h0 >= 0.5 * h:
        return 0.0
    return h0


def _covers(spec: HubSpec, j: int, p: NDArray[np.float64]) -> bool:
    """Is point ``p`` (local coordinates) well inside stump ``j`` (0.9 of its radius)?"""
    v = spec.vecs[j]
    h = float(np.linalg.norm(v))
    s = float(p @ v) / h
    if not 0.0 < s < h:
        return False
    r = float(spec.r_node[j]) + (float(spec.r_mid[j]) - float(spec.r_node[j])) * s / h
    return float(np.linalg.norm(p - s * v / h)) < 0.9 * r


def sphere_axis(spec: HubSpec) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Axis and x direction of the hub sphere: its poles inside stumps where possible.

    A sphere's parametrisation has two poles, where a mesher (BRepMesh, as PrusaSlicer
    and CAD viewers use it) puts several nodes at one point: zero-length edges that
    slicers count as open edges. A pole inside a stump is removed by the hub's fuse. The
    candidates are the stump directions, then the coordinate axes; the first with the
    most poles inside stumps wins (both for straight-through struts). The choice depends
    on the spec only, so translated copies of a hub are identical. (Making an exposed
    pole's cap from a second, turned sphere removes it too, but the result then fails in
    later booleans with the user's CAD shapes: not done.)

    Returns
    -------
    axis, xdir : (3,) float64
        Unit vectors, ``xdir`` perpendicular to ``axis``.
    covered : int
        How many of the two poles lie inside stumps.
    """
    d = len(spec.vecs)
    cands = [(spec.vecs[j] / np.linalg.norm(spec.vecs[j]), np.asarray(spec.xdirs[j]))
             for j in range(d)]  # fmt: skip
    cands += [(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])),
              (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
              (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))]  # fmt: skip
    best, best_cov = cands[-3], -1
    for u, x in cands:
        cov = sum(
            any(_covers(spec, k, sign * spec.radius * u) for k in range(d)) for sign in (1, -1)
        )
        if cov > best_cov:
            best, best_cov = (u, x), cov
    return np.asarray(best[0], dtype=np.float64), np.asarray(best[1], dtype=np.float64), best_cov


def make_sphere(spec: HubSpec) -> list[TopoDS_Shape]:
    """The hub sphere, its axis from :func:`sphere_axis` (a one-element list)."""
    axis, xdir, _ = sphere_axis(spec)
    mk = BRepPrimAPI_MakeSphere(gp_Ax2(gp_Pnt(0.0, 0.0, 0.0), _dir(axis), _dir(xdir)), spec.radius)
    mk.Build()
    check_done(mk, "sphere")
    check_valid(mk.Shape(), "sphere")
    return [mk.Shape()]


def cap_heights(
    radius: float,
    vecs: NDArray[np.float64],
    r_node: NDArray[np.float64],
    r_mid: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(d,) float64: height ``c_j`` along each stump's axis where its side meets the sphere.

    Stump ``j`` (a frustum from radius ``r_node`` at the node to ``r_mid`` at height
    ``h = |vecs[j]|``) contains exactly the cap ``{p : |p| = R, p . u_j >= c_j}`` of the
    sphere of radius ``R`` (``c_j`` the positive root of ``s^2 + r(s)^2 = R^2``), provided
    ``r_node < R < h``; NaN where that does not hold.
    """
    h = np.linalg.norm(vecs, axis=1)
    k = (r_mid - r_node) / h
    a = 1.0 + k * k
    b = 2.0 * r_node * k
    c = r_node * r_node - radius * radius
    disc = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    out = (-b + disc) / (2.0 * a)
    good = (r_node < radius) & (h > radius)
    return np.where(good, out, np.nan)


def sphere_is_covered(
    radius: float,
    vecs: NDArray[np.float64],
    r_node: NDArray[np.float64],
    r_mid: NDArray[np.float64],
) -> bool:
    """Is the ball of radius ``radius`` at the node inside the union of the stumps?

    Each stump (started at the node) is convex and contains the node, so the ball is
    inside their union as soon as its surface is (a point ``t p``, ``0 <= t <= 1``, lies in
    the stump that holds ``p``). Stump ``j`` holds the cap ``p . u_j >= c_j``
    (:func:`cap_heights`), so the sphere's uncovered points are the points of norm ``R``
    of the polytope ``P = {x : x . u_j <= c_j for all j}``, which contains the node. The
    sphere is covered iff ``P`` is bounded and inside the open ball: ``P``'s vertices are
    the polars of the facets of the convex hull of the points ``u_j / c_j``, and a facet
    at distance ``t`` from the node gives a vertex of norm ``1 / t``. Hence: covered iff
    the node is inside that hull and every facet is farther than ``1 / R`` (with a
    relative margin of 1e-6). Rigorous up to rounding; False whenever in doubt (fewer
    than 4 stumps, a degenerate hull, a stump shorter than ``R``).
    """
    if len(vecs) < 4:
        return False
    c = cap_heights(radius, vecs, r_node, r_mid)
    if not np.all(np.isfinite(c)) or np.any(c <= 0.0):
        return False
    from scipy.spatial import ConvexHull, QhullError

    u = vecs / np.linalg.norm(vecs, axis=1)[:, None]
    try:
        hull = ConvexHull(u / c[:, None])
    except (QhullError, ValueError):
        return False
    dist = -hull.equations[:, 3]  # unit outward normals: offset = -distance of the node
    return bool(dist.min() * radius > 1.0 + 1e-6)


def make_primitives(spec: HubSpec, *, trim: bool = True) -> list[TopoDS_Shape]:
    """The sphere and the stumps (cylinders or cone frustums), each checked.

    With ``trim`` (default) the fuse gets cheaper primitives for the same hub (the same
    point set): where the sphere lies inside the union of the stumps
    (:func:`sphere_is_covered`, as at every node whose struts point all around it) it is
    left out and the stumps start at the node; otherwise each stump starts at
    :func:`stump_start` instead of the node. The sphere's poles are put inside stumps
    (see :func:`sphere_axis`).
    """
    covered = trim and sphere_is_covered(spec.radius, spec.vecs, spec.r_node, spec.r_mid)
    shapes = [] if covered else make_sphere(spec)
    for j in range(len(spec.vecs)):
        shapes.append(make_stump(spec, j, trim=trim and not covered))
    return shapes


def make_stump(spec: HubSpec, j: int, *, trim: bool) -> TopoDS_Shape:
    """Stump ``j`` of the hub (cylinder or cone frustum), checked; with ``trim`` it starts at
    :func:`stump_start` (the part below lies inside the sphere), else at the node."""
    origin = gp_Pnt(0.0, 0.0, 0.0)
    v = spec.vecs[j]
    h = float(np.linalg.norm(v))
    u = v / h
    r0, r1 = float(spec.r_node[j]), float(spec.r_mid[j])
    h0 = stump_start(spec.radius, r0, r1, h) if trim else 0.0
    ax = gp_Ax2(_pnt(u * h0) if h0 > 0.0 else origin, _dir(u), _dir(spec.xdirs[j]))
    r_start = r0 + (r1 - r0) * (h0 / h)
    # OCCT refuses a cone whose radii differ by less than Precision::Confusion (1e-7 mm;
    # "cone with two identic radii", as thinned struts give): a cylinder of the
    # midpoint radius then (so both hubs of the strut still share the midpoint circle)
    if abs(r_start - r1) <= _SAME_RADIUS:
        mk = BRepPrimAPI_MakeCylinder(ax, r1, h - h0)
    else:
        mk = BRepPrimAPI_MakeCone(ax, r_start, r1, h - h0)
    mk.Build()
    check_done(mk, f"stump {j}")
    s = mk.Shape()
    check_valid(s, f"stump {j}")
    return s


def make_hub_shape(
    spec: HubSpec,
    *,
    construction: str = "fuse",
    fuzzy: float = 0.0,
    trim: bool = True,
    clock: StageClock | None = None,
) -> TopoDS_Shape:
    """The hub solid: sphere union stumps (one general fuse, or one stump at a time).

    Raises
    ------
    OCCTFailure
        A builder is not done, or a shape is invalid.
    """
    prims = make_primitives(spec, trim=trim)
    _lap(clock, "primitives")
    if construction == "tree":
        shape = tree_fuse(prims, fuzzy=fuzzy)
    elif construction == "fuse":
        shape = general_fuse(prims, fuzzy=fuzzy)
    elif construction == "sequential":
        shape = prims[0]
        for j, s in enumerate(prims[1:]):
            shape = fuse([shape], [s], fuzzy=fuzzy, parallel=False, check=False)
            check_valid(shape, f"sequential fuse after stump {j}")
    else:  # pragma: no cover - guarded by the caller
        raise ValueError(f"unknown construction {construction!r}")
    _lap(clock, "fuse")
    check_valid(shape, "hub")
    n_solids = count(shape, TopAbs_SOLID)
    if n_solids != 1:
        _lap(clock, "check")
        raise OCCTFailure(f"hub: the fuse gave {n_solids} solids instead of 1")
    check_contains_probes(shape, spec, construction)
    _lap(clock, "check")
    return shape


def interior_probes(spec: HubSpec) -> NDArray[np.float64]:
    """(K, 3) float64 points that lie inside the hub by construction (local coordinates):
    the node (inside the sphere), and along each stump, on its axis at 50 % and 90 % of its
    length and 0.7 of its radius off the axis at 75 % in two perpendicular directions."""
    pts = [np.zeros(3)] if spec.radius > 0 else []
    for j, v in enumerate(np.asarray(spec.vecs, dtype=np.float64)):
        h = float(np.linalg.norm(v))
        if not h > 0:
            continue
        u = v / h
        x = np.asarray(spec.xdirs[j], dtype=np.float64)
        x = x - (x @ u) * u
        x /= max(float(np.linalg.norm(x)), 1e-300)
        y = np.cross(u, x)
        r0, r1 = float(spec.r_node[j]), float(spec.r_mid[j])
        r75 = r0 + (r1 - r0) * 0.75
        pts += [0.5 * v, 0.9 * v]
        pts += [0.75 * v + 0.7 * r75 * d for d in (x, -x, y, -y)]
    return np.asarray(pts, dtype=np.float64).reshape(-1, 3)


def check_contains_probes(shape: TopoDS_Shape, spec: HubSpec, what: str = "hub") -> None:
    """Refuse a fused hub that is one valid solid but misses part of its primitives.

    A general fuse can return a valid single solid that is too small (a GE tet hub: 15 %
    of its volume missing, BRepCheck silent; benchmarks/check_hub_fuse_mc.py): every point
    of :func:`interior_probes` must classify IN (or ON) the solid
    (``BRepClass3d_SolidClassifier``).

    Raises
    ------
    OCCTFailure
        Naming the first point found outside.
    """
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_OUT

    scale = float(spec.radius) + float(np.linalg.norm(spec.vecs, axis=1).max())
    tol = 1e-7 * max(scale, 1e-300)
    for p in interior_probes(spec):
        state = BRepClass3d_SolidClassifier(shape, _pnt(p), tol).State()
        if state == TopAbs_OUT:
            raise OCCTFailure(
                f"{what}: the fused solid is valid but misses the inside of its primitives "
                f"(point ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) is outside)"
            )


def general_fuse(prims: list[TopoDS_Shape], *, fuzzy: float = 0.0) -> TopoDS_Shape:
    """One general fuse of all the hub's primitives (the sphere with every stump at once).

    ``BRepAlgoAPI_Fuse`` with the sphere as the argument and the stumps as tools, the
    intersection phase of all pairs in one ``BOPAlgo_PaveFiller``: oriented bounding boxes
    (``SetUseOBB``) so that pairs that cannot touch are skipped without an intersection,
    no history (nothing here asks which face came from which primitive), no inverted-solid
    check (the primitives come from ``BRepPrimAPI`` and are checked), serial (hubs are
    built in worker processes, one per core), non-destructive (the primitives stay
    untouched for the retries). Measured on the GE bracket tet lattice (issue 14): the
    same time as the plain fuse (6.4 vs 6.7 CPU s per hub, alternating runs), and 7 %
    less than ``BOPAlgo_CellsBuilder``; the time is in the stump/stump and
    sphere/stump intersections themselves.

    Raises
    ------
    OCCTFailure
        The fuse is not done.
    """
    args, tools = TopTools_ListOfShape(), TopTools_ListOfShape()
    args.Append(prims[0])
    for s in prims[1:]:
        tools.Append(s)
    op = BRepAlgoAPI_Fuse()
    op.SetArguments(args)
    op.SetTools(tools)
    op.SetRunParallel(False)
    op.SetNonDestructive(True)
    op.SetUseOBB(True)
    op.SetToFillHistory(False)
    op.SetCheckInverted(False)
    if fuzzy > 0.0:
        op.SetFuzzyValue(float(fuzzy))
    op.Build()
    check_done(op, "general fuse")
    return op.Shape()


def tree_fuse(prims: list[TopoDS_Shape], *, fuzzy: float = 0.0) -> TopoDS_Shape:
    """The union of ``prims`` by pairwise general fuses, level by level (a balanced tree).

    Neighbours in the list are fused in pairs, then the pairs in pairs, and so on; each
    fuse is :func:`general_fuse` of two shapes (``IsDone`` checked). The result is the
    same solid as one general fuse of all of them (the caller checks it with BRepCheck),
    but far cheaper on hubs: 5-11 times on GE bracket tet hubs of degree 9-18 (issue 14),
    since each level's fuse splits and classifies only the faces that are still on the
    boundary, where one general fuse splits every primitive by every other one (the
    stumps all meet at the node) and classifies every piece.

    Raises
    ------
    OCCTFailure
        A fuse is not done.
    """
    level = list(prims)
    while len(level) > 1:
        nxt = [general_fuse(level[i : i + 2], fuzzy=fuzzy) for i in range(0, len(level) - 1, 2)]
        if len(level) % 2:
            nxt.append(level[-1])
        level = nxt
    return level[0]


# ------------------------------------------------------------- tessellation
def _tessellate(
    shape: TopoDS_Shape,
    spec: HubSpec,
    deflection: float,
    angular: float,
    clock: StageClock | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], list[NDArray[np.int64]]]:
    scale = spec.radius + float(np.linalg.norm(spec.vecs, axis=1).max())
    tol = config.GEOM_RTOL * scale
    axes = spec.vecs / np.linalg.norm(spec.vecs, axis=1)[:, None]
    plane_off = np.einsum("ij,ij->i", spec.vecs, axes)
    verts: list[NDArray[np.float64]] = []
    tris: list[NDArray[np.int64]] = []
    cap_found = np.zeros(len(spec.vecs), dtype=bool)
    base = 0
    on_meshed = None if clock is None else (lambda: clock.lap("mesh"))
    for face, pts, t in face_triangulations(
        shape, deflection, angular, parallel=False, on_meshed=on_meshed, tiny=deflection
    ):
        nn = len(pts)
        # a planar face lying in a midpoint plane is a midpoint disc: dropped
        if BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane:
            proj = pts @ axes.T - plane_off  # (nn, d)
            on = np.all(np.abs(proj) < tol, axis=0)
            if on.any():
                j = int(np.flatnonzero(on)[0])
                if cap_found[j]:
                    raise OCCTFailure(f"the midpoint disc of stump {j} is split into pieces")
                area = face_area(face)
                expect = math.pi * float(spec.r_mid[j]) ** 2
                if abs(area - expect) > 1e-6 * expect:
                    raise OCCTFailure(
                        f"the midpoint disc of stump {j} is not intact (area {area:.9g}, "
                        f"expected {expect:.9g}): another stump reaches the cut"
                    )
                cap_found[j] = True
                continue
        verts.append(pts)
        tris.append(t + base)
        base += nn
    if not cap_found.all():
        missing = ", ".join(str(int(j)) for j in np.flatnonzero(~cap_found))
        raise OCCTFailure(f"no midpoint disc found for stump(s) {missing}")
    v = np.concatenate(verts)
    f = np.concatenate(tris)
    _lap(clock, "extract")
    v, f, _ = merge_close(v, f, config.MERGE_RTOL * scale)
    out = circles_first(v, f, _circles(v, f, spec, tol))
    _lap(clock, "circles")
    return out


def circle_loops(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    centres: NDArray[np.float64],
    axes: NDArray[np.float64],
    r_mid: NDArray[np.float64],
    xdirs: NDArray[np.float64],
    ydirs: NDArray[np.float64],
    tol: float,
    *,
    what: str = "strut",
) -> list[NDArray[np.int64]]:
    """Boundary loops of an open hub or cluster mesh, one per midpoint disc (centre, unit
    axis, radius and canonical frame given per disc), in canonical angle order; each
    checked to be uniformly spaced from the frame's x axis (``what`` names the disc's
    strut in errors)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, counts = unique_rows(key, return_counts=True)
    if (counts > 2).any():
        raise OCCTFailure(f"{int((counts > 2).sum())} non-manifold edge(s) in the hub mesh")
    bverts = np.unique(uniq[counts == 1])
    out = []
    used = np.zeros(len(v), dtype=bool)
    for j in range(len(centres)):
        rel = v[bverts] - centres[j]
        h = rel @ axes[j]
        rad = np.linalg.norm(rel - h[:, None] * axes[j], axis=1)
        on = (np.abs(h) < tol) & (np.abs(rad - r_mid[j]) < tol * 10)
        idx = bverts[on]
        k = len(idx)
        if k < 3:
            raise OCCTFailure(f"midpoint circle of {what} {j} has {k} boundary vertices")
        ang = np.arctan2(rel[on] @ ydirs[j], rel[on] @ xdirs[j]) % (2 * math.pi)
        step = 2 * math.pi / k
        slot = np.rint(ang / step).astype(np.int64) % k
        dev = np.abs((ang - slot * step + math.pi) % (2 * math.pi) - math.pi)
        if dev.max() > config.ANGLE_TOL or len(np.unique(slot)) != k:
            raise OCCTFailure(
                f"midpoint circle of {what} {j}: {k} vertices not uniformly spaced from "
                f"the frame's x axis (max angle error {dev.max():.3g} rad)"
            )
        ordered = np.empty(k, dtype=np.int64)
        ordered[slot] = idx
        used[idx] = True
        out.append(ordered)
    if not used[bverts].all():
        raise OCCTFailure(
            f"{int((~used[bverts]).sum())} boundary vertices of the hub mesh are not on a "
            "midpoint circle (the tessellation is not closed)"
        )
    return out


def _circles(
    v: NDArray[np.float64], f: NDArray[np.int64], spec: HubSpec, tol: float
) -> list[NDArray[np.int64]]:
    """Boundary loops of the open hub mesh, one per stump, in canonical angle order."""
    centres = np.asarray(spec.vecs, dtype=np.float64)
    axes = centres / np.linalg.norm(centres, axis=1)[:, None]
    return circle_loops(v, f, centres, axes, spec.r_mid, spec.xdirs, spec.ydirs, tol, what="stump")


def circles_first(
    v: NDArray[np.float64], f: NDArray[np.int64], circles: list[NDArray[np.int64]]
) -> tuple[NDArray[np.float64], NDArray[np.int64], list[NDArray[np.int64]]]:
    """Renumber the vertices: circle vertices first (in circle order), the rest after;
    returns the vertices, faces and circles renumbered."""
    on_circle = np.concatenate(circles) if circles else np.zeros(0, np.int64)
    order = np.concatenate([on_circle, np.setdiff1d(np.arange(len(v)), on_circle)])
    inv = np.empty(len(v), dtype=np.int64)
    inv[order] = np.arange(len(v))
    starts = np.cumsum([0] + [len(c) for c in circles])
    circles = [np.arange(starts[j], starts[j + 1], dtype=np.int64) for j in range(len(circles))]
    return v[order], inv[f], circles


# ------------------------------------------------------------------- driver
#: Build hubs that :func:`lattice_cad.occ_impl.hub_direct.direct_applies` covers (equal-radius
#: cylinder stumps around a covered sphere) face by face, without a boolean, before the
#: retry chain below (issue 14: about 10x less CPU per hub, same solid).
DIRECT = True
#: Hubs with stumps of different radii or tapered: the sphere and the largest group of equal
#: cylinder stumps face by face, then one fuse with the other stumps (issue 14; with
#: :data:`DIRECT` only).
DIRECT_FUSE = True


def direct_hub_shape(spec: HubSpec, clock: StageClock | None = None) -> tuple[TopoDS_Shape, float]:
    """The hub solid built face by face (:mod:`hub_direct`), checked, and its exact volume.

    Where :func:`hub_direct.direct_applies` covers the whole hub, the solid is built face by
    face and its volume is in closed form. Otherwise (stumps of different radii or tapered;
    :func:`_direct_plan` says ``"direct+fuse"``) the sphere and the largest group of
    cylinder stumps of one radius (:func:`hub_direct.base_group`) are built face by face,
    checked, and fused with the remaining stumps (trimmed: each starts where it is inside
    the sphere) in one :func:`general_fuse`; its volume is GProp's.

    Raises
    ------
    OCCTFailure
        The solid is not BRepCheck-valid, not one solid, or its volume is not positive.
    lattice_cad.occ_impl.hub_direct.DirectNotApplicable
        A degenerate configuration the direct construction declines.
    """
    from lattice_cad.occ_impl import hub_direct

    scale = spec.radius + float(np.linalg.norm(spec.vecs, axis=1).max())
    plan, idx = _direct_plan(spec)
    if not plan:
        raise hub_direct.DirectNotApplicable("neither direct nor direct+fuse applies")
    sub = hub_direct.sub_spec(spec, idx) if plan == "direct+fuse" else spec
    assert isinstance(sub, HubSpec)
    r = float(sub.r_mid[0])
    shape = hub_direct.build_direct(
        sub.radius, sub.vecs, r, sub.xdirs, tol=config.GEOM_RTOL * scale
    )
    if plan == "direct+fuse":
        check_valid(shape, "direct sub-hub")
        rest = np.setdiff1d(np.arange(len(spec.vecs)), idx)
        stumps = [make_stump(spec, int(j), trim=True) for j in rest]
        _lap(clock, "primitives")
        shape = general_fuse([shape, *stumps])
    _lap(clock, "fuse")
    check_valid(shape, f"{plan} hub")
    n_solids = count(shape, TopAbs_SOLID)
    _lap(clock, "check")
    if n_solids != 1:
        raise OCCTFailure(f"{plan} hub: {n_solids} solids instead of 1")
    if plan == "direct+fuse":
        check_contains_probes(shape, spec, f"{plan} hub")
        _lap(clock, "check")
    if plan == "direct":
        vol = hub_direct.analytic_volume(spec.radius, spec.vecs, r, spec.xdirs)
    else:
        vol = volume(shape, eps=config.VOLUME_EPS)
    _lap(clock, "volume")
    if not (vol > 0.0 and math.isfinite(vol)):
        raise OCCTFailure(f"{plan} hub volume {vol!r} is not positive")
    return shape, vol


def _direct_plan(spec: HubSpec) -> tuple[str, NDArray[np.int64]]:
    """``("direct", all stumps)``, ``("direct+fuse", base group)`` or ``("", [])`` (booleans)."""
    from lattice_cad.occ_impl.hub_direct import base_group, direct_applies

    none = np.zeros(0, dtype=np.int64)
    if not DIRECT:
        return "", none
    why = direct_applies(spec)
    if not why:
        return "direct", np.arange(len(spec.vecs), dtype=np.int64)
    if not DIRECT_FUSE or why != "stumps of different radii or tapered":
        return "", none
    idx, why = base_group(spec)
    return ("direct+fuse", idx) if not why else ("", none)


def _direct_applies(spec: HubSpec) -> str:
    """The direct plan's name (``""``: the boolean chain only)."""
    return _direct_plan(spec)[0]


#: Retry plan: (construction, fuzzy value relative to the hub size, trimmed stumps).
ATTEMPTS: tuple[tuple[str, float, bool], ...] = (
    ("tree", 0.0, True),
    ("fuse", 0.0, True),
    ("fuse", 1e-7, True),
    ("fuse", 0.0, False),
    ("sequential", 1e-7, False),
)


def build_hub(
    spec: HubSpec, *, deflection: float, angular: float, keep_brep: bool = True
) -> HubResult:
    """Build, check, measure and tessellate one hub; never raises for OCCT failures.

    Parameters
    ----------
    spec : HubSpec
    deflection : float
        Absolute linear deflection of ``BRepMesh_IncrementalMesh``.
    angular : float
        Angular deflection (radians).
    keep_brep : bool
        Return the solid as a BREP string (for STEP export).
    """
    t0 = time.perf_counter()
    clock = StageClock()
    scale = spec.radius + float(np.linalg.norm(spec.vecs, axis=1).max())
    attempts: list[str] = []
    plan = _direct_applies(spec)
    if plan:
        try:
            shape, vol = direct_hub_shape(spec, clock)
            v, f, circles = _tessellate(shape, spec, deflection, angular, clock)
        except Exception as exc:  # DirectNotApplicable, OCCTFailure or an OCCT exception
            attempts.append(f"{plan}: {type(exc).__name__}: {exc}")
        else:
            attempts.append(f"{plan}: ok")
            brep = to_bytes(shape) if keep_brep else b""
            clock.lap("brep")
            return HubResult(
                status="ok", attempts=attempts, volume=vol, vertices=v, faces=f,
                circles=circles, brep=brep, seconds=time.perf_counter() - t0,
                stages=clock.stages,
            )  # fmt: skip
    for construction, fuzzy_rel, trim in ATTEMPTS:
        name = (
            f"{construction}"
            + (f" (fuzzy {fuzzy_rel:g})" if fuzzy_rel else "")
            + ("" if trim else " (untrimmed stumps)")
        )
        try:
            shape = make_hub_shape(
                spec, construction=construction, fuzzy=fuzzy_rel * scale, trim=trim, clock=clock
            )
            vol = volume(shape, eps=config.VOLUME_EPS)
            clock.lap("volume")
            if not (vol > 0.0 and math.isfinite(vol)):
                raise OCCTFailure(f"hub volume {vol!r} is not positive")
            v, f, circles = _tessellate(shape, spec, deflection, angular, clock)
        except OCCTFailure as exc:
            attempts.append(f"{name}: {exc}")
            continue
        except Exception as exc:  # OCCT raises Standard_Failure subclasses, as RuntimeError etc.
            attempts.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        attempts.append(f"{name}: ok")
        brep = to_bytes(shape) if keep_brep else b""
        clock.lap("brep")
        return HubResult(
            status="ok",
            attempts=attempts,
            volume=vol,
            vertices=v,
            faces=f,
            circles=circles,
            brep=brep,
            seconds=time.perf_counter() - t0,
            stages=clock.stages,
        )
    return HubResult(
        status=attempts[-1] if attempts else "not attempted",
        attempts=attempts,
        seconds=time.perf_counter() - t0,
        stages=clock.stages,
    )


def build_hub_solid(spec: HubSpec) -> HubResult:
    """Build and check one hub solid, without tessellating it (for B-rep output).

    The same constructions as :func:`build_hub` are tried in turn, but the midpoint
    discs need not be intact (hubs of a lattice that is not clean overlap; a fuse of
    them is still exact). Never raises for OCCT failures.

    Returns
    -------
    HubResult
        ``status``, ``attempts``, ``volume``, ``brep`` and ``seconds`` (no mesh).
    """
    t0 = time.perf_counter()
    scale = spec.radius + float(np.linalg.norm(spec.vecs, axis=1).max())
    attempts: list[str] = []
    plan = _direct_applies(spec)
    if plan:
        try:
            shape, vol = direct_hub_shape(spec)
            brep = to_bytes(shape)
        except Exception as exc:  # DirectNotApplicable, OCCTFailure or an OCCT exception
            attempts.append(f"{plan}: {type(exc).__name__}: {exc}")
        else:
            return HubResult(
                status="ok", attempts=[f"{plan}: ok"], volume=vol, brep=brep,
                seconds=time.perf_counter() - t0,
            )  # fmt: skip
    for construction, fuzzy_rel, trim in ATTEMPTS:
        name = construction + (f" (fuzzy {fuzzy_rel:g})" if fuzzy_rel else "")
        try:
            shape = make_hub_shape(
                spec, construction=construction, fuzzy=fuzzy_rel * scale, trim=trim
            )
            vol = volume(shape, eps=config.VOLUME_EPS)
            if not (vol > 0.0 and math.isfinite(vol)):
                raise OCCTFailure(f"hub volume {vol!r} is not positive")
            brep = to_bytes(shape)
        except Exception as exc:  # OCCTFailure, or an OCCT exception class
            attempts.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        attempts.append(f"{name}: ok")
        return HubResult(
            status="ok", attempts=attempts, volume=vol, brep=brep,
            seconds=time.perf_counter() - t0,
        )  # fmt: skip
    return HubResult(
        status=attempts[-1] if attempts else "not attempted",
        attempts=attempts,
        seconds=time.perf_counter() - t0,
    )
