"""Parts to fill with lattices: loading STEP files, meshes and CAD shapes.

A :class:`Part` is a closed, outward-oriented triangle mesh of one solid (a
STEP solid is tessellated once with OCCT's BRepMesh), with fast queries:

* :meth:`Part.contains` / :meth:`Part.winding`: winding number along a
  vertical ray with simulation of simplicity (see :mod:`conformal._kernels`):
  exact for points off the surface, whatever their position relative to mesh
  edges and vertices;
* :meth:`Part.distance` / :meth:`Part.closest`: exact distance to the
  triangle mesh (grid ring search). For a STEP part the mesh deviates from the
  true surface by at most the tessellation ``deflection`` (default 1e-3 of the
  bounding-box diagonal), which bounds the error of every query.

Lengths are millimetres. STEP files are converted from the unit they declare
(OCCT does this on reading); meshes (STL, OBJ, PLY, 3MF, OFF) carry no unit
and are taken as millimetres unless ``units=`` says otherwise.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from conformal import _kernels
from lattice_cad.core import config
from lattice_cad.core.arrays import edge_uses, point_text, unique_rows
from lattice_cad.core.errors import LatticeWarning, MissingFileError, OCCTFailure, PartError

__all__ = ["Part", "PartError", "load_part", "UNITS"]

#: Millimetres per unit, for ``load_part(..., units=...)``.
UNITS: dict[str, float] = {
    "mm": 1.0,
    "cm": 10.0,
    "m": 1000.0,
    "um": 1e-3,
    "in": 25.4,
    "inch": 25.4,
    "ft": 304.8,
}

_STEP_SUFFIXES = {".step", ".stp"}
_MESH_SUFFIXES = {".stl", ".obj", ".ply", ".3mf", ".off"}

#: A solid whose tessellation does not close (healed or not) is tessellated again, healed
#: or not, at this times the chord error (``_closed_tessellation``) before it is refused.
FINER_TRY = 0.25

#: :meth:`Part.deepest_point` climbs from the grid's 64 deepest points, and from about this
#: many inside points spread over the part where one of them is deeper than that.
DEPTH_SPREAD = 4096


class Part:
    """A closed solid as an outward-oriented triangle mesh, with inside and distance queries.

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices in millimetres.
    faces : (F, 3) int64
        Triangles, outward oriented, forming a closed 2-manifold surface.
    name : str
        Where the part came from (used in messages).
    shape : OCP TopoDS_Shape, optional
        The exact B-rep, when the part came from CAD (used by the tet mesher).
    deflection : float
        Largest distance between the mesh and the exact surface (0 for meshes).

    Use :func:`load_part` rather than this constructor: it checks the input.
    """

    def __init__(
        self,
        vertices: ArrayLike,
        faces: ArrayLike,
        *,
        name: str = "part",
        shape: Any = None,
        deflection: float = 0.0,
    ) -> None:
        v = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
        f = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
        v.flags.writeable = False
        f.flags.writeable = False
        self.vertices: NDArray[np.float64] = v
        self.faces: NDArray[np.int64] = f
        self.name = name
        self.shape = shape
        self.deflection = float(deflection)
        #: The part this one is a finer tessellation of (:meth:`refined`; same B-rep), or None.
        self.unrefined: Part | None = None
        #: For :meth:`refined` parts: the largest deviation (mm) of a triangle centroid or
        #: edge midpoint from the exact surface, measured after refining the faces BRepMesh
        #: meshed too coarsely; and how many faces still exceed ``CHORD_CONTROL *
        #: deflection``. None / 0 when not measured.
        self.chord_error: float | None = None
        self.chord_unresolved = 0
        #: For a surface rebuilt from a part whose surface folds over itself
        #: (``conformal.unfold.rebuilt_part``): the grid spacing (mm); else 0.
        self.rebuilt = 0.0
        #: For B-rep parts as loaded (``load_part``): an upper bound (mm) on the distance
        #: of their triangle centroids and edge midpoints from the exact surface
        #: (``|S(u, v) - p|`` at the triangles' parameters, no projection), measured right
        #: after tessellating. None when not measured.
        self.chord_bound: float | None = None
        #: For B-rep parts: per solid, the triangles of each face (TopExp order) at
        #: ``deflection`` and the power of ``1 / chord error`` they grow at most as
        #: (``occ_impl.shapes.triangle_growth``), for :meth:`triangles_at`; else None.
        self.face_triangles: list[tuple[NDArray[np.int64], NDArray[np.float64]]] | None = None
        #: Whether the patches of closed holes cross the surface (said by ``load_part``).
        self._patch_crossings = False
        #: (3,) float64: the translation ``load_part(..., move_to_origin=True)`` applied to
        #: the file's coordinates (zero when the part is where its file or shape put it).
        self.moved_by: NDArray[np.float64] = np.zeros(3)
        #: True for a part read from a mesh file that stores no unit (STL, OBJ, PLY, OFF)
        #: without ``units=``: its numbers were taken as millimetres.
        self.unit_assumed = False
        #: For B-rep parts whose solids touched or overlapped: the solids OCCT's fuse made
        #: of them, which are tessellated (``shape`` keeps the solids as given: the faces a
        #: keep zone's selector counts, the offsets' and the tet mesher's input); else None.
        self.united: list[Any] | None = None

    def __repr__(self) -> str:
        size = " x ".join(f"{s:.4g}" for s in self.size)
        return f"Part({self.name!r}, {len(self.faces)} triangles, {size} mm)"

    # ----------------------------------------------------------- geometry
    @cached_property
    def triangles(self) -> NDArray[np.float64]:
        """(F, 3, 3) float64: triangle corners."""
        t = np.ascontiguousarray(self.vertices[self.faces])
        t.flags.writeable = False
        return t

    @cached_property
    def boxes(self) -> NDArray[np.float64]:
        """(F, 6) float64: each triangle's bounding box, min corner then max corner."""
        b = _kernels.triangle_boxes(self.triangles)
        b.flags.writeable = False
        return b

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: min and max corner of the bounding box."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def size(self) -> NDArray[np.float64]:
        """(3,) float64: bounding-box extents."""
        b = self.bounds
        return b[1] - b[0]

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        return float(np.linalg.norm(self.size))

    @cached_property
    def volume(self) -> float:
        """Enclosed volume (mm^3) of the mesh."""
        t = self.triangles
        return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)

    @cached_property
    def area(self) -> float:
        """Surface area (mm^2) of the mesh."""
        t = self.triangles
        return float(
            0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
        )

    @cached_property
    def self_crossings(self) -> tuple[int, NDArray[np.float64]]:
        """Where the part's surface crosses itself: ``(pairs, at)``, the number of pairs of
        its triangles that pass through each other (``fast_stitch.check``'s exact test,
        then ``fast_stitch.check.crossing_pairs``) and ``at``, (3,) float64, the centroid
        of the first such pair's first triangle (NaN when none).

        A closed, oriented mesh whose triangles cross bounds no solid: the solid overlaps
        itself (a sweep folding over its path, bodies overlapping in one shell), or two of
        its faces come closer than the tessellation. Inside tests still hold, but a cut to
        the surface (trim, skin, clip, conform, tet) can fail there. Pairs that only touch
        are not counted: solids that touch along an edge or at a point (three blocks made
        outside shared/data) gave 71 such pairs, and their skin, tet and clip fills took
        the path of a folded surface, its rebuild, and stood 27 % r out of the part at the
        contact, one body for three solids. More than ``config.CROSSING_PAIRS_CLASSIFIED``
        pairs are all counted."""
        from fast_stitch.check import check, crossing_pairs

        mesh = (self.vertices, self.faces)
        report = check(mesh, max_report=config.CROSSING_PAIRS_CLASSIFIED)
        pairs = int(report.n_self_intersections or 0)
        if not pairs:
            return 0, np.full(3, np.nan)
        found = report.self_intersection_pairs
        if pairs > len(found):
            return pairs, self.triangles[int(found[0, 0])].mean(axis=0)
        crossing = found[crossing_pairs(mesh, found)]
        if not len(crossing):
            return 0, np.full(3, np.nan)
        return len(crossing), self.triangles[int(crossing[0, 0])].mean(axis=0)

    @cached_property
    def solid_parts(self) -> list[Part]:
        """The part's separate solids, each its outer shell with the walls of the cavities
        it holds (a Part each, with its own vertices; ``[self]`` for one shell).

        A shell inside another solid's cavity is a solid of its own (a ball captive in a
        housing, printed in place): each cavity wall belongs to the smallest shell around
        it (``_cavity_holders``). An inward shell no solid holds belongs to none.
        """
        v, f = self.vertices, self.faces
        comps = _components(f, len(v))
        if len(comps) <= 1:
            return [self]
        shells = [f[c] for c in comps]
        vols = [_mesh_volume(v[fc]) for fc in shells]
        holder = _cavity_holders(v, shells, vols)
        out: list[Part] = []
        for k, fc in enumerate(shells):
            if vols[k] <= 0:
                continue
            walls = [shells[j] for j in range(len(shells)) if holder[j] == k]
            used, local = np.unique(np.vstack([fc, *walls]), return_inverse=True)
            out.append(Part(v[used], local.reshape(-1, 3), name=f"{self.name} (solid {len(out)})"))
        return out or [self]

    @cached_property
    def folds(self) -> bool:
        """Whether the B-rep's surface itself folds over itself, not only its tessellation:
        more than ``config.TRIM_HOPELESS_SHARE`` of its triangles cross another
        (:attr:`self_crossings`), and still so when it is tessellated
        ``config.FOLD_REFINE`` times finer (unchecked BRepMesh). Crossings of chords that
        meet across a thin feature go away as the chord error falls; a fold of the surface
        stays (a cabinet handle swept along a path that loops, made outside shared/data: 21 %
        of its 19,338 triangles at load, 12 % of 61,504 four times finer, 3 % of 411,288 at
        the chord a cut asks). A cut by such a surface bounds no solid, however fine, so
        none is tessellated for it. False for a mesh part (its cut is the cheap one by its
        own triangles, tried and judged by what crosses in it).

        First, OCCT's check of the B-rep for faces that intersect (in a child process, for
        at most ``config.FOLD_CHECK_SECONDS``): when it finds any, the surface folds, and
        the finer tessellation is not made (a CV-joint bellows whose convolutions curve
        tighter than its wall, made outside shared/data: 3 s instead of 33 s)."""
        share = config.TRIM_HOPELESS_SHARE
        if self.shape is None or self.self_crossings[0] <= share * len(self.faces):
            return False
        from lattice_cad.occ_impl import shapes as _occ

        solids = list(self.united if self.united is not None else self.shape)
        found = _occ.self_interfering_isolated(solids, timeout=config.FOLD_CHECK_SECONDS)
        if found:
            return True
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)
            finer = self.refined(self.deflection / config.FOLD_REFINE, checked=False)
        return bool(finer.self_crossings[0] > share * len(finer.faces))

    def crossing_note(self) -> str:
        """A sentence on :attr:`self_crossings` for messages (empty when none)."""
        pairs, at = self.self_crossings
        if not pairs:
            return ""
        return (
            f"the part's surface crosses itself ({pairs} pair(s) of its triangles, e.g. at "
            f"{point_text(at)}): the solid overlaps itself there (a sweep folding over its "
            "path, bodies overlapping in one shell), two of its faces lie closer than its "
            "tessellation, or two of its bodies touch there (face to face or along an edge)"
        )

    def transformed(self, matrix: ArrayLike) -> Part:
        """The part moved by a 4x4 rigid transform (the B-rep is dropped)."""
        m = np.asarray(matrix, dtype=np.float64)
        v = self.vertices @ m[:3, :3].T + m[:3, 3]
        faces = self.faces if np.linalg.det(m[:3, :3]) > 0 else self.faces[:, ::-1]
        return Part(v, faces, name=self.name, deflection=self.deflection)

    def triangles_at(self, deflection: float) -> float | None:
        """How many triangles this B-rep has at most, about, when tessellated with a chord
        error of ``deflection`` (mm): each face's count at :attr:`deflection` times the ratio
        of the chord errors to the power its surface grows as (``face_triangles``); None when
        not known (a mesh part). Measured on the 26 shared parts and 20 others, at the parts
        benchmark's cutting chord error and 4 x it, the total was 0.03 - 1.00 x the count
        BRepMesh gave (a single face: up to 3.1 x, the M6 screw's threaded cone, whose edges
        its neighbours refine)."""
        if self.face_triangles is None or not deflection > 0:
            return None
        ratio = max(1.0, self.deflection / float(deflection))
        return float(sum((n * ratio**g).sum() for n, g in self.face_triangles))

    def refined(self, deflection: float, *, angular: float = 0.3, checked: bool = True) -> Part:
        """The same B-rep tessellated with a chord error of at most ``deflection`` (mm).

        A part without a B-rep (a mesh), or one already tessellated that finely, is
        returned as it is. Results are cached per ``(deflection, angular, checked)``.
        With ``checked`` (the default), every face is checked against its exact surface
        and B-spline faces BRepMesh meshed too coarsely are refined
        (``lattice_cad.occ_impl.chord``); without, BRepMesh's triangulation is taken as it
        is (e.g. to count triangles). Asked right after an unchecked call with the same
        ``deflection`` and ``angular``, the checked one does not mesh the B-rep again.

        Parameters
        ----------
        deflection : float
            Largest distance (mm) between the new mesh and the exact surface.
        angular : float
            Largest angle (rad) between neighbouring normals on curved faces.

        Returns
        -------
        Part
            With the same ``name`` and ``shape``.

        Raises
        ------
        PartError
            The finer tessellation is not closed even after healing.
        """
        if not deflection > 0:
            raise ValueError(f"deflection must be > 0, got {deflection!r}")
        if self.shape is None or deflection >= self.deflection:
            return self
        cache = self.__dict__.setdefault("_refined", {})
        key = (float(deflection), float(angular), bool(checked))
        if key not in cache:
            from lattice_cad.occ_impl import shapes as _occ

            solids = list(self.united if self.united is not None else self.shape)
            shape = solids[0] if len(solids) == 1 else _occ.compound(solids)
            # the solids are meshed in place; the last (deflection, angular) is kept so that
            # a checked call right after an unchecked one reuses BRepMesh's work
            reuse = self.__dict__.get("_meshed_at") == key[:2]
            self.__dict__["_meshed_at"] = None  # in case meshing fails half-way
            # dense faces are split into patches (occ_impl.chord.split_dense_faces) once for
            # deflections within a factor 2: a checked call after an unchecked one meshes the
            # same patches (and reuses their mesh), cutting_part's budget trials share them
            split = _split_for(self.__dict__.setdefault("_split", {}), key[0], key[1])
            with warnings.catch_warnings():  # the union was announced when it was loaded
                warnings.simplefilter("ignore", LatticeWarning)
                cache[key] = _from_shape(
                    shape, self.name, key[0], key[1], checked=checked, reuse=reuse, split=split,
                    prior=None if self.face_triangles is None else
                    (self.deflection, self.face_triangles),
                    snap=self.united is not None,
                )  # fmt: skip
            cache[key].shape, cache[key].united = self.shape, self.united
            self.__dict__["_meshed_at"] = key[:2]
            cache[key].unrefined = self
            cache[key].moved_by = self.moved_by  # (the solids are the moved ones)
        return cache[key]

    # ------------------------------------------------------------ indexes
    @cached_property
    def _bins2d(self) -> tuple[Any, ...]:
        b = self.bounds
        ext = np.maximum(b[1, :2] - b[0, :2], 1e-12)
        h = float(np.sqrt(ext[0] * ext[1] / max(len(self.faces), 1)) * 2.0)
        h = max(h, float(ext.max()) / 2048)
        dims = np.maximum(1, np.ceil(ext / h).astype(np.int64) + 1)
        origin = b[0, :2] - 0.5 * h
        start, items = _kernels.bin_triangles_2d(self.triangles, origin, h, dims)
        return origin, h, dims, start, items

    @cached_property
    def _bins3d(self) -> tuple[Any, ...]:
        b = self.bounds
        ext = np.maximum(b[1] - b[0], 1e-12)
        # about 2 triangles per surface cell
        h = float(np.sqrt(self.area / max(len(self.faces), 1)) * 2.0)
        h = max(h, float(ext.max()) / 512)
        dims = np.maximum(1, np.ceil(ext / h).astype(np.int64) + 1)
        origin = b[0] - 0.5 * h
        start, items = _kernels.bin_triangles_3d(self.triangles, origin, h, dims)
        return origin, h, dims, start, items

    # ------------------------------------------------------------ queries
    def winding(self, points: ArrayLike) -> NDArray[np.int32]:
        """(P,) int32 winding numbers of (P, 3) points: 1 inside, 0 outside."""
        p = _as_points(points)
        origin, h, dims, start, items = self._bins2d
        return _kernels.points_winding(self.triangles, start, items, origin, h, dims, p)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(P,) bool: which of the (P, 3) points are inside the part.

        Points exactly on the surface may go either way.
        """
        return self.winding(points) != 0

    def grid_contains(
        self,
        origin: ArrayLike,
        step: ArrayLike,
        dims: ArrayLike,
        *,
        offset: ArrayLike | None = None,
    ) -> NDArray[np.bool_]:
        """(nx, ny, nz) bool: inside test of the grid points ``origin + (i, j, k) * step``.

        One vertical ray per (i, j) column: O(columns + crossings + points). ``offset``
        (3,) int: classify only the block of ``dims`` points starting at grid index
        ``offset`` (bit-identical to the same points of the whole grid).
        """
        o = np.asarray(origin, dtype=np.float64).reshape(3)
        s = np.asarray(step, dtype=np.float64).reshape(3)
        d = np.asarray(dims, dtype=np.int64).reshape(3)
        off = np.zeros(3, np.int64) if offset is None else np.asarray(offset, np.int64).reshape(3)
        return _kernels.grid_winding(self.triangles, o, s, d, off) != 0

    def inscribed_radius(self, *, resolution: int = 96) -> float:
        """Radius of the largest ball inside the part (half its greatest thickness), mm.

        From a distance transform of the inside on a grid of ``resolution`` points along
        the longest side, refined by the exact distance at the deepest grid points, each
        then climbed to a deeper point nearby (a pattern search on the exact distance,
        steps from ``h / 2`` down to ``h / 64``). A lower bound (the depth of a point
        inside), within a small fraction of a grid step where the deepest region is not
        narrower than the grid: a rod lying between grid points is no longer short by up
        to ``h * sqrt(2) / 2``.
        """
        return self.deepest_point(resolution=resolution)[1]

    def deepest_point(self, *, resolution: int = 96) -> tuple[NDArray[np.float64], float]:
        """The deepest point found inside the part and its depth (the
        :meth:`inscribed_radius`): ``point`` (3,) float64 (NaN when no grid point is
        inside, depth 0)."""
        cache = self.__dict__.setdefault("_deepest", {})
        if resolution not in cache:
            grid = self._depth_grid(resolution)
            if grid is None:
                cache[resolution] = (np.full(3, np.nan), 0.0)
            else:
                origin, h, depth = grid
                best = np.argsort(depth, axis=None)[-64:]
                pts = origin + np.column_stack(np.unravel_index(best, depth.shape)) * h
                p, d = self._climb(pts, h)
                k = int(np.argmax(d))
                # a spread of the other inside points too: where the surface has sheets
                # inside the solid (bodies stacked face to face, each closed), the grid's
                # depth passes through them and its deepest points lie at one, where the
                # climb stayed (1.85 mm found in two stacked boxes of 15 mm, s30); climbed
                # from where one of them is deeper than that
                inside = np.flatnonzero(depth.ravel() > 0)
                spread = inside[:: max(1, len(inside) // DEPTH_SPREAD)]
                far = origin + np.column_stack(np.unravel_index(spread, depth.shape)) * h
                if len(far) and float(self.distance(far).max()) > float(d[k]):
                    p2, d2 = self._climb(far, h)
                    if float(d2.max()) > float(d[k]):
                        p, d, k = p2, d2, int(np.argmax(d2))
                cache[resolution] = (p[k], float(d[k]))
        point, depth_ = cache[resolution]
        return point.copy(), depth_

    def _climb(
        self, pts: NDArray[np.float64], h: float, *, seeds: int = 8
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Points (Q, 3) float64 and their depths (Q,) float64 reached from up to ``seeds``
        of the (P, 3) inside grid points of spacing ``h`` (the deepest, at least ``2 h``
        apart; those that cannot lead deeper than the deepest left out), each moved to its
        deepest neighbour (axes and diagonals) at steps ``h / 2 .. h / 64`` while that is
        deeper. A move shorter than the point's depth stays inside (the ball of that radius
        is), so each result is the depth of a point inside: a lower bound of the inscribed
        radius."""
        pts = np.asarray(pts, dtype=np.float64)
        d0 = self.distance(pts)
        chosen: list[int] = []
        for i in np.argsort(-d0):
            # a point deeper than all lies within h sqrt(3) / 2 of a grid point, which is
            # at most that much less deep than it: the others cannot lead there
            if d0[i] < d0.max() - 0.5 * np.sqrt(3.0) * h or len(chosen) == seeds:
                break
            if all(np.linalg.norm(pts[i] - pts[j]) >= 2 * h for j in chosen):
                chosen.append(int(i))
        p, d = pts[chosen].copy(), d0[chosen].copy()
        diag = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        dirs = np.vstack([np.eye(3), -np.eye(3), diag / np.sqrt(3.0)])  # (14, 3) unit
        rows = np.arange(len(p))
        for level in range(1, 7):
            s = h / 2**level
            for _ in range(4):
                cand = p[:, None, :] + s * dirs[None, :, :]  # (Q, 14, 3)
                # 1-Lipschitz: no candidate is deeper than its point plus the move (with
                # room for rounding: a move straight off a plane lands at exactly that
                # depth, which the bound then called "farther", inf, and the depth found
                # became inf: a part of two boxes stacked face to face, s30)
                reach = (float(d.max()) + s) * (1.0 + 1e-9) + 1e-12
                dc = self.distance(cand.reshape(-1, 3), max_distance=reach).reshape(len(p), -1)
                dc[~np.isfinite(dc)] = -np.inf  # (not measured: never taken)
                dc[s >= d] = -np.inf  # a move must stay in the point's ball
                k = np.argmax(dc, axis=1)
                gain = dc[rows, k] > d
                if not gain.any():
                    break
                p[gain] = cand[gain, k[gain]]
                d[gain] = dc[gain, k[gain]]
        return p, d

    def _depth_grid(
        self, resolution: int
    ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]] | None:
        """(origin (3,), spacing h, depth (nx, ny, nz) float64): the distance transform of
        the grid points inside the part (0 outside), or None when no grid point is inside.

        ``depth`` at a point inside is its distance to the nearest grid point outside, so
        at least its distance to the surface (the segment between them crosses it)."""
        cache = self.__dict__.setdefault("_depth_grids", {})
        if resolution not in cache:
            cache[resolution] = self._depth_grid_uncached(resolution)
        return cache[resolution]

    def _depth_grid_uncached(
        self, resolution: int
    ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]] | None:
        from scipy.ndimage import distance_transform_edt

        # fine enough for thin walls: a few points across the mean thickness 2 V / A
        t = self.triangles
        area = 0.5 * float(
            np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
        )
        h = min(float(self.size.max()) / resolution, 0.5 * abs(self.volume) / max(area, 1e-300))
        h = max(h, (float(np.prod(self.size + 3 * h)) / 8e6) ** (1 / 3))  # at most ~8M points
        origin = self.bounds[0] - h + 0.5017 * h  # off the round coordinates of CAD faces
        dims = np.ceil(self.size / h).astype(np.int64) + 3
        inside = self.grid_contains(origin, np.full(3, h), dims)
        if not inside.any():
            return None
        return origin, h, distance_transform_edt(inside, sampling=h)

    def thinner_than(
        self, depth: float, *, resolution: int = 96, levels: int = 4, budget: int = 2_000_000
    ) -> bool:
        """Whether no point of the part lies ``depth`` (mm) or more from its surface (so an
        inset by ``depth`` is empty), proven; False when not proven.

        A branch and bound on the grid of :meth:`inscribed_radius`. Every point of the part
        lies in the cube of side ``h`` about its nearest grid point ``g``, and the distance
        to the surface is 1-Lipschitz, so the cubes whose ``d(g) + sqrt(3) / 2 * h`` stays
        below ``depth`` hold no point that deep, where ``d(g)`` is the grid's distance
        transform (inside points; an upper bound of their exact distance) or 0 (outside).
        Each cube left is cut into its eight octants, each with one corner ``c`` of the
        cube: the surface point ``q`` nearest to ``c`` is measured exactly, and no point
        ``y`` of that octant lies deeper than ``|y - q|`` (``q`` is a point of the surface),
        whose largest value over the octant is at one of its vertices (a distance to a point
        is convex). Near a flat wall that bound grows with the square of the octant's size
        (where the centre's ``+ rho`` grows linearly): a 3 mm plate is proven thinner than
        1.625 mm on the first level. The octants whose bound reaches ``depth`` are cubes of
        the next level, for up to ``levels`` levels and ``budget`` distance queries (the
        cubes' corners, each measured once); the answer is True when no cube is left. The
        grid's inside test is exact for the mesh (winding numbers); what the mesh is to the
        exact surface is the caller's tolerance.
        """
        depth = float(depth)
        grid = self._depth_grid(resolution)
        if grid is None:
            return True
        origin, h, field = grid
        rho = 0.5 * np.sqrt(3.0) * h
        if rho >= depth:  # an outside grid point bounds nothing below depth
            return False
        deep = field.ravel() + rho >= depth
        if np.count_nonzero(deep) > budget:
            return False
        # cubes on an integer lattice of step u = h / 2 ** (levels + 1): centres of level-0
        # cubes at multiples of 2 ** (levels + 1), a level-L cube's half side 2 ** (levels - L)
        half = 2**levels
        if (np.array(field.shape) * 2 * half + 2 * half + 2).max() >= 2**21:
            return False  # (a grid finer than the packing holds; not met below 8M points)
        cells = np.column_stack(np.unravel_index(np.flatnonzero(deep), field.shape))
        cells = cells.astype(np.int64) * (2 * half)
        u = h / (2 * half)
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        spent = 0
        for _ in range(levels + 1):
            if not len(cells):
                return True
            corners = (cells[:, None, :] + half * signs[None, :, :]).reshape(-1, 3)
            # one query per corner (packed: at most 2 ** 21 lattice steps an axis, from the
            # level-0 corners' -2 ** levels; a key that met another's would only give a
            # looser bound: any surface point bounds the depth)
            c = corners + (2**levels + 1)
            packed = c[:, 0] << 42 | c[:, 1] << 21 | c[:, 2]
            _keys, first, back = np.unique(packed, return_index=True, return_inverse=True)
            spent += len(first)
            if spent > budget:
                return False
            pts = origin + corners[first] * u
            dist, near = self.closest(pts, max_distance=depth + 2.0 * rho)
            deep_at = np.flatnonzero(dist >= depth)
            if len(deep_at) and bool(self.contains(pts[deep_at]).any()):
                return False  # a point that deep, found
            q = near[back.ravel()].reshape(len(cells), 8, 3)
            bound = _kernels.octant_depth_bounds(
                origin + cells * u, float(half * u), signs.astype(np.float64), q
            )
            left = ~(bound < depth)
            if half == 1 and left.any():
                return False
            cells = (cells[:, None, :] + (half // 2) * signs[None, :, :])[left]
            half //= 2
            rho *= 0.5
        return not len(cells)

    def closest(
        self, points: ArrayLike, *, max_distance: float = np.inf
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Distance to the surface and closest surface point of each point.

        Parameters
        ----------
        points : (P, 3) float
        max_distance : float
            Points farther than this get ``inf`` and NaN (faster).

        Returns
        -------
        distance : (P,) float64
        closest : (P, 3) float64
        """
        p = _as_points(points)
        origin, h, dims, start, items = self._bins3d
        dist, cp, _ = _kernels.closest_points(
            self.triangles, self.boxes, start, items, origin, h, dims, p, float(max_distance)
        )
        return dist, cp

    def distance(self, points: ArrayLike, *, max_distance: float = np.inf) -> NDArray[np.float64]:
        """(P,) float64 unsigned distance of (P, 3) points to the surface."""
        return self.closest(points, max_distance=max_distance)[0]

    def signed_distance(
        self, points: ArrayLike, *, max_distance: float = np.inf
    ) -> NDArray[np.float64]:
        """(P,) float64 signed distance: negative inside, positive outside.

        ``max_distance``: points farther than this from the surface get ``-inf`` (inside)
        or ``inf`` (outside); much faster for points deep inside a finely meshed part (the
        nearest-triangle search grows with the distance).
        """
        p = _as_points(points)
        d = self.distance(p, max_distance=max_distance)
        return np.where(self.contains(p), -d, d)

    def segment_crossings(
        self, a: ArrayLike, b: ArrayLike, *, cap: int = 8
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Where segments ``a[i] -> b[i]`` cross the surface.

        Returns
        -------
        count : (S,) int64
            Number of crossings (within 1e-9 of each other counted once).
        params : (S, cap) float64
            Sorted crossing parameters in ``[0, 1]`` (NaN beyond ``count``).
        """
        pa = _as_points(a)
        pb = _as_points(b)
        origin, h, dims, start, items = self._bins3d
        return _kernels.segment_crossings(
            self.triangles, start, items, origin, h, dims, pa, pb, int(cap)
        )


def _as_points(points: ArrayLike) -> NDArray[np.float64]:
    """(P, 3) float64 C-contiguous, a read-only view (``core.arrays.read_only``)."""
    from lattice_cad.core.arrays import read_only

    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.size == 0:
        p = np.zeros((0, 3))
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (P, 3), got {p.shape}")
    return read_only(p)


# ======================================================================= load
def load_part(
    source: str | os.PathLike[str] | Any,
    *,
    units: str | float | None = None,
    deflection: float | None = None,
    angular_deflection: float = 0.3,
    close_holes: bool = False,
    on_solids: Callable[[list[Any]], None] | None = None,
    move_to_origin: bool = False,
) -> Part:
    """Load a part to fill with a lattice.

    Parameters
    ----------
    source : path, cadquery.Workplane, cadquery.Shape, build123d shape or TopoDS_Shape
        A STEP file (``.step``/``.stp``, read by OCCT), a mesh file (``.stl``,
        ``.obj``, ``.ply``, ``.3mf``, ``.off``, read by trimesh), or an
        in-memory CAD shape (taken to be in millimetres).
    units : str or float, optional
        Unit of a *mesh* file (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ...) or
        millimetres per file unit. Meshes default to millimetres. STEP and 3MF
        files declare their unit and are always converted to millimetres; passing
        ``units`` for one of them or for a shape is an error.
    deflection : float, optional
        Largest distance between the exact CAD surface and its triangle mesh
        (default ``1e-3`` of the bounding-box diagonal).
    angular_deflection : float
        Largest angle (radians) between neighbouring mesh normals on curved
        CAD faces.
    close_holes : bool
        Close the holes of an open *mesh* file with least-area patches (a warning says
        how many, the largest and where; see :mod:`conformal.holes`) instead of refusing
        it. Meshes with non-manifold edges are still refused. Ignored for B-rep parts
        (their open faces are sewn and healed anyway).
    on_solids : callable, optional
        For a B-rep part: called with its solids (the list that becomes ``Part.shape``)
        as soon as they are known, before they are tessellated and checked; e.g.
        ``lattice_cad.Lattice.fill`` starts OCCT's skin offsets there, in a child
        process, so that they compute while this one tessellates.
    move_to_origin : bool
        Move the part so that the centre of its bounding box is the origin (the B-rep
        before it is tessellated); :attr:`Part.moved_by` keeps the translation. For parts
        exported in plant or site coordinates (kilometres from the origin), where single
        precision (STL, 3MF) cannot resolve struts of the radius asked.

    Returns
    -------
    Part

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    PartError
        The file is empty or unreadable, has no closed solid (surfaces or open
        shells only), or the mesh is not closed, not 2-manifold or not
        consistently oriented. The message names the file and the problem.

    Warns
    -----
    LatticeWarning
        Several solids or bodies were united into one part; a mesh body with
        inward-facing triangles was turned outward; holes were closed; a mesh part is
        under ``config.SMALL_MESH_MM`` across (likely in metres or inches).
    """
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if not path.exists():
            raise MissingFileError(f"part file not found: {path}")
        if path.is_dir():
            raise PartError(f"{path}: is a directory, not a part file")
        suffix = path.suffix.lower()
        if suffix in _STEP_SUFFIXES:
            if units is not None:
                raise ValueError(
                    f"{path.name}: STEP files declare their own unit (converted to mm); "
                    "do not pass units="
                )
            if path.stat().st_size == 0:
                raise PartError(f"{path}: the file is empty")
            from lattice_cad.occ_impl.step import read_step

            said: list[str] = []
            shape = read_step(path, messages=said)
            if shape is None:
                why = "; ".join(said[:3]) + (" ..." if len(said) > 3 else "")
                raise PartError(
                    f"{path}: not a readable STEP file (OCCT could not read it"
                    + (f": {why})" if why else ")")
                )
            return _said_crossings(
                _from_shape(
                    shape,
                    str(path),
                    deflection,
                    angular_deflection,
                    measure=True,
                    on_solids=on_solids,
                    move_to_origin=move_to_origin,
                    unite=True,
                )
            )
        if suffix in _MESH_SUFFIXES:
            if suffix == ".3mf" and units is not None:
                raise ValueError(
                    f"{path.name}: 3MF files declare their own unit (converted to mm); "
                    "do not pass units="
                )
            part = _from_mesh_file(
                path, _unit_scale(units), unit_given=units is not None, close_holes=close_holes
            )
            return _said_crossings(_centred(part) if move_to_origin else part)
        raise PartError(
            f"{path}: unsupported file type {suffix or '(no suffix)'!r}; use STEP "
            f"({', '.join(sorted(_STEP_SUFFIXES))}) or a mesh ({', '.join(sorted(_MESH_SUFFIXES))})"
        )
    if units is not None:
        raise ValueError("units= applies to mesh files only; CAD shapes are in millimetres")
    from lattice_cad.occ_impl import shapes as _occ

    shape = _occ.as_topods(source)
    if shape is None:
        raise TypeError(
            "source must be a file path, a cadquery Workplane or Shape, a build123d shape or a "
            f"TopoDS_Shape; got {type(source).__name__}"
        )
    return _said_crossings(
        _from_shape(
            shape,
            f"<{type(source).__name__}>",
            deflection,
            angular_deflection,
            measure=True,
            on_solids=on_solids,
            move_to_origin=move_to_origin,
            unite=True,
        )
    )


def _centre(box: NDArray[np.float64]) -> NDArray[np.float64]:
    """The centre of a bounding box ``(2, 3)`` float64, rounded to a float32-exact value
    (the translation a file's coordinates take is then exact for float32 inputs)."""
    return np.asarray(0.5 * (box[0] + box[1]), dtype=np.float32).astype(np.float64)


def _centred(part: Part) -> Part:
    """A mesh part moved so that its bounding box is centred on the origin."""
    c = _centre(part.bounds)
    move = np.eye(4)
    move[:3, 3] = -c
    out = part.transformed(move)
    out._patch_crossings = part._patch_crossings
    out.moved_by = -c
    out.unit_assumed = part.unit_assumed
    return out


def _said_crossings(part: Part) -> Part:
    """``part``, with a warning when its surface crosses itself (:attr:`Part.self_crossings`)
    that a closed hole's patch (said by ``conformal.holes``) does not explain."""
    if part.self_crossings[0] and not part._patch_crossings:
        warnings.warn(
            f"{part.name}: {part.crossing_note()}; a cut to it (trim, skin, clip, conform, "
            "tet) may fail there",
            LatticeWarning,
            stacklevel=3,
        )
    return part


def _unit_scale(units: str | float | None) -> float:
    if units is None:
        return 1.0
    if isinstance(units, str):
        try:
            return UNITS[units.lower()]
        except KeyError:
            raise ValueError(f"unknown unit {units!r}; known: {', '.join(UNITS)}") from None
    scale = float(units)
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"units must be a unit name or a positive number, got {units!r}")
    return scale


def _split_for(
    made: dict[tuple[float, float], dict[int, Any]], deflection: float, angular: float
) -> dict[int, Any]:
    """The patches (per solid, see :func:`_from_shape`) made for the deflection nearest to
    ``deflection`` within a factor 2 (and the same ``angular``), or a new empty entry."""
    near = [d for d, a in made if a == angular and 0.5 <= deflection / d <= 2.0]
    if near:
        best = min(near, key=lambda d: abs(np.log(deflection / d)))
        return made[(best, angular)]
    return made.setdefault((deflection, angular), {})


def _from_shape(
    shape: Any,
    name: str,
    deflection: float | None,
    angular: float,
    *,
    checked: bool = False,
    reuse: bool = False,
    measure: bool = False,
    split: dict[int, Any] | None = None,
    on_solids: Callable[[list[Any]], None] | None = None,
    prior: tuple[float, list[tuple[NDArray[np.int64], NDArray[np.float64]]]] | None = None,
    move_to_origin: bool = False,
    unite: bool = False,
    snap: bool = False,
) -> Part:
    """The part of a B-rep ``shape``; ``measure`` (an unchecked tessellation): also bound its
    chord error (``Part.chord_bound``). With ``split`` (solid index: what
    ``occ_impl.chord.split_dense_faces`` gave for it, filled in when missing), dense faces
    are meshed as patches; the part's ``shape`` stays the solids as they were.
    ``on_solids``: see :func:`load_part`. ``prior``: the deflection and ``face_triangles``
    of a coarser tessellation of the same solids, from which ``split_dense_faces`` may
    tell at once that no face is dense. ``move_to_origin``: see :func:`load_part`.
    ``unite``: solids that touch or overlap are united by OCCT's fuse before they are
    tessellated (``occ_impl.shapes.united_solids``; the part's ``united``; its ``shape``
    stays the solids as given), else, or when a united solid does not tessellate closed,
    their tessellations are united (manifold3d). ``snap``: a single solid's tessellation too is
    rounded to the union's grid (a finer tessellation of united solids, as theirs was)."""
    from lattice_cad.occ_impl import shapes as _occ

    moved = np.zeros(3)
    if move_to_origin:
        moved = -_centre(_occ.bounds(shape))
        shape = _occ.translated(shape, moved)
    solids = _occ.solids(shape)
    if not solids:
        solids = _solids_of_surfaces(shape, name)
    given = solids
    if on_solids is not None:
        on_solids(given)
    united = _occ.united_solids(solids) if unite and len(solids) > 1 else None
    if united is not None:
        solids = united
    box = _occ.bounds(_occ.compound(solids) if len(solids) > 1 else solids[0])
    diag = float(np.linalg.norm(box[1] - box[0]))
    defl = 1e-3 * diag if deflection is None else float(deflection)
    if not defl > 0:
        raise ValueError(f"deflection must be > 0, got {deflection!r}")
    bound: float | None = 0.0 if measure and not checked else None

    def tessellated(solids: list[Any]) -> tuple[list[Any], list[Any], float | None, float, int]:
        """(pieces, counts, bound, chord error, unresolved) of the solids' tessellations."""
        pieces, counts = [], []
        chord_error, unresolved, worst = 0.0, 0, bound
        for k, solid in enumerate(solids):
            v, f, report, dev, per_face = _closed_tessellation(
                solid, k, name, defl, angular, diag, checked, reuse, measure=worst is not None,
                split=split, prior=None if prior is None else (prior[0], *prior[1][k]),
            )  # fmt: skip
            growth = _occ.triangle_growth(solid)
            if 0 < len(per_face) <= len(growth):
                per_face = np.pad(per_face, (0, len(growth) - len(per_face)))
            counts.append((per_face, growth))
            if worst is not None and dev is not None:
                worst = max(worst, dev)
            if report is not None:
                chord_error = max(chord_error, report.max_deviation)
                unresolved += len(report.unresolved)
            t = v[f]
            if np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() < 0:
                f = f[:, ::-1]  # a solid with reversed orientation
            pieces.append((v, f))
        return pieces, counts, worst, chord_error, unresolved

    try:
        pieces, counts, bound, chord_error, unresolved = tessellated(solids)
    except Exception as exc:
        if united is None or not (
            isinstance(exc, (PartError, OCCTFailure)) or _occ.is_occt_error(exc)
        ):
            raise
        # a united solid that does not tessellate closed (solids that touch along an edge
        # only make one with a non-manifold edge; a face of the three overlapping solids of
        # shared/data's spatula BRepMesh leaves bare): the given solids, their meshes united
        united, solids = None, given
        pieces, counts, bound, chord_error, unresolved = tessellated(solids)
    if len(pieces) > 1 or united is not None or snap:
        # (united solids too: snapped to the union's grid, their seams are as the meshes'
        # union gives them; unsnapped, pymeshlab saw the GE bracket's seams, 1e-7 off the
        # grid, cross in 33 faces)
        v, f = _union_meshes(pieces, name)
    else:
        v, f = pieces[0]
    if len(given) > 1:
        if united is not None:  # the B-rep's volumes (GProp's default rule is off by 0.3 %
            # on a scaled sphere's B-spline faces: adaptive, 1e-6, 0.01-0.04 s a part)
            vols = sum(_occ.volume(s, eps=1e-6) for s in given)
            overlap = vols - sum(_occ.volume(s, eps=1e-6) for s in united)
        else:
            vols = sum(_mesh_volume(v[f]) for v, f in pieces)
            overlap = vols - _mesh_volume(v[f])
        note = f", overlapping by {overlap:.4g} mm^3" if overlap > 1e-6 * vols else ""
        # its bodies: the united solids, or the outer shells of the meshes' union
        n = len(united) if united is not None else _outer_shells(v, f)
        said = f"{len(given)} solids were united into one part{note}"
        if n == len(given):  # (s38's print-in-place hinge: it said "united")
            said = f"{n} solids, none touching another, make one part of {n} bodies"
        elif n > 1:
            said += f" of {n} bodies (those touching or overlapping were fused)"
        warnings.warn(
            f"{name}: {said}",
            LatticeWarning,
            stacklevel=3,
        )
    part = Part(v, f, name=name, shape=given, deflection=defl)
    part.united = united
    part.moved_by = moved
    part.chord_bound = bound
    if all(len(n) == len(g) for n, g in counts):
        part.face_triangles = counts
    if checked and config.CHORD_CONTROL > 0:
        part.chord_error = chord_error
        part.chord_unresolved = unresolved
    return part


def _solids_of_surfaces(shape: Any, name: str) -> list[Any]:
    """The solids of a B-rep without any: its faces sewn into closed shells, each made a
    solid (``occ_impl.shapes.solids_from_surfaces``; a STEP surface model, e.g. a
    ``SHELL_BASED_SURFACE_MODEL`` of a closed shell), said in a warning; faces left open
    are named (in the warning when some solid was made, else in the error)."""
    from lattice_cad.occ_impl import shapes as _occ

    n_faces = _occ.faces_outside_solids(shape)
    if n_faces == 0:
        raise PartError(
            f"{name}: no closed solid, no geometry at all; a lattice needs a closed volume"
        )
    made, left = _occ.solids_from_surfaces(shape)

    def named(items: list[tuple[int, NDArray[np.float64]]]) -> str:
        shown = [
            f"face {k} (free edge {point_text(w[0])} - {point_text(w[1])})" for k, w in items[:3]
        ]
        return ", ".join(shown) + (f" and {len(items) - 3} more" if len(items) > 3 else "")

    if not made:
        raise PartError(
            f"{name}: no closed solid, only {n_faces} open face(s), which do not close "
            f"into a solid even when sewn: {named(left)}; a lattice needs a closed volume "
            "(close the surfaces into a solid in your CAD tool)"
        )
    note = f"; {len(left)} face(s) that do not close were left out: {named(left)}" if left else ""
    n_shells = sum(_occ.shell_count(s) for s in made)
    cavities = (
        f" ({n_shells - len(made)} of the shells facing inward inside another: the walls of "
        "closed cavities)"
        if n_shells > len(made)
        else ""
    )
    warnings.warn(
        f"{name}: the file holds surfaces, not a solid: {n_faces - len(left)} face(s) were "
        f"sewn into {n_shells} closed shell(s) and made {len(made)} solid(s){cavities}{note}",
        LatticeWarning,
        stacklevel=4,
    )
    return made


def _mesh_volume(t: NDArray[np.float64]) -> float:
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


def _closed_tessellation(
    solid: Any,
    k: int,
    name: str,
    defl: float,
    angular: float,
    diag: float,
    checked: bool,
    reuse: bool = False,
    *,
    measure: bool = False,
    split: dict[int, Any] | None = None,
    prior: tuple[float, NDArray[np.int64], NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], Any, float | None, NDArray[np.int64]]:
    """A closed, 2-manifold triangulation of one B-rep solid, healing it if needed.

    With ``checked``, every face is checked against its exact surface and the faces that
    BRepMesh meshed coarser than ``defl`` are refined (``occ_impl.chord``); the
    ``ChordReport`` is returned third (None without ``checked``), and the triangles of
    each B-rep face (TopExp order) last. With ``measure``, the
    fourth is an upper bound on the deviation of its triangle centroids and edge midpoints
    from the exact surface (``occ_impl.chord.face_deviations``, no projection: 0.07 s for
    the M6 screw's 7,602 triangles, 0.4 s for NIST CTC-02's 37,192), else None. With ``reuse``, the
    triangulation ``solid`` carries was made with the same ``defl`` and ``angular`` and is
    kept (not meshed again).

    The whole solid is meshed at once (faces share their edge nodes); copies of edge nodes
    that differ by up to the B-rep's own tolerance are merged; if the mesh is still open,
    the solid is healed with ShapeFix and meshed again. Only then is it refused, naming the
    B-rep faces that border the holes.

    With ``split`` (see :func:`_from_shape`), the faces BRepMesh would fill densely are
    meshed as patches (``occ_impl.chord.split_dense_faces``: the same surfaces); should that
    mesh not close, the solid is meshed again as it is before it is healed.
    """
    from lattice_cad.occ_impl import shapes as _occ
    from lattice_cad.occ_impl.chord import split_dense_faces

    problem, faces_at = "", np.zeros(0, dtype=np.int64)
    patches = None
    if split is not None:
        if k not in split:
            split[k] = None if reuse else split_dense_faces(solid, defl, angular, prior=prior)
        patches = split[k]
    # (healed, patches, chord error): last, a finer chord error, healed or not (a valid
    # volute made outside shared/data: a planar sliver face 0.05 mm wide was left without
    # triangles at 0.26 mm and bordered holes at 0.2 mm; closed at 0.1 mm)
    tries = [(False, patches, defl)] + ([(False, None, defl)] if patches is not None else [])
    tries += [(True, None, defl)] + [(h, None, defl * FINER_TRY) for h in (False, True)]
    for n_try, (healed, patch, chord) in enumerate(tries):
        shape = _occ.heal(solid) if healed else solid if patch is None else patch[0]
        control = config.CHORD_CONTROL if checked else 0.0
        try:
            got = _occ.tessellate(
                shape, chord, angular, face_ids=True, control=control,
                clean=not (reuse and n_try == 0), patches_of=None if patch is None else patch[1],
            )  # fmt: skip
        except OCCTFailure as exc:  # (BRepMesh left a face without triangles)
            problem, faces_at = str(exc), np.zeros(0, dtype=np.int64)
            continue
        v, f, owner = got[:3]
        report = got[3] if control > 0 else None
        if patch is not None:  # the patches' faces back to the solid's
            owner = patch[1][owner]
            if report is not None:
                _faces_of_solid(report, patch[1])
        if len(f) == 0:
            raise PartError(f"{name}: solid {k} has no faces to triangulate")
        limit = max(1e-6 * diag, min(_occ.max_tolerance(shape), 1e-4 * diag))
        for tol in (0.0, 1e-9 * diag, 1e-7 * diag, limit):
            if tol == 0.0:
                vv, ff, kept = v, f, np.ones(len(f), dtype=bool)
            else:
                vv, ff, kept = _occ.merge_close(v, f, tol)
            problem = _closed_problem(ff)
            if not problem:
                dev = _deviation_bound(shape) if measure else None
                # (of the healed shape's faces: not the solid's, none given)
                per_face = np.bincount(owner[kept]) if not healed else np.zeros(0, np.int64)
                return vv, ff, report, dev, per_face
        problem = _closed_problem(ff, vv)  # where, for the message (not in every trial)
        faces_at = np.unique(owner[kept][_open_triangles(ff)])
        if patch is not None and split is not None:
            split[k] = None  # the patches' mesh did not close: the next call meshes it whole
    listed = ", ".join(str(int(i)) for i in faces_at[:10]) + (" ..." if len(faces_at) > 10 else "")
    where = f"; the holes border B-rep face(s) {listed} (TopExp order)" if len(faces_at) else ""
    raise PartError(
        f"{name}: solid {k} is not closed after triangulation and healing, also at a "
        f"{1 / FINER_TRY:g} x finer chord error ({problem}){where}"
    )


def _faces_of_solid(report: Any, face_of: NDArray[np.int64]) -> None:
    """Make the face indices of a ``ChordReport`` of a solid's patches (``face_of``: the
    solid's face of each patch) indices of the solid's faces, each listed once."""
    for name in ("refined", "unresolved", "within_tolerance", "finer"):
        setattr(report, name, sorted({int(face_of[i]) for i in getattr(report, name)}))
    if report.worst_face >= 0:
        report.worst_face = int(face_of[report.worst_face])


def _deviation_bound(shape: Any) -> float:
    """An upper bound (mm) on the deviation of ``shape``'s stored triangulation from its
    exact surfaces at triangle centroids and edge midpoints (``|S(u, v) - p|``)."""
    from lattice_cad.occ_impl.chord import face_deviations

    dev = face_deviations(shape, screen=float("inf"))
    return float(dev.max()) if len(dev) else 0.0


def _open_triangles(f: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(F,) bool: triangles with an edge used once or more than twice."""
    _, inv, cnt = edge_uses(f)
    return (cnt != 2)[inv].reshape(3, -1).any(axis=0)


def _closed_problem(f: NDArray[np.int64], v: NDArray[np.float64] | None = None) -> str:
    """'' for a closed, 2-manifold, consistently oriented triangle mesh, else what is wrong.

    f : (F, 3) int64 triangles; v : (V, 3) float64, optional: the vertices, to say where
    (the first offending edges' end points and, for open edges, how many holes they bound).
    """
    if len(f) == 0:
        return "no triangles"
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    und = np.sort(he, axis=1)
    rows, inv, cnt = unique_rows(und, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    open_edges = int((cnt == 1).sum())
    nonman = int((cnt > 2).sum())
    if open_edges:
        if open_edges > 0.5 * len(rows):  # a soup (the caller says so): about one "hole"
            # per triangle would be counted, which helps nobody
            return f"{open_edges} open (boundary) edge(s) of its {len(rows)} edges" + (
                _edges_at(rows[cnt == 1], v)
            )
        holes = _edge_loops(rows[cnt == 1])
        return (
            f"{open_edges} open (boundary) edge(s) around {holes} hole(s): it has holes"
            + _edges_at(rows[cnt == 1], v)
        )
    if nonman:
        return f"{nonman} non-manifold edge(s) shared by more than two triangles" + _edges_at(
            rows[cnt > 2], v
        )
    fwd = he[:, 0] < he[:, 1]
    sfwd = np.bincount(inv, weights=fwd, minlength=len(cnt))
    bad = int((sfwd != 1).sum())
    if bad:
        return f"{bad} edge(s) where neighbouring triangles have opposite orientation"
    return ""


def _edge_loops(edges: NDArray[np.int64]) -> int:
    """How many holes the open edges ``(E, 2) int64`` bound: the loops they form, E - V + C
    (a bow-tie rim, two holes touching at a vertex, is two, as ``close_holes`` closes it)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    used, local = np.unique(edges, return_inverse=True)
    local = local.reshape(-1, 2)
    g = coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])), shape=(len(used),) * 2)
    pieces = int(connected_components(g, directed=False)[0])
    return max(pieces, len(edges) - len(used) + pieces)


