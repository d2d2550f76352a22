"""The :class:`Lattice`: a part filled with a lattice, ready to mesh, save, validate.

>>> from lattice_cad.lattice import Lattice
>>> from conformal import block
>>> lat = Lattice(block("bcc", 1, cell_size=5.0, radius=0.4))
>>> lat.info()["struts"]
8

``Lattice.fill(part, ...)`` takes a build123d Part/Solid, a cadquery
Workplane/Shape, an OCCT shape, a ``conformal.Part`` or a path (STEP or mesh),
builds the lattice graph with :mod:`conformal` and keeps the part, so that a
skin can be added and a beam-lattice 3MF can carry the part as clipping mesh.
Everything heavy (the mesh, the skin, the exact reference) is built lazily, once.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Callable, Mapping
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, cast

import numpy as np

from lattice_cad.core import config
from lattice_cad.core.arrays import point_text
from lattice_cad.core.checks import check_positive
from lattice_cad.core.errors import (
    EscapeHoleError,
    ExportError,
    FillError,
    LatticeWarning,
    PartError,
    SkinError,
)
from lattice_cad.core.formats import Kind, format_for, resolve, suffixes
from lattice_cad.core.graph import LatticeGraph

if TYPE_CHECKING:
    import cadquery as cq

    from lattice_cad.core.mesh import Mesh

__all__ = ["Lattice", "Method", "Fill", "load_graph"]

Method = Literal["voxel", "tet"]
Fill = Literal["auto", "inside", "clip", "conform"]
#: ``fast_stitch.stitch``'s strut profiles (``fast_stitch.hubvolume.PROFILES``).
Profile = Literal["volume", "area", "inscribed", "circumscribed"]
_PROFILES = ("volume", "area", "inscribed", "circumscribed")


def _check_choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")
    return str(value)


def load_graph(path: str | os.PathLike[str]) -> LatticeGraph:
    """Read a lattice graph (``.json`` / ``.npz``), see :meth:`LatticeGraph.load`."""
    return LatticeGraph.load(path)


def _load_part(
    source: Any,
    units: str | float | None = None,
    close_holes: bool = False,
    on_solids: Any = None,
    move_to_origin: bool = False,
) -> Any:
    """A ``conformal.Part`` from anything :func:`conformal.load_part` accepts (``on_solids``,
    ``move_to_origin``: see there)."""
    from conformal.part import Part, load_part

    if isinstance(source, Part):
        if units is not None:
            raise ValueError("units= applies to mesh files; a loaded Part is in millimetres")
        if move_to_origin:
            raise ValueError(
                "move_to_origin applies when loading a part; load it with "
                "conformal.load_part(..., move_to_origin=True) instead"
            )
        return source
    return load_part(
        source,
        units=units,
        close_holes=close_holes,
        on_solids=on_solids,
        move_to_origin=move_to_origin,
    )


def _fill_graph(
    part: Any,
    *,
    method: str,
    cell: str,
    cell_size: float,
    radius: float,
    fill: str,
    origin: Any,
    rotation: Any,
    segments: int = config.DEFAULT_SEGMENTS,
    min_radius: float | None = None,
    profile: Profile = "volume",
    auto_fallback: Literal["conform", "clip"] = "conform",
    progress: Any = None,
    skin: float | None = None,
) -> tuple[LatticeGraph, Any]:
    """Call the conformal engine (imported lazily) for ``method``: the graph and its report.

    The radii are fitted for the profile polygons the lattice will be stitched with
    (``segments`` sides, ``profile``); with a ``skin``, the voxel method leaves out the
    struts that lie wholly inside its wall (``conformal.voxel_lattice(wall=)``).
    """
    import conformal

    built: Any
    if method == "voxel":
        built = conformal.voxel_lattice(
            part,
            cell=cell,
            cell_size=cell_size,
            radius=radius,
            fill=cast(Any, fill),
            origin=origin,
            rotation=rotation,
            return_report=True,
            segments=segments,
            min_radius=min_radius,
            profile=profile,
            auto_fallback=auto_fallback,
            wall=skin,
        )
    else:
        built = conformal.tet_lattice(
            part,
            size=cell_size,
            radius=radius,
            return_report=True,
            segments=segments,
            min_radius=min_radius,
            profile=profile,
            progress=progress,
        )
    graph, report = built
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"the {method} engine returned {type(graph).__name__}, not a graph")
    return graph, report


def _collapse_folds(mesh: Mesh, report: Any) -> Mesh:
    """Collapse the zero-area faces and the smaller face of each self-intersecting pair
    (manifold3d's booleans leave needles that rounding to float32 can fold)."""
    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh

    v, f = io.collapse_folds(
        mesh.vertices, mesh.faces, report.self_intersection_pairs, report.zero_area_faces
    )
    return Mesh(vertices=v, faces=f)


def _self_supporting_rotation(
    method: str, cell: str, rotation: Any, direction: Any, critical_angle: float
) -> Any:
    """The grid rotation that makes ``cell`` self-supporting along ``direction``, or refuse."""
    from conformal.printability import best_orientation, self_supporting_cells
    from lattice_cad.core.errors import PrintabilityError

    if method != "voxel":
        raise PrintabilityError(
            "self_supporting applies to method='voxel' (a tet lattice has no cell to orient)"
        )
    if rotation is not None:
        raise PrintabilityError("give either rotation or self_supporting=True, not both")
    best = best_orientation(cell, direction)
    if best.min_angle < critical_angle - config.ANGLE_EPS_DEG:
        cells = ", ".join(self_supporting_cells(direction, critical_angle)) or "none"
        raise PrintabilityError(
            f"no orientation makes {cell!r} self-supporting at {critical_angle:g} deg: its "
            f"best leaves struts at {best.min_angle:.4g} deg; cells that are: {cells} "
            "(or use remove_overhangs, or a smaller critical angle)"
        )
    return best.rotation


def _offset_worker(part: Any, skin: float | None) -> Any:
    """A child process for OCCT's skin offsets, started (and importing OpenCascade) before
    the part is loaded, for a skin of a part that may be a B-rep; else None."""
    if skin is None or (
        isinstance(part, (str, os.PathLike))
        and Path(part).suffix.lower() in suffixes(Kind.MESH, action="read")
    ):
        return None
    from lattice_cad.core.isolate import IsolatedWorker

    return IsolatedWorker(warm="lattice_cad.occ_impl.shapes")


def _with_skin_room(exc: FillError, part: Any, skin: float | None) -> FillError:
    """``exc`` (nothing fits the part), saying also when the skin asked leaves no room for
    a lattice either (the part nowhere thicker than twice the skin): changing the cells or
    the radius alone would not give a skinned lattice then. Else ``exc`` itself."""
    if skin is None:
        return exc
    thick = 2.0 * float(part.inscribed_radius())
    if thick > 2.0 * skin:
        return exc
    from conformal.skin import no_room_message

    return FillError(f"{exc}; and the skin leaves no room either: {no_room_message(skin, thick)}")


class _EarlyOffsets:
    """``conformal.load_part(on_solids=)`` for a skin: OCCT's offsets started in ``worker``
    from the part's solids as soon as they are read, while the part is tessellated and
    checked (on the GE bracket 1.2 s earlier than after the load, so that they are in
    when the lattice is stitched)."""

    def __init__(self, worker: Any, skin: float) -> None:
        self.worker, self.skin = worker, skin
        self.pending: Any = None

    def __call__(self, solids: list[Any]) -> None:
        from conformal.skin import start_solid_offsets

        if self.pending is not None or self.worker.submitted:
            return  # (one call per worker)
        try:
            self.pending = start_solid_offsets(solids, self.skin, worker=self.worker)
        except Exception:  # noqa: BLE001 - started again after the load, or by build_skin
            self.pending = None


def _start_offsets(worker: Any, part: Any, skin: float | None, early: Any = None) -> Any:
    """OCCT's offsets of a B-rep part started in ``worker`` (``conformal.skin.start_offsets``),
    or None (the worker closed) when the part is a mesh; ``early``: an :class:`_EarlyOffsets`
    whose offsets, started during the load, are used when they are of this part's solids."""
    if worker is None:
        return None
    if skin is None or part.shape is None:
        worker.close()
        return None
    if early is not None and early.pending is not None:
        if early.pending.adopt(part):
            return early.pending
        worker.close()
        return None  # (build_skin starts them again)
    from conformal.skin import start_offsets

    try:
        return start_offsets(part, skin, worker=worker)
    except Exception:  # noqa: BLE001 - build_skin starts them again and reports the failure
        worker.close()
        return None


#: A cut that removes more than this fraction of the lattice's volume is said in a warning.
MOSTLY_CUT = 0.5


def _warn_mostly_cut(report: Any, graph: LatticeGraph) -> None:
    """Warn when the cut to the part removed most of the lattice (struts that run outside
    a concave part: a 3 m machine bed with 200 mm cells lost 94 % of its conforming lattice's
    volume and was written with one report line)."""
    share = report.share_removed
    if not share > MOSTLY_CUT:
        return
    lengths = np.linalg.norm(
        graph.nodes[graph.edges[:, 1]] - graph.nodes[graph.edges[:, 0]], axis=1
    )
    warnings.warn(
        f"the cut to the part's surface removed {100 * share:.0f} % of the lattice's volume: "
        f"its struts (median length {float(np.median(lengths)):.3g} mm) mostly run outside "
        "the part, which is thin or hollow for cells of this size; smaller cells keep more "
        "of the lattice inside it",
        LatticeWarning,
        stacklevel=4,
    )


def _checked_single_precision(mesh: Mesh, name: str) -> Mesh:
    """A boolean result (skin, trim) rounded to float32 as STL and 3MF store it, checked in
    full (with the folds the rounding makes collapsed), or :class:`ExportError`.

    If the rounding breaks it, the slivers the booleans left (thinner than float32's
    spacing) are collapsed first by manifold3d's ``simplify`` with a tolerance of
    ``config.SIMPLIFY_ULPS`` float32 steps at the mesh's largest coordinate (the solid
    stays 2-manifold and moves by at most that), and the result is checked again; then
    with 4 and 16 times that tolerance.
    """
    try:
        return _checked_single_precision_once(mesh, name)
    except ExportError:
        from conformal.skin import as_manifold, to_arrays
        from lattice_cad.core.mesh import Mesh

        extent = float(np.abs(mesh.vertices).max()) if len(mesh.vertices) else 1.0
        ulp = float(np.spacing(np.float32(max(extent, 1.0))))
        solid = as_manifold(mesh, name=name)
        for k in (1, 4):  # a pinch left by one tolerance can go with a larger one
            v, f = to_arrays(solid.simplify(k * config.SIMPLIFY_ULPS * ulp))
            try:
                return _checked_single_precision_once(Mesh(vertices=v, faces=f), name)
            except ExportError:
                continue
        v, f = to_arrays(solid.simplify(16 * config.SIMPLIFY_ULPS * ulp))
        return _checked_single_precision_once(Mesh(vertices=v, faces=f), name)


def _short(message: str, limit: int) -> str:
    """The first line of ``message``, cut to at most ``limit`` characters at the end of a
    clause ("; ") or, failing that, of a word, with "..." (a trim's report ended "a fin or
    sliver too thin to be stored (it is near t" mid-word: s37's new parts)."""
    line = message.splitlines()[0] if message else ""
    if len(line) <= limit:
        return line
    head = line[: limit - 3]
    cut = head.rfind("; ")
    if cut < limit // 3:
        cut = len(head) if line[len(head)] == " " else head.rfind(" ")
    return (head[:cut] if cut > 0 else head).rstrip(" ,;") + "..."


def _too_folded(mesh: Mesh) -> bool:
    """Whether more than ``config.TRIM_HOPELESS_SHARE`` of the (float64) mesh's triangles
    intersect another, in pairs (``fast_stitch.check``): a cut too folded for the collapses
    of float32's folds to repair."""
    import fast_stitch

    pairs = fast_stitch.check(mesh, max_report=1).n_self_intersections or 0
    return bool(pairs > config.TRIM_HOPELESS_SHARE * len(mesh.faces))


def _checked_single_precision_once(mesh: Mesh, name: str) -> Mesh:
    """:func:`_checked_single_precision` without the sliver collapse."""
    import fast_stitch
    from fast_stitch.recheck import recheck, with_topology
    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh, weld
    from lattice_cad.io.rounding import cancel_opposite_faces, weld_merges

    out, _ = io.single_precision(mesh, name=name)
    # readers that merge vertices closer than config.NEAR_VERTEX (trimesh, and the tools
    # built on it) must find the same closed solid: merged before the (costly) full check,
    # so that a mesh needing no repair is checked once. A weld that merges nothing leaves
    # the mesh as it is: weld_merges asks that without weld's sort.
    if weld_merges(out.vertices, config.NEAR_VERTEX):
        from lattice_cad.io.rounding import pinched_vertices, repair_rounded

        v2, f2 = weld(out.vertices, out.faces, tol=config.NEAR_VERTEX)
        v2, f2, _ = cancel_opposite_faces(v2, f2)  # fins thinner than that: back to back
        if len(pinched_vertices(f2, len(v2))):  # two sheets merged there: separated again
            v2, f2 = repair_rounded(v2, f2)
        out = Mesh(vertices=v2, faces=f2)
    listed = config.COLLAPSE_MAX_REPORT
    for attempt in range(2):
        report = fast_stitch.check(out, max_report=listed)
        rounds = 0
        first = (report.n_self_intersections or 0) + report.n_zero_area
        # tiny folds where the booleans left needles: collapse them, rechecking the
        # self-intersections and zero-area faces near the collapsed faces only (the rest
        # is as checked, and a collapse looks at nothing else); the topology once, after
        while (report.n_self_intersections or report.n_zero_area) and rounds < 20:
            before, out = out, _collapse_folds(out, report)
            report = recheck(before, report, out, max_report=listed, topology=False)
            rounds += 1
            now = (report.n_self_intersections or 0) + report.n_zero_area
            if now > config.COLLAPSE_DIVERGES * max(first, config.COLLAPSE_DIVERGES_FROM):
                # the collapses make more folds than they remove (a coffee mug's skin,
                # made outside shared/data: 9,623 pairs, then 15,486, 22,720, ... 41,997,
                # still 8,776 after 20 rounds of 50 s): not to be repaired this way
                break
        if rounds:
            report = with_topology(out, report, max_report=listed)
        if not report.valid:
            raise ExportError(
                f"{name} cannot be written in single precision (STL, 3MF): rounding its "
                f"coordinates to float32 breaks it ({report})"
            )
        # readers that merge vertices closer than config.NEAR_VERTEX (trimesh, and the
        # tools built on it) must find the same closed solid: merge them here, check again
        if attempt == 1 or not weld_merges(out.vertices, config.NEAR_VERTEX):
            break
        v2, f2 = weld(out.vertices, out.faces, tol=config.NEAR_VERTEX)
        v2, f2, _ = cancel_opposite_faces(v2, f2)
        out = Mesh(vertices=v2, faces=f2)
    return out


class _HeldWarnings:
    """Warnings issued inside ``with`` blocks of this object (one at a time) are held, not
    shown (when ``active``); :meth:`release` issues them then, each text once, through the
    filters in force, and :meth:`drop` forgets them. An exception other than
    :class:`ExportError` (float32 cannot hold the mesh: a retry may follow) leaving a block
    releases them first. For a skin's attempts: the warnings of one whose mesh a retry
    replaces are not the written mesh's (a knee implant's skin said two different wall
    thicknesses, one of a skin thrown away, s38)."""

    def __init__(self, *, active: bool = True):
        self.active = active
        self.records: list[warnings.WarningMessage] = []
        self._block: Any = None

    def __enter__(self) -> _HeldWarnings:
        if self.active:
            self._block = warnings.catch_warnings(record=True)
            self._got = self._block.__enter__()
            warnings.simplefilter("always")
        return self

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if self.active:
            self._block.__exit__(kind, exc, tb)
            self.records.extend(self._got)
            if kind is not None and not issubclass(kind, ExportError):
                self.release()

    def release(self) -> None:
        records, self.records = self.records, []
        said = set()
        for w in records:  # (held under "always": once each, as the "default" action)
            key = (str(w.message), w.category, w.filename, w.lineno)
            if key not in said:
                said.add(key)
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)

    def drop(self) -> None:
        self.records = []


