"""conformal.skin_split: the skin's booleans on the struts near the wall only, the deep ones
glued back, give the same solid as the booleans on the whole lattice (real parts)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import fast_stitch
from conformal import load_part, skin_split
from lattice_cad.core.errors import ExternalCrash, LatticeWarning
from lattice_cad.core.isolate import IsolatedWorker
from lattice_cad.lattice import Lattice
from tests.conftest import DATA, assert_valid


def _triangles(mesh) -> np.ndarray:
    """(F, 9) float64: each triangle's corners from its smallest, rows sorted (a mesh's
    triangles as a set, independent of vertex and face order)."""
    t = mesh.vertices[mesh.faces]  # (F, 3, 3)
    first = np.lexsort((t[:, :, 2], t[:, :, 1], t[:, :, 0]), axis=1)[:, 0]
    idx = np.arange(len(t))
    rot = np.stack([t[idx, (first + k) % 3] for k in range(3)], axis=1).reshape(len(t), 9)
    return rot[np.lexsort(rot.T[::-1])]


def _fill(name: str, per: float, profile: str = "volume"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # solids united, struts thinned
        part = load_part(DATA / name)
        cell = float(part.size.max()) / per
        return Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6, profile=profile)


@pytest.mark.parametrize(
    ("name", "per", "profile"),
    [
        ("step/kcl_flange-with-patterns.step", 10, "volume"),
        ("meshes/bunny_closed_odedstein.obj", 10, "volume"),
        # unbanded struts: the split was never used (its layout test read P = 6 as a
        # banded P = 3, whose counts agree for every even P) and the whole lattice went
        # through the booleans
        ("step/kcl_flange-with-patterns.step", 10, "area"),
    ],
)
def test_split_skin_equals_the_skin_of_the_whole_lattice(name, per, profile, monkeypatch):
    lat = _fill(name, per, profile)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        mesh = lat.mesh()
    split = lat.skin_report.split
    assert split and split["deep"] > 0 and split["near"] > 0, lat.skin_report
    assert fast_stitch.check(mesh).valid
    assert_valid(mesh, self_intersections=False)
    assert lat.skin_report.bodies == 1
    # the same lattice with the booleans on all of it
    monkeypatch.setattr(skin_split, "split_lattice", lambda *a, **k: None)
    whole = _fill(name, per, profile)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        ref = whole.mesh()
    assert not whole.skin_report.split
    assert len(mesh.faces) == len(ref.faces) and len(mesh.vertices) == len(ref.vertices)
    np.testing.assert_array_equal(_triangles(mesh), _triangles(ref))


@pytest.fixture(scope="module")
def flange_split():
    """The flange's skinned lattice split at its voxel inner wall (struts near it, caps)."""
    lat = _fill("step/kcl_flange-with-patterns.step", 10)
    from conformal import skin
    from conformal.part import Part

    p = lat.part
    h = skin._grid_spacing(p.size, lat.skin)
    inner = skin._voxel_surfaces(p, lat.skin, h)[0][1]
    m = lat._lattice_mesh
    split = skin_split.split_lattice(
        lat.graph, m.vertices, m.faces, Part(*skin.to_arrays(inner)), margin=0.02
    )
    assert split is not None and len(split.caps)
    return split


def test_glue_refuses_a_result_without_its_caps(flange_split):
    split = flange_split
    # the near part alone, as a boolean that changed nothing would give it back
    v, f = split.near_vertices, split.near_faces
    glued = split.glue(v, f)
    assert glued is not None
    assert len(glued[1]) == len(f) - len(split.caps) + len(split.deep_faces)
    gm = fast_stitch.check((glued[0], glued[1]), self_intersections=False)
    assert gm.valid, gm  # closed, 2-manifold, consistently oriented, nothing flat
    # a cap missing (as when a boolean cut it): None, and the caller uses the whole lattice
    cap = np.sort(split.deep_vertices[split.caps[0]], axis=0)
    tri = np.sort(v[f], axis=1)
    hit = np.flatnonzero(np.all(tri == cap[None], axis=(1, 2)))
    assert len(hit) == 1
    assert split.glue(v, np.delete(f, hit, axis=0)) is None


