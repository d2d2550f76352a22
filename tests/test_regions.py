"""The report's deviation along struts and at hubs (issue 14 item 3: "surface deviation p95
under 10 % of the radius where the two model the same design").

Closed forms: along a strut, a prism of inscribed regular P-gons is at most the chord error
``r (1 - cos(pi / P))`` from its cylinder, and a prism of equal-area P-gons (circumradius
``rho = area_factor(P) r``) at most ``max(rho - r, r - rho cos(pi / P))``; at a node the
mesh's convex hub and the reference's ball and cylinders differ by a sizeable fraction of
``r``. The strut-region figures must equal the closed forms (so a mask that let hub samples
through would fail), and the hub-region figures must be far larger.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import fast_stitch
from fast_stitch.hubvolume import area_factor
from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph
from reference_boolean import build_reference, compare
from reference_boolean.compare import surface_deviation
from reference_boolean.regions import hub_zones, in_hub_zone, region_stats
from tests.conftest import ROOT, star_graph

R = 0.1
P = 6
DIRS = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]


@pytest.fixture(scope="module")
def corner():
    """Three orthogonal struts of radius 0.1, length 1 from one node (leaves at the far
    ends), its exact reference tessellated to 0.1 % of r, and the inscribed and equal-area
    P = 6 meshes."""
    g = star_graph(DIRS, lengths=1.0, radii=R)
    ref = build_reference(g, tolerance=1e-3 * R, keep_solids=False)
    meshes = {p: fast_stitch.stitch(g, P, profile=p) for p in ("inscribed", "area")}
    return g, ref, meshes


def test_hub_zone_closed_forms():
    f = config.HUB_ZONE_FACTOR
    # two struts at angle a, equal radii: t = r cot(a/2), E = sqrt(t^2 + r^2) = r / sin(a/2)
    for a in (30.0, 60.0, 90.0, 120.0):
        t = math.radians(a)
        g = star_graph([[1, 0, 0], [math.cos(t), math.sin(t), 0]], lengths=1.0, radii=R)
        z = hub_zones(g)
        want = f * max(R / math.sin(t / 2), config.SPHERE_FACTOR * R)
        assert z[0] == pytest.approx(want, rel=1e-12), a
        assert z[1] == z[2] == 0.0  # leaves end flat in both designs: no hub zone
    # straight through: the struts never meet outside the ball
    g = star_graph([[1, 0, 0], [-1, 0, 0]], lengths=1.0, radii=R)
    assert hub_zones(g)[0] == pytest.approx(f * config.SPHERE_FACTOR * R, rel=1e-12)
    # unequal radii at 90 degrees: strut i clears strut j at t_i = r_j / sin 90 = r_j
    nodes = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    g = LatticeGraph(nodes, np.array([[0, 1], [0, 2]]), np.array([0.1, 0.3]))
    # strut 0 (r 0.1) clears at 0.3: sqrt(0.09 + 0.01); strut 1 (r 0.3) at 0.1: sqrt(0.01+0.09)
    assert hub_zones(g, factor=1.0)[0] == pytest.approx(math.sqrt(0.1), rel=1e-12)
    with pytest.raises(ValueError, match="factor"):
        hub_zones(g, factor=0.9)


def test_strut_deviation_is_the_chord_error_and_the_hub_is_not(corner):
    g, ref, meshes = corner
    rep = compare(g, meshes=meshes, reference=ref, union_segments=(), samples=20_000)
    chord = R * (1 - math.cos(math.pi / P))
    rho = area_factor(P) * R
    area_dev = max(rho - R, R - rho * math.cos(math.pi / P))
    tess = 2e-3 * R  # the reference's tessellation (0.1 % of r) and sampling
    # p95 near the maximum: the inscribed prism's faces are mostly near their middle line;
    # the equal-area prism's largest distance is only at its edges
    for prof, want, low in (("inscribed", chord, 0.9), ("area", area_dev, 0.75)):
        reg = rep.comparisons[prof].regions
        s = reg["struts"]["symmetric"]
        assert 0.5 < s["fraction"] < 0.95, prof
        assert s["max"] == pytest.approx(want, abs=tess), prof
        assert low * want < s["p95"] <= s["max"], prof
        # at the hub the designs differ: the hull against the ball and the crevices
        assert reg["hubs"]["symmetric"]["max"] > 3 * want, prof
        # the whole-surface figures contain the hubs
        assert rep.comparisons[prof].hausdorff["symmetric"]["max"] == pytest.approx(
            max(s["max"], reg["hubs"]["symmetric"]["max"])
        )
    # the verdict judges the deviation along struts and says so
    v = rep.verdict("inscribed")
    assert v.deviation_region == "struts"
    assert v.deviation["p95"] == rep.comparisons["inscribed"].regions["struts"]["symmetric"]["p95"]
    assert v.deviation_hubs["max"] > 3 * chord
    # without zones: the whole surface, as before
    plain = compare(
        g, meshes=meshes, reference=ref, union_segments=(), samples=2_000, hub_zone_factor=None
    )
    assert plain.hub_zone is None and not plain.comparisons["inscribed"].regions
    assert plain.verdict("inscribed").deviation_region == "whole surface"


def test_a_too_small_hub_zone_would_let_the_hub_through(corner):
    """The mask matters: with half the zone the 'strut' figures jump to the hub's."""
    g, ref, meshes = corner
    mesh = meshes["inscribed"]
    chord = R * (1 - math.cos(math.pi / P))
    p1, d1 = surface_deviation(mesh, ref.mesh, samples=20_000)
    p2, d2 = surface_deviation(ref.mesh, mesh, samples=20_000, seed=1)
    zones = hub_zones(g)
    good = region_stats(in_hub_zone(p1, g, zones), d1, in_hub_zone(p2, g, zones), d2)
    bad = region_stats(in_hub_zone(p1, g, zones / 2), d1, in_hub_zone(p2, g, zones / 2), d2)
    assert good["struts"]["symmetric"]["max"] < 1.05 * chord
    assert bad["struts"]["symmetric"]["max"] > 2 * chord
    # every sample is in exactly one region
    for side in ("mesh_to_reference", "reference_to_mesh"):
        n = good["struts"][side]["samples"] + good["hubs"][side]["samples"]
        assert n == len(d1 if side == "mesh_to_reference" else d2)


