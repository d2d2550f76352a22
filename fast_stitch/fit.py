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
at most what keeps ``config.FIT_SLACK`` of each strut free; the offsets returned are
those before that scaling.

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

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from fast_stitch import _kernels
from fast_stitch.hubvolume import profile_factor
from fast_stitch.stitch import _clearance_elements
from lattice_cad.core import config
from lattice_cad.core.checks import check_segments

__all__ = ["end_offsets", "misfits", "clashes"]


@njit(cache=True, parallel=True, error_model="numpy")
def _node_offsets(nodes, edges, radii, offsets, inc_edge, inc_side, shrink, margin, floor_tan, out):
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
            rad[t] = radii[e, s]
        od = np.empty(d)
        det = np.empty(d, dtype=np.int64)
        _kernels.hub_offsets(dirs, rad, shrink, margin, floor_tan, od, det)
        for t in range(d):
            out[inc_edge[lo + t], inc_side[lo + t]] = od[t]


def _incidence(
    edges: NDArray[np.int64], n: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """CSR node -> (strut, side) incidence: ``offsets`` (n + 1,), ``inc_edge``, ``inc_side``."""
    flat = edges.ravel()
    order = np.argsort(flat, kind="stable")
    inc_edge = (order // 2).astype(np.int64)
    inc_side = (order % 2).astype(np.int64)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=offsets[1:])
    return offsets, inc_edge, inc_side


def _profile_radii(
    radii: ArrayLike, shape: tuple[int, int], segments: int, profile: str
) -> NDArray[np.float64]:
    """(M, 2) float64: circumradii of the stitch's profile polygons."""
    k = profile_factor(check_segments(segments), profile)
    return np.ascontiguousarray(np.broadcast_to(radii, shape), dtype=np.float64) * k


def end_offsets(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
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
    radii_a = _profile_radii(radii, edges_a.shape, segments, profile)
    n, m = len(nodes_a), len(edges_a)
    offsets, inc_edge, inc_side = _incidence(edges_a, n)
    out = np.zeros((m, 2))
    floor_tan = math.tan(math.radians(90.0 - config.FLOOR_ANGLE_DEG))
    _node_offsets(
        nodes_a, edges_a, radii_a, offsets, inc_edge, inc_side, bool(shrink),
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
    need = off.sum(axis=1)
    length = np.linalg.norm(nodes_a[edges_a[:, 1]] - nodes_a[edges_a[:, 0]], axis=1)
    bad = np.flatnonzero(need >= length * (1.0 - config.MIN_CYLINDER_FRACTION - slack))
    return bad.astype(np.int64), need, length


@njit(cache=True, parallel=True, error_model="numpy")
def _clash_pairs(
    seg_a, seg_b, rad, lo, hi, cell, origin, dims, count, members, edges, offsets, inc_edge,
    scale, n_found, start, out_pairs, out_dist, write,
):  # fmt: skip
    """Pairs of non-incident elements closer than ``scale * (rad_i + rad_j)``.

    ``write=False``: count them per cell into ``n_found``; ``write=True``:
    store them from ``start[cell]`` on.
    """
    m = edges.shape[0]
    for c in prange(dims[0] * dims[1] * dims[2]):
        k = 0
        for u in range(count[c], count[c + 1]):
            i = members[u]
            for w in range(u + 1, count[c + 1]):
                j = members[w]
                d2 = _kernels._candidate_d2(
                    i, j, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets,
                    inc_edge, scale,
                )  # fmt: skip
                if d2 < 0.0:
                    continue
                a = min(i, j)
                b = max(i, j)
                if write:
                    out_pairs[start[c] + k, 0] = a
                    out_pairs[start[c] + k, 1] = b
                    out_dist[start[c] + k] = np.sqrt(d2)
                k += 1
        if not write:
            n_found[c] = k


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
    radii_a = _profile_radii(radii, edges_a.shape, segments, profile)
    n, m = len(nodes_a), len(edges_a)
    empty = (np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0))
    if m == 0:
        return empty
    offsets, inc_edge, inc_side = _incidence(edges_a, n)
    off = end_offsets(nodes_a, edges_a, radii_a, shrink=shrink, profile="inscribed")
    vec = nodes_a[edges_a[:, 1]] - nodes_a[edges_a[:, 0]]
    length = np.linalg.norm(vec, axis=1)
    unit = vec / np.where(length > 0, length, 1.0)[:, None]
    seg_a, seg_b, rad, lo, hi, cell, origin, dims = _clearance_elements(
        nodes_a, edges_a, radii_a, off, unit, offsets, inc_edge, inc_side, pad=1.0 + margin
    )
    count, members = _kernels.element_grid(lo, hi, rad, cell, origin, dims)
    n_cells = int(np.prod(dims))
    n_found = np.zeros(n_cells, dtype=np.int64)
    start = np.zeros(n_cells + 1, dtype=np.int64)
    no_pairs = np.zeros((0, 2), dtype=np.int64)
    args = (seg_a, seg_b, rad, lo, hi, cell, origin, dims, count, members, edges_a, offsets,
            inc_edge, 1.0 + margin)  # fmt: skip
    _clash_pairs(*args, n_found, start, no_pairs, np.zeros(0), False)
    np.cumsum(n_found, out=start[1:])
    k = int(start[-1])
    if k == 0:
        return empty
    pairs = np.empty((k, 2), dtype=np.int64)
    dist = np.empty(k)
    _clash_pairs(*args, n_found, start, pairs, dist, True)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    pairs, dist = pairs[order], dist[order]
    return pairs, dist, (1.0 + margin) * rad[pairs].sum(axis=1)
