"""Tests of the unit-cell library and the exact tiling (conformal.cells)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conformal.cells import CELLS, UnitCell, block, cell_counts, tile, tile_arrays
from lattice_cad import InvalidGraphError, LatticeGraph

NAMES = sorted(CELLS)

# name -> (denominator, nodes per cell, edges per cell)
PER_CELL = {
    "cubic": (1, 8, 12),
    "bcc": (2, 9, 8),
    "bccz": (2, 9, 12),
    "fcc": (2, 14, 24),
    "fccz": (2, 14, 28),
    "box-bcc": (2, 9, 20),
    "octet": (2, 14, 36),
    "kelvin": (4, 24, 36),
    "diamond": (4, 14, 16),
    "rhombic-dodecahedron": (4, 22, 32),
    "reentrant": (8, 28, 38),
}

# degrees of the nodes strictly inside a block (the infinite lattice)
INTERIOR_DEGREES = {
    "cubic": {6},
    "bcc": {8},
    "bccz": {8, 10},
    "fcc": {4, 12},
    "fccz": {4, 14},
    "box-bcc": {8, 14},
    "octet": {12},
    "kelvin": {4},
    "diamond": {4},
    "rhombic-dodecahedron": {4, 8},
    "reentrant": {2, 5},
}

# cell_size large enough for the default radius 0.4 on every cell (shortest strut:
# kelvin, sqrt(2)/4 of a cell)
SIZE = 10.0


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)


def _grid(n: int) -> np.ndarray:
    return np.indices((n, n, n)).reshape(3, -1).T


def _reference(cell: UnitCell, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slow merge: plain dicts keyed by integer coordinate tuples."""
    d = cell.denominator
    seen: dict[tuple[int, ...], None] = {}
    pairs = set()
    local = cell.nodes.tolist()
    for c in cells.tolist():
        keys = [tuple(ci * d + li for ci, li in zip(c, loc, strict=True)) for loc in local]
        for k in keys:
            seen[k] = None
        for i, j in cell.edges.tolist():
            pairs.add(frozenset((keys[i], keys[j])))
    order = sorted(seen)
    index = {k: n for n, k in enumerate(order)}
    edges = sorted(tuple(sorted(index[k] for k in p)) for p in pairs)
    return np.array(order, dtype=np.int64).reshape(-1, 3), np.array(edges).reshape(-1, 2)


