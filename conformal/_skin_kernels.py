"""Numba kernels of ``conformal.skin``: marching tetrahedra and the exact Euclidean
distance transform.

``marching_tets_keys`` does the per-voxel work of :func:`conformal.skin.marching_tets`
(a Freudenthal split of every voxel into 6 tetrahedra) in one compiled pass over the
grid, with the same triangles in the same order and orientation as the vectorised
numpy version it replaces; the vertices (one per crossed grid segment) are numbered
afterwards in numpy from the segment keys.

``edt_squared`` is the separable exact squared Euclidean distance transform of
Felzenszwalb & Huttenlocher (lower envelope of parabolas, one pass per axis).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# Freudenthal tets (corner bit codes x=1, y=2, z=4), their 6 edges, the 3 edges at each
# corner, and for each inside mask with 2 corners in, the cycle of its 4 crossing edges
_TETS = np.array(
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]],
    dtype=np.int64,
)
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)
_EDGE_OF = np.array([[0, 1, 2], [0, 3, 4], [1, 3, 5], [2, 4, 5]], dtype=np.int64)


def _quad_cycles() -> np.ndarray:
    pair_edge = {(0, 1): 0, (0, 2): 1, (0, 3): 2, (1, 2): 3, (1, 3): 4, (2, 3): 5}
    e_idx = np.zeros((16, 4), dtype=np.int64)
    for mask in range(16):
        inn = [i for i in range(4) if (mask >> i) & 1]
        out = [i for i in range(4) if not (mask >> i) & 1]
        if len(inn) != 2:
            continue
        p, q = inn
        r, s = out

        def e(i: int, j: int) -> int:
            return pair_edge[(min(i, j), max(i, j))]

        e_idx[mask] = [e(p, r), e(p, s), e(q, s), e(q, r)]
    return e_idx


_QUAD = _quad_cycles()


@njit(cache=True, inline="always")
def _tet_work(f, i, j, k, t, tets, lin, ins, ijk):
    """Corner linear indices, inside flags and grid indices of tet ``t`` of cube (i, j, k);
    returns the number of corners inside."""
    ny, nz = f.shape[1], f.shape[2]
    n_in = 0
    for c in range(4):
        b = tets[t, c]
        a0 = i + (b & 1)
        a1 = j + ((b >> 1) & 1)
        a2 = k + ((b >> 2) & 1)
        ijk[c, 0] = a0
        ijk[c, 1] = a1
        ijk[c, 2] = a2
        lin[c] = (a0 * ny + a1) * nz + a2
        ins[c] = f[a0, a1, a2] > 0.0
        if ins[c]:
            n_in += 1
    return n_in


@njit(cache=True)
def _cube_crossed(f, i, j, k):
    n = 0
    for b in range(8):
        if f[i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)] > 0.0:
            n += 1
    return 0 < n < 8


@njit(cache=True, parallel=True)
def _count(f, tets):
    nx, ny, nz = f.shape
    counts = np.zeros(nx - 1, dtype=np.int64)
    for i in prange(nx - 1):
        lin = np.empty(4, dtype=np.int64)
        ins = np.empty(4, dtype=np.bool_)
        ijk = np.empty((4, 3), dtype=np.int64)
        n = 0
        for j in range(ny - 1):
            for k in range(nz - 1):
                if not _cube_crossed(f, i, j, k):
                    continue
                for t in range(6):
                    n_in = _tet_work(f, i, j, k, t, tets, lin, ins, ijk)
                    if n_in == 2:
                        n += 2
                    elif n_in == 1 or n_in == 3:
                        n += 1
        counts[i] = n
    return counts


@njit(cache=True, parallel=True)
def _fill(f, origin, h, tets, tet_edges, edge_of, quad, offsets, keys, cat):
    nx, ny, nz = f.shape
    ntot = nx * ny * nz
    for i in prange(nx - 1):
        lin = np.empty(4, dtype=np.int64)
        ins = np.empty(4, dtype=np.bool_)
        ijk = np.empty((4, 3), dtype=np.int64)
        ek = np.empty(6, dtype=np.int64)
        mid = np.empty((6, 3), dtype=np.float64)
        cyc = np.empty(4, dtype=np.int64)
        inside_pt = np.empty(3, dtype=np.float64)
        out = offsets[i]
        for j in range(ny - 1):
            for k in range(nz - 1):
                if not _cube_crossed(f, i, j, k):
                    continue
                for t in range(6):
                    n_in = _tet_work(f, i, j, k, t, tets, lin, ins, ijk)
                    if n_in == 0 or n_in == 4:
                        continue
                    for e in range(6):
                        a, b = tet_edges[e, 0], tet_edges[e, 1]
                        la, lb = lin[a], lin[b]
                        ek[e] = min(la, lb) * ntot + max(la, lb)
                        for d in range(3):
                            pa = origin[d] + ijk[a, d] * h
                            pb = origin[d] + ijk[b, d] * h
                            mid[e, d] = 0.5 * (pa + pb)
                    # centroid of the inside corners
                    for d in range(3):
                        s = 0.0
                        for c in range(4):
                            if ins[c]:
                                s += origin[d] + ijk[c, d] * h
                        inside_pt[d] = s / n_in
                    if n_in == 2:
                        mask = 0
                        for c in range(4):
                            if ins[c]:
                                mask |= 1 << c
                        for c in range(4):
                            cyc[c] = quad[mask, c]
                        _emit(keys, cat, out, ek, mid, inside_pt, cyc[0], cyc[1], cyc[2], 1)
                        _emit(keys, cat, out + 1, ek, mid, inside_pt, cyc[0], cyc[2], cyc[3], 2)
                        out += 2
                    else:
                        want = n_in == 1
                        lone = 0
                        for c in range(4):
                            if ins[c] == want:
                                lone = c
                                break
                        e0, e1, e2 = edge_of[lone, 0], edge_of[lone, 1], edge_of[lone, 2]
                        _emit(keys, cat, out, ek, mid, inside_pt, e0, e1, e2, 0)
                        out += 1


@njit(cache=True, inline="always")
def _emit(keys, cat, row, ek, mid, inside_pt, e0, e1, e2, kind):
    """Write the triangle of tet edges (e0, e1, e2), oriented from inside to outside (decided
    on the mid-edge triangle, as :func:`conformal.skin.marching_tets` does)."""
    ux = mid[e1, 0] - mid[e0, 0]
    uy = mid[e1, 1] - mid[e0, 1]
    uz = mid[e1, 2] - mid[e0, 2]
    vx = mid[e2, 0] - mid[e0, 0]
    vy = mid[e2, 1] - mid[e0, 1]
    vz = mid[e2, 2] - mid[e0, 2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    cx = (mid[e0, 0] + mid[e1, 0] + mid[e2, 0]) / 3.0
    cy = (mid[e0, 1] + mid[e1, 1] + mid[e2, 1]) / 3.0
    cz = (mid[e0, 2] + mid[e1, 2] + mid[e2, 2]) / 3.0
    dot = nx * (cx - inside_pt[0]) + ny * (cy - inside_pt[1]) + nz * (cz - inside_pt[2])
    if dot < 0.0:
        keys[row, 0] = ek[e2]
        keys[row, 1] = ek[e1]
        keys[row, 2] = ek[e0]
    else:
        keys[row, 0] = ek[e0]
        keys[row, 1] = ek[e1]
        keys[row, 2] = ek[e2]
    cat[row] = kind


def marching_tets_keys(
    f: np.ndarray, origin: np.ndarray, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of the surface ``f = 0`` as keys of grid segments.

    Parameters
    ----------
    f : (nx, ny, nz) float64
        The field, no sample exactly 0.
    origin : (3,) float64
    h : float

    Returns
    -------
    keys : (T, 3) int64
        Each triangle's vertices as ``lo * f.size + hi`` (linear indices of the ends of the
        grid segment the vertex lies on), oriented outwards.
    cat : (T,) int8
        0: a tet with 1 or 3 corners inside, 1 and 2: the halves of a quad.
    """
    f = np.ascontiguousarray(f, dtype=np.float64)
    origin = np.ascontiguousarray(origin, dtype=np.float64)
    counts = _count(f, _TETS)
    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    n = int(offsets[-1])
    keys = np.empty((n, 3), dtype=np.int64)
    cat = np.empty(n, dtype=np.int8)
    if n:
        _fill(f, origin, float(h), _TETS, _TET_EDGES, _EDGE_OF, _QUAD, offsets, keys, cat)
    return keys, cat