def _edges_at(edges: NDArray[np.int64], v: NDArray[np.float64] | None, most: int = 3) -> str:
    """', e.g. the edge (x, y, z) - (x, y, z), ...': where the first ``most`` edges are."""
    if v is None or not len(edges):
        return ""
    shown = "; ".join(
        "({:.4g}, {:.4g}, {:.4g}) - ({:.4g}, {:.4g}, {:.4g})".format(*v[a], *v[b])
        for a, b in edges[:most].tolist()
    )
    more = f" and {len(edges) - most} more" if len(edges) > most else ""
    return f", e.g. the edge {shown}{more}"


def _weld_open_rims(
    v: NDArray[np.float64], f: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64], int, float] | None:
    """The mesh with the end points of its open edges welded where they lie within a small
    distance of one another (``config.WELD_OPEN_RTOLS`` of the bounding-box diagonal), or
    None if no step closes any open edge.

    A triangle soup whose copies of a vertex differ in the last digits (an exporter that
    rounds each triangle's coordinates) reads as a mesh of holes; welding its open edges'
    end points makes it the closed mesh it stands for. Only vertices on open edges move,
    to the first of each group within the distance (transitively, ``merge_close``); a step
    is tried only below half the mesh's shortest edge and kept only if it leaves no edge
    shared by more than two triangles; the step that leaves the fewest open edges is
    returned.

    v : (V, 3) float64, f : (F, 3) int64 (exact duplicates merged already).

    Returns
    -------
    (vertices (V', 3) float64, faces (F', 3) int64, welded vertices, distance mm) or None.
    Triangles that become degenerate are dropped, a triangle repeated is kept once, and
    vertices no triangle uses are dropped.
    """
    from lattice_cad.occ_impl.merge import merge_close

    rows, _, cnt = edge_uses(f)
    if not (cnt == 1).any():
        return None
    lengths = np.linalg.norm(v[rows[:, 1]] - v[rows[:, 0]], axis=1)
    shortest = float(lengths[lengths > 0].min()) if (lengths > 0).any() else 0.0
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    ends = np.unique(rows[cnt == 1])
    best: tuple[NDArray[np.float64], NDArray[np.int64], int, float] | None = None
    fewest = int((cnt == 1).sum())
    for rtol in config.WELD_OPEN_RTOLS:
        tol = rtol * diag
        if tol >= 0.5 * shortest:
            break
        v2, f2, _ = merge_close(v, f, tol, only=ends)
        if len(v2) == len(v):
            continue  # nothing within this distance
        _, once = unique_rows(np.sort(f2, axis=1), return_index=True)
        f2 = f2[np.sort(once)]
        cnt2 = edge_uses(f2)[2]
        if (cnt2 > 2).any():
            break  # a larger distance joins more: no better
        left = int((cnt2 == 1).sum())
        if left < fewest:
            used, f3 = np.unique(f2, return_inverse=True)
            best = (v2[used], f3.reshape(-1, 3).astype(np.int64), len(v) - len(v2), tol)
            fewest = left
        if not left:
            break
    return best


