"""The skin's booleans on the part of the lattice near the wall only (and the trim's, near
the part's surface: ``conformal.trim.trim_to_part(graph=)`` passes the cutting part as
``inner``; there the wall elements are the struts clear outside the part, which the cut
removes).

A skin is ``outer - (inner - lattice)`` (:mod:`conformal.skin`). The lattice is by far the
largest operand (the GE bracket's octet: 1.5 M triangles against the inner surface's
0.1 M), yet only its struts near the inner surface are cut: the deep ones (inside the
inner surface, clear of it) come out of the boolean unchanged, and those in the wall (outside
it, clear of it) vanish. A stitched lattice (:func:`fast_stitch.stitch`) is made of
elements with known triangles: one hub (or end cap) per node and one tube of ``2 P``
triangles per strut, joined at the struts' profile rings (``P`` vertices each); with
``profile="volume"`` each strut end also has a band of ``2 P`` triangles between its hub
ring and its band ring, and the tube (the prism) joins the two band rings. So:

1. every hub, band and prism is classified against the inner surface, with its exact
   bounding ball (hub; band: about its node) or capsule (prism, sampled along its axis;
   the distance is 1-Lipschitz):
   **deep** (inside, clear by ``margin``), **wall** (outside, clear) or **near**; then the
   closed surface of each near element (its triangles and the fans over its rings) is
   measured exactly against the inner surface (``conformal._kernels.soups_within``), and
   those clear by ``margin`` are deep or wall after all (:func:`_refine_near`);
2. the near elements, each ring they share with a deep or wall element closed by a fan of
   ``P - 2`` triangles (no new vertex), form a closed solid ``N``; the booleans run on
   ``N`` only: ``outer - (inner - N)``; the wall elements are dropped (they lie outside
   the inner surface, where the result is the solid wall);
3. the caps toward deep elements lie inside the inner surface, clear of it, so the
   boolean leaves them as they were; :meth:`SplitLattice.glue` finds them (by their exact
   float32 coordinates) in the result, removes them and puts the deep elements in their
   place: the same closed surface as the boolean with the whole lattice, except that
   manifold3d collapses edges shorter than its tolerance in what goes through a boolean
   (e.g. a band of struts a few um thick), and the deep elements keep the stitcher's
   triangles there.

Nothing is assumed that is not checked: the mesh must have the stitcher's layout, the
caps must come out of the boolean unchanged (else :meth:`glue` returns None and the
caller runs the booleans on the whole lattice), and the deep elements must keep their
triangles and vertices through the rounding to float32 (as the stitcher guarantees).
The deep elements are not re-checked: they are a part of the stitched lattice, which is
valid in float32, and clear of everything the boolean made by ``margin``. A caller checks
the boolean's result (the near part, caps included), before :meth:`glue`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["SplitLattice", "first_vertices", "kept_pieces", "pieces", "split_lattice"]

#: Sample spacing along a strut for its distance to the inner surface, in strut radii
#: (at least ``MIN_SPACING`` mm).
SPACING_RADII = 2.0
MIN_SPACING = 0.5
#: Below this fraction of deep triangles the split is not worth it.
MIN_DEEP_FRACTION = 0.05

_DEEP, _NEAR, _WALL = 0, 1, 2


@dataclass
class SplitLattice:
    """A stitched lattice split into its near part (closed, for the booleans) and the deep
    elements glued back after them.

    Attributes
    ----------
    near_vertices : (Vn, 3) float64
        Float32-exact vertices of the near part.
    near_faces : (Fn, 3) int64
        Its triangles, caps included (a closed surface).
    deep_vertices : (Vd, 3) float64
        Float32-exact vertices of the deep elements.
    deep_faces : (Fd, 3) int64
        Their triangles (open at the rings shared with near elements).
    caps : (C, 3) int64
        The caps toward deep elements, indices into ``deep_vertices`` (the rings' vertices
        are deep vertices too), oriented as in the near part.
    cap_piece : (C,) int64
        The deep piece (``0 .. D - 1``) each cap closes.
    counts : dict
        Triangles of the lattice that are deep, near and in the wall.
    deep_index : (Vd,) int64
        The row of each deep vertex in the stitched lattice's vertices.
    """

    near_vertices: NDArray[np.float64]
    near_faces: NDArray[np.int64]
    deep_vertices: NDArray[np.float64]
    deep_faces: NDArray[np.int64]
    caps: NDArray[np.int64]
    cap_piece: NDArray[np.int64]
    counts: dict[str, int]
    deep_index: NDArray[np.int64]

    @cached_property
    def _deep_closed(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """:func:`pieces` of the deep elements closed by their (reversed) caps: each deep
        vertex's label (Vd,) int64 and each label's volume."""
        closed = np.vstack([self.deep_faces, self.caps[:, ::-1]])
        _, vlabel, vols = pieces(self.deep_vertices, closed)
        return vlabel, vols

    def _joined(self, vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> Any:
        """The connected pieces of the boolean's result joined by the deep pieces at their
        caps: ``(n, vlabel, vols, group, n_groups)`` with ``n, vlabel, vols`` as
        :func:`pieces` gives them and ``group`` (n + D,) int64 the group of each piece of
        the result, then of each deep piece (``cap_piece`` numbering), or None when a cap's
        ring is not in the result (the caps are looked up only when the result has more
        than one piece; :meth:`glue` checks them all)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        n_pieces, vlabel, vols = pieces(vertices, faces)
        n_deep = int(self.cap_piece.max(initial=-1)) + 1
        if n_pieces <= 1:  # every deep piece has a cap, so joins the one piece (if any)
            return n_pieces, vlabel, vols, np.zeros(n_pieces + n_deep, np.int64), n_pieces
        if len(self.caps) == 0:
            return n_pieces, vlabel, vols, np.arange(n_pieces + n_deep), n_pieces + n_deep
        # the piece holding each cap (its first vertex; a position may repeat in a piece)
        key = np.dtype((np.void, 24))
        hk = np.ascontiguousarray(vertices, dtype=np.float64).view(key).ravel()
        nk = np.ascontiguousarray(self.deep_vertices[self.caps[:, 0]]).view(key).ravel()
        order = np.argsort(hk)
        pos = np.minimum(np.searchsorted(hk[order], nk), len(hk) - 1)
        if len(hk) == 0 or not np.array_equal(hk[order[pos]], nk):
            return None
        n = n_pieces + n_deep
        rows, cols = vlabel[order[pos]], n_pieces + self.cap_piece
        g = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
        n_groups, group = connected_components(g, directed=False)
        return n_pieces, vlabel, vols, group.astype(np.int64), int(n_groups)

    def deep_volumes(self) -> NDArray[np.float64]:
        """(D,) float64: the volume of each deep piece (``cap_piece`` numbering), closed by
        its caps."""
        n_deep = int(self.cap_piece.max(initial=-1)) + 1
        out = np.zeros(n_deep)
        if n_deep == 0:
            return out
        vlabel, vols = self._deep_closed
        out[self.cap_piece] = vols[vlabel[self.caps[:, 0]]]
        return out

    def without(self, drop: NDArray[np.int64]) -> SplitLattice:
        """The split with the deep pieces ``drop`` (``cap_piece`` numbering) left out."""
        vlabel, _ = self._deep_closed
        piece_of_label = np.full(int(vlabel.max(initial=-1)) + 1, -1, dtype=np.int64)
        piece_of_label[vlabel[self.caps[:, 0]]] = self.cap_piece
        gone = np.zeros(int(self.cap_piece.max(initial=-1)) + 1, dtype=bool)
        gone[np.asarray(drop, dtype=np.int64)] = True
        face_piece = piece_of_label[vlabel[self.deep_faces[:, 0]]]
        keep_f = ~gone[face_piece]
        keep_c = ~gone[self.cap_piece]
        used = np.zeros(len(self.deep_vertices), dtype=bool)
        used[self.deep_faces[keep_f].ravel()] = True
        used[self.caps[keep_c].ravel()] = True
        new_id = np.cumsum(used) - 1
        return SplitLattice(
            near_vertices=self.near_vertices,
            near_faces=self.near_faces,
            deep_vertices=self.deep_vertices[used],
            deep_faces=new_id[self.deep_faces[keep_f]],
            caps=new_id[self.caps[keep_c]],
            cap_piece=self.cap_piece[keep_c],
            counts=dict(self.counts),
            deep_index=self.deep_index[used],
        )

    def bodies(
        self, vertices: NDArray[np.float64], faces: NDArray[np.int64], touches: Any
    ) -> tuple[int, NDArray[np.float64]] | None:
        """Bodies of the glued result (positive pieces reaching the outer surface, as
        ``conformal.skin._keep_attached`` counts them) and the volume of each of its sealed
        voids ((K,) float64, mm^3: the cavity walls joined by deep pieces, the volume of
        the deep pieces in them left out), or None when the glued result has
        an island (a piece of lattice joined to nothing that reaches the outer surface or
        to a cavity wall), for the full booleans to remove.

        ``vertices`` (V, 3) float64, ``faces`` (F, 3) int64: the boolean's result (the near
        part, each piece closed by its caps; a manifold3d mesh, its vertices shared by the
        triangles around them), whose connected pieces are joined here by the deep pieces
        at their caps; ``touches(vertices) -> bool``: whether a piece reaches the outer
        surface.

        The pieces are found on the arrays (:func:`pieces`), not by manifold3d's
        ``decompose``, which rebuilds a Manifold per piece (2.8 CPU s for the GE bracket's
        0.95 M triangles, against 0.1 s here).
        """
        joined = self._joined(vertices, faces)
        if joined is None:
            return None
        n_pieces, vlabel, vols, group, n_groups = joined
        neg = vols < 0  # a void: a group of cavity walls (the deep pieces' volume left out)
        gid, inv = np.unique(group[:n_pieces][neg], return_inverse=True)
        voids = np.bincount(inv, weights=-vols[neg], minlength=len(gid)).astype(np.float64)
        if n_pieces <= 1:
            return n_pieces - len(voids), voids
        anchored = np.zeros(n_groups, dtype=bool)
        anchored[group[:n_pieces][neg]] = True  # cavity walls are kept
        bodies = 0
        by_piece = np.argsort(vlabel, kind="stable")
        starts = np.searchsorted(vlabel[by_piece], np.arange(n_pieces + 1))
        for k in range(n_pieces):
            if vols[k] > 0 and touches(vertices[by_piece[starts[k] : starts[k + 1]]]):
                anchored[group[k]] = True
                bodies += 1
        if not anchored[group[:n_pieces]].all():
            return None
        return bodies, voids

    def glue(
        self, vertices: NDArray[np.float64], faces: NDArray[np.int64]
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
        """The boolean's result (from the near part) with the caps replaced by the deep
        elements, or None when a cap is not in it unchanged.

        vertices : (V, 3) float64 (float32-exact), faces : (F, 3) int64.
        Returns vertices (V', 3) float64 and faces (F', 3) int64.
        """
        if len(self.caps) == 0:  # deep elements join the result at their caps only
            return (vertices, faces) if len(self.deep_faces) == 0 else None
        ring = np.unique(self.caps.ravel())
        # ring vertices of the deep part -> vertices of the result with the same coordinates
        where = _find_rows(vertices, self.deep_vertices[ring])
        if where is None:
            return None
        to_out = np.full(len(self.deep_vertices), -1, dtype=np.int64)
        to_out[ring] = where
        caps = to_out[self.caps]
        # the caps, as triangles of the result (same orientation: any rotation of the row)
        nv = np.int64(len(vertices))
        fkey = _face_keys(faces, nv)
        ckey = _face_keys(caps, nv)
        order = np.argsort(fkey)
        pos = np.searchsorted(fkey, ckey, sorter=order)
        pos = np.minimum(pos, len(fkey) - 1)
        hit = order[pos]
        if not np.array_equal(fkey[hit], ckey) or len(np.unique(hit)) != len(hit):
            return None
        keep = np.ones(len(faces), dtype=bool)
        keep[hit] = False
        # the deep vertices not on a ring follow the result's
        other = to_out < 0
        to_out[other] = len(vertices) + np.arange(int(other.sum()))
        v = np.vstack([vertices, self.deep_vertices[other]])
        f = np.vstack([faces[keep], to_out[self.deep_faces]])
        return v, f


def pieces(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> tuple[int, NDArray[np.int64], NDArray[np.float64]]:
    """The connected pieces of a closed triangle mesh whose triangles share their vertices
    (a manifold3d mesh): their number ``n``, each vertex's piece (V,) int64 (in ``0 .. n-1``;
    a vertex of no triangle: -1) and each piece's signed volume (n,) float64, as
    ``len(Manifold.decompose())`` and the pieces' ``volume()`` give them."""
    from conformal._kernels import component_labels

    f = np.asarray(faces, dtype=np.int64)
    edges = np.concatenate([f[:, :2], f[:, 1:]])
    _, labels = component_labels(len(vertices), edges)
    used = np.zeros(len(vertices), dtype=bool)
    used[f.ravel()] = True
    # number the pieces of the used vertices 0 .. n - 1 (in the order of their first vertex)
    kinds, inverse = np.unique(labels[used], return_inverse=True)
    vlabel = np.full(len(vertices), -1, dtype=np.int64)
    vlabel[used] = inverse
    v = np.asarray(vertices, dtype=np.float64)
    vols = np.zeros(len(kinds))
    for start in range(0, len(f), 1 << 16):  # chunks: the temporaries stay in cache
        tri = v[f[start : start + (1 << 16)]]
        six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
        vols += np.bincount(vlabel[f[start : start + (1 << 16), 0]], six, len(kinds))
    return len(kinds), vlabel, vols / 6.0


def kept_pieces(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    face_kept: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The triangles ``faces[face_kept]`` (F,) bool with only the vertices they use,
    renumbered: the pieces of :func:`pieces` that are kept, as arrays."""
    f = faces[face_kept]
    used = np.zeros(len(vertices), dtype=bool)
    used[f.ravel()] = True
    new_id = np.cumsum(used) - 1
    return vertices[used], new_id[f]


def first_vertices(vlabel: NDArray[np.int64], n: int, k: int) -> list[NDArray[np.int64]]:
    """Up to ``k`` vertex indices of each of the ``n`` pieces (``vlabel`` from
    :func:`pieces`), the lowest first."""
    order = np.argsort(vlabel, kind="stable")
    starts = np.searchsorted(vlabel[order], np.arange(n + 1))
    return [order[starts[i] : min(starts[i] + k, starts[i + 1])] for i in range(n)]


#: vertex counts up to which :func:`_face_keys` packs a triangle in one int64 (21 bits each)
_PACKED_KEYS = 1 << 21


def _face_keys(f: NDArray[np.int64], nv: np.int64) -> NDArray[Any]:
    """(F,) keys, one per triangle of ``f`` (vertex indices below ``nv``), the same for its
    three rotations and different for the reversed triangle: int64 when the indices fit 21
    bits, else the rotated rows as 24-byte strings (for sorting and searching only)."""
    r = np.argmin(f, axis=1)
    idx = np.arange(len(f))
    a, b, c = f[idx, r], f[idx, (r + 1) % 3], f[idx, (r + 2) % 3]
    if nv <= _PACKED_KEYS:
        return (a << 42) | (b << 21) | c
    rows = np.ascontiguousarray(np.stack([a, b, c], axis=1), dtype=np.int64)
    return rows.view(np.dtype((np.void, 24))).ravel()


def _find_rows(
    haystack: NDArray[np.float64], needles: NDArray[np.float64]
) -> NDArray[np.int64] | None:
    """(K,) int64: the row of ``haystack`` equal to each needle, or None when one is missing
    or not unique."""
    h = np.ascontiguousarray(haystack, dtype=np.float64)
    n = np.ascontiguousarray(needles, dtype=np.float64)
    key = np.dtype((np.void, 24))
    hk = h.view(key).ravel()
    nk = n.view(key).ravel()
    order = np.argsort(hk)
    hs = hk[order]
    lo = np.searchsorted(hs, nk, side="left")
    hi = np.searchsorted(hs, nk, side="right")
    if not np.all(hi - lo == 1):
        return None
    return order[lo]


def _layout(graph: Any, v: NDArray[np.float64], f: NDArray[np.int64]) -> tuple[int, Any] | None:
    """``P``, the node face starts (N,) and counts (N,), and the first band row (-1: none) if
    ``(v, f)`` is the stitcher's mesh of ``graph`` (its layout checked), else None.

    With ``profile="volume"`` the stitcher puts a band ring per strut end after the
    ``2 M P`` hub-ring vertices and a band (``2 P`` triangles) from each hub ring to its band
    ring after the hub faces; the tube (rows ``2 P e``) then joins the two band rings."""
    from fast_stitch.stitch import _face_counts

    m = graph.num_edges
    if m == 0:
        return None
    for rings in (4, 2):  # banded (profile="volume") or not
        if len(v) % (rings * m):
            continue
        P = len(v) // (rings * m)
        if P < 3:
            continue
        counts = _face_counts(graph.degree, P)
        bbase = 2 * m * P + int(counts.sum())
        if len(f) != bbase + (4 * m * P if rings == 4 else 0):
            continue
        # the tubes: rows 2 P e + 2 k, +1 join the rings (2 e) P + k and (2 e + 1) P + k
        # (the band rings, 2 M P further on, when banded)
        tubes = f[: 2 * m * P].reshape(m, P, 2, 3)
        base = (2 * np.arange(m) * P)[:, None] + (2 * m * P if rings == 4 else 0)
        k = np.arange(P)[None, :]
        if not (
            np.array_equal(tubes[:, :, 0, 0], base + k)
            and np.array_equal(tubes[:, :, 1, 0], base + k)
        ):
            continue  # (the counts of P unbanded and P / 2 banded can agree: try both)
        start = 2 * m * P + np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        return P, (start, counts, bbase if rings == 4 else -1)
    return None


def split_lattice(
    graph: Any,
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    inner: Any,
    *,
    margin: float,
) -> SplitLattice | None:
    """Split a stitched lattice against the inner surface of a skin.

    Parameters
    ----------
    graph : LatticeGraph
        The graph the lattice was stitched from.
    vertices : (V, 3) float64, faces : (F, 3) int64
        The lattice as :func:`fast_stitch.stitch` made it (its layout is checked).
    inner : conformal.Part
        The inner surface of the skin (the same mesh the booleans use).
    margin : float
        Clearance (mm) of the deep and wall elements from the inner surface.

    Returns
    -------
    SplitLattice or None
        None when the mesh is not the stitcher's, when too little is deep to be worth it,
        or when the float32 rounding touches a deep element.
    """
    from conformal._skin_kernels import any_flat_triangle
    from lattice_cad.core.mesh import without_unused_vertices
    from lattice_cad.io._rounding_kernels import has_equal_rows

    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    lay = _layout(graph, v, f)
    if lay is None:
        return None
    P, (fstart, fcount, bbase) = lay
    nodes, edges = graph.nodes, graph.edges
    n_nodes, m = len(nodes), len(edges)
    rings = v[: 2 * m * P].reshape(m, 2, P, 3)  # the hub rings
    centre = rings.mean(axis=2)  # (m, 2, 3)
    # hub of node n: inside the ball about the node through its farthest ring vertex
    reach = np.linalg.norm(rings - nodes[edges][:, :, None, :], axis=3).max(axis=2)  # (m, 2)
    hub_r = np.zeros(n_nodes)
    np.maximum.at(hub_r, edges.ravel(), reach.ravel())
    # tube of strut e: inside the capsule about its ring centres, radius its widest ring
    tube_r = np.linalg.norm(rings - centre[:, :, None, :], axis=3).max(axis=(1, 2))  # (m,)
    if bbase >= 0:  # the band rings lie between the hub rings: widen to the widest ring
        band = v[2 * m * P :].reshape(m, 2, P, 3)
        axis_u = centre[:, 1] - centre[:, 0]
        axis_u /= np.maximum(np.linalg.norm(axis_u, axis=1), 1e-300)[:, None]
        rel = band - centre[:, :1, None, :]
        along = np.einsum("mspc,mc->msp", rel, axis_u)
        radial = np.linalg.norm(rel - along[..., None] * axis_u[:, None, None, :], axis=3)
        tube_r = np.maximum(tube_r, radial.max(axis=(1, 2)))
        # band (e, s) (between hub ring and band ring): inside the ball about its node
        # through the farther of its two rings' vertices
        band_reach = np.maximum(
            reach, np.linalg.norm(band - nodes[edges][:, :, None, :], axis=3).max(axis=2)
        )  # (m, 2)
    else:
        band_reach = reach
    seg = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    far = float(band_reach.max() + tube_r.max() + 0.5 * seg.max()) + 2.0 * margin
    dist = inner.distance(nodes, max_distance=far)  # inf beyond: clear of everything below
    inside = inner.contains(nodes)
    clear = dist > hub_r + margin
    ncls = np.where(clear, np.where(inside, _DEEP, _WALL), _NEAR)
    ncls[graph.degree == 0] = _WALL
    # tubes between two clear nodes on the same side; the distance is 1-Lipschitz, so along
    # the segment it is at least (d_a + d_b - |ab|) / 2; else sampled along the axis
    ecls = np.full(m, _NEAR)
    same = (ncls[edges[:, 0]] == ncls[edges[:, 1]]) & (ncls[edges[:, 0]] != _NEAR)
    with np.errstate(invalid="ignore"):
        sure = 0.5 * (dist[edges[:, 0]] + dist[edges[:, 1]] - seg) > tube_r + margin
    ecls[same & sure] = ncls[edges[same & sure, 0]]
    cand = np.flatnonzero(same & ~sure)
    if len(cand):
        a, b = centre[cand, 0], centre[cand, 1]
        length = np.linalg.norm(b - a, axis=1)
        s = max(MIN_SPACING, SPACING_RADII * float(tube_r.max()))
        n_seg = np.maximum(1, np.ceil(length / s).astype(np.int64))
        k_max = int(n_seg.max())
        t = np.minimum(np.arange(k_max + 1)[None, :] / n_seg[:, None], 1.0)  # (C, K+1)
        pts = a[:, None, :] + t[:, :, None] * (b - a)[:, None, :]
        reach_d = float(tube_r.max()) + margin + s  # inf beyond: clear enough
        d = inner.distance(pts.reshape(-1, 3), max_distance=reach_d).reshape(len(cand), -1)
        step = length / n_seg
        with np.errstate(invalid="ignore"):
            low = 0.5 * (d[:, 1:] + d[:, :-1] - step[:, None])  # a bound between two samples
        ok = np.all(low > tube_r[cand, None] + margin, axis=1)
        ecls[cand[ok]] = ncls[edges[cand[ok], 0]]
    # the near elements measured exactly: those clear of the inner surface by margin are
    # deep or wall after all (the bounds above are balls and capsules about them)
    # bands (banded struts): elements of their own, so that a strut crossing the inner
    # surface between two clear hubs is near with its prism only (the GE bracket's octet:
    # 2/3 of a near strut's triangles are its bands)
    bcls = np.zeros(0, dtype=np.int64)
    if bbase >= 0:
        bclear = dist[edges] > band_reach + margin  # (m, 2); inf: clear
        bcls = np.where(bclear, np.where(inside[edges], _DEEP, _WALL), _NEAR).ravel()
    _refine_near(
        v, f, P, fstart, fcount, bbase, edges, graph.degree, ncls, ecls, bcls, inner, margin
    )  # fmt: skip
    # every face's element
    fcls = np.empty(len(f), dtype=np.int64)
    fcls[: 2 * m * P] = np.repeat(ecls, 2 * P)
    fcls[2 * m * P : 2 * m * P + int(fcount.sum())] = np.repeat(ncls, fcount)
    if bbase >= 0:
        fcls[bbase:] = np.repeat(bcls, 2 * P)  # band (e, s): rows bbase + 2 P (2 e + s)
    n_deep = int((fcls == _DEEP).sum())
    if n_deep < MIN_DEEP_FRACTION * len(f):
        return None
    if n_deep == len(f):  # all of it clear inside: nothing for the booleans
        return SplitLattice(
            near_vertices=np.zeros((0, 3)),
            near_faces=np.zeros((0, 3), dtype=np.int64),
            deep_vertices=v,
            deep_faces=f,
            caps=np.zeros((0, 3), dtype=np.int64),
            cap_piece=np.zeros(0, dtype=np.int64),
            counts={"deep": n_deep, "near": 0, "wall": 0, "caps": 0},
            deep_index=np.arange(len(v), dtype=np.int64),
        )
    # the rings between elements: ring r (vertices r P .. r P + P - 1) joins element a[r]
    # (a hub, or a band at its band ring) to element b[r] (a band or a strut's prism).
    # Elements: hubs 0 .. N - 1, prisms N .. N + M - 1, bands N + M + 2 e + s.
    e_all = np.repeat(np.arange(m), 2)
    s_all = np.tile(np.array([0, 1]), m)
    prism_el = n_nodes + e_all
    if bbase >= 0:
        band_el = n_nodes + m + np.arange(2 * m)
        ring_a = np.concatenate([edges.ravel(), band_el])  # hub rings, then band rings
        ring_b = np.concatenate([band_el, prism_el])
        ring_e, ring_s = np.tile(e_all, 2), np.tile(s_all, 2)
    else:
        ring_a, ring_b, ring_e, ring_s = edges.ravel(), prism_el, e_all, s_all
    el_cls = np.concatenate([ncls, ecls, bcls])
    cls_a, cls_b = el_cls[ring_a], el_cls[ring_b]
    if np.any((cls_a != cls_b) & (cls_a != _NEAR) & (cls_b != _NEAR)):
        return None  # deep next to wall: not clear after all
    x = np.flatnonzero(cls_a != cls_b)
    near_b = cls_b[x] == _NEAR
    to_deep = (cls_a[x] == _DEEP) | (cls_b[x] == _DEEP)
    # every tube of strut e (prism, bands: fast_stitch._kernels._tube) runs along its first
    # ring forward and its second backward, or all of them the other way: read which from
    # the first triangle of the tube at ring (e, 0) (the band there when banded), which
    # holds that ring's edge (0 -> 1) or (1 -> 0); b[r] then runs along ring r forward when
    # that is forward and r is at end 0, or backward and r is at end 1
    ex = ring_e[x]
    first = f[2 * P * ex] if bbase < 0 else f[bbase + 4 * P * ex]  # (K, 3)
    base0 = 2 * ex * P
    nxt = np.roll(first, -1, axis=1)
    plus0 = np.any((first == base0[:, None]) & (nxt == base0[:, None] + 1), axis=1)
    b_plus = np.where(ring_s[x] == 0, plus0, ~plus0)
    # the cap closes the near element: against b's direction if b is near, else along it
    # (a, on the other side of the ring, runs along it against b)
    cap_plus = np.where(near_b, ~b_plus, b_plus)
    caps = _fans(x, P, cap_plus).reshape(-1, 3)
    cap_deep = np.repeat(to_deep, P - 2)
    # the deep elements must survive the rounding to float32 as they are
    v32 = v.astype(np.float32).astype(np.float64)
    deep_f = f[fcls == _DEEP]
    mask = np.zeros(len(v), dtype=bool)
    mask[deep_f.ravel()] = True
    used_d = np.flatnonzero(mask)
    if any_flat_triangle(v32, deep_f):
        return None
    u = v32[used_d] + 0.0  # -0.0 + 0.0 is +0.0: equal rows, equal bits
    if has_equal_rows(u, u.view(np.uint64)):
        return None  # two deep vertices became one
    near_f = np.vstack([f[fcls == _NEAR], caps])
    nv, nf = without_unused_vertices(v32, near_f)
    dmap = np.full(len(v), -1, dtype=np.int64)
    mask[caps[cap_deep].ravel()] = True
    dverts = np.flatnonzero(mask)
    dmap[dverts] = np.arange(len(dverts))
    if np.any(dmap[caps[cap_deep]] < 0):
        return None
    ring_piece = _deep_pieces(el_cls, ring_a[x], ring_b[x], ring_a, ring_b, to_deep)
    if ring_piece is None:
        return None  # a deep piece of lattice that joins nothing: an island (full booleans)
    return SplitLattice(
        near_vertices=nv,
        near_faces=nf,
        deep_vertices=v32[dverts],
        deep_faces=dmap[deep_f],
        deep_index=dverts.astype(np.int64),
        caps=dmap[caps[cap_deep]],
        cap_piece=np.repeat(ring_piece, P - 2),
        counts={
            "deep": n_deep,
            "near": int((fcls == _NEAR).sum()),
            "wall": int((fcls == _WALL).sum()),
            "caps": int(len(caps)),
        },
    )


def _refine_near(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    P: int,
    fstart: NDArray[np.int64],
    fcount: NDArray[np.int64],
    bbase: int,
    edges: NDArray[np.int64],
    degree: NDArray[np.int64],
    ncls: NDArray[np.int64],
    ecls: NDArray[np.int64],
    bcls: NDArray[np.int64],
    inner: Any,
    margin: float,
) -> None:
    """Reclassify, in place, the near hubs (``ncls``), prisms (``ecls``) and bands
    (``bcls``, (2 M,) for banded struts, else empty) whose closed surface (their triangles
    and the fans closing their rings) stays farther than ``margin`` from the inner surface:
    deep when inside it, wall when outside.

    Such an element's boundary lies wholly on one side of the inner surface (one vertex
    tells which), clear of it by ``margin``; so does the element, unless a whole piece of
    the inner surface fits inside it, which is ruled out when every piece of the inner
    surface is larger (bounding box) than every element. The ball and capsule bounds that
    classified the elements first hold them as near when they come within ``margin`` of
    the surface; on a thin-walled part most are far clearer than that (GE bracket, octet
    6 mm, r 0.5, skin 1.5: 988 K of 2.87 M triangles near by the bounds, 619 K exactly
    with the bands going with their prism, 0.45 s less in the booleans; 458 K with the
    bands classified on their own).
    """
    from conformal._kernels import soups_within

    m = len(edges)
    hubs = np.flatnonzero((ncls == _NEAR) & (degree > 0))
    tubes = np.flatnonzero(ecls == _NEAR)
    bands = np.flatnonzero(bcls == _NEAR)
    if len(hubs) + len(tubes) + len(bands) == 0:
        return
    # ring r: vertices r P .. r P + P - 1 (hub ring (e, s): r = 2 e + s; band ring: 2 M + r)
    n_rings = (4 if bbase >= 0 else 2) * m
    ring_v = v[: n_rings * P].reshape(n_rings, P, 3)
    ring_lo, ring_hi = ring_v.min(axis=1), ring_v.max(axis=1)  # (R, 3)
    # a prism lies between its two (band, when banded) rings, a band between its hub ring
    # and its band ring, a hub within its hub rings' bounding box
    off = 2 * m if bbase >= 0 else 0
    t0, t1 = off + 2 * tubes, off + 2 * tubes + 1
    b0, b1 = bands, 2 * m + bands

    def extent(r0: NDArray[np.int64], r1: NDArray[np.int64]) -> float:
        if len(r0) == 0:
            return 0.0
        lo = np.minimum(ring_lo[r0], ring_lo[r1])
        hi = np.maximum(ring_hi[r0], ring_hi[r1])
        return float((hi - lo).max())

    tube_ext = max(extent(t0, t1), extent(b0, b1))
    hub_ext = 0.0
    if len(hubs):
        lo = np.full((len(degree), 3), np.inf)
        hi = np.full((len(degree), 3), -np.inf)
        np.minimum.at(lo, edges.ravel(), ring_lo[: 2 * m])
        np.maximum.at(hi, edges.ravel(), ring_hi[: 2 * m])
        hub_ext = float((hi[hubs] - lo[hubs]).max())
    iv, ifc = inner.vertices, inner.faces
    n_pieces, vlabel, _ = pieces(iv, ifc)
    used = vlabel >= 0
    plo = np.full((n_pieces, 3), np.inf)
    phi = np.full((n_pieces, 3), -np.inf)
    np.minimum.at(plo, vlabel[used], iv[used])
    np.maximum.at(phi, vlabel[used], iv[used])
    if float((phi - plo).max(axis=1).min()) <= max(tube_ext, hub_ext) + 2 * margin:
        return  # a piece of the inner surface could hide inside an element
    # the soups: each near prism's triangles and the fans closing its rings; each near
    # band's likewise; each near hub's triangles; the fans closing each near hub's rings
    # (a hub is clear when its soup and all its rings' are)
    two_p = np.arange(2 * P)[None, :]
    tube_soup = np.concatenate(
        [f[(2 * P * tubes)[:, None] + two_p], _fans(t0, P), _fans(t1, P)], axis=1
    )  # (T, 2 P + 2 (P - 2), 3)
    band_soup = np.concatenate(
        [f[(bbase + 2 * P * bands)[:, None] + two_p], _fans(b0, P), _fans(b1, P)], axis=1
    )  # (B, 2 P + 2 (P - 2), 3)
    hub_len = fcount[hubs]
    hub_rows = np.repeat(fstart[hubs] - np.concatenate([[0], np.cumsum(hub_len)[:-1]]), hub_len)
    hub_rows += np.arange(int(hub_len.sum()))
    hub_mask = np.zeros(len(degree), dtype=bool)
    hub_mask[hubs] = True
    rings = np.flatnonzero(hub_mask[edges.ravel()])  # ring 2 e + s is at node edges[e, s]
    soup = np.concatenate(
        [
            tube_soup.reshape(-1, 3),
            band_soup.reshape(-1, 3),
            f[hub_rows],
            _fans(rings, P).reshape(-1, 3),
        ]
    )
    sizes = np.concatenate(
        [
            np.full(len(tubes), tube_soup.shape[1]),
            np.full(len(bands), band_soup.shape[1]),
            hub_len,
            np.full(len(rings), P - 2),
        ]
    )
    soup_start = np.concatenate([[0], np.cumsum(sizes)])
    origin, h, dims, start, items = inner._bins3d
    touch = soups_within(
        inner.triangles, inner.boxes, start, items, origin, h, dims, v, soup, soup_start, margin
    )
    n_t, n_b, n_h = len(tubes), len(bands), len(hubs)
    tube_touch = touch[:n_t]
    band_touch = touch[n_t : n_t + n_b]
    hub_touch = touch[n_t + n_b : n_t + n_b + n_h].copy()
    hub_pos = np.full(len(degree), -1, dtype=np.int64)
    hub_pos[hubs] = np.arange(n_h)
    np.logical_or.at(hub_touch, hub_pos[edges.ravel()[rings]], touch[n_t + n_b + n_h :])
    # one vertex of each clear element tells its side
    t_clear, b_clear, h_clear = tubes[~tube_touch], bands[~band_touch], hubs[~hub_touch]
    first = np.concatenate(
        [tube_soup[~tube_touch, 0, 0], band_soup[~band_touch, 0, 0], f[fstart[h_clear], 0]]
    )
    side = np.where(inner.contains(v[first]), _DEEP, _WALL)
    ecls[t_clear] = side[: len(t_clear)]
    bcls[b_clear] = side[len(t_clear) : len(t_clear) + len(b_clear)]
    ncls[h_clear] = side[len(t_clear) + len(b_clear) :]


def _fans(
    rings: NDArray[np.int64], P: int, plus: NDArray[np.bool_] | None = None
) -> NDArray[np.int64]:
    """(R, P - 2, 3) vertex ids of the fan closing each ring (ring ``r``: vertices
    ``r P .. r P + P - 1``), in the ring's direction where ``plus`` (R,) is True (default),
    against it elsewhere."""
    rb = (np.asarray(rings, dtype=np.int64) * P)[:, None]
    j = np.arange(1, P - 1)[None, :]
    fwd = np.ones((len(rb), 1), dtype=bool) if plus is None else np.asarray(plus)[:, None]
    c0 = np.broadcast_to(rb, (len(rb), P - 2))
    return np.stack(
        [c0, np.where(fwd, rb + j, rb + j + 1), np.where(fwd, rb + j + 1, rb + j)], axis=2
    )


def _deep_pieces(
    el_cls: NDArray[np.int64],
    cap_a: NDArray[np.int64],
    cap_b: NDArray[np.int64],
    ring_a: NDArray[np.int64],
    ring_b: NDArray[np.int64],
    to_deep: NDArray[np.bool_],
) -> NDArray[np.int64] | None:
    """The connected piece of deep elements (joined at shared rings: ring r joins elements
    ``ring_a[r]`` and ``ring_b[r]``, classes ``el_cls``) at each ring toward a near element
    (the rings ``cap_a``, ``cap_b`` with ``to_deep``): (K,) int64 in ``0 .. D - 1``, K =
    to_deep.sum(), D the number of deep pieces; or None when a piece has no such ring."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(el_cls)
    both = (el_cls[ring_a] == _DEEP) & (el_cls[ring_b] == _DEEP)
    rows, cols = ring_a[both], ring_b[both]
    g = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
    _, label = connected_components(g, directed=False)
    # the deep element at each ring toward a near one
    deep_el = np.where(el_cls[cap_a] == _DEEP, cap_a, cap_b)
    ring_piece = label[deep_el[to_deep]]
    joined = np.zeros(n, dtype=bool)
    joined[ring_piece] = True
    if not np.all(joined[label[el_cls == _DEEP]]):
        return None
    # the pieces numbered 0 .. D - 1
    return np.unique(ring_piece, return_inverse=True)[1].astype(np.int64).ravel()
