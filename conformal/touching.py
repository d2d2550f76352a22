"""Bodies of a mesh part that touch along an edge or a face: the edges they share split.

An assembly saved as one STL or OBJ often has bodies that touch: along an edge (the edge
is then shared by four triangles), or face to face. A wall where two bodies' faces are
the same triangles, once each way, is removed by the loader (``conformal.seams``: the
bodies are united there); where the two faces are meshed differently, their outer edges
are shared by more than two triangles. Such a mesh is not a 2-manifold surface, which
every inside test, distance and boolean needs. :func:`split_touching` sorts the triangles
about each such edge by their angle about it: a triangle whose body lies at larger
angles (it runs the edge one way) and the next one (the other way) bound one body's
wedge; each body then gets its own copy of the edge's vertices (and of every vertex it
shares with another body only at a point). The loader unites the bodies afterwards, as
it unites any others.

Numpy and scipy only (the core's floor).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.arrays import edge_uses

__all__ = ["Touching", "split_touching"]


@dataclass(frozen=True)
class Touching:
    """What :func:`split_touching` changed."""

    #: edges shared by more than two triangles, split between the bodies meeting there
    edges: int
    #: a point where bodies touch (3,) float64 (NaN if none)
    at: NDArray[np.float64]

    def summary(self) -> str:
        x, y, z = self.at
        return (
            f"{self.edges} edge(s) shared by more than two triangles (bodies that touch "
            "along an edge or a face) were split, each body keeping its own copy, e.g. at "
            f"({x:.4g}, {y:.4g}, {z:.4g})"
        )


def _alternating(theta: NDArray[np.float64], runs: NDArray[np.int64]) -> NDArray[np.int64]:
    """The order of the triangles about an edge by angle ``theta``; triangles in one plane
    (two bodies' faces against each other, meshed differently: the same angle) in the
    order that alternates ``runs`` (the two bodies' wedges on either side of that plane)."""
    s = np.argsort(theta, kind="stable")
    out: list[int] = []
    i = 0
    tie = 1e-9
    while i < len(s):
        j = i + 1
        while j < len(s) and theta[s[j]] - theta[s[i]] <= tie:
            j += 1
        group = s[i:j].tolist()
        if len(group) > 1:
            last = runs[out[-1]] if out else runs[s[-1]]
            group.sort(key=lambda t: runs[t] == last)  # a different run first
        out.extend(group)
        i = j
    return np.asarray(out, dtype=np.int64)


def split_touching(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64], Touching] | None:
    """Split the edges where bodies touch (see the module): returns the vertices, the faces
    and what was changed, or None when the mesh has no edge shared by more than two
    triangles, or when what it has is not bodies touching (a split would not give a closed
    2-manifold mesh: a body touching itself, faces inside a solid, open edges).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Welded (one vertex per position), without degenerate triangles or triangles
        stored twice.

    Returns
    -------
    vertices : (V', 3) float64
        With a copy of a vertex for each body that uses it.
    faces : (F, 3) int64
        The same triangles, on the copies.
    report : Touching
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if not len(f):
        return None
    _, edge_of, cnt = edge_uses(f)
    if not (cnt > 2).any():
        return None
    if (cnt == 1).any():
        return None  # open as well: not (only) bodies touching
    n_f = len(f)
    at = None
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    tri = np.tile(np.arange(n_f), 3)
    third = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    # triangles across each edge used twice: joined
    order = np.argsort(edge_of, kind="stable")
    e_sorted = edge_of[order]
    starts = np.concatenate([[0], np.flatnonzero(np.diff(e_sorted)) + 1])
    sizes = np.diff(np.concatenate([starts, [len(order)]]))
    rows: list[NDArray[np.int64]] = []
    cols: list[NDArray[np.int64]] = []
    two = starts[sizes == 2]
    rows.append(tri[order[two]])
    cols.append(tri[order[two + 1]])
    many = np.flatnonzero(sizes > 2)
    for k in many.tolist():
        idx = order[starts[k] : starts[k] + sizes[k]]
        a, b = he[idx[0]]
        u, w = min(a, b), max(a, b)
        axis = v[w] - v[u]
        axis /= np.linalg.norm(axis)
        rel = v[third[idx]] - v[u]
        rel -= np.outer(rel @ axis, axis)
        ref = rel[0] / np.linalg.norm(rel[0])
        theta = np.arctan2(np.cross(ref, rel) @ axis, rel @ ref)
        # +1: the triangle runs u -> w (its body at smaller angles), -1: w -> u (larger)
        runs = np.where(he[idx, 0] == u, 1, -1)
        s = _alternating(theta, runs)
        runs_s, idx_s = runs[s], idx[s]
        if np.any(runs_s == np.roll(runs_s, -1)):
            return None  # not alternating: not bodies meeting at the edge
        if runs_s[0] == 1:  # start at a triangle whose body lies at larger angles
            runs_s, idx_s = np.roll(runs_s, -1), np.roll(idx_s, -1)
        rows.append(tri[idx_s[0::2]])
        cols.append(tri[idx_s[1::2]])
        if at is None:
            at = 0.5 * (v[u] + v[w])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r)), (r, c)), shape=(n_f, n_f))
    _, body = connected_components(graph, directed=False)
    # a copy of each vertex for each body that uses it
    key = body[:, None].astype(np.int64) * len(v) + f
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    out_v = v[uniq % len(v)]
    out_f = inv.reshape(-1, 3).astype(np.int64)
    cnt2 = edge_uses(out_f)[2]
    if not np.all(cnt2 == 2):
        return None  # a body touching itself along an edge: not split here
    report = Touching(
        edges=int((cnt > 2).sum()),
        at=np.asarray(at if at is not None else np.full(3, np.nan), dtype=np.float64),
    )
    return out_v, out_f, report
