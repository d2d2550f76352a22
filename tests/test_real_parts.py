"""Regressions on real parts from ../shared/data, one per failure class of the real-parts
issue: skins (OCCT offset and voxel fallback), tet lattices (the seed's Table 5 case, mesh
inputs), thin parts, islands. Independent checkers (trimesh, manifold3d, pymeshlab) judge the
meshes beside our own checker.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import fast_stitch
from conformal import load_part, tet_lattice
from lattice_cad.core.errors import LatticeWarning
from lattice_cad.lattice import Lattice
from tests.conftest import DATA, assert_valid, independent_check


def _part(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # solids united
        return load_part(DATA / name)


def _bodies(mesh) -> int:
    import manifold3d

    man = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=mesh.vertices.astype(np.float32),
            tri_verts=mesh.faces.astype(np.uint32),
        )
    )
    return sum(1 for p in man.decompose() if p.volume() > 0)


def _voids(mesh) -> int:
    """Closed voids: the inside-out shells of the mesh (trimesh's pieces, negative volume)."""
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    return sum(1 for p in tm.split(only_watertight=True) if p.volume < 0)


def test_skin_by_occt_offset_is_exact_and_one_body():
    """kcl_bracket: OpenCascade's offset works, so the wall is exact (2 % / 0.02 mm)."""
    part = _part("step/kcl_bracket.step")
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # crowded octet struts are thinned
        lat = Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6)
        mesh = lat.mesh()
    rep = lat.skin_report
    assert rep.method == "occt" and rep.accurate, rep.summary()
    assert abs(rep.wall["min"] - cell / 6) <= max(0.02 * cell / 6, 0.02)
    assert rep.bodies == 1 and _bodies(mesh) == 1
    # the sealed voids the report names (the cavity, and any specks), as trimesh counts them
    assert rep.voids >= 1 and rep.voids + rep.pockets == _voids(mesh), rep.summary()
    assert "sealed void(s)" in rep.summary()
    np.testing.assert_array_equal(mesh.vertices, mesh.vertices.astype(np.float32))
    # exact self-intersection test (ours) plus trimesh and manifold3d; pymeshlab's test has a
    # tolerance and flags two coplanar faces 2.3 um apart here, which do not intersect
    assert fast_stitch.check(mesh).valid
    assert_valid(mesh, self_intersections=False)


@pytest.mark.slow
def test_ge_bracket_skin_takes_the_occt_path():
    """GE bracket: OCCT's offset was invalid (its hole chamfers vanish from the offset);
    with them removed first, the skin's inner wall is OCCT's offset, within 2 %."""
    part = _part("step/dolfiny_ge_bracket_rotated_nonds.step")
    cell = float(part.size.max()) / 15  # the parts benchmark's setting
    t = cell / 6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # crowded octet struts are thinned
        lat = Lattice.fill(part, "octet", cell, cell / 12, skin=t)
        mesh = lat.mesh()
    rep = lat.skin_report
    assert rep.method == "occt" and not rep.fallback and rep.accurate, rep.summary()
    assert rep.bodies == 1 and _bodies(mesh) == 1
    ours = fast_stitch.check(mesh, self_intersections=False)
    assert ours.valid, ours


@pytest.mark.slow
def test_skin_falls_back_to_the_voxel_field_and_says_so():
    """The spanner (thin: most of its faces vanish from the offset): OCCT's offset is not
    the wall; the voxel field makes the skin, the report says why and how thick the wall
    came out. Regression: OCCT's offset of the spanner as it is ran 30-60 s (intersection
    joins) to give a solid 3.07 mm off for 3.1; with more faces vanishing than can be
    removed it is not tried, and the reason says so."""
    part = _part("step/dolfiny_spanner25_lo.step")
    cell = float(part.size.max()) / 15  # the parts benchmark's setting
    t = cell / 6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # crowded octet struts are thinned
        lat = Lattice.fill(part, "octet", cell, cell / 12, skin=t)
        mesh = lat.mesh()
    rep = lat.skin_report
    assert rep.method == "voxel" and rep.fallback, rep.summary()
    assert "faces' offsets vanish" in rep.fallback and "would keep them" in rep.fallback
    assert abs(rep.wall["median"] - t) < 0.05 * t, rep.summary()
    assert rep.bodies == 1 and _bodies(mesh) == 1
    ours = fast_stitch.check(mesh, self_intersections=False)
    assert ours.valid, ours
    ind = independent_check(mesh, self_intersections=False)
    assert ind["watertight"] and ind["winding_consistent"] and ind["manifold3d"], ind


