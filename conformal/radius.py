"""Strut radii for the lattice builders, and the check that a graph will stitch.

A *radius spec* is one of

* a number: every strut end;
* an ``(M,)`` array (one per strut) or ``(M, 2)`` array (per strut end:
  tapered struts, ``[:, 0]`` at ``edges[:, 0]``);
* a callable ``f(midpoints) -> (M,) or (M, 2)`` of the ``(M, 3)`` strut
  midpoints (graded lattices; see :func:`graded_by_distance`).

:func:`check_fit` lists the struts that :func:`fast_stitch.stitch` would
reject: because their end profiles (whose offsets from the node are set by the
angles and radii of all struts at that node) would meet, or because struts and
joints that share no node would overlap (:func:`fast_stitch.fit.clashes`, e.g.
opposite edges of a flat tetrahedron). :func:`fit_radii` thins the offending
struts until every strut fits and clears the others; :func:`fit_problems`
describes what is left, for a :class:`FitError`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypedDict, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fast_stitch.fit import clashes, misfits, strut_lengths
from fast_stitch.hubvolume import Profile, profile_factor
from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.checks import check_segments
from lattice_cad.core.errors import FitError
from lattice_cad.core.graph import LatticeGraph

if TYPE_CHECKING:
    from conformal.part import Part

__all__ = [
    "RadiusSpec",
    "resolve_radii",
    "graded_by_distance",
    "StrutMisfit",
    "StrutClash",
    "fit_problems",
    "check_fit",
    "fit_radii",
    "repair_graph",
    "unstitchable_dropped",
    "RepairReport",
    "FitError",
    "Profile",
    "check_stitch_profile",
]

RadiusSpec = Union[float, ArrayLike, Callable[[NDArray[np.float64]], ArrayLike]]  # noqa: UP007


def check_stitch_profile(segments: object, profile: object) -> tuple[int, Profile]:
    """The stitch's ``segments`` and ``profile`` that a builder fits the radii for, checked.

    Raises
    ------
    TypeError, ValueError
        ``segments`` is not an integer >= 3, or ``profile`` is not one of
        ``fast_stitch.hubvolume.PROFILES`` (the message names the option).
    """
    p = check_segments(segments)
    if not isinstance(profile, str):
        raise TypeError(f"profile must be a string, got {profile!r}")
    profile_factor(p, profile)  # ValueError naming the profiles
    return p, profile  # type: ignore[return-value]


def resolve_radii(
    radius: RadiusSpec, nodes: NDArray[np.float64], edges: NDArray[np.int64]
) -> NDArray[np.float64]:
    """Turn a radius spec into per-end radii.

    Parameters
    ----------
    radius : float, (M,), (M, 2) or callable
        See the module docstring.
    nodes : (N, 3) float64
    edges : (M, 2) int64

    Returns
    -------
    (M, 2) float64

    Raises
    ------
    ValueError
        Wrong shape, or a radius that is not finite and > 0 (the message names the strut).
    """
    m = len(edges)
    if callable(radius):
        mid = 0.5 * (nodes[edges[:, 0]] + nodes[edges[:, 1]])
        r = np.asarray(radius(mid), dtype=np.float64)
        what = "the radius callable's result"
    else:
        r = np.asarray(radius, dtype=np.float64)
        what = "radius"
    if r.ndim == 0:
        out = np.full((m, 2), float(r))
    elif r.shape == (m,):
        out = np.repeat(r[:, None], 2, axis=1)
    elif r.shape == (m, 2):
        out = r.astype(np.float64, copy=True)
    else:
        raise ValueError(
            f"{what} must be a number or have shape ({m},) or ({m}, 2) for {m} struts; "
            f"got shape {r.shape}"
        )
    bad = ~(np.isfinite(out) & (out > 0)).all(axis=1)
    if bad.any():
        e = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}: strut {e} has radius {out[e].tolist()}; radii must be > 0")
    return out


def graded_by_distance(
    part: Part, *, near: float, far: float, width: float
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """A radius callable: ``near`` at the part's surface, ``far`` at ``width`` and beyond.

    Linear in the distance ``d`` of the strut midpoint to the surface:
    ``far + (near - far) * max(0, 1 - d / width)``.
    """
    if not (near > 0 and far > 0 and width > 0):
        raise ValueError("near, far and width must be > 0")

    def f(mid: NDArray[np.float64]) -> NDArray[np.float64]:
        d = part.distance(mid, max_distance=width)
        t = np.where(np.isfinite(d), np.clip(1.0 - d / width, 0.0, 1.0), 0.0)
        return far + (near - far) * t

    return f


@dataclass(frozen=True)
class StrutMisfit:
    """A strut whose end profiles would meet: stitching would fail on it."""

    edge: int
    nodes: tuple[int, int]
    length: float
    needed: float  #: sum of the two end offsets; must stay below ``length``

    def __str__(self) -> str:
        return (
            f"strut {self.edge} (nodes {self.nodes[0]}, {self.nodes[1]}): length {self.length:.4g} "
            f"but its end profiles need {self.needed:.4g}; use thinner struts or a coarser lattice"
        )


@dataclass(frozen=True)
class StrutClash:
    """Two elements that share no node but would overlap: stitching would fail on them.

    An element is a strut (``joint`` False: ``index`` is the strut) or the
    joint at a node (``joint`` True: ``index`` is the node).
    """

    first: int
    second: int
    first_joint: bool
    second_joint: bool
    distance: float  #: between the two axes (a joint's axis is its node)
    needed: float  #: sum of the two radii, with the clearance margin
    names: tuple[str, str] = ("", "")

    def __str__(self) -> str:
        return (
            f"{self.names[0]} and {self.names[1]} share no node but are {self.distance:.4g} "
            f"apart, less than the {self.needed:.4g} their radii need; use thinner struts "
            "or fit='shrink'"
        )


def _clash_list(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    shrink: bool = True,
    margin: float = config.CLEARANCE_MARGIN,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> list[StrutClash]:
    pairs, dist, need = clashes(
        nodes, edges, radii, shrink=shrink, margin=margin, segments=segments, profile=profile
    )
    m = len(edges)

    def name(el: int) -> str:
        if el < m:
            return f"strut {el} (nodes {int(edges[el, 0])}, {int(edges[el, 1])})"
        return f"the joint at node {el - m}"

    return [
        StrutClash(
            a if a < m else a - m,
            b if b < m else b - m,
            a >= m,
            b >= m,
            float(d),
            float(r),
            (name(a), name(b)),
        )
        for (a, b), d, r in zip(pairs.tolist(), dist.tolist(), need.tolist(), strict=True)
    ]


def check_fit(
    graph: LatticeGraph,
    segments: int = config.DEFAULT_SEGMENTS,
    *,
    shrink: bool = True,
    clearance: bool = True,
    profile: str = config.DEFAULT_PROFILE,
) -> list[StrutMisfit | StrutClash]:
    """What :func:`fast_stitch.stitch` would reject in ``graph``.

    Uses the stitcher's own offset rule (:mod:`fast_stitch.fit`) for the profile
    polygons of ``segments`` and ``profile`` (as in :func:`fast_stitch.stitch`: the
    default ``"volume"`` polygons have the circle's area, so their circumradius is
    larger than the strut radius, by 10 % at P = 6).

    Parameters
    ----------
    clearance : bool
        Also list struts and joints that share no node but would overlap
        (:func:`fast_stitch.fit.clashes`, with its 2 % margin).

    Returns
    -------
    list of StrutMisfit (too-short struts) then StrutClash (overlapping pairs)
        Empty when the graph will stitch.
    """
    bad, need, length = misfits(
        graph.nodes, graph.edges, graph.radii, shrink=shrink, segments=segments, profile=profile
    )
    out: list[StrutMisfit | StrutClash] = [
        StrutMisfit(
            int(e),
            (int(graph.edges[e, 0]), int(graph.edges[e, 1])),
            float(length[e]),
            float(need[e]),
        )
        for e in bad
    ]
    if clearance and not out:  # clearance is only meaningful once every strut has a cylinder
        out.extend(
            _clash_list(
                graph.nodes,
                graph.edges,
                graph.radii,
                shrink=shrink,
                segments=segments,
                profile=profile,
            )  # fmt: skip
        )
    return out


def fit_problems(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    shrink: bool = True,
    limit: int = 5,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> str:
    """A message naming the struts that will not stitch with ``radii`` ("" when all do).

    For ``fit="raise"``: too-short or too-fat struts, then pairs of struts (or
    a strut and a joint) that share no node but would overlap, with their
    distance, at most ``limit`` of each kind.
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.int64)
    radii = np.asarray(radii, dtype=np.float64)
    length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    bad, need, _ = misfits(nodes, edges, radii, shrink=shrink, segments=segments, profile=profile)
    bad = np.union1d(bad, np.flatnonzero(radii.max(axis=1) >= 0.5 * length))
    parts = []
    if len(bad):
        shown = "; ".join(
            f"strut {int(e)} (nodes {int(edges[e, 0])}, {int(edges[e, 1])}): length "
            f"{length[e]:.4g}, needs {max(need[e], 2 * radii[e].max()):.4g}"
            for e in bad[:limit]
        )
        parts.append(
            f"{len(bad)} of {len(edges)} struts are too short for their radii: {shown}"
            f"{' ...' if len(bad) > limit else ''}"
        )
    else:
        cl = _clash_list(nodes, edges, radii, shrink=shrink, segments=segments, profile=profile)
        if cl:
            shown = "; ".join(
                f"{c.names[0]} and {c.names[1]}: {c.distance:.4g} apart, need {c.needed:.4g}"
                for c in cl[:limit]
            )
            parts.append(
                f"{len(cl)} pair(s) of struts or joints that share no node would overlap: "
                f"{shown}{' ...' if len(cl) > limit else ''}"
            )
    if not parts:
        return ""
    return "; ".join(parts) + "; use thinner struts or fit='shrink'"


