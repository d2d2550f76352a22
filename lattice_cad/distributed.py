"""Sharded fill and stitch on Dask distributed: bounded memory per worker, identical output.

The part's grid of cells is cut into blocks of whole cells (one *shard* each). Every task
loads the part itself from its path, classifies and tiles its block with a halo of
``halo`` cells on every side (:func:`conformal.inside_cells`, :func:`conformal.tile_arrays`),
stitches that graph with :func:`fast_stitch.stitch` and writes the triangles it *owns*
as binary STL records to a piece file; the client streams the pieces into one STL.

Why the pieces fit together exactly
-----------------------------------
- **Global ids without a numbering pass.** A node's id is its global integer lattice
  coordinate (``conformal.tile_arrays``' ``node_ijk``) packed into an int64; its position
  is ``origin + node_ijk / denominator * cell_size`` in every shard, bit for bit, and
  cells are classified with the whole grid's arithmetic (``Part.grid_contains(offset=)``).
- **Ownership.** A node belongs to the shard whose block holds its cell
  (``node_ijk // denominator``, clipped to the grid); a strut belongs to the owner of its
  end with the lower global id (its first end: edges are sorted by global coordinates).
  Each shard writes the hubs (or caps) of its nodes and the cylinders of its struts, so
  every triangle is written exactly once and nothing is deduplicated.
- **Identical seams.** The stitcher derives a strut's frame and phase from its quantised
  direction and ``seed`` (not from its index) and a node's hub only from the struts at
  that node (hubs are shared between nodes only when their inputs are bit-identical), so a
  profile shared by two shards has the same vertices in both. A shard's hubs are correct
  when the shard graph has *all* struts at its own nodes and at their neighbours (two
  cells of halo give that for every cell whose struts stay in the cell: all built-in
  cells). With ``profile="volume"`` (the default) each hub is also scaled by ``s_n``,
  which depends on the offsets at the far ends of its node's struts: the stars must be
  complete one strut further (``stitch_sharded`` routes struts within twice the longest
  strut of a block), and ``s_n`` is iterated per node
  (:func:`fast_stitch.hubvolume.hub_scales`). A shard that finds one of those nodes on
  the halo's edge raises :class:`ShardHaloError`.
- **Iterations that reach across shards, run round by round.** The radius fit
  (:func:`conformal.radius.fit_radii`: struts at crowded nodes and struts or joints that
  come too close are thinned, repeatedly) and the capping of hub growth
  (:func:`fast_stitch.stitch.cap_growth`) are loops whose rounds are local (a strut's or
  hub's next value depends only on the elements within a bounded distance, :func:`_reach`)
  but whose decisions are global (which kind of round, when to stop). :func:`fill_sharded`
  runs them as one task per shard and round: each shard computes the next values of what
  it owns from the current values of everything within reach, exchanged through files of
  the owners; the client takes each decision from the flags of all shards. Every round is
  thus the one-process round, value for value; each shard checks that everything within
  reach of its owned elements has the whole lattice's star (else
  :class:`ShardHaloError`). Capping runs only when a grown hub is hit somewhere; then the
  shards whose owned triangles use a scale that differs from their first stitch's are
  stitched again with the capped scales (``fast_stitch.stitch``'s ``scale_override``).
  :func:`stitch_sharded` does not run these rounds: a capped hub within reach of a block
  raises :class:`ShardingError` there (use ``profile="area"``).
- **Global clean-up, done exactly.** Dangling struts are pruned in each shard twice (halo
  edge kept / halo edge pruned); the true result lies between, so equal answers near the
  block prove it exact (else :class:`ShardingError`). The largest connected piece (per
  solid of the part) is found by a union-find over the shards' component labels, joined
  by the global ids of the nodes two shards share.
- **Clip and conform.** The cut cells are tiled too; conform moves outer nodes onto the
  surface, clip adds a node where a strut crosses it, named by the strut's first end,
  direction and crossing number (ids beyond every lattice id, in the one-process order)
  and owned with its strut. Surface nodes closer than ``min_strut`` cells are merged in
  ascending pair order (``conformal.voxel.merge_close``), so a cluster merges the same
  way in any block that holds all of it; a shard whose needed clusters come within a
  strut length plus ``min_strut`` of its region's cut faces raises
  :class:`ShardingError` (the default halo is 3 cells for these fills). Pieces are
  joined over the struts a shard knows exactly (kept by the lower pruning bound, clear of
  unsure merges), and pieces without an interior node (fragments) are dropped globally.

Supported sharded: ``fill="inside"`` (also ``"auto"`` when a whole cell fits), ``"clip"``
and ``"conform"`` of any
built-in or user cell without rotation, a scalar or callable radius (a picklable
function of the (M, 3) strut midpoints), ``fit="shrink"`` (run sharded, as above) and
``fit="off"``; written as binary STL (up to 2^32 triangles) or 3MF: one merged
mesh up to :data:`MAX_3MF_TRIANGLES`, beyond (or with ``threemf="shards"``) one object
per shard in its own model part (Production extension, :mod:`lattice_cad.io.sharded_3mf`),
also with beams (``beam_lattice=True``). Refused with :class:`ShardingError`:
``rotation``, skins, keep zones, trimming to the part (the output is the stitched
lattice, ``Lattice.mesh(lattice_only=True)``) and ``method="lslt"``.

:func:`stitch_sharded` does the same for a user graph held as NPZ shards
(:func:`write_graph_shards`): struts are routed to spatial blocks (those with an end
within the longest strut of the block), and each block stitches and writes what it owns.

Files must be on a file system that the client and all workers share (``tmpdir``); the
output is written atomically (a temp file renamed into place once complete): it is
complete or absent, and a rerun gives the same bytes.
"""

from __future__ import annotations

import contextlib
import os
import resource
import shutil
import tempfile
import time
import uuid
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, cast

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.atomic import atomic_write, check_target
from lattice_cad.core.errors import (
    DistributedUnavailableError,
    InputFileError,
    LatticeWarning,
    ShardHaloError,
    ShardingError,
)

if TYPE_CHECKING:
    from fast_stitch.hubvolume import Profile

__all__ = [
    "fill_sharded",
    "stitch_sharded",
    "write_graph_shards",
    "ShardedResult",
    "ShardStats",
    "MAX_3MF_TRIANGLES",
    "INSTALL_HINT",
]

INSTALL_HINT = "pip install 'lattice-cad[distributed]'"
#: Largest sharded 3MF written as one merged mesh object (welded in the client); beyond,
#: ``threemf="auto"`` writes one object per shard (``lattice_cad.io.sharded_3mf``).
MAX_3MF_TRIANGLES = 20_000_000
_HEADER = b"lattice-cad sharded binary STL"
_REC = np.dtype([("n", "<f4", 3), ("v", "<f4", 9), ("attr", "<u2")])


def _require_dask() -> Any:
    """The ``distributed`` module, or :class:`DistributedUnavailableError`."""
    try:
        import dask  # noqa: F401
        import distributed
    except ImportError as exc:
        raise DistributedUnavailableError(
            f"the sharded path (--shards, lattice_cad.distributed) needs Dask distributed, "
            f"which is not installed ({exc}): {INSTALL_HINT}"
        ) from None
    return distributed


# ===================================================================== results
@dataclass(frozen=True)
class ShardStats:
    """What one shard did (returned by its stitch task).

    ``struts`` counts the struts of its graph (halo included), ``owned_struts`` those it
    wrote; ``peak_rss`` is the worker process's peak resident memory (bytes) during this
    task (the peak is reset when the task starts where Linux allows it, see
    :func:`_reset_peak`; else the process's lifetime peak).
    """

    shard: int
    owned_struts: int
    struts: int
    triangles: int
    seconds: float
    cpu_seconds: float
    peak_rss: int
    worker: str
    thinned: int = 0
    min_radius: float = float("inf")
    hit0: bool = False
    capped: bool = False


@dataclass
class ShardedResult:
    """The outcome of :func:`fill_sharded` / :func:`stitch_sharded`.

    Attributes
    ----------
    path : Path
        The written file.
    struts, triangles : int
        Totals of the written lattice.
    shards : list of ShardStats
        Shards that wrote something, in shard order.
    seconds : dict
        Wall time of each phase (``build``, ``stitch``, ``assemble``, ``total``).
    removed_dangling, removed_islands : int
        Clean-up counts (as ``conformal.BuildReport``).
    """

    path: Path
    struts: int
    triangles: int
    shards: list[ShardStats] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    removed_dangling: int = 0
    removed_islands: int = 0
    removed_fragments: int = 0
    build_rss: dict[str, int] = field(default_factory=dict)
    radii_reduced: int = 0

    @property
    def peak_rss_per_worker(self) -> dict[str, int]:
        """Peak resident memory (bytes) of each worker in the stitch phase (stitch one
        shard, write its piece; the 3MF parts too when written in shards)."""
        out: dict[str, int] = {}
        for s in self.shards:
            out[s.worker] = max(out.get(s.worker, 0), s.peak_rss)
        return out

    @property
    def build_peak_rss_per_worker(self) -> dict[str, int]:
        """Peak resident memory (bytes) of each worker in the build phase
        (:func:`fill_sharded`; classify, tile, prune one block)."""
        return dict(self.build_rss)

    @property
    def halo_overhead(self) -> float:
        """Struts stitched but not owned, as a fraction of the owned struts."""
        owned = sum(s.owned_struts for s in self.shards)
        return sum(s.struts for s in self.shards) / max(owned, 1) - 1.0

    def summary(self) -> str:
        """Human-readable totals, per-worker peak memory and halo overhead."""
        lines = [
            f"{self.path}: {self.struts:,} struts, {self.triangles:,} triangles in "
            f"{len(self.shards)} shard(s); halo overhead {100 * self.halo_overhead:.1f} %",
            "  " + ", ".join(f"{k} {v:.2f} s" for k, v in self.seconds.items()),
        ]
        build = self.build_rss
        for w, rss in sorted(self.peak_rss_per_worker.items()):
            b = f", build {build[w] / 2**20:.0f} MiB" if w in build else ""
            lines.append(f"  worker {w}: peak RSS stitch {rss / 2**20:.0f} MiB{b}")
        return "\n".join(lines)


# ===================================================================== helpers
def _reset_peak() -> bool:
    """Reset this process's peak resident memory (Linux >= 4.0: ``clear_refs`` 5), so
    that :func:`_peak_rss` measures one task (a worker runs one task at a time)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _peak_rss() -> int:
    """Peak resident memory (bytes) since the last :func:`_reset_peak` (VmHWM), or the
    process's lifetime peak (``ru_maxrss``)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return f"{get_worker().address} (pid {os.getpid()})"
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


@contextlib.contextmanager
def _threads(n: int) -> Iterator[None]:
    import numba

    prev = numba.get_num_threads()
    # numba.config sets its (documented) options at import time, unseen by mypy
    limit = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    numba.set_num_threads(max(1, min(int(n), limit)))
    try:
        yield
    finally:
        numba.set_num_threads(prev)


_PARTS: dict[tuple[str, float, str], Any] = {}


