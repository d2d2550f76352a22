"""Seams of mesh files that do not match (regression, s26's parts made outside shared/data):
an STL with every triangle stored twice was refused for 3,051 non-manifold edges, a block
whose top face is meshed finer than its sides (T-junctions) for "24 open edges around 5
holes" (with advice to patch them), and a housing whose T-junctions were patched with
zero-area slivers loaded "crossing itself in 107 pairs". Each is the same surface; it now
loads as that solid, with a warning saying what was mended (``conformal.seams``)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conformal import load_part
from conformal.seams import drop_duplicate_faces, drop_slivers, split_t_junctions
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import DATA


@pytest.fixture(scope="module")
def fandisk():
    """The shared fandisk with float32 vertices (as an STL stores them) and its volume."""
    part = load_part(DATA / "meshes" / "fandisk.obj")
    v = np.asarray(part.vertices).astype(np.float32).astype(np.float64)
    f = np.asarray(part.faces)
    return v, f, trimesh.Trimesh(v, f, process=False).volume


def _stl(path, v, f):
    trimesh.Trimesh(v, f, process=False).export(path)


def _t_junctions(v, f, count, seed=0):
    """Split ``count`` interior edges' first triangle at the edge's midpoint (its other
    triangle keeps the whole edge): T-junctions. Returns vertices, faces, the new
    vertices' (a, m, b) triples."""
    rng = np.random.default_rng(seed)
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    face = np.tile(np.arange(len(f)), 3)
    corner = np.repeat(np.arange(3), len(f))
    used = np.zeros(len(f), dtype=bool)
    v = v.copy()
    new, drop, triples = [], [], []
    for j in rng.permutation(len(he)):
        if len(triples) == count:
            break
        a, b = he[j]
        twin = np.flatnonzero((he[:, 0] == b) & (he[:, 1] == a))
        fi, fo = face[j], face[twin[0]]
        if used[fi] or used[fo]:
            continue
        used[fi] = used[fo] = True
        c = f[fi, (corner[j] + 2) % 3]
        m = len(v)
        v = np.vstack([v, 0.5 * (v[a] + v[b])])
        new += [[a, m, c], [m, b, c]]
        drop.append(fi)
        triples.append((a, m, b))
    keep = np.ones(len(f), dtype=bool)
    keep[drop] = False
    return v, np.vstack([f[keep], np.asarray(new)]), triples


def test_every_triangle_stored_twice_loads_once(tmp_path, fandisk):
    v, f, vol = fandisk
    path = tmp_path / "twice.stl"
    _stl(path, v, np.vstack([f, f]))
    with pytest.warns(LatticeWarning, match=r"\d+ triangle\(s\) stored twice were kept once"):
        part = load_part(path)
    assert len(part.faces) == len(f)
    assert part.volume == pytest.approx(vol, rel=1e-12)
    assert part.self_crossings[0] == 0


def test_two_bodies_touching_along_coincident_triangles_are_united():
    """A triangle and its reverse are a wall of no thickness: both go."""
    f = np.array([[0, 1, 2], [0, 1, 2], [2, 1, 0], [3, 4, 5]])
    g, same, opposite = drop_duplicate_faces(f)
    assert g.tolist() == [[3, 4, 5]] and same == 1 and opposite == 1


def test_t_junctions_in_a_real_part_are_split_to_its_solid(tmp_path, fandisk):
    v, f, vol = fandisk
    v2, f2, _ = _t_junctions(v, f, 25)
    path = tmp_path / "t.stl"
    _stl(path, v2, f2)
    with pytest.warns(LatticeWarning, match=r"25 triangle\(s\) were split .* \(T-junctions\)"):
        part = load_part(path)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert part.volume == pytest.approx(vol, rel=1e-9)
    assert part.self_crossings[0] == 0


def test_slivers_patching_t_junctions_are_removed(tmp_path, fandisk):
    v, f, vol = fandisk
    v2, f2, triples = _t_junctions(v, f, 25, seed=1)
    slivers = np.array([[b, m, a] for a, m, b in triples])  # closes each T-junction
    f3 = np.vstack([f2, slivers])
    assert trimesh.Trimesh(v2, f3, process=False).is_watertight  # closed, yet crossing
    path = tmp_path / "slivers.stl"
    _stl(path, v2, f3)
    with pytest.warns(LatticeWarning, match=r"25 zero-area triangle\(s\) .* removed"):
        part = load_part(path)
    assert part.self_crossings[0] == 0  # was 25 or more pairs
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert part.volume == pytest.approx(vol, rel=1e-9)


