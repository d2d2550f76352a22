"""OCCT shapes: conversion, exploration, checks, booleans, measures and tessellation.

Every builder result is checked (``IsDone()``, ``HasErrors()`` where the binding has it,
``BRepCheck_Analyzer``); a failure raises :class:`OCCTFailure` naming the step.
"""

from __future__ import annotations

import functools
import io
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from numpy.typing import NDArray
from OCP.BinTools import BinTools, BinTools_FormatVersion
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_Copy,
    BRepBuilderAPI_MakeSolid,
    BRepBuilderAPI_Transform,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepOffset import BRepOffset_Skin
from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeOffsetShape
from OCP.BRepTools import BRepTools
from OCP.GeomAbs import GeomAbs_Arc, GeomAbs_Intersection
from OCP.gp import gp_Trsf, gp_Vec
from OCP.GProp import GProp_GProps
from OCP.IMeshTools import IMeshTools_Parameters
from OCP.ShapeAnalysis import ShapeAnalysis_ShapeTolerance
from OCP.ShapeFix import ShapeFix_Shape, ShapeFix_Solid
from OCP.TopAbs import TopAbs_COMPOUND, TopAbs_FACE, TopAbs_REVERSED, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Face, TopoDS_Shape
from OCP.TopTools import TopTools_ListOfShape

from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.merge import merge_close

__all__ = [
    "as_topods",
    "compound",
    "solids",
    "count",
    "open_shells",
    "faces_outside_solids",
    "is_valid",
    "check_valid",
    "check_done",
    "fuse",
    "offset_solid",
    "offset_solid_isolated",
    "start_fused_offsets",
    "fused_offsets_result",
    "volume",
    "face_area",
    "bounds",
    "translated",
    "copied",
    "is_compound",
    "face_triangulations",
    "stored_triangulations",
    "tessellate",
    "merge_close",
    "heal",
    "max_tolerance",
    "write_brep",
    "to_bytes",
    "from_bytes",
    "is_occt_error",
    "occt_errors",
]


# ------------------------------------------------------------------- checks
def is_valid(shape: TopoDS_Shape) -> bool:
    """BRepCheck validity (False for a null shape)."""
    return shape is not None and not shape.IsNull() and bool(BRepCheck_Analyzer(shape).IsValid())


def check_valid(shape: TopoDS_Shape, what: str) -> None:
    """Raise :class:`OCCTFailure` unless ``shape`` is non-null and BRepCheck-valid."""
    if shape is None or shape.IsNull():
        raise OCCTFailure(f"{what}: null shape")
    if not BRepCheck_Analyzer(shape).IsValid():
        raise OCCTFailure(f"{what}: BRepCheck_Analyzer reports an invalid shape")


def check_done(builder: object, what: str) -> None:
    """Raise :class:`OCCTFailure` unless the builder is done and reports no errors."""
    if not builder.IsDone():  # type: ignore[attr-defined]
        raise OCCTFailure(f"{what}: IsDone() is false")
    has_errors = getattr(builder, "HasErrors", None)
    if has_errors is not None and has_errors():
        raise OCCTFailure(f"{what}: HasErrors() is true")


# --------------------------------------------------------------- booleans
def fuse(
    objects: list[TopoDS_Shape],
    tools: list[TopoDS_Shape] | None = None,
    *,
    fuzzy: float = 0.0,
    parallel: bool = True,
    simplify: bool = False,
    check: bool = True,
) -> TopoDS_Shape:
    """Boolean union of ``objects`` with ``tools`` (the general fuse).

    With ``tools=None`` the first object is fused with the others. ``fuzzy`` is OCCT's
    fuzzy value (absolute length); ``simplify`` merges faces split only by the boolean;
    ``check`` runs BRepCheck on the result.

    Raises
    ------
    OCCTFailure
        The fuse is not done, has errors, or (with ``check``) gives an invalid shape.
    """
    if tools is None:
        objects, tools = objects[:1], objects[1:]
    args, tls = TopTools_ListOfShape(), TopTools_ListOfShape()
    for s in objects:
        args.Append(s)
    for s in tools:
        tls.Append(s)
    op = BRepAlgoAPI_Fuse()
    op.SetArguments(args)
    op.SetTools(tls)
    op.SetRunParallel(parallel)
    op.SetNonDestructive(True)
    if fuzzy > 0.0:
        op.SetFuzzyValue(fuzzy)
    op.Build()
    check_done(op, "fuse")
    if simplify:
        op.SimplifyResult()
    res = op.Shape()
    if check:
        check_valid(res, "fuse")
    return res


def united_solids(shapes: list[TopoDS_Shape]) -> list[TopoDS_Shape] | None:
    """The solids of the union of ``shapes`` (solids) where their boxes meet, by OCCT's fuse
    (faces of one domain merged): solids that touch or overlap become one, with their
    shared faces gone. None when no two boxes meet, or the fuse fails or gives a shape
    BRepCheck refuses (the caller unites their tessellations instead).

    Tessellated one by one, the faces two solids share are meshed twice, differently where
    they are curved, and the union of the meshes keeps slivers between the two (a golf
    club head and its face insert, made outside shared/data: a fill's cut had surfaces a
    float32 step apart along the insert's rim and was refused).
    """
    if len(shapes) < 2:
        return None
    boxes = np.array([bounds(s) for s in shapes])  # (n, 2, 3)
    tol = 1e-6 * float(np.abs(boxes).max(initial=1.0))
    lo, hi = boxes[:, 0] - tol, boxes[:, 1] + tol
    meet: NDArray[np.bool_] = np.asarray(
        (lo[:, None, :] <= hi[None, :, :]).all(axis=2)
        & (lo[None, :, :] <= hi[:, None, :]).all(axis=2)
    )
    np.fill_diagonal(meet, False)
    if not meet.any():
        return None
    try:
        with occt_errors("fuse of the solids"):
            out = solids(fuse(list(shapes), simplify=True))
    except OCCTFailure:
        return None
    if not out or len(out) > len(shapes) or not all(is_valid(s) for s in out):
        return None
    return out


def _offset_error(mk: Any) -> str:
    """The name of BRepOffset_MakeOffset's error code (``""`` when it has none)."""
    try:
        err = mk.MakeOffset().Error()
    except Exception:  # pragma: no cover - bindings without the accessor
        return ""
    name = str(getattr(err, "name", err))
    return "" if name.endswith("NoError") else name.replace("BRepOffset_", "")


def _as_one_solid(out: TopoDS_Shape, what: str) -> TopoDS_Shape:
    """The one valid solid of an offset result: as it is, else healed by ShapeFix_Shape,
    else made from its one closed shell (OCCT's offset can return the shell of the
    offset, or a solid with small tolerance faults)."""
    if out is None or out.IsNull():
        raise OCCTFailure(f"{what}: null shape")
    found = solids(out)
    if len(found) == 1 and is_valid(found[0]):
        return found[0]
    candidates = []
    fix = ShapeFix_Shape(out)
    fix.Perform()
    candidates.append(fix.Shape())
    if not found and count(out, TopAbs_SHELL) == 1:
        exp = TopExp_Explorer(out, TopAbs_SHELL)
        mk = BRepBuilderAPI_MakeSolid(TopoDS.Shell_s(exp.Current()))
        if mk.IsDone():
            sfix = ShapeFix_Solid(mk.Solid())
            sfix.Perform()
            candidates.append(sfix.Solid())
    for cand in candidates:
        got = solids(cand) if cand is not None and not cand.IsNull() else []
        if len(got) == 1 and is_valid(got[0]) and volume(got[0]) > 0.0:
            return got[0]
    if len(found) > 1:
        raise OCCTFailure(f"{what}: {len(found)} solids instead of 1")
    if not found:
        raise OCCTFailure(f"{what}: no solid (not healed by ShapeFix)")
    raise OCCTFailure(f"{what}: BRepCheck_Analyzer reports an invalid shape (not healed)")


