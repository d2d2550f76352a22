"""fast_stitch.lslt (Chougrani et al. 2017): guarantees, closed forms, counts, errors."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from conftest import assert_valid, cubic_grid, independent_check, star_graph

import fast_stitch
from conformal.cells import block
from fast_stitch import StitchError
from fast_stitch.lslt import segments_for_chord_error, stitch_lslt, triangle_quality
from lattice_cad import LatticeGraph


def planar_star(d):
    t = 2 * np.pi * np.arange(d) / d
    return np.column_stack([np.cos(t), np.sin(t), np.zeros(d)])


def random_star(rng, d, *, planar=False, tapered=False):
    dirs = rng.normal(size=(d, 3))
    if planar:
        dirs[:, 2] = 0
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    cos = np.clip(dirs @ dirs.T, -1, 1) - 2 * np.eye(d)
    rmax = 0.9 * math.tan(math.acos(cos.max()) / 2)
    shape = (d, 2) if tapered else (d,)
    radii = rng.uniform(0.2, 1.0, size=shape) * min(rmax / 3, 0.2)
    return star_graph(dirs, rng.uniform(3.0, 4.0, d), radii)


# ---------------------------------------------------------------- chord error
@pytest.mark.parametrize("e", [1e-4, 0.001, 0.01, 0.02, 0.05, 0.1, 0.2, 0.29, 0.5, 0.9])
def test_segments_for_chord_error_is_the_smallest_polygon(e):
    P = segments_for_chord_error(e)
    assert P >= 3
    assert 1 - math.cos(math.pi / P) <= e
    assert P == 3 or 1 - math.cos(math.pi / (P - 1)) > e


def test_segments_for_chord_error_known_values_and_errors():
    assert segments_for_chord_error(0.05) == 10  # the paper's 5 %
    assert segments_for_chord_error(0.01) == 23
    assert segments_for_chord_error(1 - math.cos(math.pi / 6)) == 6  # exactly on the bound
    for bad in (0, -0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="chord_error"):
            segments_for_chord_error(bad)
    with pytest.raises(TypeError, match="chord_error"):
        segments_for_chord_error("0.05")


# ----------------------------------------------------------------- closed forms
@pytest.mark.parametrize("e", [0.01, 0.05, 0.1, 0.3])
def test_single_strut_is_the_exact_prism_of_the_chord_error_polygon(e):
    r, L = 0.3, 2.5
    P = segments_for_chord_error(e)
    g = LatticeGraph([[0, 0, 0], [1.5, 2.0, 0]], [[0, 1]], r)
    mesh = stitch_lslt(g, chord_error=e)
    assert len(mesh.vertices) == 2 * P
    assert len(mesh.faces) == 2 * P + 2 * (P - 2)
    polygon = 0.5 * P * r * r * math.sin(2 * math.pi / P)
    assert mesh.volume == pytest.approx(polygon * L, rel=1e-12)
    # every vertex is on the cylinder; the sagitta is within the chord error
    assert 1 - math.cos(math.pi / P) <= e
    assert_valid(mesh)


def test_collinear_chain_is_a_mitred_tube_without_holes():
    """Collinear degree-2 nodes share one section: no hole, P vertices per node."""
    P, r = segments_for_chord_error(0.05), 0.1
    x = np.array([0.0, 1.0, 2.5, 3.0, 4.2])
    g = LatticeGraph(np.column_stack([x, 0 * x, 0 * x]), [[0, 1], [1, 2], [3, 2], [3, 4]], r)
    mesh = stitch_lslt(g)
    assert len(mesh.vertices) == 5 * P  # one ring per node
    assert len(mesh.faces) == 4 * 2 * P + 2 * (P - 2)
    prism = 0.5 * P * r * r * math.sin(2 * math.pi / P) * 4.2
    assert mesh.volume == pytest.approx(prism, rel=1e-2)  # rings differ only in phase
    assert_valid(mesh)


def test_right_angle_pair_has_mandatory_vertices_on_the_node_sphere():
    """Eq. 1: N +- R O with O = d1 x d2; both sections contain them."""
    r = 0.2
    g = star_graph([[1, 0, 0], [0, 1, 0]], 2.0, r)
    mesh = stitch_lslt(g, chord_error=0.05)
    v = mesh.vertices
    for sgn in (1, -1):
        assert np.min(np.linalg.norm(v - [0, 0, sgn * r], axis=1)) < 1e-12
    # seam vertices lie on the bisecting plane x == y, at distance r from both axes
    near = (np.linalg.norm(v, axis=1) < 3 * r) & (v[:, 0] + v[:, 1] > 0)  # not the hole fan
    on_plane = near & (np.abs(v[:, 0] - v[:, 1]) < 1e-12)
    assert on_plane.sum() >= 3
    assert np.allclose(np.hypot(v[on_plane, 1], v[on_plane, 2]), r)
    assert np.allclose(np.hypot(v[on_plane, 0], v[on_plane, 2]), r)
    assert_valid(mesh)


def test_cube_corner_is_closed_without_hole_fill():
    """Six axis struts cover the whole node: every seam is shared, nothing to fill."""
    dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    g = star_graph(dirs, 1.0, 0.1)
    P = segments_for_chord_error(0.05)
    mesh = stitch_lslt(g, chord_error=0.05)
    # each section: 4 triple points (cube diagonals) + 4 seams of 90 deg, ceil(P/4) - 1 inside
    per_section = 4 + 4 * (math.ceil(P / 4) - 1)
    assert len(mesh.faces) == 6 * (per_section + P) + 6 * (P - 2)
    assert_valid(mesh)


# --------------------------------------------------------- property tests
@pytest.mark.parametrize("d", [2, 3, 4, 5, 6, 8, 10, 12, 14, 18])
@pytest.mark.parametrize("kind", ["3d", "planar", "tapered"])
def test_random_stars_are_valid(rng, d, kind):
    for trial in range(2):
        g = random_star(rng, d, planar=kind == "planar", tapered=kind == "tapered")
        e = float(rng.choice([0.01, 0.02, 0.05, 0.1, 0.3]))
        mesh = stitch_lslt(g, chord_error=e, sections=[None, 2][trial], seed=trial)
        assert_valid(mesh)


@pytest.mark.parametrize("d", [3, 4, 6, 8, 12, 16])
def test_regular_planar_stars_are_valid(d):
    """All struts in one plane: every section meets the others at the two poles."""
    mesh = stitch_lslt(star_graph(planar_star(d), 1.0, 0.1), chord_error=0.02)
    assert_valid(mesh)


@pytest.mark.parametrize("sections", [None, 1, "auto"])
def test_jittered_grid_is_valid(rng, sections):
    nodes, edges = cubic_grid(4, 1.0)
    nodes = nodes + rng.uniform(-0.2, 0.2, nodes.shape)
    g = LatticeGraph(nodes, edges, rng.uniform(0.03, 0.08, len(edges)))
    assert_valid(stitch_lslt(g, chord_error=0.05, sections=sections))


@pytest.mark.parametrize("cell", ["cubic", "bcc", "octet", "kelvin", "reentrant", "fccz"])
def test_unit_cell_blocks_are_valid(cell):
    g = block(cell, (3, 3, 2), cell_size=10.0, radius=0.35)
    assert_valid(stitch_lslt(g, chord_error=0.05))


def test_jittered_bcc_and_octet_blocks_are_valid(rng):
    for cell, sections in (("bcc", "auto"), ("octet", None)):
        g0 = block(cell, 2, cell_size=10.0, radius=0.3)
        g = LatticeGraph(g0.nodes + rng.uniform(-0.6, 0.6, g0.nodes.shape), g0.edges, g0.radii)
        assert_valid(stitch_lslt(g, chord_error=0.02, sections=sections))


@pytest.mark.parametrize(
    "angle", [0.5, 3.0, 10.0, 30.0, 90.0, 140.0, 144.0, 145.0, 160.0, 179.0, 179.99, 180.0]
)
def test_degree_two_nodes_from_tight_to_collinear(angle):
    t = math.radians(angle)
    g = star_graph([[1, 0, 0], [math.cos(t), math.sin(t), 0]], 1000.0, 0.05)
    assert_valid(stitch_lslt(g))


# ------------------------------------------------------------ triangle counts
@pytest.mark.parametrize("e", [0.01, 0.05, 0.1])
@pytest.mark.parametrize("cell", ["bcc", "cubic", "octet"])
def test_fewer_triangles_than_the_default_method_at_equal_chord_error(cell, e):
    """The paper's claim, here against the default (Verma) stitcher."""
    g = block(cell, 3, cell_size=5.0, radius=0.3)
    lslt = stitch_lslt(g, chord_error=e)
    verma = fast_stitch.stitch(g, segments_for_chord_error(e))
    assert len(lslt.faces) < 0.8 * len(verma.faces)


