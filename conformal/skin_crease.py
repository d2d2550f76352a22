"""Sharp creases on the voxel skin's inner surface (the fallback when OCCT's offset fails).

The inner wall of a skin is the level set ``d = t`` of the distance ``d`` to the part's
surface. Marching tetrahedra interpolate that level on grid segments, so away from creases
the surface is within a small fraction of the voxel of it; but the inset of a part has a
sharp crease along every convex edge of the part (and a corner at every convex vertex),
and the triangles that cross a crease cut it off as a chamfer up to about one voxel deep:
there the wall was up to +26 % of ``t`` thick (benchmarks/results/bench_wall.txt).

:func:`sharpen` puts the creases back, in the manner of the extended marching cubes
(Kobbelt et al. 2001), with the *exact* distance to the part's mesh:

1. every vertex is moved along its distance gradient ``n = (v - c) / |v - c|`` (``c`` its
   closest point on the part) onto the level set, ``v <- c + t n``;
2. every face whose centre is off the level by more than ``tol`` gets a new vertex at the
   point nearest its centre that lies on the tangent planes of its three vertices (a
   least-squares fit of the planes ``n_i . x = n_i . v_i``, truncated SVD: on a crease the
   two planes meet in the crease line, at a corner the three in the corner point), and is
   split in three there;
3. the edge between two split faces is flipped to join their two new vertices, so the
   new vertices of a strip of faces across a crease are joined along the crease.

Every change keeps the surface closed and 2-manifold (a split and a flip replace faces by
faces over the same boundary) and is only made when no face turns over and the new points
lie on the level set; a few rounds repeat 2-3 on the faces still off.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["sharpen", "project_to_level"]


def _normals(v: NDArray[np.float64], f: NDArray[np.int64]) -> NDArray[np.float64]:
    t = v[f]
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def _gradients(
    v: NDArray[np.float64], surface: Any, level: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """At points (P, 3): distance (P,), unit gradient (P, 3) away from the surface, the
    level set's tangent plane ``n . x = s`` there (``s``, (P,)) and validity (P,)."""
    d, c = surface.closest(v, max_distance=2.0 * level)
    ok = np.isfinite(d) & (d > 0.5 * level)
    n = np.zeros_like(v)
    n[ok] = (v[ok] - c[ok]) / d[ok][:, None]
    s = np.where(ok, np.einsum("ij,ij->i", n, np.where(ok[:, None], c, 0.0)) + level, 0.0)
    return d, n, s, ok


def project_to_level(
    v: NDArray[np.float64], f: NDArray[np.int64], surface: Any, level: float
) -> NDArray[np.float64]:
    """(V, 3) float64: the vertices moved along their distance gradients onto ``d = level``
    (``surface``: a :class:`conformal.part.Part`); a vertex whose move would turn a face
    over stays where it was."""
    v0 = np.asarray(v, dtype=np.float64)
    d, n, _, ok = _gradients(v0, surface, level)
    out = v0.copy()
    out[ok] = v0[ok] + (level - d[ok])[:, None] * n[ok]
    n0 = _normals(v0, f)
    for _ in range(10):
        bad = np.einsum("ij,ij->i", _normals(out, f), n0) <= 0.0
        if not bad.any():
            break
        idx = f[bad].ravel()
        out[idx] = v0[idx]
    return out