#: The ways :func:`offset_solid` tries, in order: OCCT's offset with arc joins (the true
#: offset: a concave edge of the part becomes a cylinder of radius ``|distance|``), then
#: with intersection joins (where the arcs fail; the caller checks the wall thickness).
OFFSET_JOINS = (GeomAbs_Arc, GeomAbs_Intersection)


#: Factors of the depth :func:`offset_solid` tries when OCCT's offset fails at the depth
#: asked for (far inside the skin's wall tolerance of 2 %).
OFFSET_NUDGES = (1.0001, 0.9999, 1.001, 0.999)

#: :func:`offset_solid` removes the faces whose offset vanishes only when they are at most
#: 8 or this fraction of the solid's faces (small features: chamfers, fillets).
MAX_REMOVED_FRACTION = 0.1


def offset_solid(solid: TopoDS_Shape, distance: float, *, tol: float = 1e-6) -> TopoDS_Shape:
    """The solid offset by ``distance`` (negative: inward).

    Arc joins first; when OCCT's offset is done but not one valid solid, the faces whose offset
    vanishes (:func:`vanishing_faces`: e.g. a chamfer or fillet on a convex edge narrower
    than the offset reaches; OCCT's offset cannot drop a face) are removed
    (``BRepAlgoAPI_Defeaturing``, their neighbours extended: the offset is the same
    without them) and the defeatured solid is offset. Then, the part as it is: arc joins,
    then intersection joins (:data:`OFFSET_JOINS`); a result that is not one valid solid
    is healed (ShapeFix, a solid made of its shell) before it is refused. Last, the same
    at depths nudged by :data:`OFFSET_NUDGES` (OCCT fails at some depths and not at their
    neighbours).
    The caller checks that the result is the offset asked for (its wall thickness).

    Raises
    ------
    OCCTFailure
        No way gives one valid solid; the message names each way's failure (with OCCT's
        ``BRepOffset_Error`` code).
    """
    if count(solid, TopAbs_SHELL) > 1:
        # a solid with closed voids inside (a cored casting): OCCT's offset fails on it
        # (NotConnectedShell); its outer shell and each void offset as solids of their own
        return _offset_with_voids(solid, distance, tol)
    why: list[str] = []
    # the part as it is, arc joins: done and valid is the common case
    invalid = False
    try:
        mk = BRepOffsetAPI_MakeOffsetShape()
        with occt_errors("offset"):
            mk.PerformByJoin(
                solid, float(distance), tol, BRepOffset_Skin, False, False, GeomAbs_Arc
            )
            if mk.IsDone():
                out = mk.Shape()
                found = solids(out) if out is not None and not out.IsNull() else []
                if len(found) == 1 and is_valid(found[0]):
                    return found[0]
                invalid = True  # no solid, several, or an invalid one
    except OCCTFailure:
        pass
    if invalid:
        # done but not one valid solid: the symptom of faces whose offset vanishes (OCCT cannot drop
        # them); remove those that vanish (by 2 % of the depth), then also those whose
        # offset barely reaches the depth (OCCT fails on the sliver they leave)
        tried: list[int] = []
        most = int(max(8, MAX_REMOVED_FRACTION * count(solid, TopAbs_FACE)))
        try:
            sets = _vanishing(solid, distance, 8, (0.02, 1e-4), 20000, stop_after=most)
        except Exception as exc:  # OCCT raises Standard_Failure as RuntimeError & co
            why.append(f"finding the faces whose offset vanishes: {type(exc).__name__}: {exc}")
            sets = [[], []]
        if len(sets[0]) > most:
            # OCCT's offset cannot drop a face, so an offset of the part as it is keeps
            # these, each more than 2 % of the depth off the wall (the caller's tolerance
            # from 1 mm deep), and the caller's check refuses it: not tried (the spanner's
            # intersection joins took 30-60 s to give one 3.07 mm off for 3.1; the
            # 96-fillet block's arc joins one 25 % off)
            why.append(
                f"more than {most} faces' offsets vanish (by over 2 % of the depth): too many "
                "to remove, and OCCT's offset of the part as it is would keep them"
            )
            raise OCCTFailure("; ".join(why))
        too_many: list[str] = []  # one phrase for both sets (the message repeated itself)
        for k, vanish in enumerate(sets):
            if not vanish or len(vanish) in tried:  # (the same set again)
                continue
            tried.append(len(vanish))
            if len(vanish) > most:
                # not small features: a defeaturing of that many faces can run for
                # minutes (NIST CTC-02: 69 faces) and changes the part
                too_many.append(f"{len(vanish)}" + (" (with those barely reaching)" if k else ""))
                continue
            trimmed = _without_faces(solid, vanish)
            if trimmed is None:
                why.append(f"removing the {len(vanish)} face(s) whose offset vanishes failed")
                continue
            got = _offset_ways(trimmed, distance, tol, why, f", {len(vanish)} face(s) removed")
            if got is not None:
                return got
        if too_many:
            why.append(f"{' or '.join(too_many)} faces' offsets vanish: too many to remove")
    got = _offset_ways(solid, distance, tol, why, "")
    if got is not None:
        return got
    # OCCT's offset fails at some depths and not at their neighbours (the README's example
    # bracket: null shape at 0.999 and 1.0 mm, one valid solid at 0.9999 and 1.001 mm, where
    # offset faces meet exactly): the depth nudged, by far less than a wall's tolerance (the
    # caller projects the inner surface onto the exact depth and measures it)
    for factor in OFFSET_NUDGES:
        got = _offset_ways(solid, distance * factor, tol, [], "")
        if got is not None:
            return got
    nudges = ", ".join(f"{100 * (f - 1):+g} %" for f in OFFSET_NUDGES)
    why.append(f"the same with the depth changed by {nudges}")
    raise OCCTFailure("; ".join(why))


def _offset_with_voids(solid: TopoDS_Shape, distance: float, tol: float) -> TopoDS_Shape:
    """:func:`offset_solid` of a solid with closed voids inside: its outer shell as a solid
    offset by ``distance``, less each void (its shell reversed: a solid) offset by
    ``-distance`` (inward for the part is outward for its voids).

    Raises
    ------
    OCCTFailure
        A shell cannot be made a solid, an offset fails, or the cut is not one valid solid.
    """
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeSolid
    from OCP.BRepClass3d import BRepClass3d

    outer = BRepClass3d.OuterShell_s(TopoDS.Solid_s(solid))
    if outer.IsNull():
        raise OCCTFailure("offset of a solid with voids: no outer shell")
    voids = []
    exp = TopExp_Explorer(solid, TopAbs_SHELL)
    while exp.More():
        shell = TopoDS.Shell_s(exp.Current())
        exp.Next()
        if not shell.IsSame(outer):
            voids.append(shell)

    def made(shell: Any, what: str) -> TopoDS_Shape:
        with occt_errors(f"offset of a solid with voids: {what} as a solid"):
            mk = BRepBuilderAPI_MakeSolid(shell)
            if not mk.IsDone():
                raise OCCTFailure(f"offset of a solid with voids: {what}: not a solid")
            got = mk.Solid()
        if volume(got) < 0:  # a void's shell faces into the void
            got = TopoDS.Solid_s(got.Reversed())
        check_valid(got, f"offset of a solid with voids: {what}")
        return got

    out = offset_solid(made(outer, "the outer shell"), distance, tol=tol)
    for k, shell in enumerate(voids):
        grown = offset_solid(made(shell, f"void {k}"), -distance, tol=tol)
        what = f"offset of a solid with voids: void {k} cut from the outer offset"
        with occt_errors(what):
            cut = BRepAlgoAPI_Cut(out, grown)
            check_done(cut, what)
            out = _as_one_solid(cut.Shape(), what)
    return out


