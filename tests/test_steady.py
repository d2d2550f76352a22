"""Tests of conformal.steady: direct evaluation, region export, integral properties."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

import fast_stitch
from conformal._steady_kernels import connector_local
from conformal.similarity import Similarity
from conformal.steady import SteadyLattice, SteadyLatticeError
from lattice_cad.core.errors import LatticeError
from tests.conftest import assert_valid

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load_example(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


CLUSTER = [((0.0, 0.0, 0.0), 0.1), ((0.5, 0.5, 0.5), 0.08)]
RACKS = [
    (0, 0, 1, 0, 0),
    (0, 0, 0, 1, 0),
    (0, 0, 0, 0, 1),
    (1, 0, 0, 0, 0),
    (1, 0, 1, 1, 1),
    (1, 0, 1, 0, 0),
    (0, 1, 0, 0, -1),
    (1, 1, 0, -1, 2),
]
U = Similarity(scale=1.02, axis=(0, 0, 1), angle=0.06, translation=(1.0, 0.0, 0.0))
V = Similarity(scale=0.98, axis=(1, 0, 0), angle=0.05, translation=(0.0, 1.0, 0.0))

W_CASES = {
    "screw": Similarity(axis=(0.2, 0.1, 1.0), angle=0.3, translation=(0.2, 0.1, 1.0)),
    "swirl": Similarity(scale=1.06, axis=(1.0, 0.0, 1.0), angle=0.2, translation=(0.1, 0.1, 1.0)),
    "swirl-shrink": Similarity(scale=0.93, axis=(0, 1, 1), angle=-0.4, translation=(0, 0, 1.2)),
    "translation": Similarity(translation=(0.1, 0.0, 1.0)),
    "rotation": Similarity(axis=(0, 1, 0), angle=0.1, translation=(0.0, 0.0, 0.0)).compose(
        Similarity(translation=(0.0, 0.0, 1.0))
    ),
    "half-turn screw": Similarity(axis=(0, 0, 1), angle=math.pi, translation=(3.0, 3.0, 1.0)),
    "near-translation": Similarity(
        scale=1 + 1e-10, axis=(0, 1, 1), angle=1e-8, translation=(0.0, 0.1, 1.0)
    ),
    "near-identity-screw": Similarity(axis=(1, 0, 0), angle=1e-7, translation=(0.0, 0.2, 1.0)),
}


def lattice(w, counts=(5, 4, 7), racks=RACKS) -> SteadyLattice:
    return SteadyLattice(CLUSTER, racks, u=U, v=V, w=w, counts=counts)


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / np.abs(b).max())


# ------------------------------------------------------------ elements
def hull_profile(L, r1, r2):
    sb = (r1 - r2) / L
    z1, z2 = r1 * sb, L + r2 * sb

    def rho(z):
        if z <= z1:
            return math.sqrt(max(0.0, r1 * r1 - z * z))
        if z >= z2:
            return math.sqrt(max(0.0, r2 * r2 - (z - L) ** 2))
        p1, p2 = r1 * math.sqrt(1 - sb * sb), r2 * math.sqrt(1 - sb * sb)
        return p1 + (p2 - p1) * (z - z1) / (z2 - z1)

    return rho, (-r1, z1, z2, L + r2)


@pytest.mark.parametrize(("L", "r1", "r2"), [(1.0, 0.1, 0.1), (1.0, 0.3, 0.05), (2.0, 0.2, 0.7)])
def test_connector_matches_numerical_integration(L, r1, r2):
    """Ball + connector + ball is exactly the convex hull of the two balls."""
    rho, brk = hull_profile(L, r1, r2)

    def ball2(z, c, r):
        return max(0.0, r * r - (z - c) ** 2)

    # breakpoints: hull pieces and the ends of the two balls
    pts = [brk[1], r1, L - r2, brk[2]]

    def quad(f):
        return sum(
            integrate.quad(f, a, b, epsabs=1e-16, epsrel=1e-12, limit=200)[0]
            for a, b in zip(pts, pts[1:], strict=False)
        )

    # cross-section area of the connector (hull minus both balls), first and second moments
    def area(z):
        return math.pi * (rho(z) ** 2 - ball2(z, 0, r1) - ball2(z, L, r2))

    v = quad(area)
    m = quad(lambda z: area(z) * z)

    def second(z):
        h = rho(z) ** 2
        b1, b2 = ball2(z, 0, r1), ball2(z, L, r2)
        return math.pi * ((h - b1 - b2) * z * z + 0.5 * (h * h - b1 * b1 - b2 * b2))

    j = quad(second)
    # hull surface area: surface of revolution of a finely sampled profile polyline
    z = np.concatenate([np.linspace(a, b, 40001) for a, b in zip(brk, brk[1:], strict=False)])
    p = np.array([rho(x) for x in z])
    hull_area = float(np.sum(np.pi * (p[1:] + p[:-1]) * np.hypot(np.diff(z), np.diff(p))))
    cv, ca, cm, cj = connector_local(L, r1, r2)
    assert cv == pytest.approx(v, rel=1e-10)
    assert cm == pytest.approx(m, rel=1e-9, abs=1e-12)
    assert cj == pytest.approx(j, rel=1e-10)
    assert ca + 4 * math.pi * (r1 * r1 + r2 * r2) == pytest.approx(hull_area, rel=1e-7)


def test_cylinder_connector_closed_form():
    L, r = 3.0, 0.4
    v, a, m, _ = connector_local(L, r, r)
    assert v + 2 * 4 / 3 * math.pi * r**3 == pytest.approx(
        math.pi * r * r * L + 4 / 3 * math.pi * r**3
    )
    assert a + 2 * 4 * math.pi * r * r == pytest.approx(2 * math.pi * r * L + 4 * math.pi * r * r)
    assert m / v == pytest.approx(L / 2)


# ------------------------------------------------------------ evaluation
def test_clusters_are_direct_powers():
    w = W_CASES["swirl"]
    lat = lattice(w)
    c0 = np.array([c for c, _ in CLUSTER])
    r0 = np.array([r for _, r in CLUSTER])
    for i, j, k in [(0, 0, 0), (4, 3, 6), (2, 0, 5), (1, 3, 0)]:
        p = c0
        for _ in range(i):
            p = U(p)
        for _ in range(j):
            p = V(p)
        for _ in range(k):
            p = w(p)
        centres, radii = lat.cluster(i, j, k)
        np.testing.assert_allclose(centres, p, atol=1e-12)
        np.testing.assert_allclose(radii, r0 * U.scale**i * V.scale**j * w.scale**k, rtol=1e-13)
    centres, radii = lat.balls(((1, 4), (2, 4), (3, 6)))
    assert centres.shape == (3, 2, 3, 2, 3) and radii.shape == (3, 2, 3, 2)
    c, r = lat.cluster(3, 2, 4)
    np.testing.assert_allclose(centres[2, 0, 1], c, atol=1e-12)
    np.testing.assert_allclose(radii[2, 0, 1], r, rtol=1e-13)


def test_cumulative_similarities_interpolate_end_clusters():
    ut = Similarity(scale=1.5, axis=(0, 0, 1), angle=1.0, translation=(6.0, 0.0, 0.0))
    wt = Similarity(scale=0.5, axis=(1, 1, 0), angle=2.5, translation=(0.0, 0.0, 9.0))
    lat = SteadyLattice(CLUSTER, RACKS, u=ut, w=wt, counts=(7, 1, 10), cumulative=True)
    c0 = np.array([c for c, _ in CLUSTER])
    np.testing.assert_allclose(lat.cluster(6, 0, 0)[0], ut(c0), atol=1e-12)
    np.testing.assert_allclose(lat.cluster(0, 0, 9)[0], wt(c0), atol=1e-12)
    np.testing.assert_allclose(lat.cluster(0, 0, 9)[1], 0.5 * lat.radii, rtol=1e-13)
    assert lat.v.is_identity


def test_graph_region_is_a_subgraph():
    lat = lattice(W_CASES["screw"])
    full, idx = lat.graph(return_index=True)
    assert full.num_edges == lat.num_beams == int(lat.rack_beam_counts().sum())
    key = {tuple(r): n for n, r in enumerate(idx.tolist())}
    region = ((1, 4), slice(0, 3), (2, 6))
    sub, sidx = lat.graph(region, return_index=True)
    assert (sidx[:, 0] >= 1).all() and (sidx[:, 0] < 4).all() and (sidx[:, 2] >= 2).all()
    np.testing.assert_array_equal(sub.nodes, full.nodes[[key[tuple(r)] for r in sidx.tolist()]])
    full_edges = {tuple(sorted(e)) for e in full.edges.tolist()}
    mapped = [tuple(sorted((key[tuple(sidx[a])], key[tuple(sidx[b])]))) for a, b in sub.edges]
    assert set(mapped) <= full_edges
    # every full-graph beam with both ends in the region is in the sub-graph
    inside = np.all((idx[:, :3] >= [1, 0, 2]) & (idx[:, :3] < [4, 3, 6]), axis=1)
    expected = sum(1 for a, b in full.edges if inside[a] and inside[b])
    assert sub.num_edges == expected


def test_graph_of_window_of_a_huge_lattice_is_cheap():
    u = Similarity(axis=(0, 0, 1), angle=1e-4, translation=(1.0, 0.0, 0.0))
    lat = SteadyLattice(
        CLUSTER,
        RACKS,
        u=u,
        v=u.power(0.5) @ Similarity(translation=(0, 1, 0)),
        w=W_CASES["screw"],
        counts=(100_000, 100_000, 100_000),
    )
    g = lat.graph(((50_000, 50_002), (7, 9), (99_998, 100_000)))
    assert g.num_nodes == 16
    assert lat.num_beams > 7 * 10**15


# ------------------------------------------------------------ integral properties
@pytest.mark.parametrize("name", list(W_CASES))
def test_closed_form_matches_brute_force(name):
    lat = lattice(W_CASES[name])
    closed = lat.integral_properties()
    brute = lat.integral_properties(method="brute")
    assert brute["method"] == "brute"
    assert closed["method"] == ("closed-split" if name.startswith("near") else "closed")
    for key in ("volume", "area", "spherical_inertia"):
        assert closed[key] == pytest.approx(brute[key], rel=1e-9), key
    extent = np.ptp(lat.graph().nodes, axis=0).max()
    assert np.abs(closed["centroid"] - brute["centroid"]).max() < 1e-9 * extent


def test_identity_w_and_single_slab():
    racks = [r for r in RACKS if r[4] == 0]
    lat = lattice(Similarity(), counts=(4, 3, 5), racks=racks)
    one = lattice(Similarity(), counts=(4, 3, 1), racks=racks).integral_properties()
    c = lat.integral_properties()
    assert c["volume"] == pytest.approx(5 * one["volume"], rel=1e-14)
    assert c["spherical_inertia"] == pytest.approx(5 * one["spherical_inertia"], rel=1e-12)
    np.testing.assert_allclose(c["centroid"], one["centroid"], atol=1e-13)
    b = lat.integral_properties(method="brute")
    assert c["volume"] == pytest.approx(b["volume"], rel=1e-12)


def test_brute_force_matches_independent_element_sum():
    lat = lattice(W_CASES["swirl"])
    g = lat.graph()
    centres, radii = lat.balls()
    centres, radii = centres.reshape(-1, 3), radii.ravel()
    vol = 4 / 3 * math.pi * radii**3
    moment = (vol[:, None] * centres).sum(axis=0)
    total = vol.sum()
    for (a, b), (r1, r2) in zip(g.edges, g.radii, strict=True):
        e = g.nodes[b] - g.nodes[a]
        L = np.linalg.norm(e)
        v, _, m, _ = connector_local(L, r1, r2)
        total += v
        moment += v * g.nodes[a] + m * e / L
    got = lat.integral_properties(method="brute")
    assert got["volume"] == pytest.approx(total, rel=1e-12)
    np.testing.assert_allclose(got["centroid"], moment / total, rtol=1e-11)


def test_similar_lattice_scales_properties():
    m = Similarity(scale=2.0, axis=(1, 2, 3), angle=0.7, translation=(5.0, -1.0, 2.0))
    w = W_CASES["swirl"]
    lat = lattice(w)
    moved = SteadyLattice(
        [(m(np.array(c)), 2.0 * r) for c, r in CLUSTER],
        RACKS,
        u=m @ U @ m.inverse(),
        v=m @ V @ m.inverse(),
        w=m @ w @ m.inverse(),
        counts=lat.counts,
    )
    a, b = lat.integral_properties(), moved.integral_properties()
    assert b["volume"] == pytest.approx(8 * a["volume"], rel=1e-11)
    assert b["area"] == pytest.approx(4 * a["area"], rel=1e-11)
    assert b["spherical_inertia"] == pytest.approx(32 * a["spherical_inertia"], rel=1e-10)
    np.testing.assert_allclose(b["centroid"], m(a["centroid"]), atol=1e-10)


# ------------------------------------------------------------ stitching
def test_example_graphs_stitch_to_valid_meshes():
    tire = load_example("steady_screw_tire").tire()
    assert_valid(fast_stitch.stitch(tire.graph(), segments=6))
    brick = load_example("steady_twisted_brick").twisted_brick()
    assert_valid(fast_stitch.stitch(brick.graph(((0, 3), (0, 3), (5, 9))), segments=6))


# ------------------------------------------------------------ errors
@pytest.mark.parametrize(
    ("cluster", "racks", "match"),
    [
        ([], [], "at least one ball"),
        ([((0, 0, 0), 0.1), ((1, 0), 0.1)], [], "ball 1"),
        ([((0, 0, 0), 0.1), ((1, 0, 0), -0.1)], [], "ball 1: radius"),
        ([((0, 0, 0), 0.1), ((0, 0, float("nan")), 0.1)], [], "ball 1: centre"),
        ([((0, 0, 0), 0.6), ((1, 0, 0), 0.5)], [], "balls 0 and 1"),
        (CLUSTER, [(0, 0, 1, 0, 0), (0, 2, 0, 0, 0)], "rack 1: end ball 2"),
        (CLUSTER, [(0, 0, 1, 0)], "rack 0: expected 5 integers"),
        (CLUSTER, [(0, 0, 1.0, 0, 0)], "rack 0: expected 5 integers"),
        (CLUSTER, [(1, 1, 0, 0, 0)], "rack 0: joins ball 1 to itself"),
        (CLUSTER, [(0, 1, 1, 0, 0), (0, 0, 0, 1, 0), (1, 0, -1, 0, 0)], "rack 2 .* rack 0"),
    ],
)
def test_input_errors_name_the_element(cluster, racks, match):
    with pytest.raises(SteadyLatticeError, match=match) as info:
        SteadyLattice(cluster, racks, counts=(2, 2, 2))
    assert isinstance(info.value, LatticeError) and isinstance(info.value, ValueError)


def test_other_errors():
    with pytest.raises(SteadyLatticeError, match="counts"):
        SteadyLattice(CLUSTER, RACKS, counts=(2, 0, 2))
    with pytest.raises(LatticeError, match="u must be a Similarity"):
        SteadyLattice(CLUSTER, RACKS, u="x", counts=(2, 2, 2))  # type: ignore[arg-type]
    lat = lattice(W_CASES["screw"])
    with pytest.raises(SteadyLatticeError, match="region k"):
        lat.graph(((0, 2), (0, 2), (5, 9)))
    with pytest.raises(SteadyLatticeError, match="method"):
        lat.integral_properties(method="fast")  # type: ignore[arg-type]
    # a rack whose beams join overlapping balls: named with its index and cluster
    tight = SteadyLattice(
        CLUSTER,
        [(0, 0, 1, 0, 0), (0, 0, 0, 0, 1)],
        u=U,
        w=Similarity(translation=(0, 0, 0.15)),
        counts=(3, 1, 3),
    )
    with pytest.raises(
        SteadyLatticeError, match=r"rack 1 \(0, 0, 0, 0, 1\): .* cluster \(0, 0, 0\)"
    ):
        tight.integral_properties()
