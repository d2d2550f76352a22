"""Benchmarks of reference_boolean.build_reference (printed tables).

1. A periodic lattice of ~10k hubs (cubic block, 21^3 cells): build time with the hub cache.
2. An irregular lattice (jittered cubic grid, every hub distinct): hubs per second.
   Seed anchor (Wang, Chen & Rosen, Table 1): 4,662 struts in 1,361 s on 2005 hardware.
3. The seed's Table 2 box lattice (13 x 13 x 7 cubic cells of 1.5 mm, R = 0.25 mm):
   fast_stitch's volume error against the exact reference at P = 3, 4, 6, 10, 18, 24,
   of the default mesh (``profile="volume"``) and of ``profile="area"``.

4. ``--volume-table``: volume error against the exact reference, and symmetric surface
   deviation p95 / r, of the default mesh (``profile="volume"``) and of each profile
   option at P = 4, 6, 8, 12, on the GE bracket lattices (BCC 8 mm r 0.6 inside;
   Box-BCC 5.5 mm clip and tet 5 mm where the reference builds) and on Table 2.
   Output also in ``benchmarks/results/bench_reference_volume.txt``.

Usage: ``python benchmarks/bench_reference.py [--quick] [--volume-table]``
"""

from __future__ import annotations

import argparse
import inspect
import os
import time
from pathlib import Path
from typing import Any

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
    has_vp = "profile" in inspect.signature(fast_stitch.stitch).parameters
    rows = []
    for P in (3, 4, 6, 10, 18, 24):
        v = fast_stitch.stitch(g, P).volume
        row = [str(P), f"{v:.2f}", f"{(v - vref) / vref:+.3%}"]
        if has_vp:
            vp = fast_stitch.stitch(g, P, profile="area").volume
            row += [f"{vp:.2f}", f"{(vp - vref) / vref:+.3%}"]
        else:
            row += ["n/a", "n/a"]
        rows.append(row)
    notes = (
        ""
        if has_vp
        else ("\n(profile is not in this fast_stitch.stitch yet: that column is skipped)")
    )
    print(
        table(
            f"3. Seed Table 2 box lattice {counts[0]}x{counts[1]}x{counts[2]} cubic cells "
            "of 1.5 mm, "
            f"R = 0.25 mm, {g.num_edges:,} struts: exact reference volume {vref:.3f} mm^3 "
            f"({'complete' if ref.complete else 'INCOMPLETE'}, built in {dt:.1f} s, "
            f"{ref.unique_hubs} distinct hubs){notes}",
            ["P", "default volume", "rel. error", "profile='area'", "rel. error"],
            rows,
        )
    )


GE_BRACKET = (
    Path(__file__).resolve().parents[1].parent
    / "shared"
    / "data"
    / "step"
    / "dolfiny_ge_bracket_rotated_nonds.step"
)
VOLUME_PROFILES = ("volume", "area", "inscribed", "circumscribed")


def _volume_lattices(quick: bool) -> list[tuple[str, Any]]:
    """(name, builder) of the lattices of the volume table; builders return a graph."""
    from lattice_cad import Lattice

    def ge(cell: str, size: float, radius: float, **kw: Any) -> Any:
        return lambda: Lattice.fill(GE_BRACKET, cell, size, radius, **kw).graph

    counts = (4, 4, 2) if quick else (13, 13, 7)
    out: list[tuple[str, Any]] = [
        (
            f"Table 2 box lattice {counts[0]}x{counts[1]}x{counts[2]} cubic 1.5 mm, R 0.25",
            lambda: block("cubic", counts, cell_size=1.5, radius=0.25),
        ),
        ("GE bracket BCC 8 mm r 0.6 inside", ge("bcc", 8.0, 0.6, fill="inside")),
    ]
    if not quick:
        out += [
            ("GE bracket Box-BCC 5.5 mm r 0.6 clip", ge("box-bcc", 5.5, 0.6, fill="clip")),
            ("GE bracket tet 5 mm r 0.6", ge("bcc", 5.0, 0.6, method="tet")),
        ]
    return out


