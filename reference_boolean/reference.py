"""The exact per-hub B-rep reference of a lattice (Wang, Chen & Rosen's unit trusses).

The design (docs/REFERENCE.md): struts are cylinders (cone frustums when tapered), every
node of degree >= 2 has a ball of radius ``R_n = 1.00001 * max incident radius``, and a
leaf (degree 1: a free end, or where a strut meets the part's surface) has no ball: the
strut ends flat at the node, as in the fast mesh.

For every node with struts, its *hub* (unit truss) is built as an OCCT solid:
its sphere fused with the half-struts ("stumps") from the node to each strut's midpoint
(cylinders, or cone frustums from ``r_node`` to ``r_mid = (r_a + r_b) / 2`` for tapered
struts). Where hubs only touch on the shared midpoint discs, the lattice volume is the sum
of the hub volumes (exact, from OCCT's GProp) and the lattice surface is the union of the
hub surfaces without the discs: the tessellations are stacked without any boolean between
hubs. Nodes whose hubs would overlap (short struts, struts at small angles, clipped ends)
are grouped into clusters (:mod:`reference_boolean.clusters`), each built as one fused
solid whose struts to other nodes end on midpoint discs as well
(:mod:`lattice_cad.occ_impl.cluster`); a leaf is a cluster of its own (its half-strut).
So every lattice gets an exact, watertight reference.

Shared midpoint circles: both hubs of a strut build its stump with the same
canonical frame (a function of the strut's line only) and are tessellated
with the same absolute deflections, so BRepMesh puts the same ``K`` points at
the angles ``2 pi k / K`` on both sides. This is verified for every circle
(:mod:`lattice_cad.occ_impl.truss`), then every circle vertex is replaced by one
exact canonical point per ``(strut, k)`` shared by both hubs, which makes the
stacked mesh watertight by construction (index-based). Any hub for which this
cannot be verified is reported in :attr:`Reference.failed`.

Hubs that are translates of each other (periodic lattices) are built once
(``cache=True``); distinct hubs are built in worker processes with a time
bound per hub.
"""

from __future__ import annotations

import itertools
import math
import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.checks import check_workers
from lattice_cad.core.errors import DirtyLatticeError, ReferenceBuildError
from lattice_cad.core.formats import Kind, resolve
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.isolate import die_with_parent, kill_pool
from lattice_cad.core.mesh import Mesh
from reference_boolean.frame import frame_scale, scale_spec, unscale_result
from reference_boolean.rotations import Congruence, RotationCache

__all__ = [
    "Reference",
    "ReferenceBuildError",
    "DirtyLatticeError",
    "build_reference",
    "find_overlaps",
    "strut_frames",
    "HubSolids",
    "hub_solids",
    "count_hubs",
    "run_with_estimate",
]


# Fixed "generic" unit vectors (no lattice direction is parallel or perpendicular to them by
# accident): the sign of a strut's axis comes from its dot product with _SIGN_REF, and its
# frame's x direction from the cross product with _FRAME_REF (or _FRAME_REF_ALT when the
# strut is nearly parallel to _FRAME_REF). Both depend on the strut's line only, so the two
# hubs of a strut, and translated copies of a hub, get the same frame.
_SIGN_REF = np.array([0.5773502691896258, 0.2113248654051871, 0.7886751345948129])
# _SIGN_REF is exactly perpendicular to (-1, -1, 1), a BCC strut direction: there the sign
# came from rounding noise, so translated struts could get opposite frames (and a cached hub
# the frames of another node: circles 2.98 mm off on a clipped GE bracket). Directions
# nearly perpendicular to it take their sign from the next vectors instead.
_SIGN_REFS_ALT = (
    np.array([0.8211, -0.3119, 0.4781]) / np.linalg.norm([0.8211, -0.3119, 0.4781]),
    np.array([-0.2713, 0.6523, 0.7079]) / np.linalg.norm([-0.2713, 0.6523, 0.7079]),
)
_SIGN_TOL = 1e-6
_FRAME_REF = np.array([0.3119, 0.8211, -0.4781]) / np.linalg.norm([0.3119, 0.8211, -0.4781])
_FRAME_REF_ALT = np.array([-0.6124, 0.3536, 0.7071]) / np.linalg.norm([-0.6124, 0.3536, 0.7071])


