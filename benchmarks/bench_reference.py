"""Benchmarks of reference_boolean.build_reference (printed tables).

1. A periodic lattice of ~10k hubs (cubic block, 21^3 cells): build time with the hub cache.
2. An irregular lattice (jittered cubic grid, every hub distinct): hubs per second.
   Seed anchor (Wang, Chen & Rosen, Table 1): 4,662 struts in 1,361 s on 2005 hardware.
3. The seed's Table 2 box lattice (13 x 13 x 7 cubic cells of 1.5 mm, R = 0.25 mm):
   fast_stitch's volume error against the exact reference at P = 3, 4, 6, 10, 18, 24,
   with and without ``volume_preserving``.

Usage: ``python benchmarks/bench_reference.py [--quick]``
"""

from __future__ import annotations

import argparse
import inspect
import os
import time

import numpy as np

import fast_stitch
from conformal.cells import block
from lattice_cad import LatticeGraph
from reference_boolean import build_reference


def table(title: str, cols: list[str], rows: list[list[str]]) -> str:
    w = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(cols)]
    line = "  ".join(c.rjust(w[i]) for i, c in enumerate(cols))
    out = [title, line, "-" * len(line)]
    out += ["  ".join(x.rjust(w[i]) for i, x in enumerate(r)) for r in rows]
    return "\n".join(out) + "\n"


def bench_periodic(quick: bool) -> None:
    n = 6 if quick else 21
    g = block("cubic", (n, n, n), cell_size=1.0, radius=0.1)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    rows = [
        [
            f"{g.num_nodes:,}",
            f"{g.num_edges:,}",
            str(ref.unique_hubs),
            f"{ref.cache_hits:,}",
            f"{len(ref.mesh.faces):,}",
            f"{dt:.1f}",
            f"{ref.timings['build']:.1f}",
            f"{ref.timings['stack']:.1f}",
            "PASS" if dt < 60 else "MISS",
            "yes" if ref.complete else "NO",
        ]
    ]
    print(
        table(
            f"1. Periodic cubic lattice {n}^3 cells, r = 0.1, cache on (goal: < 60 s for 10k hubs)",
            [
                "hubs",
                "struts",
                "built",
                "reused",
                "triangles",
                "total s",
                "build s",
                "stack s",
                "goal",
                "complete",
            ],
            rows,
        )
    )


def bench_irregular(quick: bool, size: int | None = None) -> None:
    n = size or (3 if quick else 5)
    g0 = block("cubic", (n, n, n), cell_size=1.0, radius=0.08)
    rng = np.random.default_rng(1)
    nodes = g0.nodes + rng.uniform(-0.12, 0.12, g0.nodes.shape)
    radii = rng.uniform(0.05, 0.09, (g0.num_edges, 2))
    g = LatticeGraph(nodes, g0.edges, radii)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    hubs = int((g.degree > 0).sum())
    deg6 = int((g.degree == 6).sum())
    rows = [
        [
            f"{hubs:,}",
            str(deg6),
            f"{g.num_edges:,}",
            str(ref.unique_hubs),
            f"{dt:.1f}",
            f"{hubs / dt:.2f}",
            f"{g.num_edges / dt:.2f}",
            f"{4662 / 1361:.2f}",
            "yes" if ref.complete else f"NO ({len(ref.failed)} failed)",
        ]
    ]
    print(
        table(
            f"2. Irregular lattice (jittered {n}^3 cubic grid, tapered random radii), "
            f"{min(2, os.cpu_count() or 1)} workers, load {os.getloadavg()[0]:.1f}",
            [
                "hubs",
                "degree 6",
                "struts",
                "built",
                "time s",
                "hubs/s",
                "struts/s",
                "seed struts/s (2005)",
                "complete",
            ],
            rows,
        )
    )


def bench_table2(quick: bool) -> None:
    counts = (4, 4, 2) if quick else (13, 13, 7)
    g = block("cubic", counts, cell_size=1.5, radius=0.25)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    vref = ref.volume
    has_vp = "volume_preserving" in inspect.signature(fast_stitch.stitch).parameters
    rows = []
    for P in (3, 4, 6, 10, 18, 24):
        v = fast_stitch.stitch(g, P).volume
        row = [str(P), f"{v:.2f}", f"{(v - vref) / vref:+.3%}"]
        if has_vp:
            vp = fast_stitch.stitch(g, P, volume_preserving=True).volume
            row += [f"{vp:.2f}", f"{(vp - vref) / vref:+.3%}"]
        else:
            row += ["n/a", "n/a"]
        rows.append(row)
    notes = (
        ""
        if has_vp
        else ("\n(volume_preserving is not in this fast_stitch.stitch yet: that column is skipped)")
    )
    print(
        table(
            f"3. Seed Table 2 box lattice {counts[0]}x{counts[1]}x{counts[2]} cubic cells "
            "of 1.5 mm, "
            f"R = 0.25 mm, {g.num_edges:,} struts: exact reference volume {vref:.3f} mm^3 "
            f"({'complete' if ref.complete else 'INCOMPLETE'}, built in {dt:.1f} s, "
            f"{ref.unique_hubs} distinct hubs){notes}",
            ["P", "fast volume", "rel. error", "vol.-preserving", "rel. error"],
            rows,
        )
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="small versions, < 1 min")
    ap.add_argument("--only", choices=["periodic", "irregular", "table2"], default=None)
    ap.add_argument(
        "--irregular-size", type=int, default=None, help="cells per side of the irregular grid"
    )
    ap.add_argument(
        "--no-trim",
        action="store_true",
        help="stumps start at the node (the construction before trimming, for comparison)",
    )
    a = ap.parse_args()
    if a.no_trim:
        from lattice_cad.core import config

        config.TRIM_FRACTION = 0.0  # stump_start() then returns 0 for every stump (forked workers)
    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}\n")
    for name, fn in (
        ("periodic", bench_periodic),
        ("irregular", lambda q: bench_irregular(q, a.irregular_size)),
        ("table2", bench_table2),
    ):
        if a.only in (None, name):
            fn(a.quick)


if __name__ == "__main__":
    main()