def test_glue_past_21_bit_vertex_indices_equals_the_packed_keys(flange_split, monkeypatch):
    """Regression (s22's 2 mm micro cube STL, conform): glue packed a triangle's vertex
    indices in 21 bits each and gave up above 2**21 (2,097,152) vertices, so the whole
    lattice was trimmed again (122 s against 32 s for the same cube from STEP). Past it,
    the keys are the rows themselves; forced here, they glue the same mesh."""
    split = flange_split
    v, f = split.near_vertices, split.near_faces
    packed = split.glue(v, f)
    assert packed is not None
    monkeypatch.setattr(skin_split, "_PACKED_KEYS", 0)
    keys = skin_split._face_keys(f, np.int64(len(v)))
    assert keys.dtype.kind == "V"
    # the three rotations of a triangle share a key, the reversed triangle has its own
    rolled = skin_split._face_keys(np.roll(f, 1, axis=1), np.int64(len(v)))
    assert np.array_equal(keys, rolled)
    assert not np.any(keys == skin_split._face_keys(f[:, ::-1], np.int64(len(v))))
    rows = split.glue(v, f)
    assert rows is not None
    np.testing.assert_array_equal(rows[0], packed[0])
    np.testing.assert_array_equal(rows[1], packed[1])
    # a cap missing: None with either key
    cap = np.sort(split.deep_vertices[split.caps[0]], axis=0)
    hit = np.flatnonzero(np.all(np.sort(v[f], axis=1) == cap[None], axis=(1, 2)))
    assert split.glue(v, np.delete(f, hit, axis=0)) is None


def test_split_refuses_a_mesh_that_is_not_the_stitchers():
    lat = _fill("step/kcl_flange-with-patterns.step", 10)
    m = lat._lattice_mesh
    from conformal.part import Part

    part = Part(lat.part.vertices, lat.part.faces)
    assert skin_split.split_lattice(lat.graph, m.vertices, m.faces[::-1], part, margin=0.02) is None
    assert skin_split.split_lattice(lat.graph, m.vertices[:-6], m.faces, part, margin=0.02) is None


