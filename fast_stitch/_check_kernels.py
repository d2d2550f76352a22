"""Numba kernels behind :func:`fast_stitch.check.check` (private).

Everything here is an ``@numba.njit(cache=True)`` function on arrays and
scalars; input validation, dtype coercion and result wrapping live in
:mod:`fast_stitch.check`. Conventions: vertices are ``(V, 3) float64``
(C-contiguous), faces are ``(F, 3) int64`` with indices already checked to be
in ``[0, V)``. Half-edge ``h = 3 * f + k`` of face ``f`` runs from
``faces[f, k]`` to ``faces[f, (k + 1) % 3]``; corner ``c = 3 * f + k`` is the
use of vertex ``faces[f, k]`` by face ``f``.

What is shared with the stitchers
---------------------------------
Only the predicates of :mod:`fast_stitch._predicates`, imported below: the
exact orientation signs (``orient3d``, ``orient2d`` and their helpers), the
exact triangle/triangle test ``tri_tri`` (and ``tri_tri_exact``, the same test
without shortcuts) and ``box_stats``. The stitchers call ``tri_tri`` in their
clearance tests and ``box_stats`` for their clearance grid. Everything in this
module is the checker's own: edge topology, components and winding numbers,
per-face geometry and degenerate faces, the broadphase grid, the tests of faces
that share a vertex (:func:`_shared_vertex_intersect`) or an edge
(:func:`_shared_edge_intersect`), the touching-boxes shortcut. A bug in the
shared predicates could hide in both the stitcher and the checker; the
independent checkers of the test suite (trimesh, manifold3d and pymeshlab in
``tests/conftest.py``: ``independent_check``, ``assert_valid``) guard against
that.

Geometric predicates
--------------------
``orient3d`` and ``orient2d`` (shared) return the *exact* sign of the usual
determinants of the float64 input coordinates: a floating-point evaluation
with Shewchuk's static error bound, falling back to exact expansion arithmetic
(Dekker/Knuth error-free transformations) when the filter cannot decide. All
triangle/triangle decisions for faces that do not share an edge are built on
these signs only, so they are exact for the given coordinates: a pair is
reported if and only if the closed triangles really meet (touching counts),
apart from the shared vertex of faces that share one.

Faces sharing an edge are the one place where a tolerance is used (see
``_shared_edge_intersect``): they are reported when they are folded onto each
other, i.e. the apex of the lower face lies within ``tol`` of the other face's
plane on the same side of the shared edge.
"""

from __future__ import annotations

import numba
import numpy as np

from fast_stitch._predicates import (
    drop_axis,
    edge_separates_2d,
    mixed,
    orient2d,
    orient3d,
    orient3d_filter,
    point_in_tri_2d,
    seg_seg_2d,
    tri_tri,
    tri_tri_exact,
)

# --------------------------------------------------------------------------------------
# Degenerate faces
# --------------------------------------------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _collinear(vertices, a, b, c):
    """True iff the three points are exactly collinear (or coincide)."""
    k = drop_axis(vertices, a, b, c)
    if orient2d(vertices, a, b, c, (k + 1) % 3, (k + 2) % 3) != 0:
        return False
    if orient2d(vertices, a, b, c, (k + 2) % 3, k) != 0:
        return False
    return orient2d(vertices, a, b, c, k, (k + 1) % 3) == 0


# --------------------------------------------------------------------------------------
# Exact tests of faces that share a vertex or an edge (the checker's own)
# --------------------------------------------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _seg_tri_coplanar(vertices, p, q, a, b, c):
    k = drop_axis(vertices, a, b, c)
    i = (k + 1) % 3
    j = (k + 2) % 3
    if point_in_tri_2d(vertices, p, a, b, c, i, j):
        return True
    if point_in_tri_2d(vertices, q, a, b, c, i, j):
        return True
    return (
        seg_seg_2d(vertices, p, q, a, b, i, j)
        or seg_seg_2d(vertices, p, q, b, c, i, j)
        or seg_seg_2d(vertices, p, q, c, a, i, j)
    )


@numba.njit(cache=True)
def _seg_tri(vertices, p, q, a, b, c, op, oq):
    """Closed segment ``pq`` / closed triangle ``abc``; ``op``, ``oq`` = orient3d(a, b, c, .)."""
    if op * oq > 0:
        return False
    if op == 0 and oq == 0:
        return _seg_tri_coplanar(vertices, p, q, a, b, c)
    return not mixed(
        orient3d(vertices, p, q, a, b),
        orient3d(vertices, p, q, b, c),
        orient3d(vertices, p, q, c, a),
    )


@numba.njit(cache=True, error_model="numpy")
def _fan_separated_2d(vertices, p, a, b, c, d):
    """Quick sufficient test that triangles ``pab`` and ``pcd`` meet only at ``p``.

    In the projection dropping one axis, the line through ``p`` and another vertex of one
    triangle strictly separates the third vertex of that triangle from the other
    triangle's two free vertices. The projections then meet only at ``p``'s image, and
    so do the triangles: the separating triangle projects with a certainly non-zero area,
    so its plane contains no direction along the dropped axis and no point of it other
    than ``p`` projects onto ``p``'s image.
    """
    k = drop_axis(vertices, p, a, b)
    i = (k + 1) % 3
    j = (k + 2) % 3
    return (
        edge_separates_2d(vertices, p, a, b, c, d, d, i, j)
        or edge_separates_2d(vertices, p, b, a, c, d, d, i, j)
        or edge_separates_2d(vertices, p, c, d, a, b, b, i, j)
        or edge_separates_2d(vertices, p, d, c, a, b, b, i, j)
    )


@numba.njit(cache=True)
def _shared_vertex_intersect(vertices, p, a, b, c, d):
    """Triangles ``(p, a, b)`` and ``(p, c, d)`` meet somewhere other than ``p`` (exact).

    They do iff edge ``ab`` meets triangle ``pcd`` or edge ``cd`` meets triangle ``pab``
    (both in the coplanar and in the general case).
    """
    fc = orient3d_filter(vertices, p, a, b, c)
    fd = orient3d_filter(vertices, p, a, b, d)
    if (fc == 1 and fd == 1) or (fc == -1 and fd == -1):
        return False
    fa = orient3d_filter(vertices, p, c, d, a)
    fb = orient3d_filter(vertices, p, c, d, b)
    if (fa == 1 and fb == 1) or (fa == -1 and fb == -1):
        return False
    if fc == 2 or fd == 2 or fa == 2 or fb == 2:
        if _fan_separated_2d(vertices, p, a, b, c, d):
            return False
        fc = orient3d(vertices, p, a, b, c)
        fd = orient3d(vertices, p, a, b, d)
        if fc * fd > 0:
            return False
        fa = orient3d(vertices, p, c, d, a)
        fb = orient3d(vertices, p, c, d, b)
        if fa * fb > 0:
            return False
    return _seg_tri(vertices, c, d, p, a, b, fc, fd) or _seg_tri(vertices, a, b, p, c, d, fa, fb)


