"""Numba kernels behind :func:`fast_stitch.recheck.recheck` (private).

``@numba.njit(cache=True)`` functions on arrays and scalars only; :mod:`fast_stitch.recheck`
coerces the dtypes and calls them. Each does in one pass what a numpy formulation did with
(F, 3, 3) temporaries and a Python loop over the changed faces, with the same float
comparisons, so the results are the same.
"""

from __future__ import annotations

import numba
import numpy as np

from fast_stitch._check_kernels import vertex_stats


@numba.njit(cache=True)
def face_boxes(vertices, faces):
    """Per-face bounding boxes, their largest extents and the box of them all.

    vertices : (V, 3) float64, faces : (F, 3) int64. Returns ``lo, hi : (F, 3) float64``
    (``vertices[faces].min(axis=1)``, ``.max(axis=1)``), ``ext : (F,) float64``
    (``(hi - lo).max(axis=1)``) and ``g0, top : (3,) float64`` (``lo.min(axis=0)``,
    ``hi.max(axis=0)``).
    """
    n = faces.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    ext = np.empty(n)
    g0 = np.full(3, np.inf)
    top = np.full(3, -np.inf)
    for f in range(n):
        e = -np.inf
        for k in range(3):
            a = vertices[faces[f, 0], k]
            b = vertices[faces[f, 1], k]
            c = vertices[faces[f, 2], k]
            mn = min(a, b, c)
            mx = max(a, b, c)
            lo[f, k] = mn
            hi[f, k] = mx
            e = max(e, mx - mn)
            g0[k] = min(g0[k], mn)
            top[k] = max(top[k], mx)
        ext[f] = e
    return lo, hi, ext, g0, top


@numba.njit(cache=True)
def near_faces(lo, hi, ext, which, eps, cell, g0, dims):
    """Faces whose box meets a box of ``which`` enlarged by ``eps``, and ``which``.

    Parameters
    ----------
    lo, hi : (F, 3) float64
        Face boxes.
    ext : (F,) float64
        Their largest extents.
    which : (K,) int64
        The changed faces.
    eps : float
    cell : float
        Cell of the marking grid (faces with ``ext <= cell`` meet at most 2 cells per axis).
    g0 : (3,) float64
        Lower corner of the grid.
    dims : (3,) int64
        Cells per axis.

    Returns
    -------
    (N,) int64, sorted. The grid only selects the faces tested; the test is the box test
    ``lo <= qhi and hi >= qlo`` against every changed box.
    """
    nk = which.shape[0]
    qlo = np.empty((nk, 3))
    qhi = np.empty((nk, 3))
    for k in range(nk):
        for j in range(3):
            qlo[k, j] = lo[which[k], j] - eps
            qhi[k, j] = hi[which[k], j] + eps
    marked = np.zeros((dims[0], dims[1], dims[2]), np.bool_)
    for k in range(nk):
        a = np.empty(3, np.int64)
        b = np.empty(3, np.int64)
        for j in range(3):
            a[j] = min(max(np.int64(np.floor((qlo[k, j] - g0[j]) / cell)), 0), dims[j] - 1)
            b[j] = min(max(np.int64(np.floor((qhi[k, j] - g0[j]) / cell)), 0), dims[j] - 1)
        for x in range(a[0], b[0] + 1):
            for y in range(a[1], b[1] + 1):
                for z in range(a[2], b[2] + 1):
                    marked[x, y, z] = True
    n = lo.shape[0]
    out = np.zeros(n, np.bool_)
    clo = np.empty(3, np.int64)
    chi = np.empty(3, np.int64)
    for f in range(n):
        hit = ext[f] > cell
        if not hit:
            for j in range(3):
                clo[j] = min(max(np.int64(np.floor((lo[f, j] - g0[j]) / cell)), 0), dims[j] - 1)
                chi[j] = min(max(np.int64(np.floor((hi[f, j] - g0[j]) / cell)), 0), dims[j] - 1)
            for x in (clo[0], chi[0]):
                for y in (clo[1], chi[1]):
                    for z in (clo[2], chi[2]):
                        if marked[x, y, z]:
                            hit = True
        if not hit:
            continue
        for k in range(nk):
            if (
                lo[f, 0] <= qhi[k, 0]
                and lo[f, 1] <= qhi[k, 1]
                and lo[f, 2] <= qhi[k, 2]
                and hi[f, 0] >= qlo[k, 0]
                and hi[f, 1] >= qlo[k, 1]
                and hi[f, 2] >= qlo[k, 2]
            ):
                out[f] = True
                break
    for k in range(nk):
        out[which[k]] = True
    return np.flatnonzero(out)


@numba.njit(cache=True)
def used_extremes(vertices, faces):
    """Bounding box and largest absolute coordinate of the vertices ``faces`` use.

    vertices : (V, 3) float64, faces : (F, 3) int64 (at least one). Returns
    ``lo, hi : (3,) float64`` and ``amax : float``.
    """
    used = np.zeros(vertices.shape[0], np.bool_)
    for f in range(faces.shape[0]):
        for k in range(3):
            used[faces[f, k]] = True
    return vertex_stats(vertices, used)
