"""Numba kernels of ``conformal``: winding numbers, triangle grids, distances, clipping.

Inside/outside is decided by the *winding number* of a closed triangle mesh,
counted along a vertical ray (+z): every triangle whose xy-projection contains
the query point and that lies above it adds the sign of its projected area.
The containment test uses simulation of simplicity (the query point is
perturbed by ``(e, e^2)``) with each edge evaluated in a canonical vertex
order, so a ray through a shared edge or vertex is counted exactly once: the
result is exact for watertight meshes up to floating-point rounding of the
orientation predicates (points within ~1e-15 relative of an edge).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# ------------------------------------------------------------- predicates


@njit(cache=True, inline="always")
def _edge_sign(ax, ay, bx, by, px, py):
    """Sign of the orientation of (a, b, p + (e, e^2)); 0 only for a == b."""
    flip = 1.0
    if ax > bx or (ax == bx and ay > by):
        ax, ay, bx, by = bx, by, ax, ay
        flip = -1.0
    w = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    if w == 0.0:
        w = -(by - ay)
        if w == 0.0:
            w = bx - ax
    if w > 0.0:
        return flip
    if w < 0.0:
        return -flip
    return 0.0


@njit(cache=True, inline="always")
def _tri_cover(tri, t, px, py):
    """+1 / -1 (sign of projected area) if the xy-projection of t covers p, else 0."""
    s0 = _edge_sign(tri[t, 0, 0], tri[t, 0, 1], tri[t, 1, 0], tri[t, 1, 1], px, py)
    s1 = _edge_sign(tri[t, 1, 0], tri[t, 1, 1], tri[t, 2, 0], tri[t, 2, 1], px, py)
    if s0 != s1 or s0 == 0.0:
        return 0
    s2 = _edge_sign(tri[t, 2, 0], tri[t, 2, 1], tri[t, 0, 0], tri[t, 0, 1], px, py)
    if s2 != s0:
        return 0
    return 1 if s0 > 0.0 else -1


@njit(cache=True, inline="always")
def _tri_z(tri, t, px, py):
    ux = tri[t, 1, 0] - tri[t, 0, 0]
    uy = tri[t, 1, 1] - tri[t, 0, 1]
    uz = tri[t, 1, 2] - tri[t, 0, 2]
    vx = tri[t, 2, 0] - tri[t, 0, 0]
    vy = tri[t, 2, 1] - tri[t, 0, 1]
    vz = tri[t, 2, 2] - tri[t, 0, 2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    if nz == 0.0:
        return tri[t, 0, 2]
    return tri[t, 0, 2] - (nx * (px - tri[t, 0, 0]) + ny * (py - tri[t, 0, 1])) / nz


# ------------------------------------------------------- column winding


@njit(cache=True, error_model="numpy")
def _col_range(lo, hi, o, h, n, off):
    a = int(np.ceil((lo - o) / h)) - off
    b = int(np.floor((hi - o) / h)) - off
    if a < 0:
        a = 0
    if b > n - 1:
        b = n - 1
    return a, b


@njit(cache=True, parallel=True)
def grid_winding(tri, origin, step, dims, offset):
    """Winding numbers at the points of a regular grid (or of a block of it).

    Parameters
    ----------
    tri : (F, 3, 3) float64
        Triangle corners of a closed, outward-oriented mesh.
    origin, step : (3,) float64
        Grid point ``(i, j, k)`` is ``origin + (i, j, k) * step``.
    dims : (3,) int64
    offset : (3,) int64
        First grid index of the block: output ``[i, j, k]`` is grid point
        ``offset + (i, j, k)``, computed with exactly the arithmetic of the whole grid
        (zeros for the whole grid).

    Returns
    -------
    (nx, ny, nz) int32
        Winding number of each grid point (1 inside, 0 outside).
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    nf = tri.shape[0]
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    # pass 1: crossings per column (serial: histogram)
    for t in range(nf):
        x0 = min(tri[t, 0, 0], min(tri[t, 1, 0], tri[t, 2, 0]))
        x1 = max(tri[t, 0, 0], max(tri[t, 1, 0], tri[t, 2, 0]))
        y0 = min(tri[t, 0, 1], min(tri[t, 1, 1], tri[t, 2, 1]))
        y1 = max(tri[t, 0, 1], max(tri[t, 1, 1], tri[t, 2, 1]))
        ia, ib = _col_range(x0, x1, origin[0], step[0], nx, offset[0])
        ja, jb = _col_range(y0, y1, origin[1], step[1], ny, offset[1])
        for i in range(ia, ib + 1):
            px = origin[0] + (offset[0] + i) * step[0]
            for j in range(ja, jb + 1):
                py = origin[1] + (offset[1] + j) * step[1]
                if _tri_cover(tri, t, px, py) != 0:
                    count[i * ny + j + 1] += 1
    start = np.cumsum(count)
    total = start[-1]
    zs = np.empty(total)
    ss = np.empty(total, dtype=np.int32)
    fill = start[:-1].copy()
    for t in range(nf):
        x0 = min(tri[t, 0, 0], min(tri[t, 1, 0], tri[t, 2, 0]))
        x1 = max(tri[t, 0, 0], max(tri[t, 1, 0], tri[t, 2, 0]))
        y0 = min(tri[t, 0, 1], min(tri[t, 1, 1], tri[t, 2, 1]))
        y1 = max(tri[t, 0, 1], max(tri[t, 1, 1], tri[t, 2, 1]))
        ia, ib = _col_range(x0, x1, origin[0], step[0], nx, offset[0])
        ja, jb = _col_range(y0, y1, origin[1], step[1], ny, offset[1])
        for i in range(ia, ib + 1):
            px = origin[0] + (offset[0] + i) * step[0]
            for j in range(ja, jb + 1):
                py = origin[1] + (offset[1] + j) * step[1]
                s = _tri_cover(tri, t, px, py)
                if s != 0:
                    c = i * ny + j
                    zs[fill[c]] = _tri_z(tri, t, px, py)
                    ss[fill[c]] = s
                    fill[c] += 1
    out = np.zeros((nx, ny, nz), dtype=np.int32)
    for c in prange(nx * ny):
        a = start[c]
        b = start[c + 1]
        if a == b:
            continue
        i = c // ny
        j = c % ny
        order = np.argsort(zs[a:b])
        # sweep from the top: winding = sum of signs of crossings above
        w = 0
        q = b - a - 1
        for k in range(nz - 1, -1, -1):
            z = origin[2] + (offset[2] + k) * step[2]
            while q >= 0 and zs[a + order[q]] > z:
                w += ss[a + order[q]]
                q -= 1
            out[i, j, k] = w
    return out