@numba.njit(cache=True, error_model="numpy")
def _shared_edge_intersect(vertices, a, b, c, d, tol):
    """Triangles ``(a, b, c)`` and ``(a, b, d)`` sharing edge ``ab`` overlap (folded).

    Not coplanar, they only meet along ``ab``. Let ``u`` and ``w`` be the components of
    ``c - a`` and ``d - a`` orthogonal to ``ab`` (the heights of the two faces over the
    shared edge, as vectors). The pair is reported when both apexes are on the same side
    (``u . w > 0``), both heights exceed ``tol`` and the lower apex lies within ``tol`` of
    the other face's plane: ``min(|u|, |w|) * sin(angle(u, w)) <= tol``.
    """
    ex = vertices[b, 0] - vertices[a, 0]
    ey = vertices[b, 1] - vertices[a, 1]
    ez = vertices[b, 2] - vertices[a, 2]
    ee = ex * ex + ey * ey + ez * ez
    if ee == 0.0:
        return False
    ux = vertices[c, 0] - vertices[a, 0]
    uy = vertices[c, 1] - vertices[a, 1]
    uz = vertices[c, 2] - vertices[a, 2]
    wx = vertices[d, 0] - vertices[a, 0]
    wy = vertices[d, 1] - vertices[a, 1]
    wz = vertices[d, 2] - vertices[a, 2]
    su = (ux * ex + uy * ey + uz * ez) / ee
    sw = (wx * ex + wy * ey + wz * ez) / ee
    ux -= su * ex
    uy -= su * ey
    uz -= su * ez
    wx -= sw * ex
    wy -= sw * ey
    wz -= sw * ez
    if ux * wx + uy * wy + uz * wz <= 0.0:
        return False
    nu = np.sqrt(ux * ux + uy * uy + uz * uz)
    nw = np.sqrt(wx * wx + wy * wy + wz * wz)
    if min(nu, nw) <= tol:
        return False
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    cross = np.sqrt(cx * cx + cy * cy + cz * cz)
    return cross <= tol * max(nu, nw)


@numba.njit(cache=True)
def _match(faces, f, v):
    """Position of vertex ``v`` in face ``f``, or -1."""
    if faces[f, 0] == v:
        return 0
    if faces[f, 1] == v:
        return 1
    if faces[f, 2] == v:
        return 2
    return -1


@numba.njit(cache=True)
def _point_on_segment_2d(vertices, p, a, b, i, j):
    """Closed test: point ``p`` on segment ``ab`` (coordinates ``i, j``; exact)."""
    if orient2d(vertices, a, b, p, i, j) != 0:
        return False
    for ax in (i, j):
        if vertices[p, ax] < min(vertices[a, ax], vertices[b, ax]):
            return False
        if vertices[p, ax] > max(vertices[a, ax], vertices[b, ax]):
            return False
    return True


@numba.njit(cache=True, error_model="numpy")
def _touching_boxes(vertices, faces, fi, fj, p):
    """Exact shortcut when the boxes of two faces only touch along a plane ``x_k = c``.

    Then the faces can only meet in that plane, where each one reduces to its vertices
    with ``x_k = c`` (a vertex or an edge). Returns 1 if these meet (beyond the shared
    vertex ``p`` if ``p >= 0``), 0 if not, -1 if the shortcut does not apply (no touching
    plane, or a whole face lies in it).
    """
    for k in range(3):
        amin = min(vertices[faces[fi, 0], k], vertices[faces[fi, 1], k], vertices[faces[fi, 2], k])
        amax = max(vertices[faces[fi, 0], k], vertices[faces[fi, 1], k], vertices[faces[fi, 2], k])
        bmin = min(vertices[faces[fj, 0], k], vertices[faces[fj, 1], k], vertices[faces[fj, 2], k])
        bmax = max(vertices[faces[fj, 0], k], vertices[faces[fj, 1], k], vertices[faces[fj, 2], k])
        if amax == bmin:
            c = amax
        elif bmax == amin:
            c = bmax
        else:
            continue
        na = 0
        a0 = -1
        a1 = -1
        for m in range(3):
            if vertices[faces[fi, m], k] == c:
                if na == 0:
                    a0 = faces[fi, m]
                else:
                    a1 = faces[fi, m]
                na += 1
        nb = 0
        b0 = -1
        b1 = -1
        for m in range(3):
            if vertices[faces[fj, m], k] == c:
                if nb == 0:
                    b0 = faces[fj, m]
                else:
                    b1 = faces[fj, m]
                nb += 1
        if na == 3 or nb == 3:
            return -1
        i = (k + 1) % 3
        j = (k + 2) % 3
        if p >= 0:
            # both parts contain p: {p}, or a segment from p
            if na == 1 or nb == 1:
                return 0
            x = a1 if a0 == p else a0
            y = b1 if b0 == p else b0
            if orient2d(vertices, p, x, y, i, j) != 0:
                return 0
            for ax in (i, j):
                dx = vertices[x, ax] - vertices[p, ax]
                if dx != 0.0:
                    dy = vertices[y, ax] - vertices[p, ax]
                    return 1 if (dx > 0.0) == (dy > 0.0) else 0
            return -1
        if na == 1 and nb == 1:
            same = vertices[a0, i] == vertices[b0, i] and vertices[a0, j] == vertices[b0, j]
            return 1 if same else 0
        if na == 1:
            return 1 if _point_on_segment_2d(vertices, a0, b0, b1, i, j) else 0
        if nb == 1:
            return 1 if _point_on_segment_2d(vertices, b0, a0, a1, i, j) else 0
        return 1 if seg_seg_2d(vertices, a0, a1, b0, b1, i, j) else 0
    return -1


@numba.njit(cache=True, error_model="numpy")
def _faces_intersect(vertices, faces, fi, fj, tol):
    """Do faces ``fi`` and ``fj`` (both non-degenerate) intersect beyond their shared part?"""
    s0 = _match(faces, fj, faces[fi, 0])
    s1 = _match(faces, fj, faces[fi, 1])
    s2 = _match(faces, fj, faces[fi, 2])
    ns = (s0 >= 0) + (s1 >= 0) + (s2 >= 0)
    if ns == 0:
        touch = _touching_boxes(vertices, faces, fi, fj, -1)
        if touch >= 0:
            return touch == 1
    if ns == 0:
        return tri_tri(
            vertices,
            faces[fi, 0],
            faces[fi, 1],
            faces[fi, 2],
            faces[fj, 0],
            faces[fj, 1],
            faces[fj, 2],
        )
    if ns == 3:
        return True
    if ns == 1:
        if s0 >= 0:
            m = 0
            n = s0
        elif s1 >= 0:
            m = 1
            n = s1
        else:
            m = 2
            n = s2
        touch = _touching_boxes(vertices, faces, fi, fj, faces[fi, m])
        if touch >= 0:
            return touch == 1
        return _shared_vertex_intersect(
            vertices,
            faces[fi, m],
            faces[fi, (m + 1) % 3],
            faces[fi, (m + 2) % 3],
            faces[fj, (n + 1) % 3],
            faces[fj, (n + 2) % 3],
        )
    # ns == 2: m is the apex of fi, n the apex of fj
    if s0 < 0:
        m = 0
    elif s1 < 0:
        m = 1
    else:
        m = 2
    n = 3 - (s0 + s1 + s2 + 1)
    return _shared_edge_intersect(
        vertices, faces[fi, (m + 1) % 3], faces[fi, (m + 2) % 3], faces[fi, m], faces[fj, n], tol
    )


