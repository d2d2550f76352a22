"""The low-memory graph builder (issue 15) gives the same graph as before, bit for bit.

``tests/reference_builder.py`` holds the builder's pieces as they were (plain numpy and
scipy, one pass over everything); each new piece is compared with its old self on seeded
random inputs and on a real part, and ``voxel_lattice`` end to end with the old pipeline.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA
from reference_builder import (
    old_clashes,
    old_cleanup,
    old_components,
    old_tile_int,
    old_validate,
)

import conformal
from conformal import voxel
from conformal.cells import CELLS, _tile_int, tile_arrays
from fast_stitch.fit import _clashes, _incidence, clashes, end_offsets, misfits
from lattice_cad.core import config
from lattice_cad.core.errors import InvalidGraphError
from lattice_cad.core.graph import LatticeGraph, _validate

BUNNY = DATA / "meshes" / "bunny_closed_odedstein.obj"


@pytest.mark.parametrize("name", sorted(CELLS))
def test_tile_by_blocks_equals_one_pass(name, rng):
    cell = CELLS[name]
    for _ in range(3):
        cells = rng.integers(-6, 9, size=(int(rng.integers(1, 300)), 3))
        n0, e0 = old_tile_int(cell, cells)
        for block in (5, 97, 1 << 20):
            n1, e1 = _tile_int(cell, cells, block=block)
            assert n1.dtype == np.int64 and e1.dtype == np.int64
            np.testing.assert_array_equal(n1, n0)
            np.testing.assert_array_equal(e1, e0)


def test_components_number_like_scipy(rng):
    for n, m in ((1, 0), (50, 20), (400, 300), (2000, 2500)):
        edges = rng.integers(0, n, size=(m, 2)) if m else np.zeros((0, 2), dtype=np.int64)
        k0, lab0 = old_components(n, edges)
        k1, lab1 = voxel._components(n, edges)
        assert k1 == k0
        np.testing.assert_array_equal(lab1, lab0)


def _box_part(s: float) -> conformal.Part:
    v = np.array([[x, y, z] for x in (0, s) for y in (0, s) for z in (0, s)], dtype=np.float64)
    f = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
    )  # fmt: skip
    return conformal.Part(v, f)


def test_cleanup_equals_old(rng):
    # sparse random cells: many dangling struts and isolated nodes to prune
    for name in ("bcc", "octet", "kelvin"):
        cells = np.unique(rng.integers(0, 7, size=(120, 3)), axis=0)
        nodes, edges, _ = tile_arrays(name, cells)
        on_surface = rng.random(len(nodes)) < 0.1
        for prune in (True, False):
            r0, r1 = voxel.BuildReport(), voxel.BuildReport()
            a = old_cleanup(nodes, edges, on_surface, 0.0, False, prune, r0)
            b = voxel._cleanup(nodes, edges, on_surface, 0.0, False, prune, r1)
            np.testing.assert_array_equal(b[0], a[0])
            np.testing.assert_array_equal(b[1], a[1])
            assert b[1].dtype == np.int64
            assert r1 == r0


@pytest.mark.parametrize("name", ["bcc", "octet", "kelvin", "fcc"])
def test_clashes_by_slabs_equal_one_pass(name, rng):
    from conformal.cells import block

    g = block(name, (4, 5, 3), cell_size=1.0, radius=0.05)
    nodes = g.nodes + rng.normal(scale=0.12, size=g.nodes.shape)
    r = rng.uniform(0.02, 0.2, size=(g.num_edges, 2))
    r[5] = 1.5  # one box many grid columns wide
    p0, d0, n0 = old_clashes(nodes, g.edges, r)
    assert len(p0) > 100  # the comparison has something to compare
    inc = _incidence(g.edges, len(nodes))
    # the old one-pass check knew only the inscribed profile (vertices on the circle)
    off = end_offsets(nodes, g.edges, r, profile="inscribed", _incidence_arrays=inc)
    for blk in (1, 60, 1 << 20):
        p1, d1, n1 = _clashes(nodes, g.edges, r, off, inc, 0.02, block=blk)
        np.testing.assert_array_equal(p1, p0)
        np.testing.assert_array_equal(d1, d0)
        np.testing.assert_array_equal(n1, n0)
    p1, d1, _ = clashes(nodes, g.edges, r, profile="inscribed")
    np.testing.assert_array_equal(p1, p0)
    np.testing.assert_array_equal(d1, d0)
    bad, need, length = misfits(nodes, g.edges, r, profile="inscribed")
    np.testing.assert_array_equal(
        length, np.linalg.norm(nodes[g.edges[:, 1]] - nodes[g.edges[:, 0]], axis=1)
    )


def _old_pipeline(part, cell, h, radius):
    """voxel_lattice(fill='inside') before issue 15, from the reference pieces."""
    from reference_builder import old_fit_radii

    from conformal.radius import resolve_radii

    vox = voxel.voxelize(part, h)
    ijk = np.argwhere(vox.inside).astype(np.int64)
    c = CELLS[cell]
    node_ijk, edges = old_tile_int(c, ijk)
    nodes = vox.origin + (node_ijk / c.denominator) * np.full(3, h)
    rep = voxel.BuildReport()
    nodes, edges = old_cleanup(nodes, edges, np.zeros(len(nodes), bool), 0.1 * h, False, True, rep)
    r = resolve_radii(radius, nodes, edges)
    new, _ = old_fit_radii(
        nodes, edges, r, min_radius=0.1 * float(r.min()), profile=config.DEFAULT_PROFILE
    )
    return nodes, edges, new


@pytest.mark.parametrize(
    ("what", "cell", "h", "radius"),
    [
        ("box", "bcc", 1.0, 0.2),
        ("box", "octet", 1.0, 0.09),
        ("bunny", "bcc", 0.12, 0.024),  # the bunny OBJ is about 1.5 units wide
        ("bunny", "octet", 0.16, 0.0128),
        ("bunny", "kelvin", 0.2, 0.01),
        ("bunny", "octet", 0.16, 0.04),  # too thick: the fit thins struts (in place)
    ],
)
@pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")
def test_voxel_lattice_equals_old_pipeline(what, cell, h, radius):
    part = _box_part(9.3) if what == "box" else conformal.load_part(BUNNY)
    g = conformal.voxel_lattice(part, cell, h, radius, fill="inside")
    nodes, edges, radii = _old_pipeline(part, cell, h, radius)
    assert g.num_edges > 500
    np.testing.assert_array_equal(g.nodes, nodes)
    np.testing.assert_array_equal(g.edges, edges)
    np.testing.assert_array_equal(g.radii, radii)
    assert g.nodes.dtype == np.float64 and g.edges.dtype == np.int64
    assert not g.edges.flags.writeable


def test_owned_graph_is_validated_and_read_only():
    nodes = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    edges = np.array([[0, 1], [0, 2]])
    g = LatticeGraph._from_owned(nodes, edges, np.full((2, 2), 0.1))
    assert g.nodes is nodes and not nodes.flags.writeable
    with pytest.raises(InvalidGraphError, match="edge 1 .* duplicates edge 0"):
        LatticeGraph._from_owned(nodes.copy(), np.array([[0, 1], [0, 1]]), np.full((2, 2), 0.1))
    with pytest.raises(InvalidGraphError, match="references node 7"):
        LatticeGraph._from_owned(nodes.copy(), np.array([[0, 7]]), np.full((1, 2), 0.1))


def _message(fn, *args):
    try:
        fn(*args)
    except InvalidGraphError as exc:
        return str(exc)
    return None


def test_validation_by_blocks_gives_the_old_messages(rng, monkeypatch):
    import lattice_cad.core.graph as graph_mod

    monkeypatch.setattr(graph_mod, "_BLOCK", 7)  # many blocks on small graphs
    base_nodes, base_edges, _ = tile_arrays("bcc", np.argwhere(np.ones((3, 3, 3), bool)))
    base_r = np.full((len(base_edges), 2), 0.1)
    cases = [(base_nodes, base_edges, base_r)]
    for k in range(40):
        nodes, edges, r = base_nodes.copy(), base_edges.copy(), base_r.copy()
        i = int(rng.integers(0, len(edges)))
        kind = k % 8
        if kind == 0:
            edges[i] = edges[(i + 3) % len(edges)][::-1]  # duplicate, reversed
        elif kind == 1:
            edges[i] = edges[(i + 5) % len(edges)]  # duplicate, same direction
        elif kind == 2:
            r[i, 1] = -0.1
        elif kind == 3:
            r[i] = 10.0  # fat
        elif kind == 4:
            nodes[edges[i, 1]] = nodes[edges[i, 0]]  # zero length, coincident
        elif kind == 5:
            nodes[int(rng.integers(0, len(nodes)))] = np.nan
        elif kind == 6:
            edges = edges[rng.permutation(len(edges))]  # unsorted, valid
        else:
            nodes = nodes[::-1].copy()  # nodes not sorted
            edges = len(nodes) - 1 - edges
            edges[i] = edges[i - 1]
        cases.append((nodes, edges, r))
    for nodes, edges, r in cases:
        assert _message(_validate, nodes, edges, r) == _message(old_validate, nodes, edges, r)
