"""Will a graph stitch? Profile offsets of :func:`fast_stitch.stitch`, before stitching.

:func:`end_offsets` computes, for every strut end, the distance from the node
to the strut's end profile with exactly the rule of :func:`fast_stitch.stitch`
(``fast_stitch._kernels.hub_offsets`` with the same margin and floor angle).
A strut fits when the offsets of its two ends leave some open cylinder:
``offset[e, 0] + offset[e, 1] < length[e] * (1 - config.MIN_CYLINDER_FRACTION)``;
:func:`misfits` lists the struts that do not.

Profiles: every function takes the stitch's ``segments`` and ``profile``, because the
profile polygons are larger than the strut's circle except with
``profile="inscribed"`` (circumradius ``r * profile_factor(P, profile)``: +10 % at the
default P = 6 with ``"volume"``/``"area"``): offsets and clearances are those of the
enlarged polygons. With ``profile="volume"`` the stitch then scales each hub about its
node (:mod:`fast_stitch.hubvolume`) by ``s_n <= 1`` where the hub is fuller than the
exact solid (the mesh shrinks inside the one checked here), and grows boundary hubs by
at most what keeps ``config.FIT_SLACK`` of each strut free and what the clearance check
allows (``fast_stitch.stitch.cap_growth``: a grown hub never makes a graph that clears
here fail the stitch's check); the offsets returned are those before that scaling.

:func:`clashes` lists the elements that share no node but whose bounding
capsules would overlap (:func:`fast_stitch.stitch`'s ``check_clearance``):
struts passing close to each other away from their nodes, or a strut through
another node's joint. A strut's capsule runs between its two profile centres
with its larger end radius; a joint's ball has the largest distance from the
node to one of its profile vertices. P-gon profiles are inscribed in these, so
elements whose capsules keep apart never overlap in the stitched mesh.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from fast_stitch import _fit_kernels, _kernels
from fast_stitch.hubvolume import profile_factor
from lattice_cad.core import config
from lattice_cad.core.arrays import read_only
from lattice_cad.core.checks import check_segments

__all__ = ["end_offsets", "misfits", "clashes"]


@njit(cache=True, parallel=True, error_model="numpy")
def _node_offsets(
    nodes, edges, radii, scale, offsets, inc_edge, inc_side, shrink, margin, floor_tan, out
):  # fmt: skip
    """``out[e, s]``: end offsets of every strut end, profile radii ``radii * scale``."""
    for n in prange(offsets.shape[0] - 1):
        lo = offsets[n]
        d = offsets[n + 1] - lo
        if d < 2:
            continue
        dirs = np.empty((d, 3))
        rad = np.empty(d)
        for t in range(d):
            e = inc_edge[lo + t]
            s = inc_side[lo + t]
            other = edges[e, 1 - s]
            vx = nodes[other, 0] - nodes[n, 0]
            vy = nodes[other, 1] - nodes[n, 1]
            vz = nodes[other, 2] - nodes[n, 2]
            nn = np.sqrt(vx * vx + vy * vy + vz * vz)
            dirs[t, 0] = vx / nn
            dirs[t, 1] = vy / nn
            dirs[t, 2] = vz / nn
            rad[t] = radii[e, s] * scale
        od = np.empty(d)
        det = np.empty(d, dtype=np.int64)
        _kernels.hub_offsets(dirs, rad, shrink, margin, floor_tan, od, det)
        for t in range(d):
            out[inc_edge[lo + t], inc_side[lo + t]] = od[t]


def _incidence(
    edges: NDArray[np.int64], n: int
) -> tuple[NDArray[np.int64], NDArray[np.int32], NDArray[np.int8]]:
    """CSR node -> (strut, side) incidence: ``offsets`` (n + 1,) int64, ``inc_edge``
    (2M,) int32, ``inc_side`` (2M,) int8 (the order of a stable argsort of the ends)."""
    if len(edges) >= 2**31:  # pragma: no cover - int32 strut ids would overflow
        flat = edges.ravel()
        order = np.argsort(flat, kind="stable")
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(flat, minlength=n), out=offsets[1:])
        return offsets, order // 2, (order % 2).astype(np.int8)  # type: ignore[return-value]
    return _fit_kernels.incidence(read_only(edges), n)


def _radii_array(radii: ArrayLike, shape: tuple[int, int]) -> NDArray[np.float64]:
    """(M, 2) float64 C-contiguous radii: ``radii`` itself when it already is one (no copy:
    the profile factor is applied inside the kernels, see :func:`_profile_scale`)."""
    return np.ascontiguousarray(np.broadcast_to(radii, shape), dtype=np.float64)


def _profile_scale(segments: int, profile: str) -> float:
    """Circumradius of the stitch's profile polygon over the strut radius."""
    return float(profile_factor(check_segments(segments), profile))