@pytest.mark.slow
def test_skin_whose_exact_result_float32_cannot_hold_is_built_again_moved():
    """Regression (bench_preview's ge-skin case): GE bracket, BCC with a skin; the exact
    boolean result gets a non-manifold edge when rounded to float32, so the product refused
    to write a mesh it had built. It now builds the skin once more with the lattice moved a
    quarter of the trim tolerance, and writes a checked mesh."""
    part = _part("step/dolfiny_ge_bracket_rotated_nonds.step")
    cell = float(np.ptp(part.vertices, axis=0).max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, "bcc", cell, cell / 12, skin=cell / 6)
        mesh = lat.mesh()
    np.testing.assert_array_equal(mesh.vertices, mesh.vertices.astype(np.float32))
    assert fast_stitch.check(mesh).valid
    ind = independent_check(mesh, self_intersections=False)
    assert ind["watertight"] and ind["winding_consistent"] and ind["manifold3d"], ind
    assert _bodies(mesh) == lat.skin_report.bodies == 1


@pytest.mark.slow
def test_tet_lattice_of_the_seeds_table5_case_stitches():
    """GE bracket, tet 5 mm, r = 0.25, P = 6 (Verma et al., Table 5: 5,853 nodes, 35.2K
    edges): refused before ("cannot be thinned enough"); the graph repair fixes it without
    thinning any strut below 0.7 of the radius."""
    part = _part("step/dolfiny_ge_bracket_rotated_nonds.step")
    # the default profile polygons (profile="volume") are 10 % wider than the circle, so
    # the fit is stricter than when this case was first fixed: a few struts (22-24 of ~31K)
    # were thinned beyond 0.7 r, at nodes gmsh crowded on the bracket's small arcs; since it
    # meshes circles with its fewest nodes (config.TET_MIN_CIRCLE_POINTS), none is
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g, rep = tet_lattice(part, size=5.0, radius=0.25, return_report=True)
    assert 4500 <= g.num_nodes <= 7000 and 27000 <= g.num_edges <= 40000, g
    assert rep.thinned_beyond_tolerance == 0
    assert not [w for w in caught if "thinner than 0.7 x the radius" in str(w.message)]
    assert rep.merged_nodes + rep.removed_short > 0  # the repair did something, and says so
    mesh = fast_stitch.stitch(g, segments=6)
    assert fast_stitch.check(mesh, self_intersections=False).valid


def test_tet_lattice_of_a_mesh_part():
    """The bunny (a closed OBJ): gmsh re-meshes its surface (it said "Wrong topology of
    boundary mesh" for several mesh parts before the fallbacks)."""
    part = _part("meshes/bunny_closed_odedstein.obj")
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        g = tet_lattice(part, size=cell, radius=cell / 20)
    mesh = fast_stitch.stitch(g, segments=6)
    assert_valid(mesh, self_intersections=False)


@pytest.mark.parametrize(
    "name",
    [
        # 40 deg: "Wrong topology of boundary mesh"; its resampled surface as it was:
        # 2,159 nodes, edges median 0.48 x size (10 % under 0.08 x); 3,858 of 3,901 struts
        # thinned beyond 0.7 r, 38 s (bench_parts' tet row)
        pytest.param("dragon_closed_rainbow.obj", id="dragon"),
        # 40 deg: HXT, Delaunay and frontal fail on the re-meshed surface; the resampled
        # one gave edges median 0.95 x size, 10 % under 0.41 x; 60 struts thinned
        pytest.param("wingnut.obj", id="wingnut"),
    ],
)
def test_tet_lattice_of_a_scan_is_meshed_at_the_size_asked(name):
    """Regression: scans whose surface gmsh cannot re-parametrise with feature edges at 40
    deg went to the resampled surface (the zero level of the signed distance, by marching
    tetrahedra), taken as it is: its triangles, a fraction of the size with slivers, bound
    the tetrahedra, whose struts were then mostly too short for the radius. The surface is
    now re-parametrised with no feature edges first (gmsh cuts it into patches it can
    parametrise): the tetrahedra have the size asked and no strut is thinned beyond 0.7 r
    (dragon: 359 nodes, median 0.91 x size, 1,186 struts, 0 thin; wingnut 0 thin)."""
    part = _part(f"meshes/{name}")
    h = float(part.size.max()) / 15  # the parts benchmark's size and radius
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g, rep = tet_lattice(part, size=h, radius=h / 12, return_report=True)
    said = [str(w.message) for w in caught]
    assert not [m for m in said if "resampled at" in m or "had to be made thinner" in m], said
    length = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    assert 0.75 * h <= float(np.median(length)) <= 1.3 * h, float(np.median(length)) / h
    assert float(np.percentile(length, 10)) >= 0.3 * h, float(np.percentile(length, 10)) / h
    assert rep.thinned_beyond_tolerance == 0 and g.num_edges > 1000
    assert_valid(fast_stitch.stitch(g, segments=6), self_intersections=False)