def _offset_ways(
    shape: TopoDS_Shape, distance: float, tol: float, why: list[str], note: str
) -> TopoDS_Shape | None:
    """:func:`offset_solid` of ``shape`` as it is: each join of :data:`OFFSET_JOINS`, and
    again with C0 faces split into C1 patches when OCCT asks for it; the one valid solid,
    or None (each failure appended to ``why``)."""
    divided = False
    ways = list(OFFSET_JOINS)
    while ways:
        join = ways.pop(0)
        what = f"offset by {distance:g} ({'arc' if join == GeomAbs_Arc else 'intersection'} joins"
        what += note + (", faces split to C1)" if divided else ")")
        err = ""
        try:
            mk = BRepOffsetAPI_MakeOffsetShape()
            with occt_errors(what):
                mk.PerformByJoin(shape, float(distance), tol, BRepOffset_Skin, False, False, join)
            err = _offset_error(mk)
            if not mk.IsDone():
                raise OCCTFailure(f"{what}: IsDone() is false" + (f" ({err})" if err else ""))
            with occt_errors(what):
                return _as_one_solid(mk.Shape(), what)
        except OCCTFailure as exc:
            why.append(str(exc))
        if err == "C0Geometry" and not divided:
            # OCCT offsets C1 surfaces only: split the C0 faces (B-splines with kinks) at
            # their kinks into C1 patches and start again
            split = _split_to_c1(shape)
            if split is not None:
                shape, divided, ways = split, True, list(OFFSET_JOINS)
    return None


def vanishing_faces(
    solid: TopoDS_Shape,
    distance: float,
    *,
    grid: int = 8,
    rtol: float = 0.02,
    max_evaluations: int = 20000,
) -> list[TopoDS_Face]:
    """The faces of ``solid`` whose offset by ``distance`` vanishes from the true offset.

    A face's offset (each point moved by ``distance`` along the face's outward normal)
    belongs to the true offset surface only where it is ``|distance|`` from the boundary;
    a face whose offset points are all nearer than that to some other face (by more than
    ``rtol * |distance|``) has no part in it: e.g. a 45 degree chamfer of width ``w`` on a
    convex edge vanishes from inward offsets deeper than ``w / (2 - sqrt 2)``, a convex
    fillet from those deeper than its radius. Each face is sampled on a ``grid`` x
    ``grid`` grid of its parameters (points inside the face) and at the centres of the
    triangles of a coarse triangulation; from the sample whose offset lies deepest, a
    pattern search in the parameters looks for a point whose offset is ``|distance|``
    deep (a face that survives in a narrow strip only). Distances are exact
    (``BRepExtrema_DistShapeShape`` to the faces whose bounding box is near enough to
    matter). After ``max_evaluations`` distances the faces left count as kept. Only
    analytic faces (planes, cylinders, cones, spheres, tori: chamfers and fillets) are
    tested; free-form faces count as kept.
    """
    return _vanishing(solid, distance, grid, (rtol,), max_evaluations)[0]


def _vanishing(
    solid: TopoDS_Shape,
    distance: float,
    grid: int,
    rtols: tuple[float, ...],
    max_evaluations: int,
    *,
    stop_after: int | None = None,
) -> list[list[TopoDS_Face]]:
    """:func:`vanishing_faces` for each of ``rtols`` (one search, to the strictest).

    ``stop_after``: stop once more than this many faces vanish by ``rtols[0]`` (the first
    list then holds ``stop_after + 1``; all that the caller needs to know is that there
    are more, and the search costs up to a minute on a part with many small fillets)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp_Face
    from OCP.BRepTopAdaptor import BRepTopAdaptor_FClass2d
    from OCP.GeomAbs import (
        GeomAbs_Cone,
        GeomAbs_Cylinder,
        GeomAbs_Plane,
        GeomAbs_Sphere,
        GeomAbs_Torus,
    )

    _ANALYTIC = (GeomAbs_Plane, GeomAbs_Cylinder, GeomAbs_Cone, GeomAbs_Sphere, GeomAbs_Torus)

    depth = abs(float(distance))
    if depth == 0.0:
        return [[] for _ in rtols]
    shape = copied(solid)
    faces = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        faces.append(TopoDS.Face_s(exp.Current()))
        exp.Next()
    box = bounds(shape)
    defl = max(0.25 * depth, 1e-3 * float(np.linalg.norm(box[1] - box[0])))
    mesher = BRepMesh_IncrementalMesh(shape, defl, False, 0.5, False)
    if not mesher.IsDone():
        raise OCCTFailure("BRepMesh_IncrementalMesh: IsDone() is false")
    near = _NearFaces(faces)
    limit = depth * (1.0 - min(rtols))
    out: list[tuple[int, float]] = []
    budget = [max_evaluations]
    for k, face in enumerate(faces):
        if BRepAdaptor_Surface(face).GetType() not in _ANALYTIC:
            continue  # chamfers and fillets are analytic; free-form faces are kept
        prop = BRepGProp_Face(face)
        inside = BRepTopAdaptor_FClass2d(face, 1e-9)
        deep = functools.partial(_offset_depth, prop, inside, near, distance, limit, budget)

        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        us = u0 + (np.arange(grid) + 0.5) * (u1 - u0) / grid
        vs = v0 + (np.arange(grid) + 0.5) * (v1 - v0) / grid
        samples = [(float(u), float(v), True) for u in us for v in vs]
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is not None and tri.HasUVNodes():
            for i in range(1, min(tri.NbTriangles(), 64) + 1):
                uv = [tri.UVNode(j) for j in tri.Triangle(i).Get()]
                u = sum(p.X() for p in uv) / 3.0
                v = sum(p.Y() for p in uv) / 3.0
                samples.append((u, v, False))
        best, at, seen = -1.0, (0.0, 0.0), 0
        for u, v, check in samples:
            d = deep(u, v, check)
            if d < 0.0:
                continue
            seen += 1
            if d > best:
                best, at = d, (u, v)
            if best >= limit:
                break
        if not seen or best >= limit:
            continue
        du, dv = 0.5 * (u1 - u0) / grid, 0.5 * (v1 - v0) / grid
        u, v = at
        for _ in range(40):  # pattern search for a point that survives
            moved = False
            for su, sv in ((du, 0.0), (-du, 0.0), (0.0, dv), (0.0, -dv)):
                d = deep(u + su, v + sv, True)
                if d > best:
                    best, u, v, moved = d, u + su, v + sv, True
                    break
            if best >= limit:
                break
            if not moved:
                du, dv = 0.5 * du, 0.5 * dv
        if best < limit and budget[0] > 0:
            out.append((k, best))
            first = depth * (1.0 - rtols[0])
            if stop_after is not None and sum(b < first for _, b in out) > stop_after:
                break
        if budget[0] <= 0:
            break
    original = []
    exp = TopExp_Explorer(solid, TopAbs_FACE)
    while exp.More():
        original.append(TopoDS.Face_s(exp.Current()))
        exp.Next()
    return [[original[k] for k, best in out if best < depth * (1.0 - r)] for r in rtols]


class _NearFaces:
    """Exact distances from points to a set of faces, measured only to the faces whose
    bounding box lies within a given reach (BRepExtrema_DistShapeShape per face)."""

    def __init__(self, faces: list[TopoDS_Face]) -> None:
        from OCP.BRepExtrema import BRepExtrema_DistShapeShape

        self.boxes = np.array([bounds(f).ravel() for f in faces]).reshape(-1, 6)
        self.tools = []
        for face in faces:
            tool = BRepExtrema_DistShapeShape()
            tool.LoadS1(face)
            self.tools.append(tool)

    def distance(self, q: Any, reach: float) -> float:
        """The distance from ``q`` (gp_Pnt) to the nearest face, or ``reach`` when no face
        is nearer than that; inf when BRepExtrema finds no distance."""
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex

        p = np.array([q.X(), q.Y(), q.Z()])
        gap = np.maximum(np.maximum(self.boxes[:, :3] - p, p - self.boxes[:, 3:]), 0.0)
        box_d = np.sqrt((gap * gap).sum(axis=1))
        best = reach
        vertex = BRepBuilderAPI_MakeVertex(q).Vertex()
        for i in np.argsort(box_d):
            if box_d[i] >= best:
                break
            tool = self.tools[i]
            tool.LoadS2(vertex)
            if not tool.Perform() or tool.NbSolution() == 0:
                return float("inf")
            best = min(best, float(tool.Value()))
        return best


def _offset_depth(
    prop: Any,
    inside: Any,
    near: _NearFaces,
    distance: float,
    limit: float,
    budget: list[int],
    u: float,
    v: float,
    check: bool,
) -> float:
    """How deep below the faces ``near`` the face's point (u, v) moved by ``distance``
    along its outward normal (``prop``: BRepGProp_Face) lies, up to ``limit``; -1 when
    (u, v) is not on the face (``inside``: BRepTopAdaptor_FClass2d, when ``check``) or the
    normal is undefined, inf when unknown or when ``budget[0]`` evaluations are spent."""
    from OCP.gp import gp_Pnt, gp_Pnt2d
    from OCP.TopAbs import TopAbs_IN

    if budget[0] <= 0:
        return float("inf")
    if check and inside.Perform(gp_Pnt2d(u, v)) != TopAbs_IN:
        return -1.0
    pnt, nrm = gp_Pnt(), gp_Vec()
    prop.Normal(u, v, pnt, nrm)
    if nrm.Magnitude() < 1e-12:
        return -1.0
    nrm.Normalize()
    budget[0] -= 1
    q = gp_Pnt(
        pnt.X() + distance * nrm.X(), pnt.Y() + distance * nrm.Y(), pnt.Z() + distance * nrm.Z()
    )
    return near.distance(q, limit)


def _without_faces(solid: TopoDS_Shape, faces: list[TopoDS_Face]) -> TopoDS_Shape | None:
    """``solid`` with ``faces`` removed and their neighbours extended to close the gap
    (``BRepAlgoAPI_Defeaturing``), as one valid solid not smaller than ``solid``, or
    None."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Defeaturing

    try:
        with occt_errors("removing faces"):
            op = BRepAlgoAPI_Defeaturing()
            op.SetShape(solid)
            op.SetRunParallel(False)
            for face in faces:
                op.AddFaceToRemove(face)
            op.Build()
            if not op.IsDone():
                return None
            got = solids(op.Shape())
    except OCCTFailure:
        return None
    if len(got) != 1 or not is_valid(got[0]):
        return None
    # faces whose offset vanishes lie on convex features (chamfers, fillets): removing
    # them adds material (the offset is then unchanged); a removal that takes material
    # away changed the part
    if volume(got[0]) < volume(solid) * (1.0 - 1e-9):
        return None
    return got[0]