def _mended_seams(
    v: NDArray[np.float64], f: NDArray[np.int64], diag: float, name: str
) -> tuple[NDArray[np.int64], str]:
    """``f`` with the seams that do not match mended (:mod:`conformal.seams`: triangles
    stored twice, T-junctions, zero-area slivers over T-junctions), each said in a
    warning, and :func:`_closed_problem` of the result. A mesh without such seams is
    returned as it is."""
    from conformal import seams

    tol = config.SEAM_RTOL * diag
    problem = _closed_problem(f)
    said: list[str] = []
    # (also when it is said to be open: holes are named before non-manifold edges, and the
    # triangles a file stores twice hid its holes from the closing of holes, which then
    # found none: a prosthetic foot's keel with a crack and 36 repeated triangles, made
    # outside shared/data)
    if problem:
        g, same, opposite = seams.drop_duplicate_faces(f)
        if same or opposite:
            f, problem = g, _closed_problem(g)
            if same:
                said.append(f"{same} triangle(s) stored twice were kept once")
            if opposite:
                said.append(
                    f"{opposite} pair(s) of coincident triangles facing opposite ways (a wall "
                    "of no thickness between two bodies) were removed"
                )
    if "open (boundary)" in problem:
        rows, _, cnt = edge_uses(f)
        if (cnt == 1).sum() <= 0.5 * len(rows):  # (a soup's copies are welded instead)
            g, n = seams.split_t_junctions(v, f, tol)
            if n:
                f, problem = g, _closed_problem(g)
                said.append(
                    f"{n} triangle(s) were split at vertices of their neighbours lying on "
                    "their edges (T-junctions)"
                )
    elif not problem:
        g, slivers = seams.drop_slivers(v, f, tol)
        if slivers:
            g, n = seams.split_t_junctions(v, g, tol)
            if not _closed_problem(g):  # else the file is kept as it is
                f = g
                said.append(
                    f"{slivers} zero-area triangle(s) with a vertex on their opposite edge "
                    f"(slivers patching T-junctions) were removed and {n} neighbour(s) split "
                    "there"
                )
    if said:
        warnings.warn(
            f"{name}: {'; '.join(said)}: the surface is the same, its triangles now meet "
            "edge to edge",
            LatticeWarning,
            stacklevel=4,
        )
    return f, problem


