"""Skins: hollow a part to a wall thickness and unite the wall with a lattice.

The printable result of ``Lattice.fill(part, skin=t)`` is one watertight solid per solid of
the part: the part minus its inset by ``t`` (the skin), united with the lattice inside it, so
every strut that reaches the boundary runs into the wall and no strut end is flush with the
outer surface. Since the inset lies inside the part, that union is computed as two
differences, ``part - (inset - lattice)``: the lattice (by far the largest mesh) takes part
in one boolean only, and no two surfaces of the operands coincide. All booleans are done by
manifold3d, whose results are guaranteed manifold.

The inner surfaces come from one of two methods, and the :class:`SkinReport` says which,
with the wall thickness measured on the result:

``"occt"`` (B-rep parts: STEP, CadQuery, build123d)
    OpenCascade's offset of each solid by ``-t`` (arc joins), checked with
    ``IsDone`` and BRepCheck, and tessellated with a chord error of 1 % of ``t``. The outer
    surface is the part's mesh, and the inner vertices are projected onto its offset: the
    wall is as exact as that mesh. ``Lattice`` passes the part tessellated again with a
    chord error of a quarter of the wall's tolerance (:func:`outer_chord`,
    ``conformal.trim.cutting_part``); with the default tessellation (1e-3 of the
    diagonal, 10-13 % of t on the benchmark's parts) the wall was off by up to +3 % of t
    against that mesh and -5 % .. +6 % against the exact B-rep.
``"voxel"`` (meshes, and B-rep parts where OCCT's offset fails)
    The inside of the part on a grid (exact winding numbers), a Euclidean distance
    transform, refined to exact point-to-triangle distances in a band around the
    level, and a marching-tetrahedra pass (a Freudenthal split of every voxel, so the
    surface is closed and 2-manifold by construction) that extracts ``d = t``. The grid
    spacing is ``t / 3`` unless the grid would exceed ``config.MAX_VOXELS`` voxels.

The wall is measured from the inner surface to the outer one (the definition of an offset):
for every inner vertex, its distance to the outer surface should be ``t``.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from conformal.skin_crease import revert_flips
from conformal.skin_untangle import unfolded, untangle
from lattice_cad.core import config
from lattice_cad.core.arrays import point_text
from lattice_cad.core.errors import LatticeWarning, OCCTFailure, SkinError
from lattice_cad.core.mesh import Mesh, mesh_arrays, weld

__all__ = [
    "SkinError",
    "SkinReport",
    "SkinResult",
    "as_manifold",
    "checked",
    "part_solid",
    "inset",
    "hollow",
    "build_skin",
    "folded_wall",
    "start_offsets",
    "start_solid_offsets",
    "PendingOffsets",
    "add_skin",
    "marching_tets",
    "wall_thickness",
    "outer_chord",
    "wall_tolerance",
]

#: A wall is accurate when every measured thickness is within this fraction of ``t`` or
#: this many mm of it, whichever is larger.
WALL_RTOL = 0.02
WALL_ATOL = 0.02
#: ... but a wall thinner than ``WALL_ATOL / WALL_ATOL_SHARE`` (0.08 mm: below what prints)
#: has this share of its thickness as the absolute part, so that the tolerance, the chord
#: of the part's surface and the split's margin scale with a part read in the wrong unit
#: (a flange in metres read as mm, 0.05 mm across: 0.02 mm was 36 x its 0.56 um wall, and
#: the split's margin took in every element: 340 s in ``skin_split._refine_near``).
WALL_ATOL_SHARE = 0.25
#: Exact distances of the voxel method's band are computed in chunks of this many points,
#: so that :func:`_surfaces`, computing it while OCCT's offsets run, sees their end soon
#: after it (the GE bracket's band, 0.7 M points, took 2.4 s in one piece).
DISTANCE_CHUNK = 100_000
#: The part's surface a skin is built on (its outer surface) is tessellated with a chord
#: error of this fraction of the wall's tolerance (:func:`outer_chord`).
OUTER_CHORD_FRACTION = 0.25
#: Exact distance queries :func:`_no_room` may spend proving that a part has no room for
#: a skin's inset (trimesh_box_sides at 2.05 mm: 0.65 M; more gives up, and the offsets
#: are waited for as before).
NO_ROOM_BUDGET = 1_000_000
#: The voxel method's surfaces are simplified to this fraction of the wall's accuracy bound.
SIMPLIFY_FRACTION = 0.25
#: Fractions of that tolerance tried in turn while the simplified surface has folds that
#: ``conformal.skin_untangle`` cannot collapse (sheets of the wall a tolerance apart cross:
#: Ventilator, skin 0.88882 mm), the unsimplified surface (valid as marching tetrahedra
#: make it) after the last.
SIMPLIFY_BACKOFF = (1.0, 0.5, 0.25, 0.1)
#: The voxel method puts the creases of its inner surface back (conformal.skin_crease):
#: box and sphere walls within max(2 % t, h/10) instead of +5.6 %; on real parts the p99
#: wall goes from +9..+14 % to +0.5..+12 % but the max stays +13..+22 % (thin-cavity
#: rims), for 2-4x the voxel method's CPU time. Off until it is cheaper.
SHARPEN_CREASES = False
#: With ``build_skin(min_cavity=)``, the voxel method closes (makes solid wall of) the parts
#: of the cavity that are thinner than ``min_cavity = 2 rho``: the cavity points farther
#: than ``sqrt(3) rho + OPEN_SLACK * h`` from every point deeper than ``thickness + rho``
#: (an opening on the grid, step ``h``, that leaves a box-shaped cavity's corners, sqrt(3)
#: rho from that core, as they are; the slack covers the grid distances' error of about h).
OPEN_SLACK = 1.5
#: ... unless what it would close is less than this share of the cavity's volume (the tips
#: of acute cavity corners, which the opening also reaches: left as they were).
CLOSE_MIN_SHARE = 0.005


@dataclass(frozen=True)
class SkinReport:
    """How a skin was made and how thick its wall really is.

    Attributes
    ----------
    thickness : float
        The wall thickness asked for (mm).
    method : str
        ``"occt"`` (OpenCascade offset) or ``"voxel"`` (distance field).
    fallback : str
        Why the OCCT offset was not used (empty when it was, or was not tried).
    voxel : float
        Grid spacing of the voxel method (NaN for ``"occt"``).
    wall : dict
        Measured wall thickness (mm): ``min``, ``p01``, ``median``, ``p99``, ``max`` over
        the inner surface's vertices and face centres (distance to the outer surface).
    accurate : bool
        Every measured thickness is within ``wall_tolerance(t)`` of ``t``.
    bodies : int
        Separate solids of the result (one per connected solid of the part).
    islands_removed : int
        Lattice pieces that touched neither the skin nor the rest of the lattice, removed.
    seconds : dict
    """

    thickness: float
    method: str
    fallback: str = ""
    voxel: float = float("nan")
    wall: dict[str, float] = field(default_factory=dict)
    accurate: bool = False
    #: The tolerance ``accurate`` was judged with (mm, :func:`wall_tolerance`).
    tolerance: float = float("nan")
    bodies: int = 0
    islands_removed: int = 0
    #: Closed voids inside the result (its inside-out shells: the skin's cavity, split
    #: where struts thicker than the cavity cut across it, and the part's own voids).
    #: Powder or resin stays in them unless escape holes are drilled. Voids under
    #: ``POCKET_SHARE`` of the largest are counted as ``pockets`` (``pocket_volume``: the
    #: largest of them, mm^3): specks the booleans leave where a strut grazes the inner
    #: wall (up to 0.0006 mm^3 on the GE bracket, whose cavity is 278,473 mm^3).
    voids: int = 0
    pockets: int = 0
    pocket_volume: float = 0.0
    seconds: dict[str, float] = field(default_factory=dict)
    #: Triangles of the lattice by element class when the booleans ran on the elements
    #: near the wall only (``deep``, ``near``, ``wall``, ``caps``; see
    #: :mod:`conformal.skin_split`); empty when they ran on the whole lattice.
    split: dict[str, int] = field(default_factory=dict)
    #: Triangles collapsed to remove folds of the inner wall (``conformal.skin_untangle``).
    untangled: int = 0
    #: When the part's surface folds over itself (``conformal.Part.folds``): the spacing
    #: (mm) of the grid its outside was rebuilt on (``conformal.unfold``); else 0.
    rebuilt: float = 0.0
    #: With ``build_skin(min_cavity=)`` (``Lattice`` passes the struts' diameter): the
    #: volume (mm^3, on the voxel grid) of the cavity made solid because it was thinner
    #: than ``min_cavity`` (mm) there; 0 when none was.
    closed: float = 0.0
    min_cavity: float = 0.0

    def summary(self) -> str:
        """One line for logs and the CLI."""
        how = "OpenCascade offset" if self.method == "occt" else f"voxel field (h={self.voxel:.3g})"
        if self.fallback:
            how += f" [OCCT offset failed: {self.fallback}]"
        if self.rebuilt:
            how += (
                f" [the part's surface folds over itself: its outside rebuilt on a "
                f"{self.rebuilt:.3g} mm grid]"
            )
        w = self.wall
        wall = (
            f"wall {w['min']:.4g} .. {w['max']:.4g} mm (median {w['median']:.4g}) for "
            f"{self.thickness:g}"
            if w
            else "wall not measured"
        )
        ok = f"{'within' if self.accurate else 'NOT within'} {self.tolerance:.3g} mm"
        islands = f", {self.islands_removed} island(s) removed" if self.islands_removed else ""
        voids = f", {self.voids:,} sealed void(s)" if self.voids else ""
        if self.pockets:
            voids += f" and {self.pockets:,} pocket(s) of at most {self.pocket_volume:.2g} mm^3"
        closed = (
            f"; the cavity thinner than {self.min_cavity:.3g} mm made solid ({self.closed:.3g} "
            "mm^3): the wall is thicker there"
            if self.closed
            else ""
        )
        return f"skin by {how}: {wall}, {ok}{closed}; {self.bodies} body(ies){voids}{islands}"


@dataclass(frozen=True)
class SkinResult:
    """The skinned solid (a ``manifold3d.Manifold``; with ``split``, a
    :class:`lattice_cad.core.mesh.Mesh` when no boolean was needed to join the skin's outer
    surface) and its :class:`SkinReport`."""

    solid: Any
    report: SkinReport
    #: With ``build_skin(graph=...)``: ``solid`` is made from the lattice's elements near
    #: the wall only (caps included); ``split.glue`` puts the deep ones back into its mesh
    #: (a ``conformal.skin_split.SplitLattice``). None: ``solid`` is the whole result.
    split: Any = None


#: Fraction of a grid step by which sampling grids are shifted off round coordinates.
_GRID_SHIFT = 0.5017


def wall_tolerance(thickness: float) -> float:
    """How far (mm) a measured wall thickness may be from ``thickness``: ``WALL_RTOL`` of it
    or ``WALL_ATOL``, whichever is larger (the absolute part at most ``WALL_ATOL_SHARE`` of
    the thickness)."""
    return max(WALL_RTOL * float(thickness), _wall_atol(thickness))


def _wall_atol(thickness: float) -> float:
    """The absolute part of :func:`wall_tolerance` (mm): ``WALL_ATOL``, at most
    ``WALL_ATOL_SHARE`` of the thickness."""
    return min(WALL_ATOL, WALL_ATOL_SHARE * float(thickness))


def outer_chord(thickness: float) -> float:
    """The chord error (mm) of the part's tessellation a skin of ``thickness`` is built on:
    ``OUTER_CHORD_FRACTION`` of the wall's tolerance (:func:`wall_tolerance`)
    (0.0075 mm for t = 1.5). The struts are cut by the skin's inner wall, not by the
    part's surface, so the strut radius does not enter (a trim cuts by the part's
    surface, with ``config.CUT_DEFLECTION_RTOL`` of the radius: 0.0025 mm for r = 0.5)."""
    return OUTER_CHORD_FRACTION * wall_tolerance(thickness)


# ------------------------------------------------------------------ conversion
def shape_mesh(
    shape: Any, tolerance: float = 0.01, angular: float = 0.2
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Tessellate a cadquery/build123d/OCCT shape into a welded triangle mesh.

    Parameters
    ----------
    shape : cadquery.Workplane, cadquery.Shape, build123d shape or TopoDS_Shape
    tolerance, angular : float
        Linear (mm) and angular (rad) deflection of the tessellation.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    """
    from lattice_cad.occ_impl import shapes as occ

    topo = occ.as_topods(shape)
    if topo is None:
        raise TypeError(f"cannot tessellate a {type(shape).__name__}")
    if not occ.solids(topo):
        raise SkinError("the shape holds no solid to tessellate")
    v, f = occ.tessellate(topo, tolerance, angular)
    return weld(v, f, tol=1e-9)