def _split_to_c1(shape: TopoDS_Shape) -> TopoDS_Shape | None:
    """``shape`` with every face (and edge) that is only C0 split into C1 pieces
    (ShapeUpgrade_ShapeDivideContinuity), or None when nothing was split."""
    from OCP.GeomAbs import GeomAbs_C1
    from OCP.ShapeUpgrade import ShapeUpgrade_ShapeDivideContinuity

    div = ShapeUpgrade_ShapeDivideContinuity(shape)
    div.SetBoundaryCriterion(GeomAbs_C1)
    div.SetPCurveCriterion(GeomAbs_C1)
    div.SetSurfaceCriterion(GeomAbs_C1)
    div.SetTolerance(1e-4)
    with occt_errors("splitting C0 faces"):
        if not div.Perform():
            return None
        out = div.Result()
    return None if out is None or out.IsNull() else out


def _offsets_bytes(brep: bytes, distances: tuple[float, ...]) -> list[bytes]:
    solid = from_bytes(brep)
    return [to_bytes(offset_solid(solid, d)) for d in distances]


def offset_solid_isolated(
    solid: TopoDS_Shape, distances: tuple[float, ...], *, timeout: float = 120.0
) -> list[TopoDS_Shape]:
    """:func:`offset_solid` for each distance, in a child process.

    OCCT's offset algorithm can crash the process (a segmentation fault) or run for a long
    time on some real parts; in a child, a crash or a timeout is an :class:`OCCTFailure`
    that the caller can fall back from, and the user's process survives.
    """
    from lattice_cad.core.errors import ExternalCrash
    from lattice_cad.core.isolate import run_isolated

    try:
        data = run_isolated(
            _offsets_bytes,
            to_bytes(solid),
            tuple(float(d) for d in distances),
            timeout=timeout,
            what="OCCT's offset",
        )
    except ExternalCrash as exc:
        raise OCCTFailure(str(exc)) from None
    return [from_bytes(b) for b in data]


def self_interfering(shapes: list[TopoDS_Shape]) -> list[int]:
    """The indices of the solids in ``shapes`` whose faces intersect one another, by OCCT's
    ``BRepAlgoAPI_Check`` (self-interference only: ``BOPAlgo_SelfIntersect``). BRepCheck
    does not look for such crossings: a sweep folded over its path passes it."""
    from OCP.BOPAlgo import BOPAlgo_CheckStatus
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Check

    out = []
    for k, shape in enumerate(shapes):
        with occt_errors(f"self-interference check of solid {k}"):
            check = BRepAlgoAPI_Check(shape, False, True)
            if not check.IsValid() and any(
                r.GetCheckStatus() == BOPAlgo_CheckStatus.BOPAlgo_SelfIntersect
                for r in check.Result()
            ):
                out.append(k)
    return out


def _self_interfering_bytes(breps: list[bytes]) -> list[int]:
    return self_interfering([from_bytes(b) for b in breps])


def self_interfering_isolated(shapes: list[TopoDS_Shape], *, timeout: float) -> list[int] | None:
    """:func:`self_interfering` in a child process, or None when it fails, crashes or takes
    longer than ``timeout`` seconds (the check is quick on a fold, 0.5-1.8 s on the parts
    measured, but it ran for minutes on NIST CTC-02 and 28 s on an M6 screw's thread)."""
    from lattice_cad.core.errors import ExternalCrash
    from lattice_cad.core.isolate import run_isolated

    try:
        return run_isolated(
            _self_interfering_bytes,
            [to_bytes(s) for s in shapes],
            timeout=timeout,
            what="OCCT's self-interference check",
        )
    except (ExternalCrash, OCCTFailure):
        return None


def _fused_offsets(
    breps: list[bytes], distances: tuple[float, ...]
) -> list[tuple[TopoDS_Shape, list[TopoDS_Shape]]]:
    """In a child: the solids fused where they touch (as they are when there is one or
    the fuse fails), and each one's offsets (see :func:`start_fused_offsets`)."""
    solids_in = [from_bytes(b) for b in breps]
    fused = solids_in
    if len(solids_in) > 1:
        try:
            fused = solids(fuse(solids_in, simplify=True)) or solids_in
        except Exception:  # OCCT raises Standard_Failure as RuntimeError & co; OCCTFailure
            fused = solids_in
    return [(s, [offset_solid(s, d) for d in distances]) for s in fused]


def _fused_offset_meshes(
    breps: list[bytes],
    distances: tuple[float, ...],
    deflection: float,
    angular: float,
    merge_tol: float,
) -> list[tuple[list[float], list[tuple[NDArray[np.float64], NDArray[np.int64]]] | None]]:
    """In a child: :func:`_fused_offsets`, then the volumes of each fused solid and its
    offsets, and the offsets' meshes (:func:`tessellate`, :func:`merge_close`); the meshes
    are None when an offset is not inside its solid by volume (the caller says so). The
    fused solid is not meshed: the caller has the part's own mesh."""
    out: list[Any] = []
    for solid, offsets in _fused_offsets(breps, distances):
        vols = [volume(s) for s in (solid, *offsets)]
        if not all(0.0 < v < vols[0] for v in vols[1:]):
            out.append((vols, None))
            continue
        meshes = []
        for shape in offsets:
            # (no triangle edge shorter than the chord error: see face_triangulations)
            v, f = tessellate(shape, deflection, angular, min_size=deflection)
            v, f, _ = merge_close(v, f, merge_tol)
            meshes.append((v, f))
        out.append((vols, meshes))
    return out


