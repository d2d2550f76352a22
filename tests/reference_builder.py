"""The graph builder as it was before the memory work (issue 15), kept as a plain
numpy/scipy reference: the new builder must give the same nodes, edges and order.

Copied from conformal/cells.py, conformal/voxel.py and lattice_cad/core/graph.py at
commit 6bab4be; only renamed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from conformal.cells import _COORD_LIMIT, _INT64_MAX, UnitCell, _unique_sorted
from lattice_cad.core import config
from lattice_cad.core.arrays import point_text
from lattice_cad.core.errors import InvalidGraphError
from lattice_cad.core.graph import precision_problem


def _unique_inverse(keys: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``np.unique(keys, return_inverse=True)`` for 1-d int64 keys, by one argsort.

    (``np.unique`` itself is several times slower on large int64 arrays in
    recent numpy versions, which default to a hash-based path.)
    """
    order = np.argsort(keys)
    s = keys[order]
    first = np.empty(len(s), dtype=bool)
    first[:1] = True
    np.not_equal(s[1:], s[:-1], out=first[1:])
    ids = np.cumsum(first) - 1
    inv = np.empty(len(keys), dtype=np.int64)
    inv[order] = ids
    return s[first], inv


def old_tile_int(
    cell: UnitCell, cells: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(node_ijk (N, 3), edges (M, 2)) of the union of the cell copies, sorted."""
    if len(cells) == 0:
        return np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2), dtype=np.int64)
    d = cell.denominator
    c_lo = [int(v) for v in cells.min(axis=0)]
    c_hi = [int(v) for v in cells.max(axis=0)]
    if max(abs(v) for v in c_lo + c_hi) * d + d > _COORD_LIMIT:
        raise ValueError(
            f"cell indices up to {max(abs(v) for v in c_lo + c_hi)} are too large "
            f"(global integer coordinates must stay below 2**52)"
        )
    k_nodes = cell.num_nodes
    g_lo = [v * d for v in c_lo]
    span = [(hi - lo + 1) * d + 1 for lo, hi in zip(c_lo, c_hi, strict=True)]
    if span[0] * span[1] * span[2] <= _INT64_MAX:
        # One int64 key per (cell, node), linear in the coordinates, so that
        # key(cell, node) = key(cell origin) + key(node offset) and key order is
        # lexicographic (x, y, z) order.
        sy, sz = span[1], span[2]
        base = ((cells[:, 0] * d - g_lo[0]) * sy + (cells[:, 1] * d - g_lo[1])) * sz + (
            cells[:, 2] * d - g_lo[2]
        )
        loc = cell.nodes
        off = (loc[:, 0] * sy + loc[:, 1]) * sz + loc[:, 2]
        keys = (base[:, None] + off[None, :]).ravel()
        del base
        uniq, inv = _unique_inverse(keys)
        del keys
        node_ijk = np.empty((len(uniq), 3), dtype=np.int64)
        rest, node_ijk[:, 2] = np.divmod(uniq, sz)
        node_ijk[:, 0], node_ijk[:, 1] = np.divmod(rest, sy)
        del rest, uniq
        node_ijk += np.asarray(g_lo, dtype=np.int64)
    else:  # a huge, sparse extent: unique on coordinate rows instead
        g = (cells[:, None, :] * d + cell.nodes[None, :, :]).reshape(-1, 3)
        node_ijk, inv = np.unique(g, axis=0, return_inverse=True)
        del g
    inv = inv.reshape(len(cells), k_nodes)
    n_nodes = len(node_ijk)
    a = inv[:, cell.edges[:, 0]]
    b = inv[:, cell.edges[:, 1]]
    del inv
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    del a, b
    if n_nodes <= 3_000_000_000:  # n_nodes**2 fits in int64
        ekeys = _unique_sorted(np.sort((lo * n_nodes + hi).ravel()))
        edges = np.stack(np.divmod(ekeys, n_nodes), axis=1)
    else:  # pragma: no cover - more than 3e9 nodes
        edges = np.unique(np.stack([lo.ravel(), hi.ravel()], axis=1), axis=0)
    return node_ijk, edges.astype(np.int64, copy=False)


def old_cleanup(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    on_surface: NDArray[np.bool_],
    min_len: float,
    boundary: bool,
    prune: bool,
    rep: Any,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    n = len(nodes)
    if boundary and len(edges):
        # merge surface nodes closer than min_len to another node (conform: projections can meet)
        surf = np.flatnonzero(on_surface)
        if len(surf):
            from scipy.spatial import cKDTree

            tree = cKDTree(nodes)
            pairs = tree.query_pairs(min_len, output_type="ndarray")
            pairs = pairs[on_surface[pairs].any(axis=1)]
            if len(pairs):
                parent = np.arange(n)
                # a surface node merges into its partner (an interior node wins)
                for i, j in pairs.tolist():
                    ri, rj = _find(parent, i), _find(parent, j)
                    if ri == rj:
                        continue
                    if on_surface[ri] and not on_surface[rj]:
                        parent[ri] = rj
                    else:
                        parent[rj] = ri
                root = np.array([_find(parent, i) for i in range(n)])
                rep.merged_nodes = int((root != np.arange(n)).sum())
                edges = root[edges]
                edges = edges[edges[:, 0] != edges[:, 1]]
                edges = np.unique(np.sort(edges, axis=1), axis=0)
        length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
        short = length < min_len
        rep.removed_short = int(short.sum())
        edges = edges[~short]
    # dangling struts: degree-1 nodes that are not on the surface, repeatedly
    alive = np.ones(len(edges), dtype=bool)
    while prune:
        deg = np.bincount(edges[alive].ravel(), minlength=n)
        leaf = (deg == 1) & ~on_surface
        drop = alive & (leaf[edges[:, 0]] | leaf[edges[:, 1]])
        if not drop.any():
            break
        rep.removed_dangling += int(drop.sum())
        alive &= ~drop
    edges = edges[alive]
    if boundary and len(edges):
        # fragments: connected pieces without any interior node
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        _, lab = connected_components(g, directed=False)
        used = np.zeros(n, dtype=bool)
        used[edges.ravel()] = True
        has_interior = np.zeros(lab.max() + 1, dtype=bool)
        has_interior[lab[used & ~on_surface]] = True
        ok = has_interior[lab[edges[:, 0]]]
        rep.removed_fragments = int((~ok).sum())
        edges = edges[ok]
    used = np.zeros(n, dtype=bool)
    used[edges.ravel()] = True
    rep.removed_isolated = int((~used).sum())
    new_id = np.cumsum(used) - 1
    return nodes[used], new_id[edges].astype(np.int64)


def _find(parent: NDArray[np.int64], i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = int(parent[i])
    return i


def old_components(n: int, edges: NDArray[np.int64]) -> tuple[int, NDArray[np.int64]]:
    """scipy's connected components (what ``main_components`` used), labels per node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)


def old_validate(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], radii: NDArray[np.float64]
) -> None:
    bad = ~np.isfinite(nodes).all(axis=1)
    if bad.any():
        n = int(np.flatnonzero(bad)[0])
        raise InvalidGraphError(f"node {n} has a non-finite coordinate {nodes[n].tolist()}")
    if len(edges) == 0:
        return
    huge = np.abs(nodes).max(axis=1) > config.MAX_COORDINATE
    if huge.any():
        n = int(np.flatnonzero(huge)[0])
        raise InvalidGraphError(
            f"node {n} at {point_text(nodes[n], digits=6)} is beyond the largest supported "
            f"coordinate {config.MAX_COORDINATE:g} (lengths' squares and the exact predicates' "
            "products would overflow); use a larger length unit (smaller numbers) or move the "
            "lattice to the origin"
        )
    loops = edges[:, 0] == edges[:, 1]
    if loops.any():
        e = int(np.flatnonzero(loops)[0])
        raise InvalidGraphError(f"edge {e} is a self-loop on node {int(edges[e, 0])}")
    key = np.sort(edges, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks = key[order]
    dup = np.flatnonzero((ks[1:] == ks[:-1]).all(axis=1))
    if len(dup):
        # report the later edge as the duplicate of the earlier one
        pairs = np.sort(np.stack([order[dup], order[dup + 1]], axis=1), axis=1)
        first, second = (int(v) for v in pairs[np.argmin(pairs[:, 1])])
        raise InvalidGraphError(
            f"edge {second} {tuple(edges[second].tolist())} duplicates edge {first} "
            f"{tuple(edges[first].tolist())}"
        )
    badr = ~np.isfinite(radii)
    if badr.any():
        e = int(np.flatnonzero(badr.any(axis=1))[0])
        raise InvalidGraphError(f"edge {e} has a non-finite radius {radii[e].tolist()}")
    nonpos = radii <= 0
    if nonpos.any():
        e, side = (int(v) for v in np.argwhere(nonpos)[0])
        raise InvalidGraphError(
            f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}; "
            "radii must be > 0"
        )
    tiny = radii < config.MIN_RADIUS
    if tiny.any():
        e, side = (int(v) for v in np.argwhere(tiny)[0])
        raise InvalidGraphError(
            f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}, below the "
            f"smallest supported radius {config.MIN_RADIUS:g} (products of such lengths "
            "underflow in floating point); use a smaller length unit"
        )
    vec = nodes[edges[:, 1]] - nodes[edges[:, 0]]
    length = np.sqrt(np.einsum("ij,ij->i", vec, vec))
    zero = length == 0.0
    if zero.any():
        e = int(np.flatnonzero(zero)[0])
        a, b = (int(v) for v in edges[e])
        raise InvalidGraphError(
            f"edge {e} ({a}, {b}) has zero length: nodes {a} and {b} coincide at "
            f"{point_text(nodes[a], digits=6)}"
        )
    fat = radii.max(axis=1) >= 0.5 * length
    if fat.any():
        e = int(np.flatnonzero(fat)[0])
        raise InvalidGraphError(
            f"edge {e} ({int(edges[e, 0])}, {int(edges[e, 1])}): radius {radii[e].max():g} is not "
            f"strictly below half its length {length[e]:g} (must be < {0.5 * length[e]:g})"
        )
    if config.PRECISION_CONTRACT:
        msg = precision_problem(nodes, edges, radii, "float64")
        if msg:
            raise InvalidGraphError(msg)
    # distinct nodes at the same position (only among nodes that carry struts)
    used = np.flatnonzero(np.bincount(edges.ravel(), minlength=len(nodes)) > 0)
    if len(used) > 1:
        pts = nodes[used]
        order = np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0]))
        same = np.flatnonzero((pts[order][1:] == pts[order][:-1]).all(axis=1))
        if len(same):
            a, b = sorted((int(used[order[same[0]]]), int(used[order[same[0] + 1]])))
            at = point_text(nodes[a], digits=6)
            raise InvalidGraphError(f"nodes {a} and {b} coincide at {at}")


