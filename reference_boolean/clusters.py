"""Which hubs of a lattice overlap, and the clusters built as one solid (numpy only).

The exact reference stacks one solid per node (a *hub*: a sphere fused with the
half-struts up to the strut midpoints) without any boolean between hubs. That is exact
only where hubs meet on their midpoint discs alone. Short struts (clipped and conforming
fills, tet meshes) put a hub's sphere or stumps across a neighbour's midpoint plane; such
hubs are grouped into *clusters* (connected components of the relation "these two hubs
may overlap") and each cluster is built as one fused solid
(:func:`lattice_cad.occ_impl.cluster.build_cluster`), whose struts to nodes outside the
cluster still end at their midpoint discs. Clusters then meet each other, and single hubs,
only on midpoint discs again, so the stacked result stays exact and watertight.

What a hub is at a leaf
-----------------------
A node of degree 1 (a *leaf*: a free strut end, or where a clipped/conforming strut ends
at the part's surface) has **no sphere**: its hub is the half-strut alone, with a flat
disc at the node. This is the same design as the fast mesh (:func:`fast_stitch.stitch`
caps a leaf with a flat polygon at the node) and as the printable mesh, which is cut flat
by the part's surface there anyway. Every node of degree >= 2 has a sphere of radius
``config.SPHERE_FACTOR * max incident radius``.

The relation (:func:`overlap_pairs`)
------------------------------------
* A ball that reaches the midpoint plane of one of its struts (``R_a >= L_e / 2``) makes
  the strut's two nodes a pair.
* Otherwise each stump is enclosed in the capsule of its axis segment (node to midpoint)
  with its larger radius, each ball is its own enclosure; two hubs with intersecting
  enclosures make a pair (conservative: a cluster may be larger than needed, never too
  small). Not compared: the two stumps of one strut (they meet on its midpoint disc by
  design) and a ball with the other node's stump of the same strut (the exact test
  above). A stump that would cut another strut's midpoint disc of its own hub touches the
  neighbour's stump behind that disc, so the two nodes are one cluster and the disc is
  never needed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph

__all__ = ["hub_radius", "overlap_pairs", "find_clusters"]


def hub_radius(graph: LatticeGraph) -> NDArray[np.float64]:
    """(N,) float64: hub sphere radius ``R_n`` of the reference; 0 at leaves and isolated nodes."""
    rmax = np.zeros(graph.num_nodes)
    np.maximum.at(rmax, graph.edges[:, 0], graph.radii[:, 0])
    np.maximum.at(rmax, graph.edges[:, 1], graph.radii[:, 1])
    return np.where(graph.degree >= 2, config.SPHERE_FACTOR * rmax, 0.0)


def _adjacent_pairs(
    graph: LatticeGraph, R: NDArray[np.float64]
) -> tuple[list[NDArray[np.int64]], list[str]]:
    """Pairs of strut-joined nodes where a ball reaches past the strut's midpoint plane."""
    L = np.asarray(graph.edge_lengths)
    edges = graph.edges
    pairs: list[NDArray[np.int64]] = []
    why: list[str] = []
    for side in (0, 1):
        n = edges[:, side]
        bad = np.flatnonzero(R[n] >= 0.5 * L)
        if len(bad):
            pairs.append(edges[bad])
            for e in bad[:20]:
                why.append(
                    f"node {int(n[e])}: sphere radius {R[n[e]]:.6g} reaches past the midpoint "
                    f"of strut {int(e)} (half length {0.5 * L[e]:.6g})"
                )
    return pairs, why


