"""Worst places of the accuracy report (issue 14 item 2): ranked by the whole-surface
deviation (both directions, hub zones and struts alike), and where each worst sample lies.

A small BCC lattice's fast mesh is perturbed at one known place; the report must rank that
place first, and say whether it is at a hub (inside its hub zone) or along a strut.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

import fast_stitch
from conformal.cells import block
from lattice_cad.core.mesh import Mesh
from reference_boolean import build_reference, compare
from reference_boolean.pictures import HIGHLIGHT, worst_places
from reference_boolean.report import first_screen, first_screen_pictures, to_text

R = 0.08


@pytest.fixture(scope="module")
def lattice():
    g = block("bcc", (2, 2, 2), cell_size=1.0, radius=R)
    ref = build_reference(g, keep_solids=False)
    assert ref.complete
    return g, ref, fast_stitch.stitch(g, 6)


def bump(mesh, centre, reach, push):
    """The mesh with every vertex within ``reach`` of ``centre`` pushed away from it by ``push``."""
    v = np.array(mesh.vertices, dtype=np.float64)
    d = v - centre
    dist = np.linalg.norm(d, axis=1)
    near = dist < reach
    assert near.sum() >= 3
    v[near] += push * d[near] / dist[near, None]
    return Mesh(vertices=v, faces=np.asarray(mesh.faces)), near


def test_a_perturbed_hub_is_the_worst_place(lattice):
    g, ref, mesh = lattice
    node = int(np.argmin(np.linalg.norm(g.nodes - np.array([1.0, 1.0, 1.0]), axis=1)))
    assert g.degree[node] == 8
    bumped, _ = bump(mesh, g.nodes[node], 2.5 * R, 2.0 * R)  # its hub's vertices (1.9 r)
    rep = compare(g, mesh=bumped, reference=ref, union_segments=(), samples=4000)
    places, _ = worst_places(rep, 4)
    assert places[0].node == node
    # the bump is the largest deviation anywhere: ~2 r, farther than any design difference
    assert places[0].deviation == pytest.approx(np.nanmax(rep.node_deviation))
    assert places[0].deviation > 1.5 * R
    # the exact ball is left far inside the swollen hub: its worst sample is in the zone
    assert places[0].region == "hub zone" and places[0].side in ("mesh", "exact")
    assert np.linalg.norm(np.subtract(places[0].point, g.nodes[node])) < 4 * R
    # unperturbed, the same node is no worse than the others' design differences at hubs
    plain = compare(g, mesh=mesh, reference=ref, union_segments=(), samples=4000)
    assert plain.node_deviation[node] < 0.7 * places[0].deviation


def test_a_perturbed_strut_is_found_and_said_to_be_along_a_strut(lattice):
    """Not only hubs: a dent in the middle of one strut (outside every hub zone) ranks first,
    at one of that strut's two nodes, and its worst sample is reported along a strut."""
    g, ref, mesh = lattice
    e = int(np.flatnonzero((g.degree[g.edges] == 8).any(axis=1))[0])
    a, b = g.edges[e]
    mid = 0.5 * (g.nodes[a] + g.nodes[b])
    # the fast mesh's strut is a prism between two rings (its 2 P triangles from row 2 P e;
    # the default profile's band rings, the hubs' own rings being a band away): push those
    # rings 4 r away from the axis, a fat strut whose middle is far outside the exact one
    v = np.array(mesh.vertices, dtype=np.float64)
    axis = (g.nodes[b] - g.nodes[a]) / np.linalg.norm(g.nodes[b] - g.nodes[a])
    w = v - mid
    along = w @ axis
    radial = w - along[:, None] * axis
    rho = np.linalg.norm(radial, axis=1)
    ring = np.zeros(len(v), dtype=bool)
    ring[np.asarray(mesh.faces)[12 * e : 12 * (e + 1)].ravel()] = True  # P = 6
    assert ring.sum() == 12 and np.all(rho[ring] < 1.5 * R)
    v[ring] += 4.0 * R * radial[ring] / rho[ring, None]
    bumped = Mesh(vertices=v, faces=np.asarray(mesh.faces))
    rep = compare(g, mesh=bumped, reference=ref, union_segments=(), samples=4000)
    places, _ = worst_places(rep, 4)
    assert places[0].node in (int(a), int(b))
    assert places[0].region == "strut"
    # on the fat strut: between its nodes, far out from the axis (the fat prism is equally
    # far from the exact strut all along; the default profile's bands flare out to it near
    # the hubs, so the single worst sample need not be at the middle)
    q = np.subtract(places[0].point, mid)
    q_along = float(q @ axis)
    assert abs(q_along) <= 0.5 * float(g.edge_lengths[e])
    assert np.linalg.norm(q - q_along * axis) > 3 * R
    assert places[0].deviation > 1.5 * R
    # the report says it on its first screen
    text = to_text(rep)
    assert f"#1 node {places[0].node}" in text and "strut, on the mesh" in text


def test_overview_highlights_the_worst_hubs(lattice):
    g, ref, mesh = lattice
    rep = compare(g, mesh=mesh, reference=ref, union_segments=(), samples=2000)
    screen = first_screen(rep)
    assert screen.places and all(p.region in ("hub zone", "strut") for p in screen.places)
    over = first_screen_pictures(rep)["overview"]
    img = np.asarray(Image.open(io.BytesIO(over)).convert("RGB"), dtype=np.float64) / 255.0
    rgb = np.array([int(HIGHLIGHT[i : i + 2], 16) for i in (1, 3, 5)]) / 255.0
    # the green rings, and the green-tinted hub-zone balls around the worst hubs
    assert int((np.abs(img - rgb).max(axis=-1) < 0.12).sum()) > 50
    greenish = (img[..., 1] > img[..., 0] + 0.08) & (img[..., 1] > img[..., 2] + 0.05)
    assert int(greenish.sum()) > 400


def test_hub_zone_of_nearly_parallel_struts_is_bounded_by_the_struts():
    """Two struts 1e-9 rad apart (a clipped lattice has such) must not give a hub zone of
    ~1e8 r that swallows the whole lattice: it ends with the node's longest strut."""
    from reference_boolean.regions import hub_zones
    from tests.conftest import star_graph

    g = star_graph([[1, 0, 0], [1, 1e-9, 0], [-1, 0, 0]], lengths=[1.0, 0.8, 1.0], radii=R)
    z = hub_zones(g)
    assert 0 < z[0] <= 1.5 * np.hypot(1.0, R) + 1e-12