# ------------------------------------------------ fast_stitch.fit.clashes before the slabs
from numba import njit, prange  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

from fast_stitch import _kernels  # noqa: E402
from fast_stitch.stitch import _clearance_elements  # noqa: E402


def _old_incidence(edges, n):
    flat = edges.ravel()
    order = np.argsort(flat, kind="stable")
    inc_edge = (order // 2).astype(np.int64)
    inc_side = (order % 2).astype(np.int64)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=offsets[1:])
    return offsets, inc_edge, inc_side


def end_offsets(nodes, edges, radii, *, shrink=True, profile="inscribed"):
    from fast_stitch.fit import end_offsets as new

    inc = _old_incidence(np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2), len(nodes))
    return new(nodes, edges, radii, shrink=shrink, profile=profile, _incidence_arrays=inc)


def _profile_radii(radii, shape, profile):
    """The profile polygons' circumradii (the stitch's P = 6), as the checks use them."""
    from fast_stitch.hubvolume import profile_factor

    r = np.ascontiguousarray(np.broadcast_to(radii, shape), dtype=np.float64)
    return r * profile_factor(config.DEFAULT_SEGMENTS, profile)


@njit(cache=True, parallel=True, error_model="numpy")
def old_clash_pairs(
    seg_a, seg_b, rad, lo, hi, cell, origin, dims, count, members, edges, offsets, inc_edge,
    scale, n_found, start, out_pairs, out_dist, write,
):  # fmt: skip
    """Pairs of non-incident elements closer than ``scale * (rad_i + rad_j)``.

    ``write=False``: count them per cell into ``n_found``; ``write=True``:
    store them from ``start[cell]`` on.
    """
    m = edges.shape[0]
    for c in prange(dims[0] * dims[1] * dims[2]):
        k = 0
        for u in range(count[c], count[c + 1]):
            i = members[u]
            for w in range(u + 1, count[c + 1]):
                j = members[w]
                d2 = _kernels._candidate_d2(
                    i, j, c, seg_a, seg_b, rad, lo, hi, cell, origin, dims, m, edges, offsets,
                    inc_edge, scale,
                )  # fmt: skip
                if d2 < 0.0:
                    continue
                a = min(i, j)
                b = max(i, j)
                if write:
                    out_pairs[start[c] + k, 0] = a
                    out_pairs[start[c] + k, 1] = b
                    out_dist[start[c] + k] = np.sqrt(d2)
                k += 1
        if not write:
            n_found[c] = k