def end_offsets(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
    _incidence_arrays: tuple[Any, Any, Any] | None = None,
) -> NDArray[np.float64]:
    """Profile offset of every strut end, as :func:`fast_stitch.stitch` computes it.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
        Radius at each strut end.
    shrink : bool
    segments : int
    profile : {"volume", "area", "inscribed", "circumscribed"}
        As in :func:`fast_stitch.stitch` (the profile polygons' size).

    Returns
    -------
    (M, 2) float64
        Distance from node ``edges[e, s]`` to the centre of strut ``e``'s end
        profile there (0 at a node of degree 1: a flat cap).
    """
    nodes_a = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    edges_a = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    radii_a = _radii_array(radii, edges_a.shape)
    scale = _profile_scale(segments, profile)
    n, m = len(nodes_a), len(edges_a)
    inc = _incidence(edges_a, n) if _incidence_arrays is None else _incidence_arrays
    offsets, inc_edge, inc_side = inc
    out = np.zeros((m, 2))
    floor_tan = math.tan(math.radians(90.0 - config.FLOOR_ANGLE_DEG))
    _node_offsets(
        nodes_a, edges_a, radii_a, scale, offsets, inc_edge, inc_side, bool(shrink),
        config.OFFSET_MARGIN, floor_tan, out,
    )  # fmt: skip
    return out


def misfits(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    slack: float = 0.0,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Struts whose end profiles would meet or cross.

    Parameters
    ----------
    slack : float
        Extra fraction of each strut's length to keep free (0: the exact
        stitch rule).
    segments, profile
        As in :func:`fast_stitch.stitch` (see :func:`end_offsets`).

    Returns
    -------
    bad : (K,) int64
        Indices of the struts that do not fit.
    need : (M,) float64
        ``offset[:, 0] + offset[:, 1]``.
    length : (M,) float64
    """
    nodes_a = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    edges_a = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    off = end_offsets(nodes_a, edges_a, radii, shrink=shrink, segments=segments, profile=profile)
    return _misfits_from(nodes_a, edges_a, off, slack)


_BLOCK = 1 << 16


def strut_lengths(nodes: NDArray[np.float64], edges: NDArray[np.int64]) -> NDArray[np.float64]:
    """(M,) float64: ``np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)``,
    by blocks of struts (no (M, 3) temporaries)."""
    out = np.empty(len(edges))
    for s in range(0, len(edges), _BLOCK):
        e = edges[s : s + _BLOCK]
        out[s : s + _BLOCK] = np.linalg.norm(nodes[e[:, 1]] - nodes[e[:, 0]], axis=1)
    return out


def _misfits_from(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], off: NDArray[np.float64], slack: float
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    need = off.sum(axis=1)
    length = strut_lengths(nodes, edges)
    bad = np.flatnonzero(need >= length * (1.0 - config.MIN_CYLINDER_FRACTION - slack))
    return bad.astype(np.int64), need, length


def clashes(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    margin: float = config.CLEARANCE_MARGIN,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Struts and joints that share no node but would come too close.

    Elements ``0 .. M-1`` are the struts, ``M + n`` the joint at node ``n``
    (nodes of degree >= 2). Two elements clash when they share no node (two
    joints: no strut joins their nodes) and the distance between their
    capsules' axes is below ``(1 + margin) * (r_a + r_b)`` (see the module
    docstring). Radii are those of the profile polygons of ``segments`` and
    ``profile`` (see :func:`end_offsets`). Uses a uniform grid: linear in the
    number of struts.

    Returns
    -------
    pairs : (K, 2) int64
        Clashing element pairs, ``pairs[:, 0] < pairs[:, 1]``, sorted.
    distance : (K,) float64
        Distance between the two axes (segments; a joint's is its node).
    needed : (K,) float64
        ``(1 + margin) * (r_a + r_b)``.
    """
    nodes_a = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    edges_a = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    radii_a = _radii_array(radii, edges_a.shape)
    if len(edges_a) == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0)
    inc = _incidence(edges_a, len(nodes_a))
    off = end_offsets(
        nodes_a, edges_a, radii_a, shrink=shrink, segments=segments, profile=profile,
        _incidence_arrays=inc,
    )  # fmt: skip
    return _clashes(
        nodes_a,
        edges_a,
        radii_a,
        off,
        inc,
        margin,
        radius_scale=_profile_scale(segments, profile),
    )


