"""Compare meshes of a lattice with its exact reference.

:func:`compare` builds the reference (:func:`~reference_boolean.build_reference`),
manifold3d unions of the same spheres and struts at several resolutions, and
measures a given mesh (e.g. from :func:`fast_stitch.stitch`) against the
reference: volume, two-sided surface deviation, validity, triangle counts and
timings, and the nodes where the mesh deviates most.
"""

from __future__ import annotations

import math
import os
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.mesh import Mesh
from reference_boolean.reference import Reference, build_reference

if TYPE_CHECKING:
    from reference_boolean.verdict import Verdict

__all__ = [
    "ValidationReport",
    "MeshComparison",
    "compare",
    "union_mesh",
    "hub_union",
    "union_sample",
    "surface_deviation",
    "two_sided_deviation",
    "two_sided_deviations",
    "mesh_validity",
]


# ------------------------------------------------------------------ union
def union_mesh(graph: LatticeGraph, segments: int) -> Mesh:
    """manifold3d union of the hub spheres and the full struts, ``segments`` per circle.

    The same design as the reference: a sphere of radius ``1.00001 * max incident
    radius`` at every node of degree >= 2, none at leaves (degree 1), where the strut
    ends flat at the node; struts are cylinders (cones for tapered struts) from node
    to node. The union converges to the reference as ``segments`` grows (error ~ 1/n^2).

    Returns
    -------
    fast_stitch.Mesh
        ``vertices`` (V, 3) float64, ``faces`` (F, 3) int64.
    """
    import manifold3d as m3

    n = int(segments)
    if n < 3:
        raise ValueError(f"segments must be >= 3, got {segments}")
    rmax = np.zeros(graph.num_nodes)
    np.maximum.at(rmax, graph.edges[:, 0], graph.radii[:, 0])
    np.maximum.at(rmax, graph.edges[:, 1], graph.radii[:, 1])
    parts = []
    unit = m3.Manifold.sphere(1.0, n)
    for i in np.flatnonzero((rmax > 0) & (graph.degree >= 2)):
        R = config.SPHERE_FACTOR * rmax[i]
        parts.append(unit.scale([R, R, R]).translate(graph.nodes[i].tolist()))
    z = np.array([0.0, 0.0, 1.0])
    for e, (a, b) in enumerate(graph.edges):
        p, q = graph.nodes[a], graph.nodes[b]
        v = q - p
        L = float(np.linalg.norm(v))
        d = v / L
        cyl = m3.Manifold.cylinder(L, float(graph.radii[e, 0]), float(graph.radii[e, 1]), n)
        # rotation taking z to d (Rodrigues), as a 3x4 affine matrix
        c = float(d @ z)
        if c < -1 + 1e-12:
            rot = np.diag([1.0, -1.0, -1.0])
        else:
            k = np.cross(z, d)
            K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            rot = np.eye(3) + K + K @ K / (1.0 + c)
        mat = np.column_stack([rot, p])
        parts.append(cyl.transform(mat.tolist()))
    u = m3.Manifold.batch_boolean(parts, m3.OpType.Add)
    mesh = u.to_mesh()
    v = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    f = np.asarray(mesh.tri_verts, dtype=np.int64)
    return Mesh(vertices=np.ascontiguousarray(v), faces=np.ascontiguousarray(f))


def hub_union(
    graph: LatticeGraph, nodes: NDArray[np.int64], segments: int
) -> tuple[float, int, bool]:
    """manifold3d unions of the unit trusses of ``nodes`` (a sample of the lattice's hubs).

    Each hub is the union of its sphere (the reference's radius; none at a leaf, which ends
    flat) and its half-struts from the node to the strut midpoints (cylinders, or cone
    frustums from the node radius to the midpoint radius), ``segments`` per circle: the
    polyhedral counterpart of one reference hub, so the sum of their volumes converges to
    the sum of those hubs' exact volumes (``Reference.hub_volume``) as ``segments`` grows.
    Each hub is a separate union: the cost is that of the sample, not of the lattice.

    Parameters
    ----------
    graph : LatticeGraph
    nodes : (k,) int64
        Nodes with at least one strut.
    segments : int

    Returns
    -------
    volume : float
        Sum of the hub unions' volumes.
    triangles : int
    valid : bool
        Every hub union is a valid manifold3d solid.
    """
    import manifold3d as m3

    n = int(segments)
    if n < 3:
        raise ValueError(f"segments must be >= 3, got {segments}")
    offsets, inc_edge, inc_side = graph.incidence
    rmax = np.zeros(graph.num_nodes)
    np.maximum.at(rmax, graph.edges[:, 0], graph.radii[:, 0])
    np.maximum.at(rmax, graph.edges[:, 1], graph.radii[:, 1])
    rmid = graph.radii.mean(axis=1)
    unit = m3.Manifold.sphere(1.0, n)
    vol, tris, valid = 0.0, 0, True
    for node in np.asarray(nodes, dtype=np.int64):
        p = graph.nodes[node]
        R = config.SPHERE_FACTOR * rmax[node]
        # no ball at a leaf: the reference ends the strut flat there (docs/REFERENCE.md)
        leaf = offsets[node + 1] - offsets[node] == 1
        parts = [] if leaf else [unit.scale([R, R, R]).translate(p.tolist())]
        es = inc_edge[offsets[node] : offsets[node + 1]]
        sd = inc_side[offsets[node] : offsets[node + 1]]
        for e, side in zip(es, sd, strict=True):
            q = 0.5 * (graph.nodes[graph.edges[e, 0]] + graph.nodes[graph.edges[e, 1]])
            v = q - p
            L = float(np.linalg.norm(v))
            cyl = m3.Manifold.cylinder(L, float(graph.radii[e, side]), float(rmid[e]), n)
            parts.append(cyl.transform(np.column_stack([_z_to(v / L), p]).tolist()))
        u = m3.Manifold.batch_boolean(parts, m3.OpType.Add)
        valid = valid and u.status() == m3.Error.NoError
        vol += float(u.volume())
        tris += int(u.num_tri())
    return vol, tris, valid


