"""Keep-solid zones: the part stays solid near chosen faces (bolt holes, mounting faces).

A zone is the set of points of the part within a distance ``t`` of some of its B-rep faces,
or the part inside an axis-aligned box grown by ``t``. The printable solid is the lattice
united with the zones, so struts that enter a zone end in solid material and join it: a
strut piece that touches a zone is one body with it.

How a face zone is built (all booleans by manifold3d, whose results are manifold):

1. the selected faces are triangulated by OCCT (BRepMesh) with a chord error of 1 % of ``t``;
2. the exact distance to those triangles is sampled on a grid of spacing ``t / 2``
   (``config.KEEP_VOXELS_PER_THICKNESS``; at most ``config.MAX_VOXELS`` points) around
   them (one grid per group of nearby faces), and the level ``d = t`` is extracted by
   marching tetrahedra (:func:`conformal.skin.marching_tets`): a closed "tube" around the
   faces that reaches ``t`` into the part and ``t`` out of it;
3. the tube is intersected with the part's own mesh, so the zone's outer surface *is* the
   part's surface (the tube crosses it only at the rim of the zone, transversally).

The distance to a plane is linear, so on planar faces the inner surface is exact (a
``">Z"`` zone of depth 2 on a 20 mm cube is 20 x 20 x 2); on curved faces the marching
tetrahedra interpolate it with an error of about ``h^2 / (8 R)`` (``R`` the radius of the
inner surface; at most ``t / 32`` where ``R >= t``).

The distance field is used rather than an OCCT thick solid of the faces because a thick
solid would end flush with the neighbouring faces (the walls of a bolt hole's thick solid lie in
the plate's top and bottom planes), and booleans between coplanar triangulations of
different meshes leave slivers; the tube crosses the part's surface instead. OCCT does the
part it does well: the exact faces and their triangulation.
"""

from __future__ import annotations

import math
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.errors import KeepError, LatticeWarning
from lattice_cad.core.mesh import mesh_arrays

__all__ = [
    "KeepError",
    "KeepZone",
    "ZoneReport",
    "KeepReport",
    "KeepResult",
    "keep_zone_mesh",
    "build_keep",
    "face_triangles",
]

#: Fraction of a grid step by which the grid is shifted off round CAD coordinates.
_GRID_SHIFT = 0.5017


@dataclass(frozen=True)
class KeepZone:
    """One keep-solid zone, resolved: B-rep faces or a box, and a thickness.

    Attributes
    ----------
    label : str
        What the user asked for (``">Z:2"``, ``"2 faces:1.5"``, ``"box:0"``), for messages.
    thickness : float
        Depth (mm) of the zone below the faces; for a box, the margin it is grown by.
    faces : tuple of TopoDS_Face
        The selected faces (empty for a box).
    face_types : tuple of str
        Geometry type of each face (``"PLANE"``, ``"CYLINDER"``, ...).
    box : (2, 3) float64 or None
        Min and max corner of an axis-aligned box.
    on_part : bool
        The faces are known to be the part's own (picked by a selector on its B-rep, which
        may include faces between touching solids, inside the part); otherwise they are
        checked to lie on the part's surface.
    """

    label: str
    thickness: float
    faces: tuple[Any, ...] = ()
    face_types: tuple[str, ...] = ()
    box: NDArray[np.float64] | None = None
    on_part: bool = False

    def __post_init__(self) -> None:
        t = self.thickness
        if isinstance(t, bool) or not isinstance(t, (int, float, np.number)):
            raise KeepError(f"keep zone {self.label!r}: thickness must be a number, got {t!r}")
        if not math.isfinite(float(t)) or float(t) < 0:
            raise KeepError(f"keep zone {self.label!r}: thickness must be >= 0, got {t!r}")
        if self.box is None:
            if not self.faces:
                raise KeepError(f"keep zone {self.label!r}: no faces and no box")
            if not float(t) > 0:
                raise KeepError(
                    f"keep zone {self.label!r}: a face zone needs a thickness > 0, got {t!r}"
                )
        else:
            b = np.asarray(self.box, dtype=np.float64)
            if b.shape != (2, 3) or not np.isfinite(b).all() or not (b[1] > b[0]).all():
                raise KeepError(
                    f"keep zone {self.label!r}: a box is ((xmin, ymin, zmin), (xmax, ymax, "
                    f"zmax)) with min < max on every axis, got {self.box!r}"
                )
            object.__setattr__(self, "box", b)