def old_clashes(
    nodes: ArrayLike,
    edges: ArrayLike,
    radii: ArrayLike,
    *,
    shrink: bool = True,
    margin: float = config.CLEARANCE_MARGIN,
    profile: str = "inscribed",
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Struts and joints that share no node but would come too close.

    Elements ``0 .. M-1`` are the struts, ``M + n`` the joint at node ``n``
    (nodes of degree >= 2). Two elements clash when they share no node (two
    joints: no strut joins their nodes) and the distance between their
    capsules' axes is below ``(1 + margin) * (r_a + r_b)`` (see the module
    docstring). Uses a uniform grid: linear in the number of struts.

    Returns
    -------
    pairs : (K, 2) int64
        Clashing element pairs, ``pairs[:, 0] < pairs[:, 1]``, sorted.
    distance : (K,) float64
        Distance between the two axes (segments; a joint's is its node).
    needed : (K,) float64
        ``(1 + margin) * (r_a + r_b)``.
    """
    nodes_a = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    edges_a = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    radii_a = _profile_radii(radii, edges_a.shape, profile)
    n, m = len(nodes_a), len(edges_a)
    empty = (np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0))
    if m == 0:
        return empty
    offsets, inc_edge, inc_side = _old_incidence(edges_a, n)
    off = end_offsets(nodes_a, edges_a, radii_a, shrink=shrink, profile="inscribed")
    vec = nodes_a[edges_a[:, 1]] - nodes_a[edges_a[:, 0]]
    length = np.linalg.norm(vec, axis=1)
    unit = vec / np.where(length > 0, length, 1.0)[:, None]
    seg_a, seg_b, rad, lo, hi, cell, origin, dims = _clearance_elements(
        nodes_a, edges_a, radii_a, off, unit, offsets, inc_edge, inc_side, pad=1.0 + margin
    )
    count, members = _kernels.element_grid(lo, hi, rad, cell, origin, dims)
    n_cells = int(np.prod(dims))
    n_found = np.zeros(n_cells, dtype=np.int64)
    start = np.zeros(n_cells + 1, dtype=np.int64)
    no_pairs = np.zeros((0, 2), dtype=np.int64)
    args = (seg_a, seg_b, rad, lo, hi, cell, origin, dims, count, members, edges_a, offsets,
            inc_edge, 1.0 + margin)  # fmt: skip
    old_clash_pairs(*args, n_found, start, no_pairs, np.zeros(0), False)
    np.cumsum(n_found, out=start[1:])
    k = int(start[-1])
    if k == 0:
        return empty
    pairs = np.empty((k, 2), dtype=np.int64)
    dist = np.empty(k)
    old_clash_pairs(*args, n_found, start, pairs, dist, True)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    pairs, dist = pairs[order], dist[order]
    return pairs, dist, (1.0 + margin) * rad[pairs].sum(axis=1)


# ------------------------------------------------ conformal.radius.fit_radii before the slabs
def old_misfits(nodes, edges, radii, *, shrink=True, slack=0.0, profile="inscribed"):
    off = end_offsets(nodes, edges, radii, shrink=shrink, profile=profile)
    need = off.sum(axis=1)
    length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    bad = np.flatnonzero(need >= length * (1.0 - config.MIN_CYLINDER_FRACTION - slack))
    return bad.astype(np.int64), need, length


def old_fit_radii(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    min_radius: float = 0.0,
    shrink: bool = True,
    clearance: bool = True,
    max_rounds: int = 60,
    profile: str = "inscribed",
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Thin the struts at crowded nodes, and struts that pass too close, until all fit.

    A strut fits when its end offsets leave ``config.FIT_SLACK`` of its length free
    and its radius is below 0.45 of its length. Offsets at a node scale
    linearly with the radii there, so the radii at both ends of a misfit
    strut's nodes are scaled down by the missing factor (which may taper
    neighbouring struts), and the check is repeated.

    With ``clearance``, once every strut fits, struts and joints that share no
    node but come closer than their radii allow (:func:`fast_stitch.fit.clashes`,
    with twice its margin as a target) are thinned too: a clashing strut is
    scaled as a whole (its taper is kept), a clashing joint by scaling the
    radii of the strut ends at its node; then everything is checked again.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
    min_radius : float
        Radii are never reduced below this.

    Returns
    -------
    radii : (M, 2) float64
        The fitted radii.
    unfit : (K,) int64
        Struts that still do not fit or clear (radius at ``min_radius``).
    """
    r = np.array(radii, dtype=np.float64, copy=True)
    length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    cap = 0.45 * length
    too_fat = r > cap[:, None]
    r[too_fat] = np.broadcast_to(cap[:, None], r.shape)[too_fat]
    bad = np.zeros(0, dtype=np.int64)
    n_nodes, m = len(nodes), len(edges)
    for _ in range(max_rounds):
        bad, need, length = old_misfits(
            nodes, edges, r, shrink=shrink, slack=config.FIT_SLACK, profile=profile
        )
        node_f = np.ones(n_nodes)
        edge_f = np.ones(m)
        if len(bad):
            factor = np.clip((1.0 - 1.5 * config.FIT_SLACK) * length[bad] / need[bad], 0.2, 0.97)
            np.minimum.at(node_f, edges[bad, 0], factor)
            np.minimum.at(node_f, edges[bad, 1], factor)
        elif clearance:
            # aim past the check's own margin so that one round usually clears a pair
            pairs, dist, reach = old_clashes(
                nodes,
                edges,
                r,
                shrink=shrink,
                margin=2 * config.CLEARANCE_MARGIN,
                profile=profile,
            )
            bad = _clash_struts(pairs, edges, m, n_nodes)
            if not len(pairs):
                return r, bad
            factor = np.repeat(np.clip(0.98 * dist / reach, 0.2, 0.97), 2)
            el = pairs.ravel()
            strut = el < m
            np.minimum.at(edge_f, el[strut], factor[strut])
            np.minimum.at(node_f, el[~strut] - m, factor[~strut])
        else:
            return r, bad
        new = r * node_f[edges] * edge_f[:, None]
        new = np.maximum(new, min_radius)
        if np.array_equal(new, r):
            break
        r = new
    return r, bad


def _clash_struts(
    pairs: NDArray[np.int64], edges: NDArray[np.int64], m: int, n_nodes: int
) -> NDArray[np.int64]:
    """The struts involved in clashes: clashing struts, and the struts at clashing joints."""
    el = np.unique(pairs.ravel())
    joint = np.zeros(n_nodes, dtype=np.bool_)
    joint[el[el >= m] - m] = True
    at_joint = np.flatnonzero(joint[edges].any(axis=1))
    return np.union1d(el[el < m], at_joint).astype(np.int64)