@pytest.mark.slow
def test_tet_lattice_of_nist_ctc02_meshes_its_brep():
    """NIST CTC-02: gmsh could not mesh the B-rep (overlapping surface meshes of close faces;
    HXT crashed), so the tetrahedra came from the part's closed triangulation (~3 min of
    failed attempts first). Since gmsh puts its fewest nodes on the B-rep's small arcs and
    curves (``config.TET_MIN_CIRCLE_POINTS``), it meshes the B-rep itself: no fallback, the
    nodes on the exact surface (within the part's tessellation's chord of its mesh; 0.018
    cell measured), in ~14 s. The benchmark's settings: cell = extent / 15, r = cell / 12.
    (The fallback itself: ``test_tet.py``'s hung B-rep.)"""
    part = _part("step/nist_ctc_02_asme1_ap242-1.stp")
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g = tet_lattice(part, size=cell, radius=cell / 12)
    said = [str(w.message) for w in caught if "gmsh could not mesh the B-rep" in str(w.message)]
    assert not said, said
    assert g.num_edges > 1000
    d = part.signed_distance(g.nodes)
    assert float(d.max()) <= 0.05 * cell, float(d.max())
    assert np.count_nonzero(np.abs(d) < 1e-2 * cell) > 0.5 * g.num_nodes
    mesh = fast_stitch.stitch(g, segments=6)
    assert fast_stitch.check(mesh, self_intersections=False).valid


@pytest.mark.slow
def test_skin_slivers_float32_cannot_hold_are_collapsed():
    """Regression (parts benchmark, kcl_flange octet skin): the booleans left slivers
    thinner than float32's spacing near (53.88, 1.31, -9.69) that no moved rebuild avoided,
    so the product refused its own mesh. manifold3d's simplify now collapses them (by at
    most a few float32 steps) before the final check."""
    part = _part("step/kcl_flange-with-patterns.step")
    cell = float(part.size.max()) / 15  # the parts benchmark's setting
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6)
        mesh = lat.mesh()
    np.testing.assert_array_equal(mesh.vertices, mesh.vertices.astype(np.float32))
    assert fast_stitch.check(mesh).valid
    ind = independent_check(mesh, self_intersections=False)
    assert ind["watertight"] and ind["winding_consistent"] and ind["manifold3d"], ind
    assert _bodies(mesh) == 1


@pytest.mark.slow
def test_skin_of_the_ventilator_needs_no_retry():
    """Regression (parts benchmark, Ventilator octet skin): manifold3d's simplify crossed
    sheets of the voxel inner wall (146 intersecting face pairs in float64 with a skin of
    0.88882 mm), which no collapse removed; the booleans carried them into the skinned
    solid and every rebuild failed the float32 check (> 10 min). It held in the parts
    benchmark only because that passes 0.888819 (cell / 6 of the unrounded cell), whose
    folds the collapses happened to remove. The wall is now simplified less where it
    folds (conformal.skin._simplified): the first attempt holds, one valid body."""
    part = _part("step/pythonocc_Ventilator.stp")

    def six(x: float) -> float:  # the parts benchmark passes 6 significant digits
        return float(f"{x:.6g}")

    cell = six(float(part.size.max()) / 15)
    with warnings.catch_warnings(record=True):  # the cut's triangle budget binds (warned)
        warnings.simplefilter("always")
        lat = Lattice.fill(part, "octet", cell, six(cell / 12), skin=six(cell / 6))
        mesh = lat.mesh()
    assert lat.skin_retry is None
    np.testing.assert_array_equal(mesh.vertices, mesh.vertices.astype(np.float32))
    assert fast_stitch.check(mesh).valid
    ind = independent_check(mesh, self_intersections=False)
    assert ind["watertight"] and ind["winding_consistent"] and ind["manifold3d"], ind
    assert _bodies(mesh) == lat.skin_report.bodies == 1


