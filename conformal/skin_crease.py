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

#: A crease point may lie at most this many edge lengths from the edge it splits (the rim
#: of a thin cavity, a wedge whose tip lies farther, stays chamfered: 4 did not help).
FAR = 1.0


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


def _project(
    v: NDArray[np.float64], f: NDArray[np.int64], surface: Any, level: float, tol: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`project_to_level`, the gradients (V, 3) and the vertices left off the
    level by more than ``tol`` (V,) bool."""
    d, n, _, ok = _gradients(np.asarray(v, dtype=np.float64), surface, level)
    out = project_to_level(v, f, surface, level, gradients=(d, n, ok))
    moved = np.any(out != v, axis=1)
    return out, n, ok & ~moved & (np.abs(d - level) > tol)


def project_to_level(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    *,
    gradients: Any = None,
) -> NDArray[np.float64]:
    """(V, 3) float64: the vertices moved along their distance gradients onto ``d = level``
    (``surface``: a :class:`conformal.part.Part`); a vertex whose move would turn a face
    over stays where it was."""
    v0 = np.asarray(v, dtype=np.float64)
    if gradients is None:
        d, n, _, ok = _gradients(v0, surface, level)
    else:
        d, n, ok = gradients
    out = v0.copy()
    out[ok] = v0[ok] + (level - d[ok])[:, None] * n[ok]
    return revert_flips(v0, out, f)


def revert_flips(
    v0: NDArray[np.float64], v: NDArray[np.float64], f: NDArray[np.int64], rounds: int = 10
) -> NDArray[np.float64]:
    """(V, 3) float64: ``v`` (the vertices ``v0`` moved) with the vertices of every face
    the move turned over (or flattened) put back where they were in ``v0``, repeated up to
    ``rounds`` times (a vertex put back can turn a neighbour). Modifies ``v`` in place."""
    n0 = _normals(v0, f)
    for _ in range(rounds):
        bad = np.einsum("ij,ij->i", _normals(v, f), n0) <= 0.0
        if not bad.any():
            break
        idx = f[bad].ravel()
        v[idx] = v0[idx]
    return v


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
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
    fixed: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.float64], int]:
    """Move the vertices still off the level (a projection would turn a face over: near
    a crease or a corner) to the point nearest them on the tangent planes of their own
    and their neighbours' closest level points, where no face turns over. ``fixed``
    (V,) bool: vertices that stay (the rim of a piece cut out of a larger surface)."""
    d, n, s, ok = _gradients(v, surface, level)
    movable = ok if fixed is None else ok & ~np.pad(fixed, (0, len(v) - len(fixed)))
    off = np.flatnonzero(movable & (np.abs(d - level) > tol))
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
    # a move that turns a face against the level set (whose outward normal, for the
    # inset, is minus the distance gradient) is undone
    outward = -(n[f[:, 0]] + n[f[:, 1]] + n[f[:, 2]])
    before = np.einsum("ij,ij->i", _normals(v, f), outward) <= 0.0
    for _ in range(10):
        bad = (np.einsum("ij,ij->i", _normals(out, f), outward) <= 0.0) & ~before
        if not bad.any():
            break
        idx = f[bad].ravel()
        out[idx] = v[idx]
    return out, int(np.count_nonzero(np.any(out != v, axis=1)))


def _crease_splits(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
    cos_crease: float = 0.985,
) -> tuple[NDArray[np.float64], NDArray[np.int64], int]:
    """Split every edge across a crease (its ends' distance gradients more than about
    10 degrees apart, its midpoint off the level) at the crease point over it: on both
    ends' tangent planes (their crease line) and on the plane through the edge across the
    surface. Every face is then split conformingly by its split edges (1: in two, 2: a
    triangle at the crease and a quad in two, 3: in four), so the surface stays closed
    and 2-manifold; a split whose faces would turn against the level set is not made."""
    d, grad, off, gok = _gradients(v, surface, level)
    nv = np.int64(len(v))
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.minimum(e[:, 0], e[:, 1]) * nv + np.maximum(e[:, 0], e[:, 1])
    ukey, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    a, b = ukey // nv, ukey % nv
    cand = gok[a] & gok[b] & (np.einsum("ij,ij->i", grad[a], grad[b]) < cos_crease)
    cand &= count == 2  # an edge of the rim of a piece is never split
    idx = np.flatnonzero(cand)
    if not len(idx):
        return v, f, 0
    a, b = a[idx], b[idx]
    mid = 0.5 * (v[a] + v[b])
    dm = surface.distance(mid, max_distance=2.0 * level)
    # the plane through the edge across the surface: spanned by the edge and the mean
    # outward normal of the level set at its ends
    nrm = -(grad[a] + grad[b])
    sec = np.cross(v[b] - v[a], nrm)
    sec /= np.maximum(np.linalg.norm(sec, axis=1, keepdims=True), 1e-300)
    normals = np.stack([grad[a], grad[b], sec], axis=1)
    offsets = np.stack([off[a], off[b], np.einsum("ij,ij->i", sec, mid)], axis=1)
    p = _plane_points(normals, offsets, mid)
    dp = surface.distance(p, max_distance=2.0 * level)
    length = np.linalg.norm(v[b] - v[a], axis=1)
    near = np.minimum(np.linalg.norm(p - v[a], axis=1), np.linalg.norm(p - v[b], axis=1))
    good = np.isfinite(dm) & (np.abs(dm - level) > tol) & np.isfinite(dp)
    good &= (np.abs(dp - level) <= 0.5 * tol) & (near > 0.05 * length)
    good &= np.linalg.norm(p - mid, axis=1) < FAR * length
    split = np.full(len(ukey), -1, dtype=np.int64)
    split[idx[good]] = nv + np.arange(int(good.sum()))
    newv = p[good]
    for _ in range(5):
        ev = split[inv].reshape(3, -1).T  # (F, 3): new vertex on edge k (k, k+1) or -1
        vv = np.vstack([v, newv])
        nf, owner = _subdivide(f, ev)
        # orientation against the level set's outward normal at the face's corners
        g_all = np.vstack([grad, _gradients(newv, surface, level)[1]]) if len(newv) else grad
        nt = _normals_of(vv[nf[:, 0]], vv[nf[:, 1]], vv[nf[:, 2]])
        out = -(g_all[nf[:, 0]] + g_all[nf[:, 1]] + g_all[nf[:, 2]])
        flipped = np.einsum("ij,ij->i", nt, out) <= 0
        flipped &= (ev[owner] >= 0).any(axis=1)  # only faces this pass made
        if not flipped.any():
            break
        bad_faces = np.unique(owner[flipped])
        drop = np.unique(inv.reshape(3, -1).T[bad_faces].ravel())
        split[drop] = -1
    used = np.unique(split[split >= 0])
    if not len(used):
        return v, f, 0
    # renumber the new vertices that are still used
    remap = np.full(len(newv), -1, dtype=np.int64)
    remap[used - nv] = nv + np.arange(len(used))
    split = np.where(split >= 0, remap[np.maximum(split - nv, 0)], -1)
    ev = split[inv].reshape(3, -1).T
    nf, _ = _subdivide(f, ev)
    return np.vstack([v, newv[used - nv]]), nf, len(used)


def _subdivide(
    f: NDArray[np.int64], ev: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Faces (F, 3) split by new vertices on their edges (``ev[i, k]``: the vertex on
    edge ``f[i, k] f[i, k+1]``, -1 for none), conformingly. Returns the new faces and,
    for each, the index of the face it came from."""
    out, owner = [], []
    cnt = (ev >= 0).sum(axis=1)
    zero = np.flatnonzero(cnt == 0)
    out.append(f[zero])
    owner.append(zero)
    for k in range(3):  # rotate so the split edges come first
        a, b, c = f[:, k], f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        eab, ebc = ev[:, k], ev[:, (k + 1) % 3]
        one = np.flatnonzero((cnt == 1) & (eab >= 0))
        out += [np.stack([a[one], eab[one], c[one]], 1), np.stack([eab[one], b[one], c[one]], 1)]
        owner += [one, one]
        # two split edges: ab and bc split, ca not (the crease runs ab -> bc around b)
        two = np.flatnonzero((cnt == 2) & (eab >= 0) & (ebc >= 0))
        m, n = eab[two], ebc[two]
        out += [
            np.stack([m, b[two], n], 1),
            np.stack([a[two], m, n], 1),
            np.stack([a[two], n, c[two]], 1),
        ]
        owner += [two, two, two]
    three = np.flatnonzero(cnt == 3)
    a, b, c = f[three, 0], f[three, 1], f[three, 2]
    m, n, o = ev[three, 0], ev[three, 1], ev[three, 2]
    out += [
        np.stack([a, m, o], 1),
        np.stack([m, b, n], 1),
        np.stack([o, n, c], 1),
        np.stack([m, n, o], 1),
    ]
    owner += [three] * 4
    return np.vstack(out).astype(np.int64), np.concatenate(owner).astype(np.int64)


def _normals_of(a: Any, b: Any, c: Any) -> Any:
    return np.cross(b - a, c - a)


def sharpen(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    level: float,
    tol: float,
    *,
    rounds: int = 2,
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
        Faces whose centres are farther than this off the level are refined.
    rounds : int
        Passes of crease splits.

    Returns
    -------
    vertices : (V', 3) float64
    faces : (F', 3) int64
        Closed, oriented and 2-manifold as the input.
    counts : dict
        ``{"moved": vertices snapped, "split": edges split at crease points}``.
    """
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(f, dtype=np.int64)
    counts = {"moved": 0, "split": 0}
    if not len(f):
        return v, f, counts
    v, grad, near = _project(v, f, surface, level, tol)
    # the work is local: the faces with a vertex within two edges of a crease (or of a
    # vertex off the level), cut out as a piece whose rim stays as it is
    fg = grad[f]
    cos = np.minimum.reduce([np.einsum("ij,ij->i", fg[:, k], fg[:, (k + 1) % 3]) for k in range(3)])
    hot = np.zeros(len(v), dtype=bool)
    hot[f[(cos < 0.985) | near[f].any(axis=1)].ravel()] = True
    for _ in range(2):
        hot[f[hot[f].any(axis=1)].ravel()] = True
    inside = hot[f].all(axis=1)
    piece = hot[f].any(axis=1)
    if not piece.any():
        return v, f, counts
    ids = np.flatnonzero(hot | np.isin(np.arange(len(v)), f[piece].ravel()))
    local = np.full(len(v), -1, dtype=np.int64)
    local[ids] = np.arange(len(ids))
    pv, pf = v[ids], local[f[piece]]
    rim = np.zeros(len(ids), dtype=bool)
    rim[local[f[piece & ~inside].ravel()]] = True  # vertices of the piece's outer faces
    pv, counts["moved"] = _snap_vertices(pv, pf, surface, level, tol, rim)
    for _ in range(rounds):
        pv, pf, n = _crease_splits(pv, pf, surface, level, tol)
        pv, moved = _snap_vertices(pv, pf, surface, level, tol, rim)
        counts["split"] += n
        counts["moved"] += moved
        if not (n or moved):
            break
    # back into the whole surface: the piece's vertices moved, its new ones appended
    v = v.copy()
    v[ids] = pv[: len(ids)]
    glob = np.concatenate([ids, len(v) + np.arange(len(pv) - len(ids))])
    v = np.vstack([v, pv[len(ids) :]])
    f = np.vstack([f[~piece], glob[pf]])
    return v, f, counts
