"""Every OCCT (OCP / cadquery / build123d) call of the ``conformal`` package.

Nothing else in ``conformal`` imports OCP, cadquery or build123d; this module
itself is imported lazily (only when a STEP file or a CAD shape is loaded), so
``import conformal`` stays fast. OCCT converts STEP lengths to millimetres on
reading (its default ``xstep.cascade.unit`` is MM), whatever unit the file
declares.
"""

from __future__ import annotations

import os
import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad import _stack

_stack.warn_once()  # before the first OCP import: a broken stack is named, with its fix

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
from OCP.TColStd import TColStd_SequenceOfAsciiString
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
    """Read a STEP file (lengths converted to mm). None when OCCT cannot read it.

    Raises
    ------
    StepUnitsError
        The length unit the file declares, the unit OCCT reports for it and the size of the
        shape OCCT returns do not agree (see :func:`check_step_units`).
    """
    reader = STEPControl_Reader()
    status = reader.ReadFile(str(path))
    if status != IFSelect_RetDone:
        return None
    names = TColStd_SequenceOfAsciiString()
    reader.FileUnits(names, TColStd_SequenceOfAsciiString(), TColStd_SequenceOfAsciiString())
    occt_units = [names.Value(i).ToCString() for i in range(1, names.Length() + 1)]
    reader.TransferRoots()
    if reader.NbShapes() == 0:
        return None
    shape = reader.OneShape()
    if shape.IsNull():
        return None
    box = bounds(shape)
    check_step_units(path, occt_units, float(np.linalg.norm(box[1] - box[0])))
    return shape


#: Millimetres per STEP length unit, by SI prefix of METRE and by conversion-based unit name.
_SI_PREFIX_MM = {"$": 1000.0, "KILO": 1e6, "DECI": 100.0, "CENTI": 10.0, "MILLI": 1.0,
                 "MICRO": 1e-3, "NANO": 1e-6}  # fmt: skip
_NAMED_MM = {"INCH": 25.4, "IN": 25.4, "FOOT": 304.8, "FT": 304.8, "MIL": 0.0254,
             "THOU": 0.0254, "YARD": 914.4, "MILE": 1609344.0, "METRE": 1000.0, "METER": 1000.0,
             "MILLIMETRE": 1.0, "MILLIMETER": 1.0, "CENTIMETRE": 10.0, "CENTIMETER": 10.0,
             "MICROMETRE": 1e-3, "MICROMETER": 1e-3, "KILOMETRE": 1e6, "KILOMETER": 1e6,
             "DECIMETRE": 100.0, "DECIMETER": 100.0}  # fmt: skip
_UNIT_ALIASES = {"MM": "MILLIMETRE", "CM": "CENTIMETRE", "M": "METRE", "KM": "KILOMETRE",
                 "UM": "MICROMETRE", "MI": "MILE", "FT": "FOOT"}  # fmt: skip
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_POINT = re.compile(
    rf"CARTESIAN_POINT\s*\(\s*'[^']*'\s*,\s*\(\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*\)",
    re.IGNORECASE,
)
_SI_LENGTH = re.compile(r"SI_UNIT\s*\(\s*(\$|\.\w+\.)\s*,\s*\.METRE\.\s*\)", re.IGNORECASE)
_NAMED_LENGTH = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'([^']*)'", re.IGNORECASE)
#: Loaded size / size from the file's own coordinates must lie in this band. The file's
#: points include B-spline control points and placements, so the loaded shape is usually a
#: bit smaller (0.49 .. 1.09 over shared/data); a unit applied twice or not at all is off by
#: 10, 25.4 or 1000.
_SIZE_RATIO_BAND = (0.15, 3.0)


