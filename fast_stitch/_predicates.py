"""Geometric predicates shared by the stitchers and the checker (private).

This is the only code that :mod:`fast_stitch.check` shares with the stitchers
(:mod:`fast_stitch.stitch`, :mod:`fast_stitch.lslt`). It holds exactly what the
stitchers call, and what that needs:

* :func:`tri_tri`: exact closed triangle/triangle intersection of two
  triangles without common vertices (Guigue & Devillers 2003 on exact
  orientation signs, after float-filtered shortcuts). The stitchers'
  clearance tests (``_kernels.clearance``, ``_lslt_kernels.tri_pairs``) call
  it on triangles of elements that share no node; the checker calls it on
  face pairs without a common vertex.
* :func:`box_stats`: bounding box of a set of active boxes. The default
  stitcher uses it for the bounds of its clearance grid, the checker for the
  Morton order of its faces.
* the helpers of :func:`tri_tri`: the exact orientation signs :func:`orient3d`
  and :func:`orient2d` (a float filter with Shewchuk's static error bound,
  Shewchuk's adaptive stages, then exact expansion arithmetic), the filter
  alone :func:`orient3d_filter`, :func:`drop_axis`, :func:`mixed`,
  :func:`point_in_tri_2d`, :func:`seg_seg_2d`, :func:`edge_separates_2d` and
  the private ones below; and :func:`tri_tri_exact`, the same test without the
  float shortcuts (a reference for tests).

The checker also uses the public helpers above inside its own tests, but
everything else of it is its own and is *not* shared: edge topology,
components and winding numbers, degenerate (zero-area) faces, the broadphase
grid, the exact tests of faces that share a vertex or an edge (fold
tolerance), the touching-boxes shortcut (see :mod:`fast_stitch._check_kernels`).

Because of this sharing, a bug in :func:`tri_tri` (or below it) could hide in
both: the stitcher's clearance check would miss an overlap and the checker
would miss the same self-intersection. The test suite guards against that with
checkers that share no code with this package: ``independent_check`` /
``assert_valid`` in ``tests/conftest.py`` judge every stitched mesh with
trimesh (watertight, consistent winding, outward volume), manifold3d (manifold
status) and pymeshlab (self-intersecting faces), and ``tests/test_check.py``
compares the checker with pymeshlab, trimesh and manifold3d and these
predicates with brute force and exact rational arithmetic.
``tests/test_shared_predicates.py`` keeps the sharing to this module.

Everything here is a ``@numba.njit(cache=True)`` function on arrays and
scalars. Names without a leading underscore are used by other modules of the
package; the others are internal to this one. Triangles and points are given
by vertex index into ``vertices : (V, 3) float64``.
"""

from __future__ import annotations

import numba
import numpy as np

_EPS = 2.0**-53
_SPLITTER = 134217729.0  # 2**27 + 1
_O3D_ERRBOUND = (7.0 + 56.0 * _EPS) * _EPS
_O3D_ERRBOUND_B = (3.0 + 28.0 * _EPS) * _EPS
_O3D_ERRBOUND_C = (26.0 + 288.0 * _EPS) * _EPS * _EPS
_CCW_ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS
_CCW_ERRBOUND_B = (2.0 + 12.0 * _EPS) * _EPS
_CCW_ERRBOUND_C = (9.0 + 64.0 * _EPS) * _EPS * _EPS
_RESULT_ERRBOUND = (3.0 + 8.0 * _EPS) * _EPS
_EXP_BUF = 256  # long enough for every expansion built below (orient3d needs <= 192)


# --------------------------------------------------------------------------------------
# Error-free transformations and expansion arithmetic (Shewchuk 1997)
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _two_sum(a, b):
    """Exact ``a + b = x + y`` with ``x = fl(a + b)``."""
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@numba.njit(cache=True)
def _two_diff(a, b):
    """Exact ``a - b = x + y`` with ``x = fl(a - b)``."""
    x = a - b
    bv = a - x
    av = x + bv
    return x, (a - av) + (bv - b)