def _without_debris(
    v: NDArray[np.float64],
    shells: list[NDArray[np.int64]],
    volumes: list[float],
    turned: list[NDArray[np.bool_]],
    name: str,
) -> tuple[list[NDArray[np.int64]], list[float], list[NDArray[np.bool_]]]:
    """The closed shells of a mesh file without its debris: shells smaller than
    ``config.DEBRIS_SIZE`` of the part's diagonal whose volume is below
    ``config.DEBRIS_VOLUME`` of the largest shell's (a speck an exporter or a scan left
    beside the part: a skin kept it as a second, unprintable body), and shells whose mean
    thickness (2 V / A) is below ``config.DEBRIS_THICKNESS`` of the part's diagonal (a face
    an exporter thickened to 0.1 um: a tet fill cut a lattice down to that sheet and wrote
    it as a second body), with a warning."""
    if len(shells) < 2:
        return shells, volumes, turned
    diag = float(np.linalg.norm(np.ptp(v[np.unique(np.concatenate(shells))], axis=0)))
    big = max(abs(x) for x in volumes)
    size = [float(np.linalg.norm(np.ptp(v[np.unique(fb)], axis=0))) for fb in shells]
    thick = []
    for k, fb in enumerate(shells):
        t = v[fb]
        area = 0.5 * float(
            np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
        )
        thick.append(2.0 * volumes[k] / area if area > 0 else 0.0)
    debris = [
        k
        for k in range(len(shells))
        if 0 < volumes[k]
        and (
            (size[k] < config.DEBRIS_SIZE * diag and volumes[k] < config.DEBRIS_VOLUME * big)
            or thick[k] < config.DEBRIS_THICKNESS * diag
        )
    ]  # (a shell facing inward may be a cavity's wall: kept)
    if not debris or len(debris) == len(shells):
        return shells, volumes, turned
    where = "; ".join(
        "{:.3g} mm across{} at ({:.4g}, {:.4g}, {:.4g})".format(
            size[k],
            f", {thick[k]:.3g} mm thick" if thick[k] < config.DEBRIS_THICKNESS * diag else "",
            *v[np.unique(shells[k])].mean(axis=0),
        )
        for k in debris[:3]
    ) + (" ..." if len(debris) > 3 else "")
    warnings.warn(
        f"{name}: {len(debris)} tiny closed shell(s) beside the part were left out as debris "
        f"({where}; each under {config.DEBRIS_SIZE:g} of the part's size and "
        f"{config.DEBRIS_VOLUME:g} of its volume, or thinner than "
        f"{config.DEBRIS_THICKNESS:g} of its size)",
        LatticeWarning,
        stacklevel=4,
    )
    keep = [k for k in range(len(shells)) if k not in set(debris)]
    return [shells[k] for k in keep], [volumes[k] for k in keep], [turned[k] for k in keep]


