"""A mould insert made outside shared/data (s39), rebuilt by CadQuery for the tests that
need it: a 120 x 120 x 60 block with a spherical dish and an 8 mm cooling channel swept
along a 3-D spline 10 mm below the dish."""

from __future__ import annotations

import math

import numpy as np


def channel_block():
    """The insert: a 120 x 120 x 60 block with a spherical dish, its top chamfered, an 8 mm
    channel swept along a spiral 10 mm below the dish, 4 holes in its bottom."""
    import cadquery as cq

    block = cq.Workplane("XY").box(120.0, 120.0, 60.0, centered=(True, True, False))
    block = block.cut(cq.Workplane("XY").sphere(50.0).translate((0.0, 0.0, 85.0)))
    block = block.faces(">Z").edges("not %CIRCLE").chamfer(1.5)
    th0, th1 = math.radians(40), math.radians(15)
    r0, z0 = 60.0 * math.sin(th0), 85.0 - 60.0 * math.cos(th0)
    pts = [(x, -r0, z0) for x in np.linspace(-75, -12, 8)]
    for u in np.linspace(0.0, 1.0, 41):
        th = th0 + (th1 - th0) * u
        ph = -math.pi / 2 + 2 * math.pi * 1.75 * u
        r = 60.0 * math.sin(th)
        pts.append((r * math.cos(ph), r * math.sin(ph), 85.0 - 60.0 * math.cos(th)))
    xe, ye, ze = pts[-1]
    for a in np.linspace(0, math.pi / 2, 8)[1:]:
        pts.append((xe, ye - 10 * math.sin(a), ze - 10 + 10 * math.cos(a)))
    pts += [(xe, ye - 10, z) for z in np.linspace(ze - 14, -15, 6)]
    clean = [pts[0]]
    for p in pts[1:]:
        if np.linalg.norm(np.subtract(p, clean[-1])) > 5.0:
            clean.append(p)
    path = cq.Edge.makeSpline([cq.Vector(*p) for p in clean])
    plane = cq.Plane(origin=cq.Vector(*clean[0]), xDir=cq.Vector(0, 0, 1), normal=path.tangentAt(0))
    channel = (
        cq.Workplane(plane)
        .circle(4.0)
        .sweep(cq.Workplane().add(cq.Wire.assembleEdges([path])), isFrenet=False)
    )
    block = block.cut(channel)
    block = block.faces("<Z").workplane().rect(100, 100, forConstruction=True).vertices()
    return block.hole(8.5, 20).val()