@numba.njit(cache=True)
def _split(a):
    c = _SPLITTER * a
    big = c - a
    hi = c - big
    return hi, a - hi


@numba.njit(cache=True)
def _two_product(a, b):
    """Exact ``a * b = x + y`` with ``x = fl(a * b)`` (Dekker's product)."""
    x = a * b
    ahi, alo = _split(a)
    bhi, blo = _split(b)
    err1 = x - ahi * bhi
    err2 = err1 - alo * bhi
    err3 = err2 - ahi * blo
    return x, alo * blo - err3


@numba.njit(cache=True)
def _two_two_diff(a1, a0, b1, b0):
    """Exact ``(a1 + a0) - (b1 + b0) = x3 + x2 + x1 + x0`` (Shewchuk's Two_Two_Diff)."""
    i, x0 = _two_diff(a0, b0)
    j, z0 = _two_sum(a1, i)
    i, x1 = _two_diff(z0, b1)
    x3, x2 = _two_sum(j, i)
    return x3, x2, x1, x0


@numba.njit(cache=True)
def _exp_scale(e, elen, b, h):
    """``h = e * b`` for an expansion ``e[:elen]`` (float64); returns the length of ``h``."""
    q, hh = _two_product(e[0], b)
    n = 0
    if hh != 0.0:
        h[n] = hh
        n += 1
    for i in range(1, elen):
        p1, p0 = _two_product(e[i], b)
        s, hh = _two_sum(q, p0)
        if hh != 0.0:
            h[n] = hh
            n += 1
        q, hh = _two_sum(p1, s)
        if hh != 0.0:
            h[n] = hh
            n += 1
    if q != 0.0 or n == 0:
        h[n] = q
        n += 1
    return n


@numba.njit(cache=True)
def _exp_sum(e, elen, f, flen, h):
    """``h = e + f``: merge by magnitude, then a Two-Sum chain (zero components dropped)."""
    i = 0
    j = 0
    if abs(f[0]) > abs(e[0]):
        q = e[0]
        i = 1
    else:
        q = f[0]
        j = 1
    n = 0
    while i < elen or j < flen:
        if j >= flen or (i < elen and abs(f[j]) > abs(e[i])):
            g = e[i]
            i += 1
        else:
            g = f[j]
            j += 1
        q, hh = _two_sum(q, g)
        if hh != 0.0:
            h[n] = hh
            n += 1
    if q != 0.0 or n == 0:
        h[n] = q
        n += 1
    return n


@numba.njit(cache=True)
def _exp_diff2(a, b, out):
    """Exact ``a - b`` as an expansion in ``out``; returns its length (1 or 2)."""
    x, y = _two_diff(a, b)
    if y != 0.0:
        out[0] = y
        out[1] = x
        return 2
    out[0] = x
    return 1


@numba.njit(cache=True)
def _exp_mul(e, elen, f, flen, h, t1, t2):
    """``h = e * f`` for two expansions; ``t1``, ``t2`` are work buffers."""
    n = _exp_scale(e, elen, f[0], h)
    for k in range(1, flen):
        m = _exp_scale(e, elen, f[k], t1)
        n = _exp_sum(h, n, t1, m, t2)
        for i in range(n):
            h[i] = t2[i]
    return n


@numba.njit(cache=True)
def _exp_two_by_two(e1, l1, f1, m1, e2, l2, f2, m2, h, w):
    """``h = e1 * f1 - e2 * f2``; ``w`` is a (4, _EXP_BUF) work array."""
    n1 = _exp_mul(e1, l1, f1, m1, w[0], w[2], w[3])
    n2 = _exp_mul(e2, l2, f2, m2, w[1], w[2], w[3])
    for i in range(n2):
        w[1, i] = -w[1, i]
    return _exp_sum(w[0], n1, w[1], n2, h)


@numba.njit(cache=True)
def _exp_sign(e, n):
    x = e[n - 1]
    if x > 0.0:
        return 1
    if x < 0.0:
        return -1
    return 0


