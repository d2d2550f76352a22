"""The exact arbiter of flagged self-intersections (``tests/exact_intersect.py``), on
closed-form cases and against a float test on random triangles in general position."""

from __future__ import annotations

import numpy as np
import pytest
from exact_intersect import confirmed_faces, triangles_intersect

A = [(0, 0, 0), (2, 0, 0), (0, 2, 0)]


@pytest.mark.parametrize(
    ("b", "expected"),
    [
        ([(0.5, 0.5, -1), (0.5, 0.5, 1), (1.5, 0.2, 0)], True),  # pierces A
        ([(5, 5, 5), (6, 5, 5), (5, 6, 5)], False),  # far away
        ([(0, 0, 0), (2, 0, 0), (1, -1, 1)], False),  # edge neighbour, bent
        ([(0, 0, 0), (2, 0, 0), (1, 0.5, 0)], True),  # edge neighbour folded onto A
        ([(0, 0, 0), (2, 0, 0), (1, -0.5, 0)], False),  # edge neighbour, flat
        ([(0, 0, 0), (-1, -0.1, 0), (-0.1, -1, 0)], False),  # coplanar, one vertex, apart
        ([(0, 0, 0), (1, 0.3, 0), (0.3, 1, 0)], True),  # coplanar, one vertex, inside A
        ([(0, 0, 0), (1, 1, -1), (1, 1, 1)], True),  # one vertex, through A's interior
        ([(0, 0, 0), (-1, 0, 1), (0, -1, 1)], False),  # one vertex, away from A
        ([(1, 0, 0), (1, -1, 1), (1, -1, -1)], True),  # touches A's edge: counted
    ],
)
def test_closed_form_pairs(b, expected):
    assert triangles_intersect(A, b) is expected
    assert triangles_intersect(b, A) is expected


def test_random_pairs_agree_with_a_float_test():
    rng = np.random.default_rng(7)

    def hits(p, q, t):
        n = np.cross(t[1] - t[0], t[2] - t[0])
        d0, d1 = n @ (p - t[0]), n @ (q - t[0])
        if d0 * d1 > 0:
            return False
        x = p + d0 / (d0 - d1) * (q - p)
        s = [np.cross(t[(i + 1) % 3] - t[i], x - t[i]) @ n for i in range(3)]
        return all(v >= 0 for v in s) or all(v <= 0 for v in s)

    found = 0
    for _ in range(300):
        a, b = rng.random((3, 3)), rng.random((3, 3))
        want = any(hits(a[i], a[(i + 1) % 3], b) or hits(b[i], b[(i + 1) % 3], a) for i in range(3))
        assert triangles_intersect(a, b) is want
        found += want
    assert 30 < found < 270  # both outcomes are exercised


def test_confirmed_faces_of_a_mesh():
    """Two tetrahedra: apart (nothing confirmed), then one pushed into the other."""
    t = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    faces = np.vstack([f, f + 4])
    apart = np.vstack([t, t + 3.0])
    assert confirmed_faces(apart, faces, np.arange(8)) == []
    inside = np.vstack([t, t + 0.2])
    assert len(confirmed_faces(inside, faces, np.arange(8))) > 0
