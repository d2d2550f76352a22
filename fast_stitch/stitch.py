"""Graph -> watertight triangle mesh (Verma, Rankouhi & Suresh 2019).

Algorithm (per node of degree d >= 2, in parallel over distinct hub shapes):

1. pairwise minimum profile offsets ``d_ij = (r_j + r_i cos t) / sin t``; the
   ideal offset of strut i is the largest over j (it is exactly where the
   cones of the two struts touch), never below ``r_i * tan(10 deg)``;
2. volume reduction (``shrink=True``): each profile starts at its ideal
   offset and is pushed out only as far as needed for every other profile to
   lie strictly below its plane; without it, all profiles sit on one sphere;
3. the hub is the convex hull of its profile vertices (incremental hull in
   plain floating point); the triangles inside each profile are removed,
   which leaves exactly ``d * P + 2d - 4`` triangles (Euler);
4. open cylinders (frustums for tapered struts) join the two profiles of each
   strut with ``2P`` triangles; degree-1 nodes get a flat cap of ``P - 2``;
5. ``profile="volume"`` (default): the profiles have the circle's area, and each hub
   is scaled about its node so that its volume is the exact solid's there
   (:mod:`fast_stitch.hubvolume`): the mesh has the exact solid's volume. The struts
   keep the unscaled profile between two *band rings* (``2 M P`` more vertices, after the
   hub rings), each joined to its scaled hub ring by a band of ``2 P`` triangles (after
   the hub and cap triangles): the correction stays at the hubs.

Profiles use one frame per strut (no twist) with a seeded pseudo-random
phase derived from the strut's direction, so hubs that are translates of
each other are identical and are computed once (periodic lattices).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import NDArray

from fast_stitch import _kernels
from fast_stitch._predicates import box_stats, tri_tri
from fast_stitch.hubvolume import (
    PROFILES,
    Profile,
    area_factor,
    band_rings,
    cap_taper_growth,
    hub_scales,
    profile_factor,
    taper_cone_pairs,
)
from lattice_cad.core import config
from lattice_cad.core.checks import (
    Progress,
    ProgressCallback,
    check_seed,
    check_segments,
    check_workers,
)
from lattice_cad.core.errors import StitchError
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.mesh import Mesh, stl_size
from lattice_cad.core.resources import require_memory

__all__ = [
    "stitch",
    "estimate",
    "Estimate",
    "ProgressCallback",
    "Profile",
    "area_factor",
    "profile_factor",
]

_CHUNK = 1 << 15


@dataclass(frozen=True)
class Estimate:
    """Exact output size of :func:`stitch`, known before building anything.

    Attributes
    ----------
    vertices, triangles : int
        Exact counts of the stitched mesh.
    stl_bytes : int
        Exact size of its binary STL file.
    memory_bytes : int
        Estimated peak memory of :func:`stitch` (output, work arrays and the clearance
        check), checked against the available memory before anything is allocated.
    """

    vertices: int
    triangles: int
    stl_bytes: int
    memory_bytes: int = 0


def _face_counts(degree: NDArray[np.int64], P: int) -> NDArray[np.int64]:
    """(N,) int64: hub (d >= 2) or cap (d == 1) triangles of each node."""
    counts = np.where(degree >= 2, degree * P + 2 * degree - 4, 0)
    counts = np.where(degree == 1, P - 2, counts)
    return counts.astype(np.int64)


def estimate(
    graph: LatticeGraph,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: Profile = "volume",
) -> Estimate:
    """Exact vertex and triangle counts, and binary STL size, of
    ``stitch(graph, segments, profile=profile)``.

    ``V = 2 M P`` and ``F = 2 M P + sum_{d >= 2} (d P + 2 d - 4) + (P - 2) * #leaves``;
    ``profile="volume"`` adds the band rings and bands: ``2 M P`` vertices and ``4 M P``
    triangles more.
    """
    P = check_segments(segments)
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"expected a LatticeGraph, got {type(graph).__name__}")
    if profile not in PROFILES:
        raise ValueError(
            f"profile must be one of {', '.join(map(repr, PROFILES))}, got {profile!r}"
        )
    m = graph.num_edges
    hub_tri = int(_face_counts(graph.degree, P).sum())
    banded = profile == "volume"
    tri = (6 if banded else 2) * m * P + hub_tri
    v = (4 if banded else 2) * m * P
    return Estimate(
        vertices=v,
        triangles=tri,
        stl_bytes=stl_size(tri),
        memory_bytes=_memory_bytes(v, tri, hub_tri, m, graph.num_nodes),
    )


def _memory_bytes(n_vertices: int, n_triangles: int, hub_triangles: int, m: int, n: int) -> int:
    """Peak bytes of :func:`stitch`: the mesh (24 B per vertex and per triangle), the hub
    triangles before they are scattered (24 B each, when no two hubs are alike), per-strut
    work arrays (frames, slots, offsets, the graph's cached incidence and clearance
    capsules and grid: about 560 B) and per-node ones (about 250 B). Measured peak RSS
    increase on bcc blocks of 10^4..10^5 struts is within this bound (see
    ``tests/test_resources.py``)."""
    return 24 * (n_vertices + n_triangles + hub_triangles) + 560 * m + 250 * n


def stitch(
    graph: LatticeGraph,
    segments: int | None = config.DEFAULT_SEGMENTS,
    *,
    method: Literal["verma", "lslt"] = "verma",
    chord_error: float | None = None,
    sections: int | Literal["auto"] | None = None,
    shrink: bool = True,
    seed: int = 0,
    workers: int | None = None,
    progress: bool | ProgressCallback | None = None,
    check_clearance: bool = True,
    profile: Profile = "volume",
    volume_preserving: bool | None = None,
    _report: dict[str, Any] | None = None,
) -> Mesh:
    """Build the watertight triangle mesh of a lattice graph.

    Parameters
    ----------
    graph : LatticeGraph
    segments : int
        P, the number of sides of every strut's polygonal profile (>= 3).
        Ignored by ``method="lslt"``; with ``chord_error`` it may be None.
    method : {"verma", "lslt"}
        ``"verma"``: the combinatorial stitcher (Verma et al. 2019, this module).
        ``"lslt"``: lightweight triangulation (Chougrani et al. 2017), see
        :func:`fast_stitch.lslt.stitch_lslt`.
    chord_error : float, optional
        Largest distance between a strut's circle and its polygon, relative to
        the radius. For ``"verma"`` it chooses ``segments`` (the smallest P
        that meets it, overriding ``segments``); for ``"lslt"`` it is the
        method's accuracy (default 0.05).
    sections : int or "auto", optional
        LSLT intermediary sections per strut (``"auto"``: the paper's Eq. 11).
    shrink : bool
        Reduce hub volume: each profile sits as close to its node as the
        geometry allows, instead of all on one sphere.
    seed : int
        Seed of the per-strut profile phase. Same graph and seed give
        byte-identical output.
    workers : int, optional
        Threads to use (default: numba's default, all cores).
    progress : bool or callable, optional
        ``True`` shows a tqdm bar; a callable is called as
        ``progress(stage, done, total)``. The run can be interrupted with
        Ctrl-C between chunks.
    check_clearance : bool
        Verify that struts and hubs that share no node do not overlap (struts
        crossing away from a node, a strut through another node's joint). The
        construction guarantees everything else; this makes the no
        self-intersection guarantee hold for every graph that stitches.
    profile : {"volume", "area", "inscribed", "circumscribed"}
        The P-gon of every strut end (``method="verma"`` only).
        ``"volume"`` (default): the mesh has the volume of the exact solid (the
        cylinders united with a ball of the largest radius at every node of
        degree >= 2, flat at leaves): profiles of the circle's area (circumradius
        ``r * sqrt(2 pi / (P sin(2 pi / P)))``, so struts keep the cylinder's
        volume) and every hub, with the strut ends at it, scaled about its node by
        ``s_n`` so that the hub has the exact solid's volume there (see
        :mod:`fast_stitch.hubvolume`; on periodic lattices ``|1 - s_n|`` is a
        few %, on irregular (tet) nodes the hull holds much more than the ball, so
        ``s_n`` is about 0.7-0.9 and the struts meet the hub in a neck; ``s_n > 1`` at
        boundary nodes whose struts all leave on one side, capped so that grown hubs
        overlap nothing: :func:`cap_growth`).
        ``"area"``: profiles of the circle's area, no hub correction (hubs are
        fuller than the exact solid: the GE bracket's Box-BCC lattice +1.4 %, its tet
        lattice +10.8 % at P = 6). ``"inscribed"``: vertices on the
        circle (the mesh is thinner than the design, e.g. -16 % of the volume at
        P = 6). ``"circumscribed"``: edges tangent to the circle (struts contain
        the cylinders).
    volume_preserving : bool, optional
        Deprecated alias: True is ``profile="area"``, False ``profile="inscribed"``.

    Returns
    -------
    Mesh
        ``vertices`` (2 M P, 3) float64 (4 M P with ``profile="volume"``: the band
        rings follow the hub rings) and ``faces`` (F, 3) int64, with F as given by
        :func:`estimate`: the struts' ``2 P`` triangles each (rows ``2 P e``), the hubs'
        and caps' (from ``2 M P``, node by node), then with ``profile="volume"`` the
        bands' ``4 P`` per strut. Watertight, 2-manifold, outward oriented,
        without zero-area triangles.

    Raises
    ------
    StitchError
        The graph has no struts; struts at a node meet at so small an angle
        that the profiles of a strut's two ends would cross (the message names
        the node, both struts, the angle and the shortest length that fits);
        two struts at a node are parallel; struts or joints that share no node
        overlap (with ``check_clearance``).
    """
    if volume_preserving is not None:
        import warnings

        warnings.warn(
            "stitch(volume_preserving=...) is deprecated: use profile='volume' (the default, "
            "exact volume including the hubs), 'area' (the former volume_preserving=True) or "
            "'inscribed' (the former default)",
            DeprecationWarning,
            stacklevel=2,
        )
        profile = "area" if volume_preserving else "inscribed"
    if profile not in PROFILES:
        raise ValueError(
            f"profile must be one of {', '.join(map(repr, PROFILES))}, got {profile!r}"
        )
    if method == "lslt":
        from fast_stitch.lslt import stitch_lslt

        return stitch_lslt(
            graph,
            chord_error=0.05 if chord_error is None else chord_error,
            sections=sections,
            seed=seed,
            workers=workers,
            progress=progress,
        )
    if method != "verma":
        raise ValueError(f"method must be 'verma' or 'lslt', got {method!r}")
    if sections is not None:
        raise ValueError("sections only applies to method='lslt'")
    if chord_error is not None:
        from fast_stitch.lslt import segments_for_chord_error

        segments = segments_for_chord_error(chord_error)
    P = check_segments(segments)
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"expected a LatticeGraph, got {type(graph).__name__}")
    seed = check_seed(seed)
    workers = check_workers(workers)
    m = graph.num_edges
    if m == 0:
        raise StitchError("the graph has no struts: nothing to stitch")
    est = estimate(graph, P, profile)
    require_memory(
        est.memory_bytes,
        f"stitching {m:,} struts ({est.triangles:,} triangles)",
        advice="use fewer or larger cells, fewer segments, or write the lattice as a 3MF "
        "beam lattice (beam_lattice=True, --beam-lattice), which needs no mesh",
    )
    prev_threads = numba.get_num_threads()
    if workers is not None:
        numba.set_num_threads(min(workers, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]
    bar = Progress(progress, graph.num_nodes, desc="stitch", unit="hub")
    try:
        prad = graph.radii * profile_factor(P, profile)
        mesh, end_offset, face_start, radii = _stitch(
            graph, prad, P, bool(shrink), int(seed) & 0xFFFFFFFFFFFFFFFF, bar,
            correct_hubs=profile == "volume", report=_report,
        )  # fmt: skip
        if check_clearance:
            bar("clearance", 0, 1)
            _check_clearance(graph, radii, mesh, end_offset, face_start, P)
            _check_tapered_neighbours(graph, prad, mesh, face_start, P)
        bar("done", 1, 1)
        return mesh
    finally:
        bar.close()
        numba.set_num_threads(prev_threads)


def _stitch(
    graph: LatticeGraph,
    radii: NDArray[np.float64],
    P: int,
    shrink: bool,
    seed: int,
    progress: Progress,
    *,
    correct_hubs: bool = False,
    report: dict[str, Any] | None = None,
) -> tuple[Mesh, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """The mesh, its profile offsets (M, 2), hub face starts (N,) and profile radii (M, 2).

    With ``correct_hubs`` the hubs are scaled to the exact solid's volume (``radii`` are
    then the area-preserving profile radii; see :mod:`fast_stitch.hubvolume`), growth
    capped by :func:`cap_growth` (its nodes go to ``report["capped"]`` when given)."""
    nodes, edges = graph.nodes, graph.edges
    n_nodes, m = graph.num_nodes, graph.num_edges
    offsets, inc_edge, inc_side = graph.incidence
    degree = graph.degree

    qdir = np.empty((m, 3), dtype=np.int64)
    sign = np.empty(m, dtype=np.int64)
    axis = np.empty((m, 3))
    fu = np.empty((m, 3))
    fv = np.empty((m, 3))
    length = np.empty(m)
    _kernels.edge_frames(nodes, edges, P, seed, qdir, sign, axis, fu, fv, length)

    slots = np.empty(2 * m, dtype=np.int64)
    slot_q = np.empty((2 * m, 3), dtype=np.int64)
    slot_r = np.empty(2 * m, dtype=np.int64)
    keys = np.empty(n_nodes, dtype=np.uint64)
    rmax = float(radii.max())
    _kernels.node_slots(
        offsets, inc_edge, inc_side, qdir, sign, radii, rmax, slots, slot_q, slot_r, keys
    )
    _check_parallel(offsets, slots, slot_q, degree)

    # distinct hub shapes: group nodes by key, verify the key really matches
    hubs = np.flatnonzero(degree >= 2)
    node_rep = np.full(n_nodes, -1, dtype=np.int64)
    if len(hubs):
        uniq, first, inverse = np.unique(keys[hubs], return_index=True, return_inverse=True)
        rep_nodes = hubs[first]
        cand = rep_nodes[inverse]
        ok = np.empty(len(hubs), dtype=np.bool_)
        _kernels.same_key(hubs, cand, offsets, slots, slot_q, radii, ok)
        node_rep[hubs] = inverse
        if not ok.all():  # hash collision: those nodes get hubs of their own
            extra = hubs[~ok]
            node_rep[extra] = len(rep_nodes) + np.arange(len(extra))
            rep_nodes = np.concatenate([rep_nodes, extra])
    else:
        rep_nodes = np.zeros(0, dtype=np.int64)
    n_rep = len(rep_nodes)
    rep_deg = degree[rep_nodes]
    rep_slot_start = np.zeros(n_rep + 1, dtype=np.int64)
    np.cumsum(rep_deg, out=rep_slot_start[1:])
    rep_tri_start = np.zeros(n_rep + 1, dtype=np.int64)
    np.cumsum(rep_deg * P + 2 * rep_deg - 4, out=rep_tri_start[1:])
    rep_d = np.empty(int(rep_slot_start[-1]))
    rep_det = np.empty(int(rep_slot_start[-1]), dtype=np.int64)
    rep_tris = np.empty((int(rep_tri_start[-1]), 3), dtype=np.int64)
    rep_status = np.empty(n_rep, dtype=np.int64)
    floor_tan = math.tan(math.radians(90.0 - config.FLOOR_ANGLE_DEG))  # r / d_floor
    # chunks keep Ctrl-C responsive and drive the progress report
    for lo in range(0, n_rep, _CHUNK):
        hi = min(n_rep, lo + _CHUNK)
        _kernels.build_hubs(
            rep_nodes[lo:hi], offsets, slots, axis, sign, fu, fv, radii, P, shrink,
            config.OFFSET_MARGIN, floor_tan,
            rep_slot_start[lo : hi + 1] - rep_slot_start[lo],
            rep_tri_start[lo : hi + 1] - rep_tri_start[lo],
            rep_d[rep_slot_start[lo] : rep_slot_start[hi]],
            rep_det[rep_slot_start[lo] : rep_slot_start[hi]],
            rep_tris[rep_tri_start[lo] : rep_tri_start[hi]],
            rep_status[lo:hi],
        )  # fmt: skip
        progress("hubs", hi, n_rep)
    bad = np.flatnonzero(rep_status != _kernels.HUB_OK)
    if len(bad):
        n = int(rep_nodes[bad[0]])
        raise StitchError(
            f"node {n}: could not build a valid hub (status {int(rep_status[bad[0]])}) from its "
            f"{int(degree[n])} struts {_edges_at(graph, n)}; this is a bug, please report it with "
            "the graph"
        )

    end_offset = np.empty((m, 2))
    _kernels.scatter_offsets(offsets, slots, node_rep, rep_slot_start, rep_d, end_offset)
    _check_fit(graph, end_offset, length, offsets, slots, node_rep, rep_slot_start, rep_det)

    n_rings = 4 if correct_hubs else 2  # hub rings, then band rings (hubvolume.band_rings)
    all_vertices = np.empty((n_rings * m * P, 3))
    vertices = all_vertices[: 2 * m * P]
    _kernels.profile_vertices(nodes, edges, axis, sign, fu, fv, radii, end_offset, P, vertices)
    counts = _face_counts(degree, P)
    face_start = np.empty(n_nodes, dtype=np.int64)
    face_start[0:1] = 2 * m * P
    if n_nodes > 1:
        np.cumsum(counts[:-1], out=face_start[1:])
        face_start[1:] += 2 * m * P
    bbase = 2 * m * P + int(counts.sum())  # first band row (profile="volume")
    faces = np.empty((bbase + (4 * m * P if correct_hubs else 0), 3), dtype=np.int64)
    if not correct_hubs:  # else band_faces writes the strut rows below
        _kernels.cylinder_faces(sign, P, faces)
    _kernels.node_faces(
        offsets, slots, sign, node_rep, rep_tri_start, rep_tris, face_start, P, faces
    )
    if correct_hubs:
        scale = np.ones(n_nodes)
        if len(hubs):
            scale, _, _ = hub_scales(
                nodes, edges, graph.incidence, degree, graph.radii, radii, end_offset, length,
                vertices, faces, face_start, node_rep, P, frames=(axis, sign, fu, fv),
            )  # fmt: skip
            if graph.is_tapered:  # no growth where a widening strut meets a neighbour
                scale = cap_taper_growth(
                    nodes, edges, graph.incidence, radii, end_offset, length, scale
                )
            if report is not None:  # the unscaled profiles and scales (the sharded cap rounds)
                report["scale0"], report["radii0"], report["offset0"] = scale, radii, end_offset
            override = None if report is None else report.get("scale_override")
            if report is None:
                scale, capped = cap_growth(nodes, edges, radii, end_offset, scale)
            else:
                scale, capped = cap_growth(nodes, edges, radii, end_offset, scale, hits0=report)
            # scales of some nodes given (lattice_cad.distributed); an override implies a report
            if override is not None and report is not None:
                idx, given = override
                scale = scale.copy()
                scale[idx] = report["scale0"][idx] if given is None else given
            if report is not None:
                report["capped"], report["scale"] = capped, scale
        # the strut between its band rings keeps the unscaled profiles (hubvolume.band_rings)
        x_off, x_rad = band_rings(scale, edges, radii, end_offset, length)
        _kernels.profile_vertices(
            nodes, edges, axis, sign, fu, fv, x_rad, x_off, P, all_vertices[2 * m * P :]
        )
        # similar hubs: same triangles, profiles (radius and offset) scaled about the node
        node_scale = scale[edges]
        hub_rad = radii * node_scale
        end_offset = end_offset * node_scale
        _kernels.profile_vertices(
            nodes, edges, axis, sign, fu, fv, hub_rad, end_offset, P, vertices
        )
        radii = np.maximum(hub_rad, x_rad)  # the clearance capsules hold the bands
        _kernels.band_faces(sign, P, 2 * m * P, bbase, faces)
    return Mesh(vertices=all_vertices, faces=faces), end_offset, face_start, radii


def cap_growth(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    end_offset: NDArray[np.float64],
    scale: NDArray[np.float64],
    *,
    rounds: int = 3,
    hits0: dict[str, Any] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Limit the growth of hubs (``s_n > 1``) to what their clearance allows.

    Grown hubs (boundary nodes of ``profile="volume"``, :mod:`fast_stitch.hubvolume`) and
    the strut ends at them reach further than the profiles the fit and the clearance check
    of the unscaled mesh saw. The bounding capsules and balls of the clearance check
    (``_clearance_elements``: struts between their profile centres with their larger end
    radius, joints to their farthest profile vertex) are computed with every node scaled;
    every grown node of an element that overlaps an element sharing no node with it has
    its growth halved (``rounds`` times, then removed: ``s_n = 1``), and the check is
    repeated until no overlapping element has a grown node. The mesh inside the capsules
    then meets nothing that the unscaled or shrunk mesh did not already meet.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii, end_offset : (M, 2) float64
        Profile circumradii and offsets before scaling.
    scale : (N,) float64
        ``s_n`` of :func:`fast_stitch.hubvolume.hub_scales`.
    hits0 : dict, optional
        Receives ``"hits0"``: (N,) bool, the grown nodes of overlapping elements in the
        first round (before any halving), for the sharded path.

    Returns
    -------
    scale : (N,) float64
        The capped scales (a copy when changed).
    capped : (K,) int64
        The nodes whose growth was reduced, ascending.
    """
    from fast_stitch.fit import _clashes, _incidence

    grown = scale > 1.0
    if not grown.any():
        return scale, np.zeros(0, dtype=np.int64)
    scale = scale.copy()
    start = scale.copy()
    m, n_nodes = len(edges), len(nodes)
    inc = _incidence(edges, n_nodes)
    halvings = np.zeros(n_nodes, dtype=np.int64)
    while True:
        node_scale = scale[edges]
        pairs, _, _ = _clashes(nodes, edges, radii * node_scale, end_offset * node_scale, inc, 1e-9)
        el = np.unique(pairs.ravel())
        hit = np.zeros(n_nodes, dtype=bool)
        hit[edges[el[el < m]].ravel()] = True
        hit[el[el >= m] - m] = True
        hit &= scale > 1.0
        if hits0 is not None and "hits0" not in hits0:
            hits0["hits0"] = hit.copy()
        if not hit.any():
            break
        halvings[hit] += 1
        less = hit & (halvings <= rounds)
        scale[less] = 1.0 + 0.5 * (scale[less] - 1.0)
        scale[hit & ~less] = 1.0
    return scale, np.flatnonzero(scale != start).astype(np.int64)