# --------------------------------------------------------------------------------------
# Orientation predicates on mesh vertices (by index)
# --------------------------------------------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _orient3d_exact(vertices, a, b, c, d):
    buf = np.empty((9, 2))
    ln = np.empty(9, np.int64)
    for k in range(3):
        ln[k] = _exp_diff2(vertices[a, k], vertices[d, k], buf[k])
        ln[3 + k] = _exp_diff2(vertices[b, k], vertices[d, k], buf[3 + k])
        ln[6 + k] = _exp_diff2(vertices[c, k], vertices[d, k], buf[6 + k])
    w = np.empty((4, _EXP_BUF))
    m = np.empty(_EXP_BUF)
    p = np.empty((3, _EXP_BUF))
    pl = np.empty(3, np.int64)
    acc = np.empty(_EXP_BUF)
    acc2 = np.empty(_EXP_BUF)
    # det[A; B; C] = A . (B x C) with A = a - d, B = b - d, C = c - d
    for k in range(3):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        # (B x C)_k = B_k1 * C_k2 - B_k2 * C_k1
        mn = _exp_two_by_two(
            buf[3 + k1], ln[3 + k1], buf[6 + k2], ln[6 + k2],
            buf[3 + k2], ln[3 + k2], buf[6 + k1], ln[6 + k1], m, w,
        )  # fmt: skip
        pl[k] = _exp_mul(m, mn, buf[k], ln[k], p[k], w[0], w[1])
    n = _exp_sum(p[0], pl[0], p[1], pl[1], acc)
    n = _exp_sum(acc, n, p[2], pl[2], acc2)
    return _exp_sign(acc2, n)


@numba.njit(cache=True)
def orient3d_filter(vertices, a, b, c, d):
    """Sign of ``det[a - d; b - d; c - d]`` if the float evaluation is certain, else 2."""
    adx = vertices[a, 0] - vertices[d, 0]
    ady = vertices[a, 1] - vertices[d, 1]
    adz = vertices[a, 2] - vertices[d, 2]
    bdx = vertices[b, 0] - vertices[d, 0]
    bdy = vertices[b, 1] - vertices[d, 1]
    bdz = vertices[b, 2] - vertices[d, 2]
    cdx = vertices[c, 0] - vertices[d, 0]
    cdy = vertices[c, 1] - vertices[d, 1]
    cdz = vertices[c, 2] - vertices[d, 2]
    bdxcdy = bdx * cdy
    cdxbdy = cdx * bdy
    cdxady = cdx * ady
    adxcdy = adx * cdy
    adxbdy = adx * bdy
    bdxady = bdx * ady
    det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady)
    perm = (
        (abs(bdxcdy) + abs(cdxbdy)) * abs(adz)
        + (abs(cdxady) + abs(adxcdy)) * abs(bdz)
        + (abs(adxbdy) + abs(bdxady)) * abs(cdz)
    )
    bound = _O3D_ERRBOUND * perm
    if det > bound:
        return 1
    if -det > bound:
        return -1
    if perm == 0.0:
        return 0
    return 2