# ------------------------------------------------------------- 2-D bins


@njit(cache=True)
def bin_triangles_2d(tri, origin, h, dims):
    """CSR lists of the triangles whose xy bounding box overlaps each xy bin."""
    nx, ny = dims[0], dims[1]
    nf = tri.shape[0]
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            start = np.cumsum(count)
            items = np.empty(start[-1], dtype=np.int64)
            fill = start[:-1].copy()
        for t in range(nf):
            x0 = min(tri[t, 0, 0], min(tri[t, 1, 0], tri[t, 2, 0]))
            x1 = max(tri[t, 0, 0], max(tri[t, 1, 0], tri[t, 2, 0]))
            y0 = min(tri[t, 0, 1], min(tri[t, 1, 1], tri[t, 2, 1]))
            y1 = max(tri[t, 0, 1], max(tri[t, 1, 1], tri[t, 2, 1]))
            ia = max(0, min(nx - 1, int(np.floor((x0 - origin[0]) / h))))
            ib = max(0, min(nx - 1, int(np.floor((x1 - origin[0]) / h))))
            ja = max(0, min(ny - 1, int(np.floor((y0 - origin[1]) / h))))
            jb = max(0, min(ny - 1, int(np.floor((y1 - origin[1]) / h))))
            for i in range(ia, ib + 1):
                for j in range(ja, jb + 1):
                    if pass_ == 0:
                        count[i * ny + j + 1] += 1
                    else:
                        items[fill[i * ny + j]] = t
                        fill[i * ny + j] += 1
    return start, items


@njit(cache=True, parallel=True)
def points_winding(tri, start, items, origin, h, dims, pts):
    """(P,) int32 winding numbers of arbitrary points (see :func:`bin_triangles_2d`)."""
    nx, ny = dims[0], dims[1]
    out = np.zeros(pts.shape[0], dtype=np.int32)
    for p in prange(pts.shape[0]):
        px = pts[p, 0]
        py = pts[p, 1]
        pz = pts[p, 2]
        fi = np.floor((px - origin[0]) / h)
        fj = np.floor((py - origin[1]) / h)
        if fi < 0 or fj < 0 or fi >= nx or fj >= ny:
            continue
        c = int(fi) * ny + int(fj)
        w = 0
        for q in range(start[c], start[c + 1]):
            t = items[q]
            s = _tri_cover(tri, t, px, py)
            if s != 0 and _tri_z(tri, t, px, py) > pz:
                w += s
        out[p] = w
    return out


# ------------------------------------------------------------- 3-D bins


