"""Beam finite-element models of a lattice graph: CalculiX/Abaqus ``.inp`` files (numpy only).

:func:`save_inp` writes the lattice as a frame of quadratic beams, ready for ``ccx`` (or
Abaqus with ``dialect="abaqus"``) once a step with supports and loads is added:

* **Elements.** Every strut is ``elements_per_strut`` (default 3,
  ``config.FE_ELEMENTS_PER_STRUT``) three-node ``B32`` beams (end, mid-node, end); CalculiX
  refuses linear ``B31`` beams with circular sections, and ``B32R`` (reduced integration) is
  available with ``element="B32R"``. One quadratic element per strut is not enough: its
  deflection is a parabola, so a strut held in rotation at both ends (every strut of a
  rigid-jointed lattice) cannot take its S shape and locks; a BCC cell under compression
  came out 14-22 % too stiff with one element, 0.1-2.1 % with two, 0.1-0.7 % with three.
* **Nodes.** Graph node ``i`` is node ``i + 1``; the mid-node of element ``e`` (1-based) is
  node ``N + e`` (``N`` graph nodes); the inner nodes of split struts follow. Nodes without
  struts are not written. Units: mm, N, MPa, tonne/mm^3.
* **Sections.** ``*BEAM SECTION, SECTION=CIRC`` per radius group: radii are rounded on a
  relative width ``radius_step`` (default ``config.FE_RADIUS_STEP``, 0.1 %; each group has
  the middle radius of its range, so A is within 0.1 % and I within 0.2 %; equal radii stay
  exact), groups are named ``R1``, ``R2``, ... by increasing radius.
  A section's first direction is one global axis for all its elements, so each group is
  split by the axis least aligned with the strut (element sets ``R1_X``, ``R1_Y``,
  ``R1_Z``): the direction makes at least 54.7 degrees with every strut, never parallel.
* **Tapered struts: stepped sections.** A strut whose end radii differ is split into ``k``
  equal elements, each with the radius at its mid-length (the midpoint rule). The flexibility
  of an element is ``int ds / r(s)^p`` (``p = 2`` axial, ``4`` bending); the midpoint rule
  underestimates it by about ``p (p + 1) / 24 * (dr / r)^2`` for a radius change ``dr``
  along the element, 0.83 ``(dr / r)^2`` in bending, the worst case. ``k`` is the smallest
  number for which this estimate is below ``taper_tol`` (default 1 %, at most
  ``config.FE_MAX_TAPER_ELEMENTS``); a strut tapering from 0.4 to 0.6 mm gets 5 elements.
* **CalculiX's circle.** CalculiX reads the CIRC line as the *diameter* (Abaqus: the
  radius) and expands each beam into 20-node bricks whose section has 8 nodes on that circle
  joined by parabolas; the outline encloses 1.18 % less area and 2.34 % less second moment
  than the circle, exactly as a circle 0.594 % smaller would. With ``dialect="calculix"``
  the diameter written is ``2 r`` times :data:`CCX_CIRC_SCALE` (1.005945), so that the
  expanded section has the area and second moment of the strut (to 1e-5).
* **What CalculiX's beams do that beam theory does not** (measured with ccx 2.20, slender
  beams; see ``tests/test_fe.py``): with a nonzero Poisson's ratio the expanded bricks are
  stiffer in bending than Euler-Bernoulli beams, by about 2.5 % at nu = 0.3 and 3.5-4.5 %
  at nu = 0.36 (axial stiffness within 0.6 %); at nu = 0 they agree within 1.3 %. Load
  with forces (``*CLOAD``): a prescribed nonzero displacement on a node whose rotations are
  also held is mishandled for struts off the axes (wrong by 5 % up to a factor 1000), and
  the reaction forces ccx prints for clamped beam nodes (``RF``) are wrong for struts off
  the axes (a skew cantilever's root reaction off by 10 times the load); take forces from
  the loads, displacements from ``U``.
* **Sets.** ``NALL`` (every node), ``NJOINT`` (the graph nodes), ``EALL`` and the user's node
  sets, each a mask or index array over the graph nodes (see :func:`select_nodes` for planes,
  boxes and axis selectors; the front resolves CAD faces).
* **Material.** ``*MATERIAL`` with ``*ELASTIC`` and ``*DENSITY`` (default PLA, see
  :data:`lattice_cad.core.config.FE_MATERIAL`).

The file holds the model only; a commented example step at its end shows how to fix one
set and load another. :func:`read_dat` reads the tables ``ccx`` prints to its ``.dat`` file.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core import config
from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.errors import ExportError, SelectionError
from lattice_cad.core.formats import Kind, format_for
from lattice_cad.core.graph import LatticeGraph

__all__ = [
    "CCX_CIRC_SCALE",
    "Dialect",
    "Element",
    "Material",
    "Plane",
    "Box",
    "BeamModel",
    "beam_model",
    "save_inp",
    "parse_selector",
    "axis_plane",
    "select_nodes",
    "distance_to_triangles",
    "taper_elements",
    "DatBlock",
    "read_dat",
]

Dialect = Literal["calculix", "abaqus"]
Element = Literal["B32", "B32R"]

#: CalculiX's CIRC section (8 nodes on the circle, parabolic sides) has the area and second
#: moment of a circle of ``1 / CCX_CIRC_SCALE`` times the radius: area ``(2 + 8 (sqrt 2 - 1)
#: / 3) r^2`` against ``pi r^2``; the second moments agree with the same factor to 1e-5.
CCX_CIRC_SCALE = math.sqrt(math.pi / (2.0 + 8.0 * (math.sqrt(2.0) - 1.0) / 3.0))

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,79}$")
_RESERVED = re.compile(r"^(NALL|NJOINT|EALL|R\d+_[XYZ])$", re.IGNORECASE)
_PER_LINE = 16  # Abaqus: at most 16 entries per data line


# ------------------------------------------------------------------------------ inputs
@dataclass(frozen=True)
class Material:
    """A linear elastic isotropic material (mm, N, MPa, tonne/mm^3).

    Attributes
    ----------
    name : str
        Material name in the file (letters, digits, ``_``).
    youngs_modulus : float
        Young's modulus E (MPa).
    poisson : float
        Poisson's ratio nu, in (-1, 0.5).
    density : float
        Density (tonne/mm^3; 1 g/cm^3 = 1e-9).
    """

    name: str = config.FE_MATERIAL
    youngs_modulus: float = config.FE_YOUNGS_MODULUS
    poisson: float = config.FE_POISSON
    density: float = config.FE_DENSITY

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(
                f"material name must start with a letter and hold only letters, digits and "
                f"'_' (at most 80), got {self.name!r}"
            )
        for what, v in (("youngs_modulus", self.youngs_modulus), ("density", self.density)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)):
                raise TypeError(f"material {what} must be a number, got {v!r}")
            if not (math.isfinite(float(v)) and float(v) > 0):
                raise ValueError(f"material {what} must be a positive number, got {v!r}")
        nu = self.poisson
        if isinstance(nu, bool) or not isinstance(nu, (int, float, np.number)):
            raise TypeError(f"material poisson must be a number, got {nu!r}")
        if not -1.0 < float(nu) < 0.5:
            raise ValueError(f"material poisson must lie in (-1, 0.5), got {nu!r}")

    @classmethod
    def from_options(cls, options: Mapping[str, Any] | Material | None) -> Material:
        """A material from ``None`` (the default), a Material, or a mapping with the keys
        ``name``, ``E`` (or ``youngs_modulus``), ``nu`` (or ``poisson``), ``density``."""
        if options is None:
            return cls()
        if isinstance(options, Material):
            return options
        alias = {
            "e": "youngs_modulus",
            "youngs_modulus": "youngs_modulus",
            "nu": "poisson",
            "poisson": "poisson",
            "density": "density",
            "rho": "density",
            "name": "name",
        }
        kw: dict[str, Any] = {}
        for key, value in dict(options).items():
            k = alias.get(str(key).lower())
            if k is None:
                raise ValueError(f"unknown material option {key!r}: use name, E, nu, density")
            kw[k] = value
        return cls(**kw)


@dataclass(frozen=True)
class Plane:
    """The plane through ``point`` with normal ``normal``: selects nodes within a tolerance.

    Attributes
    ----------
    point : (3,) float
    normal : (3,) float
        Any length but zero.
    """

    point: tuple[float, float, float]
    normal: tuple[float, float, float]

    def __post_init__(self) -> None:
        p = np.asarray(self.point, dtype=np.float64).reshape(-1)
        n = np.asarray(self.normal, dtype=np.float64).reshape(-1)
        if (
            p.shape != (3,)
            or n.shape != (3,)
            or not (np.isfinite(p).all() and np.isfinite(n).all())
        ):
            raise SelectionError(f"a plane needs a finite point and normal of 3 numbers: {self}")
        if not np.linalg.norm(n) > 0:
            raise SelectionError(f"the normal of a plane must not be zero: {self}")
        object.__setattr__(self, "point", tuple(float(x) for x in p))
        object.__setattr__(self, "normal", tuple(float(x) for x in n))


@dataclass(frozen=True)
class Box:
    """The closed axis-aligned box ``lo <= x <= hi``: selects the nodes inside it.

    Attributes
    ----------
    lo, hi : (3,) float
    """

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def __post_init__(self) -> None:
        lo = np.asarray(self.lo, dtype=np.float64).reshape(-1)
        hi = np.asarray(self.hi, dtype=np.float64).reshape(-1)
        if (
            lo.shape != (3,)
            or hi.shape != (3,)
            or not (np.isfinite(lo).all() and np.isfinite(hi).all())
        ):
            raise SelectionError(f"a box needs finite corners of 3 numbers: {self}")
        if np.any(lo > hi):
            raise SelectionError(f"a box needs lo <= hi in every axis: {self}")
        object.__setattr__(self, "lo", tuple(float(x) for x in lo))
        object.__setattr__(self, "hi", tuple(float(x) for x in hi))


# ---------------------------------------------------------------------- selection
def parse_selector(text: str) -> Plane | Box | str:
    """``"plane:x,y,z,nx,ny,nz"`` and ``"box:x0,y0,z0,x1,y1,z1"`` as :class:`Plane` and
    :class:`Box`; any other text is returned as it is (a CadQuery face selector)."""
    t = text.strip()
    head, sep, tail = t.partition(":")
    kind = head.strip().lower()
    if sep and kind in ("plane", "box"):
        try:
            values = [float(x) for x in tail.split(",")]
        except ValueError:
            raise SelectionError(f"{text!r}: expected 6 numbers after '{kind}:'") from None
        if len(values) != 6:
            raise SelectionError(f"{text!r}: expected 6 numbers after '{kind}:', got {len(values)}")
        a, b = tuple(values[:3]), tuple(values[3:])
        return Plane(a, b) if kind == "plane" else Box(a, b)  # type: ignore[arg-type]
    if not t:
        raise SelectionError("an empty selector selects nothing")
    return t


_AXIS = re.compile(r"^\s*([<>])\s*([XYZ])\s*$", re.IGNORECASE)


def axis_plane(selector: str, bounds: ArrayLike) -> Plane | None:
    """The plane of an axis selector (``">Z"``, ``"<X"``, ...) on a bounding box.

    ``">Z"`` is the plane ``z = bounds[1, 2]`` (the top), ``"<Z"`` ``z = bounds[0, 2]``.
    Returns None for any other selector.

    Parameters
    ----------
    selector : str
    bounds : (2, 3) float64
        Min and max corners.
    """
    m = _AXIS.match(selector)
    if m is None:
        return None
    b = np.asarray(bounds, dtype=np.float64).reshape(2, 3)
    axis = "XYZ".index(m.group(2).upper())
    top = m.group(1) == ">"
    point = b[1] if top else b[0]
    normal = np.zeros(3)
    normal[axis] = 1.0 if top else -1.0
    return Plane(tuple(point), tuple(normal))  # type: ignore[arg-type]


def _node_tolerance(graph: LatticeGraph, tol: float | None) -> NDArray[np.float64]:
    """(N,) float64: the selection tolerance of every node (its largest strut radius)."""
    if tol is not None:
        t = float(tol)
        if not (math.isfinite(t) and t >= 0):
            raise ValueError(f"tol must be a non-negative number, got {tol!r}")
        return np.full(graph.num_nodes, t)
    r = np.zeros(graph.num_nodes)
    np.maximum.at(r, graph.edges[:, 0], graph.radii[:, 0])
    np.maximum.at(r, graph.edges[:, 1], graph.radii[:, 1])
    return r


def distance_to_triangles(
    points: ArrayLike, triangles: ArrayLike, *, chunk: int = 250_000
) -> NDArray[np.float64]:
    """Distance of every point to the nearest of the triangles (exact, numpy).

    Parameters
    ----------
    points : (P, 3) float64
    triangles : (T, 3, 3) float64
        Corners; degenerate triangles are allowed.
    chunk : int
        Largest number of point-triangle pairs handled at once (memory).

    Returns
    -------
    (P,) float64
        ``inf`` when there are no triangles.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    out = np.full(len(p), np.inf)
    if len(t) == 0 or len(p) == 0:
        return out
    step = max(1, chunk // len(t))
    for s in range(0, len(p), step):
        q = p[s : s + step, None, :]  # (P, 1, 3)
        out[s : s + step] = np.sqrt(
            _sq_dist(q, t[None, :, 0], t[None, :, 1], t[None, :, 2]).min(axis=1)
        )
    return out


def _sq_dist(
    p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Squared distance from points to triangles (broadcast), via the plane or the edges."""
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    nn = np.einsum("...i,...i->...", n, n)
    ap = p - a
    # inside test by barycentric coordinates of the projection
    d00 = np.einsum("...i,...i->...", ab, ab)
    d01 = np.einsum("...i,...i->...", ab, ac)
    d11 = np.einsum("...i,...i->...", ac, ac)
    d20 = np.einsum("...i,...i->...", ap, ab)
    d21 = np.einsum("...i,...i->...", ap, ac)
    den = d00 * d11 - d01 * d01
    with np.errstate(divide="ignore", invalid="ignore"):
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        plane = np.einsum("...i,...i->...", ap, n) ** 2 / nn
    inside = (nn > 0) & (v >= 0) & (w >= 0) & (v + w <= 1)
    best = np.where(inside, plane, np.inf)
    for u, e in ((a, ab), (a, ac), (b, c - b)):
        ee = np.einsum("...i,...i->...", e, e)
        up = p - u
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.clip(np.einsum("...i,...i->...", up, e) / ee, 0.0, 1.0)
        s = np.where(ee > 0, s, 0.0)
        d = up - s[..., None] * e
        best = np.minimum(best, np.einsum("...i,...i->...", d, d))
    return best


def select_nodes(
    graph: LatticeGraph,
    selector: Any,
    *,
    tol: float | None = None,
    bounds: ArrayLike | None = None,
    triangles: ArrayLike | None = None,
    slack: float = 0.0,
    name: str = "node set",
) -> NDArray[np.int64]:
    """The graph nodes (with struts) a selector picks, without CAD.

    Parameters
    ----------
    graph : LatticeGraph
    selector : Plane, Box, str, (K,) int array or (N,) bool mask
        A :class:`Plane` picks the nodes within ``tol`` of it; a :class:`Box` the nodes
        inside it; ``"plane:..."``/``"box:..."`` text is parsed by :func:`parse_selector`;
        an axis selector ``">Z"``, ``"<X"``, ... the nodes within ``tol`` of that side of
        ``bounds``; integers are graph node indices, booleans a mask over the nodes.
        With ``triangles`` (a tessellated face) the selector is ignored and the nodes within
        ``tol`` of the triangles are picked.
    tol : float, optional
        Distance tolerance (mm); default per node: its largest strut radius (the node's
        material touches the face).
    bounds : (2, 3) float64, optional
        The box of axis selectors (the part's); default the graph's bounds.
    triangles : (T, 3, 3) float64, optional
    slack : float
        Added to every tolerance (the deflection of tessellated faces).
    name : str
        Used in error messages.

    Returns
    -------
    (K,) int64
        Sorted graph node indices, K >= 1.

    Raises
    ------
    SelectionError
        The selector is not understood, or picks no node (the message gives the distance of
        the nearest node).
    """
    n = graph.num_nodes
    used = graph.degree > 0
    pts = graph.nodes
    tols = _node_tolerance(graph, tol) + float(slack)
    if isinstance(selector, str) and triangles is None:
        selector = parse_selector(selector)
        if isinstance(selector, str):
            plane = axis_plane(selector, graph.bounds if bounds is None else bounds)
            if plane is None:
                raise SelectionError(
                    f"{name}: {selector!r} needs the part's B-rep (a STEP part or a CAD "
                    "object); without it use >X <X >Y <Y >Z <Z, 'plane:x,y,z,nx,ny,nz', "
                    "'box:x0,y0,z0,x1,y1,z1' or node indices"
                )
            selector = plane
    dist: NDArray[np.float64] | None = None
    if triangles is not None:
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
        near = used & np.all((pts >= lo - tols[:, None]) & (pts <= hi + tols[:, None]), axis=1)
        dist = np.full(n, np.inf)
        dist[near] = distance_to_triangles(pts[near], tri)
        if not np.any(near):  # for the message: the nearest node at all
            dist[used] = distance_to_triangles(pts[used], tri)
        mask = dist <= tols
    elif isinstance(selector, Plane):
        normal = np.asarray(selector.normal) / np.linalg.norm(selector.normal)
        dist = np.abs((pts - np.asarray(selector.point)) @ normal)
        mask = dist <= tols
    elif isinstance(selector, Box):
        lo, hi = np.asarray(selector.lo), np.asarray(selector.hi)
        mask = np.all((pts >= lo) & (pts <= hi), axis=1)
        dist = np.linalg.norm(np.maximum(np.maximum(lo - pts, pts - hi), 0.0), axis=1)
    else:
        arr = np.asarray(selector)
        if arr.dtype == np.bool_:
            if arr.shape != (n,):
                raise SelectionError(f"{name}: a node mask must have shape ({n},), got {arr.shape}")
            mask = arr.copy()
        elif arr.ndim == 1 and np.issubdtype(arr.dtype, np.integer):
            bad = arr[(arr < 0) | (arr >= n)]
            if len(bad):
                raise SelectionError(f"{name}: node index {int(bad[0])} is out of range 0..{n - 1}")
            mask = np.zeros(n, dtype=bool)
            mask[arr] = True
            lone = np.flatnonzero(mask & ~used)
            if len(lone):
                raise SelectionError(f"{name}: node {int(lone[0])} has no strut")
        else:
            raise SelectionError(
                f"{name}: cannot select nodes with {type(selector).__name__} {selector!r}"
            )
    mask &= used
    idx = np.flatnonzero(mask).astype(np.int64)
    if len(idx) == 0:
        near_msg = ""
        if dist is not None and np.any(used):
            i = int(np.flatnonzero(used)[np.argmin(dist[used])])
            near_msg = (
                f"; the nearest node ({i}) is {dist[i]:.4g} mm away, the tolerance there "
                f"{tols[i]:.4g} mm (a larger tol, or a fill that reaches the surface: "
                "fill='clip' or 'conform')"
            )
        raise SelectionError(f"{name}: {_describe(selector)} selects no node{near_msg}")
    return idx


def _describe(selector: Any) -> str:
    if isinstance(selector, (Plane, Box, str)) or hasattr(selector, "wrapped"):
        return repr(selector)
    return f"the given {type(selector).__name__}"


# ------------------------------------------------------------------------ the model
@dataclass(frozen=True)
class BeamModel:
    """The beam model of a lattice graph, as written by :func:`save_inp`.

    Attributes
    ----------
    node_ids : (K,) int64
        Node numbers (graph node ``i`` is ``i + 1``).
    nodes : (K, 3) float64
        Their coordinates (mm).
    elements : (E, 3) int64
        Node numbers of each element: end, mid-node, end (element ``e`` is number ``e + 1``).
    element_strut : (E,) int64
        The graph strut of each element (split tapered struts have several).
    element_radius : (E,) float64
        The section radius of each element, after grouping.
    element_axis : (E,) int64
        0, 1, 2: the global axis that is the first section direction.
    radii : (G,) float64
        The radius of each section group ``R1`` .. ``RG``.
    element_group : (E,) int64
        The group (0-based) of each element.
    joints : (J,) int64
        The graph nodes written (those with struts).
    """

    node_ids: NDArray[np.int64]
    nodes: NDArray[np.float64]
    elements: NDArray[np.int64]
    element_strut: NDArray[np.int64]
    element_radius: NDArray[np.float64]
    element_axis: NDArray[np.int64]
    radii: NDArray[np.float64]
    element_group: NDArray[np.int64]
    joints: NDArray[np.int64]
    node_sets: dict[str, NDArray[np.int64]] = field(default_factory=dict)

    @property
    def num_elements(self) -> int:
        """Number of beam elements E."""
        return int(len(self.elements))

    @property
    def num_nodes(self) -> int:
        """Number of nodes K written."""
        return int(len(self.node_ids))

    def elset(self, e: int) -> str:
        """The element set of element ``e`` (0-based): ``R<group>_<axis>``."""
        return f"R{int(self.element_group[e]) + 1}_{'XYZ'[int(self.element_axis[e])]}"

    def summary(self) -> str:
        """One line: nodes, elements, sections, node sets."""
        sets = ", ".join(f"{k} {len(v)}" for k, v in self.node_sets.items())
        return (
            f"{self.num_nodes:,} nodes, {self.num_elements:,} beam elements, "
            f"{len(self.radii)} section radii ({self.radii.min():.4g}..{self.radii.max():.4g} mm)"
            + (f"; node sets: {sets}" if sets else "")
        )


def _check_int(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_fraction(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and 0 < v < 1):
        raise ValueError(f"{name} must lie in (0, 1), got {value!r}")
    return v


def taper_elements(
    radii: ArrayLike,
    *,
    taper_tol: float = config.FE_TAPER_TOL,
    elements_per_strut: int = config.FE_ELEMENTS_PER_STRUT,
) -> NDArray[np.int64]:
    """(M,) int64: elements per strut, so that the stepped sections of a tapered strut keep
    the estimated bending-stiffness error ``0.83 (dr / r_min)^2`` below ``taper_tol``.

    Parameters
    ----------
    radii : (M, 2) float64
        End radii of each strut.
    """
    r = np.asarray(radii, dtype=np.float64).reshape(-1, 2)
    dr = np.abs(r[:, 1] - r[:, 0]) / r.min(axis=1)
    k = np.ceil(dr / math.sqrt(24.0 / 20.0 * taper_tol) - 1e-12).astype(np.int64)
    return np.clip(
        np.maximum(k, elements_per_strut), 1, max(elements_per_strut, config.FE_MAX_TAPER_ELEMENTS)
    )


def beam_model(
    graph: LatticeGraph,
    *,
    elements_per_strut: int = config.FE_ELEMENTS_PER_STRUT,
    taper_tol: float = config.FE_TAPER_TOL,
    radius_step: float = config.FE_RADIUS_STEP,
) -> BeamModel:
    """Nodes, elements and sections of the beam model of ``graph`` (see the module notes).

    Parameters
    ----------
    graph : LatticeGraph
    elements_per_strut : int
        Elements per strut at least (more for finer stress or buckling results).
    taper_tol : float
        Largest estimated bending-stiffness error of a tapered strut's steps.
    radius_step : float
        Relative width of a radius group.

    Returns
    -------
    BeamModel
    """
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"graph must be a LatticeGraph, got {type(graph).__name__}")
    if graph.num_edges == 0:
        raise ExportError("a beam model needs at least one strut; the graph has none")
    elements_per_strut = _check_int("elements_per_strut", elements_per_strut, 1)
    taper_tol = _check_fraction("taper_tol", taper_tol)
    radius_step = _check_fraction("radius_step", radius_step)
    n = graph.num_nodes
    e_nodes = graph.edges
    k = taper_elements(graph.radii, taper_tol=taper_tol, elements_per_strut=elements_per_strut)
    n_el = int(k.sum())
    strut = np.repeat(np.arange(graph.num_edges, dtype=np.int64), k)
    first = np.concatenate([[0], np.cumsum(k)[:-1]])
    j = np.arange(n_el, dtype=np.int64) - first[strut]  # element index within its strut
    kk = k[strut].astype(np.float64)
    t0, tm = j / kk, (j + 0.5) / kk
    a, b = graph.nodes[e_nodes[strut, 0]], graph.nodes[e_nodes[strut, 1]]
    ra, rb = graph.radii[strut, 0], graph.radii[strut, 1]
    radius = ra + (rb - ra) * tm
    # mid-nodes: N + 1 + e; inner nodes of split struts afterwards
    mid_id = n + 1 + np.arange(n_el, dtype=np.int64)
    inner = j > 0  # element starts at an inner node of its strut
    inner_id = np.zeros(n_el, dtype=np.int64)
    inner_id[inner] = n + n_el + 1 + np.arange(int(inner.sum()), dtype=np.int64)
    start = np.where(inner, inner_id, e_nodes[strut, 0] + 1)
    last = j == k[strut] - 1
    nxt = np.zeros(n_el, dtype=np.int64)
    nxt[:-1] = start[1:]
    end = np.where(last, e_nodes[strut, 1] + 1, nxt)
    elements = np.column_stack([start, mid_id, end])
    joints = np.flatnonzero(graph.degree > 0).astype(np.int64)
    ids = np.concatenate([joints + 1, mid_id, inner_id[inner]])
    xyz = np.vstack([
        graph.nodes[joints],
        a + (b - a) * tm[:, None],
        (a + (b - a) * t0[:, None])[inner],
    ])  # fmt: skip
    # radius groups: sorted radii cut where one exceeds its group's smallest by radius_step;
    # each group's radius is the middle of its range (every member within radius_step / 2)
    group, radii = _radius_groups(radius, radius_step)
    d = b - a
    axis = np.argmin(np.abs(d) / np.linalg.norm(d, axis=1)[:, None], axis=1).astype(np.int64)
    return BeamModel(
        node_ids=ids,
        nodes=xyz,
        elements=elements,
        element_strut=strut,
        element_radius=radii[group],
        element_axis=axis,
        radii=radii,
        element_group=group,
        joints=joints,
    )


def _radius_groups(
    radius: NDArray[np.float64], step: float
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Group radii: (E,) group of each, (G,) radius of each group (increasing)."""
    values, inverse = np.unique(radius, return_inverse=True)
    group_of_value = np.zeros(len(values), dtype=np.int64)
    starts = [0]
    for i in range(1, len(values)):
        if values[i] > values[starts[-1]] * (1.0 + step):
            starts.append(i)
        group_of_value[i] = len(starts) - 1
    bounds = np.append(starts, len(values))
    radii = np.array(
        [0.5 * (values[a] + values[b - 1]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    )
    return group_of_value[inverse.reshape(-1)].astype(np.int64), radii


def _check_set_name(name: Any, taken: set[str]) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ExportError(
            f"node set name {name!r}: must start with a letter and hold only letters, digits "
            "and '_' (at most 80 characters)"
        )
    if _RESERVED.match(name):
        raise ExportError(f"node set name {name!r} is reserved (NALL, NJOINT, EALL, R<n>_<axis>)")
    if name.upper() in taken:
        raise ExportError(f"node set name {name!r} is given twice (names ignore case)")
    taken.add(name.upper())
    return name


def _id_lines(ids: NDArray[np.int64]) -> list[str]:
    return [
        ", ".join(map(str, ids[i : i + _PER_LINE].tolist())) for i in range(0, len(ids), _PER_LINE)
    ]


def save_inp(
    graph: LatticeGraph,
    path: str | os.PathLike[str],
    *,
    node_sets: Mapping[str, Any] | None = None,
    material: Mapping[str, Any] | Material | None = None,
    element: Element = "B32",
    dialect: Dialect = "calculix",
    elements_per_strut: int = config.FE_ELEMENTS_PER_STRUT,
    taper_tol: float = config.FE_TAPER_TOL,
    radius_step: float = config.FE_RADIUS_STEP,
    tol: float | None = None,
    title: str = "lattice",
) -> BeamModel:
    """Write ``graph`` as a CalculiX/Abaqus beam model (atomically); see the module notes.

    Parameters
    ----------
    graph : LatticeGraph
    path : path-like
        ``.inp``.
    node_sets : mapping of str to selector, optional
        Named node sets for supports and loads: each value is anything
        :func:`select_nodes` takes (a :class:`Plane`, a :class:`Box`, ``"plane:..."``,
        ``"box:..."``, an axis selector such as ``"<Z"`` on the graph's bounds, node indices
        or a node mask). CAD faces are resolved by the front (``Lattice.save``).
    material : mapping or Material, optional
        ``{"E": MPa, "nu": ..., "density": t/mm^3, "name": ...}``; default PLA (config).
    element : {"B32", "B32R"}
        Quadratic beam, full or reduced integration.
    dialect : {"calculix", "abaqus"}
        How the CIRC section line is written: CalculiX reads a diameter (corrected for its
        polygonal section, see :data:`CCX_CIRC_SCALE`), Abaqus a radius.
    elements_per_strut, taper_tol, radius_step
        See :func:`beam_model`.
    tol : float, optional
        Tolerance of plane and axis selectors (default per node: its largest strut radius).
    title : str
        Written in the heading.

    Returns
    -------
    BeamModel
        What was written, with ``node_sets`` as node numbers.

    Raises
    ------
    ExportError
        No strut, or a bad node set name.
    SelectionError
        A node set selects nothing.
    """
    if element not in ("B32", "B32R"):
        raise ValueError(f"element must be 'B32' or 'B32R', got {element!r}")
    if dialect not in ("calculix", "abaqus"):
        raise ValueError(f"dialect must be 'calculix' or 'abaqus', got {dialect!r}")
    p = Path(path)
    format_for(p, Kind.FE_MODEL, what="beam FE model")
    mat = Material.from_options(material)
    model = beam_model(
        graph, elements_per_strut=elements_per_strut, taper_tol=taper_tol, radius_step=radius_step
    )
    taken: set[str] = set()
    sets: dict[str, NDArray[np.int64]] = {}
    for name, sel in (node_sets or {}).items():
        _check_set_name(name, taken)
        sets[name] = select_nodes(graph, sel, tol=tol, name=f"node set {name!r}") + 1
    model.node_sets.update(sets)
    text = _render(model, graph, mat, element=element, dialect=dialect, title=title)
    with atomic_write(p, "w") as fh:
        fh.write(text)
    return model


def _render(
    model: BeamModel,
    graph: LatticeGraph,
    mat: Material,
    *,
    element: str,
    dialect: str,
    title: str,
) -> str:
    out: list[str] = []
    w = out.append
    safe_title = " ".join(str(title).split())[:70]
    w("*HEADING")
    w(f"lattice-cad beam model of {safe_title}: {graph.num_edges} struts")
    w(f"** {model.summary()}")
    w("** units: mm, N, MPa, tonne/mm^3; node i+1 = graph node i, mid-node of element e = "
      f"node {graph.num_nodes} + e")  # fmt: skip
    if dialect == "calculix":
        w(f"** CIRC sections: diameter x {CCX_CIRC_SCALE:.6f} (CalculiX's 8-node circle has "
          "the strut's A and I); written for CalculiX")  # fmt: skip
    else:
        w("** CIRC sections: radius (Abaqus convention); for CalculiX write dialect='calculix'")
    w("*NODE, NSET=NALL")
    order = np.argsort(model.node_ids, kind="stable")
    for i, (x, y, z) in zip(
        model.node_ids[order].tolist(), model.nodes[order].tolist(), strict=True
    ):
        w(f"{i}, {x:.12g}, {y:.12g}, {z:.12g}")
    w("*NSET, NSET=NJOINT")
    out.extend(_id_lines(model.joints + 1))
    eid = np.arange(1, model.num_elements + 1, dtype=np.int64)
    key = model.element_group * 3 + model.element_axis
    for k in np.unique(key).tolist():
        sel = np.flatnonzero(key == k)
        w(f"*ELEMENT, TYPE={element}, ELSET={model.elset(int(sel[0]))}")
        for e, (n1, n2, n3) in zip(eid[sel].tolist(), model.elements[sel].tolist(), strict=True):
            w(f"{e}, {n1}, {n2}, {n3}")
    w("*ELSET, ELSET=EALL, GENERATE")
    w(f"1, {model.num_elements}, 1")
    for name, ids in model.node_sets.items():
        w(f"*NSET, NSET={name}")
        out.extend(_id_lines(ids))
    w(f"*MATERIAL, NAME={mat.name}")
    w("*ELASTIC")
    w(f"{float(mat.youngs_modulus):.9g}, {float(mat.poisson):.9g}")
    w("*DENSITY")
    w(f"{float(mat.density):.9g}")
    scale = 2.0 * CCX_CIRC_SCALE if dialect == "calculix" else 1.0
    for k in np.unique(key).tolist():
        g, ax = divmod(int(k), 3)
        count = int(np.count_nonzero(key == k))
        r = float(model.radii[g])
        w(f"** R{g + 1}: strut radius {r:.6g} mm, {count} element(s), first direction {'XYZ'[ax]}")
        w(f"*BEAM SECTION, ELSET=R{g + 1}_{'XYZ'[ax]}, MATERIAL={mat.name}, SECTION=CIRC")
        w(f"{r * scale:.9g}")
        direction = [0, 0, 0]
        direction[ax] = 1
        w(", ".join(map(str, direction)))
    names = list(model.node_sets)
    fix = names[0] if names else "FIXED"
    load = names[1] if len(names) > 1 else (names[0] if names else "LOAD")
    w("** Example analysis (remove the '** ' to use): hold the first node set, push the")
    w("** second with 1 N per node in -z, print the displacements. Load with forces, and take")
    w("** no RF of skew beams from ccx (see lattice_cad.io.fe).")
    w("** *BOUNDARY")
    w(f"** {fix}, 1, 6")
    w("** *STEP")
    w("** *STATIC")
    w("** *CLOAD")
    w(f"** {load}, 3, -1.0")
    w("** *NODE PRINT, NSET=NJOINT")
    w("** U")
    w("** *END STEP")
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------------- results
@dataclass(frozen=True)
class DatBlock:
    """One table of a CalculiX ``.dat`` file.

    Attributes
    ----------
    quantity : str
        ``"displacements"``, ``"forces"``, ``"stresses"``, ... (a ``total force`` line
        has the quantity of its table, ``"forces"``).
    set : str
        The node or element set.
    time : float
    total : bool
        True for a ``total ...`` line (``TOTALS=YES/ONLY``).
    ids : (n,) int64
        Node or element numbers (empty for totals).
    values : (n, k) float64
    """

    quantity: str
    set: str
    time: float
    total: bool
    ids: NDArray[np.int64]
    values: NDArray[np.float64]


_HEAD = re.compile(
    r"^\s*(total\s+)?(\w[\w ]*?)\s*\(([^)]*)\)\s*for set\s+(\S+)\s+and time\s+(\S+)", re.IGNORECASE
)


def read_dat(path: str | os.PathLike[str]) -> list[DatBlock]:
    """The tables of a CalculiX ``.dat`` file (from ``*NODE PRINT`` / ``*EL PRINT``).

    Returns
    -------
    list of DatBlock
        In file order.
    """
    lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    blocks: list[DatBlock] = []
    i = 0
    while i < len(lines):
        m = _HEAD.match(lines[i])
        i += 1
        if m is None:
            continue
        total = bool(m.group(1))
        rows: list[list[float]] = []
        while i < len(lines) and not lines[i].strip():
            i += 1
        while i < len(lines) and lines[i].strip() and _HEAD.match(lines[i]) is None:
            try:
                rows.append([float(x) for x in lines[i].split()])
            except ValueError:
                break
            i += 1
        if total:
            ids = np.zeros(0, dtype=np.int64)
            vals = np.asarray(rows, dtype=np.float64).reshape(len(rows), -1)
        else:
            arr = np.asarray(rows, dtype=np.float64).reshape(len(rows), -1)
            ids = arr[:, 0].astype(np.int64) if len(arr) else np.zeros(0, dtype=np.int64)
            vals = arr[:, 1:]
        quantity = m.group(2).strip().lower()
        if total and not quantity.endswith("s"):  # "total force": as its table, "forces"
            quantity += "s"
        blocks.append(DatBlock(quantity, m.group(4), float(m.group(5)), total, ids, vals))
    return blocks
