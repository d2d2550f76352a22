"""Compiled kernels of the float32 rounding checks (:mod:`lattice_cad.io.rounding`,
:func:`lattice_cad.io.single_precision`).

Each replaces a numpy formulation that sorted rows (``np.unique(axis=0)``) or built a
sparse graph of every corner: on a 700 K-triangle skin those took ~8 CPU s, these take
~0.1 s. All work on the half-edges grouped by their first vertex (a counting sort), so
every question about an edge looks at the few half-edges of one vertex only.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def flat_mask(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(F,) bool: triangles whose cross product is exactly zero (as computed in float64).

    v : (V, 3) float64, f : (F, 3) int64.
    """
    out = np.empty(len(f), dtype=np.bool_)
    for i in range(len(f)):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        ux, uy, uz = v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2]
        wx, wy, wz = v[c, 0] - v[a, 0], v[c, 1] - v[a, 1], v[c, 2] - v[a, 2]
        nx = uy * wz - uz * wy
        ny = uz * wx - ux * wz
        nz = ux * wy - uy * wx
        out[i] = nx == 0.0 and ny == 0.0 and nz == 0.0
    return out


@njit(cache=True, nogil=True)
def _outgoing(f: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Half-edges ``3 * face + k`` (from ``f[face, k]`` to ``f[face, k + 1]``) grouped by
    their first vertex: (nv + 1,) start offsets and (3F,) half-edge ids."""
    nh = 3 * len(f)
    start = np.zeros(nv + 1, dtype=np.int64)
    for h in range(nh):
        start[f[h // 3, h % 3] + 1] += 1
    for i in range(nv):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    ids = np.empty(nh, dtype=np.int64)
    for h in range(nh):
        a = f[h // 3, h % 3]
        ids[fill[a]] = h
        fill[a] += 1
    return start, ids


@njit(cache=True, nogil=True)
def _head(f: np.ndarray, h: int) -> int:
    return f[h // 3, (h % 3 + 1) % 3]


@njit(cache=True, nogil=True)
def closed_oriented(f: np.ndarray, nv: int) -> bool:
    """Every edge used exactly twice, once in each direction (a closed, consistently
    oriented surface). f : (F, 3) int64 with entries in ``0 .. nv - 1``."""
    start, ids = _outgoing(f, nv)
    for a in range(nv):
        for p in range(start[a], start[a + 1]):
            b = _head(f, ids[p])
            same = 0
            for q in range(start[a], start[a + 1]):
                if _head(f, ids[q]) == b:
                    same += 1
            back = 0
            for q in range(start[b], start[b + 1]):
                if _head(f, ids[q]) == a:
                    back += 1
            if same != 1 or back != 1:
                return False
    return True


@njit(cache=True, nogil=True)
def _find(parent: np.ndarray, x: int) -> int:
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:  # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True, nogil=True)
def corner_fans(f: np.ndarray, nv: int) -> np.ndarray:
    """(F, 3) int64: the fan of every corner, numbered 0.. in order of first corner.

    A fan is a connected set of the faces around a vertex, joined across edges that have
    exactly two faces using them in opposite directions (as
    ``lattice_cad.io.rounding._corner_fans`` defined it with a sparse graph).
    """
    nf = len(f)
    start, ids = _outgoing(f, nv)
    parent = np.arange(3 * nf)
    for a in range(nv):
        for p in range(start[a], start[a + 1]):
            h1 = ids[p]
            b = _head(f, h1)
            if b < a:
                continue  # each edge once, from its lower vertex
            n_ab = 0
            for q in range(start[a], start[a + 1]):
                if _head(f, ids[q]) == b:
                    n_ab += 1
            n_ba = 0
            h2 = -1
            for q in range(start[b], start[b + 1]):
                if _head(f, ids[q]) == a:
                    n_ba += 1
                    h2 = ids[q]
            if n_ab != 1 or n_ba != 1:
                continue
            # corner of a in h1 is h1 itself; of b in h1 the next corner; in h2 (b -> a)
            # the corner of b is h2, of a the next one
            fa1, ka1 = h1 // 3, h1 % 3
            fb2, kb2 = h2 // 3, h2 % 3
            ca1 = 3 * fa1 + ka1
            cb1 = 3 * fa1 + (ka1 + 1) % 3
            cb2 = 3 * fb2 + kb2
            ca2 = 3 * fb2 + (kb2 + 1) % 3
            for x, y in ((ca1, ca2), (cb1, cb2)):
                rx, ry = _find(parent, x), _find(parent, y)
                if rx != ry:
                    parent[max(rx, ry)] = min(rx, ry)
    label = np.full(3 * nf, -1, dtype=np.int64)
    out = np.empty(3 * nf, dtype=np.int64)
    n = 0
    for c in range(3 * nf):
        r = _find(parent, c)
        if label[r] < 0:
            label[r] = n
            n += 1
        out[c] = label[r]
    return out.reshape(nf, 3)


@njit(cache=True, nogil=True)
def pinched(f: np.ndarray, nv: int) -> np.ndarray:
    """(K,) int64: vertices whose corners lie in more than one fan (:func:`corner_fans`)."""
    fans = corner_fans(f, nv).ravel()
    start, ids = _outgoing(f, nv)  # the half-edges from a vertex are its corners
    out = np.empty(nv, dtype=np.int64)
    k = 0
    for a in range(nv):
        s, e = start[a], start[a + 1]
        if e - s < 1:
            continue
        first = fans[ids[s]]
        for p in range(s + 1, e):
            if fans[ids[p]] != first:
                out[k] = a
                k += 1
                break
    return out[:k]


@njit(cache=True, nogil=True)
def has_equal_rows(key: np.ndarray, bits: np.ndarray) -> bool:
    """Do two rows of ``key`` (R, 3) float64 compare equal (``==`` in every column)?

    ``bits`` (R, 3) uint64 is ``key`` viewed as integers, with no ``-0.0`` in it (equal
    values then have equal bits; a NaN equals nothing). An open-addressing hash table of
    the rows, in one pass: the question :func:`lattice_cad.core.mesh.weld` answers by
    sorting the rows, without the sort.
    """
    n = key.shape[0]
    size = 64
    while size < 2 * n:
        size *= 2
    mask = np.uint64(size - 1)
    table = np.full(size, -1, dtype=np.int64)
    for i in range(n):
        h = (
            bits[i, 0] * np.uint64(0x9E3779B97F4A7C15)
            ^ bits[i, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
            ^ bits[i, 2] * np.uint64(0x165667B19E3779F9)
        )
        h ^= h >> np.uint64(31)
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(29)
        slot = h & mask
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                break
            if key[j, 0] == key[i, 0] and key[j, 1] == key[i, 1] and key[j, 2] == key[i, 2]:
                return True
            slot = (slot + np.uint64(1)) & mask
    return False


@njit(cache=True, nogil=True)
def corners_by_vertex(corner_v: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Corners grouped by vertex (a counting sort): ``order`` is
    ``np.argsort(corner_v, kind="stable")`` and ``start`` (nv + 1,) the offsets,
    ``np.searchsorted(corner_v[order], np.arange(nv + 1))``.

    corner_v : (C,) int64 in ``[0, nv)``.
    """
    start = np.zeros(nv + 1, dtype=np.int64)
    for c in range(len(corner_v)):
        start[corner_v[c] + 1] += 1
    for x in range(nv):
        start[x + 1] += start[x]
    pos = start[:nv].copy()
    order = np.empty(len(corner_v), dtype=np.int64)
    for c in range(len(corner_v)):
        x = corner_v[c]
        order[pos[x]] = c
        pos[x] += 1
    return order, start