def start_fused_offsets(
    solid_list: Any,
    distances: tuple[float, ...],
    worker: Any,
    *,
    deflection: float,
    angular: float,
    merge_tol: float,
) -> None:
    """Start, in ``worker`` (a :class:`lattice_cad.core.isolate.IsolatedWorker`), the
    offsets of the solids fused where they touch (an assembly's offset then leaves no
    partition wall of twice the thickness between its solids), measured and meshed there
    (``tessellate(shape, deflection, angular)``, ``merge_close(..., merge_tol)``): the
    caller goes on with its own work meanwhile (the meshing too runs on the child's core)
    and collects them with :func:`fused_offsets_result`."""
    worker.submit(
        _fused_offset_meshes,
        [to_bytes(s) for s in solid_list],
        tuple(float(d) for d in distances),
        float(deflection),
        float(angular),
        float(merge_tol),
    )


def fused_offsets_result(
    worker: Any, *, timeout: float = 120.0, budget: float | None = None
) -> list[tuple[list[float], list[tuple[NDArray[np.float64], NDArray[np.int64]]] | None]]:
    """Per fused solid of :func:`start_fused_offsets`: the volumes of the solid and of its
    offsets, and the offsets' meshes (vertices (V, 3) float64, faces (F, 3) int64; None
    when an offset's volume is not between 0 and its solid's). ``budget``: the seconds
    the offsets were given in all (named when they time out; ``timeout`` is what is left).

    Raises
    ------
    OCCTFailure
        An offset failed, or the child crashed or timed out.
    """
    from lattice_cad.core.errors import ExternalCrash, ExternalTimeout

    try:
        return worker.result(timeout=timeout, what="OCCT's offset")
    except ExternalTimeout as exc:
        if budget is None:
            raise OCCTFailure(str(exc)) from None
        raise OCCTFailure(
            f"OCCT's offset did not finish within {budget:g} s of its start"
        ) from None
    except ExternalCrash as exc:
        raise OCCTFailure(str(exc)) from None


# ---------------------------------------------------------------- measures
def volume(shape: TopoDS_Shape, *, eps: float | None = None) -> float:
    """Volume of ``shape`` (mm^3) by GProp.

    With ``eps`` GProp integrates adaptively to that relative accuracy (the default Gauss
    rule is off by about 1e-5 on near-tangent sphere/strut patches).
    """
    props = GProp_GProps()
    if eps is None:
        BRepGProp.VolumeProperties_s(shape, props)
    else:
        BRepGProp.VolumeProperties_s(shape, props, eps, False)
    return float(props.Mass())


def face_area(face: TopoDS_Shape) -> float:
    """Area of a face (mm^2)."""
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())


def translated(shape: TopoDS_Shape, offset: Any) -> TopoDS_Shape:
    """A copy of ``shape`` moved by ``offset`` (3,)."""
    trsf = gp_Trsf()
    trsf.SetTranslation(gp_Vec(float(offset[0]), float(offset[1]), float(offset[2])))
    mk = BRepBuilderAPI_Transform(shape, trsf, True)
    check_done(mk, "translate")
    return mk.Shape()


def copied(shape: TopoDS_Shape, *, mesh: bool = False) -> TopoDS_Shape:
    """A deep copy of ``shape`` (geometry too; its triangulation only with ``mesh``).

    Meshing the copy leaves the original's triangulation (and the user's shape) as it was.
    """
    mk = BRepBuilderAPI_Copy(shape, True, bool(mesh))
    check_done(mk, "copy")
    out = mk.Shape()
    if out is None or out.IsNull():
        raise OCCTFailure("copy: null shape")
    return out


def is_compound(shape: TopoDS_Shape) -> bool:
    """True when ``shape`` is a compound (several shapes) rather than one solid."""
    return bool(shape.ShapeType() == TopAbs_COMPOUND)


def count(shape: TopoDS_Shape, kind: Any, avoid: Any = None) -> int:
    """Number of sub-shapes of type ``kind`` (TopAbs_*), not inside ``avoid`` if given."""
    exp = TopExp_Explorer(shape, kind) if avoid is None else TopExp_Explorer(shape, kind, avoid)
    n = 0
    while exp.More():
        n += 1
        exp.Next()
    return n


def edge_nodes(shape: TopoDS_Shape, size: float) -> int:
    """How many nodes a mesher that follows the edges of ``shape``'s faces must place on
    them at element size ``size`` (mm): each vertex, and the points that divide each
    edge into pieces no longer than ``size`` (gmsh meshing a B-rep does so).

    Where this is far more than a surface meshed at ``size`` has nodes, the faces'
    edges crowd the mesh (a gear whose flanks are hundreds of narrow faces, a thread).
    """
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GCPnts import GCPnts_AbscissaPoint
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedMapOfShape

    edges, vertices = TopTools_IndexedMapOfShape(), TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, edges)
    TopExp.MapShapes_s(shape, TopAbs_VERTEX, vertices)
    n = vertices.Size()
    for i in range(1, edges.Size() + 1):
        edge = TopoDS.Edge_s(edges.FindKey(i))
        if BRep_Tool.Degenerated_s(edge):
            continue
        with occt_errors(f"length of edge {i - 1}"):
            length = GCPnts_AbscissaPoint.Length_s(BRepAdaptor_Curve(edge))
        n += max(0, int(np.ceil(length / size)) - 1)
    return n


