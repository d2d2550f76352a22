"""lattice_cad.core.arrays.unique_rows against numpy's own row sort (np.unique(axis=0))."""

from __future__ import annotations

import numpy as np
import pytest

from lattice_cad.core.arrays import unique_rows


def _numpy(a):
    u, i, inv, c = np.unique(a, axis=0, return_index=True, return_inverse=True, return_counts=True)
    return u, i, inv.reshape(-1), c


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("cols", [1, 2, 3, 4])
def test_same_as_numpy_on_random_rows(seed, cols):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 3000))
    hi = int(rng.choice([3, 50, 10**5]))
    a = rng.integers(-hi, hi, size=(n, cols))
    if seed % 2:
        a = a.astype(np.int32)
    got = unique_rows(a, return_index=True, return_inverse=True, return_counts=True)
    want = _numpy(a)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    assert got[0].dtype == a.dtype
    np.testing.assert_array_equal(got[0][got[2]], a)  # the inverse rebuilds the rows


def test_rows_too_wide_for_one_key_fall_back_to_numpy():
    big = np.iinfo(np.int64).max // 4
    a = np.array([[0, big, 1], [0, big, 1], [big, 0, 0], [-big, 3, 2]], dtype=np.int64)
    got = unique_rows(a, return_inverse=True, return_counts=True)
    want = _numpy(a)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[2])
    np.testing.assert_array_equal(got[2], want[3])


def test_plain_call_and_empty_input():
    a = np.array([[2, 1], [0, 5], [2, 1]])
    np.testing.assert_array_equal(unique_rows(a), [[0, 5], [2, 1]])
    empty = unique_rows(np.zeros((0, 2), dtype=np.int64), return_inverse=True, return_counts=True)
    assert empty[0].shape == (0, 2) and empty[1].shape == (0,) and empty[2].shape == (0,)


def test_refuses_floats_and_vectors():
    with pytest.raises(ValueError, match="2-D integer"):
        unique_rows(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="2-D integer"):
        unique_rows(np.zeros(3, dtype=np.int64))


def test_edge_uses_of_a_tetrahedron_and_an_open_triangle():
    from lattice_cad.core.arrays import edge_uses

    tet = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    rows, inverse, counts = edge_uses(tet)
    assert len(rows) == 6 and (counts == 2).all()
    he = np.concatenate([tet[:, [0, 1]], tet[:, [1, 2]], tet[:, [2, 0]]])
    assert np.array_equal(rows[inverse], np.sort(he, axis=1))
    rows, inverse, counts = edge_uses(np.array([[4, 5, 6]]))
    assert rows.tolist() == [[4, 5], [4, 6], [5, 6]] and (counts == 1).all()
