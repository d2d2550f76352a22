"""The exact lattice as a B-rep solid: for STEP files, CadQuery and build123d.

One path serves ``Lattice.save("x.step")``, ``Lattice.to_workplane()`` and
``Lattice.to_part()``:

1. :func:`estimate` says, before any OCCT work, how long the B-rep will take and how
   large its STEP file will be (rates measured on the development machine, see
   ``config.BREP_*``), and :func:`check_size` refuses a lattice with more than
   ``max_struts`` struts with that estimate and the alternatives;
2. the distinct hubs are built (``reference_boolean.hub_solids``: the reference's design,
   flat at leaves; nodes whose hubs would overlap, as clipped and conforming fills have at
   the boundary, fused into one solid per cluster), then sewn into one solid per
   connected body;
3. with a B-rep part, the lattice is intersected with it (``trim``), so the STEP part
   keeps the part's size, as the printable mesh does; a mesh part cannot trim it (the
   STEP then holds the untrimmed exact lattice, with a warning);
4. the result is checked with BRepCheck and written atomically.

A skinned lattice is refused for STEP (the skin is never dropped silently).
"""

from __future__ import annotations

import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lattice_cad.core import config
from lattice_cad.core.errors import ExportError, LatticeWarning, OCCTFailure
from lattice_cad.core.graph import LatticeGraph

__all__ = ["BrepEstimate", "BrepReport", "estimate", "check_size", "build", "save_step"]


@dataclass(frozen=True)
class BrepEstimate:
    """What building the B-rep of a lattice will cost (before building it).

    Attributes
    ----------
    struts, hubs : int
        Struts, and distinct hubs (equal up to translation) to build.
    clean : bool
        Hubs meet only on their midpoint discs: sewn (fast); else fused (slow).
    trim : bool
        Intersected with the part.
    seconds : float
        Estimated wall time on a machine like the development one (2 cores).
    bytes : int
        Estimated STEP file size.
    """

    struts: int
    hubs: int
    clean: bool
    trim: bool
    seconds: float
    bytes: int

    def __str__(self) -> str:
        how = "sewn" if self.clean else "sewn (overlapping hubs fused in clusters)"
        return (
            f"{self.struts:,} struts, {self.hubs:,} distinct hubs, {how}"
            + (", trimmed to the part" if self.trim else "")
            + f": about {_duration(self.seconds)} and {self.bytes / 1e6:.0f} MB of STEP"
        )


@dataclass
class BrepReport:
    """What :func:`build` did.

    Attributes
    ----------
    estimate : BrepEstimate
    solids : int
        Solids of the result (one per connected body).
    bodies : int
        Connected bodies of the lattice graph (before trimming).
    volume : float
        Exact volume of the result (mm^3, GProp).
    valid : bool
        BRepCheck verdict (always True: an invalid result raises).
    seconds : dict[str, float]
        ``"hubs"``, ``"union"``, ``"trim"``, ``"check"`` (and ``"write"`` when saved).
    """

    estimate: BrepEstimate
    solids: int = 0
    bodies: int = 0
    volume: float = float("nan")
    valid: bool = False
    seconds: dict[str, float] = field(default_factory=dict)