def _clashes(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    off: NDArray[np.float64],
    inc: tuple[Any, Any, Any],
    margin: float,
    *,
    block: int = 1 << 14,
    radius_scale: float = 1.0,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`clashes` with the end offsets and incidence given, by x-slabs of the grid.

    The profile radii are ``radii * radius_scale`` (the kernels multiply: no scaled copy).

    The grid is the one of ``fast_stitch.stitch._clearance_elements`` (same origin, cell
    and dims); the elements are boxed a slab at a time (about ``block`` elements), each
    slab finds the pairs whose home cell it holds. Same pairs and distances as one pass.
    """
    n, m = len(nodes), len(edges)
    nodes, edges, radii = read_only(nodes), read_only(edges), read_only(radii)
    offsets, inc_edge, inc_side = inc
    pad = 1.0 + margin
    n_el = m + n

    def boxes(ids: NDArray[np.int64]) -> tuple[NDArray[np.float64], ...]:
        k = len(ids)
        seg_a, seg_b, lo, hi = (np.empty((k, 3)) for _ in range(4))
        rad, extent = np.empty(k), np.empty(k)
        _fit_kernels.element_boxes(
            ids, nodes, edges, radii, float(radius_scale), off, offsets, inc_edge, inc_side,
            float(pad), seg_a, seg_b, rad, lo, hi, extent,
        )  # fmt: skip
        return seg_a, seg_b, rad, lo, hi, extent

    # the grid (as _clearance_elements): bounds of the active boxes, median extent
    origin = np.full(3, np.inf)
    top = np.full(3, -np.inf)
    ext = np.empty(n_el)
    n_active = 0
    for s in range(0, n_el, block):
        _, _, rad, lo, hi, extent = boxes(np.arange(s, min(n_el, s + block)))
        act = rad >= 0
        if act.any():
            np.minimum(origin, lo[act].min(axis=0), out=origin)
            np.maximum(top, hi[act].max(axis=0), out=top)
        k = int(act.sum())
        ext[n_active : n_active + k] = extent[act]
        n_active += k
    empty = (np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0))
    if n_active == 0:
        return empty
    cell = max(float(np.median(ext[:n_active], overwrite_input=True)), 1e-300)
    del ext
    span = top - origin
    while True:
        dims = np.maximum(1, np.ceil(span / cell).astype(np.int64))
        if int(np.prod(dims)) <= 4 * n_active + 64:
            break
        cell *= 1.5
    # x-span of every element's box, then slabs of about `block` elements
    first = np.empty(n_el, dtype=np.int32)
    last = np.empty(n_el, dtype=np.int32)
    for s in range(0, n_el, block):
        _, _, rad, lo, hi, _ = boxes(np.arange(s, min(n_el, s + block)))
        _fit_kernels.x_spans(lo, hi, rad, origin, cell, dims, first[s : s + block],
                             last[s : s + block])  # fmt: skip
    nx = int(dims[0])
    start_x, order = _fit_kernels.bucket(first, nx)
    widest = int((last - first).max()) if n_el else 0  # the widest box, in columns
    del first  # the slabs need `last` only
    cuts = [0]
    for x in range(1, nx):
        if start_x[x] - start_x[cuts[-1]] >= block:
            cuts.append(x)
    cuts.append(nx)
    found_pairs, found_dist = [], []
    scale = 1.0 + margin
    for x0, x1 in zip(cuts[:-1], cuts[1:], strict=True):
        # boxes that start at most `widest` columns before the slab and reach into it
        cand = order[start_x[max(0, x0 - widest)] : start_x[x1]]
        ids = np.sort(cand[last[cand] >= x0]).astype(np.int64)
        if len(ids) < 2:
            continue
        seg_a, seg_b, rad, lo, hi, _ = boxes(ids)
        count, members = _fit_kernels.slab_grid(lo, hi, rad, cell, origin, dims, x0, x1 - 1)
        n_cells = len(count) - 1
        n_found = np.zeros(n_cells, dtype=np.int64)
        start = np.zeros(n_cells + 1, dtype=np.int64)
        args = (ids, seg_a, seg_b, rad, lo, hi, cell, origin, dims, x0, count, members, edges,
                offsets, inc_edge, scale)  # fmt: skip
        _fit_kernels.slab_pairs(*args, n_found, start, np.zeros((0, 2), dtype=np.int64),
                                np.zeros(0), False)  # fmt: skip
        np.cumsum(n_found, out=start[1:])
        k = int(start[-1])
        if k:
            pairs = np.empty((k, 2), dtype=np.int64)
            dist = np.empty(k)
            _fit_kernels.slab_pairs(*args, n_found, start, pairs, dist, True)
            found_pairs.append(pairs)
            found_dist.append(dist)
    if not found_pairs:
        return empty
    pairs = np.concatenate(found_pairs)
    dist = np.concatenate(found_dist)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    pairs, dist = pairs[order], dist[order]
    rad = boxes(pairs.ravel())[2].reshape(-1, 2)
    return pairs, dist, (1.0 + margin) * rad.sum(axis=1)
