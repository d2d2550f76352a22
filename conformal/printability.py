"""Printability of a lattice graph: overhanging struts, thin struts, unsupported nodes.

Additive manufacturing builds a part layer by layer along a *build direction* ``b``
(default +Z). A strut's *angle to the build plate* is the angle between the strut and
the plane perpendicular to ``b``::

    angle = atan2(|v . b|, |v - (v . b) b|)      (degrees, 0 = horizontal, 90 = vertical)

for the strut vector ``v``; a strut's direction along it does not matter. Struts below a
*critical angle* (default 35 degrees, ``config.OVERHANG_ANGLE_DEG``) sag or fail without
support material: they are *overhangs*. A strut is *thin* when its smallest diameter
(twice the smaller end radius) is below the printer's minimum (default 0.4 mm,
``config.MIN_STRUT_DIAMETER``). A node is *unsupported* when no strut reaches it from
below at the critical angle or steeper, and it is not at the lattice's lowest level (the
build plate): printing it starts in mid-air. The lattice is judged alone: a skin or the
part around it may support such nodes in the real print.

- :func:`printability`: the :class:`PrintabilityReport` of a graph.
- :func:`remove_overhangs`: the graph without its overhanging struts, and then without
  the loose pieces this leaves (:func:`conformal.voxel.main_components`: the largest
  piece per separate solid of the part is kept).
- :func:`cell_angles`, :func:`self_supporting_cells`: the smallest strut angle of every
  built-in cell for a build direction, and which cells need no support.
- :func:`best_orientation`: the lattice rotation that makes a cell's smallest strut
  angle as large as possible (e.g. cubic with a body diagonal along the build
  direction: every strut at 35.26 degrees).

Everything is vectorised numpy; connected pieces use scipy (through
:func:`conformal.voxel.main_components`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from conformal.cells import CELLS, UnitCell, _resolve
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeWarning, PrintabilityError
from lattice_cad.core.graph import LatticeGraph

if TYPE_CHECKING:
    from conformal.part import Part

__all__ = [
    "PrintabilityReport",
    "OverhangRemoval",
    "Orientation",
    "as_build_direction",
    "as_critical_angle",
    "as_min_diameter",
    "strut_angles",
    "printability",
    "remove_overhangs",
    "cell_angles",
    "self_supporting_cells",
    "best_orientation",
]

_AXES = {(1, 0, 0): "+X", (-1, 0, 0): "-X", (0, 1, 0): "+Y", (0, -1, 0): "-Y",
         (0, 0, 1): "+Z", (0, 0, -1): "-Z"}  # fmt: skip


# ------------------------------------------------------------------ options
def as_build_direction(value: ArrayLike) -> NDArray[np.float64]:
    """The unit build direction from any non-zero 3-vector.

    Parameters
    ----------
    value : (3,) float
        Any non-zero finite vector; it is normalised.

    Returns
    -------
    (3,) float64
        Unit vector.

    Raises
    ------
    PrintabilityError
        Not 3 finite numbers, or the zero vector.
    """
    try:
        b = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise PrintabilityError(f"build_direction must be 3 numbers, got {value!r}") from None
    if b.shape != (3,) or not np.isfinite(b).all():
        raise PrintabilityError(f"build_direction must be 3 finite numbers, got {value!r}")
    n = float(np.linalg.norm(b))
    if not n > 0.0:
        raise PrintabilityError(
            "build_direction must not be the zero vector (it is the direction the layers "
            "grow in, e.g. (0, 0, 1))"
        )
    return b / n


def as_critical_angle(value: Any) -> float:
    """``value`` as degrees in 0..90, or :class:`PrintabilityError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise PrintabilityError(f"critical_angle must be a number of degrees, got {value!r}")
    a = float(value)
    if not (math.isfinite(a) and 0.0 <= a <= 90.0):
        raise PrintabilityError(f"critical_angle must be in 0..90 degrees, got {value!r}")
    return a


def as_min_diameter(value: Any) -> float:
    """``value`` as a diameter >= 0 (mm), or :class:`PrintabilityError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise PrintabilityError(f"min_diameter must be a number (mm), got {value!r}")
    d = float(value)
    if not (math.isfinite(d) and d >= 0.0):
        raise PrintabilityError(f"min_diameter must be a finite number >= 0 (mm), got {value!r}")
    return d