def test_tet_lattice_of_a_mesh_part_has_the_size_asked():
    """Regression: gmsh took a mesh part's re-parametrised points with the spacing of its
    triangles and carried it inside, so the rocker arm's tet struts were a sixth of the
    size asked (median 0.17 x size, 42,941 struts) and 94 % of them had to be thinned
    beyond 0.7 x the radius. The size asked is the size used now."""
    part = _part("meshes/rocker-arm.off")
    h = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        g, rep = tet_lattice(part, size=h, radius=h / 12, return_report=True)
    length = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    assert 0.7 * h <= float(np.median(length)) <= 1.3 * h
    assert rep.thinned_beyond_tolerance <= 0.25 * g.num_edges
    assert_valid(fast_stitch.stitch(g, segments=6), self_intersections=False)


def test_tet_lattice_of_a_resampled_surface_has_the_size_asked():
    """Regression: the teapot cannot be re-parametrised, and its resampled surface (spacing
    size / 1.5, by marching tetrahedra) was meshed with its own triangles as the boundary:
    their spacing, a fraction of the size with slivers, bound the tetrahedra (46,527 of
    them, 44,674 struts, 42,845 thinned beyond 0.7 x the radius, 100 s). The resampled
    surface also broke at the thin handle into bubbles, which, in one surface loop with the
    body, made HXT and Delaunay fail. Now each closed piece of it is re-parametrised and
    meshed at the size asked; a piece smaller than one tetrahedron is left out, and said."""
    part = _part("meshes/teapot_closed_rainbow.obj")
    h = float(part.size.max()) / 15
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g, rep = tet_lattice(part, size=h, radius=h / 12, return_report=True)
    said = [str(w.message) for w in caught if "resampled at" in str(w.message)]
    assert len(said) == 1 and "were left out" in said[0], [str(w.message) for w in caught]
    length = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    assert 0.7 * h <= float(np.median(length)) <= 1.3 * h
    assert g.num_edges < 5000 and rep.thinned_beyond_tolerance <= 0.15 * g.num_edges
    assert_valid(fast_stitch.stitch(g, segments=6), self_intersections=False)


def test_shell_groups_put_a_cavity_with_the_solid_holding_it():
    """Closed form: two cubes side by side, one with a cube cavity: two groups, the cavity
    with its holder; a shell under ``min_volume`` is left out and counted."""
    import trimesh

    from conformal.part import Part
    from conformal.tet import _shell_groups

    a = trimesh.creation.box((2, 2, 2))
    cavity = trimesh.creation.box((1, 1, 1))
    cavity.invert()
    b = trimesh.creation.box((2, 2, 2))
    b.apply_translation((5, 0, 0))
    speck = trimesh.creation.box((0.1, 0.1, 0.1))
    speck.apply_translation((10, 0, 0))
    m = trimesh.util.concatenate([b, a, cavity, speck])
    groups, dropped = _shell_groups(Part(m.vertices, m.faces), min_volume=0.01)
    assert dropped == (1, pytest.approx(0.001))
    vols = sorted(round(g.volume, 9) for g in groups)
    assert vols == [7.0, 8.0]  # the holder less its cavity; the other cube


