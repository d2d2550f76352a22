"""Voxel lattices: unit cells tiled over the grid cells that fill a part.

As in Verma, Rankouhi & Suresh (2019), Fig. 5.

The part is voxelised on a grid of cells of size ``(hx, hy, hz)``: the corners
of every cell are classified inside/outside (one vertical ray per grid
column, winding numbers), and every cell that a surface triangle touches is
marked *cut* (exact triangle/box separating-axis test). A cell is *inside*
when its 8 corners are inside and it is not cut, i.e. its whole closed box is
inside the part. Unit cells are tiled with :func:`conformal.cells.tile_arrays`,
which merges shared nodes and struts exactly by integer lattice coordinates.

Fill modes
----------
``"inside"``
    Only inside cells.
``"clip"``
    Inside and cut cells; struts that cross the surface are cut there, with a
    new node on the surface, and the parts outside are dropped.
``"conform"``
    Inside and cut cells; struts with at least one end inside are kept and
    their outside ends are moved to the closest surface point. Nodes inside the
    part never move, so interior cells are unchanged.

After clipping or conforming, struts shorter than ``min_strut`` times the
smallest cell size, dangling struts (a strut ending at a node of degree 1
that is not on the surface, removed repeatedly), pieces with no node inside
the part, and isolated nodes are removed; :class:`BuildReport` counts them.
Finally the radii are fitted so that the graph stitches (see
:func:`conformal.radius.fit_radii`).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from conformal import _kernels
from conformal.cells import UnitCell, _resolve, tile_arrays
from conformal.part import Part, _as_points
from conformal.radius import (
    FitError,
    Profile,
    RadiusSpec,
    check_stitch_profile,
    fit_floor,
    fit_radii,
    floor_note,
    resolve_radii,
    unstitchable_dropped,
)
from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.errors import FillError, LatticeWarning
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.resources import require_memory

__all__ = [
    "voxel_lattice",
    "voxelize",
    "grid_of",
    "inside_cells",
    "BuildReport",
    "Voxels",
    "main_components",
]

FillMode = Literal["auto", "inside", "clip", "conform"]
FitMode = Literal["shrink", "raise", "off"]


@dataclass
class BuildReport:
    """What a lattice builder did (counts of cells, removed and adjusted elements)."""

    cells_inside: int = 0
    cells_cut: int = 0
    clipped_struts: int = 0
    moved_nodes: int = 0
    merged_nodes: int = 0
    removed_outside: int = 0
    removed_short: int = 0
    removed_dangling: int = 0
    removed_fragments: int = 0
    removed_isolated: int = 0
    removed_islands: int = 0
    thinned_beyond_tolerance: int = 0
    removed_unstitchable: int = 0
    #: struts removed for lying wholly inside a skin's wall (``voxel_lattice(wall=)``)
    removed_in_wall: int = 0
    bodies: int = 0
    fill: str = ""
    #: with ``fill="auto"``: the share of the part's volume in whole cells (NaN otherwise)
    inside_share: float = float("nan")
    #: the grid was moved to put a node at the part's deepest point (clip or conform, when
    #: the grid as placed left no strut in a thin part)
    origin_moved: bool = False
    radii_reduced: int = 0
    min_radius: float = float("nan")
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def removed(self) -> int:
        """Struts removed by the clean-up (short + dangling + fragments)."""
        return self.removed_short + self.removed_dangling + self.removed_fragments


@dataclass(frozen=True)
class Voxels:
    """Cell classification of a part on a grid.

    Attributes
    ----------
    origin : (3,) float64
        Corner of cell ``(0, 0, 0)``.
    cell_size : (3,) float64
    inside : (nx, ny, nz) bool
        Cells whose whole box is inside the part.
    cut : (nx, ny, nz) bool
        Cells that a surface triangle touches.
    corner_inside : (nx + 1, ny + 1, nz + 1) bool
    """

    origin: NDArray[np.float64]
    cell_size: NDArray[np.float64]
    inside: NDArray[np.bool_]
    cut: NDArray[np.bool_]
    corner_inside: NDArray[np.bool_]


def _vec3(value: ArrayLike, what: str) -> NDArray[np.float64]:
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == 0:
        v = np.full(3, float(v))
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{what} must be a number or 3 finite numbers, got {value!r}")
    return v


def voxelize(
    part: Part, cell_size: float | ArrayLike, *, origin: ArrayLike | None = None
) -> Voxels:
    """Classify the cells of a grid covering ``part``.

    Parameters
    ----------
    part : Part
    cell_size : float or (hx, hy, hz)
    origin : (3,) float, optional
        A grid point (default: the grid is centred on the part's bounding
        box, so that the part's extreme faces do not lie on cell planes). The grid covers the
        part's bounding box; cell ``(0, 0, 0)`` is the first cell that does.

    Returns
    -------
    Voxels
    """
    h = _vec3(cell_size, "cell_size")
    if (h <= 0).any():
        raise ValueError(f"cell_size must be > 0, got {h.tolist()}")
    b = part.bounds
    if origin is None:  # centre the grid on the bounding box
        n = np.maximum(np.ceil((b[1] - b[0]) / h), 1.0)
        o = 0.5 * (b[0] + b[1]) - 0.5 * n * h
    else:
        o = _vec3(origin, "origin")
    lo = np.floor((b[0] - o) / h).astype(np.int64)
    hi = np.ceil((b[1] - o) / h).astype(np.int64)
    hi = np.maximum(hi, lo + 1)
    start = o + lo * h
    dims = hi - lo
    if int(np.prod(dims + 1)) > 400_000_000:
        raise ValueError(f"grid of {dims.tolist()} cells is too large; use larger cells")
    require_memory(
        16 * int(np.prod(dims + 1)),
        f"classifying a grid of {' x '.join(str(int(d)) for d in dims)} cells",
        advice="use larger cells",
    )
    corner = part.grid_contains(start, h, dims + 1)
    cut = _kernels.mark_cut_cells(part.triangles, start, h, dims, 1e-9, np.zeros(3, np.int64))
    all_in = (
        corner[:-1, :-1, :-1]
        & corner[1:, :-1, :-1]
        & corner[:-1, 1:, :-1]
        & corner[:-1, :-1, 1:]
        & corner[1:, 1:, :-1]
        & corner[1:, :-1, 1:]
        & corner[:-1, 1:, 1:]
        & corner[1:, 1:, 1:]
    )
    return Voxels(start, h, all_in & ~cut, cut, corner)


def grid_of(
    part: Part, cell_size: float | ArrayLike, *, origin: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The cell grid :func:`voxelize` lays over ``part``, without classifying it.

    Returns
    -------
    start : (3,) float64
        Corner of cell ``(0, 0, 0)``.
    h : (3,) float64
        Cell size.
    dims : (3,) int64
        Number of cells along each axis.
    """
    h = _vec3(cell_size, "cell_size")
    if (h <= 0).any():
        raise ValueError(f"cell_size must be > 0, got {h.tolist()}")
    b = part.bounds
    if origin is None:  # the same arithmetic as voxelize
        n = np.maximum(np.ceil((b[1] - b[0]) / h), 1.0)
        o = 0.5 * (b[0] + b[1]) - 0.5 * n * h
    else:
        o = _vec3(origin, "origin")
    lo = np.floor((b[0] - o) / h).astype(np.int64)
    hi = np.ceil((b[1] - o) / h).astype(np.int64)
    hi = np.maximum(hi, lo + 1)
    return o + lo * h, h, hi - lo


def inside_cells(
    part: Part,
    start: NDArray[np.float64],
    h: NDArray[np.float64],
    lo: ArrayLike,
    hi: ArrayLike,
    *,
    with_cut: bool = False,
) -> NDArray[np.bool_]:
    """Inside cells of the block ``lo <= (i, j, k) < hi`` of the grid ``(start, h)``.

    Bit-identical to ``voxelize(...).inside[lo:hi]`` of the whole grid (the same
    arithmetic per point and cell), in memory proportional to the block. With
    ``with_cut``: the inside and the cut cells (``inside | cut``, the cells that
    ``fill="clip"`` and ``"conform"`` tile).

    Returns
    -------
    (hi - lo) bool
    """
    lo_a = np.asarray(lo, dtype=np.int64).reshape(3)
    d = np.asarray(hi, dtype=np.int64).reshape(3) - lo_a
    corner = part.grid_contains(start, h, d + 1, offset=lo_a)
    cut = _kernels.mark_cut_cells(part.triangles, start, h, d, 1e-9, lo_a)
    all_in = (
        corner[:-1, :-1, :-1]
        & corner[1:, :-1, :-1]
        & corner[:-1, 1:, :-1]
        & corner[:-1, :-1, 1:]
        & corner[1:, 1:, :-1]
        & corner[1:, :-1, 1:]
        & corner[:-1, 1:, 1:]
        & corner[1:, 1:, 1:]
    )
    if with_cut:
        return all_in | cut
    return all_in & ~cut


def _rotation(rotation: ArrayLike | None) -> NDArray[np.float64] | None:
    if rotation is None:
        return None
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise ValueError("rotation must be a 3x3 rotation matrix (orthonormal, det +1)")
    return r


def voxel_lattice(
    part: Part,
    cell: str | UnitCell = config.DEFAULT_CELL,
    cell_size: float | ArrayLike = config.DEFAULT_CELL_SIZE,
    radius: RadiusSpec = config.DEFAULT_RADIUS,
    *,
    fill: FillMode = "inside",
    origin: ArrayLike | None = None,
    rotation: ArrayLike | None = None,
    min_strut: float = 0.1,
    prune: bool = True,
    min_radius: float | None = None,
    fit: FitMode = "shrink",
    return_report: bool = False,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: Profile = config.DEFAULT_PROFILE,
    auto_fallback: Literal["conform", "clip"] = "conform",
    wall: float | None = None,
) -> LatticeGraph | tuple[LatticeGraph, BuildReport]:
    """Fill a part with a lattice of unit cells.

    Parameters
    ----------
    part : Part
        From :func:`conformal.load_part`.
    cell : str or UnitCell
        A name in :data:`conformal.CELLS` or a user-defined cell.
    cell_size : float or (hx, hy, hz)
        Cell edge lengths (mm).
    radius : float, (M,), (M, 2) or callable
        Strut radius; see :mod:`conformal.radius`. A callable receives the
        (M, 3) strut midpoints (in the part's frame).
    fill : {"inside", "clip", "conform", "auto"}
        See the module docstring. ``"auto"``: ``"inside"`` when the whole cells that fit
        fill at least ``config.AUTO_INSIDE_SHARE`` of the part's volume and keep a strut
        once the dangling ones are pruned, else ``"conform"`` (thin parts, coils, parts
        where a few whole cells fit: the surface nodes follow the walls, so the lattice
        fills the part and stays connected); the report's ``fill`` says which.
    origin : (3,) float, optional
        A lattice grid point, in the lattice frame (default: centred on the
        part's bounding box in that frame).
    rotation : (3, 3) float, optional
        Orientation of the lattice: lattice axes are the columns of the
        matrix (world = rotation @ lattice).
    min_strut : float
        Struts shorter than this fraction of the smallest cell size are
        removed after clipping/conforming.
    prune : bool
        Remove dangling struts (ending at a degree-1 node inside the part) and
        isolated nodes. With ``prune=False`` and ``fill="inside"`` the graph is
        exactly :func:`conformal.cells.tile` of the inside cells.
    min_radius : float, optional
        ``fit="shrink"`` never thins a strut below this (default: a tenth of
        the smallest requested radius).
    fit : {"shrink", "raise", "off"}
        What to do with struts that would not stitch (their end profiles would
        meet): thin the struts at the crowded nodes (a :class:`LatticeWarning`
        says how many), raise :class:`conformal.radius.FitError` listing them,
        or nothing.
    return_report : bool
        Also return a :class:`BuildReport`.
    auto_fallback : {"conform", "clip"}
        The fill ``"auto"`` takes when whole cells do not: ``"clip"`` keeps every strut's
        direction (a self-supporting orientation stays self-supporting), ``"conform"``
        moves the surface nodes onto the walls.
    segments, profile
        The profile polygons the graph will be stitched with (``fast_stitch.stitch``'s
        P and ``profile``): the fit is for them. Fewer sides make wider polygons
        (circumradius ``r * fast_stitch.hubvolume.profile_factor(segments, profile)``:
        +25 % at P = 4, +55 % at P = 3 with ``"volume"``), so a graph fitted for P = 6
        may not stitch at P = 3 or 4.
    wall : float, optional
        The thickness (mm) of a skin the lattice will be joined to (``conformal.skin``),
        with ``fill="clip"`` or ``"conform"``: struts that lie wholly inside that wall
        (:func:`struts_in_wall`) are removed before the radii are fitted. The skin
        swallows them, and the struts beside them need not be thinned for them (the GE
        bracket's octet 6 mm, r 0.5 under a 1.5 mm skin: 2,481 struts thinned below 0.7 r,
        most of them in the wall, where they are not printed). ``rep.removed_in_wall``
        counts them.

    Returns
    -------
    LatticeGraph, or (LatticeGraph, BuildReport)

    Raises
    ------
    ValueError
        Bad parameters; no cell of the grid qualifies (the part is thinner than
        a cell for ``fill="inside"``).
    FitError
        With ``fit="raise"``, when some struts do not fit.
    """
    if fill not in ("auto", "inside", "clip", "conform"):
        raise ValueError(f"fill must be 'auto', 'inside', 'clip' or 'conform', got {fill!r}")
    if fit not in ("shrink", "raise", "off"):
        raise ValueError(f"fit must be 'shrink', 'raise' or 'off', got {fit!r}")
    if not isinstance(part, Part):
        raise TypeError(f"part must be a conformal.Part (see load_part), got {type(part).__name__}")
    segments, profile = check_stitch_profile(segments, profile)
    c = _resolve(cell)
    h = _vec3(cell_size, "cell_size")
    if (h <= 0).any():
        raise ValueError(f"cell_size must be > 0, got {h.tolist()}")
    rot = _rotation(rotation)
    rep = BuildReport()
    t0 = time.perf_counter()
    local = part if rot is None else part.transformed(_homog(rot.T))
    vox = voxelize(local, h, origin=origin)
    rep.cells_inside = int(vox.inside.sum())
    rep.cells_cut = int(vox.cut.sum())
    rep.seconds["voxelize"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    auto = fill == "auto"
    if auto:
        if auto_fallback not in ("conform", "clip"):
            raise ValueError(f"auto_fallback must be 'conform' or 'clip', got {auto_fallback!r}")
        share = rep.cells_inside * float(np.prod(h)) / max(abs(part.volume), 1e-300)
        fill = "inside" if share >= config.AUTO_INSIDE_SHARE else auto_fallback
        rep.inside_share = share
    rep.fill = fill
    occupied = vox.inside if fill == "inside" else (vox.inside | vox.cut)
    ijk = np.argwhere(occupied).astype(np.int64, copy=False)
    del occupied
    if not len(ijk):
        raise _nothing_fits(part, h, radius, f"no cell of size {_mm(h)} fits inside")
    # the builder's own estimate: the graph itself (about 40 bytes per strut) and the
    # temporaries of tiling, fitting and validation, by blocks (bench_builder_memory.py:
    # 60-130 bytes per strut at the peak; cell-local counts overcount shared struts)
    require_memory(
        len(ijk) * (120 * len(c.edges) + 60 * len(c.nodes)),
        f"a lattice of {len(ijk):,} {c.name} cells (about {len(ijk) * len(c.edges):,} struts)",
        advice="use larger cells",
    )
    nodes, edges = tile_arrays(c, ijk, cell_size=h, origin=vox.origin)[:2]
    del ijk  # the builder's peak comes later (fit): hold only the graph by then
    rep.seconds["tile"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    on_surface = np.zeros(len(nodes), dtype=bool)
    if fill == "clip":
        nodes, edges, on_surface = _clip(local, nodes, edges, rep)
    elif fill == "conform":
        nodes, edges, on_surface = _conform(local, nodes, edges, rep)
    min_len = float(min_strut) * float(h.min())
    if prune or fill != "inside":
        nodes, edges = _cleanup(nodes, edges, on_surface, min_len, fill != "inside", prune, rep)
    if len(edges):
        n_struts = len(edges)

        def advice() -> str:  # only when most of it fell apart
            best, tried = _joined_trials(
                part, c, h, fill, origin, rotation, min_strut, prune, n_struts
            )
            if not best:  # the advice as it is, and what was tried
                said = f" (tried, the share of the struts kept joined: {tried})" if tried else ""
                return JOINED_ADVICE.get(fill, "") + said
            cause = JOINED_CAUSE.get(fill, "")
            said = f" (tried before: {tried})" if tried else ""
            return f"{cause}{'; ' if cause else ''}{best}{said}"

        nodes, edges = keep_main_components(local, nodes, edges, rep, advice=advice)
    rep.seconds["clip"] = time.perf_counter() - t0
    if not len(edges) and auto and fill == "inside":
        # whole cells fit, but none keeps a strut once the dangling ones are pruned (cells
        # alone in a thin coil or rod): the conforming fill, as when no cell fits
        return voxel_lattice(
            part, c, h, radius, fill=auto_fallback, origin=origin, rotation=rotation,
            min_strut=min_strut, prune=prune, min_radius=min_radius, fit=fit,
            return_report=return_report, segments=segments, profile=profile,
        )  # fmt: skip
    if not len(edges) and fill in ("clip", "conform") and origin is None:
        # a part thinner than the cells (a rod) can lie between the grid's nodes, so that
        # no strut has an end inside it: the grid moved to put a node at its deepest point
        shifted = _origin_at_deepest(local, c, h)
        if shifted is not None:
            again = voxel_lattice(
                part, c, h, radius, fill=fill, origin=shifted, rotation=rotation,
                min_strut=min_strut, prune=prune, min_radius=min_radius, fit=fit,
                return_report=True, segments=segments, profile=profile,
            )  # fmt: skip
            assert isinstance(again, tuple)
            graph, moved = again
            moved.origin_moved = True
            return (graph, moved) if return_report else graph
    if not len(edges):
        raise _nothing_fits(
            part, h, radius, f"no strut of {_mm(h)} cells is left inside", fill=fill
        )
    if rot is not None:
        nodes = nodes @ rot.T
    if wall is not None and fill in ("clip", "conform"):
        nodes, edges, radius = _without_wall_struts(part, nodes, edges, radius, wall, rep)
    t0 = time.perf_counter()
    try:
        graph = _finish(
            nodes, edges, radius, min_radius, fit, rep, owned=True,
            segments=segments, profile=profile,
        )  # fmt: skip
    except FitError as err:
        if fit != "shrink":
            raise
        graph = _finish_without_unstitchable(
            part, local, rot, nodes, edges, radius, min_radius, rep, err,
            segments=segments, profile=profile,
        )  # fmt: skip
    rep.seconds["fit"] = time.perf_counter() - t0
    if fill in ("clip", "conform") and len(graph.radii):
        refuse_too_thick(part, nodes, graph, radius, rep, h=h, fill=fill)
    return (graph, rep) if return_report else graph


def refuse_too_thick(
    part: Part,
    nodes: NDArray[np.float64],
    graph: LatticeGraph,
    asked: RadiusSpec,
    rep: BuildReport,
    *,
    h: NDArray[np.float64],
    fill: str,
    fitted: bool = True,
) -> None:
    """Raise :class:`FillError` (with the radius that fits) when the struts of a lattice
    that follows the part's walls (clip, conform, tet) are too thick for the part.

    That is, when 2 r is at least ``THICKER_THAN_PART`` times the part's greatest thickness
    (``Part.inscribed_radius``, a lower bound), for r either

    - the median radius after the fit: the trim would cut nearly every strut away (a 2 m
      I-beam of 5-8 mm walls with 22 mm struts: a 76-triangle fragment was written), or
    - the median radius asked, when the fit thinned more than ``MOST_THINNED`` of the
      struts below ``config.THIN_TOLERANCE`` times it (``rep.thinned_beyond_tolerance``):
      the lattice written would not be the one asked (a 1.2 mm sheet enclosure at
      r = 0.69: bcc's conform fill thinned 1,455 of 1,479 struts below 0.7 x and tet all
      6,482, where kelvin's, which its fit did not thin, was refused).

    Parameters
    ----------
    part : Part
        In the frame of ``nodes`` (the world frame).
    nodes : (N, 3) float64
        The graph's nodes.
    graph : LatticeGraph
        The fitted graph.
    asked : float, (M,), (M, 2) or callable
        The radius asked (:mod:`conformal.radius`).
    rep : BuildReport
        The build's report (its ``thinned_beyond_tolerance``).
    h : (3,) float64
        Cell size (tet: the tet size), for the advice.
    fill : str
        The fill, for the advice.
    fitted : bool
        Test the radius after the fit too (the voxel fills). A tet lattice's struts join
        nodes of a mesh of the part, so their axes lie inside it, and a strut a little
        thicker than the part is trimmed to it, not cut away (the sheet-metal bracket,
        2.28 mm thick at r = 1.27: 11 of 719 struts thinned, written in one body).
    """
    n = graph.num_edges
    if not n:
        return
    r_fit = float(np.median(graph.radii))
    if fitted and _thicker_than_part(part, nodes, r_fit):
        raise _nothing_fits(
            part, h, r_fit, f"no strut of radius {r_fit:.4g} mm fits inside", fill=fill
        )
    if rep.thinned_beyond_tolerance <= MOST_THINNED * n:
        return
    r_asked = float(np.median(resolve_radii(asked, nodes, graph.edges)))
    if _thicker_than_part(part, nodes, r_asked):
        raise _nothing_fits(
            part, h, r_asked,
            f"no strut of radius {r_asked:.4g} mm fits inside",
            fill=fill,
            note=f" (the fit would thin {rep.thinned_beyond_tolerance:,} of {n:,} struts below "
            f"{config.THIN_TOLERANCE:g} x that radius to stitch them)",
        )  # fmt: skip


def struts_in_wall(
    part: Part,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    wall: float,
) -> NDArray[np.bool_]:
    """(M,) bool: the struts that lie wholly inside a skin of thickness ``wall``.

    A strut is inside the wall when every point of its capsule (its axis and the radius
    around it) is within ``WALL_SHARE * wall`` of the part's surface: the skin's cavity
    begins about ``wall`` deep (the voxel method's inner wall was measured up to 7.6 %
    thinner than asked, OCCT's within 2 %), so no part of such a strut reaches it.
    The distance to the surface changes by at most the distance moved, so its largest
    value along the axis is at most the largest at ``K`` evenly spaced samples plus half
    their spacing: the test can only keep a strut that lies in the wall, never drop
    one that does not.

    Parameters
    ----------
    part : Part
        In the frame of ``nodes``.
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M,) float64
        The largest radius of each strut.
    wall : float
        The skin's thickness (mm).
    """
    limit = WALL_SHARE * float(wall) - np.asarray(radii, dtype=np.float64)  # (M,)
    out = np.zeros(len(edges), dtype=bool)
    idx = np.flatnonzero(limit > 0)
    if not len(idx):
        return out
    a, b = nodes[edges[idx, 0]], nodes[edges[idx, 1]]
    reach = float(wall)  # farther than this: inf, not in the wall
    ends = part.distance(np.concatenate([a, b]), max_distance=reach)
    da, db = ends[: len(idx)], ends[len(idx) :]
    near = (da <= limit[idx]) & (db <= limit[idx])
    idx, a, b = idx[near], a[near], b[near]
    if not len(idx):
        return out
    best = np.maximum(da[near], db[near])
    length = np.linalg.norm(b - a, axis=1)
    k = int(min(WALL_SAMPLES, max(2, math.ceil(float(length.max()) / (0.25 * wall)) + 1)))
    t = np.linspace(0.0, 1.0, k)
    for j in range(1, k - 1):  # (the ends are measured above)
        d = part.distance(a + t[j] * (b - a), max_distance=reach)
        np.maximum(best, d, out=best)
    out[idx] = best + 0.5 * length / (k - 1) <= limit[idx]
    return out


def _without_wall_struts(
    part: Part,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radius: RadiusSpec,
    wall: float,
    rep: BuildReport,
) -> tuple[NDArray[np.float64], NDArray[np.int64], RadiusSpec]:
    """``nodes``, ``edges`` and ``radius`` (an array of per-strut radii: its rows kept) without
    the struts inside a skin of thickness ``wall`` (:func:`struts_in_wall`), counted in
    ``rep.removed_in_wall``. The pieces left are joined by the skin (each touches the
    wall where a removed strut was), so no island check follows."""
    r = resolve_radii(radius, nodes, edges)
    inside = struts_in_wall(part, nodes, edges, r.max(axis=1), wall)
    n = int(inside.sum())
    if not n or n == len(edges):  # (all of it: left to the skin's own refusal)
        return nodes, edges, radius
    rep.removed_in_wall = n
    keep = ~inside
    if not callable(radius) and np.ndim(radius) > 0:
        radius = np.asarray(radius)[keep]
    edges = edges[keep]
    used = np.zeros(len(nodes), dtype=bool)
    used[edges.ravel()] = True
    nodes, edges = _renumber(nodes, edges, used)
    return nodes, edges, radius


#: A strut whose capsule lies within this fraction of a skin's thickness of the part's
#: surface is inside the skin's wall (:func:`struts_in_wall`).
WALL_SHARE = 0.8
#: At most this many samples along a strut for :func:`struts_in_wall` (fewer: a looser bound).
WALL_SAMPLES = 33


def _thicker_than_part(part: Part, nodes: NDArray[np.float64], r: float) -> bool:
    """Whether struts of radius ``r`` are too thick for ``part`` (``THICKER_THAN_PART``)."""
    return 2.0 * r >= THICKER_THAN_PART * float(part.size.min()) or (
        not _room_for(part, nodes, r)
        and 2.0 * r >= THICKER_THAN_PART * 2.0 * part.inscribed_radius()
    )


def _room_for(part: Part, nodes: NDArray[np.float64], r: float) -> bool:
    """Whether some of ``nodes`` (up to 2,000 of them, in the frame of ``part``) lies
    inside ``part`` deeper than ``THICKER_THAN_PART * r``: the part is then surely thick
    enough for a strut of radius ``r`` (a quick test before ``Part.inscribed_radius``)."""
    sample = nodes[:: max(1, len(nodes) // 2000)]
    need = THICKER_THAN_PART * r
    depth = part.distance(sample, max_distance=2.0 * need)
    deep = sample[depth > need]  # (inf: farther than 2 need from the surface)
    return bool(len(deep)) and bool(part.contains(deep).any())


#: A clip, conform or tet lattice whose median strut is this many times thicker than the
#: part's greatest thickness (``Part.inscribed_radius``, a lower bound) is refused
#: (:func:`refuse_too_thick`): most struts lie inside the part nowhere (the benchmark's
#: kcl_sheet-metal-bracket, 2.28 mm thick: r = 1.27 asked is 1.11 x too thick).
THICKER_THAN_PART = 1.1

#: ... or whose radius asked is, when the fit thinned more than this fraction of the struts
#: below ``config.THIN_TOLERANCE`` times it (:func:`refuse_too_thick`).
MOST_THINNED = 0.5

#: at most this fraction of a voxel lattice's struts may be dropped as unstitchable
MAX_DROPPED = 0.10


def _finish_without_unstitchable(
    part: Part,
    local: Part,
    rot: NDArray[np.float64] | None,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radius: RadiusSpec,
    min_radius: float | None,
    rep: BuildReport,
    err: FitError,
    *,
    segments: int,
    profile: Profile,
) -> LatticeGraph:
    """The graph without the few struts that cannot be stitched even at the thinnest radius.

    Where the surface cuts or pulls cells (clip, conform), a strut can end up nearly
    parallel to a neighbour; no radius above the floor lets both be stitched. Such struts
    (at most :data:`MAX_DROPPED` of the lattice) are dropped, loose pieces removed, and the
    rest fitted as usual; ``rep.removed_unstitchable`` counts them and a warning says how
    many and where. Otherwise ``err`` (the fit's error, which names a strut) is raised.
    """
    if not (callable(radius) or np.ndim(radius) == 0):
        raise err  # per-strut radii are given for these struts: nothing may be dropped
    r = resolve_radii(radius, nodes, edges)
    floor = fit_floor(nodes, edges, float(r.min()), min_radius)
    keep = unstitchable_dropped(
        nodes, edges, r, min_radius=floor, segments=segments, profile=profile
    )
    dropped = int((~keep).sum())
    if dropped == 0 or dropped > MAX_DROPPED * len(edges):
        raise err
    mids = 0.5 * (nodes[edges[~keep, 0]] + nodes[edges[~keep, 1]])
    edges = edges[keep]
    used = np.zeros(len(nodes), dtype=bool)
    used[edges.ravel()] = True
    nodes, edges = _renumber(nodes, edges, used)
    loc = nodes if rot is None else nodes @ rot  # keep_main_components works in part frame
    loc, edges = keep_main_components(local, loc, edges, rep)
    nodes = loc if rot is None else loc @ rot.T
    rep.removed_unstitchable = dropped
    where = ", ".join("(" + ", ".join(f"{c:.4g}" for c in m) + ")" for m in mids[:3])
    warnings.warn(
        f"{dropped} of {len(keep)} strut(s) ({100 * dropped / len(keep):.2g} %) of the lattice "
        f"of {part.name} were removed: they "
        f"meet a neighbour too closely to be stitched even at radius {floor:g} (e.g. at "
        f"{where}); a smaller radius or another cell avoids it",
        LatticeWarning,
        stacklevel=3,
    )
    return _finish(nodes, edges, radius, min_radius, "shrink", rep, segments=segments,
                   profile=profile)  # fmt: skip


def _mm(h: NDArray[np.float64]) -> str:
    return "x".join(f"{x:.4g}" for x in h) + " mm" if np.ptp(h) > 0 else f"{h[0]:.4g} mm"


def _origin_at_deepest(
    part: Part, c: UnitCell, h: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """A grid origin (3,) that puts the cell's most connected node (the one nearest the
    cell's centre among them) at the part's deepest point (:meth:`Part.deepest_point`), or
    None (no point inside)."""
    deep, r_in = part.deepest_point()
    if not r_in > 0:
        return None
    frac = np.asarray(c.nodes, dtype=np.float64) / c.denominator
    valence = np.bincount(np.asarray(c.edges).ravel(), minlength=len(frac))
    best = np.flatnonzero(valence == valence.max())
    k = best[np.argmin(np.linalg.norm(frac[best] - 0.5, axis=1))]
    return np.asarray(deep - frac[k] * h, dtype=np.float64)


def _nothing_fits(
    part: Part,
    h: NDArray[np.float64],
    radius: RadiusSpec,
    what: str,
    *,
    fill: str = "inside",
    note: str = "",
) -> FillError:
    """A :class:`FillError` that says what would fit the part (``fill``: the fill tried)."""
    r_in = part.inscribed_radius()
    thick = 2.0 * r_in
    # a whole cube of edge c fits in a ball of radius c sqrt(3) / 2
    cube = 2.0 * r_in / math.sqrt(3.0)
    r = float(np.min(radius)) if isinstance(radius, (int, float, np.ndarray)) else float("nan")
    hint = (
        f"its greatest thickness is about {thick:.3g} mm: cells up to about {cube:.3g} mm fit "
        "whole, and fill='conform' fills it with any cell size (fill='clip' too, but cells "
        "much thicker than the part fall apart into pieces, of which it keeps the largest)"
    )
    if fill in ("clip", "conform"):
        hint = (
            f"its greatest thickness is about {thick:.3g} mm, and no strut of these cells "
            f"keeps an end inside it even with a node at its deepest point: use smaller "
            f"cells (about {thick:.3g} mm or less) or another cell (bcc has a node at each "
            "cell's centre)"
        )
    if r == r and 2 * r >= thick:
        hint = (
            f"its greatest thickness is about {thick:.3g} mm, too thin for struts of radius "
            f"{r:g}: use a radius below {0.5 * r_in:.3g} mm"
        )
    return FillError(f"{what} {part.name}{note}; {hint}")


def _homog(r: NDArray[np.float64]) -> NDArray[np.float64]:
    m = np.eye(4)
    m[:3, :3] = r
    return m


def _finish(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radius: RadiusSpec,
    min_radius: float | None,
    fit: str,
    rep: BuildReport,
    *,
    owned: bool = False,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: Profile = config.DEFAULT_PROFILE,
) -> LatticeGraph:
    """Radii, fitting and the graph (shared by the voxel and tet builders).

    ``owned``: ``nodes`` and ``edges`` are the builder's own arrays; the graph takes them
    over without copies (they become read-only). ``segments``, ``profile``: the stitch's
    profile polygons, which the radii are fitted for.
    """
    r = resolve_radii(radius, nodes, edges)
    if fit == "shrink":
        floor = fit_floor(nodes, edges, float(r.min()), min_radius)
        # one radius for all (the usual case): the fit may work on r itself
        same = bool(len(r)) and float(r.min()) == float(r.max())
        r0 = float(r.flat[0]) if same else 0.0
        new, unfit = fit_radii(
            nodes, edges, r, min_radius=floor, overwrite_input=same, segments=segments,
            profile=profile,
        )  # fmt: skip
        if same:
            del r
            r = np.full((1, 2), r0)  # what r held everywhere, for the counts below
        changed = int((new < r).any(axis=1).sum())
        if len(unfit):
            note = floor_note(nodes, edges, floor)
            raise FitError(
                f"{len(unfit)} strut(s) cannot be thinned enough to stitch (min radius {floor:g}"
                f"{note}); e.g. strut {int(unfit[0])} (nodes {edges[unfit[0]].tolist()}); "
                + (
                    "move the part nearer the origin, or use larger cells and a larger radius"
                    if note
                    else "use larger cells, a smaller radius or more segments (--segments), or "
                    "a lower min_radius (--min-radius)"
                )
            )
        if changed:
            warnings.warn(
                f"{changed} of {len(edges)} struts were thinned (down to radius "
                f"{float(new.min()):.4g}) so that every strut can be stitched",
                LatticeWarning,
                stacklevel=3,
            )
        rep.radii_reduced = changed
        # against the radius given here (for a tet lattice, the repair's fitted radii, whose
        # count against the radius asked the tet builder set before)
        beyond = int((new < config.THIN_TOLERANCE * r * (1 - 1e-9)).any(axis=1).sum())
        rep.thinned_beyond_tolerance = max(rep.thinned_beyond_tolerance, beyond)
        r = new
    elif fit == "raise":
        from conformal.radius import fit_problems

        msg = fit_problems(nodes, edges, r, segments=segments, profile=profile)
        if msg:
            raise FitError(
                f"struts would not stitch with these radii: {msg}; "
                "use thinner struts or fit='shrink'"
            )
    rep.min_radius = float(r.min())
    if owned:
        return LatticeGraph._from_owned(nodes, edges, r)
    return LatticeGraph(nodes, edges, r)


# ------------------------------------------------------------------- clip
def _clip(
    part: Part,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    rep: BuildReport,
    *,
    sources: list[NDArray[np.int64]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]]:
    """Cut the struts at the part's surface. The crossing nodes are appended in the order
    of their struts, then along each strut; ``sources``, if given, receives (K,) int64
    struts and (K,) int64 crossing numbers of the K new nodes (the sharded path names
    them by these)."""
    inside = part.contains(nodes)
    a = nodes[edges[:, 0]]
    b = nodes[edges[:, 1]]
    count, params = part.segment_crossings(a, b, cap=8)
    if (count > 8).any():
        count = np.minimum(count, 8)
    plain = count == 0
    keep_plain = plain & inside[edges[:, 0]]
    rep.removed_outside = int((plain & ~inside[edges[:, 0]]).sum())
    new_nodes: list[NDArray[np.float64]] = []
    new_edges: list[NDArray[np.int64]] = [edges[keep_plain]]
    n0 = len(nodes)
    crossed = np.flatnonzero(~plain)
    rep.clipped_struts = len(crossed)
    if len(crossed):
        # sub-intervals between crossings; classify their midpoints
        k = count[crossed]
        t = params[crossed]
        cols = np.arange(params.shape[1] + 1)
        bounds = np.concatenate([np.zeros((len(crossed), 1)), t, np.ones((len(crossed), 1))], 1)
        # put the closing 1 right after the last crossing
        bounds[np.arange(len(crossed)), k + 1] = 1.0
        valid = cols[None, :] <= k[:, None]  # sub-interval j in 0..k
        lo_t = bounds[:, :-1]
        hi_t = bounds[:, 1:]
        mid_t = 0.5 * (lo_t + hi_t)
        ea = a[crossed][:, None, :]
        eb = b[crossed][:, None, :]
        mids = ea + mid_t[:, :, None] * (eb - ea)
        sel = np.argwhere(valid)
        mid_in = np.zeros(valid.shape, dtype=bool)
        mid_in[sel[:, 0], sel[:, 1]] = part.contains(mids[sel[:, 0], sel[:, 1]])
        # node ids: t = 0 -> edges[:,0], t = 1 -> edges[:,1], crossing j -> new node
        cross_ids = np.full(t.shape, -1, dtype=np.int64)
        cv = np.argwhere(cols[None, :-1] < k[:, None])
        cross_ids[cv[:, 0], cv[:, 1]] = n0 + np.arange(len(cv))
        if sources is not None:
            sources.extend([crossed[cv[:, 0]], cv[:, 1].astype(np.int64)])
        pts = a[crossed][cv[:, 0]] + t[cv[:, 0], cv[:, 1]][:, None] * (
            b[crossed][cv[:, 0]] - a[crossed][cv[:, 0]]
        )
        new_nodes.append(pts)
        ids = np.concatenate(
            [edges[crossed, :1], cross_ids, np.full((len(crossed), 1), -1, dtype=np.int64)], 1
        )
        ids[np.arange(len(crossed)), k + 1] = edges[crossed, 1]
        keep = mid_in & valid
        kk = np.argwhere(keep)
        pieces = np.stack([ids[kk[:, 0], kk[:, 1]], ids[kk[:, 0], kk[:, 1] + 1]], axis=1)
        new_edges.append(pieces)
    nodes_out = np.vstack([nodes, *new_nodes]) if new_nodes else nodes
    edges_out = np.vstack(new_edges)
    on_surface = np.zeros(len(nodes_out), dtype=bool)
    on_surface[n0:] = True
    return nodes_out, edges_out, on_surface


# ---------------------------------------------------------------- conform
def _conform(
    part: Part, nodes: NDArray[np.float64], edges: NDArray[np.int64], rep: BuildReport
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]]:
    inside = part.contains(nodes)
    ein = inside[edges]
    keep = ein.any(axis=1)
    rep.removed_outside = int((~keep).sum())
    edges = edges[keep]
    move = np.zeros(len(nodes), dtype=bool)
    move[edges[~inside[edges]]] = True
    idx = np.flatnonzero(move)
    nodes = nodes.copy()
    if len(idx):
        _, cp = part.closest(nodes[idx])
        nodes[idx] = cp
    rep.moved_nodes = len(idx)
    on_surface = move.copy()
    return nodes, edges, on_surface


# ---------------------------------------------------------------- cleanup
def _cleanup(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    on_surface: NDArray[np.bool_],
    min_len: float,
    boundary: bool,
    prune: bool,
    rep: BuildReport,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    n = len(nodes)
    if boundary and len(edges):
        # merge surface nodes closer than min_len to another node (conform: projections can meet)
        edges, _ = merge_close(nodes, edges, on_surface, min_len, rep)
        length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
        short = length < min_len
        rep.removed_short = int(short.sum())
        edges = edges[~short]
    # dangling struts: degree-1 nodes that are not on the surface, repeatedly (the degrees
    # are kept up to date by subtraction; the edges are copied once, at the end)
    alive: NDArray[np.bool_] | None = None
    if prune:
        deg = np.bincount(np.ascontiguousarray(edges).ravel(), minlength=n)
        while True:
            leaf = (deg == 1) & ~on_surface
            if not leaf.any():
                break
            drop = _touching(edges, leaf)
            if alive is not None:
                drop = drop[alive[drop]]
            if not len(drop):
                break
            if alive is None:
                alive = np.ones(len(edges), dtype=bool)
            rep.removed_dangling += len(drop)
            alive[drop] = False
            np.subtract.at(deg, edges[drop].ravel(), 1)
        del deg
    if alive is not None:
        edges = edges[alive]
        del alive
    if boundary and len(edges):
        # fragments: connected pieces without any interior node
        _, lab = _components(n, edges)
        used = np.zeros(n, dtype=bool)
        used[edges.ravel()] = True
        has_interior = np.zeros(lab.max() + 1, dtype=bool)
        has_interior[lab[used & ~on_surface]] = True
        ok = has_interior[lab[edges[:, 0]]]
        rep.removed_fragments = int((~ok).sum())
        edges = edges[ok]
    used = np.zeros(n, dtype=bool)
    used[np.ascontiguousarray(edges).ravel()] = True
    rep.removed_isolated = int((~used).sum())
    return _renumber(nodes, edges, used)


def merge_close(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    on_surface: NDArray[np.bool_],
    min_len: float,
    rep: BuildReport | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64] | None]:
    """Merge every surface node closer than ``min_len`` to another node into it (an
    interior node wins; between two surface nodes the lower id wins).

    The pairs are taken in ascending (i, j) order, so the result depends only on the
    nodes' relative order, not on the k-d tree's traversal (a block of the lattice with
    the nodes in the same order merges a cluster the same way).

    Returns
    -------
    edges : (M', 2) int64
        Renamed onto the surviving nodes, loops dropped, unique, ``edges[:, 0] <
        edges[:, 1]`` (unchanged when nothing merges).
    root : (N,) int64 or None
        The node each node merged into (itself if none); None when nothing merged.
    """
    n = len(nodes)
    if not on_surface.any() or not len(edges):
        return edges, None
    from scipy.spatial import cKDTree

    pairs = cKDTree(nodes).query_pairs(min_len, output_type="ndarray")
    pairs = pairs[on_surface[pairs].any(axis=1)]
    if not len(pairs):
        return edges, None
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    parent = np.arange(n)
    for i, j in pairs.tolist():
        ri, rj = _find(parent, i), _find(parent, j)
        if ri == rj:
            continue
        if on_surface[ri] and not on_surface[rj]:
            parent[ri] = rj
        else:
            parent[rj] = ri
    root = np.array([_find(parent, i) for i in range(n)], dtype=np.int64)
    if rep is not None:
        rep.merged_nodes = int((root != np.arange(n)).sum())
    edges = root[edges]
    edges = edges[edges[:, 0] != edges[:, 1]]
    edges = unique_rows(np.sort(edges, axis=1))
    return edges, root


_BLOCK = 1 << 16


def _touching(edges: NDArray[np.int64], mark: NDArray[np.bool_]) -> NDArray[np.int64]:
    """(K,) int64: the struts with a marked end, ascending (by blocks of struts)."""
    out = []
    for s in range(0, len(edges), _BLOCK):
        e = edges[s : s + _BLOCK]
        hit = mark[e[:, 0]]
        hit |= mark[e[:, 1]]
        out.append(np.flatnonzero(hit) + s)
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def _renumber(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], used: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The ``used`` nodes and the edges renumbered onto them (int64, a new array unless
    every node is used and ``edges`` already is a contiguous int64 array)."""
    if used.all():
        return nodes, np.ascontiguousarray(edges, dtype=np.int64)
    new_id = np.cumsum(used) - 1
    out = np.empty(edges.shape, dtype=np.int64)
    for s in range(0, len(edges), _BLOCK):
        np.take(new_id, edges[s : s + _BLOCK], out=out[s : s + _BLOCK])
    return nodes[used], out


def _components(n: int, edges: NDArray[np.int64]) -> tuple[int, NDArray[np.int64]]:
    """Connected components: their count and the (n,) int64 label of every node, numbered
    in the order of their smallest node (as scipy's ``connected_components``)."""
    return _kernels.component_labels(n, np.ascontiguousarray(edges, dtype=np.int64))


def _solid_shells(part: Part) -> list[Part]:
    """The part's separate solids (``Part.solid_parts``: each outer shell with the walls of
    its cavities, so a solid captive in another's cavity is one of its own)."""
    return part.solid_parts


def shell_owner(shells: list[Part], points: ArrayLike) -> NDArray[np.int64]:
    """(P,) int64: the index in ``shells`` of the solid each of (P, 3) ``points`` lies in.

    A point that no shell contains (it lies on a surface, as a cut lattice's vertices and a
    clipped strut's end do, or within rounding of one) belongs to the nearest shell. Before,
    such a point fell to shell 0, and a speck cut off on the surface of one solid was kept as
    the "largest piece" of another (kcl_enclosure, tet: a second body of 8 triangles).
    """
    p = _as_points(points)
    owner = np.zeros(len(p), dtype=np.int64)
    if len(shells) <= 1 or not len(p):
        return owner
    found = np.zeros(len(p), dtype=bool)
    for i, shell in enumerate(shells):
        inside = shell.contains(p) & ~found
        owner[inside] = i
        found |= inside
    rest = np.flatnonzero(~found)
    if len(rest):
        d = np.stack([s.distance(p[rest]) for s in shells])
        owner[rest] = np.argmin(d, axis=0)
    return owner


def main_components(
    part: Part | None, nodes: NDArray[np.float64], edges: NDArray[np.int64]
) -> tuple[NDArray[np.bool_], int, int]:
    """Which struts belong to the largest connected piece of each separate solid.

    Parameters
    ----------
    part : Part or None
        The part; None treats the lattice as lying in one solid (keep the largest piece).
    nodes : (N, 3) float64
    edges : (M, 2) int64

    Returns
    -------
    keep : (M,) bool
        The struts of the kept pieces.
    pieces : int
        Connected pieces that have struts.
    bodies : int
        Pieces kept (at most one per separate solid of the part).
    """
    n = len(nodes)
    if not len(edges):
        return np.zeros(0, dtype=bool), 0, 0
    k, lab = _components(n, edges)
    elab = lab[edges[:, 0]]
    del lab
    size = np.bincount(elab, minlength=k)
    present = np.flatnonzero(size)
    if len(present) <= 1:
        return np.ones(len(edges), dtype=bool), len(present), len(present)
    shells = _solid_shells(part) if part is not None else []
    # the solid of each piece: the shell that contains the midpoint of its first strut
    first = np.full(k, -1, dtype=np.int64)
    first[elab[::-1]] = np.arange(len(edges))[::-1]
    mids = 0.5 * (nodes[edges[first[present], 0]] + nodes[edges[first[present], 1]])
    owner = shell_owner(shells, mids)
    keep = np.zeros(k, dtype=bool)
    for o in np.unique(owner):
        mine = present[owner == o]
        keep[mine[np.argmax(size[mine])]] = True
    return keep[elab], len(present), int(keep.sum())


#: When the loose pieces removed hold more than this fraction of the struts, the warning
#: says that most of the lattice is gone, and what keeps it (``keep_main_components``).
MOST_REMOVED = 0.5


def keep_main_components(
    part: Part,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    rep: BuildReport,
    *,
    advice: str | Callable[[], str] = "",
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Keep, in each separate solid of the part, only the largest connected piece.

    Smaller pieces would print as loose islands (inside a skin they would rattle in the
    cavity). ``rep.removed_islands`` counts the struts removed, ``rep.bodies`` the pieces
    kept (at most one per solid). See :func:`main_components`. The warning gives the
    share of the struts removed, and ``advice`` (what keeps the lattice joined) when that
    is more than ``MOST_REMOVED``: a clip fill of a part thinner than its cells falls
    apart into pieces of a few struts (the spanner at 18.6 mm cells: 8 of 116 kept). A
    callable ``advice`` is called only then (it may build graphs to find what keeps it).

    nodes : (N, 3) float64, edges : (M, 2) int64. Returns the kept nodes and edges
    (renumbered).
    """
    n = len(nodes)
    ok, pieces, bodies = main_components(part, nodes, edges)
    rep.bodies = bodies
    if pieces <= 1:
        return nodes, edges
    rep.removed_islands = int((~ok).sum())
    total = len(edges)
    edges = edges[ok]
    used = np.zeros(n, dtype=bool)
    used[edges.ravel()] = True
    if rep.removed_islands:
        if callable(advice):
            advice = advice() if rep.removed_islands > MOST_REMOVED * total else ""
        warnings.warn(
            islands_message(rep.removed_islands, total, pieces - rep.bodies, rep.bodies, advice),
            LatticeWarning,
            stacklevel=3,
        )
    return _renumber(nodes, edges, used)


def islands_message(removed: int, total: int, pieces: int, bodies: int, advice: str = "") -> str:
    """The warning of :func:`keep_main_components` (also the sharded fill's): ``removed``
    of ``total`` struts in ``pieces`` loose pieces, ``bodies`` kept; ``advice`` is added
    when that is more than ``MOST_REMOVED`` of the struts."""
    share = removed / total if total else 0.0
    most = f"; that is most of the lattice: {advice}" if advice and share > MOST_REMOVED else ""
    return (
        f"{removed} of {total} strut(s) ({100 * share:.3g} %) in {pieces} loose piece(s) were "
        f"removed: they touched neither the main lattice nor another piece ({bodies} "
        f"body(ies) left, one per separate solid at most){most}"
    )


#: Set while :func:`_joined_trials` builds its graphs (their own warnings try nothing).
_TRYING: ContextVar[bool] = ContextVar("joined_trials", default=False)


def _joined_trials(
    part: Part,
    cell: UnitCell,
    h: NDArray[np.float64],
    fill: FillMode,
    origin: ArrayLike | None,
    rotation: ArrayLike | None,
    min_strut: float,
    prune: bool,
    n_struts: int,
) -> tuple[str, str]:
    """(best, tried): what keeps a fill that fell apart joined, found by building the
    graphs (``config.JOINED_*``): the conform fill at the same size (for inside and clip),
    then smaller cells with the same fill, until one keeps ``config.JOINED_KEPT`` of its
    struts in the main pieces: that one ('cells of 5.625 mm keep 100 % of their struts
    joined', '' if none did), and the others with the share each keeps ('' when nothing
    was tried: a graph would be too large, or trials are running already).

    The spanner's clip at 18.6 mm kept 8 of 116 struts, and the advice "fill='conform'
    joins them" was right there; a threaded rod 8 mm across with 13.3 mm kelvin cells kept
    7 % clipped and 7 % conformed, so that advice was wrong (s24's parts made outside
    shared/data).
    """
    if _TRYING.get():
        return "", ""
    trials: list[tuple[FillMode, float]] = [("conform", 1.0)] if fill in ("inside", "clip") else []
    trials += [(fill, config.JOINED_SHRINK**k) for k in range(1, config.JOINED_TRIALS + 1)]
    r = 1e-6 * float(h.min())  # (the pieces do not depend on the radius: not fitted)
    said: list[str] = []
    token = _TRYING.set(True)
    try:
        for how, scale in trials:
            if n_struts / scale**3 > config.JOINED_TRIAL_STRUTS:
                break
            what = (f"fill='{how}'" if scale == 1.0 else f"cells of {_mm(h * scale)}") + (
                "" if how == fill or scale == 1.0 else f" (fill='{how}')"
            )
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", LatticeWarning)
                    got = voxel_lattice(
                        part, cell, h * scale, r, fill=how, origin=origin,
                        rotation=rotation, min_strut=min_strut, prune=prune, fit="off",
                        return_report=True,
                    )  # fmt: skip
            except FillError:
                said.append(f"{what}: none fits")
                continue
            assert isinstance(got, tuple)
            graph, report = got
            total = graph.num_edges + report.removed_islands
            kept = graph.num_edges / total if total else 0.0
            if kept >= config.JOINED_KEPT:
                verb = "keeps" if scale == 1.0 else "keep"
                return f"{what} {verb} {100 * kept:.0f} % of the struts joined", ", ".join(said)
            said.append(f"{what} {100 * kept:.0f} %")
    finally:
        _TRYING.reset(token)
    return "", ", ".join(said)


#: Why a fill fell apart into loose pieces (said before what was found to keep it joined).
JOINED_CAUSE = {
    "inside": "the part's narrow parts hold no whole cell",
    "clip": "the part is thin for cells of this size, which the clip cuts into separate pieces",
    "conform": "",
}
#: What keeps a fill's lattice joined when most of it fell into loose pieces (when no
#: trial found it, and in the sharded fill, which tries nothing): its cause, then this.
_JOINED_GUESS = {
    "inside": "fill='conform' joins the cells along the surface, or use smaller cells",
    "clip": "fill='conform' joins them along the surface, or use smaller cells",
    "conform": "use smaller cells",
}
JOINED_ADVICE = {
    k: "; ".join(p for p in (JOINED_CAUSE[k], guess) if p) for k, guess in _JOINED_GUESS.items()
}


def _find(parent: NDArray[np.int64], i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = int(parent[i])
    return i