def surface_kinds(shape: TopoDS_Shape) -> list[str]:
    """The surface type of each face of ``shape`` (TopExp order): ``"Plane"``,
    ``"Cylinder"``, ``"BSplineSurface"``, ... (``GeomAbs_SurfaceType`` without its prefix)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    out = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        kind = BRepAdaptor_Surface(TopoDS.Face_s(exp.Current())).GetType()
        out.append(str(getattr(kind, "name", kind)).replace("GeomAbs_", ""))
        exp.Next()
    return out


def triangle_growth(shape: TopoDS_Shape) -> NDArray[np.float64]:
    """(n_faces,) float64, for each face of ``shape`` (TopExp order), the power of ``1 / d``
    its triangle count grows at most as when the chord error ``d`` shrinks: 0.5 for planes
    (their triangles follow the nodes on their edges, whose count on a curved edge grows
    as ``1 / sqrt(d)``), cylinders and cones (curved one way), 1 for the rest (BRepMesh
    meshes an extrusion as any surface: the spanner's B-spline extrusion grew as 1 / d^0.75,
    716 -> 10,510 triangles for a 37 x finer chord error). Measured by
    ``benchmarks/bench_triangle_growth.py``."""
    one_way = ("Plane", "Cylinder", "Cone")
    return np.asarray([0.5 if k in one_way else 1.0 for k in surface_kinds(shape)])


# ------------------------------------------------------------ tessellation
def mesh_parameters(
    deflection: float,
    angular: float,
    parallel: bool,
    *,
    force_face: bool = False,
    min_size: float = 0.0,
) -> IMeshTools_Parameters:
    """BRepMesh's parameters: absolute chord error ``deflection``, ``angular``, in parallel
    or not (as ``BRepMesh_IncrementalMesh(shape, deflection, False, angular, parallel)``
    sets them); ``force_face``: ``ForceFaceDeflection``; ``min_size`` > 0: ``MinSize``
    (see :func:`face_triangulations`)."""
    params = IMeshTools_Parameters()
    params.Deflection = float(deflection)
    params.Angle = float(angular)
    params.Relative = False
    params.InParallel = bool(parallel)
    params.ForceFaceDeflection = bool(force_face)
    if min_size > 0:
        params.MinSize = float(min_size)
    return params


def face_triangulations(
    shape: TopoDS_Shape,
    deflection: float,
    angular: float = 0.25,
    *,
    parallel: bool = True,
    on_meshed: Any = None,
    tiny: float = 0.0,
    min_size: float = 0.0,
) -> Iterator[tuple[TopoDS_Face, NDArray[np.float64], NDArray[np.int64]]]:
    """Triangulate ``shape`` with BRepMesh and yield each face's triangulation.

    ``min_size`` > 0: BRepMesh's ``MinSize``, no triangle edge shorter (its default is a
    tenth of ``deflection``). On some faces BRepMesh's Delaunay refinement otherwise adds
    nodes for minutes: OpenCascade's offset of a mould insert's swept cooling channel
    (one of its faces, meshed alone, still running after 3 minutes) meshed in 3.6 s at
    ``min_size`` = ``deflection`` and had not finished after 10 minutes without it.

    ``on_meshed``, if given, is called (without arguments) once BRepMesh is done, before
    the first face is read (for profiling). A face BRepMesh leaves without triangles whose
    bounding box is smaller than ``tiny`` (e.g. a speck of a hub's sphere, 1e-5 of its
    radius across, where three stumps nearly meet on it) is yielded as a fan through the
    nodes BRepMesh put on its outer boundary's edges (read from the neighbouring faces'
    triangulations, so the fan shares them): every point of the face is within ``tiny`` of
    it (the callers' checks - closed, manifold, circles - still decide).

    Yields
    ------
    face : TopoDS_Face
    vertices : (n, 3) float64
        The face's nodes in global coordinates. Nodes on an edge shared by two faces are
        computed once by BRepMesh, so both faces carry bit-identical copies.
    faces : (t, 3) int64
        Triangles (0-based into ``vertices``), oriented by the face orientation (outward for
        a valid solid).

    Raises
    ------
    OCCTFailure
        BRepMesh is not done, or leaves a face without triangulation.
    """
    if min_size > 0:
        params = mesh_parameters(deflection, angular, parallel, min_size=min_size)
        mesher = BRepMesh_IncrementalMesh(shape, params)
    else:
        mesher = BRepMesh_IncrementalMesh(shape, float(deflection), False, float(angular), parallel)
    if not mesher.IsDone():
        raise OCCTFailure("BRepMesh_IncrementalMesh: IsDone() is false")
    if on_meshed is not None:
        on_meshed()
    yield from stored_triangulations(shape, tiny=tiny)


def stored_triangulations(
    shape: TopoDS_Shape, *, tiny: float = 0.0
) -> Iterator[tuple[TopoDS_Face, NDArray[np.float64], NDArray[np.int64]]]:
    """Each face's triangulation as :func:`face_triangulations` yields it, from a shape
    already meshed (``tiny``: as there).

    Raises
    ------
    OCCTFailure
        A face has no triangulation.
    """
    from lattice_cad.occ_impl.triangulation import triangulation_arrays

    exp = TopExp_Explorer(shape, TopAbs_FACE)
    edge_faces: dict[str, Any] = {}
    found = []
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        found.append((face, loc, None if tri is None or tri.NbTriangles() == 0 else tri))
    meshed = [tri for _face, _loc, tri in found if tri is not None]
    # all nodes and triangles in one read (the same values), else node by node
    read: list[Any] = triangulation_arrays(meshed) or [None] * len(meshed)
    bulk = iter(read)
    for i, (face, loc, tri) in enumerate(found):
        if tri is None:
            fan = _speck_fan(shape, face, tiny, edge_faces) if tiny > 0.0 else None
            if fan is None:
                raise OCCTFailure(f"BRepMesh left face {i} (TopExp order) without triangulation")
            yield face, fan[0], fan[1]
            continue
        got = next(bulk)
        if got is not None:
            pts, t = got[0], got[2]
        else:
            nn = tri.NbNodes()
            node = tri.Node
            pts = np.array(
                [(p.X(), p.Y(), p.Z()) for p in (node(i) for i in range(1, nn + 1))],
                dtype=np.float64,
            ).reshape(nn, 3)
            tri_at = tri.Triangle
            t = np.array(
                [tri_at(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64
            ).reshape(-1, 3)
        if not loc.IsIdentity():
            m = loc.Transformation()
            rot = np.array([[m.Value(r, c) for c in (1, 2, 3)] for r in (1, 2, 3)])
            pts = pts @ rot.T + np.array([m.Value(r, 4) for r in (1, 2, 3)])
        t -= 1
        if face.Orientation() == TopAbs_REVERSED:
            t = t[:, ::-1]
        yield face, pts, t


def _speck_fan(
    shape: TopoDS_Shape, face: TopoDS_Face, tiny: float, edge_faces: dict[str, Any]
) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """Fan triangles over the outer boundary of a face smaller than ``tiny``, through the
    nodes BRepMesh put on its edges (read from each edge's neighbour face), oriented as the
    face (outward); None if the face is larger, or an edge has no discretised neighbour."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools_WireExplorer
    from OCP.gp import gp_Pnt as _P
    from OCP.gp import gp_Vec as _V
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    box = Bnd_Box()
    BRepBndLib.Add_s(face, box)
    if box.IsVoid() or box.SquareExtent() ** 0.5 >= tiny:
        return None
    if "map" not in edge_faces:
        m = TopTools_IndexedDataMapOfShapeListOfShape()
        TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, m)
        edge_faces["map"] = m
    emap = edge_faces["map"]
    pts: list[NDArray[np.float64]] = []
    wexp = BRepTools_WireExplorer(BRepTools.OuterWire_s(face), face)
    while wexp.More():
        edge = wexp.Current()
        wexp.Next()
        chain = None
        for other in emap.FindFromKey(edge):
            f2 = TopoDS.Face_s(other)
            if f2.IsSame(face):
                continue
            loc = TopLoc_Location()
            tri = BRep_Tool.Triangulation_s(f2, loc)
            if tri is None:
                continue
            poly = BRep_Tool.PolygonOnTriangulation_s(edge, tri, loc)
            if poly is None:
                continue
            idx = [poly.Node(i) for i in range(1, poly.NbNodes() + 1)]
            q = np.array([(tri.Node(i).X(), tri.Node(i).Y(), tri.Node(i).Z()) for i in idx])
            if not loc.IsIdentity():
                tr = loc.Transformation()
                rot = np.array([[tr.Value(r, c) for c in (1, 2, 3)] for r in (1, 2, 3)])
                q = q @ rot.T + np.array([tr.Value(r, 4) for r in (1, 2, 3)])
            chain = q
            break
        if chain is None:
            return None
        if edge.Orientation() == TopAbs_REVERSED:
            chain = chain[::-1]
        pts.append(chain[:-1])
    if not pts:
        return None
    v = np.vstack(pts)
    if len(v) < 3:
        return None
    t = np.column_stack([np.zeros(len(v) - 2, np.int64), np.arange(1, len(v) - 1),
                         np.arange(2, len(v))])  # fmt: skip
    # orient by the surface normal at the middle of the face's parameter box
    umin, umax, vmin, vmax = BRepTools.UVBounds_s(face)
    p0, du, dv = _P(), _V(), _V()
    BRepAdaptor_Surface(face).D1(0.5 * (umin + umax), 0.5 * (vmin + vmax), p0, du, dv)
    n = np.array([du.Y() * dv.Z() - du.Z() * dv.Y(), du.Z() * dv.X() - du.X() * dv.Z(),
                  du.X() * dv.Y() - du.Y() * dv.X()])  # fmt: skip
    if face.Orientation() == TopAbs_REVERSED:
        n = -n
    area = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]).sum(axis=0)
    if not np.linalg.norm(area) > 0.0:
        return None
    if float(area @ n) < 0.0:
        t = t[:, ::-1]
    return v, t


