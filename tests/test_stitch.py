"""fast_stitch.stitch: guarantees, golden counts, errors, determinism, I/O."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from conftest import assert_valid, cubic_grid, independent_check, star_graph
from reference_stitch import canonical_faces, reference_stitch

import fast_stitch
from conformal.cells import block
from fast_stitch import ExportError, StitchError
from fast_stitch.hubvolume import area_factor
from lattice_cad import LatticeGraph, LatticeWarning


def counts_ok(mesh, graph, P, profile="volume"):
    est = fast_stitch.estimate(graph, P, profile)
    rings = 4 if profile == "volume" else 2  # volume: hub rings and band rings
    return (
        len(mesh.vertices) == est.vertices == rings * graph.num_edges * P
        and len(mesh.faces) == est.triangles
    )


def axis_dirs():
    return np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def edge_dirs():
    return np.array(
        [[a, b, 0] for a in (1, -1) for b in (1, -1)]
        + [[a, 0, b] for a in (1, -1) for b in (1, -1)]
        + [[0, a, b] for a in (1, -1) for b in (1, -1)],
        float,
    )


def planar_star(d):
    t = 2 * np.pi * np.arange(d) / d
    return np.column_stack([np.cos(t), np.sin(t), np.zeros(d)])


# ------------------------------------------------------------ golden counts
@pytest.mark.parametrize(
    ("dirs", "expected"),
    [
        (planar_star(4), 252),
        (planar_star(8), 508),
        (planar_star(16), 1020),
        (np.vstack([axis_dirs(), edge_dirs()]), 1148),
    ],
    ids=["4 beams", "8 beams", "16 beams", "18 beams 3D"],
)
def test_paper_table1_counts(dirs, expected):
    """Verma et al. Table 1: beams of length 1, radius 0.1, P = 16 (the paper's
    construction: no hub correction, so no bands)."""
    g = star_graph(dirs, 1.0, 0.1)
    mesh = fast_stitch.stitch(g, 16, profile="inscribed")
    assert len(mesh.faces) == expected
    assert counts_ok(mesh, g, 16, "inscribed")
    assert_valid(mesh)
    # the default adds a band ring per strut end and a band of 2 P triangles
    mesh = fast_stitch.stitch(g, 16)
    assert len(mesh.faces) == expected + 4 * g.num_edges * 16
    assert counts_ok(mesh, g, 16)
    assert_valid(mesh)


def test_estimate_formula_by_hand():
    g = LatticeGraph([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1], [0, 2], [1, 3]], 0.1)
    # degrees: node0 2, node1 2, node2 1, node3 1
    P = 5
    est = fast_stitch.estimate(g, P, "area")
    assert est.vertices == 2 * 3 * P
    assert est.triangles == 2 * 3 * P + 2 * (2 * P + 0) + 2 * (P - 2)
    assert est.stl_bytes == 84 + 50 * est.triangles
    est = fast_stitch.estimate(g, P)  # profile="volume": band rings and bands
    assert est.vertices == 4 * 3 * P
    assert est.triangles == 6 * 3 * P + 2 * (2 * P + 0) + 2 * (P - 2)


# ------------------------------------------------------ closed-form volumes
@pytest.mark.parametrize("P", [3, 4, 6, 11, 32])
def test_single_strut_is_an_exact_prism(P):
    r, L = 0.3, 2.5
    g = LatticeGraph([[0, 0, 0], [1.5, 2.0, 0]], [[0, 1]], r)  # length 2.5
    mesh = fast_stitch.stitch(g, P, profile="inscribed")
    polygon = 0.5 * P * r * r * math.sin(2 * math.pi / P)
    assert mesh.volume == pytest.approx(polygon * L, rel=1e-12)
    assert len(mesh.faces) == 2 * P + 2 * (P - 2)
    assert_valid(mesh)
    # the default profile has the circle's area; circumscribed polygons' edges touch it
    assert fast_stitch.stitch(g, P).volume == pytest.approx(math.pi * r * r * L, rel=1e-12)
    outer = fast_stitch.stitch(g, P, profile="circumscribed").volume
    assert outer == pytest.approx(P * r * r * math.tan(math.pi / P) * L, rel=1e-12)


@pytest.mark.parametrize("P", [3, 6, 12])
def test_volume_preserving_strut_keeps_the_cylinder_volume(P):
    r, L = 0.3, 2.5
    g = LatticeGraph([[0, 0, 0], [1.5, 2.0, 0]], [[0, 1]], r)
    mesh = fast_stitch.stitch(g, P, profile="area")
    assert mesh.volume == pytest.approx(math.pi * r * r * L, rel=1e-12)
    assert_valid(mesh)
    with pytest.warns(DeprecationWarning, match="volume_preserving"):
        alias = fast_stitch.stitch(g, P, volume_preserving=True)
    assert np.array_equal(alias.vertices, mesh.vertices)
    with pytest.warns(DeprecationWarning):
        plain = fast_stitch.stitch(g, P, volume_preserving=False)
    assert np.array_equal(plain.vertices, fast_stitch.stitch(g, P, profile="inscribed").vertices)
    bcc = block("bcc", 2, cell_size=5.0, radius=0.3)
    for profile in ("area", "volume", "circumscribed"):
        assert_valid(fast_stitch.stitch(bcc, P, profile=profile))
    with pytest.raises(ValueError, match="profile must be one of"):
        fast_stitch.stitch(g, P, profile="exact")


def cross_volume(r, L, axes):
    """Exact volume of the union of a ball (radius r) and half-cylinders [0, L] along
    +x, +y, +z and, with ``axes == 6``, also -x, -y, -z (inclusion-exclusion with the
    Steinmetz solids: bicylinder 16/3 r^3, tricylinder 8 (2 - sqrt 2) r^3)."""
    tri = 8 * (2 - math.sqrt(2)) * r**3
    if axes == 6:  # three full cylinders of length 2L; the ball is inside them
        return 3 * math.pi * r * r * 2 * L - 3 * 16 / 3 * r**3 + tri
    # three half-cylinders: pairs overlap in a quarter bicylinder, all three in an eighth
    # tricylinder; the ball's octant x, y, z < 0 is outside all of them
    return 3 * math.pi * r * r * L - 3 * 4 / 3 * r**3 + tri / 8 + math.pi * r**3 / 6


@pytest.mark.parametrize("axes", [3, 6])
@pytest.mark.parametrize("P", [4, 6, 8, 12])
def test_volume_profile_matches_the_exact_cross(axes, P):
    """profile='volume': the hub correction makes the mesh's volume the exact solid's,
    for a hub fuller than the exact solid (6 axes: shrinks) and for a corner whose hull
    misses the back of the ball (3 axes: grows); leaves are flat in both."""
    r, L = 0.25, 1.5
    dirs = axis_dirs()[[0, 2, 4]] if axes == 3 else axis_dirs()
    g = star_graph(dirs, L, r)
    exact = cross_volume(r, L, axes)
    mesh = fast_stitch.stitch(g, P)
    assert mesh.volume == pytest.approx(exact, rel=2e-4)
    assert counts_ok(mesh, g, P)
    assert_valid(mesh)
    area = fast_stitch.stitch(g, P, profile="area").volume
    assert abs(area - exact) > 10 * abs(mesh.volume - exact)  # the correction matters
    assert fast_stitch.stitch(g, P, profile="inscribed").volume < exact


def test_tapered_strut_is_an_exact_frustum():
    P, r0, r1, L = 8, 0.4, 0.1, 3.0
    g = LatticeGraph([[0, 0, 0], [0, 0, L]], [[0, 1]], [[r0, r1]])
    mesh = fast_stitch.stitch(g, P, profile="inscribed")
    area = lambda r: 0.5 * P * r * r * math.sin(2 * math.pi / P)  # noqa: E731
    a0, a1 = area(r0), area(r1)
    assert mesh.volume == pytest.approx(L / 3 * (a0 + a1 + math.sqrt(a0 * a1)), rel=1e-12)
    assert_valid(mesh)


def test_collinear_chain_is_one_exact_prism():
    """Collinear degree-2 nodes: parallel struts share a phase, so the hub is a prism slice."""
    P, r = 6, 0.1
    x = np.array([0.0, 1.0, 2.5, 3.0, 4.2])
    g = LatticeGraph(np.column_stack([x, 0 * x, 0 * x]), [[0, 1], [1, 2], [3, 2], [3, 4]], r)
    mesh = fast_stitch.stitch(g, P, profile="inscribed")
    assert mesh.volume == pytest.approx(0.5 * P * r * r * math.sin(2 * math.pi / P) * 4.2, rel=1e-9)
    assert counts_ok(mesh, g, P, "inscribed")
    assert_valid(mesh)
    # exact solid: one cylinder (balls inside it); hubs are prism slices, nothing to correct
    vol = fast_stitch.stitch(g, P)
    assert vol.volume == pytest.approx(math.pi * r * r * 4.2, rel=1e-4)
    assert_valid(vol)


# --------------------------------------------- property tests on many graphs
def random_star(rng, d, *, planar=False, tapered=False):
    dirs = rng.normal(size=(d, 3))
    if planar:
        dirs[:, 2] = 0
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    cos = np.clip(dirs @ dirs.T, -1, 1) - 2 * np.eye(d)
    min_angle = math.acos(cos.max())
    rmax = 0.9 * math.tan(min_angle / 2) * 1.0  # profiles fit in struts of length ~ 3
    shape = (d, 2) if tapered else (d,)
    radii = rng.uniform(0.2, 1.0, size=shape) * min(rmax / 3, 0.2)
    return star_graph(dirs, rng.uniform(3.0, 4.0, d), radii)


@pytest.mark.parametrize("d", [2, 3, 4, 5, 6, 8, 10, 12, 14, 18, 22, 26])
@pytest.mark.parametrize("kind", ["3d", "planar", "tapered"])
def test_random_stars_are_valid(rng, d, kind):
    for trial in range(3):
        g = random_star(rng, d, planar=kind == "planar", tapered=kind == "tapered")
        P = int(rng.choice([3, 4, 6, 8, 12]))
        mesh = fast_stitch.stitch(g, P, seed=trial)
        assert counts_ok(mesh, g, P)
        assert_valid(mesh)


def test_stars_match_the_slow_reference(rng):
    for trial in range(12):
        g = random_star(rng, int(rng.integers(2, 15)), tapered=bool(trial % 2))
        P = int(rng.choice([3, 5, 6, 9]))
        shrink = bool(trial % 3)
        mesh = fast_stitch.stitch(g, P, seed=trial, shrink=shrink, profile="inscribed")
        v, f = reference_stitch(g, P, seed=trial, shrink=shrink)
        np.testing.assert_allclose(mesh.vertices, v, rtol=0, atol=1e-12)
        assert canonical_faces(mesh.faces) == canonical_faces(f)


def test_jittered_grid_matches_reference_and_is_valid(rng):
    nodes, edges = cubic_grid(4, 1.0)
    nodes = nodes + rng.uniform(-0.2, 0.2, nodes.shape)
    g = LatticeGraph(nodes, edges, rng.uniform(0.03, 0.08, (len(edges), 2)))
    mesh = fast_stitch.stitch(g, 7, seed=3, profile="inscribed")
    v, f = reference_stitch(g, 7, seed=3)
    np.testing.assert_allclose(mesh.vertices, v, rtol=0, atol=1e-12)
    assert canonical_faces(mesh.faces) == canonical_faces(f)
    assert counts_ok(mesh, g, 7, "inscribed")
    assert_valid(mesh)


@pytest.mark.parametrize(
    "cell", ["cubic", "bcc", "bccz", "fcc", "fccz", "box-bcc", "octet", "kelvin", "diamond",
             "rhombic-dodecahedron", "reentrant"],
)  # fmt: skip
def test_unit_cell_blocks_are_valid(cell):
    g = block(cell, (3, 3, 2), cell_size=10.0, radius=0.35)
    P = 6
    mesh = fast_stitch.stitch(g, P)
    assert counts_ok(mesh, g, P)
    assert_valid(mesh)


def test_jittered_octet_block_is_valid(rng):
    g0 = block("octet", 3, cell_size=10.0, radius=0.3)
    g = LatticeGraph(g0.nodes + rng.uniform(-0.6, 0.6, g0.nodes.shape), g0.edges, g0.radii)
    mesh = fast_stitch.stitch(g, 6)
    assert counts_ok(mesh, g, 6)
    assert_valid(mesh)


def test_shrink_reduces_volume_and_both_are_valid():
    """A tight pair makes a big hub; shrinking pulls the other profiles back in."""
    t = math.radians(20)
    dirs = [[1, 0, 0], [math.cos(t), math.sin(t), 0], [0, 0, 1], [0, 0, -1], [-1, 0, 0]]
    g = star_graph(dirs, 3.0, 0.1)
    small = fast_stitch.stitch(g, 8, shrink=True, profile="inscribed")
    big = fast_stitch.stitch(g, 8, shrink=False, profile="inscribed")
    assert small.volume < 0.9 * big.volume
    # the default profile corrects both hubs to the exact solid's volume
    a, b = fast_stitch.stitch(g, 8, shrink=True), fast_stitch.stitch(g, 8, shrink=False)
    assert a.volume == pytest.approx(b.volume, rel=1e-3)
    assert_valid(a)
    assert_valid(b)
    assert len(small.faces) == len(big.faces)
    assert_valid(small)
    assert_valid(big)


# ------------------------------------------------------------- at the limit
def tight_v(angle_deg, r=0.05, L=1.0):
    t = math.radians(angle_deg)
    return star_graph([[1, 0, 0], [math.cos(t), math.sin(t), 0]], L, r)


@pytest.mark.parametrize("angle", [0.5, 2.0, 5.0, 20.0])
def test_small_angle_error_names_node_edges_angle_and_length(angle):
    with pytest.raises(StitchError) as err:
        fast_stitch.stitch(tight_v(angle, r=0.05, L=0.5 / math.tan(math.radians(angle) / 2) * 0.1))
    msg = str(err.value)
    assert re.search(r"node 0: struts [01] and [01] meet at", msg), msg
    assert f"{angle:.3g} degrees" in msg
    needed = float(re.search(r"longer than ([0-9.e+-]+)", msg).group(1))
    # the reported length really is (just) the shortest one that fits
    ok = fast_stitch.stitch(tight_v(angle, r=0.05, L=needed * 1.001))
    assert_valid(ok)
    with pytest.raises(StitchError):
        fast_stitch.stitch(tight_v(angle, r=0.05, L=needed * 0.98))


@pytest.mark.parametrize("angle", [0.5, 3.0, 10.0, 30.0, 150.0, 175.0, 179.0, 179.99])
def test_near_parallel_and_near_collinear_struts_at_the_limit(angle):
    g = tight_v(angle, r=0.05, L=1000.0)  # long enough for any offset
    mesh = fast_stitch.stitch(g, 6)
    assert counts_ok(mesh, g, 6)
    assert_valid(mesh)


def test_short_strut_between_two_hubs_is_reported():
    # two tight V's joined by a short strut
    g = LatticeGraph(
        [[0, 0, 0], [0.3, 0, 0], [5, 0.3, 0], [-5, 0.3, 0], [5.3, 0.3, 0]],
        [[0, 1], [0, 2], [1, 3], [1, 4]], 0.05,
    )  # fmt: skip
    with pytest.raises(StitchError, match=r"strut 0 \(length 0.3\)"):
        fast_stitch.stitch(g)


@pytest.mark.parametrize(
    ("nodes", "edges", "message"),
    [
        ([[-1, 0, 0], [1, 0, 0], [0, -1, 0.05], [0, 1, 0.05]], [[0, 1], [2, 3]],
         r"strut 0 \(nodes 0, 1\) and strut 1 \(nodes 2, 3\) overlap"),
        ([[-1, 0, 0], [1, 0, 0], [0, 0.02, 0.0], [0, 1, 1], [0, 1, -1]], [[0, 1], [2, 3], [2, 4]],
         r"strut 0 \(nodes 0, 1\) and the joint at node 2 overlap"),
    ],
)  # fmt: skip
def test_struts_crossing_away_from_nodes_are_reported(nodes, edges, message):
    g = LatticeGraph(nodes, edges, 0.05)
    with pytest.raises(StitchError, match=message):
        fast_stitch.stitch(g)
    # without the check the mesh self-intersects, as an independent checker confirms
    mesh = fast_stitch.stitch(g, check_clearance=False)
    assert independent_check(mesh)["self_intersecting_faces"] > 0


def test_clearance_passes_struts_just_apart():
    g = LatticeGraph([[-1, 0, 0], [1, 0, 0], [0, -1, 0.101], [0, 1, 0.101]], [[0, 1], [2, 3]], 0.05)
    assert_valid(fast_stitch.stitch(g, profile="inscribed"))
    # the default polygons have the circle's area: circumradius 1.0996 r at P = 6
    g = LatticeGraph([[-1, 0, 0], [1, 0, 0], [0, -1, 0.111], [0, 1, 0.111]], [[0, 1], [2, 3]], 0.05)
    assert_valid(fast_stitch.stitch(g))


def test_parallel_struts_are_reported():
    # distinct nodes on the same ray from node 0 (quantised to one direction)
    g = LatticeGraph([[0, 0, 0], [1, 0, 0], [2, 1e-12, 0]], [[0, 1], [0, 2]], 0.01)
    with pytest.raises(StitchError, match="node 0: struts 0 and 1 leave it in the same direction"):
        fast_stitch.stitch(g)


# ---------------------------------------------------------------- API edges
def test_bad_arguments():
    g = tight_v(90)
    with pytest.raises(ValueError, match="segments must be >= 3"):
        fast_stitch.stitch(g, 2)
    with pytest.raises(TypeError, match="segments"):
        fast_stitch.stitch(g, 6.0)
    with pytest.raises(TypeError, match="LatticeGraph"):
        fast_stitch.stitch(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="seed"):
        fast_stitch.stitch(g, seed=-1)
    with pytest.raises(ValueError, match="workers"):
        fast_stitch.stitch(g, workers=0)
    with pytest.raises(StitchError, match="no struts"):
        fast_stitch.stitch(LatticeGraph(np.zeros((0, 3)), np.zeros((0, 2), int), 0.1))


def test_isolated_nodes_are_ignored():
    with pytest.warns(LatticeWarning):
        g = LatticeGraph([[0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]], [[0, 1], [0, 2]], 0.1)
    mesh = fast_stitch.stitch(g, 6)
    assert counts_ok(mesh, g, 6)
    assert_valid(mesh)


def test_same_seed_is_byte_identical_and_seed_changes_phase(tmp_path):
    g = block("bcc", 2, cell_size=5.0, radius=0.3)
    a = fast_stitch.stitch(g, 6, seed=7, workers=1).save(tmp_path / "a.stl")
    b = fast_stitch.stitch(g, 6, seed=7, workers=2).save(tmp_path / "b.stl")
    c = fast_stitch.stitch(g, 6, seed=8).save(tmp_path / "c.stl")
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes() and a.stat().st_size == c.stat().st_size


def test_translated_hubs_are_identical():
    """The hub cache: a periodic block's hubs are translates of each other."""
    g = block("bcc", 3, cell_size=4.0, radius=0.3)
    shift = np.array([400.0, -800.0, 1200.0])
    moved = LatticeGraph(g.nodes + shift, g.edges, g.radii)
    a, b = fast_stitch.stitch(g), fast_stitch.stitch(moved)
    assert np.array_equal(a.faces, b.faces)
    np.testing.assert_allclose(b.vertices - shift, a.vertices, atol=1e-9)