def _direction_label(b: NDArray[np.float64]) -> str:
    key = tuple(int(round(float(x))) for x in b)
    if key in _AXES and np.allclose(b, key, rtol=0.0, atol=1e-15):
        return _AXES[key]
    return "(" + ", ".join(f"{float(x):.4g}" for x in b) + ")"


def _angles(vectors: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(M,) float64 degrees in [0, 90] of the (M, 3) vectors to the plane normal to ``b``."""
    along = vectors @ b
    across = np.linalg.norm(vectors - along[:, None] * b[None, :], axis=1)
    return np.degrees(np.arctan2(np.abs(along), across))


def strut_angles(
    graph: LatticeGraph, build_direction: ArrayLike = config.BUILD_DIRECTION
) -> NDArray[np.float64]:
    """The angle of every strut to the build plate.

    Parameters
    ----------
    graph : LatticeGraph
    build_direction : (3,) float
        Non-zero; normalised.

    Returns
    -------
    (M,) float64
        Degrees, 0 (horizontal) to 90 (along the build direction).
    """
    b = as_build_direction(build_direction)
    return _angles(graph.edge_vectors, b)


# ------------------------------------------------------------------- report
@dataclass(frozen=True, eq=False)
class PrintabilityReport:
    """Overhangs, thin struts and unsupported nodes of a lattice for one build direction.

    Attributes
    ----------
    build_direction : (3,) float64
        Unit vector.
    critical_angle : float
        Degrees; struts below it are overhangs.
    min_diameter : float
        mm; struts thinner than it are thin.
    num_struts, num_nodes : int
        Of the graph (nodes with at least one strut).
    angles : (M,) float64
        Every strut's angle to the build plate (degrees).
    overhanging : (K,) int64
        Indices of the overhanging struts, ascending.
    thin : (T,) int64
        Indices of the thin struts, ascending.
    unsupported : (U,) int64
        Indices of the unsupported nodes, ascending.
    diameters : (M,) float64
        Smallest diameter of every strut (mm).
    examples : (E, 5) float64
        A few overhangs, lowest angle first: strut index, angle, midpoint x, y, z.
    """

    build_direction: NDArray[np.float64]
    critical_angle: float
    min_diameter: float
    num_struts: int
    num_nodes: int
    angles: NDArray[np.float64] = field(repr=False)
    overhanging: NDArray[np.int64] = field(repr=False)
    thin: NDArray[np.int64] = field(repr=False)
    unsupported: NDArray[np.int64] = field(repr=False)
    diameters: NDArray[np.float64] = field(repr=False)
    examples: NDArray[np.float64] = field(repr=False)

    # ------------------------------------------------------------ numbers
    @property
    def overhang_count(self) -> int:
        """Number of overhanging struts."""
        return int(len(self.overhanging))

    @property
    def overhang_fraction(self) -> float:
        """Overhanging struts over all struts (0 for an empty graph)."""
        return self.overhang_count / self.num_struts if self.num_struts else 0.0

    @property
    def thin_count(self) -> int:
        """Number of struts thinner than ``min_diameter``."""
        return int(len(self.thin))

    @property
    def thin_fraction(self) -> float:
        """Thin struts over all struts."""
        return self.thin_count / self.num_struts if self.num_struts else 0.0

    @property
    def min_angle(self) -> float:
        """Smallest strut angle (degrees; NaN without struts)."""
        return float(self.angles.min()) if len(self.angles) else float("nan")

    @property
    def thinnest(self) -> float:
        """Smallest strut diameter (mm; NaN without struts)."""
        return float(self.diameters.min()) if len(self.diameters) else float("nan")

    @property
    def self_supporting(self) -> bool:
        """No overhanging strut and no unsupported node."""
        return self.overhang_count == 0 and len(self.unsupported) == 0

    @property
    def direction_label(self) -> str:
        """``"+Z"`` for an axis, else the vector."""
        return _direction_label(self.build_direction)

    # ------------------------------------------------------------ output
    def lines(self) -> list[str]:
        """The summary, one finding per line (what ``str()`` joins)."""
        a = self.critical_angle
        out = [
            f"printability (build direction {self.direction_label}, critical angle {a:g} deg, "
            f"min diameter {self.min_diameter:g} mm):"
        ]
        over = (
            f"  overhangs: {self.overhang_count:,} of {self.num_struts:,} struts "
            f"({self.overhang_fraction:.1%}) below {a:g} deg"
        )
        if self.num_struts:
            over += f" (smallest angle {self.min_angle:.3g} deg)"
        if len(self.examples):
            ex = "; ".join(
                f"strut {int(e[0])} at {e[1]:.3g} deg, mid ({e[2]:.4g}, {e[3]:.4g}, {e[4]:.4g})"
                for e in self.examples[:3]
            )
            over += f", e.g. {ex}"
        out.append(over)
        thin = f"  thin: {self.thin_count:,} strut(s) below {self.min_diameter:g} mm diameter"
        if self.num_struts:
            thin += f" (thinnest {self.thinnest:.4g} mm)"
        out.append(thin)
        out.append(
            f"  unsupported nodes: {len(self.unsupported):,} of {self.num_nodes:,} (no strut "
            f"from below at >= {a:g} deg, above the lowest level)"
        )
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())

    def to_dict(self, *, max_indices: int = 1000) -> dict[str, Any]:
        """JSON-ready summary; index lists are cut to ``max_indices`` entries."""
        return {
            "build_direction": [float(x) for x in self.build_direction],
            "critical_angle": self.critical_angle,
            "min_diameter": self.min_diameter,
            "struts": self.num_struts,
            "nodes": self.num_nodes,
            "overhangs": self.overhang_count,
            "overhang_fraction": self.overhang_fraction,
            "min_angle": self.min_angle if self.num_struts else None,
            "thin": self.thin_count,
            "thinnest": self.thinnest if self.num_struts else None,
            "unsupported_nodes": int(len(self.unsupported)),
            "overhanging_struts": self.overhanging[:max_indices].tolist(),
            "thin_struts": self.thin[:max_indices].tolist(),
            "unsupported_node_ids": self.unsupported[:max_indices].tolist(),
            "examples": [
                {"strut": int(e[0]), "angle": float(e[1]), "midpoint": [float(x) for x in e[2:]]}
                for e in self.examples
            ],
        }

    def to_records(self) -> list[dict[str, str]]:
        """The summary as (quantity, value) rows, for the accuracy report's tables."""
        rows = [
            ("build direction", f"{self.direction_label}"),
            ("critical angle (deg)", f"{self.critical_angle:g}"),
            (
                "overhanging struts",
                f"{self.overhang_count} of {self.num_struts} ({self.overhang_fraction:.2%})",
            ),
            ("smallest strut angle (deg)", f"{self.min_angle:.4g}"),
            ("minimum diameter (mm)", f"{self.min_diameter:g}"),
            ("thin struts", f"{self.thin_count} (thinnest {self.thinnest:.4g} mm)"),
            ("unsupported nodes", f"{len(self.unsupported)} of {self.num_nodes}"),
        ]
        for e in self.examples:
            rows.append(
                (
                    f"overhang example: strut {int(e[0])}",
                    f"{e[1]:.4g} deg, midpoint ({e[2]:.6g}, {e[3]:.6g}, {e[4]:.6g})",
                )
            )
        return [{"quantity": q, "value": v} for q, v in rows]


def printability(
    graph: LatticeGraph,
    *,
    build_direction: ArrayLike = config.BUILD_DIRECTION,
    critical_angle: float = config.OVERHANG_ANGLE_DEG,
    min_diameter: float = config.MIN_STRUT_DIAMETER,
    examples: int = 5,
) -> PrintabilityReport:
    """Overhanging and thin struts and unsupported nodes of a lattice.

    Parameters
    ----------
    graph : LatticeGraph
    build_direction : (3,) float
        Direction the layers grow in (any non-zero vector; normalised). Default +Z.
    critical_angle : float
        Degrees in 0..90: struts whose angle to the build plate is below it (by more than
        ``config.ANGLE_EPS_DEG``) are overhangs. Default 35.
    min_diameter : float
        mm, >= 0: struts whose smallest diameter is below it are thin. Default 0.4.
    examples : int
        How many overhangs (lowest angle first) the report names with coordinates.

    Returns
    -------
    PrintabilityReport

    Raises
    ------
    PrintabilityError
        A zero or non-finite build direction, an angle outside 0..90, a negative diameter.
    """
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"graph must be a LatticeGraph, got {type(graph).__name__}")
    b = as_build_direction(build_direction)
    crit = as_critical_angle(critical_angle)
    dmin = as_min_diameter(min_diameter)
    nodes, edges = graph.nodes, graph.edges
    angles = _angles(graph.edge_vectors, b)
    over_mask = angles < crit - config.ANGLE_EPS_DEG
    overhanging = np.flatnonzero(over_mask).astype(np.int64)
    diameters = 2.0 * graph.radii.min(axis=1)
    thin = np.flatnonzero(diameters < dmin).astype(np.int64)
    # unsupported nodes: not on the plate and no steep-enough strut from below
    used = graph.degree > 0
    h = nodes @ b
    if used.any():
        hu = h[used]
        tol = config.PLATE_RTOL * max(float(hu.max() - hu.min()), float(np.abs(hu).max()), 1.0)
        on_plate = h <= float(hu.min()) + tol
    else:
        tol = 0.0
        on_plate = np.zeros(len(nodes), dtype=bool)
    steep = ~over_mask
    ha, hb = h[edges[:, 0]], h[edges[:, 1]]
    supported = np.zeros(len(nodes), dtype=bool)
    supported[edges[steep & (hb > ha + tol), 1]] = True
    supported[edges[steep & (ha > hb + tol), 0]] = True
    unsupported = np.flatnonzero(used & ~on_plate & ~supported).astype(np.int64)
    k = max(int(examples), 0)
    order = overhanging[np.argsort(angles[overhanging], kind="stable")][:k]
    mids = 0.5 * (nodes[edges[order, 0]] + nodes[edges[order, 1]])
    ex = np.column_stack([order.astype(np.float64), angles[order], mids]).reshape(-1, 5)
    return PrintabilityReport(
        build_direction=b,
        critical_angle=crit,
        min_diameter=dmin,
        num_struts=graph.num_edges,
        num_nodes=int(used.sum()),
        angles=angles,
        overhanging=overhanging,
        thin=thin,
        unsupported=unsupported,
        diameters=diameters,
        examples=ex,
    )