@dataclass(frozen=True, eq=False)
class Reference:
    """The exact reference of a lattice.

    Attributes
    ----------
    graph : LatticeGraph
    volume : float
        Sum of the hub solids' volumes (OCCT GProp). Exact for a clean lattice
        when :attr:`complete`; otherwise the sum over the hubs that were built.
    mesh : fast_stitch.Mesh
        The stacked tessellation: ``vertices`` (V, 3) float64, ``faces`` (F, 3)
        int64, outward. Watertight when :attr:`complete`.
    face_node : (F,) int64
        Node whose hub each triangle belongs to.
    hub_volume : (N,) float64
        Volume of each node's hub (NaN for isolated or failed nodes). A cluster's volume
        is given to its first member (its anchor), 0 to the others, so the sum is
        :attr:`volume`.
    failed : dict[int, str]
        Node index -> reason, for every hub that could not be built or stacked.
    attempts : dict[int, list[str]]
        Node index -> constructions tried, for hubs that needed a retry or failed.
    tolerance, angular : float
        Linear (absolute) and angular deflection of the tessellation.
    unique_hubs : int
        Hubs and clusters actually built (distinct up to translation when cached).
    cache_hits : int
        Hubs and clusters reused from another build.
    timings : dict[str, float]
        Seconds spent in ``"check"`` (clustering), ``"build"``, ``"stack"`` and ``"total"``.
    node_template : (N,) int64
        Index into :attr:`breps` of the solid (hub or cluster) each node belongs to.
    breps : list of bytes
        Binary BREP of each distinct hub or cluster (its anchor node at the origin).
    clusters : list of (c,) int64
        Member nodes of every cluster of two or more nodes (hubs that would overlap,
        built as one fused solid; see :mod:`reference_boolean.clusters`).
    """

    graph: LatticeGraph
    volume: float
    mesh: Mesh
    face_node: NDArray[np.int64]
    hub_volume: NDArray[np.float64]
    failed: dict[int, str]
    attempts: dict[int, list[str]]
    tolerance: float
    angular: float
    unique_hubs: int
    cache_hits: int
    timings: dict[str, float]
    node_template: NDArray[np.int64] = field(repr=False)
    breps: list[bytes] = field(repr=False)
    clusters: list[NDArray[np.int64]] = field(default_factory=list, repr=False)
    units: Any = field(default=None, repr=False)

    @property
    def complete(self) -> bool:
        """True when every hub was built and stacked (the volume is exact)."""
        return not self.failed

    def __repr__(self) -> str:
        state = "complete" if self.complete else f"INCOMPLETE, {len(self.failed)} failed hub(s)"
        return (
            f"Reference(volume={self.volume:.9g}, {len(self.mesh.faces)} triangles, "
            f"{self.unique_hubs} distinct hubs, {state})"
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the stacked mesh (``.stl``, ``.3mf``, ...) or the exact solid (``.step``).

        The STEP file holds the hub solids sewn along their shared midpoint circles: one
        BRepCheck-valid solid per connected body, whose volume is :attr:`volume`. It is
        written atomically.

        Raises
        ------
        OCCTFailure
            A hub failed, or OCCT could not sew or write the solid (naming the file).
        """
        p = Path(path)
        _, kind = resolve(p, (Kind.SOLIDS, Kind.MESH), what="reference")
        if kind is Kind.MESH:
            from lattice_cad import io

            return io.save_mesh(self.mesh, p)
        from lattice_cad.occ_impl.lattice_brep import as_one, sew_hubs
        from lattice_cad.occ_impl.step import write_step

        g = self.graph
        u = self.units
        discs = [_discs(spec) for spec in u.specs]
        mids = [d[0] for d in discs]
        axes = [d[1] for d in discs]
        inst_of = {int(n): i for i, mem in enumerate(u.members) for n in mem}
        failed = {int(u.template[inst_of[n]]): why for n, why in self.failed.items()}
        shapes = sew_hubs(
            self.breps,
            u.template,
            g.nodes[u.anchor],
            mids,
            axes=axes,
            tolerance=config.BREP_SEW_RTOL * float(g.radii.min()),
            failed=failed,
            rotations=u.rotation,
        )
        write_step(as_one(shapes, str(p)), p)
        return p


# ---------------------------------------------------------------- geometry
def _canonical_dir(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """(M, 3) unit directions with a sign that depends on the line only."""
    u = d / np.linalg.norm(d, axis=1)[:, None]
    dot = u @ _SIGN_REF
    for ref in _SIGN_REFS_ALT:
        weak = np.abs(dot) < _SIGN_TOL
        dot[weak] = u[weak] @ ref
    s = np.sign(dot)
    s[s == 0] = 1.0
    return u * s[:, None]


def strut_frames(
    graph: LatticeGraph,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Canonical frame of each strut's midpoint circle.

    Returns
    -------
    axis, xdir, ydir : (M, 3) float64
        ``axis`` is the strut direction with a sign fixed by the line alone;
        ``xdir`` is perpendicular to it (from fixed generic vectors, so it is
        the same for translated copies), ``ydir = axis x xdir``.
    """
    D = _canonical_dir(np.asarray(graph.edge_vectors))
    x = np.cross(D, _FRAME_REF)
    bad = np.linalg.norm(x, axis=1) < 0.3
    x[bad] = np.cross(D[bad], _FRAME_REF_ALT)
    x /= np.linalg.norm(x, axis=1)[:, None]
    y = np.cross(D, x)
    return D, x, y


def _node_radius(graph: LatticeGraph) -> NDArray[np.float64]:
    """(N,) float64: hub sphere radius R_n (0 for isolated nodes)."""
    rmax = np.zeros(graph.num_nodes)
    np.maximum.at(rmax, graph.edges[:, 0], graph.radii[:, 0])
    np.maximum.at(rmax, graph.edges[:, 1], graph.radii[:, 1])
    return config.SPHERE_FACTOR * rmax


def find_overlaps(graph: LatticeGraph) -> list[str]:
    """Why per-node hubs with a ball at *every* node would overlap (empty: a clean lattice).

    The check of the STEP path (:mod:`lattice_cad.brep`: sew or fuse); the reference
    builds such nodes as clusters instead (:func:`reference_boolean.clusters.find_clusters`).

    Two cases are detected, each named by node and strut:

    * a hub sphere reaches the cut plane of one of its struts (``R_n >= L / 2``);
    * a stump reaches the cut plane of another strut of the same node (struts
      at a small angle), so it may enter the neighbouring hub.

    Struts that cross each other away from the nodes are not detected.
    """
    R = _node_radius(graph)
    L = np.asarray(graph.edge_lengths)
    offsets, inc_edge, inc_side = graph.incidence
    out: list[str] = []
    for side in (0, 1):
        n = graph.edges[:, side]
        bad = np.flatnonzero(R[n] >= 0.5 * L)
        for e in bad[:50]:
            out.append(
                f"node {int(n[e])}: sphere radius {R[n[e]]:.6g} reaches past the midpoint of "
                f"strut {int(e)} (half length {0.5 * L[e]:.6g})"
            )
    rmid = graph.radii.mean(axis=1)
    u = np.asarray(graph.edge_vectors) / L[:, None]
    for node in np.flatnonzero(graph.degree >= 2):
        es = inc_edge[offsets[node] : offsets[node + 1]]
        sd = inc_side[offsets[node] : offsets[node + 1]]
        d = u[es] * np.where(sd == 0, 1.0, -1.0)[:, None]
        cos = np.clip(d @ d.T, -1.0, 1.0)
        sin = np.sqrt(1.0 - cos**2)
        h = 0.5 * L[es]
        # farthest point of stump j along strut i's axis (its end disc, or its node disc)
        rn = graph.radii[es, sd]
        reach = np.maximum(h[None, :] * cos + rmid[es][None, :] * sin, rn[None, :] * sin)
        np.fill_diagonal(reach, -np.inf)
        ii, jj = np.nonzero(reach >= h[:, None])
        for i, j in zip(ii[:5], jj[:5], strict=True):
            out.append(
                f"node {int(node)}: the stump of strut {int(es[j])} reaches the cut plane of "
                f"strut {int(es[i])} (angle {math.degrees(math.acos(cos[i, j])):.3g} deg)"
            )
        if len(out) > 200:
            break
    return out


# ------------------------------------------------------------------ specs
def _hub_specs(
    graph: LatticeGraph, cache: bool
) -> tuple[list[Any], NDArray[np.int64], list[NDArray[np.int64]], list[NDArray[np.int64]]]:
    """Distinct hub specs, the template of each node, and slot -> strut of each node."""
    from lattice_cad.occ_impl.truss import HubSpec

    nodes, edges, radii = graph.nodes, graph.edges, graph.radii
    offsets, inc_edge, inc_side = graph.incidence
    R = _node_radius(graph)
    _, X, Y = strut_frames(graph)
    rmid = radii.mean(axis=1)
    q = config.CACHE_QUANTUM * float(np.max(graph.edge_lengths))
    specs: list[Any] = []
    keys: dict[bytes, int] = {}
    template = np.full(graph.num_nodes, -1, dtype=np.int64)
    slot_edges: list[NDArray[np.int64]] = [np.zeros(0, np.int64)] * graph.num_nodes
    members: list[list[int]] = []
    for n in np.flatnonzero(graph.degree > 0):
        es = inc_edge[offsets[n] : offsets[n + 1]]
        sd = inc_side[offsets[n] : offsets[n + 1]]
        other = edges[es, 1 - sd]
        vec = 0.5 * (nodes[other] - nodes[n])
        rn = radii[es, sd]
        rm = rmid[es]
        rows = np.column_stack([vec, rn, rm])
        qrows = np.rint(rows / q).astype(np.int64)
        order = np.lexsort(qrows.T[::-1])
        es, vec, rn, rm, qrows = es[order], vec[order], rn[order], rm[order], qrows[order]
        slot_edges[n] = es
        key = qrows.tobytes() + np.int64(np.rint(R[n] / q)).tobytes()
        t = keys.get(key, -1) if cache else -1
        if t < 0:
            t = len(specs)
            if cache:
                keys[key] = t
            specs.append(
                HubSpec(
                    radius=float(R[n]),
                    vecs=vec,
                    r_node=rn,
                    r_mid=rm,
                    xdirs=X[es],
                    ydirs=Y[es],
                )
            )
            members.append([])
        template[n] = t
        members[t].append(int(n))
    return specs, template, slot_edges, [np.asarray(m, dtype=np.int64) for m in members]


# ------------------------------------------------------------------ units
@dataclass(frozen=True, eq=False)
class _Units:
    """How the reference is cut into solids: single hubs and clusters (see ``clusters``).

    ``specs[t]`` is a ``HubSpec`` (one node of degree >= 2 whose hub overlaps no other) or a
    ``ClusterSpec`` (several nodes, or one leaf); each *instance* ``i`` is one placed copy:
    ``template[i]``, its ``anchor[i]`` node (the spec's origin), its ``members[i]`` (nodes, in
    the spec's member order) and ``slots[i]`` (the struts leaving it, in circle order).
    """

    specs: list[Any]
    template: NDArray[np.int64]
    anchor: NDArray[np.int64]
    members: list[NDArray[np.int64]]
    slots: list[NDArray[np.int64]]
    node_instance: NDArray[np.int64]
    reasons: list[str]
    #: (I, 3, 3) float64: orthogonal map of each instance's template onto it (identity
    #: for copies by translation; see :mod:`reference_boolean.rotations`); None: all identity.
    rotation: NDArray[np.float64] | None = None

    def turned(self) -> NDArray[np.bool_]:
        """(I,) bool: instances placed with a rotation or reflection (not a translation)."""
        if self.rotation is None:
            return np.zeros(len(self.template), dtype=bool)
        return np.abs(self.rotation - np.eye(3)[None]).max(axis=(1, 2)) > 0.0

    def instances_of(self) -> list[NDArray[np.int64]]:
        """Instances of each template."""
        order = np.argsort(self.template, kind="stable")
        cuts = np.searchsorted(self.template[order], np.arange(len(self.specs) + 1))
        return [order[cuts[t] : cuts[t + 1]] for t in range(len(self.specs))]


def _unit_specs(graph: LatticeGraph, cache: bool, *, rotations: bool = False) -> _Units:
    """Cluster the nodes and describe every distinct hub or cluster (cached by translation;
    with ``rotations`` also single hubs equal up to a rotation or reflection, see
    :mod:`reference_boolean.rotations`)."""
    from lattice_cad.occ_impl.cluster import ClusterSpec
    from lattice_cad.occ_impl.truss import HubSpec
    from reference_boolean.clusters import find_clusters, hub_radius

    nodes, edges, radii = graph.nodes, graph.edges, graph.radii
    offsets, inc_edge, inc_side = graph.incidence
    R = hub_radius(graph)
    _, X, Y = strut_frames(graph)
    rmid = radii.mean(axis=1)
    q = config.CACHE_QUANTUM * float(np.max(graph.edge_lengths))
    label, reasons = find_clusters(graph)
    used = np.flatnonzero(label >= 0)
    order = used[np.argsort(label[used], kind="stable")]
    cuts = np.searchsorted(label[order], np.arange(int(label.max()) + 2))

    def node_spec(n: int) -> tuple[Any, NDArray[np.int64], NDArray[np.int64], bytes]:
        es = inc_edge[offsets[n] : offsets[n + 1]]
        sd = inc_side[offsets[n] : offsets[n + 1]]
        vec = 0.5 * (nodes[edges[es, 1 - sd]] - nodes[n])
        rows = np.column_stack([vec, radii[es, sd], rmid[es]])
        qrows = np.rint(rows / q).astype(np.int64)
        o = np.lexsort(qrows.T[::-1])
        es, sd, vec = es[o], sd[o], vec[o]
        spec = HubSpec(
            radius=float(R[n]), vecs=vec, r_node=radii[es, sd], r_mid=rmid[es],
            xdirs=X[es], ydirs=Y[es],
        )  # fmt: skip
        key = qrows[o].tobytes() + np.int64(np.rint(R[n] / q)).tobytes()
        return spec, es, sd, key

    specs: list[Any] = []
    keys: dict[bytes, int] = {}
    template: list[int] = []
    anchor, members, slots = [], [], []
    turns: dict[int, NDArray[np.float64]] = {}
    scale = float(np.max(graph.edge_lengths))
    rcache = (
        RotationCache(config.ROTATION_KEY_RTOL * scale, config.ROTATION_RTOL * scale)
        if cache and rotations
        else None
    )
    node_instance = np.full(graph.num_nodes, -1, dtype=np.int64)
    for c in range(len(cuts) - 1):
        group = order[cuts[c] : cuts[c + 1]]
        turn: tuple[int, Congruence] | None = None
        if len(group) == 1 and R[group[0]] > 0:  # a single hub
            n = int(group[0])
            spec, es, _, key = node_spec(n)
            key = b"H" + key
            mem, slot = np.array([n], np.int64), es
            if rcache is not None and key not in keys:
                radii_ = np.column_stack([spec.r_node, spec.r_mid])
                hit = rcache.find(spec.radius, spec.vecs, radii_)
                if hit[0] is None:  # hit[1] is the key to register the template under
                    rcache.add(hit[1], len(specs), spec.vecs, radii_)
                else:  # template stump k is this hub's stump perm[k]
                    turn = hit
                    slot = es[hit[1].perm]
        else:  # a cluster (or one leaf)
            pos = np.rint((nodes[group] - nodes[group].min(axis=0)) / q).astype(np.int64)
            mem = group[np.lexsort(pos.T[::-1])].astype(np.int64)
            where = {int(n): i for i, n in enumerate(mem)}
            base = nodes[mem[0]]
            hubs, inner, inner_r, inner_x = [], [], [], []
            lv_m, lv_e, lv_sd = [], [], []
            for i, n in enumerate(mem):
                hs, es, sd, _ = node_spec(int(n))
                hubs.append(hs)
                for e, s_ in zip(es, sd, strict=True):
                    other = int(edges[e, 1 - s_])
                    if other in where:
                        if where[other] > i:
                            inner.append((i, where[other]))
                            inner_r.append((radii[e, s_], radii[e, 1 - s_]))
                            inner_x.append(X[e])
                    else:
                        lv_m.append(i)
                        lv_e.append(int(e))
                        lv_sd.append(int(s_))
            lv_e_a = np.asarray(lv_e, dtype=np.int64)
            lv_sd_a = np.asarray(lv_sd, dtype=np.int64)
            lv_m_a = np.asarray(lv_m, dtype=np.int64)
            vec = 0.5 * (nodes[edges[lv_e_a, 1 - lv_sd_a]] - nodes[mem[lv_m_a]]).reshape(-1, 3)
            offs = nodes[mem] - base
            spec = ClusterSpec(
                offsets=offs,
                hubs=hubs,
                inner=np.asarray(inner, dtype=np.int64).reshape(-1, 2),
                inner_radii=np.asarray(inner_r, dtype=np.float64).reshape(-1, 2),
                inner_xdirs=np.asarray(inner_x, dtype=np.float64).reshape(-1, 3),
                member=lv_m_a,
                vecs=vec,
                r_node=radii[lv_e_a, lv_sd_a],
                r_mid=rmid[lv_e_a],
                xdirs=X[lv_e_a].reshape(-1, 3),
                ydirs=Y[lv_e_a].reshape(-1, 3),
            )
            key = b"C" + b"|".join(
                [
                    np.rint(offs / q).astype(np.int64).tobytes(),
                    np.rint(np.array([h.radius for h in hubs]) / q).astype(np.int64).tobytes(),
                    spec.inner.tobytes(),
                    np.rint(spec.inner_radii / q).astype(np.int64).tobytes(),
                    lv_m_a.tobytes(),
                    np.rint(np.column_stack([vec, spec.r_node, spec.r_mid]) / q)
                    .astype(np.int64)
                    .tobytes(),
                ]
            )
            slot = lv_e_a
        t = keys.get(key, -1) if cache else -1
        if turn is not None:
            t = turn[0]
            turns[len(template)] = turn[1].rotation
        elif t < 0:
            t = len(specs)
            specs.append(spec)
            if cache:
                keys[key] = t
        node_instance[mem] = len(template)
        template.append(t)
        anchor.append(int(mem[0]))
        members.append(mem)
        slots.append(np.asarray(slot, dtype=np.int64))
    return _Units(
        specs=specs,
        template=np.asarray(template, dtype=np.int64),
        anchor=np.asarray(anchor, dtype=np.int64),
        members=members,
        slots=slots,
        node_instance=node_instance,
        reasons=reasons,
        rotation=_rotations(len(template), turns),
    )


def _rotations(n: int, turns: dict[int, NDArray[np.float64]]) -> NDArray[np.float64] | None:
    """(n, 3, 3) float64: identity but for the turned instances; None if there are none."""
    if not turns:
        return None
    out = np.repeat(np.eye(3)[None], n, axis=0)
    for i, q in turns.items():
        out[i] = q
    return out


# ---------------------------------------------------------------- workers
def _build_one(args: tuple[Any, float, float, bool]) -> Any:
    from lattice_cad.occ_impl import truss as _occ
    from lattice_cad.occ_impl.cluster import ClusterSpec, build_cluster

    spec, deflection, angular, keep = args
    # built where its radius is ~1 (OCCT's absolute tolerances), then scaled back
    s = frame_scale(spec)
    spec = scale_spec(spec, 1.0 / s)
    if isinstance(spec, ClusterSpec):
        res = build_cluster(spec, deflection=deflection / s, angular=angular, keep_brep=keep)
    elif deflection <= 0.0:  # the solid only (hub_solids)
        res = _occ.build_hub_solid(spec)
    else:
        res = _occ.build_hub(spec, deflection=deflection / s, angular=angular, keep_brep=keep)
    return unscale_result(res, s)


def _run(
    specs: list[Any],
    deflection: float,
    angular: float,
    keep: bool,
    workers: int,
    timeout: float,
    progress: Any,
) -> list[Any]:
    from lattice_cad.occ_impl.truss import HubResult

    results: list[Any] = [None] * len(specs)
    if workers == 0:  # in process, no time bound (debugging)
        for i, s in enumerate(specs):
            results[i] = _build_one((s, deflection, angular, keep))
            if progress:
                progress("build", i + 1, len(specs))
        return results
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    todo = list(range(len(specs)))
    done_count = 0
    while todo:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=die_with_parent)
        try:
            timed_out = _run_pool(
                pool, specs, todo, results, (deflection, angular, keep), timeout,
                progress, done_count, workers,
            )  # fmt: skip
        except BaseException:  # Ctrl-C (KeyboardInterrupt) or an error: no worker left behind
            kill_pool(pool, wait=True)
            raise
        done_count = sum(r is not None for r in results)
        if timed_out is not None:
            results[timed_out] = HubResult(
                status=f"timeout: the hub build took more than {timeout:g} s (stopped)"
            )
            kill_pool(pool, wait=True)
        else:
            pool.shutdown(wait=True)
        todo = [i for i in todo if results[i] is None]
    return results


