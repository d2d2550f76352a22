"""Escape holes: let powder or resin out of the cavities of a skinned part, and prove it.

A skinned part (:mod:`conformal.skin`) is a closed wall around the lattice: the space
between the struts is an enclosed cavity, and unfused powder or uncured resin stays
trapped in it. :func:`drill` gives every enclosed cavity at least one hole of a given
diameter through its wall, and :func:`verify` checks on the final solid that every empty
region connects to the outside.

Cavities
    The empty space of the solid on a grid of step ``h`` (default ``d / 4``): a cube around
    a grid point is empty when its centre is outside the material (``Part.grid_contains``,
    exact winding numbers) and no triangle meets it. Empty cubes are joined by
    26-connectivity (``scipy.ndimage.label``); two empty cubes that share a corner hold
    the segment between their centres, so a region never leaks through a wall, however
    thin. The region that touches the grid's padded border is the outside; every other
    region is an enclosed cavity. A gap narrower than the grid can close, so small
    regions (up to ``POCKET_VOXELS`` cubes) are re-checked on a grid ``POCKET_REFINE``
    times finer around them and joined to what they reach. Errors are on the safe side:
    a region is called connected only when a chain of empty cubes reaches the outside;
    a cavity split by gaps narrower than the grid counts as several (each gets a hole).
Placement
    By default one hole per cavity at its lowest point for the build direction ``b``
    (default +Z, so the lowest ``z``), drilled along ``-b``. Candidate axes start at the
    cavity's lowest grid points (the centre of the lowest layer first). User points
    (``points=``) are drilled along the wall normal at the nearest point of the outer
    surface, into the cavity behind it.
Fit
    A candidate is checked with rays (``manifold3d.Manifold.ray_cast``) along the axis and
    along lines on the hole's circumscribed radius: each line must start in the cavity,
    cross the wall once into the outside, and meet nothing else up to the end of the
    drill, so the cylinder cuts the wall and nothing else of the part. A candidate whose
    lines also pass through struts just above the floor is used only when no clean one
    fits in the lowest layer. A cavity without a fitting hole gets the status
    ``"no fit"`` (and :class:`EscapeHoleError` from the front).
Drilling
    Every hole is a cylinder with a regular polygon section that circumscribes the circle
    of the asked diameter (so the hole holds a disc of diameter ``d``), from just inside
    the cavity to just outside the wall, subtracted with manifold3d (whose results are
    manifold). Lattice pieces cut loose by the holes are removed and counted.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core.checks import check_positive
from lattice_cad.core.errors import EscapeHoleError

__all__ = [
    "EscapeHoleError",
    "Hole",
    "Cavity",
    "Connectivity",
    "EscapeReport",
    "EscapeResult",
    "drill",
    "verify",
    "grid_step",
    "MAX_VOXELS",
]

#: Largest flood-fill grid (voxels); a finer grid needed than this is reported as not
#: resolved (``Connectivity.resolved``), never silently trusted.
MAX_VOXELS = 40_000_000

#: Grid steps per hole diameter of the flood fill (a hole holds a chain of empty cubes
#: when the step is below ``d / (2 sqrt 3)``).
STEPS_PER_DIAMETER = 4.0
#: ... and at least this many per wall thickness.
STEPS_PER_WALL = 2.0

#: Enclosed regions of at most this many cubes are re-checked on a grid this much finer.
POCKET_VOXELS = 512
POCKET_REFINE = 4

#: Lines checked around the axis of a candidate hole (outer ring; the inner ring has half).
_RING = 16
#: Candidates tried per cavity: in its lowest layer, then higher up.
_LOWEST_CANDIDATES = 24
_MORE_CANDIDATES = 48
#: Fraction of a grid step by which the grid is shifted off round coordinates.
_GRID_SHIFT = 0.5017

HoleSource = Literal["lowest", "point"]


@dataclass(frozen=True)
class Hole:
    """One drilled hole.

    Attributes
    ----------
    cavity : int
        Index of the cavity it opens (into :attr:`EscapeReport.cavities`).
    inner, outer : (3,) float64
        Where the axis meets the cavity's wall and the part's outer surface (mm).
    axis : (3,) float64
        Unit vector from the cavity to the outside.
    diameter : float
        Diameter of the circle inscribed in the hole's polygon section (mm).
    length : float
        Length of the drill cylinder (mm): the wall plus a margin at both ends.
    source : {"lowest", "point"}
        Placed at the cavity's lowest point, or at a user point.
    clean : bool
        The drill cuts the wall only (no strut crossed its checked lines above the floor).
    """

    cavity: int
    inner: NDArray[np.float64]
    outer: NDArray[np.float64]
    axis: NDArray[np.float64]
    diameter: float
    length: float
    source: HoleSource
    clean: bool = True


@dataclass(frozen=True)
class Cavity:
    """One enclosed cavity of the solid before drilling.

    Attributes
    ----------
    volume : float
        Empty volume (mm^3, grid estimate).
    lowest : (3,) float64
        Its lowest grid point along the build direction.
    bounds : (2, 3) float64
        Bounding box of its grid points.
    status : {"drilled", "no fit"}
        Whether a hole opens it (from its lowest point or a user point).
    """

    volume: float
    lowest: NDArray[np.float64]
    bounds: NDArray[np.float64]
    status: str = "drilled"


@dataclass(frozen=True)
class Connectivity:
    """Flood fill of the empty space of a solid.

    Attributes
    ----------
    voxel : float
        Grid step (mm).
    resolved : bool
        The step is the one asked for (``False``: the grid would have exceeded
        :data:`MAX_VOXELS` and was coarsened, so a hole may be too narrow for it and
        its cavity reported enclosed; ``connected`` is then False).
    enclosed : int
        Empty regions not connected to the outside.
    regions : list of dict
        ``volume`` (mm^3), ``lowest`` and ``centroid`` (mm) of each enclosed region,
        largest first.
    seconds : float
    """

    voxel: float
    resolved: bool
    enclosed: int
    regions: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def connected(self) -> bool:
        """Every empty region of the solid connects to the outside (on a resolved grid)."""
        return self.enclosed == 0 and self.resolved

    def summary(self) -> str:
        res = "" if self.resolved else " (grid coarsened: NOT resolved)"
        if self.enclosed == 0:
            return f"all empty space connects to the outside (flood fill, h={self.voxel:.3g}){res}"
        vols = ", ".join(f"{r['volume']:.3g}" for r in self.regions[:5])
        return (
            f"{self.enclosed} enclosed region(s) of {vols} mm^3 (flood fill, "
            f"h={self.voxel:.3g}){res}"
        )


@dataclass(frozen=True)
class EscapeReport:
    """What :func:`drill` found and did.

    Attributes
    ----------
    diameter : float
    build_direction : (3,) float64
        Unit vector; lowest points are the minima of ``x . build_direction``.
    cavities : tuple of Cavity
        The enclosed cavities before drilling.
    holes : tuple of Hole
    islands_removed : int
        Lattice pieces cut loose by the holes, removed.
    verification : Connectivity or None
        The flood fill of the drilled solid (None when not run).
    seconds : dict
    """

    diameter: float
    build_direction: NDArray[np.float64]
    cavities: tuple[Cavity, ...]
    holes: tuple[Hole, ...]
    islands_removed: int = 0
    verification: Connectivity | None = None
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def all_connected(self) -> bool | None:
        """The verification's verdict (None when not verified)."""
        return None if self.verification is None else self.verification.connected

    @property
    def failed(self) -> list[int]:
        """Indices of the cavities no hole opens."""
        return [i for i, c in enumerate(self.cavities) if c.status != "drilled"]

    def summary(self) -> str:
        """A few lines for logs and the CLI."""
        lines = [
            f"escape holes d={self.diameter:g} mm: {len(self.cavities)} cavity(ies), "
            f"{len(self.holes)} hole(s)"
            + (f", {self.islands_removed} loose piece(s) removed" if self.islands_removed else "")
        ]
        for h in self.holes:
            at = ", ".join(f"{x:.4g}" for x in h.outer)
            lines.append(
                f"  hole in cavity {h.cavity} at ({at}) [{h.source}], length {h.length:.3g} mm"
                + ("" if h.clean else ", also cuts struts at its mouth")
            )
        for i in self.failed:
            c = self.cavities[i]
            lo = ", ".join(f"{x:.4g}" for x in c.lowest)
            lines.append(f"  cavity {i} ({c.volume:.4g} mm^3, lowest at ({lo})): {c.status}")
        if self.verification is not None:
            verdict = "yes" if self.verification.connected else "NO"
            lines.append(f"  all cavities connected: {verdict}; {self.verification.summary()}")
        return "\n".join(lines)


