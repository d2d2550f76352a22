"""Local repair of a closed mesh whose vertices were rounded to float32.

Rounding a boolean's result to float32 (as STL and 3MF store it) can break it in two
local ways, which :func:`repair_rounded` fixes without moving anything else:

* **flat triangles**: a sliver thinner than the float32 spacing becomes a segment. A
  *needle* (two corners at the same point) loses its zero-length edge; a *cap* (one
  corner on the segment between the other two) is removed by flipping its longest edge,
  so no vertex moves.
* **pinched vertices**: two sheets of the surface that were less than a float32 step
  apart (or already shared a position, as manifold3d's booleans can leave where a strut
  grazes a wall) meet in one vertex, whose faces form several fans (cones). Each fan gets
  its own copy of the vertex, and every copy moves a few float32 steps toward the centre
  of its own fan's ring, so the cones separate.

* **cancelling pairs**: a fin of the surface thinner than the float32 spacing (a sliver
  of a cavity between two struts) can round to two triangles on the same three vertices,
  back to back: :func:`cancel_opposite_faces` removes both (zero volume; every edge keeps
  one use in each direction for each it had).

All keep the mesh closed; the caller checks the result in full (self-intersections
included), since a repair this local cannot prove that nothing else touches.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.mesh import without_unused_vertices

__all__ = [
    "cancel_opposite_faces",
    "flat_triangles",
    "pinched_vertices",
    "repair_rounded",
    "weld_merges",
]

#: How far (in float32 steps at the vertex's largest coordinate) the copies of a pinched
#: vertex move toward the centres of their fans.
PINCH_ULPS = 8


def flat_triangles(v: NDArray[np.float64], f: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(F,) bool: triangles of exactly zero area in the coordinates given.

    v : (V, 3) float64, f : (F, 3) int64.
    """
    from lattice_cad.io._rounding_kernels import flat_mask

    v = np.ascontiguousarray(v, dtype=np.float64)
    return flat_mask(v, np.ascontiguousarray(f, dtype=np.int64))


def _corner_fans(f: NDArray[np.int64], n_vertices: int) -> NDArray[np.int64]:
    """(F, 3) int64: the fan (connected set of faces around a vertex, joined across edges
    that have exactly two faces of opposite orientation) of every corner, numbered 0.."""
    from lattice_cad.io._rounding_kernels import corner_fans

    return corner_fans(np.ascontiguousarray(f, dtype=np.int64), int(n_vertices))


def pinched_vertices(f: NDArray[np.int64], n_vertices: int) -> NDArray[np.int64]:
    """(K,) int64: vertices whose faces form more than one fan (or lie on an edge with
    other than two faces)."""
    from lattice_cad.io._rounding_kernels import pinched

    if len(f) == 0:
        return np.zeros(0, dtype=np.int64)
    return pinched(np.ascontiguousarray(f, dtype=np.int64), int(n_vertices))


