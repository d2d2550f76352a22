"""Trim on parts made of several solids (issue 13 item 2, the parts benchmark's fallbacks).

bench_parts (cell = largest extent / 15, r = cell / 12) wrote the UNCUT lattice with a
"NOT cut" report on kcl_enclosure (tet, 100 % of r outside) and trimesh_box_sides (bcc
152 %, tet 151 %). The cause was the part, not the lattice: the solids of these files
touch, each solid is tessellated on its own, and the shared faces came out a float64 ulp
or two apart (z = 204.7674172753175 against 204.76741727531748); manifold3d's exact union
kept a slit of zero thickness there, so the part's own surface self-intersected and every
cut by it inherited folded, coplanar triangles that float32 rounding could not hold.
``conformal.part`` now rounds the solids to one grid before the union.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import fast_stitch
from conformal import load_part
from conformal.trim import cutting_part, protrusion
from lattice_cad import Lattice
from lattice_cad.core import config
from lattice_cad.core.mesh import Mesh
from tests.conftest import DATA

STEP = DATA / "step"
pytestmark = pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")


@pytest.mark.parametrize(
    "name", ["trimesh_box_sides.STEP", "kcl_enclosure.step", "kcl_bracket.step"]
)
def test_touching_solids_give_a_surface_without_self_intersections(name):
    part = load_part(STEP / name)
    report = fast_stitch.check(Mesh(vertices=part.vertices, faces=part.faces))
    assert report.valid, str(report)
    # independent: pymeshlab finds no self-intersecting face either
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(part.vertices, part.faces))
    ms.compute_selection_by_self_intersections_per_face()
    assert ms.current_mesh().selected_face_number() == 0
    tm = trimesh.Trimesh(part.vertices, part.faces)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0


def _bench_fill(name: str, **kw) -> tuple[Lattice, object]:
    part = load_part(STEP / name)
    cell = float(np.max(part.size)) / 15
    return Lattice.fill(part, cell_size=cell, radius=cell / 12, **kw), part


def _assert_cut_and_valid(lat: Lattice, part) -> None:
    m = lat.mesh()
    rep = lat.trim_report
    assert not rep.failed, rep.summary()
    assert rep.trimmed and rep.within_tolerance
    assert rep.tolerance == pytest.approx(config.TRIM_RTOL * float(lat.graph.radii.max()))
    # cut by the B-rep tessellated again for r (conformal.trim.cutting_part): checked on it
    part = cutting_part(part, float(lat.graph.radii.max()))
    assert protrusion(part, m.vertices) <= rep.tolerance
    assert fast_stitch.check(m).valid
    # independent: trimesh (vertices merged) sees a closed solid, and every vertex is
    # inside or within the tolerance of the part
    tm = trimesh.Trimesh(m.vertices, m.faces)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    tm_part = trimesh.Trimesh(part.vertices, part.faces)
    sample = m.vertices[:: max(1, len(m.vertices) // 4000)]
    assert trimesh.proximity.signed_distance(tm_part, sample).min() >= -rep.tolerance


@pytest.mark.slow
def test_box_sides_bcc_is_cut_to_the_part():
    lat, part = _bench_fill("trimesh_box_sides.STEP", cell="bcc")
    _assert_cut_and_valid(lat, part)


@pytest.fixture(scope="module")
def kcl_enclosure_tet() -> tuple[Lattice, object]:
    """The bench tet fill of kcl_enclosure, built once: both tests below check the same fill
    (the cut and validity, and the bodies), neither changes it (the mesh is cached)."""
    return _bench_fill("kcl_enclosure.step", method="tet")


@pytest.mark.slow
def test_kcl_enclosure_tet_is_cut_to_the_part(kcl_enclosure_tet):
    lat, part = kcl_enclosure_tet
    _assert_cut_and_valid(lat, part)


@pytest.mark.slow
def test_box_sides_tet_is_cut_to_the_part():
    lat, part = _bench_fill("trimesh_box_sides.STEP", method="tet")
    _assert_cut_and_valid(lat, part)


def test_a_point_on_a_solids_surface_belongs_to_that_solid():
    """Regression (kcl_enclosure, tet): points that no solid contains (on a surface) went to
    solid 0, so a speck cut off on solid 1's surface was kept as solid 0's "largest piece"."""
    from conformal.part import Part
    from conformal.voxel import _solid_shells, shell_owner

    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.box(extents=(1, 1, 1))
    b.apply_translation((3, 0, 0))
    both = trimesh.util.concatenate([a, b])
    shells = _solid_shells(Part(both.vertices, both.faces))
    assert len(shells) == 2
    points = np.array([[3.5, 0.0, 0.0], [3.2, 0.5, 0.1], [0.5, 0.2, 0.2], [0.1, 0.1, 0.1]])
    owner = shell_owner(shells, points)
    # whichever order the shells come in, each point goes to the box whose surface it is on
    # (or inside which it lies): the first two to the box at x = 3, the others to the box at 0
    at3 = [int(s.triangles[:, :, 0].min() > 1) for s in shells]
    assert [at3[o] for o in owner] == [1, 1, 0, 0]


@pytest.mark.slow
def test_kcl_enclosure_tet_gives_one_body_without_specks(kcl_enclosure_tet):
    """The bench setting gave a second body of 8 triangles (8.7e-5 mm^3) on the surface."""
    lat, _ = kcl_enclosure_tet
    m = lat.mesh()
    tm = trimesh.Trimesh(m.vertices, m.faces)
    bodies = tm.split(only_watertight=False)
    assert len(bodies) == 1, [(len(b.faces), b.volume) for b in bodies]
    assert lat.trim_report.bodies == 1


def test_a_solid_whose_largest_piece_is_a_fragment_keeps_none():
    """A scan's 0.8 mm blob beside its body loads as a solid of its own; the conform fill's
    cut kept in it a 0.2 mm fragment of a strut (0.0003 mm^3) as that solid's largest piece:
    a second body of no use (s31, made outside shared/data). A solid's largest piece under
    a strut stub as long as it is thick (2 pi r^3) is removed now; the largest of all stays."""
    import trimesh as _tm

    from conformal.part import Part
    from conformal.trim import _largest_per_solid

    body = _tm.creation.box(extents=(20, 20, 20))
    blob = _tm.creation.box(extents=(0.8, 0.8, 0.8))
    blob.apply_translation((15, 0, 0))
    both = _tm.util.concatenate([body, blob])
    part = Part(np.asarray(both.vertices), np.asarray(both.faces, dtype=np.int64), name="two")
    assert len(part.solid_parts) == 2
    in_body, in_blob = np.array([[1.0, 2.0, 3.0]]), np.array([[15.1, 0.1, -0.1]])
    samples = [in_body, in_blob, in_body]
    r = 0.44  # 2 pi r^3 = 0.535 mm^3
    assert _largest_per_solid(part, np.array([100.0, 3e-4, 50.0]), samples, radius=r) == [0]
    assert _largest_per_solid(part, np.array([100.0, 0.6, 50.0]), samples, radius=r) == [0, 1]
    # the largest of all is kept however small
    assert _largest_per_solid(part, np.array([1e-4, 3e-5, 1e-5]), samples, radius=r) == [0]