@dataclass(frozen=True)
class EscapeResult:
    """The drilled solid (a ``manifold3d.Manifold``) and its :class:`EscapeReport`."""

    solid: Any
    report: EscapeReport


# ------------------------------------------------------------------ flood fill
@dataclass
class _Grid:
    origin: NDArray[np.float64]
    h: float
    labels: NDArray[np.int32]  # 0 = solid, else empty region label
    outside: int
    resolved: bool

    def index(self, points: NDArray[np.float64]) -> NDArray[np.int64]:
        idx = np.rint((points - self.origin) / self.h).astype(np.int64)
        return np.clip(idx, 0, np.array(self.labels.shape) - 1)

    def label_at(self, points: NDArray[np.float64]) -> NDArray[np.int32]:
        i = self.index(np.atleast_2d(points))
        return self.labels[i[:, 0], i[:, 1], i[:, 2]]


def grid_step(diameter: float, thickness: float | None = None) -> float:
    """The flood-fill grid step (mm): ``diameter / 4`` resolves a hole of ``diameter``;
    with a wall ``thickness``, at most ``thickness / 2`` (so that a skin's cavity, which
    a grid can only see if it holds whole empty cubes, is seen in small parts too)."""
    h = diameter / STEPS_PER_DIAMETER
    return h if thickness is None else min(h, thickness / STEPS_PER_WALL)