# ------------------------------------------------------------------ removal
@dataclass(frozen=True)
class OverhangRemoval:
    """What :func:`remove_overhangs` removed.

    Attributes
    ----------
    struts_before, struts_after : int
    removed_overhangs : int
        Overhanging struts removed.
    removed_islands : int
        Struts removed afterwards because they were left in loose pieces.
    islands : int
        Loose pieces removed.
    bodies : int
        Connected pieces left (one per separate solid of the part at most).
    removed_nodes : int
        Nodes left without any strut, dropped.
    kept : (M,) bool
        Which struts of the input graph are in the output (in the same order).
    critical_angle : float
    build_direction : (3,) float64
    """

    struts_before: int
    struts_after: int
    removed_overhangs: int
    removed_islands: int
    islands: int
    bodies: int
    removed_nodes: int
    kept: NDArray[np.bool_] = field(repr=False)
    critical_angle: float = config.OVERHANG_ANGLE_DEG
    build_direction: NDArray[np.float64] = field(
        default_factory=lambda: np.array(config.BUILD_DIRECTION), repr=False
    )

    def __str__(self) -> str:
        return (
            f"removed {self.removed_overhangs:,} overhanging strut(s) (below "
            f"{self.critical_angle:g} deg to the plate, build direction "
            f"{_direction_label(self.build_direction)}) and {self.removed_islands:,} strut(s) "
            f"in {self.islands:,} loose piece(s); {self.struts_after:,} of "
            f"{self.struts_before:,} struts left in {self.bodies} body(ies)"
        )


