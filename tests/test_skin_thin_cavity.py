"""A skin's cavity thinner than the struts is made solid wall (s35).

A coffee mug made outside shared/data (``regression_coffee_mug.step``: 82 mm across, a
3 mm wall, a 6 mm bottom, an elliptic swept handle) with the parts benchmark's skin
(octet, cell 7.98 mm, radius 0.665 mm, skin 1.33 mm) left a 0.34 mm cavity in its wall,
thinner than the voxel grid and than the struts: they were cut into ~1,000 sealed slivers
that float32 could not hold, and the skin timed out after 10 minutes of retries (s34). The
cavity is now kept only where it is at least a strut's diameter thick
(``build_skin(min_cavity=)``); the wall is solid elsewhere, and the report says how much.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import manifold3d
import numpy as np
import pytest

import fast_stitch
from conformal import Part, block
from conformal import skin as _skin
from lattice_cad.core.errors import LatticeWarning, SkinError

MUG = Path(__file__).parent / "regression_coffee_mug.step"  # made by CadQuery (s34)


def _part(man: manifold3d.Manifold, name: str) -> Part:
    mesh = man.to_mesh()
    return Part(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name=name)


def _skinned(path: Path, **kw: float):
    """An octet fill of ``path`` with a skin (``Lattice.fill`` keywords ``kw``; its
    warnings ignored), its mesh, and the warnings the mesh gave."""
    from lattice_cad import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(path, cell="octet", **kw)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = lat.mesh()
    return lat, mesh, [str(w.message) for w in caught]


def _block_with_fin() -> Part:
    """A 20 mm cube with a 3 mm thick fin, 30 x 20 mm, off one side."""
    cube = manifold3d.Manifold.cube([20.0, 20.0, 20.0])
    fin = manifold3d.Manifold.cube([31.0, 20.0, 3.0]).translate([19.0, 0.0, 0.0])
    return _part(cube + fin, "block with fin")


def _inner(part: Part, thickness: float, min_cavity: float | None):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        h = thickness / 3
        surfaces, field = _skin._voxel_surfaces(part, thickness, h)
        (outer, inner), closed = _skin._closed_cavity(surfaces, field, h, thickness, min_cavity)
    return inner, closed, [str(w.message) for w in caught]


def test_a_cavity_thinner_than_the_struts_is_closed_the_rest_kept():
    part = _block_with_fin()
    t = 1.0
    inner, closed, _ = _inner(part, t, None)
    assert closed is None
    v = np.asarray(inner.to_mesh().vert_properties)[:, :3]
    assert v[:, 0].max() > 45.0  # without: the cavity runs 1 mm thick along the fin
    inner2, closed2, _ = _inner(part, t, 2.0)  # struts 2 mm across: the 1 mm cavity closed
    assert closed2 is not None
    volume, at = closed2
    # the fin's cavity (~29 x 18 x 1 mm) closed, to within the grid and the slack
    assert 300.0 < volume < 700.0, volume
    assert at[0] > 20.0 and at[2] < 3.0, at
    v2 = np.asarray(inner2.to_mesh().vert_properties)[:, :3]
    # what is left is the cube's cavity (its corners as they were), reaching at most the
    # opening's reach into the fin
    reach = 3**0.5 * 1.0 + _skin.OPEN_SLACK * t / 3
    assert v2[:, 0].max() < 19.0 + reach + 0.2
    cube_cavity = 18.0**3
    assert inner2.volume() == pytest.approx(cube_cavity, rel=0.05)
    assert inner.volume() > inner2.volume() + 300.0


def test_a_cavity_as_thick_as_the_struts_everywhere_is_left_as_it_is():
    part = _block_with_fin()
    inner, closed, _ = _inner(part, 0.5, 1.0)  # the fin's cavity is 2 mm: kept
    assert closed is None
    assert np.asarray(inner.to_mesh().vert_properties)[:, 0].max() > 45.0


def test_no_room_for_the_struts_anywhere_is_said_with_what_would_fit():
    plate = _part(manifold3d.Manifold.cube([40.0, 30.0, 3.0]), "plate")
    graph = block("bcc", 3, cell_size=8.0, radius=0.8)
    lattice = fast_stitch.stitch(graph)
    with pytest.raises(SkinError, match=r"cavity nowhere as thick as the struts \(1.6 mm") as e:
        _skin.build_skin(lattice, plate, 1.0, check=False, min_cavity=1.6)
    # the plate is 3 mm thick: a skin under 0.4 x (3 - 1.6) mm leaves room
    assert "thinner than about 0.56 mm" in str(e.value)
    # the skin alone leaves a 1 mm cavity: built as before without min_cavity
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        done = _skin.build_skin(lattice, plate, 1.0, check=False)
    assert done.report.closed == 0.0


@pytest.mark.slow
def test_the_mug_s_skin_is_written_with_its_thin_wall_solid(tmp_path):
    from lattice_cad.cli import main
    from tests.conftest import assert_valid

    lat, mesh, said = _skinned(MUG, cell_size=7.981, radius=0.665083, skin=1.33017)
    assert [m for m in said if "cavity thinner than the struts" in m], said
    assert not [m for m in said if "could not hold" in m or "cannot be written" in m], said
    rep = lat.skin_report
    # the 3 mm wall's 0.34 mm cavity: 2 pi 41 mm x 95 mm x 0.34 mm is about 8,300 mm^3
    assert 5000.0 < rep.closed < 10000.0, rep.summary()
    assert rep.bodies == 1 and "made solid" in rep.summary()
    assert rep.voids < 50, rep.summary()  # the bottom's and the handle's cavities
    assert_valid(mesh)
    path = tmp_path / "mug.stl"
    lat.save(path)
    assert main(["check", str(path)]) == 0


def test_occt_skin_closes_a_cavity_the_struts_cut_apart(tmp_path):
    """Regression (s36): OCCT's offsets are exact, and the cavity between them in a fin
    3.4 mm thick under a 1.4 mm skin is 0.6 mm, half the struts' diameter: the struts cut
    it into 67 sealed voids (trapped powder or resin in each), where the voxel method
    closes such a cavity. More sealed voids than the cavity has pieces now closes it on
    the voxel field too, and the booleans run again on the offset with it taken out."""
    import cadquery as cq
    import trimesh

    from lattice_cad.cli import main

    fin = cq.Workplane().box(40, 40, 20).faces(">Z").workplane().rect(30, 3.4).extrude(30)
    path = tmp_path / "fin.step"
    cq.exporters.export(fin, str(path))
    lat, mesh, said = _skinned(path, cell_size=5.0, radius=0.6, skin=1.4)
    assert [m for m in said if "cavity thinner than the struts" in m], said
    rep = lat.skin_report
    assert rep.method == "occt" and rep.accurate, rep.summary()
    # the fin's cavity: 0.6 mm x 27.2 mm x ~28.6 mm (up to the opening's reach) ~ 470 mm^3
    assert 250.0 < rep.closed < 600.0, rep.summary()
    assert rep.bodies == 1 and rep.voids == 1, rep.summary()  # the block's cavity only
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    # the fin is solid above the block's cavity: no lattice, no void between its walls
    # (a point in the middle of the fin, 12 mm up, 0.2 mm off its mid-plane)
    assert bool(tm.contains([[0.0, 0.2, 22.0]])[0]) and bool(tm.contains([[5.0, -0.2, 30.0]])[0])
    out = tmp_path / "fin.stl"
    lat.save(out)
    assert main(["check", str(out)]) == 0


def test_no_room_in_a_part_thick_enough_says_the_grid_missed_it():
    """A tapered wing 17.7 mm thick under a 5.56 mm skin with 5.56 mm struts (made outside
    shared/data) was refused with "a cavity nowhere as thick as the struts" beside its own
    17.7 mm, which leaves 6.6 mm: its cavity is that thick only within about 0.4 mm of
    its mid-surface, narrower than the voxel grid (1.85 mm) keeps. The message says so."""
    text = _skin.no_room_message(5.55556, 17.7, strut=5.55556, closed=True, grid=1.85)
    assert "as thick as the struts (5.56 mm across) only in spots narrower than its voxel " in text
    assert "grid keeps (1.85 mm)" in text and "nowhere" not in text
    assert "a skin thinner than about 4.86 mm leaves room" in text
    # 3 < 2 + 1.6: nowhere
    plate = _skin.no_room_message(1.0, 3.0, strut=1.6, closed=True, grid=0.33)
    assert "leaves a cavity nowhere as thick as the struts (1.6 mm across)" in plate
    occt = _skin.no_room_message(5.55556, 17.7, strut=5.55556, closed=True, grid=float("nan"))
    assert "nowhere" in occt