def test_progress_callback_and_bar():
    g = block("bcc", 2, cell_size=5.0, radius=0.3)
    calls = []
    fast_stitch.stitch(g, progress=lambda stage, done, total: calls.append((stage, done, total)))
    assert calls and calls[-1][0] == "done" and calls[-1][1] == calls[-1][2]
    fast_stitch.stitch(g, progress=False)


# ----------------------------------------------------------------------- STL
def test_stl_is_binary_checked_and_reads_back(tmp_path):
    import trimesh

    g = block("octet", 2, cell_size=5.0, radius=0.25)
    mesh = fast_stitch.stitch(g, 6)
    path = mesh.save(tmp_path / "lattice.stl")
    data = path.read_bytes()
    assert not data[:80].lower().startswith(b"solid")
    n = int(np.frombuffer(data[80:84], "<u4")[0])
    assert n == len(mesh.faces) and len(data) == 84 + 50 * n == fast_stitch.estimate(g, 6).stl_bytes
    back = trimesh.load(path, process=True)
    assert back.is_watertight and back.is_winding_consistent
    assert back.volume == pytest.approx(mesh.volume, rel=1e-5)


def test_stl_float32_collapse_is_refused_and_nothing_is_written(tmp_path):
    # |x| / r = 5e8: inside the float64 precision contract (1e9), far outside float32 (3e4)
    g = LatticeGraph([[5e4, 0, 0], [5e4 + 0.01, 0, 0], [5e4, 0.01, 0]], [[0, 1], [0, 2]], 1e-4)
    mesh = fast_stitch.stitch(g, 6)
    assert_valid(mesh, self_intersections=False)  # fine in float64
    with pytest.raises(ExportError, match="single precision"):
        mesh.save(tmp_path / "far.stl")
    assert list(tmp_path.iterdir()) == []


