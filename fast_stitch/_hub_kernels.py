"""Numba kernels of the hub volume correction of :func:`fast_stitch.stitch` (``profile="volume"``).

Arrays and scalars only. See :mod:`fast_stitch.hubvolume` for the derivation.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, error_model="numpy")
def sphere_directions(n):
    """(n, 3) float64: the Fibonacci (golden spiral) directions, equal weights ``4 pi / n``."""
    out = np.empty((n, 3))
    golden = np.pi * (3.0 - np.sqrt(5.0))
    for i in range(n):
        z = 1.0 - 2.0 * (i + 0.5) / n
        rr = np.sqrt(max(0.0, 1.0 - z * z))
        ph = i * golden
        out[i, 0] = rr * np.cos(ph)
        out[i, 1] = rr * np.sin(ph)
        out[i, 2] = z
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def exact_hub_volumes(reps, axis, sign, offsets, inc_edge, inc_side, radii, end_offset, W, out):
    """Volume of the exact solid's part on the node's side of all its profile planes.

    The exact solid near node ``n`` is the ball of radius ``R = max r_i`` united with
    the strut cylinders ``C_i`` (radius ``r_i`` at this end, from the node to the
    profile plane at ``end_offset``), cut by the half-spaces ``x . a_i <= d_i``. It is
    star-shaped about the node, so its volume is ``int rho(w)^3 / 3 dw`` over the unit
    sphere, with the radial function ``rho = min(max(R, max_i rho_Ci), min_i d_i / (w . a_i))``;
    integrated with the equal-weight directions ``W``.

    Parameters
    ----------
    reps : (K,) int64
        Nodes (degree >= 2) to measure.
    axis : (M, 3) float64, sign : (M,) int64
        The stitch's canonical strut axes (``_kernels.edge_frames``): the strut leaves its
        first node along ``sign * axis``. Directions from these, not from the node
        positions, so that translated hubs (one representative per shape) have
        bit-identical volumes whichever member represents them.
    radii : (M, 2) float64
        True strut radii (of the design, not of the polygons).
    end_offset : (M, 2) float64
        Profile offsets.
    W : (Q, 3) float64
    out : (K,) float64, out
    """
    q = W.shape[0]
    wgt = 4.0 * np.pi / q / 3.0
    for ri in prange(reps.shape[0]):
        n = reps[ri]
        lo = offsets[n]
        d = offsets[n + 1] - lo
        a = np.empty((d, 3))
        r = np.empty(d)
        r2 = np.empty(d)
        off = np.empty(d)
        R = 0.0
        for t in range(d):
            e = inc_edge[lo + t]
            s = inc_side[lo + t]
            sg = float(sign[e]) if s == 0 else -float(sign[e])
            a[t, 0] = sg * axis[e, 0]
            a[t, 1] = sg * axis[e, 1]
            a[t, 2] = sg * axis[e, 2]
            r[t] = radii[e, s]
            r2[t] = r[t] * r[t]
            off[t] = end_offset[e, s]
            R = max(R, r[t])
        total = 0.0
        for k in range(q):
            grow = R
            clip = np.inf
            for t in range(d):
                c = W[k, 0] * a[t, 0] + W[k, 1] * a[t, 1] + W[k, 2] * a[t, 2]
                if c <= 0.0:
                    continue
                p = off[t] / c
                clip = min(clip, p)
                if p <= grow:  # the cylinder's radial distance is at most p
                    continue
                s2 = max(0.0, 1.0 - c * c)
                if s2 * p * p > r2[t]:  # leaves through the side: r / sin
                    p = r[t] / np.sqrt(s2)
                grow = max(grow, p)
            rho = min(grow, clip)
            total += rho * rho * rho
        out[ri] = total * wgt


@njit(cache=True, inline="always")
def _rel_vertex(i, axis, sign, frame_u, frame_v, prad, end_offset, P, c):
    """Coordinate ``c`` of profile vertex ``i`` relative to its node: the terms of
    ``_kernels.profile_vertices`` without the node (the same for translated hubs)."""
    e = i // (2 * P)
    side = (i // P) % 2
    k = i % P
    s = float(sign[e]) if side == 0 else -float(sign[e])
    dd = end_offset[e, side] * s
    r = prad[e, side]
    ang = 2.0 * np.pi * k / P
    return dd * axis[e, c] + np.cos(ang) * r * frame_u[e, c] + np.sin(ang) * r * frame_v[e, c]


@njit(cache=True, parallel=True, error_model="numpy")
def hub_mesh_volumes(reps, axis, sign, frame_u, frame_v, faces, face_start, offsets, inc_edge,
                     inc_side, prad, end_offset, P, out):  # fmt: skip
    """Volume of each hub polyhedron: the convex hull of its profiles.

    The hub's triangles (``d P + 2 d - 4`` rows from ``face_start[n]``, outward) plus its
    profile polygons (area ``P / 2 rho^2 sin(2 pi / P)`` at distance ``d_i`` from the node)
    close it; volumes are cones from the node. The vertices are taken relative to the
    node from the stitch's frames (``_kernels.edge_frames``), not from their absolute
    positions, so that translated hubs have bit-identical volumes whichever member
    represents them (a shard and the whole lattice may pick different members).

    Parameters
    ----------
    axis, frame_u, frame_v : (M, 3) float64, sign : (M,) int64
        The stitch's canonical strut frames.
    prad : (M, 2) float64
        Profile circumradius of each strut end.
    out : (K,) float64, out
    """
    poly = 0.5 * P * np.sin(2.0 * np.pi / P)
    for ri in prange(reps.shape[0]):
        n = reps[ri]
        lo = offsets[n]
        d = offsets[n + 1] - lo
        total = 0.0
        for f in range(face_start[n], face_start[n] + d * P + 2 * d - 4):
            i = faces[f, 0]
            j = faces[f, 1]
            k = faces[f, 2]
            ax = _rel_vertex(i, axis, sign, frame_u, frame_v, prad, end_offset, P, 0)
            ay = _rel_vertex(i, axis, sign, frame_u, frame_v, prad, end_offset, P, 1)
            az = _rel_vertex(i, axis, sign, frame_u, frame_v, prad, end_offset, P, 2)
            bx = _rel_vertex(j, axis, sign, frame_u, frame_v, prad, end_offset, P, 0)
            by = _rel_vertex(j, axis, sign, frame_u, frame_v, prad, end_offset, P, 1)
            bz = _rel_vertex(j, axis, sign, frame_u, frame_v, prad, end_offset, P, 2)
            cx = _rel_vertex(k, axis, sign, frame_u, frame_v, prad, end_offset, P, 0)
            cy = _rel_vertex(k, axis, sign, frame_u, frame_v, prad, end_offset, P, 1)
            cz = _rel_vertex(k, axis, sign, frame_u, frame_v, prad, end_offset, P, 2)
            total += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        total /= 6.0
        for t in range(d):
            e = inc_edge[lo + t]
            s = inc_side[lo + t]
            total += poly * prad[e, s] * prad[e, s] * end_offset[e, s] / 3.0
        out[ri] = total


@njit(cache=True, inline="always", error_model="numpy")
def _band_end(s, d, rho, rho_far, body, gap0, gap_far, up):
    """One strut end scaled by ``s`` (:func:`fast_stitch.hubvolume.band_rings`).

    ``r(t)`` is the unscaled strut's radius at distance ``t`` from the end's node (the line
    from ``(d, rho)`` to ``(d + body, rho_far)``). Returns the band ring's offset ``x`` and
    radius ``b = max(s, 1) r(x)``; ``delta(s)``: the volume of the band (frustum from
    ``(s d, s rho)`` to ``(x, b)``) and of the strut from there to the far end's band ring
    with that end unscaled (``T = d + body - gap_far``, radius ``r(T)``), minus the
    unscaled strut's between ``d`` and ``T``; and ``d delta / d s`` (one-sided at ``s = 1``:
    from above where ``up``, else from below). Volumes divided by ``poly / 3`` (a regular
    P-gon of circumradius rho has area ``poly rho^2``)."""
    sig = max(s, 1.0)
    a1 = max(1.0 - s, 0.0) * d
    gap = np.sqrt(a1 * a1 + gap0 * gap0)
    x = s * d + gap
    dx = d - a1 * d / gap
    k = (rho_far - rho) / body
    rx = rho + k * (x - d)
    b = sig * rx
    db = sig * k * dx
    if s > 1.0 or (s == 1.0 and up):
        db += rx
    a = s * rho
    t_far = body - gap_far
    r_t = rho + k * t_far
    qa = a * a + a * b + b * b
    band = gap * qa
    dband = (dx - d) * qa + gap * (2.0 * a * rho + rho * b + a * db + 2.0 * b * db)
    h_mid = t_far - (x - d)
    qm = b * b + b * r_t + r_t * r_t
    mid = h_mid * qm
    dmid = -dx * qm + h_mid * (2.0 * b * db + db * r_t)
    full = t_far * (rho * rho + rho * r_t + r_t * r_t)
    return x, b, band + mid - full, dband + dmid


@njit(cache=True, parallel=True, error_model="numpy")
def band_scales(offsets, inc_edge, inc_side, prad, end_offset, length, gap0, v_hull, v_exact,
                lo_s, hi_s, poly, out):  # fmt: skip
    """Newton's method for every node's ``s_n`` (``hubvolume.hub_scales``), from 1.

    Each node iterates on its own (at most 20 steps, until a step is below 1e-13): its
    result depends on its own struts only, so a shard gives the same bits. The derivative
    at ``s = 1`` is taken on the side the node moves to (grows where the hub is lighter
    than the exact solid)."""
    c = poly / 3.0
    for n in prange(offsets.shape[0] - 1):
        lo = offsets[n]
        hi = offsets[n + 1]
        s = 1.0
        if hi - lo >= 2:
            for _ in range(20):
                g = s * s * s * v_hull[n] - v_exact[n]
                for pass_ in range(2):  # g first (its sign picks the side), then dg
                    up = g < 0.0
                    dg = 3.0 * s * s * v_hull[n]
                    gsum = 0.0
                    for t in range(lo, hi):
                        e = inc_edge[t]
                        sd = inc_side[t]
                        body = length[e] - end_offset[e, 0] - end_offset[e, 1]
                        _, _, de, dde = _band_end(
                            s, end_offset[e, sd], prad[e, sd], prad[e, 1 - sd], body,
                            gap0[e, sd], gap0[e, 1 - sd], up,
                        )  # fmt: skip
                        gsum += c * de
                        dg += c * dde
                    if pass_ == 0:
                        g += gsum
                step = g / dg if dg > 0.0 else 0.0
                new = min(max(s - step, lo_s), hi_s[n])
                moved = abs(new - s) > 1e-13
                s = new
                if not moved:
                    break
        out[n] = s


@njit(cache=True, parallel=True, error_model="numpy")
def band_rings(edges, scale, prad, end_offset, length, gap0, out_x, out_b):
    """(M, 2) band ring offset and radius of every strut end (``hubvolume.band_rings``)."""
    for e in prange(edges.shape[0]):
        body = length[e] - end_offset[e, 0] - end_offset[e, 1]
        for sd in range(2):
            x, b, _, _ = _band_end(
                scale[edges[e, sd]], end_offset[e, sd], prad[e, sd], prad[e, 1 - sd], body,
                gap0[e, sd], gap0[e, 1 - sd], False,
            )  # fmt: skip
            out_x[e, sd] = x
            out_b[e, sd] = b


@njit(cache=True, parallel=True, error_model="numpy")
def taper_cone_pairs(nodes, edges, offsets, inc_edge, inc_side, length, base, off_a, rad_a,
                     off_b, rad_b, far_off_a, far_rad_a, far_off_b, far_rad_b, n_found, start,
                     out, write):  # fmt: skip
    """Pairs of struts at a node that a widening strut may bring together
    (``fast_stitch.hubvolume.taper_cone_pairs``).

    Every strut end (e, s) has two rings at each end of the strut: ``off_a``/``rad_a`` (the
    hub ring) and ``off_b``/``rad_b`` (the band ring; the same arrays where there is none),
    offsets from the end's own node; the rings at the far end, seen from node n, are read
    from ``far_*`` (the same arrays, or bounds). Seen from node ``n = edges[e, s]``, the
    strut lies in the cone of half-angle ``H`` (the largest ``atan(radius / distance)`` of
    its four rings): the frustums between rings are convex hulls of rings inside the cone. The end
    is *loose* when a ring beyond its near hub ring is wider than ``base[e, s]`` (the radius
    the hub was built for): only then can the strut reach a neighbour of the same node.
    A pair at n is listed when one end is loose and ``H_a + H_b >= angle``.

    Two passes: ``write=False`` counts per node (``n_found``), ``write=True`` fills ``out``
    (K, 3) int64 ``(n, e_a, e_b)`` from ``start`` (the exclusive prefix sum of the counts).
    """
    for n in prange(offsets.shape[0] - 1):
        lo = offsets[n]
        d = offsets[n + 1] - lo
        k = 0
        if d >= 2:
            dirs = np.empty((d, 3))
            half = np.empty(d)
            loose = np.zeros(d, dtype=np.bool_)
            for t in range(d):
                e = inc_edge[lo + t]
                s = inc_side[lo + t]
                f = 1 - s
                other = edges[e, f]
                L = length[e]
                for c in range(3):
                    dirs[t, c] = (nodes[other, c] - nodes[n, c]) / L
                h = max(np.arctan2(rad_a[e, s], off_a[e, s]), np.arctan2(rad_b[e, s], off_b[e, s]))
                for far_off, far_rad in (
                    (far_off_a[e, f], far_rad_a[e, f]),
                    (far_off_b[e, f], far_rad_b[e, f]),
                ):
                    dist = L - far_off
                    h = max(h, np.arctan2(far_rad, dist) if dist > 0.0 else 0.5 * np.pi)
                half[t] = h
                widest = max(rad_b[e, s], max(far_rad_a[e, f], far_rad_b[e, f]))
                loose[t] = widest > base[e, s] * (1.0 + 1e-9)
            for a in range(d):
                for b in range(a + 1, d):
                    if not (loose[a] or loose[b]):
                        continue
                    c = dirs[a, 0] * dirs[b, 0] + dirs[a, 1] * dirs[b, 1] + dirs[a, 2] * dirs[b, 2]
                    ang = np.arccos(min(1.0, max(-1.0, c)))
                    if half[a] + half[b] < ang:
                        continue
                    if write:
                        out[start[n] + k, 0] = n
                        ea = inc_edge[lo + a]
                        eb = inc_edge[lo + b]
                        out[start[n] + k, 1] = ea
                        out[start[n] + k, 2] = eb
                    k += 1
        if not write:
            n_found[n] = k