def _flood(v: NDArray[np.float64], f: NDArray[np.int64], h: float) -> _Grid:
    """Label the empty space: cubes of side ``h`` around the grid points that hold no
    material and meet no triangle, joined by 26-connectivity. Two such cubes sharing a
    corner hold the segment between their centres, so no region leaks through a wall,
    however thin; narrow gaps may close (a false cavity, never a false opening)."""

    from conformal.part import Part

    part = Part(v, f, name="the solid")
    lo, hi = part.bounds
    size = hi - lo
    resolved = True
    n = float(np.prod(size / h + 5))
    if n > MAX_VOXELS:
        h *= (n / MAX_VOXELS) ** (1.0 / 3.0)
        resolved = False
    origin = lo - 2 * h + _GRID_SHIFT * h
    dims = np.ceil((size + 4 * h) / h).astype(np.int64) + 1
    labels = _label_empty(part, origin, h, dims)
    grid = _Grid(origin, h, labels, int(labels[0, 0, 0]), resolved)
    _refine_pockets(part, grid)
    return grid


def _label_empty(
    part: Any, origin: NDArray[np.float64], h: float, dims: NDArray[np.int64]
) -> NDArray[np.int32]:
    """(nx, ny, nz) int32: 0 for cubes with material or a triangle, else the label of the
    empty region (26-connectivity)."""
    from scipy import ndimage

    from conformal import _kernels

    step = np.full(3, h)
    solid = part.grid_contains(origin, step, dims)
    solid |= _kernels.mark_cut_cells(
        part.triangles, origin - 0.5 * h, step, dims, 1e-6, np.zeros(3, np.int64)
    )
    labels, _ = ndimage.label(~solid, structure=np.ones((3, 3, 3), dtype=bool))
    return labels.astype(np.int32, copy=False)


def _pocket_joins(part: Any, grid: _Grid, k: int, sl: tuple[slice, ...]) -> int:
    """The label of a region that region ``k`` reaches on a finer grid (0 if none): the
    fine flood fill runs in a box around ``k`` grown until the pocket's fine region either
    reaches a cube of another region or stays inside the box."""
    lab = grid.labels
    r = POCKET_REFINE
    for grow in (2, 4, 8):
        lo = np.array([max(0, s.start - grow) for s in sl])
        hi = np.array([min(n, s.stop + grow) for s, n in zip(sl, lab.shape, strict=True)])
        f_origin = grid.origin + (lo - 0.5 + 0.5 / r) * grid.h
        f_dims = (hi - lo) * r
        fine = _label_empty(part, f_origin, grid.h / r, f_dims)
        # the coarse cube of every fine cube (the fine cubes tile each coarse cube)
        idx = np.indices(tuple(f_dims)).reshape(3, -1).T // r + lo
        coarse = lab[idx[:, 0], idx[:, 1], idx[:, 2]]
        fl = fine.ravel()
        mine = np.unique(fl[(coarse == k) & (fl > 0)])
        reached = np.isin(fl, mine) & (fl > 0)
        other = {int(x) for x in np.unique(coarse[reached])} - {0, k}
        if other:
            return grid.outside if grid.outside in other else min(other)
        border = np.zeros(fine.shape, dtype=bool)
        border[[0, -1], :, :] = border[:, [0, -1], :] = border[:, :, [0, -1]] = True
        if not np.any(reached.reshape(fine.shape) & border):
            return 0  # enclosed at the fine resolution too
    return 0