def test_intermediary_sections_add_rings_and_improve_quality():
    """Eq. 17: each intermediary section adds one ring of triangles (quality goes up)."""
    g = block("bcc", 2, cell_size=10.0, radius=0.5)
    base = stitch_lslt(g, chord_error=0.05)
    one = stitch_lslt(g, chord_error=0.05, sections=1)
    two = stitch_lslt(g, chord_error=0.05, sections=2)
    ring = len(one.faces) - len(base.faces)
    assert ring > 0
    assert len(two.faces) > len(one.faces)
    auto = stitch_lslt(g, chord_error=0.05, sections="auto")
    q0, qa = triangle_quality(base), triangle_quality(auto)
    assert np.median(qa) > np.median(q0)
    for m in (one, two, auto):
        assert_valid(m)


def test_triangle_quality_metric():
    from lattice_cad.core.mesh import Mesh

    s3 = math.sqrt(3)
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, s3 / 2, 0], [0, 1, 0], [100, 0, 0]], float)
    q = triangle_quality(Mesh(v, np.array([[0, 1, 2], [0, 1, 3], [0, 4, 3]])))
    assert q[0] == pytest.approx(1.0)
    # right isosceles: inradius (2 - sqrt 2) / 2, circumradius sqrt(2) / 2
    assert q[1] == pytest.approx(2 * (2 - math.sqrt(2)) / 2 / (math.sqrt(2) / 2), rel=1e-12)
    assert q[2] < 0.05