def _flip_or_collapse(
    v: NDArray[np.float64], f: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64], bool]:
    """One pass over the flat triangles: caps flip their longest edge, needles collapse
    their shortest. Returns the mesh and whether anything changed."""
    from lattice_cad.io.exchange import collapse_faces

    bad = np.flatnonzero(flat_triangles(v, f))
    if not len(bad):
        return v, f, False
    t = v[f[bad]]
    lengths = np.stack([np.linalg.norm(t[:, (k + 1) % 3] - t[:, k], axis=1) for k in range(3)])
    needle = lengths.min(axis=0) == 0.0
    f = f.copy()
    changed = False
    # caps: flip the longest edge (a, b) of face (a, b, c) with its neighbour (b, a, d)
    nv = np.int64(len(v))
    he_key = np.concatenate([f[:, k] * nv + f[:, (k + 1) % 3] for k in range(3)])
    he_face = np.tile(np.arange(len(f)), 3)
    order = np.argsort(he_key)
    he_key, he_face = he_key[order], he_face[order]
    und = np.unique(
        np.minimum(he_key // nv, he_key % nv) * nv + np.maximum(he_key // nv, he_key % nv)
    )

    def face_of(a: int, b: int) -> int | None:
        i = int(np.searchsorted(he_key, a * nv + b))
        return int(he_face[i]) if i < len(he_key) and he_key[i] == a * nv + b else None

    def has_edge(a: int, b: int) -> bool:
        key = min(a, b) * nv + max(a, b)
        i = int(np.searchsorted(und, key))
        return i < len(und) and und[i] == key

    done = np.zeros(len(f), dtype=bool)
    added: set[tuple[int, int]] = set()
    longest = np.argmax(lengths[:, ~needle], axis=0)
    for i, k in zip(bad[~needle].tolist(), longest.tolist(), strict=True):
        if done[i]:
            continue
        a, b, c = int(f[i, k]), int(f[i, (k + 1) % 3]), int(f[i, (k + 2) % 3])
        j = face_of(b, a)
        if j is None or done[j]:
            continue
        d = int(next(x for x in f[j].tolist() if x not in (a, b)))
        if d == c or has_edge(c, d) or (min(c, d), max(c, d)) in added:
            continue
        f[i] = (c, a, d)
        f[j] = (c, d, b)
        done[i] = done[j] = True
        added.add((min(c, d), max(c, d)))
        changed = True
    if needle.any():
        v, f = collapse_faces(v, f, bad[needle])
        changed = True
    return v, f, changed


def _separate_pinches(
    v: NDArray[np.float64], f: NDArray[np.int64], pinched: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A copy of each pinched vertex per fan, moved toward the centre of its fan's ring."""
    fans = _corner_fans(f, len(v))
    is_pinched = np.zeros(len(v), dtype=bool)
    is_pinched[pinched] = True
    corners = np.argwhere(is_pinched[f])  # (C, 2): face, k
    vid = f[corners[:, 0], corners[:, 1]]
    fan = fans[corners[:, 0], corners[:, 1]]
    groups, inv = unique_rows(np.stack([vid, fan], axis=1), return_inverse=True)
    inv = inv.reshape(-1)
    new_v = [v]
    new_f = f.copy()
    base = len(v)
    pos = v[groups[:, 0]]
    # ring centre of each fan: mean of the other two corners of its faces
    ring = np.zeros((len(groups), 3))
    n = np.zeros(len(groups))
    for s in (1, 2):
        other = v[f[corners[:, 0], (corners[:, 1] + s) % 3]]
        np.add.at(ring, inv, other)
        np.add.at(n, inv, 1.0)
    ring /= n[:, None]
    direction = ring - pos
    length = np.linalg.norm(direction, axis=1)
    ulp = np.spacing(np.abs(pos).max(axis=1).astype(np.float32)).astype(np.float64)
    step = np.minimum(PINCH_ULPS * ulp, 0.25 * length)
    moved = pos + direction / np.maximum(length, 1e-300)[:, None] * step[:, None]
    moved = moved.astype(np.float32).astype(np.float64)
    new_v.append(moved)
    new_f[corners[:, 0], corners[:, 1]] = base + inv
    out_v = np.vstack(new_v)
    used = np.zeros(len(out_v), dtype=bool)
    used[new_f.ravel()] = True
    new_id = np.cumsum(used) - 1
    return out_v[used], new_id[new_f]


def cancel_opposite_faces(
    v: NDArray[np.float64], f: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64], int]:
    """Remove the pairs of triangles on the same three vertices with opposite orientations
    (a zero-thickness fin, as rounding makes of one thinner than a float32 step), and the
    vertices no face uses any more.

    Found on a coffee mug's skin (3 mm wall, 1.33 mm skin: a 0.34 mm cavity that the struts
    cut into a thousand slivers): one such pair, on an edge of four faces, made the
    rounded mesh non-manifold, and every retry of the skin after it (ten minutes) too.

    v : (V, 3) float64, f : (F, 3) int64. Returns ``(v', f', removed)``: the mesh unchanged
    (the same arrays) when no pair is found, ``removed`` the number of triangles dropped.
    """
    if len(f) < 2:
        return v, f, 0
    key = np.sort(f, axis=1)
    _, inverse, counts = unique_rows(key, return_inverse=True, return_counts=True)
    shared = np.flatnonzero(counts[inverse] > 1)
    if not len(shared):
        return v, f, 0
    # orientation: even or odd permutation of the sorted vertices
    t = f[shared]
    turn = np.argmin(t, axis=1)
    rolled = t[np.arange(len(t))[:, None], (turn[:, None] + np.arange(3)) % 3]
    odd = rolled[:, 1] > rolled[:, 2]
    group = inverse[shared]
    order = np.lexsort((odd, group))
    group, odd, shared = group[order], odd[order], shared[order]
    # within a group, pair its even faces with its odd ones, as many as both have
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    size = np.diff(np.r_[starts, len(group)])
    n_odd = np.add.reduceat(odd.astype(np.int64), starts)
    n_even = size - n_odd
    pairs = np.minimum(n_odd, n_even)
    rank = np.arange(len(group)) - np.repeat(starts, size)
    first_odd = np.repeat(starts + n_even, size)
    drop_even = ~odd & (rank < np.repeat(pairs, size))
    drop_odd = odd & ((np.arange(len(group)) - first_odd) < np.repeat(pairs, size))
    drop = shared[drop_even | drop_odd]
    if not len(drop):
        return v, f, 0
    keep = np.ones(len(f), dtype=bool)
    keep[drop] = False
    v, f = without_unused_vertices(v, f[keep])
    return v, f, len(drop)


def repair_rounded(
    v: NDArray[np.float64], f: NDArray[np.int64], *, rounds: int = 10
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Remove flat triangles and separate pinched vertices of a float32-rounded mesh.

    Parameters
    ----------
    v : (V, 3) float64
        Vertices, exactly representable in float32 (the result's are too).
    f : (F, 3) int64
        Triangles of a closed surface (vertices with equal coordinates already merged).
    rounds : int
        Passes of flips, collapses and separations before giving up.

    Returns
    -------
    vertices : (V', 3) float64, faces : (F', 3) int64
        Unchanged if nothing was flat or pinched. The caller must check the result.
    """
    for _ in range(rounds):
        changed = True
        for _ in range(20):
            v, f, changed = _flip_or_collapse(v, f)
            if not changed:
                break
        pinched = pinched_vertices(f, len(v))
        if not len(pinched):
            return v, f
        v, f = _separate_pinches(v, f, pinched)
    return v, f


def weld_merges(v: NDArray[np.float64], tol: float) -> bool:
    """Would :func:`lattice_cad.core.mesh.weld` ``(v, f, tol=tol)`` merge any vertices?

    The same rows (``v`` itself, or ``np.round(v / tol)``) compared the same way (equal in
    every coordinate, ``-0.0 == 0.0``), in one hashing pass instead of weld's sort.
    v : (V, 3) float64.
    """
    from lattice_cad.io._rounding_kernels import has_equal_rows

    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    key = v if tol == 0 else np.round(v / tol)
    key = np.ascontiguousarray(key + 0.0)  # -0.0 + 0.0 is +0.0: equal rows, equal bits
    return bool(has_equal_rows(key, key.view(np.uint64)))
