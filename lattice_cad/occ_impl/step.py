"""STEP files: read (converted to mm) and write (in a chosen unit), with unit cross-checks.

OCCT converts STEP lengths to millimetres on reading (``xstep.cascade.unit`` is MM), whatever
unit the file declares. Because one OCCT build's unit handling has been wrong before (7.8's
writer ignored ``write.step.unit``; an inconsistent install converted twice), every read and
every write is cross-checked here against the file's own text: see
:func:`check_step_units`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPControl import (
    STEPControl_AsIs,
    STEPControl_Controller,
    STEPControl_Reader,
    STEPControl_Writer,
)
from OCP.TColStd import TColStd_SequenceOfAsciiString
from OCP.TopoDS import TopoDS_Shape

from lattice_cad.core.errors import OCCTFailure, StepUnitsError
from lattice_cad.occ_impl.quiet import c_stdout_captured
from lattice_cad.occ_impl.shapes import (
    compound,
    from_bytes,
    is_valid,
    occt_errors,
    solids,
    translated,
)
from lattice_cad.occ_impl.shapes import volume as shape_volume

__all__ = [
    "read_step",
    "write_step",
    "write_step_solids",
    "read_step_solids",
    "declared_length_unit",
    "check_step_units",
]


def read_step(
    path: str | os.PathLike[str], *, messages: list[str] | None = None
) -> TopoDS_Shape | None:
    """Read a STEP file (lengths converted to mm). None when OCCT cannot read it.

    OCCT's console messages (``**** ERR StepFile ...``) never reach stdout: they are
    captured and, when ``messages`` is given, appended to it (to explain a failure).

    Raises
    ------
    StepUnitsError
        The length unit the file declares, the unit OCCT reports for it and the size of the
        shape OCCT returns do not agree (see :func:`check_step_units`).
    """
    with occt_errors(f"cannot read {os.fspath(path)}"):
        reader = STEPControl_Reader()
        with c_stdout_captured() as said:
            status = reader.ReadFile(str(path))
        if messages is not None:
            messages.extend(said)
        if status != IFSelect_RetDone:
            return None
        names = TColStd_SequenceOfAsciiString()
        reader.FileUnits(names, TColStd_SequenceOfAsciiString(), TColStd_SequenceOfAsciiString())
        occt_units = [names.Value(i).ToCString() for i in range(1, names.Length() + 1)]
        with c_stdout_captured() as said:
            reader.TransferRoots()
        if messages is not None:
            messages.extend(said)
        if reader.NbShapes() == 0:
            return None
        shape = reader.OneShape()
    if shape.IsNull():
        return None
    check_step_units(path, occt_units, shape)
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
_NAME = r"'(?:[^']|'')*'"
_POINT_ID = re.compile(
    rf"#(\d+)\s*=\s*CARTESIAN_POINT\s*\(\s*{_NAME}\s*,\s*\(\s*({_NUM})\s*,\s*({_NUM})\s*,"
    rf"\s*({_NUM})\s*\)",
    re.IGNORECASE,
)
_VERTEX = re.compile(rf"#(\d+)\s*=\s*VERTEX_POINT\s*\(\s*{_NAME}\s*,\s*#(\d+)\s*\)", re.IGNORECASE)
_EDGE = re.compile(rf"EDGE_CURVE\s*\(\s*{_NAME}\s*,\s*#(\d+)\s*,\s*#(\d+)", re.IGNORECASE)
#: Edge lengths (end to end) of the loaded shape and of the file's text agree when they are
#: within this relative tolerance; the unit is taken as right when at least
#: ``_MATCHED_FRACTION`` of the shape's edges find their length among the file's.
_LENGTH_RTOL = 1e-4
_MATCHED_FRACTION = 0.5
#: At most this many of the shape's edges are compared.
_MAX_EDGES = 4000
_SI_LENGTH = re.compile(r"SI_UNIT\s*\(\s*(\$|\.\w+\.)\s*,\s*\.METRE\.\s*\)", re.IGNORECASE)
_NAMED_LENGTH = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'([^']*)'", re.IGNORECASE)
#: When the edges cannot be matched (a file without EDGE_CURVEs between VERTEX_POINTs, or
#: edges OCCT split or merged), the longest edge of the shape over the longest of the file
#: must lie in this band; a unit applied twice or not at all is off by 10, 25.4 or 1000.
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
    path: str | os.PathLike[str], occt_units: list[str], shape: TopoDS_Shape
) -> None:
    """Cross-check the unit a STEP file declares against OCCT's reading of it.

    Two independent checks, so that a change in one OCCT build's unit handling cannot scale
    a part silently (an inconsistent OCP install once loaded inch files 25.4 times too
    large):

    1. the length unit parsed from the file's text equals the unit OCCT reports
       (``STEPControl_Reader.FileUnits``);
    2. the edges of the loaded ``shape`` (mm, end vertex to end vertex) are as long as the
       file's own ``EDGE_CURVE`` entities (between their ``VERTEX_POINT`` ones) times the declared
       unit: at least half of them find their length among the file's (within
       ``_LENGTH_RTOL``), and no other ratio of two length units fits better. Lengths do
       not change under an assembly's placements; the span of the file's points does (it
       takes in the placements' origins, so a part far from the origin looked thousands of
       times too small) and misses curved extents (a sphere's points are its centre and
       poles). When no edge can be matched, the longest edges are compared
       (``_SIZE_RATIO_BAND``).

    Raises
    ------
    StepUnitsError
        Naming the file, both units and the scale found.
    """
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
    file_len = _file_edge_lengths(text) * mm_per_unit
    shape_len = _shape_edge_lengths(shape)
    if len(file_len) == 0 or len(shape_len) == 0:
        return
    scale, fit = _best_scale(np.sort(file_len), shape_len)
    if scale is None:  # nothing matches: the longest edges
        ratio = float(shape_len.max() / file_len.max())
        lo, hi = _SIZE_RATIO_BAND
        if lo <= ratio <= hi:
            return
        scale, fit = ratio, 0.0
    elif scale == 1.0:
        return
    how = f"{100 * fit:.0f} % of its edges match at that scale" if fit else "its longest edge"
    raise StepUnitsError(
        f"{name}: declared unit {unit} ({mm_per_unit:g} mm), but the shape OCCT loaded has "
        f"edges {scale:.3g} times as long as the file's own ({how}); the OCCT install "
        "converts units wrongly (check `pip check` and that only one package provides OCP)"
    )


def _file_edge_lengths(text: str) -> NDArray[np.float64]:
    """(E,) float64: the nonzero end-to-end lengths of the file's EDGE_CURVEs, in its unit."""
    pts = {int(i): (float(x), float(y), float(z)) for i, x, y, z in _POINT_ID.findall(text)}
    verts = {int(i): pts.get(int(p)) for i, p in _VERTEX.findall(text)}
    ends = [(verts.get(int(a)), verts.get(int(b))) for a, b in _EDGE.findall(text)]
    ab = np.array([(a, b) for a, b in ends if a is not None and b is not None], dtype=np.float64)
    if len(ab) == 0:
        return np.zeros(0)
    length = np.linalg.norm(ab[:, 1] - ab[:, 0], axis=1)
    return length[length > 0]