def fit_radii(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    min_radius: float = 0.0,
    shrink: bool = True,
    clearance: bool = True,
    max_rounds: int = 60,
    overwrite_input: bool = False,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Thin the struts at crowded nodes, and struts that pass too close, until all fit.

    A strut fits when its end offsets leave ``config.FIT_SLACK`` of its length free
    and its radius is below 0.45 of its length. Offsets at a node scale
    linearly with the radii there, so the radii at both ends of a misfit
    strut's nodes are scaled down by the missing factor (which may taper
    neighbouring struts), and the check is repeated.

    With ``clearance``, once every strut fits, struts and joints that share no
    node but come closer than their radii allow (:func:`fast_stitch.fit.clashes`,
    with twice its margin as a target) are thinned too: a clashing strut is
    scaled as a whole (its taper is kept), a clashing joint by scaling the
    radii of the strut ends at its node; then everything is checked again.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
    min_radius : float
        Radii are never reduced below this.
    overwrite_input : bool
        Work on ``radii`` itself (when it is a C-contiguous float64 array) rather than on
        a copy: it may hold the result, or be left changed (saves 16 bytes per strut).
    segments, profile
        The stitch's profile polygons (:func:`fast_stitch.stitch`): the check is for
        their circumradius, ``r * fast_stitch.hubvolume.profile_factor(segments, profile)``.

    Returns
    -------
    radii : (M, 2) float64
        The fitted radii.
    unfit : (K,) int64
        Struts that still do not fit or clear (radius at ``min_radius``).
    """
    own = (
        overwrite_input and isinstance(radii, np.ndarray) and radii.dtype == np.float64
        and radii.flags.c_contiguous and radii.flags.writeable
    )  # fmt: skip
    r = radii if own else np.array(radii, dtype=np.float64, copy=True)
    length = strut_lengths(nodes, edges)
    for s in range(0, len(edges), _BLOCK):  # by blocks: no (M, 2) temporaries
        cap = 0.45 * length[s : s + _BLOCK]
        rb = r[s : s + _BLOCK]
        too_fat = rb > cap[:, None]
        rb[too_fat] = np.broadcast_to(cap[:, None], rb.shape)[too_fat]
    del length
    bad = np.zeros(0, dtype=np.int64)
    n_nodes, m = len(nodes), len(edges)
    for _ in range(max_rounds):
        bad, need, length = misfits(
            nodes, edges, r, shrink=shrink, slack=config.FIT_SLACK, segments=segments,
            profile=profile,
        )  # fmt: skip
        if len(bad):
            factor = np.clip((1.0 - 1.5 * config.FIT_SLACK) * length[bad] / need[bad], 0.2, 0.97)
            del need, length
            node_f = np.ones(n_nodes)
            edge_f = np.ones(m)
            np.minimum.at(node_f, edges[bad, 0], factor)
            np.minimum.at(node_f, edges[bad, 1], factor)
        elif clearance:
            del need, length
            # aim past the check's own margin so that one round usually clears a pair
            pairs, dist, reach = clashes(
                nodes, edges, r, shrink=shrink, margin=2 * config.CLEARANCE_MARGIN,
                segments=segments, profile=profile,
            )  # fmt: skip
            bad = _clash_struts(pairs, edges, m, n_nodes)
            if not len(pairs):
                return r, bad
            node_f = np.ones(n_nodes)
            edge_f = np.ones(m)
            factor = np.repeat(np.clip(0.98 * dist / reach, 0.2, 0.97), 2)
            el = pairs.ravel()
            strut = el < m
            np.minimum.at(edge_f, el[strut], factor[strut])
            np.minimum.at(node_f, el[~strut] - m, factor[~strut])
        else:
            return r, bad
        if not _scale_radii(r, edges, node_f, edge_f, min_radius):
            break
    return r, bad


def _scale_radii(
    r: NDArray[np.float64],
    edges: NDArray[np.int64],
    node_f: NDArray[np.float64],
    edge_f: NDArray[np.float64],
    min_radius: float,
) -> bool:
    """``r[:] = max(r * node_f[edges] * edge_f[:, None], min_radius)`` in place, by blocks
    of struts (no (M, 2) temporaries); whether any radius changed."""
    changed = False
    for s in range(0, len(edges), _BLOCK):
        rb = r[s : s + _BLOCK]
        new = rb * node_f[edges[s : s + _BLOCK]] * edge_f[s : s + _BLOCK, None]
        np.maximum(new, min_radius, out=new)
        if not changed and not np.array_equal(new, rb):
            changed = True
        rb[...] = new
    return changed


_BLOCK = 1 << 16


def _clash_struts(
    pairs: NDArray[np.int64], edges: NDArray[np.int64], m: int, n_nodes: int
) -> NDArray[np.int64]:
    """The struts involved in clashes: clashing struts, and the struts at clashing joints."""
    el = np.unique(pairs.ravel())
    joint = np.zeros(n_nodes, dtype=np.bool_)
    joint[el[el >= m] - m] = True
    at_joint = np.flatnonzero(joint[edges].any(axis=1))
    return np.union1d(el[el < m], at_joint).astype(np.int64)


# ----------------------------------------------------------------- graph repair
@dataclass
class RepairReport:
    """What :func:`repair_graph` changed.

    Attributes
    ----------
    merged : int
        Short struts collapsed (their two nodes merged into one).
    dropped : int
        Struts removed because they met a neighbour at too small an angle.
    thinned : int
        Struts left thinner than asked (by less than the tolerance).
    unfit : int
        Struts that still had to be made thinner than ``tolerance`` times the asked radius
        (0 after a complete repair); they are thinned down to a tenth at most.
    where : list of (3,) float
        Midpoints of up to 10 unfit struts.
    """

    merged: int = 0
    dropped: int = 0
    thinned: int = 0
    unfit: int = 0
    where: list[list[float]] = field(default_factory=list)


class _Polygons(TypedDict):
    """The stitch's profile polygons (the options of :func:`fast_stitch.stitch`)."""

    segments: int
    profile: str