def _segment_distance(
    p0: NDArray[np.float64],
    p1: NDArray[np.float64],
    q0: NDArray[np.float64],
    q1: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(K,) float64: distance between segments ``p0 p1`` and ``q0 q1`` (each (K, 3)).

    Ericson's closest points of two segments (Real-Time Collision Detection, 5.1.9),
    vectorised; a segment may have zero length (a sphere's centre).
    """
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    eps = 1e-30
    pa, pe = a > eps, e > eps
    sa, se = np.where(pa, a, 1.0), np.where(pe, e, 1.0)
    denom = a * e - b * b
    gen = pa & pe & (denom > 1e-14 * sa * se)
    s = np.where(gen, np.clip((b * f - c * e) / np.where(gen, denom, 1.0), 0.0, 1.0), 0.0)
    s = np.where(pa & ~pe, np.clip(-c / sa, 0.0, 1.0), s)
    t = np.where(pe, (b * s + f) / se, 0.0)
    lo, hi = pe & (t < 0.0), pe & (t > 1.0)
    t = np.clip(t, 0.0, 1.0)
    s = np.where(lo & pa, np.clip(-c / sa, 0.0, 1.0), s)
    s = np.where(hi & pa, np.clip((b - c) / sa, 0.0, 1.0), s)
    cp = p0 + s[:, None] * d1
    cq = q0 + t[:, None] * d2
    return np.linalg.norm(cp - cq, axis=1)


def _capsule_pairs(
    graph: LatticeGraph, R: NDArray[np.float64]
) -> tuple[NDArray[np.int64], list[str]]:
    """Pairs of nodes whose hubs' enclosing capsules intersect (beyond a shared disc)."""
    from scipy.spatial import cKDTree

    nodes, edges = graph.nodes, graph.edges
    m = graph.num_edges
    mid = 0.5 * (nodes[edges[:, 0]] + nodes[edges[:, 1]])
    rmid = graph.radii.mean(axis=1)
    # primitives: stump (e, side) = capsule node..mid, radius max(r_node, r_mid); spheres
    p0 = np.concatenate([nodes[edges[:, 0]], nodes[edges[:, 1]]])
    p1 = np.concatenate([mid, mid])
    rad = np.concatenate([np.maximum(graph.radii[:, 0], rmid), np.maximum(graph.radii[:, 1], rmid)])
    owner = np.concatenate([edges[:, 0], edges[:, 1]])
    sph = np.flatnonzero(R > 0)
    p0 = np.concatenate([p0, nodes[sph]])
    p1 = np.concatenate([p1, nodes[sph]])
    rad = np.concatenate([rad, R[sph]])
    owner = np.concatenate([owner, sph])
    centre = 0.5 * (p0 + p1)
    bound = 0.5 * np.linalg.norm(p1 - p0, axis=1) + rad
    if len(centre) < 2:
        return np.zeros((0, 2), np.int64), []
    tree = cKDTree(centre)
    cand = tree.query_pairs(r=2.0 * float(bound.max()), output_type="ndarray")
    if len(cand) == 0:
        return np.zeros((0, 2), np.int64), []
    i, j = cand[:, 0], cand[:, 1]
    keep = owner[i] != owner[j]
    keep &= np.linalg.norm(centre[i] - centre[j], axis=1) < bound[i] + bound[j]
    i, j = i[keep], j[keep]
    # the two stumps of one strut meet on its disc, by design
    stump_i, stump_j = i < 2 * m, j < 2 * m
    keep = ~(stump_i & stump_j & (i % m == j % m))
    # a ball and the other end's stump of a strut at its node: the exact test R >= L / 2
    for sph_, stp in ((i, j), (j, i)):
        is_pair = (sph_ >= 2 * m) & (stp < 2 * m)
        e = stp % m
        keep &= ~(is_pair & ((edges[e, 0] == owner[sph_]) | (edges[e, 1] == owner[sph_])))
    i, j = i[keep], j[keep]
    if len(i) == 0:
        return np.zeros((0, 2), np.int64), []
    dist = _segment_distance(p0[i], p1[i], p0[j], p1[j])
    hit = dist <= (rad[i] + rad[j]) * (1.0 + 1e-9)
    i, j = i[hit], j[hit]

    def name(k: int) -> str:
        return (
            f"sphere of node {int(owner[k])}"
            if k >= 2 * m
            else (f"stump of strut {int(k % m)} at node {int(owner[k])}")
        )

    n = np.int64(graph.num_nodes)
    ekey = set(
        (np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])).tolist()
    )

    def joined(a: int, b: int) -> str:
        k = min(owner[a], owner[b]) * n + max(owner[a], owner[b])
        return "joined by a strut" if int(k) in ekey else "no strut between them"

    why = [
        f"nodes {int(owner[a])} and {int(owner[b])} ({joined(a, b)}): the {name(a)} "
        f"and the {name(b)} may touch"
        for a, b in zip(i[:20], j[:20], strict=True)
    ]
    return np.column_stack([owner[i], owner[j]]).astype(np.int64), why


def overlap_pairs(graph: LatticeGraph) -> tuple[NDArray[np.int64], list[str]]:
    """Pairs of nodes whose hubs may overlap (more than on a shared midpoint disc).

    Returns
    -------
    pairs : (K, 2) int64
        Node pairs (unordered, possibly repeated).
    reasons : list of str
        Up to about 60 human-readable places (node, strut, what reaches where).
    """
    R = hub_radius(graph)
    adj, why = _adjacent_pairs(graph, R)
    far, why_far = _capsule_pairs(graph, R)
    pairs = np.concatenate([*adj, far]) if adj else far
    return pairs.reshape(-1, 2).astype(np.int64), why + why_far


def find_clusters(graph: LatticeGraph) -> tuple[NDArray[np.int64], list[str]]:
    """Group the nodes into clusters: connected components of :func:`overlap_pairs`.

    Returns
    -------
    label : (N,) int64
        Cluster id of each node with struts (``0..C-1``; a node whose hub overlaps no other
        is a cluster of its own), -1 for isolated nodes.
    reasons : list of str
        Why nodes were grouped (see :func:`overlap_pairs`).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = graph.num_nodes
    pairs, why = overlap_pairs(graph)
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(adj, directed=False)
    used = graph.degree > 0
    label = np.full(n, -1, dtype=np.int64)
    _, label[used] = np.unique(comp[used], return_inverse=True)
    return label, why