def _shape_edge_lengths(shape: TopoDS_Shape) -> NDArray[np.float64]:
    """(E,) float64: the nonzero end-to-end lengths (mm) of up to ``_MAX_EDGES`` edges of
    ``shape`` (evenly spread over its edge map)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedMapOfShape

    edges = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, edges)
    n = edges.Extent()
    if n == 0:
        return np.zeros(0)
    out = []
    for k in np.unique(np.linspace(1, n, min(n, _MAX_EDGES)).astype(int)).tolist():
        edge = TopoDS.Edge_s(edges.FindKey(k))
        v0, v1 = TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)
        if v0.IsNull() or v1.IsNull():
            continue
        a, b = BRep_Tool.Pnt_s(v0), BRep_Tool.Pnt_s(v1)
        out.append(a.Distance(b))
    length = np.asarray(out, dtype=np.float64)
    return length[length > 0]


def _best_scale(
    file_len: NDArray[np.float64], shape_len: NDArray[np.float64]
) -> tuple[float | None, float]:
    """The ratio of length units (1 first) by which the most of ``shape_len`` are found in
    the sorted ``file_len``, and that fraction; (None, 0) when none reaches
    ``_MATCHED_FRACTION``."""
    units = sorted(set(_NAMED_MM.values()) | set(_SI_PREFIX_MM.values()))
    scales = [1.0] + sorted({a / b for a in units for b in units if a != b})
    best: tuple[float | None, float] = (None, 0.0)
    for s in scales:
        ref = file_len * s
        i = np.clip(np.searchsorted(ref, shape_len), 1, len(ref) - 1) if len(ref) > 1 else None
        if i is None:
            near = np.abs(shape_len - ref[0])
        else:
            near = np.minimum(np.abs(shape_len - ref[i - 1]), np.abs(shape_len - ref[i]))
        fit = float(np.mean(near <= _LENGTH_RTOL * shape_len))
        if fit >= _MATCHED_FRACTION and fit > best[1]:
            best = (s, fit)
        if s == 1.0 and fit >= _MATCHED_FRACTION:
            return best  # the declared unit fits: no other ratio is looked at
    return best


#: The header's time stamp: ``SOURCE_DATE_EPOCH`` (the reproducible-builds convention) if set,
#: else this fixed date, so that writing the same shape twice gives the same bytes.
STEP_TIME_STAMP = "2000-01-01T00:00:00"


def _stable_header(path: str, name: str) -> None:
    """Replace the FILE_NAME header's name (OCCT writes the temp file's) and time stamp,
    and the session counter OCCT appends to the product's name."""
    import re
    import time

    epoch = os.environ.get("SOURCE_DATE_EPOCH", "")
    stamp = (
        time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(int(epoch)))
        if epoch.isdigit()
        else STEP_TIME_STAMP
    )
    with open(path, "rb") as fh:
        data = fh.read()
    end = data.find(b"ENDSEC;")
    if end < 0:
        raise OCCTFailure(f"cannot write {name}: OCCT wrote a STEP file without a header")
    safe = name.replace("'", "''").encode("latin-1", "replace")
    head = re.sub(
        rb"FILE_NAME\('(?:[^']|'')*','[^']*'",
        b"FILE_NAME('" + safe + b"','" + stamp.encode() + b"'",
        data[:end],
        count=1,
    )
    # OCCT numbers the product per session ("name 1", "name 2", ...): drop the counter
    stem = re.escape(Path(name).stem.replace("'", "''").encode("latin-1", "replace"))
    body = re.sub(rb"PRODUCT\('(" + stem + rb") \d+','" + stem + rb" \d+'", rb"PRODUCT('\1','\1'",
                  data[end:])  # fmt: skip
    with open(path, "wb") as fh:
        fh.write(head + body)