def _load(path: str, units: str | float | None) -> Any:
    """The part at ``path``, loaded once per worker process (keyed by path and mtime)."""
    from conformal import load_part

    key = (path, os.path.getmtime(path), repr(units))
    if key not in _PARTS:
        _PARTS.clear()
        _PARTS[key] = load_part(path, units=units)
    return _PARTS[key]


def _split(dims: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """(3,) blocks per axis, product >= n: split the axis with the longest blocks."""
    counts = np.ones(3, dtype=np.int64)
    while int(np.prod(counts)) < n:
        a = int(np.argmax(dims / counts))
        if counts[a] >= dims[a]:
            break
        counts[a] += 1
    return counts


def _pack(ijk: NDArray[np.int64], span: NDArray[np.int64]) -> NDArray[np.int64]:
    """Global node ids from integer lattice coordinates (0 <= ijk < span)."""
    return (ijk[:, 0] * span[1] + ijk[:, 1]) * span[2] + ijk[:, 2]


def _prune(n: int, edges: NDArray[np.int64], protected: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Struts left after repeatedly removing struts at unprotected degree-1 nodes (the
    rule of ``conformal.voxel_lattice``'s clean-up)."""
    alive = np.ones(len(edges), dtype=bool)
    while True:
        deg = np.bincount(edges[alive].ravel(), minlength=n)
        leaf = (deg == 1) & ~protected
        drop = alive & (leaf[edges[:, 0]] | leaf[edges[:, 1]])
        if not drop.any():
            return alive
        alive &= ~drop


def _hops(profile: Profile) -> int:
    """How far (in struts) from an owned node the complete stars must reach.

    A profile's offset at a node depends on all struts at that node; the owned triangles
    (hubs at owned nodes, cylinders of owned struts) use the offsets at the owned nodes
    and at their neighbours: 1. With ``profile="volume"`` they also use each of those
    nodes' hub scale, which depends on the offsets at the far ends of its struts (the
    frustum lengths, :func:`fast_stitch.hubvolume.hub_scales`): 2.
    """
    return 2 if profile == "volume" else 1


def _within(seed: NDArray[np.bool_], edges: NDArray[np.int64], hops: int) -> NDArray[np.bool_]:
    """(N,) bool: the nodes at most ``hops`` struts away from a ``seed`` node."""
    out = seed.copy()
    for _ in range(hops):
        touch = out[edges].any(axis=1)
        out[edges[touch].ravel()] = True
    return out


def _write_piece(path: Path, records: Iterator[NDArray[Any]]) -> None:
    """Write STL records to ``path`` via a temp file and rename (a retried task
    overwrites a half-written piece of a killed attempt)."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.part")
    try:
        with open(tmp, "wb") as fh:
            for rec in records:
                fh.write(rec.tobytes())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _owned_records(
    graph: Any,
    mesh: Any,
    owned_node: NDArray[np.bool_],
    owned_strut: NDArray[np.bool_],
    P: int,
    where: str,
) -> tuple[Iterator[NDArray[Any]], int]:
    """STL records (chunks of the ``_REC`` dtype) of the owned cylinders, hubs and caps."""
    from lattice_cad.core.mesh import stl_records

    m = graph.num_edges
    deg = graph.degree
    counts = np.where(deg >= 2, deg * P + 2 * deg - 4, np.where(deg == 1, P - 2, 0))
    mask = np.concatenate([np.repeat(owned_strut, 2 * P), np.repeat(owned_node, counts)])
    if len(mesh.faces) > len(mask):  # profile="volume": the bands of each strut follow
        mask = np.concatenate([mask, np.repeat(owned_strut, 4 * P)])
    assert len(mask) == len(mesh.faces) and len(mesh.faces) - 2 * m * P >= counts.sum()
    rows = np.flatnonzero(mask)

    def gen() -> Iterator[NDArray[Any]]:
        chunk = 1 << 18
        buf = np.empty((min(len(rows), chunk), 12), dtype=np.float32)
        for lo in range(0, len(rows), chunk):
            part = rows[lo : lo + chunk]
            out = buf[: len(part)]
            bad = stl_records(mesh.vertices, mesh.faces[part], out)
            if bad:
                raise ShardingError(
                    f"{where}: {bad} triangle(s) become flat when rounded to single precision "
                    "(STL); the single-process path repairs them, the sharded one cannot: "
                    "use thicker struts or move the part closer to the origin"
                )
            rec = np.zeros(len(part), dtype=_REC)
            rec["n"] = out[:, :3]
            rec["v"] = out[:, 3:]
            yield rec

    return gen(), len(rows)


def _stitch_owned(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    owned_node: NDArray[np.bool_],
    owned_strut: NDArray[np.bool_],
    *,
    segments: int,
    seed: int,
    profile: Profile,
    piece: Path,
    where: str,
    report: dict[str, Any] | None = None,
) -> int:
    """Stitch one shard's graph and write the triangles it owns; their count.

    Without ``report``, a hub near the owned nodes whose growth the clearance capped
    raises :class:`ShardingError`; with it (:func:`fill_sharded`, which runs the capping
    rounds sharded), the stitch's report is left there (``scale_override`` may be given
    in it)."""
    import fast_stitch
    from lattice_cad.core.graph import LatticeGraph

    graph = LatticeGraph(nodes, edges, radii)
    graph.check_precision("float32")
    refuse = report is None
    report = {} if report is None else report
    mesh = fast_stitch.stitch(
        graph, segments, seed=seed, profile=profile, workers=None, _report=report
    )
    capped = report.get("capped", np.zeros(0, dtype=np.int64))
    # the owned triangles use the hub scales of the owned nodes and their neighbours
    near = _within(owned_node, edges, 1)[capped] if len(capped) else np.zeros(0, dtype=bool)
    if refuse and near.any():
        k = int(capped[near][0])
        raise ShardingError(
            f"{where}: the hub at {nodes[k].tolist()} may not grow to the exact solid's "
            "volume without overlapping a strut (fast_stitch.stitch.cap_growth); that limit "
            "depends on struts beyond the halo: run in one process, or use profile='area'"
        )
    records, n = _owned_records(graph, mesh, owned_node, owned_strut, segments, where)
    _write_piece(piece, records)
    return n


# ================================================================ the fill tasks
@dataclass(frozen=True)
class _FillSpec:
    path: str
    units: str | float | None
    cell: Any
    start: tuple[float, float, float]
    h: tuple[float, float, float]
    dims: tuple[int, int, int]
    counts: tuple[int, int, int]
    size: tuple[int, int, int]
    halo: int
    prune: bool
    hops: int
    tmpdir: str
    threads: int
    beams: bool = False
    fill: str = "inside"
    min_len: float = 0.0


def _block(spec: _FillSpec, shard: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    b = np.array(np.unravel_index(shard, spec.counts), dtype=np.int64)
    size, dims = np.array(spec.size), np.array(spec.dims)
    lo = b * size
    return lo, np.minimum(lo + size, dims)


def _fill_build(spec: _FillSpec, shard: int) -> dict[str, Any] | None:
    """Phase 1 of a shard: classify, tile, prune; save the shard graph; report its
    connected pieces (for the global largest-piece selection)."""
    _reset_peak()
    out = _fill_build_task(spec, shard)
    if out is not None:
        out["peak_rss"] = _peak_rss()
        out["worker"] = _worker_name()
    return out


def _fill_build_task(spec: _FillSpec, shard: int) -> dict[str, Any] | None:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    import conformal

    with _threads(spec.threads):
        part = _load(spec.path, spec.units)
        cell = conformal.CELLS[spec.cell] if isinstance(spec.cell, str) else spec.cell
        den = int(cell.denominator)
        start, h = np.array(spec.start), np.array(spec.h)
        dims = np.array(spec.dims, dtype=np.int64)
        size = np.array(spec.size, dtype=np.int64)
        lo, hi = _block(spec, shard)
        r_lo = np.maximum(lo - spec.halo, 0)
        r_hi = np.minimum(hi + spec.halo, dims)
        boundary = spec.fill in ("clip", "conform")
        inside = conformal.inside_cells(part, start, h, r_lo, r_hi, with_cut=boundary)
        ijk = np.argwhere(inside).astype(np.int64) + r_lo
        where = f"shard {shard} (cells {lo.tolist()}..{(hi - 1).tolist()})"
        if not len(ijk):
            return None
        nodes, edges, nijk = conformal.tile_arrays(cell, ijk, cell_size=h, origin=start)
        n = len(nodes)
        # nodes on a face of the region that the halo cut (the grid's own faces are
        # complete: no cell lies beyond them) may have struts outside the region
        incomplete = np.zeros(n, dtype=bool)
        for a in range(3):
            if r_lo[a] > 0:
                incomplete |= nijk[:, a] == r_lo[a] * den
            if r_hi[a] < dims[a]:
                incomplete |= nijk[:, a] == r_hi[a] * den
        ncell = np.minimum(nijk // den, dims - 1)
        owned = ((ncell // size) == (lo // size)).all(axis=1)
        on_surface = np.zeros(n, dtype=bool)
        bad = None
        span = dims * den + 1
        key = _pack(nijk, span)
        if boundary:
            nodes, edges, on_surface, bad, src, new_key = _boundary_fill(
                part, spec, nodes, edges, nijk, key, start, h, r_lo, r_hi, dims, den
            )
            if len(src):  # clip's crossing nodes: named and owned as their struts
                owned = np.concatenate([owned, owned[src]])
                incomplete = np.concatenate([incomplete, np.zeros(len(src), dtype=bool)])
                nijk = np.concatenate([nijk, nijk[src]])
                key = np.concatenate([key, new_key])
                n = len(nodes)
        if spec.prune:  # surface nodes are never pruned (as in one process)
            alive = _prune(n, edges, incomplete | on_surface)
            lower = _prune(n, edges, on_surface)
        else:
            alive = lower = np.ones(len(edges), dtype=bool)
        # the nodes whose hubs this shard needs: its own, their neighbours (and theirs
        # with profile="volume", see _hops)
        need = _within(owned, edges[alive], spec.hops)
        relevant = need[edges].any(axis=1)
        if incomplete[need].any():
            k = int(np.flatnonzero(need & incomplete)[0])
            raise ShardHaloError(
                f"{where}: node at {nodes[k].tolist()} needs struts beyond the halo of "
                f"{spec.halo} cell(s); use a larger halo"
            )
        if (relevant & (alive != lower)).any():
            raise ShardHaloError(
                f"{where}: pruning dangling struts reaches beyond the halo of {spec.halo} "
                "cell(s); use a larger halo (or prune=False)"
            )
        # struts whose state this shard knows exactly: kept in the lower bound of pruning,
        # and (clip/conform) clear of node merges that may involve nodes beyond the halo
        trusted = lower[alive]
        if bad is not None:
            if (relevant & bad[edges].any(axis=1)).any():
                raise ShardHaloError(
                    f"{where}: merging close surface nodes reaches beyond the halo of "
                    f"{spec.halo} cell(s); use a larger halo"
                )
            trusted &= ~bad[edges[alive]].any(axis=1)
        # nodes whose star (its struts and their far ends) is the whole lattice's: not on
        # a cut face of the region, no strut of unsure pruning, no unsure merge at either
        # end (the distributed radius fit needs them well beyond the owned nodes)
        exact = ~incomplete
        unsure = alive != lower
        if bad is not None:
            exact &= ~bad
            unsure |= bad[edges].any(axis=1)
        exact[edges[unsure].ravel()] = False
        pruned_owned = int((~alive & owned[edges[:, 0]]).sum())
        edges = edges[alive]
        used = np.zeros(n, dtype=bool)
        used[edges.ravel()] = True
        if not owned[edges[:, 0]].any() and not (owned & used).any():
            return {"shard": shard, "empty": True, "pruned": pruned_owned}
        new_id = np.cumsum(used) - 1
        nodes, nijk, owned, on_surface = nodes[used], nijk[used], owned[used], on_surface[used]
        key, exact = key[used], exact[used]
        edges = new_id[edges]
        # connected pieces over the struts known exactly (all of them for "inside");
        # joined across shards by the nodes they share, they give the global pieces
        te = edges[trusted] if boundary else edges
        g = coo_matrix((np.ones(len(te)), (te[:, 0], te[:, 1])), shape=(len(nodes), len(nodes)))
        n_lab, label = connected_components(g, directed=False)
        interior = np.zeros(n_lab, dtype=bool)
        t_used = np.zeros(len(nodes), dtype=bool)
        t_used[te.ravel()] = True
        interior[label[t_used & ~on_surface]] = True
        own_e = owned[edges[:, 0]]
        owned_count = np.bincount(label[edges[own_e, 0]], minlength=n_lab)
        min_key = np.full(n_lab, np.iinfo(np.int64).max, dtype=np.int64)
        np.minimum.at(min_key, label, key)
        first = np.full(n_lab, -1, dtype=np.int64)
        oe = np.flatnonzero(own_e)
        first[label[edges[oe[::-1], 0]]] = oe[::-1]
        rep = np.full((n_lab, 3), np.nan)
        has = first >= 0
        rep[has] = 0.5 * (nodes[edges[first[has], 0]] + nodes[edges[first[has], 1]])
        # nodes another shard may also hold: all that are not ours, and ours near a face
        nc = np.minimum(nijk // den, dims - 1)
        inner = ((nc >= lo + spec.halo + 1) & (nc < hi - spec.halo - 1)).all(axis=1)
        link = ~owned | ~inner
        np.savez(
            Path(spec.tmpdir) / f"graph-{shard}.npz",
            nodes=nodes,
            edges=edges,
            owned=owned,
            label=label,
            key=key,
            exact=exact,
        )
        return {
            "shard": shard,
            "empty": False,
            "pruned": pruned_owned,
            "owned_count": owned_count,
            "min_key": min_key,
            "rep": rep,
            "link_key": key[link],
            "link_label": label[link],
            "interior": interior,
        }


def _boundary_fill(
    part: Any,
    spec: _FillSpec,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    nijk: NDArray[np.int64],
    key: NDArray[np.int64],
    start: NDArray[np.float64],
    h: NDArray[np.float64],
    r_lo: NDArray[np.int64],
    r_hi: NDArray[np.int64],
    dims: NDArray[np.int64],
    den: int,
) -> tuple[
    NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_], NDArray[np.bool_],
    NDArray[np.int64], NDArray[np.int64],
]:  # fmt: skip
    """``fill="clip"`` or ``"conform"`` on a shard's region, as ``conformal.voxel_lattice``
    does it on the whole grid: surface nodes, close-node merges, short struts removed.

    Returns nodes, edges (node ids kept: merged nodes lose their struts; clip's crossing
    nodes appended in the order of their struts, as in one process), ``on_surface``,
    ``bad`` (N,) bool: nodes whose merge cluster may reach a node beyond the region (one
    closer to a cut face of the region than the longest strut plus ``min_len``: a node
    beyond the face moves at most a strut length), and for clip's K crossing nodes the
    lattice node each inherits its owner from (the strut's first end) and its global id
    (beyond every lattice id: the strut's first end, direction and crossing number).
    """
    from conformal.voxel import BuildReport, _clip, _conform, merge_close

    lmax = float(np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1).max())
    src = np.zeros(0, dtype=np.int64)
    new_key = np.zeros(0, dtype=np.int64)
    if spec.fill == "conform":
        nodes, edges, on_surface = _conform(part, nodes, edges, BuildReport())
    elif spec.fill == "clip":
        sources: list[NDArray[np.int64]] = []
        n0 = len(nodes)
        strut_edges = edges
        nodes, edges, on_surface = _clip(part, nodes, edges, BuildReport(), sources=sources)
        if sources:
            strut, j = sources
            a, b = strut_edges[strut, 0], strut_edges[strut, 1]
            src = a
            w = 2 * den + 1
            d = nijk[b] - nijk[a] + den
            d_code = (d[:, 0] * w + d[:, 1]) * w + d[:, 2]
            span = dims * den + 1
            base = int(np.prod(span))
            new_key = base + (key[a] * w**3 + d_code) * 9 + j
        assert len(nodes) == n0 + len(src)
    else:
        raise ShardingError(f"fill={spec.fill!r} is not supported sharded")
    n = len(nodes)
    edges, root = merge_close(nodes, edges, on_surface, spec.min_len)
    length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    edges = edges[length >= spec.min_len]
    margin = lmax + spec.min_len
    near = np.zeros(n, dtype=bool)
    for a in range(3):
        if r_lo[a] > 0:
            near |= nodes[:, a] < start[a] + r_lo[a] * h[a] + margin
        if r_hi[a] < dims[a]:
            near |= nodes[:, a] > start[a] + r_hi[a] * h[a] - margin
    if root is None:
        return nodes, edges, on_surface, near, src, new_key
    bad_root = np.zeros(n, dtype=bool)
    bad_root[root[near]] = True
    return nodes, edges, on_surface, bad_root[root], src, new_key


# ======================================================= the distributed radius fit
def _shard_graph(
    spec: _FillSpec, shard: int, keep_label: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_], NDArray[np.int64],
           NDArray[np.bool_]] | None:  # fmt: skip
    """A shard's graph of phase 1 with the selected pieces only: nodes (N, 3), edges
    (M, 2) (local ids, in global order), owned (N,) bool, key (N,) int64 global ids and
    exact (N,) bool (the star is the whole lattice's); None when it owns nothing."""
    with np.load(Path(spec.tmpdir) / f"graph-{shard}.npz") as data:
        nodes, edges, owned, label = data["nodes"], data["edges"], data["owned"], data["label"]
        key, exact = data["key"], data["exact"]
    edges = edges[keep_label[label[edges[:, 0]]]]
    used = np.zeros(len(nodes), dtype=bool)
    used[edges.ravel()] = True
    if not (owned & used).any():
        return None
    edges = (np.cumsum(used) - 1)[edges]
    return nodes[used], edges, owned[used], key[used], exact[used]


def _strut_ids(
    key: NDArray[np.int64], edges: NDArray[np.int64]
) -> tuple[NDArray[Any], NDArray[np.bool_]]:
    """(M,) 16-byte global strut ids (the two ends' global ids, lower first) and (M,) bool
    ``swap``: the strut's local orientation is the reverse of its id's."""
    a, b = key[edges[:, 0]], key[edges[:, 1]]
    swap = a > b
    pair = np.stack([np.where(swap, b, a), np.where(swap, a, b)], axis=1)
    return np.ascontiguousarray(pair).view(np.dtype((np.void, 16))).ravel(), swap


def _canon(r: NDArray[np.float64], swap: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Per-end radii in the orientation of the strut ids (an involution)."""
    return np.where(swap[:, None], r[:, ::-1], r)


def _neighbour_shards(spec: _FillSpec, shard: int) -> list[int]:
    """The shards whose blocks a shard's region (block and halo) may reach."""
    bi = np.array(np.unravel_index(shard, spec.counts))
    reach = -(-spec.halo // np.array(spec.size))
    out = []
    for s in range(int(np.prod(spec.counts))):
        bj = np.array(np.unravel_index(s, spec.counts))
        if (np.abs(bj - bi) <= reach).all():
            out.append(s)
    return out


def _gather_radii(
    spec: _FillSpec, shard: int, ids: NDArray[Any], swap: NDArray[np.bool_], rnd: int,
    col: str, fallback: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:  # fmt: skip
    """The radii of a shard's struts as their owners computed them in round ``rnd``
    (column ``col``): (M, 2) float64 in local orientation, and (M,) bool found (the others
    keep ``fallback``: struts that no shard owns, outside what this shard must know)."""
    r = _canon(fallback, swap)
    found = np.zeros(len(ids), dtype=bool)
    for s in _neighbour_shards(spec, shard):
        p = Path(spec.tmpdir) / f"fit-{rnd}-{s}.npz"
        if not p.exists():
            continue
        with np.load(p) as d:
            oid = d["ids"].view(np.dtype((np.void, 16))).ravel()
            at = np.searchsorted(oid, ids)
            at[at >= len(oid)] = 0
            hit = oid[at] == ids if len(oid) else np.zeros(len(ids), dtype=bool)
            if hit.any():
                r[hit] = d[col][at[hit]]
                found |= hit
    return _canon(r, swap), found


def _reach(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    owned: NDArray[np.bool_],
    *,
    segments: int,
    profile: Profile,
    pad: float,
    growth: float = 1.0,
    misfit_hops: bool = True,
) -> float:
    """How far from an owned node the nodes whose stars one round of the radius fit
    (:func:`conformal.radius.fit_radii`) or of hub-growth capping
    (:func:`fast_stitch.stitch.cap_growth`) reads for the owned struts and nodes can be.

    The elements read: the struts at the owned nodes and the joints at them and at their
    neighbours (the node factors of the far ends), of actual reach ``E`` (capsule radius,
    or joint ball: the farthest profile vertex, :func:`fast_stitch.fit.end_offsets`, times
    ``growth``); any element sharing no node with them that comes within ``pad * (E + E')``
    of them, whose nodes are then within ``l + pad * (E + B)`` (a joint at such a node, of
    ball ``B <= sqrt(l^2 + R^2)`` once every strut fits) or ``2 l + pad * (E + R)`` (a strut)
    of the owned node; with ``misfit_hops``, the misfits two struts away (``2 l``).
    ``l``: the longest strut, ``R``: the largest profile radius (times ``growth``).
    """
    from fast_stitch.fit import end_offsets
    from fast_stitch.hubvolume import profile_factor

    lmax = float(np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1).max())
    k = profile_factor(segments, profile)
    big_r = float(radii.max()) * k * growth
    ball_bar = float(np.hypot(lmax, big_r))
    off = end_offsets(nodes, edges, radii, segments=segments, profile=profile)
    ball = np.hypot(off, radii * k) * growth  # (M, 2): profile vertex distance per end
    at = _within(owned, edges, 1)  # joints read: at the owned nodes and their neighbours
    e_x = max(float(ball[at[edges]].max(initial=0.0)), big_r)
    reach = max(lmax + pad * (e_x + ball_bar), 2.0 * lmax + pad * (e_x + big_r))
    if misfit_hops:
        reach = max(reach, 2.0 * lmax)
    return reach * (1 + 1e-9)


def _check_reach(
    nodes: NDArray[np.float64], owned: NDArray[np.bool_], ok: NDArray[np.bool_],
    reach: float, what: str, where: str, halo: int,
) -> None:  # fmt: skip
    """:class:`ShardingError` unless every node within ``reach`` of an owned node is ``ok``
    (its star is the whole lattice's, with the current radii)."""
    if ok.all():
        return
    from scipy.spatial import cKDTree

    d, i = cKDTree(nodes[~ok]).query(nodes[owned], k=1, distance_upper_bound=reach)
    if np.isfinite(d).any():
        k = int(np.flatnonzero(~ok)[i[np.isfinite(d)][0]])
        raise ShardHaloError(
            f"{where}: {what} reads struts within {reach:.4g} of the owned nodes, but the "
            f"node at {nodes[k].tolist()} may have struts beyond the halo of {halo} cell(s); "
            "use a larger halo"
        )


def _fit_round(
    spec: _FillSpec,
    shard: int,
    keep_label: NDArray[np.bool_],
    rnd: int,
    prev: str,
    radius: Any,
    floor: float,
    segments: int,
    profile: Profile,
) -> dict[str, Any] | None:
    """Round ``rnd`` of the radius fit of :func:`conformal.radius.fit_radii`, for the struts
    this shard owns.

    Round 0 resolves the radii and caps them at 0.45 of the length (``cur``). Round k >= 1
    reads the radii of every strut of the shard as their owners wrote them in round k - 1
    (column ``prev``: ``cur``, or the candidate the client chose, ``M`` or ``C``), and
    computes, as one process does for the whole lattice, both candidates: ``M`` (the
    struts at nodes with misfits thinned, :func:`fast_stitch.fit.misfits`) and, unless an
    owned strut misfits (then the lattice is in a misfit round), ``C`` (struts and joints
    that clash thinned, :func:`fast_stitch.fit.clashes`). The client decides from all
    shards' flags which one the whole lattice takes (the one-process rule), so every round
    is the one-process round, strut for strut. Exact because every node within
    :func:`_fit_reach` of an owned node has the lattice's star (checked in round 0), and
    the radii are exchanged every round.
    """
    from conformal.radius import _clash_struts, resolve_radii
    from fast_stitch.fit import clashes, misfits, strut_lengths
    from lattice_cad.core.config import CLEARANCE_MARGIN, FIT_SLACK

    with _threads(spec.threads):
        g = _shard_graph(spec, shard, keep_label)
        if g is None:
            return None
        nodes, edges, owned, key, exact = g
        lo, hi = _block(spec, shard)
        where = f"shard {shard} (cells {lo.tolist()}..{(hi - 1).tolist()})"
        owned_strut = owned[edges[:, 0]]
        ids, swap = _strut_ids(key, edges)
        order = np.argsort(ids[owned_strut], kind="stable")
        out_ids = ids[owned_strut][order]

        def save(**cols: NDArray[np.float64]) -> None:
            data = {k: _canon(v, swap)[owned_strut][order] for k, v in cols.items()}
            # numpy's stub also matches **data against savez's allow_pickle: bool; the
            # keys are column names ("M", "C", ...), never "allow_pickle"
            np.savez(Path(spec.tmpdir) / f"fit-{rnd}-{shard}.npz",
                     ids=out_ids.view(np.int64).reshape(-1, 2), **data)  # type: ignore[arg-type]  # fmt: skip

        r_res = resolve_radii(radius, nodes, edges)
        if rnd == 0:
            r = r_res.copy()
            length = strut_lengths(nodes, edges)
            cap = 0.45 * length
            too_fat = r > cap[:, None]
            r[too_fat] = np.broadcast_to(cap[:, None], r.shape)[too_fat]
            save(cur=r, res=r_res)
            return {"min": float(r_res[owned_strut].min()) if owned_strut.any() else np.inf}
        r, found = _gather_radii(spec, shard, ids, swap, rnd - 1, prev, r_res)
        ok = exact.copy()
        ok[edges[~found].ravel()] = False
        reach = _reach(nodes, edges, r, owned, segments=segments, profile=profile,
                       pad=1.0 + 2.0 * CLEARANCE_MARGIN)  # fmt: skip
        _check_reach(nodes, owned, ok, reach, "fitting the radii", where, spec.halo)
        n_nodes, m = len(nodes), len(edges)
        bad, need, length = misfits(nodes, edges, r, slack=FIT_SLACK, segments=segments,
                                    profile=profile)  # fmt: skip
        node_f = np.ones(n_nodes)
        edge_f = np.ones(m)
        if len(bad):
            factor = np.clip((1.0 - 1.5 * FIT_SLACK) * length[bad] / need[bad], 0.2, 0.97)
            np.minimum.at(node_f, edges[bad, 0], factor)
            np.minimum.at(node_f, edges[bad, 1], factor)
        new_m = np.maximum(r * node_f[edges] * edge_f[:, None], floor)
        mis_owned = np.zeros(m, dtype=bool)
        mis_owned[bad] = True
        mis_owned &= owned_strut
        out: dict[str, Any] = {
            "misfit": int(mis_owned.sum()),
            "eq_m": bool(np.array_equal(new_m[owned_strut], r[owned_strut])),
            "pairs": 0, "clash": 0, "eq_c": True,
            "where": (nodes[edges[np.flatnonzero(mis_owned)[0]]].tolist()
                      if mis_owned.any() else None),
        }  # fmt: skip
        cols = {"M": new_m}
        if not mis_owned.any():
            pairs, dist, clash_reach = clashes(
                nodes, edges, r, margin=2 * CLEARANCE_MARGIN, segments=segments,
                profile=profile,
            )  # fmt: skip
            node_f = np.ones(n_nodes)
            edge_f = np.ones(m)
            factor = np.repeat(np.clip(0.98 * dist / clash_reach, 0.2, 0.97), 2)
            el = pairs.ravel()
            strut = el < m
            np.minimum.at(edge_f, el[strut], factor[strut])
            np.minimum.at(node_f, el[~strut] - m, factor[~strut])
            new_c = np.maximum(r * node_f[edges] * edge_f[:, None], floor)
            # a pair is seen exactly by the owners of its elements (a joint: its node's)
            own_el = np.concatenate([owned_strut, owned])
            out["pairs"] = int(own_el[pairs].any(axis=1).sum())
            cl = np.zeros(m, dtype=bool)
            cl[_clash_struts(pairs, edges, m, n_nodes)] = True
            cl &= owned_strut
            out["clash"] = int(cl.sum())
            if cl.any():
                out["where"] = nodes[edges[np.flatnonzero(cl)[0]]].tolist()
            out["eq_c"] = bool(np.array_equal(new_c[owned_strut], r[owned_strut]))
            cols["C"] = new_c
        save(**cols)
        return out


def _fit_sharded(
    client: Any,
    spec: _FillSpec,
    live: list[int],
    keep: dict[int, NDArray[np.bool_]],
    radius: Any,
    min_radius: float | None,
    segments: int,
    profile: Profile,
    *,
    retries: int,
    progress: bool,
    max_rounds: int = 60,
) -> tuple[int, str]:
    """:func:`conformal.radius.fit_radii` (``clearance=True``) over the shards, round by
    round (:func:`_fit_round`); the client takes each round's decision of the one-process
    loop from the owned flags of all shards. Returns the round and column of the fitted
    radii (the owners' ``fit-ROUND-SHARD.npz``). Raises :class:`FitError` when struts
    cannot be thinned enough; unlike ``conformal.voxel_lattice``, which then drops up to
    10 % of such struts (``BuildReport.removed_unstitchable``), the sharded fit drops none,
    so that no shard changes the graph its neighbours see."""
    from lattice_cad.core.errors import FitError

    def run(rnd: int, prev: str, floor: float) -> list[dict[str, Any]]:
        got = _run(client, _fit_round, [(spec, s, keep[s], rnd, prev) for s in live],
                   retries=retries, progress=progress, desc=f"fit{rnd}",
                   extra=(radius, floor, segments, profile))  # fmt: skip
        return [x for x in got if x is not None]

    init = run(0, "cur", 0.0)
    floor = 0.1 * min(x["min"] for x in init) if min_radius is None else float(min_radius)
    prev = "cur"
    unfit: list[dict[str, Any]] = []
    final = (max_rounds, "M")
    for rnd in range(1, max_rounds + 1):
        flags = run(rnd, prev, floor)
        if any(x["misfit"] for x in flags):
            unfit = [x for x in flags if x["misfit"]]
            if all(x["eq_m"] for x in flags):
                final = (rnd - 1, prev)
                break
            prev = "M"
        else:
            if not any(x["pairs"] for x in flags):
                unfit = []
                final = (rnd - 1, prev)
                break
            unfit = [x for x in flags if x["clash"]]
            if all(x["eq_c"] for x in flags):
                final = (rnd - 1, prev)
                break
            prev = "C"
    else:
        final = (max_rounds, prev)
    if unfit:
        n = sum(x["misfit"] or x["clash"] for x in unfit)
        raise FitError(
            f"{n} strut(s) cannot be thinned enough to stitch (min radius {floor:g}); e.g. "
            f"the strut from {unfit[0]['where'][0]} to {unfit[0]['where'][1]}; use larger "
            "cells, a smaller radius or more segments (--segments), or a lower min_radius "
            "(the one-process fill, without --shards, drops such struts when they are few)"
        )
    return final


# ================================================ hub growth capped, sharded
#: Largest hub growth ``s_n`` (profile="volume") the sharded reach of capping allows for.
_MAX_GROWTH = 1.5


def _near(nodes: NDArray[np.float64], seed: NDArray[np.bool_], reach: float) -> NDArray[np.bool_]:
    """(N,) bool: the nodes within ``reach`` of a ``seed`` node."""
    from scipy.spatial import cKDTree

    out = seed.copy()
    if seed.any() and not seed.all():
        d, _ = cKDTree(nodes[seed]).query(nodes[~seed], k=1, distance_upper_bound=reach)
        out[~seed] = np.isfinite(d)
    return out


def _gather_scales(
    spec: _FillSpec, shard: int, key: NDArray[np.int64], rnd: int, where: str,
    fallback: NDArray[np.float64] | None = None,
    halvings: bool = False,
) -> Any:  # fmt: skip
    """Node scales (and halvings) as their owners wrote them in capping round ``rnd``;
    a node no owner wrote keeps ``fallback`` (without one: :class:`ShardingError`)."""
    scale = np.full(len(key), np.nan) if fallback is None else fallback.copy()
    halv = np.zeros(len(key), dtype=np.int64)
    found = np.zeros(len(key), dtype=bool)
    for s in _neighbour_shards(spec, shard):
        p = Path(spec.tmpdir) / f"capr-{rnd}-{s}.npz"
        if not p.exists():
            continue
        with np.load(p) as d:
            ids = d["key"]
            if not len(ids):
                continue
            at = np.minimum(np.searchsorted(ids, key), len(ids) - 1)
            hit = ids[at] == key
            scale[hit] = d["scale"][at[hit]]
            halv[hit] = d["halvings"][at[hit]]
            found |= hit
    if fallback is None and not found.all():
        raise ShardHaloError(f"{where}: no shard capped the hub growth of a node it needs; "
                            "use a larger halo")  # fmt: skip
    return (scale, halv, found) if halvings else scale


def _cap_round(spec: _FillSpec, shard: int, rnd: int) -> bool | None:
    """Round ``rnd`` of :func:`fast_stitch.stitch.cap_growth` for the nodes this shard
    owns: the scales of every node within :func:`_cap_reach` as their owners wrote them
    in round ``rnd - 1`` (round 0: the hub scales of the stitch), the clearance check of
    the scaled elements, the growth of hit owned nodes halved. Returns whether an owned
    node was hit (the one-process loop stops at the first round without any)."""
    from fast_stitch.fit import _clashes, _incidence

    p = Path(spec.tmpdir) / f"cap-{shard}.npz"
    if not p.exists():
        return None
    with _threads(spec.threads), np.load(p) as d:
        nodes, edges, radii, off = d["nodes"], d["edges"], d["radii0"], d["offset0"]
        s0, key, owned, near = d["scale0"], d["key"], d["owned"], d["near"]
        lo, hi = _block(spec, shard)
        where = f"shard {shard} (cells {lo.tolist()}..{(hi - 1).tolist()})"
        if rnd == 0:
            scale, halv = s0, np.zeros(len(nodes), dtype=np.int64)
        else:
            scale, halv, found = _gather_scales(spec, shard, key, rnd - 1, where, fallback=s0,
                                                halvings=True)  # fmt: skip
            if (near & ~found).any():
                raise ShardHaloError(f"{where}: no shard capped the hub growth of a node "
                                    "within reach; use a larger halo")  # fmt: skip
        m, n_nodes = len(edges), len(nodes)
        node_scale = scale[edges]
        pairs, _, _ = _clashes(nodes, edges, radii * node_scale, off * node_scale,
                               _incidence(edges, n_nodes), 1e-9)  # fmt: skip
        el = np.unique(pairs.ravel())
        hit = np.zeros(n_nodes, dtype=bool)
        hit[edges[el[el < m]].ravel()] = True
        hit[el[el >= m] - m] = True
        hit &= (scale > 1.0) & owned
        new = scale.copy()
        halv = halv.copy()
        halv[hit] += 1
        less = hit & (halv <= 3)
        new[less] = 1.0 + 0.5 * (scale[less] - 1.0)
        new[hit & ~less] = 1.0
        order = np.argsort(key[owned])
        np.savez(Path(spec.tmpdir) / f"capr-{rnd}-{shard}.npz", key=key[owned][order],
                 scale=new[owned][order], halvings=halv[owned][order])  # fmt: skip
        return bool(hit.any())


def _cap_changed(spec: _FillSpec, shard: int, rnd: int) -> bool:
    """Whether the final scales (round ``rnd``) of the nodes whose scales a shard's owned
    triangles use differ from those its first stitch used (then it is stitched again)."""
    p = Path(spec.tmpdir) / f"cap-{shard}.npz"
    if not p.exists():
        return True
    with np.load(p) as d:
        seen, key, scale = d["seen"], d["key"], d["scale"]
    lo, hi = _block(spec, shard)
    where = f"shard {shard} (cells {lo.tolist()}..{(hi - 1).tolist()})"
    final = _gather_scales(spec, shard, key[seen], rnd, where)
    return not np.array_equal(final, scale[seen])


def _cap_sharded(
    client: Any, spec: _FillSpec, live: list[int], *, retries: int, progress: bool
) -> int:
    """The capping rounds of :func:`fast_stitch.stitch.cap_growth` over the shards (scales
    exchanged between owners every round); the round whose files hold the final scales."""
    for rnd in range(10_000):
        hits = _run(client, _cap_round, [(spec, s, rnd) for s in live], retries=retries,
                    progress=progress, desc=f"cap{rnd}")  # fmt: skip
        if not any(h for h in hits if h is not None):
            return rnd
    raise ShardingError("capping hub growth did not settle")  # pragma: no cover


def _fill_stitch(
    spec: _FillSpec,
    shard: int,
    keep_label: NDArray[np.bool_],
    fitted: tuple[int, str] | None,
    cap: int | None,
    radius: Any,
    segments: int,
    seed: int,
    profile: Profile,
) -> ShardStats | None:
    """Phase 2 of a shard: keep the selected pieces, radii (the fitted ones of their
    owners, :func:`_fit_sharded`), stitch, write owned triangles."""
    from conformal.radius import resolve_radii

    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    with _threads(spec.threads):
        g = _shard_graph(spec, shard, keep_label)
        if g is None:
            return None
        nodes, edges, owned, key, _ = g
        lo, hi = _block(spec, shard)
        where = f"shard {shard} (cells {lo.tolist()}..{(hi - 1).tolist()})"
        r = resolve_radii(radius, nodes, edges)
        thinned, r_min = 0, np.inf
        found = np.ones(len(edges), dtype=bool)
        if fitted is not None:
            ids, swap = _strut_ids(key, edges)
            asked = r
            r, found = _gather_radii(spec, shard, ids, swap, fitted[0], fitted[1], asked)
            need = _within(owned, edges, _hops(profile))
            lost = need[edges].any(axis=1) & ~found
            if lost.any():
                e = int(np.flatnonzero(lost)[0])
                raise ShardHaloError(
                    f"{where}: no shard fitted the strut from {nodes[edges[e, 0]].tolist()} "
                    f"to {nodes[edges[e, 1]].tolist()}, which this shard needs; use a larger "
                    "halo"
                )
            mine = owned[edges[:, 0]]
            thinned = int(((r < asked).any(axis=1) & mine).sum())
            r_min = float(r[mine].min()) if mine.any() else np.inf
        # stitch only what the owned triangles depend on: the struts at the owned nodes
        # and at the nodes within _hops (whose hubs are complete here); with "volume",
        # also what the capping rounds of hub growth read (_cap_round): the scales of the
        # nodes within _cap_reach of the owned nodes, so the stars one strut further
        need = _within(owned, edges, _hops(profile))
        capping = profile == "volume"
        if capping:
            ok = g[4].copy()
            ok[edges[~found].ravel()] = False
            reach = _reach(nodes, edges, r, owned, segments=segments, profile=profile,
                           pad=1.0 + 1e-9, growth=_MAX_GROWTH, misfit_hops=False)  # fmt: skip
            near = _near(nodes, owned, reach)
            need |= _within(near, edges, 1)
            # the scales read (near) are exact when the stars one strut further are
            _check_reach(nodes, owned, ok | ~_within(near, edges, 1), np.inf,
                         "limiting hub growth", where, spec.halo)  # fmt: skip
        sub = need[edges].any(axis=1)
        edges, r = edges[sub], r[sub]
        used = np.zeros(len(nodes), dtype=bool)
        used[edges.ravel()] = True
        nodes, owned, key = nodes[used], owned[used], key[used]
        need = need[used]
        edges = (np.cumsum(used) - 1)[edges]
        owned_strut = owned[edges[:, 0]]
        if spec.beams:  # the owned struts as beams (degrees of the whole lattice)
            _save_beams(Path(spec.tmpdir) / f"beams-{shard}.npz", nodes, edges, r, owned_strut,
                        key)  # fmt: skip
        report: dict[str, Any] | None = None
        seen = _within(owned, edges, 1)  # the nodes whose scales the owned triangles use
        if capping:
            report = {}
            if cap is not None:
                idx = np.flatnonzero(seen)
                if cap < 0:  # nothing is capped in the lattice: the uncapped scales
                    report["scale_override"] = (idx, None)
                else:
                    report["scale_override"] = (idx, _gather_scales(spec, shard, key[idx],
                                                                    cap, where))  # fmt: skip
        n = _stitch_owned(
            nodes, edges, r, owned, owned_strut,
            segments=segments, seed=seed, profile=profile,
            piece=Path(spec.tmpdir) / f"piece-{shard}.stl", where=where, report=report,
        )  # fmt: skip
        hit0 = capped_seen = False
        if report is not None and cap is None:
            near = near[used]
            grow = float(report["scale0"][near].max()) if "scale0" in report else 1.0
            if grow > _MAX_GROWTH:
                raise ShardingError(
                    f"{where}: a hub grows by {grow:.4g}, more than the {_MAX_GROWTH} the "
                    "sharded path allows for"
                )
            hits = report.get("hits0")
            hit0 = bool(hits is not None and (hits & owned).any())
            capped_seen = bool(seen[report.get("capped", np.zeros(0, dtype=np.int64))].any())
            if "scale0" in report:
                np.savez(Path(spec.tmpdir) / f"cap-{shard}.npz", nodes=nodes, edges=edges,
                         radii0=report["radii0"], offset0=report["offset0"],
                         scale0=report["scale0"], key=key, owned=owned, near=near,
                         seen=seen, scale=report["scale"])  # fmt: skip
        return ShardStats(
            shard=shard,
            owned_struts=int(owned_strut.sum()),
            struts=len(edges),
            triangles=n,
            seconds=time.perf_counter() - t0,
            cpu_seconds=time.process_time() - c0,
            peak_rss=_peak_rss(),
            worker=_worker_name(),
            thinned=thinned,
            min_radius=r_min,
            hit0=hit0,
            capped=capped_seen,
        )


def _save_beams(
    path: Path,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    owned_strut: NDArray[np.bool_],
    key: NDArray[np.int64],
) -> None:
    """The owned struts of a shard as beams: their nodes, edges, radii, the degree of each
    node in the shard graph (complete at the ends of owned struts), and the balls this
    shard writes.

    A seam node's struts are owned by several shards; its ball is written once, by the
    owner of the node's strut whose other end has the lowest global id (``key`` (N,)
    int64, the nodes' global ids): every shard holding one of the node's struts has the
    node's whole star and the same ids, so exactly one of them takes the ball. Its radius
    is the largest strut radius at the node over the whole star (as in one process).
    """
    n = len(nodes)
    degree = np.bincount(edges.ravel(), minlength=n)
    other = key[edges[:, ::-1]]  # (M, 2): the global id of the far end, per strut end
    best = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(best, edges.ravel(), other.ravel())
    first = other == best[edges]  # the end's strut is the node's ball strut
    ball = np.zeros(n, dtype=bool)
    ball[edges[first & owned_strut[:, None]]] = True
    ball_radius = np.zeros(n)
    np.maximum.at(ball_radius, edges.ravel(), radii.ravel())
    e = edges[owned_strut]
    used = np.zeros(n, dtype=bool)
    used[e.ravel()] = True
    np.savez(path, nodes=nodes[used], edges=(np.cumsum(used) - 1)[e],
             radii=radii[owned_strut], degree=degree[used], ball=ball[used],
             ball_radius=ball_radius[used])  # fmt: skip


def _piece_part(tmpdir: str, shard: int, beams: bool) -> dict[str, Any]:
    """Phase 3 (3MF in shards) of a shard: its STL piece welded by exact coordinates (and
    its beams) as a one-object 3MF, ``part-K.3mf``."""
    from lattice_cad.io.sharded_3mf import write_part

    work = Path(tmpdir)
    recs = np.fromfile(work / f"piece-{shard}.stl", dtype=_REC)
    corners = np.ascontiguousarray(recs["v"]).reshape(-1, 3)
    del recs
    # weld by the exact float32 coordinates (the seams' vertices are bit-identical)
    keyed = corners.view(np.dtype((np.void, 12))).ravel()
    _, first, inverse = np.unique(keyed, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # vertices in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = corners[first[order]].astype(np.float64)
    faces = rank[inverse.ravel()].reshape(-1, 3).astype(np.int64)
    b = None
    if beams:
        with np.load(work / f"beams-{shard}.npz") as d:
            b = {k: d[k] for k in d.files}
    return write_part(work / f"part-{shard}.3mf", vertices, faces, name=f"shard {shard}",
                      beams=b)  # fmt: skip


def _assemble_3mf_shards(
    client: Any,
    out: Path,
    work: Path,
    shards: Sequence[int],
    *,
    beams: bool,
    retries: int,
    progress: bool,
) -> None:
    """One 3MF whose build object is made of one component per shard (Production
    extension ``p:path`` parts), each shard's part written by a worker."""
    from lattice_cad.io.sharded_3mf import assemble_parts

    metas = _run(client, _piece_part, [(str(work), s, beams) for s in shards],
                 retries=retries, progress=progress, desc="3mf")  # fmt: skip
    assemble_parts(out, [work / f"part-{s}.3mf" for s in shards], metas, name="lattice")


def _threemf_layout(mode: str, triangles: int, beams: bool) -> str:
    if mode not in ("auto", "merged", "shards"):
        raise ValueError(f"threemf={mode!r}: choose 'auto', 'merged' or 'shards'")
    if beams:
        return "shards"
    if mode == "auto":
        return "shards" if triangles > MAX_3MF_TRIANGLES else "merged"
    return mode


# =============================================================== orchestration
@contextlib.contextmanager
def _client(scheduler: Any, workers: int | None) -> Iterator[Any]:
    """A Dask client: ``scheduler`` (a Client, or an address ``tcp://host:8786``), or a
    LocalCluster of ``workers`` processes (one thread each) closed afterwards."""
    distributed = _require_dask()
    if scheduler is not None and not isinstance(scheduler, str):
        yield scheduler
        return
    if isinstance(scheduler, str):
        client = distributed.Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    cluster = distributed.LocalCluster(
        n_workers=workers or 2,
        threads_per_worker=1,
        processes=True,
        # no dashboard, and the scheduler's HTTP server on a free port (the default 8787
        # may be taken by another cluster: distributed then warns)
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": ":0"},
    )
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def _run(
    client: Any,
    fn: Callable[..., Any],
    items: Sequence[Any],
    *,
    retries: int,
    progress: bool,
    desc: str,
    extra: Sequence[Any] = (),
) -> list[Any]:
    """``fn(*item, *extra)`` for every item on the cluster, with retries, one progress bar
    over the shards, and every future cancelled on an error or Ctrl-C."""
    distributed = _require_dask()
    token = uuid.uuid4().hex[:8]
    futures = [
        client.submit(fn, *item, *extra, key=f"lattice-{desc}-{token}-{i}", retries=retries,
                      pure=False)
        for i, item in enumerate(items)
    ]  # fmt: skip
    bar = None
    try:
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(futures), desc=f"{desc} shards", unit="shard", leave=False)
        for fut in distributed.as_completed(futures):
            if fut.status == "error":
                fut.result()  # raises the task's exception here
            if bar is not None:
                bar.update(1)
        return list(client.gather(futures))
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        if bar is not None:
            bar.close()


def _assemble(path: Path, pieces: Sequence[Path], triangles: int, *, fmt: str) -> None:
    """Stream the pieces into one file (atomically: complete or absent)."""
    from lattice_cad.core.mesh import stl_size
    from lattice_cad.core.resources import require_disk

    if fmt == "stl":
        require_disk(path, stl_size(triangles))
        if triangles >= 2**32:
            raise ShardingError(f"{path}: {triangles:,} triangles exceed binary STL's uint32 count")
        with atomic_write(path) as fh:
            fh.write(_HEADER.ljust(80, b" "))
            fh.write(np.uint32(0).tobytes())  # the count goes in last
            total = 0
            for p in pieces:
                total += p.stat().st_size // 50
                with open(p, "rb") as src:
                    shutil.copyfileobj(src, fh, 1 << 22)
                # the pieces are ours (in the work directory): free the disk as we go, so
                # the peak is one STL plus one piece (a failure reruns the stitch phase)
                p.unlink()
            if total != triangles:
                raise ShardingError(f"{path}: pieces hold {total} triangles, expected {triangles}")
            fh.seek(80)
            fh.write(np.uint32(total).tobytes())
        return
    # 3MF: one merged mesh, welded by exact coordinates
    from lattice_cad.core.mesh import Mesh, weld
    from lattice_cad.io import save_mesh

    if triangles > MAX_3MF_TRIANGLES:
        raise ShardingError(
            f"{path}: a merged sharded 3MF holds at most {MAX_3MF_TRIANGLES:,} "
            f"triangles ({triangles:,} here): use threemf='shards' (one object per shard) "
            "or write .stl"
        )
    recs = np.concatenate([np.fromfile(p, dtype=_REC) for p in pieces]) if pieces else None
    if recs is None or not len(recs):
        raise ShardingError(f"{path}: nothing to write")
    corners = recs["v"].reshape(-1, 3).astype(np.float64)
    faces = np.arange(len(corners), dtype=np.int64).reshape(-1, 3)
    v, f = weld(corners, faces)
    save_mesh(Mesh(vertices=v, faces=f), path)


def _format(path: Path) -> str:
    suf = path.suffix.lower()
    if suf not in (".stl", ".3mf"):
        raise ShardingError(
            f"{path.name}: the sharded path writes a mesh as .stl or .3mf, got {suf or 'none'!r}"
        )
    return suf[1:]


@contextlib.contextmanager
def _workdir(tmpdir: str | os.PathLike[str] | None, keep: bool) -> Iterator[Path]:
    d = Path(tempfile.mkdtemp(prefix="lattice-cad-shards-", dir=tmpdir))
    try:
        yield d
    finally:
        if not keep:
            shutil.rmtree(d, ignore_errors=True)


def _check_profile(profile: object) -> Profile:
    """``profile`` as a plain str, one of the profiles of :func:`fast_stitch.stitch` (all
    give identical seams sharded)."""
    if profile not in ("volume", "area", "inscribed", "circumscribed"):
        raise ValueError(f"unknown profile {profile!r}")
    return cast("Profile", str(profile))


def _default_halo(fill: str, fit: str, profile: Profile) -> int:
    """The first halo (cells) :func:`fill_sharded` tries: 1 cell for the struts of cells
    that stay inside the cell (2 for ``"clip"``, whose merges of surface nodes reach a
    strut length plus ``min_strut`` further, 3 for ``"conform"``, whose moved nodes make
    longer struts), plus 1 for the neighbours' hubs (2 with ``profile="volume"``, whose
    hub scales reach one strut further), plus 1 for what the radius fit and hub-growth
    capping read around the owned struts (``fit="shrink"`` or ``profile="volume"``)."""
    base = {"clip": 2, "conform": 3}.get(fill, 1) + _hops(profile)
    return base + (1 if fit == "shrink" or profile == "volume" else 0)


def fill_sharded(
    part: str | os.PathLike[str],
    path: str | os.PathLike[str],
    cell: Any = config.DEFAULT_CELL,
    cell_size: float | Sequence[float] = config.DEFAULT_CELL_SIZE,
    radius: float | Callable[[NDArray[np.float64]], Any] = config.DEFAULT_RADIUS,
    *,
    shards: int = 2,
    scheduler: Any = None,
    workers: int | None = None,
    fill: Literal["inside", "auto", "clip", "conform"] = "inside",
    segments: int = config.DEFAULT_SEGMENTS,
    seed: int = 0,
    origin: Any = None,
    units: str | float | None = None,
    prune: bool = True,
    fit: Literal["shrink", "off"] = "shrink",
    min_radius: float | None = None,
    profile: Profile = config.DEFAULT_PROFILE,
    min_strut: float = 0.1,
    halo: int | None = None,
    retries: int = 2,
    threads_per_task: int = 1,
    progress: bool = False,
    tmpdir: str | os.PathLike[str] | None = None,
    threemf: Literal["auto", "merged", "shards"] = "auto",
    beam_lattice: bool = False,
) -> ShardedResult:
    """Fill a part with a lattice on a Dask cluster, one block of cells per task.

    The same lattice as ``conformal.voxel_lattice(part, cell, cell_size, radius,
    fill=fill, segments=segments, profile=profile)`` stitched by
    ``fast_stitch.stitch(graph, segments, seed=seed, profile=profile)``: the
    written triangles are those of the single-process result (see the module docstring).

    Parameters
    ----------
    part : path
        A STEP or closed mesh file, loaded by each task (``conformal.load_part``).
    path : path
        Output ``.stl`` (binary, streamed from the shard pieces) or ``.3mf``.
    cell, cell_size, radius, segments, seed, origin, units, prune, min_radius,
    profile
        As for ``conformal.voxel_lattice`` and ``fast_stitch.stitch``. ``radius``: a
        number or a picklable callable of the (M, 3) strut midpoints.
    shards : int
        Number of blocks the grid is cut into (at least; blocks are whole cells).
    scheduler : str or distributed.Client, optional
        An existing scheduler's address (``"tcp://host:8786"``) or client; default a
        LocalCluster of ``workers`` processes with one thread each.
    workers : int, optional
        Worker processes of the LocalCluster (default 2; ignored with ``scheduler``).
    fill : {"inside", "auto", "clip", "conform"}
        ``"auto"`` is ``"inside"`` (other fills are refused when no whole cell fits).
        ``"clip"`` / ``"conform"``: the cut cells too, struts cut at the surface / outer
        nodes moved onto it, surface nodes closer than ``min_strut`` cells merged (as
        ``conformal.voxel_lattice``); a shard whose merges could reach beyond its halo
        raises :class:`ShardingError`.
    min_strut : float
        ``"clip"`` / ``"conform"``: merge distance and shortest strut, in cells (as
        ``conformal.voxel_lattice``).
    fit : {"shrink", "off"}
        ``"shrink"``: the radii are fitted as ``conformal.voxel_lattice`` fits them
        (:func:`conformal.radius.fit_radii`), sharded: round by round, every shard
        computes the new radii of the struts it owns from the current radii of every strut
        within reach (exchanged through files between rounds), and the client takes the
        decisions of the one-process loop (misfit or clearance round, when to stop) from
        the flags of all shards, so that every round is the one-process round. The
        thinning warning and :class:`FitError` are those of one process.
    halo : int, optional
        Cells of overlap on every side of a block. The default (:func:`_default_halo`:
        4 cells for ``"inside"``, 5 for ``"clip"``, 6 for ``"conform"`` with the default
        fit and profile) is grown by 2 cells, twice, when a shard finds it too small
        (:class:`ShardHaloError`); a halo given is used as it is (too small: the error).
    retries : int
        Dask retries of a failed task (a worker that dies is replaced and its tasks rerun).
    threads_per_task : int
        Numba threads per task (one per worker process by default).
    progress : bool
        A progress bar over the shards of each phase.
    tmpdir : path, optional
        Where shard graphs and pieces go (must be shared by the client and the workers).
    threemf : {"auto", "merged", "shards"}
        A ``.3mf`` output as one merged mesh object (``"merged"``, welded in the client),
        or as one object per shard in its own model part, referenced by one components
        object of the build (``"shards"``, 3MF Production extension: see
        :mod:`lattice_cad.io.sharded_3mf`; the workers write the parts, the client only
        streams them into the zip). ``"auto"``: merged up to :data:`MAX_3MF_TRIANGLES`.
    beam_lattice : bool
        With a ``.3mf`` output: each shard's object also holds its struts as beams (3MF
        Beam Lattice extension, balls at the joints), beside its triangles; always
        written in shards.

    Returns
    -------
    ShardedResult

    Raises
    ------
    DistributedUnavailableError
        Dask distributed is not installed.
    ShardingError
        An unsupported option, a halo too small, or radius fitting that would thin struts.
    FillError
        No cell fits inside the part.
    """
    if halo is None:  # the default, grown while a shard finds it too small
        kw = dict(locals())
        base = _default_halo(fill, fit, profile)
        for grow in (0, 2, 4):
            with warnings.catch_warnings(record=True) as seen:
                warnings.simplefilter("always")
                try:
                    result = fill_sharded(**{**kw, "halo": base + grow})
                except ShardHaloError:
                    if grow == 4:
                        raise
                    continue
            for w in seen:  # the warnings of the attempt that worked only
                warnings.warn(w.message, w.category, stacklevel=2)
            return result
        raise AssertionError("unreachable: the last attempt returns or raises")
    from conformal.voxel import _nothing_fits, grid_of

    t_start = time.perf_counter()
    _require_dask()
    profile = _check_profile(profile)
    out = check_target(path)
    fmt = _format(out)
    if fill not in ("inside", "auto", "clip", "conform"):
        raise ShardingError(
            f"fill={fill!r} is not supported sharded (choose 'inside', 'auto', 'clip' or 'conform')"
        )
    if fit not in ("shrink", "off"):
        raise ShardingError(f"fit={fit!r} is not supported sharded ('shrink' or 'off')")
    _threemf_layout(threemf, 0, False)
    if beam_lattice and fmt != "3mf":
        raise ShardingError(f"{out.name}: a beam lattice is written as .3mf, not .{fmt}")
    if int(halo) < 1 or int(shards) < 1 or int(retries) < 0:
        raise ValueError(f"halo and shards must be >= 1 and retries >= 0 (got {halo}, "
                         f"{shards}, {retries})")  # fmt: skip
    src = Path(part)
    if not src.is_file():
        raise InputFileError(f"{src}: the part must be a file that every worker can read")
    import conformal

    if isinstance(cell, str) and cell not in conformal.CELLS:
        raise ValueError(f"unknown cell {cell!r}; choose from {', '.join(sorted(conformal.CELLS))}")
    the_part = _load(str(src.resolve()), units)
    start, h, dims = grid_of(the_part, cell_size, origin=origin)
    counts = _split(dims, int(shards))
    size = -(-dims // counts)
    counts = -(-dims // size)
    spec = _FillSpec(
        path=str(src.resolve()), units=units, cell=cell,
        start=tuple(start.tolist()), h=tuple(h.tolist()), dims=tuple(dims.tolist()),
        counts=tuple(counts.tolist()), size=tuple(size.tolist()), halo=int(halo),
        prune=bool(prune), hops=_hops(profile), tmpdir="", threads=int(threads_per_task),
        beams=bool(beam_lattice), fill=fill if fill in ("clip", "conform") else "inside",
        min_len=float(min_strut) * float(h.min()),
    )  # fmt: skip
    n_shards = int(np.prod(counts))
    result = ShardedResult(path=out, struts=0, triangles=0)
    with _workdir(tmpdir, keep=False) as work, _client(scheduler, workers) as client:
        spec = _FillSpec(**{**spec.__dict__, "tmpdir": str(work)})
        t0 = time.perf_counter()
        built = _run(client, _fill_build, [(spec, i) for i in range(n_shards)],
                     retries=retries, progress=progress, desc="build")  # fmt: skip
        result.seconds["build"] = time.perf_counter() - t0
        result.removed_dangling = sum(int(b["pruned"]) for b in built if b is not None)
        for b in built:
            if b is not None:
                w = b["worker"]
                result.build_rss[w] = max(result.build_rss.get(w, 0), int(b["peak_rss"]))
        live = [b for b in built if b is not None and not b["empty"]]
        if not live:
            raise _nothing_fits(the_part, h, radius if not callable(radius) else 0.0,
                                f"no cell of size {h[0]:.4g} mm fits inside")  # fmt: skip
        keep = _select_pieces(the_part, live, result, spec.fill)
        fitted = None
        if fit == "shrink":
            t0 = time.perf_counter()
            fitted = _fit_sharded(client, spec, [b["shard"] for b in live], keep, radius,
                                  min_radius, int(segments), profile, retries=retries,
                                  progress=progress)  # fmt: skip
            result.seconds["fit"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        extra = (radius, int(segments), int(seed), str(profile))
        stats = _run(
            client, _fill_stitch, [(spec, b["shard"], keep[b["shard"]], fitted, None)
                                   for b in live],
            retries=retries, progress=progress, desc="stitch", extra=extra,
        )  # fmt: skip
        result.seconds["stitch"] = time.perf_counter() - t0
        # hub growth capped (profile="volume"): if a hub is hit anywhere, the capping
        # rounds run sharded and the shards are stitched again with the capped scales;
        # if none is, a shard that capped a hub it shows (wrongly, from its halo) is
        # stitched again with the uncapped scales
        redo: dict[int, int] = {}
        if any(s.hit0 for s in stats if s is not None):
            t0 = time.perf_counter()
            last = _cap_sharded(client, spec, [b["shard"] for b in live], retries=retries,
                                progress=progress)  # fmt: skip
            done = [s.shard for s in stats if s is not None]
            changed = _run(client, _cap_changed, [(spec, k, last) for k in done],
                           retries=retries, progress=False, desc="capcheck")  # fmt: skip
            redo = {k: last for k, c in zip(done, changed, strict=True) if c}
            result.seconds["cap"] = time.perf_counter() - t0
        else:
            redo = {s.shard: -1 for s in stats if s is not None and s.capped}
        if redo:
            t0 = time.perf_counter()
            again = _run(
                client, _fill_stitch, [(spec, k, keep[k], fitted, c) for k, c in redo.items()],
                retries=retries, progress=progress, desc="restitch", extra=extra,
            )  # fmt: skip
            by = {s.shard: s for s in again if s is not None}
            stats = [by.get(s.shard, s) if s is not None else None for s in stats]
            result.seconds["restitch"] = time.perf_counter() - t0
        result.shards = [s for s in stats if s is not None]
        result.struts = sum(s.owned_struts for s in result.shards)
        result.triangles = sum(s.triangles for s in result.shards)
        result.radii_reduced = sum(s.thinned for s in result.shards)
        if result.radii_reduced:  # the warning of conformal.voxel_lattice, same words
            warnings.warn(
                f"{result.radii_reduced} of {result.struts} struts were thinned (down to "
                f"radius {min(s.min_radius for s in result.shards):.4g}) so that every "
                "strut can be stitched",
                LatticeWarning,
                stacklevel=2,
            )
        t0 = time.perf_counter()
        if fmt == "3mf" and _threemf_layout(threemf, result.triangles, beam_lattice) == "shards":
            _assemble_3mf_shards(client, out, work, [s.shard for s in result.shards],
                                 beams=bool(beam_lattice), retries=retries,
                                 progress=progress)  # fmt: skip
        else:
            pieces = [work / f"piece-{s.shard}.stl" for s in result.shards]
            _assemble(out, pieces, result.triangles, fmt=fmt)
        result.seconds["assemble"] = time.perf_counter() - t0
    result.seconds["total"] = time.perf_counter() - t_start
    return result


def _select_pieces(
    part: Any, live: list[dict[str, Any]], result: ShardedResult, fill: str
) -> dict[int, Any]:
    """Union-find of the shards' component labels: keep the largest connected piece of each
    separate solid (as ``conformal.voxel.keep_main_components``); per shard, which of its
    labels to keep."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from conformal.voxel import JOINED_ADVICE, _solid_shells, islands_message, shell_owner

    base = np.cumsum([0] + [len(b["owned_count"]) for b in live])
    total = int(base[-1])
    keys = np.concatenate([b["link_key"] for b in live])
    gids = np.concatenate([b["link_label"] + base[i] for i, b in enumerate(live)])
    order = np.lexsort((gids, keys))
    keys, gids = keys[order], gids[order]
    same = keys[1:] == keys[:-1]
    a, b = gids[:-1][same], gids[1:][same]
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(total, total))
    n_root, root = connected_components(g, directed=False)
    size = np.bincount(root, weights=np.concatenate([b["owned_count"] for b in live]),
                       minlength=n_root)  # fmt: skip
    min_key = np.full(n_root, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(min_key, root, np.concatenate([b["min_key"] for b in live]))
    rep = np.full((n_root, 3), np.nan)
    all_rep = np.concatenate([b["rep"] for b in live])
    ok = ~np.isnan(all_rep[:, 0])
    rep[root[ok]] = all_rep[ok]
    # pieces without an interior node (clip/conform: fragments of surface nodes) go first
    interior = np.zeros(n_root, dtype=bool)
    np.logical_or.at(interior, root, np.concatenate([b["interior"] for b in live]))
    fragments = (size > 0) & ~interior
    result.removed_fragments = int(size[fragments].sum())
    size = np.where(fragments, 0, size)
    present = np.flatnonzero(size > 0)
    # the order of conformal's labels: by the smallest global node id of each piece
    present = present[np.argsort(min_key[present], kind="stable")]
    shells = _solid_shells(part) if len(present) > 1 else []
    owner = shell_owner(shells, rep[present])
    keep_root = np.zeros(n_root, dtype=bool)
    for o in np.unique(owner):
        mine = present[owner == o]
        keep_root[mine[np.argmax(size[mine])]] = True
    removed = int(size[~keep_root].sum())
    result.removed_islands = removed
    if removed:
        bodies = int(keep_root.sum())
        advice = JOINED_ADVICE.get(fill, "")
        total = int(size.sum())
        warnings.warn(
            islands_message(removed, total, len(present) - bodies, bodies, advice),
            LatticeWarning,
            stacklevel=3,
        )
    return {b["shard"]: keep_root[root[base[i] : base[i + 1]]] for i, b in enumerate(live)}


# ========================================================= sharded user graphs
def write_graph_shards(graph: Any, directory: str | os.PathLike[str], *, chunks: int) -> list[Path]:
    """Write a graph as NPZ shards of struts (the input of :func:`stitch_sharded`).

    Each ``graph-shard-K.npz`` holds ``edges`` (m, 2) int64 global node ids, ``radii``
    (m, 2) float64, and ``node_ids`` (n,) int64 / ``nodes`` (n, 3) float64 for every node
    its struts use. Any producer can write these files chunk by chunk (the whole graph is
    never needed in one process).

    Returns
    -------
    list of Path
    """
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    m = graph.num_edges
    bounds = np.linspace(0, m, int(chunks) + 1).astype(np.int64)
    out = []
    for k in range(int(chunks)):
        e = graph.edges[bounds[k] : bounds[k + 1]]
        ids = np.unique(e)
        p = d / f"graph-shard-{k}.npz"
        np.savez(p, edges=e, radii=graph.radii[bounds[k] : bounds[k + 1]], node_ids=ids,
                 nodes=graph.nodes[ids])  # fmt: skip
        out.append(p)
    return out


def _read_shard(p: str) -> dict[str, NDArray[Any]]:
    try:
        with np.load(p) as z:
            data = {k: z[k] for k in ("edges", "radii", "node_ids", "nodes")}
    except (OSError, KeyError, ValueError) as exc:
        raise InputFileError(
            f"{p}: not a graph shard (NPZ with edges, radii, node_ids, nodes): {exc}"
        ) from None
    return data


def _scan(p: str) -> tuple[NDArray[np.float64], NDArray[np.float64], float, int]:
    d = _read_shard(p)
    if not len(d["edges"]):
        return np.full(3, np.inf), np.full(3, -np.inf), 0.0, 0
    idx = np.searchsorted(d["node_ids"], d["edges"])
    a, b = d["nodes"][idx[:, 0]], d["nodes"][idx[:, 1]]
    length = float(np.linalg.norm(b - a, axis=1).max())
    return d["nodes"].min(axis=0), d["nodes"].max(axis=0), length, len(d["edges"])


def _route(p: str, k: int, box: tuple[Any, ...], tmpdir: str) -> int:
    """Map step: split one input shard's struts over the blocks that need them."""
    lo, step, counts, margin = (np.asarray(x) for x in box)
    d = _read_shard(p)
    idx = np.searchsorted(d["node_ids"], d["edges"])
    ends = d["nodes"][idx]  # (m, 2, 3)
    written = 0
    n_blocks = int(np.prod(counts))
    # a strut goes to every block whose box grown by ``margin`` holds one of its ends
    b_lo = np.clip(np.floor((ends - margin - lo) / step).astype(np.int64), 0, counts - 1)
    b_hi = np.clip(np.floor((ends + margin - lo) / step).astype(np.int64), 0, counts - 1)
    for blk in range(n_blocks):
        bi = np.array(np.unravel_index(blk, tuple(counts)))
        hit = ((b_lo <= bi) & (b_hi >= bi)).all(axis=2).any(axis=1)
        if not hit.any():
            continue
        e = d["edges"][hit]
        ids = np.unique(e)
        np.savez(Path(tmpdir) / f"route-{blk}-{k}.npz", edges=e, radii=d["radii"][hit],
                 node_ids=ids, nodes=d["nodes"][np.searchsorted(d["node_ids"], ids)])  # fmt: skip
        written += int(hit.sum())
    return written


def _graph_stitch(
    blk: int,
    inputs: list[str],
    box: tuple[Any, ...],
    tmpdir: str,
    segments: int,
    seed: int,
    profile: Profile,
    threads: int,
    beams: bool = False,
) -> ShardStats | None:
    """Reduce step: one block's struts (halo included), stitched; owned triangles written
    (and, with ``beams``, the owned struts as beams with the balls this block owns)."""
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    lo, step, counts, _ = (np.asarray(x) for x in box)
    parts = [_read_shard(p) for p in inputs if Path(p).exists()]
    if not parts:
        return None
    with _threads(threads):
        e_glob = np.concatenate([q["edges"] for q in parts])
        radii = np.concatenate([q["radii"] for q in parts])
        # a strut routed from two input shards appears once per input; keep one copy
        e_glob, first = unique_rows(e_glob, return_index=True)
        radii = radii[first]
        ids, where_ = np.unique(np.concatenate([q["node_ids"] for q in parts]), return_index=True)
        nodes = np.concatenate([q["nodes"] for q in parts])[where_]
        edges = np.searchsorted(ids, e_glob)
        bi = np.array(np.unravel_index(blk, tuple(counts)))
        nb = np.clip(np.floor((nodes - lo) / step).astype(np.int64), 0, counts - 1)
        owned = (nb == bi).all(axis=1)
        # the end with the lower global id owns the strut (ids are sorted: lower index)
        owner_end = np.minimum(edges[:, 0], edges[:, 1])
        owned_strut = owned[owner_end]
        if not owned_strut.any() and not owned.any():
            return None
        if beams:
            _save_beams(Path(tmpdir) / f"beams-{blk}.npz", nodes, edges, radii, owned_strut,
                        ids)  # fmt: skip
        n = _stitch_owned(
            nodes, edges, radii, owned, owned_strut, segments=segments, seed=seed,
            profile=profile, piece=Path(tmpdir) / f"piece-{blk}.stl",
            where=f"block {blk}",
        )  # fmt: skip
        return ShardStats(
            shard=blk,
            owned_struts=int(owned_strut.sum()),
            struts=len(edges),
            triangles=n,
            seconds=time.perf_counter() - t0,
            cpu_seconds=time.process_time() - c0,
            peak_rss=_peak_rss(),
            worker=_worker_name(),
        )


def stitch_sharded(
    graph_shards: Sequence[str | os.PathLike[str]],
    path: str | os.PathLike[str],
    segments: int = config.DEFAULT_SEGMENTS,
    *,
    blocks: int = 2,
    seed: int = 0,
    profile: Profile = config.DEFAULT_PROFILE,
    scheduler: Any = None,
    workers: int | None = None,
    retries: int = 2,
    threads_per_task: int = 1,
    progress: bool = False,
    tmpdir: str | os.PathLike[str] | None = None,
    threemf: Literal["auto", "merged", "shards"] = "auto",
    beam_lattice: bool = False,
) -> ShardedResult:
    """Stitch a graph held as NPZ shards (:func:`write_graph_shards`) on a Dask cluster.

    The same triangles as ``fast_stitch.stitch(graph, segments, seed=seed)`` (with the
    edges as given, orientation included), written as one binary STL (or 3MF). The box
    of the nodes is cut into ``blocks`` spatial blocks; each gets the struts with an end
    within the longest strut of its box (twice that with ``profile="volume"``: so every
    hub and hub scale it needs is complete), stitches
    them and writes the cylinders of the struts whose lower-id end it owns and the hubs
    of its nodes.

    Parameters
    ----------
    graph_shards : sequence of paths
        NPZ files with ``edges`` (global node ids), ``radii``, ``node_ids``, ``nodes``.
    path : path
        Output ``.stl`` or ``.3mf``.
    segments, seed, profile
        As for :func:`fast_stitch.stitch` (``method="verma"``).
    blocks : int
        Spatial blocks (stitch tasks), at least.
    scheduler, workers, retries, threads_per_task, progress, tmpdir, threemf
        As for :func:`fill_sharded`.
    beam_lattice : bool
        With a ``.3mf`` output: each block's object also holds the struts it owns as
        beams (3MF Beam Lattice extension) and the balls of the nodes it owns (each ball
        once, see :func:`_save_beams`); always written in shards, as :func:`fill_sharded`.

    Returns
    -------
    ShardedResult
    """
    t_start = time.perf_counter()
    _require_dask()
    profile = _check_profile(profile)
    out = check_target(path)
    fmt = _format(out)
    _threemf_layout(threemf, 0, False)
    if beam_lattice and fmt != "3mf":
        raise ShardingError(f"{out.name}: a beam lattice is written as .3mf, not .{fmt}")
    srcs = [str(Path(p).resolve()) for p in graph_shards]
    for p in srcs:
        if not Path(p).is_file():
            raise InputFileError(f"{p}: graph shard not found")
    if not srcs:
        raise ShardingError("no graph shards given")
    result = ShardedResult(path=out, struts=0, triangles=0)
    with _workdir(tmpdir, keep=False) as work, _client(scheduler, workers) as client:
        t0 = time.perf_counter()
        scans = _run(client, _scan, [(p,) for p in srcs], retries=retries, progress=progress,
                     desc="scan")  # fmt: skip
        lo = np.min([s[0] for s in scans], axis=0)
        hi = np.max([s[1] for s in scans], axis=0)
        lmax = max(s[2] for s in scans)
        if sum(s[3] for s in scans) == 0:
            raise ShardingError("the graph shards hold no struts")
        span = np.maximum(hi - lo, 1e-300)
        counts = _split(np.maximum(np.round(span / span.max() * 1024), 1).astype(np.int64),
                        int(blocks))  # fmt: skip
        step = span / counts * (1 + 1e-12)
        # an end within k lmax of the box (k = _hops): every strut at a node within
        # k lmax (k struts from an owned node at most) is routed too
        margin = _hops(profile) * lmax * (1 + 1e-9) + 1e-12 * float(
            np.abs(np.concatenate([lo, hi])).max()
        )
        box = (lo, step, counts, margin)
        _run(client, _route, [(p, k, box, str(work)) for k, p in enumerate(srcs)],
             retries=retries, progress=progress, desc="route")  # fmt: skip
        result.seconds["route"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        n_blocks = int(np.prod(counts))
        items = [
            (b, [str(work / f"route-{b}-{k}.npz") for k in range(len(srcs))])
            for b in range(n_blocks)
        ]
        extra = (box, str(work), int(segments), int(seed), str(profile),
                 int(threads_per_task), bool(beam_lattice))  # fmt: skip
        stats = _run(client, _graph_stitch, items, retries=retries, progress=progress,
                     desc="stitch", extra=extra)  # fmt: skip
        result.seconds["stitch"] = time.perf_counter() - t0
        result.shards = [s for s in stats if s is not None]
        result.struts = sum(s.owned_struts for s in result.shards)
        result.triangles = sum(s.triangles for s in result.shards)
        t0 = time.perf_counter()
        layout = _threemf_layout(threemf, result.triangles, bool(beam_lattice))
        if fmt == "3mf" and layout == "shards":
            _assemble_3mf_shards(client, out, work, [s.shard for s in result.shards],
                                 beams=bool(beam_lattice), retries=retries,
                                 progress=progress)  # fmt: skip
        else:
            _assemble(out, [work / f"piece-{s.shard}.stl" for s in result.shards],
                      result.triangles, fmt=fmt)  # fmt: skip
        result.seconds["assemble"] = time.perf_counter() - t0
    result.seconds["total"] = time.perf_counter() - t_start
    return result
