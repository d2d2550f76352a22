"""Beams of a beam-lattice 3MF clipped to the part (issue 13 items 1 and 2).

The graph's struts reach beyond the part: by their radius, and by as much as their axis
cuts across a concave region (a chord of a hole). The clipped beams are checked by dense
sampling along every beam (independent of the bisection that clipped them), by trimesh's
signed distance, and on the beams read back from the written file with lib3mf.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conformal import load_part
from conformal.beam_clip import clip_beams
from lattice_cad import Lattice, LatticeGraph
from lattice_cad.core import config
from tests.conftest import DATA


def _box():
    import cadquery as cq

    return load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))


def _dense(graph, part, *, solid: bool, n: int = 257) -> float:
    """Largest ``sd + r`` (solid) or ``sd`` (axis) at n points along every beam."""
    t = np.linspace(0.0, 1.0, n)
    worst = -np.inf
    for i in range(0, graph.num_edges, 1000):
        e = graph.edges[i : i + 1000]
        r = graph.radii[i : i + 1000]
        a, b = graph.nodes[e[:, 0]], graph.nodes[e[:, 1]]
        p = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
        sd = part.signed_distance(p.reshape(-1, 3)).reshape(p.shape[:2])
        if solid:
            sd = sd + r[:, :1] + t[None, :] * (r[:, 1:] - r[:, :1])
        worst = max(worst, float(sd.max()))
    return worst


def test_one_tapered_strut_through_a_box_face_closed_form():
    """x from 5 to 15 through the face x = 10 of a 10 mm cube, radius 1 -> 0.5.

    axis: the end moves to x = 10 (t = 0.5) with the radius there, 0.75;
    solid: it moves to where 10 - x = r(x) = 1 - 0.05 (x - 5), x = 8.75 / 0.95.
    """
    part = _box()
    g = LatticeGraph([[5, 5, 5], [15, 5, 5]], [[0, 1]], [[1.0, 0.5]])
    tol = config.TRIM_RTOL * 1.0
    axis, rep = clip_beams(g, part, keep="axis")
    assert rep.cut == 1 and rep.removed == 0 and axis.num_edges == 1
    assert rep.outside_before == pytest.approx(5.0)
    end = axis.nodes[axis.edges[0, 1]]
    assert end == pytest.approx([10.0, 5.0, 5.0], abs=1e-9)
    assert axis.radii[0] == pytest.approx([1.0, 0.75])
    assert (axis.nodes[axis.edges[0, 0]] == g.nodes[0]).all()  # the inside node is kept
    solid, rep = clip_beams(g, part, keep="solid")
    x = solid.nodes[solid.edges[0, 1], 0]
    # f = sd + r = (x - 10) + 1 - 0.05 (x - 5): 0 at x = 8.75 / 0.95, tol at (8.75 + tol) / 0.95;
    # the end lies where f <= tol, shortened by at most 2 tol / K of the beam (K = 10.5)
    assert 8.75 / 0.95 - 2 * 10 * tol / 10.5 <= x <= (8.75 + tol) / 0.95 + 1e-9
    assert solid.radii[0, 1] == pytest.approx(1.0 - 0.5 * (x - 5) / 10, rel=1e-12)
    assert _dense(solid, part, solid=True) <= tol


def test_a_chord_leaving_and_reentering_is_split_and_outside_beams_dropped():
    """A U-shaped part (a slot cut into a box): a strut across the slot is split in two;
    a strut wholly outside is dropped."""
    import cadquery as cq

    part = load_part(
        cq.Workplane("XY").box(30, 10, 10, centered=False)
        - cq.Workplane("XY").box(10, 10, 6, centered=False).translate((10, 0, 4))
    )
    g = LatticeGraph([[2, 5, 7], [28, 5, 7], [2, 5, 20], [28, 5, 20]], [[0, 1], [2, 3]], 0.5)
    out, rep = clip_beams(g, part, keep="axis")
    assert rep.removed == 1 and rep.cut == 1 and out.num_edges == 2
    xs = sorted(out.nodes[out.edges].reshape(-1, 3)[:, 0].tolist())
    assert xs == pytest.approx([2.0, 10.0, 20.0, 28.0], abs=1e-9)
    assert _dense(out, part, solid=False) <= 1e-9


def test_beams_inside_are_untouched():
    part = _box()
    g = LatticeGraph([[3, 5, 5], [7, 5, 5]], [[0, 1]], 0.5)
    out, rep = clip_beams(g, part)
    assert rep.cut == 0 and rep.removed == 0
    assert (out.nodes[out.edges] == g.nodes[g.edges]).all() and (out.radii == g.radii).all()


def test_bad_keep_is_named():
    with pytest.raises(ValueError, match="keep must be"):
        clip_beams(LatticeGraph([[3, 5, 5], [7, 5, 5]], [[0, 1]], 0.5), _box(), keep="all")


def _beams_from_3mf(path):
    """(positions (V, 3), beams (B, 2), radii (B, 2)) of the beam-lattice object, lib3mf."""
    import lib3mf

    model = lib3mf.get_wrapper().CreateModel()
    reader = model.QueryReader("3mf")
    reader.SetStrictModeActive(True)
    reader.ReadFromFile(str(path))
    it = model.GetMeshObjects()
    while it.MoveNext():
        obj = it.GetCurrentMeshObject()
        bl = obj.BeamLattice()
        if bl.GetBeamCount():
            beams = [bl.GetBeam(i) for i in range(bl.GetBeamCount())]
            idx = np.array([[b.Indices[0], b.Indices[1]] for b in beams], dtype=np.int64)
            rad = np.array([[b.Radii[0], b.Radii[1]] for b in beams])
            pos = np.array([[p.Coordinates[k] for k in range(3)] for p in obj.GetVertices()])
            return pos.reshape(-1, 3), idx, rad
    raise AssertionError("no beam lattice in the file")


@pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")
@pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.BeamOnlyWarning")
def test_real_part_beams_lie_inside_the_part(tmp_path):
    """KCL flange, conform fill at the parts benchmark's settings (cell = extent / 15,
    r = cell / 12): the uncut beams reach far outside (their axes cross the bolt holes);
    after clipping, every round beam of the default file and every axis of the beam-only
    file lies inside the part within the tolerance, on the file as read back."""
    part = load_part(DATA / "step" / "kcl_flange-with-patterns.step")
    cell = float(np.max(part.size)) / 15
    r = cell / 12
    lat = Lattice.fill(part, "bcc", cell, r, fill="conform")
    tol = config.TRIM_RTOL * float(lat.graph.radii.max())
    # beams are clipped by the B-rep tessellated again for r (conformal.trim.cutting_part,
    # within 0.5 % r of the exact surface): the checks are against that one
    part = part.refined(config.CUT_DEFLECTION_RTOL * r, angular=config.CUT_ANGULAR_DEFLECTION)
    assert _dense(lat.graph, part, solid=True, n=33) > 0.9 * r  # the fault: beams stick out
    assert _dense(lat.graph, part, solid=False, n=33) > 10 * tol  # axes too (chords of holes)

    out = lat.save(tmp_path / "lattice.3mf", beam_lattice=True)
    rep = lat.beam_clip_report
    assert rep.keep == "solid" and rep.cut > 0 and rep.tolerance == pytest.approx(tol)
    pos, idx, rad = _beams_from_3mf(out)
    assert len(idx) == rep.beams_after
    file_graph = LatticeGraph(pos, idx, rad)
    # float32 positions in the file: a few ulps on top of the tolerance
    slack = 4 * float(np.spacing(np.float32(np.abs(part.bounds).max())))
    assert _dense(file_graph, part, solid=True, n=65) <= tol + slack
    ends = np.unique(idx)
    tm_part = trimesh.Trimesh(part.vertices, part.faces)
    depth = trimesh.proximity.signed_distance(tm_part, pos[ends])  # positive inside
    r_end = np.zeros(len(pos))
    np.maximum.at(r_end, idx.ravel(), rad.ravel())
    assert (depth - r_end[ends]).min() >= -(tol + slack)  # each end's ball/cap is inside

    only = lat.save(tmp_path / "only.3mf", beam_lattice="only")
    rep = lat.beam_clip_report
    assert rep.keep == "axis" and rep.cut > 0
    pos, idx, rad = _beams_from_3mf(only)
    ends = np.unique(idx)
    assert part.signed_distance(pos[ends]).max() <= tol + slack  # every beam vertex
    assert trimesh.proximity.signed_distance(tm_part, pos[ends]).min() >= -(tol + slack)
    assert _dense(LatticeGraph(pos, idx, rad), part, solid=False, n=65) <= tol + slack
