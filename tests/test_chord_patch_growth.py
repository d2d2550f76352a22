"""A face split into patches is meshed finer only when all its patches fit (s39).

A mould insert made outside shared/data has an 8 mm cooling channel: a circle swept along a
3-D spline (a B-spline face that ``split_dense_faces`` cuts into 334 patches). Its cutting
tessellation (chord error 0.5 % of a 0.667 mm strut radius) left one patch of 1,254
triangles 6.7 x over the limit. ``_mesh_faces_finer`` checked that patch's growth against
the triangle cap, then meshed every patch of the face at a tenth of the chord error (their
0.37 M triangles would make the mesh 3.6 M, for a cap of 1.05 M): BRepMesh was still running
6 minutes later (about 15 at the 3.5 K triangles a second measured on that face), and the
tet, conform and clip fills of the part timed out (400 s). The growth of all the patches is
now what is checked; the face stays as it is, said in the chord warning.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from lattice_cad.core.errors import LatticeWarning


def _channel_block():
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


@pytest.mark.slow
def test_the_patches_of_a_face_are_meshed_finer_only_when_they_all_fit(monkeypatch):
    from conformal import load_part
    from conformal.trim import cutting_part
    from lattice_cad.occ_impl import chord

    shape = _channel_block()
    assert shape.isValid()
    part = load_part(shape)
    clean_around = chord._clean_around
    asked: list[float] = []

    def predicted(shape, scale):
        # the first round: every face at the cutting chord error; those in ``scale`` at
        # ``s`` times it grow about as 1 / s
        if isinstance(scale, dict) and not asked:  # (a list: the knot rounds before)
            counts = chord._triangle_counts(chord._faces(shape)).astype(np.float64)
            idx = np.array(sorted(scale))
            s = np.array([scale[i] for i in idx])
            total = counts.sum() + float((counts[idx] * (1.0 / s - 1.0)).sum())
            cap = max(float(chord.FINER_MAX_TRIANGLES), 2.0 * float(counts.sum()))
            asked.append(total)
            assert total <= cap, f"{len(idx)} faces meshed finer: {total:.3g} triangles > {cap:.3g}"
        return clean_around(shape, scale)

    monkeypatch.setattr(chord, "_clean_around", predicted)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always", LatticeWarning)
        cut = cutting_part(part, 0.666667)
    said = " | ".join(str(w.message) for w in rec)
    assert cut is not part and len(cut.faces) > len(part.faces)
    # the channel's face is left over the chord error asked, and the warning says so
    assert "could not be tessellated within the chord error asked" in said, said