def fit_floor(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    r_min: float,
    min_radius: float | None = None,
) -> float:
    """The thinnest radius a builder may fit a strut to.

    ``min_radius`` (default a tenth of ``r_min``, the thinnest radius asked), raised to the
    thinnest radius STL and 3MF files can hold where the struts are: single-precision
    coordinates resolve ``|x| / config.PRECISION_RATIO_F32`` there (the contract
    :meth:`LatticeGraph.check_precision` enforces when writing). A strut the fit would
    thin further is repaired or dropped like one that cannot be stitched, instead of
    making a lattice its own writer refuses (a part 5,000 mm from the origin). Not raised
    when ``r_min`` itself is below that radius: the writer's refusal then names the
    radius needed, which is the user's to choose.
    """
    floor = 0.1 * float(r_min) if min_radius is None else float(min_radius)
    single = _single_precision_radius(nodes, edges)
    return max(floor, single) if single <= float(r_min) else floor


def _single_precision_radius(nodes: NDArray[np.float64], edges: NDArray[np.int64]) -> float:
    if len(edges) == 0:
        return 0.0
    big = float(np.abs(nodes[np.unique(edges)]).max())
    return big / config.PRECISION_RATIO_F32 * (1.0 + 1e-9)


def floor_note(nodes: NDArray[np.float64], edges: NDArray[np.int64], floor: float) -> str:
    """Why the fit's floor is ``floor`` when float32 coordinates set it (see
    :func:`fit_floor`), for an error message; "" otherwise."""
    single = _single_precision_radius(nodes, edges)
    if single == 0.0 or floor != single:  # (fit_floor returns this very value when it binds)
        return ""
    big = single * config.PRECISION_RATIO_F32
    return (
        f", the thinnest that STL and 3MF (single-precision coordinates) hold {big:.5g} mm "
        "from the origin, where the lattice lies"
    )