def _manifold(v: NDArray[np.float64], f: NDArray[np.int64], name: str) -> Any:
    import manifold3d

    man = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(v, dtype=np.float32),
            tri_verts=np.ascontiguousarray(f, dtype=np.uint32),
        )
    )
    status = man.status()
    if status != manifold3d.Error.NoError:
        raise SkinError(f"{name} is not a closed 2-manifold solid (manifold3d: {status.name})")
    return man


def as_manifold(obj: Any, *, name: str = "part") -> Any:
    """A ``manifold3d.Manifold`` of a part or mesh.

    Parameters
    ----------
    obj : Manifold, Mesh, trimesh.Trimesh, (vertices, faces), CAD shape, or Part
        A ``conformal.Part`` is used through its mesh.
    name : str
        What to call the object in error messages.

    Raises
    ------
    SkinError
        When the mesh is not a closed 2-manifold (manifold3d's status is named).
    """
    import manifold3d

    if isinstance(obj, manifold3d.Manifold):
        return obj
    arrays = mesh_arrays(obj)
    if arrays is None:
        arrays = shape_mesh(obj)
    v, f = arrays
    if len(f) == 0:
        raise SkinError(f"{name} has no triangles")
    v, f = weld(v, f, tol=1e-9)
    return _manifold(v, f, name)


def part_solid(part: Any) -> Any:
    """The part as one ``manifold3d.Manifold``: its solids, each with its cavities
    (``Part.solid_parts``), united.

    Assemblies often hold solids that touch (share faces) or overlap; their tessellation
    then has coincident faces, which a boolean would carry into the result. Uniting the
    solids (manifold3d's union merges touching faces) gives the region the part occupies.
    A solid inside another's cavity (a ball captive in a housing) is one of them; an inward
    shell that no solid holds (inside an even number of others) is left out.

    Parameters
    ----------
    part : conformal.Part

    Returns
    -------
    manifold3d.Manifold
    """
    import manifold3d

    name = f"the part {getattr(part, 'name', '')}".strip()
    shape = as_manifold(part, name=name)
    comps = shape.decompose()
    if len(comps) <= 1:
        return shape
    solid_parts = getattr(part, "solid_parts", None)
    if solid_parts is None:  # (not a conformal.Part: its shells as they are)
        return shape
    # each solid with its own cavities, then united: a solid in another's cavity (a ball
    # captive in a housing) stays; subtracting every void from the union removed it
    solids = [
        _manifold(s.vertices, s.faces, f"{name}, solid {k}") for k, s in enumerate(solid_parts)
    ]
    return manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add)


