"""Trim a lattice to its part: the printable solid never lies outside the part's surface.

A lattice graph fills a part with struts whose *axes* lie inside it (fill ``"clip"``,
``"conform"`` and tet lattices put nodes on the surface itself), so a stitched strut of
radius ``r`` reaches up to ``r`` beyond the surface: the printed part would be too big.
:func:`trim_to_part` intersects the stitched lattice with the part (manifold3d, whose
results are guaranteed 2-manifold), so every strut that reaches the boundary is cut by the
part's surface, and measures the protrusion before and after on the vertices.

Cutting can leave pieces that were joined only outside the part; as for the graph (see
``conformal.voxel.keep_main_components``), each separate solid of the part keeps its largest
piece and the others are removed and counted.

The protrusion is measured against the part's tessellation (the surface the lattice is cut
by). A part's default tessellation (chord error 1e-3 of its diagonal) lies *outside* the
exact surface of concave faces (holes, inner fillets) by up to that chord error, several %
of a strut radius on real parts; :func:`cutting_part` therefore tessellates a B-rep part
again, with a chord error of ``config.CUT_DEFLECTION_RTOL`` times the strut radius, before
it cuts (``Lattice`` does; measured by ``benchmarks/bench_protrusion_exact.py`` against the
exact B-rep).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config

__all__ = [
    "TrimReport",
    "TrimResult",
    "trim_to_part",
    "protrusion",
    "cutting_part",
    "cut_shortfall",
    "unfolded_tessellation",
]


@dataclass(frozen=True)
class TrimReport:
    """What :func:`trim_to_part` did.

    Attributes
    ----------
    trimmed : bool
        Whether the lattice reached outside the part (else it is returned unchanged).
    protrusion_before, protrusion_after : float
        Largest distance (mm) of a mesh vertex outside the part's surface (0 when none is
        outside), before and after trimming.
    tolerance : float
        The stated bound on ``protrusion_after`` (mm): ``config.TRIM_RTOL`` times the
        largest strut radius, but never below float32 rounding of the coordinates.
    volume_removed : float
        Volume (mm^3) cut away, including removed pieces.
    bodies : int
        Connected bodies of the result (at most one per solid of the part).
    pieces_removed : int
        Pieces cut loose by the trim and removed.
    seconds : float
    failed : str
        Why the trimmed lattice could not be written (then the lattice is written uncut and
        ``protrusion_before`` is what the file has; the part's surface crossing itself, or
        float32 not holding the cut); empty when it was.
    clearance : float
        When :func:`clear_inside` proved the lattice inside the part on the part's own
        tessellation: the clearance (mm) from the exact surface it proved; else 0.
    volume_before : float
        Volume (mm^3) of the lattice before the cut (NaN when not measured).
    rebuilt : float
        When the part's surface folds over itself (``conformal.Part.folds``) and the cut
        was by its rebuild (``conformal.unfold.rebuilt_part``): that grid's spacing (mm);
        else 0. The protrusions are measured against the part as loaded.
    """

    trimmed: bool
    protrusion_before: float
    protrusion_after: float
    tolerance: float
    volume_removed: float
    bodies: int
    pieces_removed: int
    seconds: float
    failed: str = ""
    clearance: float = 0.0
    rebuilt: float = 0.0
    volume_before: float = float("nan")

    @property
    def share_removed(self) -> float:
        """The fraction of the lattice's volume the cut removed (NaN when not known)."""
        if not self.volume_before > 0:
            return float("nan")
        return self.volume_removed / self.volume_before

    @property
    def within_tolerance(self) -> bool:
        return not self.failed and self.protrusion_after <= self.tolerance

    def summary(self) -> str:
        if self.failed:
            return (
                f"trim: NOT cut to the part's surface ({self.failed}); the lattice reaches up to "
                f"{self.protrusion_before:.3g} mm outside the part"
            )
        if not self.trimmed:
            if self.clearance:
                return (
                    f"trim: the lattice lies inside the part, clear of its surface by more "
                    f"than {self.clearance:.3g} mm (nothing to cut)"
                )
            return (
                f"trim: the lattice lies inside the part (largest protrusion "
                f"{self.protrusion_before:.3g} mm)"
            )
        removed = f", {self.pieces_removed} loose piece(s) removed" if self.pieces_removed else ""
        by = (
            f"to the part's surface rebuilt on a {self.rebuilt:.3g} mm grid (the part's own "
            "surface folds over itself)"
            if self.rebuilt
            else "to the part's surface"
        )
        return (
            f"trim: cut {by}: protrusion {self.protrusion_before:.3g} mm -> "
            f"{self.protrusion_after:.2g} mm (tolerance {self.tolerance:.2g} mm), "
            f"{self.volume_removed:.4g} mm^3 removed{removed}, {self.bodies} body(ies), "
            f"{self.seconds:.1f} s"
        )


