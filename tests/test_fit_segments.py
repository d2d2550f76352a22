"""The builders fit strut radii for the profile polygons the lattice is stitched with.

Fewer sides make wider polygons (``profile="volume"``: circumradius ``1.25 r`` at P = 4,
``1.56 r`` at P = 3, against ``1.10 r`` at the default P = 6), so radii fitted for P = 6
may not stitch at P = 3 or 4. ``Lattice.fill(segments=P)``, ``lattice-cad fill
--segments P``, ``voxel_lattice(segments=P)`` and ``tet_lattice(segments=P)`` fit for P.
"""

from __future__ import annotations

import numpy as np
import pytest

import fast_stitch
from conformal import tet_lattice, voxel_lattice
from conformal.part import load_part
from conformal.radius import check_fit, check_stitch_profile, fit_radii, repair_graph
from fast_stitch import StitchError
from lattice_cad import Lattice
from lattice_cad.cli import main
from lattice_cad.core.errors import FitError, LatticeWarning
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.lattice import load_graph
from tests.conftest import DATA, assert_valid

ROCKER = DATA / "meshes" / "rocker-arm.off"  # 1 unit tall: an octet of 0.1 conforms to it
SPANNER = DATA / "step" / "dolfiny_spanner25_lo.step"
GE_BRACKET = DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step"


# thinning is what these fills are for
pytestmark = [
    pytest.mark.filterwarnings("ignore:.*were thinned:lattice_cad.core.errors.LatticeWarning"),
    pytest.mark.filterwarnings("ignore:.*thinner than:lattice_cad.core.errors.LatticeWarning"),
]


@pytest.fixture(scope="module")
def rocker():
    return load_part(ROCKER)


@pytest.mark.parametrize("P", [3, 4])
def test_fill_fits_for_its_segments(rocker, P):
    lat = Lattice.fill(rocker, "octet", 0.1, 0.005, segments=P)
    assert lat.segments == P and lat.build_report.fill == "conform"
    assert check_fit(lat.graph, P) == []
    assert_valid(lat.mesh(lattice_only=True), self_intersections=False)
    # the same graph fitted for the default P = 6 does not stitch at P (the old fill)
    lat6 = Lattice.fill(rocker, "octet", 0.1, 0.005)
    g6 = lat6.graph
    np.testing.assert_array_equal(g6.edges, lat.graph.edges)
    assert check_fit(g6, P) != []
    with pytest.raises(StitchError, match="too small an angle"):
        fast_stitch.stitch(g6, P)
    # the wider polygons need more thinning, never thicker struts than asked
    assert lat.build_report.radii_reduced > lat6.build_report.radii_reduced
    assert lat.graph.radii.max() == 0.005


def test_cli_fill_segments(rocker, tmp_path, capsys):
    out = tmp_path / "g.npz"
    argv = ["fill", str(ROCKER), "-o", str(out), "--cell", "octet", "--cell-size", "0.1",
            "--radius", "0.005", "--segments", "4", "-q"]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    g = load_graph(out)
    assert check_fit(g, 4) == []
    assert_valid(fast_stitch.stitch(g, 4), self_intersections=False)


@pytest.fixture(scope="module")
def ge_bracket():
    with pytest.warns(LatticeWarning, match="solids were united"):
        return load_part(GE_BRACKET)


def test_voxel_inside_fill_fits_for_segments(ge_bracket):
    # whole octet cells of 8 mm at r = 1.15: the P = 6 hexagons fit (nothing thinned),
    # the P = 3 triangles (circumradius 1.56 r) need thinner struts at every node
    part = ge_bracket
    g6, rep6 = voxel_lattice(part, "octet", 8.0, 1.15, fit="off", return_report=True)
    assert check_fit(g6, 6) == [] and check_fit(g6, 3) != []
    with pytest.raises(StitchError):
        fast_stitch.stitch(g6, 3)
    g3, rep3 = voxel_lattice(part, "octet", 8.0, 1.15, segments=3, return_report=True)
    assert rep3.radii_reduced > 0 and check_fit(g3, 3) == []
    fast_stitch.stitch(g3, 3)  # raises if it does not stitch
    # the inscribed triangles are no wider than the circle: they fit as P = 6 "volume"
    gi = voxel_lattice(part, "octet", 8.0, 1.15, segments=3, profile="inscribed")
    np.testing.assert_array_equal(gi.radii, g6.radii)
    assert check_fit(gi, 3, profile="inscribed") == []
    with pytest.raises(FitError, match="would not stitch"):
        voxel_lattice(part, "octet", 8.0, 1.15, segments=3, fit="raise")