@numba.njit(cache=True)
def _orient3d_adapt(vertices, a, b, c, d):
    """Stages B and C of Shewchuk's adaptive orient3d, then the exact evaluation."""
    pa0 = vertices[a, 0]
    pa1 = vertices[a, 1]
    pa2 = vertices[a, 2]
    pb0 = vertices[b, 0]
    pb1 = vertices[b, 1]
    pb2 = vertices[b, 2]
    pc0 = vertices[c, 0]
    pc1 = vertices[c, 1]
    pc2 = vertices[c, 2]
    pd0 = vertices[d, 0]
    pd1 = vertices[d, 1]
    pd2 = vertices[d, 2]
    adx = pa0 - pd0
    bdx = pb0 - pd0
    cdx = pc0 - pd0
    ady = pa1 - pd1
    bdy = pb1 - pd1
    cdy = pc1 - pd1
    adz = pa2 - pd2
    bdz = pb2 - pd2
    cdz = pc2 - pd2
    permanent = (
        (abs(bdx * cdy) + abs(cdx * bdy)) * abs(adz)
        + (abs(cdx * ady) + abs(adx * cdy)) * abs(bdz)
        + (abs(adx * bdy) + abs(bdx * ady)) * abs(cdz)
    )
    ws = np.empty(72)
    m = ws[64:68]
    # stage B: exact determinant of the rounded differences
    p1, p0 = _two_product(bdx, cdy)
    q1, q0 = _two_product(cdx, bdy)
    m[3], m[2], m[1], m[0] = _two_two_diff(p1, p0, q1, q0)
    alen = _exp_scale(m, 4, adz, ws[0:8])
    p1, p0 = _two_product(cdx, ady)
    q1, q0 = _two_product(adx, cdy)
    m[3], m[2], m[1], m[0] = _two_two_diff(p1, p0, q1, q0)
    blen = _exp_scale(m, 4, bdz, ws[8:16])
    p1, p0 = _two_product(adx, bdy)
    q1, q0 = _two_product(bdx, ady)
    m[3], m[2], m[1], m[0] = _two_two_diff(p1, p0, q1, q0)
    clen = _exp_scale(m, 4, cdz, ws[16:24])
    ablen = _exp_sum(ws[0:8], alen, ws[8:16], blen, ws[24:40])
    flen = _exp_sum(ws[24:40], ablen, ws[16:24], clen, ws[40:64])
    det = 0.0
    for i in range(flen):
        det += ws[40 + i]
    bound = _O3D_ERRBOUND_B * permanent
    if det >= bound and det != 0.0:
        return 1
    if -det >= bound and det != 0.0:
        return -1
    # stage C: first-order correction with the tails of the differences
    adxt = _two_diff(pa0, pd0)[1]
    bdxt = _two_diff(pb0, pd0)[1]
    cdxt = _two_diff(pc0, pd0)[1]
    adyt = _two_diff(pa1, pd1)[1]
    bdyt = _two_diff(pb1, pd1)[1]
    cdyt = _two_diff(pc1, pd1)[1]
    adzt = _two_diff(pa2, pd2)[1]
    bdzt = _two_diff(pb2, pd2)[1]
    cdzt = _two_diff(pc2, pd2)[1]
    if (
        adxt == 0.0
        and bdxt == 0.0
        and cdxt == 0.0
        and adyt == 0.0
        and bdyt == 0.0
        and cdyt == 0.0
        and adzt == 0.0
        and bdzt == 0.0
        and cdzt == 0.0
    ):
        return _exp_sign(ws[40:64], flen)  # the differences were exact
    bound = _O3D_ERRBOUND_C * permanent + _RESULT_ERRBOUND * abs(det)
    det += (
        (
            adz * ((bdx * cdyt + cdy * bdxt) - (bdy * cdxt + cdx * bdyt))
            + adzt * (bdx * cdy - bdy * cdx)
        )
        + (
            bdz * ((cdx * adyt + ady * cdxt) - (cdy * adxt + adx * cdyt))
            + bdzt * (cdx * ady - cdy * adx)
        )
        + (
            cdz * ((adx * bdyt + bdy * adxt) - (ady * bdxt + bdx * adyt))
            + cdzt * (adx * bdy - ady * bdx)
        )
    )
    if det >= bound and det != 0.0:
        return 1
    if -det >= bound and det != 0.0:
        return -1
    return _orient3d_exact(vertices, a, b, c, d)


@numba.njit(cache=True)
def orient3d(vertices, a, b, c, d):
    """Exact sign of ``det[a - d; b - d; c - d]`` for vertex indices ``a, b, c, d``.

    Zero iff the four points are coplanar; swapping two arguments flips the sign.
    """
    s = orient3d_filter(vertices, a, b, c, d)
    if s != 2:
        return s
    return _orient3d_adapt(vertices, a, b, c, d)


