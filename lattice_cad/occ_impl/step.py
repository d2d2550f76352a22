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
    bounds,
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
        box = bounds(shape)
        check_step_units(tmp, [unit], float(np.linalg.norm(box[1] - box[0])))
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
