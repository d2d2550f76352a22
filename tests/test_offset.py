"""Skin walls: OCCT's offset on more real parts, and the voxel fallback's accuracy (issue 11,
item 2). Closed forms (a box and a sphere eroded by t) and an independent measure (random
points on the inner surface, by trimesh, against a finer tessellation of the B-rep) judge
the walls; the wall definition is the distance from the inner surface to the outer one.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from conformal import load_part
from conformal import skin as S
from conformal.part import Part
from lattice_cad.core.errors import CutBudgetWarning, LatticeWarning, OCCTFailure
from tests.conftest import DATA


def _part(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        return load_part(DATA / "step" / name)


@pytest.mark.slow
def test_cycloidal_gear_skin_by_occt_offset():
    """The cycloidal gear's B-spline flanks are only C0: OCCT refused the offset
    (BRepOffset_C0Geometry) and the wall came from the voxel field (up to +26 % of t).
    Its faces are now split into C1 patches first: OCCT's offset, wall within 2 %."""
    import manifold3d
    import trimesh

    from conformal.trim import cutting_part
    from lattice_cad.occ_impl import shapes as occ

    part = _part("kcl_cycloidal-gear.step")
    cell = float(part.size.max()) / 15  # the parts benchmark's setting
    t = float(f"{cell / 6:.6g}")
    with warnings.catch_warnings():  # the gear's flanks take the whole triangle budget
        warnings.simplefilter("ignore", CutBudgetWarning)  # (0.70 % r reached, 0.5 % asked)
        cut = cutting_part(part, cell / 12)
    res = S.build_skin(manifold3d.Manifold(), cut, t, method="occt", check=False)
    rep = res.report
    tol = S.wall_tolerance(t)
    assert rep.method == "occt" and not rep.fallback, rep.summary()
    assert rep.accurate, rep.summary()
    assert abs(rep.wall["min"] - t) <= tol and abs(rep.wall["max"] - t) <= tol
    # independent: random points of the inner surface against a finer mesh of the B-rep
    solid = list(part.shape)[0]
    fine = Part(*occ.tessellate(solid, 0.002 * t, 0.1), name="fine")
    inner = S._occt_surfaces(cut, t)[1]
    v, f = S.to_arrays(inner)
    pts = trimesh.Trimesh(v, f).sample(20000, seed=7)
    d = fine.distance(pts)
    assert np.all(np.abs(d - t) <= tol), (d.min(), d.max(), t)
    # the inner solid is inside the part and smaller by about area * t
    assert 0 < inner.volume() < occ.volume(solid)


def test_occt_offset_failure_names_the_offset_error():
    """A part OCCT cannot offset (the countersunk screw: an edge both tangent and sharp
    along its length) fails with OCCT's own error code for each way tried."""
    from lattice_cad.occ_impl import shapes as occ

    solid = list(_part("build123d_M6-1x12-countersunk-screw.step").shape)[0]
    err = r"arc joins\): IsDone\(\) is false \(MixedConnectivity"
    with pytest.raises(OCCTFailure, match=err) as e:
        occ.offset_solid(solid, -0.1333)
    assert "intersection joins" in str(e.value)


def _box_part(size, angle: float = 0.0) -> Part:
    import trimesh

    m = trimesh.creation.box(size)
    if angle:
        m.apply_transform(trimesh.transformations.rotation_matrix(angle, [1, 2, 3]))
    m.apply_translation(-m.bounds[0] + 0.123)
    return Part(m.vertices, m.faces, name="box")


@pytest.fixture
def sharpen_creases(monkeypatch):
    """The voxel method with its creases put back (``conformal.skin.SHARPEN_CREASES``)."""
    monkeypatch.setattr(S, "SHARPEN_CREASES", True)


@pytest.mark.usefixtures("sharpen_creases")
def test_voxel_fallback_wall_on_a_box_is_within_a_tenth_of_a_voxel():
    """The inset of a box by t is the box shrunk by t on every side (closed form); the
    voxel surface's creases are put back (conformal.skin_crease), so the wall is within
    max(2 % of t, a tenth of the voxel) everywhere (was +5.6 % at vertices and +8 % at
    random points, the chamfered edges)."""
    import trimesh

    t = 1.0
    part = _box_part((20, 16, 12))
    h = S._grid_spacing(part.size, t)
    cav = S.inset(part, t)  # the voxel field (forced: a mesh part)
    lo, hi = np.asarray(cav.bounding_box()).reshape(2, 3)
    np.testing.assert_allclose(lo, part.bounds[0] + t, atol=0.02 * t)
    np.testing.assert_allclose(hi, part.bounds[1] - t, atol=0.02 * t)
    assert cav.volume() == pytest.approx(18 * 14 * 10, rel=1e-3)
    goal = max(0.02 * t, 0.1 * h)
    wall = S.wall_thickness(cav, part)
    assert np.abs(wall - t).max() <= goal, (wall.min(), wall.max())
    v, f = S.to_arrays(cav)
    d = part.distance(trimesh.Trimesh(v, f).sample(20000, seed=3))
    assert np.abs(d - t).max() <= goal, (d.min(), d.max())


