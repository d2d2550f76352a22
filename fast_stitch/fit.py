"""Will a graph stitch? Profile offsets of :func:`fast_stitch.stitch`, before stitching.

:func:`end_offsets` computes, for every strut end, the distance from the node
to the strut's end profile with exactly the rule of :func:`fast_stitch.stitch`
(``fast_stitch._kernels.hub_offsets`` with the same margin and floor angle).
A strut fits when the offsets of its two ends leave some open cylinder:
``offset[e, 0] + offset[e, 1] < length[e] * (1 - MIN_CYLINDER_FRACTION)``;
:func:`misfits` lists the struts that do not. Offsets do not depend on the
number of segments.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from fast_stitch import _kernels
from fast_stitch.stitch import FLOOR_ANGLE_DEG, MIN_CYLINDER_FRACTION, OFFSET_MARGIN

__all__ = ["end_offsets", "misfits", "MIN_CYLINDER_FRACTION"]


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


def end_offsets(
    nodes: ArrayLike, edges: ArrayLike, radii: ArrayLike, *, shrink: bool = True
) -> NDArray[np.float64]:
    """Profile offset of every strut end, as :func:`fast_stitch.stitch` computes it.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
        Radius at each strut end.
    shrink : bool
        As in :func:`fast_stitch.stitch`.

    Returns
    -------
    (M, 2) float64
        Distance from node ``edges[e, s]`` to the centre of strut ``e``'s end
        profile there (0 at a node of degree 1: a flat cap).
    """
    nodes_a = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    edges_a = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    radii_a = np.ascontiguousarray(np.broadcast_to(radii, edges_a.shape), dtype=np.float64)
    n, m = len(nodes_a), len(edges_a)
    flat = edges_a.ravel()
    order = np.argsort(flat, kind="stable")
    inc_edge = (order // 2).astype(np.int64)
    inc_side = (order % 2).astype(np.int64)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=offsets[1:])
    out = np.zeros((m, 2))
    floor_tan = math.tan(math.radians(90.0 - FLOOR_ANGLE_DEG))
    _node_offsets(
        nodes_a, edges_a, radii_a, offsets, inc_edge, inc_side, bool(shrink),
        OFFSET_MARGIN, floor_tan, out,
    )  # fmt: skip
    return out


def misfits(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    slack: float = 0.0,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Struts whose end profiles would meet or cross.

    Parameters
    ----------
    slack : float
        Extra fraction of each strut's length to keep free (0: the exact
        stitch rule).

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
    off = end_offsets(nodes_a, edges_a, radii, shrink=shrink)
    need = off.sum(axis=1)
    length = np.linalg.norm(nodes_a[edges_a[:, 1]] - nodes_a[edges_a[:, 0]], axis=1)
    bad = np.flatnonzero(need >= length * (1.0 - MIN_CYLINDER_FRACTION - slack))
    return bad.astype(np.int64), need, length