#: Hubs submitted per worker process at a time (:func:`_run_pool`): enough to keep every
#: worker busy while the results of the others come back.
_IN_FLIGHT_PER_WORKER = 8


def _run_pool(
    pool: ProcessPoolExecutor,
    specs: list[Any],
    todo: list[int],
    results: list[Any],
    opts: tuple[float, float, bool],
    timeout: float,
    progress: Any,
    done_count: int,
    workers: int = 1,
) -> int | None:
    """Submit ``todo`` to ``pool`` (``workers`` processes; a few hubs per worker in flight
    at a time) and collect into ``results``; the first hub over time."""
    from lattice_cad.occ_impl.truss import HubResult

    deflection, angular, keep = opts
    # a bounded number of hubs in flight: with every hub submitted at once (5K+ futures on a
    # tet lattice), each wait() and the running() scan walk all of them, and this process
    # burnt ~100 CPU s next to the workers on the GE tet reference
    queue = iter(todo)
    futs: dict[Future[Any], int] = {}
    pending: set[Future[Any]] = set()

    def submit(n: int) -> None:
        for i in itertools.islice(queue, n):
            f = pool.submit(_build_one, (specs[i], deflection, angular, keep))
            futs[f] = i
            pending.add(f)

    submit(_IN_FLIGHT_PER_WORKER * max(int(workers), 1))
    started: dict[Future[Any], float] = {}
    timed_out: int | None = None
    while pending and timed_out is None:
        done, _ = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
        for f in done:
            pending.discard(f)
            i = futs.pop(f)
            started.pop(f, None)
            try:
                results[i] = f.result()
            except Exception as exc:  # a worker died (e.g. an OCCT crash)
                results[i] = HubResult(status=f"worker failed: {type(exc).__name__}: {exc}")
            done_count += 1
            if progress:
                progress("build", done_count, len(specs))
        submit(len(done))
        now = time.monotonic()
        for f in pending:
            if f.running():
                started.setdefault(f, now)
                if now - started[f] > timeout:
                    timed_out = futs[f]
                    break
    return timed_out