def remove_overhangs(
    graph: LatticeGraph,
    *,
    build_direction: ArrayLike = config.BUILD_DIRECTION,
    critical_angle: float = config.OVERHANG_ANGLE_DEG,
    part: Part | None = None,
) -> tuple[LatticeGraph, OverhangRemoval]:
    """The lattice without its overhanging struts, kept in one piece.

    The overhanging struts (see :func:`printability`) are removed; the pieces this cuts
    loose are then removed too, keeping the largest connected piece in each separate
    solid of ``part`` (the whole lattice is one solid without a part), as the voxel
    builder does (:func:`conformal.voxel.main_components`). Nodes left without struts
    are dropped; the kept struts keep their radii and their order.

    Parameters
    ----------
    graph : LatticeGraph
    build_direction : (3,) float
    critical_angle : float
    part : conformal.Part, optional
        The filled part (one kept piece per separate solid of it).

    Returns
    -------
    LatticeGraph, OverhangRemoval

    Raises
    ------
    PrintabilityError
        Every strut is an overhang (nothing would be left), or bad options.

    Warns
    -----
    LatticeWarning
        When loose pieces had to be removed (with the self-supporting cells).
    """
    from conformal.voxel import main_components

    rep = printability(graph, build_direction=build_direction, critical_angle=critical_angle)
    m = graph.num_edges
    keep = np.ones(m, dtype=bool)
    keep[rep.overhanging] = False
    if m and not keep.any():
        raise PrintabilityError(
            f"all {m} struts are below {rep.critical_angle:g} deg to the build plate "
            f"(build direction {rep.direction_label}); removing them leaves nothing: choose "
            "another cell, another build direction or a smaller critical angle"
        )
    sub = np.flatnonzero(keep)
    ok, pieces, bodies = main_components(part, graph.nodes, graph.edges[sub])
    keep[sub[~ok]] = False
    edges = graph.edges[keep]
    used = np.zeros(graph.num_nodes, dtype=bool)
    used[edges.ravel()] = True
    new_id = np.cumsum(used) - 1
    out = LatticeGraph(graph.nodes[used], new_id[edges], graph.radii[keep])
    removal = OverhangRemoval(
        struts_before=m,
        struts_after=int(keep.sum()),
        removed_overhangs=rep.overhang_count,
        removed_islands=int((~ok).sum()),
        islands=pieces - bodies,
        bodies=bodies,
        removed_nodes=int((graph.degree > 0).sum() - used.sum()),
        kept=keep,
        critical_angle=rep.critical_angle,
        build_direction=rep.build_direction,
    )
    if removal.removed_islands:
        cells = ", ".join(self_supporting_cells(rep.build_direction, rep.critical_angle))
        warnings.warn(
            f"removing the overhangs cut {removal.islands} loose piece(s) off the lattice "
            f"({removal.removed_islands} more strut(s) removed, {removal.struts_after} of "
            f"{m} left): the cell is not self-supporting along {rep.direction_label}; cells "
            f"that are (at {rep.critical_angle:g} deg): {cells or 'none'}",
            LatticeWarning,
            stacklevel=2,
        )
    return out, removal