def to_arrays(man: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices (V, 3) float64 and faces (F, 3) int64 of a manifold3d.Manifold."""
    arrays = mesh_arrays(man)
    assert arrays is not None
    return arrays


def _as_part(part: Any) -> Any:
    """A :class:`conformal.Part` of a Part, a Manifold, a mesh, a path or a CAD shape."""
    from conformal.part import Part, load_part

    if isinstance(part, Part):
        return part
    arrays = mesh_arrays(part)
    if arrays is not None:
        v, f = weld(*arrays, tol=1e-9)
        return Part(v, f, name="part")
    return load_part(part)


# ---------------------------------------------------------------- OCCT offsets
@dataclass
class PendingOffsets:
    """OCCT offsets of a part computing in a child process (:func:`start_offsets`)."""

    worker: Any
    part: Any
    thickness: float
    mid_wall: bool
    #: ``time.monotonic()`` when the offsets were started
    started: float = field(default_factory=time.monotonic)
    #: the solids the offsets were started from, until :meth:`adopt` names their part
    solids: list[Any] | None = None

    def remaining(self) -> float:
        """Seconds left of ``config.OFFSET_TIMEOUT`` (counted from the start; at least 1)."""
        return max(1.0, config.OFFSET_TIMEOUT - (time.monotonic() - self.started))

    def adopt(self, part: Any) -> bool:
        """Make these the offsets of ``part`` when they were started from its solids
        (:func:`start_solid_offsets` with the list that became ``part.shape``, the same
        objects); else False (the caller closes them)."""
        solids = self.solids
        shape = getattr(part, "shape", None)
        if solids is None or shape is None or len(shape) != len(solids):
            return False
        if not all(a is b for a, b in zip(shape, solids, strict=True)):
            return False
        self.part, self.solids = part, None
        return True


def _offset_depths(thickness: float, mid_wall: bool) -> tuple[float, ...]:
    return (thickness, 0.5 * thickness) if mid_wall else (thickness,)


def start_offsets(
    part: Any, thickness: float, *, mid_wall: bool = False, worker: Any = None
) -> PendingOffsets:
    """Start OCCT's offsets of a B-rep part in a child process and return at once.

    The child (``worker``, a :class:`lattice_cad.core.isolate.IsolatedWorker`, started
    here when not given) fuses the solids and offsets them while the caller builds the
    lattice; :func:`build_skin` (``offsets=``) collects the result. On this 2-core
    machine's GE bracket that hides the child's start-up (importing OpenCascade) and the
    offset behind the lattice fill and stitch.
    """
    if part.shape is None:
        raise SkinError("OCCT offsets need a B-rep part (STEP, CadQuery or build123d)")
    pending = start_solid_offsets(list(part.shape), thickness, mid_wall=mid_wall, worker=worker)
    pending.part, pending.solids = part, None
    return pending


def start_solid_offsets(
    solids: list[Any], thickness: float, *, mid_wall: bool = False, worker: Any = None
) -> PendingOffsets:
    """:func:`start_offsets` of a part's solids, before the part is made of them (they are
    tessellated and checked meanwhile: ``conformal.load_part(on_solids=)``); then
    :meth:`PendingOffsets.adopt` names the part."""
    from lattice_cad.core.isolate import IsolatedWorker
    from lattice_cad.occ_impl import shapes as occ

    worker = IsolatedWorker() if worker is None else worker
    depths = _offset_depths(thickness, mid_wall)
    deflection, angular, merge_tol = _offset_meshing(thickness)
    occ.start_fused_offsets(
        list(solids),
        tuple(-d for d in depths),
        worker,
        deflection=deflection,
        angular=angular,
        merge_tol=merge_tol,
    )
    pending = PendingOffsets(worker, None, float(thickness), bool(mid_wall))
    pending.solids = list(solids)
    return pending


def _offset_meshing(thickness: float) -> tuple[float, float, float]:
    """How the child meshes OCCT's offsets: chord deflection, angular deflection, and the
    distance below which ``merge_close`` merges the faces' copies of edge nodes."""
    return 0.01 * thickness, 0.1, 1e-6 * thickness


def _pending_for(pending: PendingOffsets, part: Any, thickness: float, mid_wall: bool) -> bool:
    """Whether ``pending`` are the offsets of ``part`` (or of the B-rep it was tessellated
    again from: ``Part.refined``, as ``Lattice`` cuts by), ``thickness`` and ``mid_wall``."""
    same = pending.part is part or pending.part is getattr(part, "unrefined", None)
    return same and pending.thickness == thickness and pending.mid_wall == mid_wall


def _occt_surfaces(
    part: Any, thickness: float, mid_wall: bool = False, pending: PendingOffsets | None = None
) -> tuple[Any, ...]:
    """Outer and inner surfaces of a B-rep part from OCCT's offset (Manifolds): the outer
    one is the part's mesh (:func:`part_solid`), the inner ones OCCT's offsets, each
    checked against that mesh (every vertex at its depth below it).

    ``pending``: the offsets already started by :func:`start_offsets` (used when they are
    of this part, thickness and ``mid_wall``; otherwise started here).

    Raises
    ------
    OCCTFailure
        An offset is not done, invalid, not one solid, or not inside its solid.
    """
    import manifold3d

    from lattice_cad.occ_impl import shapes as occ

    if pending is not None and not _pending_for(pending, part, thickness, mid_wall):
        pending.worker.close()
        pending = None
    if pending is None:
        pending = start_offsets(part, thickness, mid_wall=mid_wall)
    tol = wall_tolerance(thickness)
    chord = max(float(getattr(part, "deflection", 0.0)), getattr(part, "chord_error", None) or 0.0)
    dists = _offset_depths(thickness, mid_wall)
    out = [manifold3d.Manifold() for _ in dists]
    # volumes and meshes come from the child (meshed there, while this process stitched)
    results = occ.fused_offsets_result(
        pending.worker, timeout=pending.remaining(), budget=config.OFFSET_TIMEOUT
    )
    if all(meshes is not None for _, meshes in results):  # else the loop says which solid
        _check_inset_volume(part, thickness, sum(vols[1] for vols, _ in results))
        insets = [m[0] for _, m in results if m is not None]
        _check_deep_points_inside(part, thickness, insets, tol + chord)
    for k, (vols, meshes) in enumerate(results):
        if meshes is None:
            bad = next(d for d, v in zip(dists, vols[1:], strict=True) if not 0.0 < v < vols[0])
            raise OCCTFailure(f"solid {k}: the offset by {-bad:g} is not inside the solid")
        # the offsets must really be offsets: every inner vertex at its depth below the
        # part's surface (OCCT can return valid solids that are not; the fused solids
        # bound the part's volume, so the nearest surface of an inner vertex is its own),
        # measured on the part's mesh, which deviates from it by up to its chord error
        for (v, _), dist in zip(meshes, dists, strict=True):
            depth = part.distance(v)
            worst = float(np.abs(depth - dist).max())
            if worst > tol + chord:
                raise OCCTFailure(
                    f"solid {k}: the offset by {-dist:g} is up to {worst:.3g} mm off the wall "
                    "thickness asked for"
                )
        pieces = [_manifold(v, f, f"solid {k} (offset)") for v, f in meshes]
        out = [a + b for a, b in zip(out, pieces, strict=True)]
    return (part_solid(part), *out)


def _check_inset_volume(part: Any, thickness: float, inset: float) -> None:
    """Refuse OCCT's offsets when their volume (``inset``, mm^3, all solids) is not about
    what the part's distance field holds deeper than ``thickness``.

    OCCT can return a valid solid that is the offset of a piece of the part only (a box
    with filleted edges united with a block: the block's inset alone, 702 of the 7,300
    mm^3 expected); each of its vertices lies at the right depth, so the per-vertex check
    passes, and the skin would leave the rest of the part solid. The distance transform of
    :meth:`Part.inscribed_radius`'s grid (spacing ``h``) gives the volume deeper than
    ``thickness`` to within about one grid layer of the inset's surface, at most the
    part's area times ``h``: a difference of more than twice that is not an offset.
    """
    grid = part._depth_grid(96)
    if grid is None or not math.isfinite(inset):
        return
    _, h, depth = grid
    expected = float(np.count_nonzero(depth > thickness)) * h**3
    slack = 2.0 * float(part.area) * h
    if abs(inset - expected) > slack:
        raise OCCTFailure(
            f"the offset by {-thickness:g} holds {inset:.4g} mm^3, where the part's distance "
            f"field has about {expected:.4g} mm^3 (+- {slack:.3g}) deeper than {thickness:g} "
            "mm: OCCT offset a piece of the part only"
        )