def _clock(seconds: float) -> str:
    """``"1 h 02 min"``, ``"4 min 05 s"`` or ``"12 s"``."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    if s >= 60:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s} s"


#: Build time of a hub ~ degree ** _COST_POWER (pairwise tree fuse; measured on the GE
#: bracket tet hubs, degree 7 -> 19: 0.31 -> 1.35 CPU s, benchmarks/bench_hub_profile.py).
_COST_POWER = 1.5


def run_with_estimate(
    specs: list[Any],
    template: NDArray[np.int64],
    deflection: float,
    angular: float,
    keep: bool,
    workers: int,
    timeout: float,
    *,
    calibration: int = 2,
    stream: Any = None,
    estimate: dict[str, float] | None = None,
) -> list[Any]:
    """Build the distinct hubs with an up-front estimate and a tqdm bar over the hubs.

    Prints to ``stream`` (default stderr), before the work: how many hubs the lattice has,
    how many are built and how many reused; then builds ``calibration`` hubs of the median
    degree (among the hubs and clusters: leaves do not count) in this process (their
    results are kept, not built twice) and prints the estimated CPU and wall seconds of the
    rest, assuming the time of a hub grows with the 1.5th power of its degree
    (:data:`_COST_POWER`) and that ``workers`` cores are free. A tqdm bar follows the rest.
    Ctrl-C stops the worker processes and re-raises ``KeyboardInterrupt``.

    Parameters
    ----------
    specs : list of HubSpec or ClusterSpec
    template : (I,) int64
        Index into ``specs`` of each placed hub or cluster (-1 entries are ignored).
    deflection, angular : float
        Tessellation deflections (``deflection <= 0``: solids only).
    keep : bool
        Keep the BREP strings.
    workers, timeout
        As for :func:`build_reference`.
    calibration : int
        Hubs timed in this process before the estimate.
    estimate : dict, optional
        Filled with ``"estimate"`` (wall seconds), ``"estimate_cpu"`` and
        ``"calibration_cpu"`` (CPU seconds of the calibration hubs).

    Returns
    -------
    list of HubResult
        One per spec, in order.
    """
    from tqdm.auto import tqdm

    out = sys.stderr if stream is None else stream
    d = len(specs)
    n_hubs = int((template >= 0).sum())
    results: list[Any] = [None] * d
    if d == 0:
        return results
    # stumps per solid: a cluster's inner struts count at both ends
    deg = np.array(
        [len(s.vecs) + 2 * len(getattr(s, "inner", ())) for s in specs], dtype=np.float64
    )
    print(
        f"reference: {n_hubs:,} hubs and clusters, {d:,} distinct to build "
        f"({n_hubs - d:,} reused), "
        f"degree {int(deg.min())}-{int(deg.max())}, {max(workers, 1)} worker(s)",
        file=out,
        flush=True,
    )
    k = min(max(int(calibration), 1), d)
    # calibrate on the hubs and clusters (leaves, degree 1, cost next to nothing: a clipped
    # lattice has more leaves than hubs, and a leaf's time says little about a hub's)
    pool = np.flatnonzero(deg > 1)
    if len(pool) < k:
        pool = np.arange(d)
    cal = pool[np.argsort(np.abs(deg[pool] - np.median(deg[pool])), kind="stable")[:k]]
    c0 = time.process_time()
    for i in cal:
        results[int(i)] = _build_one((specs[int(i)], deflection, angular, keep))
    cpu = time.process_time() - c0
    rest = [i for i in range(d) if results[i] is None]
    per_d2 = cpu / float((deg[cal] ** _COST_POWER).sum())
    est_cpu = per_d2 * float((deg[rest] ** _COST_POWER).sum())
    est_wall = est_cpu / max(workers, 1)
    print(
        f"reference: calibration {k} hub(s) in {cpu:.2f} CPU s; estimate for the other "
        f"{len(rest):,}: {est_cpu:,.0f} CPU s, about {_clock(est_wall)} with "
        f"{max(workers, 1)} free core(s) (load average now {os.getloadavg()[0]:.1f})",
        file=out,
        flush=True,
    )
    if estimate is not None:
        estimate.update({"estimate": est_wall, "estimate_cpu": est_cpu, "calibration_cpu": cpu})
    bar = tqdm(total=d, initial=k, unit="hub", desc="reference hubs", file=out, smoothing=0.05)

    def tick(stage: str, done: int, total: int) -> None:
        bar.n = k + int(done)
        bar.refresh()

    try:
        sub = _run([specs[i] for i in rest], deflection, angular, keep, workers, timeout, tick)
    finally:
        bar.close()
    for i, r in zip(rest, sub, strict=True):
        results[i] = r
    return results


# ------------------------------------------------------------- hub solids
@dataclass(frozen=True, eq=False)
class HubSolids:
    """The hub and cluster solids of a lattice, for sewing into its exact B-rep.

    The same solids as the reference (:func:`build_reference`): a hub per node, a fused
    solid per cluster of nodes whose hubs would overlap, a half-strut (flat at the node)
    per leaf. They meet only on midpoint discs, so sewing them along the midpoint
    circles gives the lattice (:func:`lattice_cad.occ_impl.lattice_brep.sew_hubs`).

    Attributes
    ----------
    breps : list of bytes
        Binary BREP of each distinct solid (empty for a failed one), its anchor at the origin.
    template : (N,) int64
        Index into ``breps`` of the solid each node belongs to (-1 for isolated nodes).
    mid_vectors : list of (d, 3) float64
        Per distinct solid, anchor -> midpoint vector of each disc it ends on.
    failed : dict[int, str]
        Distinct solid index -> why it could not be built.
    seconds : float
    instance_template : (I,) int64
        Index into ``breps`` of each placed solid.
    anchors : (I,) int64
        The node each placed solid's origin is at.
    axes : list of (d, 3) float64
        Per distinct solid, the strut axis of each midpoint disc.
    """

    breps: list[bytes]
    template: NDArray[np.int64]
    mid_vectors: list[NDArray[np.float64]]
    failed: dict[int, str]
    seconds: float
    instance_template: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    anchors: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    axes: list[NDArray[np.float64]] = field(default_factory=list)


def _discs(spec: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(d, 3) disc centres (from the anchor) and (d, 3) axes of a hub or cluster spec."""
    if hasattr(spec, "centres"):
        return spec.centres, spec.axes
    vecs = np.asarray(spec.vecs, dtype=np.float64)
    return vecs, vecs / np.linalg.norm(vecs, axis=1)[:, None]