def test_save_refuses_other_suffixes(tmp_path):
    mesh = fast_stitch.stitch(tight_v(90), 6)
    with pytest.raises(ValueError, match=".obj"):
        mesh.save(tmp_path / "x.obj")


def test_independent_checker_catches_a_broken_mesh():
    """The checker used above can fail: drop a face and flip another."""
    mesh = fast_stitch.stitch(tight_v(60), 6)
    rep = independent_check(type(mesh)(mesh.vertices, mesh.faces[1:]))
    assert not rep["watertight"] and not rep["manifold3d"]
    flipped = mesh.faces.copy()
    flipped[0] = flipped[0, ::-1]
    assert not independent_check(type(mesh)(mesh.vertices, flipped))["winding_consistent"]


def test_method_dispatch_and_chord_error():
    from fast_stitch.lslt import segments_for_chord_error

    g = block("bcc", 2, cell_size=5.0, radius=0.3)
    P = segments_for_chord_error(0.05)
    assert 1 - math.cos(math.pi / P) <= 0.05 < 1 - math.cos(math.pi / (P - 1))
    by_error = fast_stitch.stitch(g, chord_error=0.05)
    assert len(by_error.faces) == fast_stitch.estimate(g, P).triangles
    lslt = fast_stitch.stitch(g, method="lslt", chord_error=0.05)
    assert_valid(lslt)
    assert len(lslt.faces) < len(by_error.faces)
    with pytest.raises(ValueError, match="method"):
        fast_stitch.stitch(g, method="marching-cubes")
    with pytest.raises(ValueError, match="sections"):
        fast_stitch.stitch(g, sections=2)