@numba.njit(cache=True)
def _orient2d_exact(vertices, a, b, c, i, j):
    buf = np.empty((4, 2))
    l0 = _exp_diff2(vertices[a, i], vertices[c, i], buf[0])
    l1 = _exp_diff2(vertices[a, j], vertices[c, j], buf[1])
    l2 = _exp_diff2(vertices[b, i], vertices[c, i], buf[2])
    l3 = _exp_diff2(vertices[b, j], vertices[c, j], buf[3])
    w = np.empty((4, 16))
    h = np.empty(16)
    n = _exp_two_by_two(buf[0], l0, buf[3], l3, buf[1], l1, buf[2], l2, h, w)
    return _exp_sign(h, n)


@numba.njit(cache=True)
def _orient2d_filter(vertices, a, b, c, i, j):
    """Sign of the 2D orientation on axes ``(i, j)`` if the float evaluation is certain, else 2."""
    acx = vertices[a, i] - vertices[c, i]
    bcy = vertices[b, j] - vertices[c, j]
    acy = vertices[a, j] - vertices[c, j]
    bcx = vertices[b, i] - vertices[c, i]
    left = acx * bcy
    right = acy * bcx
    det = left - right
    bound = _CCW_ERRBOUND * (abs(left) + abs(right))
    if det > bound:
        return 1
    if -det > bound:
        return -1
    if left == 0.0 and right == 0.0:
        return 0
    return 2


@numba.njit(cache=True)
def _orient2d_adapt(vertices, a, b, c, i, j):
    """Stages B and C of Shewchuk's adaptive orient2d, then the exact evaluation."""
    pa0 = vertices[a, i]
    pa1 = vertices[a, j]
    pb0 = vertices[b, i]
    pb1 = vertices[b, j]
    pc0 = vertices[c, i]
    pc1 = vertices[c, j]
    acx = pa0 - pc0
    bcx = pb0 - pc0
    acy = pa1 - pc1
    bcy = pb1 - pc1
    left1, left0 = _two_product(acx, bcy)
    right1, right0 = _two_product(acy, bcx)
    detsum = abs(left1) + abs(right1)
    x3, x2, x1, x0 = _two_two_diff(left1, left0, right1, right0)
    det = x0 + x1 + x2 + x3
    bound = _CCW_ERRBOUND_B * detsum
    if det >= bound and det != 0.0:
        return 1
    if -det >= bound and det != 0.0:
        return -1
    acxt = _two_diff(pa0, pc0)[1]
    bcxt = _two_diff(pb0, pc0)[1]
    acyt = _two_diff(pa1, pc1)[1]
    bcyt = _two_diff(pb1, pc1)[1]
    if acxt == 0.0 and acyt == 0.0 and bcxt == 0.0 and bcyt == 0.0:
        # exact differences: the sign of the exact expansion x3 + x2 + x1 + x0
        for x in (x3, x2, x1, x0):
            if x > 0.0:
                return 1
            if x < 0.0:
                return -1
        return 0
    bound = _CCW_ERRBOUND_C * detsum + _RESULT_ERRBOUND * abs(det)
    det += (acx * bcyt + bcy * acxt) - (acy * bcxt + bcx * acyt)
    if det >= bound and det != 0.0:
        return 1
    if -det >= bound and det != 0.0:
        return -1
    return _orient2d_exact(vertices, a, b, c, i, j)


@numba.njit(cache=True)
def orient2d(vertices, a, b, c, i, j):
    """Exact sign of the 2D orientation of vertices ``a, b, c`` projected on axes ``(i, j)``."""
    s = _orient2d_filter(vertices, a, b, c, i, j)
    if s != 2:
        return s
    return _orient2d_adapt(vertices, a, b, c, i, j)


@numba.njit(cache=True)
def drop_axis(vertices, a, b, c):
    """Index of the largest component of the (float) normal of triangle ``a, b, c``."""
    ux = vertices[b, 0] - vertices[a, 0]
    uy = vertices[b, 1] - vertices[a, 1]
    uz = vertices[b, 2] - vertices[a, 2]
    vx = vertices[c, 0] - vertices[a, 0]
    vy = vertices[c, 1] - vertices[a, 1]
    vz = vertices[c, 2] - vertices[a, 2]
    nx = abs(uy * vz - uz * vy)
    ny = abs(uz * vx - ux * vz)
    nz = abs(ux * vy - uy * vx)
    if nx >= ny and nx >= nz:
        return 0
    if ny >= nz:
        return 1
    return 2


