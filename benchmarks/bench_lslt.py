"""LSLT (Chougrani et al. 2017) vs the default (Verma et al. 2019) stitcher.

Prints, for a BCC lattice filling a bunny-like shape and for a box (cubic)
lattice:

1. triangle counts of both methods at equal chord error (1, 2, 5, 10 % of the
   strut radius): the default method uses ``P = segments_for_chord_error(e)``
   segments per profile, LSLT the same angular resolution (no gap between
   consecutive section vertices above ``2 pi / P``);
2. the triangle-quality distribution, ``2 * inradius / circumradius`` (1 for an
   equilateral triangle), in deciles as in the paper's Figs. 20-21: decile 1 is
   quality in (0.9, 1], decile 10 is [0, 0.1]; for the default method, LSLT
   without intermediary sections and LSLT with ``sections="auto"`` (Eq. 11).

Set-up (the paper's Table 1 for the bunny: 7 mm cells, R = 0.5 mm):

* bunny: ``../shared/data/meshes/bunny_closed_odedstein.obj`` (beside the repository) (vertices
  merged), bounding-box minimum moved to the origin and scaled uniformly so
  that its largest extent is 100 mm; a block of 7 mm BCC cells covering it,
  keeping the cells whose centre is inside (``trimesh.Trimesh.contains``);
  R = 0.5 mm;
* box: the cubic cell on a 13 x 13 x 7 grid of 1.5 mm cells (the 20 x 20 x 10 mm
  cuboid of Verma et al. Table 2), R = 0.25 mm.

Every mesh is checked for watertightness and orientation (trimesh); timings
are best of 3 after a warm-up call. ``python benchmarks/bench_lslt.py``
(``--quick`` skips the checks and uses one timing run).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import trimesh

import fast_stitch
from conformal.cells import tile
from fast_stitch.lslt import segments_for_chord_error, stitch_lslt, triangle_quality
from lattice_cad import LatticeGraph

#: The shared test data beside the repository root (../shared), never an absolute path.
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BUNNY_PATH = DATA / "meshes" / "bunny_closed_odedstein.obj"
ERRORS = (0.01, 0.02, 0.05, 0.10)


def bunny_bcc(cell: float = 7.0, size: float = 100.0, radius: float = 0.5) -> LatticeGraph:
    """BCC cells (edge ``cell`` mm) whose centre is inside the bunny scaled to ``size`` mm."""
    m = trimesh.load(BUNNY_PATH, force="mesh", process=False)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    v = np.asarray(m.vertices, dtype=np.float64)
    v = (v - v.min(axis=0)) * (size / float(np.ptp(v, axis=0).max()))
    bunny = trimesh.Trimesh(v, m.faces, process=True)
    n = np.ceil(v.max(axis=0) / cell).astype(int)
    ijk = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    inside = bunny.contains((ijk + 0.5) * cell)
    return tile("bcc", ijk[inside], cell_size=cell, radius=radius)


def box_cubic() -> LatticeGraph:
    i = np.stack(np.meshgrid(np.arange(13), np.arange(13), np.arange(7), indexing="ij"), -1)
    return tile("cubic", i.reshape(-1, 3), cell_size=1.5, radius=0.25)


def best_time(fn, runs: int) -> tuple[float, object]:
    out = fn()  # warm-up (JIT, caches)
    best = float("inf")
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def check(mesh: fast_stitch.Mesh) -> str:
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    ok = tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    return "ok" if ok else "INVALID"


def deciles(q: np.ndarray) -> list[float]:
    """% of triangles per quality decile; decile 1 = (0.9, 1], decile 10 = [0, 0.1]."""
    idx = np.clip(np.ceil((1.0 - q) * 10.0 - 1e-12).astype(int), 1, 10)
    idx[q >= 1.0 - 1e-12] = 1
    return [100.0 * float(np.mean(idx == k)) for k in range(1, 11)]


def run(name: str, g: LatticeGraph, quick: bool) -> None:
    runs = 1 if quick else 3
    print(f"\n## {name}: {g.num_nodes} nodes, {g.num_edges} struts")
    head = (
        f"{'chord err':>9} {'P':>4} {'verma tris':>11} {'lslt tris':>10} {'lslt/verma':>10} "
        f"{'verma s':>8} {'lslt s':>8} {'lslt+auto tris':>14} {'valid':>6}"
    )
    print(head)
    print("-" * len(head))
    meshes = {}
    for e in ERRORS:
        P = segments_for_chord_error(e)
        tv, mv = best_time(lambda P=P: fast_stitch.stitch(g, P), runs)
        tl, ml = best_time(lambda e=e: stitch_lslt(g, chord_error=e), runs)
        ma = stitch_lslt(g, chord_error=e, sections="auto")
        valid = "-" if quick else ("ok" if {check(mv), check(ml), check(ma)} == {"ok"} else "BAD")
        nv, nl = len(mv.faces), len(ml.faces)
        print(
            f"{100 * e:>8.0f}% {P:>4d} {nv:>11,d} {nl:>10,d} {nl / nv:>10.3f} "
            f"{tv:>8.3f} {tl:>8.3f} {len(ma.faces):>14,d} {valid:>6}"
        )
        meshes[e] = (mv, ml, ma)
    for e in (0.05, 0.01):
        mv, ml, ma = meshes[e]
        print(f"\nTriangle quality 2 r_in / R_circ at {100 * e:.0f}% chord error: % of triangles")
        print(f"{'decile':>22} " + " ".join(f"{k:>5d}" for k in range(1, 11)) + "   median")
        for label, m in (("default (Verma)", mv), ("LSLT", ml), ("LSLT sections=auto", ma)):
            q = triangle_quality(m)
            row = " ".join(f"{p:>5.1f}" for p in deciles(q))
            print(f"{label:>22} {row}   {np.median(q):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one timing run, no validity checks")
    args = ap.parse_args()
    import numba

    print(f"numba threads: {numba.get_num_threads()}")
    run("BCC in the bunny (7 mm cells, R = 0.5 mm)", bunny_bcc(), args.quick)
    run("Box lattice (cubic, 13 x 13 x 7 cells of 1.5 mm, R = 0.25 mm)", box_cubic(), args.quick)


if __name__ == "__main__":
    main()