# --------------------------------------------------------------------------------------
# Per-face geometry
# --------------------------------------------------------------------------------------


@numba.njit(parallel=True, cache=True)
def face_geometry(vertices, faces, center):
    """Per-face area, signed volume, bounding box and degeneracy.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    center : (3,) float64
        Reference point of the volume integrals (any point; a central one is most accurate).

    Returns
    -------
    area : (F,) float64
        ``0.5 * |(v1 - v0) x (v2 - v0)|``.
    volume : (F,) float64
        Signed volume of the tetrahedron ``(center, v0, v1, v2)``.
    boxes : (F, 6) float64
        ``(xmin, ymin, zmin, xmax, ymax, zmax)``.
    degenerate : (F,) bool
        Repeated vertex index, or three exactly collinear points.
    """
    n = faces.shape[0]
    area = np.empty(n)
    volume = np.empty(n)
    boxes = np.empty((n, 6))
    degenerate = np.zeros(n, np.bool_)
    for f in numba.prange(n):
        i0 = faces[f, 0]
        i1 = faces[f, 1]
        i2 = faces[f, 2]
        ux = vertices[i1, 0] - vertices[i0, 0]
        uy = vertices[i1, 1] - vertices[i0, 1]
        uz = vertices[i1, 2] - vertices[i0, 2]
        vx = vertices[i2, 0] - vertices[i0, 0]
        vy = vertices[i2, 1] - vertices[i0, 1]
        vz = vertices[i2, 2] - vertices[i0, 2]
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        area[f] = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
        ax = vertices[i0, 0] - center[0]
        ay = vertices[i0, 1] - center[1]
        az = vertices[i0, 2] - center[2]
        bx = vertices[i1, 0] - center[0]
        by = vertices[i1, 1] - center[1]
        bz = vertices[i1, 2] - center[2]
        cx = vertices[i2, 0] - center[0]
        cy = vertices[i2, 1] - center[1]
        cz = vertices[i2, 2] - center[2]
        volume[f] = (
            ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
        ) / 6.0
        for k in range(3):
            lo = min(vertices[i0, k], vertices[i1, k], vertices[i2, k])
            hi = max(vertices[i0, k], vertices[i1, k], vertices[i2, k])
            boxes[f, k] = lo
            boxes[f, 3 + k] = hi
        if i0 == i1 or i1 == i2 or i2 == i0:
            degenerate[f] = True
        else:
            degenerate[f] = _collinear(vertices, i0, i1, i2)
    return area, volume, boxes, degenerate


@numba.njit(parallel=True, cache=True)
def volume_permanents(vertices, faces, center):
    """(F,) float64: ``|a| . (|b| x |c|)``-style permanent of each face's volume term.

    Bounds the rounding error of :func:`face_geometry`'s ``volume``: the float triple
    product of the coordinates relative to ``center`` is within ``8 eps`` of this
    (Shewchuk's orient3d bound is ``7 eps``), divided by 6.
    """
    n = faces.shape[0]
    out = np.empty(n)
    for f in numba.prange(n):
        i0 = faces[f, 0]
        i1 = faces[f, 1]
        i2 = faces[f, 2]
        ax = abs(vertices[i0, 0] - center[0])
        ay = abs(vertices[i0, 1] - center[1])
        az = abs(vertices[i0, 2] - center[2])
        bx = abs(vertices[i1, 0] - center[0])
        by = abs(vertices[i1, 1] - center[1])
        bz = abs(vertices[i1, 2] - center[2])
        cx = abs(vertices[i2, 0] - center[0])
        cy = abs(vertices[i2, 1] - center[1])
        cz = abs(vertices[i2, 2] - center[2])
        out[f] = (
            ax * (by * cz + bz * cy) + ay * (bz * cx + bx * cz) + az * (bx * cy + by * cx)
        ) / 6.0
    return out


# Double-double arithmetic (about 106-bit significands) for the volume of thin components,
# whose float sum cancels below its rounding error (a strut of radius 1e-9 and length 1).


@numba.njit(cache=True, inline="always")
def _dd_two_sum(a, b):
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@numba.njit(cache=True, inline="always")
def _dd_two_prod(a, b):
    x = a * b
    c = 134217729.0 * a
    ahi = c - (c - a)
    alo = a - ahi
    c = 134217729.0 * b
    bhi = c - (c - b)
    blo = b - bhi
    return x, ((ahi * bhi - x) + ahi * blo + alo * bhi) + alo * blo


@numba.njit(cache=True, inline="always")
def _dd_add(ah, al, bh, bl):
    s, e = _dd_two_sum(ah, bh)
    e += al + bl
    return _dd_two_sum(s, e)


@numba.njit(cache=True, inline="always")
def _dd_mul(ah, al, bh, bl):
    p, e = _dd_two_prod(ah, bh)
    e += ah * bl + al * bh
    return _dd_two_sum(p, e)


@numba.njit(cache=True, inline="always")
def _dd_diff(a, b):
    """``a - b`` exactly, as a double-double."""
    return _dd_two_sum(a, -b)


@numba.njit(cache=True)
def component_volumes_dd(vertices, faces, labels, center, wanted):
    """Signed volume of the components with ``wanted[c]``, in double-double arithmetic.

    The coordinates relative to ``center`` are exact double-doubles; each face's triple
    product and the sums are double-double, in face order (deterministic).

    Returns
    -------
    (C,) float64
        The volumes (0 for components not wanted).
    """
    n_comp = wanted.shape[0]
    hi = np.zeros(n_comp)
    lo = np.zeros(n_comp)
    for f in range(faces.shape[0]):
        c = labels[f]
        if not wanted[c]:
            continue
        p = np.empty((3, 3, 2))
        for k in range(3):
            for j in range(3):
                h, l_ = _dd_diff(vertices[faces[f, k], j], center[j])
                p[k, j, 0] = h
                p[k, j, 1] = l_
        det_h = 0.0
        det_l = 0.0
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            # a_j * (b_j1 c_j2 - b_j2 c_j1)
            m1h, m1l = _dd_mul(p[1, j1, 0], p[1, j1, 1], p[2, j2, 0], p[2, j2, 1])
            m2h, m2l = _dd_mul(p[1, j2, 0], p[1, j2, 1], p[2, j1, 0], p[2, j1, 1])
            dh, dl = _dd_add(m1h, m1l, -m2h, -m2l)
            th, tl = _dd_mul(p[0, j, 0], p[0, j, 1], dh, dl)
            det_h, det_l = _dd_add(det_h, det_l, th, tl)
        hi[c], lo[c] = _dd_add(hi[c], lo[c], det_h, det_l)
    return (hi + lo) / 6.0