class Lattice:
    """A lattice graph, optionally with the part it fills and a skin.

    Parameters
    ----------
    graph : LatticeGraph
    part : conformal.Part, optional
        The filled part (needed for ``skin`` and for a beam lattice's clipping mesh).
    skin : float, optional
        Wall thickness of the part's skin; the printable solid is then the skin
        united with the lattice (see :mod:`conformal.skin`).
    segments : int
        Sides of every strut's polygonal profile in the stitched mesh (>= 3).
    profile : {"volume", "area", "inscribed", "circumscribed"}
        The stitched struts' profile (``fast_stitch.stitch``). ``"volume"`` (default): the
        mesh has the exact design's volume (within 0.01 % on the GE bracket lattices at
        P = 6): struts are the circle's equal-area polygon and each hub is scaled to the
        exact node volume. The hull of an irregular node holds more than the design's
        ball and cylinders, so that scale is below 1 there and each strut meets its hub in
        a neck: on the GE bracket tet lattice the hub ring's circumradius is 0.88 r
        (median), down to 0.75 r (``benchmarks/results/bench_reference_volume_win.txt``).
        ``"area"``: the same struts with unscaled hubs, no neck, heavier (+1.4 % on the
        Box-BCC lattice, +10.8 % on the tet lattice, P = 6). ``"inscribed"``: strut
        polygons inside the circle (struts thinner than the design; hubs unscaled, so on
        irregular nodes it can even outweigh ``"volume"``); ``"circumscribed"``: polygons
        around it (struts contain the design's cylinders).
    trim : bool
        Cut the lattice by the part's surface (with a part and no skin), so the printable
        solid never lies outside the part (see :mod:`conformal.trim`). Default True.
    escape_holes : float, optional
        With a skin: drill escape holes of this diameter (mm) so that every enclosed
        cavity opens to the outside, and verify it (see :mod:`conformal.escape`).
    escape_at : (P, 3) float, optional
        User hole positions (mm) on the outer surface; cavities they do not open get a
        hole at their lowest point.
    build_direction : (3,) float, optional
        Up direction of the print (default +Z): holes go at the lowest points along it.

    Attributes
    ----------
    graph : LatticeGraph
    part : conformal.Part or None
    skin : float or None
    segments : int
    build_direction : (3,) float
        Printability settings used by :meth:`printability` and :meth:`info` (defaults
        +Z, ``config.OVERHANG_ANGLE_DEG``, ``config.MIN_STRUT_DIAMETER``; set by
        :meth:`fill` or by hand).
    critical_angle : float
    min_diameter : float
    overhang_removal : conformal.printability.OverhangRemoval or None
        What ``fill(..., remove_overhangs=True)`` removed.
    keep : tuple of conformal.keep.KeepZone
        Keep-solid zones (see :meth:`fill`), resolved on the part.
    """

    _pending_offsets: Any  # OCCT's offsets started by fill(), collected by the skin

    def __init__(
        self,
        graph: LatticeGraph,
        *,
        part: Any = None,
        skin: float | None = None,
        segments: int = config.DEFAULT_SEGMENTS,
        profile: Profile = "volume",
        trim: bool = True,
        escape_holes: float | None = None,
        escape_at: Any = None,
        build_direction: Any = None,
        keep: Any = None,
    ) -> None:
        if not isinstance(graph, LatticeGraph):
            raise TypeError(f"graph must be a LatticeGraph, got {type(graph).__name__}")
        if skin is not None:
            skin = check_positive("skin", skin)
            if part is None:
                raise ValueError("a skin needs the part: use Lattice.fill(part, skin=...)")
        if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)):
            raise TypeError(f"segments must be an integer >= 3, got {segments!r}")
        if segments < 3:
            raise ValueError(f"segments must be >= 3, got {segments}")
        self.graph = graph
        self.part = part
        self.skin = skin
        #: How the skin was made and its measured wall (set when the mesh is built).
        self.skin_report: Any = None
        #: The retry that gave a skinned mesh float32 can hold ("mid-wall", "shifted",
        #: "shifted mid-wall", "coarse"), None when the first attempt did.
        self.skin_retry: str | None = None
        #: Enclosed voids too small to drain that the escape holes' step filled.
        self.escape_voids_filled = 0
        #: What the lattice builder did (``conformal.BuildReport``; set by :meth:`fill`).
        self.build_report: Any = None
        self.segments = int(segments)
        self.profile: Profile = cast(Profile, _check_choice("profile", profile, _PROFILES))
        if not isinstance(trim, (bool, np.bool_)):
            raise TypeError(f"trim must be True or False, got {trim!r}")
        self.trim = bool(trim)
        #: How the lattice was cut to the part (``conformal.trim.TrimReport``; set when the
        #: mesh is built, None when there was nothing to trim against).
        self.trim_report: Any = None
        #: How the beams of the last beam-lattice 3MF were clipped to the part
        #: (``conformal.beam_clip.BeamClipReport``; None before one is written).
        self.beam_clip_report: Any = None
        self.progress: bool = False
        self.build_direction: Any = config.BUILD_DIRECTION
        self.critical_angle: float = config.OVERHANG_ANGLE_DEG
        self.min_diameter: float = config.MIN_STRUT_DIAMETER
        self.overhang_removal: Any = None
        #: The beam FE model last written by :meth:`save_inp` (``lattice_cad.io.fe.BeamModel``).
        self.fe_model: Any = None
        if escape_holes is not None or escape_at is not None:
            if skin is None:
                raise ValueError("escape holes open the cavity of a skin: pass skin= as well")
            escape_holes = check_positive("escape_holes", escape_holes or config.ESCAPE_DIAMETER)
        if escape_at is not None:
            try:
                escape_at = np.asarray(escape_at, dtype=np.float64).reshape(-1, 3)
            except (TypeError, ValueError):
                raise ValueError(
                    f"escape_at must be points (P, 3) in mm, got {escape_at!r}"
                ) from None
        self.escape_holes = escape_holes
        self.escape_at = escape_at
        if build_direction is not None:
            self.build_direction = build_direction
        #: Cavities, holes and the flood-fill verdict (``conformal.escape.EscapeReport``).
        self.escape_report: Any = None
        #: What the last B-rep build did (``lattice_cad.brep.BrepReport``; STEP, to_workplane).
        self.brep_report: Any = None
        #: Keep-solid zones (issue 13): resolved faces or boxes, built with the mesh.
        self.keep: tuple[Any, ...] = ()
        #: The zones' volumes, faces matched and bodies (set when the mesh is built).
        self.keep_report: Any = None
        if keep is not None:
            if part is None:
                raise ValueError("keep-solid zones need the part: use Lattice.fill(part, keep=...)")
            from lattice_cad.keep import resolve_keep

            self.keep = resolve_keep(part, keep)

    # ---------------------------------------------------------------- build
    @classmethod
    def fill(
        cls,
        part: Any,
        cell: str = config.DEFAULT_CELL,
        cell_size: float = config.DEFAULT_CELL_SIZE,
        radius: float = config.DEFAULT_RADIUS,
        *,
        method: Method = "voxel",
        fill: Fill | None = None,
        skin: float | None = None,
        segments: int = config.DEFAULT_SEGMENTS,
        profile: Profile = "volume",
        min_radius: float | None = None,
        origin: Any = None,
        rotation: Any = None,
        trim: bool = True,
        build_direction: Any = None,
        critical_angle: float | None = None,
        min_diameter: float | None = None,
        remove_overhangs: bool = False,
        self_supporting: bool = False,
        escape_holes: float | None = None,
        escape_at: Any = None,
        keep: Any = None,
        units: str | float | None = None,
        close_holes: bool = False,
        move_to_origin: bool = False,
        progress: Callable[[str, int, int], None] | None = None,
    ) -> Lattice:
        """Fill a part with a lattice.

        Parameters
        ----------
        part : build123d Part/Solid, cadquery Workplane/Shape, TopoDS_Shape, conformal.Part or path
            A path may name a STEP file or a closed mesh (STL, OBJ, PLY, 3MF, OFF).
            Coordinates are global (a cadquery Workplane's solids where they are).
        cell : str
            Unit cell name (see ``conformal.CELLS`` or ``lattice-cad cells``).
        cell_size : float
            Cell edge length (mm) for ``method="voxel"``; target element size for ``"tet"``.
        radius : float
            Strut radius (mm).
        method : {"voxel", "tet"}
            Periodic cells on a grid, or struts along the edges of a tetrahedral mesh.
        fill : {"auto", "inside", "clip", "conform"}, optional
            How the voxel lattice meets the boundary (see ``conformal.voxel_lattice``);
            default ``"clip"`` with a skin or ``keep`` zones (struts reach into the wall
            and the zones), else ``"auto"`` (``"inside"`` when whole cells fill at least
            ``config.AUTO_INSIDE_SHARE`` of the part, else ``"conform"``, or ``"clip"``
            with ``self_supporting``, whose struts keep their directions).
            Voxel only: a tet lattice always conforms (its surface nodes lie on the
            part's surface), so passing ``fill`` with ``method="tet"`` is an error.
        skin : float, optional
            Hollow the part to this wall thickness and unite the wall with the lattice.
        segments : int
            Profile sides of the stitched struts.
        profile : {"volume", "area", "inscribed", "circumscribed"}
            The stitched struts' profile (see :class:`Lattice`); the radii are fitted for
            it. Default ``"volume"``: the design's exact volume.
        min_radius : float, optional
            Thinnest a strut may be made so that it stitches where struts meet at small
            angles (default a tenth of ``radius``); struts that would need less raise
            ``FitError`` naming them.
        origin, rotation : optional
            Placement of the cell grid (passed to ``conformal.voxel_lattice``; voxel only).
            ``cell`` is ignored by ``method="tet"``.
        trim : bool
            Cut struts by the part's surface so the printable solid keeps the part's size
            (default; with a skin the struts end inside the wall instead).
        build_direction : (3,) float, optional
            Direction the layers grow in (any non-zero vector; default +Z), for the
            printability report (:meth:`printability`) and the options below.
        critical_angle : float, optional
            Struts below this angle to the build plate (degrees) are overhangs (default 35).
        min_diameter : float, optional
            Struts thinner than this (mm) are reported as thin (default 0.4).
        remove_overhangs : bool
            Remove the overhanging struts, then the loose pieces that leaves (see
            ``conformal.remove_overhangs``); ``overhang_removal`` says what went.
        self_supporting : bool
            Voxel only: rotate the cell grid so that the cell's smallest strut angle to the
            build plate is largest (``conformal.best_orientation``; e.g. cubic with a body
            diagonal along the build direction). Refused with ``rotation``, and when even
            the best orientation leaves struts below the critical angle.
        escape_holes : float, optional
            With ``skin``: hole diameter (mm); every enclosed cavity gets a hole (at its
            lowest point along ``build_direction``, or at ``escape_at``), and a flood
            fill of the final solid verifies that every cavity connects to the outside
            (``escape_report``; :class:`EscapeHoleError` if a cavity stays closed).
        escape_at : (P, 3) float, optional
            Points (mm) on the outer surface where holes are drilled along the wall
            normal (implies ``escape_holes`` of ``config.ESCAPE_DIAMETER`` if not given).
        keep : (faces, thickness), "SELECTOR:THICKNESS" or a list of them, optional
            Keep-solid zones: the part stays solid within ``thickness`` mm of the faces
            (a CadQuery selector such as ``">Z"`` or ``"%CYLINDER"``, build123d/cadquery
            faces, or a box ``((xmin, ymin, zmin), (xmax, ymax, zmax))`` with a margin);
            struts that enter a zone join it. See :mod:`lattice_cad.keep`.
        units : str or float, optional
            Unit of a mesh file (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ...) or millimetres
            per file unit (default millimetres; see :func:`conformal.load_part`). STEP files
            declare their unit, so passing it for one is an error.
        close_holes : bool
            Close the holes of an open mesh file with least-area patches, with a warning
            (see :func:`conformal.load_part`), instead of refusing it.
        move_to_origin : bool
            Move the part so that its bounding box is centred on the origin before filling
            it; ``lattice.part.moved_by`` is the translation, and the lattice and every file
            written are in the moved coordinates (as are ``origin``, keep boxes and
            ``escape_at``). For parts far from the origin (plant coordinates), where single
            precision (STL, 3MF) cannot resolve the struts; slicers place the part on their
            bed anyway.
        progress : callable, optional
            ``progress(stage, done, total)`` says which step of the fill runs (for
            ``method="tet"``: which gmsh attempt; see ``conformal.tet_mesh``).

        Returns
        -------
        Lattice

        Raises
        ------
        conformal.PartError
            The part cannot be read or is not a closed solid.
        PrintabilityError
            A zero build direction, an angle outside 0..90, a cell that no rotation makes
            self-supporting, or nothing left after removing the overhangs.
        KeepError
            A keep selector matches no face (the message lists the part's faces).
        ValueError, TypeError
            An option out of range (named in the message).
        """
        _check_choice("method", method, ("voxel", "tet"))
        _check_choice("profile", profile, _PROFILES)
        if method == "tet":
            given = [k for k, v in (("fill", fill), ("origin", origin), ("rotation", rotation))
                     if v is not None]  # fmt: skip
            if given:
                verb = "applies" if len(given) == 1 else "apply"
                raise ValueError(
                    f"{' and '.join(given)} only {verb} to method='voxel'; a tet lattice "
                    "follows the part's surface by construction (leave them out)"
                )
        if fill is None:  # with a skin or keep zones, struts must reach the boundary
            fill = "clip" if skin is not None or keep is not None else "auto"
        _check_choice("fill", fill, ("auto", "inside", "clip", "conform"))
        if not isinstance(cell, str):
            raise TypeError(f"cell must be a cell name, got {type(cell).__name__}")
        from conformal import CELLS

        if method == "voxel" and cell not in CELLS:
            raise ValueError(f"unknown cell {cell!r}; choose from {', '.join(sorted(CELLS))}")
        cell_size = check_positive("cell_size", cell_size)
        radius = check_positive("radius", radius)
        if skin is not None:
            skin = check_positive("skin", skin)
        from conformal import printability as _pr

        direction = _pr.as_build_direction(
            config.BUILD_DIRECTION if build_direction is None else build_direction
        )
        crit = _pr.as_critical_angle(
            config.OVERHANG_ANGLE_DEG if critical_angle is None else critical_angle
        )
        dmin = _pr.as_min_diameter(
            config.MIN_STRUT_DIAMETER if min_diameter is None else min_diameter
        )
        if self_supporting:
            rotation = _self_supporting_rotation(method, cell, rotation, direction, crit)
        worker = _offset_worker(part, skin)  # OCCT's offsets start while the lattice is built
        early = _EarlyOffsets(worker, skin) if worker is not None and skin is not None else None
        try:
            the_part = _load_part(
                part, units, close_holes, on_solids=early, move_to_origin=move_to_origin
            )
        except BaseException:
            if worker is not None:
                worker.close()
            raise
        # the child offsets the part while this process builds and stitches the lattice
        pending = _start_offsets(worker, the_part, skin, early)
        try:
            zones = None
            if keep is not None:  # resolved before the lattice: a wrong selector fails fast
                from lattice_cad.keep import resolve_keep

                zones = resolve_keep(the_part, keep)
            try:
                graph, report = _fill_graph(
                    the_part,
                    method=method,
                    cell=cell,
                    cell_size=cell_size,
                    radius=radius,
                    fill=fill,
                    origin=origin,
                    rotation=rotation,
                    segments=segments,
                    min_radius=min_radius,
                    profile=profile,
                    # a self-supporting grid stays so only if the struts keep their directions
                    auto_fallback="clip" if self_supporting else "conform",
                    progress=progress,
                    skin=skin,
                )
            except FillError as exc:
                raise _with_skin_room(exc, the_part, skin) from exc
            removal = None
            if remove_overhangs:
                graph, removal = _pr.remove_overhangs(
                    graph, build_direction=direction, critical_angle=crit, part=the_part
                )
            lat = cls(
                graph,
                part=the_part,
                skin=skin,
                segments=segments,
                profile=profile,
                trim=trim,
                escape_holes=escape_holes,
                escape_at=escape_at,
                build_direction=direction,
            )
            lat.keep = zones or ()
            lat.build_report = report
            lat.build_direction, lat.critical_angle, lat.min_diameter = direction, crit, dmin
            lat.overhang_removal = removal
        except BaseException:  # the child is not left running for a failed fill
            if pending is not None:
                pending.worker.close()
            raise
        lat._pending_offsets = pending
        return lat

    def printability(
        self,
        *,
        build_direction: Any = None,
        critical_angle: float | None = None,
        min_diameter: float | None = None,
    ) -> Any:
        """Overhanging and thin struts, unsupported nodes (``conformal.printability``).

        Options left out take the lattice's ``build_direction``, ``critical_angle`` and
        ``min_diameter``.

        Returns
        -------
        conformal.PrintabilityReport
        """
        from conformal.printability import printability

        return printability(
            self.graph,
            build_direction=self.build_direction if build_direction is None else build_direction,
            critical_angle=self.critical_angle if critical_angle is None else critical_angle,
            min_diameter=self.min_diameter if min_diameter is None else min_diameter,
        )

    def __repr__(self) -> str:
        part = f", part={getattr(self.part, 'name', 'part')!r}" if self.part is not None else ""
        skin = f", skin={self.skin:g}" if self.skin is not None else ""
        prof = f", profile={self.profile!r}" if self.profile != "volume" else ""
        return (
            f"Lattice({self.graph.num_nodes} nodes, {self.graph.num_edges} struts, "
            f"segments={self.segments}{prof}{part}{skin})"
        )

    # ----------------------------------------------------------------- mesh
    @cached_property
    def _lattice_mesh(self) -> Mesh:
        import fast_stitch

        return fast_stitch.stitch(
            self.graph, self.segments, profile=self.profile, progress=self.progress
        )

    @cached_property
    def _kept_mesh(self) -> Mesh:
        """The lattice united with its keep-solid zones (the lattice when it has none)."""
        if not self.keep:
            return self._lattice_mesh
        from conformal.keep import build_keep
        from lattice_cad.core.mesh import Mesh

        result = build_keep(self._lattice_mesh, self._cutting_part, self.keep)
        self.keep_report = result.report
        return Mesh(vertices=result.vertices, faces=result.faces)

    @cached_property
    def _solid_mesh(self) -> Mesh:
        from conformal import skin as _skin
        from lattice_cad.core.mesh import Mesh

        if self.skin is None:
            if self.part is None or not self.trim or self.graph.num_edges == 0:
                return self._kept_mesh
            trimmed = self._cut()  # checked below, after rounding to float32
            self.trim_report = trimmed.report
            _warn_mostly_cut(trimmed.report, self.graph)
            self._split = trimmed.split
            if not trimmed.report.trimmed:
                return self._kept_mesh
            v, f = _skin.to_arrays(trimmed.solid)
            return Mesh(vertices=v, faces=f)

        return self._skinned()

    def _skinned(
        self, *, shift: float = 0.0, mid_wall: bool = False, split: bool = True,
        coarse: bool = False, rebuilt: bool = False,
    ) -> Mesh:  # fmt: skip
        """The lattice (with its keep zones) inside its skin, not yet checked; ``shift``
        moves the lattice by that many trim tolerances (``config.TRIM_RTOL`` r) in a
        generic direction, and ``mid_wall`` builds the skin the older way (see
        ``conformal.skin.build_skin``), for the retries when float32 cannot hold the exact
        result; ``coarse`` builds it on the part's own tessellation, ``rebuilt`` on the
        part's surface rebuilt from the region it encloses (``conformal.unfold``)."""
        from conformal import skin as _skin
        from conformal.trim import SHIFT_DIRECTION
        from lattice_cad.core.mesh import Mesh

        lattice = self._kept_mesh
        if shift:
            step = shift * config.TRIM_RTOL * float(self.graph.radii.max())
            moved = lattice.vertices + SHIFT_DIRECTION * step
            lattice = Mesh(vertices=moved, faces=lattice.faces)
        if self.skin is None:
            raise ValueError("this lattice has no skin: Lattice(..., skin=MM) builds one")
        # checked after rounding to float32 (what the files hold)
        pending = self.__dict__.pop("_pending_offsets", None)
        # the booleans on the struts near the wall only, the deep ones glued back after the
        # float32 check (conformal.skin_split): for the stitched lattice as it is
        local = split and lattice is self._lattice_mesh and self.escape_holes is None
        # (a B-rep whose surface folds over itself, Part.folds: its rebuild, conformal.unfold,
        # with the voxel skin: OCCT's offset of such a surface folds too)
        cut = self._coarse_cut if coarse else self._cutting_part
        if rebuilt:
            cut = self._rebuilt_part
        elif self.part is not None and self.part.self_crossings[0] >= config.SKIN_FOLD_PAIRS:
            # the part's tessellation folds over itself (said at load): when the one the
            # skin is built on folds too, its outer wall would, and the skinned mesh could
            # not be written (a mesh part that folds: the folded elbow's tessellation as an
            # STL); the part's surface rebuilt from the region it encloses instead
            if _skin.folded_wall(cut) is not None:
                cut = self._rebuilt_part
        result = _skin.build_skin(
            lattice,
            cut,
            self.skin,
            check=False,
            mid_wall=mid_wall,
            offsets=pending,
            graph=self.graph if local else None,
            min_cavity=2.0 * float(self.graph.radii.max()),
        )
        self._split = result.split
        self.skin_report = result.report
        solid = result.solid
        if result.report.rebuilt and not shift and not coarse and self.part is not None:
            # the outer wall is the rebuild: how far it stands out of the part as loaded
            from conformal.trim import _tolerance, protrusion

            out = protrusion(self.part, _skin.to_arrays(solid)[0])
            tol = _tolerance(float(self.graph.radii.max()), float(self.part.size.max()))
            self._warn_rebuilt(out, tol, result.report.rebuilt, "the skin")
        if self.escape_holes is not None:
            solid = self._drill(solid)
        v, f = _skin.to_arrays(solid)
        return Mesh(vertices=v, faces=f)

    @cached_property
    def _printable_mesh(self) -> Mesh:

        self.graph.check_precision("float32")  # before stitching: STL/3MF store float32
        first = _HeldWarnings(active=self.skin is not None)  # said if its mesh is written
        with first:
            solid = self._solid_mesh
        # a stitched lattice keeps its clearances through the rounding; a skin or a trim
        # (manifold3d booleans) can have surfaces a float32 step apart: checked in full
        if solid is not self._lattice_mesh:
            # a trim by a surface that crosses itself: where many of its crossings pass into
            # the cut, before any rounding, the cut bounds no solid, and neither the
            # collapses of float32's folds nor a second cut off the surface repair it (the
            # folded pipe elbow: 9,139 pairs in 187,800 triangles, 73 s of them before the
            # uncut lattice was written); a few are needles the collapses remove (a noisy
            # genus-2 scan: 32 pairs in 113,076, cut in 0.3 s)
            hopeless = (
                self.skin is None
                and self.part is not None
                and self.part.self_crossings[0] > 0
                and _too_folded(solid)
            )
            try:
                if hopeless:
                    raise ExportError("the cut crosses itself")
                with first:
                    mesh = _checked_single_precision(solid, "the lattice")
                    mesh = self._glue_deep(mesh)
                first.release()
            except ExportError as exc:
                rebuilt = self.skin_report is not None and self.skin_report.rebuilt
                if self.skin is not None and rebuilt:
                    first.release()
                    # a skin on the rebuild of a surface that folds (conformal.unfold): the
                    # retries below rebuild and rebool the same voxel walls (the folded
                    # elbow's 2 mm tube under a 0.96 mm skin: 3,137 pieces, 10 minutes)
                    raise SkinError(
                        f"{self.part.name}: {self.part.crossing_note()}; the skin built on "
                        f"its surface rebuilt on a {rebuilt:.3g} mm grid cannot be written "
                        f"in single precision either ({_short(str(exc), 200)}): "
                        "fill it without a skin, or repair the part (its overlapping "
                        "bodies united) and fill again"
                    ) from exc
                if self.skin is not None:
                    # the booleans left surfaces a float32 step apart (a strut grazing the
                    # skin's inner wall): the same solid the older way (with the mid-wall
                    # surface), then with the lattice moved a quarter of the trim tolerance
                    # last: the part's own (load) tessellation instead of the finer cutting
                    # one, whose near-coincident facets float32 may not hold (said in a warning)
                    # (shift, mid_wall, coarse, rebuilt)
                    tries = [
                        (0.0, True, False, False),
                        (0.25, False, False, False),
                        (0.25, True, False, False),
                    ]
                    folded = None
                    if self._cutting_part is not self.part:
                        # a fine cutting tessellation that folds over itself where the
                        # part's own does not (a B-spline fillet corner folding by 0.05 mm:
                        # a wheel hub made outside shared/data, 0 pairs at load, 652 at the
                        # skin's chord): the outer wall folds in every retry on it, and the
                        # mid-wall one is refused for it (conformal.skin.folded_wall);
                        # straight to the part's own tessellation
                        from conformal.skin import folded_wall

                        folded = folded_wall(self._cutting_part)
                        tries = [] if folded is not None else tries
                        tries.append((0.0, False, True, False))
                    if folded is None and self._cutting_part.self_crossings[0] > 0:
                        # the surface the skin was built on crosses itself, in fewer pairs
                        # than make a folded wall: the outer wall, that surface as it is,
                        # crosses itself in every retry on it (a knee implant's OFF mesh
                        # made outside shared/data, 16 pairs: 70 crossing pairs in each of
                        # four tries, 216 s, then refused). First the part's own
                        # tessellation if that one does not cross, then the surface rebuilt
                        # from the region it encloses (said in a warning), then the rest
                        own = (
                            self._cutting_part is not self.part and self.part.self_crossings[0] == 0
                        )
                        lead = [(0.0, False, True, False)] if own else []
                        tries = [*lead, (0.0, False, False, True)] + [
                            t for t in tries if t not in lead
                        ]
                    for shift, mid_wall, coarse, rebuild in tries:
                        held = _HeldWarnings()
                        try:
                            with held:
                                mesh = _checked_single_precision(
                                    self._skinned(
                                        shift=shift,
                                        mid_wall=mid_wall,
                                        coarse=coarse,
                                        rebuilt=rebuild,
                                    ),
                                    "the lattice",
                                )
                                # a split skin
                                mesh = self._glue_deep(mesh, coarse=coarse, rebuilt=rebuild)
                        except ExportError:
                            continue
                        first.drop()  # the first skin's, thrown away
                        held.release()
                        self.skin_retry = (
                            "coarse"
                            if coarse
                            else "rebuilt"
                            if rebuild
                            else ("shifted " if shift else "") + ("mid-wall" if mid_wall else "")
                        ).strip()
                        if coarse:
                            self._warn_coarse_skin(folded)
                        if self.escape_holes is not None:
                            self._verify_escape(mesh)
                        return mesh
                    first.release()  # (no retry written: the first skin's, with the error)
                    if folded is not None:
                        raise folded from exc
                    raise
                self.__dict__.pop("_split", None)
                if self.keep or self.trim_report is None:
                    raise
                # the cut by the part's surface left slivers that float32 cannot hold (tiny
                # struts lying in the surface): cut once more a quarter of the tolerance
                # off the surface, else write the lattice uncut and say so in the report
                # (a cut by a mesh surface that folds over itself: by its rebuild instead)
                retry = self._rebuilt_retrim() if hopeless else self._retrim()
                if retry is not None:
                    return retry
                crossing = self.part.crossing_note() if self.part is not None else ""
                why = (
                    f"{crossing}, and the cut by such a surface bounds no solid"
                    if crossing
                    else "the cut could not be written in single precision: "
                    + _short(str(exc), 300)
                )
                self.trim_report = dataclasses.replace(self.trim_report, failed=why)
                return self._stitched_single_precision()
        else:
            first.release()
            mesh = self._stitched_single_precision()
        if self.escape_holes is not None:
            self._verify_escape(mesh)
        return mesh

    def _warn_coarse_skin(self, folded: Exception | None) -> None:
        """The :class:`LatticeWarning` for a skin built on the part's own tessellation
        instead of the fine cutting one (``folded``: the cutting one's
        ``conformal.skin.folded_wall`` error, when that was why)."""
        assert self.part is not None
        used = self._coarse_cut
        bound = used.chord_bound if used is self.part else used.chord_error
        off = (
            f"up to {bound:.3g} mm (its chord error, measured)"
            if bound is not None
            else f"up to about {used.deflection:.3g} mm (its chord error)"
        )
        why = (
            "the fine cutting tessellation crosses itself "
            f"({self._cutting_part.self_crossings[0]} pair(s) of triangles, e.g. at "
            f"{point_text(self._cutting_part.self_crossings[1])}: a face of the part folds "
            "over itself, on a scale finer than the part's own tessellation), so no skin "
            "built on it could be written"
            if folded is not None
            else "float32 (STL, 3MF) could not hold the skin built on the fine cutting tessellation"
        )
        warnings.warn(
            f"{self.part.name}: {why}; it was built on "
            + ("the part's own tessellation" if used is self.part else "a coarser tessellation")
            + f", whose surface stands {off} off the exact one",
            LatticeWarning,
            stacklevel=3,
        )

    def _glue_deep(self, mesh: Mesh, *, coarse: bool = False, rebuilt: bool = False) -> Mesh:
        """The checked skin or trim of the struts near the wall or the part's surface with
        the deep struts glued back (``conformal.skin_split``); if a cap of the split did not
        come out of the booleans as it went in, the booleans on the whole lattice, checked
        (a skin on the same surface: ``coarse`` and ``rebuilt`` as ``_skinned``'s)."""
        from conformal import skin as _skin
        from lattice_cad.core.mesh import Mesh

        split = self.__dict__.pop("_split", None)
        if split is None:
            return mesh
        glued = split.glue(mesh.vertices, mesh.faces)
        if glued is not None:
            return Mesh(vertices=glued[0], faces=glued[1])
        if self.skin is not None:
            whole = self._skinned(split=False, coarse=coarse, rebuilt=rebuilt)
            return _checked_single_precision(whole, "the lattice")
        trimmed = self._cut(split=False)
        self.trim_report = trimmed.report
        v, f = _skin.to_arrays(trimmed.solid)
        return _checked_single_precision(Mesh(vertices=v, faces=f), "the lattice")

    @cached_property
    def _rebuilt_part(self) -> Any:
        """The part's surface rebuilt from the region it encloses
        (``conformal.unfold.rebuilt_part``), for a part whose surface folds over itself."""
        from conformal.unfold import rebuild_spacing, rebuilt_part

        radius = float(self.graph.radii.max())
        return rebuilt_part(self.part, spacing=rebuild_spacing(self.part, radius))

    def _rebuilt_retrim(self) -> Mesh | None:
        """The trim cut by :attr:`_rebuilt_part`, checked, when the cut by the part's own
        surface crosses itself too much to be repaired (a mesh part whose surface folds;
        a B-rep that folds is cut by its rebuild at once, ``conformal.trim.cutting_part``);
        None if that fails too."""
        from conformal import skin as _skin
        from lattice_cad.core.errors import LatticeError
        from lattice_cad.core.mesh import Mesh

        if self.part is None or bool(getattr(self._cutting_part, "rebuilt", None)):
            return None
        try:
            self.__dict__["_cutting_part"] = self._rebuilt_part
            trimmed = self._cut()
            self._split = trimmed.split
            if not trimmed.report.trimmed:
                mesh = self._stitched_single_precision()
            else:
                v, f = _skin.to_arrays(trimmed.solid)
                mesh = _checked_single_precision(Mesh(vertices=v, faces=f), "the lattice")
                mesh = self._glue_deep(mesh)
        except LatticeError:
            return None
        self.trim_report = trimmed.report
        return mesh

    def _retrim(self) -> Mesh | None:
        """The trim cut again when the first cut cannot be written in float32: with the
        part moved off its surface by a quarter of the tolerance (see
        ``conformal.trim.trim_to_part(shift=)``), then, for a B-rep part, by a cutting
        tessellation ``config.RETRIM_FINER`` times as fine; None if those fail too.

        The second is for a cutting tessellation whose facets meet the lattice in surfaces
        a float32 step apart wherever the part is moved (a rocket fin can made outside
        shared/data, a fin's edge flush with its tube: the bcc fill was written uncut,
        2.32 mm out of the part; cut at 0.8 x the chord, 0.0021 mm)."""
        from conformal import skin as _skin
        from lattice_cad.core.mesh import Mesh

        tries: list[dict[str, Any]] = [{"shift": 0.25}]
        if self.part is not None and self.part.shape is not None and not self.keep:
            tries.append({"finer": config.RETRIM_FINER})
        for kw in tries:
            try:
                trimmed = self._cut(**kw)
            except PartError:  # (the finer tessellation could not be made closed)
                continue
            v, f = _skin.to_arrays(trimmed.solid)
            try:
                mesh = _checked_single_precision(Mesh(vertices=v, faces=f), "the lattice")
            except ExportError:
                continue
            self.trim_report = trimmed.report
            return mesh
        return None

    def _cut(self, *, shift: float = 0.0, split: bool = True, finer: float = 1.0) -> Any:
        """The lattice (with its keep zones) cut by the part's surface, not yet checked
        (``conformal.trim.trim_to_part``; ``shift``: see there); ``split``: the boolean on
        the struts near the surface only, the deep ones in ``TrimResult.split``; ``finer``
        < 1: by a tessellation of the B-rep with that fraction of the cutting one's chord
        error, the whole lattice (a retry)."""
        from conformal.trim import trim_to_part

        radius = float(self.graph.radii.max())
        if self.keep:
            return self._cut_then_keep(shift=shift)
        if finer < 1.0:
            assert self.part is not None
            cut_by = self.part.refined(self._cutting_part.deflection * finer)
            return trim_to_part(self._kept_mesh, cut_by, radius=radius, check=False)
        if split and not shift and "_cutting_part" not in self.__dict__:
            # clear inside the part's own tessellation (an inside fill, usually): no finer
            # cutting tessellation (minutes on threads and small fillets) and no boolean
            from conformal.trim import clear_inside

            clear = clear_inside(self._kept_mesh, self.part, self.graph, radius=radius)
            if clear is not None:
                return clear
        cut_by = self._cutting_part
        trimmed = trim_to_part(
            self._kept_mesh,
            cut_by,
            radius=radius,
            check=False,
            shift=shift,
            graph=self.graph if split and not shift else None,
        )
        if getattr(cut_by, "rebuilt", 0.0):
            # the part's surface folds over itself: cut by its rebuild (conformal.unfold),
            # the protrusion measured against the part as loaded
            from conformal.skin import to_arrays
            from conformal.trim import TrimResult, protrusion

            before = protrusion(self.part, self._kept_mesh.vertices)
            out = protrusion(self.part, to_arrays(trimmed.solid)[0])
            split_part = trimmed.split
            if split_part is not None:  # (the deep struts lie inside the rebuild: inside)
                out = max(out, protrusion(self.part, split_part.deep_vertices))
            report = dataclasses.replace(
                trimmed.report,
                rebuilt=cut_by.rebuilt,
                protrusion_before=before,
                protrusion_after=out,
                trimmed=trimmed.report.trimmed or before > 0,
            )
            trimmed = TrimResult(solid=trimmed.solid, report=report, split=split_part)
            if not shift:
                self._warn_rebuilt(out, report.tolerance, cut_by.rebuilt, "the lattice")
        return trimmed

    def _warn_rebuilt(self, out: float, tol: float, h: float, what: str) -> None:
        """A :class:`LatticeWarning` when ``what``, cut or skinned on the part's surface
        rebuilt on a grid of ``h`` mm (``conformal.unfold``), stands ``out`` mm out of the
        part as loaded, more than the trim's tolerance ``tol`` (a helper's rounded ASCII
        STL: 0.066 mm for 0.0022 mm, said only in the trim's line until s30)."""
        if not out > tol:
            return
        assert self.part is not None
        warnings.warn(
            f"{self.part.name}: {what} stands up to {out:.3g} mm out of the part's surface, "
            f"{out / tol:.0f} x the tolerance of {tol:.2g} mm: that surface crosses itself, so "
            f"{what} was cut to it rebuilt on a {h:.3g} mm grid, whose concave creases stand "
            "up to about 0.7 x the grid out of it; repair the part (its overlapping bodies "
            "united, its folds removed) for a cut within the tolerance, or use a thinner radius "
            "(a finer grid)",
            LatticeWarning,
            stacklevel=2,
        )

    def _cut_then_keep(self, *, shift: float = 0.0) -> Any:
        """With keep zones: the lattice alone cut by the part's surface, then united with
        the zones (``conformal.keep.build_keep``, zones inside the same cutting part), so
        the zones' faces on the part's surface and the cut faces never meet in one
        boolean's intersection (issue 13 item 4; the other order left points of the zones
        outside the printable solid after the float32 check on the mounting plate)."""
        import dataclasses

        from conformal.keep import _manifold, build_keep
        from conformal.trim import TrimResult, protrusion, trim_to_part
        from lattice_cad.core.mesh import Mesh

        radius = float(self.graph.radii.max())
        cut_by = self._cutting_part
        trimmed = trim_to_part(self._lattice_mesh, cut_by, radius=radius, check=False, shift=shift)
        result = build_keep(trimmed.solid, cut_by, self.keep)
        self.keep_report = result.report
        if not trimmed.report.trimmed:  # the lattice lies inside: the same as uncut
            self.__dict__["_kept_mesh"] = Mesh(vertices=result.vertices, faces=result.faces)
        report = dataclasses.replace(
            trimmed.report, protrusion_after=protrusion(cut_by, result.vertices)
        )
        solid = _manifold(result.vertices, result.faces, "the lattice with its keep zones")
        return TrimResult(solid=solid, report=report)

    @cached_property
    def _cutting_part(self) -> Any:
        """The part the lattice is cut by (trim, skin, beam clipping): a B-rep part
        tessellated again for the largest strut radius (``conformal.trim.cutting_part``),
        so the cut lies within ``config.TRIM_RTOL`` r of the exact surface (keep zones are
        built inside it too; see ``_cut_then_keep``); with a skin, for the wall's
        tolerance (``conformal.skin.outer_chord``)."""
        if self.part is None or self.graph.num_edges == 0:
            return self.part
        from conformal.trim import cutting_part

        return cutting_part(self.part, float(self.graph.radii.max()), chord=self._cut_chord)

    @cached_property
    def _coarse_cut(self) -> Any:
        """The part a skin's last retry is built on (``_skinned(coarse=True)``): the part's
        own tessellation, or when the fine cutting one crosses itself, the finest one
        between them that does not (``conformal.trim.unfolded_tessellation``)."""
        from conformal.skin import folded_wall

        cut = self._cutting_part
        if self.part is None or cut is self.part or folded_wall(cut) is None:
            return self.part
        from conformal.trim import unfolded_tessellation

        return unfolded_tessellation(self.part, cut)

    @property
    def _cut_chord(self) -> float | None:
        """The chord error the cutting part is asked for when it is not the radius's."""
        if self.skin is None:
            return None
        from conformal.skin import outer_chord

        return outer_chord(self.skin)

    def _stitched_single_precision(self) -> Mesh:
        """The stitched lattice in single precision: the stitch keeps its clearances through
        the rounding, so only a mesh the rounding repaired is checked again."""
        import fast_stitch
        from lattice_cad import io

        mesh, repaired = io.single_precision(self._lattice_mesh, name="the lattice")
        if repaired:
            report = fast_stitch.check(mesh)
            if not report.valid:
                raise ExportError(
                    f"the lattice cannot be written in single precision (STL, 3MF): rounding "
                    f"its coordinates to float32 breaks it ({report}); move it closer to the "
                    "origin or use thicker struts"
                )
        return mesh

    def _drill(self, solid: Any) -> Any:
        """Escape holes in the skinned solid (``conformal.escape.drill``), unverified."""
        from conformal import escape

        up = self.build_direction  # config.BUILD_DIRECTION unless given
        assert self.escape_holes is not None and self.skin is not None
        res = escape.drill(
            solid,
            self.escape_holes,
            thickness=self.skin,
            points=self.escape_at,
            build_direction=up,
            check=False,
        )
        self.escape_report = res.report
        if res.report.failed:
            raise EscapeHoleError(
                f"no escape hole of diameter {self.escape_holes:g} mm fits "
                f"{len(res.report.failed)} cavity(ies):\n{res.report.summary()}\n"
                "use a smaller diameter or place holes with escape_at (--escape-at)"
            )
        # enclosed voids smaller than one cell of the escape flood fill (pockets between
        # struts and the wall, e.g. 0.02 mm^3 in the spanner's octet skin) cannot be drained
        # and would trap powder: they are filled, and counted in ``escape_voids_filled``
        import manifold3d as m3

        step = escape.grid_step(self.escape_holes, self.skin)
        pieces = res.solid.decompose()
        keep = [p for p in pieces if not (-(step**3) < p.volume() < 0.0)]
        self.escape_voids_filled = len(pieces) - len(keep)
        if self.escape_voids_filled:
            return m3.Manifold.compose(keep)
        return res.solid

    def _verify_escape(self, mesh: Mesh) -> None:
        """Flood fill of the final (written) mesh: every cavity must reach the outside."""
        import dataclasses

        from conformal import escape

        assert self.escape_holes is not None
        up = self.build_direction  # config.BUILD_DIRECTION unless given
        step = escape.grid_step(self.escape_holes, self.skin)
        check = escape.verify(mesh, voxel=step, build_direction=up)
        self.escape_report = dataclasses.replace(self.escape_report, verification=check)
        if not check.connected:
            raise EscapeHoleError(
                f"after drilling, the solid still has enclosed empty space:\n"
                f"{self.escape_report.summary()}\nadd holes with escape_at (--escape-at)"
            )

    def mesh(self, *, lattice_only: bool = False) -> Mesh:
        """The printable watertight mesh (built on first use, then cached).

        Its vertices are exactly representable in single precision (as STL and 3MF store
        them), so every file written from it is the mesh that was checked.

        Parameters
        ----------
        lattice_only : bool
            The stitched lattice as the graph gives it: without the skin and not trimmed
            to the part.

        Returns
        -------
        fast_stitch.Mesh
            The stitched lattice (united with its keep-solid zones) cut by the part's
            surface (when the part is known; see ``trim``), or (with a skin) the union of
            skin and lattice.
        """
        return self._lattice_mesh if lattice_only else self._printable_mesh

    # ---------------------------------------------------------------- files
    def save(
        self,
        path: str | os.PathLike[str],
        *,
        beam_lattice: bool | Literal["only"] = False,
        node_sets: Mapping[str, Any] | None = None,
        material: Mapping[str, Any] | None = None,
        max_struts: int | None = None,
    ) -> Path:
        """Write the lattice; the format is chosen by the suffix.

        Parameters
        ----------
        path : path-like
            ``.stl``, ``.3mf``, ``.ply``, ``.obj``: the printable mesh;
            ``.json``, ``.npz``: the graph; ``.step``/``.stp``: the exact B-rep, one
            BRepCheck-valid solid per connected body, trimmed to the part when the part
            is a B-rep (see :mod:`lattice_cad.brep`);
            ``.inp``: a CalculiX/Abaqus beam model (see :meth:`save_inp`).
        beam_lattice : bool or "only"
            With ``.3mf``: write the 3MF Beam Lattice extension (beams with per-end radii,
            balls). ``True``: the beam-lattice object also holds the printable mesh
            (:meth:`mesh`, skin included) as its triangles, so readers without the
            extension (PrusaSlicer, Bambu Studio...) slice the mesh and beam-aware readers
            the union of mesh and beams (no clipping mesh: PrusaSlicer refuses a 3MF with
            an object outside the build). ``"only"``: beams without triangles and the
            part as clipping mesh, a tiny file that most slicers cannot open (warns
            :class:`~lattice_cad.core.errors.BeamOnlyWarning`); a skin is then written
            as a separate mesh object of the build. With a part (and ``trim``), the beams
            are clipped to it (:mod:`conformal.beam_clip`): with ``True`` every round
            beam lies inside the part within the trim tolerance (beams near the surface
            are shortened; the trimmed mesh reaches the surface), with ``"only"`` the beam
            axes end where they cross the surface (the round beams still reach up to their
            radius beyond it; the clipping mesh trims them for readers that honour it).
            Cut ends keep the radius the beam had there and get flat caps;
            :attr:`beam_clip_report` says what was cut.
        node_sets, material : mapping, optional
            With ``.inp``: named node sets by face selector (``{"fixed": "<Z"}``) and the
            material (``{"E": 3500, "nu": 0.36, "density": 1.24e-9}``); see
            :meth:`save_inp`.
        max_struts : int, optional
            With ``.step``: the largest lattice built as a B-rep (default
            ``config.MAX_BREP_STRUTS``); a larger one is refused before any work, with
            the estimated time and size.

        Returns
        -------
        Path

        Raises
        ------
        ExportError
            A STEP of a lattice over ``max_struts``, or with a skin.
        OCCTFailure
            OpenCascade failed building or writing the B-rep (the message names the file).
        """
        from lattice_cad import io

        p = Path(path)
        if self.keep and (beam_lattice == "only" or p.suffix.lower() in suffixes(Kind.SOLIDS)):
            raise ExportError(  # never drop the zones silently
                f"{p.name}: keep-solid zones are solid material, not struts: they cannot be "
                "written as beams only or as the exact strut B-rep; write a mesh (.stl, .3mf, "
                "or a beam-lattice 3MF with its mesh)"
            )
        if p.suffix.lower() in suffixes(Kind.FE_MODEL) and beam_lattice is False:
            self.save_inp(p, node_sets=node_sets, material=material)
            return p
        if node_sets is not None or material is not None:
            raise ValueError(f"node_sets and material apply to .inp beam models, not {p.name}")
        if beam_lattice is not False:
            return self._save_beam_lattice(p, beam_lattice)
        _, kind = resolve(p, (Kind.MESH, Kind.GRAPH, Kind.SOLIDS), what="lattice")
        if kind is Kind.GRAPH:
            return io.save_graph(self.graph, p)
        if kind is Kind.SOLIDS:
            from lattice_cad.brep import save_step

            out, self.brep_report = save_step(self, p, max_struts=max_struts)
            return out
        return io.save_mesh(self.mesh(), p)

    def save_inp(
        self,
        path: str | os.PathLike[str],
        *,
        node_sets: Mapping[str, Any] | None = None,
        material: Mapping[str, Any] | None = None,
        tol: float | None = None,
        element: Literal["B32", "B32R"] = "B32",
        dialect: Literal["calculix", "abaqus"] = "calculix",
        elements_per_strut: int = config.FE_ELEMENTS_PER_STRUT,
    ) -> Any:
        """Write the lattice as a CalculiX/Abaqus beam model (see :mod:`lattice_cad.io.fe`).

        Parameters
        ----------
        path : path-like
            ``.inp``.
        node_sets : mapping of str to selector, optional
            Named node sets for supports and loads, e.g. ``{"fixed": "<Z", "load": ">Z"}``:
            CadQuery face selectors on the part's B-rep, CAD faces, ``"plane:..."``,
            ``"box:..."``, node indices (see :mod:`lattice_cad.selectors`). ``NALL``,
            ``NJOINT`` (the lattice nodes) and ``EALL`` are always written.
        material : mapping, optional
            ``name``, ``E`` (MPa), ``nu``, ``density`` (t/mm^3); default PLA
            (``config.FE_MATERIAL``).
        tol : float, optional
            Distance (mm) within which a node is on a selected face; default the node's
            largest strut radius (plus the tessellation deflection).
        element : {"B32", "B32R"}
        dialect : {"calculix", "abaqus"}
            CalculiX reads a circular section's diameter, Abaqus its radius.
        elements_per_strut : int
            Quadratic elements per strut (default 3: one cannot bend in double curvature).

        Returns
        -------
        lattice_cad.io.fe.BeamModel
            What was written (nodes, elements, sections, node sets); also kept as
            ``self.fe_model``.
        """
        from lattice_cad.io import fe
        from lattice_cad.selectors import resolve_node_sets

        format_for(path, Kind.FE_MODEL, what="beam FE model")
        if self.skin is not None:
            warnings.warn(
                "the beam model holds the lattice only: the skin is not in it",
                LatticeWarning,
                stacklevel=2,
            )
        sets = resolve_node_sets(self.graph, node_sets, part=self.part, tol=tol)
        name = getattr(self.part, "name", None) or "lattice"
        model = fe.save_inp(
            self.graph,
            path,
            node_sets=sets,
            material=material,
            element=element,
            dialect=dialect,
            elements_per_strut=elements_per_strut,
            title=Path(str(name)).name,
        )
        self.fe_model = model
        return model

    def _save_beam_lattice(self, p: Path, mode: Any) -> Path:
        """``save(p, beam_lattice=mode)`` for ``mode`` True or "only"."""
        from lattice_cad import io

        if mode is not True and mode != "only":
            raise ValueError(f"beam_lattice must be False, True or 'only'; got {mode!r}")
        io.format_for(p, Kind.BEAM_LATTICE)
        if mode is True:  # no clipping mesh: PrusaSlicer refuses any object not in the build
            mesh = self.mesh()
            return io.save_beam_lattice(self._clipped_beams("solid"), p, mesh=mesh)
        clip = (self.part.vertices, self.part.faces) if self.part is not None else None
        skin = self._skin_wall_mesh if self.skin is not None else None
        return io.save_beam_lattice(self._clipped_beams("axis"), p, skin=skin, clip=clip)

    def _clipped_beams(self, keep: Literal["solid", "axis"]) -> LatticeGraph:
        """The graph's beams clipped to the part (``conformal.beam_clip``): the whole round
        beams beside the trimmed mesh, the axes in a beams-only file (which carries the
        part as clipping mesh). The graph itself without a part or with ``trim=False``."""
        if self.part is None or not self.trim or self.graph.num_edges == 0:
            return self.graph
        from conformal.beam_clip import clip_beams

        clipped, self.beam_clip_report = clip_beams(self.graph, self._cutting_part, keep=keep)
        if clipped is None:
            raise ExportError(
                f"no beam fits inside the part ({self.beam_clip_report.summary()}); write "
                "the mesh (.stl, or .3mf without --beam-lattice)"
            )
        return clipped

    @cached_property
    def _skin_wall_mesh(self) -> Mesh:
        """The skin alone (the part's wall, no struts), float32-exact and checked: written
        beside a beam-only lattice. Made by the skin builder with an empty lattice."""
        import manifold3d

        from conformal import skin as _skin
        from lattice_cad.core.mesh import Mesh

        if self.skin is None:
            raise ValueError("this lattice has no skin: Lattice(..., skin=MM) builds one")
        result = _skin.build_skin(manifold3d.Manifold(), self._cutting_part, self.skin, check=False)
        v, f = _skin.to_arrays(result.solid)
        return _checked_single_precision(Mesh(vertices=v, faces=f), "the skin")

    # ------------------------------------------------------------ reference
    def reference(self, **options: Any) -> Any:
        """The exact B-rep reference (``reference_boolean.build_reference``), cached."""
        cached = self.__dict__.get("_reference")
        if cached is None or options:
            from reference_boolean import build_reference

            cached = build_reference(self.graph, **options)
            if not options:
                self.__dict__["_reference"] = cached
        return cached

    def validate(self, report: str | os.PathLike[str] | None = None, **options: Any) -> Any:
        """Compare the stitched mesh with the exact reference (see ``lattice_cad.validate``).

        Parameters
        ----------
        report : path-like, optional
            Write the report there (``.html``, ``.md`` or ``.json``).
        **options
            More keyword arguments of :func:`lattice_cad.validate.validate`. ``profiles``
            defaults to the lattice's own ``profile`` (the mesh it writes, judged by the
            verdict) and the other of ``"volume"`` / ``"inscribed"`` beside it.

        Returns
        -------
        reference_boolean.ValidationReport
        """
        from lattice_cad.validate import validate

        if "profiles" not in options and "volume_preserving" not in options:
            other = "inscribed" if self.profile == "volume" else "volume"
            options["profiles"] = (self.profile, other)

        rep = validate(self.graph, self.segments, report=None, **options)
        pr = self.printability()
        rep.extra[
            f"Printability (build direction {pr.direction_label}, critical angle "
            f"{pr.critical_angle:g} deg)"
        ] = pr.to_records()
        if self.overhang_removal is not None:
            rep.extra["Overhang removal"] = [
                {"quantity": "removed", "value": str(self.overhang_removal)}
            ]
        if report is not None:
            rep.save(report)
        return rep

    def _brep_compound(self, max_struts: int) -> Any:
        """The exact lattice B-rep (the STEP path, :func:`lattice_cad.brep.build`), untrimmed."""
        from lattice_cad.brep import build

        shape, self.brep_report = build(
            Lattice(self.graph, segments=self.segments), max_struts=max_struts, what="the B-rep"
        )
        return shape

    def to_workplane(self, *, max_struts: int = config.MAX_BREP_STRUTS) -> cq.Workplane:
        """The exact lattice solid as a CadQuery Workplane (small lattices only).

        The hub solids of the exact reference are fused into one B-rep, usable
        in further CadQuery booleans (e.g. ``part.cut(...)``, ``.union(...)``).

        Raises
        ------
        LatticeError
            More than ``max_struts`` struts, or a hub that OCCT could not build.
        """
        import cadquery as cq

        return cq.Workplane("XY").newObject([cq.Shape.cast(self._brep_compound(max_struts))])

    def to_part(self, *, max_struts: int = config.MAX_BREP_STRUTS) -> Any:
        """The exact lattice solid as a build123d shape (small lattices only).

        See :meth:`to_workplane`.
        """
        import build123d as bd

        shape = self._brep_compound(max_struts)
        from lattice_cad.occ_impl.shapes import is_compound

        # build123d 0.10's Shape.cast gives None for a plain TopoDS_Shape: wrap by type
        if is_compound(shape):
            return bd.Compound(shape)
        return bd.Solid(shape)

    # ----------------------------------------------------------------- info
    def strut_volume(self) -> float:
        """Sum of the struts' frustum volumes (overlaps at nodes counted twice)."""
        g = self.graph
        r0, r1 = g.radii[:, 0], g.radii[:, 1]
        return float(np.sum(math.pi * g.edge_lengths * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0))

    def info(self) -> dict[str, Any]:
        """Counts, volume, relative density and estimated file sizes.

        Returns
        -------
        dict
            ``nodes``, ``struts``, ``vertices`` and ``triangles`` (of the stitched
            lattice, exact before building it), ``volume`` (mm^3: of the printable mesh if
            built, else the strut-volume estimate), ``volume_exact`` (whether it is the
            mesh's), ``part_volume`` and ``relative_density`` (when the part is known: the
            printable mesh is then built, so both are exact and the density is at most 1),
            ``skin``,
            and ``file_bytes``: estimated sizes of ``stl``, ``3mf``, ``ply``, ``obj``
            and ``3mf_beam`` (beam-only) files of the lattice (without skin); ``printability``: the
            :meth:`printability` report (overhangs, thin struts, unsupported nodes; print
            it for a summary) and ``overhang_removal`` (what ``remove_overhangs`` removed,
            or None); ``cut_budget``: :meth:`cut_shortfall`.
        """
        import fast_stitch
        from lattice_cad import io as export

        g = self.graph
        est = fast_stitch.estimate(g, self.segments, self.profile)
        # the relative density is a fraction of the part: from the printable solid itself
        # (a union, trimmed to the part), never from a sum of overlapping strut volumes
        built = (
            self.part is not None
            or "_printable_mesh" in self.__dict__
            or (self.skin is None and "_lattice_mesh" in self.__dict__)
        )
        volume = self.mesh().volume if built else self.strut_volume()
        out: dict[str, Any] = {
            "nodes": g.num_nodes,
            "struts": g.num_edges,
            "segments": self.segments,
            "profile": self.profile,
            "vertices": est.vertices,
            "triangles": est.triangles,
            "volume": volume,
            "volume_exact": built,
            "skin": self.skin,
            "keep": [z.label for z in self.keep],
        }
        if self.part is not None:
            pv = float(self.part.volume)
            out["part_volume"] = pv
            out["relative_density"] = volume / pv if pv > 0 else None
        n_used = int(np.count_nonzero(g.degree))
        out["file_bytes"] = {
            s.lstrip("."): export.estimate_bytes(s, est.vertices, est.triangles)
            for s in export.MESH_SUFFIXES
        }
        out["file_bytes"]["3mf_beam"] = export.estimate_bytes(
            ".3mf", n_used, 0, n_beams=g.num_edges
        )
        out["printability"] = self.printability()
        out["overhang_removal"] = self.overhang_removal
        out["cut_budget"] = self.cut_shortfall()
        return out

    def cut_shortfall(self) -> float | None:
        """Chord error (% of the largest strut radius) of the tessellation the lattice is
        cut by, when its triangle budget made it coarser than asked
        (``conformal.trim.cut_shortfall``; a ``CutBudgetWarning`` said so), else None
        (also when nothing has been cut yet)."""
        if "_cutting_part" not in self.__dict__ or self.part is None:
            return None
        from conformal.trim import cut_shortfall

        return cut_shortfall(
            self.part, self._cutting_part, float(self.graph.radii.max()), chord=self._cut_chord
        )