def _refine_pockets(part: Any, grid: _Grid) -> None:
    """Join small enclosed regions to the region they reach through gaps narrower than
    the grid: a flood fill at ``h / POCKET_REFINE`` in a box around each. In place."""
    from scipy import ndimage

    lab = grid.labels
    settled: set[int] = {0, grid.outside}  # pockets that reach nothing else
    for _ in range(3):  # a pocket may reach another pocket that reaches further
        counts = np.bincount(lab.ravel())
        small = [
            int(k)
            for k in np.flatnonzero((counts > 0) & (counts <= POCKET_VOXELS))
            if k not in settled
        ]
        if not small:
            return
        objs = ndimage.find_objects(lab)
        changed = False
        for k in small:
            target = _pocket_joins(part, grid, k, objs[k - 1])
            if target:
                lab[lab == k] = target
                changed = True
            else:
                settled.add(k)
        if not changed:
            return


def _regions(grid: _Grid, b: NDArray[np.float64]) -> list[tuple[int, dict[str, Any]]]:
    """Enclosed regions (label, facts), largest first."""
    from scipy import ndimage

    lab = grid.labels
    counts = np.bincount(lab.ravel())
    ids = [k for k in np.flatnonzero(counts) if k not in (0, grid.outside)]
    if not ids:
        return []
    objs = ndimage.find_objects(lab)
    out = []
    for k in ids:
        sl = objs[k - 1]
        idx = np.argwhere(lab[sl] == k) + np.array([s.start for s in sl])
        pts = grid.origin + idx * grid.h
        height = pts @ b
        out.append(
            (
                int(k),
                {
                    "volume": float(len(idx) * grid.h**3),
                    "lowest": pts[int(np.argmin(height))],
                    "centroid": pts.mean(axis=0),
                    "bounds": np.stack([pts.min(axis=0), pts.max(axis=0)]),
                    "points": pts,
                    "heights": height,
                },
            )
        )
    out.sort(key=lambda kv: -kv[1]["volume"])
    return out


def verify(
    solid: Any,
    *,
    voxel: float,
    build_direction: ArrayLike = (0.0, 0.0, 1.0),
) -> Connectivity:
    """Flood fill of a solid's empty space: is every empty region connected to the outside?

    Parameters
    ----------
    solid : Mesh, manifold3d.Manifold, (vertices, faces) or trimesh
        A closed, outward-oriented solid.
    voxel : float
        Grid step (mm); :func:`grid_step` gives the one that resolves a hole diameter and
        a wall thickness.
    build_direction : (3,) float
        Only used to report the lowest point of each enclosed region.

    Returns
    -------
    Connectivity
    """
    from lattice_cad.core.mesh import mesh_arrays

    t0 = time.perf_counter()
    h = check_positive("voxel", voxel)
    b = _unit(build_direction, "build_direction")
    arrays = mesh_arrays(solid)
    if arrays is None:
        raise TypeError(f"cannot verify a {type(solid).__name__}: expected a mesh")
    grid = _flood(arrays[0], arrays[1], h)
    regions = [
        {key: facts[key] for key in ("volume", "lowest", "centroid")}
        for _, facts in _regions(grid, b)
    ]
    return Connectivity(
        voxel=grid.h,
        resolved=grid.resolved,
        enclosed=len(regions),
        regions=regions,
        seconds=time.perf_counter() - t0,
    )