# ------------------------------------------------------------------- errors
def tight_v(angle_deg, r=0.05, L=1.0):
    t = math.radians(angle_deg)
    return star_graph([[1, 0, 0], [math.cos(t), math.sin(t), 0]], L, r)


@pytest.mark.parametrize("angle", [0.5, 5.0, 20.0])
def test_small_angle_error_names_node_edges_angle_and_length(angle):
    with pytest.raises(StitchError) as err:
        stitch_lslt(tight_v(angle, r=0.05, L=0.6 * 0.05 / math.tan(math.radians(angle) / 2)))
    msg = str(err.value)
    assert re.search(r"node 0: struts [01] and [01] meet at", msg), msg
    assert f"{angle:.3g} degrees" in msg
    needed = float(re.search(r"longer than ([0-9.e+-]+)", msg).group(1))
    assert_valid(stitch_lslt(tight_v(angle, r=0.05, L=needed * 1.02)))


def test_parallel_struts_are_reported():
    g = LatticeGraph([[0, 0, 0], [1, 0, 0], [2, 1e-13, 0]], [[0, 1], [0, 2]], 0.01)
    with pytest.raises(StitchError, match="node 0: struts 0 and 1 leave it in the same direction"):
        stitch_lslt(g)


@pytest.mark.parametrize(
    "nodes, edges",
    [
        ([[-1, 0, 0], [1, 0, 0], [0, -1, 0.05], [0, 1, 0.05]], [[0, 1], [2, 3]]),
        ([[-1, 0, 0], [1, 0, 0], [0, 0.02, 0.0], [0, 1, 1], [0, 1, -1]], [[0, 1], [2, 3], [2, 4]]),
    ],
)
def test_struts_crossing_away_from_nodes_are_reported(nodes, edges):
    g = LatticeGraph(nodes, edges, 0.05)
    with pytest.raises(StitchError, match=r"strut 0 \(nodes 0, 1\) and strut 1 .* overlap"):
        stitch_lslt(g)


def test_clearance_passes_struts_just_apart():
    g = LatticeGraph([[-1, 0, 0], [1, 0, 0], [0, -1, 0.101], [0, 1, 0.101]], [[0, 1], [2, 3]], 0.05)
    assert_valid(stitch_lslt(g))


def test_bad_arguments():
    g = tight_v(90)
    with pytest.raises(ValueError, match="chord_error"):
        stitch_lslt(g, chord_error=0)
    with pytest.raises(ValueError, match="sections"):
        stitch_lslt(g, sections=-1)
    with pytest.raises(ValueError, match="sections"):
        stitch_lslt(g, sections="many")
    with pytest.raises(TypeError, match="LatticeGraph"):
        stitch_lslt(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="seed"):
        stitch_lslt(g, seed=-1)
    with pytest.raises(ValueError, match="workers"):
        stitch_lslt(g, workers=0)
    with pytest.raises(StitchError, match="no struts"):
        stitch_lslt(LatticeGraph(np.zeros((0, 3)), np.zeros((0, 2), int), 0.1))


def test_deterministic_and_progress():
    g = block("bcc", 2, cell_size=5.0, radius=0.3)
    a = stitch_lslt(g, seed=3, workers=1)
    b = stitch_lslt(g, seed=3, workers=2)
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.vertices, b.vertices)
    calls = []
    stitch_lslt(g, progress=lambda s, d, t: calls.append((s, d, t)))
    assert calls and calls[-1] == ("done", 1, 1)


def test_independent_checker_sees_lslt_mesh_breakage():
    mesh = stitch_lslt(tight_v(60))
    rep = independent_check(type(mesh)(mesh.vertices, mesh.faces[1:]))
    assert not rep["watertight"]


@pytest.mark.parametrize("jitter", [1e-11, 1e-8, 1e-6, 1e-4])
@pytest.mark.parametrize("cell", ["bcc", "cubic", "octet"])
def test_micro_jittered_blocks_near_cocircular_nodes(rng, cell, jitter):
    """Nodes a hair away from a co-circular configuration (floating-point noise)."""
    g0 = block(cell, 2, cell_size=10.0, radius=0.3)
    g = LatticeGraph(
        g0.nodes + rng.uniform(-10 * jitter, 10 * jitter, g0.nodes.shape), g0.edges, 0.3
    )
    assert_valid(stitch_lslt(g, chord_error=0.05), self_intersections=False)


@pytest.mark.parametrize("tilt", [1e-12, 1e-8, 3e-6, 1.5e-5, 3e-5, 1e-3])
@pytest.mark.parametrize("d", [3, 5, 8])
def test_nearly_planar_stars(rng, tilt, d):
    t = 2 * np.pi * np.arange(d) / d + 0.1
    dirs = np.column_stack([np.cos(t), np.sin(t), np.full(d, tilt)])
    dirs[0, 2] = -0.5 * tilt
    g = star_graph(dirs, 1.0, rng.uniform(0.02, 0.08, d))
    assert_valid(stitch_lslt(g, chord_error=0.02))
