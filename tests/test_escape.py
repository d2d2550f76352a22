"""Escape holes for skinned parts (conformal.escape): closed-form boxes, the Lattice and the
CLI, and a real part; independent checks by trimesh and manifold3d."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from conformal import escape
from lattice_cad.core.errors import EscapeHoleError, LatticeWarning
from tests.conftest import DATA, assert_valid, independent_check

SEG = 32


def _polygon_area(d: float, n: int = SEG) -> float:
    """Section of a hole: the regular n-gon circumscribing the circle of diameter d."""
    return n * (d / 2) ** 2 * math.tan(math.pi / n)


def _hollow_box(size=(20.0, 16.0, 12.0), t=1.0):
    import manifold3d

    s = np.asarray(size, dtype=float)
    return manifold3d.Manifold.cube(s, True) - manifold3d.Manifold.cube(s - 2 * t, True)


def _pieces(man):
    """(solid pieces, cavity walls) of a manifold3d solid."""
    vols = [p.volume() for p in man.decompose()]
    tiny = 1e-9 * max(vols)  # manifold3d may split off empty slivers of zero volume
    return sum(v > tiny for v in vols), sum(v < -tiny for v in vols)


def _trimesh(man):
    import trimesh

    m = man.to_mesh()
    return trimesh.Trimesh(m.vert_properties[:, :3], m.tri_verts, process=False)


# ----------------------------------------------------------------- closed form
def test_hollow_box_gets_one_hole_at_the_bottom_centre():
    box = _hollow_box()
    # before: the flood fill finds the cavity (18 x 14 x 10 less the cubes that touch its
    # walls), enclosed
    closed = escape.verify(box, voxel=0.5)
    assert closed.enclosed == 1 and not closed.connected
    assert 17 * 13 * 9 <= closed.regions[0]["volume"] <= 18 * 14 * 10
    assert closed.regions[0]["lowest"][2] == pytest.approx(-4.5, abs=0.5)

    res = escape.drill(box, 2.0, thickness=1.0)
    rep = res.report
    assert len(rep.cavities) == 1 and rep.cavities[0].status == "drilled"
    assert len(rep.holes) == 1 and rep.failed == []
    hole = rep.holes[0]
    assert hole.source == "lowest" and hole.clean
    np.testing.assert_allclose(hole.axis, [0, 0, -1])
    np.testing.assert_allclose(hole.outer, [0, 0, -6], atol=0.5)  # the bottom's centre
    assert hole.inner[2] == pytest.approx(-5.0) and hole.outer[2] == pytest.approx(-6.0)
    assert rep.verification is not None and rep.verification.connected
    assert rep.all_connected is True
    assert "all cavities connected: yes" in rep.summary()
    # independent: the volume lost is the hole's prism through the 1 mm wall, one valid
    # body with no cavity left, a sphere-like surface (genus 0: the cavity is now outside)
    assert box.volume() - res.solid.volume() == pytest.approx(_polygon_area(2.0) * 1.0, rel=1e-6)
    assert _pieces(res.solid) == (1, 0)
    assert res.solid.genus() == 0
    tm = _trimesh(res.solid)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0


def test_build_direction_and_user_points():
    box = _hollow_box()
    # built along +x: the lowest points are on the x = -10 wall
    res = escape.drill(box, 2.0, thickness=1.0, build_direction=(1, 0, 0))
    (hole,) = res.report.holes
    np.testing.assert_allclose(hole.axis, [-1, 0, 0], atol=1e-12)
    assert hole.outer[0] == pytest.approx(-10.0)
    # user points: drilled along the wall normal, and no lowest hole where they open it
    pts = [[10.0, 0.0, 0.0], [0.3, 8.2, 3.0]]
    res = escape.drill(box, 1.5, thickness=1.0, points=pts)
    rep = res.report
    assert [h.source for h in rep.holes] == ["point", "point"]
    np.testing.assert_allclose(rep.holes[0].axis, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rep.holes[1].axis, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rep.holes[1].outer, [0.3, 8.0, 3.0], atol=1e-9)
    assert rep.all_connected
    assert box.volume() - res.solid.volume() == pytest.approx(2 * _polygon_area(1.5), rel=1e-6)


def test_a_cavity_too_narrow_for_the_hole_is_reported():
    # the cavity is 1 mm wide in y: a 2 mm hole does not fit, a 0.6 mm one does
    box = _hollow_box((20.0, 3.0, 12.0), 1.0)
    res = escape.drill(box, 2.0, thickness=1.0, voxel=0.15)
    rep = res.report
    assert len(rep.cavities) == 1 and rep.failed == [0] and rep.holes == ()
    assert rep.cavities[0].status == "no fit"
    assert rep.all_connected is False and rep.verification.enclosed == 1
    assert "no fit" in rep.summary() and "all cavities connected: NO" in rep.summary()
    res = escape.drill(box, 0.6, thickness=1.0)
    assert res.report.all_connected and len(res.report.holes) == 1


def test_two_cavities_each_get_a_hole_and_bad_points_are_named():
    import manifold3d

    a = _hollow_box((10.0, 10.0, 10.0), 1.0)
    b = _hollow_box((10.0, 10.0, 6.0), 1.0).translate((9.0, 0.0, 0.0))  # shares a 1 mm wall
    solid = a + b
    res = escape.drill(solid, 1.5, thickness=1.0)
    rep = res.report
    assert len(rep.cavities) == 2 and len(rep.holes) == 2 and rep.all_connected
    assert sorted(h.outer[2] for h in rep.holes) == pytest.approx([-5.0, -3.0])
    assert _pieces(res.solid) == (1, 0)
    # a point on a solid block beside it has no cavity behind it
    block = manifold3d.Manifold.cube([4.0, 4.0, 4.0], True).translate((20.0, 0.0, 0.0))
    with pytest.raises(EscapeHoleError, match=r"no escape hole fits at \(20, 0, 2\)"):
        escape.drill(a + block, 1.5, thickness=1.0, points=[[20.0, 0.0, 2.0]])
    # on top of a box that sits on the cavity's lid, the user hole goes through both
    block = manifold3d.Manifold.cube([4.0, 4.0, 4.0], True).translate((0.0, 0.0, 7.0))
    res = escape.drill(a + block, 1.5, thickness=1.0, points=[[0.0, 0.0, 9.0]])
    (hole,) = res.report.holes
    assert hole.inner[2] == pytest.approx(4.0) and hole.outer[2] == pytest.approx(9.0)
    assert res.report.all_connected


def test_options_are_checked():
    box = _hollow_box()
    with pytest.raises(ValueError, match="diameter must be a positive number"):
        escape.drill(box, -1.0, thickness=1.0)
    with pytest.raises(ValueError, match="build_direction must be a non-zero"):
        escape.drill(box, 1.0, thickness=1.0, build_direction=(0, 0, 0))
    with pytest.raises(ValueError, match=r"points must be \(P, 3\)"):
        escape.drill(box, 1.0, thickness=1.0, points=[[1.0, 2.0]])
    with pytest.raises(ValueError, match="segments must be an integer >= 3"):
        escape.drill(box, 1.0, thickness=1.0, segments=2)


# --------------------------------------------------------------------- Lattice
@pytest.fixture(scope="module")
def box_part():
    import cadquery as cq

    return cq.Workplane("XY").box(20, 16, 12)


def test_lattice_with_skin_and_escape_holes(box_part):
    from lattice_cad.lattice import Lattice

    closed = Lattice.fill(box_part, "bcc", 4.0, 0.4, skin=1.0)
    m0 = closed.mesh()
    assert escape.verify(m0, voxel=0.5).enclosed == 1  # the skin traps the lattice's space
    lat = Lattice(closed.graph, part=closed.part, skin=1.0, escape_holes=2.0)
    m = lat.mesh()
    rep = lat.escape_report
    assert len(rep.cavities) == 1 and len(rep.holes) == 1
    assert rep.holes[0].outer[2] == pytest.approx(-6.0, abs=1e-6)  # the bottom wall
    assert rep.verification is not None and rep.verification.connected
    assert_valid(m, self_intersections=False)
    ind = independent_check(m, self_intersections=False)
    assert ind["watertight"] and ind["manifold3d"]
    # the hole removes its prism through the 1 mm wall (struts end inside the wall, so
    # the drill cuts wall material only when it is clean)
    lost = m0.volume - m.volume
    expected = _polygon_area(2.0) * 1.0
    if rep.holes[0].clean:
        # "clean" is judged on a ring of rays; since the default profile polygons are 10 %
        # wider than the strut radius a strut can graze the drill between two rays (here
        # +6 % of the prism's volume)
        assert expected * 0.98 < lost < expected * 1.1
    else:
        assert expected * 0.98 < lost < expected * 1.5


def test_lattice_escape_options_checked(box_part):
    from lattice_cad.lattice import Lattice

    with pytest.raises(ValueError, match="escape holes open the cavity of a skin"):
        Lattice.fill(box_part, "bcc", 4.0, 0.4, escape_holes=2.0)
    with pytest.raises(ValueError, match="escape_holes must be a positive number"):
        Lattice.fill(box_part, "bcc", 4.0, 0.4, skin=1.0, escape_holes=-2.0)
    with pytest.raises(ValueError, match=r"escape_at must be points \(P, 3\)"):
        Lattice.fill(box_part, "bcc", 4.0, 0.4, skin=1.0, escape_at=[[1.0, 2.0, 3.0, 4.0]])


def test_cli_escape_holes(capsys, tmp_path):
    import cadquery as cq

    from lattice_cad.cli import main
    from lattice_cad.core.mesh import Mesh
    from lattice_cad.io import read_mesh

    step = tmp_path / "box.step"
    cq.exporters.export(cq.Workplane("XY").box(20, 16, 12), str(step))
    out = tmp_path / "box.stl"
    argv = ["fill", step, "-o", out, "--skin", "1", "--cell-size", "4", "--escape-holes", "1.5"]
    argv += ["--escape-at", "10,0,0", "--build-direction", "0,1,0"]
    code = main([str(a) for a in argv])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "escape holes d=1.5 mm: 1 cavity(ies), 1 hole(s)" in text
    assert "hole in cavity 0 at (10, 0, 0) [point]" in text
    assert "all cavities connected: yes" in text
    # independently, on the file: the flood fill finds no enclosed space, and it is valid
    v, f = read_mesh(out)
    assert escape.verify((v, f), voxel=0.375).connected
    assert independent_check(Mesh(vertices=v, faces=f), self_intersections=False)["watertight"]
    with pytest.raises(SystemExit) as e:
        main(["fill", str(step), "-o", str(out), "--escape-at", "1,2"])
    assert e.value.code == 2
    assert "expected three numbers X,Y,Z, got '1,2'" in capsys.readouterr().err


# ------------------------------------------------------------------- real part
@pytest.mark.slow
def test_real_part_every_cavity_opens():
    """The spanner (STEP): every cavity of its skin gets a hole, the flood fill of the
    written mesh finds no enclosed space, and the mesh is one valid body."""
    from conformal import load_part
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        part = load_part(DATA / "step/dolfiny_spanner25_lo.step")
        cell = float(part.size.max()) / 15
        lat = Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6, escape_holes=2.0)
        mesh = lat.mesh()
    rep = lat.escape_report
    assert len(rep.cavities) >= 1 and rep.failed == []
    # pockets between struts and the wall below the flood fill's cell (one of 0.02 mm^3
    # on the radius's tessellation, two on the wall's: skin.outer_chord) are filled rather
    # than left as powder traps (the manifold3d check below sees none)
    assert 1 <= lat.escape_voids_filled <= 3
    assert {h.cavity for h in rep.holes} == set(range(len(rep.cavities)))
    assert rep.all_connected, rep.summary()
    assert_valid(mesh, self_intersections=False)
    # independently: no cavity wall left in the final mesh (manifold3d), one body
    from conformal.skin import as_manifold

    assert _pieces(as_manifold(mesh)) == (1, 0)
