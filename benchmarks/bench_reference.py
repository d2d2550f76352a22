"""Benchmarks of reference_boolean.build_reference (printed tables).

1. A periodic lattice of ~10k hubs (cubic block, 21^3 cells): build time with the hub cache.
2. An irregular lattice (jittered cubic grid, every hub distinct): hubs per second.
   Seed anchor (Wang, Chen & Rosen, Table 1): 4,662 struts in 1,361 s on 2005 hardware.
3. The seed's Table 2 box lattice (13 x 13 x 7 cubic cells of 1.5 mm, R = 0.25 mm):
   fast_stitch's volume error against the exact reference at P = 3, 4, 6, 10, 18, 24,
   with and without ``volume_preserving``.

4. ``--refused`` (issue 14): how many lattices the reference refuses, over every fill mode
   (bcc inside, bcc clip, kelvin conform, tet) on the parts in ``../shared/data``: cell =
   largest extent / 8, radius = cell / 12, lattices of at most ``--max-struts`` struts.
   For each: the places the former per-hub check (``find_overlaps``) refused, the clusters
   now built as one solid, whether the reference is complete and watertight (trimesh and
   manifold3d), and its time.

Usage: ``python benchmarks/bench_reference.py [--quick] [--refused [--max-struts N]]``
"""

from __future__ import annotations

import argparse
import inspect
import os
import time
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


REFUSED_SETTINGS: dict[str, dict[str, object]] = {
    "bcc": {"cell": "bcc", "fill": "inside"},
    "clip": {"cell": "bcc", "fill": "clip"},
    "conform": {"cell": "kelvin", "fill": "conform"},
    "tet": {"method": "tet"},
}


def bench_refused(
    max_struts: int = 1500,
    parts: list[str] | None = None,
    settings: list[str] | None = None,
    budget: float = 3600.0,
    build_max_struts: int = 600,
) -> list[list[str]]:
    """Issue 14: count the lattices the exact reference refuses, over every fill mode."""
    from pathlib import Path

    data = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    files = sorted((data / "step").glob("*")) + sorted((data / "meshes").glob("*"))
    if parts:
        files = [f for f in files if any(p in f.name for p in parts)]
    rows: list[list[str]] = []
    t_start = time.perf_counter()
    counts = {"refused": 0, "refused before": 0, "built": 0, "skipped": 0}
    try:
        _refused_rows(files, settings, max_struts, build_max_struts, budget, t_start, rows, counts)
    except KeyboardInterrupt:  # Ctrl-C: print the partial table
        print("interrupted: partial table", flush=True)
    print(
        table(
            "4. Lattices refused by the exact reference (issue 14; cell = extent / 8, "
            f"r = cell / 12, at most {max_struts:,} struts, built up to {build_max_struts:,})",
            ["part", "fill", "struts", "leaves", "former check", "clusters, solids", "reference"],
            [r + [""] * (7 - len(r)) if len(r) < 7 else r for r in rows],
        )
    )
    print(
        f"refused now: {counts['refused']} of {counts['built']} built; refused by the former "
        f"per-hub check: {counts['refused before']} of {len(rows)} lattices; "
        f"not built: {counts['skipped']}"
    )
    return rows


def _refused_rows(
    files: list[Any],
    settings: list[str] | None,
    max_struts: int,
    build_max_struts: int,
    budget: float,
    t_start: float,
    rows: list[list[str]],
    counts: dict[str, int],
) -> None:
    import resource
    import warnings

    from conformal import load_part
    from lattice_cad import Lattice
    from reference_boolean import find_overlaps
    from reference_boolean.compare import mesh_validity
    from reference_boolean.reference import _unit_specs

    for f in files:
        for name, opts in REFUSED_SETTINGS.items():
            if settings and name not in settings:
                continue
            row = [f.name[:34], name]
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    part = load_part(f)
                    cell = float(np.max(part.size)) / 8.0
                    lat = Lattice.fill(part, cell_size=cell, radius=cell / 12.0, **opts)
                g = lat.graph
            except Exception as exc:
                rows.append(row + ["-", "-", "-", "-", "-", f"no lattice: {type(exc).__name__}"])
                print("  ".join(rows[-1]), flush=True)
                continue
            old = find_overlaps(g)
            counts["refused before"] += bool(old)
            row += [f"{g.num_edges:,}", str(int((g.degree == 1).sum()))]
            row.append(f"refused ({len(old)})" if old else "clean")
            units = _unit_specs(g, True)  # the clustering alone (cheap): never refuses
            multi = [len(m) for m in units.members if len(m) > 1]
            plan = f"{len(multi)} (max {max(multi, default=1)}), {len(units.specs)} solids"
            why = ""
            if g.num_edges > max_struts:
                why = f"skipped: {g.num_edges:,} > {max_struts:,} struts"
            elif g.num_edges > build_max_struts:
                why = f"not built: {g.num_edges:,} > {build_max_struts:,} struts"
            elif time.perf_counter() - t_start > budget:
                why = "not built: time budget spent"
            if why:
                counts["skipped"] += 1
                rows.append(row + [plan, why])
                print("  ".join(rows[-1]), flush=True)
                continue
            t = time.perf_counter()
            c0 = time.process_time()
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            try:
                ref = build_reference(g, keep_solids=False, hub_timeout=120.0)
            except Exception as exc:
                counts["refused"] += 1
                rows.append(row + ["-", f"REFUSED: {type(exc).__name__}: {str(exc)[:60]}"])
                print("  ".join(rows[-1]), flush=True)
                continue
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = time.process_time() - c0 + (r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
            wall = time.perf_counter() - t
            counts["built"] += 1
            row.append(plan)
            if not ref.complete:
                counts["refused"] += 1
                n, why = next(iter(ref.failed.items()))
                verdict = f"INCOMPLETE {len(ref.failed)} nodes, e.g. {n}: {why[:50]}"
            else:
                v = mesh_validity(ref.mesh)
                verdict = "ok, watertight" if v["valid"] else f"ok, mesh {v}"
            load = os.getloadavg()[0]
            rows.append(row + [f"{verdict}; {wall:.0f} s wall, {cpu:.0f} s cpu, load {load:.1f}"])
            print("  ".join(rows[-1]), flush=True)


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
    ap.add_argument("--refused", action="store_true", help="issue 14: lattices refused (only)")
    ap.add_argument("--max-struts", type=int, default=1500, help="with --refused")
    ap.add_argument("--parts", nargs="+", default=None, help="with --refused: name filters")
    ap.add_argument("--settings", nargs="+", default=None, choices=list(REFUSED_SETTINGS))
    ap.add_argument("--budget", type=float, default=3600.0, help="with --refused: seconds")
    ap.add_argument(
        "--build-max-struts", type=int, default=600, help="with --refused: build up to this"
    )
    a = ap.parse_args()
    if a.refused:
        print(f"cpus {os.cpu_count()}, load {os.getloadavg()}\n")
        bench_refused(a.max_struts, a.parts, a.settings, a.budget, a.build_max_struts)
        return
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
