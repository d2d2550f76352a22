"""Independent validity checker for triangle meshes.

:func:`check` inspects a triangle mesh (a :class:`fast_stitch.Mesh`, a
``trimesh.Trimesh``, or a ``(vertices, faces)`` tuple) and returns a
:class:`CheckReport`: boundary / non-manifold / inconsistently oriented edges,
non-manifold vertices, zero-area faces, components, signed volume and
self-intersecting face pairs.

It shares only its geometric predicates with the stitchers: the exact
triangle/triangle test (with the exact orientation signs below it) and the
bounding box of a set of boxes, in :mod:`fast_stitch._predicates`, which the
stitchers use for their clearance checks. Everything else (topology,
components, orientation, degenerate faces, the broadphase, the tests of faces
sharing a vertex or an edge) is the checker's own, so it can be used to test
the stitchers. A bug in the shared predicates could hide in both; the test
suite guards against it with independent checkers (trimesh, manifold3d and
pymeshlab: ``independent_check`` and ``assert_valid`` in ``tests/conftest.py``).

Topology is purely index based: two faces share a vertex only if they use the
same vertex *index*; coincident vertices with different indices are distinct
(so an unmerged STL "soup" has only boundary edges, and two bodies that touch
through coincident but distinct vertices are reported as self-intersecting).

Self-intersections
------------------
Two faces intersect when the closed triangles meet anywhere except in what
they share by index:

* no common vertex: they intersect if they meet at all (touching counts);
* one common vertex: if they meet anywhere other than that vertex;
* a common edge: if they overlap, i.e. are folded onto each other (see below);
* three common vertices (a duplicated face): always.

Except for the common-edge case, the decisions are exact for the float64
coordinates: they only use the signs of orientation determinants, evaluated
with a floating-point filter and an exact (expansion arithmetic) fallback, so
there are neither false positives nor false negatives from rounding.

Faces sharing an edge meet only along it unless they are coplanar and on the
same side of it. That is decided with a tolerance
``tol = coplanar_rtol * scale``, where ``scale`` is the largest absolute
coordinate (or the bounding-box diagonal if larger): the pair is reported
when the two apexes are on the same side of the shared edge and the lower
apex lies within ``tol`` of the other face's plane (a fold of almost zero
dihedral angle). Flat continuations (apexes on opposite sides) are never
reported, however close to coplanar, and neither is a face whose apex lies
within ``tol`` of the shared edge's line (a sliver along the edge; it cannot
overlap its neighbour by more than ``tol``).

Degenerate faces (a repeated vertex index, or three exactly collinear points)
take no part in the self-intersection test; they are reported as zero-area.

Candidate pairs come from a hashed uniform grid over the faces sorted in
Morton order; long faces are cut into pieces along their longest axis so that
thin diagonal faces (lattice struts, slivers) only occupy the cells they cross.
Pairs whose bounding boxes only touch along an axis-aligned plane, faces that
are certainly on one side of each other's plane and nearly coplanar faces
separated in 2D are settled without exact arithmetic; the rest go to the
Guigue-Devillers test with exact signs. Everything runs in numba kernels, in
parallel over faces, with results independent of the number of threads.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numba.core.errors import NumbaWarning
from numpy.typing import NDArray

from fast_stitch import _check_kernels as _k
from fast_stitch._predicates import box_stats
from lattice_cad.core.arrays import read_only

__all__ = ["check", "CheckReport", "crossing_pairs"]

#: Bound on the grid entries per face; the cell grows when it would be exceeded.
_MAX_ENTRIES_PER_FACE = 8
#: Mean grid entries per face aimed at when choosing the cell size (on a sample).
_TARGET_ENTRIES_PER_FACE = 5.0
#: Maximum number of pieces a long face is cut into for the broadphase.
_MAX_PIECES = 256

#: Budget of (query, face) solid-angle evaluations for the cavity test of inverted shells
#: whose ray test (``_ray_winding``) is not certain, or of any inverted shell when a
#: component is open; past it, the rest count as inverted.
_WINDING_BUDGET = 200_000_000
#: Barycentric weights of the points of a shell's flattest face (largest seen from above)
#: from which the ray test is tried, in turn, until it is certain (its centroid first).
_RAY_QUERY_WEIGHTS = (
    np.full(3, 1.0 / 3.0),
    np.array([0.5, 0.3, 0.2]),
    np.array([0.2, 0.17, 0.63]),
)


@dataclass(frozen=True, eq=False)
class CheckReport:
    """Result of :func:`check`.

    Example arrays hold at most ``max_report`` rows, in increasing index order
    (edges by their vertex pair); the ``n_*`` counts are always complete.

    Attributes
    ----------
    n_vertices, n_faces : int
        Sizes of the input.
    n_edges : int
        Distinct undirected edges (vertex index pairs; self-loops of degenerate faces
        are not edges).
    n_unused_vertices : int
        Vertices used by no face.
    n_boundary_edges : int
        Edges used by exactly one face.
    n_nonmanifold_edges : int
        Edges used by more than two faces.
    n_inconsistent_edges : int
        Edges used by two faces that traverse them in the same direction.
    n_nonmanifold_vertices : int
        Vertices whose incident faces form more than one fan (faces linked across edges
        at the vertex, including non-manifold edges). Only meaningful when the edges are
        manifold.
    n_zero_area : int
        Faces with area ``<= area_tol`` (float64 cross product), a repeated vertex index,
        or three exactly collinear vertices (exact test: the float area of such a face may
        be a small rounding artefact).
    n_self_intersections : int or None
        Intersecting face pairs (see the module docstring); None if not computed.
    n_self_intersecting_faces : int or None
        Faces involved in at least one intersecting pair; None if not computed.
    volume : float
        Signed volume (divergence theorem; positive for an outward-oriented closed mesh).
        For an open mesh it depends on the reference point, the centre of the bounding
        box of the used vertices.
    euler_characteristic : int
        ``V_used - E + F``.
    n_components : int
        Connected components of faces linked across shared edges.
    n_inverted_components : int
        Closed components (without boundary edges) with negative volume that are not
        cavities, i.e. not enclosed by the rest of the mesh: the winding number of the
        other components at a point of the component is at most 0. It is counted exactly
        by the crossings of a ray along +z from a point of the component's flattest face;
        where the ray meets an edge, a vertex or a plane, and in meshes with an open
        component, the generalized winding number (solid angles) at the centroid of its
        largest face, below 0.5, within a budget of evaluations past which the rest
        count. (Open components have no meaningful orientation and are never counted.)
    unused_vertices : (K,) int64
    boundary_edges : (K, 3) int64
        Rows ``(v0, v1, face)``: edge ``v0 < v1`` and the lowest face using it.
    nonmanifold_edges : (K, 3) int64
        Same layout.
    inconsistent_edges : (K, 3) int64
        Same layout.
    nonmanifold_vertices : (K,) int64
    zero_area_faces : (K,) int64
    self_intersection_pairs : (K, 2) int64
        Lexicographically smallest intersecting pairs ``(f0, f1)``, ``f0 < f1``.
    inverted_component_faces : (K,) int64
        One face (the lowest) of each inverted component.
    """

    n_vertices: int
    n_faces: int
    n_edges: int
    n_unused_vertices: int
    n_boundary_edges: int
    n_nonmanifold_edges: int
    n_inconsistent_edges: int
    n_nonmanifold_vertices: int
    n_zero_area: int
    n_self_intersections: int | None
    n_self_intersecting_faces: int | None
    volume: float
    euler_characteristic: int
    n_components: int
    n_inverted_components: int
    unused_vertices: NDArray[np.int64]
    boundary_edges: NDArray[np.int64]
    nonmanifold_edges: NDArray[np.int64]
    inconsistent_edges: NDArray[np.int64]
    nonmanifold_vertices: NDArray[np.int64]
    zero_area_faces: NDArray[np.int64]
    self_intersection_pairs: NDArray[np.int64]
    inverted_component_faces: NDArray[np.int64]

    # ---------------------------------------------------------------- derived
    @property
    def watertight(self) -> bool:
        """No boundary edges and no non-manifold edges."""
        return self.n_boundary_edges == 0 and self.n_nonmanifold_edges == 0

    @property
    def manifold(self) -> bool:
        """No non-manifold edges and no non-manifold vertices."""
        return self.n_nonmanifold_edges == 0 and self.n_nonmanifold_vertices == 0

    @property
    def oriented(self) -> bool:
        """No edge traversed twice in the same direction."""
        return self.n_inconsistent_edges == 0

    @property
    def outward(self) -> bool:
        """Positive total volume and no inverted component (cavities may be negative)."""
        return self.volume > 0.0 and self.n_inverted_components == 0

    @property
    def valid(self) -> bool:
        """Watertight, manifold, oriented, outward, no zero-area face, no self-intersection.

        Self-intersections are ignored when they were not computed.
        """
        return (
            self.watertight
            and self.manifold
            and self.oriented
            and self.outward
            and self.n_zero_area == 0
            and not self.n_self_intersections
        )

    # ---------------------------------------------------------------- output
    def problems(self) -> list[str]:
        """One human-readable line per kind of problem found (empty if none)."""
        lines = []

        def count(n: int | None, noun: str, plural: str = "") -> str:
            return f"{n} {noun if n == 1 else (plural or noun + 's')}"

        def edges(arr: NDArray[np.int64]) -> str:
            ex = ", ".join(f"{a}-{b} (face {f})" for a, b, f in arr[:3].tolist())
            return f" (e.g. edge {ex})" if ex else ""

        def items(arr: NDArray[np.int64], what: str) -> str:
            ex = ", ".join(str(x) for x in arr[:5].tolist())
            return f" (e.g. {what} {ex})" if ex else ""

        if self.n_boundary_edges:
            lines.append(
                f"{count(self.n_boundary_edges, 'boundary edge')}{edges(self.boundary_edges)}"
            )
        if self.n_nonmanifold_edges:
            lines.append(
                f"{count(self.n_nonmanifold_edges, 'non-manifold edge')} (used by > 2 faces)"
                f"{edges(self.nonmanifold_edges)}"
            )
        if self.n_inconsistent_edges:
            lines.append(
                f"{count(self.n_inconsistent_edges, 'inconsistently oriented edge')}"
                f"{edges(self.inconsistent_edges)}"
            )
        if self.n_nonmanifold_vertices:
            nm = count(self.n_nonmanifold_vertices, "non-manifold vertex", "non-manifold vertices")
            lines.append(f"{nm}{items(self.nonmanifold_vertices, 'vertex')}")
        if self.n_zero_area:
            lines.append(
                f"{count(self.n_zero_area, 'zero-area face')}{items(self.zero_area_faces, 'face')}"
            )
        if self.n_self_intersections:
            ex = ", ".join(f"{a}/{b}" for a, b in self.self_intersection_pairs[:3].tolist())
            ex = f" (e.g. faces {ex})" if ex else ""
            lines.append(
                f"{count(self.n_self_intersections, 'self-intersecting face pair')} "
                f"({count(self.n_self_intersecting_faces, 'face')}){ex}"
            )
        if self.n_inverted_components:
            lines.append(
                f"{count(self.n_inverted_components, 'inside-out component')}"
                f"{items(self.inverted_component_faces, 'the one with face')}"
            )
        if self.volume <= 0.0:
            lines.append(f"total volume {self.volume:.6g} is not positive")
        return lines

    def __str__(self) -> str:
        si = (
            "self-intersections not checked"
            if self.n_self_intersections is None
            else "self-intersections checked"
        )
        head = (
            f"{self.n_faces} faces, {self.n_vertices} vertices, {self.n_edges} edges, "
            f"{self.n_components} component{'s' if self.n_components != 1 else ''}, "
            f"volume {self.volume:.6g}, Euler characteristic {self.euler_characteristic} "
            f"({si}): {'valid' if self.valid else 'INVALID'}"
        )
        lines = [head] + [f"  - {p}" for p in self.problems()]
        if self.n_unused_vertices:
            lines.append(f"  note: {self.n_unused_vertices} unused vertices")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary: every field (arrays as lists) plus the derived flags."""
        out: dict[str, Any] = {}
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                out[name] = value.tolist()
            elif value is None or isinstance(value, (bool, str)):
                out[name] = value
            elif isinstance(value, (int, np.integer)):
                out[name] = int(value)
            else:
                out[name] = float(value)
        for name in ("watertight", "manifold", "oriented", "outward", "valid"):
            out[name] = bool(getattr(self, name))
        return out