def test_fit_checks_the_profile_polygons():
    """fast_stitch.fit and conformal.check_fit check the polygons the stitch builds: the
    default (area-preserving) hexagons are 1.0996 r wide, so a strut that fits inscribed
    ones can be too short for them; both agree with the stitch."""
    from conformal.radius import check_fit
    from fast_stitch.fit import end_offsets, misfits

    g = tight_v(20.0, r=0.05, L=0.30)
    off_in = end_offsets(g.nodes, g.edges, g.radii, profile="inscribed")
    off_vol = end_offsets(g.nodes, g.edges, g.radii)
    np.testing.assert_allclose(off_vol, off_in * area_factor(6), rtol=1e-12)
    assert off_in.sum(axis=1).max() < 0.30 < off_vol.sum(axis=1).max()
    assert len(misfits(g.nodes, g.edges, g.radii, profile="inscribed")[0]) == 0
    assert len(misfits(g.nodes, g.edges, g.radii)[0]) == 2
    assert check_fit(g, profile="inscribed") == [] and len(check_fit(g)) == 2
    assert_valid(fast_stitch.stitch(g, profile="inscribed"))
    with pytest.raises(StitchError, match="too small an angle"):
        fast_stitch.stitch(g)
    # P changes the polygon: at P = 12 the area-preserving polygon is 1.0236 r wide
    assert len(misfits(g.nodes, g.edges, g.radii, segments=12)[0]) == 0
    assert_valid(fast_stitch.stitch(g, 12))