def write_step(shape: TopoDS_Shape, path: str | os.PathLike[str], unit: str = "MM") -> None:
    """Write ``shape`` (in mm) to a STEP file declaring ``unit`` ("MM", "INCH", "M", ...).

    The coordinates are converted to ``unit``; the written text is checked afterwards (the
    declared unit times the span of its points must give the shape's size), so a file can
    never declare one unit and hold coordinates in another (OCCT 7.8's writer ignores
    ``write.step.unit`` unless the model's write length unit is set too).

    The file is written atomically: OCCT writes a temp file beside ``path``, which is
    renamed onto ``path`` once written and checked (nothing half-written is left).

    Raises
    ------
    OCCTFailure
        OCCT could not transfer or write the shape (naming the file; an exception raised
        inside OCCT is wrapped).
    """
    target = os.fspath(path)
    tmp = os.path.join(
        os.path.dirname(target) or ".", f".{os.path.basename(target)}.{os.getpid()}.part.step"
    )
    STEPControl_Controller.Init_s()
    unit = {"IN": "INCH"}.get(unit.upper(), unit.upper())
    if not Interface_Static.SetCVal_s("write.step.unit", unit):
        raise ValueError(f"OCCT does not know the STEP unit {unit!r}")
    try:
        mm_per_unit = _NAMED_MM.get(unit, _NAMED_MM.get(_UNIT_ALIASES.get(unit, ""), 0.0))
        if mm_per_unit <= 0:
            raise ValueError(f"unknown STEP unit {unit!r}")
        # the same shape gives the same bytes: the product is named after the file (OCCT
        # numbers it per session otherwise) and the header's time stamp is fixed below
        Interface_Static.SetCVal_s("write.step.product.name", Path(target).stem or "lattice")
        # OCCT prints its transfer statistics on the C stdout: captured, never shown
        with occt_errors(f"cannot write {target}: STEP transfer"):
            writer = STEPControl_Writer()
            writer.Model().SetWriteLengthUnit(mm_per_unit)
            with c_stdout_captured() as said:
                done = writer.Transfer(shape, STEPControl_AsIs)
            if done != IFSelect_RetDone:
                raise OCCTFailure(
                    f"cannot write {target}: the STEP transfer failed ({' '.join(said)[:200]})"
                )
        with occt_errors(f"cannot write {target}"):
            with c_stdout_captured() as said:
                done = writer.Write(tmp)
            if done != IFSelect_RetDone:
                raise OCCTFailure(
                    f"cannot write {target}: OCCT's STEP writer failed ({' '.join(said)[:200]})"
                )
        _stable_header(tmp, Path(target).name)
        check_step_units(tmp, [unit], shape)
        os.replace(tmp, target)
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_step_solids(
    path: str | os.PathLike[str], breps: list[bytes], translations: list[object]
) -> int:
    """Write one solid per (binary BREP, translation) pair into one STEP file (in mm).

    Equal BREP strings are decoded once. Returns the number of solids written.
    """
    cache: dict[int, TopoDS_Shape] = {}
    shapes = []
    for brep, t in zip(breps, translations, strict=True):
        key = id(brep)
        if key not in cache:
            cache[key] = from_bytes(brep)
        shapes.append(translated(cache[key], t))
    write_step(compound(shapes), path)
    return len(shapes)


def read_step_solids(path: str | os.PathLike[str]) -> list[tuple[bool, float]]:
    """(BRepCheck valid, volume) of every solid in a STEP file."""
    shape = read_step(path)
    if shape is None:
        raise OCCTFailure(f"cannot read STEP file {path}")
    return [(is_valid(s), shape_volume(s, eps=1e-10)) for s in solids(shape)]
