"""Check a BRepMesh triangulation against the exact surfaces, and refine faces it misses.

BRepMesh does not always honour the chord error it is asked for: on a twisted ruled
B-spline face (degree 3 x 1, e.g. face 78 of ``trimesh_featuretype.STEP``) it places no
interior node in the linear direction, since every isoline there is straight, and its
triangles span the whole face diagonally, up to 25 times the chord error away from the
surface (neither ``DeflectionInterior``, ``MinSize`` nor
``EnableControlSurfaceDeflectionAllSurfaces`` changes that).

:func:`face_deviations` measures, face by face, the distance between the surface point
``S(u, v)`` at the parameters of each triangle's centroid and edge midpoints and the
corresponding point of the flat triangle (an upper bound on the distance of that point
to the surface: exact surface evaluations, no projection). :func:`refine_bad_faces`
inserts knots (the same surface, exactly) into the B-spline faces whose deviation exceeds
the chord error asked, where their bad triangles lie, and meshes the shape again, so
BRepMesh's own grid gets finer there; the shape stays one mesh with shared edge nodes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepTools import BRepTools
from OCP.Extrema import (
    Extrema_ExtAlgo_Grad,
    Extrema_ExtFlag_MINMAX,
    Extrema_ExtPS,
    Extrema_GenLocateExtPS,
)
from OCP.Geom import Geom_BSplineSurface, Geom_OffsetSurface, Geom_RectangularTrimmedSurface
from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Plane
from OCP.gp import gp_Pnt
from OCP.IMeshTools import IMeshTools_Parameters
from OCP.ShapeAnalysis import ShapeAnalysis_ShapeTolerance
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Face, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.surface_eval import surface_points
from lattice_cad.occ_impl.triangulation import triangulation_arrays

#: The meshing of faces alone with a finer deflection (:func:`_mesh_faces_finer`) stops
#: where the whole mesh would hold more triangles than the larger of this (the cutting
#: tessellation's budget, ``config.CUT_MAX_TRIANGLES``, with the 1.5 margin
#: ``conformal.trim.cutting_part`` allows its trials) and twice what it held before the
#: stage: the faces left are reported unresolved. Without it a face BRepMesh
#: cannot follow was meshed finer and finer (kcl exhaust manifold: 290 K, then 610 K
#: triangles for one face, minutes per solid).
FINER_MAX_TRIANGLES = int(1.5 * config.CUT_MAX_TRIANGLES)
#: A face whose knots left it more than this many times over the limit, and worse than
#: before the round, gets no more knots (BRepMesh does not follow them). On the shared
#: parts every knot round ends at most 2.9 times over (the gear's protrusion reference in
#: bench_parts; its cutting tessellation 1.25, the Ventilator's 2.6); the exhaust manifold's
#: B-spline faces go 11.8 -> 2.2 -> 13.1 and 11.7 -> 5.7 -> 22.1 and on for all 8 rounds
#: (10-25 s each) without ever coming under it.
KNOT_GIVE_UP = 6.0

#: surface types curved one way only: their triangles grow as 1 / sqrt(chord error)
_RULED = (GeomAbs_Cylinder, GeomAbs_Cone)
#: :func:`split_dense_faces` skips its coarse pass when the prior counts predict every face
#: this many times under the split's limit (a face's count came out up to 3.1 x its
#: prediction: the M6 screw's threaded cone, whose edges its neighbours refine).
PRIOR_SPARE = 4.0

__all__ = ["ChordReport", "face_deviations", "mesh_checked"]


@dataclass
class ChordReport:
    """What :func:`mesh_checked` measured and did.

    Attributes
    ----------
    deflection : float
        The chord error asked (mm).
    max_deviation : float
        The largest deviation found (mm) of a triangle centroid or edge midpoint from the
        exact surface, after refinement (an upper bound: ``|S(uv) - p|``).
    worst_face : int
        TopExp index of the face with ``max_deviation`` (-1 if none).
    refined : list of int
        Faces refined by knot insertion.
    unresolved : list of int
        Faces still over ``factor * deflection`` after refinement (not B-spline, or the
        rounds ran out).
    within_tolerance : list of int
        Faces over ``factor * deflection`` by no more than their B-rep tolerance (their
        edge nodes lie off the surface by up to it: not a chord error; left as they are).
    rounds : int
        BRepMesh runs after the first.
    finer : list of int
        Faces brought under the limit by meshing them alone with a finer deflection.
    """

    deflection: float
    max_deviation: float = 0.0
    worst_face: int = -1
    refined: list[int] = field(default_factory=list)
    unresolved: list[int] = field(default_factory=list)
    within_tolerance: list[int] = field(default_factory=list)
    rounds: int = 0
    finer: list[int] = field(default_factory=list)


def _faces(shape: TopoDS_Shape) -> list[TopoDS_Face]:
    out = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        out.append(TopoDS.Face_s(exp.Current()))
        exp.Next()
    return out


def _uv_triangulation(
    face: TopoDS_Face,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None:
    """(nodes in global coordinates, uv nodes, 0-based triangles), or None without uv."""
    loc = TopLoc_Location()
    tri = BRep_Tool.Triangulation_s(face, loc)
    if tri is None or tri.NbTriangles() == 0 or not tri.HasUVNodes():
        return None
    nn = tri.NbNodes()
    node, uvn = tri.Node, tri.UVNode
    pts = np.array([node(i).Coord() for i in range(1, nn + 1)], dtype=np.float64).reshape(nn, 3)
    uv = np.array([uvn(i).Coord() for i in range(1, nn + 1)], dtype=np.float64).reshape(nn, 2)
    if not loc.IsIdentity():
        m = loc.Transformation()
        rot = np.array([[m.Value(r, c) for c in (1, 2, 3)] for r in (1, 2, 3)])
        pts = pts @ rot.T + np.array([m.Value(r, 4) for r in (1, 2, 3)])
    tri_at = tri.Triangle
    t = np.array([tri_at(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64)
    return pts, uv, t.reshape(-1, 3) - 1


def _unique_edges(t: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The distinct edges of the triangles ``t`` as sorted (low, high) rows, and for each of
    the 3T edges ``[t01, t12, t20]`` its row in them: ``np.unique(edges, axis=0,
    return_inverse=True)``, by one int64 key per edge (``core.arrays.unique_rows``)."""
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    uniq, inv = unique_rows(edges, return_inverse=True)
    return uniq, inv