def _check_deep_points_inside(
    part: Any, thickness: float, insets: list[Any], tol: float, samples: int = 4000
) -> None:
    """Refuse OCCT's offsets (``insets``: (vertices, faces) of each solid's offset by
    ``thickness``) when a point of the part deeper than ``thickness + tol`` (exact distance
    to its mesh) lies outside all of them: the inset holds every such point.

    Up to ``samples`` points of :meth:`Part._depth_grid` are tested (spread by a fixed
    stride). :func:`_check_inset_volume` cannot see a piece missing when its allowance
    (twice the area times the grid step) exceeds the volume itself: a V-grooved pulley with
    spokes, t = 1.11 mm, where OCCT offset 14 of 47 faces (11,895 of ~53,000 mm^3) and the
    skin came out in 5 bodies that no retry could write."""
    from conformal.part import Part

    grid = part._depth_grid(96)
    if grid is None:
        return
    origin, h, depth = grid
    cand = np.argwhere(depth > thickness + tol)
    if not len(cand):
        return
    cand = cand[:: max(1, len(cand) // samples)]
    pts = origin + cand * h
    deep = pts[part.distance(pts) > thickness + tol]
    if not len(deep):
        return
    v = np.vstack([m[0] for m in insets])
    offsets = np.cumsum([0] + [len(m[0]) for m in insets[:-1]])
    f = np.vstack([m[1] + o for m, o in zip(insets, offsets, strict=True)])
    out = ~Part(v, f, name="the offsets").contains(deep)
    if out.any():
        x, y, z = deep[np.argmax(out)]
        raise OCCTFailure(
            f"the offset by {-thickness:g} leaves out {int(out.sum())} of {len(deep)} points "
            f"of the part deeper than that (e.g. ({x:.4g}, {y:.4g}, {z:.4g})): OCCT offset "
            "a piece of the part only"
        )


# ---------------------------------------------------------------- voxel field
def _grid_spacing(extent: NDArray[np.float64], thickness: float) -> float:
    h = thickness / config.VOXELS_PER_THICKNESS
    vol = float(np.prod(extent + 4 * h))
    if vol / h**3 > config.MAX_VOXELS:
        h = (vol / config.MAX_VOXELS) ** (1.0 / 3.0)
    return h


def _distance_field(
    part: Any, thickness: float, h: float, low: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Depth below the surface at grid points (negative outside), exact near the level.

    Returns
    -------
    depth : (nx, ny, nz) float64
        Distance to the part's surface at points inside, ``-thickness`` outside.
    origin : (3,) float64
        Position of grid point ``[0, 0, 0]``.
    """
    return _finish(_distance_field_steps(part, thickness, h, low))


def _distance_field_steps(part: Any, thickness: float, h: float, low: float | None = None) -> Any:
    """:func:`_distance_field` as a generator: yields between its stages, returns the
    result (see :func:`_finish`)."""
    from conformal._skin_kernels import edt_squared

    pad = 2 * h
    # off the round positions a CAD part's faces sit on: a vertical ray of the inside test
    # along a face would be ambiguous
    origin = part.bounds[0] - pad + _GRID_SHIFT * h
    dims = tuple(int(n) for n in np.ceil((part.size + 2 * pad) / h).astype(np.int64) + 1)
    inside = part.grid_contains(origin, np.full(3, h), dims)
    # exact Euclidean distance transform (as scipy's distance_transform_edt, compiled)
    depth = np.sqrt(edt_squared(inside, h))
    depth -= 0.5 * h
    depth[~inside] = -thickness
    yield
    # exact distances where the level t is extracted (the transform is off by up to half a
    # voxel there)
    low = thickness if low is None else low  # the lowest level extracted
    band = inside & (depth > low - 2 * h) & (depth < thickness + 2 * h)
    idx = np.argwhere(band)
    if len(idx):
        pts = origin + idx * h
        exact = np.empty(len(pts))
        for start in range(0, len(pts), DISTANCE_CHUNK):
            if start:
                yield  # (in chunks: a caller waiting for OCCT looks again between them)
            stop = start + DISTANCE_CHUNK
            exact[start:stop] = part.distance(pts[start:stop], max_distance=thickness + 4 * h)
        depth[band] = np.where(np.isfinite(exact), exact, depth[band])
    return depth, origin


def _finish(steps: Any) -> Any:
    """Run a generator of stages (``yield`` between them) to its end; its return value."""
    try:
        while True:
            next(steps)
    except StopIteration as stop:
        return stop.value


def _voxel_surfaces(
    part: Any, thickness: float, h: float, mid_wall: bool = False
) -> tuple[tuple[Any, ...], tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Outer and inner (and mid-wall) surfaces of a part from its distance field
    (Manifolds), and that field (``depth``, ``origin``: :func:`_distance_field`)."""
    return _finish(_voxel_steps(part, thickness, h, mid_wall))


def _voxel_steps(part: Any, thickness: float, h: float, mid_wall: bool = False) -> Any:
    """:func:`_voxel_surfaces` as a generator of its stages (yields between them, returns
    what it returns), so that it can run while OCCT's offset is still computing in its
    child and be left off when that succeeds (:func:`_surfaces`)."""
    import manifold3d

    low = 0.5 * thickness if mid_wall else None
    depth, origin = yield from _distance_field_steps(part, thickness, h, low)
    yield
    out = [part_solid(part)]  # touching solids of an assembly united
    # marching tetrahedra give about 20 triangles per voxel face of the surface, mostly on
    # flat walls: manifold3d's simplification (no surface moves by more than the tolerance,
    # a quarter of the wall's relative accuracy bound) removes ~95 % of them before the
    # booleans. Relative only: on a small part the absolute bound (0.02 mm) is a large
    # fraction of the wall, and so coarse a surface folds when rounded to float32.
    tol = SIMPLIFY_FRACTION * WALL_RTOL * thickness
    for level in (thickness, 0.5 * thickness) if mid_wall else (thickness,):
        v, f = marching_tets(depth - level, origin, h)  # depth is sampled at the grid points
        if SHARPEN_CREASES and len(f):  # the creases back (conformal.skin_crease)
            from conformal.skin_crease import sharpen

            v, f, _ = sharpen(v, f, part, level, 0.5 * WALL_RTOL * level)
        if len(f) == 0:
            out.append(manifold3d.Manifold())
            continue
        yield
        man = _manifold(v, f, f"the inset by {level:g}")
        del v, f
        yield
        out.append(_simplified(man, tol, f"the inset by {level:g}"))
    return tuple(out), (depth, origin)


def _closed_cavity(
    surfaces: tuple[Any, ...],
    field: tuple[NDArray[np.float64], NDArray[np.float64]],
    h: float,
    thickness: float,
    min_cavity: float | None,
) -> tuple[tuple[Any, ...], tuple[float, NDArray[np.float64]] | None]:
    """The skin's ``surfaces`` (outer, inner, ...) with the cavity closed where it is thinner
    than ``min_cavity`` (:func:`_cavity_closing` on ``field``, the part's distance field:
    the one the voxel method's surfaces were extracted from, or one computed for OCCT's
    offsets), and what was closed (volume, a point) or None. For the voxel method, done
    only once the voxel surfaces are the ones used, not while OCCT's offsets compute:
    there it delayed the GE bracket's skin, whose offsets succeed (its surfaces' stage
    5.5 s against 3.7 s in alternating runs on a loaded machine)."""
    if not min_cavity:
        return surfaces, None
    depth, origin = field
    closing = _cavity_closing(depth, origin, h, thickness, 0.5 * float(min_cavity))
    if closing is None:
        return surfaces, None
    room, volume, at = closing
    out = list(surfaces)
    out[1] = out[1] ^ room  # the cavity where struts fit
    return tuple(out), (volume, at)


def _cavity_closing(
    depth: NDArray[np.float64],
    origin: NDArray[np.float64],
    h: float,
    thickness: float,
    rho: float,
) -> tuple[Any, float, NDArray[np.float64]] | None:
    """Where the skin's cavity (``depth > thickness``) is thinner than ``2 rho``: None when
    nowhere (or in less than ``CLOSE_MIN_SHARE`` of it); else the region the cavity is kept
    in (a Manifold: the points within ``sqrt(3) rho + OPEN_SLACK * h`` of the points deeper
    than ``thickness + rho``; empty when none is), the volume of the cavity outside it
    (mm^3) and (3,) float64 one point of that.

    A 3 mm mug wall under a 1.33 mm skin left a 0.34 mm cavity, thinner than the voxel
    grid and than the struts (1.33 mm across): the struts cut into it fell into ~1,000
    sealed slivers that float32 could not hold, and every retry of the skin failed (made
    outside shared/data, s34). Such a cavity holds no strut: it is made wall instead.

    Parameters
    ----------
    depth : (nx, ny, nz) float64
        The distance field (:func:`_distance_field`).
    origin : (3,) float64
        Position of its grid point ``[0, 0, 0]``.
    """
    import manifold3d

    from conformal._skin_kernels import edt_squared

    cavity = depth > thickness
    if not cavity.any():
        return None
    core = depth > thickness + rho
    reach = math.sqrt(3.0) * rho + OPEN_SLACK * h
    near = edt_squared(~core, h) if core.any() else None  # squared distance to the core
    closed = cavity if near is None else cavity & (near > reach * reach)
    n = int(np.count_nonzero(closed))
    if not n or (near is not None and n < CLOSE_MIN_SHARE * np.count_nonzero(cavity)):
        return None
    at = origin + np.argwhere(closed)[0] * h
    if near is None:
        return manifold3d.Manifold(), n * h**3, at
    field = reach - np.sqrt(np.minimum(near, 4.0 * reach * reach))
    v, f = marching_tets(field, origin, h)
    if not len(f):
        return manifold3d.Manifold(), n * h**3, at
    room = _manifold(v, f, "the cavity's room for struts")
    tol = SIMPLIFY_FRACTION * WALL_RTOL * thickness
    return _simplified(room, tol, "the cavity's room for struts"), n * h**3, at


def _simplified(man: Any, tol: float, name: str) -> Any:
    """``man.simplify(tol)`` without folds (``conformal.skin_untangle.unfolded``); where
    the simplification folds the surface beyond repair, a smaller tolerance
    (``SIMPLIFY_BACKOFF``), else ``man`` itself. The booleans would carry the folds into
    the skinned solid, which then fails the float32 check in every retry."""
    for k in SIMPLIFY_BACKOFF:
        done = unfolded(man.simplify(k * tol), name)
        if done is not None:
            return done[0]
    return man


def _project_to_offset(
    inner: Any, surface: Any, thickness: float, steps: int = 3, *, refine: bool = True
) -> Any:
    """The inner surface (a Manifold) with every vertex moved along the direction to its
    closest point on ``surface`` (a Part) until it lies at ``thickness`` from it.

    The offset of the part's mesh is exactly the set of points at that distance; a vertex
    of the marching tetrahedra (linear interpolation of a sampled distance) or of OCCT's
    offset of the exact B-rep (whose faces lie within the tessellation's deflection of
    the part's mesh) is off it by up to a few percent of the wall. Newton steps on the
    distance move it there; a vertex whose move would turn a face over stays where it was.
    """
    v0, f = to_arrays(inner)
    if len(f) == 0:
        return inner
    # faces turned over (or flattened): their vertices go back
    v = revert_flips(v0, _newton_to_offset(v0, surface, thickness, steps), f)
    if refine:  # (the voxel method's creases do not converge: measured no better there)
        tol = 0.5 * wall_tolerance(thickness)
        v, f = _refine_to_offset(v, f, surface, thickness, tol)
    return _manifold(v, f, "the inner surface")


def _newton_to_offset(
    p: NDArray[np.float64], surface: Any, thickness: float, steps: int = 3
) -> NDArray[np.float64]:
    """(P, 3) float64: points moved along the direction to their closest points on
    ``surface`` until they lie at ``thickness`` from it (points far off stay)."""
    p = np.array(p, dtype=np.float64)
    for _ in range(steps):
        d, c = surface.closest(p, max_distance=2.0 * thickness)
        ok = np.isfinite(d) & (d > 0.5 * thickness)
        p[ok] += (thickness - d[ok])[:, None] * (p[ok] - c[ok]) / d[ok][:, None]
    return p


def _refine_to_offset(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    surface: Any,
    thickness: float,
    tol: float,
    rounds: int = 16,
    growth: float = 2.0,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Split the longest edge of every face whose centre is more than ``tol`` off the
    offset (a face across a crease of it, or across several facets of the part's mesh),
    at its midpoint moved onto the offset; both faces of the edge are halved, so the
    surface stays closed and 2-manifold. Up to ``rounds`` passes, and no more than
    ``growth`` times the faces it started with (a sharp crease of the offset is never
    within ``tol`` of a face across it, only closer).

    v : (V, 3) float64, f : (F, 3) int64; returns the refined (V', 3), (F', 3).
    """
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(f, dtype=np.int64)

    def normal(a: Any, b: Any, c: Any) -> Any:
        return np.cross(b - a, c - a)

    limit = int(growth * len(f))
    check = np.arange(len(f))  # the faces whose centres are measured (new ones after a pass)
    for _ in range(rounds):
        d = surface.distance(v[f[check]].mean(axis=1), max_distance=2.0 * thickness)
        bad = check[np.isfinite(d) & (np.abs(d - thickness) > tol)]
        if not len(bad) or len(f) >= limit:
            break
        bad = bad[: max(1, (limit - len(f)) // 2)]
        t = v[f[bad]]
        lengths = np.stack(
            [np.linalg.norm(t[:, (k + 1) % 3] - t[:, k], axis=1) for k in range(3)], axis=1
        )
        k = np.argmax(lengths, axis=1)
        a, b = f[bad, k], f[bad, (k + 1) % 3]
        nv = np.int64(len(v))
        he_key = np.concatenate([f[:, m] * nv + f[:, (m + 1) % 3] for m in range(3)])
        he_face = np.tile(np.arange(len(f)), 3)
        he_k = np.repeat(np.arange(3), len(f))
        order = np.argsort(he_key)
        he_key, he_face, he_k = he_key[order], he_face[order], he_k[order]
        twin = b * nv + a
        pos = np.minimum(np.searchsorted(he_key, twin), len(he_key) - 1)
        has = he_key[pos] == twin
        fi, ki, fj, kj = bad[has], k[has], he_face[pos[has]], he_k[pos[has]]
        # every face is split at most once a pass: an edge is split when it is the first
        # candidate of both its faces
        first = np.full(len(f), len(fi), dtype=np.int64)
        idx = np.arange(len(fi))
        np.minimum.at(first, fi, idx)
        np.minimum.at(first, fj, idx)
        sel = np.flatnonzero((first[fi] == idx) & (first[fj] == idx))
        if not len(sel):
            break
        fi, ki, fj, kj = fi[sel], ki[sel], fj[sel], kj[sel]
        va, vb = f[fi, ki], f[fi, (ki + 1) % 3]
        vc, vd = f[fi, (ki + 2) % 3], f[fj, (kj + 2) % 3]
        mid = 0.5 * (v[va] + v[vb])
        proj = _newton_to_offset(mid, surface, thickness)
        ni, nj = normal(v[va], v[vb], v[vc]), normal(v[vb], v[va], v[vd])
        keep = np.ones(len(mid), dtype=bool)  # no new face may turn over
        for tri, n0 in (
            ((v[va], proj, v[vc]), ni),
            ((proj, v[vb], v[vc]), ni),
            ((v[vb], proj, v[vd]), nj),
            ((proj, v[va], v[vd]), nj),
        ):
            keep &= np.einsum("ij,ij->i", normal(*tri), n0) > 0
        vm = nv + np.arange(len(mid))
        v = np.vstack([v, np.where(keep[:, None], proj, mid)])
        f = f.copy()
        f[fi] = np.stack([va, vm, vc], axis=1)
        f[fj] = np.stack([vb, vm, vd], axis=1)
        n0 = len(f)
        f = np.vstack([f, np.stack([vm, vb, vc], axis=1), np.stack([vm, va, vd], axis=1)])
        check = np.concatenate([fi, fj, np.arange(n0, len(f))])
    return v, f


def wall_thickness(inner: Any, outer: Any) -> NDArray[np.float64]:
    """(V + F,) float64: distance from each vertex and each face centre of the inner
    surface to the outer surface (the centres see where a face cuts across a crease).

    ``outer`` may be a Manifold, a mesh or a Part (whose distance bins are then reused).
    """
    iv, fi = to_arrays(inner)
    if len(iv) == 0:
        return np.zeros(0)
    return _as_part(outer).distance(np.vstack([iv, iv[fi].mean(axis=1)]))


# ------------------------------------------------------------------- public API
def checked(solid: Any, what: str) -> Any:
    """``solid`` (a Manifold) if ``fast_stitch.check`` accepts it, else a :class:`SkinError`.

    manifold3d's booleans are 2-manifold by construction, but surfaces that meet within a
    rounding step can still touch or cross; every solid this module hands to a user is
    checked in full (self-intersections included), and the error says where.
    """
    import fast_stitch
    from lattice_cad.core.mesh import Mesh

    if solid.is_empty():
        return solid
    v, f = to_arrays(solid)
    report = fast_stitch.check(Mesh(vertices=v, faces=f))
    if report.valid:
        return solid
    faces = np.concatenate(
        [
            np.asarray(report.zero_area_faces, dtype=np.int64).ravel(),
            np.asarray(report.self_intersection_pairs, dtype=np.int64).ravel(),
        ]
    )
    where = ""
    if len(faces):
        x, y, z = v[f[faces[0]]].mean(axis=0)
        where = f"; first problem near ({x:.4g}, {y:.4g}, {z:.4g})"
    raise SkinError(f"{what} is not a valid solid ({report}){where}")


def inset(part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """The part shrunk by ``thickness`` (its cavity when hollowed), as a Manifold.

    Uses the voxel distance field (see the module docstring); empty when the part is
    nowhere thicker than ``2 * thickness``.
    """
    _check_thickness(thickness)
    p = _as_part(part)
    h = float(voxel) if voxel is not None else _grid_spacing(p.size, thickness)
    return checked(_voxel_surfaces(p, thickness, h)[0][1], f"the inset by {thickness:g}")


def hollow(part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """The skin: ``part`` minus its inset by ``thickness`` (a Manifold).

    Raises
    ------
    SkinError
        When the part has no room for a cavity (it is thinner than ``2 * thickness``).
    """
    p = _as_part(part)
    cavity = inset(p, thickness, voxel=voxel)
    if cavity.is_empty():
        raise SkinError(
            f"the part is nowhere thicker than twice the skin thickness {thickness:g}: "
            "no room for a lattice (use a thinner skin)"
        )
    return checked(as_manifold(p) - cavity, f"the skin of {p.name}")


def _check_thickness(thickness: Any) -> None:
    if not (isinstance(thickness, (int, float)) and math.isfinite(thickness) and thickness > 0):
        raise ValueError(f"skin thickness must be a positive number, got {thickness!r}")


def no_room_message(
    thickness: float,
    greatest: float,
    *,
    strut: float | None = None,
    closed: bool = False,
    grid: float | None = None,
) -> str:
    """Why a skin of ``thickness`` (mm) leaves no cavity for a lattice in a part whose
    greatest thickness is ``greatest`` (mm; twice ``Part.inscribed_radius``), and which
    skin would. ``strut``: the struts' diameter (mm, ``build_skin(min_cavity=)``): a skin
    advised leaves a cavity at least that thick (one leaving a thinner cavity would be
    refused next). ``closed``: the cavity left was nowhere as thick as ``strut`` on the
    voxel grid of step ``grid`` (mm), and was made solid wall."""
    if strut is not None and closed:
        room = greatest - strut
        better = (
            f"a skin thinner than about {0.4 * room:.3g} mm leaves room for them"
            if room > 0
            else "thinner struts and a thinner skin would be needed"
        )
        where = f"nowhere as thick as the struts ({strut:.3g} mm across)"
        if grid is not None and math.isfinite(grid) and greatest > 2.0 * thickness + strut:
            # (a tapered wing 17.7 mm thick under a 5.56 mm skin, 5.56 mm struts: its cavity
            # is that thick only within about 0.4 mm of its mid-surface; made outside
            # shared/data)
            where = (
                f"as thick as the struts ({strut:.3g} mm across) only in spots narrower than "
                f"its voxel grid keeps ({grid:.3g} mm)"
            )
        return (
            f"the skin of {thickness:g} mm leaves a cavity {where}: no room for the lattice; "
            f"the part's greatest thickness is about {greatest:.3g} mm, so {better}, or fill "
            "it without a skin"
        )
    if greatest > 2.0 * thickness:
        # (the inset came out empty though the part is thicker somewhere: its thick spots,
        # rib crossings of a machine bed, are narrower than the voxel grid resolves)
        return (
            f"the inset of the part by the skin thickness {thickness:g} mm came out empty: "
            f"its greatest thickness is about {greatest:.3g} mm, but only in spots too small "
            f"for a cavity to hold a lattice; a skin thinner than about "
            f"{0.4 * greatest:.3g} mm leaves a cavity for the lattice there"
        )
    said = (
        f"the part is nowhere thicker than twice the skin thickness {thickness:g} mm: "
        f"no room for a lattice; its greatest thickness is about {greatest:.3g} mm, so "
    )
    if strut is None:
        advice = f"a skin thinner than about {0.4 * greatest:.3g} mm leaves a cavity for a lattice"
    elif greatest > strut:
        advice = (
            f"a skin thinner than about {0.4 * (greatest - strut):.3g} mm leaves a cavity as "
            f"thick as the struts ({strut:.3g} mm across)"
        )
    else:  # (a tapered tube's 2 mm wall, 2.44 mm struts: the advised skin was refused next)
        advice = (
            f"no skin leaves a cavity as thick as the struts ({strut:.3g} mm across): struts "
            f"of radius below {0.25 * greatest:.3g} mm under a skin thinner than about "
            f"{0.2 * greatest:.3g} mm would fit"
        )
    return f"{said}{advice}, or fill it without a skin"


def _no_room(part: Any, thickness: float) -> bool:
    """Whether no point of ``part`` (a :class:`conformal.Part`) lies ``thickness`` deep,
    proven (:meth:`conformal.Part.thinner_than`) with the skin's tolerance
    (``WALL_RTOL * thickness``) and twice the tessellation's chord error to spare: then
    the exact inset is empty too, and OCCT's offset cannot give a wall (nor room for a
    lattice)."""
    chord = float(getattr(part, "chord_error", None) or getattr(part, "deflection", 0.0) or 0.0)
    depth = (1.0 - WALL_RTOL) * thickness - 2.0 * chord
    return depth > 0 and bool(part.thinner_than(depth, budget=NO_ROOM_BUDGET))


def _surfaces(
    part: Any,
    thickness: float,
    method: str,
    voxel: float | None,
    mid_wall: bool = False,
    pending: PendingOffsets | None = None,
    min_cavity: float | None = None,
) -> tuple[tuple[Any, ...], str, str, float, tuple[float, NDArray[np.float64]] | None]:
    """(outer, inner[, mid]), the method used, why OCCT was not used, the voxel size, and
    what the voxel method closed of a cavity thinner than ``min_cavity`` (volume, a point;
    see :func:`_cavity_closing`) or None.

    With ``method="auto"`` and OCCT's offsets still computing in their child (``pending``),
    the voxel surfaces are computed meanwhile, stage by stage, until the child is done:
    if the offset fails (the GE bracket's does, after ~2 s), that work was not waited for;
    if it succeeds, at most one stage is spent in vain.
    """
    fallback = ""
    h = float(voxel) if voxel is not None else _grid_spacing(part.size, thickness)
    steps = None  # the voxel surfaces, begun while OCCT's offsets compute
    voxel_done = None  # ... and finished meanwhile
    if (
        method == "auto"
        and part.shape is not None
        and pending is not None
        and _pending_for(pending, part, thickness, mid_wall)
        and pending.worker.running
    ):
        steps = _voxel_steps(part, thickness, h, mid_wall)
        try:
            while pending.worker.running:
                next(steps)
        except StopIteration as stop:
            voxel_done = stop.value
        if voxel_done is not None and voxel_done[0][1].is_empty() and _no_room(part, thickness):
            # no room for the inset, proven: the offsets, which cannot succeed, are not
            # waited for (trimesh_box_sides: OCCT tried its ways for 30 s before failing)
            pending.worker.close()
            why = "the part is thinner than twice the skin"
            return voxel_done[0], "voxel", why, h, None
    if method in ("auto", "occt") and part.shape is not None:
        try:
            occt = _occt_surfaces(part, thickness, mid_wall, pending)
            return occt, "occt", "", float("nan"), None
        except (OCCTFailure, SkinError) as exc:
            if method == "occt":
                raise SkinError(f"OpenCascade's offset failed: {exc}") from exc
            fallback = str(exc)
        except Exception as exc:  # OCCT raises Standard_Failure as RuntimeError & co
            if method == "occt":
                raise SkinError(f"OpenCascade's offset failed: {exc}") from exc
            fallback = f"{type(exc).__name__}: {exc}"
    elif method == "occt":
        raise SkinError("method='occt' needs a B-rep part (STEP, CadQuery or build123d)")
    if pending is not None:
        pending.worker.close()
    if steps is not None:
        surfaces, field = voxel_done if voxel_done is not None else _finish(steps)
    else:
        surfaces, field = _voxel_surfaces(part, thickness, h, mid_wall)
    surfaces, closed = _closed_cavity(surfaces, field, h, thickness, min_cavity)
    return surfaces, "voxel", fallback, h, closed


def _keep_attached(solid: Any, outer: Any) -> tuple[Any, int, int, NDArray[np.float64]]:
    """Drop the pieces that do not reach the outer surface (lattice islands).

    Returns the kept solid, the number of bodies, the number of islands removed, and the
    volume (mm^3) of each sealed void ((K,) float64; the negative-volume components:
    cavity walls, always kept). ``outer``: Manifold or Part.

    The pieces are found on the arrays (``conformal.skin_split.pieces``), not by
    ``Manifold.decompose``, whose time grows with the number of pieces times the mesh: a
    dome shelled to 1.8 mm under a skin of 0.8 mm (made outside shared/data) leaves a
    0.2 mm cavity that its 0.8 mm struts cut into 2,295 closed voids, and ``decompose`` of
    that 1.08 M-triangle solid ran for more than 5 minutes (the arrays: 1.2 s).
    """
    from conformal.skin_split import kept_pieces, pieces

    v, f = to_arrays(solid)
    n, vlabel, vols = pieces(v, f)
    voids = -vols[vols < 0]
    if n <= 1:
        return solid, n - len(voids), 0, voids
    surface = _as_part(outer)
    tol = 1e-4 * float(np.linalg.norm(surface.size))
    # each positive piece's vertices, up to about 2,000 of them (every k-th), in one query
    used = np.flatnonzero(vlabel >= 0)
    lab = vlabel[used]
    order = np.argsort(lab, kind="stable")
    counts = np.bincount(lab, minlength=n)
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order)) - np.repeat(np.cumsum(counts) - counts, counts)
    step = np.maximum(1, counts // 2000)
    pick = (vols[lab] >= 0) & (rank % step[lab] == 0)
    near = np.full(n, np.inf)
    if pick.any():
        d = surface.distance(v[used[pick]], max_distance=2 * tol)
        np.minimum.at(near, lab[pick], d)
    attached = near <= tol
    keep = (vols < 0) | attached
    bodies = int(np.count_nonzero((vols >= 0) & attached))
    islands = int(np.count_nonzero(~keep))
    if not islands:
        return solid, bodies, 0, voids
    # Manifold.compose drops negative (cavity) components: the kept triangles instead
    kv, kf = kept_pieces(v, f, keep[vlabel[f[:, 0]]])
    return _manifold(kv, kf, "the skinned part"), bodies, islands, voids


def build_skin(
    lattice: Any,
    part: Any,
    thickness: float,
    *,
    method: str = "auto",
    voxel: float | None = None,
    check: bool = True,
    mid_wall: bool = False,
    offsets: PendingOffsets | None = None,
    graph: Any = None,
    min_cavity: float | None = None,
) -> SkinResult:
    """One solid per solid of the part: its skin united with the lattice inside it.

    Parameters
    ----------
    lattice : Mesh, Manifold or mesh-like
        The stitched lattice (struts may cross the part's boundary: what lies outside the
        inset by ``thickness`` is wall or is cut away, so every strut reaching the
        boundary ends inside the wall).
    part : conformal.Part, path or CAD shape
    thickness : float
        Wall thickness (mm).
    method : {"auto", "occt", "voxel"}
        ``"auto"``: OCCT offsets for B-rep parts, the voxel field otherwise or when OCCT
        fails (the report says why).
    voxel : float, optional
        Grid spacing of the voxel method.
    check : bool
        Check the solid in full (:func:`checked`; a :class:`SkinError` names where it
        fails). ``Lattice`` passes False: it checks the mesh after rounding it to float32.
    mid_wall : bool
        Build the same solid the older way, ``(part - inset) + (lattice & mid-wall inset)``
        (one more surface and boolean, slower): a fallback for the rare result of the
        default ``part - (inset - lattice)`` that cannot be rounded to float32.
    offsets : PendingOffsets, optional
        OCCT's offsets already started by :func:`start_offsets` (used when they are of
        this part, thickness and ``mid_wall``).
    graph : LatticeGraph, optional
        The graph ``lattice`` was stitched from (``fast_stitch.stitch``), with
        ``check=False``: the booleans then run on the lattice's elements near the wall only
        and ``SkinResult.split`` glues the deep ones back (see :mod:`conformal.skin_split`).
    min_cavity : float, optional
        The thinnest cavity (mm) a lattice is kept in, e.g. its struts' diameter: with the
        voxel method, where the cavity inside the wall is thinner than this it is made
        wall (solid), said in a warning and in the report (``closed``). A cavity that thin
        holds slivers of struts only (a 0.34 mm cavity in a mug's 3 mm wall under a
        1.33 mm skin: ~1,000 of them, which float32 could not hold). Not applied to
        OCCT's offsets.

    Returns
    -------
    SkinResult
        ``solid`` (a ``manifold3d.Manifold``, watertight and 2-manifold) and its report.
    """
    _check_thickness(thickness)
    if method not in ("auto", "occt", "voxel"):
        raise ValueError(f"method must be 'auto', 'occt' or 'voxel', got {method!r}")
    t0 = time.perf_counter()
    p = _as_part(part)
    surfaces, used, fallback, h, closed = _surfaces(
        p, thickness, method, voxel, mid_wall, offsets, min_cavity
    )
    outer, inner = surfaces[0], surfaces[1]
    if inner.is_empty():
        raise SkinError(
            no_room_message(
                thickness,
                2.0 * p.inscribed_radius(),
                strut=min_cavity,
                closed=closed is not None,
                grid=h,
            )
        )
    surface = _as_part(outer)  # one distance structure for the islands and the wall
    if used == "occt":  # the voxel surface: projecting its creases folds faces (screw)
        inner = _project_to_offset(inner, surface, thickness, refine=True)
    # folds of the inner wall would pass into the result, which float32 then cannot hold:
    # collapsed here (conformal.skin_untangle; the voxel wall comes without them)
    inner, untangled = untangle(inner)
    if mid_wall:
        surfaces = (outer, inner, untangle(surfaces[2])[0])
    t1 = time.perf_counter()
    wall = wall_thickness(inner, surface)
    t_wall = time.perf_counter() - t1

    def booleans(inner: Any) -> tuple[Any, Any, int, int, NDArray[np.float64]]:
        """(solid, split or None, bodies, islands removed, sealed voids' volumes)."""
        split = None
        if graph is not None and not mid_wall and not check:
            split = _split(lattice, graph, inner, thickness)
        if split is not None:
            # the booleans on the elements near the wall only (conformal.skin_split)
            near = _manifold(split.near_vertices, split.near_faces, "the lattice near the wall")
            solid = _outer_minus(outer, inner - near, inner, surface, wall, thickness)
            tol = 1e-4 * float(np.linalg.norm(surface.size))

            def touches(v: NDArray[np.float64]) -> bool:
                sample = v[:: max(1, len(v) // 2000)]
                return bool(surface.distance(sample, max_distance=2 * tol).min() <= tol)

            # pieces found on the arrays (one vertex per position: no vertex properties)
            n_bodies = (
                split.bodies(*to_arrays(solid), touches)
                if isinstance(solid, Mesh) or solid.num_prop() == 0
                else None
            )
            if n_bodies is None:  # islands: the booleans on the whole lattice remove them
                split = None
            else:
                (bodies, voids), islands = n_bodies, 0
        folded = folded_wall(surface, name=p.name) if split is None else None
        if folded is not None:
            # the booleans on the whole lattice with an outer wall that folds over itself (a
            # pipe elbow swept past its path, too thin for the split) ran for more than 10
            # minutes; that wall bounds no solid, so their result could not be written anyway
            raise folded
        if split is None and getattr(p, "rebuilt", None) and graph is not None:
            # the outside rebuilt from a folded surface (conformal.unfold): where the lattice
            # near the wall cannot be split off (the folded elbow: a 2 mm tube wall under a
            # 0.96 mm skin, a 0.1 mm cavity), the booleans on the whole lattice fell apart into
            # 3,043 pieces that float32 could not hold, after 201 s: refused here instead
            raise SkinError(
                f"{p.name}: the part's surface folds over itself, and on its surface rebuilt on a "
                f"{p.rebuilt:.3g} mm grid the skin of {thickness:g} mm leaves a cavity too thin "
                "for the lattice to be joined to the wall: fill it without a skin, or with a "
                "thinner skin, or repair the part (its overlapping bodies united) and fill again"
            )
        if split is None:
            lat = as_manifold(lattice, name="lattice mesh")
            # (outer - inner) + (lat ^ inner) as two differences: the lattice in one boolean only
            solid = (outer - inner) + (lat ^ surfaces[2]) if mid_wall else outer - (inner - lat)
            solid, bodies, islands, voids = _keep_attached(solid, surface)
        return solid, split, bodies, islands, voids

    solid, split, bodies, islands, voids = booleans(inner)
    if used == "occt" and min_cavity and _fragmented(voids, inner, outer):
        # the struts cut the cavity between OCCT's offsets into more sealed voids than it
        # has pieces: it is thinner than they are somewhere (a 3.4 mm fin under a 1.4 mm
        # skin, 1.2 mm struts: 67 voids; made outside shared/data). Closed as the voxel
        # method closes it (on the voxel field, computed for this only), and the booleans
        # run again on the offset with the closed region taken out
        h = _grid_spacing(p.size, thickness)
        field = _distance_field(p, thickness, h)
        (_, inner), closed = _closed_cavity((outer, inner), field, h, thickness, min_cavity)
        del field
        if closed is not None:
            if inner.is_empty():
                raise SkinError(
                    no_room_message(
                        thickness, 2.0 * p.inscribed_radius(), strut=min_cavity, closed=True, grid=h
                    )
                )
            solid, split, bodies, islands, voids = booleans(inner)
    if closed is not None:
        _warn_closed(p.name, thickness, float(min_cavity or 0.0), closed)
    t2 = time.perf_counter()
    stats = {
        "min": float(wall.min()),
        "p01": float(np.percentile(wall, 1)),
        "median": float(np.median(wall)),
        "p99": float(np.percentile(wall, 99)),
        "max": float(wall.max()),
    }
    pocket = voids < POCKET_SHARE * voids.max(initial=0.0)
    tol = wall_tolerance(thickness)
    off = np.abs(wall - thickness)
    accurate = bool(np.all(off <= tol))
    if not accurate:
        iv, fi = to_arrays(inner)
        k = int(np.argmax(off))
        x, y, z = iv[k] if k < len(iv) else iv[fi[k - len(iv)]].mean(axis=0)
        how = "OpenCascade's offset" if used == "occt" else f"the voxel field (h={h:.3g} mm)"
        warnings.warn(
            f"the skin's wall, by {how}, is {stats['min']:.4g} .. {stats['max']:.4g} mm "
            f"thick for {thickness:g} asked: {int(np.count_nonzero(off > tol)):,} of "
            f"{len(wall):,} points measured on its inner surface are more than "
            f"{tol:.3g} mm off (the tolerance), the most at ({x:.4g}, {y:.4g}, {z:.4g}), "
            f"{float(wall[k]):.4g} mm",
            LatticeWarning,
            stacklevel=2,
        )
    report = SkinReport(
        thickness=float(thickness),
        method=used,
        fallback=fallback,
        voxel=h,
        wall=stats,
        accurate=accurate,
        tolerance=tol,
        bodies=bodies,
        islands_removed=islands,
        voids=int(np.count_nonzero(~pocket)),
        pockets=int(np.count_nonzero(pocket)),
        pocket_volume=float(voids[pocket].max(initial=0.0)),
        split=dict(split.counts) if split is not None else {},
        untangled=untangled,
        rebuilt=float(getattr(p, "rebuilt", None) or 0.0),
        closed=closed[0] if closed is not None else 0.0,
        min_cavity=float(min_cavity or 0.0),
        seconds={
            "surfaces": t1 - t0,
            "booleans": t2 - t1 - t_wall,
            "measure": time.perf_counter() - t2 + t_wall,
        },
    )
    if check:
        solid = checked(solid, "the skinned lattice")
    return SkinResult(solid=solid, report=report, split=split)


def _warn_closed(
    name: str, thickness: float, min_cavity: float, closed: tuple[float, NDArray[np.float64]]
) -> None:
    """The warning for a cavity closed where it is thinner than the struts."""
    warnings.warn(
        f"{name}: the skin of {thickness:g} mm leaves a cavity thinner than the struts "
        f"({min_cavity:.3g} mm across) in places, e.g. at {point_text(closed[1])}: "
        f"{closed[0]:.3g} mm^3 of it was made solid (the part is less than "
        f"{2 * thickness + min_cavity:.3g} mm thick there, twice the skin and a strut); a "
        "thinner skin or thinner struts keep a lattice there",
        LatticeWarning,
        stacklevel=3,
    )


def _fragmented(voids: NDArray[np.float64], inner: Any, outer: Any) -> bool:
    """Whether a skin's result has more sealed voids (``voids``: their volumes, those
    under ``POCKET_SHARE`` of the largest not counted) than its cavity has pieces (the
    pieces of the inner surface, ``inner``) plus the part's own closed voids (``outer``'s
    inward pieces): the struts then cut the cavity apart somewhere."""
    from conformal.skin_split import pieces

    n_voids = int(np.count_nonzero(voids >= POCKET_SHARE * voids.max(initial=0.0)))
    if n_voids <= 1:
        return False
    _, _, vin = pieces(*to_arrays(inner))
    _, _, vout = pieces(*to_arrays(outer))
    return n_voids > int(np.count_nonzero(vin > 0)) + int(np.count_nonzero(vout < 0))


def folded_wall(surface: Any, *, name: str | None = None) -> SkinError | None:
    """The error for a skin whose outer wall, ``surface`` (a ``conformal.Part``: the part's
    tessellation the skin is built on), crosses itself in at least
    ``config.SKIN_FOLD_PAIRS`` pairs of its triangles, or None.

    Such a wall bounds no solid, and a skin keeps it as it is, so the skinned mesh would
    cross itself too: no skin of the part can be written until the part is repaired.
    """
    if surface.self_crossings[0] < config.SKIN_FOLD_PAIRS:
        return None
    return SkinError(
        f"{name or surface.name}: {surface.crossing_note()}; the skin's outer wall is that "
        "surface, so a skin of this part cannot be one solid until the part is repaired "
        "(its overlapping bodies united, or a face that folds over itself remade); fill it "
        "without a skin, or repair it and fill again"
    )


#: Sealed voids under this share of the largest one's volume are reported as pockets
#: (:attr:`SkinReport.pockets`).
POCKET_SHARE = 1e-6

#: The skin's outer surface and the lattice's cavity (inner surface minus lattice) are joined
#: without a boolean when the inner surface lies inside the outer one with at least this
#: fraction of the thickness between them (see :func:`_outer_minus`).
COMPOSE_CLEARANCE = 0.5


def _outer_minus(
    outer: Any, cavity: Any, inner: Any, surface: Any, wall: NDArray[np.float64], thickness: float
) -> Any:
    """``outer - cavity`` for a cavity inside the inner surface (``inner - lattice``).

    When every measured wall (``wall``, :func:`wall_thickness` of ``inner``) is at least
    ``COMPOSE_CLEARANCE * thickness`` and every vertex of ``inner`` lies inside ``surface``
    (the outer surface as a Part), the cavity lies inside the outer surface, clear of it:
    the difference has no intersection to compute, and is the outer surface's triangles
    with the cavity's reversed (a :class:`lattice_cad.core.mesh.Mesh`; manifold3d's
    boolean returns the same triangles, 1-1.3 s on the GE bracket's 1.1 M). Otherwise the
    boolean (a ``manifold3d.Manifold``). A cavity that somehow crossed the outer surface
    anyway would be refused by the full check every skinned mesh gets before it is written.
    """
    if (
        len(wall)
        and float(wall.min()) >= COMPOSE_CLEARANCE * thickness
        and bool(np.all(surface.contains(to_arrays(inner)[0])))
    ):
        vo, fo = to_arrays(outer)
        vc, fc = to_arrays(cavity)
        return Mesh(
            vertices=np.vstack([vo, vc]),
            faces=np.vstack([fo, fc[:, ::-1] + len(vo)]),
        )
    return outer - cavity


def _split(lattice: Any, graph: Any, inner: Any, thickness: float) -> Any:
    """``conformal.skin_split.split_lattice`` of a stitched lattice, or None."""
    from conformal.part import Part
    from conformal.skin_split import split_lattice

    arrays = mesh_arrays(lattice)
    if arrays is None:
        return None
    margin = max(_wall_atol(thickness), 0.01 * thickness)
    split = split_lattice(graph, *arrays, Part(*to_arrays(inner), name="inner"), margin=margin)
    if split is None or split.counts["near"] == 0:
        return None  # (all of it deep: an island in the cavity, for the whole booleans)
    return split


def add_skin(lattice: Any, part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """The solid of :func:`build_skin` (a ``manifold3d.Manifold``); warns about islands."""
    result = build_skin(lattice, part, thickness, voxel=voxel, check=True)
    if result.report.islands_removed:
        warnings.warn(result.report.summary(), LatticeWarning, stacklevel=2)
    return result.solid


# ---------------------------------------------------------- marching tetrahedra
# (the Freudenthal split and the per-voxel work: conformal._skin_kernels)


def marching_tets(
    field: NDArray[np.float64], origin: NDArray[np.float64], h: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Closed, outward-oriented surface ``field = 0`` of a grid sampled field.

    Parameters
    ----------
    field : (nx, ny, nz) float64
        Positive inside, negative outside; must be negative on the whole grid boundary.
    origin : (3,) float64
        Position of sample ``[0, 0, 0]``.
    h : float
        Grid spacing.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Each vertex lies on a grid edge or Freudenthal diagonal, shared by all the
        triangles that cross that edge, so the surface is watertight and 2-manifold.
    """
    # no sample on (or within 0.1 % of a voxel of) the surface: a crossing exactly at a grid
    # point would give zero-area triangles; moving it by at most h / 1000 does not
    from conformal._skin_kernels import marching_tets_keys, max_step_x, unique_inverse

    field = np.ascontiguousarray(field, dtype=np.float64)
    step = float(max_step_x(field)) if field.size else 0.0  # field change per voxel
    snap = 1e-3 * step if step > 0 else 1e-12
    f = np.where(np.abs(field) < snap, -snap, field)

    n_grid = f.size
    keys, cat = marching_tets_keys(f, origin, h)  # the triangles, in the order of the tets
    if len(keys) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    # 1 or 3 inside (one triangle), then the first and the second halves of the quads
    # (a stable sort by category: the same order as one pass per category)
    order = np.argsort(cat, kind="stable")
    keys = keys[order]
    # one vertex per crossed grid segment lo - hi, numbered in the order of the keys,
    # interpolated from the lower end
    uniq, inv = unique_inverse(keys.ravel())
    faces = inv.reshape(-1, 3).astype(np.int64, copy=False)
    lo, hi = uniq // n_grid, uniq % n_grid
    pa = origin + np.column_stack(np.unravel_index(lo, f.shape)) * h
    pb = origin + np.column_stack(np.unravel_index(hi, f.shape)) * h
    flat = f.ravel()
    ta, tb = flat[lo], flat[hi]
    vertices = pa + (ta / (ta - tb))[:, None] * (pb - pa)
    return vertices, faces


# ------------------------------------------------------------------- hollowing