@njit(cache=True)
def bin_triangles_3d(tri, origin, h, dims):
    """CSR lists of the triangles whose bounding box overlaps each 3-D cell."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    nf = tri.shape[0]
    count = np.zeros(nx * ny * nz + 1, dtype=np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            start = np.cumsum(count)
            items = np.empty(start[-1], dtype=np.int64)
            fill = start[:-1].copy()
        for t in range(nf):
            lo = np.empty(3, dtype=np.int64)
            hi = np.empty(3, dtype=np.int64)
            for a in range(3):
                mn = min(tri[t, 0, a], min(tri[t, 1, a], tri[t, 2, a]))
                mx = max(tri[t, 0, a], max(tri[t, 1, a], tri[t, 2, a]))
                lo[a] = max(0, min(dims[a] - 1, int(np.floor((mn - origin[a]) / h))))
                hi[a] = max(0, min(dims[a] - 1, int(np.floor((mx - origin[a]) / h))))
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    for k in range(lo[2], hi[2] + 1):
                        c = (i * ny + j) * nz + k
                        if pass_ == 0:
                            count[c + 1] += 1
                        else:
                            items[fill[c]] = t
                            fill[c] += 1
    return start, items


@njit(cache=True)
def triangle_boxes(tri):
    """(T, 6) float64: each triangle's box, min corner then max corner."""
    nt = tri.shape[0]
    box = np.empty((nt, 6))
    for t in range(nt):
        for a in range(3):
            box[t, a] = min(tri[t, 0, a], min(tri[t, 1, a], tri[t, 2, a]))
            box[t, 3 + a] = max(tri[t, 0, a], max(tri[t, 1, a], tri[t, 2, a]))
    return box


@njit(cache=True, inline="always")
def _closest_on_tri(tri, t, px, py, pz):
    """Squared distance from p to triangle t and the closest point (Ericson 5.1.5)."""
    ax, ay, az = tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2]
    bx, by, bz = tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2]
    cx, cy, cz = tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = bx, by, bz
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                v = d1 / (d1 - d3)
                qx, qy, qz = ax + v * abx, ay + v * aby, az + v * abz
            else:
                cpx, cpy, cpz = px - cx, py - cy, pz - cz
                d5 = abx * cpx + aby * cpy + abz * cpz
                d6 = acx * cpx + acy * cpy + acz * cpz
                if d6 >= 0.0 and d5 <= d6:
                    qx, qy, qz = cx, cy, cz
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        w = d2 / (d2 - d6)
                        qx, qy, qz = ax + w * acx, ay + w * acy, az + w * acz
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            qx = bx + w * (cx - bx)
                            qy = by + w * (cy - by)
                            qz = bz + w * (cz - bz)
                        else:
                            den = va + vb + vc
                            if den == 0.0:
                                qx, qy, qz = ax, ay, az
                            else:
                                v = vb / den
                                w = vc / den
                                qx = ax + abx * v + acx * w
                                qy = ay + aby * v + acy * w
                                qz = az + abz * v + acz * w
    dx, dy, dz = px - qx, py - qy, pz - qz
    return dx * dx + dy * dy + dz * dz, qx, qy, qz


@njit(cache=True, parallel=True)
def closest_points(tri, box, start, items, origin, h, dims, pts, max_dist):
    """Closest surface point of each query point (exact, grid ring search; ``box`` (T, 6):
    the triangles' boxes, :func:`triangle_boxes`).

    Returns
    -------
    dist : (P,) float64
        Distance to the surface (``inf`` when farther than ``max_dist``).
    closest : (P, 3) float64
    face : (P,) int64
        Triangle of the closest point (-1 when not found).
    """
    n = pts.shape[0]
    dist = np.full(n, np.inf)
    closest = np.full((n, 3), np.nan)
    face = np.full(n, -1, dtype=np.int64)
    nx, ny, nz = dims[0], dims[1], dims[2]
    rmax = max(nx, max(ny, nz))
    for p in prange(n):
        px, py, pz = pts[p, 0], pts[p, 1], pts[p, 2]
        # distance from p to the grid box (rings are measured from the clamped cell)
        gap = 0.0
        ci = np.empty(3, dtype=np.int64)
        for a in range(3):
            f = (pts[p, a] - origin[a]) / h
            if f < 0:
                gap = max(gap, -f * h)
                ci[a] = 0
            elif f >= dims[a]:
                gap = max(gap, (f - dims[a]) * h)
                ci[a] = dims[a] - 1
            else:
                ci[a] = int(f)
        best = np.inf
        bx = by = bz = np.nan
        bt = -1
        for r in range(rmax + 1):
            if gap + (r - 1) * h > max_dist:
                break
            for i in range(ci[0] - r, ci[0] + r + 1):
                if i < 0 or i >= nx:
                    continue
                for j in range(ci[1] - r, ci[1] + r + 1):
                    if j < 0 or j >= ny:
                        continue
                    for k in range(ci[2] - r, ci[2] + r + 1):
                        if k < 0 or k >= nz:
                            continue
                        if abs(i - ci[0]) != r and abs(j - ci[1]) != r and abs(k - ci[2]) != r:
                            continue
                        c = (i * ny + j) * nz + k
                        for q in range(start[c], start[c + 1]):
                            t = items[q]
                            # the triangle's box farther than the best: it cannot win (a
                            # relative 1e-9 above rounding, so ties are measured as before)
                            ex = max(box[t, 0] - px, max(0.0, px - box[t, 3]))
                            ey = max(box[t, 1] - py, max(0.0, py - box[t, 4]))
                            ez = max(box[t, 2] - pz, max(0.0, pz - box[t, 5]))
                            if ex * ex + ey * ey + ez * ez > best * (1.0 + 1e-9):
                                continue
                            d2, qx, qy, qz = _closest_on_tri(tri, t, px, py, pz)
                            if d2 < best:
                                best = d2
                                bx, by, bz = qx, qy, qz
                                bt = t
            if bt >= 0 and np.sqrt(best) <= gap + r * h:
                break
        d = np.sqrt(best)
        if bt >= 0 and d <= max_dist:
            dist[p] = d
            closest[p, 0] = bx
            closest[p, 1] = by
            closest[p, 2] = bz
            face[p] = bt
    return dist, closest, face