@dataclass(frozen=True)
class ZoneReport:
    """What one zone became.

    Attributes
    ----------
    label : str
    faces : int
        Faces matched (0 for a box).
    face_types : dict
        Count of matched faces per geometry type.
    thickness : float
    volume : float
        Volume (mm^3) of the zone (inside the part).
    voxel : float
        Grid spacing of its distance field (NaN for a box).
    """

    label: str
    faces: int
    face_types: dict[str, int]
    thickness: float
    volume: float
    voxel: float = float("nan")


@dataclass(frozen=True)
class KeepReport:
    """The keep-solid zones of a lattice.

    Attributes
    ----------
    zones : tuple of ZoneReport
    volume : float
        Volume (mm^3) of the union of the zones.
    lattice_inside : float
        Volume of the lattice inside the zones (absorbed by them).
    added : float
        Volume the zones added to the lattice (``volume - lattice_inside``).
    bodies : int
        Separate solids of lattice united with the zones.
    detached : int
        Zone pieces that no strut reaches (they print as separate bodies).
    seconds : dict
    """

    zones: tuple[ZoneReport, ...]
    volume: float
    lattice_inside: float = 0.0
    added: float = 0.0
    bodies: int = 0
    detached: int = 0
    seconds: dict[str, float] = field(default_factory=dict)

    def summary(self) -> str:
        """One line for logs and the CLI."""
        parts = []
        for z in self.zones:
            what = (
                ", ".join(f"{n} {k}" for k, n in sorted(z.face_types.items())) if z.faces else "box"
            )
            parts.append(f"{z.label} ({what}: {z.volume:.4g} mm^3)")
        detached = f", {self.detached} zone piece(s) not reached by struts" if self.detached else ""
        return (
            f"keep-solid {len(self.zones)} zone(s): {'; '.join(parts)}; together "
            f"{self.volume:.4g} mm^3, adds {self.added:.4g} mm^3 to the lattice; "
            f"{self.bodies} body(ies){detached}"
        )


@dataclass(frozen=True)
class KeepResult:
    """The lattice united with the zones, the zones alone, and the report.

    Attributes
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        The union of lattice and zones (closed, 2-manifold).
    zone : tuple of ((Z, 3) float64, (G, 3) int64)
        The union of the zones alone.
    report : KeepReport
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    zone: tuple[NDArray[np.float64], NDArray[np.int64]]
    report: KeepReport


# ------------------------------------------------------------------------ helpers
def _manifold(v: NDArray[np.float64], f: NDArray[np.int64], name: str) -> Any:
    import manifold3d

    man = manifold3d.Manifold(
        manifold3d.Mesh64(
            # copies: nanobind refuses read-only arrays (a Part's are)
            vert_properties=np.array(v, dtype=np.float64, order="C"),
            tri_verts=np.array(f, dtype=np.uint64, order="C"),
        )
    )
    if man.status() != manifold3d.Error.NoError:
        raise KeepError(f"{name} is not a closed 2-manifold solid (manifold3d: {man.status()})")
    return man


def _arrays(man: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    arrays = mesh_arrays(man)
    assert arrays is not None
    return np.ascontiguousarray(arrays[0]), np.ascontiguousarray(arrays[1])


def face_triangles(
    faces: tuple[Any, ...], deflection: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The triangles of B-rep faces (OCCT's BRepMesh), as one (possibly open) mesh.

    Parameters
    ----------
    faces : tuple of TopoDS_Face
    deflection : float
        Chord error (mm).

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    """
    from lattice_cad.occ_impl import shapes as occ

    vs, fs, base = [], [], 0
    for k, face in enumerate(faces):
        # a copy: meshing the face itself would replace the triangulation of the user's shape
        v, f = occ.tessellate(occ.copied(face), deflection, 0.1)
        if len(f) == 0:
            raise KeepError(f"face {k} of the zone has no area to triangulate")
        vs.append(v)
        fs.append(f + base)
        base += len(v)
    return np.vstack(vs), np.vstack(fs)


def _check_on_part(part: Any, zone: KeepZone, v: NDArray[np.float64]) -> None:
    """Every face of the zone must lie on the part's surface (within the tessellation)."""
    tol = max(2.0 * float(part.deflection), 1e-3 * float(part.diagonal))
    d = part.distance(v, max_distance=100 * tol)
    worst = float(np.max(np.where(np.isfinite(d), d, np.inf)))
    if worst > tol:
        off = f"up to {worst:.4g} mm" if math.isfinite(worst) else f"more than {100 * tol:.3g} mm"
        raise KeepError(
            f"keep zone {zone.label!r}: its faces are not on the part's surface ({off} off, "
            f"tolerance {tol:.3g} mm); select faces of the part being filled"
        )