def _z_to(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) rotation taking the z axis to the unit vector ``d`` (Rodrigues)."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(d @ z)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(z, d)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def union_sample(
    reference: Reference,
    hubs: int,
    seed: int = 0,
    *,
    max_stumps: int | None = config.UNION_MAX_STUMPS,
) -> NDArray[np.int64]:
    """(k,) int64: a seeded sample of at most ``hubs`` nodes whose reference hub was built
    on its own (nodes fused into a cluster solid are left out: their hubs overlap, so the
    sum of their separate unions is not the cluster's volume).

    The sample also holds at most ``max_stumps`` half-struts in all (the seeded order is
    cut where the running sum of the degrees would pass it; at least one hub): the cost
    of the unions grows with the stumps, so a lattice of high-degree hubs (a tet lattice,
    degree ~12) gets fewer hubs than a clipped voxel lattice with many leaves, and the
    study's time stays bounded and does not depend on the machine. None: no such bound.
    """
    single = np.isfinite(reference.hub_volume)
    for members in reference.clusters:
        single[np.asarray(members, dtype=np.int64)] = False
    ok = np.flatnonzero(single)
    degree = reference.graph.degree
    if len(ok) <= hubs and (max_stumps is None or int(degree[ok].sum()) <= max_stumps):
        return ok
    rng = np.random.default_rng(seed)
    pick = rng.choice(ok, size=min(int(hubs), len(ok)), replace=False)
    if max_stumps is not None:
        keep = int(np.searchsorted(np.cumsum(degree[pick]), int(max_stumps), side="right"))
        pick = pick[: max(keep, 1)]
    return np.sort(pick)


# ---------------------------------------------------------------- measures
#: :func:`reference_validity` per reference (a reference's mesh does not change: it is a
#: frozen dataclass; the check takes ~30 s on a 30K-strut tet reference and every
#: ``to_dict`` / ``save`` asks for it).
_REFERENCE_VALIDITY: weakref.WeakKeyDictionary[Reference, dict[str, bool]] = (
    weakref.WeakKeyDictionary()
)


def reference_validity(reference: Reference) -> dict[str, bool]:
    """:func:`mesh_validity` of ``reference.mesh`` (``{"valid": False}`` when it is empty),
    computed once per reference."""
    got = _REFERENCE_VALIDITY.get(reference)
    if got is None:
        mesh = reference.mesh
        got = mesh_validity(mesh) if len(mesh.faces) else {"valid": False}
        _REFERENCE_VALIDITY[reference] = got
    return dict(got)


def mesh_validity(mesh: Mesh) -> dict[str, bool]:
    """Watertight / winding-consistent / outward and manifold, by manifold3d (and trimesh
    when manifold3d refuses the mesh, to say which of the first two fails).

    manifold3d accepts a mesh (status ``NoError``) only when every edge is shared by two
    triangles of opposite orientation: watertight and consistently wound; the sign of its
    volume then says outward. That is all the report needs on a valid mesh, and trimesh's
    own checks (half of the time on a 5M-triangle reference) are only run on a refused one.
    """
    import manifold3d as m3

    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    man = m3.Manifold(m3.Mesh(vert_properties=v.astype(np.float32), tri_verts=f.astype(np.uint32)))
    if man.status() == m3.Error.NoError:
        out = {
            "watertight": True,
            "winding_consistent": True,
            "outward": bool(man.volume() > 0),
            "manifold3d": True,
        }
    else:
        import trimesh

        tm = trimesh.Trimesh(vertices=v, faces=f, process=False)
        out = {
            "watertight": bool(tm.is_watertight),
            "winding_consistent": bool(tm.is_winding_consistent),
            "outward": bool(tm.volume > 0),
            "manifold3d": False,
        }
    out["valid"] = all(out.values())
    return out