def tessellate(
    shape: TopoDS_Shape,
    deflection: float,
    angular: float = 0.25,
    *,
    face_ids: bool = False,
    control: float = 0.0,
    clean: bool = True,
    patches_of: NDArray[np.int64] | None = None,
    min_size: float = 0.0,
) -> Any:
    """Triangulate the whole of ``shape`` at once, faces sharing their edge nodes.

    Triangulations stored in the shape (STEP AP242 files can carry their own) are dropped
    first, so every face is meshed by the same BRepMesh run; with ``clean`` False, the
    caller knows the stored one was made by this function with the same ``deflection``
    and ``angular``, and BRepMesh keeps it (no second meshing).

    With ``control`` > 0, every face's triangulation is checked against its exact surface,
    and B-spline faces deviating by more than ``control * deflection`` are refined
    (:func:`lattice_cad.occ_impl.chord.mesh_checked`: BRepMesh does not always honour the
    chord error); a :class:`~lattice_cad.occ_impl.chord.ChordReport` is then returned last.
    ``patches_of`` (F,) int64: when the faces are patches of larger ones
    (:func:`~lattice_cad.occ_impl.chord.split_dense_faces`), the face each is part of (the
    patches of one face are refined together).
    ``min_size`` > 0 (without ``control``): no triangle edge shorter
    (:func:`face_triangulations`).

    Returns
    -------
    vertices : (V, 3) float64
        Each distinct node once (the copies on shared edges are merged by exact equality).
    faces : (F, 3) int64
        Triangles, outward for a valid solid.
    face_of : (F,) int64
        Only with ``face_ids``: the index of the B-rep face (in TopExp order) of each
        triangle.
    report : ChordReport
        Only with ``control``.
    """
    verts: list[NDArray[np.float64]] = []
    tris: list[NDArray[np.int64]] = []
    owner: list[NDArray[np.int64]] = []
    base = 0
    if control > 0:
        from lattice_cad.occ_impl.chord import mesh_checked

        meshed, report = mesh_checked(
            shape, deflection, angular, factor=control, clean=clean, face_of=patches_of
        )
        faces = stored_triangulations(meshed)
    else:
        if clean:
            BRepTools.Clean_s(shape)
        faces = face_triangulations(shape, deflection, angular, min_size=min_size)
    for i, (_face, v, t) in enumerate(faces):
        verts.append(v)
        tris.append(t + base)
        owner.append(np.full(len(t), i, dtype=np.int64))
        base += len(v)
    if not verts:
        out: tuple[Any, ...] = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
        ids = np.zeros(0, dtype=np.int64)
    else:
        f = np.vstack(tris)
        uniq, inverse = np.unique(np.vstack(verts), axis=0, return_inverse=True)
        out, ids = (uniq, inverse.reshape(-1)[f]), np.concatenate(owner)
    if face_ids:
        out = (*out, ids)
    return (*out, report) if control > 0 else out


def heal(shape: TopoDS_Shape) -> TopoDS_Shape:
    """``shape`` after ShapeFix_Shape (wires, edges, tolerances); the input if nothing helps."""
    fix = ShapeFix_Shape(shape)
    fix.Perform()
    out = fix.Shape()
    return shape if out is None or out.IsNull() else out


def max_tolerance(shape: TopoDS_Shape) -> float:
    """The largest vertex/edge/face tolerance of ``shape`` (mm)."""
    return float(ShapeAnalysis_ShapeTolerance().Tolerance(shape, 1))


# ------------------------------------------------------------------ errors
def is_occt_error(exc: BaseException) -> bool:
    """True for an exception raised inside OCCT (``Standard_Failure`` and its kin).

    OCP maps every OCCT exception class (``Standard_OutOfRange``,
    ``StdFail_NotDone``, ``Standard_ConstructionError``, ...) to its own Python class
    deriving from ``Exception`` directly, not from a common base: they are recognised by
    their module.
    """
    return type(exc).__module__.split(".")[0] == "OCP"


@contextmanager
def occt_errors(what: str) -> Iterator[None]:
    """Turn an exception raised inside OCCT into :class:`OCCTFailure` naming ``what``.

    ``with occt_errors("cannot write x.step: STEP transfer"): ...`` gives
    ``OCCTFailure("cannot write x.step: STEP transfer: OCCT raised Standard_OutOfRange
    (NCollection_IndexedMap::FindKey)")``; our own errors pass through unchanged.
    """
    try:
        yield
    except OCCTFailure:
        raise
    except Exception as exc:
        if not is_occt_error(exc):
            raise
        detail = " ".join(str(exc).split())
        raise OCCTFailure(
            f"{what}: OCCT raised {type(exc).__name__}" + (f" ({detail})" if detail else "")
        ) from exc


# --------------------------------------------------------------------- I/O
#: Binary BREP format of :func:`to_bytes`. Version 4 (OCCT 7.6+, the default) stores
#: back-references as stream positions that the reader seeks to; OCP's Python stream
#: wrapper loses track of the position on such seeks (CadQuery/OCP issue 192), so some
#: shapes written by version 4 cannot be read back from bytes: ``Standard_OutOfRange:
#: NCollection_IndexedMap::FindKey`` (a degree-6 BCC hub of the GE bracket, with its
#: triangulation). Version 3 is read strictly sequentially.
_BREP_VERSION = BinTools_FormatVersion.BinTools_FormatVersion_VERSION_3


def to_bytes(shape: TopoDS_Shape) -> bytes:
    """``shape`` as binary BREP (for passing shapes between processes).

    Triangulations are left out (a quarter of the size; every user meshes again), and
    the format is one that reads back from bytes (see ``_BREP_VERSION``).
    """
    buf = io.BytesIO()
    with occt_errors("writing a shape as binary BREP"):
        BinTools.Write_s(shape, buf, False, False, _BREP_VERSION)
    return buf.getvalue()


def from_bytes(data: bytes) -> TopoDS_Shape:
    """A shape back from :func:`to_bytes`.

    Raises
    ------
    OCCTFailure
        The bytes do not hold a shape OCCT can read.
    """
    shape = TopoDS_Shape()
    with occt_errors("reading a shape back from binary BREP"):
        BinTools.Read_s(shape, io.BytesIO(data))
    if shape.IsNull():
        raise OCCTFailure("cannot read a solid back from binary BREP")
    return shape


# ------------------------------------------------------------- conversion
def as_topods(obj: Any) -> TopoDS_Shape | None:
    """The OCCT shape of a cadquery Workplane/Shape, a build123d shape, or a TopoDS_Shape."""
    if isinstance(obj, TopoDS_Shape):
        return obj
    vals = getattr(obj, "vals", None)
    if callable(vals) and type(obj).__name__ == "Workplane":  # cadquery.Workplane
        shapes = [
            v.wrapped for v in vals() if isinstance(getattr(v, "wrapped", None), TopoDS_Shape)
        ]
        if not shapes:
            return None
        return shapes[0] if len(shapes) == 1 else compound(shapes)
    wrapped = getattr(obj, "wrapped", None)  # cadquery.Shape, build123d Shape/Part
    if isinstance(wrapped, TopoDS_Shape):
        return wrapped
    return None


def compound(shapes: list[TopoDS_Shape]) -> TopoDS_Compound:
    """A compound of ``shapes``."""
    comp = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(comp)
    for s in shapes:
        builder.Add(comp, s)
    return comp