def hub_solids(
    graph: LatticeGraph,
    *,
    workers: int | None = None,
    hub_timeout: float = config.DEFAULT_HUB_TIMEOUT,
    progress: Any = None,
) -> HubSolids:
    """Build every distinct hub and cluster solid (equal up to translation: built once).

    Nothing is tessellated; any lattice (clusters where hubs would overlap).

    Parameters
    ----------
    graph : LatticeGraph
    workers : int, optional
        Worker processes (default ``min(2, cpu_count)``); 0 builds in this process.
    hub_timeout : float
        Seconds after which one build is stopped and reported as failed.
    progress : callable, optional
        Called as ``progress("build", done, total)``.

    Returns
    -------
    HubSolids
    """
    t0 = time.perf_counter()
    if graph.num_edges == 0:
        raise ReferenceBuildError("the graph has no struts: nothing to build")
    workers = check_workers(workers, minimum=0)
    if workers is None:
        workers = min(2, os.cpu_count() or 1)
    units = _unit_specs(graph, True)
    results = _run(units.specs, 0.0, 0.0, True, workers, float(hub_timeout), progress)
    failed = {t: r.status for t, r in enumerate(results) if r.status != "ok"}
    discs = [_discs(s) for s in units.specs]
    return HubSolids(
        breps=[r.brep for r in results],
        template=np.where(
            units.node_instance >= 0, units.template[np.maximum(units.node_instance, 0)], -1
        ),
        mid_vectors=[d[0] for d in discs],
        failed=failed,
        seconds=time.perf_counter() - t0,
        instance_template=units.template,
        anchors=units.anchor,
        axes=[d[1] for d in discs],
    )


