"""An exact arbiter for triangle pairs another checker flags as self-intersecting.

pymeshlab (vcg) flags some pairs of coplanar triangles that share one vertex and do not
overlap (their corners at that vertex 4 degrees apart: the face-recognition part's tet
lattice, ``tests/test_tet.py``). Here every coordinate is a ``Fraction`` (a float64 is
one exactly) and every predicate is evaluated exactly, so a flagged pair is confirmed
only when the two triangles really share a point that is not a vertex they share.
Touching counts as intersecting (conservative); slow, for a few flagged faces only.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

Q = Fraction


def _pt(p) -> tuple[Q, Q, Q]:
    return (Q(float(p[0])), Q(float(p[1])), Q(float(p[2])))


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sign(x) -> int:
    return (x > 0) - (x < 0)


def _orient3(a, b, c, d) -> int:
    return _sign(_dot(_cross(_sub(b, a), _sub(c, a)), _sub(d, a)))


def _orient2(a, b, c) -> int:
    return _sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def _project(points, normal):
    """Drop the axis of the largest normal component: exact 2-D images of coplanar points."""
    k = max(range(3), key=lambda i: abs(normal[i]))
    keep = [i for i in range(3) if i != k]
    return [(p[keep[0]], p[keep[1]]) for p in points]


def _inside2(p, tri, strict: bool) -> bool:
    s = [_orient2(tri[i], tri[(i + 1) % 3], p) for i in range(3)]
    if strict:
        return all(x > 0 for x in s) or all(x < 0 for x in s)
    return all(x >= 0 for x in s) or all(x <= 0 for x in s)


def _cross2(p1, p2, q1, q2) -> bool:
    """Segments cross at a point inside both (not at an end)."""
    return (
        _orient2(p1, p2, q1) * _orient2(p1, p2, q2) < 0
        and _orient2(q1, q2, p1) * _orient2(q1, q2, p2) < 0
    )


def _sub2(a, b):
    return (a[0] - b[0], a[1] - b[1])


def _coplanar_overlap(a, b, normal) -> bool:
    """Interiors of two coplanar triangles overlap."""
    a2, b2 = _project(a, normal), _project(b, normal)
    for i in range(3):
        for j in range(3):
            if _cross2(a2[i], a2[(i + 1) % 3], b2[j], b2[(j + 1) % 3]):
                return True
    if any(_inside2(p, b2, True) for p in a2) or any(_inside2(p, a2, True) for p in b2):
        return True
    # edges from a shared vertex along the same ray (a shared edge is one): the interiors
    # overlap when the third vertices lie on the same side of that ray's line
    shared = [p for p in a2 if p in b2]
    for s in shared:
        for u in (p for p in a2 if p != s):
            for w in (p for p in b2 if p != s):
                du, dw = _sub2(u, s), _sub2(w, s)
                if du[0] * dw[1] - du[1] * dw[0] != 0 or du[0] * dw[0] + du[1] * dw[1] <= 0:
                    continue
                (ta,) = [p for p in a2 if p not in (s, u)]
                (tb,) = [p for p in b2 if p not in (s, w)]
                if _orient2(s, u, ta) * _orient2(s, u, tb) > 0:
                    return True
    return False


def _segment_hits(p, q, tri, shared) -> bool:
    """The segment pq meets triangle ``tri`` (not coplanar with it as a whole) at a point
    that is not one of the ``shared`` vertices."""
    d0, d1 = _orient3(*tri, p), _orient3(*tri, q)
    if d0 * d1 > 0:
        return False
    normal = _cross(_sub(tri[1], tri[0]), _sub(tri[2], tri[0]))
    if d0 == 0 and d1 == 0:  # the segment lies in the triangle's plane
        t2 = _project(tri, normal)
        p2, q2 = _project([p, q], normal)
        mid = ((p2[0] + q2[0]) / 2, (p2[1] + q2[1]) / 2)
        if _inside2(mid, t2, True):
            return True
        return any(_cross2(p2, q2, t2[i], t2[(i + 1) % 3]) for i in range(3))
    # the one point where the segment meets the plane
    a = _dot(normal, _sub(p, tri[0]))
    b = _dot(normal, _sub(q, tri[0]))
    t = a / (a - b)
    x = tuple(p[i] + t * (q[i] - p[i]) for i in range(3))
    if x in shared:
        return False
    t2 = _project(tri, normal)
    (x2,) = _project([x], normal)
    return _inside2(x2, t2, False)


def triangles_intersect(a, b) -> bool:
    """Two triangles (3 points each, float64 or Fraction) share a point that is not a
    vertex they both have (edge-sharing neighbours meet only along that edge)."""
    a = [_pt(p) for p in a]
    b = [_pt(p) for p in b]
    shared = [p for p in a if p in b]
    normal = _cross(_sub(a[1], a[0]), _sub(a[2], a[0]))
    if all(_orient3(*a, p) == 0 for p in b):
        return _coplanar_overlap(a, b, normal)
    if len(shared) >= 2:  # not coplanar: they meet along the shared edge only
        return False
    for x, y in ((a, b), (b, a)):
        for i in range(3):
            if _segment_hits(x[i], x[(i + 1) % 3], y, shared):
                return True
    return False


def confirmed_faces(vertices, faces, flagged) -> list[int]:
    """Of the ``flagged`` faces, those that intersect some other face of the mesh exactly
    (candidates: faces whose bounding boxes overlap theirs)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    lo, hi = v[f].min(axis=1), v[f].max(axis=1)
    out = []
    for k in np.asarray(flagged, dtype=np.int64).tolist():
        near = np.flatnonzero(((lo <= hi[k]) & (hi >= lo[k])).all(axis=1))
        if any(j != k and triangles_intersect(v[f[k]], v[f[j]]) for j in near.tolist()):
            out.append(k)
    return out
