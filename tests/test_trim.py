"""Parts keep their size: the printable lattice is cut by the part's surface (issue 13).

The protrusion is checked independently of our own distance code: manifold3d's difference
``mesh - part`` must have (next to) no volume, and trimesh's ray test must find every
sampled vertex inside or on the part.
"""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

import fast_stitch
from conformal import load_part
from conformal.trim import protrusion, trim_to_part
from lattice_cad import Lattice, LatticeGraph
from lattice_cad.core import config
from tests.conftest import DATA, ROOT

BRACKET = ROOT / "examples" / "bracket.step"


def _manifold(v, f):
    m = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(v, dtype=np.float32),
            tri_verts=np.ascontiguousarray(f, dtype=np.uint32),
        )
    )
    assert m.status() == manifold3d.Error.NoError
    return m


def _outside_volume(mesh, part) -> float:
    """Volume of ``mesh`` outside ``part`` (the part's solids united first: they may touch)."""
    solids = _manifold(part.vertices, part.faces).decompose()
    cutter = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add)
    return (_manifold(mesh.vertices, mesh.faces) - cutter).volume()


def test_one_strut_through_a_box_is_cut_at_its_faces():
    """A strut 20 mm long crossing a 10 mm cube: exactly the middle half remains."""
    import cadquery as cq

    part = load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))
    g = LatticeGraph([[-5, 5, 5], [15, 5, 5]], [[0, 1]], 1.0)
    lat = Lattice(g, part=part)
    whole = lat.mesh(lattice_only=True)
    cut = lat.mesh()
    assert lat.trim_report.trimmed
    assert cut.volume == pytest.approx(whole.volume / 2, rel=1e-6)
    lo, hi = cut.vertices.min(axis=0), cut.vertices.max(axis=0)
    assert lo[0] == pytest.approx(0.0, abs=1e-6) and hi[0] == pytest.approx(10.0, abs=1e-6)
    assert lat.trim_report.protrusion_before == pytest.approx(5.0, rel=1e-3)
    assert lat.trim_report.protrusion_after <= lat.trim_report.tolerance
    # without trimming the strut keeps its length
    raw = Lattice(g, part=part, trim=False).mesh()
    assert raw.volume == pytest.approx(whole.volume, rel=1e-6)


def test_a_lattice_inside_the_part_is_not_touched():
    import cadquery as cq

    part = load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))
    g = LatticeGraph([[2, 5, 5], [8, 5, 5]], [[0, 1]], 1.0)
    lat = Lattice(g, part=part)
    assert lat.mesh() is not None and not lat.trim_report.trimmed
    assert lat.trim_report.protrusion_before == 0.0
    assert len(lat.mesh().faces) == len(lat.mesh(lattice_only=True).faces)


def test_trim_keeps_the_largest_piece_per_solid():
    """Two struts joined only outside the part: the smaller inside piece is removed."""
    import cadquery as cq

    part = load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))
    # a long strut inside and a short one, joined by a node outside the box
    g = LatticeGraph([[1, 5, 5], [12, 5, 5], [12, 5, 8], [9, 5, 8]], [[0, 1], [1, 2], [2, 3]], 0.5)
    res = trim_to_part(fast_stitch.stitch(g, 6), part, radius=0.5)
    assert res.report.trimmed and res.report.pieces_removed == 1 and res.report.bodies == 1
    assert len(res.solid.decompose()) == 1


@pytest.mark.filterwarnings("ignore:.*struts were thinned:lattice_cad.core.errors.LatticeWarning")
@pytest.mark.filterwarnings("ignore:.*loose piece:lattice_cad.core.errors.LatticeWarning")
@pytest.mark.parametrize("fill", ["clip", "conform"])
def test_example_bracket_keeps_its_size(fill):
    part = load_part(BRACKET)
    lat = Lattice.fill(part, "bcc", 5.0, 0.4, fill=fill)
    raw = lat.mesh(lattice_only=True)
    assert _outside_volume(raw, part) > 1.0  # the fault this fixes: struts stick out
    assert protrusion(part, raw.vertices) > 0.3
    m = lat.mesh()
    rep = lat.trim_report
    assert rep.trimmed and rep.within_tolerance
    assert rep.tolerance == pytest.approx(config.TRIM_RTOL * 0.4)
    # cut by the B-rep tessellated again for r (conformal.trim.cutting_part), which lies
    # outside the default mesh's chords of convex faces: the checks are against that one
    part = part.refined(config.CUT_DEFLECTION_RTOL * 0.4, angular=config.CUT_ANGULAR_DEFLECTION)
    assert part.deflection == pytest.approx(0.002)
    assert protrusion(part, m.vertices) <= rep.tolerance
    # independent: no volume outside, every vertex inside or on the part (trimesh)
    assert _outside_volume(m, part) < 1e-6 * m.volume
    tm_part = trimesh.Trimesh(part.vertices, part.faces)
    sample = m.vertices[:: max(1, len(m.vertices) // 3000)]
    d = trimesh.proximity.signed_distance(tm_part, sample)  # positive inside
    assert d.min() >= -rep.tolerance
    assert fast_stitch.check(m).valid
    tm = trimesh.Trimesh(m.vertices, m.faces)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    assert len(tm.split(only_watertight=False)) == 1
    info = lat.info()
    assert info["volume_exact"] and 0 < info["relative_density"] < 1
    assert info["volume"] == pytest.approx(m.volume)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")
def test_tet_lattice_on_a_real_part_keeps_its_size():
    part = load_part(DATA / "step" / "kcl_bracket.step")
    cell = float(np.max(part.size)) / 15
    lat = Lattice.fill(part, cell_size=cell, radius=cell / 12, method="tet")
    m = lat.mesh()
    assert lat.trim_report.trimmed and lat.trim_report.within_tolerance
    part = part.refined(config.CUT_DEFLECTION_RTOL * cell / 12)  # what it was cut by
    assert _outside_volume(m, part) < 1e-6 * m.volume
    assert fast_stitch.check(m).valid


def test_relative_density_is_a_fraction_even_when_struts_overlap():
    """Issue 12: thick struts on small cells summed to a 'density' above 1."""
    import cadquery as cq

    part = load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))
    lat = Lattice.fill(part, "bcc", 2.0, 0.45, fill="clip")
    assert lat.strut_volume() > part.volume  # the old estimate: above 1
    info = lat.info()
    assert info["volume_exact"]
    assert 0 < info["relative_density"] <= 1
    assert info["relative_density"] == pytest.approx(lat.mesh().volume / part.volume)


@pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")
def test_regression_tiny_mesh_part_trim_is_closed_for_trimesh():
    """bench_parts (armadillo, 0.8 mm, r = 5.5 um, kelvin conform): the trimmed mesh had
    vertices 1e-8 apart; trimesh merged them and found it open, and the STL writer refused
    its rounding. Such vertices are merged before the final check now."""
    part = load_part(DATA / "meshes" / "armadillo_closed_odedstein.obj")
    cell = float(np.max(part.size)) / 15
    lat = Lattice.fill(part, "kelvin", cell, cell / 12, fill="conform")
    m = lat.mesh()
    assert lat.trim_report.trimmed and lat.trim_report.within_tolerance
    tm = trimesh.Trimesh(m.vertices, m.faces)  # merges vertices closer than 1e-8
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    assert fast_stitch.check(m).valid