@pytest.mark.usefixtures("sharpen_creases")
def test_voxel_fallback_wall_on_a_sphere():
    """Sphere of radius R eroded by t: the sphere of radius R - t (against the mesh the
    wall is measured by: every inner point at t from it within 2 %)."""
    import trimesh

    R, t = 10.0, 1.5
    m = trimesh.creation.icosphere(subdivisions=5, radius=R)
    part = Part(m.vertices + 12.3, m.faces, name="sphere")
    cav = S.inset(part, t)
    v, f = S.to_arrays(cav)
    r = np.linalg.norm(v - 12.3, axis=1)
    chord = R - np.linalg.norm(m.triangles_center, axis=1).min()  # the mesh's own error
    assert np.abs(r - (R - t)).max() < 0.02 * t + chord
    wall = S.wall_thickness(cav, part)
    d = part.distance(trimesh.Trimesh(v, f).sample(20000, seed=5))
    assert np.abs(wall - t).max() <= 0.02 * t, (wall.min(), wall.max())
    assert np.abs(d - t).max() <= 0.02 * t, (d.min(), d.max())


def test_crease_sharpening_is_closed_and_better_on_a_tilted_box():
    """A box tilted off the grid: the sharpened surface is closed, 2-manifold and valid,
    its volume is the eroded box's within 0.05 % (0.2 % without), and 99 % of random
    points on it are within 2 % of t (the residue: a few vertices at the corners)."""
    import trimesh

    from conformal.skin_crease import sharpen

    t = 1.5
    part = _box_part((20, 14, 9), angle=0.3)
    h = S._grid_spacing(part.size, t)
    depth, origin = S._distance_field(part, t, h)
    v, f = S.marching_tets(depth - t, origin, h)
    v2, f2, counts = sharpen(v, f, part, t, 0.01 * t)
    assert counts["split"] > 0
    before = S._manifold(v, f, "raw")
    after = S._manifold(v2, f2, "sharp")  # raises unless closed and 2-manifold
    exact = 17 * 11 * 6
    assert abs(after.volume() - exact) < 5e-4 * exact
    assert abs(after.volume() - exact) < 0.5 * abs(before.volume() - exact)
    S.checked(after, "the sharpened inset")  # no self-intersections
    d_after = part.distance(trimesh.Trimesh(v2, f2).sample(20000, seed=11))
    d_before = part.distance(trimesh.Trimesh(v, f).sample(20000, seed=11))
    assert np.percentile(np.abs(d_after - t), 99) <= 0.02 * t
    assert np.percentile(np.abs(d_after - t), 99) < 0.5 * np.percentile(np.abs(d_before - t), 99)