@pytest.fixture(scope="module")
def flange_graph():
    """An octet lattice graph of the flange (clipped at its surface: leaves, hubs of every
    degree)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        part = load_part(DATA / "step/kcl_flange-with-patterns.step")
        cell = float(part.size.max()) / 6
        return Lattice.fill(part, "octet", cell, cell / 16).graph


@pytest.mark.parametrize("segments", [6, 7, 8])
@pytest.mark.parametrize("profile", ["volume", "area", "inscribed", "circumscribed"])
def test_the_layout_of_every_profile_is_read_with_its_segments(flange_graph, segments, profile):
    """The stitcher's layout is recognised for every profile, with its own P: unbanded
    (2 M P vertices) at an even P has the counts of banded at P / 2."""
    m = fast_stitch.stitch(flange_graph, segments, profile=profile)
    lay = skin_split._layout(flange_graph, m.vertices, m.faces)
    assert lay is not None and lay[0] == segments
    assert (lay[1][2] >= 0) == (profile == "volume")  # the first band row, or -1


def test_isolated_worker_result_error_and_crash():
    w = IsolatedWorker(warm="json")
    w.submit(divmod, 17, 5)
    assert w.result(timeout=60, what="divmod") == (3, 2)
    w = IsolatedWorker()
    w.submit(divmod, 1, 0)
    with pytest.raises(ZeroDivisionError):
        w.result(timeout=60, what="divmod")
    import os

    w = IsolatedWorker()
    w.submit(os.abort)
    with pytest.raises(ExternalCrash, match="abort crashed"):
        w.result(timeout=60, what="abort")


def test_pieces_equal_manifold_decompose_on_a_real_part():
    """skin_split.pieces (what SplitLattice.bodies counts, on the arrays) gives the pieces
    manifold3d's decompose gives: a real part with a spherical cavity (a negative piece), a
    ball inside the cavity and a loose copy of the part beside it."""
    import manifold3d

    from conformal.skin import as_manifold, to_arrays

    part = load_part(DATA / "meshes" / "fandisk.obj")
    solid = as_manifold(part)
    size = np.asarray(part.size, dtype=np.float64)
    centre = list(np.asarray(part.vertices, dtype=np.float64).mean(axis=0))
    r = 0.1 * float(size.min())
    cavity = manifold3d.Manifold.sphere(r, 48).translate(centre)
    ball = manifold3d.Manifold.sphere(0.5 * r, 24).translate(centre)
    loose = solid.translate([2.0 * float(size[0]), 0.0, 0.0])
    whole = (solid - cavity) + ball + loose
    v, f = to_arrays(whole)
    n, vlabel, vols = skin_split.pieces(v, f)
    expected = sorted(p.volume() for p in whole.decompose())
    assert n == len(expected) == 4 and expected[0] < 0  # the cavity wall
    assert np.allclose(sorted(vols), expected, rtol=1e-9, atol=1e-12)
    assert (vlabel >= 0).all() and set(np.unique(vlabel)) == set(range(n))
    assert (vlabel[f] == vlabel[f[:, :1]]).all()  # a triangle's corners lie in one piece


def _sphere(r: float, centre=(0.0, 0.0, 0.0)):
    import manifold3d

    return manifold3d.Manifold.sphere(r, 64).translate(centre)


def test_outer_minus_a_cavity_clear_of_the_wall_is_composed_without_a_boolean():
    """A cavity inside the inner surface, the wall at least half the thickness: the outer
    surface's triangles and the cavity's reversed, the same set as manifold3d's boolean."""
    from conformal import skin
    from conformal.part import Part
    from lattice_cad.core.mesh import Mesh

    outer, inner = _sphere(10.0), _sphere(8.0)
    cavity = inner - _sphere(3.0, (0.0, 0.0, 7.5))  # a "strut" reaching into the wall
    surface = Part(*skin.to_arrays(outer), name="outer")
    wall = skin.wall_thickness(inner, surface)
    got = skin._outer_minus(outer, cavity, inner, surface, wall, 2.0)
    assert isinstance(got, Mesh)
    ref = outer - cavity
    v, f = skin.to_arrays(ref)
    np.testing.assert_array_equal(_triangles(got), _triangles(Mesh(vertices=v, faces=f)))
    assert fast_stitch.check(got).valid
    assert got.volume == pytest.approx(ref.volume(), rel=1e-9)


def test_outer_minus_falls_back_to_the_boolean_when_the_wall_is_thin_or_crossed():
    from conformal import skin
    from conformal.part import Part

    outer = _sphere(10.0)
    surface = Part(*skin.to_arrays(outer), name="outer")
    # wall 0.5 for a thickness 2: under COMPOSE_CLEARANCE
    inner = _sphere(9.5)
    got = skin._outer_minus(outer, inner, inner, surface, skin.wall_thickness(inner, surface), 2.0)
    assert hasattr(got, "status")  # a manifold3d.Manifold: the boolean
    # an "inner" surface partly outside the outer one: distances alone would pass
    shifted = _sphere(8.0, (0.0, 0.0, 16.0))
    wall = skin.wall_thickness(shifted, surface)
    got = skin._outer_minus(outer, shifted, shifted, surface, np.full_like(wall, 2.0), 2.0)
    assert hasattr(got, "status")  # a manifold3d.Manifold: the boolean
    assert got.volume() == pytest.approx((outer - shifted).volume())
