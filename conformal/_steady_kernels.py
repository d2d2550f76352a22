"""Numba kernels of :mod:`conformal.steady` (arrays and scalars only, no I/O).

Element quantities (all exact up to rounding):

* ball of radius ``r``: volume ``4/3 pi r^3``, area ``4 pi r^2``, second moment
  about its centre ``3/5 r^2 v``;
* beam *connector* between balls ``(c1, r1)`` and ``(c2, r2)`` with
  ``|c2 - c1| = L > r1 + r2``: the convex hull of the two balls minus both balls.
  Its profile is the common tangent line of the two circles; the solid is the
  frustum between the two tangent circles minus the two spherical caps of the
  balls inside it. Volume and moments are integrals of polynomials of degree
  <= 4 along the axis (3-point Gauss-Legendre is exact); area is the frustum's
  lateral area minus the two cap areas ``2 pi r h``.

Moments are accumulated per *family* (index 0: balls, 1 + p: rack p) as six
numbers: volume, area, first moment about a reference point ``ref`` (3), and
second (spherical) moment ``integral |x - ref|^2 dV``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

_GX = math.sqrt(3.0 / 5.0)
_GW0 = 5.0 / 9.0
_GW1 = 8.0 / 9.0
_PI = math.pi
#: Reassociation lets LLVM vectorise the sums; no assumptions about NaN or inf.
_FAST = {"reassoc", "contract", "arcp", "nsz"}


@numba.njit(cache=True, inline="always", fastmath=_FAST)
def _gl_frustum(za, zb, pa, pb):  # pragma: no cover - numba
    """Volume, axial first moment, second moment about z=0 of a frustum (z, rho linear)."""
    h = 0.5 * (zb - za)
    zm = 0.5 * (za + zb)
    pm = 0.5 * (pa + pb)
    dp = 0.5 * (pb - pa)
    zl = zm - _GX * h
    zh = zm + _GX * h
    ql = (pm - _GX * dp) ** 2
    qm = pm * pm
    qh = (pm + _GX * dp) ** 2
    v = _GW0 * (ql + qh) + _GW1 * qm
    m = _GW0 * (ql * zl + qh * zh) + _GW1 * qm * zm
    j = _GW0 * (ql * (zl * zl + 0.5 * ql) + qh * (zh * zh + 0.5 * qh)) + _GW1 * qm * (
        zm * zm + 0.5 * qm
    )
    f = _PI * h
    return f * v, f * m, f * j


@numba.njit(cache=True, inline="always", fastmath=_FAST)
def _gl_cap(c, r, za, zb):  # pragma: no cover - numba
    """Same for the slab za <= z <= zb of the ball of centre z=c and radius r."""
    h = 0.5 * (zb - za)
    zm = 0.5 * (za + zb)
    zl = zm - _GX * h
    zh = zm + _GX * h
    ql = r * r - (zl - c) * (zl - c)
    qm = r * r - (zm - c) * (zm - c)
    qh = r * r - (zh - c) * (zh - c)
    v = _GW0 * (ql + qh) + _GW1 * qm
    m = _GW0 * (ql * zl + qh * zh) + _GW1 * qm * zm
    j = _GW0 * (ql * (zl * zl + 0.5 * ql) + qh * (zh * zh + 0.5 * qh)) + _GW1 * qm * (
        zm * zm + 0.5 * qm
    )
    f = _PI * h
    return f * v, f * m, f * j


@numba.njit(cache=True, inline="always", fastmath=_FAST)
def connector_local(L, r1, r2):  # pragma: no cover - numba
    """(volume, area, axial first moment, second moment) about the centre of ball 1."""
    sb = (r1 - r2) / L
    cb = math.sqrt(max(0.0, 1.0 - sb * sb))
    z1 = r1 * sb
    p1 = r1 * cb
    z2 = L + r2 * sb
    p2 = r2 * cb
    vf, mf, jf = _gl_frustum(z1, z2, p1, p2)
    v1, m1, j1 = _gl_cap(0.0, r1, z1, r1)
    v2, m2, j2 = _gl_cap(L, r2, L - r2, z2)
    h1 = r1 * (1.0 - sb)
    h2 = r2 * (1.0 + sb)
    slant = L * cb  # length of the common tangent between the tangent circles
    area = _PI * (p1 + p2) * slant - 2.0 * _PI * (r1 * h1 + r2 * h2)
    return vf - v1 - v2, area, mf - m1 - m2, jf - j1 - j2


@numba.njit(cache=True, inline="always", fastmath=_FAST)
def _compose(s1, r1, t1, s2, r2, t2):  # pragma: no cover - numba
    """(s1, r1, t1) after (s2, r2, t2) as (scale, (3, 3), (3,))."""
    r = np.empty((3, 3))
    t = np.empty(3)
    for a in range(3):
        for b in range(3):
            r[a, b] = r1[a, 0] * r2[0, b] + r1[a, 1] * r2[1, b] + r1[a, 2] * r2[2, b]
        t[a] = s1 * (r1[a, 0] * t2[0] + r1[a, 1] * t2[1] + r1[a, 2] * t2[2]) + t1[a]
    return s1 * s2, r, t


@numba.njit(cache=True, parallel=True, fastmath=_FAST)
def family_moments(
    pts,
    usc,
    radii,
    vsc,
    vrot,
    vtr,
    wsc,
    wrot,
    wtr,
    koff,
    racks,
    lo,
    hi,
    ref,
    k0,
    k1,
    out,
    err,
):  # pragma: no cover - numba
    """Moments of all balls and beams with start cluster k in [k0, k1), per (k, j) row.

    Parameters
    ----------
    pts : (ni, n, 3) float64
        ``U^i c_b`` for every i and base ball b.
    usc : (ni,) float64
        ``m_u^i``.
    radii : (n,) float64
        Base ball radii.
    vsc, vrot, vtr : (nj,), (nj, 3, 3), (nj, 3) float64
        ``V^j``.
    wsc, wrot, wtr : (K,), (K, 3, 3), (K, 3) float64
        ``W^(k + z)`` is entry ``k + z + koff``.
    racks : (P, 5) int64
        ``(start, end, di, dj, dk)``.
    lo, hi : (1 + P, 3) int64
        Family f counts the element started at cluster ``(i, j, k)`` when
        ``lo[f] <= (i, j, k) < hi[f]`` (and ``k0 <= k < k1``).
    ref : (3,) float64
        Reference point of the first and second moments.
    out : (rows, 1 + P, 6) float64, rows = (k1 - k0) * nj
        Zeroed on entry; row ``(k - k0) * nj + j`` gets the sums of that row:
        volume, area, first moment about ``ref`` (3), second moment about ``ref``.
    err : (rows, 4) int64
        -1 on entry; gets ``(rack, i, j, k)`` of the first beam whose balls
        overlap (``L <= r1 + r2``) in the row.
    """
    ni = pts.shape[0]
    nb = pts.shape[1]
    nj = vsc.shape[0]
    npk = racks.shape[0]
    rows = (k1 - k0) * nj
    for row in prange(rows):
        k = k0 + row // nj
        j = row - (row // nj) * nj
        kw = k + koff
        o = out[row]
        # start-cluster transform W^k V^j and the row's ball centres
        sm, rm, tm = _compose(wsc[kw], wrot[kw], wtr[kw], vsc[j], vrot[j], vtr[j])
        buf = np.empty((ni, nb, 3))
        for i in range(ni):
            for b in range(nb):
                p0 = pts[i, b, 0]
                p1 = pts[i, b, 1]
                p2 = pts[i, b, 2]
                for c in range(3):
                    buf[i, b, c] = (
                        sm * (rm[c, 0] * p0 + rm[c, 1] * p1 + rm[c, 2] * p2) + tm[c] - ref[c]
                    )
        if lo[0, 1] <= j < hi[0, 1] and lo[0, 2] <= k < hi[0, 2]:
            sv = 0.0
            sa = 0.0
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            sj = 0.0
            for i in range(lo[0, 0], hi[0, 0]):
                for b in range(nb):
                    r = sm * usc[i] * radii[b]
                    v = 4.0 / 3.0 * _PI * r * r * r
                    d0 = buf[i, b, 0]
                    d1 = buf[i, b, 1]
                    d2 = buf[i, b, 2]
                    sv += v
                    sa += 4.0 * _PI * r * r
                    s0 += v * d0
                    s1 += v * d1
                    s2 += v * d2
                    sj += v * (0.6 * r * r + d0 * d0 + d1 * d1 + d2 * d2)
            o[0, 0] += sv
            o[0, 1] += sa
            o[0, 2] += s0
            o[0, 3] += s1
            o[0, 4] += s2
            o[0, 5] += sj
        for q in range(npk):
            f = q + 1
            if not (lo[f, 1] <= j < hi[f, 1] and lo[f, 2] <= k < hi[f, 2]):
                continue
            bs = racks[q, 0]
            be = racks[q, 1]
            di = racks[q, 2]
            jj = j + racks[q, 3]
            ke = kw + racks[q, 4]
            se, re, te = _compose(wsc[ke], wrot[ke], wtr[ke], vsc[jj], vrot[jj], vtr[jj])
            for c in range(3):
                te[c] -= ref[c]
            r00, r01, r02 = re[0, 0], re[0, 1], re[0, 2]
            r10, r11, r12 = re[1, 0], re[1, 1], re[1, 2]
            r20, r21, r22 = re[2, 0], re[2, 1], re[2, 2]
            t0, t1, t2 = te[0], te[1], te[2]
            rs0 = sm * radii[bs]
            re0 = se * radii[be]
            sv = 0.0
            sa = 0.0
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            sj = 0.0
            nbad = 0
            for i in range(lo[f, 0], hi[f, 0]):
                d0 = buf[i, bs, 0]
                d1 = buf[i, bs, 1]
                d2 = buf[i, bs, 2]
                p0 = pts[i + di, be, 0]
                p1 = pts[i + di, be, 1]
                p2 = pts[i + di, be, 2]
                e0 = se * (r00 * p0 + r01 * p1 + r02 * p2) + t0 - d0
                e1 = se * (r10 * p0 + r11 * p1 + r12 * p2) + t1 - d1
                e2 = se * (r20 * p0 + r21 * p1 + r22 * p2) + t2 - d2
                r1 = rs0 * usc[i]
                r2 = re0 * usc[i + di]
                L = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                # branch-free (vectorisable): overlapping balls are counted, then reported
                ok = L > r1 + r2
                nbad += 0 if ok else 1
                Ls = L if ok else 3.0 * (r1 + r2)
                v, a, mz, jl = connector_local(Ls, r1, r2)
                wgt = 1.0 if ok else 0.0
                v *= wgt
                a *= wgt
                jl *= wgt
                mz *= wgt / Ls
                sv += v
                sa += a
                s0 += mz * e0 + v * d0
                s1 += mz * e1 + v * d1
                s2 += mz * e2 + v * d2
                sj += (
                    jl
                    + 2.0 * mz * (e0 * d0 + e1 * d1 + e2 * d2)
                    + v * (d0 * d0 + d1 * d1 + d2 * d2)
                )
            if nbad > 0 and err[row, 0] < 0:
                for i in range(lo[f, 0], hi[f, 0]):
                    p0 = pts[i + di, be, 0]
                    p1 = pts[i + di, be, 1]
                    p2 = pts[i + di, be, 2]
                    e0 = se * (r00 * p0 + r01 * p1 + r02 * p2) + t0 - buf[i, bs, 0]
                    e1 = se * (r10 * p0 + r11 * p1 + r12 * p2) + t1 - buf[i, bs, 1]
                    e2 = se * (r20 * p0 + r21 * p1 + r22 * p2) + t2 - buf[i, bs, 2]
                    L = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                    if not L > rs0 * usc[i] + re0 * usc[i + di]:
                        err[row, 0] = q
                        err[row, 1] = i
                        err[row, 2] = j
                        err[row, 3] = k
                        break
            o[f, 0] += sv
            o[f, 1] += sa
            o[f, 2] += s0
            o[f, 3] += s1
            o[f, 4] += s2
            o[f, 5] += sj
    return 0


def empty_outputs(rows: int, families: int) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed ``out`` and ``err`` arrays for :func:`family_moments`."""
    return np.zeros((rows, families, 6)), np.full((rows, 4), -1, dtype=np.int64)