def _plane_points(
    normals: NDArray[np.float64], offsets: NDArray[np.float64], centre: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(B, 3): for each face, the point nearest ``centre`` (B, 3) that minimises the
    squared distances to the planes ``normals[:, i] . x = offsets[:, i]`` (normals:
    (B, 3, 3), offsets: (B, 3)); directions with a singular value below 0.15 of the
    largest are left at the centre (two nearly parallel planes do not make a crease)."""
    b = offsets - np.einsum("bij,bj->bi", normals, centre)
    u, s, vt = np.linalg.svd(normals)
    inv = np.where(s > 0.15 * s[:, :1], 1.0 / np.where(s > 0, s, 1.0), 0.0)
    y = np.einsum("bji,bj->bi", u, b) * inv
    return centre + np.einsum("bji,bj->bi", vt, y)


def _snap_vertices(
    v: NDArray[np.float64], f: NDArray[np.int64], surface: Any, level: float, tol: float
) -> tuple[NDArray[np.float64], int]:
    """Move the vertices still off the level (a projection would turn a face over: near
    a crease or a corner) to the point nearest them on the tangent planes of their own
    and their neighbours' closest level points, where no face turns over."""
    d, n, s, ok = _gradients(v, surface, level)
    off = np.flatnonzero(ok & (np.abs(d - level) > tol))
    if not len(off):
        return v, 0
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    want = np.zeros(len(v), dtype=bool)
    want[off] = True
    sel = want[a] & ok[b]
    a, b = a[sel], b[sel]
    mat = np.zeros((len(v), 3, 3))
    rhs = np.zeros((len(v), 3))
    for i, j in ((a, b), (off, off)):  # the neighbours' planes and the vertex's own
        np.add.at(mat, i, n[j][:, :, None] * n[j][:, None, :])
        np.add.at(rhs, i, n[j] * s[j][:, None])
    mat, rhs, x0 = mat[off], rhs[off], v[off]
    lam, vec = np.linalg.eigh(mat)
    inv = np.where(lam > 0.02 * lam[:, -1:], 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
    r = rhs - np.einsum("bij,bj->bi", mat, x0)
    x = x0 + np.einsum("bij,bj->bi", vec, np.einsum("bji,bj->bi", vec, r) * inv)
    dx = surface.distance(x, max_distance=2.0 * level)
    good = np.isfinite(dx) & (np.abs(dx - level) <= 0.5 * tol)
    good &= np.linalg.norm(x - x0, axis=1) < 2.0 * level
    out = v.copy()
    out[off[good]] = x[good]
    n0 = _normals(v, f)
    for _ in range(10):  # a move that turns a face over is undone
        bad = np.einsum("ij,ij->i", _normals(out, f), n0) <= 0.0
        if not bad.any():
            break
        idx = f[bad].ravel()
        out[idx] = v[idx]
    return out, int(np.count_nonzero(np.any(out != v, axis=1)))


def _split(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
    grad: NDArray[np.float64],
    off: NDArray[np.float64],
    gok: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], int]:
    """Split the faces whose centres are off the level at their crease points.

    Returns the new vertices and faces, for each face the index of its new apex vertex
    (-1: not a child of a split), and the number of faces split.
    """
    dc = surface.distance(v[f].mean(axis=1), max_distance=2.0 * level)
    bad = np.flatnonzero(np.isfinite(dc) & (np.abs(dc - level) > tol) & gok[f].all(axis=1))
    apex = np.full(len(f), -1, dtype=np.int64)
    if not len(bad):
        return v, f, apex, 0
    tri = v[f[bad]]
    centre = tri.mean(axis=1)
    p = _plane_points(grad[f[bad]], off[f[bad]], centre)
    # the point must lie on the level and over the face (barycentric coordinates of its
    # projection inside), and no part of the face may turn over
    dp = surface.distance(p, max_distance=2.0 * level)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    nrm = np.cross(e1, e2)
    nn = np.einsum("ij,ij->i", nrm, nrm)
    w = p - tri[:, 0]
    b1 = np.einsum("ij,ij->i", np.cross(w, e2), nrm) / nn
    b2 = np.einsum("ij,ij->i", np.cross(e1, w), nrm) / nn
    good = np.isfinite(dp) & (np.abs(dp - level) <= 0.5 * tol) & (nn > 0)
    good &= (b1 > 0.02) & (b2 > 0.02) & (1.0 - b1 - b2 > 0.02)
    for k in range(3):
        a, c = tri[:, k], tri[:, (k + 1) % 3]
        good &= np.einsum("ij,ij->i", np.cross(c - a, p - a), nrm) > 0
    bad, p = bad[good], p[good]
    if not len(bad):
        return v, f, apex, 0
    nv = len(v)
    new = nv + np.arange(len(bad), dtype=np.int64)
    a, b, c = f[bad, 0], f[bad, 1], f[bad, 2]
    f = f.copy()
    f[bad] = np.stack([a, b, new], axis=1)
    f = np.vstack([f, np.stack([b, c, new], axis=1), np.stack([c, a, new], axis=1)])
    apex = np.full(len(f), -1, dtype=np.int64)
    apex[bad] = new
    apex[len(f) - 2 * len(bad) :] = np.concatenate([new, new])
    return np.vstack([v, p]), f, apex, len(bad)


def _flip(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    apex: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
) -> tuple[NDArray[np.int64], int]:
    """Flip the base edge ``a b`` of two children ``(a, b, p)``, ``(b, a, q)`` of split
    faces to ``p q`` where the two new faces lie closer to the level (each child has one
    base edge, so the flips of a pass are disjoint)."""
    kids = np.flatnonzero(apex >= 0)
    if not len(kids):
        return f, 0
    # children are stored with the apex last: (a, b, p)
    a, b = f[kids, 0], f[kids, 1]
    nv = np.int64(len(v))
    key = a * nv + b
    order = np.argsort(key)
    skey = key[order]
    twin = b * nv + a
    pos = np.minimum(np.searchsorted(skey, twin), len(skey) - 1)
    has = skey[pos] == twin
    i = kids[has]
    j = kids[order[pos[has]]]
    keep = i < j  # each pair once
    i, j = i[keep], j[keep]
    if not len(i):
        return f, 0
    a, b, p, q = f[i, 0], f[i, 1], f[i, 2], f[j, 2]
    old = np.abs(
        np.stack(
            [
                surface.distance(v[f[i]].mean(axis=1), max_distance=2.0 * level),
                surface.distance(v[f[j]].mean(axis=1), max_distance=2.0 * level),
            ]
        )
        - level
    ).max(axis=0)
    n1 = np.stack([a, q, p], axis=1)
    n2 = np.stack([b, p, q], axis=1)
    new = np.abs(
        np.stack(
            [
                surface.distance(v[n1].mean(axis=1), max_distance=2.0 * level),
                surface.distance(v[n2].mean(axis=1), max_distance=2.0 * level),
                surface.distance(0.5 * (v[p] + v[q]), max_distance=2.0 * level),
            ]
        )
        - level
    ).max(axis=0)
    ref = _normals(v, f[i]) + _normals(v, f[j])
    ok = np.isfinite(new) & (new < old) & (new <= tol)
    for tri in (n1, n2):
        ok &= np.einsum("ij,ij->i", _normals(v, tri), ref) > 0
    i, j = i[ok], j[ok]
    f = f.copy()
    f[i], f[j] = n1[ok], n2[ok]
    return f, len(i)


def sharpen(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
    *,
    rounds: int = 3,
) -> tuple[NDArray[np.float64], NDArray[np.int64], dict[str, int]]:
    """The level set ``d = level`` of the distance to ``surface`` with its creases put back.

    Parameters
    ----------
    v : (V, 3) float64
    f : (F, 3) int64
        A closed, oriented, 2-manifold approximation of the level set (marching tetrahedra).
    surface : conformal.part.Part
        The part whose distance defines the level set.
    level : float
        The distance (the wall thickness), > 0.
    tol : float
        Faces whose centres are farther than this off the level are split and flipped.
    rounds : int
        Passes of split-and-flip.

    Returns
    -------
    vertices : (V', 3) float64
    faces : (F', 3) int64
        Closed, oriented and 2-manifold as the input.
    counts : dict
        ``{"split": faces split, "flipped": edges flipped}`` over all rounds.
    """
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(f, dtype=np.int64)
    counts = {"moved": 0, "split": 0, "flipped": 0}
    if not len(f):
        return v, f, counts
    v = project_to_level(v, f, surface, level)
    v, counts["moved"] = _snap_vertices(v, f, surface, level, tol)
    for _ in range(rounds):
        _, grad, off, gok = _gradients(v, surface, level)
        v, f, apex, n_split = _split(v, f, surface, level, tol, grad, off, gok)
        if not n_split:
            break
        f, n_flip = _flip(v, f, apex, surface, level, tol)
        counts["split"] += n_split
        counts["flipped"] += n_flip
    return v, f, counts