# ----------------------------------------------------------------- the cells
def _cell_directions(cell: UnitCell, cell_size: ArrayLike) -> NDArray[np.float64]:
    """(E, 3) float64 unit strut directions of a cell (lattice frame)."""
    h = np.broadcast_to(np.asarray(cell_size, dtype=np.float64), (3,))
    if not (np.isfinite(h).all() and (h > 0).all()):
        raise PrintabilityError(f"cell_size must be > 0, got {np.asarray(cell_size).tolist()}")
    d = (cell.nodes[cell.edges[:, 1]] - cell.nodes[cell.edges[:, 0]]) * h
    return d / np.linalg.norm(d, axis=1)[:, None]


def _rotation(rotation: ArrayLike | None) -> NDArray[np.float64]:
    if rotation is None:
        return np.eye(3)
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9):
        raise PrintabilityError("rotation must be a 3x3 rotation matrix (orthonormal)")
    return r


def cell_angles(
    build_direction: ArrayLike = config.BUILD_DIRECTION,
    *,
    rotation: ArrayLike | None = None,
    cell_size: float | ArrayLike = 1.0,
    cells: dict[str, UnitCell] | None = None,
) -> dict[str, float]:
    """The smallest strut angle to the build plate of every cell.

    Parameters
    ----------
    build_direction : (3,) float
    rotation : (3, 3) float, optional
        The lattice's orientation as in ``conformal.voxel_lattice`` (world = rotation @
        lattice); default: lattice axes = world axes.
    cell_size : float or (hx, hy, hz)
        Only the ratios matter (non-cubic cells tilt the struts).
    cells : dict, optional
        Default: every built-in cell (:data:`conformal.CELLS`).

    Returns
    -------
    dict[str, float]
        Cell name -> degrees (the cell is self-supporting when this is >= the critical angle).
    """
    b = as_build_direction(build_direction)
    r = _rotation(rotation)
    out = {}
    for name, cell in (CELLS if cells is None else cells).items():
        world = _cell_directions(cell, cell_size) @ r.T
        out[name] = float(_angles(world, b).min())
    return out


def self_supporting_cells(
    build_direction: ArrayLike = config.BUILD_DIRECTION,
    critical_angle: float = config.OVERHANG_ANGLE_DEG,
    *,
    rotation: ArrayLike | None = None,
    cell_size: float | ArrayLike = 1.0,
) -> list[str]:
    """Names of the built-in cells with no strut below ``critical_angle`` (sorted).

    Along +Z at 35 degrees: bcc, bccz, diamond, rhombic-dodecahedron (their slanted
    struts are body diagonals, at asin(1/sqrt(3)) = 35.26 degrees).
    """
    crit = as_critical_angle(critical_angle)
    angles = cell_angles(build_direction, rotation=rotation, cell_size=cell_size)
    return sorted(n for n, a in angles.items() if a >= crit - config.ANGLE_EPS_DEG)


