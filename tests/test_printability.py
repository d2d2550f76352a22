"""conformal.printability: strut angles to the build plate, overhangs, thin struts,
unsupported nodes, overhang removal, self-supporting cells and orientations; the front
(Lattice.fill / info / validate, the CLI)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DATA, ROOT, star_graph
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from conformal import CELLS, block, load_part
from conformal.printability import (
    as_build_direction,
    best_orientation,
    cell_angles,
    printability,
    remove_overhangs,
    self_supporting_cells,
    strut_angles,
)
from lattice_cad import LatticeGraph
from lattice_cad.core.errors import LatticeWarning, PrintabilityError
from lattice_cad.lattice import Lattice

BCC_ANGLE = math.degrees(math.asin(1.0 / math.sqrt(3.0)))  # 35.26...
ANGLES = np.array([0.0, 30.0, 35.0, 45.0, 90.0])


def _dirs(angles_deg, azimuths_deg):
    a, p = np.radians(angles_deg), np.radians(azimuths_deg)
    return np.column_stack([np.cos(a) * np.cos(p), np.cos(a) * np.sin(p), np.sin(a)])


def _random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _pieces(g: LatticeGraph) -> int:
    n = g.num_nodes
    m = coo_matrix((np.ones(g.num_edges), (g.edges[:, 0], g.edges[:, 1])), shape=(n, n))
    k, lab = connected_components(m, directed=False)
    return len(np.unique(lab[g.edges[:, 0]]))


def _star(rotation=None, lengths=(1.0, 2.0, 1.5, 3.0, 0.7)):
    """Struts at 0, 30, 35, 45, 90 degrees to the XY plane (azimuths 0, 50, 100, 150, 200)."""
    d = _dirs(ANGLES, [0.0, 50.0, 100.0, 150.0, 200.0])
    if rotation is not None:
        d = d @ rotation.T
    return star_graph(d, lengths=np.asarray(lengths), radii=0.05)


# ------------------------------------------------------------------ angles
def test_angles_closed_form():
    g = _star()
    np.testing.assert_allclose(strut_angles(g), ANGLES, atol=1e-9)
    rep = printability(g)
    assert rep.overhanging.tolist() == [0, 1]  # 0 and 30; exactly 35 is not an overhang
    assert rep.overhang_count == 2 and rep.overhang_fraction == pytest.approx(0.4)
    assert rep.min_angle == pytest.approx(0.0, abs=1e-12)
    assert printability(g, critical_angle=45.0).overhanging.tolist() == [0, 1, 2]
    assert printability(g, critical_angle=45.0 + 1e-6).overhanging.tolist() == [0, 1, 2, 3]
    assert printability(g, critical_angle=0.0).overhang_count == 0
    assert printability(g, critical_angle=90.0).overhanging.tolist() == [0, 1, 2, 3]
    # the strut direction does not matter: reversed struts have the same angles
    rev = LatticeGraph(g.nodes, g.edges[:, ::-1], g.radii)
    np.testing.assert_allclose(strut_angles(rev), ANGLES, atol=1e-9)


def test_tilted_build_direction(rng):
    for _ in range(5):
        r = _random_rotation(rng)
        g = _star(r)
        b = r @ np.array([0.0, 0.0, 1.0])
        np.testing.assert_allclose(strut_angles(g, 7.5 * b), ANGLES, atol=1e-9)
        assert printability(g, build_direction=-3 * b).overhanging.tolist() == [0, 1]
    # a strut along x stands at 45 degrees for the build direction (1, 0, 1)
    g = star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1]])
    np.testing.assert_allclose(strut_angles(g, (1, 0, 1)), [45, 0, 45, 90], atol=1e-9)
    rep = printability(g, build_direction=(1, 0, 1))
    np.testing.assert_allclose(rep.build_direction, [2**-0.5, 0, 2**-0.5])
    assert rep.overhanging.tolist() == [1]
    assert "(0.7071, 0, 0.7071)" in str(rep)
    assert "build direction +Z" in str(printability(g))
    assert "build direction -X" in str(printability(g, build_direction=(-2, 0, 0)))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"build_direction": (0, 0, 0)}, "must not be the zero vector"),
        ({"build_direction": (0, 0, float("nan"))}, "3 finite numbers"),
        ({"build_direction": (0, 1)}, "3 finite numbers"),
        ({"build_direction": "up"}, "3 numbers"),
        ({"critical_angle": 91}, r"0\.\.90"),
        ({"critical_angle": -1}, r"0\.\.90"),
        ({"critical_angle": True}, "number of degrees"),
        ({"min_diameter": -0.1}, ">= 0"),
        ({"min_diameter": float("inf")}, ">= 0"),
    ],
)
def test_bad_options_are_named(kwargs, match):
    with pytest.raises(PrintabilityError, match=match):
        printability(_star(), **kwargs)
    assert issubclass(PrintabilityError, ValueError)


def test_as_build_direction_normalises():
    np.testing.assert_allclose(as_build_direction([0, 0, 5]), [0, 0, 1])
    np.testing.assert_allclose(as_build_direction([3, 4, 0]), [0.6, 0.8, 0])


def test_thin_struts():
    g = star_graph(np.eye(3), lengths=2.0, radii=np.array([[0.1, 0.3], [0.25, 0.2], [0.19, 0.5]]))
    rep = printability(g, min_diameter=0.4)
    np.testing.assert_allclose(rep.diameters, [0.2, 0.4, 0.38])
    assert rep.thin.tolist() == [0, 2]  # 0.4 exactly is printable
    assert rep.thinnest == pytest.approx(0.2)
    assert printability(g, min_diameter=0.0).thin_count == 0
    assert printability(g).min_diameter == 0.4  # the documented default


def test_unsupported_nodes():
    # plate node 0; node 1 straight above (vertical strut: supported); node 2 level with
    # node 1 and joined only horizontally (unsupported); node 3 reached from node 0 at 30
    # degrees only (unsupported at 35, supported at 25); node 4 above node 2 (supported
    # by a vertical strut from an unsupported node: the strut itself is printable)
    c30 = (math.cos(math.radians(30)), 0.0, math.sin(math.radians(30)))
    nodes = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 1], [*c30], [0, 1, 2]], dtype=float)
    nodes[3] *= 2.0
    edges = np.array([[0, 1], [1, 2], [0, 3], [2, 4]])
    g = LatticeGraph(nodes, edges, 0.05)
    assert printability(g).unsupported.tolist() == [2, 3]
    assert printability(g, critical_angle=25.0).unsupported.tolist() == [2]
    # upside down: node 4 is the lowest (the plate), everything hangs from it
    up = printability(g, build_direction=(0, 0, -1))
    # 0 stands on 1 (vertical); 1 hangs beside 2 and under 0; 3 hangs at 30 deg under 0
    assert up.unsupported.tolist() == [1, 3]
    assert not printability(g).self_supporting


def test_examples_lowest_angle_first():
    g = _star()
    rep = printability(g, critical_angle=40.0, examples=2)
    assert rep.examples[:, 0].tolist() == [0, 1]
    np.testing.assert_allclose(rep.examples[:, 1], [0, 30], atol=1e-9)
    mids = 0.5 * (g.nodes[g.edges[[0, 1], 0]] + g.nodes[g.edges[[0, 1], 1]])
    np.testing.assert_allclose(rep.examples[:, 2:], mids)
    d = rep.to_dict()
    assert d["overhangs"] == 3 and d["overhanging_struts"] == [0, 1, 2]
    assert d["examples"][1]["strut"] == 1
    rows = {r["quantity"]: r["value"] for r in rep.to_records()}
    assert rows["overhanging struts"] == "3 of 5 (60.00%)"


# ------------------------------------------------------------- unit cells
def test_blocks_closed_form():
    n = 3
    # bcc: every strut is a body diagonal, at asin(1/sqrt(3)) = 35.26 degrees
    rep = printability(block("bcc", n, cell_size=5.0, radius=0.4))
    np.testing.assert_allclose(rep.angles, BCC_ANGLE, atol=1e-9)
    assert rep.overhang_count == 0 and rep.self_supporting
    assert printability(block("bcc", n, cell_size=5.0), critical_angle=36).overhang_fraction == 1
    # octet: 4 horizontal face diagonals per z-face, 4 octahedron equator edges per cell
    rep = printability(block("octet", n, cell_size=5.0, radius=0.4))
    assert rep.overhang_count == 4 * n * n * (n + 1) + 4 * n**3
    assert set(np.round(rep.angles, 9)) == {0.0, 45.0}
    # cubic: the two horizontal families of cube edges
    rep = printability(block("cubic", n, cell_size=5.0, radius=0.4))
    assert rep.overhang_count == 2 * n * (n + 1) ** 2
    assert set(np.round(rep.angles, 9)) == {0.0, 90.0}


def test_cell_angles_and_self_supporting_cells():
    angles = cell_angles()
    for name, cell in CELLS.items():  # from the integer coordinates, independently
        d = (cell.nodes[cell.edges[:, 1]] - cell.nodes[cell.edges[:, 0]]).astype(float)
        s = np.abs(d[:, 2]) / np.linalg.norm(d, axis=1)
        assert angles[name] == pytest.approx(math.degrees(math.asin(s.min())), abs=1e-9)
    assert self_supporting_cells() == ["bcc", "bccz", "diamond", "rhombic-dodecahedron"]
    assert "reentrant" in self_supporting_cells(critical_angle=26.5)  # atan(1/2) = 26.57
    # lying on its side (build direction +X) the cubic grid is as bad; bcc as good
    assert angles["cubic"] == 0.0 == cell_angles((1, 0, 0))["cubic"]
    assert cell_angles((1, 0, 0))["bcc"] == pytest.approx(BCC_ANGLE)
    # a grid rotated by 45 degrees about x: bcc gets horizontal struts (0, 1, 1) -> ...
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    assert cell_angles(rotation=rot)["bcc"] == pytest.approx(0.0, abs=1e-9)
    assert cell_angles(rotation=rot)["cubic"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    ("cell", "angle", "direction"),
    [
        ("cubic", BCC_ANGLE, np.ones(3) / math.sqrt(3)),
        ("bcc", BCC_ANGLE, np.array([0.0, 0.0, 1.0])),  # already best: not rotated
        ("octet", math.degrees(math.asin(1 / math.sqrt(10))), None),  # a (2, 1, 0) direction
        ("kelvin", math.degrees(math.asin(1 / math.sqrt(10))), None),
    ],
)
def test_best_orientation(cell, angle, direction, rng):
    for b in (np.array([0.0, 0.0, 1.0]), rng.normal(size=3)):
        o = best_orientation(cell, b)
        bu = b / np.linalg.norm(b)
        assert o.min_angle == pytest.approx(angle, abs=1e-9)
        r = o.rotation
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r @ o.lattice_direction, bu, atol=1e-12)
        # the rotated cell, measured independently, has that smallest angle
        assert cell_angles(b, rotation=r)[cell] == pytest.approx(angle, abs=1e-9)
        if direction is not None:  # up to the cell's symmetry
            np.testing.assert_allclose(np.sort(np.abs(o.lattice_direction)), direction, atol=1e-12)
        else:
            assert sorted(np.round(np.abs(o.lattice_direction) ** 2 * 5, 9)) == [0, 1, 4]
    assert np.allclose(best_orientation("bcc").rotation, np.eye(3))


# ---------------------------------------------------------------- removal
def test_remove_overhangs_octet_stays_one_body():
    g = block("octet", 3, cell_size=5.0, radius=np.linspace(0.3, 0.4, 756))
    out, rm = remove_overhangs(g)
    assert (rm.removed_overhangs, rm.removed_islands, rm.islands, rm.bodies) == (252, 0, 0, 1)
    assert out.num_edges == rm.struts_after == 504 and rm.kept.sum() == 504
    assert _pieces(out) == 1
    assert printability(out).overhang_count == 0
    # the kept struts are the same struts, with their radii, in order
    kept = np.flatnonzero(rm.kept)
    np.testing.assert_array_equal(out.nodes[out.edges], g.nodes[g.edges[kept]])
    np.testing.assert_array_equal(out.radii, g.radii[kept])
    assert "removed 252 overhanging strut(s)" in str(rm)


def test_remove_overhangs_cuts_islands_and_says_so():
    n = 3
    g = block("cubic", n, cell_size=5.0, radius=0.4)
    with pytest.warns(LatticeWarning, match=r"15 loose piece\(s\).*bcc, bccz, diamond"):
        out, rm = remove_overhangs(g)
    # only the (n+1)^2 vertical columns of n struts are left; one column is kept
    assert rm.removed_overhangs == 2 * n * (n + 1) ** 2
    assert rm.islands == (n + 1) ** 2 - 1 and rm.removed_islands == rm.islands * n
    assert out.num_edges == n and _pieces(out) == 1
    assert rm.removed_nodes == (n + 1) ** 3 - (n + 1)


def test_remove_overhangs_tilted_direction():
    # build direction (1, 1, 0): half of bcc's body diagonals are horizontal
    g = block("bcc", 3, cell_size=5.0, radius=0.4)
    b = (1.0, 1.0, 0.0)
    rep = printability(g, build_direction=b)
    assert rep.overhang_count == g.num_edges // 2
    d = g.edge_vectors
    assert set(rep.overhanging) == set(np.flatnonzero(np.abs(d[:, 0] + d[:, 1]) < 1e-9))
    with pytest.warns(LatticeWarning, match="not self-supporting"):
        out, rm = remove_overhangs(g, build_direction=b)
    assert _pieces(out) == 1 and printability(out, build_direction=b).overhang_count == 0
    assert rm.removed_overhangs == g.num_edges // 2


def test_remove_everything_is_refused():
    g = star_graph([[1, 0, 0], [0, 1, 0]])
    with pytest.raises(PrintabilityError, match="all 2 struts are below 35 deg"):
        remove_overhangs(g)


# --------------------------------------------------------------- real part
@pytest.fixture(scope="module")
def ge_bracket():
    with pytest.warns(LatticeWarning, match="solids were united"):
        return load_part(DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step")


def test_ge_bracket_bcc_and_octet(ge_bracket):
    bcc = Lattice.fill(ge_bracket, "bcc", 6.0, 0.4)
    rep = bcc.info()["printability"]
    assert rep.num_struts == bcc.graph.num_edges > 5000
    assert rep.overhang_count == 0 and rep.min_angle == pytest.approx(BCC_ANGLE, abs=1e-6)
    assert rep.thin_count == 0 and rep.thinnest <= 0.8
    # octet: the struts with no z extent are exactly the overhangs (the others are at 45)
    octet = Lattice.fill(ge_bracket, "octet", 6.0, 0.4)
    rep = octet.printability()
    d = octet.graph.edge_vectors
    flat = np.abs(d[:, 2]) <= 1e-9 * np.linalg.norm(d, axis=1)
    assert rep.overhang_count == flat.sum() > 0
    assert set(rep.overhanging) == set(np.flatnonzero(flat))
    assert 0.25 < rep.overhang_fraction < 0.4  # 1/3 in the infinite lattice
    # and with a 0.9 mm printer the 0.8 mm struts are thin (those thinned by the fit too)
    thin = octet.printability(min_diameter=0.9)
    assert thin.thin_count == octet.graph.num_edges
    # removal keeps one body of the part, without overhangs
    lat = Lattice.fill(ge_bracket, "octet", 6.0, 0.4, remove_overhangs=True)
    rm = lat.overhang_removal
    assert rm.removed_overhangs == rep.overhang_count and rm.bodies == 1
    assert _pieces(lat.graph) == 1
    assert lat.printability().overhang_count == 0
    assert lat.info()["overhang_removal"] is rm


def test_self_supporting_cubic_on_a_part(ge_bracket):
    lat = Lattice.fill(ge_bracket, "cubic", 6.0, 0.4, self_supporting=True)
    rep = lat.printability()
    assert rep.overhang_count == 0
    np.testing.assert_allclose(rep.angles, BCC_ANGLE, atol=1e-9)
    with pytest.raises(PrintabilityError, match=r"no orientation makes 'octet'.*18\.43"):
        Lattice.fill(ge_bracket, "octet", 6.0, 0.4, self_supporting=True)
    with pytest.raises(PrintabilityError, match="not both"):
        Lattice.fill(ge_bracket, "cubic", 6.0, self_supporting=True, rotation=np.eye(3))
    with pytest.raises(PrintabilityError, match="zero vector"):
        Lattice.fill(ge_bracket, "cubic", 6.0, build_direction=(0, 0, 0))


# ------------------------------------------------------------------ front
def test_lattice_printability_settings():
    lat = Lattice(block("octet", 2, cell_size=5.0, radius=0.4))
    assert lat.info()["printability"].overhang_count == 4 * 4 * 3 + 4 * 8
    assert lat.info()["overhang_removal"] is None
    lat.build_direction = (0, 1, 0)  # octet is cubic-symmetric: the same count along y
    assert lat.printability().overhang_count == 4 * 4 * 3 + 4 * 8
    assert lat.printability(critical_angle=0).overhang_count == 0


@pytest.mark.slow
def test_validate_report_has_the_printability_table(tmp_path):
    lat = Lattice(block("bcc", 1, cell_size=5.0, radius=0.4))
    lat.critical_angle = 40.0
    rep = lat.validate(report=tmp_path / "r.md", union_segments=(16,), samples=2000)
    text = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert "## Printability (build direction +Z, critical angle 40 deg)" in text
    assert "| overhanging struts | 8 of 8 (100.00%) |" in text
    assert any(k.startswith("Printability") for k in rep.extra)


def _cli(capsys, *argv):
    from lattice_cad.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


BRACKET = ROOT / "examples" / "bracket.step"


def test_cli_fill_prints_printability(capsys, tmp_path):
    out = tmp_path / "g.json"
    code, text, err = _cli(
        capsys, "fill", BRACKET, "-o", out, "--cell", "octet", "--cell-size", "6",
        "--build-direction", "0,1,0", "--critical-angle", "40", "--min-diameter", "0.9",
    )  # fmt: skip
    assert code == 0, err
    g = LatticeGraph.load(out)
    rep = printability(g, build_direction=(0, 1, 0), critical_angle=40, min_diameter=0.9)
    assert "build direction +Y, critical angle 40 deg, min diameter 0.9 mm" in text
    assert f"overhangs: {rep.overhang_count:,} of {g.num_edges:,} struts" in text
    assert f"thin: {rep.thin_count:,} strut(s) below 0.9 mm" in text
    assert "self-supporting cells along +Y at 40 deg: none" in text
    code, text, err = _cli(
        capsys, "fill", BRACKET, "-o", out, "--cell", "octet", "--cell-size", "6",
        "--remove-overhangs",
    )  # fmt: skip
    assert code == 0, err
    g = LatticeGraph.load(out)
    assert printability(g).overhang_count == 0 and _pieces(g) == 1
    assert "removed " in text and "overhanging strut(s)" in text


def test_cli_self_supporting_and_errors(capsys, tmp_path):
    out = tmp_path / "g.json"
    code, text, err = _cli(
        capsys, "fill", BRACKET, "-o", out, "--cell", "cubic", "--cell-size", "6",
        "--self-supporting",
    )  # fmt: skip
    assert code == 0, err
    assert printability(LatticeGraph.load(out)).overhang_count == 0
    code, text, err = _cli(
        capsys, "fill", BRACKET, "-o", out, "--cell", "octet", "--self-supporting"
    )
    assert code == 1 and "no orientation makes 'octet' self-supporting" in err
    for bad in (["--build-direction", "0,0,0"], ["--build-direction", "1,2"],
                ["--critical-angle", "95"], ["--min-diameter", "-1"]):  # fmt: skip
        with pytest.raises(SystemExit) as e:
            _cli(capsys, "fill", BRACKET, "-o", out, *bad)
        assert e.value.code == 2


def test_cli_graph_options(tmp_path):
    """``validate GRAPH`` applies the options to a graph read from a file (no part)."""
    from lattice_cad.cli import _graph_print_options, build_parser

    src = tmp_path / "g.json"
    block("cubic", 2, cell_size=5.0, radius=0.4).save(src)
    args = build_parser().parse_args(
        ["validate", str(src), "--report", "r", "--remove-overhangs", "--critical-angle", "30"]
    )
    lat = Lattice(LatticeGraph.load(src))
    with pytest.warns(LatticeWarning, match=r"8 loose piece\(s\)"):
        _graph_print_options(lat, args)
    assert lat.critical_angle == 30.0 and lat.overhang_removal.removed_overhangs == 36
    assert lat.graph.num_edges == 2 and lat.printability().overhang_count == 0
    args = build_parser().parse_args(["validate", str(src), "--report", "r", "--self-supporting"])
    with pytest.raises(PrintabilityError, match="not a graph"):
        _graph_print_options(lat, args)
