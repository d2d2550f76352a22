"""Closing the holes of an open triangle mesh (a documented repair of mesh part files).

Scanned parts and meshes exported by hand often have a few missing triangles. A lattice
needs a closed volume, so :func:`conformal.load_part` refuses them, naming where the open
edges are; with ``close_holes=True`` (``lattice-cad fill --close-holes``) each hole is
closed first and a warning says how many, how large and where:

1. the faces are oriented consistently (breadth-first over shared edges);
2. the boundary half-edges (edges used by one triangle) are chained into loops; where two
   loops touch at a vertex (two boundary edges leave it: a pinched, bow-tie rim) the walk
   is cut there into simple loops, each closed on its own;
3. each loop is triangulated by the triangulation of least total area (dynamic
   programming over its vertices, O(n^3): ``conformal._kernels.min_area_fill``), using no
   chord that is an edge of the mesh already (it would be shared by three triangles).
   Loops of more than ``config.CLOSE_HOLES_MAX_EDGES`` edges are refused.

The patches are the smallest surfaces spanning the holes' rims, not the shape that is
missing: a hole in a flat or gently curved region closes as the region would; a large
opening (the bottom of a scanned bust) closes with a flat-ish lid. The closed mesh is
checked again like any other part (closed, 2-manifold, consistently oriented), but a patch
is not kept from crossing the rest of the surface: where a rim lies inside another body
its patch does, and the union of the bodies removes it; a patch that crosses its own body
(a teapot's handle end entering the body, or a patch folding through it: the bunny's hole
at (13.9, 35.3, 12.4), 2 face pairs) leaves the inside there to the winding number, which
can take in or leave out a sliver. Those are found (``fast_stitch.check``'s exact
intersection test on each patch and its body's faces near it) and the warning names them
(``HoleReport.crossing``). What is written is checked in full as always.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from conformal import _kernels
from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.errors import PartError

__all__ = ["close_holes", "HoleReport"]


@dataclass
class HoleReport:
    """What :func:`close_holes` did.

    Attributes
    ----------
    holes : int
        Holes closed.
    added : int
        Triangles added.
    edges : list of int
        Boundary edges of each hole, largest first.
    perimeters : list of float
        Length (mm) of each hole's rim, in the order of ``edges``.
    centres : list of tuple of float
        Mean of each hole's rim vertices, in the order of ``edges``.
    """

    holes: int = 0
    added: int = 0
    edges: list[int] = field(default_factory=list)
    perimeters: list[float] = field(default_factory=list)
    centres: list[tuple[float, float, float]] = field(default_factory=list)
    #: (pairs, centre) of each hole whose patch crosses the rest of the mesh: the number of
    #: face pairs that intersect (a patch face with any other face, by
    #: ``fast_stitch.check``), and the hole's centre; largest first
    crossing: list[tuple[int, tuple[float, float, float]]] = field(default_factory=list)

    def summary(self) -> str:
        """One line: how many holes, the largest with where it is, and the patches that
        cross the surface."""
        if not self.holes:
            return "no holes"
        x, y, z = self.centres[0]
        out = (
            f"{self.holes} hole(s) closed with {self.added} triangle(s); the largest has "
            f"{self.edges[0]} edges, {self.perimeters[0]:.4g} mm around, at "
            f"({x:.4g}, {y:.4g}, {z:.4g})"
        )
        if self.crossing:
            pairs, (x, y, z) = self.crossing[0]
            out += (
                f"; the patch of {len(self.crossing)} hole(s) crosses the surface (the "
                f"most: {pairs} face pair(s), hole at ({x:.4g}, {y:.4g}, {z:.4g})): the "
                "inside is then where the surface winds around a point (nonzero winding), "
                "which can take in or leave out a sliver where they cross; look there, or "
                "close that hole in a mesh editor"
            )
        return out


def _boundary_loops(f: NDArray[np.int64], v: NDArray[np.float64], name: str) -> list[list[int]]:
    """The loops of boundary half-edges of ``f`` (each in the direction its face runs).

    Where holes touch at a vertex (two open edges leave it: a pinched, bow-tie rim), the
    walk is cut there into simple loops, each closed on its own: a loop is emitted as soon
    as the walk comes back to a vertex it has passed.
    """
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    _, inv, cnt = unique_rows(np.sort(he, axis=1), return_inverse=True, return_counts=True)
    if (cnt > 2).any():
        return []  # non-manifold edges: not a hole to close (the caller says so)
    bnd = he[(cnt == 1)[inv.reshape(-1)]]
    if not len(bnd):
        return []
    out: dict[int, list[int]] = {}
    for a, b in bnd.tolist():
        out.setdefault(a, []).append(b)
    n_in = np.bincount(bnd[:, 1], minlength=len(v))
    n_out = np.bincount(bnd[:, 0], minlength=len(v))
    if (n_in != n_out).any():
        x, y, z = v[int(np.argmax(n_in != n_out))]
        raise PartError(
            f"{name}: the open edges at ({x:.4g}, {y:.4g}, {z:.4g}) do not close "
            "into a loop; repair the mesh"
        )
    loops: list[list[int]] = []
    for s in bnd[:, 0].tolist():
        if not out.get(s):
            continue
        path = [s]
        at = {s: 0}  # position of each vertex on the current walk
        a = s
        while path:
            b = out[a].pop()
            if b in at:  # back at a vertex of the walk: the part after it is a loop
                k = at[b]
                loops.append(path[k:])
                for w in path[k + 1 :]:
                    del at[w]
                del path[k + 1 :]
                if not out[b]:  # the walk's start, its open edges all used
                    break
                a = b
            else:
                at[b] = len(path)
                path.append(b)
                a = b
    return loops


def close_holes(
    v: NDArray[np.float64], f: NDArray[np.int64], *, name: str = "mesh"
) -> tuple[NDArray[np.int64], HoleReport]:
    """Close every hole of a triangle mesh with minimal-area patches.

    Parameters
    ----------
    v : (V, 3) float64
        Vertices (duplicates merged: holes are found from shared vertex indices).
    f : (F, 3) int64
        Triangles; their orientation may be inconsistent (it is made consistent).
    name : str
        Named in errors (the file).

    Returns
    -------
    faces : (F + A, 3) int64
        The mesh's triangles, consistently oriented, and the A added ones.
    report : HoleReport

    Raises
    ------
    PartError
        Open edges that do not form loops, a loop of more than ``config.CLOSE_HOLES_MAX_EDGES``
        edges, or one that every triangulation would join to an existing edge.
    """
    from conformal.part import _orient

    v = np.ascontiguousarray(v, dtype=np.float64)
    f = _orient(np.ascontiguousarray(f, dtype=np.int64))
    report = HoleReport()
    loops = _boundary_loops(f, v, name)
    if not loops:
        return f, report
    und = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    added: list[NDArray[np.int64]] = []
    rows: list[tuple[int, float, tuple[float, float, float]]] = []
    for loop in loops:
        ids = np.asarray(loop, dtype=np.int64)
        n = len(ids)
        x, y, z = v[ids].mean(axis=0)
        if n > config.CLOSE_HOLES_MAX_EDGES:
            raise PartError(
                f"{name}: a hole of {n} edges at ({x:.4g}, {y:.4g}, {z:.4g}) is larger than "
                f"the {config.CLOSE_HOLES_MAX_EDGES} edges holes are closed up to; close it "
                "in a mesh editor"
            )
        local = np.full(len(v), -1, dtype=np.int64)
        local[ids] = np.arange(n)
        inner = und[(local[und[:, 0]] >= 0) & (local[und[:, 1]] >= 0)]
        forbidden = np.zeros((n, n), dtype=np.bool_)
        li, lj = local[inner[:, 0]], local[inner[:, 1]]
        forbidden[li, lj] = forbidden[lj, li] = True
        tri = _kernels.min_area_fill(v[ids], forbidden)
        if len(tri) != n - 2:
            raise PartError(
                f"{name}: the hole of {n} edges at ({x:.4g}, {y:.4g}, {z:.4g}) cannot be "
                "closed without joining edges the mesh has already; repair the mesh"
            )
        added.append(ids[tri])
        # loops that touch at a vertex: no chord of this patch may be another's too
        und = np.vstack([und, np.sort(ids[tri][:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)])
        perimeter = float(np.linalg.norm(v[np.roll(ids, -1)] - v[ids], axis=1).sum())
        rows.append((n, perimeter, (float(x), float(y), float(z))))
    crossing = _crossings(v, f, added)
    order = sorted(range(len(rows)), key=lambda k: (-rows[k][0], -rows[k][1]))
    report.holes = len(loops)
    report.added = int(sum(len(a) for a in added))
    report.edges = [rows[k][0] for k in order]
    report.perimeters = [rows[k][1] for k in order]
    report.centres = [rows[k][2] for k in order]
    report.crossing = sorted(
        ((n, rows[k][2]) for k, n in enumerate(crossing) if n), key=lambda c: -c[0]
    )
    return np.vstack([f, *added]), report


def _crossings(
    v: NDArray[np.float64], f: NDArray[np.int64], patches: list[NDArray[np.int64]]
) -> list[int]:
    """For each patch ((P_k, 3) int64 triangles of ``v``), the number of face pairs in
    which one of its triangles intersects another triangle of its own body (the closed
    mesh ``f`` plus the patches, connected through shared vertices), by
    ``fast_stitch.check``'s exact test on the patch and the faces whose boxes meet its box.

    A patch inside another body is left out: the union of the bodies removes it. One that
    crosses its own body (a rim that enters it, as a teapot's handle end does, or a patch
    folding through it, the bunny's) leaves the inside to the winding number there."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from fast_stitch.check import check

    every = np.vstack([f, *patches])
    n = len(v)
    rows = np.concatenate([every[:, 0], every[:, 1]])
    cols = np.concatenate([every[:, 1], every[:, 2]])
    graph = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
    label = connected_components(graph, directed=False)[1][every[:, 0]]
    t = v[every]
    lo_f, hi_f = t.min(axis=1), t.max(axis=1)
    start = np.cumsum([len(f)] + [len(q) for q in patches])
    out = []
    for k, patch in enumerate(patches):
        mine = np.zeros(len(every), dtype=bool)
        mine[start[k] : start[k] + len(patch)] = True
        box = v[patch.ravel()]
        lo, hi = box.min(axis=0), box.max(axis=0)
        pad = 1e-9 * max(1.0, float(np.abs(box).max()))
        near = (
            ~mine
            & (label == label[start[k]])
            & np.all((hi_f >= lo - pad) & (lo_f <= hi + pad), axis=1)
        )
        sub = np.vstack([patch, every[near]])  # the patch first: its faces are 0 .. P - 1
        pairs = check((v, sub), max_report=1_000_000).self_intersection_pairs
        pairs = pairs[pairs.min(axis=1) < len(patch)]
        # a patch that is its rim's triangle turned over (a sheet, refused after as one)
        same = np.all(np.sort(sub[pairs[:, 0]], axis=1) == np.sort(sub[pairs[:, 1]], axis=1), 1)
        out.append(int(np.count_nonzero(~same)))
    return out