# ------------------------------------------------------ distance transform
@njit(cache=True, inline="always")
def _edt_line(g, n, w2, out, v, z, inf):
    """1D squared distance transform of ``g[:n]`` (``w2``: the spacing squared), the lower
    envelope of the parabolas ``w2 (q - p)^2 + g[p]``."""
    first = -1
    for q in range(n):
        if g[q] < inf:
            first = q
            break
    if first < 0:
        for q in range(n):
            out[q] = inf
        return
    k = 0
    v[0] = first
    z[0] = -inf
    z[1] = inf
    for q in range(first + 1, n):
        if g[q] >= inf:
            continue
        fq = g[q] + w2 * q * q
        p = v[k]
        s = (fq - (g[p] + w2 * p * p)) / (2.0 * w2 * (q - p))
        while s <= z[k]:
            k -= 1
            p = v[k]
            s = (fq - (g[p] + w2 * p * p)) / (2.0 * w2 * (q - p))
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = inf
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        p = v[k]
        d = q - p
        out[q] = w2 * d * d + g[p]


@njit(cache=True, parallel=True)
def edt_squared(inside, h):
    """Squared Euclidean distance (spacing ``h`` on every axis) of every True voxel of
    ``inside`` (nx, ny, nz) bool to the nearest False voxel (0 at False voxels); the same
    as ``scipy.ndimage.distance_transform_edt(inside, sampling=h) ** 2`` when ``inside``
    has a False voxel (+inf everywhere otherwise)."""
    nx, ny, nz = inside.shape
    inf = np.inf
    w2 = h * h
    d = np.empty((nx, ny, nz), dtype=np.float64)
    m = max(nx, max(ny, nz))
    # along z
    for i in prange(nx):
        g = np.empty(m)
        o = np.empty(m)
        v = np.empty(m, dtype=np.int64)
        z = np.empty(m + 1)
        for j in range(ny):
            for k in range(nz):
                g[k] = inf if inside[i, j, k] else 0.0
            _edt_line(g, nz, w2, o, v, z, inf)
            for k in range(nz):
                d[i, j, k] = o[k]
    # along y
    for i in prange(nx):
        g = np.empty(m)
        o = np.empty(m)
        v = np.empty(m, dtype=np.int64)
        z = np.empty(m + 1)
        for k in range(nz):
            for j in range(ny):
                g[j] = d[i, j, k]
            _edt_line(g, ny, w2, o, v, z, inf)
            for j in range(ny):
                d[i, j, k] = o[j]
    # along x
    for j in prange(ny):
        g = np.empty(m)
        o = np.empty(m)
        v = np.empty(m, dtype=np.int64)
        z = np.empty(m + 1)
        for k in range(nz):
            for i in range(nx):
                g[i] = d[i, j, k]
            _edt_line(g, nx, w2, o, v, z, inf)
            for i in range(nx):
                d[i, j, k] = o[i]
    return d