# ------------------------------------------------------------------------- input


def _as_arrays(mesh: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Validate and coerce the input to ``(V, 3) float64`` C-contiguous and ``(F, 3) int64``."""
    if isinstance(mesh, (tuple, list)):
        if len(mesh) != 2:
            raise ValueError(f"expected a (vertices, faces) pair, got a sequence of {len(mesh)}")
        vertices, faces = mesh
    elif hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices, faces = mesh.vertices, mesh.faces
    else:
        raise TypeError(
            "mesh must have .vertices and .faces or be a (vertices, faces) tuple, "
            f"got {type(mesh).__name__}"
        )
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.size == 0 and v.ndim <= 2:
        v = v.reshape(0, 3)
    if f.size == 0 and f.ndim <= 2:
        f = f.reshape(0, 3)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must have shape (F, 3), got {f.shape}")
    if not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer)):
        raise ValueError(f"vertices must be numeric, got dtype {v.dtype}")
    if not np.issubdtype(f.dtype, np.integer):
        if f.dtype == np.bool_ or not np.issubdtype(f.dtype, np.floating):
            raise ValueError(f"faces must be integer indices, got dtype {f.dtype}")
        bad = ~np.all(np.isfinite(f) & (f == np.round(f)), axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"face {i} has non-integer vertex indices {f[i].tolist()}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    if f.dtype == np.uint64 and f.size and f.max() > np.iinfo(np.int64).max:
        i = int(np.flatnonzero((f > np.iinfo(np.int64).max).any(axis=1))[0])
        raise ValueError(f"face {i} references vertex {f[i].max()} (out of range)")
    f = np.ascontiguousarray(f, dtype=np.int64)
    nv = v.shape[0]
    bad = ((f < 0) | (f >= nv)).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"face {i} references vertex indices {f[i].tolist()}, but there are {nv} vertices"
        )
    finite = np.isfinite(v).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"vertex {i} has non-finite coordinates {v[i].tolist()}")
    return read_only(v), read_only(f)  # one kernel version for writable and read-only


def _start_threads() -> None:
    """Start numba's thread pool, silencing its warning about an unusable TBB.

    When a library bundling an old TBB (e.g. pymeshlab) is loaded first, numba warns
    that it falls back to another threading layer; that is harmless but fatal under
    ``-W error``. ``numba.get_num_threads`` starts the pool (once per process).
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="(?s).*TBB", category=NumbaWarning)
        numba.get_num_threads()


