"""Clip the beams of a beam-lattice 3MF to the part (issue 13, "parts keep their size").

A beam-lattice 3MF stores the graph's struts as round beams; a beam-aware reader prints
them as they are. The graph of a ``clip``, ``conform`` or tet lattice has nodes on the
part's surface and struts that cut across concave regions (chords of holes and fillets),
so its beams reach beyond the surface: by their radius, and by as much as their axis
leaves the part. :func:`clip_beams` keeps, of every beam, the parts that lie inside:

``keep="solid"``
    Every point of a kept beam, round surface and caps included, lies inside the part
    (within the tolerance): the axis is kept where its distance to the surface is at least
    the beam's radius there. Used when the file also holds the trimmed triangle mesh
    (``Lattice.save(..., beam_lattice=True)``): the mesh reaches the surface, the beams
    add nothing outside it.
``keep="axis"``
    The axis is kept where it lies inside the part; the round beam still reaches up to its
    radius beyond the surface near it. Used for beams-only files, which also carry the part
    as the beam lattice's clipping mesh for the readers that honour it.

A beam keeps its radius profile: where it is cut, the new end has the radius the beam had
at that point (the linear taper of a tapered strut is kept), and as an end of a single
beam it gets a flat (butt) cap. A beam that leaves and re-enters the part becomes several
beams; a beam with nothing inside is dropped, and so is a cut piece no longer than twice
its radius (a graph's struts are longer than that; the node's ball or the triangle mesh
covers such a stub).

How ("solid"): ``f(t) = sd(p(t)) + r(t)`` along each beam (``sd``: signed distance to the
part's tessellation, negative inside) is Lipschitz in ``t`` with constant
``K = |b - a| + |r_b - r_a|``. Intervals of ``t`` are bisected until the
bound ``(f_0 + f_1 + K dt) / 2`` proves ``f <= tol`` on them, or ``(f_0 + f_1 - K dt) / 2 > 0``
proves them outside, or they are shorter than ``tol / K`` (then kept only if both ends have
``f <= tol / 2``). So every kept point satisfies ``f <= tol`` (a guarantee, not a sample),
and a beam is shortened by at most ``tol / K`` of its length beyond what must go.
("axis"): each axis is split where it crosses the tessellation (``Part.segment_crossings``)
and the pieces whose midpoint is inside are kept (exact; bisection with ``f = sd`` would
crawl along the struts of a tet lattice that lie in the surface). Such a strut is on
either side by rounding; it is kept when 33 points along it are within half the tolerance
of the surface (a sample, not a bound: the round beam reaches its radius beyond the
surface anyway, and a beams-only file carries the part as clipping mesh). An axis with
more than ``_CAP`` crossings is bisected as above.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.graph import LatticeGraph

__all__ = ["BeamClipReport", "clip_beams"]

Keep = Literal["solid", "axis"]

#: Bisection rounds at most (each halves every undecided interval): 2**-48 of a beam.
_MAX_ROUNDS = 48

#: Crossings with the surface handled exactly per beam ("axis"); beams with more are bisected.
_CAP = 8

#: Points checked along a strut lying in the surface ("axis"), see _between_crossings.
_SAMPLES = 33

#: Crossing parameters this close to 0 or 1 are the beam's end node.
_AT_NODE = 1e-9

Intervals = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], float]


@dataclass(frozen=True)
class BeamClipReport:
    """What :func:`clip_beams` did.

    Attributes
    ----------
    keep : "solid" or "axis"
    beams_before, beams_after : int
    cut : int
        Beams shortened or split (at least one piece kept).
    removed : int
        Beams with nothing inside the part (dropped).
    outside_before : float
        Largest ``f`` found on the beams before clipping (mm): how far the round beam
        ("solid") or its axis ("axis") reached outside the part, at the points evaluated
        (a lower bound of the true largest value).
    tolerance : float
        Every point of a kept beam has ``f <= tolerance`` (mm).
    seconds : float
    """

    keep: Keep
    beams_before: int
    beams_after: int
    cut: int
    removed: int
    outside_before: float
    tolerance: float
    seconds: float

    def summary(self) -> str:
        what = "round beams" if self.keep == "solid" else "beam axes"
        if not self.cut and not self.removed:
            return f"beams: all {self.beams_before:,} {what} lie inside the part"
        return (
            f"beams: {what} clipped to the part: {self.cut:,} cut, {self.removed:,} removed "
            f"({self.beams_before:,} -> {self.beams_after:,} beams); they reached "
            f"{max(self.outside_before, 0.0):.3g} mm outside, now at most "
            f"{self.tolerance:.2g} mm"
        )


def clip_beams(
    graph: LatticeGraph,
    part: Any,
    *,
    keep: Keep = "solid",
    tolerance: float | None = None,
) -> tuple[LatticeGraph | None, BeamClipReport]:
    """The beams of ``graph`` clipped to the part.

    Parameters
    ----------
    graph : LatticeGraph
    part : conformal.Part
    keep : "solid" or "axis"
        What must lie inside the part: the whole round beam, or its axis (see the module
        docstring).
    tolerance : float, optional
        How far (mm) a kept beam may reach outside the part's surface; default
        ``config.TRIM_RTOL`` times the largest radius (as ``conformal.trim.trim_to_part``),
        but at least twice the float32 spacing at the part's coordinates.

    Returns
    -------
    graph : LatticeGraph or None
        The nodes that keep a beam (in their order), then the new cut ends; radii
        ``(M', 2) float64`` follow each beam's taper. None when no beam is left.
    report : BeamClipReport

    Raises
    ------
    ValueError
        ``keep`` is not "solid" or "axis", or ``tolerance`` is not positive.
    """
    from conformal.trim import _tolerance

    if keep not in ("solid", "axis"):
        raise ValueError(f"keep must be 'solid' or 'axis', got {keep!r}")
    t_start = time.perf_counter()
    w = 1.0 if keep == "solid" else 0.0
    nodes, edges, radii = graph.nodes, graph.edges, graph.radii
    m = len(edges)
    extent = float(np.abs(part.bounds).max()) if len(part.vertices) else 1.0
    rmax = float(radii.max()) if m else 0.0
    tol = _tolerance(rmax, extent) if tolerance is None else float(tolerance)
    if not tol > 0:
        raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
    if m == 0:
        report = BeamClipReport(keep, 0, 0, 0, 0, 0.0, tol, time.perf_counter() - t_start)
        return None, report

    a = nodes[edges[:, 0]]
    b = nodes[edges[:, 1]]
    r0, r1 = radii[:, 0], radii[:, 1]
    lip = np.linalg.norm(b - a, axis=1) + w * np.abs(r1 - r0)  # (M,) Lipschitz in t
    used = np.unique(edges)
    sd_nodes = np.zeros(len(nodes))
    sd_nodes[used] = part.signed_distance(nodes[used])
    f0 = sd_nodes[edges[:, 0]] + w * r0
    f1 = sd_nodes[edges[:, 1]] + w * r1
    worst = float(max(f0.max(), f1.max()))

    def f_at(e: NDArray[np.int64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        p = a[e] + t[:, None] * (b[e] - a[e])
        return part.signed_distance(p) + w * (r0[e] + t * (r1[e] - r0[e]))

    ie = np.arange(m, dtype=np.int64)
    kept: list[Intervals] = []
    if keep == "axis":
        # exact: split at the crossings with the surface, keep the pieces whose midpoint is
        # inside (bisection would crawl along the struts that lie in the surface)
        count, params = part.segment_crossings(a, b, cap=_CAP)
        exact = count <= _CAP
        kept.append(_between_crossings(part, a, b, np.flatnonzero(exact), count, params, tol))
        worst = max(worst, kept[-1][3])
        ie = np.flatnonzero(~exact)
    if len(ie):
        kept.append(_bisect(ie, f0[ie], f1[ie], lip, tol, f_at))
        worst = max(worst, kept[-1][3])
    ke = np.concatenate([x[0] for x in kept])
    ks = np.concatenate([x[1] for x in kept])
    kt = np.concatenate([x[2] for x in kept])
    order = np.lexsort((ks, ke))
    ke, ks, kt = ke[order], ks[order], kt[order]
    # merge touching intervals of the same beam into pieces
    start = np.ones(len(ke), dtype=bool)
    start[1:] = (ke[1:] != ke[:-1]) | (ks[1:] != kt[:-1])
    piece = np.cumsum(start) - 1
    pe = ke[start]
    ps = ks[start]
    pt = np.zeros(len(pe))
    np.maximum.at(pt, piece, kt)
    # a graph's strut is longer than its two end radii (``LatticeGraph``): a cut piece as
    # short as that is dropped (its node's ball, or the triangle mesh, covers it)
    length = (pt - ps) * np.linalg.norm(b[pe] - a[pe], axis=1)
    ra, rb = r0[pe] + ps * (r1[pe] - r0[pe]), r0[pe] + pt * (r1[pe] - r0[pe])
    long_enough = ((ps == 0.0) & (pt == 1.0)) | (length > 2.0 * np.maximum(ra, rb) * (1 + 1e-9))
    pe, ps, pt = pe[long_enough], ps[long_enough], pt[long_enough]

    whole = (ps == 0.0) & (pt == 1.0)
    n_pieces = np.bincount(pe, minlength=m)
    n_whole = np.bincount(pe[whole], minlength=m)
    removed = int((n_pieces == 0).sum())
    cut = int(((n_pieces > 0) & (n_whole == 0)).sum())

    # node ids of the piece ends: the original node at t = 0 / 1, else a new node
    new_pts: list[NDArray[np.float64]] = []
    ends = np.zeros((len(pe), 2), dtype=np.int64)
    rad = np.zeros((len(pe), 2))
    n_new = len(nodes)
    for col, t in ((0, ps), (1, pt)):
        at_node = t == float(col)
        ends[at_node, col] = edges[pe[at_node], col]
        fresh = np.flatnonzero(~at_node)
        e = pe[fresh]
        new_pts.append(a[e] + t[fresh, None] * (b[e] - a[e]))
        ends[fresh, col] = n_new + np.arange(len(fresh))
        n_new += len(fresh)
        rad[:, col] = r0[pe] + t * (r1[pe] - r0[pe])
    out_nodes = np.vstack([nodes, *new_pts])
    keep_nodes = np.unique(ends)  # nodes with a beam left, in their order
    remap = np.full(len(out_nodes), -1, dtype=np.int64)
    remap[keep_nodes] = np.arange(len(keep_nodes))
    out = LatticeGraph(out_nodes[keep_nodes], remap[ends], rad) if len(pe) else None
    report = BeamClipReport(
        keep=keep,
        beams_before=m,
        beams_after=len(pe),
        cut=cut,
        removed=removed,
        outside_before=worst,
        tolerance=tol,
        seconds=time.perf_counter() - t_start,
    )
    return out, report


def _bisect(
    ie: NDArray[np.int64],
    f0: NDArray[np.float64],
    f1: NDArray[np.float64],
    lip: NDArray[np.float64],
    tol: float,
    f_at: Any,
) -> Intervals:
    """Parts ``[t0, t1]`` of the beams ``ie`` where ``f <= tol`` is proven (module docstring).

    ie : (K,) int64 beam ids, f0, f1 : (K,) float64 ``f`` at their ends, lip : (M,) float64
    Lipschitz constants of all beams, ``f_at(e, t)``: ``f`` at parameters ``t`` of beams ``e``.
    Returns beam ids, t0, t1 (float64) of the kept intervals and the largest ``f`` evaluated.
    """
    it0, it1 = np.zeros(len(ie)), np.ones(len(ie))
    if0, if1 = f0.copy(), f1.copy()
    worst = float(max(f0.max(initial=-np.inf), f1.max(initial=-np.inf)))
    out: list[tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]] = []
    for _ in range(_MAX_ROUNDS + 1):
        if not len(ie):
            break
        k = lip[ie] * (it1 - it0)
        upper = 0.5 * (if0 + if1 + k)
        lower = 0.5 * (if0 + if1 - k)
        short = k <= tol
        inside = (upper <= tol) | (short & (np.maximum(if0, if1) <= 0.5 * tol))
        outside = ~inside & ((lower > 0) | short)
        out.append((ie[inside], it0[inside], it1[inside]))
        split = ~inside & ~outside
        ie, it0, it1, if0, if1 = ie[split], it0[split], it1[split], if0[split], if1[split]
        if not len(ie):
            break
        tm = 0.5 * (it0 + it1)
        fm = f_at(ie, tm)
        worst = max(worst, float(fm.max()))
        ie = np.concatenate([ie, ie])
        it0, it1 = np.concatenate([it0, tm]), np.concatenate([tm, it1])
        if0, if1 = np.concatenate([if0, fm]), np.concatenate([fm, if1])
    # intervals still undecided after _MAX_ROUNDS (shorter than 2**-48 of a beam) are dropped
    if not out:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), worst
    return (
        np.concatenate([x[0] for x in out]),
        np.concatenate([x[1] for x in out]),
        np.concatenate([x[2] for x in out]),
        worst,
    )


def _between_crossings(
    part: Any,
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    ie: NDArray[np.int64],
    count: NDArray[np.int64],
    params: NDArray[np.float64],
    tol: float,
) -> Intervals:
    """Parts of the segments ``a[ie] -> b[ie]`` between consecutive crossings of the surface
    whose midpoint is inside the part. count : (M,) int64, params : (M, cap) float64 from
    ``Part.segment_crossings``; returns beam ids, t0, t1 and the largest signed distance of
    a midpoint."""
    k = count[ie]
    j = np.arange(params.shape[1] + 1)
    valid = j[None, :] <= k[:, None]  # sub-interval j of k + 1
    bounds = np.concatenate([np.zeros((len(ie), 1)), params[ie], np.ones((len(ie), 1))], 1)
    bounds[np.arange(len(ie)), k + 1] = 1.0
    # a crossing at a node (nodes on the surface) is the node itself
    bounds = np.where(bounds < _AT_NODE, 0.0, np.where(bounds > 1.0 - _AT_NODE, 1.0, bounds))
    valid &= bounds[:, 1:] > bounds[:, :-1]
    rows, cols = np.nonzero(valid)
    e = ie[rows]
    t0, t1 = bounds[rows, cols], bounds[rows, cols + 1]
    mid = 0.5 * (t0 + t1)
    sd = part.signed_distance(a[e] + mid[:, None] * (b[e] - a[e]))
    inside = sd <= 0.0
    # struts lying in the surface (tet lattices, planar faces) are on either side by
    # rounding: kept when _SAMPLES points along them are within half the tolerance
    near = np.flatnonzero(~inside & (sd <= 0.5 * tol))
    if len(near):
        s = np.linspace(0.0, 1.0, _SAMPLES)
        tt = t0[near, None] + s[None, :] * (t1 - t0)[near, None]  # (K, S)
        en = e[near]
        pts = a[en, None, :] + tt[:, :, None] * (b[en] - a[en])[:, None, :]
        sds = part.signed_distance(pts.reshape(-1, 3)).reshape(tt.shape)
        inside[near[sds.max(axis=1) <= 0.5 * tol]] = True
    return e[inside], t0[inside], t1[inside], float(sd.max(initial=-np.inf))
