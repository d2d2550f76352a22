"""The vectorised numpy marching tetrahedra that ``conformal.skin.marching_tets`` used before
its per-voxel work moved to a numba kernel (``conformal/_skin_kernels.py``): the reference
the kernel must reproduce exactly (same vertices, triangles, order and orientation)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

_TETS = np.array(
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]],
    dtype=np.int64,
)
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def reference_marching_tets(
    field: NDArray[np.float64], origin: NDArray[np.float64], h: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Closed, outward-oriented surface ``field = 0`` of a grid sampled field.

    Parameters
    ----------
    field : (nx, ny, nz) float64
        Positive inside, negative outside; must be negative on the whole grid boundary.
    origin : (3,) float64
        Position of sample ``[0, 0, 0]``.
    h : float
        Grid spacing.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Each vertex lies on a grid edge or Freudenthal diagonal, shared by all the
        triangles that cross that edge, so the surface is watertight and 2-manifold.
    """
    # no sample on (or within 0.1 % of a voxel of) the surface: a crossing exactly at a grid
    # point would give zero-area triangles; moving it by at most h / 1000 does not
    step = float(np.abs(np.diff(field, axis=0)).max(initial=0.0))  # field change per voxel
    snap = 1e-3 * step if step > 0 else 1e-12
    f = np.where(np.abs(field) < snap, -snap, field)
    nx, ny, nz = f.shape
    inside = f > 0
    # cubes that the surface crosses
    c = inside[:-1, :-1, :-1]
    corners = [
        inside[dx : nx - 1 + dx, dy : ny - 1 + dy, dz : nz - 1 + dz]
        for dz in (0, 1)
        for dy in (0, 1)
        for dx in (0, 1)
    ]
    any_in = np.zeros_like(c)
    all_in = np.ones_like(c)
    for cc in corners:
        any_in |= cc
        all_in &= cc
    cubes = np.argwhere(any_in & ~all_in)  # (C, 3)
    if len(cubes) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    bits = np.array([[(b >> 0) & 1, (b >> 1) & 1, (b >> 2) & 1] for b in range(8)], dtype=np.int64)
    stride = np.array([ny * nz, nz, 1], dtype=np.int64)
    # tet corner grid indices (T, 4, 3)
    tet_ijk = cubes[:, None, None, :] + bits[_TETS][None, :, :, :]
    tet_ijk = tet_ijk.reshape(-1, 4, 3)
    lin = tet_ijk @ stride  # (T, 4)
    val = f.ravel()[lin]
    ins = val > 0
    n_in = ins.sum(axis=1)
    keep = (n_in > 0) & (n_in < 4)
    lin, val, ins, tet_ijk, n_in = lin[keep], val[keep], ins[keep], tet_ijk[keep], n_in[keep]
    # crossing points on the 6 tet edges, keyed by their grid vertex pair
    a, b = _TET_EDGES[:, 0], _TET_EDGES[:, 1]
    va, vb = val[:, a], val[:, b]  # (T, 6)
    crosses = ins[:, a] != ins[:, b]
    la, lb = lin[:, a], lin[:, b]
    key_lo = np.minimum(la, lb)
    key_hi = np.maximum(la, lb)
    keys = key_lo * (nx * ny * nz) + key_hi  # unique id of a grid segment
    flat_keys = keys[crosses]
    _, first, inv = np.unique(flat_keys, return_index=True, return_inverse=True)
    rows, cols = np.nonzero(crosses)
    rows, cols = rows[first], cols[first]
    pa = origin + tet_ijk[rows, a[cols], :] * h
    pb = origin + tet_ijk[rows, b[cols], :] * h
    ta, tb = va[rows, cols], vb[rows, cols]
    vertices = pa + (ta / (ta - tb))[:, None] * (pb - pa)
    midpoints = 0.5 * (pa + pb)  # the same crossing at mid-edge: never degenerate
    vid = np.full(keys.shape, -1, dtype=np.int64)
    vid[crosses] = inv.reshape(-1)
    # triangles: 1 or 3 inside -> one triangle; 2 inside -> a quad (two triangles)
    tris = []
    odd = np.flatnonzero(n_in != 2)
    if len(odd):
        # the lone vertex (inside when n_in == 1, outside when n_in == 3)
        lone_is_in = n_in[odd] == 1
        lone = np.argmax(ins[odd] == lone_is_in[:, None], axis=1)
        # the 3 edges at the lone vertex
        edge_of = np.array([[0, 1, 2], [0, 3, 4], [1, 3, 5], [2, 4, 5]], dtype=np.int64)
        e3 = edge_of[lone]
        tris.append(np.take_along_axis(vid[odd], e3, axis=1))
    quad = np.flatnonzero(n_in == 2)
    if len(quad):
        # inside pair (p, q), outside pair (r, s): crossing edges p-r, p-s, q-s, q-r form a cycle
        pair_edge = {(0, 1): 0, (0, 2): 1, (0, 3): 2, (1, 2): 3, (1, 3): 4, (2, 3): 5}
        e_idx = np.zeros((16, 4), dtype=np.int64)
        for mask in range(16):
            inn = [i for i in range(4) if (mask >> i) & 1]
            out = [i for i in range(4) if not (mask >> i) & 1]
            if len(inn) != 2:
                continue
            p, q = inn
            r, s = out

            def e(i: int, j: int) -> int:
                return pair_edge[(min(i, j), max(i, j))]

            e_idx[mask] = [e(p, r), e(p, s), e(q, s), e(q, r)]
        masks = (ins[quad] * np.array([1, 2, 4, 8])).sum(axis=1)
        cyc = np.take_along_axis(vid[quad], e_idx[masks], axis=1)
        tris.append(cyc[:, [0, 1, 2]])
        tris.append(cyc[:, [0, 2, 3]])
    faces = np.vstack(tris)
    # orientation: the normal must point from inside to outside (along -grad f). It is
    # decided on the mid-edge triangles, which have the orientation of the real ones (each
    # vertex only slides along its tet edge) but never degenerate, so a crossing at a grid
    # point (a zero-area triangle) cannot get a random orientation.
    src = np.concatenate([odd, quad, quad]) if len(quad) else odd
    wsum = np.where(ins[src], 1.0, 0.0)
    corner_pos = origin + tet_ijk[src] * h
    inside_pt = (corner_pos * wsum[..., None]).sum(axis=1) / wsum.sum(axis=1)[:, None]
    tri_pts = midpoints[faces]
    normal = np.cross(tri_pts[:, 1] - tri_pts[:, 0], tri_pts[:, 2] - tri_pts[:, 0])
    centre = tri_pts.mean(axis=1)
    flip = np.einsum("ij,ij->i", normal, centre - inside_pt) < 0
    faces[flip] = faces[flip][:, ::-1]
    return vertices, faces
