"""Build the shipped example part, a mounting bracket, with CadQuery.

Run: python examples/make_example_part.py [OUT.step]   (default: examples/bracket.step)

The bracket is an L-shaped block of about 60 x 40 x 20 mm with a filleted inner
corner, two counterbored holes in the base and one hole in the upright. It is
thick enough everywhere for a 5 mm lattice with a 1 mm skin.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cadquery as cq

HERE = Path(__file__).resolve().parent


def bracket() -> cq.Workplane:
    """The bracket as a CadQuery solid (millimetres, base on z = 0)."""
    base = cq.Workplane("XY").box(60, 40, 10, centered=(True, True, False))
    upright = (
        cq.Workplane("XY").box(14, 40, 20, centered=(True, True, False)).translate((-23, 0, 0))
    )
    body = base.union(upright).edges("|Y").edges(">Z").fillet(2.0)
    body = (
        body.faces(">Z[-2]")
        .workplane(centerOption="CenterOfBoundBox")
        .pushPoints([(14, 10), (14, -10)])
        .cboreHole(5.0, 9.0, 3.0)
    )
    body = body.faces("<X").workplane(centerOption="CenterOfBoundBox").hole(6.0, depth=14.0)
    return body


def main(out: str | None = None) -> Path:
    """Write the bracket to ``out`` (STEP) and return the path."""
    path = Path(out) if out else HERE / "bracket.step"
    part = bracket()
    cq.exporters.export(part, str(path))
    solid = part.val()
    bb = solid.BoundingBox()
    print(
        f"wrote {path}: {bb.xlen:.0f} x {bb.ylen:.0f} x {bb.zlen:.0f} mm, "
        f"volume {solid.Volume():.0f} mm^3, valid={solid.isValid()}"
    )
    return path


if __name__ == "__main__":
    main(*sys.argv[1:])
