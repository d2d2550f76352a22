"""Array helpers the engines share (numpy only).

:func:`unique_rows` is ``np.unique(a, axis=0)`` for integer rows (edges, triangles, grid
indices). numpy sorts rows through a structured view, which is about 15x slower than sorting
one integer key per row: on the 2 million half-edges of a 660k-triangle tessellation
4.4 s against 0.28 s. Where the rows can be packed into one ``int64`` without overflow, they
are; otherwise numpy's row sort is used. The results are the same in both cases.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["edge_uses", "point_text", "read_only", "unique_rows"]

_INT64_MAX = np.iinfo(np.int64).max


def _row_keys(a: NDArray[np.integer[Any]]) -> NDArray[np.int64] | None:
    """(R,) int64 keys in the rows' lexicographic order, or None when they would overflow."""
    if a.shape[0] == 0 or a.shape[1] == 0:
        return None
    lo = a.min(axis=0).astype(np.int64)
    span = (a.max(axis=0).astype(np.int64) - lo) + 1
    base = int(span.max())
    if base ** a.shape[1] > _INT64_MAX:  # Python ints: the test itself cannot overflow
        return None
    key = np.zeros(a.shape[0], dtype=np.int64)
    for j in range(a.shape[1]):  # a row (x, y, z) -> ((x * base) + y) * base + z
        key *= base
        key += a[:, j].astype(np.int64) - lo[j]
    return key


def unique_rows(
    a: NDArray[np.integer[Any]],
    *,
    return_index: bool = False,
    return_inverse: bool = False,
    return_counts: bool = False,
) -> Any:
    """The unique rows of an integer array, as ``np.unique(a, axis=0, ...)`` returns them.

    Parameters
    ----------
    a : (R, C) integer
        Rows to deduplicate (e.g. sorted edges ``(E, 2)`` or faces ``(F, 3)``).
    return_index, return_inverse, return_counts : bool
        As for ``np.unique``; the inverse is always 1-D ``(R,)``.

    Returns
    -------
    uniq : (U, C), same dtype as ``a``, rows in lexicographic order
        Followed by ``index : (U,) int64``, ``inverse : (R,) int64`` and ``counts : (U,)
        int64`` for the options asked, in that order (a tuple when any is asked).
    """
    a = np.asarray(a)
    if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"unique_rows needs a 2-D integer array, got shape {a.shape}, {a.dtype}")
    key = _row_keys(a)
    if key is None:
        out = np.unique(a, axis=0, return_index=True, return_inverse=True, return_counts=True)
        uniq, index, inverse, counts = out
        inverse = inverse.reshape(-1)
    else:
        _, index, inverse, counts = np.unique(
            key, return_index=True, return_inverse=True, return_counts=True
        )
        uniq = a[index]
        inverse = inverse.reshape(-1)
    extra = []
    if return_index:
        extra.append(index.astype(np.int64, copy=False))
    if return_inverse:
        extra.append(inverse.astype(np.int64, copy=False))
    if return_counts:
        extra.append(counts.astype(np.int64, copy=False))
    return (uniq, *extra) if extra else uniq


def edge_uses(
    faces: NDArray[np.integer[Any]],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The undirected edges of triangles ``faces`` (F, 3): ``rows`` (E, 2) int64 (sorted
    ends), the edge of each half-edge ``inverse`` (3 F,) int64 (edges (0, 1), then (1, 2),
    then (2, 0) of every triangle), and how many half-edges use each ``counts`` (E,) int64
    (2 in a closed 2-manifold mesh)."""
    f = np.asarray(faces)
    und = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    rows, inverse, counts = unique_rows(und, return_inverse=True, return_counts=True)
    return rows, np.asarray(inverse).reshape(-1), counts


def read_only(a: NDArray[Any]) -> NDArray[Any]:
    """A read-only view of ``a`` (no copy; ``a`` itself stays writable if it was).

    numba compiles (and loads from its cache) one version of a kernel per argument type,
    and a read-only array is another type than a writable one: inputs passed as read-only
    views whatever the caller had (a ``Mesh``'s and a ``LatticeGraph``'s arrays are
    read-only, fresh ones are not) keep it to one version, each costing 5-20 ms to load
    in every process and seconds to compile once.
    """
    view = a.view()
    view.flags.writeable = False
    return view


def point_text(p: Any, *, digits: int = 4) -> str:
    """A point for messages, ``(x, y, z)`` with ``digits`` significant digits each.

    ``p`` : (3,) float64 (any sequence of numbers).
    """
    return "(" + ", ".join(f"{float(c):.{digits}g}" for c in p) + ")"