def _segment_distance(p1, q1, p2, q2):
    """Closest distance between segments p1q1 and p2q2 (rows), Ericson's algorithm."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    b = np.einsum("ij,ij->i", d1, d2)
    c = np.einsum("ij,ij->i", d1, r)
    f = np.einsum("ij,ij->i", d2, r)
    denom = a * e - b * b
    s = np.where(
        denom > 1e-12, np.clip((b * f - c * e) / np.where(denom > 1e-12, denom, 1), 0, 1), 0
    )
    t = (b * s + f) / e
    s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
    t = np.clip(t, 0, 1)
    diff = (p1 + d1 * s[:, None]) - (p2 + d2 * t[:, None])
    return np.sqrt(np.einsum("ij,ij->i", diff, diff))


def _point_segment_distance(p, q, x):
    """Distance from points x to segments pq (rows)."""
    d = q - p
    t = np.clip(np.einsum("ij,ij->i", x - p, d) / np.einsum("ij,ij->i", d, d), 0, 1)
    diff = p + d * t[:, None] - x
    return np.sqrt(np.einsum("ij,ij->i", diff, diff))


# ------------------------------------------------------------- the library
def test_library_contents():
    assert set(CELLS) == set(PER_CELL)
    for name, cell in CELLS.items():
        d, k, e = PER_CELL[name]
        assert cell.name == name
        assert (cell.denominator, cell.num_nodes, cell.num_edges) == (d, k, e), name
        assert cell.description and "\n" not in cell.description
        assert cell.nodes.dtype == np.int64 and cell.edges.dtype == np.int64
        assert cell.nodes.min() >= 0 and cell.nodes.max() <= d
        assert cell.is_periodic(), name
        assert cell_counts(cell, 1) == (k, e)


@pytest.mark.parametrize("name", NAMES)
def test_counts_match_formula(name):
    cell = CELLS[name]
    for n in range(1, 5):
        g = block(cell, (n, n, n), cell_size=SIZE)
        assert (g.num_nodes, g.num_edges) == cell_counts(cell, n), (name, n)
        assert cell_counts(name, n) == cell_counts(cell, n)


@pytest.mark.parametrize("name", NAMES)
def test_block_structure(name):
    cell = CELLS[name]
    g = block(cell, 3, cell_size=SIZE)
    _, edges, ijk = tile_arrays(cell, _grid(3), cell_size=SIZE)
    assert np.array_equal(g.edges, edges)
    # no duplicate edges (as unordered pairs), every edge has positive length
    key = np.sort(g.edges, axis=1)
    assert len(np.unique(key, axis=0)) == g.num_edges
    assert (g.edge_lengths > 0).all()
    assert (g.degree >= 1).all()
    top = 3 * cell.denominator
    interior = ((ijk > 0) & (ijk < top)).all(axis=1)
    assert interior.any()
    assert set(g.degree[interior].tolist()) == INTERIOR_DEGREES[name]


@pytest.mark.parametrize("name", NAMES)
def test_tiling_is_sorted(name):
    nodes, edges, ijk = tile_arrays(CELLS[name], _grid(2)[::-1])
    diff = np.diff(ijk, axis=0)
    first = diff[np.arange(len(diff)), np.argmax(diff != 0, axis=1)]
    assert (first > 0).all()  # strictly increasing lexicographically
    assert (edges[:, 0] < edges[:, 1]).all()
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    assert np.array_equal(order, np.arange(len(edges)))
    assert np.array_equal(nodes, ijk / CELLS[name].denominator)


@pytest.mark.parametrize("name", NAMES)
def test_no_crossing_struts(name):
    """In a 2x2x2 block struts meet only at shared end nodes."""
    _, edges, ijk = tile_arrays(CELLS[name], _grid(2))
    pts = ijk.astype(np.float64)
    m = len(edges)
    # no node strictly inside an edge
    ei, ni = np.meshgrid(np.arange(m), np.arange(len(pts)), indexing="ij")
    ei, ni = ei.ravel(), ni.ravel()
    keep = (edges[ei, 0] != ni) & (edges[ei, 1] != ni)
    ei, ni = ei[keep], ni[keep]
    dist = _point_segment_distance(pts[edges[ei, 0]], pts[edges[ei, 1]], pts[ni])
    assert dist.min() > 1e-6
    # non-adjacent edges do not touch
    i, j = np.triu_indices(m, k=1)
    shared = (edges[i][:, :, None] == edges[j][:, None, :]).any(axis=(1, 2))
    i, j = i[~shared], j[~shared]
    dist = _segment_distance(pts[edges[i, 0]], pts[edges[i, 1]], pts[edges[j, 0]], pts[edges[j, 1]])
    assert dist.min() > 1e-6


@pytest.mark.parametrize("name", NAMES)
def test_random_subset_matches_reference(name, rng):
    cell = CELLS[name]
    cells = _grid(5)[rng.random(125) < 0.35] + np.array([-2, -1, 3])
    cells = rng.permutation(np.vstack([cells, cells[:3]]))  # shuffled, with repeats
    ref_ijk, ref_edges = _reference(cell, cells)
    nodes, edges, ijk = tile_arrays(cell, cells, cell_size=SIZE)
    assert np.array_equal(ijk, ref_ijk)
    assert np.array_equal(edges, ref_edges)
    g = tile(cell, cells, cell_size=SIZE)
    assert np.array_equal(g.nodes, nodes) and np.array_equal(g.edges, edges)
    # the order of the cells does not matter
    again = tile(cell, cells[::-1], cell_size=SIZE)
    assert again == g


# ----------------------------------------------------------- placement
def test_non_cubic_cell_size():
    h = np.array([1.0, 2.5, 4.0])
    g = block("bcc", (2, 3, 1), cell_size=h, radius=0.1)
    _, _, ijk = tile_arrays("bcc", np.indices((2, 3, 1)).reshape(3, -1).T)
    assert np.allclose(g.nodes, ijk / 2 * h, rtol=0, atol=1e-12)
    assert np.array_equal(g.bounds, [[0, 0, 0], [2.0, 7.5, 4.0]])
    assert [0.5, 1.25, 2.0] in g.nodes.tolist()  # body centre of cell (0, 0, 0)


def test_origin_translation():
    o = np.array([-3.0, 10.0, 0.25])
    g0 = block("octet", (2, 2, 2), cell_size=SIZE)
    g1 = block("octet", (2, 2, 2), cell_size=SIZE, origin=o)
    assert np.array_equal(g0.edges, g1.edges)
    assert np.allclose(g1.nodes, g0.nodes + o, rtol=0, atol=1e-12)
    assert np.array_equal(g1.bounds[0], o)


def test_negative_cell_indices():
    g = tile("cubic", [[-1, -1, -1]], cell_size=2.0)
    assert np.array_equal(g.bounds, [[-2, -2, -2], [0, 0, 0]])


# -------------------------------------------------------------- radii
def test_radius_forms_pass_through():
    cells = _grid(2)
    m = cell_counts("bcc", 2)[1]
    r1 = np.linspace(0.1, 0.3, m)
    assert np.array_equal(tile("bcc", cells, radius=r1).radii, np.stack([r1, r1], axis=1))
    r2 = np.stack([r1, r1[::-1]], axis=1)
    assert np.array_equal(tile("bcc", cells, radius=r2).radii, r2)
    assert (tile("bcc", cells, radius=0.2).radii == 0.2).all()


def test_radius_errors_propagate():
    with pytest.raises(InvalidGraphError, match="radius"):
        block("bcc", 2, radius=0.5)  # half strut length is sqrt(3)/4 = 0.433
    with pytest.raises(InvalidGraphError, match="radii must be > 0"):
        block("bcc", 2, radius=-1.0)
    with pytest.raises(InvalidGraphError, match="radii must be"):
        block("bcc", 2, radius=[0.1, 0.2])
    # the default radius 0.4 needs struts longer than 0.8
    with pytest.raises(InvalidGraphError):
        block("kelvin", 1)


# ------------------------------------------------------- user-defined cells
def test_from_fractions():
    third = 1 / 3
    cell = UnitCell.from_fractions(
        "thirds",
        [[0, 0, 0], [third, third, third], [2 * third, 2 * third, 2 * third], [1, 1, 1]],
        [[0, 1], [1, 2], [2, 3]],
        description="body diagonal in three pieces",
    )
    assert cell.denominator == 3
    assert cell.nodes.tolist() == [[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]]
    g = block(cell, (2, 1, 1), cell_size=3.0, radius=0.1)
    # the corner (1, 1, 1) of cell 0 is not the corner (0, 0, 0) of cell 1: 8 nodes
    assert g.num_nodes == 8 and g.num_edges == 6
    assert np.allclose(g.nodes[1], [1, 1, 1], rtol=0, atol=1e-12)
    half = UnitCell.from_fractions("half", [[0, 0, 0], [0.5, 0.25, 1]], [[0, 1]])
    assert half.denominator == 4 and half.nodes.tolist() == [[0, 0, 0], [2, 1, 4]]
    # one strut in the face x = 0 and none in x = 1: it would not tile seamlessly
    lone = UnitCell.from_fractions("lone", [[0, 0, 0], [0, 1, 0]], [[0, 1]])
    assert not lone.is_periodic()
    with pytest.raises(ValueError, match=r"no closed-form counts"):
        cell_counts(half, 2)


def test_from_fractions_errors():
    with pytest.raises(ValueError, match=r"node 1 coordinate y=0\.123456789123 is not a fraction"):
        UnitCell.from_fractions("bad", [[0, 0, 0], [0.5, 0.123456789123, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match=r"node 0 coordinate z=1\.5 is outside"):
        UnitCell.from_fractions("bad", [[0, 0, 1.5], [0.5, 0.5, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match=r"node 1 has a non-finite"):
        UnitCell.from_fractions("bad", [[0, 0, 0], [np.nan, 0, 0]], [[0, 1]])
    with pytest.raises(ValueError, match=r"shape \(K, 3\)"):
        UnitCell.from_fractions("bad", [[0, 0], [1, 1]], [[0, 1]])
    # a 1/7 grid is fine with the default max_denominator, not with 5
    UnitCell.from_fractions("sevenths", [[0, 0, 0], [1 / 7, 0, 0]], [[0, 1]])
    with pytest.raises(ValueError, match="denominator <= 5"):
        UnitCell.from_fractions("sevenths", [[0, 0, 0], [1 / 7, 0, 0]], [[0, 1]], max_denominator=5)


_SQUARE = [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]


@pytest.mark.parametrize(
    ("nodes", "den", "edges", "match"),
    [
        (
            _SQUARE + [[0, 0, 3]],
            2,
            [[0, 1], [1, 2], [2, 3], [3, 4]],
            r"node 4 .* z=3 outside 0\.\.2",
        ),
        (_SQUARE + [[-1, 0, 0]], 2, [[0, 1], [1, 4]], r"node 4 .* x=-1 outside"),
        (_SQUARE + [[2, 0, 0]], 2, [[0, 1], [2, 3]], r"node 4 duplicates node 1"),
        (_SQUARE, 2, [[0, 1], [1, 7]], r"edge 1 \(1, 7\) references a node outside 0\.\.3"),
        (_SQUARE, 2, [[0, 1], [2, 2]], r"edge 1 is a self-loop on node 2"),
        (_SQUARE, 2, [[0, 1], [1, 2], [1, 0]], r"edge 2 \(1, 0\) duplicates edge 0"),
        (_SQUARE, 2, [[0, 1], [1, 2]], r"node 3 \(0, 2, 0\) has no edge"),
        (_SQUARE + [[1, 0, 0]], 2, [[0, 1], [0, 4], [2, 3]], r"node 4 .* lies inside edge 0"),
        (_SQUARE, 0, [[0, 1], [2, 3]], r"denominator must be an integer >= 1"),
        ([[0, 0, 0.5], [1, 1, 1]], 2, [[0, 1]], r"node 0 has a non-integer value"),
        ([[0, 0], [1, 1]], 2, [[0, 1]], r"shape \(N, 3\)"),
        (_SQUARE, 2, [], r"at least one node and one edge"),
    ],
)
def test_invalid_cells(nodes, den, edges, match):
    with pytest.raises(ValueError, match=match):
        UnitCell("bad", "an invalid cell", np.array(nodes), den, np.array(edges))


def test_unit_cell_is_immutable_and_comparable():
    cell = CELLS["bcc"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        cell.name = "other"  # type: ignore[misc]
    with pytest.raises(ValueError):
        cell.nodes[0, 0] = 1
    copy = UnitCell(cell.name, cell.description, cell.nodes.copy(), 2, cell.edges.tolist())
    assert copy == cell and hash(copy) == hash(cell)
    assert copy != CELLS["cubic"]
    other = UnitCell("bcc", "bcc with one strut", [[0, 0, 0], [1, 1, 1]], 2, [[0, 1]])
    with pytest.raises(ValueError, match="no closed-form counts"):
        cell_counts(other, 2)  # same name as a built-in cell, different content


def test_argument_errors():
    with pytest.raises(ValueError, match="unknown cell 'nope'"):
        tile("nope", [[0, 0, 0]])
    with pytest.raises(TypeError):
        tile(42, [[0, 0, 0]])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"shape \(C, 3\)"):
        tile("bcc", [[0, 0]])
    with pytest.raises(ValueError, match="integer cell indices"):
        tile("bcc", [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="cell_size"):
        tile("bcc", [[0, 0, 0]], cell_size=(1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="origin"):
        tile("bcc", [[0, 0, 0]], origin=(0.0, np.inf, 0.0))
    with pytest.raises(ValueError, match="counts"):
        block("bcc", (2, 0, 2))
    with pytest.raises(ValueError, match="n must be"):
        cell_counts("bcc", 0)
    with pytest.raises(ValueError, match="too large"):
        tile_arrays("bcc", [[2**60, 0, 0]])


def test_empty_tiling():
    g = tile("octet", np.zeros((0, 3), dtype=np.int64))
    assert isinstance(g, LatticeGraph) and g.num_nodes == 0 and g.num_edges == 0


def test_sparse_huge_extent_uses_row_fallback():
    # the bounding box of these cells has more integer points than int64 keys allow
    cells = np.array([[0, 0, 0], [2**30, 2**30, 2**30], [1, 0, 0]])
    ref_ijk, ref_edges = _reference(CELLS["fcc"], cells)
    _, edges, ijk = tile_arrays("fcc", cells)
    assert np.array_equal(ijk, ref_ijk) and np.array_equal(edges, ref_edges)


@pytest.mark.slow
def test_million_cell_bcc_block_counts():
    # its speed is measured by benchmarks/bench_conformal.py, not asserted here
    g = block("bcc", 100, cell_size=1.0, radius=0.1)
    assert (g.num_nodes, g.num_edges) == cell_counts("bcc", 100)