def _clusters(boxes: NDArray[np.float64]) -> list[list[int]]:
    """Groups of faces whose grids are better sampled together.

    Two groups merge when the box around both is no larger than their two boxes together
    (they overlap a lot, such as the two halves of a bolt hole); far apart faces keep a
    grid each, so a few small holes in a large plate need no grid over the whole plate.

    boxes : (K, 2, 3) float64, the grid box of each face.
    """
    groups = [[k] for k in range(len(boxes))]
    lo, hi = boxes[:, 0].copy(), boxes[:, 1].copy()
    merged = True
    while merged:  # passes until none merges (each pass: one vector test per group)
        merged = False
        i = 0
        while i < len(groups):
            both_lo, both_hi = np.minimum(lo[i], lo), np.maximum(hi[i], hi)
            own = np.prod(hi - lo, axis=1)
            fits = np.prod(both_hi - both_lo, axis=1) <= own[i] + own
            fits[i] = False
            if not fits.any():
                i += 1
                continue
            j = int(np.argmax(fits))
            groups[i] += groups[j]
            lo[i], hi[i] = both_lo[j], both_hi[j]
            del groups[j]
            lo, hi = np.delete(lo, j, axis=0), np.delete(hi, j, axis=0)
            if j < i:
                i -= 1
            merged = True
    return groups