#: per face: [key of the inputs measured, the result], see :func:`_measured`
_Cache = dict[int, list[Any]]


def _uv_triangulations(
    faces: list[TopoDS_Face],
) -> list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None]:
    """:func:`_uv_triangulation` of each of ``faces``, read in one go where possible
    (:func:`~lattice_cad.occ_impl.triangulation.triangulation_arrays`: the same values)."""
    out: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None]
    out = [None] * len(faces)
    tris, locs, at = [], [], []
    for k, face in enumerate(faces):
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0 or not tri.HasUVNodes():
            continue
        tris.append(tri)
        locs.append(loc)
        at.append(k)
    bulk = triangulation_arrays(tris) if len(tris) > 1 else None
    if bulk is None:
        for k in at:
            out[k] = _uv_triangulation(faces[k])
        return out
    for k, loc, (pts, uv, t) in zip(at, locs, bulk, strict=True):
        if uv is None:
            continue
        if not loc.IsIdentity():
            m = loc.Transformation()
            rot = np.array([[m.Value(r, c) for c in (1, 2, 3)] for r in (1, 2, 3)])
            pts = pts @ rot.T + np.array([m.Value(r, 4) for r in (1, 2, 3)])
        out[k] = (pts, uv, t - 1)
    return out


def _triangle_deviation(
    face: TopoDS_Face,
    limit: float,
    cache: list[Any] | None = None,
    read: Any = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None:
    """Per triangle, the deviation from the exact surface over its centroid and edge midpoints.

    First screened by ``|S(uv) - p|`` (the surface point at the mean parameters against
    the point of the flat triangle: an upper bound, but also counting the tangential shift
    of a non-uniform parametrisation); points over ``limit`` are then measured by their
    distance to the surface near ``S(uv)`` (``Extrema_GenLocateExtPS``, distance criterion,
    started at ``uv``: a local minimum, so still an upper bound on the distance).

    Returns (deviation (T,), uv nodes, triangles), or None for a plane or a face without
    uv nodes. ``cache``, if given, is ``[key, result]`` of the last measurement of this
    face (its surface unchanged since): the result is returned again when the nodes, uv
    nodes, triangles and ``limit`` are the same, and ``cache`` is updated otherwise.
    ``read(face)``, if given, gives the triangulation (what :func:`_uv_triangulations`
    read before) instead of :func:`_uv_triangulation`.
    """
    surf = BRepAdaptor_Surface(face)
    if surf.GetType() == GeomAbs_Plane:
        return None
    got = _uv_triangulation(face) if read is None else read(face)
    if got is None:
        return None
    pts, uv, t = got
    key = (pts.tobytes(), uv.tobytes(), t.tobytes(), limit)
    if cache is not None and cache[0] == key:
        return cache[1]
    uniq, inv = _unique_edges(t)
    p3 = np.concatenate([pts[t].mean(axis=1), pts[uniq].mean(axis=1)])
    q = np.concatenate([uv[t].mean(axis=1), uv[uniq].mean(axis=1)])
    # on arrays where the surface type allows (checked against OCCT's Value), else one
    # Python call per point, from 1-D lists (a list of pairs costs as much as the calls)
    s = surface_points(surf, q[:, 0], q[:, 1])
    if s is None:
        values = map(surf.Value, q[:, 0].tolist(), q[:, 1].tolist())
        s = np.fromiter((x for p in values for x in p.Coord()), dtype=np.float64, count=3 * len(q))
    d = np.linalg.norm(s.reshape(-1, 3) - p3, axis=1)
    over = np.flatnonzero(d > limit)
    if len(over):
        loc = Extrema_GenLocateExtPS(surf, 1e-9, 1e-9)
        ext = None
        for k in over.tolist():
            p = gp_Pnt(*p3[k])
            loc.Perform(p, float(q[k, 0]), float(q[k, 1]), True)
            if loc.IsDone():
                d[k] = min(d[k], float(np.sqrt(loc.SquareDistance())))
            if d[k] > limit:  # the local search stopped at the domain's boundary: global
                if ext is None:  # one search for the face: its grid of samples is built once
                    ext = _global_search(surf)
                ext.Perform(p)
                if ext.IsDone() and ext.NbExt() > 0:
                    sq = min(ext.SquareDistance(i) for i in range(1, ext.NbExt() + 1))
                    d[k] = min(d[k], float(np.sqrt(sq)))
    nt = len(t)
    dev = np.maximum(d[:nt], d[nt:][inv.reshape(-1)].reshape(3, nt).max(axis=0))
    result = (dev, uv, t)
    if cache is not None:
        cache[:] = [key, result]
    return result


def _global_search(surf: BRepAdaptor_Surface) -> Extrema_ExtPS:
    """``Extrema_ExtPS`` over the whole face, for many points (``Perform``): the same
    search as ``Extrema_ExtPS(point, surf, 1e-9, 1e-9)`` (that constructor is this
    ``Initialize`` and a ``Perform``), but its grid of samples of the surface is built
    once, not once per point (the bottle's degree-14 loft and its offset: 1,568 searches,
    4.4 s)."""
    ext = Extrema_ExtPS()
    ext.SetFlag(Extrema_ExtFlag_MINMAX)
    ext.SetAlgo(Extrema_ExtAlgo_Grad)
    ext.Initialize(
        surf,
        surf.FirstUParameter(),
        surf.LastUParameter(),
        surf.FirstVParameter(),
        surf.LastVParameter(),
        1e-9,
        1e-9,
    )
    return ext


def _measured(
    faces: list[TopoDS_Face], which: Iterable[int], limit: float, cache: _Cache
) -> dict[int, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None]:
    """:func:`_triangle_deviation` of the faces ``which`` (screened at ``limit`` plus each
    face's tolerance), reusing ``cache`` (face index: (key, result), updated in place) for a
    face whose triangulation (nodes, uv nodes, triangles) and screen are the same as when it
    was measured: the same inputs, so the same result, without evaluating the surface."""
    out = {}
    which = list(which)
    curved = [i for i in which if BRepAdaptor_Surface(faces[i]).GetType() != GeomAbs_Plane]
    read = dict(zip(curved, _uv_triangulations([faces[i] for i in curved]), strict=True))
    for i in which:
        face = faces[i]
        entry: list[Any] = [None, None] if i not in cache else cache[i]
        got = _triangle_deviation(
            face, limit + _tolerance(face), entry, lambda _f, i=i: read.get(i)
        )
        cache[i] = entry
        out[i] = got
    return out


def split_dense_faces(
    shape: TopoDS_Shape,
    deflection: float,
    angular: float,
    *,
    target: int | None = None,
    coarse: float | None = None,
    prior: tuple[float, NDArray[np.int64], NDArray[np.float64]] | None = None,
) -> tuple[TopoDS_Shape, NDArray[np.int64]] | None:
    """``shape`` with each face that BRepMesh would fill with more than
    ``config.MESH_SPLIT_MIN`` triangles at ``deflection`` split into patches of about
    ``target`` triangles, or None when no face is that dense (or no split succeeded).

    The count is predicted from a coarse BRepMesh pass at ``coarse * deflection``: its count
    times ``coarse`` (triangles grow at most as 1 / chord error), times its square root for
    cylinders and cones (curved one way); planes are not split. Faces are split by area
    (``ShapeUpgrade_FaceDivideArea``: iso-parametric cuts of the same surface, so the
    geometry is unchanged), all in one ``ShapeBuild_ReShape`` context, so a neighbour whose
    edge was cut gets the same new edges and vertices: the patches share their edge nodes
    with each other and with the neighbours when meshed. BRepMesh's time per face grows
    faster than its triangle count, and the patches are meshed in parallel: the M6 screw's
    cutting tessellation at 0.5 % r takes 17 s as 28 faces, 3.4 s as 116. The split runs
    in a child process (``lattice_cad.core.isolate``): OCCT's face split can die of a
    segmentation fault, and then (or after ``config.MESH_SPLIT_SECONDS``) the faces are
    meshed whole (None).

    ``prior``, ``(d0, counts, growth)``: the triangles of each face (TopExp order) in a
    tessellation at chord error ``d0`` and the power of ``1 / chord error`` each grows at
    most as (``conformal.Part.face_triangles``). When no face but a plane is predicted
    dense from it, ``counts * (d0 / deflection) ** growth``, with ``PRIOR_SPARE`` to spare,
    None is returned without the coarse pass (a perforated plate's 700 faces: 2 s of
    BRepMesh, most of it in its two planar faces with 344 holes each, never split).

    ``shape``'s own stored triangulation is dropped (the coarse pass).

    Returns
    -------
    split : TopoDS_Shape
    face_of : (F',) int64
        For each face of ``split`` (TopExp order), the TopExp index of the face of ``shape``
        it is part of.
    """
    from lattice_cad.occ_impl.shapes import face_area

    target = int(config.MESH_FACE_TRIANGLES if target is None else target)
    k = float(config.MESH_SPLIT_COARSE if coarse is None else coarse)
    if not (target > 0 and k >= 1.0 and deflection > 0):
        raise ValueError(f"split_dense_faces: bad target {target} or coarse {k}")
    limit = max(float(config.MESH_SPLIT_MIN), 2.0 * target)
    faces = _faces(shape)
    kinds = [BRepAdaptor_Surface(f).GetType() for f in faces]
    if prior is not None and len(prior[1]) == len(faces) == len(prior[2]):
        ratio = max(1.0, float(prior[0]) / float(deflection))
        at_most = np.asarray(prior[1], dtype=np.float64) * ratio ** np.asarray(prior[2])
        at_most[[t == GeomAbs_Plane for t in kinds]] = 0.0
        if not (at_most > limit / PRIOR_SPARE).any():
            return None
    BRepTools.Clean_s(shape)
    _mesh(shape, k * deflection, angular, True)
    # planes do not grow (and are meshed fast, while splitting one with many holes is
    # slow: NIST CTC-02, 0.5 s a face); cylinders and cones grow as the square root
    growth = np.array([0.0 if t == GeomAbs_Plane else np.sqrt(k) if t in _RULED else k
                       for t in kinds])  # fmt: skip
    predicted = _triangle_counts(faces).astype(np.float64) * growth
    BRepTools.Clean_s(shape)
    dense = np.flatnonzero(predicted > limit)
    if not len(dense):
        return None
    areas = {i: face_area(faces[i]) for i in dense.tolist()}
    asks = [(i, a * target / float(predicted[i])) for i, a in areas.items() if a > 0]
    if not asks:
        return None
    from lattice_cad.core.errors import ExternalCrash
    from lattice_cad.core.isolate import run_isolated
    from lattice_cad.occ_impl.shapes import from_bytes, to_bytes

    # in a child process: ShapeUpgrade_FaceDivideArea dies of a segmentation fault on some
    # B-spline faces (a trefoil knot swept as three fused tubes, made outside shared/data:
    # every fill of it ended the user's process); a face that crashes it, or a split that
    # hangs, is meshed whole
    try:
        got = run_isolated(
            _divided_faces,
            to_bytes(shape),
            len(faces),
            asks,
            timeout=config.MESH_SPLIT_SECONDS,
            what="OCCT's split of dense faces (ShapeUpgrade_FaceDivideArea)",
        )
    except ExternalCrash:
        return None
    if got is None:
        return None
    return from_bytes(got[0]), got[1]


def _divided_faces(
    data: bytes, n_faces: int, asks: list[tuple[int, float]]
) -> tuple[bytes, NDArray[np.int64]] | None:
    """:func:`split_dense_faces`' split, in a child process: the shape (``to_bytes``, its
    ``n_faces`` faces in TopExp order) with face ``i`` split into patches of at most
    ``max_area`` for each ``(i, max_area)`` of ``asks``; the result as bytes, and for each
    of its faces (TopExp order) the index of the face it is part of. None when no face
    was split or the result fails BRepCheck."""
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.ShapeBuild import ShapeBuild_ReShape
    from OCP.ShapeExtend import ShapeExtend_Status
    from OCP.ShapeFix import ShapeFix_Shape
    from OCP.ShapeUpgrade import ShapeUpgrade_FaceDivideArea
    from OCP.TopTools import TopTools_IndexedMapOfShape

    from lattice_cad.occ_impl.shapes import from_bytes, to_bytes

    shape = from_bytes(data)
    faces = _faces(shape)
    if len(faces) != n_faces:  # (cannot be: the bytes keep the shape's structure)
        return None
    context = ShapeBuild_ReShape()
    done = 0
    for i, max_area in asks:
        face = faces[i]
        tool = ShapeUpgrade_FaceDivideArea(face)
        tool.MaxArea = max_area
        tool.SetContext(context)
        try:
            tool.Perform()
        except Exception:  # OCCT raised (Standard_Failure): this face stays whole
            continue
        if tool.Status(ShapeExtend_Status.ShapeExtend_FAIL) or not tool.Status(
            ShapeExtend_Status.ShapeExtend_DONE
        ):
            continue
        context.Replace(face, tool.Result())
        done += 1
    if not done:
        return None
    # the new edges' tolerances and pcurves as BRepCheck wants them (M6: 20 patches fail
    # BRepCheck before, none after); a shape that still fails is meshed whole
    fix = ShapeFix_Shape(context.Apply(shape))
    fix.Perform()
    out = fix.Shape()
    if out is None or out.IsNull() or not BRepCheck_Analyzer(out).IsValid():
        return None
    # each new face back to the face it came from: the faces' images in the contexts (a
    # neighbour rebuilt only for its cut edge is one face; a split face several)
    index = TopTools_IndexedMapOfShape()
    new_faces = _faces(out)
    for f in new_faces:
        index.Add(f)
    face_of = np.full(len(new_faces), -1, dtype=np.int64)
    for i, face in enumerate(faces):
        # recursively: a patch whose edge a neighbour's cut split, then the fix's changes
        image = fix.Context().Apply(context.Apply(face))
        for part in _faces(image) if not image.IsNull() else []:
            j = index.FindIndex(part)
            if j > 0:
                face_of[j - 1] = i
    if (face_of < 0).any():  # not traced: do not risk a wrong map, mesh the faces as they are
        return None
    return to_bytes(out), face_of


def face_deviations(shape: TopoDS_Shape, screen: float = 0.0) -> NDArray[np.float64]:
    """(n_faces,) the largest deviation (mm) of each face's stored triangulation from its
    exact surface (0 for planes and faces without uv nodes), in TopExp order.

    Measured at each triangle's centroid and edge midpoints: ``|S(u, v) - p|``, the
    surface point at the mean parameters against the point of the flat triangle, and
    where that exceeds ``screen`` (mm), the distance to the surface near ``S(u, v)``.
    Both are upper bounds on the distance to the surface.

    Raises
    ------
    OCCTFailure
        A face has no triangulation.
    """
    out = []
    for face in _faces(shape):
        if BRep_Tool.Triangulation_s(face, TopLoc_Location()) is None:
            raise OCCTFailure("face_deviations: a face has no triangulation")
        got = _triangle_deviation(face, screen)
        out.append(0.0 if got is None or len(got[0]) == 0 else float(got[0].max()))
    return np.asarray(out, dtype=np.float64)


def _tolerance(face: TopoDS_Face) -> float:
    """The largest tolerance of the face and its edges and vertices (mm)."""
    return float(ShapeAnalysis_ShapeTolerance().Tolerance(face, 1))


def _over(face: TopoDS_Face, deviation: float, limit: float) -> bool:
    """True when ``deviation`` exceeds ``limit`` by more than the face's B-rep tolerance
    (nodes on its edges lie off the surface by up to the edges' tolerance)."""
    return deviation > limit and deviation > limit + _tolerance(face)


def _triangle_counts(faces: list[TopoDS_Face]) -> NDArray[np.int64]:
    """(n,) int64: the triangles of each face's stored triangulation (0 without one)."""
    out = np.zeros(len(faces), dtype=np.int64)
    for i, face in enumerate(faces):
        tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
        out[i] = 0 if tri is None else tri.NbTriangles()
    return out


def _has_triangulation(face: TopoDS_Face) -> bool:
    tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    return tri is not None and tri.NbTriangles() > 0


def _bspline(face: TopoDS_Face) -> Geom_BSplineSurface | None:
    """The B-spline surface whose knots shape ``face``'s meshing: its surface's, or the
    basis surface's of an offset surface (parametrised as its basis: BRepMesh splits it at
    the basis's knots)."""
    surf = BRep_Tool.Surface_s(face)
    if isinstance(surf, Geom_RectangularTrimmedSurface):
        surf = surf.BasisSurface()
    if isinstance(surf, Geom_OffsetSurface):
        surf = surf.BasisSurface()
        if isinstance(surf, Geom_RectangularTrimmedSurface):
            surf = surf.BasisSurface()
    return surf if isinstance(surf, Geom_BSplineSurface) else None


def _new_knots(
    lo: NDArray[np.float64], hi: NDArray[np.float64], existing: NDArray[np.float64]
) -> list[float]:
    """Knots at the middle of the bad triangles' parameter spans ``[lo, hi]``, skipping
    those within a quarter span of a knot already there or chosen."""
    span = hi - lo
    mid = 0.5 * (lo + hi)
    order = np.argsort(-span)  # the widest first
    taken = np.sort(existing).tolist()
    chosen: list[float] = []
    for i in order:
        if span[i] <= 0:
            continue
        m = float(mid[i])
        j = int(np.searchsorted(taken, m))
        near = [taken[k] for k in (j - 1, j) if 0 <= k < len(taken)]
        if any(abs(k - m) < 0.25 * span[i] for k in near):
            continue
        taken.insert(j, m)
        chosen.append(m)
    return chosen


def _insert_knots(bs: Geom_BSplineSurface, uv: NDArray[np.float64], t: NDArray[np.int64]) -> int:
    """Insert u and v knots (multiplicity 1) at the middle of the triangles ``t``; how many."""
    box_lo, box_hi = uv[t].min(axis=1), uv[t].max(axis=1)
    u0, u1, v0, v1 = bs.Bounds()
    n = 0
    for axis, (a, b), nknots, knot, insert in (
        (0, (u0, u1), bs.NbUKnots, bs.UKnot, bs.InsertUKnot),
        (1, (v0, v1), bs.NbVKnots, bs.VKnot, bs.InsertVKnot),
    ):
        existing = np.array([knot(i) for i in range(1, nknots() + 1)], dtype=np.float64)
        tol = 1e-9 * max(b - a, 1e-300)
        for k in _new_knots(box_lo[:, axis], box_hi[:, axis], existing):
            if a + tol < k < b - tol:
                insert(k, 1, tol, False)
                n += 1
    return n


def _params(deflection: float, angular: float, parallel: bool) -> IMeshTools_Parameters:
    """BRepMesh's parameters: ``ForceFaceDeflection``, else BRepMesh meshes each face with
    the largest deflection of its edges' discretisation, which edges with a large B-rep
    tolerance raise (Ventilator face 26: tolerance 4.25e-3 mm, asked 4.4e-3, meshed at
    8.4e-3: 1.9 % r for 1 % r asked; 1.0 % r with it)."""
    from lattice_cad.occ_impl.shapes import mesh_parameters

    return mesh_parameters(deflection, angular, parallel, force_face=True)


def _mesh(shape: TopoDS_Shape, deflection: float, angular: float, parallel: bool) -> None:
    mesher = BRepMesh_IncrementalMesh(shape, _params(deflection, angular, parallel))
    if not mesher.IsDone():
        raise OCCTFailure("BRepMesh_IncrementalMesh: IsDone() is false")


def _plain_edges(face: TopoDS_Face) -> list[Any]:
    """The edges of ``face`` that are not degenerate (a cone's apex, a sphere's pole)."""
    out = []
    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        exp.Next()
        if not BRep_Tool.Degenerated_s(edge):
            out.append(edge)
    return out


def _edges_shared(shape: TopoDS_Shape, faces: list[TopoDS_Face]) -> bool:
    """True when every edge of ``faces`` has the same nodes in the triangulation of each
    face of ``shape`` that holds it (the faces share their edge nodes: a closed mesh)."""
    ancestors = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, ancestors)
    for face in faces:
        for edge in _plain_edges(face):
            nodes = set()
            for other in ancestors.FindFromKey(edge):
                loc = TopLoc_Location()
                tri = BRep_Tool.Triangulation_s(TopoDS.Face_s(other), loc)
                pol = None if tri is None else BRep_Tool.PolygonOnTriangulation_s(edge, tri, loc)
                if pol is None:
                    return False
                n = pol.NbNodes()
                par = pol.Parameter if pol.HasParameters() else (lambda k: 0.0)
                nodes.add(tuple(par(k) for k in range(1, n + 1)))
            if len(nodes) > 1:  # the same edge nodes (parameters) in every face
                return False
    return True