@njit(cache=True, inline="always")
def _seg_tri(tri, t, ax, ay, az, dx, dy, dz):
    """Parameter in [0, 1] where segment a + s d meets triangle t (Moller-Trumbore), or -1."""
    e1x = tri[t, 1, 0] - tri[t, 0, 0]
    e1y = tri[t, 1, 1] - tri[t, 0, 1]
    e1z = tri[t, 1, 2] - tri[t, 0, 2]
    e2x = tri[t, 2, 0] - tri[t, 0, 0]
    e2y = tri[t, 2, 1] - tri[t, 0, 1]
    e2z = tri[t, 2, 2] - tri[t, 0, 2]
    px = dy * e2z - dz * e2y
    py = dz * e2x - dx * e2z
    pz = dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:
        return -1.0
    inv = 1.0 / det
    tx = ax - tri[t, 0, 0]
    ty = ay - tri[t, 0, 1]
    tz = az - tri[t, 0, 2]
    u = (tx * px + ty * py + tz * pz) * inv
    if u < -1e-12 or u > 1.0 + 1e-12:
        return -1.0
    qx = ty * e1z - tz * e1y
    qy = tz * e1x - tx * e1z
    qz = tx * e1y - ty * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if v < -1e-12 or u + v > 1.0 + 1e-12:
        return -1.0
    s = (e2x * qx + e2y * qy + e2z * qz) * inv
    if s < 0.0 or s > 1.0:
        return -1.0
    return s


@njit(cache=True, error_model="numpy")
def _segment_params(tri, start, items, origin, h, dims, a, b, buf):
    """Crossing parameters of segment a-b with the surface (unsorted, may repeat)."""
    ny, nz = dims[1], dims[2]
    dx, dy, dz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for ax_ in range(3):
        mn = min(a[ax_], b[ax_])
        mx = max(a[ax_], b[ax_])
        lo[ax_] = max(0, int(np.floor((mn - origin[ax_]) / h)))
        hi[ax_] = min(dims[ax_] - 1, int(np.floor((mx - origin[ax_]) / h)))
    n = 0
    for i in range(lo[0], hi[0] + 1):
        for j in range(lo[1], hi[1] + 1):
            for k in range(lo[2], hi[2] + 1):
                c = (i * ny + j) * nz + k
                for q in range(start[c], start[c + 1]):
                    s = _seg_tri(tri, items[q], a[0], a[1], a[2], dx, dy, dz)
                    if s < 0.0:
                        continue
                    # report each hit once: in the cell that contains the hit point
                    hx = int(np.floor((a[0] + s * dx - origin[0]) / h))
                    hy = int(np.floor((a[1] + s * dy - origin[1]) / h))
                    hz = int(np.floor((a[2] + s * dz - origin[2]) / h))
                    hx = max(lo[0], min(hi[0], hx))
                    hy = max(lo[1], min(hi[1], hy))
                    hz = max(lo[2], min(hi[2], hz))
                    if hx != i or hy != j or hz != k:
                        continue
                    if n < buf.shape[0]:
                        buf[n] = s
                    n += 1
    return n


@njit(cache=True, parallel=True)
def segment_crossings(tri, start, items, origin, h, dims, seg_a, seg_b, cap):
    """Sorted crossing parameters in (0, 1) of each segment with the surface.

    Returns
    -------
    count : (S,) int64
        Number of crossings of each segment (duplicates within 1e-9 removed).
    params : (S, cap) float64
        The first ``min(count, cap)`` sorted parameters of each segment.
    """
    ns = seg_a.shape[0]
    count = np.zeros(ns, dtype=np.int64)
    params = np.full((ns, cap), np.nan)
    for e in prange(ns):
        buf = np.empty(64)
        n = _segment_params(tri, start, items, origin, h, dims, seg_a[e], seg_b[e], buf)
        n = min(n, 64)
        vals = np.sort(buf[:n])
        m = 0
        last = -1.0
        for q in range(n):
            if vals[q] - last > 1e-9:
                if m < cap:
                    params[e, m] = vals[q]
                m += 1
                last = vals[q]
        count[e] = m
    return count, params