# --------------------------------------------------------------------------------------
# Exact segment / triangle tests in 2D
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def mixed(s1, s2, s3):
    """True iff the three signs contain both a strictly positive and a strictly negative one."""
    return (s1 > 0 or s2 > 0 or s3 > 0) and (s1 < 0 or s2 < 0 or s3 < 0)


@numba.njit(cache=True)
def point_in_tri_2d(vertices, x, a, b, c, i, j):
    """Closed point-in-triangle test in the projection on axes ``(i, j)``."""
    return not mixed(
        orient2d(vertices, a, b, x, i, j),
        orient2d(vertices, b, c, x, i, j),
        orient2d(vertices, c, a, x, i, j),
    )


@numba.njit(cache=True)
def seg_seg_2d(vertices, p, q, a, b, i, j):
    """Closed segment/segment intersection in the projection on axes ``(i, j)``."""
    o1 = orient2d(vertices, p, q, a, i, j)
    o2 = orient2d(vertices, p, q, b, i, j)
    if o1 * o2 > 0:
        return False
    o3 = orient2d(vertices, a, b, p, i, j)
    o4 = orient2d(vertices, a, b, q, i, j)
    if o3 * o4 > 0:
        return False
    if o1 == 0 and o2 == 0:
        # collinear: the intervals must overlap on both axes
        for ax in (i, j):
            lo1 = min(vertices[p, ax], vertices[q, ax])
            hi1 = max(vertices[p, ax], vertices[q, ax])
            lo2 = min(vertices[a, ax], vertices[b, ax])
            hi2 = max(vertices[a, ax], vertices[b, ax])
            if max(lo1, lo2) > min(hi1, hi2):
                return False
    return True


# --------------------------------------------------------------------------------------
# Triangle / triangle intersection (Guigue & Devillers 2003, exact signs)
# --------------------------------------------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _tri_tri_coplanar(vertices, a, b, c, d, e, f):
    k = drop_axis(vertices, a, b, c)
    i = (k + 1) % 3
    j = (k + 2) % 3
    t1 = (a, b, c)
    t2 = (d, e, f)
    for m in range(3):
        p = t1[m]
        q = t1[(m + 1) % 3]
        for n in range(3):
            if seg_seg_2d(vertices, p, q, t2[n], t2[(n + 1) % 3], i, j):
                return True
    # no edge crossings: intersect iff one triangle lies inside the other
    if point_in_tri_2d(vertices, d, a, b, c, i, j):
        return True
    return point_in_tri_2d(vertices, a, d, e, f, i, j)


@numba.njit(cache=True)
def _same_side_certain(s1, s2, s3):
    """Filtered signs (2 = uncertain) all certainly of the same strict sign."""
    return (s1 == 1 and s2 == 1 and s3 == 1) or (s1 == -1 and s2 == -1 and s3 == -1)


@numba.njit(cache=True)
def edge_separates_2d(vertices, u, v, w, x, y, z, i, j):
    """Line ``uv`` certainly has ``w`` strictly on one side and ``x, y, z`` strictly on the other.

    Float filter only (an uncertain sign means "no"). ``z`` may repeat ``y``.
    """
    sw = _orient2d_filter(vertices, u, v, w, i, j)
    if sw != 1 and sw != -1:
        return False
    return (
        _orient2d_filter(vertices, u, v, x, i, j) == -sw
        and _orient2d_filter(vertices, u, v, y, i, j) == -sw
        and _orient2d_filter(vertices, u, v, z, i, j) == -sw
    )


