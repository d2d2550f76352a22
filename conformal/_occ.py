"""Every OCCT (OCP / cadquery / build123d) call of the ``conformal`` package.

Nothing else in ``conformal`` imports OCP, cadquery or build123d; this module
itself is imported lazily (only when a STEP file or a CAD shape is loaded), so
``import conformal`` stays fast. OCCT converts STEP lengths to millimetres on
reading (its default ``xstep.cascade.unit`` is MM), whatever unit the file
declares.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepTools import BRepTools
from OCP.GProp import GProp_GProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPControl import (
    STEPControl_AsIs,
    STEPControl_Controller,
    STEPControl_Reader,
    STEPControl_Writer,
)
from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Shape
from OCP.TopTools import TopTools_ListOfShape

__all__ = [
    "read_step",
    "write_step",
    "as_topods",
    "solids",
    "open_shells",
    "fuse",
    "tessellate",
    "volume",
    "bounds",
    "write_brep",
    "compound",
]


def read_step(path: str | os.PathLike[str]) -> TopoDS_Shape | None:
    """Read a STEP file (lengths converted to mm). None when OCCT cannot read it."""
    reader = STEPControl_Reader()
    status = reader.ReadFile(str(path))
    if status != IFSelect_RetDone:
        return None
    reader.TransferRoots()
    if reader.NbShapes() == 0:
        return None
    shape = reader.OneShape()
    return None if shape.IsNull() else shape


def write_step(shape: TopoDS_Shape, path: str | os.PathLike[str], unit: str = "MM") -> None:
    """Write ``shape`` (in mm) to a STEP file declaring ``unit`` ("MM", "INCH", "M", ...)."""
    STEPControl_Controller.Init_s()
    unit = {"IN": "INCH"}.get(unit.upper(), unit.upper())
    if not Interface_Static.SetCVal_s("write.step.unit", unit):
        raise ValueError(f"OCCT does not know the STEP unit {unit!r}")
    try:
        writer = STEPControl_Writer()
        writer.Transfer(shape, STEPControl_AsIs)
        if writer.Write(str(path)) != IFSelect_RetDone:
            raise OSError(f"OCCT could not write {path}")
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")


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
    n = 0
    exp = TopExp_Explorer(shape, TopAbs_SHELL, TopAbs_SOLID)
    while exp.More():
        n += 1
        exp.Next()
    return n


def faces_outside_solids(shape: TopoDS_Shape) -> int:
    """Number of faces of ``shape`` that are not part of a solid."""
    n = 0
    exp = TopExp_Explorer(shape, TopAbs_FACE, TopAbs_SOLID)
    while exp.More():
        n += 1
        exp.Next()
    return n


def is_valid(shape: TopoDS_Shape) -> bool:
    """BRepCheck validity."""
    return bool(BRepCheck_Analyzer(shape).IsValid())


def fuse(parts: list[TopoDS_Shape], fuzzy: float = 0.0) -> TopoDS_Shape | None:
    """Boolean union of several solids; None when OCCT fails or gives an invalid shape."""
    args = TopTools_ListOfShape()
    args.Append(parts[0])
    tools = TopTools_ListOfShape()
    for p in parts[1:]:
        tools.Append(p)
    op = BRepAlgoAPI_Fuse()
    op.SetArguments(args)
    op.SetTools(tools)
    op.SetRunParallel(True)
    if fuzzy > 0:
        op.SetFuzzyValue(fuzzy)
    op.Build()
    if not op.IsDone():
        return None
    op.SimplifyResult()
    res = op.Shape()
    if res.IsNull() or not is_valid(res):
        return None
    return res


def volume(shape: TopoDS_Shape) -> float:
    """Volume of ``shape`` (mm^3)."""
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return float(props.Mass())


def bounds(shape: TopoDS_Shape) -> NDArray[np.float64]:
    """(2, 3) float64 bounding box of ``shape``."""
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return np.array([[x0, y0, z0], [x1, y1, z1]])


def tessellate(
    shape: TopoDS_Shape, deflection: float, angular: float = 0.25
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Triangulate every face of ``shape`` (BRepMesh).

    Returns
    -------
    vertices : (V, 3) float64
        Per-face vertices (not merged across faces).
    faces : (F, 3) int64
        Triangles, oriented by the face orientation (outward for a valid solid).
    """
    BRepMesh_IncrementalMesh(shape, float(deflection), False, float(angular), True)
    verts: list[NDArray[np.float64]] = []
    tris: list[NDArray[np.int64]] = []
    base = 0
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None:
            continue
        trsf = loc.Transformation()
        nn = tri.NbNodes()
        v = np.empty((nn, 3))
        for i in range(nn):
            p = tri.Node(i + 1).Transformed(trsf)
            v[i] = (p.X(), p.Y(), p.Z())
        nt = tri.NbTriangles()
        t = np.empty((nt, 3), dtype=np.int64)
        for i in range(nt):
            t[i] = tri.Triangle(i + 1).Get()
        t -= 1
        if face.Orientation() == TopAbs_REVERSED:
            t = t[:, ::-1]
        verts.append(v)
        tris.append(t + base)
        base += nn
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.vstack(verts), np.vstack(tris)


def write_brep(shape: TopoDS_Shape, path: str | os.PathLike[str]) -> None:
    """Write ``shape`` as an OCCT ``.brep`` file (for gmsh)."""
    if not BRepTools.Write_s(shape, str(path)):
        raise OSError(f"OCCT could not write {path}")