def _readonly(a: NDArray[Any]) -> NDArray[Any]:
    a = np.ascontiguousarray(a, dtype=np.int64)
    a.setflags(write=False)
    return a


# ------------------------------------------------------------------------- helpers


def _component_volumes(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    labels: NDArray[np.int64],
    vol: NDArray[np.float64],
    center: NDArray[np.float64],
    n_comp: int,
) -> NDArray[np.float64]:
    """(C,) float64 signed volume of each component, its sign certain (scale-aware).

    The float sum of the faces' volume terms is used when it exceeds its rounding-error
    bound (the terms' permanents times ``(8 + n) eps``, n faces summed); thinner
    components (a strut of radius 1e-9 and length 1 cancels below it) are summed again in
    double-double arithmetic, whose error is about 1e-16 of the float bound.
    """
    comp_volume = np.bincount(labels, weights=vol, minlength=n_comp).astype(np.float64)
    if faces.shape[0] == 0:
        return comp_volume
    perm = _k.volume_permanents(vertices, faces, center)
    comp_perm = np.bincount(labels, weights=perm, minlength=n_comp)
    comp_faces = np.bincount(labels, minlength=n_comp)
    bound = comp_perm * (8.0 + comp_faces) * 2.0**-52
    unsure = np.abs(comp_volume) <= bound
    if unsure.any():
        exact = _k.component_volumes_dd(vertices, faces, labels, center, unsure)
        comp_volume = np.where(unsure, exact, comp_volume)
    return comp_volume