@numba.njit(cache=True, error_model="numpy")
def _separated_2d(vertices, a, b, c, d, e, f):
    """Quick sufficient test: the projections of ``abc`` and ``def`` (dropping the dominant
    normal axis of ``abc``) are strictly separated by the line of one of their edges.
    If so the triangles are disjoint (a common point would project to a common point)."""
    k = drop_axis(vertices, a, b, c)
    i = (k + 1) % 3
    j = (k + 2) % 3
    return (
        edge_separates_2d(vertices, a, b, c, d, e, f, i, j)
        or edge_separates_2d(vertices, b, c, a, d, e, f, i, j)
        or edge_separates_2d(vertices, c, a, b, d, e, f, i, j)
        or edge_separates_2d(vertices, d, e, f, a, b, c, i, j)
        or edge_separates_2d(vertices, e, f, d, a, b, c, i, j)
        or edge_separates_2d(vertices, f, d, e, a, b, c, i, j)
    )


@numba.njit(cache=True, inline="always")
def _gd_rotation(dp, dq, dr):
    """Guigue-Devillers case table for a triangle (p, q, r) with plane sides dp, dq, dr.

    Returns ``(rot, swap)``: the rotation that puts the vertex alone on its side first
    (0: ``(p, q, r)``, 1: ``(r, p, q)``, 2: ``(q, r, p)``; -1: all three on the plane,
    i.e. coplanar) and whether the other triangle's last two vertices must be swapped.
    """
    if dp > 0:
        if dq > 0:
            return 1, True
        if dr > 0:
            return 2, True
        return 0, False
    if dp < 0:
        if dq < 0:
            return 1, False
        if dr < 0:
            return 2, False
        return 0, True
    if dq < 0:
        if dr >= 0:
            return 2, True
        return 0, False
    if dq > 0:
        if dr > 0:
            return 0, True
        return 2, False
    if dr > 0:
        return 1, False
    if dr < 0:
        return 1, True
    return -1, False


@numba.njit(cache=True, inline="always")
def _rot3(p, q, r, rot):
    """``(p, q, r)`` rotated by ``rot`` (see :func:`_gd_rotation`)."""
    if rot == 1:
        return r, p, q
    if rot == 2:
        return q, r, p
    return p, q, r


@numba.njit(cache=True)
def _gd_tri2(vertices, p1, q1, r1, p2, q2, r2, dp2, dq2, dr2):
    """Guigue-Devillers ``TRI_TRI_3D`` then ``CHECK_MIN_MAX``: ``p1`` is alone on its side
    of the second plane; do the two intervals on the planes' common line overlap?"""
    # choose the order (a, b, c) of the first triangle and (x, y, z) of the second
    rot, swap = _gd_rotation(dp2, dq2, dr2)
    if rot < 0:
        return _tri_tri_coplanar(vertices, p1, q1, r1, p2, q2, r2)
    x, y, z = _rot3(p2, q2, r2, rot)
    a, b, c = (p1, r1, q1) if swap else (p1, q1, r1)
    # CHECK_MIN_MAX(a, b, c, x, y, z)
    if orient3d(vertices, x, a, y, b) > 0:
        return False
    return orient3d(vertices, x, c, z, a) <= 0


@numba.njit(cache=True)
def _gd_main(vertices, p1, q1, r1, p2, q2, r2, dp1, dq1, dr1, dp2, dq2, dr2):
    """Guigue & Devillers (2003), "Fast and robust triangle-triangle overlap test using
    orientation predicates", with exact signs: do the closed triangles overlap?

    ``d*1`` are the (exact) sides of the first triangle's vertices w.r.t. the second
    triangle's oriented plane and ``d*2`` conversely, where the side of ``X`` w.r.t.
    ``(a, b, c)`` is the sign of ``((b - a) x (c - a)) . (X - a)`` = ``orient3d(b, c, X, a)``
    = ``-orient3d(a, b, c, X)``.
    """
    if (dp1 > 0 and dq1 > 0 and dr1 > 0) or (dp1 < 0 and dq1 < 0 and dr1 < 0):
        return False
    if (dp2 > 0 and dq2 > 0 and dr2 > 0) or (dp2 < 0 and dq2 < 0 and dr2 < 0):
        return False
    # rotate the first triangle so that its first vertex is alone on its side, swapping
    # the second triangle's last two vertices (and signs) where the original does
    rot, swap = _gd_rotation(dp1, dq1, dr1)
    if rot < 0:
        return _tri_tri_coplanar(vertices, p1, q1, r1, p2, q2, r2)
    a, b, c = _rot3(p1, q1, r1, rot)
    if swap:
        return _gd_tri2(vertices, a, b, c, p2, r2, q2, dp2, dr2, dq2)
    return _gd_tri2(vertices, a, b, c, p2, q2, r2, dp2, dq2, dr2)