def solids(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    """The solids of ``shape``."""
    out = []
    exp = TopExp_Explorer(shape, TopAbs_SOLID)
    while exp.More():
        out.append(TopoDS.Solid_s(exp.Current()))
        exp.Next()
    return out


def open_shells(shape: TopoDS_Shape) -> int:
    """Number of shells of ``shape`` that are not part of a solid."""
    return count(shape, TopAbs_SHELL, TopAbs_SOLID)


def shell_count(shape: TopoDS_Shape) -> int:
    """Number of shells of ``shape`` (a solid with closed cavities has one more for each)."""
    return count(shape, TopAbs_SHELL)


def faces_outside_solids(shape: TopoDS_Shape) -> int:
    """Number of faces of ``shape`` that are not part of a solid."""
    return count(shape, TopAbs_FACE, TopAbs_SOLID)


def solids_from_surfaces(
    shape: TopoDS_Shape, *, tolerance: float | None = None
) -> tuple[list[TopoDS_Shape], list[tuple[int, NDArray[np.float64]]]]:
    """Solids made of the faces of ``shape`` that lie in no solid (a surface model: a
    STEP ``SHELL_BASED_SURFACE_MODEL`` holding a closed shell, or loose faces that meet).

    The faces are sewn (``BRepBuilderAPI_Sewing``, at ``tolerance``: default the largest
    tolerance of ``shape``, at least 1e-6 mm); each closed shell of the result becomes a
    solid (``BRepBuilderAPI_MakeSolid``, oriented outward by ``ShapeFix_Solid``) when
    BRepCheck accepts it and its volume is positive.

    Returns
    -------
    solids : list of TopoDS_Solid
    open_faces : list of (int, (2, 3) float64)
        The faces (1-based, in the order ``TopExp_Explorer`` visits the faces of ``shape``)
        in no solid made: each with the end points of one of its free edges after sewing,
        or its bounding box when it has none (a closed shell that gave no valid solid).
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    in_solids = _shape_map(solids(shape), TopAbs_FACE)
    loose = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    k = 0
    while exp.More():
        k += 1
        if not in_solids.Contains(exp.Current()):
            loose.append((k, TopoDS.Face_s(exp.Current())))
        exp.Next()
    if not loose:
        return [], []
    tol = max(1e-6, max_tolerance(shape)) if tolerance is None else float(tolerance)
    with occt_errors("sewing the faces into shells"):
        sew = BRepBuilderAPI_Sewing(tol)
        for _, face in loose:
            sew.Add(face)
        sew.Perform()
        sewn = sew.SewedShape()
    if sewn is None or sewn.IsNull():
        return [], [(k, bounds(face)) for k, face in loose]
    made: list[TopoDS_Shape] = []
    shells: list[Any] = []  # each solid's shell as sewn, and its signed volume so
    exp = TopExp_Explorer(sewn, TopAbs_SHELL)
    while exp.More():
        shell = TopoDS.Shell_s(exp.Current())
        exp.Next()
        if not BRep_Tool.IsClosed_s(shell):
            continue
        mk = BRepBuilderAPI_MakeSolid(shell)
        if not mk.IsDone():
            continue
        signed = volume(mk.Solid())
        fix = ShapeFix_Solid(mk.Solid())
        fix.Perform()
        got = solids(fix.Solid())
        if len(got) == 1 and is_valid(got[0]) and volume(got[0]) > 0.0:
            made.append(got[0])
            shells.append((shell, signed))
    made = _with_cavities(made, shells)
    in_made = _shape_map(made, TopAbs_FACE)
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(sewn, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    left: list[tuple[int, NDArray[np.float64]]] = []
    for k, face in loose:
        new = sew.ModifiedSubShape(face) if sew.IsModifiedSubShape(face) else face
        if in_made.Contains(new):
            continue
        where = bounds(new)
        e = TopExp_Explorer(new, TopAbs_EDGE)
        while e.More():
            edge = TopoDS.Edge_s(e.Current())
            e.Next()
            if edge_faces.Contains(edge) and edge_faces.FindFromKey(edge).Size() == 1:
                a = BRep_Tool.Pnt_s(TopExp.FirstVertex_s(edge))
                b = BRep_Tool.Pnt_s(TopExp.LastVertex_s(edge))
                where = np.array([[a.X(), a.Y(), a.Z()], [b.X(), b.Y(), b.Z()]])
                break
        left.append((k, where))
    return made, left


def _with_cavities(made: list[TopoDS_Shape], shells: list[Any]) -> list[TopoDS_Shape]:
    """The solids :func:`solids_from_surfaces` made of closed shells (``made``, each
    oriented outward; ``shells``: each one's shell as sewn and the signed volume it
    encloses so), with every shell that faced inward and lies inside an odd number of the
    others made a cavity of the smallest of those (a hollow vessel written as a surface
    model, its outer wall facing out and its cavity's wall facing in, as a solid with a
    void is; each made a solid on its own, their union was the full vessel). A cavity's
    solid that BRepCheck refuses leaves the two solids as they were."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_IN, TopAbs_VERTEX

    inward = [k for k, (_, signed) in enumerate(shells) if signed < 0.0]
    if not inward or len(made) < 2:
        return made
    vols = [volume(s) for s in made]
    holder = [-1] * len(made)
    for k in inward:
        exp = TopExp_Explorer(made[k], TopAbs_VERTEX)
        point = BRep_Tool.Pnt_s(TopoDS.Vertex_s(exp.Current()))
        around = []
        for j, solid in enumerate(made):
            if j != k:
                inside = BRepClass3d_SolidClassifier(solid, point, 1e-7)
                if inside.State() == TopAbs_IN:
                    around.append(j)
        if len(around) % 2 == 1:
            holder[k] = min(around, key=lambda j: vols[j])
    # (a cavity inside a cavity is from overlapping shells, not nested ones: left alone)
    holder = [h if h < 0 or holder[h] < 0 else -1 for h in holder]
    out = list(made)
    for j in sorted(set(holder) - {-1}):
        cavities = [k for k, h in enumerate(holder) if h == j]
        mk = BRepBuilderAPI_MakeSolid(TopoDS.Solid_s(made[j]))
        for k in cavities:
            mk.Add(shells[k][0])  # facing inward, as sewn
        if not mk.IsDone():
            continue
        fix = ShapeFix_Solid(mk.Solid())
        fix.Perform()
        got = solids(fix.Solid())
        expect = vols[j] - sum(vols[k] for k in cavities)
        if len(got) == 1 and is_valid(got[0]) and abs(volume(got[0]) - expect) <= 1e-6 * vols[j]:
            out[j] = got[0]
            for k in cavities:
                out[k] = None
    return [s for s in out if s is not None]


def _shape_map(shapes: list[TopoDS_Shape], kind: Any) -> Any:
    """A ``TopTools_IndexedMapOfShape`` of the sub-shapes of type ``kind`` of ``shapes``
    (``Contains`` is ``IsSame``: orientation aside)."""
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedMapOfShape

    out = TopTools_IndexedMapOfShape()
    for sh in shapes:
        TopExp.MapShapes_s(sh, kind, out)
    return out


def bounds(shape: TopoDS_Shape) -> NDArray[np.float64]:
    """(2, 3) float64 bounding box of ``shape``."""
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return np.array([[x0, y0, z0], [x1, y1, z1]])


def write_brep(shape: TopoDS_Shape, path: str | os.PathLike[str]) -> None:
    """Write ``shape`` as an OCCT ``.brep`` file (for gmsh)."""
    if not BRepTools.Write_s(shape, str(path)):
        raise OSError(f"OCCT could not write {path}")


def scaled_brep(data: bytes, factor: float) -> bytes:
    """Binary BREP ``data`` scaled by ``factor`` about the origin (empty bytes stay empty).

    The hubs of the reference are built in a frame where their radius is about 1
    (:mod:`reference_boolean.frame`); this brings a solid back to the lattice's units.
    """
    if not data or factor == 1.0:
        return data
    trsf = gp_Trsf()
    trsf.SetScaleFactor(float(factor))
    mk = BRepBuilderAPI_Transform(from_bytes(data), trsf, True)
    check_done(mk, "scale")
    return to_bytes(mk.Shape())
