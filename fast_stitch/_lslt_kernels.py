"""Numba kernels of the LSLT stitcher (Chougrani et al. 2017), see :mod:`fast_stitch.lslt`.

Arrays and scalars only. Conventions:

* a node's struts are its *slots* ``0..d-1`` with unit outward directions
  ``dirs`` and radii ``rad``;
* the node structure is the normal fan of ``conv({0} U {dirs})``: point 0 is
  the origin (the "hole", i.e. the part of the node sphere that no strut
  covers), point ``j + 1`` is slot ``j``; facets are maximal coplanar point
  sets, stored as convex polygons ordered counter-clockwise seen from outside;
* every section (and the hole boundary) is listed counter-clockwise seen from
  outside, i.e. around the slot's outward direction.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fast_stitch._predicates import tri_tri

ST_OK = 0
ST_DEGENERATE = 1  # no facets / a point missing from the hull
ST_TOPOLOGY = 2  # inconsistent facet polygons
ST_ARC = 3  # an arc of zero angular length or a non-monotone section
ST_HOLE = 4  # hole barycentre undefined
ST_CAPACITY = 5

TWO_PI = 2.0 * np.pi


# ------------------------------------------------------------------ helpers
@njit(cache=True, inline="always", error_model="numpy")
def _frame(dx, dy, dz):
    """Orthonormal (e1, e2) with e1 x e2 = d (Duff et al. 2017)."""
    sg = 1.0 if dz >= 0.0 else -1.0
    aa = -1.0 / (sg + dz)
    bb = dx * dy * aa
    e1 = np.array([1.0 + sg * dx * dx * aa, sg * bb, -sg * dx])
    e2 = np.array([bb, sg + dy * dy * aa, -dy])
    return e1, e2


@njit(cache=True, inline="always", error_model="numpy")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always", error_model="numpy")
def _az(x, e1, e2):
    a = np.arctan2(_dot(x, e2), _dot(x, e1))
    if a < 0.0:
        a += TWO_PI
    return a


@njit(cache=True, error_model="numpy")
def arc_segments(span, step):
    """Segments needed so that no angular gap exceeds ``step``."""
    m = int(np.ceil(span / step - 1e-9))
    return max(1, m)


# ------------------------------------------------------------ node structure
@njit(cache=True, error_model="numpy")
def node_structure(dirs, rad, P, eps, mitre):
    """Vertices, sections and hole fan of one node.

    Steps: the facets of ``conv({0} U dirs)`` (:func:`_hull_facets`,
    :func:`_maximal_facets`), their polygons (:func:`_facet_polygons`), one vertex
    per facet (:func:`_facet_vertices`), the sections around every slot and the hole
    boundary (:func:`_sections`), the hole fan (:func:`_hole_fan`).

    Parameters
    ----------
    dirs : (d, 3) float64
        Unit outward strut directions, d >= 2, pairwise non-parallel.
    rad : (d,) float64
        Strut radius at this node.
    P : int
        Angular resolution: no two consecutive vertices of a section are more
        than ``2 pi / P`` apart in azimuth around the strut.
    eps : float
        Coplanarity tolerance of the hull of ``{0} U dirs`` (unit scale).
    mitre : bool
        Degree-2 node joined by one shared section on the bisecting plane
        (no hole; used when the mitre is within the chord error).

    Returns
    -------
    verts : (V, 3) float64
        Vertex offsets from the node.
    sec_ptr : (d + 1,) int64
    sec_ids : (S,) int64
        Section of slot j: ``sec_ids[sec_ptr[j]:sec_ptr[j + 1]]`` (local vertex
        ids, counter-clockwise around ``dirs[j]``).
    fan : (H, 3) int64
        Hole triangles (local ids), outward.
    status : int
    """
    d = dirs.shape[0]
    empty_v = np.zeros((0, 3))
    empty_i = np.zeros(0, dtype=np.int64)
    empty_f = np.zeros((0, 3), dtype=np.int64)
    if mitre:
        verts, sec_ptr, sec_ids = _mitre_structure(dirs, rad, P)
        return verts, sec_ptr, sec_ids, empty_f, ST_OK
    n = d + 1
    q = np.zeros((n, 3))
    for j in range(d):
        for c in range(3):
            q[j + 1, c] = dirs[j, c]
    fn, foff, fmask, nf, status = _hull_facets(q, eps)
    if status != ST_OK:
        return empty_v, empty_i, empty_i, empty_f, status
    keep = _maximal_facets(fn, fmask, nf)
    poly_ptr, poly, emap, hole, status = _facet_polygons(q, fn, fmask, keep, nf, eps)
    if status != ST_OK:
        return empty_v, empty_i, empty_i, empty_f, status
    cap_v = nf + 1 + 2 * (d + 1) * (P + 4) + 8 * n
    verts, fvid, nv, status = _facet_vertices(fn, foff, keep, poly_ptr, poly, rad, nf, cap_v)
    if status != ST_OK:
        return empty_v, empty_i, empty_i, empty_f, status
    sec_ptr, sec_ids, ns, hole_ids, nh, nv, status = _sections(
        dirs, rad, P, hole, verts, nv, fvid, poly_ptr, poly, emap, nf
    )
    if status != ST_OK:
        return empty_v, empty_i, empty_i, empty_f, status
    fan, nv, status = _hole_fan(verts, nv, hole_ids, nh, rad, hole)
    if status != ST_OK:
        return empty_v, empty_i, empty_i, empty_f, status
    return verts[:nv].copy(), sec_ptr, sec_ids[:ns].copy(), fan, ST_OK


@njit(cache=True, error_model="numpy")
def _mitre_structure(dirs, rad, P):
    """One section on the bisecting plane of a degree-2 node, shared by both struts.

    Parameters
    ----------
    dirs : (2, 3) float64
    rad : (2,) float64
    P : int

    Returns
    -------
    verts : (P, 3) float64
    sec_ptr : (3,) int64
    sec_ids : (2 P,) int64
        The loop counter-clockwise around ``dirs[0]``, then around ``dirs[1]``.
    """
    step = TWO_PI / P
    e1, e2 = _frame(dirs[0, 0], dirs[0, 1], dirs[0, 2])
    nrm = dirs[0] - dirs[1]
    nd = _dot(nrm, dirs[0])
    rs = max(rad[0], rad[1])
    verts = np.empty((P, 3))
    for k in range(P):
        ph = step * k
        e = np.cos(ph) * e1 + np.sin(ph) * e2
        t = -rs * _dot(nrm, e) / nd
        for c in range(3):
            verts[k, c] = rs * e[c] + t * dirs[0, c]
    sec_ptr = np.array([0, P, 2 * P], dtype=np.int64)
    sec_ids = np.empty(2 * P, dtype=np.int64)
    for k in range(P):
        sec_ids[k] = k
        sec_ids[P + k] = P - 1 - k
    return verts, sec_ptr, sec_ids


@njit(cache=True, error_model="numpy")
def _hull_facets(q, eps):
    """Supporting planes of ``conv(q)`` through three points, one per point set.

    Parameters
    ----------
    q : (n, 3) float64
        The origin (point 0) and the unit directions, n <= 64.
    eps : float
        Coplanarity tolerance.

    Returns
    -------
    fn : (cap, 3) float64
        Unit outward normals (the first ``nf`` rows are set).
    foff : (cap,) float64
        Offsets: the plane is ``fn[f] . x == foff[f]``.
    fmask : (cap,) uint64
        Bit mask of the points within ``eps`` of the plane.
    nf : int
    status : int
        ``ST_CAPACITY`` or ``ST_DEGENERATE`` (no facet) on failure.
    """
    n = q.shape[0]
    cap = 4 * n + 8
    fn = np.empty((cap, 3))
    foff = np.empty(cap)
    fmask = np.empty(cap, dtype=np.uint64)
    nf = 0
    one = np.uint64(1)
    for a in range(n):
        for b in range(a + 1, n):
            for c in range(b + 1, n):
                u = q[b] - q[a]
                w = q[c] - q[a]
                nx = u[1] * w[2] - u[2] * w[1]
                ny = u[2] * w[0] - u[0] * w[2]
                nz = u[0] * w[1] - u[1] * w[0]
                nn = np.sqrt(nx * nx + ny * ny + nz * nz)
                if nn < 1e-10:
                    continue
                for sgn in (1.0, -1.0):
                    vx = sgn * nx / nn
                    vy = sgn * ny / nn
                    vz = sgn * nz / nn
                    off = vx * q[a, 0] + vy * q[a, 1] + vz * q[a, 2]
                    ok = True
                    mask = np.uint64(0)
                    for m in range(n):
                        h = vx * q[m, 0] + vy * q[m, 1] + vz * q[m, 2] - off
                        if h > eps:
                            ok = False
                            break
                        if h >= -eps:
                            mask |= one << np.uint64(m)
                    if not ok:
                        continue
                    dup = False
                    for f in range(nf):
                        if fmask[f] == mask and (
                            fn[f, 0] * vx + fn[f, 1] * vy + fn[f, 2] * vz > 0.0
                        ):
                            dup = True
                            break
                    if dup:
                        continue
                    if nf >= cap:
                        return fn, foff, fmask, nf, ST_CAPACITY
                    fn[nf, 0] = vx
                    fn[nf, 1] = vy
                    fn[nf, 2] = vz
                    foff[nf] = off
                    fmask[nf] = mask
                    nf += 1
    if nf == 0:
        return fn, foff, fmask, nf, ST_DEGENERATE
    return fn, foff, fmask, nf, ST_OK


@njit(cache=True, error_model="numpy")
def _maximal_facets(fn, fmask, nf):
    """(nf,) bool: facets whose point set is not a strict subset of a facet of about the
    same normal (``fn``, ``fmask`` from :func:`_hull_facets`; eps inconsistencies)."""
    keep = np.ones(nf, dtype=np.bool_)
    for f in range(nf):
        for g in range(nf):
            if f != g and keep[g] and fmask[f] != fmask[g] and (fmask[f] & fmask[g]) == fmask[f]:
                if fn[f, 0] * fn[g, 0] + fn[f, 1] * fn[g, 1] + fn[f, 2] * fn[g, 2] > 0.5:
                    keep[f] = False
                    break
    return keep


@njit(cache=True, error_model="numpy")
def _facet_polygons(q, fn, fmask, keep, nf, eps):
    """Convex polygons of the kept facets, counter-clockwise seen from outside.

    Parameters
    ----------
    q : (n, 3) float64
    fn : (cap, 3) float64
    fmask : (cap,) uint64
    keep : (nf,) bool
    nf : int
    eps : float

    Returns
    -------
    poly_ptr : (nf + 1,) int64
    poly : (nf * n,) int64
        Polygon of facet f: ``poly[poly_ptr[f]:poly_ptr[f + 1]]`` (point indices; the
        origin only where it is a corner).
    emap : (n, n) int64
        Facet of each directed polygon edge ``(a, b)``, -1 if none.
    hole : bool
        The origin is a corner of some facet (part of the node sphere is uncovered).
    status : int
        ``ST_TOPOLOGY`` (inconsistent polygons) or ``ST_DEGENERATE`` (a slot is not a
        corner) on failure.
    """
    n = q.shape[0]
    one = np.uint64(1)
    poly_ptr = np.zeros(nf + 1, dtype=np.int64)
    poly = np.empty(nf * n, dtype=np.int64)
    emap = np.full((n, n), -1, dtype=np.int64)
    pts = np.empty(n, dtype=np.int64)
    ang = np.empty(n)
    is_vertex = np.zeros(n, dtype=np.bool_)
    for f in range(nf):
        poly_ptr[f + 1] = poly_ptr[f]
        if not keep[f]:
            continue
        v = fn[f]
        e1, e2 = _frame(v[0], v[1], v[2])
        k = 0
        cx = 0.0
        cy = 0.0
        cz = 0.0
        for m in range(n):
            if (fmask[f] >> np.uint64(m)) & one:
                pts[k] = m
                cx += q[m, 0]
                cy += q[m, 1]
                cz += q[m, 2]
                k += 1
        if k < 3:
            return poly_ptr, poly, emap, False, ST_TOPOLOGY
        cx /= k
        cy /= k
        cz /= k
        for i in range(k):
            m = pts[i]
            rx = q[m, 0] - cx
            ry = q[m, 1] - cy
            rz = q[m, 2] - cz
            ang[i] = np.arctan2(
                rx * e2[0] + ry * e2[1] + rz * e2[2], rx * e1[0] + ry * e1[1] + rz * e1[2]
            )
        _sort_by_angle(pts, ang, k)
        kk = _drop_inner_origin(q, v, pts, k, eps, poly[poly_ptr[f] :])
        poly_ptr[f + 1] = poly_ptr[f] + kk
        for i in range(kk):
            a = poly[poly_ptr[f] + i]
            b = poly[poly_ptr[f] + (i + 1) % kk]
            if emap[a, b] != -1:
                return poly_ptr, poly, emap, False, ST_TOPOLOGY
            emap[a, b] = f
            is_vertex[a] = True
    for a in range(n):
        for b in range(n):
            if emap[a, b] >= 0 and emap[b, a] < 0:
                return poly_ptr, poly, emap, False, ST_TOPOLOGY
    for m in range(1, n):
        if not is_vertex[m]:
            return poly_ptr, poly, emap, False, ST_DEGENERATE
    return poly_ptr, poly, emap, is_vertex[0], ST_OK


@njit(cache=True, inline="always", error_model="numpy")
def _sort_by_angle(pts, ang, k):
    """Insertion sort of ``pts[:k]`` (int64) by ``ang[:k]`` (float64), in place."""
    for i in range(1, k):
        j = i
        while j > 0 and ang[j] < ang[j - 1]:
            ta = ang[j]
            ang[j] = ang[j - 1]
            ang[j - 1] = ta
            tp = pts[j]
            pts[j] = pts[j - 1]
            pts[j - 1] = tp
            j -= 1


@njit(cache=True, inline="always", error_model="numpy")
def _drop_inner_origin(q, v, pts, k, eps, out):
    """Copy the facet polygon ``pts[:k]`` (normal ``v``) to ``out``, without the origin
    where it is not a corner (the only point that may be non-extreme); returns its size."""
    kk = 0
    for i in range(k):
        m = pts[i]
        if m == 0:
            a = pts[(i - 1 + k) % k]
            b = pts[(i + 1) % k]
            ux = q[0, 0] - q[a, 0]
            uy = q[0, 1] - q[a, 1]
            uz = q[0, 2] - q[a, 2]
            wx = q[b, 0] - q[0, 0]
            wy = q[b, 1] - q[0, 1]
            wz = q[b, 2] - q[0, 2]
            turn = (
                (uy * wz - uz * wy) * v[0] + (uz * wx - ux * wz) * v[1] + (ux * wy - uy * wx) * v[2]
            )
            if turn <= eps:
                continue
        out[kk] = m
        kk += 1
    return kk


@njit(cache=True, error_model="numpy")
def _facet_vertices(fn, foff, keep, poly_ptr, poly, rad, nf, cap_v):
    """One vertex per facet: its normal scaled to the largest radius it needs.

    A facet through the node gives a mandatory vertex (Eq. 1) at the radius of its
    struts; any other facet gives a Voronoi vertex, equidistant from its struts.

    Parameters
    ----------
    fn : (cap, 3) float64
    foff : (cap,) float64
    keep : (nf,) bool
    poly_ptr, poly : int64
        Facet polygons (see :func:`_facet_polygons`).
    rad : (d,) float64
    nf, cap_v : int
        Facets, vertex capacity.

    Returns
    -------
    verts : (cap_v, 3) float64
        The first ``nv`` rows are set.
    fvid : (nf,) int64
        Vertex of each facet, -1 for dropped facets.
    nv : int
    status : int
    """
    verts = np.empty((cap_v, 3))
    nv = 0
    fvid = np.full(nf, -1, dtype=np.int64)
    for f in range(nf):
        if not keep[f] or poly_ptr[f + 1] == poly_ptr[f]:
            continue
        s = 0.0
        if foff[f] <= 1e-9:  # plane through the node: mandatory vertex (Eq. 1)
            for i in range(poly_ptr[f], poly_ptr[f + 1]):
                m = poly[i]
                if m > 0:
                    s = max(s, rad[m - 1])
        else:  # Voronoi vertex: equidistant from its struts
            sin_t = np.sqrt(max(0.0, 1.0 - foff[f] * foff[f]))
            if sin_t < 1e-12:
                return verts, fvid, nv, ST_DEGENERATE
            for i in range(poly_ptr[f], poly_ptr[f + 1]):
                m = poly[i]
                if m > 0:
                    s = max(s, rad[m - 1] / sin_t)
        for c in range(3):
            verts[nv, c] = s * fn[f, c]
        fvid[f] = nv
        nv += 1
    return verts, fvid, nv, ST_OK


@njit(cache=True, error_model="numpy")
def _sections(dirs, rad, P, hole, verts, nv, fvid, poly_ptr, poly, emap, nf):
    """Sections of the slots and boundary of the hole, sampling the arcs between facets.

    Around each point ``x`` (slots first, then the origin if ``hole``), the facets
    are visited in order (:func:`_facet_cycle`); between two consecutive facet
    vertices lies the arc shared with neighbour ``y``, sampled once by its owner
    (:func:`_sample_arc`) and walked backwards by the other side.

    Parameters
    ----------
    dirs : (d, 3) float64
    rad : (d,) float64
    P : int
    hole : bool
    verts : (cap_v, 3) float64
        Vertex buffer, ``nv`` rows set (facet vertices); arc samples are appended.
    nv : int
    fvid : (nf,) int64
    poly_ptr, poly, emap : int64
        Facet polygons (see :func:`_facet_polygons`).
    nf : int

    Returns
    -------
    sec_ptr : (d + 1,) int64
    sec_ids : (cap,) int64
        Sections (first ``ns`` entries set).
    ns : int
    hole_ids : (cap,) int64
        Hole boundary, counter-clockwise seen from outside (first ``nh`` set).
    nh : int
    nv : int
        Vertices now in ``verts``.
    status : int
    """
    d = dirs.shape[0]
    n = d + 1
    step = TWO_PI / P
    arc_start = np.full((n, n), -1, dtype=np.int64)
    arc_cnt = np.zeros((n, n), dtype=np.int64)
    sec_ptr = np.zeros(d + 1, dtype=np.int64)
    sec_cap = 2 * (d + 1) * (P + 4) + 8 * n + 4 * nf
    sec_ids = np.empty(sec_cap, dtype=np.int64)
    ns = 0
    cyc_f = np.empty(nf + 1, dtype=np.int64)
    cyc_y = np.empty(nf + 1, dtype=np.int64)
    hole_ids = np.empty(sec_cap, dtype=np.int64)
    nh = 0
    e1 = np.zeros(3)
    e2 = np.zeros(3)
    j = 0
    for x in range(1, n + 1):
        xx = x if x < n else 0  # slots first, the hole (point 0) last
        if xx == 0 and not hole:
            break
        mcyc, status = _facet_cycle(xx, poly_ptr, poly, emap, nf, cyc_f, cyc_y)
        if status != ST_OK:
            return sec_ptr, sec_ids, ns, hole_ids, nh, nv, status
        if xx > 0:
            j = xx - 1
            e1, e2 = _frame(dirs[j, 0], dirs[j, 1], dirs[j, 2])
        # ccw: vertices F_0, F_{m-1}, ..., arc F_{-s} -> F_{-s-1} across y_{-s-1}
        start_ns = ns
        for s in range(mcyc):
            fa = cyc_f[(-s) % mcyc]
            fb = cyc_f[(-s - 1) % mcyc]
            y = cyc_y[(-s - 1) % mcyc]
            if xx > 0:
                sec_ids[ns] = fvid[fa]
                ns += 1
            else:
                hole_ids[nh] = fvid[fa]
                nh += 1
            lo = min(xx, y)
            hi = max(xx, y)
            own = (xx == lo and lo > 0) or (lo == 0 and xx == hi)
            if own:
                arc_start[lo, hi] = nv
                m, nv, status = _sample_arc(
                    dirs, rad, j, y, e1, e2, step, verts, fvid[fa], fvid[fb], nv
                )
                if status != ST_OK:
                    return sec_ptr, sec_ids, ns, hole_ids, nh, nv, status
                arc_cnt[lo, hi] = m - 1
                for i in range(m - 1):
                    sec_ids[ns] = arc_start[lo, hi] + i
                    ns += 1
            else:
                st = arc_start[lo, hi]
                if st < 0:
                    return sec_ptr, sec_ids, ns, hole_ids, nh, nv, ST_TOPOLOGY
                for i in range(arc_cnt[lo, hi] - 1, -1, -1):
                    if xx > 0:
                        sec_ids[ns] = st + i
                        ns += 1
                    else:
                        hole_ids[nh] = st + i
                        nh += 1
        if xx > 0:
            sec_ptr[j + 1] = ns
            if not _turns_once(verts, sec_ids[start_ns:ns], e1, e2):
                return sec_ptr, sec_ids, ns, hole_ids, nh, nv, ST_ARC
    return sec_ptr, sec_ids, ns, hole_ids, nh, nv, ST_OK


@njit(cache=True, error_model="numpy")
def _facet_cycle(xx, poly_ptr, poly, emap, nf, cyc_f, cyc_y):
    """The facets around point ``xx``, clockwise seen from outside.

    Fills ``cyc_f[:mcyc]`` (facets) and ``cyc_y[:mcyc]`` (the point after ``xx`` in each
    facet's polygon, i.e. the neighbour across the next seam); returns ``(mcyc, status)``.
    """
    f0 = -1
    for f in range(nf):
        for i in range(poly_ptr[f], poly_ptr[f + 1]):
            if poly[i] == xx:
                f0 = f
                break
        if f0 >= 0:
            break
    if f0 < 0:
        return 0, ST_DEGENERATE
    mcyc = 0
    f = f0
    while True:
        kf = poly_ptr[f + 1] - poly_ptr[f]
        y = -1
        for i in range(kf):
            if poly[poly_ptr[f] + i] == xx:
                y = poly[poly_ptr[f] + (i + 1) % kf]
                break
        if mcyc >= nf:
            return mcyc, ST_TOPOLOGY
        cyc_f[mcyc] = f
        cyc_y[mcyc] = y
        mcyc += 1
        f = emap[y, xx]
        if f < 0:
            return mcyc, ST_TOPOLOGY
        if f == f0:
            break
    return mcyc, ST_OK


@njit(cache=True, error_model="numpy")
def _sample_arc(dirs, rad, j, y, e1, e2, step, verts, va, vb, nv):
    """Interior samples of the arc of slot ``j`` from vertex ``va`` to ``vb`` (ccw).

    The arc borders the hole (``y == 0``: on the circle of radius ``rad[j]``) or the
    seam with slot ``y - 1`` (pushed along ``dirs[j]`` onto the bisecting plane, Eq. 10,
    at the larger radius of the two). Samples are no more than ``step`` apart in
    azimuth about ``dirs[j]`` (frame ``e1, e2``); they are appended to ``verts`` from
    row ``nv``.

    Returns
    -------
    m : int
        Segments of the arc (``m - 1`` samples).
    nv : int
        Vertices now in ``verts``.
    status : int
        ``ST_ARC`` (empty arc) or ``ST_CAPACITY`` on failure.
    """
    cap_v = verts.shape[0]
    pa = verts[va]
    pb = verts[vb]
    aa = _az(pa, e1, e2)
    span = _az(pb, e1, e2) - aa
    if span < 0.0:
        span += TWO_PI
    if span <= 1e-12:
        return 0, nv, ST_ARC
    m = arc_segments(span, step)
    dj = dirs[j]
    nx = 0.0
    ny = 0.0
    nz = 0.0
    nd = 0.0
    if y == 0:
        rs = rad[j]
    else:
        k2 = y - 1
        rs = max(rad[j], rad[k2])
        nx = dj[0] - dirs[k2, 0]
        ny = dj[1] - dirs[k2, 1]
        nz = dj[2] - dirs[k2, 2]
        nd = nx * dj[0] + ny * dj[1] + nz * dj[2]
    for i in range(1, m):
        ph = aa + span * i / m
        cp = np.cos(ph)
        sp = np.sin(ph)
        ex = cp * e1[0] + sp * e2[0]
        ey = cp * e1[1] + sp * e2[1]
        ez = cp * e1[2] + sp * e2[2]
        t = 0.0
        if y != 0:
            t = -rs * (nx * ex + ny * ey + nz * ez) / nd
        if nv >= cap_v:
            return m, nv, ST_CAPACITY
        verts[nv, 0] = rs * ex + t * dj[0]
        verts[nv, 1] = rs * ey + t * dj[1]
        verts[nv, 2] = rs * ez + t * dj[2]
        nv += 1
    return m, nv, ST_OK


@njit(cache=True, error_model="numpy")
def _turns_once(verts, ids, e1, e2):
    """The loop ``verts[ids]`` turns once counter-clockwise about ``e1 x e2``, in steps
    of more than 0 and at most pi of azimuth."""
    tot = 0.0
    cnt = ids.shape[0]
    for i in range(cnt):
        a0 = _az(verts[ids[i]], e1, e2)
        a1 = _az(verts[ids[(i + 1) % cnt]], e1, e2)
        da = a1 - a0
        if da < 0.0:
            da += TWO_PI
        if da <= 0.0 or da > np.pi + 1e-9:
            return False
        tot += da
    return not abs(tot - TWO_PI) > 1e-6  # (NaN passes, as it always has)


@njit(cache=True, error_model="numpy")
def _hole_fan(verts, nv, hole_ids, nh, rad, hole):
    """Fan closing the hole: its barycentre pushed onto the node sphere (Eq. 16).

    Parameters
    ----------
    verts : (cap_v, 3) float64
        The apex is appended at row ``nv``.
    hole_ids : (cap,) int64
        Hole boundary (first ``nh`` entries), counter-clockwise seen from outside.
    rad : (d,) float64
    hole : bool
        False: no hole, empty fan.

    Returns
    -------
    fan : (nh, 3) int64
    nv : int
    status : int
        ``ST_HOLE`` if the barycentre is (nearly) the node.
    """
    fan = np.empty((nh, 3), dtype=np.int64)
    if not hole:
        return fan, nv, ST_OK
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for i in range(nh):
        gx += verts[hole_ids[i], 0]
        gy += verts[hole_ids[i], 1]
        gz += verts[hole_ids[i], 2]
    gn = np.sqrt(gx * gx + gy * gy + gz * gz)
    rmax = 0.0
    for j in range(rad.shape[0]):
        rmax = max(rmax, rad[j])
    if gn <= 1e-9 * rmax * nh:
        return fan, nv, ST_HOLE
    verts[nv, 0] = rmax * gx / gn  # barycentre pushed onto the node sphere (Eq. 16)
    verts[nv, 1] = rmax * gy / gn
    verts[nv, 2] = rmax * gz / gn
    for i in range(nh):
        fan[i, 0] = nv
        fan[i, 1] = hole_ids[i]
        fan[i, 2] = hole_ids[(i + 1) % nh]
    nv += 1
    return fan, nv, ST_OK


@njit(cache=True, inline="always", error_model="numpy")
def _det(vertices, a, b, c, o):
    ax = vertices[a, 0] - o[0]
    ay = vertices[a, 1] - o[1]
    az = vertices[a, 2] - o[2]
    bx = vertices[b, 0] - o[0]
    by = vertices[b, 1] - o[1]
    bz = vertices[b, 2] - o[2]
    cx = vertices[c, 0] - o[0]
    cy = vertices[c, 1] - o[1]
    cz = vertices[c, 2] - o[2]
    d = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
    na = np.sqrt(ax * ax + ay * ay + az * az)
    nb = np.sqrt(bx * bx + by * by + bz * bz)
    nc = np.sqrt(cx * cx + cy * cy + cz * cz)
    return d / max(na * nb * nc, 1e-300)


# -------------------------------------------------------------------- tubes
@njit(cache=True, error_model="numpy")
def _unwrap_from_min(ids, vertices, centre, u, v, out_ids, out_az):
    """Rotate a ccw loop to start at its smallest azimuth; unwrapped azimuths."""
    k = ids.shape[0]
    best = 1e300
    i0 = 0
    tmp = np.empty(k)
    for i in range(k):
        x = vertices[ids[i]] - centre
        a = np.arctan2(_dot(x, v), _dot(x, u))
        if a < 0.0:
            a += TWO_PI
        tmp[i] = a
        if a < best:
            best = a
            i0 = i
    prev = best
    for i in range(k):
        a = tmp[(i0 + i) % k]
        while a < prev:
            a += TWO_PI
        out_ids[i] = ids[(i0 + i) % k]
        out_az[i] = a
        prev = a


@njit(cache=True, error_model="numpy")
def _band_score(vertices, a, b, c, s, nsec, ca, cb, ax, hub_a, hub_b):
    """Smallest normalised orientation of triangle (a, b, c) seen from the points that
    the validity check uses: node a for the first band, node b for the last, else the
    axis point level with the centroid."""
    best = 1e300
    if s == 0 and hub_a:
        best = min(best, _det(vertices, a, b, c, ca))
    if s == nsec - 2 and hub_b:
        best = min(best, _det(vertices, a, b, c, cb))
    if not ((s == 0 and hub_a) or (s == nsec - 2 and hub_b)):
        cen = (vertices[a] + vertices[b] + vertices[c]) / 3.0
        h = _dot(cen - ca, ax)
        best = _det(vertices, a, b, c, ca + h * ax)
    return best


@njit(cache=True, parallel=True, error_model="numpy")
def build_tubes(
    nodes, degree, edges, axis, fu, fv, radii, sec_ptr, sec_ids,
    n_inter, inter_cnt_ptr, inter_cnt, inter_vstart, face_start, vertices, faces,
):  # fmt: skip
    """Intermediary sections and tube triangles of every strut.

    Parameters
    ----------
    nodes : (N, 3) float64
    degree : (N,) int64
    edges : (M, 2) int64
    axis, fu, fv : (M, 3) float64
        Unit axis ``nodes[e1] - nodes[e0]`` and a frame ``fu x fv == axis``.
    radii : (M, 2) float64
    sec_ptr : (2M + 1,) int64
    sec_ids : (S,) int64
        Section of end ``2e + side``, ccw around that end's outward direction.
    n_inter : (M,) int64
        Intermediary sections of each strut.
    inter_cnt_ptr : (M + 1,) int64
    inter_cnt : (sum n_inter,) int64
        Vertex count of each intermediary section (Eq. 13).
    inter_vstart : (M,) int64
        First vertex row of the strut's intermediary sections.
    face_start : (M,) int64
        First face row of the strut (it has the sum of consecutive section sizes).
    vertices : (V, 3) float64, in/out
    faces : (F, 3) int64, out
    """
    m = edges.shape[0]
    for e in prange(m):
        a = edges[e, 0]
        b = edges[e, 1]
        na = sec_ptr[2 * e + 1] - sec_ptr[2 * e]
        nb = sec_ptr[2 * e + 2] - sec_ptr[2 * e + 1]
        u = fu[e]
        v = fv[e]
        ca = nodes[a]
        cb = nodes[b]
        hub_a = degree[a] >= 2
        hub_b = degree[b] >= 2
        ida = np.empty(na, dtype=np.int64)
        aza = np.empty(na)
        _unwrap_from_min(sec_ids[sec_ptr[2 * e] : sec_ptr[2 * e + 1]], vertices, ca, u, v, ida, aza)
        rev = np.empty(nb, dtype=np.int64)
        for i in range(nb):
            rev[i] = sec_ids[sec_ptr[2 * e + 2] - 1 - i]
        idb = np.empty(nb, dtype=np.int64)
        azb = np.empty(nb)
        _unwrap_from_min(rev, vertices, cb, u, v, idb, azb)
        k = n_inter[e]
        # axial extent of the two end sections (along the axis, from node a)
        t0 = -1e300
        for i in range(na):
            t0 = max(t0, _dot(vertices[ida[i]] - ca, axis[e]))
        t1 = 1e300
        for i in range(nb):
            t1 = min(t1, _dot(vertices[idb[i]] - ca, axis[e]))
        # sections in order: a, intermediaries, b
        nsec = k + 2
        sz = np.empty(nsec, dtype=np.int64)
        st = np.empty(nsec, dtype=np.int64)
        sz[0] = na
        sz[nsec - 1] = nb
        tot = na + nb
        for s in range(k):
            sz[s + 1] = inter_cnt[inter_cnt_ptr[e] + s]
            tot += sz[s + 1]
        ids = np.empty(tot, dtype=np.int64)
        az = np.empty(tot)
        st[0] = 0
        for s in range(1, nsec):
            st[s] = st[s - 1] + sz[s - 1]
        for i in range(na):
            ids[i] = ida[i]
            az[i] = aza[i]
        for i in range(nb):
            ids[st[nsec - 1] + i] = idb[i]
            az[st[nsec - 1] + i] = azb[i]
        row = inter_vstart[e]
        for s in range(k):
            tau = (s + 1.0) / (k + 1.0)
            ts = t0 + tau * (t1 - t0)
            rr = (1.0 - tau) * radii[e, 0] + tau * radii[e, 1]
            ns = sz[s + 1]
            for i in range(ns):
                fr = i / ns
                # angular positions blended between the two extremity sections (Eqs. 14-15)
                xa = fr * na
                ia = int(xa)
                wa = xa - ia
                pa = aza[ia] * (1.0 - wa) + (aza[ia + 1] if ia + 1 < na else aza[0] + TWO_PI) * wa
                xb = fr * nb
                ib = int(xb)
                wb = xb - ib
                pb = azb[ib] * (1.0 - wb) + (azb[ib + 1] if ib + 1 < nb else azb[0] + TWO_PI) * wb
                ph = (1.0 - tau) * pa + tau * pb
                cp = np.cos(ph) * rr
                sp = np.sin(ph) * rr
                for c in range(3):
                    vertices[row, c] = ca[c] + ts * axis[e, c] + cp * u[c] + sp * v[c]
                ids[st[s + 1] + i] = row
                az[st[s + 1] + i] = ph
                row += 1
        # zipper between consecutive sections, by azimuth (advancing front)
        f = face_start[e]
        for s in range(nsec - 1):
            pa0 = st[s]
            n0 = sz[s]
            pb0 = st[s + 1]
            n1 = sz[s + 1]
            i = 0
            j = 0
            while i < n0 or j < n1:
                nxa = az[pa0 + i + 1] if i + 1 < n0 else az[pa0] + TWO_PI
                nxb = az[pb0 + j + 1] if j + 1 < n1 else az[pb0] + TWO_PI
                A = ids[pa0 + i % n0]
                B = ids[pb0 + j % n1]
                adv_a = j >= n1 or (i < n0 and nxa <= nxb)
                if i < n0 and j < n1:
                    # prefer the triangle seen from outside by the nodes / the axis
                    A1 = ids[pa0 + (i + 1) % n0]
                    B1 = ids[pb0 + (j + 1) % n1]
                    sa = _band_score(vertices, A, A1, B, s, nsec, ca, cb, axis[e], hub_a, hub_b)
                    sb = _band_score(vertices, A, B1, B, s, nsec, ca, cb, axis[e], hub_a, hub_b)
                    if adv_a and sa <= 1e-9 and sb > sa:
                        adv_a = False
                    elif not adv_a and sb <= 1e-9 and sa > sb:
                        adv_a = True
                if adv_a:
                    faces[f, 0] = A
                    faces[f, 1] = ids[pa0 + (i + 1) % n0]
                    faces[f, 2] = B
                    i += 1
                else:
                    faces[f, 0] = A
                    faces[f, 1] = ids[pb0 + (j + 1) % n1]
                    faces[f, 2] = B
                    j += 1
                f += 1


# ------------------------------------------------------------------- checks
@njit(cache=True, parallel=True, error_model="numpy")
def check_tubes(
    nodes, edges, axis, offsets, inc_edge, inc_side, sec_ptr, sec_ids, face_start, face_stop,
    vertices, faces, margin, bad_node, bad_other, bad_kind,
):  # fmt: skip
    """Validity of every strut's tube at both of its nodes.

    A tube is valid at node n when (1) each of its vertices that does not
    belong to its section at n lies strictly inside its cone at n (the
    half-spaces of the bisecting planes with every other strut at n, and
    the half-space in front of the node), and (2) every tube triangle is seen
    from the node from its outer side (positive orientation). Together with
    the node structure this makes the surface around each node a radial graph
    (no self-intersections).

    bad_node, bad_other, bad_kind : (M,) int64, out
        -1 if valid; else the node, the other strut (or -1) and 1 for a cone
        violation, 2 for a mis-oriented triangle.
    """
    m = edges.shape[0]
    for e in prange(m):
        bad_node[e] = -1
        bad_other[e] = -1
        bad_kind[e] = 0
        # (2) orientation: a triangle touching the section at a node of degree >= 2 is
        # seen from that node; the others (intermediary sections, leaf ends) from the
        # axis point level with their centroid
        for f in range(face_start[e], face_stop[e]):
            judged = False
            for side in range(2):
                n = edges[e, side]
                if offsets[n + 1] - offsets[n] < 2:
                    continue
                touch = False
                for c in range(3):
                    for i in range(sec_ptr[2 * e + side], sec_ptr[2 * e + side + 1]):
                        if sec_ids[i] == faces[f, c]:
                            touch = True
                            break
                if touch:
                    judged = True
                    if _det(vertices, faces[f, 0], faces[f, 1], faces[f, 2], nodes[n]) <= 1e-12:
                        bad_node[e] = n
                        bad_kind[e] = 2
            if not judged:
                o = nodes[edges[e, 0]]
                cen = (vertices[faces[f, 0]] + vertices[faces[f, 1]] + vertices[faces[f, 2]]) / 3.0
                h = _dot(cen - o, axis[e])
                if _det(vertices, faces[f, 0], faces[f, 1], faces[f, 2], o + h * axis[e]) <= 1e-12:
                    bad_node[e] = edges[e, 0]
                    bad_kind[e] = 2
            if bad_kind[e] != 0:
                break
        for side in range(2):
            if bad_kind[e] != 0:
                break
            n = edges[e, side]
            o = nodes[n]
            sg = 1.0 if side == 0 else -1.0
            de = sg * axis[e]
            lo_own = sec_ptr[2 * e + side]
            hi_own = sec_ptr[2 * e + side + 1]
            # (1) cones: all tube vertices not in the own section
            for f in range(face_start[e], face_stop[e]):
                for c in range(3):
                    x = faces[f, c]
                    own = False
                    for i in range(lo_own, hi_own):
                        if sec_ids[i] == x:
                            own = True
                            break
                    if own:
                        continue
                    rx = vertices[x, 0] - o[0]
                    ry = vertices[x, 1] - o[1]
                    rz = vertices[x, 2] - o[2]
                    scale = np.sqrt(rx * rx + ry * ry + rz * rz)
                    if rx * de[0] + ry * de[1] + rz * de[2] <= margin * scale:
                        bad_node[e] = n
                        bad_kind[e] = 1
                    for t in range(offsets[n], offsets[n + 1]):
                        k = inc_edge[t]
                        if k == e or bad_kind[e] != 0:
                            continue
                        sk = 1.0 if inc_side[t] == 0 else -1.0
                        nx = de[0] - sk * axis[k, 0]
                        ny = de[1] - sk * axis[k, 1]
                        nz = de[2] - sk * axis[k, 2]
                        h = rx * nx + ry * ny + rz * nz
                        if h <= margin * scale * np.sqrt(nx * nx + ny * ny + nz * nz):
                            bad_node[e] = n
                            bad_other[e] = k
                            bad_kind[e] = 1
                    if bad_kind[e] != 0:
                        break
                if bad_kind[e] != 0:
                    break
            if bad_kind[e] != 0:
                break


@njit(cache=True, parallel=True, error_model="numpy")
def check_fans(nodes, fan_node, faces, start, vertices, bad):
    """bad[i] = hole triangle start + i is not seen from its node's outer side."""
    for i in prange(fan_node.shape[0]):
        f = start + i
        bad[i] = _det(vertices, faces[f, 0], faces[f, 1], faces[f, 2], nodes[fan_node[i]]) <= 1e-12


@njit(cache=True, parallel=True, error_model="numpy")
def triangle_quality(vertices, faces, out):
    """out[f] = 2 * inradius / circumradius of triangle f (1 for equilateral)."""
    for f in prange(faces.shape[0]):
        a = vertices[faces[f, 0]]
        b = vertices[faces[f, 1]]
        c = vertices[faces[f, 2]]
        la = np.sqrt(_dot(b - c, b - c))
        lb = np.sqrt(_dot(a - c, a - c))
        lc = np.sqrt(_dot(a - b, a - b))
        s = 0.5 * (la + lb + lc)
        num = (s - la) * (s - lb) * (s - lc)
        den = la * lb * lc
        out[f] = 8.0 * num / den if den > 0.0 else 0.0


@njit(cache=True, parallel=True, error_model="numpy")
def tri_pairs(vertices, faces, order, bounds, pairs, out):
    """out[p] = some triangle of strut pairs[p, 0] meets one of strut pairs[p, 1] (exact).

    The triangles of strut e are ``faces[order[bounds[e]:bounds[e + 1]]]``; the
    two struts share no node, hence no vertex.
    """
    for p in prange(pairs.shape[0]):
        e = pairs[p, 0]
        k = pairs[p, 1]
        hit = False
        for i in range(bounds[e], bounds[e + 1]):
            fa = order[i]
            for j in range(bounds[k], bounds[k + 1]):
                fb = order[j]
                if tri_tri(
                    vertices, faces[fa, 0], faces[fa, 1], faces[fa, 2],
                    faces[fb, 0], faces[fb, 1], faces[fb, 2],
                ):  # fmt: skip
                    hit = True
                    break
            if hit:
                break
        out[p] = hit