def _grown_v_and_a_strut_above() -> tuple[LatticeGraph, int]:
    """A 30-degree V (its node's hub grows ~22 % with profile="volume": the hull misses
    the back of the ball) and a strut 2.1 profile radii above the V's first strut: clear of
    it at the unscaled size (P = 24: the polygons reach at most 1 profile radius), into it
    once the V's end grows (> 1.2 x 0.99 + 0.99 > 2.1)."""
    P, r = 24, 0.1
    rho = r * area_factor(P)
    t, D = math.radians(30.0), 2.1 * rho
    nodes = [[0, 0, 0], [2, 0, 0], [2 * math.cos(t), 2 * math.sin(t), 0], [0.2, 0, D],
             [1.6, 0, D]]  # fmt: skip
    return LatticeGraph(nodes, [[0, 1], [0, 2], [3, 4]], r), P


def test_hub_growth_is_capped_by_clearance(monkeypatch):
    """Issue 11: boundary hubs grown to the exact volume overlapped a neighbouring strut
    that the unscaled mesh (and the fit) cleared; their growth is now limited."""
    import importlib

    st = importlib.import_module("fast_stitch.stitch")
    g, P = _grown_v_and_a_strut_above()
    assert_valid(fast_stitch.stitch(g, P, profile="area"))
    report: dict = {}
    mesh = fast_stitch.stitch(g, P, _report=report)  # the default profile="volume"
    assert report["capped"].tolist() == [0]
    assert independent_check(mesh)["self_intersecting_faces"] == 0
    # without the cap: the grown hub and strut overlap the strut above (exact check, and
    # an independent checker agrees)
    monkeypatch.setattr(st, "cap_growth", lambda n, e, r, o, s: (s, np.zeros(0, np.int64)))
    with pytest.raises(StitchError, match=r"strut [01] \(nodes 0, [12]\) and strut 2"):
        fast_stitch.stitch(g, P)
    grown = fast_stitch.stitch(g, P, check_clearance=False)
    assert independent_check(grown)["self_intersecting_faces"] > 0
    assert grown.volume > mesh.volume


def test_cap_growth_leaves_free_hubs_alone():
    """Grown hubs with nothing near keep their growth (the V alone), shrunk ones too."""
    from fast_stitch.fit import end_offsets
    from fast_stitch.stitch import cap_growth

    g, P = _grown_v_and_a_strut_above()
    nodes, edges = g.nodes[:3], g.edges[:2]
    rho = np.full((2, 2), 0.1 * area_factor(P))
    off = end_offsets(nodes, edges, 0.1, segments=P)
    scale = np.array([1.2, 1.0, 1.0])
    out, capped = cap_growth(nodes, edges, rho, off, scale)
    assert np.array_equal(out, scale) and len(capped) == 0
    # with the strut above: halved three times, then no growth
    off3 = np.vstack([off, np.zeros((1, 2))])
    out, capped = cap_growth(g.nodes, g.edges, np.full((3, 2), rho[0, 0]), off3,
                             np.array([1.2, 1.0, 1.0, 1.0, 1.0]))  # fmt: skip
    assert capped.tolist() == [0] and out[0] == 1.0