def _edges_at(graph: LatticeGraph, n: int) -> list[int]:
    offsets, inc_edge, _ = graph.incidence
    return [int(e) for e in inc_edge[offsets[n] : offsets[n + 1]]]


def _angle_deg(graph: LatticeGraph, n: int, e: int, f: int) -> float:
    def out_dir(k: int) -> NDArray[np.float64]:
        a, b = graph.edges[k]
        v = graph.nodes[b] - graph.nodes[a]
        return v if a == n else -v

    u, w = out_dir(e), out_dir(f)
    c = float(np.dot(u, w) / (np.linalg.norm(u) * np.linalg.norm(w)))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def _smallest_angle(graph: LatticeGraph, n: int) -> tuple[int, int, float]:
    """The two struts of node n that meet at the smallest angle, and that angle in degrees."""
    inc = _edges_at(graph, n)
    best = (inc[0], inc[1], 180.0)
    for i, e in enumerate(inc):
        for f in inc[i + 1 :]:
            ang = _angle_deg(graph, n, e, f)
            if ang < best[2]:
                best = (e, f, ang)
    return best


def _check_parallel(
    offsets: NDArray[np.int64],
    slots: NDArray[np.int64],
    slot_q: NDArray[np.int64],
    degree: NDArray[np.int64],
) -> None:
    """Two struts of one node with the same (quantised) direction cannot be stitched."""
    idx = np.flatnonzero(degree >= 2)
    if not len(idx):
        return
    node_of = np.repeat(np.arange(len(degree)), degree)
    same = (slot_q[1:] == slot_q[:-1]).all(axis=1) & (node_of[1:] == node_of[:-1])
    if same.any():
        t = int(np.flatnonzero(same)[0])
        n = int(node_of[t])
        e, f = sorted((int(slots[t] // 2), int(slots[t + 1] // 2)))
        raise StitchError(f"node {n}: struts {e} and {f} leave it in the same direction (parallel)")


def _check_fit(
    graph: LatticeGraph,
    end_offset: NDArray[np.float64],
    length: NDArray[np.float64],
    offsets: NDArray[np.int64],
    slots: NDArray[np.int64],
    node_rep: NDArray[np.int64],
    rep_slot_start: NDArray[np.int64],
    rep_det: NDArray[np.int64],
) -> None:
    """Raise StitchError if the two profiles of some strut would meet or cross."""
    need = end_offset.sum(axis=1)
    over = need >= length * (1.0 - config.MIN_CYLINDER_FRACTION)
    if not over.any():
        return
    e = int(np.flatnonzero(over)[np.argmax((need / length)[over])])
    side = int(np.argmax(end_offset[e]))
    n = int(graph.edges[e, side])
    lo = int(offsets[n])
    t = int(np.flatnonzero(slots[lo : offsets[n + 1]] == 2 * e + side)[0])
    det = int(rep_det[rep_slot_start[node_rep[n]] + t])
    other = int(graph.edges[e, 1 - side])
    needs = f"{end_offset[e, side]:.4g} at node {n} + {end_offset[e, 1 - side]:.4g} at node {other}"
    fits = f"it would need to be longer than {need[e]:.4g}"
    if det >= 0:
        f = int(slots[lo + det] // 2)
        ang = _angle_deg(graph, n, e, f)
        a, b, amin = _smallest_angle(graph, n)
        cause = (
            ""
            if {a, b} == {e, f}
            else (
                f"; the hub is that large because struts {a} and {b} meet at only "
                f"{amin:.3g} degrees"
            )
        )
        raise StitchError(
            f"node {n}: struts {e} and {f} meet at {ang:.3g} degrees, too small an angle for "
            f"strut {e} (length {length[e]:.4g}): its end profiles need {needs} and would cross; "
            f"{fits} (or use thinner struts or a larger angle){cause}"
        )
    raise StitchError(
        f"strut {e} (nodes {n}, {other}, length {length[e]:.4g}) is too short for its radius: its "
        f"end profiles need {needs} and would cross; {fits}"
    )


def _clearance_elements(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    end_offset: NDArray[np.float64],
    unit: NDArray[np.float64],
    offsets: NDArray[np.int64],
    inc_edge: NDArray[np.int64],
    inc_side: NDArray[np.int64],
    *,
    pad: float = 1.0,
) -> tuple[Any, ...]:
    """Bounding shapes of struts and joints, and a grid over them, for clearance checks.

    Elements ``0..M-1`` are struts: capsules between their two profile centres
    with their larger end radius; elements ``M + n`` are joints: balls around
    node n reaching its farthest profile vertex (``rad == -1`` for degree < 2).
    Used by :func:`stitch` (exact confirmation on the mesh) and by
    :mod:`fast_stitch.fit` (before building).

    Returns
    -------
    seg_a, seg_b : (M + N, 3) float64
    rad : (M + N,) float64
    lo, hi : (M + N, 3) float64
        Boxes, padded by ``pad * rad``.
    cell : float
    origin : (3,) float64
    dims : (3,) int64
    """
    m, n_nodes = len(edges), len(nodes)
    seg_a = np.empty((m + n_nodes, 3))
    seg_b = np.empty((m + n_nodes, 3))
    rad = np.empty(m + n_nodes)
    lo = np.empty((m + n_nodes, 3))
    hi = np.empty((m + n_nodes, 3))
    extent = np.empty(m + n_nodes)
    _kernels.clearance_elements(
        nodes, edges, radii, end_offset, unit, offsets, inc_edge, inc_side, float(pad),
        seg_a, seg_b, rad, lo, hi, extent,
    )  # fmt: skip
    active = rad >= 0
    origin, top = box_stats(lo, hi, active)
    span = top - origin
    cell = max(float(np.median(extent[active])), 1e-300)
    n_el = int(active.sum())
    while True:
        dims = np.maximum(1, np.ceil(span / cell).astype(np.int64))
        if int(np.prod(dims)) <= 4 * n_el + 64:
            break
        cell *= 1.5
    return seg_a, seg_b, rad, lo, hi, cell, origin, dims


def _check_clearance(
    graph: LatticeGraph,
    radii: NDArray[np.float64],
    mesh: Mesh,
    end_offset: NDArray[np.float64],
    face_start: NDArray[np.int64],
    P: int,
) -> None:
    """Raise StitchError if elements that share no node overlap (exact triangle test)."""
    edges, m = graph.edges, graph.num_edges
    offsets, inc_edge, inc_side = graph.incidence
    degree = graph.degree
    unit = graph.edge_vectors / graph.edge_lengths[:, None]
    seg_a, seg_b, rad, lo, hi, cell, origin, dims = _clearance_elements(
        graph.nodes, edges, radii, end_offset, unit, offsets, inc_edge, inc_side
    )
    bbase = _band_base(graph, mesh, P)
    max_rows = max(8 * P, int((degree * P + 2 * degree).max()))
    found = np.empty((int(np.prod(dims)), 2), dtype=np.int64)
    _kernels.clearance(
        mesh.vertices, mesh.faces, edges, degree, offsets, inc_edge, face_start, P, bbase,
        seg_a, seg_b, rad, lo, hi, cell, origin, dims, max_rows, found,
    )  # fmt: skip
    hits = np.flatnonzero(found[:, 0] >= 0)
    if not len(hits):
        return
    a, b = (int(v) for v in found[hits[0]])

    def name(el: int) -> str:
        if el < m:
            return f"strut {el} (nodes {int(edges[el, 0])}, {int(edges[el, 1])})"
        return f"the joint at node {el - m}"

    raise StitchError(
        f"{name(a)} and {name(b)} overlap although they share no node "
        f"({len(hits)} overlapping pair(s) found); struts must not cross or touch away from "
        "their nodes: move them apart or make them thinner"
    )


def _check_tapered_neighbours(
    graph: LatticeGraph,
    prad: NDArray[np.float64],
    mesh: Mesh,
    face_start: NDArray[np.int64],
    P: int,
) -> None:
    """Raise StitchError if a tapered strut widens into a neighbour at the same node.

    The hub construction keeps the struts of one node apart beyond their profiles for the
    radius each hub was built for. A strut wider than that somewhere beyond its near
    profile (it widens away from the node, or the band ring of a grown far hub) can reach
    its neighbour at a small angle: struts of 0.02 -> 0.07 and 0.05 at 14 degrees (the
    fuzzer), 0.005 -> 0.009 and 0.005 -> 0.0087 at 20.7 degrees on a tet lattice of
    ``meshes/hammer.obj``. Pairs whose cones from the node are apart are safe
    (:func:`fast_stitch.hubvolume.taper_cone_pairs`, from the mesh's own rings); the
    others are tested exactly, triangle by triangle (strut against strut, and each
    against the joint at the other's far end).
    """
    if not graph.is_tapered:
        return
    edges, L = graph.edges, graph.edge_lengths
    m = graph.num_edges
    v, f = mesh.vertices, mesh.faces
    bb = _band_base(graph, mesh, P)

    def rings(first: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Offset and radius of the rings from vertex row ``first`` (ring (e, s) at
        ``first + (2 e + s) P``), measured from the end's own node."""
        ring0 = v[first + np.arange(2 * m) * P].reshape(m, 2, 3) - graph.nodes[edges]
        axis = graph.edge_vectors / L[:, None]
        off = np.einsum("msk,mk->ms", ring0, axis) * np.array([1.0, -1.0])
        rad = np.linalg.norm(ring0 - off[:, :, None] * (axis[:, None, :] * np.array(
            [[1.0], [-1.0]])), axis=2)  # fmt: skip
        return off, rad

    hub = rings(0)
    band = rings(2 * m * P) if bb >= 0 else None
    pairs = taper_cone_pairs(
        graph.nodes, edges, graph.incidence, L, np.maximum(prad, hub[1]), hub, band
    )
    if not len(pairs):
        return
    unit = graph.edge_vectors / L[:, None]
    for n, ea, eb in pairs.tolist():
        hit = _faces_meet(v, f, _strut_faces(ea, P, bb), _strut_faces(eb, P, bb))
        for e_cyl, e_far in ((ea, eb), (eb, ea)):
            if hit:
                break
            far = int(edges[e_far, 1] if edges[e_far, 0] == n else edges[e_far, 0])
            count = int(_face_counts(graph.degree[far : far + 1], P)[0])
            far_faces = np.arange(face_start[far], face_start[far] + count)
            hit = _faces_meet(v, f, _strut_faces(e_cyl, P, bb), far_faces)
        if hit:
            da = unit[ea] * (1.0 if edges[ea, 0] == n else -1.0)
            db = unit[eb] * (1.0 if edges[eb, 0] == n else -1.0)
            ang = math.degrees(math.acos(max(-1.0, min(1.0, float(da @ db)))))
            raise StitchError(
                f"node {n}: struts {ea} and {eb} meet at {ang:.3g} degrees and one widens "
                f"away from the node (radii {graph.radii[ea].tolist()} and "
                f"{graph.radii[eb].tolist()}), so they overlap beyond the joint; use a larger "
                "angle or less taper"
            )


def _band_base(graph: LatticeGraph, mesh: Mesh, P: int) -> int:
    """First band row of a stitched mesh (``profile="volume"``), -1 if it has no bands."""
    bbase = 2 * graph.num_edges * P + int(_face_counts(graph.degree, P).sum())
    return bbase if len(mesh.faces) > bbase else -1


def _strut_faces(e: int, P: int, bbase: int = -1) -> NDArray[np.int64]:
    """Face rows of strut e: its prism and, from row ``bbase`` if >= 0, its two bands."""
    rows = np.arange(2 * P * e, 2 * P * (e + 1), dtype=np.int64)
    if bbase < 0:
        return rows
    return np.concatenate([rows, np.arange(bbase + 4 * P * e, bbase + 4 * P * (e + 1))])


def _faces_meet(
    v: NDArray[np.float64], f: NDArray[np.int64], fa: NDArray[np.int64], fb: NDArray[np.int64]
) -> bool:
    """Do any of the faces ``fa`` meet any of ``fb`` (those sharing a vertex skipped)?"""
    ta, tb = v[f[fa]], v[f[fb]]
    lo_a, hi_a = ta.min(axis=1), ta.max(axis=1)
    lo_b, hi_b = tb.min(axis=1), tb.max(axis=1)
    over = np.all((lo_a[:, None] <= hi_b[None]) & (lo_b[None] <= hi_a[:, None]), axis=2)
    for i, j in np.argwhere(over):
        x, y = f[fa[i]], f[fb[j]]
        if np.intersect1d(x, y).size:
            continue
        if tri_tri(v, int(x[0]), int(x[1]), int(x[2]), int(y[0]), int(y[1]), int(y[2])):
            return True
    return False