def bench_volume_table(quick: bool, out_path: Path | None = None) -> str:
    """Volume error and deviation p95 / r of each profile option against the exact reference."""
    import warnings

    from reference_boolean import compare

    text: list[str] = []

    def emit(s: str) -> None:
        print(s, flush=True)
        text.append(s)

    emit(
        f"4. Volume of the fast mesh against the exact reference (cpus {os.cpu_count()}, "
        f"load {os.getloadavg()[0]:.1f}); error = (V_mesh - V_exact) / V_exact; dev = "
        "symmetric surface deviation p95 / r (20k samples per direction)\n"
    )
    for name, build in _volume_lattices(quick):
        t = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                g = build()
        except Exception as exc:  # noqa: BLE001 - report and go on
            emit(f"{name}: lattice not built: {type(exc).__name__}: {exc}\n")
            continue
        tg = time.perf_counter() - t
        t = time.perf_counter()
        try:
            ref = build_reference(g, keep_solids=False)
        except Exception as exc:  # noqa: BLE001 - the reference refuses some lattices
            emit(
                f"{name}: {g.num_nodes:,} nodes, {g.num_edges:,} struts (built in {tg:.0f} s): "
                f"NO REFERENCE: {type(exc).__name__}: {str(exc)[:300]}\n"
            )
            continue
        tr = time.perf_counter() - t
        if not ref.complete:
            emit(f"{name}: reference incomplete ({len(ref.failed)} hubs failed): skipped\n")
            continue
        vref = ref.volume
        r = float(np.median(g.radii))
        leaves = int((g.degree == 1).sum())
        rows = []
        t = time.perf_counter()
        for P in (4, 6, 8, 12):
            row = [str(P)]
            meshes = {}
            for prof in VOLUME_PROFILES:
                ts = time.process_time()
                meshes[prof] = fast_stitch.stitch(g, P, profile=prof)
                if prof == "volume":
                    cpu = time.process_time() - ts
            rep = compare(
                g, meshes=meshes, reference=ref, union_segments=(), samples=20_000
            )
            for prof in VOLUME_PROFILES:
                c = rep.comparisons[prof]
                row += [
                    f"{c.relative_volume_error:+.3%}",
                    f"{c.hausdorff['symmetric']['p95'] / r:.3f}",
                ]
            row.append(f"{cpu:.2f}")
            rows.append(row)
        cols = ["P"]
        for prof in VOLUME_PROFILES:
            label = "default (volume)" if prof == "volume" else prof
            cols += [f"{label} error", "dev"]
        cols.append("default stitch cpu s")
        emit(
            table(
                f"{name}: {g.num_nodes:,} nodes, {g.num_edges:,} struts, {leaves} leaves, "
                f"r {r:g}; exact volume {vref:.4f} mm^3 (reference built in {tr:.0f} s, "
                f"{ref.unique_hubs} distinct hubs; lattice in {tg:.0f} s; meshes and "
                f"deviations in {time.perf_counter() - t:.0f} s)"
                + (
                    "\n(leaves: flat in the mesh; the reference's leaf ends decide whether "
                    "the two model the same design there)"
                    if leaves
                    else ""
                ),
                cols,
                rows,
            )
        )
    result = "\n".join(text) + "\n"
    if out_path is not None:
        out_path.parent.mkdir(parents=True, exist_ok=True)
        out_path.write_text(result)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="small versions, < 1 min")
    ap.add_argument("--only", choices=["periodic", "irregular", "table2"], default=None)
    ap.add_argument(
        "--volume-table",
        action="store_true",
        help="only the volume/deviation table of the profile options (section 4)",
    )
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
    if a.volume_table:
        name = "bench_reference_volume" + ("_quick" if a.quick else "") + ".txt"
        bench_volume_table(a.quick, Path(__file__).resolve().parent / "results" / name)
        return
    for name, fn in (
        ("periodic", bench_periodic),
        ("irregular", lambda q: bench_irregular(q, a.irregular_size)),
        ("table2", bench_table2),
    ):
        if a.only in (None, name):
            fn(a.quick)


if __name__ == "__main__":
    main()
