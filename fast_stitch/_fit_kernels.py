"""Numba kernels of :mod:`fast_stitch.fit` that work on blocks of elements.

The clearance check of :func:`fast_stitch.fit.clashes` is the same as that of
``_kernels.clearance_elements`` + ``element_grid`` + ``fit._clash_pairs``, but the
element boxes are computed for a list of element ids at a time (one x-slab of the
grid), so that the check needs memory for one slab, not for all elements. The formulas
are copied from ``_kernels.clearance_elements`` operation for operation, so that the
boxes, cells and distances are bit-identical.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fast_stitch._kernels import _cell_span, _excluded, _seg_seg_dist2


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
    ids, nodes, edges, radii, end_offset, offsets, inc_edge, inc_side, pad,
    seg_a, seg_b, rad, lo, hi, extent,
):  # fmt: skip
    """``_kernels.clearance_elements`` for the elements ``ids`` only (row k: element
    ``ids[k]``; struts ``0..M-1``, joints ``M + n``). The unit strut direction is
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
            u0 = vx / length
            u1 = vy / length
            u2 = vz / length
            for c in range(3):
                uc = u0 if c == 0 else (u1 if c == 1 else u2)
                seg_a[k, c] = nodes[a, c] + end_offset[i, 0] * uc
                seg_b[k, c] = nodes[b, c] - end_offset[i, 1] * uc
            rad[k] = max(radii[i, 0], radii[i, 1])
        else:
            n = i - m
            for c in range(3):
                seg_a[k, c] = nodes[n, c]
                seg_b[k, c] = nodes[n, c]
            r = -1.0
            if offsets[n + 1] - offsets[n] >= 2:
                for t in range(offsets[n], offsets[n + 1]):
                    e = inc_edge[t]
                    s = inc_side[t]
                    r = max(r, np.sqrt(end_offset[e, s] ** 2 + radii[e, s] ** 2))
            rad[k] = r
        w = 0.0
        for c in range(3):
            lo_c = min(seg_a[k, c], seg_b[k, c]) - pad * rad[k]
            hi_c = max(seg_a[k, c], seg_b[k, c]) + pad * rad[k]
            lo[k, c] = lo_c
            hi[k, c] = hi_c
            w = max(w, hi_c - lo_c)
        extent[k] = w


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
    (local cell ``((x - x0) * ny + y) * nz + z``)."""
    ny, nz = dims[1], dims[2]
    n_cells = (x1 - x0 + 1) * ny * nz
    count = np.zeros(n_cells + 1, dtype=np.int64)
    members = np.empty(0, dtype=np.int32)
    fill = count[:-1]
    for sweep in range(2):  # sweep 0 counts, sweep 1 fills
        for i in range(lo.shape[0]):
            if rad[i] < 0.0:
                continue
            xa, xb = _cell_span(lo, hi, i, origin, cell, dims, 0)
            xa = max(xa, x0)
            xb = min(xb, x1)
            y0, y1 = _cell_span(lo, hi, i, origin, cell, dims, 1)
            z0, z1 = _cell_span(lo, hi, i, origin, cell, dims, 2)
            for x in range(xa, xb + 1):
                for y in range(y0, y1 + 1):
                    for z in range(z0, z1 + 1):
                        c = ((x - x0) * ny + y) * nz + z
                        if sweep == 0:
                            count[c + 1] += 1
                        else:
                            members[fill[c]] = i
                            fill[c] += 1
        if sweep == 0:
            for c in range(n_cells):
                count[c + 1] += count[c]
            members = np.empty(count[n_cells], dtype=np.int32)
            fill = count[:-1].copy()
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
                d2 = _local_d2(
                    i, j, c, gid, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges,
                    offsets, inc_edge, scale,
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


@njit(cache=True, inline="always", error_model="numpy")
def _local_d2(
    i, j, c, gid, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets, inc_edge,
    scale,
):  # fmt: skip
    """``_kernels._candidate_d2`` on local rows ``i``, ``j`` (global ids ``gid``)."""
    for a in range(3):
        if lo[i, a] > hi[j, a] or lo[j, a] > hi[i, a]:
            return -1.0
    ny, nz = dims[1], dims[2]
    for a in range(3):
        home = (c // (ny * nz)) if a == 0 else ((c // nz) % ny if a == 1 else c % nz)
        o = min(dims[a] - 1, max(0, int((max(lo[i, a], lo[j, a]) - origin[a]) / cell)))
        if o != home:
            return -1.0
    a = min(i, j)
    b = max(i, j)
    if _excluded(gid[a], gid[b], m, edges, offsets, inc_edge):
        return -1.0
    reach = scale * (rad[a] + rad[b])
    d2 = _seg_seg_dist2(seg_a, seg_b, a, b)
    if d2 >= reach * reach:
        return -1.0
    return d2


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
