"""Numba kernels of :mod:`fast_stitch.fit` that work on blocks of elements.

The clearance check of :func:`fast_stitch.fit.clashes` is the same as that of
``_kernels.clearance_elements`` + ``element_grid`` + ``fit._clash_pairs``, but the
element boxes are computed for a list of element ids at a time (one x-slab of the
grid), so that the check needs memory for one slab, not for all elements. The capsules,
balls and boxes are those of ``_kernels.clearance_elements`` (the same inlined helpers),
so that the boxes, cells and distances are bit-identical.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fast_stitch._kernels import (
    _cell_span,
    _element_box,
    _grid_sweep,
    _joint_ball,
    _pair_d2,
    _strut_capsule,
)


@njit(cache=True)
def incidence(edges, n):
    """CSR node -> (strut, side) incidence by counting sort (the order of a stable
    argsort of ``edges.ravel()``).

    Returns
    -------
    offsets : (n + 1,) int64
    inc_edge : (2M,) int32
    inc_side : (2M,) int8
    """
    m = edges.shape[0]
    offsets = np.zeros(n + 1, dtype=np.int64)
    for e in range(m):
        offsets[edges[e, 0] + 1] += 1
        offsets[edges[e, 1] + 1] += 1
    for i in range(n):
        offsets[i + 1] += offsets[i]
    fill = offsets[:-1].copy()
    inc_edge = np.empty(2 * m, dtype=np.int32)
    inc_side = np.empty(2 * m, dtype=np.int8)
    for e in range(m):
        for s in range(2):
            v = edges[e, s]
            inc_edge[fill[v]] = e
            inc_side[fill[v]] = s
            fill[v] += 1
    return offsets, inc_edge, inc_side


@njit(cache=True, parallel=True, error_model="numpy")
def element_boxes(
    ids, nodes, edges, radii, scale, end_offset, offsets, inc_edge, inc_side, pad,
    seg_a, seg_b, rad, lo, hi, extent,
):  # fmt: skip
    """``_kernels.clearance_elements`` for the elements ``ids`` only (row k: element
    ``ids[k]``; struts ``0..M-1``, joints ``M + n``), with the profile radii
    ``radii * scale`` (computed here: no scaled copy of ``radii``). The unit strut direction is
    computed here as numpy does it for ``fit.clashes``: ``v / norm(v)``, the squares
    summed x, y, z in that order."""
    m = edges.shape[0]
    for k in prange(ids.shape[0]):
        i = ids[k]
        if i < m:
            a = edges[i, 0]
            b = edges[i, 1]
            vx = nodes[b, 0] - nodes[a, 0]
            vy = nodes[b, 1] - nodes[a, 1]
            vz = nodes[b, 2] - nodes[a, 2]
            length = np.sqrt(vx * vx + vy * vy + vz * vz)
            if not length > 0:
                length = 1.0
            _strut_capsule(
                nodes, edges, radii, scale, end_offset, i, vx / length, vy / length, vz / length, k,
                seg_a, seg_b, rad,
            )  # fmt: skip
        else:
            _joint_ball(nodes, radii, scale, end_offset, offsets, inc_edge, inc_side, i - m, k,
                        seg_a, seg_b, rad)  # fmt: skip
        extent[k] = _element_box(seg_a, seg_b, rad, pad, k, lo, hi)


@njit(cache=True, parallel=True)
def x_spans(lo, hi, rad, origin, cell, dims, first, last):
    """First and last grid cell along x of every box (-1, -2 for inactive elements)."""
    for k in prange(lo.shape[0]):
        if rad[k] < 0.0:
            first[k] = -1
            last[k] = -2
        else:
            f, t = _cell_span(lo, hi, k, origin, cell, dims, 0)
            first[k] = f
            last[k] = t


@njit(cache=True, error_model="numpy")
def slab_grid(lo, hi, rad, cell, origin, dims, x0, x1):
    """``_kernels.element_grid`` restricted to the grid cells with ``x0 <= x <= x1``
    (local cell ``((x - x0) * ny + y) * nz + z``; members int32)."""
    n_cells = (x1 - x0 + 1) * dims[1] * dims[2]
    count = np.zeros(n_cells + 1, dtype=np.int64)
    members = np.empty(0, dtype=np.int32)
    _grid_sweep(lo, hi, rad, cell, origin, dims, x0, x1, count, members, count, False)
    for c in range(n_cells):
        count[c + 1] += count[c]
    members = np.empty(count[n_cells], dtype=np.int32)
    _grid_sweep(lo, hi, rad, cell, origin, dims, x0, x1, count, members, count[:-1].copy(), True)
    return count, members


@njit(cache=True, parallel=True, error_model="numpy")
def slab_pairs(
    gid, seg_a, seg_b, rad, lo, hi, cell, origin, dims, x0, count, members, edges, offsets,
    inc_edge, scale, n_found, start, out_pairs, out_dist, write,
):  # fmt: skip
    """``fit._clash_pairs`` on one slab: local elements (global ids ``gid``, ascending),
    local cells of :func:`slab_grid`; pairs are written with their global ids."""
    m = edges.shape[0]
    ny, nz = dims[1], dims[2]
    base = x0 * ny * nz
    for lc in prange(count.shape[0] - 1):
        c = base + lc  # the global cell, for the home test
        k = 0
        for u in range(count[lc], count[lc + 1]):
            i = members[u]
            for w in range(u + 1, count[lc + 1]):
                j = members[w]
                d2 = _pair_d2(
                    i, j, gid[i], gid[j], c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m,
                    edges, offsets, inc_edge, scale,
                )  # fmt: skip
                if d2 < 0.0:
                    continue
                if write:
                    out_pairs[start[lc] + k, 0] = gid[min(i, j)]
                    out_pairs[start[lc] + k, 1] = gid[max(i, j)]
                    out_dist[start[lc] + k] = np.sqrt(d2)
                k += 1
        if not write:
            n_found[lc] = k


@njit(cache=True)
def bucket(first, nx):
    """Elements by the first x cell of their box (counting sort; ``first < 0``: left out).

    Returns ``start`` (nx + 1,) int64 and ``order`` (K,) int32: the elements whose box
    starts in column x are ``order[start[x]:start[x + 1]]``, ascending.
    """
    start = np.zeros(nx + 1, dtype=np.int64)
    for i in range(first.shape[0]):
        if first[i] >= 0:
            start[first[i] + 1] += 1
    for x in range(nx):
        start[x + 1] += start[x]
    order = np.empty(start[nx], dtype=np.int32)
    fill = start[:-1].copy()
    for i in range(first.shape[0]):
        f = first[i]
        if f >= 0:
            order[fill[f]] = i
            fill[f] += 1
    return start, order
