"""A perforated plate (regression, s28's parts made outside shared/data).

A 150 x 100 x 3 mm grille with 344 D3 holes took about 30 s for any fill, and its skin
of 1.67 mm was refused after 62 s:

- the cutting tessellation (``conformal.trim.cutting_part``) guessed its triangle count
  as growing with 1 / chord error from the part's own 60 K triangles, so 44 x finer meant
  2.6 M, over the budget: a BRepMesh trial at 0.0155 mm (60 K triangles, 4.3 s), then one
  at the chord error asked (86 K, 6.1 s). Planes and cylinders grow as the square root of
  it (``Part.triangles_at``): the tessellation asked for is meshed at once;
- ``occ_impl.chord.split_dense_faces`` meshed the whole part once more (a coarse pass,
  2 s) to find dense faces; the part's own counts tell that none can be;
- ``Part.thinner_than`` bounded a cube's depth by its centre's plus its half-diagonal:
  to prove the 3 mm plate thinner than 1.625 mm, cubes of 0.1 mm, 4.8 M distance
  queries, over the budget, and OCCT's offsets (which cannot succeed) were waited for
  (43 s). An octant's depth is now bounded by its distance to the surface point nearest
  its corner, which grows with the square of its size along a flat wall.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from conformal import load_part, trim
from conformal import skin as _skin
from conformal.part import Part
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeWarning


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    """A 120 x 80 x 3 mm plate with 13 x 19 = 247 D3 holes on a 6 mm pitch."""
    import cadquery as cq

    wp = cq.Workplane("XY").box(120, 80, 3).faces(">Z").workplane().rarray(6, 6, 19, 13).hole(3)
    path = tmp_path_factory.mktemp("plate") / "perforated_plate.step"
    cq.exporters.export(wp, str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        return load_part(path)


def test_the_triangle_bound_holds_and_the_cut_is_meshed_once(plate, monkeypatch, refined_calls):
    r = 0.6667  # the parts benchmark's radius for a 120 mm part
    want = trim._wanted(plate, r, None)
    bound = plate.triangles_at(want)
    # from the part's own counts: a bound, and under the budget (1 / chord error: 2 M)
    assert bound is not None and bound < config.CUT_MAX_TRIANGLES
    assert plate.deflection * len(plate.faces) / want > config.CUT_MAX_TRIANGLES
    calls = refined_calls
    meshes = []
    from lattice_cad.occ_impl import chord

    real_mesh = chord._mesh
    monkeypatch.setattr(chord, "_mesh", lambda *a: (meshes.append(a[1]), real_mesh(*a))[1])
    with warnings.catch_warnings():
        warnings.simplefilter("error", LatticeWarning)  # no budget warning either
        cut = trim.cutting_part(plate, r)
    assert calls == [(pytest.approx(want), True)]  # no trial
    # no coarse pass of split_dense_faces (at MESH_SPLIT_COARSE x the chord error)
    assert not [d for d in meshes if d > 2 * want]
    assert cut.deflection == pytest.approx(want)
    assert len(cut.faces) <= bound
    assert trim.cut_shortfall(plate, cut, r) is None
    # the tessellation reached the chord error: the holes' polygons hold their area
    assert len(cut.faces) > 2 * len(plate.faces) / 3


def _slab(extents, holes=0):
    import manifold3d

    box = manifold3d.Manifold.cube(extents, center=True)
    for k in range(holes):
        x = -0.4 * extents[0] + 0.8 * extents[0] * (k % 10) / 9
        y = -0.4 * extents[1] + 0.8 * extents[1] * (k // 10) / max(1, (holes - 1) // 10)
        hole = manifold3d.Manifold.cylinder(2 * extents[2], 1.5, 1.5, 48, center=True)
        box = box - hole.translate((x, y, 0.0))
    m = box.to_mesh()
    return Part(np.asarray(m.vert_properties[:, :3], dtype=np.float64), np.asarray(m.tri_verts))


@pytest.mark.parametrize("holes", [0, 40])
def test_a_wide_thin_plate_is_proven_within_the_no_room_budget(holes):
    plate = _slab((150.0, 100.0, 3.0), holes)
    # 1.5 mm deep at most (the mid-plane): proven with 0.125 mm to spare, within the
    # budget the skin spends (before: 4.8 M queries wanted, not proven)
    assert plate.thinner_than(1.625, budget=_skin.NO_ROOM_BUDGET)
    assert plate.thinner_than(1.55, budget=_skin.NO_ROOM_BUDGET)
    # and never a false statement: points of the mid-plane are 1.5 mm deep
    assert not plate.thinner_than(1.499, budget=_skin.NO_ROOM_BUDGET)
    assert not plate.thinner_than(1.0, budget=_skin.NO_ROOM_BUDGET)


def test_the_bound_of_an_octant_holds_on_a_rotated_ball(rng):
    # the depth of a ball's centre is its radius; whatever the grid, never proven below
    ball = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    ball.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
    part = Part(np.asarray(ball.vertices), np.asarray(ball.faces))
    centre = np.asarray(ball.vertices).mean(axis=0)
    depth = float(part.distance(centre[None])[0])
    assert not part.thinner_than(0.999 * depth)
    assert part.thinner_than(1.05 * depth)


@pytest.mark.slow
def test_the_plate_skin_with_no_room_is_refused_without_the_offsets(plate, monkeypatch):
    from lattice_cad import Lattice

    class Waited(BaseException):  # not caught as an OCCT failure (those fall back)
        pass

    def waited(*a, **k):
        raise Waited("OCCT's offsets were waited for")

    monkeypatch.setattr(_skin, "_occt_surfaces", waited)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(plate, "octet", 8.0, 0.6667, skin=1.6667)
        with pytest.raises(_skin.SkinError, match="nowhere thicker than twice the skin"):
            lat.mesh()