def count_hubs(graph: LatticeGraph) -> int:
    """Number of distinct hubs and clusters (up to translation) :func:`hub_solids` builds."""
    return len(_unit_specs(graph, True).specs)


# ----------------------------------------------------------------- driver
def build_reference(
    graph: LatticeGraph,
    *,
    tolerance: float | None = None,
    angular: float = config.DEFAULT_ANGULAR,
    workers: int | None = None,
    cache: bool = True,
    hub_timeout: float = config.DEFAULT_HUB_TIMEOUT,
    keep_solids: bool = True,
    progress: Any = None,
    reuse: Literal["translation", "rotation"] = "rotation",
) -> Reference:
    """Build the exact per-hub B-rep reference of a lattice.

    Parameters
    ----------
    graph : LatticeGraph
        Any lattice: nodes whose hubs would overlap are built as clusters.
    tolerance : float, optional
        Absolute linear deflection of the tessellation (chordal error bound);
        default ``0.01 * smallest strut radius``. Does not affect :attr:`Reference.volume`,
        which is exact.
    angular : float
        Angular deflection of the tessellation (radians).
    workers : int, optional
        Worker processes (default ``min(2, cpu_count)``); 0 builds in this
        process, without the time bound.
    cache : bool
        Build hubs and clusters that are equal up to translation once.
    hub_timeout : float
        Seconds after which one hub build is stopped and reported as failed.
    keep_solids : bool
        Keep the hub solids (binary BREP) for :meth:`Reference.save` to STEP.
    progress : callable or True, optional
        Called as ``progress(stage, done, total)``. ``True``: print the number of hubs
        to build and an estimate of the time from a short calibration (two hubs) to
        stderr first, then show a tqdm bar over the hubs (see :func:`run_with_estimate`);
        the estimate lands in ``timings["estimate"]``.
    reuse : {"rotation", "translation"}
        With ``cache``: build single hubs that are equal up to a rotation or reflection
        once ("rotation", the default: :mod:`reference_boolean.rotations`; the stacked
        mesh stays watertight, see :func:`_stack`), or only those equal up to a
        translation. Clusters are reused up to translation only.

    Returns
    -------
    Reference

    Raises
    ------
    ReferenceBuildError
        The graph has no struts, or the options are invalid. (Overlapping hubs are no
        longer refused: see :attr:`Reference.clusters`.)
    """
    t0 = time.perf_counter()
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"expected a LatticeGraph, got {type(graph).__name__}")
    if graph.num_edges == 0:
        raise ReferenceBuildError("the graph has no struts: nothing to build")
    workers = check_workers(workers, minimum=0)
    if workers is None:
        workers = min(2, os.cpu_count() or 1)
    if tolerance is None:
        tolerance = config.DEFAULT_TOLERANCE_REL * float(graph.radii.min())
    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    if not (0 < angular < math.pi):
        raise ValueError(f"angular must be in (0, pi), got {angular!r}")
    if reuse not in ("translation", "rotation"):
        raise ValueError(f"reuse must be 'translation' or 'rotation', got {reuse!r}")
    units = _unit_specs(graph, cache, rotations=reuse == "rotation")
    t_check = time.perf_counter()
    specs = units.specs
    estimate: dict[str, float] = {}
    if progress is True:
        results = run_with_estimate(
            specs, units.template, float(tolerance), float(angular), keep_solids, workers,
            float(hub_timeout), estimate=estimate,
        )  # fmt: skip
    else:
        results = _run(
            specs, float(tolerance), float(angular), keep_solids, workers, float(hub_timeout),
            progress,
        )  # fmt: skip
    t_build = time.perf_counter()
    mesh, face_node, hub_volume, failed = _stack(graph, results, units)
    attempts: dict[int, list[str]] = {}
    by_template = units.instances_of()
    for t, res in enumerate(results):
        if res.status != "ok" or len(res.attempts) > 1:
            for i in by_template[t]:
                for n in units.members[i]:
                    attempts[int(n)] = list(res.attempts)
    volume = float(np.nansum(hub_volume))
    t_end = time.perf_counter()
    return Reference(
        graph=graph,
        volume=volume,
        mesh=mesh,
        face_node=face_node,
        hub_volume=hub_volume,
        failed=dict(sorted(failed.items())),
        attempts=attempts,
        tolerance=float(tolerance),
        angular=float(angular),
        unique_hubs=len(specs),
        cache_hits=len(units.template) - len(specs),
        timings={
            "check": t_check - t0,
            "build": t_build - t_check,
            "stack": t_end - t_build,
            "total": t_end - t0,
            **estimate,
        },
        node_template=np.where(
            units.node_instance >= 0, units.template[np.maximum(units.node_instance, 0)], -1
        ),
        breps=[r.brep for r in results],
        clusters=[mem for mem in units.members if len(mem) > 1],
        units=units,
    )


def _turned_phases(
    res: Any,
    q: NDArray[np.float64],
    at: NDArray[np.float64],
    es: NDArray[np.int64],
    mid: NDArray[np.float64],
    X: NDArray[np.float64],
    Y: NDArray[np.float64],
) -> list[tuple[float, int]] | str:
    """Where a turned copy's midpoint circles land in their struts' frames.

    Per circle ``j`` of the template (strut ``es[j]`` of the copy): ``(phi, sigma)`` such that
    template vertex ``k`` lies at the angle ``phi + sigma * 2 pi k / K`` of the strut's frame
    (``sigma = -1`` where the copy runs the circle the other way). A message if the circle is
    not uniform there (it then cannot be stacked).
    """
    out: list[tuple[float, int]] = []
    for j, c in enumerate(res.circles):
        e = int(es[j])
        k = len(c)
        p = res.vertices[c] @ q.T + at - mid[e]
        ang = np.arctan2(p @ Y[e], p @ X[e])
        step = 2.0 * math.pi / k
        d1 = (ang[1] - ang[0] + math.pi) % (2.0 * math.pi) - math.pi
        sigma = 1 if d1 > 0 else -1
        dev = (ang - ang[0] - sigma * step * np.arange(k) + math.pi) % (2.0 * math.pi) - math.pi
        if np.abs(dev).max() > 10.0 * config.ANGLE_TOL:
            return (
                f"midpoint circle of strut {e}: the turned copy's {k} vertices are not "
                f"uniformly spaced (max angle error {np.abs(dev).max():.3g} rad)"
            )
        out.append((float(ang[0] % (2.0 * math.pi)), sigma))
    return out