def _clean_around(shape: TopoDS_Shape, which: Iterable[int]) -> None:
    """Drop the triangulations of the faces ``which`` (TopExp indices) of ``shape`` and of
    their neighbours across an edge, with their edges' polygons. A face left with an edge
    that lost its polygon is meshed again by BRepMesh too (its triangulation is no longer
    consistent), so the faces still share their edge nodes."""
    faces = _faces(shape)
    ancestors = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, ancestors)
    drop = []  # (a face listed twice is cleaned twice: harmless)
    for i in which:
        drop += [faces[i], *_edge_neighbours(faces[i], ancestors)]
    BRepTools.Clean_s(_compound(drop))


def _edge_neighbours(
    face: TopoDS_Face, ancestors: TopTools_IndexedDataMapOfShapeListOfShape
) -> list[TopoDS_Face]:
    """The faces sharing a (non-degenerate) edge with ``face``."""
    out = []
    for edge in _plain_edges(face):
        for other in ancestors.FindFromKey(edge):
            if not other.IsSame(face):
                out.append(TopoDS.Face_s(other))
    return out


def _compound(faces: list[TopoDS_Face]) -> TopoDS_Compound:
    builder = BRep_Builder()
    out = TopoDS_Compound()
    builder.MakeCompound(out)
    for face in faces:
        builder.Add(out, face)
    return out