def _duration(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min"


def _bodies(graph: LatticeGraph) -> int:
    """Connected components of the graph's nodes that have struts."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = graph.num_nodes
    e = graph.edges
    adj = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, label = connected_components(adj, directed=False)
    return int(len(np.unique(label[graph.degree > 0])))


def _trims(part: Any) -> bool:
    return part is not None and getattr(part, "shape", None) is not None


def estimate(
    graph: LatticeGraph, *, trim: bool = False, workers: int | None = None
) -> BrepEstimate:
    """Estimate the time and STEP size of the lattice's B-rep (cheap: numpy only).

    Parameters
    ----------
    graph : LatticeGraph
    trim : bool
        Whether the result will be intersected with the part.
    workers : int, optional
        Processes building hubs (default ``min(2, cpu_count)``).

    Returns
    -------
    BrepEstimate
    """
    from reference_boolean import find_overlaps
    from reference_boolean.reference import _hub_specs

    specs, _, _, _ = _hub_specs(graph, True)
    clean = not find_overlaps(graph)
    w = max(1, workers if workers is not None else min(2, os.cpu_count() or 1))
    stumps = sum(len(s.vecs) for s in specs)
    m = graph.num_edges
    per_strut = config.BREP_SEW_SECONDS if clean else config.BREP_FUSE_SECONDS
    seconds = (
        config.BREP_START_SECONDS
        + config.BREP_HUB_SECONDS * stumps / w
        + (per_strut + config.BREP_WRITE_SECONDS) * m
        + (config.BREP_TRIM_SECONDS * m if trim else 0.0)
    )
    return BrepEstimate(
        struts=m,
        hubs=len(specs),
        clean=clean,
        trim=trim,
        seconds=float(seconds),
        bytes=int(config.BREP_STEP_BYTES * m),
    )


def check_size(
    graph: LatticeGraph,
    max_struts: int | None,
    *,
    what: str,
    trim: bool = False,
    option: str = "max_struts=",
) -> BrepEstimate:
    """Refuse, before any OCCT work, a lattice too large for a B-rep in reasonable time.

    Parameters
    ----------
    graph : LatticeGraph
    max_struts : int or None
        Largest strut count accepted (None: ``config.MAX_BREP_STRUTS``).
    what : str
        What is being built, for the message (e.g. ``"x.step"``).
    trim : bool
        Whether the part trims the lattice (counted in the estimate).
    option : str
        How the caller raises the limit (``"max_struts="`` or a CLI flag).

    Returns
    -------
    BrepEstimate

    Raises
    ------
    ExportError
        More than ``max_struts`` struts; the message gives the estimate and the
        alternatives.
    """
    limit = config.MAX_BREP_STRUTS if max_struts is None else max_struts
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise ValueError(f"max_struts must be a positive integer, got {max_struts!r}")
    est = estimate(graph, trim=trim)
    if graph.num_edges > limit:
        raise ExportError(
            f"{what}: the lattice is too large for an exact B-rep (B-rep solids are built for "
            f"at most {limit:,} struts): "
            f"{est}. Write a mesh instead (.stl or .3mf, seconds), or raise the limit "
            f"({option}{graph.num_edges}) to build it anyway"
        )
    return est


def build(
    lattice: Any,
    *,
    max_struts: int | None = None,
    trim: bool | None = None,
    what: str = "the B-rep",
    option: str = "max_struts=",
    progress: Any = None,
) -> tuple[Any, BrepReport]:
    """The lattice's exact B-rep: one solid per connected body, BRepCheck-valid.

    Parameters
    ----------
    lattice : Lattice
    max_struts : int, optional
        See :func:`check_size`.
    trim : bool, optional
        Intersect with the part (default: when the part is a B-rep).
    what, option : str
        For messages (the file being written, how to raise the limit).
    progress : callable, optional
        ``progress(stage, done, total)`` while the hubs are built.

    Returns
    -------
    shape : TopoDS_Shape
        A solid, or a compound of solids.
    report : BrepReport

    Raises
    ------
    ExportError
        Too large (see :func:`check_size`), or a skin that a STEP cannot hold yet.
    OCCTFailure
        An OCCT step failed (the message names it; OCCT's own exceptions are wrapped).
    """
    graph = lattice.graph
    if lattice.skin is not None:
        raise ExportError(
            f"{what}: a B-rep with the skin is not supported: the skin is a mesh boolean "
            "(write .stl or .3mf for the skinned part), or save the lattice alone with "
            "Lattice(lat.graph, part=lat.part).save(...)"
        )
    can_trim = _trims(lattice.part)
    if trim is None:
        trim = can_trim
    elif trim and not can_trim:
        raise ExportError(f"{what}: trimming needs a B-rep part (STEP or CAD shape), not a mesh")
    est = check_size(graph, max_struts, what=what, trim=trim, option=option)
    if lattice.part is not None and not can_trim:
        warnings.warn(
            f"{what}: the part is a mesh, so the exact lattice is not trimmed to it: struts "
            "that reach the boundary stick out by up to their radius",
            LatticeWarning,
            stacklevel=3,
        )
    from lattice_cad.occ_impl import lattice_brep as lb
    from lattice_cad.occ_impl.shapes import volume
    from reference_boolean import hub_solids

    rep = BrepReport(estimate=est, bodies=_bodies(graph))
    t0 = time.perf_counter()
    hs = hub_solids(graph, progress=progress)
    t1 = time.perf_counter()
    # hubs, clusters of overlapping hubs and leaves meet only on midpoint discs: sewn
    tol = config.BREP_SEW_RTOL * float(graph.radii.min())
    shapes = lb.sew_hubs(
        hs.breps,
        hs.instance_template,
        graph.nodes[hs.anchors],
        hs.mid_vectors,
        axes=hs.axes,
        tolerance=tol,
        failed=hs.failed,
    )
    t2 = time.perf_counter()
    if not trim and len(shapes) > rep.bodies:
        raise OCCTFailure(
            f"{what}: the union has {len(shapes)} solids for {rep.bodies} connected "
            "bodies of the lattice"
        )
    if trim:
        shapes = lb.trim(shapes, lattice.part.shape)
    t3 = time.perf_counter()
    shape = lb.as_one(shapes, what)
    rep.solids = len(shapes)
    rep.valid = True
    rep.volume = float(sum(volume(s) for s in shapes))
    t4 = time.perf_counter()
    rep.seconds = {"hubs": t1 - t0, "union": t2 - t1, "trim": t3 - t2, "check": t4 - t3}
    if not (rep.volume > 0 and math.isfinite(rep.volume)):
        raise OCCTFailure(f"{what}: the B-rep's volume is {rep.volume!r}")
    return shape, rep


def save_step(
    lattice: Any,
    path: str | os.PathLike[str],
    *,
    max_struts: int | None = None,
    trim: bool | None = None,
    option: str = "max_struts=",
    progress: Any = None,
) -> tuple[Path, BrepReport]:
    """Write the lattice's exact B-rep to a STEP file (atomically); see :func:`build`.

    Returns
    -------
    path : Path
    report : BrepReport
    """
    from lattice_cad.occ_impl.step import write_step

    p = Path(path)
    if not p.parent.is_dir():
        raise FileNotFoundError(f"cannot write {p}: directory {p.parent} does not exist")
    shape, rep = build(
        lattice, max_struts=max_struts, trim=trim, what=str(p), option=option, progress=progress
    )
    t0 = time.perf_counter()
    write_step(shape, p)
    rep.seconds["write"] = time.perf_counter() - t0
    return p, rep