def _sample(mesh: Mesh, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n, 3) float64 area-weighted uniform samples, plus all vertices."""
    v, f = mesh.vertices, mesh.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    tri = rng.choice(len(f), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    pts = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]
    return np.vstack([pts, v])


def surface_deviation(
    source: Mesh, target: Mesh, *, samples: int = config.DEFAULT_SAMPLES, seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Distances from points sampled densely on ``source`` to the surface of ``target``.

    Returns
    -------
    points : (S, 3) float64
        ``samples`` area-weighted random points on ``source`` (the first ``samples`` rows:
        the statistics of the surface, mean and percentiles, are taken over these) and then
        all its vertices (they add the extremes: a polygonal strut's corners lie farthest
        from the exact cylinder; the max is taken over every point).
    distance : (S,) float64
        Exact point-to-triangle distance to ``target`` (libigl's AABB tree,
        ``igl.AABB.squared_distance``), queried in chunks of
        ``config.DEVIATION_CHUNK`` points so memory stays bounded (trimesh's
        ``closest_point`` needed 16 GB for 20,000 points near an 82K-triangle sphere).
    """
    pts = _sample(source, samples, np.random.default_rng(seed))
    return pts, _distances(_Tree(target), pts)


class _Tree:
    """libigl's AABB tree of one mesh (built once, queried for any number of point sets)."""

    def __init__(self, mesh: Mesh) -> None:
        import igl

        self.v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
        self.f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        self.tree = igl.AABB()
        self.tree.init(self.v, self.f)