# --------------------------------------------------------------------------------------
# Edge topology
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _find(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@numba.njit(cache=True)
def _union(parent, x, y):
    """Union by smallest root index (deterministic labels)."""
    rx = _find(parent, x)
    ry = _find(parent, y)
    if rx < ry:
        parent[ry] = rx
    elif ry < rx:
        parent[rx] = ry


@numba.njit(cache=True)
def edge_topology(faces, n_vertices, max_report):
    """Edge, vertex-fan and component analysis of a triangle mesh.

    Half-edges whose two end points are the same vertex index are ignored; every
    other half-edge belongs to the undirected edge ``(min, max)`` of its end points.

    Parameters
    ----------
    faces : (F, 3) int64
    n_vertices : int
    max_report : int
        Maximum number of examples stored per kind of problem.

    Returns
    -------
    counts : (7,) int64
        ``n_edges, n_boundary_edges, n_nonmanifold_edges, n_inconsistent_edges,
        n_nonmanifold_vertices, n_unused_vertices, n_components``.
    boundary : (K, 3) int64
        Examples ``(v0, v1, face)``: edge ``v0 < v1`` and the lowest face using it.
    nonmanifold : (K, 3) int64
        Same for edges used by more than two faces.
    inconsistent : (K, 3) int64
        Same for edges used by two faces in the same direction.
    nm_vertices : (K,) int64
        Vertices whose incident faces form several fans (linked across edges at the vertex).
    unused : (K,) int64
        Vertices not used by any face.
    labels : (F,) int64
        Connected component of each face (faces linked across shared edges), numbered in
        order of their lowest face.
    used : (V,) bool
        Vertices used by some face.
    open_components : (C,) bool
        Components with a boundary edge.
    """
    nf = faces.shape[0]
    nh = 3 * nf
    # ---- counting sort of the half-edges by their lower vertex
    start = np.zeros(n_vertices + 1, np.int64)
    for h in range(nh):
        f = h // 3
        k = h - 3 * f
        a = faces[f, k]
        b = faces[f, (k + 1) % 3]
        if a != b:
            start[min(a, b) + 1] += 1
    for v in range(n_vertices):
        start[v + 1] += start[v]
    n_valid = start[n_vertices]
    order = np.empty(n_valid, np.int64)
    other = np.empty(n_valid, np.int64)  # higher vertex of each sorted half-edge
    pos = start[:n_vertices].copy()
    for h in range(nh):
        f = h // 3
        k = h - 3 * f
        a = faces[f, k]
        b = faces[f, (k + 1) % 3]
        if a != b:
            lo = min(a, b)
            order[pos[lo]] = h
            other[pos[lo]] = max(a, b)
            pos[lo] += 1
    # ---- sort each bucket by (higher vertex, half-edge); Shell sort with insertion-sort
    # gaps (the pairs are distinct, so stability does not matter)
    for v in range(n_vertices):
        s = start[v]
        e = start[v + 1]
        gap = 1
        while 3 * gap + 1 < e - s:
            gap = 3 * gap + 1
        while gap >= 1:
            for i in range(s + gap, e):
                kh = order[i]
                ko = other[i]
                j = i - gap
                while j >= s and (other[j] > ko or (other[j] == ko and order[j] > kh)):
                    order[j + gap] = order[j]
                    other[j + gap] = other[j]
                    j -= gap
                order[j + gap] = kh
                other[j + gap] = ko
            gap //= 3
    # ---- scan the groups of equal edges
    face_parent = np.arange(nf)
    corner_parent = np.arange(nh)
    boundary = np.empty((max_report, 3), np.int64)
    nonmanifold = np.empty((max_report, 3), np.int64)
    inconsistent = np.empty((max_report, 3), np.int64)
    n_edges = 0
    n_boundary = 0
    n_nonmanifold = 0
    n_inconsistent = 0
    on_boundary = np.zeros(nf, np.bool_)
    lo_vertex = 0
    g0 = 0
    while g0 < n_valid:
        while start[lo_vertex + 1] <= g0:
            lo_vertex += 1
        hi_vertex = other[g0]
        g1 = g0 + 1
        while g1 < start[lo_vertex + 1] and other[g1] == hi_vertex:
            g1 += 1
        n_edges += 1
        count = g1 - g0
        h0 = order[g0]
        f0 = h0 // 3
        forward = 0
        c_lo0 = -1
        c_hi0 = -1
        for g in range(g0, g1):
            h = order[g]
            f = h // 3
            k = h - 3 * f
            c_start = h
            c_end = 3 * f + (k + 1) % 3
            if faces[f, k] == lo_vertex:
                forward += 1
                c_lo = c_start
                c_hi = c_end
            else:
                c_lo = c_end
                c_hi = c_start
            if g == g0:
                c_lo0 = c_lo
                c_hi0 = c_hi
            else:
                _union(face_parent, f0, f)
                _union(corner_parent, c_lo0, c_lo)
                _union(corner_parent, c_hi0, c_hi)
        if count == 1:
            on_boundary[f0] = True
            if n_boundary < max_report:
                boundary[n_boundary, 0] = lo_vertex
                boundary[n_boundary, 1] = hi_vertex
                boundary[n_boundary, 2] = f0
            n_boundary += 1
        elif count > 2:
            if n_nonmanifold < max_report:
                nonmanifold[n_nonmanifold, 0] = lo_vertex
                nonmanifold[n_nonmanifold, 1] = hi_vertex
                nonmanifold[n_nonmanifold, 2] = f0
            n_nonmanifold += 1
        elif forward != 1:
            if n_inconsistent < max_report:
                inconsistent[n_inconsistent, 0] = lo_vertex
                inconsistent[n_inconsistent, 1] = hi_vertex
                inconsistent[n_inconsistent, 2] = f0
            n_inconsistent += 1
        g0 = g1
    # ---- corners of one face at the same vertex belong to the same fan
    for f in range(nf):
        for k in range(3):
            for k2 in range(k + 1, 3):
                if faces[f, k] == faces[f, k2]:
                    _union(corner_parent, 3 * f + k, 3 * f + k2)
    # ---- fans per vertex
    fans = np.zeros(n_vertices, np.int64)
    used = np.zeros(n_vertices, np.bool_)
    for c in range(nh):
        f = c // 3
        v = faces[f, c - 3 * f]
        used[v] = True
        if _find(corner_parent, c) == c:
            fans[v] += 1
    nm_vertices = np.empty(max_report, np.int64)
    unused = np.empty(max_report, np.int64)
    n_nm_vertices = 0
    n_unused = 0
    for v in range(n_vertices):
        if fans[v] > 1:
            if n_nm_vertices < max_report:
                nm_vertices[n_nm_vertices] = v
            n_nm_vertices += 1
        if not used[v]:
            if n_unused < max_report:
                unused[n_unused] = v
            n_unused += 1
    # ---- face components
    labels = np.empty(nf, np.int64)
    n_components = 0
    for f in range(nf):
        r = _find(face_parent, f)
        if r == f:
            labels[f] = n_components
            n_components += 1
        else:
            labels[f] = labels[r]  # r < f: already labelled
    open_components = np.zeros(n_components, np.bool_)
    for f in range(nf):
        if on_boundary[f]:
            open_components[labels[f]] = True
    counts = np.array(
        [n_edges, n_boundary, n_nonmanifold, n_inconsistent, n_nm_vertices, n_unused, n_components],
        dtype=np.int64,
    )
    return (
        counts,
        boundary[: min(n_boundary, max_report)].copy(),
        nonmanifold[: min(n_nonmanifold, max_report)].copy(),
        inconsistent[: min(n_inconsistent, max_report)].copy(),
        nm_vertices[: min(n_nm_vertices, max_report)].copy(),
        unused[: min(n_unused, max_report)].copy(),
        labels,
        used,
        open_components,
    )


# --------------------------------------------------------------------------------------
# Components: representative faces and winding numbers
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def component_rep_faces(labels, area, n_components):
    """Largest-area face of each component (lowest index on ties).

    Parameters
    ----------
    labels : (F,) int64
    area : (F,) float64
    n_components : int

    Returns
    -------
    rep : (C,) int64
    """
    rep = np.full(n_components, -1, np.int64)
    for f in range(labels.shape[0]):
        c = labels[f]
        if rep[c] < 0 or area[f] > area[rep[c]]:
            rep[c] = f
    return rep


@numba.njit(parallel=True, cache=True)
def straddling_pairs(vertices, faces, pairs):
    """Whether each face of each pair has corners strictly on both sides of the other's
    plane (exact ``orient3d`` signs): two intersecting faces that pass through each other,
    not faces that only touch (at an edge, a vertex, or coplanar).

    vertices : (V, 3) float64, faces : (F, 3) int64, pairs : (P, 2) int64 face indices.
    Returns (P,) bool.
    """
    n = pairs.shape[0]
    out = np.zeros(n, np.bool_)
    for k in numba.prange(n):
        fa, fb = pairs[k, 0], pairs[k, 1]
        both = True
        for one, other in ((fa, fb), (fb, fa)):
            a, b, c = faces[other, 0], faces[other, 1], faces[other, 2]
            pos = False
            neg = False
            for m in range(3):
                s = orient3d(vertices, a, b, c, faces[one, m])
                pos |= s > 0
                neg |= s < 0
            both &= pos and neg
        out[k] = both
    return out


@numba.njit(cache=True)
def flattest_faces(vertices, faces, labels, wanted):
    """Face of each wanted component whose projection on the xy plane is largest (lowest
    index on ties; -1 for the others).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    labels : (F,) int64
    wanted : (C,) bool

    Returns
    -------
    rep : (C,) int64
    """
    n = wanted.shape[0]
    rep = np.full(n, -1, np.int64)
    best = np.full(n, -1.0)
    for f in range(labels.shape[0]):
        c = labels[f]
        if not wanted[c]:
            continue
        a, b, d = faces[f, 0], faces[f, 1], faces[f, 2]
        ux = vertices[b, 0] - vertices[a, 0]
        uy = vertices[b, 1] - vertices[a, 1]
        vx = vertices[d, 0] - vertices[a, 0]
        vy = vertices[d, 1] - vertices[a, 1]
        az = abs(ux * vy - uy * vx)
        if az > best[c]:
            best[c] = az
            rep[c] = f
    return rep


@numba.njit(parallel=True, cache=True)
def ray_winding_numbers(points, faces, labels, n_vertices, query_labels, grid, cell_start, order):
    """Winding number of the faces *not* in ``query_labels[q]`` at query point ``q``, by
    the signed crossings of the ray from it along +z, with exact predicates.

    Parameters
    ----------
    points : (V + Q, 3) float64
        The mesh's vertices, then the query points (query ``q`` is point ``n_vertices + q``).
    faces : (F, 3) int64
    labels : (F,) int64
        Component of each face.
    n_vertices : int
    query_labels : (Q,) int64
        Component whose faces are left out for each query point.
    grid : (5,) float64
        ``x0, y0, h, nx, ny``: the cells of side ``h`` over the queries' xy box.
    cell_start : (nx * ny + 1,) int64
    order : (Q,) int64
        Queries sorted by cell (cell ``c`` holds ``order[cell_start[c]:cell_start[c + 1]]``).

    Returns
    -------
    w : (Q,) int64
        Sum over the crossed faces of the sign of their normal's z: the winding number of
        closed, consistently oriented components (+1 inside an outward one, 0 outside).
    unsure : (Q,) bool
        The ray meets an edge, a vertex or the plane of a face at the query point (an
        exact zero): ``w`` does not count; ask :func:`winding_numbers`.
    """
    nf = faces.shape[0]
    nq = query_labels.shape[0]
    x0, y0, h = grid[0], grid[1], grid[2]
    nx, ny = np.int64(grid[3]), np.int64(grid[4])
    n_chunks = max(1, min(64, 20_000_000 // max(1, nq)))
    chunk = (nf + n_chunks - 1) // n_chunks
    partial = np.zeros((n_chunks, nq), np.int64)
    flags = np.zeros((n_chunks, nq), np.bool_)
    for ch in numba.prange(n_chunks):
        for f in range(ch * chunk, min(nf, (ch + 1) * chunk)):
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            if a == b or b == c or c == a:
                continue
            lox = min(points[a, 0], points[b, 0], points[c, 0])
            hix = max(points[a, 0], points[b, 0], points[c, 0])
            loy = min(points[a, 1], points[b, 1], points[c, 1])
            hiy = max(points[a, 1], points[b, 1], points[c, 1])
            i0 = max(np.int64(0), np.int64(np.floor((lox - x0) / h)))
            i1 = min(nx - 1, np.int64(np.floor((hix - x0) / h)))
            j0 = max(np.int64(0), np.int64(np.floor((loy - y0) / h)))
            j1 = min(ny - 1, np.int64(np.floor((hiy - y0) / h)))
            if i0 > i1 or j0 > j1:
                continue
            sgn = 2  # the face's orientation seen from above (0: vertical; 2: not yet known)
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    cell = i * ny + j
                    for k in range(cell_start[cell], cell_start[cell + 1]):
                        q = order[k]
                        if labels[f] == query_labels[q]:
                            continue
                        p = n_vertices + q
                        if not (lox <= points[p, 0] <= hix and loy <= points[p, 1] <= hiy):
                            continue
                        if sgn == 2:
                            sgn = orient2d(points, a, b, c, 0, 1)
                            if sgn == 0:
                                break  # a vertical face: no ray crosses it
                        s0 = orient2d(points, a, b, p, 0, 1)
                        s1 = orient2d(points, b, c, p, 0, 1)
                        s2 = orient2d(points, c, a, p, 0, 1)
                        if s0 == -sgn or s1 == -sgn or s2 == -sgn:
                            continue  # outside the face's shadow
                        if s0 == 0 or s1 == 0 or s2 == 0:
                            flags[ch, q] = True  # on an edge or a vertex of it
                            continue
                        up = orient3d(points, a, b, c, p)  # sign of sgn * (z_face - z_p)
                        if up == 0:
                            flags[ch, q] = True  # in the face
                        elif up == sgn:
                            partial[ch, q] += sgn
                    if sgn == 0:
                        break
                if sgn == 0:
                    break
    w = np.zeros(nq, np.int64)
    unsure = np.zeros(nq, np.bool_)
    for ch in range(n_chunks):
        for q in range(nq):
            w[q] += partial[ch, q]
            unsure[q] |= flags[ch, q]
    return w, unsure


@numba.njit(parallel=True, cache=True)
def winding_numbers(vertices, faces, labels, queries, query_labels):
    """Generalized winding number of the faces *not* in ``query_labels[q]`` at ``queries[q]``.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    labels : (F,) int64
        Component of each face.
    queries : (Q, 3) float64
    query_labels : (Q,) int64
        Component whose faces are left out for each query point.

    Returns
    -------
    w : (Q,) float64
        Sum of the signed solid angles over ``4 pi`` (about +1 inside a closed, outward
        oriented surface, 0 outside). Summed in fixed chunks: independent of threading.
    """
    nf = faces.shape[0]
    nq = queries.shape[0]
    n_chunks = 64
    chunk = (nf + n_chunks - 1) // n_chunks
    partial = np.zeros((n_chunks, nq))
    for ch in numba.prange(n_chunks):
        f_start = ch * chunk
        f_end = min(nf, f_start + chunk)
        for f in range(f_start, f_end):
            i0 = faces[f, 0]
            i1 = faces[f, 1]
            i2 = faces[f, 2]
            if i0 == i1 or i1 == i2 or i2 == i0:
                continue
            for q in range(nq):
                if labels[f] == query_labels[q]:
                    continue
                ax = vertices[i0, 0] - queries[q, 0]
                ay = vertices[i0, 1] - queries[q, 1]
                az = vertices[i0, 2] - queries[q, 2]
                bx = vertices[i1, 0] - queries[q, 0]
                by = vertices[i1, 1] - queries[q, 1]
                bz = vertices[i1, 2] - queries[q, 2]
                cx = vertices[i2, 0] - queries[q, 0]
                cy = vertices[i2, 1] - queries[q, 1]
                cz = vertices[i2, 2] - queries[q, 2]
                la = np.sqrt(ax * ax + ay * ay + az * az)
                lb = np.sqrt(bx * bx + by * by + bz * bz)
                lc = np.sqrt(cx * cx + cy * cy + cz * cz)
                det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
                den = (
                    la * lb * lc
                    + (ax * bx + ay * by + az * bz) * lc
                    + (ax * cx + ay * cy + az * cz) * lb
                    + (bx * cx + by * cy + bz * cz) * la
                )
                partial[ch, q] += 2.0 * np.arctan2(det, den)
    w = np.zeros(nq)
    for ch in range(n_chunks):
        for q in range(nq):
            w[q] += partial[ch, q]
    return w / (4.0 * np.pi)


# --------------------------------------------------------------------------------------
# Self-intersections: hashed uniform grid broadphase + exact narrowphase
#
# Long faces (struts of a lattice, slivers) would make box-based broadphases scan far too
# many candidates, so every face is cut along the longest axis of its box into ``k``
# slabs ("pieces") of length <= h, h being the cell size; each piece gets the box of the
# part of the triangle inside its slab (conservatively enlarged by ``margin``), and the
# face is entered in the buckets of the grid cells overlapped by any of its pieces (a
# thin diagonal face then only occupies the cells along it, not all those of its box).
# A face ``f`` scans its own buckets for faces ``g > f`` whose box overlaps its box; the
# candidates of ``f`` are deduplicated before the exact test, so each pair is examined
# once.
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _cell_hash(ix, iy, iz, mask):
    """Bucket of grid cell ``(ix, iy, iz)``: blocks of 4x4x4 cells are hashed (splitmix64
    finalizer) to runs of 64 consecutive buckets, which keeps neighbouring cells close in
    memory. ``mask + 1`` is a power of two >= 64."""
    k = (
        np.uint64(ix >> 2) * np.uint64(0x9E3779B97F4A7C15)
        ^ np.uint64(iy >> 2) * np.uint64(0xC2B2AE3D27D4EB4F)
        ^ np.uint64(iz >> 2) * np.uint64(0x165667B19E3779F9)
    )
    k ^= k >> np.uint64(31)
    k *= np.uint64(0xBF58476D1CE4E5B9)
    k ^= k >> np.uint64(29)
    low = ((ix & 3) << 4) | ((iy & 3) << 2) | (iz & 3)
    return (np.int64(k << np.uint64(6)) | low) & mask


@numba.njit(cache=True, error_model="numpy")
def _n_pieces(boxes, f, h, max_pieces):
    ext = max(boxes[f, 3] - boxes[f, 0], boxes[f, 4] - boxes[f, 1], boxes[f, 5] - boxes[f, 2])
    k = np.int64(np.ceil(ext / h)) if ext > 0.0 else 1
    return max(1, min(k, max_pieces))


@numba.njit(cache=True, error_model="numpy")
def _piece_box(vertices, faces, boxes, f, i, k, margin, out):
    """Box of the part of face ``f`` inside slab ``i`` of ``k`` along its box's longest
    axis, enlarged by ``margin`` across that axis (it covers the exact part).

    ``out`` : (6,) float64, written ``(xmin, ymin, zmin, xmax, ymax, zmax)``.
    """
    ax = 0
    ext = boxes[f, 3] - boxes[f, 0]
    for kk in (1, 2):
        if boxes[f, 3 + kk] - boxes[f, kk] > ext:
            ext = boxes[f, 3 + kk] - boxes[f, kk]
            ax = kk
    if k == 1:
        for kk in range(6):
            out[kk] = boxes[f, kk]
        return
    lo = boxes[f, ax]
    s0 = lo if i == 0 else lo + ext * i / k
    s1 = boxes[f, 3 + ax] if i == k - 1 else lo + ext * (i + 1) / k
    for kk in range(3):
        out[kk] = np.inf
        out[3 + kk] = -np.inf
    for m in range(3):
        p = faces[f, m]
        x = vertices[p, ax]
        if s0 <= x <= s1:
            for kk in range(3):
                out[kk] = min(out[kk], vertices[p, kk])
                out[3 + kk] = max(out[3 + kk], vertices[p, kk])
        q = faces[f, (m + 1) % 3]
        y = vertices[q, ax]
        if x == y:
            continue
        for s in (s0, s1):
            if min(x, y) < s < max(x, y):
                t = (s - x) / (y - x)
                for kk in range(3):
                    c = vertices[p, kk] + t * (vertices[q, kk] - vertices[p, kk])
                    out[kk] = min(out[kk], c)
                    out[3 + kk] = max(out[3 + kk], c)
    for kk in range(3):
        if kk == ax:
            out[kk] = s0
            out[3 + kk] = s1
        else:
            out[kk] = max(out[kk] - margin, boxes[f, kk])
            out[3 + kk] = min(out[3 + kk] + margin, boxes[f, 3 + kk])


@numba.njit(cache=True, error_model="numpy")
def _cell(x, o, h):
    return np.int64(np.floor((x - o) / h))


@numba.njit(cache=True)
def _grow(buf):
    """A copy of ``buf`` (int64) with twice the length."""
    bigger = np.empty(2 * buf.shape[0], np.int64)
    for i in range(buf.shape[0]):
        bigger[i] = buf[i]
    return bigger


@numba.njit(cache=True, error_model="numpy")
def _sort_unique(buf, n):
    """Sort ``buf[:n]`` (int64) in place and drop duplicates; returns the new length."""
    gap = 1
    while 3 * gap + 1 < n:
        gap = 3 * gap + 1
    while gap >= 1:  # Shell sort (plain insertion sort for short lists)
        for i in range(gap, n):
            x = buf[i]
            j = i - gap
            while j >= 0 and buf[j] > x:
                buf[j + gap] = buf[j]
                j -= gap
            buf[j + gap] = x
        gap //= 3
    m = 0
    for i in range(n):
        if m == 0 or buf[i] != buf[m - 1]:
            buf[m] = buf[i]
            m += 1
    return m


@numba.njit(cache=True)
def _face_buckets(vertices, faces, boxes, f, origin, h, max_pieces, margin, mask, out, buf):
    """Distinct buckets (sorted) of the cells overlapped by the pieces of face ``f``.

    ``out`` : (6,) float64 work array; ``buf`` : (m,) int64 work array, returned (it is
    replaced by a longer one when needed) with the count.
    """
    n = 0
    k = _n_pieces(boxes, f, h, max_pieces)
    for i in range(k):
        _piece_box(vertices, faces, boxes, f, i, k, margin, out)
        for ix in range(_cell(out[0], origin[0], h), _cell(out[3], origin[0], h) + 1):
            for iy in range(_cell(out[1], origin[1], h), _cell(out[4], origin[1], h) + 1):
                for iz in range(_cell(out[2], origin[2], h), _cell(out[5], origin[2], h) + 1):
                    if n == buf.shape[0]:
                        buf = _grow(buf)
                    buf[n] = _cell_hash(ix, iy, iz, mask)
                    n += 1
    return _sort_unique(buf, n), buf


@numba.njit(parallel=True, cache=True)
def grid_face_buckets(
    vertices, faces, boxes, origin, h, max_pieces, margin, n_buckets, offsets, out_buckets
):
    """Buckets of every face: count them (an upper bound), or write the distinct ones.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    boxes : (F, 6) float64
    origin : (3,) float64
        Lower corner of cell ``(0, 0, 0)``; every box lies above it.
    h : float
        Cell size and largest piece length.
    max_pieces : int
    margin : float
    n_buckets : int
        A power of two >= 64.
    offsets : (F + 1,) int64
        Empty: only count the cells of the pieces (with repeats, an upper bound). Else
        where to write the distinct buckets of each face (room for the upper bound).
    out_buckets : (N,) int32
        Output when ``offsets`` is given (sorted per face).

    Returns
    -------
    counts : (F,) int64
        Upper bounds, or the numbers of distinct buckets written.
    """
    nf = faces.shape[0]
    mask = n_buckets - 1
    counts = np.zeros(nf, np.int64)
    write = offsets.shape[0] > 0
    chunk = 256
    for ch in numba.prange((nf + chunk - 1) // chunk):
        out = np.empty(6)
        buf = np.empty(64, np.int64)
        for f in range(ch * chunk, min(nf, (ch + 1) * chunk)):
            if not write:
                k = _n_pieces(boxes, f, h, max_pieces)
                total = 0
                for i in range(k):
                    _piece_box(vertices, faces, boxes, f, i, k, margin, out)
                    total += (
                        (_cell(out[3], origin[0], h) - _cell(out[0], origin[0], h) + 1)
                        * (_cell(out[4], origin[1], h) - _cell(out[1], origin[1], h) + 1)
                        * (_cell(out[5], origin[2], h) - _cell(out[2], origin[2], h) + 1)
                    )
                counts[f] = total
                continue
            n, buf = _face_buckets(
                vertices, faces, boxes, f, origin, h, max_pieces, margin, mask, out, buf
            )
            counts[f] = n
            for m in range(n):
                out_buckets[offsets[f] + m] = buf[m]
    return counts


@numba.njit(cache=True)
def grid_fill(face_buckets, offsets, counts, n_buckets):
    """Bucket lists (counting sort of the faces by bucket).

    Parameters
    ----------
    face_buckets : (N,) int32
    offsets : (F + 1,) int64
    counts : (F,) int64
        From :func:`grid_face_buckets`: the buckets of face ``f`` are
        ``face_buckets[offsets[f]:offsets[f] + counts[f]]``.
    n_buckets : int

    Returns
    -------
    bucket_start : (n_buckets + 1,) int64
    entries : (M,) int32
        Face indices, ascending and distinct inside each bucket.
    """
    nf = counts.shape[0]
    bucket_start = np.zeros(n_buckets + 1, np.int64)
    for f in range(nf):
        for e in range(offsets[f], offsets[f] + counts[f]):
            bucket_start[face_buckets[e] + 1] += 1
    for b in range(n_buckets):
        bucket_start[b + 1] += bucket_start[b]
    entries = np.empty(bucket_start[n_buckets], np.int32)
    pos = bucket_start[:n_buckets].copy()
    for f in range(nf):
        for e in range(offsets[f], offsets[f] + counts[f]):
            b = face_buckets[e]
            entries[pos[b]] = f
            pos[b] += 1
    return bucket_start, entries


@numba.njit(cache=True)
def _reinsert(buf, n, f, size):
    """New dedup tables of ``size`` slots holding the ``n`` candidates of face ``f``."""
    keys = np.empty(size, np.int64)
    stamps = np.full(size, -1, np.int64)
    for m in range(n):
        g = buf[m]
        slot = (g * 2654435761) & (size - 1)
        while stamps[slot] == f:
            slot = (slot + 1) & (size - 1)
        stamps[slot] = f
        keys[slot] = g
    return keys, stamps


@numba.njit(parallel=True, cache=True)
def grid_pairs(
    vertices, faces, boxes, face_buckets, offsets, bucket_counts, bucket_start, entries, tol,
    mode, orig, max_first, prev_counts, pair_offsets, face_hit, pairs,
):  # fmt: skip
    """Count (or collect) the intersecting face pairs ``(f, g > f)`` found through the grid.

    Each face scans the buckets of its pieces' cells (the distinct ones) for faces
    ``g > f`` whose box overlaps its box; duplicates are dropped with a small hash table
    (stamped with ``f``, so it is never cleared) before the exact test. Every face given
    must be non-degenerate; for speed they should be in a spatially coherent order.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    boxes : (F, 6) float64
    face_buckets : (N,) int32
    offsets : (F + 1,) int64
    bucket_counts : (F,) int64
        As given to :func:`grid_fill`.
    bucket_start : (B + 1,) int64
    entries : (M,) int32
        From :func:`grid_fill`.
    tol : float
        Absolute fold tolerance for faces that share an edge.
    mode : int
        0: count the pairs of every face and set ``face_hit`` to 1 for the faces
        involved; 1: count only the pairs with ``min(orig[f], orig[g]) <= max_first``,
        scanning only the faces with ``prev_counts[f] > 0``; 2: like 1, and write them
        into ``pairs[pair_offsets[f]:pair_offsets[f + 1]]``.
    orig : (F,) int64
        Original index of each face (for ``max_first``).
    max_first : int
    prev_counts : (F,) int64
        Counts of mode 0 (modes 1 and 2).
    pair_offsets : (F + 1,) int64
        Write positions (mode 2).
    face_hit : (F,) uint8
        Output of mode 0.
    pairs : (P, 2) int64
        Output of mode 2: ``(f, g)``, ``f < g``, in the numbering of ``faces``.

    Returns
    -------
    counts : (F,) int64
        Pairs ``(f, g > f)`` counted per face ``f``.
    """
    nf = faces.shape[0]
    counts = np.zeros(nf, np.int64)
    chunk = 256
    for ch in numba.prange((nf + chunk - 1) // chunk):
        buf = np.empty(256, np.int64)
        size = 1024
        keys = np.empty(size, np.int64)
        stamps = np.full(size, -1, np.int64)
        for f in range(ch * chunk, min(nf, (ch + 1) * chunk)):
            if mode != 0 and prev_counts[f] == 0:
                continue
            fx0 = boxes[f, 0]
            fy0 = boxes[f, 1]
            fz0 = boxes[f, 2]
            fx1 = boxes[f, 3]
            fy1 = boxes[f, 4]
            fz1 = boxes[f, 5]
            n = 0
            for e in range(offsets[f], offsets[f] + bucket_counts[f]):
                b = face_buckets[e]
                lo_k = bucket_start[b]
                hi_k = bucket_start[b + 1]
                while lo_k < hi_k:  # first entry > f (entries are ascending)
                    mid = (lo_k + hi_k) >> 1
                    if entries[mid] <= f:
                        lo_k = mid + 1
                    else:
                        hi_k = mid
                for kk in range(lo_k, bucket_start[b + 1]):
                    g = entries[kk]
                    if (
                        fx0 > boxes[g, 3]
                        or boxes[g, 0] > fx1
                        or fy0 > boxes[g, 4]
                        or boxes[g, 1] > fy1
                        or fz0 > boxes[g, 5]
                        or boxes[g, 2] > fz1
                    ):
                        continue
                    if mode != 0 and min(orig[f], orig[g]) > max_first:
                        continue
                    slot = (g * 2654435761) & (size - 1)
                    while stamps[slot] == f and keys[slot] != g:
                        slot = (slot + 1) & (size - 1)
                    if stamps[slot] == f:
                        continue  # seen in another bucket
                    stamps[slot] = f
                    keys[slot] = g
                    if n == buf.shape[0]:
                        buf = _grow(buf)
                    buf[n] = g
                    n += 1
                    if 2 * n > size:
                        size *= 2
                        keys, stamps = _reinsert(buf, n, f, size)
            cnt = 0
            for m in range(n):
                g = buf[m]
                if _faces_intersect(vertices, faces, f, g, tol):
                    if mode == 2:
                        pairs[pair_offsets[f] + cnt, 0] = f
                        pairs[pair_offsets[f] + cnt, 1] = g
                    elif mode == 0:
                        face_hit[f] = 1
                        face_hit[g] = 1
                    cnt += 1
            counts[f] = cnt
    return counts


@numba.njit(cache=True)
def vertex_stats(vertices, used):
    """Bounding box and largest absolute coordinate of the used vertices.

    Parameters
    ----------
    vertices : (V, 3) float64
    used : (V,) bool

    Returns
    -------
    lo, hi : (3,) float64
        Bounding box (``+inf`` / ``-inf`` when no vertex is used).
    max_abs : float
    """
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    max_abs = 0.0
    for v in range(vertices.shape[0]):
        if used[v]:
            for k in range(3):
                x = vertices[v, k]
                lo[k] = min(lo[k], x)
                hi[k] = max(hi[k], x)
                max_abs = max(max_abs, abs(x))
    return lo, hi, max_abs


@numba.njit(parallel=True, cache=True)
def morton_keys(boxes, active, lo, scale):
    """Morton (Z-order) code of each box centre, 21 bits per axis.

    Parameters
    ----------
    boxes : (F, 6) float64
    active : (F,) bool
        Inactive faces get the largest key (they sort last).
    lo : (3,) float64
        Lower corner of the domain.
    scale : float
        ``(2**21 - 1) / extent`` of the domain.

    Returns
    -------
    keys : (F,) int64
    """
    n = boxes.shape[0]
    keys = np.empty(n, np.int64)
    for f in numba.prange(n):
        if not active[f]:
            keys[f] = np.iinfo(np.int64).max
            continue
        key = 0
        for k in range(3):
            c = 0.5 * (boxes[f, k] + boxes[f, 3 + k])
            q = np.int64((c - lo[k]) * scale)
            q = min(max(q, 0), 2097151)
            for bit in range(21):
                key |= ((q >> bit) & 1) << (3 * bit + k)
        keys[f] = key
    return keys


@numba.njit(parallel=True, cache=True)
def gather_faces(faces, boxes, perm):
    """``faces[perm]`` and ``boxes[perm]``.

    Parameters
    ----------
    faces : (F, 3) int64
    boxes : (F, 6) float64
    perm : (n,) int64

    Returns
    -------
    sub_faces : (n, 3) int64
    sub_boxes : (n, 6) float64
    """
    n = perm.shape[0]
    sub_faces = np.empty((n, 3), np.int64)
    sub_boxes = np.empty((n, 6))
    for i in numba.prange(n):
        f = perm[i]
        for k in range(3):
            sub_faces[i, k] = faces[f, k]
        for k in range(6):
            sub_boxes[i, k] = boxes[f, k]
    return sub_faces, sub_boxes


@numba.njit(parallel=True, cache=True)
def gather_vertices(vertices, index):
    """``vertices[index]``: (V, 3) float64, (n,) int64 -> (n, 3) float64."""
    n = index.shape[0]
    out = np.empty((n, 3))
    for i in numba.prange(n):
        for k in range(3):
            out[i, k] = vertices[index[i], k]
    return out


@numba.njit(cache=True)
def renumber_vertices(faces, n_vertices):
    """Renumber the vertices in order of first use by ``faces``.

    Parameters
    ----------
    faces : (F, 3) int64
    n_vertices : int

    Returns
    -------
    new_faces : (F, 3) int64
    old_index : (U,) int64
        Original index of each used vertex, in the new order.
    """
    new_id = np.full(n_vertices, -1, np.int64)
    old_index = np.empty(n_vertices, np.int64)
    new_faces = np.empty_like(faces)
    n = 0
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            if new_id[v] < 0:
                new_id[v] = n
                old_index[n] = v
                n += 1
            new_faces[f, k] = new_id[v]
    return new_faces, old_index[:n].copy()


@numba.njit(cache=True)
def faces_intersect(vertices, faces, fi, fj, tol):
    """Public (to the package) single-pair test, for checks and debugging.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    fi, fj : int
        Non-degenerate faces.
    tol : float
        Fold tolerance for faces sharing an edge (absolute).

    Returns
    -------
    bool
    """
    return _faces_intersect(vertices, faces, fi, fj, tol)


@numba.njit(cache=True)
def triangles_intersect_exact(vertices, a, b, c, d, e, f):
    """Closed triangles ``abc`` and ``def`` intersect (exact, without any shortcut; for
    tests). Vertex indices; the triangles must be non-degenerate.

    See :func:`fast_stitch._predicates.tri_tri_exact` (the test shared with the stitchers).
    """
    return tri_tri_exact(vertices, a, b, c, d, e, f)


@numba.njit(cache=True)
def orient3d_sign(vertices, a, b, c, d):
    """Exact sign of ``det[a - d; b - d; c - d]`` (vertex indices; for tests).

    See :func:`fast_stitch._predicates.orient3d`.
    """
    return orient3d(vertices, a, b, c, d)


@numba.njit(cache=True)
def orient2d_sign(vertices, a, b, c, i, j):
    """Exact sign of the 2D orientation on axes ``(i, j)`` (for tests).

    See :func:`fast_stitch._predicates.orient2d`.
    """
    return orient2d(vertices, a, b, c, i, j)