def repair_graph(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    surface: NDArray[np.bool_] | None = None,
    tolerance: float = 0.7,
    max_rounds: int = 60,
    max_change: float = 0.3,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], RepairReport]:
    """Change the graph, not the radius, where struts cannot be stitched at the radius asked.

    Struts that meet a neighbour at too small an angle for their radius, or pass too close
    to a strut or joint they share no node with (opposite edges of a flat tetrahedron),
    would have to be thinned (a tet mesh has some at almost every node). Thinning a strut
    to a tenth of its radius is not a fix: here a strut may lose at most ``1 - tolerance``
    of its radius.
    Beyond that, short struts (under a quarter of the median length) are collapsed, their nodes
    merged (a node on the part's surface keeps its place), and longer ones are dropped, as
    long as both of their nodes keep at least two struts; the graph stays connected (the
    largest piece is kept).

    Parameters
    ----------
    nodes : (N, 3) float64, edges : (M, 2) int64, radii : (M, 2) float64
    surface : (N,) bool, optional
        Nodes on the part's surface (they are never moved).
    tolerance : float
        Smallest fraction of the asked radius a strut may be thinned to.
    max_change : float
        At most this fraction of the struts is collapsed or dropped; what is still unfit
        then is thinned (and counted in ``report.unfit``). 0.3 (was 0.15): tet lattices of
        the shared parts at r = cell / 12 (``bench_parts.py``) keep the radius asked on far
        more struts for a few more dropped (GE bracket: 415 struts below 0.7 r of 4,627
        left, against 1,616 of 5,668 at 0.15).
    segments, profile
        The stitch's profile polygons, which the graph is repaired and fitted for (as in
        :func:`fit_radii`).

    Returns
    -------
    nodes : (N', 3) float64, edges : (M', 2) int64, radii : (M', 2) float64
        The repaired graph with fitted radii: each at least ``tolerance`` times the asked
        one, except for the ``report.unfit`` struts (listed by ``report.where``).
    report : RepairReport
    """
    nodes = np.array(nodes, dtype=np.float64, copy=True)
    edges = np.asarray(edges, dtype=np.int64)
    asked = np.asarray(radii, dtype=np.float64)
    on_surf = np.zeros(len(nodes), bool) if surface is None else np.asarray(surface, bool).copy()
    rep = RepairReport()
    poly: _Polygons = {"segments": segments, "profile": profile}  # what the stitch will build
    solid = _piece_labels(len(nodes), edges)  # the separate solids (a mesh's own pieces)
    median = float(np.median(np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)))
    budget = max_change * len(edges)  # the repair changes the lattice, it must not replace it
    for _ in range(max_rounds):
        if rep.merged + rep.dropped >= budget or not len(edges):
            break
        bad = _unfit_at(nodes, edges, tolerance * asked, **poly)
        if not len(bad):
            break
        length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
        short = bad[length[bad] < 0.25 * median]
        if len(short):
            nodes, edges, asked, on_surf, n = _collapse(nodes, edges, asked, on_surf, short)
            rep.merged += n
            continue
        deg = np.bincount(edges.ravel(), minlength=len(nodes))
        drop = np.zeros(len(edges), dtype=bool)
        # struts that would not fit even at a twentieth of the radius (nearly parallel to a
        # neighbour) go whatever the degree of their nodes
        hopeless = np.intersect1d(bad, misfits(nodes, edges, 0.05 * asked, **poly)[0])
        drop[hopeless] = True
        np.subtract.at(deg, edges[hopeless].ravel(), 1)
        room = int(budget - rep.merged - rep.dropped - len(hopeless))
        for e in bad[np.argsort(-length[bad])]:  # longest first
            a, b = edges[e]
            if not drop[e] and deg[a] > 2 and deg[b] > 2 and room > 0:
                room -= 1
                drop[e] = True
                deg[a] -= 1
                deg[b] -= 1
        if not drop.any():
            break
        rep.dropped += int(drop.sum())
        edges, asked = edges[~drop], asked[~drop]
    # struts that cannot be stitched even at a tenth of their radius (nearly parallel to a
    # neighbour, or crossing another) go in any case, however much has changed
    n_asked, r_asked = len(radii), float(np.min(radii)) if len(radii) else 0.0
    floor = fit_floor(nodes, edges, r_asked)
    keep = unstitchable_dropped(nodes, edges, asked, min_radius=floor, **poly)
    rep.dropped += int((~keep).sum())
    if not keep.any():
        raise FitError(
            f"none of the {n_asked} strut(s) can be stitched at radius {r_asked:g} even when "
            f"thinned to {floor:g}{floor_note(nodes, edges, floor)}: the radius is too large "
            f"for the strut lengths (median {median:g}); use a smaller radius or a larger size"
        )
    edges, asked = edges[keep], asked[keep]
    nodes, edges, asked = _largest_piece(nodes, edges, asked, group=solid)
    fitted, unfit = fit_radii(
        nodes, edges, asked, min_radius=max(tolerance * float(asked.min()), floor), **poly
    )
    if len(unfit):  # what the repair could not fix is thinned further, and counted
        fitted, unfit = fit_radii(nodes, edges, fitted, min_radius=floor, **poly)
    low = (fitted < tolerance * asked * (1 - 1e-9)).any(axis=1)
    bad = np.union1d(np.flatnonzero(low), unfit)
    rep.unfit = len(bad)
    rep.thinned = int(((fitted < asked * (1 - 1e-9)).any(axis=1)).sum())
    mids = 0.5 * (nodes[edges[bad, 0]] + nodes[edges[bad, 1]])
    rep.where = mids[:10].tolist()
    return nodes, edges, fitted, rep