def _spread_bits(x: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """The low 21 bits of ``x`` spread to every third bit (for a 63-bit Morton code)."""
    x = x & np.uint64(0x1FFFFF)
    for shift, mask in (
        (32, 0x1F00000000FFFF),
        (16, 0x1F0000FF0000FF),
        (8, 0x100F00F00F00F00F),
        (4, 0x10C30C30C30C30C3),
        (2, 0x1249249249249249),
    ):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def morton_order(pts: NDArray[np.float64]) -> NDArray[np.int64]:
    """The order of ``pts`` (S, 3) along a Morton (Z-order) curve over their bounding box
    (21 bits per axis): nearby points come one after another."""
    if not len(pts):
        return np.zeros(0, dtype=np.int64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    q = ((pts - lo) * ((2**21 - 1) / np.maximum(hi - lo, 1e-300))).astype(np.uint64)
    code = (
        _spread_bits(q[:, 0])
        | (_spread_bits(q[:, 1]) << np.uint64(1))
        | (_spread_bits(q[:, 2]) << np.uint64(2))
    )
    return np.argsort(code, kind="stable")


def _distances(tree: _Tree, pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Exact distances of ``pts`` to the mesh of ``tree``, in chunks of
    ``config.DEVIATION_CHUNK`` points.

    The points are queried in Morton order (:func:`morton_order`) and the distances put
    back in their order: each query then walks the tree where the previous one did, which
    halved the CPU time of the random surface samples against a 1M-triangle reference
    (libigl's tree of a 5M-triangle reference does not fit in the CPU caches); every
    distance is the same, bit for bit (each point's query is independent)."""
    order = morton_order(pts)
    dist = np.empty(len(pts), dtype=np.float64)
    step = config.DEVIATION_CHUNK
    for i in range(0, len(pts), step):
        idx = order[i : i + step]
        d2, _, _ = tree.tree.squared_distance(tree.v, tree.f, np.ascontiguousarray(pts[idx]))
        dist[idx] = np.sqrt(np.maximum(d2, 0.0))
    return dist


def _to_reference(
    meshes: list[Mesh], reference: Mesh, samples: int, seed: int
) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """:func:`surface_deviation` of each mesh to ``reference`` (seed ``seed``), with one
    tree of the reference for all of them."""
    tree = _Tree(reference)
    out = []
    for m in meshes:
        pts = _sample(m, samples, np.random.default_rng(seed))
        out.append((pts, _distances(tree, pts)))
    return out


def _from_reference(
    meshes: list[Mesh], reference: Mesh, samples: int, seed: int
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    """:func:`surface_deviation` of ``reference`` to each mesh (seed ``seed``): the
    reference's points, sampled once, and their distances to each mesh."""
    pts = _sample(reference, samples, np.random.default_rng(seed))
    return pts, [_distances(_Tree(m), pts) for m in meshes]


#: The meshes of :func:`two_sided_deviation` while a forked child measures one side (the
#: child inherits them instead of receiving pickled copies).
_FORKED: dict[str, tuple[list[Mesh], Mesh]] = {}


def _forked_deviation(
    samples: int, seed: int
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    meshes, reference = _FORKED["pair"]
    return _from_reference(meshes, reference, samples, seed)


def two_sided_deviation(
    mesh: Mesh, reference: Mesh, *, samples: int = config.DEFAULT_SAMPLES, seed: int = 0
) -> tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]:
    """:func:`surface_deviation` of ``mesh`` to ``reference`` (seed ``seed``) and of
    ``reference`` to ``mesh`` (seed ``seed + 1``): ``((p1, d1), (p2, d2))``.

    libigl's tree holds the GIL, so with more than one CPU and at least
    ``config.DEVIATION_PARALLEL_MIN`` vertices in all, the second side is measured by a
    forked child process (Linux; it inherits the meshes) while this one measures the first:
    the same numbers (same seeds); the GE tet report's deviation stage took 78 -> 56 s.
    """
    return two_sided_deviations([mesh], reference, samples=samples, seed=seed)[0]


def two_sided_deviations(
    meshes: list[Mesh],
    reference: Mesh,
    *,
    samples: int = config.DEFAULT_SAMPLES,
    seed: int = 0,
    while_waiting: Callable[[], object] | None = None,
) -> list[tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]]:
    """:func:`two_sided_deviation` of each of ``meshes`` against one ``reference``, each
    mesh's numbers the same as alone; the reference's tree is built once and its points
    sampled once (they are the same for every mesh: same seed), so a second mesh (the
    report compares two) costs only its own side and its own tree.

    ``while_waiting``, if given, is called once in this process after its own side while
    the forked child may still measure the other (on the GE tet lattice the reference's
    side is the longer: the report checks the reference's validity there); not called
    when both sides are measured here (small meshes, one CPU)."""
    import multiprocessing as mp
    import sys
    from concurrent.futures import ProcessPoolExecutor

    from lattice_cad.core.isolate import die_with_parent, kill_pool

    meshes = list(meshes)
    if not meshes:
        return []
    big = (
        max(len(m.vertices) for m in meshes) + len(reference.vertices)
        >= config.DEVIATION_PARALLEL_MIN
    )
    if not (big and (os.cpu_count() or 1) > 1 and sys.platform.startswith("linux")):
        first = _to_reference(meshes, reference, samples, seed)
        p2, d2s = _from_reference(meshes, reference, samples, seed + 1)
    else:
        _FORKED["pair"] = (meshes, reference)
        pool = ProcessPoolExecutor(
            max_workers=1, mp_context=mp.get_context("fork"), initializer=die_with_parent
        )
        try:
            future = pool.submit(_forked_deviation, samples, seed + 1)
            first = _to_reference(meshes, reference, samples, seed)
            if while_waiting is not None:
                while_waiting()
            p2, d2s = future.result()
        except BaseException:  # Ctrl-C or an error: no child left behind
            kill_pool(pool, wait=True)
            raise
        finally:
            _FORKED.pop("pair", None)
        pool.shutdown(wait=True)
    return [(one, (p2, d2)) for one, d2 in zip(first, d2s, strict=True)]


def _stats(d: NDArray[np.float64], samples: int | None = None) -> dict[str, float]:
    """max over every point; mean and p95 over the first ``samples`` (the area-weighted
    random points of :func:`surface_deviation`; None: all). The vertices that follow them
    are not a uniform sample of the surface: counted in the percentiles, they weigh each
    region by its vertex density (a fine tessellation's small fillets, a polygon's corners,
    where the deviation peaks) instead of its area."""
    da = d if samples is None else d[: int(samples)]
    return {
        "max": float(d.max()),
        "mean": float(da.mean()),
        "p95": float(np.percentile(da, 95)),
        "samples": int(len(da)),
    }


# ------------------------------------------------------------------ report
@dataclass(frozen=True, eq=False)
class MeshComparison:
    """One mesh measured against the reference (one row of the report).

    Attributes
    ----------
    label : str
    mesh : Mesh
    volume : float
    relative_volume_error : float
        ``(volume - V_ref) / V_ref``.
    valid : dict[str, bool]
        :func:`mesh_validity`.
    hausdorff : dict[str, dict[str, float]]
        ``"mesh_to_reference"`` / ``"reference_to_mesh"`` / ``"symmetric"`` (max, mean, p95),
        over the whole surfaces.
    node_deviation : (N,) float64
        Largest sampled deviation near each node.
    distances : dict[str, (S,) float64]
    timings : dict[str, float]
        ``"mesh_checks"`` and ``"deviation"`` seconds.
    regions : dict[str, dict[str, dict[str, float]]]
        The same deviation split by where the samples lie
        (:func:`reference_boolean.regions.region_stats`): ``"struts"`` (outside every hub
        zone, where the mesh and the reference model the same design) and ``"hubs"``
        (inside a hub zone: the convex hub against the ball and cylinders); each with
        ``"mesh_to_reference"``, ``"reference_to_mesh"``, ``"symmetric"`` (max, mean, p95,
        samples, fraction). Empty when not measured.
    node_worst_point : (N, 3) float64 or None
        Where :attr:`node_deviation` was sampled: the sample (on either surface) of the
        largest distance among those nearest to each node (NaN where none).
    node_worst_side : (N,) int8 or None
        Which surface that sample lies on: 0 the mesh (distance to the reference), 1 the
        reference (distance to the mesh), -1 none.
    """

    label: str
    mesh: Mesh
    volume: float
    relative_volume_error: float
    valid: dict[str, bool]
    hausdorff: dict[str, dict[str, float]]
    node_deviation: NDArray[np.float64] = field(repr=False)
    distances: dict[str, NDArray[np.float64]] = field(repr=False)
    timings: dict[str, float] = field(default_factory=dict)
    regions: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    node_worst_point: NDArray[np.float64] | None = field(default=None, repr=False)
    node_worst_side: NDArray[np.int8] | None = field(default=None, repr=False)

    def summary(self) -> dict[str, Any]:
        """JSON-ready row: label, volume, relative error, triangles, valid, hausdorff."""
        return {
            "label": self.label,
            "volume": self.volume,
            "relative_volume_error": self.relative_volume_error,
            "triangles": int(len(self.mesh.faces)),
            "valid": dict(self.valid),
            "hausdorff": self.hausdorff,
            "deviation_regions": self.regions,
            "timings": dict(self.timings),
        }


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Numbers (and the data for the plots) of :func:`compare`.

    Attributes
    ----------
    graph : LatticeGraph
    reference : Reference
    volume_union : dict[int, float]
        manifold3d union volume per circle resolution.
    union_triangles, union_valid, union_seconds : dict[int, ...]
    convergence_order : float or None
        Fitted ``p`` of ``|V_union(n) - V_ref| ~ C n^-p`` (2 expected).
    mesh : Mesh or None
        The compared mesh.
    volume_mesh : float or None
    mesh_valid : dict or None
    hausdorff : dict[str, dict[str, float]]
        ``"mesh_to_reference"`` / ``"reference_to_mesh"`` (max, mean, p95) and
        ``"symmetric"`` (the larger of each).
    node_deviation : (N,) float64
        Largest sampled deviation near each node (NaN without a mesh).
    distances : dict[str, (S,) float64]
        The sampled distances (for the histogram).
    timings : dict[str, float]
    label : str
        Name of the compared mesh (e.g. ``"fast_stitch P=6"``).
    extra : dict
        Free-form additions (shown in every format).
    comparisons : dict[str, MeshComparison]
        Every compared mesh by label, in the order given. ``mesh``,
        ``volume_mesh``, ``mesh_valid``, ``hausdorff``, ``node_deviation``,
        ``distances`` and ``label`` above are those of the first one.
    union_scope : str
        What the unions cover: ``"lattice"`` (the whole lattice) or a sentence naming
        the sample of hubs (:func:`hub_union`).
    union_reference_volume : float or None
        The exact volume the unions converge to (the sampled hubs' sum); None: the
        reference volume.
    tolerance : float or None
        Surface tolerance of the verdict, mm (None: 10 % of the median strut
        radius); see :mod:`reference_boolean.verdict`.
    tolerance_volume : float or None
        Relative volume tolerance of the verdict (None: 0.01).
    hub_zone : (N,) float64 or None
        Radius of each node's hub zone (:func:`reference_boolean.regions.hub_zones`), the
        mask of the strut / hub deviations; None: not measured.
    hub_zone_factor : float or None
        The factor the zones were computed with.
    """

    graph: LatticeGraph
    reference: Reference
    volume_union: dict[int, float]
    union_triangles: dict[int, int]
    union_valid: dict[int, bool]
    union_seconds: dict[int, float]
    convergence_order: float | None
    mesh: Mesh | None
    volume_mesh: float | None
    mesh_valid: dict[str, bool] | None
    hausdorff: dict[str, dict[str, float]]
    node_deviation: NDArray[np.float64]
    distances: dict[str, NDArray[np.float64]] = field(repr=False)
    timings: dict[str, float] = field(default_factory=dict)
    label: str = "mesh"
    extra: dict[str, Any] = field(default_factory=dict)
    comparisons: dict[str, MeshComparison] = field(default_factory=dict, repr=False)
    union_scope: str = "lattice"
    union_reference_volume: float | None = None
    tolerance: float | None = None
    tolerance_volume: float | None = None
    hub_zone: NDArray[np.float64] | None = field(default=None, repr=False)
    hub_zone_factor: float | None = None

    def verdict(self, label: str | None = None) -> Verdict:
        """PASS / FAIL of the first mesh (or ``label``) against the report's tolerances.

        See :func:`reference_boolean.verdict.judge`; an incomplete reference never passes.
        """
        from reference_boolean.verdict import judge

        return judge(
            self, tolerance=self.tolerance, tolerance_volume=self.tolerance_volume, label=label
        )

    def worst_nodes(self, k: int = 10) -> list[tuple[int, float]]:
        """The ``k`` nodes with the largest local deviation, as (node, deviation)."""
        d = self.node_deviation
        ok = np.flatnonzero(np.isfinite(d))
        order = ok[np.argsort(-d[ok], kind="stable")][:k]
        return [(int(i), float(d[i])) for i in order]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays except the worst nodes).

        With at most one compared mesh, ``volume_mesh`` is a float (or None),
        ``relative_volume_error["mesh"]``, ``valid["mesh"]``, ``triangles["mesh"]``
        are that mesh's, and ``hausdorff`` is ``{"mesh_to_reference": ...,
        "reference_to_mesh": ..., "symmetric": ...}``. With several meshes, each
        of these becomes a dict keyed by label (``volume_mesh[label]``,
        ``relative_volume_error["mesh"][label]``, ``hausdorff[label]["symmetric"]``,
        ...). ``"meshes"`` always lists one summary row per mesh
        (:meth:`MeshComparison.summary`), in order.
        """
        ref = self.reference
        vref = ref.volume
        vu = vref if self.union_reference_volume is None else self.union_reference_volume
        rel_union = {int(n): (v - vu) / vu for n, v in self.volume_union.items()}
        comps = list(self.comparisons.values())
        if len(comps) > 1:
            volume_mesh: Any = {c.label: c.volume for c in comps}
            rel_mesh: Any = {c.label: c.relative_volume_error for c in comps}
            hausdorff: Any = {c.label: c.hausdorff for c in comps}
            valid_mesh: Any = {c.label: c.valid for c in comps}
            tri_mesh: Any = {c.label: int(len(c.mesh.faces)) for c in comps}
        else:
            volume_mesh = self.volume_mesh
            rel_mesh = None if self.volume_mesh is None else (self.volume_mesh - vref) / vref
            hausdorff = self.hausdorff
            valid_mesh = self.mesh_valid
            tri_mesh = None if self.mesh is None else int(len(self.mesh.faces))
        out: dict[str, Any] = {
            "graph": {
                "nodes": self.graph.num_nodes,
                "struts": self.graph.num_edges,
                "tapered": self.graph.is_tapered,
            },
            "label": self.label,
            "volume_reference": vref,
            "reference_complete": ref.complete,
            "reference_failed": {str(k): v for k, v in ref.failed.items()},
            "volume_reference_mesh": ref.mesh.volume,
            "volume_union": {int(n): float(v) for n, v in self.volume_union.items()},
            "volume_mesh": volume_mesh,
            "meshes": [c.summary() for c in comps],
            "relative_volume_error": {
                "mesh": rel_mesh,
                "reference_mesh": (ref.mesh.volume - vref) / vref,
                "union": rel_union,
            },
            "convergence_order": self.convergence_order,
            "union_scope": self.union_scope,
            "volume_union_reference": vu,
            "hausdorff": hausdorff,
            "valid": {
                "reference": reference_validity(ref),
                "mesh": valid_mesh,
                "union": {int(n): bool(v) for n, v in self.union_valid.items()},
            },
            "triangles": {
                "reference": int(len(ref.mesh.faces)),
                "mesh": tri_mesh,
                "union": {int(n): int(t) for n, t in self.union_triangles.items()},
            },
            "timings": {
                **{k: float(v) for k, v in self.timings.items()},
                "reference": dict(ref.timings),
                "union": {int(n): float(t) for n, t in self.union_seconds.items()},
            },
            "reference_hubs": {
                "unique": ref.unique_hubs,
                "cache_hits": ref.cache_hits,
                "clusters": len(ref.clusters),
                "largest_cluster": max((len(c) for c in ref.clusters), default=1),
            },
            "tessellation": {"tolerance": ref.tolerance, "angular": ref.angular},
            "hub_zone": self._zone_summary(),
            "worst_nodes": [{"node": n, "deviation": d} for n, d in self.worst_nodes()],
            "verdict": self.verdict().to_dict(),
            "verdicts": {lab: self.verdict(lab).to_dict() for lab in self.comparisons},
        }
        if self.extra:
            out["extra"] = self.extra
        return out

    def _zone_summary(self) -> dict[str, Any] | None:
        if self.hub_zone is None:
            return None
        from reference_boolean.regions import RULE

        z = self.hub_zone[self.hub_zone > 0]
        return {
            "factor": self.hub_zone_factor,
            "rule": RULE.format(f=self.hub_zone_factor or 0.0),
            "nodes": int(len(z)),
            "radius_min": float(z.min()) if len(z) else None,
            "radius_median": float(np.median(z)) if len(z) else None,
            "radius_max": float(z.max()) if len(z) else None,
        }

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the report as ``.json``, ``.md`` or ``.html`` (self-contained, PNGs inline)."""
        from reference_boolean import report

        return report.save(self, path)


def _fit_order(volumes: dict[int, float], vref: float) -> float | None:
    ns = np.array(sorted(volumes), dtype=np.float64)
    err = np.array([abs(volumes[int(n)] - vref) for n in ns])
    ok = err > 0
    if ok.sum() < 2:
        return None
    slope = np.polyfit(np.log(ns[ok]), np.log(err[ok]), 1)[0]
    return float(-slope)


def _measure(
    graph: LatticeGraph,
    reference: Reference,
    mesh: Mesh | Any,
    label: str,
    samples: int,
    seed: int,
    zones: NDArray[np.float64] | None = None,
    *,
    deviation: tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...] | None = None,
    deviation_seconds: float = 0.0,
    shared: dict[str, Any] | None = None,
) -> MeshComparison:
    """Volume, validity and two-sided deviation of one mesh against the reference
    (split into strut and hub regions by ``zones``, :mod:`reference_boolean.regions`).

    ``deviation``: the mesh's :func:`two_sided_deviation`, already measured (with the
    other meshes', :func:`two_sided_deviations`; ``deviation_seconds`` its share of that
    time); ``shared``: a dict kept across the meshes of one report (the hub-zone mask of
    the reference's points, the same for every mesh, is computed once)."""
    m = Mesh(
        vertices=np.asarray(mesh.vertices, dtype=np.float64),
        faces=np.asarray(mesh.faces, dtype=np.int64),
    )
    timings: dict[str, float] = {}
    t = time.perf_counter()
    vmesh = float(m.volume)
    mvalid = mesh_validity(m)
    timings["mesh_checks"] = time.perf_counter() - t
    t = time.perf_counter()
    if deviation is None:
        deviation = two_sided_deviation(m, reference.mesh, samples=samples, seed=seed)
    (p1, d1), (p2, d2) = deviation
    regions: dict[str, dict[str, dict[str, float]]] = {}
    if zones is not None:
        from reference_boolean.regions import in_hub_zone, region_stats

        shared = {} if shared is None else shared
        if shared.get("points") is not p2:
            shared["points"], shared["hub2"] = p2, in_hub_zone(p2, graph, zones)
        regions = region_stats(
            in_hub_zone(p1, graph, zones),
            d1,
            shared["hub2"],
            d2,
            area1=np.arange(len(d1)) < samples,
            area2=np.arange(len(d2)) < samples,
        )
    timings["deviation"] = deviation_seconds + time.perf_counter() - t
    hausdorff = {
        "mesh_to_reference": _stats(d1, samples),
        "reference_to_mesh": _stats(d2, samples),
    }
    hausdorff["symmetric"] = {
        k: max(hausdorff["mesh_to_reference"][k], hausdorff["reference_to_mesh"][k])
        for k in ("max", "mean", "p95")
    }
    from scipy.spatial import cKDTree

    # each sample of either surface goes to its nearest node; per node the farthest one
    node_dev = np.full(graph.num_nodes, np.nan)
    node_pt = np.full((graph.num_nodes, 3), np.nan)
    node_side = np.full(graph.num_nodes, -1, dtype=np.int8)
    used = np.flatnonzero(graph.degree > 0)
    tree = cKDTree(graph.nodes[used])
    for side, (p, d) in enumerate(((p1, d1), (p2, d2))):
        if side == 1 and shared is not None and shared.get("near_of") is p:
            nid = shared["near"]  # the reference's points: the same for every mesh
        else:
            _, idx = tree.query(p)
            nid = used[idx]
            if side == 1 and shared is not None:
                shared["near_of"], shared["near"] = p, nid
        order = np.lexsort((d, nid))  # by node, then distance: the last of a node is its max
        last = np.r_[nid[order][1:] != nid[order][:-1], True]
        sel = order[last]
        n_sel = nid[sel]
        better = ~(node_dev[n_sel] >= d[sel])  # NaN (no sample yet) counts as worse
        node_dev[n_sel[better]] = d[sel][better]
        node_pt[n_sel[better]] = p[sel][better]
        node_side[n_sel[better]] = side
    vref = reference.volume
    return MeshComparison(
        label=label,
        mesh=m,
        volume=vmesh,
        relative_volume_error=(vmesh - vref) / vref,
        valid=mvalid,
        hausdorff=hausdorff,
        node_deviation=node_dev,
        distances={"mesh_to_reference": d1, "reference_to_mesh": d2},
        timings=timings,
        regions=regions,
        node_worst_point=node_pt,
        node_worst_side=node_side,
    )


def compare(
    graph: LatticeGraph,
    *,
    mesh: Mesh | Any | None = None,
    meshes: dict[str, Mesh | Any] | None = None,
    union_segments: tuple[int, ...] = (16, 32, 64, 128),
    reference: Reference | None = None,
    samples: int = config.DEFAULT_SAMPLES,
    label: str = "mesh",
    seed: int = 0,
    union_hubs: int | None = config.DEFAULT_UNION_HUBS,
    hub_zone_factor: float | None = config.HUB_ZONE_FACTOR,
    **reference_options: Any,
) -> ValidationReport:
    """Measure manifold3d unions and one or more meshes against the exact reference.

    Parameters
    ----------
    graph : LatticeGraph
    mesh : Mesh or object with ``vertices`` (V, 3) and ``faces`` (F, 3), optional
        The mesh to validate (e.g. ``fast_stitch.stitch(graph)``), named ``label``.
    meshes : dict[str, Mesh], optional
        More meshes to validate against the same reference, by label (e.g.
        ``{"fast P=6": m1, "fast P=6 volume-preserving": m2}``): one row each in
        the report. With ``mesh`` too, ``mesh`` comes first.
    union_segments : tuple of int
        Circle resolutions of the manifold3d unions (empty: no unions).
    reference : Reference, optional
        A reference already built for ``graph`` (else it is built here).
    samples : int
        Random surface samples per direction of the deviation measure (all
        vertices are added).
    label : str
        Name of ``mesh`` in the report.
    seed : int
        Seed of the surface sampling (the same for every mesh).
    union_hubs : int or None
        The convergence study unions a seeded sample of this many hubs (unit trusses,
        :func:`hub_union`) and compares them with the sum of the same hubs' exact
        volumes: it shows the trend at a bounded cost (the union of a 3.5K-strut
        lattice at 16-128 segments took 170 s). None: union the whole lattice.
    hub_zone_factor : float or None
        The deviation is also reported separately along the struts (outside every node's
        hub zone, where mesh and reference model the same design) and at the hubs (inside,
        where the convex hub and the ball differ by design); the zones are
        :func:`reference_boolean.regions.hub_zones` with this factor. None: whole
        surfaces only.
    **reference_options
        Passed to :func:`build_reference` (``tolerance``, ``workers``, ...).

    Returns
    -------
    ValidationReport
        Its ``comparisons`` holds every mesh; the single-mesh attributes
        (``volume_mesh``, ``hausdorff``, ...) are those of the first.

    Raises
    ------
    ValueError
        The reference belongs to another graph, or a label is used twice.
    """
    t0 = time.perf_counter()
    todo: list[tuple[str, Any]] = []
    if mesh is not None:
        todo.append((str(label), mesh))
    for lab, m in (meshes or {}).items():
        if any(lab == t[0] for t in todo):
            raise ValueError(f"mesh label {lab!r} is used twice")
        todo.append((str(lab), m))
    if reference is None:
        reference = build_reference(graph, **reference_options)
    elif reference.graph != graph:
        raise ValueError("the reference was built for another graph")
    timings: dict[str, float] = {"reference": time.perf_counter() - t0}
    vols, tris, valid, secs = {}, {}, {}, {}
    scope, vu = "lattice", reference.volume
    sample = None
    if union_hubs is not None and union_segments:
        if int(union_hubs) < 1:
            raise ValueError(f"union_hubs must be >= 1 or None, got {union_hubs!r}")
        sample = union_sample(reference, int(union_hubs), seed)
        vu = float(np.sum(reference.hub_volume[sample]))
        n_all = int(np.isfinite(reference.hub_volume).sum())
        scope = (
            f"{len(sample)} of {n_all} hubs (seeded sample; each hub's sphere and "
            "half-struts, against the sum of their exact volumes)"
        )
    for n in union_segments:
        t = time.perf_counter()
        if sample is None:
            um = union_mesh(graph, int(n))
            vols[int(n)] = um.volume
            tris[int(n)] = int(len(um.faces))
            valid[int(n)] = mesh_validity(um)["valid"]
        else:
            vols[int(n)], tris[int(n)], valid[int(n)] = hub_union(graph, sample, int(n))
        secs[int(n)] = time.perf_counter() - t
    timings["unions"] = float(sum(secs.values()))
    order = _fit_order(vols, vu) if reference.complete else None
    zones = None
    if hub_zone_factor is not None:
        from reference_boolean.regions import hub_zones

        zones = hub_zones(graph, factor=float(hub_zone_factor))
    t = time.perf_counter()
    as_mesh = [
        Mesh(
            vertices=np.asarray(m.vertices, dtype=np.float64),
            faces=np.asarray(m.faces, dtype=np.int64),
        )
        for _, m in todo
    ]
    tv = 0.0

    def validity() -> None:  # cached for the report's files (it used to run after this)
        nonlocal tv
        t1 = time.perf_counter()
        reference_validity(reference)
        tv = time.perf_counter() - t1

    devs = two_sided_deviations(
        as_mesh, reference.mesh, samples=samples, seed=seed, while_waiting=validity
    )
    # the validity check ran within the deviation's wall time (overlapped with the child;
    # 0 when the deviation ran in this process alone)
    timings["reference_validity"] = tv
    share = (time.perf_counter() - t) / max(len(todo), 1)  # each mesh's share of the time
    shared: dict[str, Any] = {}
    comps = {
        lab: _measure(
            graph,
            reference,
            m,
            lab,
            samples,
            seed,
            zones,
            deviation=dev,
            deviation_seconds=share,
            shared=shared,
        )
        for (lab, _), m, dev in zip(todo, as_mesh, devs, strict=True)
    }
    if comps:
        timings["mesh_checks"] = sum(c.timings["mesh_checks"] for c in comps.values())
        timings["deviation"] = sum(c.timings["deviation"] for c in comps.values())
    timings["total"] = time.perf_counter() - t0
    if not math.isfinite(timings["total"]):  # pragma: no cover
        timings["total"] = 0.0
    first = next(iter(comps.values()), None)
    return ValidationReport(
        graph=graph,
        reference=reference,
        volume_union=vols,
        union_triangles=tris,
        union_valid=valid,
        union_seconds=secs,
        convergence_order=order,
        mesh=None if first is None else first.mesh,
        volume_mesh=None if first is None else first.volume,
        mesh_valid=None if first is None else first.valid,
        hausdorff={} if first is None else first.hausdorff,
        node_deviation=(
            np.full(graph.num_nodes, np.nan) if first is None else first.node_deviation
        ),
        distances={} if first is None else first.distances,
        timings=timings,
        label=label if first is None else first.label,
        comparisons=comps,
        union_scope=scope,
        union_reference_volume=None if sample is None else vu,
        hub_zone=zones,
        hub_zone_factor=None if zones is None else float(hub_zone_factor),  # type: ignore[arg-type]
    )