def test_a_shared_file_whose_non_manifold_edge_is_zero_area_loads():
    """shared/data's wallhole OBJ (Rhino): its one non-manifold edge is made by two
    zero-area triangles facing opposite ways, and 7 more slivers patch T-junctions; the
    solid they bound is the file's own (its signed volume, by trimesh)."""
    path = DATA / "broken" / "trimesh_wallhole_open.obj"
    with pytest.warns(LatticeWarning, match=r"1 pair\(s\) of coincident triangles .*slivers"):
        part = load_part(path)
    raw = trimesh.load(path, force="mesh", process=False)  # fans; the signed volume holds
    assert part.volume == pytest.approx(raw.volume, rel=1e-12)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert part.self_crossings[0] == 0


def test_a_vertex_off_the_edge_is_no_t_junction():
    v = np.array([[0, 0, 0], [2, 0, 0], [1, 1, 0], [1, 1e-3, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2]])
    g, n = split_t_junctions(v, np.vstack([f, [[1, 0, 3]]]), 1e-6)
    assert n == 0
    g, n = drop_slivers(v, np.array([[1, 0, 3]]), 1e-6)
    assert n == 0 and len(g) == 1


def _beside(path, v, f, extents, at):
    """An STL at ``path`` of the mesh (v, f) and a box of ``extents`` centred at ``at``."""
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(at)
    trimesh.util.concatenate([trimesh.Trimesh(v, f), box]).export(path)
    return path


def test_a_speck_beside_a_real_part_is_left_out_as_debris(tmp_path, fandisk):
    """Regression (s26, a bracket STL with a 0.05 mm tetrahedron 4 mm beside it, made
    outside shared/data): the speck was united with the part, and a skin wrote it as a
    second, unprintable body. A closed shell under 1 % of the part's size and 1e-6 of its
    volume is left out with a warning; a small body that is not debris stays."""
    v, f, vol = fandisk
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    path = _beside(tmp_path / "speck.stl", v, f, [2e-3 * size] * 3, hi + 0.05 * size)
    with pytest.warns(LatticeWarning, match=r"1 tiny closed shell\(s\) beside the part were left "
                      r"out as debris \([\d.e-]+ mm across(, [\d.e-]+ mm thick)? at"):  # fmt: skip
        part = load_part(path)
    assert len(part.faces) == len(f)
    assert part.volume == pytest.approx(vol, rel=1e-9)
    # a body of 5 % of the part's size is kept (and united with it, as before)
    path = _beside(tmp_path / "two.stl", v, f, [0.05 * size] * 3, hi + 0.1 * size)
    with pytest.warns(LatticeWarning, match="2 bodies, none overlapping another, make one part"):
        part = load_part(path)
    assert part.volume == pytest.approx(vol + (0.05 * size) ** 3, rel=1e-6)


def test_a_sheet_of_no_thickness_beside_a_real_part_is_left_out_as_debris(tmp_path, fandisk):
    """Regression (s29, a bracket STL with a 30 x 20 mm face an exporter thickened to
    0.1 um beside it, made outside shared/data): not a speck (30 mm across), it was united
    with the part; a tet fill cut a lattice down to that sheet and wrote it as a second
    body of 0.018 mm^3, a skin copied it through. A shell thinner (2 V / A) than 1e-4 of the
    part's size is debris too; a thin plate that prints is not."""
    v, f, vol = fandisk
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    extents = [0.5 * size, 0.3 * size, 1e-6 * size]
    path = _beside(tmp_path / "sheet.stl", v, f, extents, hi + 0.2 * size)
    with pytest.warns(LatticeWarning, match=r"left out as debris \([\d.e-]+ mm across, "
                      r"[\d.e-]+ mm thick at"):  # fmt: skip
        part = load_part(path)
    assert len(part.faces) == len(f)
    assert part.volume == pytest.approx(vol, rel=1e-9)
    # a plate 1e-2 of the part's size thick is kept
    extents = [0.5 * size, 0.3 * size, 1e-2 * size]
    path = _beside(tmp_path / "plate.stl", v, f, extents, hi + 0.2 * size)
    with pytest.warns(LatticeWarning, match="2 bodies, none overlapping another, make one part"):
        part = load_part(path)
    assert part.volume == pytest.approx(vol + float(np.prod(extents)), rel=1e-6)
