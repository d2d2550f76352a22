"""LatticeGraph: construction, validation messages, immutability and I/O."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lattice_cad import InvalidGraphError, LatticeError, LatticeGraph, LatticeWarning

TRI = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_radius_forms_are_normalised_per_end():
    e = [[0, 1], [0, 2]]
    assert LatticeGraph(TRI, e, 0.1).radii.tolist() == [[0.1, 0.1], [0.1, 0.1]]
    assert LatticeGraph(TRI, e, [0.1, 0.2]).radii.tolist() == [[0.1, 0.1], [0.2, 0.2]]
    g = LatticeGraph(TRI, e, [[0.1, 0.05], [0.2, 0.2]])
    assert g.radii.tolist() == [[0.1, 0.05], [0.2, 0.2]]
    assert g.is_tapered and not LatticeGraph(TRI, e, 0.1).is_tapered


def test_arrays_are_read_only_copies():
    nodes = TRI.copy()
    g = LatticeGraph(nodes, [[0, 1], [1, 2]], 0.1)
    nodes[0, 0] = 5.0  # the caller's array is not shared
    assert g.nodes[0, 0] == 0.0
    for a in (g.nodes, g.edges, g.radii, g.edge_lengths, g.degree):
        with pytest.raises(ValueError):
            a[0] = 1


def test_derived_quantities():
    g = LatticeGraph(TRI, [[0, 1], [0, 2]], 0.1)
    assert g.num_nodes == 3 and g.num_edges == 2 and len(g) == 2
    assert g.degree.tolist() == [2, 1, 1]
    np.testing.assert_allclose(g.edge_lengths, [1.0, 1.0])
    offsets, edge_ids, sides = g.incidence
    assert offsets.tolist() == [0, 2, 3, 4]
    assert edge_ids.tolist() == [0, 1, 0, 1] and sides.tolist() == [0, 0, 1, 1]
    assert g.bounds.tolist() == [[0, 0, 0], [1, 1, 0]]


def test_error_hierarchy():
    assert issubclass(InvalidGraphError, LatticeError)
    assert issubclass(InvalidGraphError, ValueError)


@pytest.mark.parametrize(
    ("nodes", "edges", "radii", "message"),
    [
        ([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], [[0, 1]], 0.1, "node 1 has a non-finite"),
        ([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]], [[0, 2]], 0.1, "node 1 has a non-finite"),
        (TRI, [[0, 1], [0, 2]], [0.1, np.nan], "edge 1 has a non-finite radius"),
        (TRI, [[0, 1], [0, 2]], [0.1, 0.0], "edge 1 has radius 0 at node 0"),
        (TRI, [[0, 1], [0, 2]], [[0.1, 0.1], [0.1, -0.2]], "edge 1 has radius -0.2 at node 2"),
        (TRI, [[0, 1], [0, 3]], 0.1, "edge 1 references node 3"),
        (TRI, [[0, 1], [-1, 2]], 0.1, "edge 1 references node -1"),
        (TRI, [[0, 1], [2, 2]], 0.1, "edge 1 is a self-loop on node 2"),
        (TRI, [[0, 1], [0, 2], [1, 0]], 0.1, "edge 2 (1, 0) duplicates edge 0 (0, 1)"),
        (TRI, [[0, 1], [0, 2], [0, 1]], 0.1, "edge 2 (0, 1) duplicates edge 0 (0, 1)"),
        ([[0, 0, 0], [0, 0, 0], [1, 0, 0]], [[0, 2], [0, 1]], 0.1, "edge 1 (0, 1) has zero length"),
        (TRI, [[0, 1], [0, 2]], [0.1, 0.5], "edge 1 (0, 2): radius 0.5 is not strictly below"),
        (TRI, [[0, 1], [1, 2]], [0.1, 0.8], "edge 1 (1, 2): radius 0.8"),
        (
            [[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0]],
            [[0, 1], [2, 3]],
            0.1,
            "nodes 1 and 2 coincide",
        ),
        (TRI, [[0.5, 1]], 0.1, "edge 0 has a non-integer node index"),
        (TRI, [[0, 1, 2]], 0.1, "edges must have shape (M, 2)"),
        ([[0, 0], [1, 1]], [[0, 1]], 0.1, "nodes must have shape (N, 3)"),
        (TRI, [[0, 1], [0, 2]], [0.1, 0.1, 0.1], "radii must be a number, shape (2,) or (2, 2)"),
    ],
)
def test_bad_input_names_the_element(nodes, edges, radii, message):
    with pytest.raises(InvalidGraphError) as err:
        LatticeGraph(nodes, edges, radii)
    assert message in str(err.value)


def test_isolated_nodes_warn_and_are_kept():
    nodes = np.vstack([TRI, [[5, 5, 5]]])
    with pytest.warns(LatticeWarning, match=r"1 isolated node\(s\).*node 3"):
        g = LatticeGraph(nodes, [[0, 1], [0, 2]], 0.1)
    assert g.isolated_nodes.tolist() == [3]


def test_empty_graph_is_allowed():
    g = LatticeGraph(np.zeros((0, 3)), np.zeros((0, 2), dtype=int), 0.1)
    assert g.num_nodes == 0 and g.num_edges == 0 and g.radii.shape == (0, 2)


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_save_load_round_trip_is_exact(tmp_path, rng, suffix):
    nodes = rng.uniform(-10, 10, size=(20, 3))
    edges = np.column_stack([np.arange(19), np.arange(1, 20)])
    radii = rng.uniform(0.001, 0.01, size=(19, 2))
    g = LatticeGraph(nodes, edges, radii)
    path = g.save(tmp_path / f"g{suffix}")
    assert LatticeGraph.load(path) == g
    assert [p.name for p in tmp_path.iterdir()] == [f"g{suffix}"]  # no temp file left


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.json"):
        LatticeGraph.load(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(InvalidGraphError, match="bad.json"):
        LatticeGraph.load(bad)
    broken = tmp_path / "broken.json"
    broken.write_text(
        json.dumps({"format": "lattice-cad-graph", "version": 1, "nodes": [[0, 0, 0], [1, 0, 0]],
                    "edges": [[0, 5]], "radii": [[0.1, 0.1]]})
    )  # fmt: skip
    with pytest.raises(InvalidGraphError, match=r"broken.json: edge 0 references node 5"):
        LatticeGraph.load(broken)
    with pytest.raises(ValueError, match=".txt"):
        LatticeGraph(TRI, [[0, 1], [1, 2]], 0.1).save(tmp_path / "g.txt")


def test_saved_files_honour_the_umask(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        path = LatticeGraph(TRI, [[0, 1], [1, 2]], 0.1).save(tmp_path / "g.npz")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644