def unstitchable_dropped(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    min_radius: float,
    rounds: int = 10,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> NDArray[np.bool_]:
    """(M,) bool: the struts kept when those that cannot be stitched even at ``min_radius``
    (nearly parallel to a neighbour, or crossing another strut) are dropped.

    :func:`fit_radii` names the hopeless struts; they are dropped and the rest is fitted
    again (dropping one frees its neighbours), at most ``rounds`` times.

    Parameters
    ----------
    nodes : (N, 3) float64, edges : (M, 2) int64, radii : (M, 2) float64
    min_radius : float
        The thinnest radius allowed.
    """
    keep = np.ones(len(edges), dtype=bool)
    for _ in range(rounds):
        idx = np.flatnonzero(keep)
        if not len(idx):
            break
        _, hopeless = fit_radii(
            nodes, edges[idx], radii[idx], min_radius=min_radius, segments=segments,
            profile=profile,
        )  # fmt: skip
        if not len(hopeless):
            break
        keep[idx[hopeless]] = False
    return keep


def _unfit_at(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: str = config.DEFAULT_PROFILE,
) -> NDArray[np.int64]:
    """Struts that do not fit at ``radii`` (end profiles meet) and those that clash with a
    strut or joint that shares no node, for the stitch's ``segments`` and ``profile``.

    Both, not the clashes only once every strut fits: in a tet mesh the opposite edges of
    flat tetrahedra pass close to each other, and left to :func:`fit_radii` each clash
    thins a strut as a whole (GE bracket at r = cell / 12: 4,498 of 6,910 struts clash at
    0.7 r; 2,352 ended below 0.7 r when the repair saw the misfits only)."""
    bad, _, _ = misfits(
        nodes, edges, radii, slack=config.FIT_SLACK, segments=segments, profile=profile
    )
    # the clashes among the struts that fit (clashes() measures each strut between its end
    # offsets, which a misfit's overlap makes meaningless); a strut passing a joint is the
    # one to change there, not every strut at the joint; two joints too close, all theirs
    sub = np.setdiff1d(np.arange(len(edges)), bad)
    pairs, _, _ = clashes(nodes, edges[sub], radii[sub], segments=segments, profile=profile)
    m = len(sub)
    struts = pairs[pairs < m]
    joints = pairs[(pairs >= m).all(axis=1)].ravel() - m
    at = np.zeros(len(nodes), dtype=np.bool_)
    at[joints] = True
    near = np.flatnonzero(at[edges[sub]].any(axis=1))
    return np.union1d(bad, sub[np.union1d(struts, near)])


def _collapse(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    surface: NDArray[np.bool_],
    which: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_], int]:
    """Merge the two nodes of each strut in ``which`` (an independent set of them)."""
    n = len(nodes)
    target = np.arange(n)
    busy = np.zeros(n, dtype=bool)
    merged = 0
    for e in which:
        a, b = (int(x) for x in edges[e])
        if busy[a] or busy[b]:
            continue
        busy[a] = busy[b] = True
        if surface[b] and not surface[a]:
            a, b = b, a  # keep the surface node where it is
        elif not surface[b]:
            nodes[a] = 0.5 * (nodes[a] + nodes[b]) if not surface[a] else nodes[a]
        target[b] = a
        surface[a] |= surface[b]
        merged += 1
    e2 = target[edges]
    keep = e2[:, 0] != e2[:, 1]
    e2, r2 = np.sort(e2[keep], axis=1), radii[keep]
    _, first = unique_rows(e2, return_index=True)
    first = np.sort(first)
    return nodes, e2[first], r2[first], surface, merged