def _circle_edge_faces(res: Any) -> list[NDArray[np.int64]] | None:
    """Per circle ``j``: the face holding the boundary edge from vertex ``k`` to ``k + 1``
    (``(K_j,)`` int64); None if an edge is not found exactly once."""
    f = np.asarray(res.faces, dtype=np.int64)
    nv = len(res.vertices)
    e = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.minimum(e[:, 0], e[:, 1]) * nv + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(key, kind="stable")
    skey = key[order]
    out = []
    for c in res.circles:
        a, b = c, np.roll(c, -1)
        want = np.minimum(a, b) * nv + np.maximum(a, b)
        lo = np.searchsorted(skey, want, side="left")
        hi = np.searchsorted(skey, want, side="right")
        if np.any(hi - lo != 1):
            return None
        out.append(order[lo] // 3)
    return out


def _stack(
    graph: LatticeGraph, results: list[Any], units: _Units
) -> tuple[Mesh, NDArray[np.int64], NDArray[np.float64], dict[int, str]]:
    """Stack the hub and cluster tessellations; shared circle vertices become one point.

    Copies placed by translation put their circle vertices at the angles ``2 pi k / K`` of
    each strut's canonical frame, so both ends of a strut share ``K`` points. A turned copy
    (:mod:`reference_boolean.rotations`) puts them at ``phi + 2 pi k / K`` for some ``phi``:
    where the two ends of a strut disagree on ``phi``, the strut's circle gets both sets
    (``2 K`` points on the exact circle) and each end's boundary triangle on an edge
    between two of its own points is split at the other end's point between them. No vertex
    moves, every vertex stays on the exact surface, and the stack stays watertight.
    """
    m = graph.num_edges
    failed: dict[int, str] = {}
    K = np.zeros(m, dtype=np.int64)
    K_node = np.full(m, -1, dtype=np.int64)
    hub_volume = np.full(graph.num_nodes, np.nan)
    n_inst = len(units.template)
    inst_ok = np.zeros(n_inst, dtype=bool)
    turned = units.turned()
    rot = units.rotation
    _, X, Y = strut_frames(graph)
    mid = 0.5 * (graph.nodes[graph.edges[:, 0]] + graph.nodes[graph.edges[:, 1]])
    rmid = graph.radii.mean(axis=1)

    def fail(i: int, why: str) -> None:
        mem = units.members[i]
        pre = "" if len(mem) == 1 else f"cluster of nodes {mem.tolist()}: "
        for n in mem:
            failed[int(n)] = pre + why

    by_template = units.instances_of()
    inst_phase: dict[int, list[tuple[float, int]]] = {}
    # 1. circle sizes: both sides of a strut must agree
    for t, res in enumerate(results):
        if res.status != "ok":
            for i in by_template[t]:
                fail(int(i), res.status)
            continue
        ks = np.array([len(c) for c in res.circles], dtype=np.int64)
        for i in by_template[t]:
            es = units.slots[i]
            clash = (K[es] != 0) & (K[es] != ks)
            if clash.any():
                j = int(np.flatnonzero(clash)[0])
                fail(
                    int(i),
                    f"midpoint circle of strut {int(es[j])} has {int(ks[j])} vertices here but "
                    f"{int(K[es[j]])} at node {int(K_node[es[j]])}",
                )
                continue
            if turned[i]:
                assert rot is not None
                ph = _turned_phases(res, rot[i], graph.nodes[units.anchor[i]], es, mid, X, Y)
                if isinstance(ph, str):
                    fail(int(i), ph)
                    continue
                inst_phase[int(i)] = ph
            K[es] = ks
            K_node[es] = units.anchor[i]
            inst_ok[i] = True
    # 1b. phases of the struts a turned copy ends on (both ends), in [0, 2 pi / K)
    ends: dict[int, list[float]] = {}
    for i, ph in inst_phase.items():
        for j, (phi, _) in enumerate(ph):
            e = int(units.slots[i][j])
            ends.setdefault(e, []).append(phi % (2.0 * math.pi / K[e]))
    special = np.zeros(m, dtype=bool)
    special[list(ends)] = True
    for i in np.flatnonzero(inst_ok & ~turned):
        es = units.slots[i]
        for e in es[special[es]]:
            ends[int(e)].append(0.0)
    n_ph = np.ones(m, dtype=np.int64)
    phases: dict[int, list[float]] = {}
    for e, angles in ends.items():
        step = 2.0 * math.pi / K[e]
        uniq: list[float] = []
        for p in sorted(angles):
            if not any(min(abs(p - u), step - abs(p - u)) < 10.0 * config.ANGLE_TOL for u in uniq):
                uniq.append(p)
        phases[e] = uniq
        n_ph[e] = len(uniq)
    base = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(K * n_ph, out=base[1:])
    circ = np.empty((int(base[-1]), 3))
    plain = (K > 0) & ~special
    for k_val in np.unique(K[plain]):
        es = np.flatnonzero(plain & (K == k_val))
        ang = 2.0 * np.pi * np.arange(k_val) / k_val
        pts = mid[es, None, :] + rmid[es, None, None] * (
            np.cos(ang)[None, :, None] * X[es, None, :]
            + np.sin(ang)[None, :, None] * Y[es, None, :]
        )
        idx = base[es][:, None] + np.arange(k_val)[None, :]
        circ[idx.ravel()] = pts.reshape(-1, 3)
    for e, uniq in phases.items():  # point k * n + p at the angle uniq[p] + 2 pi k / K
        k_val, n = int(K[e]), len(uniq)
        ang = np.asarray(uniq)[None, :] + 2.0 * np.pi * np.arange(k_val)[:, None] / k_val
        ang = ang.ravel()
        circ[base[e] : base[e] + k_val * n] = mid[e] + rmid[e] * (
            np.cos(ang)[:, None] * X[e] + np.sin(ang)[:, None] * Y[e]
        )
    # 2. per template, all its plain instances at once; turned ones (and those next to one)
    # one by one
    verts = [circ]
    faces: list[NDArray[np.int64]] = []
    fnode: list[NDArray[np.int64]] = []
    offset = len(circ)
    scale = float(np.max(graph.edge_lengths))
    for t, res in enumerate(results):
        if res.status != "ok":
            continue
        inst = by_template[t]
        inst = inst[inst_ok[inst]]
        if len(inst) == 0:
            continue
        nc = sum(len(c) for c in res.circles)
        nv = len(res.vertices)
        ni = nv - nc
        one_by_one = np.array(
            [turned[i] or bool(special[units.slots[i]].any()) for i in inst], dtype=bool
        )
        for i in inst[one_by_one]:
            got = _stack_one(
                int(i), res, units, graph, inst_phase.get(int(i)), base, n_ph, phases, K,
                circ, offset, scale,
            )  # fmt: skip
            if isinstance(got, str):
                fail(int(i), got)
                continue
            v_i, f_i, src = got
            verts.append(v_i)
            offset += len(v_i)
            faces.append(f_i)
            mem_i = units.members[i]
            if len(mem_i) == 1:
                fnode.append(np.full(len(f_i), mem_i[0], dtype=np.int64))
            else:  # each triangle to the nearest member node (as below), by its source face
                local = graph.nodes[mem_i] - graph.nodes[mem_i[0]]
                cen = res.vertices[res.faces].mean(axis=1)
                near = np.argmin(np.linalg.norm(cen[:, None, :] - local[None], axis=2), axis=1)
                fnode.append(mem_i[near[src]])
            hub_volume[units.members[i]] = 0.0
            hub_volume[units.anchor[i]] = res.volume
        inst = inst[~one_by_one]
        if len(inst) == 0:
            continue
        vmap = np.empty((len(inst), nv), dtype=np.int64)
        if nc:
            E = np.stack([units.slots[i] for i in inst])  # (c, d)
            col = 0
            for j, c in enumerate(res.circles):
                vmap[:, col : col + len(c)] = base[E[:, j]][:, None] + np.arange(len(c))[None, :]
                col += len(c)
        vmap[:, nc:] = offset + np.arange(len(inst) * ni).reshape(len(inst), ni)
        offset += len(inst) * ni
        anchors = units.anchor[inst]
        placed = res.vertices[None, :, :] + graph.nodes[anchors][:, None, :]
        bad = np.zeros(len(inst), dtype=bool)
        if nc:  # snapping check: circle vertices must already be at their canonical points
            move = np.abs(placed[:, :nc, :] - circ[vmap[:, :nc]]).max(axis=(1, 2))
            bad = move > config.SNAP_RTOL * scale
            for i, mv in zip(inst[bad], move[bad], strict=True):
                fail(int(i), f"a midpoint circle vertex is {mv:.3g} away from its canonical point")
        verts.append(placed[:, nc:, :].reshape(-1, 3))
        inst, vmap = inst[~bad], vmap[~bad]  # their vertices stay (unused, compacted below)
        if len(inst) == 0:
            continue
        faces.append(vmap[:, res.faces].reshape(-1, 3))
        mem = np.stack([units.members[i] for i in inst])  # (c, members)
        if mem.shape[1] == 1:
            fnode.append(np.repeat(mem[:, 0], len(res.faces)))
        else:  # each triangle to the nearest member node
            local = graph.nodes[mem[0]] - graph.nodes[mem[0, 0]]
            cen = res.vertices[res.faces].mean(axis=1)
            near = np.argmin(np.linalg.norm(cen[:, None, :] - local[None, :, :], axis=2), axis=1)
            fnode.append(mem[:, near].reshape(-1))
        hub_volume[mem.ravel()] = 0.0
        hub_volume[units.anchor[inst]] = res.volume
    V = np.concatenate(verts) if verts else np.zeros((0, 3))
    F = np.concatenate(faces) if faces else np.zeros((0, 3), dtype=np.int64)
    FN = np.concatenate(fnode) if fnode else np.zeros(0, dtype=np.int64)
    # compact vertices that no face uses (circles of failed hubs' struts, dropped nodes)
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    if not used.all():
        new = np.cumsum(used) - 1
        V, F = V[used], new[F]
    for n in failed:
        hub_volume[n] = np.nan
    return (
        Mesh(vertices=np.ascontiguousarray(V), faces=np.ascontiguousarray(F)),
        FN,
        hub_volume,
        failed,
    )


def _stack_one(
    i: int,
    res: Any,
    units: _Units,
    graph: LatticeGraph,
    phase: list[tuple[float, int]] | None,
    base: NDArray[np.int64],
    n_ph: NDArray[np.int64],
    phases: dict[int, list[float]],
    K: NDArray[np.int64],
    circ: NDArray[np.float64],
    offset: int,
    scale: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]] | str:
    """One placed (possibly turned) copy: its own vertices (numbered from ``offset``), its
    faces (global numbering, boundary triangles split where the strut's circle has the
    other end's points too) and the template face each comes from; a message if it cannot
    be stacked."""
    q = np.eye(3) if units.rotation is None else units.rotation[i]
    es = units.slots[i]
    nc = sum(len(c) for c in res.circles)
    nv = len(res.vertices)
    vmap = np.empty(nv, dtype=np.int64)
    vmap[nc:] = offset + np.arange(nv - nc)
    local = np.asarray(res.faces, dtype=np.int64)
    if np.linalg.det(q) < 0.0:  # a reflection turns the triangles inside out
        local = local[:, ::-1]
    splits: list[tuple[int, int, int, int]] = []  # (face, a, b, middle point)
    edge_faces: list[NDArray[np.int64]] | None = None
    for j, c in enumerate(res.circles):
        e = int(es[j])
        k_val = len(c)
        step = 2.0 * math.pi / k_val
        phi, sigma = phase[j] if phase is not None else (0.0, 1)
        n = int(n_ph[e])
        ph = phases.get(e, [0.0])
        dist = [min(abs(phi % step - u), step - abs(phi % step - u)) for u in ph]
        p = int(np.argmin(dist))
        k0 = int(np.rint((phi - ph[p]) / step)) % k_val
        pos = (k0 + sigma * np.arange(k_val)) % k_val
        vmap[c] = base[e] + pos * n + p
        if n == 2:
            if edge_faces is None:
                edge_faces = _circle_edge_faces(res)
                if edge_faces is None:
                    return "a midpoint circle edge is not on exactly one triangle"
            middle = base[e] + (pos * n + p + sigma) % (k_val * n)
            for k in range(k_val):
                splits.append((int(edge_faces[j][k]), int(c[k]), int(c[(k + 1) % k_val]),
                               int(middle[k])))  # fmt: skip
        elif n != 1:
            return f"midpoint circle of strut {e} has {n} phases (expected 1 or 2)"
    placed = res.vertices @ q.T + graph.nodes[units.anchor[i]]
    move = np.abs(placed[:nc] - circ[vmap[:nc]]).max() if nc else 0.0
    if move > config.SNAP_RTOL * scale:
        return f"a midpoint circle vertex is {move:.3g} away from its canonical point"
    keep = np.ones(len(local), dtype=bool)
    extra: list[NDArray[np.int64]] = []
    if splits:
        s = np.asarray(splits, dtype=np.int64)
        if len(np.unique(s[:, 0])) != len(s):
            return "a triangle has two midpoint circle edges (cannot split both)"
        tri = local[s[:, 0]]
        third = np.argmax((tri != s[:, 1:2]) & (tri != s[:, 2:3]), axis=1)
        r = np.arange(len(s))
        x0 = vmap[tri[r, (third + 1) % 3]]
        x1 = vmap[tri[r, (third + 2) % 3]]
        x2 = vmap[tri[r, third]]
        mpt = s[:, 3]
        extra.append(np.column_stack([x0, mpt, x2]))
        extra.append(np.column_stack([mpt, x1, x2]))
        keep[s[:, 0]] = False
    f = np.concatenate([vmap[local[keep]], *extra])
    src = np.arange(len(local), dtype=np.int64)[keep]
    if splits:
        src = np.concatenate([src, s[:, 0], s[:, 0]])
    return np.ascontiguousarray(placed[nc:]), f, src