def declared_length_unit(text: str) -> tuple[str, float] | None:
    """The length unit a STEP file declares, as (name, millimetres per unit).

    A conversion-based length unit (INCH, FOOT, ...) wins over the SI unit it is defined
    from; None when the file declares none this module knows.
    """
    named: tuple[str, float] | None = None
    si: tuple[str, float] | None = None
    for entity in text.split(";"):
        if "LENGTH_UNIT" not in entity.upper():
            continue
        m = _NAMED_LENGTH.search(entity)
        if m and m.group(1).strip().upper() in _NAMED_MM:
            name = m.group(1).strip().upper()
            named = (name, _NAMED_MM[name])
            continue
        m = _SI_LENGTH.search(entity)
        if m:
            prefix = m.group(1).strip(".").upper()
            if prefix in _SI_PREFIX_MM:
                si = ("METRE" if prefix == "$" else prefix + "METRE", _SI_PREFIX_MM[prefix])
    return named or si


def check_step_units(
    path: str | os.PathLike[str], occt_units: list[str], loaded_diagonal: float
) -> None:
    """Cross-check the unit a STEP file declares against OCCT's reading of it.

    Two independent checks, so that a change in one OCCT build's unit handling cannot scale
    a part silently (an inconsistent OCP install once loaded inch files 25.4 times too
    large):

    1. the length unit parsed from the file's text equals the unit OCCT reports
       (``STEPControl_Reader.FileUnits``);
    2. the diagonal of the loaded shape (mm) is close to the diagonal of the file's own
       ``CARTESIAN_POINT`` coordinates times the declared unit (within ``_SIZE_RATIO_BAND``).

    Raises
    ------
    StepUnitsError
        Naming the file, both units and both sizes.
    """
    from conformal.part import StepUnitsError

    name = os.fspath(path)
    with open(path, encoding="latin-1") as fh:
        text = fh.read()
    declared = declared_length_unit(text)
    if declared is None:
        return
    unit, mm_per_unit = declared
    known = [u for u in occt_units if u.strip().upper() in _NAMED_MM]
    if known and all(_NAMED_MM[u.strip().upper()] != mm_per_unit for u in known):
        raise StepUnitsError(
            f"{name}: the file declares its lengths in {unit}, but OCCT reads them as "
            f"{', '.join(known)}; refusing to guess the part's size"
        )
    pts = np.array(_POINT.findall(text), dtype=np.float64)
    if len(pts) < 2 or loaded_diagonal <= 0:
        return
    raw = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) * mm_per_unit
    if raw <= 0:
        return
    ratio = loaded_diagonal / raw
    lo, hi = _SIZE_RATIO_BAND
    if not lo <= ratio <= hi:
        raise StepUnitsError(
            f"{name}: declared unit {unit} ({mm_per_unit:g} mm) makes the file's points span "
            f"{raw:.4g} mm, but OCCT loaded a shape {loaded_diagonal:.4g} mm across "
            f"({ratio:.3g} times as large); the OCCT install converts units wrongly "
            "(check `pip check` and that only one package provides OCP)"
        )


def write_step(shape: TopoDS_Shape, path: str | os.PathLike[str], unit: str = "MM") -> None:
    """Write ``shape`` (in mm) to a STEP file declaring ``unit`` ("MM", "INCH", "M", ...).

    The coordinates are converted to ``unit``; the written text is checked afterwards (the
    declared unit times the span of its points must give the shape's size), so a file can
    never declare one unit and hold coordinates in another (OCCT 7.8's writer ignores
    ``write.step.unit`` unless the model's write length unit is set too).
    """
    STEPControl_Controller.Init_s()
    unit = {"IN": "INCH"}.get(unit.upper(), unit.upper())
    if not Interface_Static.SetCVal_s("write.step.unit", unit):
        raise ValueError(f"OCCT does not know the STEP unit {unit!r}")
    try:
        writer = STEPControl_Writer()
        mm_per_unit = _NAMED_MM.get(unit, _NAMED_MM.get(_UNIT_ALIASES.get(unit, ""), 0.0))
        if mm_per_unit <= 0:
            raise ValueError(f"unknown STEP unit {unit!r}")
        writer.Model().SetWriteLengthUnit(mm_per_unit)
        writer.Transfer(shape, STEPControl_AsIs)
        if writer.Write(str(path)) != IFSelect_RetDone:
            raise OSError(f"OCCT could not write {path}")
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")
    box = bounds(shape)
    check_step_units(path, [unit], float(np.linalg.norm(box[1] - box[0])))


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