def test_tet_fill_fits_for_segments():
    part = load_part(SPANNER)
    g, rep = tet_lattice(part, 4.0, 0.4, segments=4, return_report=True)
    assert check_fit(g, 4) == []
    assert_valid(fast_stitch.stitch(g, 4), self_intersections=False)


def test_repair_and_fit_take_segments():
    # two struts at 40 degrees to a third one: r = 0.27 fits at P = 6 (up to 0.31), not at
    # P = 3 (up to 0.22)
    d = np.radians(40.0)
    nodes = np.array([[0, 0, 0], [1, 0, 0], [np.cos(d), np.sin(d), 0], [np.cos(d), 0, np.sin(d)],
                      [-1, 0, 0]], dtype=np.float64)  # fmt: skip
    edges = np.array([[0, 1], [0, 2], [0, 3], [0, 4]])
    r = np.full((4, 2), 0.27)
    assert len(fit_radii(nodes, edges, r)[1]) == 0
    r6, _ = fit_radii(nodes, edges, r)
    r3, _ = fit_radii(nodes, edges, r, segments=3)
    assert (r3 <= r6).all() and (r3 < r6).any()
    assert check_fit(LatticeGraph(nodes, edges, r6), 3) != []
    assert check_fit(LatticeGraph(nodes, edges, r3), 3) == []
    n2, e2, fitted, _ = repair_graph(nodes, edges, r, segments=3)
    assert check_fit(LatticeGraph(n2, e2, fitted), 3) == []
    n2, e2, fitted, _ = repair_graph(nodes, edges, r)
    assert check_fit(LatticeGraph(n2, e2, fitted), 3) != []  # fitted for P = 6


@pytest.mark.parametrize(
    ("segments", "profile", "error"),
    [(2, "volume", ValueError), (4.0, "volume", TypeError), (True, "volume", TypeError),
     (4, "round", ValueError), (4, None, TypeError)],
)  # fmt: skip
def test_bad_segments_or_profile(segments, profile, error):
    with pytest.raises(error, match="segments|profile"):
        check_stitch_profile(segments, profile)


@pytest.mark.slow
def test_ge_bracket_tet_at_four_segments(ge_bracket):
    # the case seen: tet 5 mm r 0.6 of the GE bracket, fitted for P = 6, did not stitch at 4
    lat = Lattice.fill(ge_bracket, method="tet", cell_size=5.0, radius=0.6, segments=4)
    assert check_fit(lat.graph, 4) == []
    assert_valid(lat.mesh(lattice_only=True), self_intersections=False)


def test_fill_and_cli_take_min_radius(ge_bracket, tmp_path, capsys):
    """``Lattice.fill(min_radius=)`` / ``--min-radius``: the thinnest a strut may be made.
    The P = 3 octet needs thinning (above); forbidding any thinning is a FitError that
    names the option, a floor below what the fit needs is kept by every strut."""
    with pytest.raises(FitError, match="--min-radius"):
        Lattice.fill(ge_bracket, "octet", 8.0, 1.15, fill="inside", segments=3,
                     min_radius=1.15)  # fmt: skip
    lat = Lattice.fill(ge_bracket, "octet", 8.0, 1.15, fill="inside", segments=3,
                       min_radius=0.5)  # fmt: skip
    r = lat.graph.radii
    assert r.min() >= 0.5 and r.min() < 1.15
    out = tmp_path / "g.npz"
    argv = ["fill", str(GE_BRACKET), "-o", str(out), "--cell", "octet", "--cell-size", "8",
            "--radius", "1.15", "--fill", "inside", "--segments", "3", "--min-radius",
            "1.15", "-q"]  # fmt: skip
    assert main(argv) == 1
    assert "--min-radius" in capsys.readouterr().err
    assert not out.exists()


def test_repair_of_struts_far_too_thick_names_the_radius():
    """Regression (`lattice-cad fill rocker-arm.off --method tet --segments 3` with the
    default 5 mm cell and radius 0.4 on a part 1 unit tall): every strut was hopeless, the
    repair dropped them all and a raw numpy error ("zero-size array to reduction operation
    minimum") reached the user. It is a FitError naming the radius now."""
    rng = np.random.default_rng(7)
    nodes = rng.random((40, 3))
    tri = __import__("scipy.spatial", fromlist=["Delaunay"]).Delaunay(nodes)
    from conformal.tet import tet_edges

    edges = tet_edges(np.asarray(tri.simplices, dtype=np.int64))
    # struts of length <= 1.7 at radius 4: none fits even at a tenth of it
    with pytest.raises(FitError, match="radius 4 .*smaller radius"):
        repair_graph(nodes, edges, np.full((len(edges), 2), 4.0), segments=3)
