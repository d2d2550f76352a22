"""The chord check's finer stage gives up a round that makes the worst face worse.

Found on a running-shoe midsole made outside shared/data (s32): one smooth B-spline loft
through 10 superelliptic sections, 270 x 96 x 30 mm. At r = 1.5 its cutting tessellation
(chord 0.0075 mm) left one patch 1 % over the limit after the knots; the finer stage meshed
the face's patches at half the deflection, which put others 3.3 times over it (BRepMesh
does not follow this surface), and its next round, at a tenth, took 37 s and 1.55 M
triangles to end 1.6 times over: every fill of the part took about 150 s, for a warning.
A round whose worst face is worse than the worst before the stage is now undone (the plain
mesh, measured again): 180 K triangles, 1.1 times over, 12 s (the STEP file; the loft
made here: 176 K, 1.3 times).
"""

from __future__ import annotations

import math
import warnings

import pytest

pytestmark = pytest.mark.slow

#: x, width, thickness, y-offset of the centre, bottom z of each section (mm)
SECTIONS = [
    (0, 46, 26, 0, 3), (15, 66, 30, 0, 0), (45, 72, 29, 1, 0), (85, 64, 25, -3, 0),
    (120, 62, 21, -6, 0), (160, 86, 17, -4, 0), (195, 96, 15, 0, 0.5),
    (225, 92, 13, 3, 2), (252, 74, 11, 4, 5), (270, 40, 9, 4, 9),
]  # fmt: skip


def _midsole():
    import cadquery as cq

    wires = []
    for x, w, t, yc, z0 in SECTIONS:
        pts = []
        for k in range(28):  # |u/a|^3 + |v/b|^3 = 1
            c, s = math.cos(2 * math.pi * k / 28), math.sin(2 * math.pi * k / 28)
            u = w / 2 * math.copysign(abs(c) ** (2 / 3), c)
            v = t / 2 * math.copysign(abs(s) ** (2 / 3), s)
            pts.append(cq.Vector(x, yc + u, z0 + t / 2 + v))
        wires.append(cq.Wire.assembleEdges([cq.Edge.makeSpline(pts, periodic=True)]))
    return cq.Solid.makeLoft(wires, False)


def test_a_finer_round_that_makes_the_worst_face_worse_is_undone():
    from conformal import load_part
    from conformal.trim import cutting_part

    part = load_part(_midsole())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the chord error not reached is said in a warning
        cut = cutting_part(part, 1.5)
    assert cut.deflection == pytest.approx(0.0075)
    # before: 1,554,326 triangles and 0.018 mm after two finer rounds
    assert len(cut.faces) < 400_000
    assert cut.chord_error < 1.5 * 1.5 * cut.deflection  # (the limit: 1.5 x the chord)