def _soup_note(v: NDArray[np.float64], f: NDArray[np.int64]) -> str:
    """'; most of its edges are open ...' for a mesh most of whose edges are open (a
    triangle soup whose copies of a vertex are farther apart than the weld goes), with how
    far apart they are; '' otherwise."""
    from scipy.spatial import cKDTree

    rows, _, cnt = edge_uses(f)
    if (cnt == 1).sum() <= 0.5 * len(rows):
        return ""
    ends = np.unique(rows[cnt == 1])
    dist = cKDTree(v[ends]).query(v[ends], k=2)[0][:, 1]
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    return (
        f"; most of its edges are open: a triangle soup whose copies of a vertex lie "
        f"{float(np.median(dist)):.3g} mm apart (median; welded up to "
        f"{config.WELD_OPEN_RTOLS[-1] * diag:.3g} mm, {config.WELD_OPEN_RTOLS[-1]:g} of its "
        "size)? export it again with more digits, or weld it in a mesh editor"
    )


def _from_mesh_file(
    path: Path, scale: float, *, unit_given: bool = False, close_holes: bool = False
) -> Part:

    from lattice_cad.core.errors import InputFileError
    from lattice_cad.io.exchange import check_mesh_file

    if path.stat().st_size == 0:
        raise PartError(f"{path}: the file is empty")
    try:
        check_mesh_file(path)  # not the format of its suffix: say so, before trimesh guesses
    except InputFileError as exc:
        raise PartError(str(exc)) from None
    if path.suffix.lower() == ".3mf":  # lib3mf: build items, components, the model's unit
        from lattice_cad.io.exchange import read_mesh

        try:
            v, f = read_mesh(path)
        except InputFileError as exc:
            raise PartError(str(exc)) from None
    else:  # trimesh, with polygon faces split as polygons (lattice_cad.io.polygons)
        from lattice_cad.core.formats import Kind, format_for
        from lattice_cad.io.exchange import read_mesh_faces

        try:
            v, f = read_mesh_faces(path, format_for(path, Kind.MESH, action="read").name)
        except InputFileError as exc:
            raise PartError(str(exc)) from None
    v, f = v.reshape(-1, 3), f.reshape(-1, 3)
    if len(f) == 0:
        raise PartError(f"{path}: the mesh has no triangles (empty file)")
    if not np.isfinite(v).all():
        raise PartError(f"{path}: the mesh has non-finite vertex coordinates")
    v = v * scale
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    # merge duplicated vertices (STL stores each triangle separately): exact positions
    uniq, inv = np.unique(v, axis=0, return_inverse=True)
    f = inv.reshape(-1)[f]
    v = uniq
    degenerate = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    f = f[~degenerate]
    f, problem = _mended_seams(v, f, diag, str(path))
    if "open (boundary)" in problem:
        welded = _weld_open_rims(v, f)
        if welded is not None:
            open_before = problem.split(" ", 1)[0]
            v, f, n_welded, tol = welded
            problem = _closed_problem(f)
            left = problem.split(" ", 1)[0] if "open (boundary)" in problem else "no"
            warnings.warn(
                f"{path}: {n_welded} end point(s) of open edges lay within {tol:.3g} mm of "
                f"another and were welded ({open_before} open edge(s) before, {left} after): "
                "the file stores copies of its vertices that differ slightly (a triangle "
                "soup, coordinates rounded by the exporter, or a crack between two pieces)",
                LatticeWarning,
                stacklevel=3,
            )
    if problem:
        problem = _closed_problem(f, v)  # where, for the messages
    patch_crossings = False  # a closed hole's patch crosses the surface (said there)
    if problem and close_holes and "open (boundary)" in problem:
        from conformal.holes import close_holes as _close

        f, holes = _close(v, f, name=str(path))
        patch_crossings = bool(holes.crossing)
        warnings.warn(
            f"{path}: {holes.summary()} (close_holes: least-area patches spanning each "
            "hole's rim, not the missing shape)",
            LatticeWarning,
            stacklevel=3,
        )
        problem = _closed_problem(f, v)
    if problem and "non-manifold" in problem:
        # bodies that touch along an edge or face (an assembly saved as one mesh)
        from conformal.touching import split_touching

        split = split_touching(v, f)
        if split is not None:
            v, f, touching = split
            warnings.warn(f"{path}: {touching.summary()}", LatticeWarning, stacklevel=3)
            problem = _closed_problem(f, v)
    if problem and "opposite orientation" not in problem:
        hint = (
            "; close_holes=True (--close-holes) closes them with least-area patches"
            if "open (boundary)" in problem and not close_holes
            else ""
        )
        if "non-manifold" in problem:
            hint = (
                ": not bodies that touch one another (those are split apart), but a body "
                "that touches itself along an edge, or faces inside the solid; unite or "
                "separate its pieces in the program it came from (or export it as STEP)"
            )
        soup = _soup_note(v, f) if "open (boundary)" in problem else ""
        hint = "" if soup else hint  # patches would make each triangle a sheet
        raise PartError(f"{path}: the mesh is not a closed solid: {problem}{soup}{hint}")
    bodies = _components(f, len(v))
    shells: list[NDArray[np.int64]] = []
    volumes: list[float] = []
    turned: list[NDArray[np.bool_]] = []  # per shell: its triangles reversed by _orient
    for body in bodies:
        fb = f[body]
        fixed = np.zeros(len(fb), dtype=bool)
        if _closed_problem(fb):
            oriented = _orient(fb)
            fixed = np.any(oriented != fb, axis=1)
            fb = oriented
            if _closed_problem(fb):
                raise PartError(
                    f"{path}: body {len(shells)} cannot be oriented consistently "
                    f"({_closed_problem(fb, v)}); repair the mesh"
                )
        vol = _mesh_volume(v[fb])
        if vol == 0.0:
            x, y, z = v[np.unique(fb)].mean(axis=0)
            raise PartError(
                f"{path}: body {len(shells)} ({len(fb)} triangle(s) about ({x:.4g}, {y:.4g}, "
                f"{z:.4g})) encloses no volume: a sheet, not a solid"
            )
        shells.append(fb)
        volumes.append(vol)
        turned.append(fixed)
    shells, volumes, turned = _without_debris(v, shells, volumes, turned, str(path))
    # a shell facing inward inside an odd number of the others bounds a cavity (a hollow
    # box's inner wall): it stays as it is and goes with the smallest shell holding it;
    # any other shell facing inward is turned outward (a mirrored body)
    holder = _cavity_holders(v, shells, volumes)
    repaired: list[tuple[int, str]] = []  # (triangles flipped, where)
    grouped: dict[int, list[NDArray[np.int64]]] = {}
    for k, fb in enumerate(shells):
        if holder[k] >= 0:
            continue
        flipped = turned[k]
        if volumes[k] < 0:  # inward as a whole: the triangles _orient kept were the flipped
            fb = fb[:, ::-1]
            flipped = ~flipped
        if flipped.any():
            n = int(np.count_nonzero(flipped))
            repaired.append((n, "body {} at ({:.4g}, {:.4g}, {:.4g}): {:,} of {:,}".format(
                k, *v[np.unique(fb)].mean(axis=0), n, len(fb)
            )))  # fmt: skip
        grouped[k] = [fb]
    for k, h in enumerate(holder):
        if h >= 0:
            grouped[h].append(shells[k])
    pieces: list[tuple[NDArray[np.float64], NDArray[np.int64]]] = [
        (v, np.concatenate(g)) for g in grouped.values()
    ]
    if repaired:
        which = "; ".join(w for _, w in repaired[:5]) + (" ..." if len(repaired) > 5 else "")
        n = sum(n for n, _ in repaired)
        warnings.warn(
            f"{path}: {n:,} flipped (inward-facing) triangle(s) in {len(repaired)} of "
            f"{len(bodies)} bodies ({which}; a body named by the mean of its vertices); "
            "they were re-oriented outward",
            LatticeWarning,
            stacklevel=3,
        )
    if len(pieces) > 1:
        v, f = _union_meshes(pieces, str(path))
        n = _outer_shells(v, f)
        said = f"{len(pieces)} bodies were united into one part"
        if n == len(pieces):  # (two blocks touching at a corner)
            said = f"{n} bodies, none overlapping another, make one part"
        elif n > 1:
            said += f" of {n} bodies (those overlapping were fused)"
        warnings.warn(
            f"{path}: {said}",
            LatticeWarning,
            stacklevel=3,
        )
    else:
        f = pieces[0][1]
    if diag == 0:
        raise PartError(f"{path}: the mesh has zero size")
    across = float(np.max(v.max(axis=0) - v.min(axis=0)))
    unitless = not unit_given and path.suffix.lower() != ".3mf"
    if unitless and across < config.SMALL_MESH_MM:
        # STL, OBJ, PLY and OFF store no unit: a part in metres or inches reads as tiny
        warnings.warn(
            f"{path}: the mesh is {across:.3g} mm across, read as millimetres; if its unit "
            "is another (metres, inches: "
            f"{across:.3g} m = {1000 * across:.3g} mm, {across:.3g} in = {25.4 * across:.3g} mm), "
            "pass it (units='m', or --units m)",
            LatticeWarning,
            stacklevel=3,
        )
    elif unitless and across > config.LARGE_MESH_MM:  # ... and one in micrometres as huge
        warnings.warn(
            f"{path}: the mesh is {across:.4g} mm across, read as millimetres; if its unit "
            f"is micrometres ({across / 1000:.4g} mm across), pass it (units='um', or "
            "--units um)",
            LatticeWarning,
            stacklevel=3,
        )
    part = Part(v, f, name=str(path))
    part._patch_crossings = patch_crossings
    part.unit_assumed = unitless
    return part