def _field_tube(
    part: Any, label: str, v: NDArray[np.float64], f: NDArray[np.int64], t: float
) -> tuple[Any, float]:
    """Closed surface ``d = t`` around the triangles (v, f) (a Manifold), and its spacing."""
    from conformal.part import Part
    from conformal.skin import marching_tets

    h = t / config.KEEP_VOXELS_PER_THICKNESS

    def grid_box(h: float) -> NDArray[np.float64]:
        reach = t + 2.0 * h
        lo = np.maximum(v.min(axis=0) - reach, part.bounds[0] - 2.0 * h)
        hi = np.minimum(v.max(axis=0) + reach, part.bounds[1] + 2.0 * h)
        return np.stack([lo, hi])

    box = grid_box(h)
    if float(np.prod((box[1] - box[0]) / h + 3)) > config.MAX_VOXELS:
        h = (float(np.prod(box[1] - box[0] + 3 * h)) / config.MAX_VOXELS) ** (1.0 / 3.0)
        box = grid_box(h)
    origin = box[0] - _GRID_SHIFT * h
    dims = np.ceil((box[1] - origin) / h).astype(np.int64) + 2
    axes = [origin[i] + h * np.arange(dims[i]) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    reach = t + 2.0 * h
    d = Part(v, f, name=f"keep zone {label}").distance(pts, max_distance=reach)
    level = (t - np.where(np.isfinite(d), d, reach)).reshape(tuple(dims))
    # closed where the grid was cut at the part's bounding box (outside the part)
    for axis in range(3):
        idx: list[Any] = [slice(None)] * 3
        for end in (0, -1):
            idx[axis] = end
            level[tuple(idx)] = -h
    tv, tf = marching_tets(level, origin, h)
    if len(tf) == 0:
        raise KeepError(f"keep zone {label!r}: the faces give an empty zone")
    tube = _manifold(tv, tf, f"the tube of keep zone {label!r}")
    # marching tetrahedra leave slivers where the level passes near a grid point; cut by
    # struts they become needles that rounding to float32 folds: collapse them first
    return tube.simplify(config.KEEP_SIMPLIFY * h), h


def _tube(part: Any, zone: KeepZone) -> tuple[Any, float]:
    """The points within ``t`` of the zone's faces (a Manifold), and the coarsest spacing."""
    import manifold3d

    t = float(zone.thickness)
    meshes = [face_triangles((face,), config.KEEP_FACE_DEFLECTION * t) for face in zone.faces]
    if not zone.on_part:
        _check_on_part(part, zone, np.vstack([v for v, _ in meshes]))
    boxes = np.array([[v.min(axis=0) - t, v.max(axis=0) + t] for v, _ in meshes])
    tube, spacing = manifold3d.Manifold(), 0.0
    for group in _clusters(boxes):
        vs, fs, base = [], [], 0
        for k in group:
            v, f = meshes[k]
            vs.append(v)
            fs.append(f + base)
            base += len(v)
        piece, h = _field_tube(part, zone.label, np.vstack(vs), np.vstack(fs), t)
        tube = tube + piece
        spacing = max(spacing, h)
    return tube, spacing


def _zone_solid(part: Any, part_solid: Any, zone: KeepZone) -> tuple[Any, float]:
    """The zone inside the part (a Manifold) and the grid spacing used (NaN for a box)."""
    import manifold3d

    if zone.box is not None:
        b = zone.box + np.array([[-1.0], [1.0]]) * zone.thickness
        cube = manifold3d.Manifold.cube(tuple(float(x) for x in b[1] - b[0])).translate(
            tuple(float(x) for x in b[0])
        )
        return part_solid ^ cube, float("nan")
    tube, h = _tube(part, zone)
    return part_solid ^ tube, h


def _face_components(f: NDArray[np.int64], n_vertices: int) -> NDArray[np.int64]:
    """(F,) int64: the connected body of each triangle (triangles sharing vertices)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(f) == 0:
        return np.zeros(0, dtype=np.int64)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    _, label = connected_components(g, directed=False)
    return np.asarray(label[f[:, 0]], dtype=np.int64)


# ------------------------------------------------------------------- public API
def keep_zone_mesh(
    part: Any, zones: list[KeepZone] | tuple[KeepZone, ...]
) -> tuple[tuple[NDArray[np.float64], NDArray[np.int64]], tuple[ZoneReport, ...]]:
    """The union of the keep-solid zones, inside the part.

    Parameters
    ----------
    part : conformal.Part
        The filled part (its mesh bounds every zone).
    zones : sequence of KeepZone

    Returns
    -------
    mesh : ((V, 3) float64, (F, 3) int64)
        The zones' union, closed and 2-manifold (empty arrays if no zone has volume).
    reports : tuple of ZoneReport
        One per zone.

    Raises
    ------
    KeepError
        A face not on the part, a zone that is empty (a box that misses the part).
    """
    import manifold3d

    part_solid = _manifold(part.vertices, part.faces, "the part")
    union = manifold3d.Manifold()
    reports = []
    for zone in zones:
        solid, h = _zone_solid(part, part_solid, zone)
        vol = float(solid.volume())
        if solid.is_empty() or vol <= 0:
            raise KeepError(
                f"keep zone {zone.label!r} holds no part of the solid"
                + (" (the box misses the part)" if zone.box is not None else "")
            )
        union = union + solid
        reports.append(
            ZoneReport(
                label=zone.label,
                faces=len(zone.faces),
                face_types=dict(Counter(zone.face_types)),
                thickness=float(zone.thickness),
                volume=vol,
                voxel=h,
            )
        )
    return _arrays(union), tuple(reports)


def build_keep(lattice: Any, part: Any, zones: list[KeepZone] | tuple[KeepZone, ...]) -> KeepResult:
    """The lattice united with its keep-solid zones.

    Parameters
    ----------
    lattice : Mesh or mesh-like
        The stitched lattice (closed, 2-manifold).
    part : conformal.Part
    zones : sequence of KeepZone

    Returns
    -------
    KeepResult
        The union (struts that enter a zone end in it), the zones and a report.
    """
    t0 = time.perf_counter()
    (zv, zf), reports = keep_zone_mesh(part, zones)
    t1 = time.perf_counter()
    arrays = mesh_arrays(lattice)
    if arrays is None:
        raise TypeError(f"lattice must be a mesh, got {type(lattice).__name__}")
    lat = _manifold(*arrays, "the lattice mesh").as_original()
    zone = _manifold(zv, zf, "the keep zones")
    solid = lat + zone
    out = solid.to_mesh64()
    v = np.ascontiguousarray(np.asarray(out.vert_properties, dtype=np.float64)[:, :3])
    f = np.ascontiguousarray(np.asarray(out.tri_verts, dtype=np.int64))
    # which triangles come from the lattice (manifold3d keeps the runs of each input)
    from_lattice = np.zeros(len(f), dtype=bool)
    runs = np.asarray(out.run_index, dtype=np.int64) // 3
    for k, oid in enumerate(np.asarray(out.run_original_id)):
        if int(oid) == lat.original_id():
            from_lattice[runs[k] : runs[k + 1]] = True
    body = _face_components(f, len(v))
    bodies = int(body.max()) + 1 if len(body) else 0
    # a body without lattice triangles is a zone piece no strut reaches: reported, not
    # removed (it is part of what the user asked to keep)
    reached = np.zeros(bodies, dtype=bool)
    reached[body[from_lattice]] = True
    detached = int((~reached).sum())
    if detached:
        warnings.warn(
            f"{detached} piece(s) of the keep-solid zones are not reached by any strut and "
            "print as separate bodies (fill='clip' or 'conform', or a skin, joins them)",
            LatticeWarning,
            stacklevel=3,
        )
    t2 = time.perf_counter()
    v_lat, v_zone, v_all = float(lat.volume()), float(zone.volume()), float(solid.volume())
    report = KeepReport(
        zones=reports,
        volume=v_zone,
        lattice_inside=v_lat + v_zone - v_all,
        added=v_all - v_lat,
        bodies=bodies,
        detached=detached,
        seconds={"zones": t1 - t0, "union": t2 - t1},
    )
    return KeepResult(vertices=v, faces=f, zone=(zv, zf), report=report)
