"""Merging a triangle mesh's vertices that lie within a distance of one another.

Shared by OpenCascade's tessellations (per-face copies of edge nodes, apart by up to the
B-rep's edge tolerances: :mod:`~lattice_cad.occ_impl.shapes`, ``cluster``, ``truss``) and
mesh part files (a triangle soup's copies of a vertex: ``conformal.part``). numpy and
scipy only: importing it does not import OCP.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["merge_close"]


def merge_close(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    tol: float,
    *,
    only: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]]:
    """Merge vertices closer than ``tol`` (transitively), as OCCT's edge tolerances allow.

    Per-face triangulations carry their own copies of edge nodes; on a B-rep whose edges
    have a tolerance, the copies can differ by up to that tolerance.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    tol : float
        Distance (mm) below which two vertices are one.
    only : (K,) int64, optional
        Merge only these vertices, among themselves (e.g. the ends of a mesh's open
        edges); the others stay as they are.

    Returns
    -------
    vertices : (V', 3) float64
        The first vertex of each merged group.
    faces : (F', 3) int64
        Faces that still have three distinct vertices.
    kept : (F,) bool
        Which input faces were kept.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(vertices)
    pairs = cKDTree(vertices if only is None else vertices[only]).query_pairs(
        tol, output_type="ndarray"
    )
    if only is not None:
        pairs = np.asarray(only, dtype=np.int64)[pairs].reshape(-1, 2)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    keep = np.sort(first)
    new_id = np.empty(label.max() + 1, dtype=np.int64)
    new_id[label[keep]] = np.arange(len(keep))
    f2 = new_id[label[faces]]
    good = (f2[:, 0] != f2[:, 1]) & (f2[:, 1] != f2[:, 2]) & (f2[:, 0] != f2[:, 2])
    return vertices[keep], f2[good], good