@dataclass(frozen=True)
class TrimResult:
    """``solid``: the trimmed lattice (``manifold3d.Manifold``, or the lattice as given when
    it was not cut); ``report``: a TrimReport; ``split``: with ``trim_to_part(graph=)``, a
    ``conformal.skin_split.SplitLattice`` whose deep struts ``split.glue`` puts back into
    ``solid`` (then only the struts near the part's surface), else None."""

    solid: Any
    report: TrimReport
    split: Any = None


def protrusion(part: Any, vertices: NDArray[np.float64]) -> float:
    """Largest distance (mm) of ``vertices`` outside the part's surface, 0 if none is.

    Parameters
    ----------
    part : conformal.Part
    vertices : (V, 3) float64

    Returns
    -------
    float
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if len(v) == 0:
        return 0.0
    outside = ~part.contains(v)
    if not outside.any():
        return 0.0
    return float(part.distance(v[outside]).max())


#: Floor of the cutting tessellation's chord error, as a fraction of the part's diagonal
#: (bounds the triangle count for struts very thin against the part).
CUT_DEFLECTION_FLOOR = 2e-6


def _wanted(part: Any, radius: float, chord: float | None) -> float:
    """The chord error :func:`cutting_part` asks for (mm)."""
    asked = config.CUT_DEFLECTION_RTOL * float(radius) if chord is None else float(chord)
    return max(asked, CUT_DEFLECTION_FLOOR * part.diagonal)


def cutting_part(part: Any, radius: float, *, chord: float | None = None) -> Any:
    """The part tessellated finely enough to cut struts of ``radius`` by it.

    A B-rep part (STEP, CadQuery, build123d) is tessellated again with a chord error of
    ``config.CUT_DEFLECTION_RTOL * radius``, or ``chord`` when given (but not below
    ``CUT_DEFLECTION_FLOOR`` of its diagonal), so that a lattice cut by that mesh lies
    outside the *exact* surface by less than ``config.TRIM_RTOL * radius``; a mesh part, or
    one already tessellated that finely, is returned unchanged. A skin asks its own
    ``chord`` (``conformal.skin.outer_chord``): there the struts are cut by the skin's
    inner wall, and the part's surface is the wall's outside.

    The tessellation holds at most about ``config.CUT_MAX_TRIANGLES`` triangles. Where the
    chord error asked for would need more (threads, gear teeth, many small fillets), the
    chord error is chosen from measured triangle counts (starting from the pessimistic
    guess that triangles grow as 1 / chord error, then refining while the count stays
    well under the budget), and a :class:`~lattice_cad.core.errors.CutBudgetWarning`
    names the part and the chord error reached in % of ``radius``
    (:func:`cut_shortfall` gives it). When the finer tessellation fails (it is not
    closed), the part is returned unchanged with a
    :class:`~lattice_cad.core.errors.LatticeWarning`. A B-rep whose surface folds over
    itself (``Part.folds``) is rebuilt instead (:func:`conformal.unfold.rebuilt_part` on a
    grid of :func:`conformal.unfold.rebuild_spacing`; its ``rebuilt`` says so).

    Parameters
    ----------
    part : conformal.Part
    radius : float
        The largest strut radius (mm).
    chord : float, optional
        The chord error asked (mm), instead of ``config.CUT_DEFLECTION_RTOL * radius``.

    Returns
    -------
    conformal.Part
    """
    import warnings

    from lattice_cad.core.errors import CutBudgetWarning, LatticeWarning, PartError

    if getattr(part, "shape", None) is None or not radius > 0:
        return part
    if part.folds:
        # no tessellation of a surface that folds over itself bounds a solid (the swept
        # handle: 237 s of chord-checked tessellation before its cut was given up): the
        # region it encloses, rebuilt on a grid (conformal.unfold)
        from conformal.unfold import rebuild_spacing, rebuilt_part

        return rebuilt_part(part, spacing=rebuild_spacing(part, radius))
    want = _wanted(part, radius, chord)
    budget = config.CUT_MAX_TRIANGLES
    defl = max(want, _budget_guess(part, want, budget))  # the pessimistic guess
    at = getattr(part, "triangles_at", None)
    # the estimate (an upper bound: 1.1 - 8 x the count on the shared parts) is near the
    # budget: the first trial at the chord error asked, which usually holds (the
    # Ventilator: 1.07 M estimated, 0.59 M meshed; a trial of 3 s saved)
    near = defl > want and at is not None and (at(want) or np.inf) <= TRY_WANTED * budget
    angular = config.CUT_ANGULAR_DEFLECTION
    try:
        if defl <= want * (1 + 1e-9):  # the budget does not bind: no trial to count
            cut = part.refined(defl, angular=angular)
        else:
            cut = _budgeted(part, want if near else defl, want, budget, angular)
    except PartError as exc:
        warnings.warn(
            f"{part.name}: the lattice is cut by the part's default tessellation (chord error "
            f"{part.deflection:.3g} mm): a finer one ({defl:.3g} mm) failed: {exc}",
            LatticeWarning,
            stacklevel=2,
        )
        return part
    short = cut_shortfall(part, cut, radius, chord=chord)
    if short is not None:
        warnings.warn(
            f"{part.name}: the lattice is cut by a tessellation with chord error "
            f"{cut.deflection:.3g} mm = {short:.2f} % of the strut radius (asked "
            f"{want:.3g} mm): {len(cut.faces):,} triangles, the "
            f"budget (config.CUT_MAX_TRIANGLES = {budget:,}) binds; the cut may stand out of "
            f"the exact surface by about that much",
            CutBudgetWarning,
            stacklevel=2,
        )
    measured = float(getattr(cut, "chord_error", None) or 0.0)
    if getattr(cut, "chord_unresolved", 0) and measured > config.CHORD_CONTROL * cut.deflection:
        # faces BRepMesh does not follow (knots and finer meshing did not bring them down,
        # e.g. the exhaust manifold's B-spline faces): the chord error asked does not hold
        warnings.warn(
            f"{part.name}: {cut.chord_unresolved} face(s) could not be tessellated within the "
            f"chord error asked ({cut.deflection:.3g} mm; OpenCascade's mesher does not follow "
            f"them): the tessellation the lattice is cut by deviates from the exact surface by "
            f"up to {measured:.3g} mm = {100 * measured / radius:.3g} % of the strut radius there",
            CutBudgetWarning,
            stacklevel=2,
        )
    return cut


def unfolded_tessellation(part: Any, finer: Any) -> Any:
    """The finest tessellation of ``part``'s B-rep coarser than ``finer`` (a
    :func:`cutting_part` of it that crosses itself) that crosses itself in no more pairs of
    triangles than ``part`` as loaded does; ``part`` itself when none does.

    A face that folds over itself by less than the part's own chord error (a B-spline
    fillet corner of a wheel hub made outside shared/data, folding by about 0.05 mm: 0
    pairs at load, 0.287 mm; 0 at 0.072 mm; 18 at 0.036 mm; 695 at the skin's 0.011 mm)
    shows only in the finer tessellations. The chord error is doubled from
    ``finer.deflection`` until one holds; each trial is one BRepMesh run and one check.

    Parameters
    ----------
    part : conformal.Part
        As loaded.
    finer : conformal.Part
        A finer tessellation of the same B-rep.

    Returns
    -------
    conformal.Part
    """
    from lattice_cad.core.errors import PartError

    if getattr(part, "shape", None) is None or finer is part:
        return part
    allowed = part.self_crossings[0]
    deflection = 2.0 * finer.deflection
    while deflection < part.deflection:
        try:
            tried = part.refined(deflection)
        except PartError:
            tried = None
        if tried is not None and tried.self_crossings[0] <= allowed:
            return tried
        deflection *= 2.0
    return part


def _budget_guess(part: Any, want: float, budget: int) -> float:
    """The finest chord error (mm, not below ``want``) at which ``part``'s tessellation is
    expected to stay within ``budget`` triangles: from each face's count at the part's own
    chord error and how fast its surface's count grows (``Part.triangles_at``: planes and
    cylinders as the square root of the ratio; a perforated plate's 60 K triangles at
    0.18 mm are 86 K at 0.0042 mm, where 1 / chord error said 2.6 M and sent it through a
    4 s trial), else from the part's triangles growing as 1 / chord error. The trials of
    :func:`_budgeted` then count the triangles."""
    at = getattr(part, "triangles_at", None)
    if at is None or at(part.deflection) is None:
        return float(part.deflection * len(part.faces) / budget)
    if at(want) <= budget:
        return float(want)
    lo, hi = float(np.log(want)), float(np.log(part.deflection))  # at(e^lo) > budget
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if at(float(np.exp(mid))) > budget:
            lo = mid
        else:
            hi = mid
    return float(np.exp(hi))


#: :func:`cutting_part` tries the chord error asked first when :meth:`Part.triangles_at`
#: estimates at most this many times the budget there (the estimate is high: 1.1 - 8 x).
TRY_WANTED = 2.0
#: A trial over this many times the budget is not taken (:func:`_budgeted`).
OVER_BUDGET = 1.5


def _budgeted(part: Any, defl: float, want: float, budget: int, angular: float) -> Any:
    """:func:`cutting_part`'s tessellation when the triangle budget may bind (``defl``, the
    first trial, is the pessimistic guess or just above ``want``); a first trial over
    ``OVER_BUDGET`` times the budget is followed by coarser ones (triangles ~ 1 / chord)."""
    # the trials only count triangles: BRepMesh's own, without the chord check, which
    # the chosen one gets at the end (reusing its meshing when it was the last trial)
    cut = part.refined(defl, angular=angular, checked=False)
    for _ in range(4):  # the first trial asked too much: coarser (planes shrink slower)
        if len(cut.faces) <= OVER_BUDGET * budget:
            break
        defl *= len(cut.faces) / budget
        cut = part.refined(defl, angular=angular, checked=False)
    # planar faces do not grow with a finer chord error: measure and refine further
    # while the count stays under the budget (triangles assumed ~ 1 / chord)
    for _ in range(4):
        n = len(cut.faces)
        if defl <= want * (1 + 1e-9) or n >= 0.9 * budget:
            break
        finer = max(want, defl * n / budget)
        if finer > 0.95 * defl:
            break
        trial = part.refined(finer, angular=angular, checked=False)
        if len(trial.faces) > OVER_BUDGET * budget:
            break
        cut, defl = trial, finer
    cut = part.refined(defl, angular=angular)
    return cut


def cut_shortfall(
    part: Any, cut: Any, radius: float, *, chord: float | None = None
) -> float | None:
    """The chord error of ``cut`` in % of ``radius`` when the triangle budget made it coarser
    than :func:`cutting_part` asks for, else None.

    Parameters
    ----------
    part : conformal.Part
        The part as loaded.
    cut : conformal.Part
        What :func:`cutting_part` returned for it.
    radius : float
    chord : float, optional
        The chord error :func:`cutting_part` was asked for, if not the radius's.

    Returns
    -------
    float or None
    """
    if (
        getattr(part, "shape", None) is None
        or not radius > 0
        or bool(getattr(cut, "rebuilt", None))
    ):
        return None
    want = _wanted(part, radius, chord)
    if cut.deflection <= want * (1 + 1e-9):
        return None
    return 100.0 * float(cut.deflection) / float(radius)


def _tolerance(radius: float, extent: float) -> float:
    # float32 output moves a coordinate by up to half a unit in the last place
    rounding = float(np.spacing(np.float32(max(extent, 1.0)))) * 2.0
    return max(config.TRIM_RTOL * radius, rounding)


#: A direction parallel to no face a CAD user draws (unit vector), for ``shift``.
_S = np.array([0.5317, -0.3183, 0.7854])
SHIFT_DIRECTION = _S / np.linalg.norm(_S)


#: Clearance from the part's surface of the struts :func:`trim_to_part` leaves out of its
#: boolean (``graph=``), in strut radii (at least ``NEAR_MARGIN_ULPS`` float32 steps).
NEAR_MARGIN_RTOL = 0.02
NEAR_MARGIN_ULPS = 16


def trim_to_part(
    lattice: Any,
    part: Any,
    *,
    radius: float,
    check: bool = True,
    shift: float = 0.0,
    graph: Any = None,
) -> TrimResult:
    """Intersect a stitched lattice with its part.

    Parameters
    ----------
    lattice : Mesh, Manifold or mesh-like
        The stitched lattice (closed, 2-manifold).
    part : conformal.Part
    radius : float
        The largest strut radius (mm): the tolerance is stated relative to it.
    shift : float
        Cut with the part moved by this fraction of the tolerance in a fixed generic
        direction (0: exactly at the surface). A retry when the exact cut leaves slivers
        that do not survive float32 (surfaces of struts that lie in the part's surface);
        the protrusion stays below ``shift`` times the tolerance.
    check : bool
        Check the result in full (``conformal.skin.checked``: a ``SkinError`` names where
        it fails). ``Lattice`` passes False: it checks after rounding to float32.
    graph : LatticeGraph, optional
        The graph ``lattice`` was stitched from (``fast_stitch.stitch``), with
        ``check=False`` and no ``shift``: the boolean then runs on the struts near the
        part's surface only (``conformal.skin_split.split_lattice`` against the part, with
        a clearance of ``NEAR_MARGIN_RTOL`` r); the struts deep inside are left out and
        ``TrimResult.split.glue`` puts them back after the caller's float32 check, and
        those clear outside the part are dropped. Falls back to the whole lattice when the
        split does not apply (too little deep, not the stitcher's mesh, a cap not kept).

    Returns
    -------
    TrimResult
        The lattice unchanged (as a Manifold) when no vertex lies outside the part and
        nothing is cut; otherwise the intersection, in each solid of the part its largest
        piece.
    """
    from conformal.skin import as_manifold, part_solid, to_arrays

    t0 = time.perf_counter()
    extent = float(np.abs(part.bounds).max()) if len(part.vertices) else 1.0
    tol = _tolerance(radius, extent)
    if graph is not None and not check and not shift:
        near = _trim_near(lattice, part, graph, radius=radius, tol=tol, extent=extent, t0=t0)
        if near is not None:
            return near
    lat = as_manifold(lattice, name="the lattice mesh")
    v0, f0 = to_arrays(lat)
    before = protrusion(part, v0)
    shape = part_solid(part)
    if shift:
        shape = shape.translate(tuple(float(c) for c in SHIFT_DIRECTION * (shift * tol)))
    outside = lat - shape
    if outside.is_empty():
        return _untouched(lat, v0, f0, tol=tol, before=before, t0=t0)
    cut = lat ^ shape
    pieces = cut.decompose()
    removed = 0
    if len(pieces) > 1:
        vols = np.array([p.volume() for p in pieces])
        keep = _largest_per_solid(part, vols, [to_arrays(p)[0][:64] for p in pieces], radius=radius)
        removed = len(pieces) - len(keep)
        if removed:
            import manifold3d

            cut = manifold3d.Manifold.compose([pieces[i] for i in sorted(keep)])
            pieces = [pieces[i] for i in sorted(keep)]
    if check:
        from conformal.skin import checked

        cut = checked(cut, "the trimmed lattice")
    v1, _ = to_arrays(cut)
    whole = float(lat.volume())
    report = TrimReport(
        trimmed=True,
        protrusion_before=before,
        protrusion_after=protrusion(part, v1),
        tolerance=tol,
        volume_removed=whole - float(cut.volume()),
        volume_before=whole,
        bodies=len(pieces),
        pieces_removed=removed,
        seconds=time.perf_counter() - t0,
    )
    return TrimResult(solid=cut, report=report)


#: :func:`clear_inside`: the part's own tessellation stands off the exact surface by about
#: its measured chord error (an upper bound at triangle centroids and edge midpoints) plus
#: the B-rep's tolerance; a lattice clear inside it by this many times that lies inside the
#: exact solid.
CLEAR_CHORD_FACTOR = 2.0
#: :func:`clear_inside` tessellates the part again to prove a clearance the part's own
#: tessellation cannot, when that tessellation's chord error is at least this many times
#: the cutting one's (:func:`cutting_part`): else it would cost about as much.
CLEAR_FINER_RATIO = 4.0


def clear_inside(lattice: Any, part: Any, graph: Any, *, radius: float) -> TrimResult | None:
    """The lattice reported untrimmed, without the finer cutting tessellation, when it lies
    clear inside the part's own tessellation; else None (then :func:`cutting_part` and
    :func:`trim_to_part` decide).

    :func:`cutting_part` tessellates a B-rep part again for the strut radius, which on
    threads and small fillets takes minutes (the M6 screw: 77 s); a lattice filled with
    whole cells inside the part (``fill="inside"``) is then usually found not to touch the
    surface at all. Here the stitched lattice is split (``conformal.skin_split``) against
    the part's own tessellation, with the trim's clearance widened by
    ``CLEAR_CHORD_FACTOR`` times the larger of that tessellation's measured chord error
    (``Part.chord_bound``, measured when it was loaded) and its deflection, plus the
    B-rep's largest tolerance: when every element is deep, every point of the lattice is
    inside the exact solid by more than the trim's clearance. When some elements come
    closer than that, but no nearer than allows a tessellation at least
    ``CLEAR_FINER_RATIO`` times coarser than the cutting one, the part is tessellated
    again (checked against its exact surface) just finely enough, and the proof is made
    on that (the cycloidal gear's inside fill). Nodes on or near the surface (clip, conform
    and tet fills) end the test before the split.

    Parameters
    ----------
    lattice : Mesh
        The lattice as :func:`fast_stitch.stitch` made ``graph`` into.
    part : conformal.Part
        A B-rep part as loaded (with its ``chord_bound``); other parts give None.
    graph : LatticeGraph
    radius : float
        The largest strut radius (mm).

    Returns
    -------
    TrimResult or None
        ``report.trimmed`` is False and ``report.clearance`` the clearance proven (mm).
    """
    from conformal.skin_split import split_lattice
    from lattice_cad.core.errors import PartError
    from lattice_cad.core.mesh import mesh_arrays
    from lattice_cad.occ_impl.shapes import max_tolerance

    t0 = time.perf_counter()
    bound = getattr(part, "chord_bound", None)
    if getattr(part, "shape", None) is None or bound is None:
        return None
    arrays = mesh_arrays(lattice)
    if arrays is None or graph.num_edges == 0:
        return None
    v, f = arrays
    extent = float(np.abs(part.bounds).max()) if len(part.vertices) else 1.0
    ulp = float(np.spacing(np.float32(max(extent, 1.0))))
    # how far the tessellation may stand off the exact surface, and the clearance from it
    # that proves the trim's clearance from the exact surface (with a factor of safety)
    tol_b = max(max_tolerance(s) for s in part.shape)
    dev = max(float(part.deflection), float(bound)) + tol_b
    near = max(NEAR_MARGIN_RTOL * float(radius), NEAR_MARGIN_ULPS * ulp)
    nodes = graph.nodes[graph.degree > 0]  # (a node without struts has no mesh)
    if not bool(np.all(part.contains(nodes))):
        return None
    if float(part.distance(nodes, max_distance=2.0 * near).min()) <= near:
        return None  # nodes on the surface (clip, conform and tet fills)
    margin = near + CLEAR_CHORD_FACTOR * dev
    split = split_lattice(graph, v, f, part, margin=margin)
    if split is None or split.counts["wall"]:
        return None
    if split.counts["deep"] != len(f):
        # near the surface, inside it: a tessellation fine enough to prove the clearance,
        # if it is much coarser than the cutting one
        # (the vertices' clearance from this tessellation: from the exact surface it may be
        # up to ``dev`` less, or more; the finer tessellation is a try, proven or not)
        c = float(part.distance(split.near_vertices, max_distance=margin).min())
        finer = 0.5 * (c - near - CLEAR_CHORD_FACTOR * tol_b) / (1 + CLEAR_CHORD_FACTOR)
        if not finer >= CLEAR_FINER_RATIO * _wanted(part, radius, None):
            return None
        try:
            medium = part.refined(finer, angular=config.CUT_ANGULAR_DEFLECTION, checked=True)
        except PartError:
            return None
        dev = max(finer, float(medium.chord_error or 0.0)) + tol_b
        margin = near + CLEAR_CHORD_FACTOR * dev
        split = split_lattice(graph, v, f, medium, margin=margin)
        if split is None or split.counts["deep"] != len(f):
            return None
    result = _untouched(lattice, v, f, tol=_tolerance(radius, extent), before=0.0, t0=t0)
    return TrimResult(solid=result.solid, report=replace(result.report, clearance=margin - dev))


#: A piece of the cut lattice kept as a solid's largest must hold at least a strut stub as
#: long as it is thick, ``2 pi r^3`` times this; a smaller one (a 0.2 mm fragment of a strut,
#: 0.0003 mm^3, in a 0.8 mm blob a scan left beside its body, made outside shared/data) is
#: removed as a loose piece, unless it is the largest piece of all.
MIN_PIECE_STUBS = 1.0


def _largest_per_solid(
    part: Any,
    vols: NDArray[np.float64],
    samples: list[NDArray[np.float64]],
    *,
    radius: float = 0.0,
) -> list[int]:
    """The bodies kept: in each solid of the part its largest, by ``vols`` (B,) float64; a
    body's solid is the one most of its ``samples[i]`` (K, 3) float64 vertices lie in. A
    solid's largest under ``MIN_PIECE_STUBS`` strut stubs of ``radius`` is not kept (the
    largest of all always is)."""
    from conformal.voxel import _solid_shells, shell_owner

    owner = np.zeros(len(vols), dtype=np.int64)
    shells = _solid_shells(part)
    if len(shells) > 1:
        for i, pts in enumerate(samples):
            votes = shell_owner(shells, pts)
            owner[i] = int(np.argmax(np.bincount(votes, minlength=len(shells))))
    keep = []
    least = MIN_PIECE_STUBS * 2.0 * np.pi * float(radius) ** 3
    biggest = int(np.argmax(vols))
    for o in np.unique(owner):
        mine = np.flatnonzero(owner == o)
        best = int(mine[np.argmax(vols[mine])])
        if best == biggest or vols[best] >= least:
            keep.append(best)
    return sorted(keep)


def _untouched(
    lattice: Any,
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    *,
    tol: float,
    before: float,
    t0: float,
) -> TrimResult:
    """The lattice as given (its arrays ``v`` (V, 3) float64, ``f`` (F, 3) int64, one vertex
    per position in each body, as manifold3d's and the stitcher's), reported not cut."""
    from conformal.skin_split import pieces

    report = TrimReport(
        trimmed=False,
        protrusion_before=before,
        protrusion_after=before,
        tolerance=tol,
        volume_removed=0.0,
        bodies=pieces(v, f)[0],
        pieces_removed=0,
        seconds=time.perf_counter() - t0,
    )
    return TrimResult(solid=lattice, report=report)


def _trim_near(
    lattice: Any, part: Any, graph: Any, *, radius: float, tol: float, extent: float, t0: float
) -> TrimResult | None:
    """:func:`trim_to_part` on the struts near the part's surface only, or None when the
    split does not apply (see ``trim_to_part(graph=)``)."""
    from conformal.skin import _manifold, part_solid, to_arrays
    from conformal.skin_split import first_vertices, kept_pieces, split_lattice
    from lattice_cad.core.mesh import Mesh, mesh_arrays, signed_volume

    arrays = mesh_arrays(lattice)
    if arrays is None:
        return None
    v, f = arrays
    ulp = float(np.spacing(np.float32(max(extent, 1.0))))
    margin = max(NEAR_MARGIN_RTOL * float(radius), NEAR_MARGIN_ULPS * ulp)
    split = split_lattice(graph, v, f, part, margin=margin)
    if split is None:
        return None
    if split.counts["near"] == 0:  # all of it clear inside the part
        return _untouched(lattice, v, f, tol=tol, before=0.0, t0=t0)
    # the deep vertices lie inside the part, clear of it: the protrusion is the others'
    outer = np.ones(len(v), dtype=bool)
    outer[split.deep_index] = False
    before = protrusion(part, v[outer])
    near = _manifold(split.near_vertices, split.near_faces, "the lattice near the part")
    shape = part_solid(part)
    if split.counts["wall"] == 0 and before == 0.0 and (near - shape).is_empty():
        # nothing outside the part: the lattice as given, no boolean on all of it
        return _untouched(lattice, v, f, tol=tol, before=before, t0=t0)
    cut = near ^ shape
    vc, fc = to_arrays(cut)
    joined = split._joined(vc, fc)
    if joined is None:
        return None  # a cap was cut: the boolean on the whole lattice
    n_pieces, vlabel, vols, group, n_groups = joined
    deep_vols = split.deep_volumes()
    weights = np.concatenate([vols, deep_vols])
    gvol = np.bincount(group, weights, minlength=n_groups).astype(np.float64)
    removed = 0
    if n_groups > 1:
        # a group's solid from the vertices of its first piece of the cut
        first = np.full(n_groups, -1, dtype=np.int64)
        first[group[:n_pieces][::-1]] = np.arange(n_pieces)[::-1]
        if np.any(first < 0):
            return None  # a deep piece joins no piece of the cut (cannot be: caps found)
        some = first_vertices(vlabel, n_pieces, 64)
        samples = [vc[some[k]] for k in first]
        keep = _largest_per_solid(part, gvol, samples, radius=radius)
        removed = n_groups - len(keep)
        if removed:
            kept = np.zeros(n_groups, dtype=bool)
            kept[keep] = True
            vc, fc = kept_pieces(vc, fc, kept[group[vlabel[fc[:, 0]]]])
            split = split.without(np.flatnonzero(~kept[group[n_pieces:]]))
            gvol = gvol[kept]
            cut = Mesh(vertices=vc, faces=fc)
    total = signed_volume(v.astype(np.float32).astype(np.float64), f)  # as manifold3d has it
    report = TrimReport(
        trimmed=True,
        protrusion_before=before,
        protrusion_after=protrusion(part, vc),
        tolerance=tol,
        volume_removed=float(total - gvol.sum()),
        volume_before=float(total),
        bodies=n_groups - removed,
        pieces_removed=removed,
        seconds=time.perf_counter() - t0,
    )
    return TrimResult(solid=cut, report=report, split=split)
