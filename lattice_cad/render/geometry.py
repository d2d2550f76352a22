"""Display geometry of a lattice graph: struts as tapered tubes, nodes as balls.

The tubes are for pictures only (open prisms with smooth radial normals,
closed off by a ball at every node); the printable mesh is fast_stitch's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.arrays import unique_rows

__all__ = ["tubes", "strut_angles", "node_values"]


def _icosphere(level: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A unit sphere: the icosahedron, each face split in 4 ``level`` times (outward faces)."""
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [
            [-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0],
            [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
            [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1],
        ],
        dtype=np.float64,
    )  # fmt: skip
    f = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ],
        dtype=np.int64,
    )  # fmt: skip
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = unique_rows(edges, return_inverse=True)
        mid = v[uniq].mean(axis=1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = inv.reshape(-1) + len(v)
        n = len(f)
        ab, bc, ca = m[:n], m[n : 2 * n], m[2 * n :]
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        f = np.concatenate(
            [
                np.stack([a, ab, ca], 1),
                np.stack([b, bc, ab], 1),
                np.stack([c, ca, bc], 1),
                np.stack([ab, bc, ca], 1),
            ]
        )
        v = np.concatenate([v, mid])
    return v, f


def strut_angles(nodes: NDArray[np.float64], edges: NDArray[np.int64]) -> NDArray[np.float64]:
    """Angle of every strut to the build plate (the xy plane), in degrees.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64

    Returns
    -------
    (M,) float64
        0 for a horizontal strut, 90 for a vertical one.
    """
    d = nodes[edges[:, 1]] - nodes[edges[:, 0]]
    length = np.linalg.norm(d, axis=1)
    s = np.abs(d[:, 2]) / np.maximum(length, 1e-300)
    return np.degrees(np.arcsin(np.clip(s, 0.0, 1.0)))


def node_values(
    num_nodes: int, edges: NDArray[np.int64], values: NDArray[np.float64], how: str = "max"
) -> NDArray[np.float64]:
    """Per-node values from per-strut-end values ``(M, 2)``: the max or mean over the struts.

    Nodes with no strut get NaN.
    """
    idx = edges.reshape(-1)
    val = np.asarray(values, dtype=np.float64).reshape(-1)
    if how == "max":
        out = np.full(num_nodes, -np.inf)
        np.maximum.at(out, idx, val)
        out[np.isneginf(out)] = np.nan
        return out
    total = np.bincount(idx, weights=val, minlength=num_nodes)
    count = np.bincount(idx, minlength=num_nodes)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def tubes(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    sides: int = 8,
    end_values: NDArray[np.float64] | None = None,
    node_scalars: NDArray[np.float64] | None = None,
    balls: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float32], NDArray[np.float64] | None]:
    """Struts as tapered tubes (``sides``-gon prisms) plus a ball at every node.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
        Radius at each end of each strut.
    sides : int
        Polygon sides of the tubes.
    end_values : (M, 2) float64, optional
        A quantity at each end of each strut (interpolated along the tube).
    node_scalars : (N,) float64, optional
        The quantity on the balls (default: the max of ``end_values`` at the node).
    balls : bool
        Add a ball of the largest incident radius at every node.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Outward-oriented.
    normals : (V, 3) float32
    scalars : (V,) float64 or None
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1, 2)
    from lattice_cad.render import _kernels

    m = len(edges)
    verts = np.empty((2 * sides * m, 3), dtype=np.float64)
    normals = np.empty((2 * sides * m, 3), dtype=np.float32)
    _kernels.tube_vertices(nodes, edges, radii, sides, verts, normals)
    k = np.arange(sides)
    k1 = (k + 1) % sides
    local = np.concatenate(
        [np.stack([k, k1, sides + k1], 1), np.stack([k, sides + k1, sides + k], 1)]
    )
    faces = (local[None, :, :] + (2 * sides * np.arange(m))[:, None, None]).reshape(-1, 3)
    scalars = None
    if end_values is not None:
        ev = np.asarray(end_values, dtype=np.float64).reshape(-1, 2)
        scalars = np.repeat(ev, sides, axis=1).reshape(-1)
    if balls and m:
        used = np.unique(edges)
        big = len(used) > 50_000
        sv, sf = _icosphere(0 if big else 1)
        rmax = node_values(len(nodes), edges, radii, "max")[used]
        bv = nodes[used][:, None, :] + rmax[:, None, None] * sv[None, :, :]
        bf = sf[None, :, :] + (len(verts) + len(sv) * np.arange(len(used)))[:, None, None]
        verts = np.concatenate([verts, bv.reshape(-1, 3)])
        faces = np.concatenate([faces, bf.reshape(-1, 3)])
        normals = np.concatenate([normals, np.tile(sv, (len(used), 1)).astype(np.float32)])
        if scalars is not None:
            ns = (
                np.asarray(node_scalars, dtype=np.float64)
                if node_scalars is not None
                else node_values(len(nodes), edges, end_values, "max")  # type: ignore[arg-type]
            )
            scalars = np.concatenate([scalars, np.repeat(ns[used], len(sv))])
    return verts, faces, normals.astype(np.float32, copy=False), scalars