def _piece_labels(n: int, edges: NDArray[np.int64]) -> NDArray[np.int64]:
    """(n,) int64: the connected piece of each node (an unused node is a piece of its own)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)[1].astype(np.int64)


def _largest_piece(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    group: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """The largest connected piece (by struts) of each ``group`` of nodes ((N,) int64, e.g.
    the separate solids of a tet mesh; default: one group), nodes renumbered (unused nodes
    dropped)."""
    n = len(nodes)
    lab = _piece_labels(n, edges)
    elab = lab[edges[:, 0]]
    size = np.bincount(elab, minlength=n)
    grp = np.zeros(n, dtype=np.int64) if group is None else np.asarray(group, dtype=np.int64)
    # per group, the piece with the most struts (a piece lies in one group: the repair only
    # merges and drops struts, so it never joins two groups)
    piece_group = np.zeros(n, dtype=np.int64)
    piece_group[elab] = grp[edges[:, 0]]
    pieces = np.flatnonzero(size)
    order = pieces[np.lexsort((-size[pieces], piece_group[pieces]))]
    first = np.ones(len(order), dtype=bool)
    first[1:] = piece_group[order[1:]] != piece_group[order[:-1]]
    keep = np.isin(elab, order[first])
    edges, radii = edges[keep], radii[keep]
    used = np.zeros(n, dtype=bool)
    used[edges.ravel()] = True
    new_id = np.cumsum(used) - 1
    return nodes[used], new_id[edges], radii