@numba.njit(cache=True)
def tri_tri_exact(vertices, a, b, c, d, e, f):
    """Exact closed triangle/triangle overlap (no shortcut; see :func:`_gd_main`)."""
    return _gd_main(
        vertices, a, b, c, d, e, f,
        -orient3d(vertices, d, e, f, a),
        -orient3d(vertices, d, e, f, b),
        -orient3d(vertices, d, e, f, c),
        -orient3d(vertices, a, b, c, d),
        -orient3d(vertices, a, b, c, e),
        -orient3d(vertices, a, b, c, f),
    )  # fmt: skip


@numba.njit(cache=True)
def tri_tri(vertices, a, b, c, d, e, f):
    """Exact closed triangle/triangle intersection for triangles without common vertices.

    Shared: the checker's narrowphase (:mod:`fast_stitch._check_kernels`) and the
    stitchers' clearance checks (``_kernels.clearance``, ``_lslt_kernels.tri_pairs``)
    call it with the signature ``(vertices, a, b, c, d, e, f)`` (vertex indices).
    """
    # signs of each triangle's vertices w.r.t. the other's plane: certain float ones first
    s1 = orient3d_filter(vertices, a, b, c, d)
    s2 = orient3d_filter(vertices, a, b, c, e)
    s3 = orient3d_filter(vertices, a, b, c, f)
    if _same_side_certain(s1, s2, s3):
        return False
    t1 = orient3d_filter(vertices, d, e, f, a)
    t2 = orient3d_filter(vertices, d, e, f, b)
    t3 = orient3d_filter(vertices, d, e, f, c)
    if _same_side_certain(t1, t2, t3):
        return False
    if s1 == 2 or s2 == 2 or s3 == 2 or t1 == 2 or t2 == 2 or t3 == 2:
        # nearly coplanar: try a cheap 2D separation before exact arithmetic
        if _separated_2d(vertices, a, b, c, d, e, f):
            return False
        if s1 == 2:
            s1 = _orient3d_exact(vertices, a, b, c, d)
        if s2 == 2:
            s2 = _orient3d_exact(vertices, a, b, c, e)
        if s3 == 2:
            s3 = _orient3d_exact(vertices, a, b, c, f)
        if t1 == 2:
            t1 = _orient3d_exact(vertices, d, e, f, a)
        if t2 == 2:
            t2 = _orient3d_exact(vertices, d, e, f, b)
        if t3 == 2:
            t3 = _orient3d_exact(vertices, d, e, f, c)
    return _gd_main(vertices, a, b, c, d, e, f, -t1, -t2, -t3, -s1, -s2, -s3)


# --------------------------------------------------------------------------------------
# Bounding boxes
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def box_stats(lo, hi, active):
    """Bounding box of the active boxes.

    Parameters
    ----------
    lo, hi : (F, 3) float64
        Lower and upper corners of the boxes.
    active : (F,) bool

    Returns
    -------
    lo, hi : (3,) float64
    """
    out_lo = np.full(3, np.inf)
    out_hi = np.full(3, -np.inf)
    for f in range(lo.shape[0]):
        if active[f]:
            for k in range(3):
                out_lo[k] = min(out_lo[k], lo[f, k])
                out_hi[k] = max(out_hi[k], hi[f, k])
    return out_lo, out_hi