def test_fast_stitch_hubs_lie_inside_the_hub_zones():
    """HUB_ZONE_FACTOR covers fast_stitch's convex hub (every profile vertex of a node's
    struts) at P >= 4 for every profile, on a real part's clipped lattice (short struts,
    small angles, grown boundary hubs)."""
    from lattice_cad.core.errors import LatticeWarning
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        g = Lattice.fill(ROOT / "examples" / "bracket.step", "bcc", 5.0, 0.5, fill="clip").graph
    zones = hub_zones(g)
    hub = g.degree >= 2
    assert hub.sum() > 100
    worst = 0.0
    for P_ in (4, 6, 12):
        for prof in ("volume", "area", "inscribed", "circumscribed"):
            try:
                m = fast_stitch.stitch(g, P_, profile=prof)
            except Exception:  # noqa: BLE001 - a profile that does not fit is not measured
                continue
            # hub rings, then (profile="volume") the band rings: (k, M, 2, P, 3)
            v = m.vertices.reshape(-1, g.num_edges, 2, P_, 3)
            d = np.linalg.norm(v - g.nodes[g.edges][None, :, :, None, :], axis=-1)
            d = d.max(axis=(0, 3))
            ext = np.zeros(g.num_nodes)
            np.maximum.at(ext, g.edges.ravel(), d.ravel())
            ratio = ext[hub] / zones[hub]
            worst = max(worst, float(ratio.max()))
            assert ratio.max() <= 1.0, (P_, prof, float(ratio.max()))
    assert worst > 0.8  # the zone is not far larger than needed


def test_surface_statistics_are_over_the_area_samples_and_the_max_over_all():
    """surface_deviation returns area samples, then every vertex; the p95, mean and fraction
    describe the surface (area-weighted), so vertices (dense at fillets and polygon corners,
    where the deviation peaks) must not weigh in them; they still count for the max."""
    from reference_boolean.compare import _stats

    rng = np.random.default_rng(0)
    n, nv = 10_000, 40_000
    d = np.concatenate([rng.uniform(0.0, 1.0, n), np.full(nv, 5.0)])  # vertices: all at 5
    area = np.arange(n + nv) < n
    s = _stats(d, n)
    assert s["p95"] == pytest.approx(0.95, abs=0.02) and s["mean"] == pytest.approx(0.5, abs=0.02)
    assert s["max"] == 5.0 and s["samples"] == n
    assert _stats(d)["p95"] == 5.0  # counting the vertices, the p95 would be theirs
    hub = np.zeros(n + nv, dtype=bool)
    hub[: n // 4] = True  # a quarter of the area samples in hub zones, no vertex
    reg = region_stats(hub, d, hub, d, area1=area, area2=area)
    st = reg["struts"]["symmetric"]
    assert st["max"] == 5.0 and st["p95"] < 1.0
    assert st["fraction"] == pytest.approx(0.75) and st["samples"] == n - n // 4
    assert reg["hubs"]["symmetric"]["max"] <= 1.0  # no vertex in the hub zones
    # without masks every point is an area sample (as before)
    assert region_stats(hub, d, hub, d)["struts"]["symmetric"]["p95"] == 5.0