def _chamfered_box(a: float, b: float, c: float, leg: float):
    """An a x b x c box with one edge (along z, at x = a, y = b) chamfered by ``leg``."""
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeChamfer
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    from lattice_cad.occ_impl import shapes as occ

    box = BRepPrimAPI_MakeBox(a, b, c).Shape()
    mk = BRepFilletAPI_MakeChamfer(box)
    exp = TopExp_Explorer(box, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        exp.Next()
        lo, hi = occ.bounds(edge)
        if np.allclose(lo[:2], (a, b), atol=1e-6) and np.allclose(hi[:2], (a, b), atol=1e-6):
            mk.Add(leg, edge)
    mk.Build()
    return occ.solids(mk.Shape())[0]


def test_offset_drops_a_chamfer_whose_offset_vanishes():
    """Closed form: a box's chamfer of leg w (45 degrees) on a convex edge vanishes from
    the inward offset by t > w / (2 - sqrt 2): the offset is then the box eroded by t,
    (a - 2t)(b - 2t)(c - 2t), exactly as without the chamfer. OCCT's offset cannot drop a
    face, so the chamfer is removed first (the faces next to it extended)."""
    from lattice_cad.occ_impl import shapes as occ

    a, b, c, w = 20.0, 16.0, 12.0, 0.5
    solid = _chamfered_box(a, b, c, w)
    assert occ.count(solid, occ.TopAbs_FACE) == 7
    threshold = w / (2 - np.sqrt(2))  # 0.854
    assert len(occ.vanishing_faces(solid, -1.0)) == 1  # the chamfer
    assert occ.vanishing_faces(solid, -0.8) == []
    assert occ.vanishing_faces(solid, -0.5) == []
    for t in (1.0, 2.0):
        assert t > threshold
        inner = occ.offset_solid(solid, -t)
        assert occ.is_valid(inner)
        want = (a - 2 * t) * (b - 2 * t) * (c - 2 * t)
        assert occ.volume(inner) == pytest.approx(want, rel=1e-6)
    # below the threshold the chamfer stays, cut back: the offset of the chamfered box
    t = 0.5
    inner = occ.offset_solid(solid, -t)
    cut = (w - (2 - np.sqrt(2)) * t) ** 2 / 2 * (c - 2 * t)  # the smaller chamfer's prism
    want = (a - 2 * t) * (b - 2 * t) * (c - 2 * t) - cut
    assert occ.volume(inner) == pytest.approx(want, rel=1e-6)


@pytest.mark.slow
def test_ge_bracket_skin_by_occt_offset():
    """The GE bracket (5 solids fused into one) has 0.635 mm chamfers at its four bolt
    holes: their offsets vanish beyond t = 1.08 mm, and OCCT's offset returned an invalid
    shape (a valid one 9 mm off after healing), so the skin came from the voxel field
    (wall up to +20 % of t). With the chamfers removed first, the issue's case t = 1.5 takes
    OCCT's path, wall within 2 %; t = 1.0 (the chamfers stay) too."""
    import manifold3d

    from lattice_cad.occ_impl import shapes as occ

    part = _part("dolfiny_ge_bracket_rotated_nonds.step")
    solid = occ.solids(occ.fuse(list(part.shape), simplify=True))[0]
    gone = occ.vanishing_faces(solid, -1.5)
    assert len(gone) == 4
    assert occ.vanishing_faces(solid, -1.0) == []
    fine = Part(*occ.tessellate(solid, 0.002, 0.1), name="fine")
    for t in (1.5, 1.0):
        inner = occ.offset_solid(solid, -t)
        assert occ.is_valid(inner)
        v, f = occ.tessellate(inner, 0.01 * t, 0.1)
        d = fine.distance(np.vstack([v, v[f].mean(axis=1)]))
        tol = S.wall_tolerance(t)
        assert np.all(np.abs(d - t) <= tol), (t, d.min(), d.max())
    res = S.build_skin(manifold3d.Manifold(), part, 1.5, method="auto", check=False)
    rep = res.report
    assert rep.method == "occt" and not rep.fallback, rep.summary()
    assert rep.accurate, rep.summary()


def _face_set(f: np.ndarray) -> np.ndarray:
    """The triangles as a sorted set of rows, each from its smallest vertex (orientation
    kept)."""
    r = np.argmin(f, axis=1)[:, None]
    rot = np.take_along_axis(f, (r + np.arange(3)[None, :]) % 3, axis=1)
    return rot[np.lexsort(rot.T[::-1])]


def test_offsets_meshed_in_the_child_equal_the_meshes_made_here():
    """start_offsets has the child mesh OCCT's offsets too (so that the meshing runs while
    this process stitches): the volumes and meshes it returns equal those made here from
    the same offset of the same real part. The solid itself is measured, not meshed (the
    caller checks the offsets against its own mesh of the part)."""
    from lattice_cad.occ_impl import shapes as occ

    part = _part("kcl_mounting-plate.step")
    t = 1.0
    pending = S.start_offsets(part, t)
    [(vols, meshes)] = occ.fused_offsets_result(pending.worker)
    assert meshes is not None and len(vols) == 2 and len(meshes) == 1
    solid = list(_part("kcl_mounting-plate.step").shape)[0]
    offset = occ.offset_solid(solid, -t)
    assert vols[0] == pytest.approx(occ.volume(solid), rel=1e-12)
    assert vols[1] == pytest.approx(occ.volume(offset), rel=1e-12)
    deflection, angular, merge_tol = S._offset_meshing(t)
    [(v, f)] = meshes
    v2, f2, _ = occ.merge_close(*occ.tessellate(offset, deflection, angular), merge_tol)
    np.testing.assert_array_equal(v, v2)
    np.testing.assert_array_equal(_face_set(f), _face_set(f2))  # (in another order)
    assert 0 < vols[1] < vols[0]
