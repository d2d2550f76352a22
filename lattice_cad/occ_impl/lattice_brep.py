"""The exact B-rep of a whole lattice: hub solids sewn or fused into one solid per body.

The hubs (:mod:`lattice_cad.occ_impl.truss`: a sphere fused with the half-struts up to
the strut midpoints) of a *clean* lattice meet only on their midpoint discs, and both
hubs of a strut build that disc on the same circle (the strut's canonical frame). Their
union is then the hubs' faces without the discs, sewn along the midpoint circles: no
boolean between hubs, a few seconds for thousands of struts
(:func:`sew_hubs`). Hubs of a lattice that is not clean (clipped or conforming fills put
short struts at the boundary) overlap; they are united by one general fuse
(:func:`fuse_hubs`), much slower. Either way the result has one solid per connected body
of the lattice. :func:`trim` intersects it with the part (``BRepAlgoAPI_Common``).

Every OCCT call is checked (``IsDone``, BRepCheck, closed shells); an exception raised
inside OCCT becomes :class:`OCCTFailure` naming the step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_MakeSolid,
    BRepBuilderAPI_Sewing,
    BRepBuilderAPI_Transform,
)
from OCP.BRepLib import BRepLib
from OCP.GeomAbs import GeomAbs_Plane
from OCP.gp import gp_Trsf, gp_Vec
from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Shape
from OCP.TopTools import TopTools_ListOfShape

from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.shapes import (
    check_done,
    check_valid,
    compound,
    from_bytes,
    fuse,
    occt_errors,
    solids,
)

__all__ = ["place_hubs", "disc_faces", "sew_hubs", "fuse_hubs", "trim", "as_one"]


def _moved(shape: TopoDS_Shape, offset: NDArray[np.float64]) -> TopoDS_Shape:
    trsf = gp_Trsf()
    trsf.SetTranslation(gp_Vec(float(offset[0]), float(offset[1]), float(offset[2])))
    return shape.Moved(TopLoc_Location(trsf))


def _turned(
    shape: TopoDS_Shape, q: NDArray[np.float64], offset: NDArray[np.float64]
) -> TopoDS_Shape:
    """A copy of ``shape`` mapped by ``x -> q x + offset`` (``q`` orthogonal, maybe a
    reflection, which ``BRepBuilderAPI_Transform`` handles by copying the geometry)."""
    trsf = gp_Trsf()
    trsf.SetValues(*(float(v) for r in range(3) for v in (*q[r], offset[r])))
    mk = BRepBuilderAPI_Transform(shape, trsf, True)
    check_done(mk, "placing a turned hub")
    return mk.Shape()


def _decode(breps: Sequence[bytes], failed: dict[int, str]) -> list[TopoDS_Shape | None]:
    if failed:
        t, why = next(iter(failed.items()))
        raise OCCTFailure(f"{len(failed)} distinct hub(s) could not be built, e.g. hub {t}: {why}")
    return [from_bytes(b) for b in breps]


def place_hubs(
    breps: Sequence[bytes],
    template: NDArray[np.int64],
    nodes: NDArray[np.float64],
    *,
    failed: dict[int, str] | None = None,
) -> list[TopoDS_Shape]:
    """Every node's hub solid at its node (shared geometry, located copies).

    Parameters
    ----------
    breps : sequence of bytes
        Binary BREP of each distinct hub, node at the origin.
    template : (N,) int64
        Index into ``breps`` per node (-1: isolated node, no hub).
    nodes : (N, 3) float64
    failed : dict[int, str], optional
        Distinct hubs that could not be built: an :class:`OCCTFailure`.
    """
    hubs = _decode(breps, failed or {})
    return [_moved(hubs[t], nodes[n]) for n, t in enumerate(template) if t >= 0]


def disc_faces(
    hub: TopoDS_Shape,
    mid_vectors: NDArray[np.float64],
    tol: float,
    axes: NDArray[np.float64] | None = None,
) -> list[bool]:
    """Which faces of a hub (in ``TopExp`` order) are midpoint discs.

    Parameters
    ----------
    hub : TopoDS_Shape
        The hub solid, node at the origin.
    mid_vectors : (d, 3) float64
        Node -> midpoint vector of each stump.
    tol : float
        Distance (mm) within which the disc's plane must pass through the midpoint.
    axes : (d, 3) float64, optional
        Strut axis of each disc (default: along ``mid_vectors``, as for one hub; a
        cluster's leaving struts do not start at its origin).
    """
    if axes is None:
        axes = mid_vectors / np.linalg.norm(mid_vectors, axis=1)[:, None]
    out = []
    exp = TopExp_Explorer(hub, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        surf = BRepAdaptor_Surface(face)
        is_disc = False
        if surf.GetType() == GeomAbs_Plane:
            ax = surf.Plane().Axis()
            d, p = ax.Direction(), ax.Location()
            n = np.array([d.X(), d.Y(), d.Z()])
            at = np.array([p.X(), p.Y(), p.Z()])
            parallel = np.abs(np.abs(axes @ n) - 1.0) < 1e-9
            through = np.abs((at - mid_vectors) @ n) < tol
            is_disc = bool(np.any(parallel & through))
        out.append(is_disc)
    return out


def _shells_to_solids(shape: TopoDS_Shape, what: str) -> list[TopoDS_Shape]:
    out = []
    exp = TopExp_Explorer(shape, TopAbs_SHELL)
    while exp.More():
        shell = TopoDS.Shell_s(exp.Current())
        exp.Next()
        mk = BRepBuilderAPI_MakeSolid(shell)
        check_done(mk, f"{what}: making a solid of a sewn shell")
        solid = mk.Solid()
        BRepLib.OrientClosedSolid_s(solid)
        out.append(solid)
    return out


def sew_hubs(
    breps: Sequence[bytes],
    template: NDArray[np.int64],
    nodes: NDArray[np.float64],
    mid_vectors: Sequence[NDArray[np.float64]],
    *,
    tolerance: float,
    failed: dict[int, str] | None = None,
    axes: Sequence[NDArray[np.float64]] | None = None,
    rotations: NDArray[np.float64] | None = None,
) -> list[TopoDS_Shape]:
    """The union of the hubs of a clean lattice, by sewing (one solid per body).

    Parameters
    ----------
    breps, template, nodes, failed
        As for :func:`place_hubs`.
    mid_vectors : sequence of (d, 3) float64
        Per distinct hub, the node -> midpoint vector of each stump.
    tolerance : float
        Sewing tolerance (mm); the shared midpoint circles agree to rounding.
    axes : sequence of (d, 3) float64, optional
        Per distinct solid, the axis of each midpoint disc (see :func:`disc_faces`);
        needed for the clusters of the exact reference.
    rotations : (len(template), 3, 3) float64, optional
        Orthogonal map applied to each placed solid before its translation (hubs reused up
        to a rotation or reflection, :mod:`reference_boolean.rotations`); default none.

    Returns
    -------
    list of TopoDS_Shape
        The solids, outward oriented.

    Raises
    ------
    OCCTFailure
        A hub lacks a midpoint disc, or an edge is left free (a shell is not closed) or
        shared by more than two faces.
    """
    hubs = _decode(breps, failed or {})
    kept: list[list[TopoDS_Shape]] = []
    for t, hub in enumerate(hubs):
        mask = disc_faces(hub, mid_vectors[t], tolerance, None if axes is None else axes[t])
        if sum(mask) != len(mid_vectors[t]):
            raise OCCTFailure(
                f"sewing hubs: distinct hub {t} has {sum(mask)} midpoint disc(s) for "
                f"{len(mid_vectors[t])} struts (is the lattice clean?)"
            )
        faces, exp, i = [], TopExp_Explorer(hub, TopAbs_FACE), 0
        while exp.More():
            if not mask[i]:
                faces.append(exp.Current())
            exp.Next()
            i += 1
        kept.append(faces)
    with occt_errors("sewing the hub solids"):
        sew = BRepBuilderAPI_Sewing(float(tolerance))
        for n, t in enumerate(template):
            if t < 0:
                continue
            q = None if rotations is None else rotations[n]
            if q is not None and not np.abs(q - np.eye(3)).max() > 0.0:
                q = None  # the identity: a plain move
            for f in kept[t]:
                sew.Add(_moved(f, nodes[n]) if q is None else _turned(f, q, nodes[n]))
        sew.Perform()
        if sew.NbFreeEdges() or sew.NbMultipleEdges():
            raise OCCTFailure(
                f"sewing the hub solids left {sew.NbFreeEdges()} free and "
                f"{sew.NbMultipleEdges()} multiple edge(s) (the midpoint circles do not match)"
            )
        return _shells_to_solids(sew.SewedShape(), "sewing the hub solids")


def fuse_hubs(
    breps: Sequence[bytes],
    template: NDArray[np.int64],
    nodes: NDArray[np.float64],
    *,
    failed: dict[int, str] | None = None,
) -> list[TopoDS_Shape]:
    """The union of the hubs of any lattice by one general fuse (one solid per body)."""
    placed = place_hubs(breps, template, nodes, failed=failed)
    if len(placed) == 1:
        return placed
    with occt_errors("fusing the hub solids"):
        return solids(fuse(placed, check=False))


def trim(shapes: Sequence[TopoDS_Shape], part: Sequence[TopoDS_Shape]) -> list[TopoDS_Shape]:
    """The lattice solids intersected with the part's solids (``BRepAlgoAPI_Common``).

    Several part solids are fused first (a part may come as touching or overlapping
    solids, as the GE bracket's body and bolt volumes).
    """
    with occt_errors("trimming the lattice to the part"):
        tool = part[0] if len(part) == 1 else fuse(list(part), check=False)
        args, tools = TopTools_ListOfShape(), TopTools_ListOfShape()
        for s in shapes:
            args.Append(s)
        tools.Append(tool)
        op = BRepAlgoAPI_Common()
        op.SetArguments(args)
        op.SetTools(tools)
        op.SetRunParallel(True)
        op.SetNonDestructive(True)
        op.Build()
        check_done(op, "trimming the lattice to the part (common)")
        return solids(op.Shape())


def as_one(shapes: Sequence[TopoDS_Shape], what: str) -> Any:
    """One solid, or a compound of the solids; BRepCheck-valid or :class:`OCCTFailure`."""
    if not shapes:
        raise OCCTFailure(f"{what}: no solid left")
    out = shapes[0] if len(shapes) == 1 else compound(list(shapes))
    with occt_errors(f"{what}: BRepCheck"):
        check_valid(out, what)
    return out
