#!/usr/bin/env python
"""Benchmarks of ``fast_stitch.stitch`` against the seed paper and manifold3d.

Run from the repository root::

    python benchmarks/bench_stitch.py            # full run (several minutes)
    python benchmarks/bench_stitch.py --quick    # small versions of everything (< 60 s)

Prints plain-text tables and writes the same results as JSON to
``benchmarks/results/bench_stitch.json`` (``bench_stitch_quick.json`` with
``--quick``). See ``benchmarks/README.md`` for what each benchmark measures.

Paper: Verma, Rankouhi & Suresh, "A combinatorial approach for constructing
lattice structures", J. Mech. Des. 2019 (Tables 2-4 are copied below).
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

import fast_stitch
from conformal.cells import block, cell_counts, tile
from lattice_cad.core.errors import InvalidGraphError, StitchError
from lattice_cad.core.graph import LatticeGraph

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
#: The shared test data beside the repository root (../shared), never an absolute path.
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BUNNY_PATH = DATA / "meshes" / "bunny_closed_odedstein.obj"

P_DEFAULT = 6
#: Bunny: cells whose centre is inside; the bunny is scaled so that 1 mm BCC cells
#: give about 1.08 M struts (BCC has exactly 8 struts per cell, none shared).
BUNNY_TARGET_CELLS = 135_000
BUNNY_RADIUS = 0.25
BUNNY_RESOLUTIONS = (7.0, 3.5, 2.0, 1.75, 1.0)

# ----------------------------------------------------------------------------- paper data
#: Paper Table 3 ("proposed" rows; Stanford bunny, BCC, P = 6, R = 0.25 mm, 8 cores):
#: voxel resolution (mm) -> (graph edges, triangles, time s).
PAPER_TABLE3: dict[float, tuple[int, int, float]] = {
    7.0: (3_496, 93_000, 0.019),
    3.5: (29_200, 785_000, 0.127),
    2.0: (141_000, 2_660_000, 0.66),
    1.75: (208_000, 3_940_000, 0.866),
    1.0: (1_080_000, 29_200_000, 4.45),
}
#: Paper Table 4 (bunny, parallelisation): resolution (mm) -> times (s) on 1, 2, 4, 8 cores.
PAPER_TABLE4: dict[float, tuple[float, float, float, float]] = {
    2.0: (3.38, 1.86, 1.13, 0.66),
    1.0: (25.45, 13.37, 8.2, 4.45),
}
#: Paper Table 2 (box lattice in a 20 x 20 x 10 mm cuboid, 1.5 mm voxels, R = 0.25 mm,
#: 8 cores): P -> (triangles, volume mm^3, time s).
PAPER_TABLE2: dict[int, tuple[int, float, float]] = {
    3: (62_272, 598.1, 0.010),
    4: (79_408, 772.8, 0.014),
    6: (113_686, 948.3, 0.016),
    10: (182_260, 1037.3, 0.026),
    18: (319_397, 1071.3, 0.055),
    24: (422_297, 1082.3, 0.080),
}

# ----------------------------------------------------------------------------- goals
GOAL_BUNNY_EDGES_PER_S = 250_000.0
GOAL_BUNNY_TIME_S = 4.5
GOAL_OCTET_EDGES_PER_S = 120_000.0
GOAL_BYTES_PER_TRIANGLE = 120.0
GOAL_MANIFOLD_RATIO = 100.0
MANIFOLD_STOP_S = 60.0


# ============================================================================ utilities
def machine_info() -> dict[str, Any]:
    import manifold3d
    import scipy
    import trimesh

    try:
        from importlib.metadata import version

        m3_version = version("manifold3d")
    except Exception:  # pragma: no cover - metadata missing
        m3_version = getattr(manifold3d, "__version__", "?")
    try:
        load = os.getloadavg()
    except OSError:  # pragma: no cover - not on Unix
        load = (float("nan"),) * 3
    return {
        "cpu_count": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "numba_threading_layer": _threading_layer(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "scipy": scipy.__version__,
        "trimesh": trimesh.__version__,
        "manifold3d": m3_version,
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "loadavg_at_start": [round(x, 2) for x in load],
    }


def _threading_layer() -> str:
    try:
        return str(numba.threading_layer())
    except Exception:
        return "not initialised"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def fmt_int(n: float | None) -> str:
    return "-" if n is None else f"{int(round(n)):,}"


def fmt_f(x: float | None, digits: int = 3) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def fmt_rate(x: float | None) -> str:
    return "-" if x is None else f"{x / 1e3:,.0f}k"


def table(
    title: str, headers: Sequence[str], rows: Sequence[Sequence[str]], notes: Sequence[str] = ()
) -> str:
    """Plain-text table; the first column is left-aligned, the others right-aligned."""
    cols = [list(headers)] + [list(r) for r in rows]
    widths = [max(len(str(r[i])) for r in cols) for i in range(len(headers))]

    def line(r: Sequence[str]) -> str:
        cells = [
            str(v).ljust(widths[i]) if i == 0 else str(v).rjust(widths[i]) for i, v in enumerate(r)
        ]
        return "  ".join(cells).rstrip()

    out = [title, "=" * len(title), line(headers), "  ".join("-" * w for w in widths)]
    out += [line(r) for r in rows]
    out += [f"  {n}" for n in notes]
    return "\n".join(out)


def emit(text: str) -> None:
    print(text + "\n", flush=True)


def time_stitch(
    graph: LatticeGraph, P: int = P_DEFAULT, *, repeats: int = 3, workers: int | None = None
) -> tuple[float, list[float], fast_stitch.Mesh]:
    """Best wall time of ``repeats`` calls of ``fast_stitch.stitch`` (and the last mesh).

    Each call gets a fresh copy of the graph (built outside the timer), so the
    graph's derived data (incidence, degrees, strut vectors), which ``stitch``
    computes on first use and the graph then caches, is inside every timing.
    """
    times = []
    mesh = None
    for _ in range(repeats):
        mesh = None
        fresh = LatticeGraph(graph.nodes, graph.edges, graph.radii)
        gc.collect()
        t0 = time.perf_counter()
        mesh = fast_stitch.stitch(fresh, P, workers=workers)
        times.append(time.perf_counter() - t0)
    assert mesh is not None
    return min(times), times, mesh


def warm_up() -> float:
    """One stitch (and one STL write) on a small graph: numba JIT / cache load."""
    t0 = time.perf_counter()
    g = block("bcc", 2, cell_size=1.0, radius=0.1)
    m = fast_stitch.stitch(g, P_DEFAULT)
    _ = m.volume
    with tempfile.TemporaryDirectory() as d:
        m.save(Path(d) / "warm.stl")
    return time.perf_counter() - t0


def timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


# ============================================================================ bunny voxelisation
def load_bunny() -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The closed bunny with merged vertices (the OBJ repeats vertices per face corner)."""
    import trimesh

    m = trimesh.load(BUNNY_PATH, force="mesh", process=False)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    if not m.is_watertight:
        raise RuntimeError(f"{BUNNY_PATH} is not watertight after merging vertices")
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def inside_cells(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], h: float
) -> NDArray[np.int64]:
    """Cells ``(i, j, k)`` of the grid ``[i, i+1] x [j, j+1] x [k, k+1] * h`` (origin 0)
    whose centre lies inside the closed mesh, by ray parity along +z.

    Every grid column ``(i, j)`` is a vertical ray through ``((i + .5) h, (j + .5) h)``;
    each triangle is tested against the columns in its xy bounding box (exact
    edge functions, evaluated in a canonical vertex order so that the two
    triangles of an edge give bit-identical values, with the top-left tie rule
    so that a ray through an edge or vertex is counted once); a cell centre is
    inside iff an odd number of crossings lies below it. Vectorised numpy,
    O(F + crossings + cells).
    """
    nx, ny, nz = (max(1, int(math.ceil(v / h))) for v in vertices.max(axis=0))
    tri_xy = vertices[faces][:, :, :2]
    area2 = (tri_xy[:, 1, 0] - tri_xy[:, 0, 0]) * (tri_xy[:, 2, 1] - tri_xy[:, 0, 1]) - (
        tri_xy[:, 1, 1] - tri_xy[:, 0, 1]
    ) * (tri_xy[:, 2, 0] - tri_xy[:, 0, 0])
    keep = area2 != 0.0  # vertical triangles are grazed, never crossed
    f = faces[keep].copy()
    flip = area2[keep] < 0  # every projected triangle counter-clockwise
    f[flip, 1], f[flip, 2] = faces[keep][flip, 2], faces[keep][flip, 1]
    xy = vertices[:, :2] / h - 0.5  # column (i, j) sits at the integer point (i, j)
    t = xy[f]
    lo = np.maximum(np.ceil(t.min(axis=1)).astype(np.int64), 0)
    hi = np.minimum(np.floor(t.max(axis=1)).astype(np.int64), [nx - 1, ny - 1])
    ni = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    nj = np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    cnt = ni * nj
    tid = np.repeat(np.arange(len(f)), cnt)
    loc = np.arange(len(tid)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    ci = lo[tid, 0] + loc // nj[tid]
    cj = lo[tid, 1] + loc % nj[tid]
    px, py = ci.astype(np.float64), cj.astype(np.float64)
    ff = f[tid]
    w = np.empty((len(tid), 3))
    hit = np.ones(len(tid), dtype=bool)
    for e in range(3):
        va, vb = ff[:, (e + 1) % 3], ff[:, (e + 2) % 3]  # the edge opposite corner e
        swap = va > vb
        p, q = xy[np.where(swap, vb, va)], xy[np.where(swap, va, vb)]
        we = (q[:, 0] - p[:, 0]) * (py - p[:, 1]) - (q[:, 1] - p[:, 1]) * (px - p[:, 0])
        we = np.where(swap, -we, we)
        d = xy[vb] - xy[va]
        owns = (d[:, 1] < 0) | ((d[:, 1] == 0) & (d[:, 0] > 0))
        hit &= (we > 0) | ((we == 0) & owns)
        w[:, e] = we
    ci, cj, w, ff = ci[hit], cj[hit], w[hit], ff[hit]
    z = (w * vertices[ff][:, :, 2]).sum(axis=1) / w.sum(axis=1)
    k0 = np.clip(np.floor(z / h - 0.5).astype(np.int64) + 1, 0, nz)  # first centre above z
    toggles = np.zeros((nx, ny, nz + 1), dtype=np.int32)
    np.add.at(toggles, (ci, cj, k0), 1)
    parity = np.cumsum(toggles, axis=2) % 2
    if parity[:, :, -1].any():
        raise RuntimeError("a grid column crosses the mesh an odd number of times")
    return np.argwhere(parity[:, :, :nz] == 1).astype(np.int64)


def scaled_bunny() -> tuple[NDArray[np.float64], NDArray[np.int64], float, list[str]]:
    """The bunny translated to the positive octant (bbox min at 0) and uniformly scaled
    so that ~BUNNY_TARGET_CELLS 1 mm cells have their centre inside."""
    v0, f = load_bunny()
    v0 = v0 - v0.min(axis=0)
    vol = float(np.einsum("ij,ij->i", v0[f[:, 0]], np.cross(v0[f[:, 1]], v0[f[:, 2]])).sum() / 6)
    s = (BUNNY_TARGET_CELLS / vol) ** (1 / 3)
    best = (math.inf, s)
    for _ in range(6):  # the count is a step function of s: a few secant steps suffice
        n = len(inside_cells(v0 * s, f, 1.0))
        best = min(best, (abs(n - BUNNY_TARGET_CELLS), s))
        if n == BUNNY_TARGET_CELLS:
            break
        s *= (BUNNY_TARGET_CELLS / n) ** (1 / 3)
    s = best[1]
    v = v0 * s
    log = [f"scale {s:.6g}", "extent " + " x ".join(f"{x:.2f}" for x in v.max(axis=0)) + " mm"]
    return v, f, s, log


def bunny_graph(
    v: NDArray[np.float64], f: NDArray[np.int64], h: float
) -> tuple[LatticeGraph, int, float]:
    cells, t_vox = timed(lambda: inside_cells(v, f, h))
    g = tile("bcc", cells, cell_size=h, radius=BUNNY_RADIUS)
    return g, len(cells), t_vox


def check_voxels_against_trimesh(
    v: NDArray[np.float64], f: NDArray[np.int64], h: float, n_samples: int
) -> tuple[int, int, float]:
    """Agreement of :func:`inside_cells` with ``trimesh.Trimesh.contains`` on random centres."""
    import trimesh

    cells = inside_cells(v, f, h)
    shape = tuple(int(math.ceil(x / h)) for x in v.max(axis=0))
    occ = np.zeros(shape, dtype=bool)
    occ[tuple(cells.T)] = True
    rng = np.random.default_rng(1)
    sample = np.column_stack([rng.integers(0, n, n_samples) for n in shape])
    tm = trimesh.Trimesh(v, f, process=False)
    ins, dt = timed(lambda: tm.contains((sample + 0.5) * h))
    agree = int((occ[tuple(sample.T)] == ins).sum())
    return agree, n_samples, dt


# ============================================================================ 1. bunny
def bench_bunny(quick: bool, res: dict[str, Any]) -> dict[str, Any]:
    (v, f, scale, log), t_scale = timed(scaled_bunny)
    resolutions = BUNNY_RESOLUTIONS[:3] if quick else BUNNY_RESOLUTIONS
    agree, n_s, t_tm = check_voxels_against_trimesh(v, f, 3.5, 500 if quick else 3000)
    rows, out = [], []
    for h in resolutions:
        g, n_cells, t_vox = bunny_graph(v, f, h)
        big = g.num_edges > 500_000
        rep = 3 if big else (5 if quick else 10)
        t2, t2_all, mesh = time_stitch(g, repeats=rep)
        tris = len(mesh.faces)
        vol = mesh.volume
        del mesh
        t1, t1_all, mesh = time_stitch(g, repeats=rep, workers=1)
        del mesh
        pe, pt, ptime = PAPER_TABLE3[h]
        p4 = PAPER_TABLE4.get(h)
        rec = {
            "resolution_mm": h,
            "cells": n_cells,
            "nodes": g.num_nodes,
            "edges": g.num_edges,
            "triangles": tris,
            "volume_mm3": vol,
            "voxelise_s": t_vox,
            "time_s": t2,
            "times_s": t2_all,
            "time_1thread_s": t1,
            "times_1thread_s": t1_all,
            "edges_per_s": g.num_edges / t2,
            "edges_per_s_1thread": g.num_edges / t1,
            "triangles_per_s": tris / t2,
            "paper_edges": pe,
            "paper_triangles": pt,
            "paper_time_8core_s": ptime,
            "paper_time_2core_s": p4[1] if p4 else None,
            "paper_time_1core_s": p4[0] if p4 else None,
        }
        out.append(rec)
        rows.append(
            [
                f"{h:g} mm",
                fmt_int(g.num_edges),
                fmt_int(tris),
                fmt_f(t2),
                fmt_f(t1),
                fmt_rate(g.num_edges / t2),
                fmt_rate(g.num_edges / t1),
                fmt_int(pe),
                fmt_int(pt),
                fmt_f(ptime),
                fmt_f(p4[1]) if p4 else "-",
                fmt_f(p4[0]) if p4 else "-",
            ]
        )
        del g
        gc.collect()
    emit(
        table(
            "1. Stanford bunny, BCC, R = 0.25 mm, P = 6 (paper Tables 3 and 4)",
            [
                "voxel",
                "edges",
                "triangles",
                f"t {numba.get_num_threads()}thr s",
                "t 1thr s",
                f"edges/s {numba.get_num_threads()}thr",
                "edges/s 1thr",
                "paper edges",
                "paper tris",
                "paper 8c s",
                "paper 2c s",
                "paper 1c s",
            ],
            rows,
            [
                f"bunny {BUNNY_PATH.name}, bbox min at the origin, {', '.join(log)}, "
                f"calibrated so that {BUNNY_TARGET_CELLS:,} 1 mm cells ({8 * BUNNY_TARGET_CELLS:,} "
                f"struts) have their centre inside (calibration {t_scale:.2f} s)",
                "cells = grid cells whose centre is inside (z-ray parity, vectorised numpy); "
                "voxelisation time per resolution: "
                + ", ".join(
                    f"{r['resolution_mm']:g} mm {r['voxelise_s'] * 1e3:.0f} ms" for r in out
                )
                + " (not part of the stitch time)",
                f"inside test vs trimesh.contains on {n_s} random 3.5 mm cell centres: "
                f"{agree}/{n_s} agree (trimesh took {t_tm:.2f} s)",
                "times: best of 3 (> 500k edges) or 10 (5 with --quick) calls of "
                "fast_stitch.stitch only (graph built, JIT warmed up; a fresh graph per call, so "
                "its derived data is timed); 1thr = workers=1",
            ],
        )
    )
    res["bunny"] = {
        "scale": scale,
        "scale_log": log,
        "trimesh_check": {"agree": agree, "samples": n_s, "trimesh_s": t_tm},
        "rows": out,
    }
    return {"vertices": v, "faces": f, "scale": scale}


# ============================================================================ 2. jittered octet
def octet_graph(n: int, jitter: float, radius_frac: float, h: float = 1.0) -> LatticeGraph:
    base = block("octet", n, cell_size=h, radius=radius_frac * h)
    rng = np.random.default_rng(12345)
    nodes = base.nodes + rng.uniform(-jitter * h, jitter * h, base.nodes.shape)
    return LatticeGraph(nodes, base.edges, radius_frac * h)


OCTET_SETTINGS = ((0.10, 0.04), (0.05, 0.04), (0.05, 0.03), (0.02, 0.03))


def bench_octet(quick: bool, res: dict[str, Any]) -> dict[str, Any]:
    n = 8 if quick else 35
    tried = []
    for jitter, rfrac in OCTET_SETTINGS:
        try:
            g, t_build = timed(lambda j=jitter, r=rfrac: octet_graph(n, j, r))
            t, t_all, mesh = time_stitch(g, repeats=3)
        except (StitchError, InvalidGraphError) as exc:
            tried.append({"jitter": jitter, "radius_frac": rfrac, "error": str(exc)[:300]})
            continue
        break
    else:
        res["octet"] = {"n": n, "failed": tried}
        emit(f"2. Jittered octet: FAILED for all settings: {tried}")
        return {}
    tris = len(mesh.faces)
    rec = {
        "cells_per_side": n,
        "cell_size": 1.0,
        "jitter_frac": jitter,
        "radius_frac": rfrac,
        "nodes": g.num_nodes,
        "edges": g.num_edges,
        "triangles": tris,
        "volume": mesh.volume,
        "build_graph_s": t_build,
        "time_s": t,
        "times_s": t_all,
        "edges_per_s": g.num_edges / t,
        "triangles_per_s": tris / t,
        "failed_settings": tried,
    }
    res["octet"] = rec
    notes = [
        f"octet block {n}^3 cells (cell_counts: {cell_counts('octet', n)[1]:,} edges), cell 1, "
        f"nodes jittered by U(-{jitter:g}, {jitter:g}) per coordinate (seed 12345), "
        f"r = {rfrac:g}, best of 3 (graph build {t_build:.2f} s, not timed)",
    ]
    for tr in tried:
        notes.append(
            f"jitter {tr['jitter']:g} / r {tr['radius_frac']:g} FAILED: {tr['error'][:150]}"
        )
    emit(
        table(
            "2. Jittered octet, P = 6",
            ["case", "edges", "triangles", "time s", "edges/s", "Mtris/s"],
            [
                [
                    f"octet {n}^3 +-{jitter:g}",
                    fmt_int(g.num_edges),
                    fmt_int(tris),
                    fmt_f(t),
                    fmt_rate(g.num_edges / t),
                    fmt_f(tris / t / 1e6, 2),
                ]
            ],
            notes,
        )
    )
    return {"jitter": jitter, "radius_frac": rfrac, "n": n}


# ============================================================================ 3. memory
def _status_kb(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return -1


def _reset_peak() -> bool:
    """Reset the peak RSS (Linux >= 4.0: ``echo 5 > /proc/self/clear_refs``)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _maxrss_kb() -> int:
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)  # KB on Linux


def _peak_kb() -> int:
    """Peak RSS of this process in KB: VmHWM, else ``ru_maxrss``.

    ``ru_maxrss`` alone is not usable in a subprocess: Linux folds the peak of
    the pre-exec image (the forked copy of the parent, which may be GBs) into
    it, and ``clear_refs`` does not reset that part; VmHWM is the current
    address space's own high-water mark, which ``clear_refs`` does reset.
    """
    hwm = _status_kb("VmHWM")
    return hwm if hwm > 0 else _maxrss_kb()


def child_memory(spec: dict[str, Any]) -> dict[str, Any]:
    """Runs in a fresh interpreter: build the graph, warm up, then measure stitch and STL peaks."""
    if spec["case"] == "bunny":
        v, f = load_bunny()
        v = (v - v.min(axis=0)) * spec["scale"]
        g, _, _ = bunny_graph(v, f, spec["h"])
        del v, f
    elif spec["case"] == "octet":
        g = octet_graph(spec["n"], spec["jitter"], spec["radius_frac"])
    elif spec["case"] == "bcc":
        g = block("bcc", spec["n"], cell_size=1.0, radius=0.1)
    else:
        raise ValueError(spec["case"])
    warm_up()
    gc.collect()
    reset_ok = _reset_peak()
    before = _status_kb("VmRSS")
    t0 = time.perf_counter()
    mesh = fast_stitch.stitch(g, P_DEFAULT)
    t_stitch = time.perf_counter() - t0
    peak = _peak_kb()
    maxrss = _maxrss_kb()
    after = _status_kb("VmRSS")
    tris = len(mesh.faces)
    out_bytes = mesh.vertices.nbytes + mesh.faces.nbytes
    gc.collect()
    reset_ok &= _reset_peak()
    before_save = _status_kb("VmRSS")
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "bench.stl"
        t0 = time.perf_counter()
        mesh.save(path)
        t_save = time.perf_counter() - t0
        peak_save = _peak_kb()
        stl_bytes = path.stat().st_size
    return {
        "case": spec,
        "edges": g.num_edges,
        "triangles": tris,
        "peak_reset": reset_ok,
        "rss_before_stitch_kb": before,
        "peak_stitch_kb": peak,
        "ru_maxrss_after_stitch_kb": maxrss,
        "rss_after_stitch_kb": after,
        "stitch_bytes_per_triangle": (peak - before) * 1024 / tris,
        "output_bytes_per_triangle": out_bytes / tris,
        "stitch_s": t_stitch,
        "rss_before_save_kb": before_save,
        "peak_save_kb": peak_save,
        "save_bytes_per_triangle": (peak_save - before_save) * 1024 / tris,
        "save_s": t_save,
        "stl_bytes": stl_bytes,
        "stl_MB_per_s": stl_bytes / t_save / 1e6,
    }


def run_child(spec: dict[str, Any]) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps(spec)]
    p = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if p.returncode != 0:
        return {"case": spec, "error": (p.stderr or p.stdout)[-500:]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def bench_memory(
    quick: bool, res: dict[str, Any], bunny: dict[str, Any], octet: dict[str, Any]
) -> None:
    specs = [{"case": "bunny", "h": 3.5 if quick else 1.0, "scale": bunny["scale"]}]
    if octet:
        specs.append({"case": "octet", "n": 8 if quick else octet["n"], "jitter": octet["jitter"],
                      "radius_frac": octet["radius_frac"]})  # fmt: skip
    specs.append({"case": "bcc", "n": 12 if quick else 51})
    out, rows = [], []
    for spec in specs:
        r = run_child(spec)
        out.append(r)
        label = {
            "bunny": lambda s: f"bunny {s['h']:g} mm",
            "octet": lambda s: f"octet {s['n']}^3 jit",
            "bcc": lambda s: f"bcc {s['n']}^3",
        }[spec["case"]](spec)
        if "error" in r:
            rows.append([label, "ERROR", "", "", "", "", "", "", ""])
            print(f"memory child {spec} failed:\n{r['error']}", file=sys.stderr)
            continue
        rows.append(
            [
                label,
                fmt_int(r["edges"]),
                fmt_int(r["triangles"]),
                fmt_f(r["rss_before_stitch_kb"] / 1024, 0),
                fmt_f(r["peak_stitch_kb"] / 1024, 0),
                fmt_f(r["stitch_bytes_per_triangle"], 1),
                fmt_f(r["output_bytes_per_triangle"], 1),
                fmt_f(r["save_bytes_per_triangle"], 1),
                fmt_f(r["save_s"], 2),
            ]
        )
    emit(
        table(
            "3. Peak memory per output triangle (fresh subprocess per case, P = 6)",
            [
                "case",
                "edges",
                "triangles",
                "RSS before MB",
                "peak MB",
                "stitch B/tri",
                "(output B/tri)",
                "STL write B/tri",
                "STL write s",
            ],
            rows,
            [
                "stitch B/tri = (peak RSS during stitch - RSS just before it) / triangles; "
                "the peak is reset (echo 5 > /proc/self/clear_refs) after the graph is built "
                "and the JIT warmed up, then read as VmHWM (/proc/self/status); ru_maxrss is "
                "not used: in a subprocess it includes the parent's RSS at fork",
                "output B/tri = Mesh.vertices.nbytes + Mesh.faces.nbytes per triangle "
                "(the part of the peak that is the result itself)",
                "STL write B/tri: the same for Mesh.save to a temporary directory (mesh alive "
                "before and after)",
            ],
        )
    )
    res["memory"] = out


# ============================================================================ 4. manifold3d
def _strut_transforms(graph: LatticeGraph) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(M, 3, 4) affine maps taking the z axis [0, L] onto each strut, and the lengths."""
    a = graph.nodes[graph.edges[:, 0]]
    d = graph.edge_vectors
    L = graph.edge_lengths
    u = d / L[:, None]
    ref = np.where(np.abs(u[:, 0:1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(ref, u)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(u, e1)
    mats = np.empty((len(u), 3, 4))
    mats[:, :, 0], mats[:, :, 1], mats[:, :, 2], mats[:, :, 3] = e1, e2, u, a
    return mats, L


def manifold_union(graph: LatticeGraph, P: int) -> tuple[Any, float, int]:
    """Cylinders + node spheres unioned by manifold3d; returns (result, seconds, #solids)."""
    from manifold3d import Manifold, OpType

    t0 = time.perf_counter()
    mats, L = _strut_transforms(graph)
    r = graph.radii
    solids = [
        Manifold.cylinder(float(L[i]), float(r[i, 0]), float(r[i, 1]), P, False).transform(mats[i])
        for i in range(graph.num_edges)
    ]
    rnode = np.zeros(graph.num_nodes)
    np.maximum.at(rnode, graph.edges[:, 0], r[:, 0])
    np.maximum.at(rnode, graph.edges[:, 1], r[:, 1])
    for n in np.flatnonzero(rnode > 0):
        solids.append(Manifold.sphere(float(rnode[n]), P).translate(graph.nodes[n].tolist()))
    out = Manifold.batch_boolean(solids, OpType.Add)
    mesh = out.to_mesh()  # forces the (lazy) evaluation and extracts the arrays
    n_tri = len(np.asarray(mesh.tri_verts))
    dt = time.perf_counter() - t0
    return out, dt, n_tri if n_tri else out.num_tri()


def bench_manifold(quick: bool, res: dict[str, Any]) -> None:
    sizes = (3, 5) if quick else (5, 9, 14, 20, 26)
    h, r = 2.0, 0.25
    out, rows = [], []
    stop_note = f"all sizes {', '.join(f'{n}^3' for n in sizes)} run"
    for i, n in enumerate(sizes):
        g = block("bcc", n, cell_size=h, radius=r)
        m_out, t_m, n_tri_m = manifold_union(g, P_DEFAULT)
        vol_m = m_out.volume()
        del m_out
        reps = 10 if g.num_edges < 100_000 else 3
        t_s, _, mesh = time_stitch(g, repeats=reps)
        rec = {
            "cells_per_side": n,
            "edges": g.num_edges,
            "nodes": g.num_nodes,
            "manifold_s": t_m,
            "stitch_s": t_s,
            "ratio": t_m / t_s,
            "manifold_triangles": n_tri_m,
            "stitch_triangles": len(mesh.faces),
            "manifold_volume": vol_m,
            "stitch_volume": mesh.volume,
        }
        out.append(rec)
        rows.append(
            [
                f"bcc {n}^3",
                fmt_int(g.num_edges),
                fmt_f(t_m, 3),
                fmt_f(t_s, 4),
                f"{t_m / t_s:,.0f}x",
                fmt_int(n_tri_m),
                fmt_int(len(mesh.faces)),
                fmt_f(vol_m, 2),
                fmt_f(mesh.volume, 2),
            ]
        )
        del mesh, g
        if i + 1 < len(sizes):
            # manifold's time grows at least linearly with the strut count
            predicted = t_m * cell_counts("bcc", sizes[i + 1])[1] / rec["edges"]
            if t_m > MANIFOLD_STOP_S or predicted > MANIFOLD_STOP_S:
                stop_note = (
                    f"stopped after {n}^3: manifold took {t_m:.1f} s, so {sizes[i + 1]}^3 "
                    f"would take > {predicted:.0f} s (limit {MANIFOLD_STOP_S:g} s)"
                )
                break
    emit(
        table(
            "4. manifold3d batch_boolean union vs fast_stitch "
            "(BCC block, cell 2 mm, r = 0.25 mm, P = 6)",
            [
                "case",
                "struts",
                "manifold s",
                "stitch s",
                "ratio",
                "manifold tris",
                "stitch tris",
                "manifold vol",
                "stitch vol",
            ],
            rows,
            [
                "manifold: Manifold.cylinder(L, r, r, P) transformed onto each strut + "
                "Manifold.sphere(r_max, P) at each node (rounded up to 8 segments by manifold), "
                "Manifold.batch_boolean(..., OpType.Add), to_mesh(); time includes building the "
                "solids",
                "stitch: best of 3 (>= 100k struts) or 10 calls of fast_stitch.stitch, each on "
                "a fresh copy of the graph; "
                f"sizes grow while manifold's time, extrapolated linearly in the strut count, "
                f"stays under {MANIFOLD_STOP_S:g} s; {stop_note}",
                "volumes differ by design: spheres at the joints vs convex hubs with shrink",
            ],
        )
    )
    res["manifold"] = out
    res["manifold_stop"] = stop_note


# ============================================================================ 5. paper Table 2
def bench_table2(quick: bool, res: dict[str, Any]) -> None:
    # The cuboid is 20 x 20 x 10 mm and 1.5 mm does not divide it. As for the bunny, we keep
    # the cells whose centre is inside the cuboid: (0.75 + 1.5 i) < 20 -> 13 cells, < 10 -> 7
    # cells, i.e. 13 x 13 x 7 cubic cells (19.5 x 19.5 x 10.5 mm), 4,284 struts. This is the
    # paper's edge count too: its triangle counts grow by 17,138 per unit of P = 4 * 4,284.5.
    counts = (13, 13, 7)
    g = block("cubic", counts, cell_size=1.5, radius=0.25)
    reps = 5 if quick else 20
    out, rows = [], []
    for P, (ptri, pvol, ptime) in PAPER_TABLE2.items():
        t, _, mesh = time_stitch(g, P, repeats=reps)
        t1, _, _ = time_stitch(g, P, repeats=reps, workers=1)
        vol = mesh.volume
        rec = {
            "P": P,
            "edges": g.num_edges,
            "triangles": len(mesh.faces),
            "volume_mm3": vol,
            "time_s": t,
            "time_1thread_s": t1,
            "paper_triangles": ptri,
            "paper_volume_mm3": pvol,
            "paper_time_s": ptime,
        }
        out.append(rec)
        rows.append(
            [
                str(P),
                fmt_int(len(mesh.faces)),
                fmt_int(ptri),
                f"{len(mesh.faces) / ptri - 1:+.2%}",
                fmt_f(vol, 1),
                fmt_f(pvol, 1),
                f"{vol / pvol - 1:+.1%}",
                fmt_f(t * 1e3, 2),
                fmt_f(t1 * 1e3, 2),
                fmt_f(ptime * 1e3, 0),
            ]
        )
    emit(
        table(
            "5. Paper Table 2: box (cubic) lattice in a 20 x 20 x 10 mm cuboid, "
            "1.5 mm cells, R = 0.25 mm",
            [
                "P",
                "triangles",
                "paper",
                "diff",
                "volume mm3",
                "paper",
                "diff",
                f"time {numba.get_num_threads()}thr ms",
                "time 1thr ms",
                "paper 8c ms",
            ],
            rows,
            [
                f"13 x 13 x 7 cubic cells (cells whose centre is inside the cuboid), "
                f"{g.num_nodes:,} nodes, {g.num_edges:,} struts; shrink=True; time best of {reps}",
                "paper: 8-core i7-5960X class machine; numbers copied from its Table 2",
            ],
        )
    )
    res["table2"] = out


# ============================================================================ 6. hub cache
def distinct_hubs(graph: LatticeGraph, P: int = P_DEFAULT, seed: int = 0) -> tuple[int, int] | None:
    """(distinct hub keys, nodes of degree >= 2), from fast_stitch's private kernels.

    The hub cache is not exposed; this replays its first steps (strut frames and
    per-node keys, see ``fast_stitch.stitch._stitch``). Returns None if the
    private API changed.
    """
    try:
        from fast_stitch import _kernels

        m, n = graph.num_edges, graph.num_nodes
        offsets, inc_edge, inc_side = graph.incidence
        qdir = np.empty((m, 3), dtype=np.int64)
        sign = np.empty(m, dtype=np.int64)
        axis, fu, fv = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        length = np.empty(m)
        _kernels.edge_frames(graph.nodes, graph.edges, P, seed, qdir, sign, axis, fu, fv, length)
        slots = np.empty(2 * m, dtype=np.int64)
        slot_q = np.empty((2 * m, 3), dtype=np.int64)
        slot_r = np.empty(2 * m, dtype=np.int64)
        keys = np.empty(n, dtype=np.uint64)
        _kernels.node_slots(
            offsets, inc_edge, inc_side, qdir, sign, graph.radii, float(graph.radii.max()),
            slots, slot_q, slot_r, keys,
        )  # fmt: skip
        hubs = np.flatnonzero(graph.degree >= 2)
        return len(np.unique(keys[hubs])), len(hubs)
    except Exception:
        return None


def bench_hub_cache(quick: bool, res: dict[str, Any]) -> None:
    n = 12 if quick else 40
    h, r = 1.0, 0.1
    base = block("bcc", n, cell_size=h, radius=r)
    rng = np.random.default_rng(7)
    jit = LatticeGraph(
        base.nodes + rng.uniform(-1e-3 * h, 1e-3 * h, base.nodes.shape), base.edges, r
    )
    out, rows = [], []
    for label, g in (("periodic", base), ("jittered 1e-3", jit)):
        t, _, mesh = time_stitch(g, repeats=3)
        hubs = distinct_hubs(g)
        rec = {
            "case": label,
            "edges": g.num_edges,
            "triangles": len(mesh.faces),
            "time_s": t,
            "edges_per_s": g.num_edges / t,
            "distinct_hubs": hubs[0] if hubs else None,
            "hub_nodes": hubs[1] if hubs else None,
        }
        out.append(rec)
        rows.append(
            [
                label,
                fmt_int(g.num_edges),
                fmt_int(len(mesh.faces)),
                fmt_f(t),
                fmt_rate(g.num_edges / t),
                fmt_int(hubs[0]) if hubs else "n/a",
                fmt_int(hubs[1]) if hubs else "n/a",
            ]
        )
        del mesh
    ratio = out[1]["time_s"] / out[0]["time_s"]
    emit(
        table(
            f"6. Hub cache: periodic BCC {n}^3 vs the same jittered by U(+-1e-3) cell, "
            "r = 0.1, P = 6",
            ["case", "edges", "triangles", "time s", "edges/s", "distinct hubs", "hub nodes"],
            rows,
            [
                f"jittered / periodic time = {ratio:.2f}; best of 3",
                "distinct hubs: number of distinct hub keys, recomputed with fast_stitch's "
                "private kernels (edge_frames, node_slots); not part of the timing",
            ],
        )
    )
    res["hub_cache"] = {"rows": out, "time_ratio": ratio}


# ============================================================================ goals / main
def goals(res: dict[str, Any], quick: bool) -> None:
    rows, out = [], []

    def add(name: str, value: float | None, target: str, ok: bool | None, shown: str) -> None:
        status = "n/a" if ok is None else ("PASS" if ok else "MISS")
        out.append({"goal": name, "value": value, "target": target, "status": status})
        rows.append([name, shown, target, status])

    big = max(res.get("bunny", {}).get("rows", []), key=lambda r: r["edges"], default=None)
    if big:
        eps = big["edges_per_s"]
        add(
            f"bunny {big['resolution_mm']:g} mm edges/s",
            eps,
            f">= {GOAL_BUNNY_EDGES_PER_S / 1e3:.0f}k",
            eps >= GOAL_BUNNY_EDGES_PER_S,
            fmt_rate(eps),
        )
        add(
            f"bunny {big['resolution_mm']:g} mm time",
            big["time_s"],
            f"< {GOAL_BUNNY_TIME_S} s" + (" (1 mm)" if quick else ""),
            big["time_s"] < GOAL_BUNNY_TIME_S if big["resolution_mm"] == 1.0 else None,
            f"{big['time_s']:.3f} s",
        )
    oc = res.get("octet", {})
    if "edges_per_s" in oc:
        add(
            "jittered octet edges/s",
            oc["edges_per_s"],
            f">= {GOAL_OCTET_EDGES_PER_S / 1e3:.0f}k",
            oc["edges_per_s"] >= GOAL_OCTET_EDGES_PER_S,
            fmt_rate(oc["edges_per_s"]),
        )
    for r in res.get("memory", []):
        if "error" in r:
            continue
        c = r["case"]
        lab = {
            "bunny": f"bunny {c.get('h', 0):g} mm",
            "octet": "octet",
            "bcc": f"bcc {c.get('n')}^3",
        }[c["case"]]
        for key, what in (
            ("stitch_bytes_per_triangle", "stitch"),
            ("save_bytes_per_triangle", "STL"),
        ):
            add(
                f"{lab} {what} B/tri",
                r[key],
                f"<= {GOAL_BYTES_PER_TRIANGLE:g}",
                r[key] <= GOAL_BYTES_PER_TRIANGLE,
                f"{r[key]:.1f}",
            )
    man = res.get("manifold", [])
    if man:
        worst = min(man, key=lambda r: r["ratio"])
        add(
            "manifold / stitch time (min)",
            worst["ratio"],
            f">= {GOAL_MANIFOLD_RATIO:g}x",
            worst["ratio"] >= GOAL_MANIFOLD_RATIO,
            f"{worst['ratio']:,.0f}x ({worst['edges']:,} struts)",
        )
    emit(
        table(
            "Goals" + (" (--quick: small sizes, not representative)" if quick else ""),
            ["goal", "measured", "target", "status"],
            rows,
        )
    )
    res["goals"] = out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="small versions of everything (< 60 s)")
    ap.add_argument("--out", type=Path, default=None, help="JSON output path")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        print(json.dumps(child_memory(json.loads(args.child))))
        return 0

    t_start = time.perf_counter()
    info = machine_info()
    t_warm = warm_up()
    info["numba_threading_layer"] = _threading_layer()
    print(
        f"machine: {info['cpu_count']} CPUs ({info['cpu']}), numba {info['numba']} with "
        f"{info['numba_threads']} threads ({info['numba_threading_layer']}), "
        f"numpy {info['numpy']}, "
        f"manifold3d {info['manifold3d']}, trimesh {info['trimesh']}, python {info['python']}, "
        f"load average {info['loadavg_at_start']}; JIT warm-up {t_warm:.2f} s"
        + (" [--quick]" if args.quick else "")
        + "\n",
        flush=True,
    )
    res: dict[str, Any] = {
        "mode": "quick" if args.quick else "full",
        "machine": info,
        "warm_up_s": t_warm,
    }
    res["loadavg_after"] = {}

    def section(name: str, fn: Callable[[], Any]) -> Any:
        value, dt = timed(fn)
        load = [round(x, 2) for x in os.getloadavg()]
        res["loadavg_after"][name] = load
        print(f"[{name}: {dt:.1f} s; load average after it {load}]\n", flush=True)
        return value

    bunny = section("bunny", lambda: bench_bunny(args.quick, res))
    octet = section("octet", lambda: bench_octet(args.quick, res))
    section("memory", lambda: bench_memory(args.quick, res, bunny, octet))
    section("manifold", lambda: bench_manifold(args.quick, res))
    section("table2", lambda: bench_table2(args.quick, res))
    section("hub_cache", lambda: bench_hub_cache(args.quick, res))
    goals(res, args.quick)
    res["total_s"] = time.perf_counter() - t_start
    out = args.out or RESULTS / ("bench_stitch_quick.json" if args.quick else "bench_stitch.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1, default=float) + "\n")
    print(f"total {res['total_s']:.1f} s; results written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