# ---------------------------------------------------------------- hole checks
def _unit(vec: ArrayLike, name: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(vec, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers, got {vec!r}") from None
    n = float(np.linalg.norm(a))
    if not (np.all(np.isfinite(a)) and n > 0):
        raise ValueError(f"{name} must be a non-zero finite vector, got {vec!r}")
    return a / n


def _frame(u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit vectors completing ``u`` to a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, u)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


@dataclass
class _Line:
    t_in: float  # where the line enters the wall (from its start)
    t_out: float  # where it leaves into the outside
    t_next: float  # next material after t_out (inf if none)
    pairs_before: int  # material pieces (struts) crossed before the wall


class _Rays:
    """Line queries on a solid: hits by manifold3d's BVH, regions by the flood-fill grid."""

    def __init__(self, solid: Any, grid: _Grid, diagonal: float) -> None:
        self.solid = solid
        self.grid = grid
        self.length = 2.0 * diagonal + 10.0 * grid.h

    def hits(self, a: NDArray[np.float64], u: NDArray[np.float64]) -> list[tuple[float, float]]:
        """(distance, sign) of the surface crossings of the ray ``a + t u``; sign < 0 where
        the ray enters material. Crossings of one point (an edge or vertex) count once."""
        end = a + self.length * u
        out: list[tuple[float, float]] = []
        for hit in self.solid.ray_cast(tuple(a), tuple(end)):
            t = float(hit.distance) * self.length
            s = float(np.dot(hit.normal, u))
            if (
                out
                and abs(t - out[-1][0]) <= 1e-9 * self.length
                and np.sign(s) == np.sign(out[-1][1])
            ):
                continue
            out.append((t, s))
        return out

    def region(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> int:
        """The grid label of the empty segment ``a -> b`` (0 if no empty cube lies on it)."""
        n = max(3, min(64, int(np.linalg.norm(b - a) / (0.25 * self.grid.h)) + 2))
        pts = a + np.linspace(0.0, 1.0, n)[1:-1, None] * (b - a)
        labels = self.grid.label_at(pts)
        labels = labels[labels > 0]
        return int(labels[0]) if len(labels) else 0

    def same_cavity(self, a: NDArray[np.float64], b: NDArray[np.float64], cavity: int) -> bool:
        """Is ``b`` in the cavity of the empty point ``a``? The segment may pass through
        struts (material entered and left), but no empty stretch of it may belong to the
        outside or another cavity."""
        hits = self.solid.ray_cast(tuple(a), tuple(b))
        if len(hits) % 2:
            return False
        ts = [0.0] + [float(h.distance) for h in hits] + [1.0]
        for t0, t1 in zip(ts[::2], ts[1::2], strict=True):
            if self.region(a + t0 * (b - a), a + t1 * (b - a)) not in (0, cavity):
                return False
        return True

    def line(self, a: NDArray[np.float64], u: NDArray[np.float64], cavity: int) -> _Line | None:
        """The wall crossing of the line from ``a`` (in the cavity labelled ``cavity``) along
        ``u``: the first exit from material into the outside, past struts in the cavity.
        None if ``a`` is in material, or the line meets another cavity first, or never
        reaches the outside."""
        hits = self.hits(a, u)
        pairs = 0
        k = 0
        while k + 1 < len(hits):
            (t0, s0), (t1, s1) = hits[k], hits[k + 1]
            if s0 >= 0 or s1 <= 0:  # not enter-then-leave: starts in material, or bad mesh
                return None
            t_next = hits[k + 2][0] if k + 2 < len(hits) else math.inf
            if not math.isfinite(t_next):
                return _Line(t0, t1, t_next, pairs)
            region = self.region(a + t1 * u, a + t_next * u)
            if region == self.grid.outside:
                return _Line(t0, t1, t_next, pairs)
            if region != cavity:  # another cavity, or a gap too thin to tell
                return None
            pairs += 1
            k += 2
        return None


@dataclass
class _Plan:
    start: NDArray[np.float64]  # inner end of the drill (on the axis)
    axis: NDArray[np.float64]
    length: float
    inner: NDArray[np.float64]
    outer: NDArray[np.float64]
    clean: bool


def _plan(
    rays: _Rays,
    c: NDArray[np.float64],
    u: NDArray[np.float64],
    radius: float,
    margin: float,
    reach: float,
    cavity: int,
) -> _Plan | None:
    """A drill along ``u`` from the point ``c`` of the cavity labelled ``cavity`` through
    its wall, or None if it does not fit (see the module docstring)."""
    centre = rays.line(c, u, cavity)
    if centre is None:
        return None
    e1, e2 = _frame(u)
    ang = np.linspace(0.0, 2 * np.pi, _RING, endpoint=False)
    ring = np.concatenate(
        [
            radius * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2),
            0.5 * radius * (np.cos(ang[::2])[:, None] * e1 + np.sin(ang[::2])[:, None] * e2),
        ]
    )
    e = margin
    while e <= reach:
        s = centre.t_in - e  # inner end of the drill, measured from c
        start = c + s * u
        lines = [rays.line(start, u, cavity)]
        ok = lines[0] is not None
        for off in ring if ok else ():
            p = start + off
            if not rays.same_cavity(start, p, cavity):
                ok = False
                break
            ln = rays.line(p, u, cavity)
            if ln is None:
                ok = False
                break
            lines.append(ln)
        if ok:
            break
        e *= 2.0
    else:
        return None
    good = [ln for ln in lines if ln is not None]
    end = max(ln.t_out for ln in good) + margin
    if any(ln.t_next <= end + 0.5 * margin for ln in good):  # the drill would cut more
        return None
    if end - min(ln.t_in for ln in good) > reach + 2 * margin:  # no wall that thin here
        return None
    return _Plan(
        start=start,
        axis=u,
        length=end,
        inner=start + good[0].t_in * u,
        outer=start + good[0].t_out * u,
        clean=all(ln.pairs_before == 0 for ln in good),
    )


def _candidates(
    facts: dict[str, Any], grid: _Grid, label: int, band: float
) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    """Grid points of a cavity to start a lowest-point hole from: its lowest layer (the
    point nearest the layer's centre first), and higher points, lowest first."""
    pts, height = facts["points"], facts["heights"]
    low = height <= height.min() + band
    layer = pts[low]
    centre = layer.mean(axis=0)
    if grid.label_at(centre)[0] != label:  # the layer's centre is not in the cavity
        centre = layer[np.argmin(np.linalg.norm(layer - centre, axis=1))]
    order = np.argsort(np.linalg.norm(layer - centre, axis=1), kind="stable")
    first = _spread(np.vstack([centre, layer[order]]), 0.75 * grid.h, _LOWEST_CANDIDATES)
    rest = pts[~low][np.argsort(height[~low], kind="stable")]
    return first, _spread(rest, 2.0 * grid.h, _MORE_CANDIDATES)


def _spread(pts: NDArray[np.float64], gap: float, cap: int) -> list[NDArray[np.float64]]:
    """Up to ``cap`` of the points, in order, each at least ``gap`` from those taken."""
    taken: list[NDArray[np.float64]] = []
    for p in pts:
        if all(np.linalg.norm(p - q) >= gap for q in taken):
            taken.append(p)
            if len(taken) >= cap:
                break
    return taken


def _cylinder(plan: _Plan, radius: float, segments: int) -> Any:
    import manifold3d

    rc = radius / math.cos(math.pi / segments)  # circumscribes the circle of the diameter
    cyl = manifold3d.Manifold.cylinder(plan.length, rc, rc, segments)
    e1, e2 = _frame(plan.axis)
    m = np.column_stack([e1, e2, plan.axis, plan.start])  # (3, 4): z -> axis
    return cyl.transform(m)


# ------------------------------------------------------------------- drilling
def drill(
    solid: Any,
    diameter: float,
    *,
    thickness: float,
    points: ArrayLike | None = None,
    build_direction: ArrayLike = (0.0, 0.0, 1.0),
    lowest: bool = True,
    segments: int = 32,
    voxel: float | None = None,
    check: bool = True,
) -> EscapeResult:
    """Drill escape holes so that every enclosed cavity of ``solid`` opens to the outside.

    Parameters
    ----------
    solid : manifold3d.Manifold, Mesh, (vertices, faces) or trimesh
        A closed solid, typically a skinned part (:func:`conformal.skin.build_skin`).
    diameter : float
        Hole diameter (mm): every hole holds a disc of this diameter.
    thickness : float
        Wall thickness of the skin (mm): sets the flood-fill grid and the drill's margins.
    points : (P, 3) float, optional
        User hole positions (mm), near the outer surface: each is drilled along the wall
        normal at the nearest surface point, into the cavity behind it.
    build_direction : (3,) float
        Up direction of the print; lowest points minimise ``x . build_direction``.
    lowest : bool
        Drill every cavity that no user point opens at its lowest point (default). With
        ``False``, only the user points are drilled (cavities left closed are reported
        with status ``"no hole"``).
    segments : int
        Sides of the hole's polygon section (>= 3).
    voxel : float, optional
        Flood-fill grid step (default ``grid_step(diameter, thickness)``). An empty region
        too small to hold a whole cube of this size is not seen.
    check : bool
        Verify the drilled solid by a flood fill (``report.verification``).

    Returns
    -------
    EscapeResult
        ``solid`` (a ``manifold3d.Manifold``) and the :class:`EscapeReport`.

    Raises
    ------
    EscapeHoleError
        A user point has no cavity behind it (the message names the point).
    ValueError, TypeError
        An option out of range.
    """
    import manifold3d

    from conformal.skin import as_manifold
    from lattice_cad.core.mesh import mesh_arrays

    t0 = time.perf_counter()
    d = check_positive("diameter", diameter)
    wall = check_positive("thickness", thickness)
    b = _unit(build_direction, "build_direction")
    if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)) or segments < 3:
        raise ValueError(f"segments must be an integer >= 3, got {segments!r}")
    user = np.zeros((0, 3)) if points is None else np.asarray(points, dtype=np.float64)
    if user.size and (user.ndim not in (1, 2) or user.shape[-1] != 3):
        raise ValueError(f"points must be (P, 3) coordinates, got shape {user.shape}")
    user = user.reshape(-1, 3)
    if not np.all(np.isfinite(user)):
        raise ValueError("points must be finite coordinates")
    h = check_positive("voxel", voxel) if voxel is not None else grid_step(d, wall)

    man = solid if isinstance(solid, manifold3d.Manifold) else as_manifold(solid, name="solid")
    arrays = mesh_arrays(man)
    assert arrays is not None
    v, f = arrays
    grid = _flood(v, f, h)
    regions = _regions(grid, b)
    t1 = time.perf_counter()

    diagonal = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    rays = _Rays(man, grid, diagonal)
    r = 0.5 * d
    rc = r / math.cos(math.pi / segments)
    margin = max(0.1 * wall, 0.5 * grid.h)
    reach = 2.0 * d + 4.0 * wall  # deepest mouth and thickest wall a hole may pass
    label_index = {k: i for i, (k, _) in enumerate(regions)}
    plans: list[tuple[int, _Plan, HoleSource]] = []
    opened: set[int] = set()

    # user points: along the wall normal at the nearest outer surface point
    if len(user):
        from conformal import _kernels
        from conformal.part import Part

        surf = Part(v, f, name="the solid")
        origin, hb, dims, start, items = surf._bins3d
        _, near, face = _kernels.closest_points(
            surf.triangles,
            surf.boxes,
            start,
            items,
            origin,
            hb,
            dims,
            np.ascontiguousarray(user),
            np.inf,
        )
        tri = surf.triangles[face]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        for x, q, n in zip(user, near, normals, strict=True):
            plan, cav = _user_plan(rays, grid, label_index, q, n, rc, margin, reach)
            if plan is None:
                where = ", ".join(f"{c:g}" for c in x)
                raise EscapeHoleError(
                    f"no escape hole fits at ({where}): no enclosed cavity lies behind the "
                    f"wall there, or a hole of diameter {d:g} mm does not fit (nearest surface "
                    f"point {tuple(round(float(c), 4) for c in q)})"
                )
            plans.append((cav, plan, "point"))
            opened.add(cav)

    statuses = []
    for i, (label, facts) in enumerate(regions):
        if i in opened:
            statuses.append("drilled")
            continue
        if not lowest:
            statuses.append("no hole")
            continue
        plan = _lowest_plan(rays, label, facts, -b, rc, margin, reach, d)
        if plan is None:
            statuses.append("no fit")
            continue
        plans.append((i, plan, "lowest"))
        statuses.append("drilled")
    t2 = time.perf_counter()

    islands = 0
    out = man
    if plans:
        drills = [_cylinder(p, r, segments) for _, p, _ in plans]
        cut = (
            drills[0]
            if len(drills) == 1
            else manifold3d.Manifold.batch_boolean(drills, manifold3d.OpType.Add)
        )
        out = man - cut
        out, islands = _drop_loose(out, sum(1 for p in man.decompose() if p.volume() > 0))
    t3 = time.perf_counter()

    cavities = tuple(
        Cavity(
            volume=facts["volume"],
            lowest=facts["lowest"],
            bounds=facts["bounds"],
            status=status,
        )
        for (_, facts), status in zip(regions, statuses, strict=True)
    )
    holes = tuple(
        Hole(
            cavity=i,
            inner=p.inner,
            outer=p.outer,
            axis=p.axis,
            diameter=d,
            length=p.length,
            source=src,
            clean=p.clean,
        )
        for i, p, src in plans
    )
    verification = verify(out, voxel=h, build_direction=b) if check else None
    seconds = {"cavities": t1 - t0, "placement": t2 - t1, "drilling": t3 - t2}
    if verification is not None:
        seconds["verify"] = verification.seconds
    report = EscapeReport(
        diameter=d,
        build_direction=b,
        cavities=cavities,
        holes=holes,
        islands_removed=islands,
        verification=verification,
        seconds=seconds,
    )
    return EscapeResult(solid=out, report=report)