# ------------------------------------------------------ marching tets helpers
@njit(cache=True, parallel=True)
def max_step_x(f):
    """Largest ``|f[i + 1, j, k] - f[i, j, k]|`` of a (nx, ny, nz) float64 field (0 for
    ``nx < 2``): the field's change per voxel, as ``np.abs(np.diff(f, axis=0)).max()``
    without its two temporary copies of the field."""
    nx, ny, nz = f.shape
    best = np.zeros(max(nx - 1, 1))
    for i in prange(nx - 1):
        b = 0.0
        for j in range(ny):
            for k in range(nz):
                d = abs(f[i + 1, j, k] - f[i, j, k])
                if d > b:
                    b = d
        best[i] = b
    return best.max()


@njit(cache=True)
def unique_inverse(a):
    """``np.unique(a, return_inverse=True)`` of (n,) non-negative int64 keys, by hashing
    (open addressing) and sorting only the distinct keys: ~5x faster than numpy's sort of
    all ``n`` keys when each key repeats several times (marching tets: ~6x)."""
    n = len(a)
    bits = 1
    while (1 << bits) < 2 * max(n, 1):
        bits += 1
    size = 1 << bits
    mask = np.uint64(size - 1)
    shift = np.uint64(64 - bits)
    golden = np.uint64(0x9E3779B97F4A7C15)
    table = np.full(size, -1, dtype=np.int64)  # slot -> provisional id
    first = np.empty(n, dtype=np.int64)  # provisional id -> key
    ids = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        key = a[i]
        s = (np.uint64(key) * golden) >> shift
        while True:
            slot = table[s]
            if slot < 0:
                table[s] = m
                first[m] = key
                ids[i] = m
                m += 1
                break
            if first[slot] == key:
                ids[i] = slot
                break
            s = (s + np.uint64(1)) & mask
    keys = first[:m].copy()
    order = np.argsort(keys)
    rank = np.empty(m, dtype=np.int64)
    for r in range(m):
        rank[order[r]] = r
    inv = np.empty(n, dtype=np.int64)
    for i in range(n):
        inv[i] = rank[ids[i]]
    return keys[order], inv


@njit(cache=True)
def any_flat_triangle(v, f):
    """Whether a triangle ``f`` (F, 3) of vertices ``v`` (V, 3) float64 has a zero normal
    (``cross(b - a, c - a)``, each component exactly as ``np.cross`` computes it: a
    product minus a product, no fused multiply-add), without the (F, 3, 3) temporaries."""
    for i in range(f.shape[0]):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        ux, uy, uz = v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2]
        wx, wy, wz = v[c, 0] - v[a, 0], v[c, 1] - v[a, 1], v[c, 2] - v[a, 2]
        if uy * wz - uz * wy == 0.0 and uz * wx - ux * wz == 0.0 and ux * wy - uy * wx == 0.0:
            return True
    return False