def _adjacent_groups(
    shape: TopoDS_Shape, faces: list[TopoDS_Face], which: list[int]
) -> list[list[int]]:
    """The faces ``which`` (TopExp indices into ``faces``) grouped by shared edges
    (connected components; degenerate edges do not connect)."""
    ancestors = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, ancestors)
    parent = {i: i for i in which}

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in which:
        for other in _edge_neighbours(faces[i], ancestors):
            for j in which:
                if j != i and faces[j].IsSame(other):
                    parent[root(j)] = root(i)
    groups: dict[int, list[int]] = {}
    for i in which:
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def _mesh_alone(
    shape: TopoDS_Shape,
    asked: dict[int, float],
    deflection: float,
    angular: float,
    parallel: bool = False,
) -> None:
    """Mesh the faces ``asked`` (TopExp index: deflection, mm) of ``shape`` without the
    rest, and stamp their triangulations and edge polygons with ``deflection``, so that a
    BRepMesh run on the whole ``shape`` at ``deflection`` keeps them (and their edge
    nodes, which the neighbouring faces then share).

    Neighbouring faces are meshed together, finest first: one run per distinct deflection
    of the group, each with the faces meshed before (BRepMesh keeps their finer, so
    consistent, triangulation and takes their nodes on the edges they share with the next
    faces). Meshed each alone, two neighbours put their own nodes on their common edge
    (M6 countersunk screw, faces 1-3 and 3-11: 285 and 273 nodes) and the whole mesh is
    open. Faces of one deflection share one (parallel) run: the M6's thread split into
    patches (:func:`split_dense_faces`) is 110 faces in a few runs, not 110.
    """
    faces = _faces(shape)
    for group in _adjacent_groups(shape, faces, sorted(asked)):
        for level in sorted({asked[i] for i in group}):
            run = [faces[j] for j in group if asked[j] <= level]
            _mesh(_compound(run), level, angular, parallel)
    for i in asked:
        face = faces[i]
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None:
            continue
        tri.Deflection(float(deflection))  # consistent for the whole-shape run: kept
        exp = TopExp_Explorer(face, TopAbs_EDGE)
        while exp.More():
            pol = BRep_Tool.PolygonOnTriangulation_s(TopoDS.Edge_s(exp.Current()), tri, loc)
            if pol is not None:
                pol.Deflection(float(deflection))
            exp.Next()