# ------------------------------------------------------- triangle / box


@njit(cache=True, inline="always")
def _axis_test(p0, p1, p2, ax, ay, az, ex, ey, ez):
    # projections of the three (box-centred) vertices on the axis
    a = p0[0] * ax + p0[1] * ay + p0[2] * az
    b = p1[0] * ax + p1[1] * ay + p1[2] * az
    c = p2[0] * ax + p2[1] * ay + p2[2] * az
    r = ex * abs(ax) + ey * abs(ay) + ez * abs(az)
    return not (min(a, min(b, c)) > r or max(a, max(b, c)) < -r)


@njit(cache=True)
def _tri_box(tri, t, cx, cy, cz, ex, ey, ez):
    """True when triangle t overlaps the box centre c, half sizes e (separating axes)."""
    v0 = np.empty(3)
    v1 = np.empty(3)
    v2 = np.empty(3)
    c = (cx, cy, cz)
    for a in range(3):
        v0[a] = tri[t, 0, a] - c[a]
        v1[a] = tri[t, 1, a] - c[a]
        v2[a] = tri[t, 2, a] - c[a]
    e = (ex, ey, ez)
    for a in range(3):
        if min(v0[a], min(v1[a], v2[a])) > e[a] or max(v0[a], max(v1[a], v2[a])) < -e[a]:
            return False
    f0 = v1 - v0
    f1 = v2 - v1
    f2 = v0 - v2
    nx = f0[1] * f1[2] - f0[2] * f1[1]
    ny = f0[2] * f1[0] - f0[0] * f1[2]
    nz = f0[0] * f1[1] - f0[1] * f1[0]
    if not _axis_test(v0, v1, v2, nx, ny, nz, ex, ey, ez):
        return False
    for f in (f0, f1, f2):
        # cross products of the edge with the three box axes
        if not _axis_test(v0, v1, v2, 0.0, -f[2], f[1], ex, ey, ez):
            return False
        if not _axis_test(v0, v1, v2, f[2], 0.0, -f[0], ex, ey, ez):
            return False
        if not _axis_test(v0, v1, v2, -f[1], f[0], 0.0, ex, ey, ez):
            return False
    return True


