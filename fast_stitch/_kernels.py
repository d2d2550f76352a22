"""Numba kernels of the combinatorial stitcher (Verma, Rankouhi & Suresh 2019).

Arrays and scalars only: no I/O, no logging, no Python objects. The public
wrappers in :mod:`fast_stitch.stitch` validate inputs, coerce dtypes, call
these kernels and wrap the results.

Vertex numbering: profile vertex ``k`` of strut ``e`` at end ``side`` has id
``(2 * e + side) * P + k``, so ``V == 2 * M * P`` exactly; with ``profile="volume"`` the
band rings (:func:`band_faces`) follow: ``V == 4 * M * P``.

Every strut gets one frame ``(u, v)`` shared by both of its ends (no twist).
The frame and a pseudo-random phase are derived from the strut's *quantised,
unsigned* direction and the seed, so struts that are translates of each other
get identical profiles; this makes hubs that are translates of each other
identical too, so a periodic lattice needs each distinct hub computed once.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fast_stitch._predicates import tri_tri

QSCALE = 1073741824.0  # 2**30: directions are snapped to this grid
RSCALE = 1099511627776.0  # 2**40: radii (relative to the largest) are keyed on this grid

# Status codes of hub construction (see fast_stitch.stitch for messages)
HUB_OK = 0
HUB_HULL_FAILED = 1
HUB_BOUNDARY_MISMATCH = 2
HUB_DEGENERATE = 3


# ---------------------------------------------------------------- hashing
@njit(cache=True, inline="always", error_model="numpy")
def _mix64(x):
    x = x + np.uint64(0x9E3779B97F4A7C15)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(cache=True, inline="always", error_model="numpy")
def _hash_combine(h, v):
    return _mix64(h ^ (np.uint64(v) + np.uint64(0x632BE59BD9B4E019)))


# ------------------------------------------------------------- edge frames
@njit(cache=True, parallel=True, error_model="numpy")
def edge_frames(nodes, edges, P, seed, qdir, sign, axis, frame_u, frame_v, length):
    """Per-strut canonical axis, frame and length.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    P : int
        Segments per profile.
    seed : int
        Seed of the per-strut phase.
    qdir : (M, 3) int64, out
        Quantised canonical (unsigned) direction: the first non-zero component is positive.
    sign : (M,) int64, out
        +1 if ``nodes[e1] - nodes[e0]`` points along the canonical axis, else -1.
    axis : (M, 3) float64, out
        Canonical unit axis (normalised ``qdir``); identical for translates.
    frame_u, frame_v : (M, 3) float64, out
        Orthonormal profile frame, ``u x v == axis``, rotated by the strut's phase.
    length : (M,) float64, out
    """
    m = edges.shape[0]
    two_pi_p = 2.0 * np.pi / P
    for e in prange(m):
        a = edges[e, 0]
        b = edges[e, 1]
        dx = nodes[b, 0] - nodes[a, 0]
        dy = nodes[b, 1] - nodes[a, 1]
        dz = nodes[b, 2] - nodes[a, 2]
        L = np.sqrt(dx * dx + dy * dy + dz * dz)
        length[e] = L
        qx = np.int64(np.rint(dx / L * QSCALE))
        qy = np.int64(np.rint(dy / L * QSCALE))
        qz = np.int64(np.rint(dz / L * QSCALE))
        s = 1
        if qx < 0 or (qx == 0 and (qy < 0 or (qy == 0 and qz < 0))):
            s = -1
        qx *= s
        qy *= s
        qz *= s
        qdir[e, 0] = qx
        qdir[e, 1] = qy
        qdir[e, 2] = qz
        sign[e] = s
        cx = float(qx)
        cy = float(qy)
        cz = float(qz)
        cn = np.sqrt(cx * cx + cy * cy + cz * cz)
        cx /= cn
        cy /= cn
        cz /= cn
        axis[e, 0] = cx
        axis[e, 1] = cy
        axis[e, 2] = cz
        # Duff et al. 2017 orthonormal basis (branch on the quantised sign of z)
        sg = 1.0 if qz >= 0 else -1.0
        aa = -1.0 / (sg + cz)
        bb = cx * cy * aa
        b1x = 1.0 + sg * cx * cx * aa
        b1y = sg * bb
        b1z = -sg * cx
        b2x = bb
        b2y = sg + cy * cy * aa
        b2z = -cy
        # b1 x b2 == c (right-handed); phase from the seeded hash of qdir
        h = _hash_combine(_mix64(np.uint64(seed)), qx)
        h = _hash_combine(h, qy)
        h = _hash_combine(h, qz)
        phase = float(h >> np.uint64(11)) * (1.0 / 9007199254740992.0) * two_pi_p
        cp = np.cos(phase)
        sp = np.sin(phase)
        frame_u[e, 0] = cp * b1x + sp * b2x
        frame_u[e, 1] = cp * b1y + sp * b2y
        frame_u[e, 2] = cp * b1z + sp * b2z
        frame_v[e, 0] = -sp * b1x + cp * b2x
        frame_v[e, 1] = -sp * b1y + cp * b2y
        frame_v[e, 2] = -sp * b1z + cp * b2z


# ----------------------------------------------------------- node ordering
@njit(cache=True, inline="always", error_model="numpy")
def _slot_less(qa, ra, qb, rb):
    for c in range(3):
        if qa[c] != qb[c]:
            return qa[c] < qb[c]
    return ra < rb


@njit(cache=True, parallel=True, error_model="numpy")
def node_slots(offsets, inc_edge, inc_side, qdir, sign, radii, rmax, slots, slot_q, slot_r, keys):
    """Canonical order of the struts at each node, and a hash key per node.

    Struts at a node are sorted by their quantised outward direction, so nodes
    that are translates of each other list their struts in the same order.

    Parameters
    ----------
    offsets : (N + 1,) int64
    inc_edge, inc_side : (2M,) int64
        CSR incidence (see ``LatticeGraph.incidence``).
    qdir : (M, 3) int64
    sign : (M,) int64
    radii : (M, 2) float64
    rmax : float
        Largest radius (keys quantise radii relative to it).
    slots : (2M,) int64, out
        Incidence entries re-ordered canonically: entry ``offsets[n] + t`` is
        ``2 * e + side`` of the t-th strut of node n.
    slot_q : (2M, 3) int64, out
        Quantised outward direction of each slot.
    slot_r : (2M,) int64, out
        Quantised radius of each slot.
    keys : (N,) uint64, out
        Hash of the node's sorted (direction, radius) slots; 0 for degree < 2.
    """
    n_nodes = offsets.shape[0] - 1
    for n in prange(n_nodes):
        lo = offsets[n]
        hi = offsets[n + 1]
        for t in range(lo, hi):
            e = inc_edge[t]
            side = inc_side[t]
            s = sign[e] if side == 0 else -sign[e]
            slots[t] = 2 * e + side
            slot_q[t, 0] = s * qdir[e, 0]
            slot_q[t, 1] = s * qdir[e, 1]
            slot_q[t, 2] = s * qdir[e, 2]
            slot_r[t] = np.int64(np.rint(radii[e, side] / rmax * RSCALE))
        # insertion sort (degrees are small)
        for t in range(lo + 1, hi):
            j = t
            while j > lo and _slot_less(slot_q[j], slot_r[j], slot_q[j - 1], slot_r[j - 1]):
                for c in range(3):
                    tmp = slot_q[j, c]
                    slot_q[j, c] = slot_q[j - 1, c]
                    slot_q[j - 1, c] = tmp
                tr = slot_r[j]
                slot_r[j] = slot_r[j - 1]
                slot_r[j - 1] = tr
                ts = slots[j]
                slots[j] = slots[j - 1]
                slots[j - 1] = ts
                j -= 1
        if hi - lo < 2:
            keys[n] = np.uint64(0)
            continue
        h = _mix64(np.uint64(hi - lo))
        for t in range(lo, hi):
            h = _hash_combine(h, slot_q[t, 0])
            h = _hash_combine(h, slot_q[t, 1])
            h = _hash_combine(h, slot_q[t, 2])
            h = _hash_combine(h, slot_r[t])
        if h == np.uint64(0):
            h = np.uint64(1)
        keys[n] = h


@njit(cache=True, parallel=True, error_model="numpy")
def same_key(nodes_a, nodes_b, offsets, slots, slot_q, radii, out):
    """out[i] = node nodes_a[i] has exactly the slots of node nodes_b[i] (hash check).

    Radii are compared exactly (not by their quantised key), so a node shares the hub of
    another only when the hub's inputs are bit-identical: the hub of a node is then a
    function of its own struts alone, whichever node of its group was built (what
    sharded stitching relies on for identical seams)."""
    for i in prange(nodes_a.shape[0]):
        a = nodes_a[i]
        b = nodes_b[i]
        da = offsets[a + 1] - offsets[a]
        ok = da == offsets[b + 1] - offsets[b]
        if ok:
            for t in range(da):
                ta = offsets[a] + t
                tb = offsets[b] + t
                ea = slots[ta]
                eb = slots[tb]
                if (
                    radii[ea // 2, ea % 2] != radii[eb // 2, eb % 2]
                    or slot_q[ta, 0] != slot_q[tb, 0]
                    or slot_q[ta, 1] != slot_q[tb, 1]
                    or slot_q[ta, 2] != slot_q[tb, 2]
                ):
                    ok = False
                    break
        out[i] = ok


# -------------------------------------------------------------- offsets
@njit(cache=True, error_model="numpy")
def hub_offsets(dirs, rad, shrink, margin, floor_tan, out_d, out_det):
    """Profile offsets of one hub (distance from the node to each profile centre).

    ``d_ij = (r_j + r_i cos t) / sin t`` (Verma et al., Fig. 9) is exactly the
    offset at which the cones of the two struts from the node touch; the ideal
    offset of strut i is the largest over j (times ``1 + margin``), and at least
    ``r_i / floor_tan``. With ``shrink`` the offsets are then raised, as little
    as possible, until every other profile lies strictly below the plane of
    each profile (fixed-point iteration; the hub is then the convex hull of its
    profiles with every profile a facet). Without ``shrink`` all profile
    vertices lie on one sphere (the paper's unshrunk node hull).

    Parameters
    ----------
    dirs : (d, 3) float64
        Unit outward strut directions.
    rad : (d,) float64
        Strut radius at this node.
    out_d : (d,) float64, out
    out_det : (d,) int64, out
        Slot whose constraint set the offset (-1: the floor), for messages.
    """
    d = dirs.shape[0]
    cosm = np.empty((d, d))
    sinm = np.empty((d, d))
    for i in range(d):
        for j in range(d):
            c = dirs[i, 0] * dirs[j, 0] + dirs[i, 1] * dirs[j, 1] + dirs[i, 2] * dirs[j, 2]
            c = min(1.0, max(-1.0, c))
            cosm[i, j] = c
            sinm[i, j] = np.sqrt(max(0.0, 1.0 - c * c))
    # the floor: cone half-angle at most alpha_max, tan(alpha_max) == floor_tan
    alpha_max = np.arctan(floor_tan)
    ideal = np.empty(d)
    for i in range(d):
        best = rad[i] / floor_tan
        arg = -1
        for j in range(d):
            if j == i or sinm[i, j] <= 1e-12:
                continue
            # tangent split of the angle between the two cones
            dij = (rad[j] + rad[i] * cosm[i, j]) / sinm[i, j]
            dji = (rad[i] + rad[j] * cosm[i, j]) / sinm[i, j]
            if dji * floor_tan < rad[j]:
                # j's share would exceed alpha_max: j is floored anyway, so i
                # only has to stay within theta - alpha_max
                rest = np.arccos(cosm[i, j]) - alpha_max
                if rest >= 0.5 * np.pi:
                    continue
                dij = rad[i] / np.tan(rest)
            dij *= 1.0 + margin
            if dij > best:
                best = dij
                arg = j
        ideal[i] = best
        out_det[i] = arg
    rho2 = 0.0
    for i in range(d):
        rho2 = max(rho2, ideal[i] * ideal[i] + rad[i] * rad[i])
    if not shrink:
        for i in range(d):
            out_d[i] = np.sqrt(rho2 - rad[i] * rad[i])
        return
    delta = margin * np.sqrt(rho2)
    for i in range(d):
        out_d[i] = ideal[i]
    converged = False
    prev = np.empty(d)
    for _sweep in range(200):
        # Jacobi sweeps (every update reads the previous sweep), so the result
        # does not depend on the order of the struts
        for i in range(d):
            prev[i] = out_d[i]
        changed = False
        for i in range(d):
            for j in range(d):
                if j == i:
                    continue
                dj = prev[j] if cosm[i, j] > 0.0 else ideal[j]
                need = dj * cosm[i, j] + rad[j] * sinm[i, j] + delta
                if need > prev[i] * (1.0 + 1e-9) and need + 0.1 * delta > out_d[i]:
                    # a little slack stops the geometric creep of coupled constraints
                    out_d[i] = need + 0.1 * delta
                    out_det[i] = j
                    changed = True
        if not changed:
            converged = True
            break
    if not converged:
        for i in range(d):
            out_d[i] = np.sqrt(rho2 - rad[i] * rad[i])
    else:
        # never beyond the common-sphere configuration
        for i in range(d):
            out_d[i] = min(out_d[i], np.sqrt(rho2 - rad[i] * rad[i]))


# ------------------------------------------------------------ convex hull
@njit(cache=True, inline="always", error_model="numpy")
def _plane(pts, a, b, c, nrm, off, tol, eps, f):
    """Plane of face f through points a, b, c: ``nrm[f] . x == off[f]``.

    The normal is not normalised (no division on the hull's critical path);
    ``tol[f] = eps * |nrm[f]|`` is the visibility threshold in the same units.
    """
    ux = pts[b, 0] - pts[a, 0]
    uy = pts[b, 1] - pts[a, 1]
    uz = pts[b, 2] - pts[a, 2]
    vx = pts[c, 0] - pts[a, 0]
    vy = pts[c, 1] - pts[a, 1]
    vz = pts[c, 2] - pts[a, 2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    nn2 = nx * nx + ny * ny + nz * nz
    if nn2 <= 1e-280:
        return False
    nrm[f, 0] = nx
    nrm[f, 1] = ny
    nrm[f, 2] = nz
    off[f] = nx * pts[a, 0] + ny * pts[a, 1] + nz * pts[a, 2]
    tol[f] = eps * np.sqrt(nn2)
    return True


@njit(cache=True, error_model="numpy")
def convex_hull(pts, order, eps, cap):
    """Incremental 3D convex hull of points in convex position.

    Steps: an initial tetrahedron (:func:`_initial_tetrahedron`); then, for each
    point in turn, a face it sees, the connected region of faces it sees and the
    cone of new faces from the horizon of that region to the point; finally the
    faces still alive (:func:`_alive_faces`). The per-point steps stay in this
    loop: as helpers (even ``inline="always"``) they made the hull about 40 %
    slower (array arguments cost reference counting on every call).

    Parameters
    ----------
    pts : (n, 3) float64
        Points, scaled to about unit size.
    order : (n,) int64
        Insertion order (a permutation of 0..n-1).
    eps : float
        A point sees a face when it lies more than ``eps`` above its plane.
    cap : int
        Face capacity.

    Returns
    -------
    faces : (F, 3) int64
        Outward-oriented triangles (counter-clockwise seen from outside).
    status : int
        0 on success; 1 if the hull is degenerate or capacity ran out;
        2 if some point is not a hull vertex.
    """
    n = pts.shape[0]
    empty = np.zeros((0, 3), dtype=np.int64)
    fv = np.empty((cap, 3), dtype=np.int64)
    fnb = np.empty((cap, 3), dtype=np.int64)
    alive = np.zeros(cap, dtype=np.bool_)
    nrm = np.empty((cap, 3))
    off = np.empty(cap)
    tol = np.empty(cap)
    i0, i1, i2, i3, ok = _initial_tetrahedron(pts, order, eps, fv, fnb, alive, nrm, off, tol)
    if not ok:
        return empty, 1
    nf = 4
    used = np.zeros(n, dtype=np.bool_)
    used[i0] = True
    used[i1] = True
    used[i2] = True
    used[i3] = True
    visible = np.zeros(cap, dtype=np.bool_)
    vis_list = np.empty(cap, dtype=np.int64)
    start_at = np.full(n, -1, dtype=np.int64)
    end_at = np.full(n, -1, dtype=np.int64)
    new_list = np.empty(cap, dtype=np.int64)
    last = 0
    n_last = 1
    for t in range(n):
        p = order[t]
        if used[p]:
            continue
        px = pts[p, 0]
        py = pts[p, 1]
        pz = pts[p, 2]
        # start from the best face of the previous point's fan (consecutive
        # points are neighbours), walk greedily on the height above the
        # visibility threshold, then flood-fill the connected visible region
        f = last
        dist = nrm[f, 0] * px + nrm[f, 1] * py + nrm[f, 2] * pz - off[f] - tol[f]
        for iv in range(1, n_last):
            g = new_list[iv]
            dg = nrm[g, 0] * px + nrm[g, 1] * py + nrm[g, 2] * pz - off[g] - tol[g]
            if dg > dist:
                dist = dg
                f = g
        for _step in range(nf):
            if dist > 0.0:
                break
            best_g = -1
            best_dist = dist
            for j in range(3):
                g = fnb[f, j]
                dg = nrm[g, 0] * px + nrm[g, 1] * py + nrm[g, 2] * pz - off[g] - tol[g]
                if dg > best_dist:
                    best_dist = dg
                    best_g = g
            if best_g == -1:
                break
            f = best_g
            dist = best_dist
        if dist <= 0.0:  # stuck on a local maximum: scan every face
            f = -1
            for g in range(nf):
                if alive[g] and nrm[g, 0] * px + nrm[g, 1] * py + nrm[g, 2] * pz - off[g] > tol[g]:
                    f = g
                    break
            if f == -1:
                continue  # not extreme: reported below
        visible[f] = True
        vis_list[0] = f
        nvis = 1
        head = 0
        while head < nvis:
            g0 = vis_list[head]
            head += 1
            for j in range(3):
                g = fnb[g0, j]
                if not visible[g] and (
                    nrm[g, 0] * px + nrm[g, 1] * py + nrm[g, 2] * pz - off[g] > tol[g]
                ):
                    visible[g] = True
                    vis_list[nvis] = g
                    nvis += 1
        used[p] = True
        # the cone from the horizon of the visible region to p
        nnew = 0
        for iv in range(nvis):
            f = vis_list[iv]
            for j in range(3):
                g = fnb[f, j]
                if visible[g]:
                    continue
                a = fv[f, j]
                b = fv[f, (j + 1) % 3]
                if nf >= cap or start_at[a] != -1 or end_at[b] != -1:
                    return empty, 1
                h = nf
                nf += 1
                fv[h, 0] = a
                fv[h, 1] = b
                fv[h, 2] = p
                alive[h] = True
                if not _plane(pts, a, b, p, nrm, off, tol, eps, h):
                    return empty, 1
                fnb[h, 0] = g
                for k in range(3):
                    if fnb[g, k] == f:
                        fnb[g, k] = h
                start_at[a] = h
                end_at[b] = h
                new_list[nnew] = h
                nnew += 1
        for iv in range(nnew):
            h = new_list[iv]
            a = fv[h, 0]
            b = fv[h, 1]
            nb1 = start_at[b]
            nb2 = end_at[a]
            if nb1 == -1 or nb2 == -1:
                return empty, 1
            fnb[h, 1] = nb1
            fnb[h, 2] = nb2
        for iv in range(nnew):
            h = new_list[iv]
            start_at[fv[h, 0]] = -1
            end_at[fv[h, 1]] = -1
        for iv in range(nvis):
            f = vis_list[iv]
            alive[f] = False
            visible[f] = False
        last = new_list[0]
        n_last = nnew
    for q in range(n):
        if not used[q]:
            return empty, 2
    return _alive_faces(fv, alive, nf), 0


@njit(cache=True, error_model="numpy")
def _initial_tetrahedron(pts, order, eps, fv, fnb, alive, nrm, off, tol):
    """The first four faces of the hull: an outward tetrahedron of well spread points.

    ``i0 = order[0]``, ``i1`` the point farthest from it, ``i2`` the farthest from the
    line ``i0 i1``, ``i3`` the farthest from the plane ``i0 i1 i2``. Sets rows 0..3 of
    the face arrays (``fv``, ``fnb`` (cap, 3) int64: vertices and neighbours across
    edge ``j``; ``alive`` (cap,) bool; planes ``nrm``, ``off``, ``tol``, see
    :func:`_plane`).

    Returns
    -------
    i0, i1, i2, i3 : int
    ok : bool
        False if the points are (nearly) coplanar.
    """
    n = pts.shape[0]
    i0 = order[0]
    best = -1.0
    i1 = -1
    for t in range(n):
        q = order[t]
        dx = pts[q, 0] - pts[i0, 0]
        dy = pts[q, 1] - pts[i0, 1]
        dz = pts[q, 2] - pts[i0, 2]
        dd = dx * dx + dy * dy + dz * dz
        if dd > best:
            best = dd
            i1 = q
    ex = pts[i1, 0] - pts[i0, 0]
    ey = pts[i1, 1] - pts[i0, 1]
    ez = pts[i1, 2] - pts[i0, 2]
    best = -1.0
    i2 = -1
    for t in range(n):
        q = order[t]
        dx = pts[q, 0] - pts[i0, 0]
        dy = pts[q, 1] - pts[i0, 1]
        dz = pts[q, 2] - pts[i0, 2]
        cx = ey * dz - ez * dy
        cy = ez * dx - ex * dz
        cz = ex * dy - ey * dx
        dd = cx * cx + cy * cy + cz * cz
        if dd > best:
            best = dd
            i2 = q
    if not _plane(pts, i0, i1, i2, nrm, off, tol, eps, 0):
        return i0, i1, i2, -1, False
    best = -1.0
    i3 = -1
    for t in range(n):
        q = order[t]
        dd = abs(nrm[0, 0] * pts[q, 0] + nrm[0, 1] * pts[q, 1] + nrm[0, 2] * pts[q, 2] - off[0])
        if dd > best:
            best = dd
            i3 = q
    if best <= tol[0]:
        return i0, i1, i2, i3, False
    if nrm[0, 0] * pts[i3, 0] + nrm[0, 1] * pts[i3, 1] + nrm[0, 2] * pts[i3, 2] - off[0] > 0.0:
        tmp = i1
        i1 = i2
        i2 = tmp
    # faces of the tetrahedron, outward
    tet = ((i0, i1, i2), (i0, i3, i1), (i1, i3, i2), (i2, i3, i0))
    for f in range(4):
        fv[f, 0] = tet[f][0]
        fv[f, 1] = tet[f][1]
        fv[f, 2] = tet[f][2]
        alive[f] = True
        if not _plane(pts, fv[f, 0], fv[f, 1], fv[f, 2], nrm, off, tol, eps, f):
            return i0, i1, i2, i3, False
    for f in range(4):
        for j in range(3):
            a = fv[f, j]
            b = fv[f, (j + 1) % 3]
            for g in range(4):
                if g == f:
                    continue
                for k in range(3):
                    if fv[g, k] == b and fv[g, (k + 1) % 3] == a:
                        fnb[f, j] = g
    return i0, i1, i2, i3, True


@njit(cache=True, error_model="numpy")
def _alive_faces(fv, alive, nf):
    """(F, 3) int64: the vertices of the faces ``f < nf`` still alive, in order."""
    count = 0
    for f in range(nf):
        if alive[f]:
            count += 1
    out = np.empty((count, 3), dtype=np.int64)
    c = 0
    for f in range(nf):
        if alive[f]:
            out[c, 0] = fv[f, 0]
            out[c, 1] = fv[f, 1]
            out[c, 2] = fv[f, 2]
            c += 1
    return out


# ------------------------------------------------------------------- hubs
@njit(cache=True, error_model="numpy")
def build_hub(dirs, rad, pu, pv, ccw, P, shrink, margin, floor_tan, out_d, out_det, out_tris):
    """Offsets and triangles of one hub (node of degree d >= 2).

    Parameters
    ----------
    dirs : (d, 3) float64
        Unit outward directions of the struts, in canonical slot order.
    rad : (d,) float64
        Radius of each strut at this node.
    pu, pv : (d, 3) float64
        Profile frame of each strut (shared with the strut's other end).
    ccw : (d,) bool
        True when the profile order ``k = 0..P-1`` turns counter-clockwise about
        the outward direction (i.e. ``pu x pv == dirs``).
    out_d : (d,) float64, out
    out_det : (d,) int64, out
    out_tris : (d * P + 2 * d - 4, 3) int64, out
        Local vertex ids ``slot * P + k``; outward-oriented.

    Returns
    -------
    status : int
        ``HUB_OK`` or an error code.
    """
    d = dirs.shape[0]
    hub_offsets(dirs, rad, shrink, margin, floor_tan, out_d, out_det)
    n = d * P
    pts = np.empty((n, 3))
    scale = 0.0
    cosk = np.empty(P)
    sink = np.empty(P)
    for k in range(P):
        cosk[k] = np.cos(2.0 * np.pi * k / P)
        sink[k] = np.sin(2.0 * np.pi * k / P)
    for i in range(d):
        for k in range(P):
            ca = cosk[k] * rad[i]
            sa = sink[k] * rad[i]
            q = i * P + k
            for c in range(3):
                pts[q, c] = out_d[i] * dirs[i, c] + ca * pu[i, c] + sa * pv[i, c]
            scale = max(scale, np.sqrt(pts[q, 0] ** 2 + pts[q, 1] ** 2 + pts[q, 2] ** 2))
    for q in range(n):
        for c in range(3):
            pts[q, c] /= scale
    # profile by profile: consecutive points are neighbours, so the walk to
    # the first visible face is short
    order = np.arange(n)
    faces, st = convex_hull(pts, order, 1e-12, 16 * n + 64)
    if st != 0:
        faces, st = convex_hull(pts, order, 1e-12, n * n + 64)
        if st != 0:
            return HUB_HULL_FAILED
    expected = d * P + 2 * d - 4
    c = 0
    for f in range(faces.shape[0]):
        g0 = faces[f, 0] // P
        if g0 == faces[f, 1] // P and g0 == faces[f, 2] // P:
            continue
        if c >= expected:
            return HUB_BOUNDARY_MISMATCH
        out_tris[c, 0] = faces[f, 0]
        out_tris[c, 1] = faces[f, 1]
        out_tris[c, 2] = faces[f, 2]
        c += 1
    if c != expected:
        return HUB_BOUNDARY_MISMATCH
    # every profile edge must border the hub exactly once, in the right direction
    seen = np.zeros(n, dtype=np.int64)
    for f in range(expected):
        for j in range(3):
            a = out_tris[f, j]
            b = out_tris[f, (j + 1) % 3]
            if a // P != b // P:
                continue
            i = a // P
            ka = a % P
            kb = b % P
            if ccw[i]:
                if ka != (kb + 1) % P:
                    return HUB_BOUNDARY_MISMATCH
                seen[b] += 1
            else:
                if kb != (ka + 1) % P:
                    return HUB_BOUNDARY_MISMATCH
                seen[a] += 1
        # area check (in unit-scaled coordinates)
        a = out_tris[f, 0]
        b = out_tris[f, 1]
        cc = out_tris[f, 2]
        ux = pts[b, 0] - pts[a, 0]
        uy = pts[b, 1] - pts[a, 1]
        uz = pts[b, 2] - pts[a, 2]
        vx = pts[cc, 0] - pts[a, 0]
        vy = pts[cc, 1] - pts[a, 1]
        vz = pts[cc, 2] - pts[a, 2]
        ar2 = (uy * vz - uz * vy) ** 2 + (uz * vx - ux * vz) ** 2 + (ux * vy - uy * vx) ** 2
        if ar2 <= 1e-28:
            return HUB_DEGENERATE
    for q in range(n):
        if seen[q] != 1:
            return HUB_BOUNDARY_MISMATCH
    return HUB_OK


@njit(cache=True, parallel=True, error_model="numpy")
def build_hubs(
    reps,
    offsets,
    slots,
    axis,
    sign,
    frame_u,
    frame_v,
    radii,
    P,
    shrink,
    margin,
    floor_tan,
    rep_slot_start,
    rep_tri_start,
    rep_d,
    rep_det,
    rep_tris,
    rep_status,
):
    """Build the hubs of representative nodes in parallel.

    Parameters
    ----------
    reps : (R,) int64
        Representative node of each distinct hub shape.
    rep_slot_start : (R + 1,) int64
        Start of each representative's slots in ``rep_d`` / ``rep_det``.
    rep_tri_start : (R + 1,) int64
        Start of each representative's triangles in ``rep_tris``.
    rep_d : (S,) float64, out
        Profile offset of each slot.
    rep_det : (S,) int64, out
        Slot (local) that determined each offset, -1 for the floor.
    rep_tris : (T, 3) int64, out
        Local triangles (``slot * P + k``).
    rep_status : (R,) int64, out
    """
    for ri in prange(reps.shape[0]):
        n = reps[ri]
        lo = offsets[n]
        d = offsets[n + 1] - lo
        dirs = np.empty((d, 3))
        rad = np.empty(d)
        pu = np.empty((d, 3))
        pv = np.empty((d, 3))
        ccw = np.empty(d, dtype=np.bool_)
        for t in range(d):
            es = slots[lo + t]
            e = es // 2
            side = es % 2
            s = 1.0 if (sign[e] == 1) == (side == 0) else -1.0
            for c in range(3):
                dirs[t, c] = s * axis[e, c]
                pu[t, c] = frame_u[e, c]
                pv[t, c] = frame_v[e, c]
            rad[t] = radii[e, side]
            ccw[t] = s > 0.0
        s0 = rep_slot_start[ri]
        t0 = rep_tri_start[ri]
        rep_status[ri] = build_hub(
            dirs,
            rad,
            pu,
            pv,
            ccw,
            P,
            shrink,
            margin,
            floor_tan,
            rep_d[s0 : s0 + d],
            rep_det[s0 : s0 + d],
            rep_tris[t0 : rep_tri_start[ri + 1]],
        )


# --------------------------------------------------------------- assembly
@njit(cache=True, parallel=True, error_model="numpy")
def scatter_offsets(offsets, slots, node_rep, rep_slot_start, rep_d, end_offset):
    """end_offset[e, side] = profile offset of strut e at that end (0 at leaves)."""
    n_nodes = offsets.shape[0] - 1
    for n in prange(n_nodes):
        lo = offsets[n]
        d = offsets[n + 1] - lo
        if d == 1:
            es = slots[lo]
            end_offset[es // 2, es % 2] = 0.0
        elif d >= 2:
            s0 = rep_slot_start[node_rep[n]]
            for t in range(d):
                es = slots[lo + t]
                end_offset[es // 2, es % 2] = rep_d[s0 + t]


@njit(cache=True, parallel=True, error_model="numpy")
def profile_vertices(nodes, edges, axis, sign, frame_u, frame_v, radii, end_offset, P, out):
    """out[(2e + side) * P + k]: vertex k of the profile of strut e at that end."""
    m = edges.shape[0]
    for e in prange(m):
        for side in range(2):
            n = edges[e, side]
            s = float(sign[e]) if side == 0 else -float(sign[e])
            dd = end_offset[e, side] * s
            r = radii[e, side]
            base = (2 * e + side) * P
            for k in range(P):
                ang = 2.0 * np.pi * k / P
                ca = np.cos(ang) * r
                sa = np.sin(ang) * r
                for c in range(3):
                    out[base + k, c] = (
                        nodes[n, c] + dd * axis[e, c] + ca * frame_u[e, c] + sa * frame_v[e, c]
                    )


@njit(cache=True, inline="always", error_model="numpy")
def _tube(a0, a1, row, plus, P, out):
    """2P outward triangles (rows ``row`` onward) joining the rings of P vertices from ``a0``
    and from ``a1`` (``a0`` nearer the strut's first node; ``plus``: ``sign == 1``)."""
    c1, c2 = (1, 2) if plus else (2, 1)  # the other sign: the same triangles, reversed
    for k in range(P):
        k1 = (k + 1) % P
        out[row + 2 * k, 0] = a0 + k
        out[row + 2 * k, c1] = a0 + k1
        out[row + 2 * k, c2] = a1 + k1
        out[row + 2 * k + 1, 0] = a0 + k
        out[row + 2 * k + 1, c1] = a1 + k1
        out[row + 2 * k + 1, c2] = a1 + k


@njit(cache=True, parallel=True, error_model="numpy")
def cylinder_faces(sign, P, out):
    """2P side triangles per strut, outward (rows ``2 * P * e`` onward)."""
    m = sign.shape[0]
    for e in prange(m):
        _tube(2 * e * P, (2 * e + 1) * P, 2 * P * e, sign[e] == 1, P, out)


@njit(cache=True, parallel=True, error_model="numpy")
def band_faces(sign, P, xbase, bbase, out):
    """Struts with band rings (``profile="volume"``, :func:`fast_stitch.hubvolume.band_rings`).

    The band ring of end (e, side) is vertices ``xbase + (2e + side) P + k``. Rows ``2 P e``
    onward: the strut's prism between its two band rings; rows ``bbase + 2 P (2e + side)``
    onward: the band joining the hub ring ``(2e + side) P`` to the band ring."""
    m = sign.shape[0]
    for e in prange(m):
        plus = sign[e] == 1
        h0 = 2 * e * P
        h1 = h0 + P
        x0 = xbase + h0
        x1 = xbase + h1
        _tube(x0, x1, 2 * P * e, plus, P, out)
        _tube(h0, x0, bbase + 4 * P * e, plus, P, out)
        _tube(x1, h1, bbase + 4 * P * e + 2 * P, plus, P, out)


@njit(cache=True, parallel=True, error_model="numpy")
def node_faces(offsets, slots, sign, node_rep, rep_tri_start, rep_tris, face_start, P, out):
    """Hub triangles (degree >= 2) and end caps (degree 1) of every node."""
    n_nodes = offsets.shape[0] - 1
    for n in prange(n_nodes):
        lo = offsets[n]
        d = offsets[n + 1] - lo
        row = face_start[n]
        if d == 1:
            es = slots[lo]
            e = es // 2
            side = es % 2
            base = es * P
            ccw = (sign[e] == 1) == (side == 0)
            for k in range(1, P - 1):
                out[row, 0] = base
                if ccw:
                    out[row, 1] = base + k + 1
                    out[row, 2] = base + k
                else:
                    out[row, 1] = base + k
                    out[row, 2] = base + k + 1
                row += 1
        elif d >= 2:
            r = node_rep[n]
            for f in range(rep_tri_start[r], rep_tri_start[r + 1]):
                for j in range(3):
                    q = rep_tris[f, j]
                    out[row, j] = slots[lo + q // P] * P + q % P
                row += 1


@njit(cache=True, parallel=True, error_model="numpy")
def signed_volume(vertices, faces):
    """Signed volume of a closed triangle mesh (divergence theorem)."""
    total = 0.0
    for f in prange(faces.shape[0]):
        a = faces[f, 0]
        b = faces[f, 1]
        c = faces[f, 2]
        total += (
            vertices[a, 0] * (vertices[b, 1] * vertices[c, 2] - vertices[b, 2] * vertices[c, 1])
            - vertices[a, 1] * (vertices[b, 0] * vertices[c, 2] - vertices[b, 2] * vertices[c, 0])
            + vertices[a, 2] * (vertices[b, 0] * vertices[c, 1] - vertices[b, 1] * vertices[c, 0])
        )
    return total / 6.0


@njit(cache=True, parallel=True, error_model="numpy")
def stl_records(vertices, faces, start, stop, out):
    """Fill binary-STL records for faces[start:stop].

    out : (stop - start, 12) float32
        Normal (3) then the three vertices (9), in single precision.
    Returns the number of records whose triangle has zero area in float32.
    """
    bad = 0
    for i in prange(stop - start):
        f = start + i
        for j in range(3):
            v = faces[f, j]
            for c in range(3):
                out[i, 3 + 3 * j + c] = np.float32(vertices[v, c])
        ux = float(out[i, 6]) - float(out[i, 3])
        uy = float(out[i, 7]) - float(out[i, 4])
        uz = float(out[i, 8]) - float(out[i, 5])
        vx = float(out[i, 9]) - float(out[i, 3])
        vy = float(out[i, 10]) - float(out[i, 4])
        vz = float(out[i, 11]) - float(out[i, 5])
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        nn = np.sqrt(nx * nx + ny * ny + nz * nz)
        if nn > 0.0:
            out[i, 0] = np.float32(nx / nn)
            out[i, 1] = np.float32(ny / nn)
            out[i, 2] = np.float32(nz / nn)
        else:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
            bad += 1
    return bad


# -------------------------------------------------------------- clearance
@njit(cache=True, inline="always", error_model="numpy")
def _dot3(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@njit(cache=True, inline="always", error_model="numpy")
def _seg_seg_dist2(sa, sb, i, j):
    """Squared distance between segments sa[i]-sb[i] and sa[j]-sb[j] (scalar arithmetic)."""
    d1x = sb[i, 0] - sa[i, 0]
    d1y = sb[i, 1] - sa[i, 1]
    d1z = sb[i, 2] - sa[i, 2]
    d2x = sb[j, 0] - sa[j, 0]
    d2y = sb[j, 1] - sa[j, 1]
    d2z = sb[j, 2] - sa[j, 2]
    rx = sa[i, 0] - sa[j, 0]
    ry = sa[i, 1] - sa[j, 1]
    rz = sa[i, 2] - sa[j, 2]
    a = _dot3(d1x, d1y, d1z, d1x, d1y, d1z)
    e = _dot3(d2x, d2y, d2z, d2x, d2y, d2z)
    f = _dot3(d2x, d2y, d2z, rx, ry, rz)
    s = 0.0
    t = 0.0
    if a <= 1e-300 and e <= 1e-300:
        pass
    elif a <= 1e-300:
        t = min(1.0, max(0.0, f / e))
    else:
        c = _dot3(d1x, d1y, d1z, rx, ry, rz)
        if e <= 1e-300:
            s = min(1.0, max(0.0, -c / a))
        else:
            b = _dot3(d1x, d1y, d1z, d2x, d2y, d2z)
            den = a * e - b * b
            s = min(1.0, max(0.0, (b * f - c * e) / den)) if den > 1e-300 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(1.0, max(0.0, -c / a))
            elif t > 1.0:
                t = 1.0
                s = min(1.0, max(0.0, (b - c) / a))
    wx = rx + d1x * s - d2x * t
    wy = ry + d1y * s - d2y * t
    wz = rz + d1z * s - d2z * t
    return _dot3(wx, wy, wz, wx, wy, wz)


@njit(cache=True, inline="always", error_model="numpy")
def _elem_rows(el, m, edges, degree, face_start, P, bbase, rows):
    """Face rows of element el (struts 0..m-1 incl. leaf caps and bands from row ``bbase``
    when ``bbase >= 0``; hubs m + node)."""
    c = 0
    if el < m:
        for k in range(2 * P):
            rows[c] = 2 * P * el + k
            c += 1
        if bbase >= 0:
            for k in range(4 * P):
                rows[c] = bbase + 4 * P * el + k
                c += 1
        for side in range(2):
            n = edges[el, side]
            if degree[n] == 1:
                for k in range(P - 2):
                    rows[c] = face_start[n] + k
                    c += 1
    else:
        n = el - m
        d = degree[n]
        for k in range(d * P + 2 * d - 4):
            rows[c] = face_start[n] + k
            c += 1
    return c


@njit(cache=True, inline="always", error_model="numpy")
def _excluded(i, j, m, edges, offsets, inc_edge):
    """Pairs whose disjointness the construction already guarantees."""
    if i < m and j < m:
        return (
            edges[i, 0] == edges[j, 0]
            or edges[i, 0] == edges[j, 1]
            or edges[i, 1] == edges[j, 0]
            or edges[i, 1] == edges[j, 1]
        )
    if i < m:
        n = j - m
        return edges[i, 0] == n or edges[i, 1] == n
    if j < m:
        n = i - m
        return edges[j, 0] == n or edges[j, 1] == n
    a = i - m
    b = j - m
    for t in range(offsets[a], offsets[a + 1]):
        e = inc_edge[t]
        if edges[e, 0] == b or edges[e, 1] == b:
            return True
    return False


@njit(cache=True, inline="always", error_model="numpy")
def _strut_capsule(
    nodes, edges, radii, scale, end_offset, e, u0, u1, u2, k, seg_a, seg_b, rad
):  # fmt: skip
    """Row ``k`` of the clearance elements: strut ``e``'s capsule, its axis between its
    profile centres (``end_offset`` from its nodes along the unit direction ``u``), its
    radius the larger end radius times ``scale`` (shared by :func:`clearance_elements` and
    ``_fit_kernels.element_boxes``; ``max(a, b) * s == max(a * s, b * s)`` in floating
    point, as rounding is monotone)."""
    a = edges[e, 0]
    b = edges[e, 1]
    for c in range(3):
        uc = u0 if c == 0 else (u1 if c == 1 else u2)
        seg_a[k, c] = nodes[a, c] + end_offset[e, 0] * uc
        seg_b[k, c] = nodes[b, c] - end_offset[e, 1] * uc
    rad[k] = max(radii[e, 0], radii[e, 1]) * scale


@njit(cache=True, inline="always", error_model="numpy")
def _joint_ball(
    nodes, radii, scale, end_offset, offsets, inc_edge, inc_side, n, k, seg_a, seg_b, rad
):  # fmt: skip
    """Row ``k`` of the clearance elements: the ball of the joint at node ``n`` (degenerate
    axis at the node; radius the distance to its farthest profile vertex, -1 below degree
    2; profile radii are ``radii * scale``)."""
    for c in range(3):
        seg_a[k, c] = nodes[n, c]
        seg_b[k, c] = nodes[n, c]
    r = -1.0
    if offsets[n + 1] - offsets[n] >= 2:
        for t in range(offsets[n], offsets[n + 1]):
            e = inc_edge[t]
            s = inc_side[t]
            r = max(r, np.sqrt(end_offset[e, s] ** 2 + (radii[e, s] * scale) ** 2))
    rad[k] = r


@njit(cache=True, inline="always", error_model="numpy")
def _element_box(seg_a, seg_b, rad, pad, k, lo, hi):
    """Box of element row ``k`` padded by ``pad * rad[k]``; returns its largest side."""
    w = 0.0
    for c in range(3):
        a = min(seg_a[k, c], seg_b[k, c]) - pad * rad[k]
        b = max(seg_a[k, c], seg_b[k, c]) + pad * rad[k]
        lo[k, c] = a
        hi[k, c] = b
        w = max(w, b - a)
    return w


@njit(cache=True, parallel=True, error_model="numpy")
def clearance_elements(
    nodes, edges, radii, end_offset, unit, offsets, inc_edge, inc_side, pad,
    seg_a, seg_b, rad, lo, hi, extent,
):  # fmt: skip
    """Bounding capsules (struts) and balls (joints) of the clearance checks.

    Parameters
    ----------
    end_offset : (M, 2) float64
        Profile offset of each strut end.
    unit : (M, 3) float64
        Unit strut directions.
    pad : float
        Boxes are padded by ``pad * rad``.
    seg_a, seg_b : (M + N, 3) float64, out
        Element axes: struts ``0..M-1`` between their profile centres, joints
        ``M + n`` degenerate at node n.
    rad : (M + N,) float64, out
        Larger end radius of a strut; distance from node n to its farthest
        profile vertex for a joint, -1 when the node has degree < 2 (no joint).
    lo, hi : (M + N, 3) float64, out
    extent : (M + N,) float64, out
        Largest side of each box.
    """
    m = edges.shape[0]
    n_nodes = nodes.shape[0]
    for e in prange(m):
        _strut_capsule(
            nodes, edges, radii, 1.0, end_offset, e, unit[e, 0], unit[e, 1], unit[e, 2], e,
            seg_a, seg_b, rad,
        )  # fmt: skip
    for n in prange(n_nodes):
        _joint_ball(nodes, radii, 1.0, end_offset, offsets, inc_edge, inc_side, n, m + n,
                    seg_a, seg_b, rad)  # fmt: skip
    for i in prange(m + n_nodes):
        extent[i] = _element_box(seg_a, seg_b, rad, pad, i, lo, hi)


@njit(cache=True, inline="always", error_model="numpy")
def _cell_span(lo, hi, i, origin, cell, dims, a):
    """First and last grid cell along axis a covered by box i."""
    top = dims[a] - 1
    first = min(top, max(0, int((lo[i, a] - origin[a]) / cell)))
    last = min(top, max(0, int((hi[i, a] - origin[a]) / cell)))
    return first, last


@njit(cache=True, error_model="numpy")
def element_grid(lo, hi, rad, cell, origin, dims):
    """Counting sort of the elements (``rad >= 0``) into the grid cells their boxes touch.

    Returns
    -------
    count : (cells + 1,) int64
        Members of cell c are ``members[count[c]:count[c + 1]]``.
    members : (K,) int64
    """
    n_cells = dims[0] * dims[1] * dims[2]
    count = np.zeros(n_cells + 1, dtype=np.int64)
    members = np.empty(0, dtype=np.int64)
    _grid_sweep(lo, hi, rad, cell, origin, dims, 0, dims[0] - 1, count, members, count, False)
    for c in range(n_cells):
        count[c + 1] += count[c]
    members = np.empty(count[n_cells], dtype=np.int64)
    _grid_sweep(
        lo, hi, rad, cell, origin, dims, 0, dims[0] - 1, count, members, count[:-1].copy(), True
    )
    return count, members


@njit(cache=True, inline="always", error_model="numpy")
def _grid_sweep(lo, hi, rad, cell, origin, dims, x0, x1, count, members, fill, write):
    """One sweep of the counting sort of :func:`element_grid` over the grid cells with
    ``x0 <= x <= x1`` (local cell ``((x - x0) * ny + y) * nz + z``): count the members of
    each cell in ``count[c + 1]``, or (``write``) put them at ``members[fill[c]]``
    (shared with ``_fit_kernels.slab_grid``)."""
    ny, nz = dims[1], dims[2]
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
                    if write:
                        members[fill[c]] = i
                        fill[c] += 1
                    else:
                        count[c + 1] += 1


@njit(cache=True, inline="always", error_model="numpy")
def _candidate_d2(
    i, j, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets, inc_edge, scale,
):  # fmt: skip
    """Squared axis distance of elements i, j met in grid cell c, or -1 to skip the pair.

    Skipped: boxes apart, pairs met in another cell (each pair is tested once, in
    the cell holding the low corner of the boxes' overlap), pairs whose
    disjointness the construction guarantees, and pairs at least
    ``scale * (rad_i + rad_j)`` apart.
    """
    return _pair_d2(
        i, j, i, j, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets,
        inc_edge, scale,
    )  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def _pair_d2(
    i, j, gi, gj, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets, inc_edge,
    scale,
):  # fmt: skip
    """:func:`_candidate_d2` of rows ``i``, ``j`` of the element arrays, which hold the
    elements ``gi``, ``gj`` (their ids for the shared-node exclusion; ``c`` is a cell of the
    whole grid). Shared with ``_fit_kernels.slab_pairs``, whose rows are one slab's."""
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
    ga = gi if i < j else gj
    gb = gj if i < j else gi
    if _excluded(ga, gb, m, edges, offsets, inc_edge):
        return -1.0
    reach = scale * (rad[a] + rad[b])
    d2 = _seg_seg_dist2(seg_a, seg_b, a, b)
    if d2 >= reach * reach:
        return -1.0
    return d2


@njit(cache=True, parallel=True, error_model="numpy")
def clearance(
    vertices, faces, edges, degree, offsets, inc_edge, face_start, P, bbase,
    seg_a, seg_b, rad, lo, hi, cell, origin, dims, max_rows, found,
):  # fmt: skip
    """Find overlapping non-incident elements (struts, hubs) of a stitched mesh.

    Elements ``0..m-1`` are struts: capsules ``seg_a[i]``-``seg_b[i]`` of radius
    ``rad[i]``; elements ``m + n`` are hubs: balls around ``seg_a`` of radius
    ``rad`` (``seg_b == seg_a``); elements with ``rad < 0`` are skipped. Pairs
    are found with a uniform grid over the boxes ``lo``/``hi``, kept when their
    bounding capsules/balls overlap, and confirmed with an exact
    triangle/triangle test.

    found : (cells, 2) int64, out
        For each grid cell (flattened), the first confirmed pair or -1.
    """
    m = edges.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    count, members = element_grid(lo, hi, rad, cell, origin, dims)
    for c in prange(n_cells):
        found[c, 0] = -1
        found[c, 1] = -1
        for u in range(count[c], count[c + 1]):
            i = members[u]
            for w in range(u + 1, count[c + 1]):
                j = members[w]
                d2 = _candidate_d2(
                    i, j, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets,
                    inc_edge, 1.0,
                )  # fmt: skip
                if d2 < 0.0:
                    continue
                a = min(i, j)
                b = max(i, j)
                rows_i = np.empty(max_rows, dtype=np.int64)
                rows_j = np.empty(max_rows, dtype=np.int64)
                na = _elem_rows(a, m, edges, degree, face_start, P, bbase, rows_i)
                nb = _elem_rows(b, m, edges, degree, face_start, P, bbase, rows_j)
                hit = False
                for p in range(na):
                    fa = rows_i[p]
                    for q in range(nb):
                        fb = rows_j[q]
                        if tri_tri(
                            vertices, faces[fa, 0], faces[fa, 1], faces[fa, 2],
                            faces[fb, 0], faces[fb, 1], faces[fb, 2],
                        ):  # fmt: skip
                            hit = True
                            break
                    if hit:
                        break
                if hit and found[c, 0] == -1:
                    found[c, 0] = a
                    found[c, 1] = b