def _quarter_octave(x: float) -> float:
    """The largest power of 2 ** (1/4) not above ``x`` (> 0)."""
    return float(2.0 ** (np.floor(4.0 * np.log2(x) + 1e-9) / 4.0))


def _mesh_faces_finer(
    shape: TopoDS_Shape,
    over: dict[int, float],
    deflection: float,
    angular: float,
    limit: float,
    parallel: bool,
    rounds: int,
    dev: NDArray[np.float64],
    cache: _Cache | None = None,
    face_of: NDArray[np.int64] | None = None,
) -> tuple[TopoDS_Shape, list[int], list[int]]:
    """Mesh the faces ``over`` (index: deviation, mm) alone with a finer deflection, then
    the whole ``shape`` around them; repeat for the faces still over ``limit``.

    Each face's deflection is scaled by ``min(0.5, 0.8 * limit / deviation)`` per round,
    while the whole mesh is predicted (triangles ~ 1 / deflection) to stay under the cap of
    :data:`FINER_MAX_TRIANGLES`; a face that would exceed it is left as it is.
    The finer triangulation and its edge polygons are stamped with ``deflection``, so the
    whole-shape BRepMesh run takes them as consistent and keeps them (with the edge nodes,
    which the neighbouring faces then share: the mesh stays closed). Every face is
    measured again after each run (``dev`` is updated in place), and any face over the
    limit joins the next round. ``cache``: measurements of ``shape``'s faces so far (see
    :func:`_measured`), reused for faces BRepMesh gave the same triangulation again.
    ``face_of`` (patches of one face, :func:`split_dense_faces`): every patch of a face gets
    the finest step any of them needs. Meshed at different deflections, the patches of one
    surface meet at edges discretised for the finer one, and BRepMesh's triangles along
    them deviate more (M6 screw, head patches: 0.48 -> 1.64 x the chord error).

    Returns
    -------
    shape : TopoDS_Shape
        ``shape``, meshed (plainly again if BRepMesh left a face without triangulation).
    finer : list of int
        Faces meshed finer and now under the limit.
    still : list of int
        Faces still over the limit.
    """
    scale: dict[int, float] = {}
    cache = {} if cache is None else cache
    todo = dict(over)
    dev0 = dev.copy()
    # the whole mesh may grow to FINER_MAX_TRIANGLES, or to twice what it holds now (a
    # caller asking for a finer mesh, e.g. a reference tessellation, gets room in proportion)
    cap = max(float(FINER_MAX_TRIANGLES), 2.0 * float(_triangle_counts(_faces(shape)).sum()))
    for _ in range(rounds):
        if not todo:
            break
        # triangles grow about as 1 / chord error: a face whose finer mesh would take the
        # whole mesh over the cap stays as it is (still over the limit)
        counts = _triangle_counts(_faces(shape))
        total = float(counts.sum())
        # what is meshed finer together: a face, or every patch of a face (face_of)
        units: dict[int, tuple[float, float, list[int]]] = {}  # key: (deviation, step, faces)
        for i, d in todo.items():
            key = i if face_of is None else int(face_of[i])
            worst, least, members = units.get(key, (0.0, 1.0, []))
            units[key] = (max(worst, d), min(least, min(0.5, 0.8 * limit / d)), members)
        if face_of is not None:
            for j, whole in enumerate(face_of.tolist()):
                if whole in units:
                    units[whole][2].append(j)
        else:
            for i in units:
                units[i][2].append(i)
        now: dict[int, float] = {}
        for _key, (_, step, members) in sorted(units.items(), key=lambda u: (u[1][0], u[0])):
            # the growth of all the faces meshed finer: a face split into patches is meshed
            # finer in every patch (a mould insert's cooling channel, made outside shared/data:
            # its one patch over the limit, 1,254 triangles, brought its 333 others, 0.37 M,
            # to a tenth of the chord error: BRepMesh still ran 6 minutes later)
            grown = float(counts[members].sum()) * (1.0 / step - 1.0)
            if total + grown <= cap:
                total += grown
                for j in members:
                    now[j] = min(now.get(j, 1.0), step)
        if not now:
            break
        for i, step in now.items():
            # down to a quarter octave (at most 19 % finer than needed): few distinct
            # deflections, so few BRepMesh runs in _mesh_alone
            scale[i] = _quarter_octave(scale.get(i, 1.0) * step)
        # only these faces and their neighbours lose their triangulation: BRepMesh keeps the
        # rest (meshed at ``deflection`` by the last whole run) instead of meshing the whole
        # shape again (M6 screw: 29-35 s a round for 3 faces)
        _clean_around(shape, scale)
        _mesh_alone(
            shape, {i: deflection * s for i, s in scale.items()}, deflection, angular, parallel
        )
        _mesh(shape, deflection, angular, parallel)
        faces = _faces(shape)
        if not all(_has_triangulation(f) for f in faces) or not _edges_shared(
            shape, [faces[i] for i in scale]
        ):
            # BRepMesh failed, or meshed an edge of these faces again for a neighbour
            # (M6 countersunk screw, thread faces: 1338 open edges): the plain mesh
            BRepTools.Clean_s(shape)
            _mesh(shape, deflection, angular, parallel)
            dev[:] = dev0
            return shape, [], sorted(over)
        # BRepMesh ran on the whole shape again: measure every face, not only these
        todo = _measure_all(faces, limit, dev, cache)
        if todo and dev.max() > dev0.max():
            # the finer meshing made the worst face worse than before it (BRepMesh does not
            # follow it: a shoe midsole's B-spline loft, made outside shared/data, went from
            # 1.01 to 3.3 times the limit in its patches at half the deflection, and the next
            # round, at a tenth, took 37 s and 1.55 M triangles to reach 1.6 times): the
            # plain mesh, as before this stage, measured again
            BRepTools.Clean_s(shape)
            _mesh(shape, deflection, angular, parallel)
            return shape, [], sorted(_measure_all(_faces(shape), limit, dev, cache))
    return shape, sorted(i for i in scale if i not in todo), sorted(todo)