def _components(f: NDArray[np.int64], n_vertices: int) -> list[NDArray[np.int64]]:
    """Face indices of each edge-connected body: triangles sharing an edge are one body;
    bodies that share only a vertex are two (two blocks touching at a corner; taken as
    one when vertices joined them, the fill of one was removed as a loose piece)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(f) == 0:
        return []
    ends = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    key = ends[:, 0].astype(np.int64) * np.int64(max(n_vertices, 1)) + ends[:, 1]
    face = np.tile(np.arange(len(f), dtype=np.int64), 3)
    order = np.argsort(key)
    same = key[order[1:]] == key[order[:-1]]  # (the faces of an edge, in a chain)
    rows, cols = face[order[:-1]][same], face[order[1:]][same]
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(f), len(f)))
    _, face_lab = connected_components(g, directed=False)
    order = np.argsort(face_lab, kind="stable")
    splits = np.flatnonzero(np.diff(face_lab[order])) + 1
    return list(np.split(order, splits))


def _outer_shells(v: NDArray[np.float64], f: NDArray[np.int64]) -> int:
    """How many bodies a closed, outward mesh (a union's result) has: its edge-connected
    shells that enclose a positive volume (a cavity's shell encloses a negative one).

    v : (V, 3) float64, f : (F, 3) int64.
    """
    return sum(_mesh_volume(v[f[c]]) > 0 for c in _components(f, len(v)))


def _orient(f: NDArray[np.int64]) -> NDArray[np.int64]:
    """Consistently orient a closed 2-manifold triangle mesh (breadth-first over edges)."""
    import trimesh

    tm = trimesh.Trimesh(vertices=np.zeros((int(f.max()) + 1, 3)), faces=f, process=False)
    adj = tm.face_adjacency
    edges = tm.face_adjacency_edges
    out = f.copy()
    nbrs: list[list[tuple[int, int, int]]] = [[] for _ in range(len(f))]
    for (a, b), (u, w) in zip(adj.tolist(), edges.tolist(), strict=True):
        nbrs[a].append((b, u, w))
        nbrs[b].append((a, u, w))
    done = np.zeros(len(f), dtype=bool)
    for seed in range(len(f)):
        if done[seed]:
            continue
        done[seed] = True
        stack = [seed]
        while stack:
            a = stack.pop()
            fa = out[a].tolist()
            for b, u, w in nbrs[a]:
                if done[b]:
                    continue
                # a traverses the shared edge u->w or w->u; b must traverse it the other way
                ia, ib = fa.index(u), fa.index(w)
                a_uw = (ib - ia) % 3 == 1
                fb = out[b].tolist()
                ja, jb = fb.index(u), fb.index(w)
                b_uw = (jb - ja) % 3 == 1
                if a_uw == b_uw:
                    out[b] = out[b][::-1]
                done[b] = True
                stack.append(b)
    return out


def _cavity_holders(
    v: NDArray[np.float64], shells: list[NDArray[np.int64]], volumes: list[float]
) -> list[int]:
    """For each closed, consistently oriented shell (faces ``shells[k]`` into the (V, 3)
    vertices ``v``, signed volume ``volumes[k]``): the index of the smallest other shell
    holding it when it faces inward and lies inside an odd number of the others (a
    cavity's wall), else -1."""
    holder = [-1] * len(shells)
    inward = [k for k, vol in enumerate(volumes) if vol < 0]
    if not inward or len(shells) == 1:
        return holder
    solids = [Part(v, fb if volumes[j] > 0 else fb[:, ::-1]) for j, fb in enumerate(shells)]
    for k in inward:
        point = v[shells[k][0, 0]][None]
        around = [j for j in range(len(shells)) if j != k and solids[j].contains(point)[0]]
        if len(around) % 2 == 1:
            holder[k] = min(around, key=lambda j: abs(volumes[j]))
    # (shells nested properly never hold a cavity in a cavity; overlapping ones might:
    # such a shell is then turned outward like any other)
    return [h if h < 0 or holder[h] < 0 else -1 for h in holder]


def _union_meshes(
    pieces: list[tuple[NDArray[np.float64], NDArray[np.int64]]], name: str
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Boolean union of closed meshes (manifold3d, double precision).

    The pieces are first rounded to one grid (``config.UNION_SNAP`` of the largest
    coordinate, a power of two): faces where solids touch are then exactly coincident,
    which the union merges, instead of a float64 ulp apart, which it keeps as a slit of
    zero thickness (a self-intersecting surface; seen on trimesh_box_sides.STEP and
    kcl_enclosure.step).
    """
    import manifold3d

    big = max(float(np.abs(v[np.unique(fb)]).max(initial=0.0)) for v, fb in pieces)
    if big > 0:
        h = 2.0 ** np.floor(np.log2(config.UNION_SNAP * big))
        pieces = [(np.round(v / h) * h, fb) for v, fb in pieces]
    result = None
    for k, (v, fb) in enumerate(pieces):
        used, local = np.unique(fb, return_inverse=True)
        m = manifold3d.Manifold(
            manifold3d.Mesh64(
                vert_properties=np.ascontiguousarray(v[used], dtype=np.float64),
                tri_verts=np.ascontiguousarray(local.reshape(-1, 3), dtype=np.uint64),
            )
        )
        if m.status() != manifold3d.Error.NoError:
            raise PartError(f"{name}: body {k} is not a valid closed solid ({m.status()})")
        result = m if result is None else result + m
    assert result is not None
    out = result.to_mesh64()
    vv = np.asarray(out.vert_properties, dtype=np.float64)[:, :3]
    ff = np.asarray(out.tri_verts, dtype=np.int64)
    if len(ff) == 0:
        raise PartError(f"{name}: the union of the bodies is empty")
    return np.ascontiguousarray(vv), np.ascontiguousarray(ff)