@njit(cache=True, parallel=True)
def mark_cut_cells(tri, origin, h, dims, pad, offset):
    """(nx, ny, nz) bool: cells ``origin + [i, i+1] * h`` that a triangle touches.

    Each box is grown by ``pad`` (relative) so that the test is conservative. ``offset``
    (3,) int64: first cell index of the block (output ``[i, j, k]`` is grid cell
    ``offset + (i, j, k)``, with the whole grid's arithmetic; zeros for the whole grid).
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    cut = np.zeros((nx, ny, nz), dtype=np.bool_)
    ex = 0.5 * h[0] * (1.0 + pad)
    ey = 0.5 * h[1] * (1.0 + pad)
    ez = 0.5 * h[2] * (1.0 + pad)
    for t in prange(tri.shape[0]):
        lo = np.empty(3, dtype=np.int64)
        hi = np.empty(3, dtype=np.int64)
        for a in range(3):
            mn = min(tri[t, 0, a], min(tri[t, 1, a], tri[t, 2, a]))
            mx = max(tri[t, 0, a], max(tri[t, 1, a], tri[t, 2, a]))
            lo[a] = max(0, int(np.floor((mn - origin[a]) / h[a] - pad)) - offset[a])
            hi[a] = min(dims[a] - 1, int(np.floor((mx - origin[a]) / h[a] + pad)) - offset[a])
        for i in range(lo[0], hi[0] + 1):
            cx = origin[0] + (offset[0] + i + 0.5) * h[0]
            for j in range(lo[1], hi[1] + 1):
                cy = origin[1] + (offset[1] + j + 0.5) * h[1]
                for k in range(lo[2], hi[2] + 1):
                    if cut[i, j, k]:
                        continue
                    cz = origin[2] + (offset[2] + k + 0.5) * h[2]
                    if _tri_box(tri, t, cx, cy, cz, ex, ey, ez):
                        cut[i, j, k] = True
    return cut


# ------------------------------------------------------------ components


@njit(cache=True)
def component_labels(n, edges):
    """Connected components of an undirected graph by union-find.

    Parameters
    ----------
    n : int
        Number of nodes.
    edges : (M, 2) int

    Returns
    -------
    count : int
    labels : (n,) int64
        Components numbered in the order of their smallest node (as scipy's
        ``connected_components`` numbers them); a node without edges is its own one.
    """
    parent = np.arange(n)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        b = edges[e, 1]
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
    # every root is the smallest node of its tree; label the roots in node order
    labels = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        r = i
        while parent[r] != r:
            r = parent[r]
        parent[i] = r
        if r == i:
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]
    return count, labels


# ------------------------------------------------- clearance of triangle soups
@njit(cache=True, inline="always")
def _clamp01(x):
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@njit(cache=True, inline="always", error_model="numpy")
def _seg_seg_dist2(px, py, pz, qx, qy, qz, rx, ry, rz, sx, sy, sz):
    """Squared distance between segments pq and rs (Ericson 5.1.9)."""
    d1x, d1y, d1z = qx - px, qy - py, qz - pz
    d2x, d2y, d2z = sx - rx, sy - ry, sz - rz
    wx, wy, wz = px - rx, py - ry, pz - rz
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * wx + d2y * wy + d2z * wz
    if a <= 1e-300 and e <= 1e-300:
        s = 0.0
        t = 0.0
    elif a <= 1e-300:
        s = 0.0
        t = _clamp01(f / e)
    else:
        c = d1x * wx + d1y * wy + d1z * wz
        if e <= 1e-300:
            t = 0.0
            s = _clamp01(-c / a)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            den = a * e - b * b
            s = _clamp01((b * f - c * e) / den) if den > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = _clamp01(-c / a)
            elif t > 1.0:
                t = 1.0
                s = _clamp01((b - c) / a)
    dx = px + d1x * s - (rx + d2x * t)
    dy = py + d1y * s - (ry + d2y * t)
    dz = pz + d1z * s - (rz + d2z * t)
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, error_model="numpy")
def triangles_within(a, i, b, j, eps):
    """Whether triangles ``a[i]`` and ``b[j]`` ((3, 3) rows of (K, 3, 3) arrays) come within
    ``eps`` of each other (touching and crossing included). A degenerate triangle (a
    segment or a point) is measured by its edges (numpy's error model: a division by zero
    in the other tests only makes them miss).

    Disjoint triangles are closest at a vertex of one and the other triangle, or at two
    edges; crossing ones have an edge of one through the other (Moller-Trumbore, with a
    tolerance that only ever adds hits)."""
    e2 = eps * eps
    for u in range(3):
        if _closest_on_tri(b, j, a[i, u, 0], a[i, u, 1], a[i, u, 2])[0] <= e2:
            return True
        if _closest_on_tri(a, i, b[j, u, 0], b[j, u, 1], b[j, u, 2])[0] <= e2:
            return True
    for u in range(3):
        u2 = (u + 1) % 3
        for w in range(3):
            w2 = (w + 1) % 3
            d2 = _seg_seg_dist2(
                a[i, u, 0], a[i, u, 1], a[i, u, 2], a[i, u2, 0], a[i, u2, 1], a[i, u2, 2],
                b[j, w, 0], b[j, w, 1], b[j, w, 2], b[j, w2, 0], b[j, w2, 1], b[j, w2, 2],
            )  # fmt: skip
            if d2 <= e2:
                return True
    for u in range(3):
        u2 = (u + 1) % 3
        ax, ay, az = a[i, u, 0], a[i, u, 1], a[i, u, 2]
        if _seg_tri(b, j, ax, ay, az, a[i, u2, 0] - ax, a[i, u2, 1] - ay, a[i, u2, 2] - az) >= 0:
            return True
        bx, by, bz = b[j, u, 0], b[j, u, 1], b[j, u, 2]
        if _seg_tri(a, i, bx, by, bz, b[j, u2, 0] - bx, b[j, u2, 1] - by, b[j, u2, 2] - bz) >= 0:
            return True
    return False


@njit(cache=True, parallel=True, error_model="numpy")
def soups_within(tri, box, start, items, origin, h, dims, v, soup, soup_start, eps):
    """Which triangle soups come within ``eps`` of a binned mesh.

    tri (T, 3, 3), box (T, 6), start, items, origin, h, dims: the mesh, its triangles' boxes
    (:func:`triangle_boxes`) and its 3-D bins (:func:`bin_triangles_3d`); v (V, 3): vertices;
    soup (K, 3): the soups' triangles (rows of ``v``), soup ``s`` being rows
    ``soup_start[s]:soup_start[s + 1]``.
    Returns (S,) bool.
    """
    n = soup_start.shape[0] - 1
    out = np.zeros(n, dtype=np.bool_)
    ny, nz = dims[1], dims[2]
    nt = tri.shape[0]
    tlo = box[:, :3]
    thi = box[:, 3:]
    # unit normals and offsets of the mesh's triangles (0: degenerate, no plane test)
    tn = np.zeros((nt, 4))
    for t in range(nt):
        ux, uy, uz = (
            tri[t, 1, 0] - tri[t, 0, 0],
            tri[t, 1, 1] - tri[t, 0, 1],
            tri[t, 1, 2] - tri[t, 0, 2],
        )
        wx, wy, wz = (
            tri[t, 2, 0] - tri[t, 0, 0],
            tri[t, 2, 1] - tri[t, 0, 1],
            tri[t, 2, 2] - tri[t, 0, 2],
        )
        cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        norm = np.sqrt(cx * cx + cy * cy + cz * cz)
        if norm > 0.0:
            tn[t, 0], tn[t, 1], tn[t, 2] = cx / norm, cy / norm, cz / norm
            tn[t, 3] = -(
                tn[t, 0] * tri[t, 0, 0] + tn[t, 1] * tri[t, 0, 1] + tn[t, 2] * tri[t, 0, 2]
            )
    for s in prange(n):
        k0, k1 = soup_start[s], soup_start[s + 1]
        if k1 == k0:
            continue
        a = np.empty((k1 - k0, 3, 3))
        alo = np.empty((k1 - k0, 3))
        ahi = np.empty((k1 - k0, 3))
        slo = np.full(3, np.inf)
        shi = np.full(3, -np.inf)
        for k in range(k1 - k0):
            for u in range(3):
                for ax in range(3):
                    a[k, u, ax] = v[soup[k0 + k, u], ax]
            for ax in range(3):
                alo[k, ax] = min(a[k, 0, ax], min(a[k, 1, ax], a[k, 2, ax]))
                ahi[k, ax] = max(a[k, 0, ax], max(a[k, 1, ax], a[k, 2, ax]))
                slo[ax] = min(slo[ax], alo[k, ax])
                shi[ax] = max(shi[ax], ahi[k, ax])
        lo = np.empty(3, dtype=np.int64)
        hi = np.empty(3, dtype=np.int64)
        for ax in range(3):
            lo[ax] = max(0, min(dims[ax] - 1, int(np.floor((slo[ax] - eps - origin[ax]) / h))))
            hi[ax] = max(0, min(dims[ax] - 1, int(np.floor((shi[ax] + eps - origin[ax]) / h))))
        # the mesh's triangles near the soup's box, each once
        m = 0
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                c0 = (i * ny + j) * nz
                m += start[c0 + hi[2] + 1] - start[c0 + lo[2]]
        if m == 0:
            continue
        cand = np.empty(m, dtype=np.int64)
        m = 0
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                c0 = (i * ny + j) * nz
                for q in range(start[c0 + lo[2]], start[c0 + hi[2] + 1]):
                    t = items[q]
                    if (
                        tlo[t, 0] - shi[0] <= eps and slo[0] - thi[t, 0] <= eps
                        and tlo[t, 1] - shi[1] <= eps and slo[1] - thi[t, 1] <= eps
                        and tlo[t, 2] - shi[2] <= eps and slo[2] - thi[t, 2] <= eps
                    ):  # fmt: skip
                        cand[m] = t
                        m += 1
        if m == 0:
            continue
        cand = np.unique(cand[:m])
        hit = False
        for t in cand:
            for k in range(k1 - k0):
                if (
                    tlo[t, 0] - ahi[k, 0] > eps or alo[k, 0] - thi[t, 0] > eps
                    or tlo[t, 1] - ahi[k, 1] > eps or alo[k, 1] - thi[t, 1] > eps
                    or tlo[t, 2] - ahi[k, 2] > eps or alo[k, 2] - thi[t, 2] > eps
                ):  # fmt: skip
                    continue
                if tn[t, 0] != 0.0 or tn[t, 1] != 0.0 or tn[t, 2] != 0.0:
                    # all of triangle k farther than eps on one side of t's plane: apart
                    d0 = tn[t, 0] * a[k, 0, 0] + tn[t, 1] * a[k, 0, 1] + tn[t, 2] * a[k, 0, 2]
                    d1 = tn[t, 0] * a[k, 1, 0] + tn[t, 1] * a[k, 1, 1] + tn[t, 2] * a[k, 1, 2]
                    d2 = tn[t, 0] * a[k, 2, 0] + tn[t, 1] * a[k, 2, 1] + tn[t, 2] * a[k, 2, 2]
                    lo_d = min(d0, min(d1, d2)) + tn[t, 3]
                    hi_d = max(d0, max(d1, d2)) + tn[t, 3]
                    if lo_d > eps or hi_d < -eps:
                        continue
                if triangles_within(a, k, tri, t, eps):
                    hit = True
                    break
            if hit:
                break
        out[s] = hit
    return out


@njit(cache=True, inline="always")
def _area(p, i, k, j):
    """Area of the triangle of rows ``i, k, j`` of ``p`` (n, 3)."""
    u0, u1, u2 = p[k, 0] - p[i, 0], p[k, 1] - p[i, 1], p[k, 2] - p[i, 2]
    w0, w1, w2 = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1], p[j, 2] - p[i, 2]
    c0, c1, c2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
    return 0.5 * np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


@njit(cache=True)
def min_area_fill(p, forbidden):
    """A minimal-area triangulation of a closed polygon (a hole's boundary loop).

    p : (n, 3) float64 loop vertices in order; forbidden : (n, n) bool, chords (i, j) that
    must not be used (they are edges of the mesh already). Returns (n - 2, 3) int64 local
    triangles ``(i, j, k)`` for ``i < k < j`` (the reverse of the loop's direction along its
    edges), or an empty array when every triangulation uses a forbidden chord. O(n^3).
    """
    n = p.shape[0]
    inf = np.inf
    w = np.full((n, n), inf)
    arg = np.full((n, n), -1, dtype=np.int64)
    for i in range(n - 1):
        w[i, i + 1] = 0.0
    for span in range(2, n):
        for i in range(n - span):
            j = i + span
            if span < n - 1 and forbidden[i, j]:
                continue
            best = inf
            bk = -1
            for k in range(i + 1, j):
                c = w[i, k] + w[k, j]
                if c >= best:
                    continue
                c += _area(p, i, k, j)
                if c < best:
                    best = c
                    bk = k
            w[i, j] = best
            arg[i, j] = bk
    out = np.empty((max(n - 2, 0), 3), dtype=np.int64)
    if n < 3 or arg[0, n - 1] < 0:
        return out[:0]
    stack = np.empty((n, 2), dtype=np.int64)
    top = 0
    stack[0, 0] = 0
    stack[0, 1] = n - 1
    top = 1
    m = 0
    while top > 0:
        top -= 1
        i = stack[top, 0]
        j = stack[top, 1]
        if j - i < 2:
            continue
        k = arg[i, j]
        out[m, 0] = i
        out[m, 1] = j
        out[m, 2] = k
        m += 1
        stack[top, 0] = i
        stack[top, 1] = k
        top += 1
        stack[top, 0] = k
        stack[top, 1] = j
        top += 1
    return out[:m]


# ------------------------------------------------------------ depth bounds
@njit(cache=True, inline="always")
def _dist(px, py, pz, q):
    return np.sqrt((px - q[0]) ** 2 + (py - q[1]) ** 2 + (pz - q[2]) ** 2)


@njit(cache=True)
def octant_depth_bounds(centres, a, signs, near):
    """An upper bound of the distance to a surface over each octant of cubes.

    Cube ``c`` has centre ``centres[c]`` (C, 3) and half side ``a``; its octant ``o`` is
    the box between the centre and the corner ``centres[c] + a * signs[o]`` (signs (8, 3)),
    and ``near[c, o]`` (C, 8, 3) is a point of the surface (the nearest to that corner; NaN:
    none found). Every point ``y`` of the octant lies no farther from the surface than from
    ``q_o = near[c, o]``, nor than the nearer of ``q_o`` and another ``q_j``: the box cut
    by their bisector plane gives two convex pieces, on each of which the distance to its
    nearer point is convex, so it is largest at a vertex of the piece: a vertex of the box
    or where the plane crosses one of its edges. The bound is the least of those maxima over
    ``j`` (``j = o``: the box's vertices alone). Returns (C, 8) float64 (inf: no bound).
    """
    n = centres.shape[0]
    out = np.empty((n, 8))
    box = np.empty((8, 3))
    for c in range(n):
        for o in range(8):
            qi = near[c, o]
            if not (np.isfinite(qi[0]) and np.isfinite(qi[1]) and np.isfinite(qi[2])):
                out[c, o] = np.inf
                continue
            for v in range(8):  # vertex bits (x, y, z): 0 the centre's side, 1 the corner's
                for k in range(3):
                    box[v, k] = centres[c, k] + a * signs[o, k] * ((v >> (2 - k)) & 1)
            best = np.inf
            for j in range(8):
                qj = near[c, j]
                if not (np.isfinite(qj[0]) and np.isfinite(qj[1]) and np.isfinite(qj[2])):
                    continue
                worst = 0.0
                for v in range(8):
                    d = _dist(box[v, 0], box[v, 1], box[v, 2], qi)
                    if j != o:
                        d = min(d, _dist(box[v, 0], box[v, 1], box[v, 2], qj))
                    worst = max(worst, d)
                if j != o:
                    nx, ny, nz = qj[0] - qi[0], qj[1] - qi[1], qj[2] - qi[2]
                    mx, my, mz = 0.5 * (qi[0] + qj[0]), 0.5 * (qi[1] + qj[1]), 0.5 * (qi[2] + qj[2])
                    for v in range(8):
                        for k in range(3):
                            w = v | (1 << (2 - k))
                            if w == v:
                                continue  # each edge once, from its 0 end
                            s1 = nx * (box[v, 0] - mx) + ny * (box[v, 1] - my)
                            s1 += nz * (box[v, 2] - mz)
                            s2 = nx * (box[w, 0] - mx) + ny * (box[w, 1] - my)
                            s2 += nz * (box[w, 2] - mz)
                            if s1 * s2 < 0.0:
                                t = s1 / (s1 - s2)
                                px = box[v, 0] + t * (box[w, 0] - box[v, 0])
                                py = box[v, 1] + t * (box[w, 1] - box[v, 1])
                                pz = box[v, 2] + t * (box[w, 2] - box[v, 2])
                                worst = max(worst, _dist(px, py, pz, qi))
                best = min(best, worst)
            out[c, o] = best
    return out
