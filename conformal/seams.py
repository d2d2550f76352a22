"""Seams of mesh files that do not match: triangles stored twice, T-junctions, slivers.

Three ways an exporter (or a hand repair) leaves a closed surface that is not closed as a
triangle mesh, each found on files made outside shared/data:

- **every triangle stored twice** (an STL written from two copies of one body): each edge
  has four triangles, so the mesh is "non-manifold" everywhere. Copies with the same
  vertices and turn are one triangle; a triangle and its reverse are a wall of no
  thickness between two bodies that touch there, and both go (the bodies are united).
- **T-junctions**: a vertex of one side lies on an edge of the other (a face meshed finer
  than its neighbour): the edge is open on both sides, though no gap is there.
  :func:`split_t_junctions` splits the triangle of the long edge at those vertices.
- **zero-area slivers**: a T-junction "patched" with a triangle whose three vertices lie
  on one line. The mesh is closed, but the sliver lies on its neighbours' edges, so the
  surface "crosses itself" there and every cut to it may fail. It is removed, which
  leaves the T-junction, split as above.

Each change keeps every triangle in its plane: the surface is the same set of points.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.arrays import unique_rows

__all__ = ["drop_duplicate_faces", "split_t_junctions", "drop_slivers"]

#: At most this many passes of :func:`split_t_junctions` (a triangle with several open
#: edges is split at one edge per pass).
MAX_PASSES = 8


def drop_duplicate_faces(f: NDArray[np.int64]) -> tuple[NDArray[np.int64], int, int]:
    """``f`` (F, 3) int64 without repeated triangles: the kept faces (in their order),
    how many copies of a triangle with the same turn were dropped, and how many pairs of
    a triangle and its reverse were dropped (both)."""
    f = np.asarray(f, dtype=np.int64)
    # the same triangle turned the same way: the rotation starting at its smallest index
    r = np.argmin(f, axis=1)
    idx = np.arange(len(f))
    rot = np.stack([f[idx, r], f[idx, (r + 1) % 3], f[idx, (r + 2) % 3]], axis=1)
    _, first, inverse = np.unique(rot, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    keep = np.zeros(len(f), dtype=bool)
    keep[first] = True
    same = int(len(f) - len(first))
    # a triangle and its reverse: the same sorted vertices, both turns present
    g = f[keep]
    _, inv, counts = unique_rows(np.sort(g, axis=1), return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    pair = counts[inv] == 2
    kept = np.flatnonzero(keep)
    keep[kept[pair]] = False
    return f[keep], same, int(pair.sum()) // 2


def drop_slivers(
    v: NDArray[np.float64], f: NDArray[np.int64], tol: float
) -> tuple[NDArray[np.int64], int]:
    """``f`` without its slivers: triangles one of whose vertices lies within ``tol`` of the
    opposite edge, strictly between its ends (three vertices on one line), and how many
    were dropped. Their removal leaves T-junctions (:func:`split_t_junctions`)."""
    f = np.asarray(f, dtype=np.int64)
    t = v[f]  # (F, 3, 3)
    sliver = np.zeros(len(f), dtype=bool)
    for k in range(3):
        m, a, b = t[:, k], t[:, (k + 1) % 3], t[:, (k + 2) % 3]
        ab = b - a
        ll = np.einsum("ij,ij->i", ab, ab)
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.einsum("ij,ij->i", m - a, ab) / ll
        foot = a + s[:, None] * ab
        d = np.linalg.norm(m - foot, axis=1)
        sliver |= (ll > 0) & (s > 0) & (s < 1) & (d <= tol)
    return f[~sliver], int(sliver.sum())


def split_t_junctions(
    v: NDArray[np.float64], f: NDArray[np.int64], tol: float
) -> tuple[NDArray[np.int64], int]:
    """``f`` with every open edge that has end points of other open edges on it (within
    ``tol``, strictly between its ends) split there: its triangle becomes a fan from its
    opposite vertex. Returns the faces and how many triangles were split.

    v : (V, 3) float64; f : (F, 3) int64.
    """
    from scipy.spatial import cKDTree

    f = np.asarray(f, dtype=np.int64)
    split = 0
    for _ in range(MAX_PASSES):
        he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        face = np.tile(np.arange(len(f)), 3)
        corner = np.repeat(np.arange(3), len(f))
        nv = np.int64(len(v))
        key = he[:, 0] * nv + he[:, 1]
        twin = he[:, 1] * nv + he[:, 0]
        open_he = ~np.isin(twin, key)
        if not open_he.any():
            break
        ends = np.unique(he[open_he].ravel())
        tree = cKDTree(v[ends])
        rows = np.flatnonzero(open_he)
        a, b = v[he[rows, 0]], v[he[rows, 1]]
        mid, half = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=1)
        near = tree.query_ball_point(mid, half + tol)
        cuts: dict[int, tuple[int, list[tuple[float, int]]]] = {}
        for j, cand in enumerate(near):
            if not cand:
                continue
            i0, i1 = he[rows[j], 0], he[rows[j], 1]
            ab = b[j] - a[j]
            ll = float(ab @ ab)
            on: list[tuple[float, int]] = []
            for m in ends[cand]:
                if m == i0 or m == i1:
                    continue
                s = float((v[m] - a[j]) @ ab) / ll
                if 0.0 < s < 1.0 and np.linalg.norm(v[m] - (a[j] + s * ab)) <= tol:
                    on.append((s, int(m)))
            fi = int(face[rows[j]])
            if on and fi not in cuts:  # one edge of a triangle per pass
                cuts[fi] = (int(corner[rows[j]]), sorted(on))
        if not cuts:
            break
        new: list[list[int]] = []
        drop = np.zeros(len(f), dtype=bool)
        for fi, (k, on) in cuts.items():
            i0, i1, c = f[fi, k], f[fi, (k + 1) % 3], f[fi, (k + 2) % 3]
            chain = [int(i0)] + [m for _, m in on] + [int(i1)]
            new += [[chain[q], chain[q + 1], int(c)] for q in range(len(chain) - 1)]
            drop[fi] = True
        split += len(cuts)
        f = np.vstack([f[~drop], np.asarray(new, dtype=np.int64)])
    return f, split