def _measure_all(
    faces: list[Any], limit: float, dev: NDArray[np.float64], cache: _Cache
) -> dict[int, float]:
    """Measure every face (``dev`` (F,) float64 updated in place with each one's largest
    deviation, mm); the faces over ``limit`` with their deviations."""
    over: dict[int, float] = {}
    for i, got in _measured(faces, range(len(faces)), limit, cache).items():
        dev[i] = 0.0 if got is None or not len(got[0]) else got[0].max()
        if got is not None and _over(faces[i], dev[i], limit):
            over[i] = float(dev[i])
    return over


def mesh_checked(
    shape: TopoDS_Shape,
    deflection: float,
    angular: float,
    *,
    factor: float = 1.5,
    rounds: int = 8,
    parallel: bool = True,
    clean: bool = True,
    finer_rounds: int = 2,
    face_of: NDArray[np.int64] | None = None,
) -> tuple[TopoDS_Shape, ChordReport]:
    """Mesh ``shape`` with BRepMesh, check every face against its exact surface, and refine
    the B-spline faces whose triangles deviate by more than ``factor * deflection`` (plus
    the face's B-rep tolerance, by which its edge nodes may lie off the surface).

    A face whose knots leave it more than ``KNOT_GIVE_UP`` times over the limit, and worse
    than before the round, gets no more knots; when that is so of every face knots went
    into, the plain mesh is kept (as if none had been inserted).

    Faces still over the limit after that (other surface types, e.g. a torus BRepMesh
    meshes 4.5 times coarser than asked on ``pythonocc_Ventilator.stp``, or knots that did
    not help) are meshed alone with a finer deflection, scaled by how far they are over,
    before the whole shape is meshed again around them (BRepMesh keeps their triangulation
    and edge nodes, so the faces still share them), for up to ``finer_rounds`` rounds
    (:func:`_mesh_faces_finer`); those that came down are listed in ``finer``, the rest in
    ``unresolved``. If BRepMesh fails on the refined copy, the plain mesh of ``shape`` is
    kept and the faces are reported as unresolved. ``face_of`` (F,) int64: when ``shape``'s
    faces are patches of larger ones (:func:`split_dense_faces`), the face each is part of:
    the patches of one face are meshed finer together.

    ``shape`` is meshed in place: its stored triangulation is dropped first, unless
    ``clean`` is False (the caller knows it was made with the same ``deflection`` and
    ``angular``: BRepMesh then keeps it). When a face needs refining, a deep copy of ``shape``
    gets the extra knots (the geometry is unchanged; the caller's shape keeps its own
    surfaces) and is meshed again as a whole, so faces still share their edge nodes.

    Returns
    -------
    meshed : TopoDS_Shape
        ``shape`` or the refined copy, carrying the triangulation to read (same faces in
        the same TopExp order).
    report : ChordReport
    """
    from lattice_cad.occ_impl.shapes import copied

    if clean:
        BRepTools.Clean_s(shape)
    _mesh(shape, deflection, angular, parallel)
    report = ChordReport(float(deflection))
    limit = factor * float(deflection)
    faces = _faces(shape)
    dev = np.zeros(len(faces))
    bad: dict[int, tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]] = {}
    # each face's last measurement, for its triangulation and surface then: faces meshed
    # the same again are not measured again (a deep copy's surfaces evaluate the same;
    # a face's entry goes when knots are inserted into its surface)
    cache: _Cache = {}
    knotted: set[int] = set()
    # points within the face's tolerance of the limit are not measured more exactly
    for i, got in _measured(faces, range(len(faces)), limit, cache).items():
        face = faces[i]
        if got is not None and len(got[0]):
            dev[i] = got[0].max()
            if _over(face, dev[i], limit):
                bad[i] = (got[1], got[2], got[0])
            elif dev[i] > limit:
                report.within_tolerance.append(i)
    meshed, dev0, bad0 = shape, dev.copy(), dict(bad)
    hopeless: set[int] = set()  # knots made them far worse: no more knots
    for _ in range(rounds):
        todo = {i: b for i, b in bad.items() if i not in report.unresolved and i not in hopeless}
        if not todo:
            break
        faces = _faces(meshed)
        report.unresolved += [i for i in todo if _bspline(faces[i]) is None]
        todo = {i: b for i, b in todo.items() if i not in report.unresolved}
        if not todo:
            break
        if meshed is shape:  # the caller's surfaces stay as they are (the mesh is copied too)
            meshed = copied(shape, mesh=True)
            faces = _faces(meshed)
        inserted = 0
        knots_now = []
        for i, (uv, t, d) in todo.items():
            bs = _bspline(faces[i])
            added = 0 if bs is None else _insert_knots(bs, uv, t[d > limit])
            if added:
                cache.pop(i, None)
                knotted.add(i)
                knots_now.append(i)
                inserted += added
                if i not in report.refined:
                    report.refined.append(i)
            else:
                report.unresolved.append(i)
        if not inserted:
            if not report.refined:  # a fresh copy without triangulation: keep the plain mesh
                meshed = shape
            break
        # the faces with new knots and their neighbours are meshed again, the rest kept
        _clean_around(meshed, knots_now)
        _mesh(meshed, deflection, angular, parallel)
        report.rounds += 1
        faces = _faces(meshed)
        if not all(_has_triangulation(f) for f in faces):
            # BRepMesh failed on the refined copy: keep the plain mesh, say which faces
            meshed, dev, bad = shape, dev0, {}
            for i in knotted:  # measured on the copy's surfaces
                cache.pop(i, None)
            report.unresolved = sorted(bad0)
            report.refined = []
            break
        bad = {i: b for i, b in bad.items() if i in hopeless}
        for i, got in _measured(faces, todo, limit, cache).items():
            before = dev[i]
            dev[i] = 0.0 if got is None or not len(got[0]) else got[0].max()
            if got is not None and _over(faces[i], dev[i], limit):
                bad[i] = (got[1], got[2], got[0])
                if dev[i] > max(before, KNOT_GIVE_UP * limit):
                    hopeless.add(i)
    if hopeless and hopeless >= set(report.refined):
        # knots made every face they went into far worse (BRepMesh does not follow them):
        # the plain mesh, as before any was inserted, for the finer stage to start from
        for i in knotted:  # measured on the copy's surfaces
            cache.pop(i, None)
        meshed, dev, bad = shape, dev0.copy(), dict(bad0)
        report.refined = []
    over = sorted(set(report.unresolved) | set(bad))
    if over and finer_rounds > 0:
        meshed, report.finer, over = _mesh_faces_finer(
            meshed,
            {i: float(dev[i]) for i in over},
            deflection,
            angular,
            limit,
            parallel,
            finer_rounds,
            dev,
            cache,
            face_of,
        )
    report.unresolved = over
    if len(dev):
        report.worst_face = int(np.argmax(dev))
        report.max_deviation = float(dev.max())
    return meshed, report