@pytest.mark.parametrize("name", ["meshes/wingnut.obj", "meshes/dragon_closed_rainbow.obj"])
def test_conforming_octet_drops_the_struts_no_radius_can_stitch(name):
    """Octet conform at cell = extent / 15, r = cell / 12 raised FitError on 6 of the 11
    mesh parts (struts pulled onto the surface nearly parallel to a neighbour). The few
    that cannot be stitched even at the floor radius are dropped, said in a warning; the
    rest stitches into one closed body."""
    import conformal

    part = _part(name)
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)  # the fit also thins crowded struts
        g, rep = conformal.voxel_lattice(
            part, "octet", cell, cell / 12, fill="conform", return_report=True
        )
    said = [str(w.message) for w in caught if "meet a neighbour too closely" in str(w.message)]
    assert len(said) == 1 and f"{rep.removed_unstitchable} of " in said[0]
    assert 0 < rep.removed_unstitchable <= 0.10 * (g.num_edges + rep.removed_unstitchable)
    assert np.bincount(g.edges.ravel(), minlength=g.num_nodes).min() >= 1  # no isolated node
    assert float(g.radii.min()) >= 0.1 * cell / 12 * (1 - 1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # crowded struts thinned
        mesh = fast_stitch.stitch(g)
    assert fast_stitch.check(mesh).valid
    assert_valid(mesh)
    assert _bodies(mesh) == rep.bodies == 1


def test_clip_fill_of_a_thin_part_says_most_of_it_fell_apart():
    """The spanner (a 10 mm plate) with the parts benchmark's bcc cells (18.6 mm) and
    fill='clip': the cut cells fall apart into 15 pieces and only the largest (8 of 116
    struts) is kept. The warning says so in numbers, that it is most of the lattice, and that
    fill='conform' keeps it joined, which it does (far more struts, one body)."""
    from conformal.voxel import voxel_lattice

    part = _part("step/dolfiny_spanner25_lo.step")
    h = float(f"{float(part.size.max()) / 15:.6g}")
    r = float(f"{h / 12:.6g}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g, rep = voxel_lattice(part, "bcc", h, r, fill="clip", return_report=True)
    said = [str(w.message) for w in caught if "loose piece" in str(w.message)]
    assert len(said) == 1, said
    total = rep.removed_islands + g.num_edges
    assert rep.removed_islands > 0.9 * total and rep.bodies == 1
    assert f"{rep.removed_islands} of {total} strut(s)" in said[0], said[0]
    assert "most of the lattice" in said[0], said[0]
    tried = re.search(r"fill='conform' keeps (\d+) % of the struts joined", said[0])
    assert tried, said[0]  # found by building it, not guessed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        gc, rep_c = voxel_lattice(part, "bcc", h, r, fill="conform", return_report=True)
    assert rep_c.bodies == 1 and gc.num_edges > 10 * g.num_edges
    kept = gc.num_edges / (rep_c.removed_islands + gc.num_edges)
    assert kept >= 0.9 and f"{100 * kept:.0f}" == tried.group(1)


def test_a_fill_that_falls_apart_says_the_cell_size_that_keeps_it_joined():
    """The hammer scan (a plate 0.64 mm thick), conforming kelvin cells of 1 mm: most of
    the lattice falls apart into loose pieces, and "use smaller cells" said neither how
    small nor whether that helps (a threaded rod made outside shared/data: 13.3 mm kelvin
    cells kept 7 % clipped and 7 % conformed, and the clip's advice was to conform). The
    warning now names the size found by building the graphs, which keeps it joined."""
    from conformal.voxel import voxel_lattice

    part = _part("meshes/hammer.obj")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        voxel_lattice(part, "kelvin", 1.0, 0.05, fill="conform")
    said = [str(w.message) for w in caught if "loose piece" in str(w.message)]
    assert len(said) == 1 and "most of the lattice" in said[0], said
    found = re.search(r"cells of ([\d.]+) mm keep (\d+) % of the struts joined", said[0])
    assert found, said[0]
    size = float(found.group(1))
    assert size < 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        g, rep = voxel_lattice(part, "kelvin", size, 0.05, fill="conform", return_report=True)
    kept = g.num_edges / (g.num_edges + rep.removed_islands)
    assert kept >= 0.9 and f"{100 * kept:.0f}" == found.group(2)


@pytest.mark.slow
def test_a_voxel_skin_is_the_same_in_any_unit(tmp_path):
    """fandisk.obj, and the same mesh in metres read as mm (1e-3 of it): the absolute
    floor of the wall tolerance (0.02 mm) was larger than the whole part there, so the
    split's margin took in every element and the booleans ran on the whole lattice (s24's
    flange in metres: 568 s, 340 s of them measuring that margin). The floor is now at most
    a quarter of the wall (``skin.WALL_ATOL_SHARE``): the split, the verdict and the wall,
    scaled, are the same at both scales."""
    import trimesh

    src = _part("meshes/fandisk.obj")
    extent = float(src.size.max())
    got = []
    for k in (1.0, 1e-3):
        path = tmp_path / f"fandisk_{k}.stl"
        trimesh.Trimesh(src.vertices * k, src.faces, process=False).export(path)
        cell = extent * k / 15
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)  # thinned struts, tiny part
            lat = Lattice.fill(str(path), "octet", cell, cell / 12, skin=cell / 6)
            mesh = lat.mesh()
        rep = lat.skin_report
        assert rep.method == "voxel" and rep.bodies == 1 and _bodies(mesh) == 1
        got.append((rep, len(mesh.faces)))
    (big, n_big), (small, n_small) = got
    # the same elements near the wall, up to those whose clearance is the margin to the
    # rounding (s27, bands split elements of their own: two bands 0.996 and 1.0003
    # margins from the wall at one scale, 1.001 and 0.999 at the other, change sides)
    total = sum(big.split[k] for k in ("deep", "near", "wall"))
    assert big.split and small.split.keys() == big.split.keys()
    for key, count in big.split.items():
        assert abs(small.split[key] - count) <= 1e-4 * total, (key, small.split, big.split)
    assert small.accurate == big.accurate
    for key, value in big.wall.items():
        assert small.wall[key] == pytest.approx(1e-3 * value, rel=1e-3), key
    assert n_small == pytest.approx(n_big, rel=1e-3)