@dataclass(frozen=True)
class Orientation:
    """A lattice orientation found by :func:`best_orientation`.

    Attributes
    ----------
    rotation : (3, 3) float64
        World = rotation @ lattice (pass it as ``rotation=`` to ``voxel_lattice`` or
        ``Lattice.fill``).
    lattice_direction : (3,) float64
        The build direction in the lattice's own frame (unit).
    min_angle : float
        The smallest strut angle to the build plate, degrees.
    """

    rotation: NDArray[np.float64] = field(repr=False)
    lattice_direction: NDArray[np.float64]
    min_angle: float


def _fibonacci_hemisphere(n: int) -> NDArray[np.float64]:
    i = np.arange(n) + 0.5
    z = i / n  # upper hemisphere, z in (0, 1)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    s = np.sqrt(1.0 - z * z)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


def _integer_directions(k: int) -> NDArray[np.float64]:
    r = np.arange(-k, k + 1)
    g = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3).astype(np.float64)
    g = g[np.abs(g).sum(axis=1) > 0]
    return g / np.linalg.norm(g, axis=1)[:, None]


def _rotation_taking(u: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The smallest rotation R with R @ u = b (unit vectors)."""
    c = float(u @ b)
    k = np.cross(u, b)
    if c < -1.0 + 1e-12:  # opposite: half turn about any axis normal to u
        a = np.cross(u, np.eye(3)[int(np.argmin(np.abs(u)))])
        a /= np.linalg.norm(a)
        return 2.0 * np.outer(a, a) - np.eye(3)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + kx + kx @ kx / (1.0 + c)


def best_orientation(
    cell: UnitCell | str,
    build_direction: ArrayLike = config.BUILD_DIRECTION,
    *,
    cell_size: float | ArrayLike = 1.0,
) -> Orientation:
    """The lattice rotation that makes the cell's smallest strut angle largest.

    The best build direction in the lattice frame maximises ``min_e |d_e . u|`` over the
    cell's unit strut directions ``d_e``. It is searched among small integer directions
    (components -4..4, where the optimum of the built-in cells lies: (1, 1, 1) for cubic,
    35.26 degrees; (0, 0, 1) for bcc; (2, 1, 0) for octet, fcc and kelvin, only
    asin(1/sqrt(10)) = 18.43 degrees) and a refined sphere sampling; an integer direction
    is preferred when it is as good within 1e-12, and among those the one closest to the
    build direction (so a cell that is already best along it is not rotated). The rotation
    is the smallest one taking that direction onto ``build_direction``.

    Returns
    -------
    Orientation
    """
    c = _resolve(cell)
    b = as_build_direction(build_direction)
    d = _cell_directions(c, cell_size)

    def score(u: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.abs(u @ d.T).min(axis=1)

    # exact candidates: b itself (no rotation) first, then small integer directions
    ints = np.vstack([b, _integer_directions(4)])
    s_int = score(ints)
    cand = np.vstack([ints, _fibonacci_hemisphere(4000)])
    s = score(cand)
    top = cand[np.argsort(-s)[:16]]
    rng = np.random.default_rng(0)
    step = 0.05
    for _ in range(40):  # shrinking random local search around the best candidates
        trial = top[:, None, :] + step * rng.normal(size=(len(top), 32, 3))
        trial = np.concatenate([top[:, None, :], trial], axis=1).reshape(-1, 3)
        trial /= np.linalg.norm(trial, axis=1)[:, None]
        st = score(trial).reshape(len(top), 33)
        top = trial.reshape(len(top), 33, 3)[np.arange(len(top)), np.argmax(st, axis=1)]
        step *= 0.8
    s_top = score(top)
    u = top[int(np.argmax(s_top))]
    tied = np.flatnonzero(s_int >= max(float(s_top.max()), float(s_int.max())) - 1e-12)
    if len(tied):  # the exact direction closest to b (the smallest rotation)
        u = ints[tied[int(np.argmax(np.abs(ints[tied] @ b)))]]
    if u @ b < 0:  # either sign of u is as good: take the one closer to b
        u = -u
    min_angle = float(np.degrees(np.arcsin(min(float(score(u[None, :])[0]), 1.0))))
    return Orientation(rotation=_rotation_taking(u, b), lattice_direction=u, min_angle=min_angle)