def _inverted_components(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    labels: NDArray[np.int64],
    area: NDArray[np.float64],
    comp_volume: NDArray[np.float64],
    open_components: NDArray[np.bool_],
) -> NDArray[np.int64]:
    """Closed components (sorted ids) with negative volume that are not enclosed cavities.

    vertices : (V, 3) float64, faces : (F, 3) int64, labels : (F,) int64 component of
    each face, area : (F,) float64, comp_volume : (C,) float64, open_components : (C,) bool.
    """
    n_components = comp_volume.shape[0]
    negative = np.flatnonzero((comp_volume < 0.0) & ~open_components)
    if negative.size == 0 or n_components == 1:
        return negative.astype(np.int64)
    inverted = np.zeros(0, np.int64)
    if not open_components.any():
        # every shell closed: each negative one's winding number counted along a ray
        # (exact; a ray that meets an edge or a plane is left to the solid angles below)
        # (from the centroid of the shell's face that is largest seen from above, then from
        # two other points of it: a face seen edge-on would put the ray in other planes)
        wanted = np.zeros(n_components, np.bool_)
        wanted[negative] = True
        flat = _k.flattest_faces(vertices, faces, labels, wanted)
        corners = vertices[faces[flat[negative]]]
        for weights in _RAY_QUERY_WEIGHTS:
            queries = np.ascontiguousarray(np.einsum("k,qkd->qd", weights, corners))
            w, unsure = _ray_winding(vertices, faces, labels, queries, negative)
            inverted = np.concatenate([inverted, negative[~unsure & (w <= 0)]])
            negative, corners = negative[unsure], corners[unsure]
            if negative.size == 0:
                return np.sort(inverted).astype(np.int64)
    # Test the largest shells first, within a fixed budget; the rest count as inverted.
    by_size = negative[np.argsort(comp_volume[negative], kind="stable")]
    n_test = min(by_size.size, max(1, _WINDING_BUDGET // max(1, faces.shape[0])))
    tested = by_size[:n_test]
    rep = _k.component_rep_faces(labels, area, n_components)[tested]
    queries = np.ascontiguousarray(vertices[faces[rep]].mean(axis=1))
    w = _k.winding_numbers(vertices, faces, labels, queries, np.ascontiguousarray(tested))
    inverted = np.concatenate([inverted, tested[w < 0.5], by_size[n_test:]])
    return np.sort(inverted).astype(np.int64)


def crossing_pairs(mesh: Any, pairs: Any) -> NDArray[np.bool_]:
    """Which intersecting face pairs pass through each other (each face has corners strictly
    on both sides of the other's plane; exact signs), as opposed to pairs that only touch:
    along an edge or at a vertex, or coplanar. Bodies that touch (blocks sharing an edge)
    give touching pairs; a surface that folds through itself gives crossing ones.

    Parameters
    ----------
    mesh : Mesh, trimesh.Trimesh or tuple
        As for :func:`check`.
    pairs : (P, 2) int
        Face index pairs, e.g. ``CheckReport.self_intersection_pairs``.

    Returns
    -------
    crossing : (P,) bool
    """
    vertices, faces = _as_arrays(mesh)
    pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
    if len(pairs) and (pairs.min() < 0 or pairs.max() >= len(faces)):
        raise ValueError(f"pairs name faces outside 0 .. {len(faces) - 1}")
    return _k.straddling_pairs(vertices, faces, pairs)


def _ray_winding(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    labels: NDArray[np.int64],
    queries: NDArray[np.float64],
    query_labels: NDArray[np.int64],
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Winding number of the faces not in ``query_labels[q]`` at ``queries[q]``, by the
    exact crossings of a ray along +z (``_k.ray_winding_numbers``).

    vertices : (V, 3) float64, faces : (F, 3) int64, labels : (F,) int64, queries : (Q, 3)
    float64, query_labels : (Q,) int64. Returns ``w : (Q,) int64`` and ``unsure : (Q,)
    bool`` (the ray met an edge, a vertex or a face's plane at the query: ``w`` not valid).
    The queries are binned on an xy grid of about ``Q`` cells, each face visits the cells
    its xy box covers: about ``F`` face visits instead of the ``F Q`` solid angles.
    """
    nq = queries.shape[0]
    if query_labels.shape != (nq,) or queries.shape != (nq, 3):
        raise ValueError("queries must be (Q, 3) with (Q,) query_labels")
    lo = queries[:, :2].min(axis=0)
    hi = queries[:, :2].max(axis=0)
    ext = hi - lo
    # about Q cells: square ones over a box, Q along a line, one for a single point (and
    # never more than 4 Q + 4: a box much longer than wide gets cells as long as needed)
    h = math.sqrt(float(ext[0] * ext[1]) / nq) or float(ext.max()) / nq or 1.0
    h = max(h, float(ext.max()) / (4 * nq))
    n = np.floor(ext / h).astype(np.int64) + 1
    ij = np.minimum(np.floor((queries[:, :2] - lo) / h).astype(np.int64), n - 1)
    cell = ij[:, 0] * n[1] + ij[:, 1]
    order = np.argsort(cell, kind="stable").astype(np.int64)
    cell_start = np.zeros(int(n[0] * n[1]) + 1, np.int64)
    np.cumsum(np.bincount(cell, minlength=int(n[0] * n[1])), out=cell_start[1:])
    grid = np.array([lo[0], lo[1], h, n[0], n[1]], np.float64)
    points = np.ascontiguousarray(np.vstack([vertices, queries]))
    return _k.ray_winding_numbers(
        points,
        faces,
        labels,
        vertices.shape[0],
        np.ascontiguousarray(query_labels, dtype=np.int64),
        grid,
        cell_start,
        order,
    )


def _self_intersections(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    boxes: NDArray[np.float64],
    active: NDArray[np.bool_],
    tol: float,
    scale: float,
    max_report: int,
) -> tuple[int, int, NDArray[np.int64]]:
    """Count intersecting pairs and faces, and collect the first ``max_report`` pairs.

    vertices : (V, 3) float64, faces : (F, 3) int64, boxes : (F, 6) float64,
    active : (F,) bool (the non-degenerate faces), tol: fold tolerance, scale: coordinate
    scale (largest absolute coordinate or more). Returns the number of pairs, the
    number of faces involved and the lexicographically smallest pairs, (K, 2) int64.
    """
    empty = np.zeros((0, 2), np.int64)
    n = int(np.count_nonzero(active))
    if n < 2:
        return 0, 0, empty
    # Work on a spatially sorted copy (Morton order of the boxes, vertices renumbered in
    # order of first use): the grid scan is then cache friendly whatever the input order.
    lo, hi = box_stats(boxes[:, :3], boxes[:, 3:], active)
    extent = float((hi - lo).max())
    scale = (2.0**21 - 1.0) / extent if extent > 0.0 else 0.0
    keys = _k.morton_keys(boxes, active, lo, scale)
    perm = np.argsort(keys, kind="stable")[:n]
    sub_faces, sub_boxes = _k.gather_faces(faces, boxes, perm)
    sub_faces, vmap = _k.renumber_vertices(sub_faces, vertices.shape[0])
    sub_vertices = _k.gather_vertices(vertices, vmap)

    # Cell size: 1.5 x the median largest extent of the boxes (long faces are cut into
    # pieces, see _check_kernels). A strided sample keeps it cheap.
    sample = sub_boxes[:: max(1, n // 65536)]
    h = 1.5 * float(np.median((sample[:, 3:] - sample[:, :3]).max(axis=1)))
    if not h > 0.0:
        h = extent if extent > 0.0 else 1.0
    h = max(h, extent * 2.0**-40)  # keeps cell coordinates far from int64 overflow
    margin = 1e-13 * max(scale, extent)  # >> rounding of the pieces' boxes
    limit = _MAX_ENTRIES_PER_FACE * n + 1024
    n_buckets = 1 << max(6, int(limit // 4).bit_length())  # about 4 entries per bucket
    no_offsets = np.zeros(0, np.int64)
    no_buckets = np.zeros(0, np.int32)

    def entry_counts(fc: NDArray[np.int64], bx: NDArray[np.float64]) -> NDArray[np.int64]:
        return _k.grid_face_buckets(
            sub_vertices, fc, bx, lo, h, _MAX_PIECES, margin, n_buckets, no_offsets, no_buckets
        )

    # Grow the cell while a sample of the faces has too many entries per face ...
    step = max(1, n // 20000)
    sample_faces = np.ascontiguousarray(sub_faces[::step])
    sample_boxes = np.ascontiguousarray(sub_boxes[::step])
    while entry_counts(sample_faces, sample_boxes).mean() > _TARGET_ENTRIES_PER_FACE:
        h *= 1.25
    # ... and while all of them have more than the hard limit.
    while True:
        counts = entry_counts(sub_faces, sub_boxes)
        if int(counts.sum()) <= limit:
            break
        h *= 1.5
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    face_buckets = np.empty(int(offsets[-1]), np.int32)
    bucket_counts = _k.grid_face_buckets(
        sub_vertices, sub_faces, sub_boxes, lo, h, _MAX_PIECES, margin, n_buckets,
        offsets, face_buckets,
    )  # fmt: skip
    bucket_start, entries = _k.grid_fill(face_buckets, offsets, bucket_counts, n_buckets)

    def run(mode: int, max_first: int, prev: NDArray[np.int64], pair_offsets: NDArray[np.int64],
            hit: NDArray[np.uint8], pairs: NDArray[np.int64]) -> NDArray[np.int64]:  # fmt: skip
        return _k.grid_pairs(
            sub_vertices, sub_faces, sub_boxes, face_buckets, offsets, bucket_counts,
            bucket_start, entries, tol, mode, perm, max_first, prev, pair_offsets, hit, pairs,
        )  # fmt: skip

    none_i = np.zeros(0, np.int64)
    hit = np.zeros(n, np.uint8)
    counts = run(0, 0, none_i, none_i, hit, empty)
    n_pairs = int(counts.sum())
    n_faces_hit = int(hit.sum(dtype=np.int64))
    if n_pairs == 0 or max_report == 0:
        return n_pairs, n_faces_hit, empty
    # The max_report smallest pairs (in the original numbering) start at or below the
    # (2 * max_report)-th involved face: at least max_report pairs start there or below.
    hit_orig = np.sort(perm[hit.astype(bool)])
    max_first = int(hit_orig[min(hit_orig.size, 2 * max_report) - 1])
    sel = run(1, max_first, counts, none_i, hit, empty)
    pair_offsets = np.zeros(n + 1, np.int64)
    np.cumsum(sel, out=pair_offsets[1:])
    pairs = np.empty((int(pair_offsets[-1]), 2), np.int64)
    run(2, max_first, sel, pair_offsets, hit, pairs)
    pairs = np.sort(perm[pairs], axis=1)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))[:max_report]
    return n_pairs, n_faces_hit, pairs[order]


# ------------------------------------------------------------------------- API


def check(
    mesh: Any,
    *,
    self_intersections: bool = True,
    area_tol: float = 0.0,
    max_report: int = 100,
    coplanar_rtol: float = 1e-12,
) -> CheckReport:
    """Check a triangle mesh for the defects that make it an invalid solid.

    Parameters
    ----------
    mesh : Mesh, trimesh.Trimesh or tuple
        Anything with ``.vertices`` ``(V, 3)`` and ``.faces`` ``(F, 3)``, or a
        ``(vertices, faces)`` tuple: ``vertices : (V, 3) float``, ``faces : (F, 3) int``.
    self_intersections : bool
        Look for intersecting face pairs (the expensive part). When False the report's
        ``n_self_intersections`` is None and :attr:`CheckReport.valid` ignores it.
    area_tol : float
        Faces with area ``<= area_tol`` are zero-area (0: exactly zero float64 area).
    max_report : int
        Maximum number of examples kept per kind of problem.
    coplanar_rtol : float
        Relative fold tolerance for faces sharing an edge: multiplied by the coordinate
        scale (largest absolute coordinate or bounding-box diagonal, whichever is larger).
        See the module docstring.

    Returns
    -------
    CheckReport

    Raises
    ------
    ValueError
        Wrong array shapes or dtypes, a face index out of range (the message names the
        face), non-finite coordinates (names the vertex), or bad options.
    TypeError
        ``mesh`` is neither a mesh object nor a ``(vertices, faces)`` tuple.
    """
    if not (isinstance(area_tol, (int, float)) and math.isfinite(area_tol) and area_tol >= 0):
        raise ValueError(f"area_tol must be a finite number >= 0, got {area_tol!r}")
    if isinstance(max_report, bool) or not isinstance(max_report, (int, np.integer)):
        raise ValueError(f"max_report must be an int >= 0, got {max_report!r}")
    if max_report < 0:
        raise ValueError(f"max_report must be >= 0, got {max_report}")
    if not (math.isfinite(coplanar_rtol) and coplanar_rtol >= 0):
        raise ValueError(f"coplanar_rtol must be a finite number >= 0, got {coplanar_rtol!r}")
    max_report = int(max_report)
    vertices, faces = _as_arrays(mesh)
    _start_threads()
    nv, nf = vertices.shape[0], faces.shape[0]

    (counts, boundary, nonmanifold, inconsistent, nm_vertices, unused, labels, used, open_comp) = (
        _k.edge_topology(faces, nv, max_report)
    )
    n_edges, n_boundary, n_nm_edges, n_inconsistent, n_nm_vertices, n_unused, n_comp = (
        int(x) for x in counts
    )

    if nf:
        lo, hi, max_abs = _k.vertex_stats(vertices, used)
        center = 0.5 * (lo + hi)
        scale = max(float(max_abs), float(np.linalg.norm(hi - lo)))
    else:
        center = np.zeros(3)
        scale = 0.0
    area, vol, boxes, degenerate = _k.face_geometry(vertices, faces, center)

    zero = (area <= area_tol) | degenerate  # degenerate: repeated index or collinear
    zero_faces = np.flatnonzero(zero)

    comp_volume = _component_volumes(vertices, faces, labels, vol, center, n_comp)
    volume = float(comp_volume.sum())
    inverted = _inverted_components(vertices, faces, labels, area, comp_volume, open_comp)
    if inverted.size:
        first_face = np.full(n_comp, nf, np.int64)
        np.minimum.at(first_face, labels, np.arange(nf))
        inverted_faces = first_face[inverted[:max_report]]
    else:
        inverted_faces = inverted

    if self_intersections:
        n_si, n_si_faces, pairs = _self_intersections(
            vertices, faces, boxes, ~degenerate, coplanar_rtol * scale, scale, max_report
        )
    else:
        n_si, n_si_faces, pairs = None, None, np.zeros((0, 2), np.int64)

    return CheckReport(
        n_vertices=nv,
        n_faces=nf,
        n_edges=n_edges,
        n_unused_vertices=n_unused,
        n_boundary_edges=n_boundary,
        n_nonmanifold_edges=n_nm_edges,
        n_inconsistent_edges=n_inconsistent,
        n_nonmanifold_vertices=n_nm_vertices,
        n_zero_area=int(zero_faces.size),
        n_self_intersections=n_si,
        n_self_intersecting_faces=n_si_faces,
        volume=volume,
        euler_characteristic=(nv - n_unused) - n_edges + nf,
        n_components=n_comp,
        n_inverted_components=int(inverted.size),
        unused_vertices=_readonly(unused),
        boundary_edges=_readonly(boundary.reshape(-1, 3)),
        nonmanifold_edges=_readonly(nonmanifold.reshape(-1, 3)),
        inconsistent_edges=_readonly(inconsistent.reshape(-1, 3)),
        nonmanifold_vertices=_readonly(nm_vertices),
        zero_area_faces=_readonly(zero_faces[:max_report]),
        self_intersection_pairs=_readonly(pairs.reshape(-1, 2)),
        inverted_component_faces=_readonly(inverted_faces),
    )