def _drop_loose(solid: Any, bodies: int) -> tuple[Any, int]:
    """Keep the ``bodies`` largest solid pieces (and every cavity wall); the number dropped.

    The holes cut the wall only, so a new solid piece is a strut end cut loose."""
    from conformal.skin import _manifold, to_arrays

    pieces = solid.decompose()
    solids = sorted((p for p in pieces if p.volume() > 0), key=lambda p: -p.volume())
    if len(solids) <= bodies:
        return solid, 0
    keep = solids[:bodies] + [p for p in pieces if p.volume() <= 0]
    vs, fs, base = [], [], 0
    for piece in keep:  # Manifold.compose drops cavity walls: join the meshes instead
        v, f = to_arrays(piece)
        vs.append(v)
        fs.append(f + base)
        base += len(v)
    return _manifold(np.vstack(vs), np.vstack(fs), "the drilled solid"), len(solids) - bodies


def _lowest_plan(
    rays: _Rays,
    label: int,
    facts: dict[str, Any],
    u: NDArray[np.float64],
    rc: float,
    margin: float,
    reach: float,
    d: float,
) -> _Plan | None:
    """The first clean fitting drill of the lowest layer, else the first fitting one there,
    else the lowest fitting one higher up."""
    band = max(rays.grid.h, 0.25 * d)
    first, rest = _candidates(facts, rays.grid, label, band)
    fallback = None
    for c in first:
        plan = _plan(rays, c, u, rc, margin, reach, label)
        if plan is None:
            continue
        if plan.clean:
            return plan
        if fallback is None:
            fallback = plan
    if fallback is not None:
        return fallback
    for c in rest:
        plan = _plan(rays, c, u, rc, margin, reach, label)
        if plan is not None:
            return plan
    return None


def _user_plan(
    rays: _Rays,
    grid: _Grid,
    label_index: dict[int, int],
    q: NDArray[np.float64],
    n: NDArray[np.float64],
    rc: float,
    margin: float,
    reach: float,
) -> tuple[_Plan | None, int]:
    """A drill along the wall normal ``n`` at the surface point ``q``: into the material,
    out into the first cavity behind it."""
    a = q + margin * n
    hits = rays.hits(a, -n)
    if len(hits) < 2 or hits[0][1] >= 0 or hits[1][1] <= 0:
        return None, -1
    t_cav = hits[1][0]
    t_end = hits[2][0] if len(hits) > 2 else t_cav + 4 * grid.h
    seg = a - n * np.linspace(t_cav, t_end, 12)[1:-1, None]
    labels = [int(x) for x in grid.label_at(seg) if x in label_index]
    if not labels:
        return None, -1
    label = max(set(labels), key=labels.count)
    c = a - n * (0.5 * (t_cav + min(t_end, t_cav + 2 * reach)))
    return _plan(rays, c, n, rc, margin, reach, label), label_index[label]
