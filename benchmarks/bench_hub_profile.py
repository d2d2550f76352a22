"""Where the CPU time of one hub (and one cluster) of the exact reference goes (issue 14,
item 2).

Builds a seeded sample of the distinct hubs and clusters of the GE bracket lattices in this
process, exactly as a worker does (:func:`reference_boolean.reference._build_one`), and
prints per stage (:class:`lattice_cad.occ_impl.truss.StageClock`: primitives with their
BRepCheck, general fuse, BRepCheck of the result, GProp volume, BRepMesh, reading the
triangles, merging/circle loops, BREP bytes) the CPU seconds in total, per hub and as a
share; pickling of the spec and the result (what crosses the process boundary); and the
fuse time per hub degree. Singles hubs, clusters (with their size distribution) and leaves
get their own tables.

Usage::

    python benchmarks/bench_hub_profile.py [--lattice tet|voxel|both] [--sample N]
        [--graphs DIR]   # cache of the lattice graphs (.npz), built once (~50 s each)
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

STAGES = ["primitives", "fuse", "check", "volume", "mesh", "extract", "circles", "brep"]


def table(title: str, cols: list[str], rows: list[list[str]]) -> str:
    w = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(cols)]
    line = "  ".join(c.rjust(w[i]) for i, c in enumerate(cols))
    out = [title, line, "-" * len(line)]
    out += ["  ".join(x.rjust(w[i]) for i, x in enumerate(r)) for r in rows]
    return "\n".join(out) + "\n"


def graph(kind: str, cache: Path | None):
    """The GE bracket lattice ``kind`` ("tet" or "voxel"), from ``cache`` if there."""
    from lattice_cad import LatticeGraph

    f = cache / f"ge_{kind}.npz" if cache else None
    if f is not None and f.exists():
        d = np.load(f)
        return LatticeGraph(d["nodes"], d["edges"], d["radii"])
    from bench_reference import ge_lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = ge_lattice(kind)
    if f is not None:
        f.parent.mkdir(parents=True, exist_ok=True)
        np.savez(f, nodes=g.nodes, edges=g.edges, radii=g.radii)
    return g


def kind_of(spec) -> str:
    from lattice_cad.occ_impl.cluster import ClusterSpec

    if not isinstance(spec, ClusterSpec):
        return "hub"
    return "leaf" if len(spec.hubs) == 1 else "cluster"


def degree(spec) -> int:
    return len(spec.vecs) + 2 * len(getattr(spec, "inner", ()))


def profile(specs: list, tol: float, angular: float) -> list[dict]:
    """Build each spec in this process; per spec: stages, pickling, wall and CPU."""
    from reference_boolean.reference import _build_one

    rows = []
    for s in specs:
        c0 = time.process_time()
        p = pickle.dumps((s, tol, angular, False))
        pickle.loads(p)
        c1 = time.process_time()
        res = _build_one((s, tol, angular, False))
        c2 = time.process_time()
        q = pickle.dumps(res)
        pickle.loads(q)
        c3 = time.process_time()
        st = dict(res.stages)
        st["pickle"] = (c1 - c0) + (c3 - c2)
        st["other"] = max((c2 - c1) - sum(res.stages.values()), 0.0)
        rows.append({"kind": kind_of(s), "deg": degree(s), "size": len(getattr(s, "hubs", [0])),
                     "stages": st, "cpu": c3 - c0, "ok": res.status == "ok",
                     "status": res.status, "bytes": len(p) + len(q),
                     "tris": len(res.faces)})  # fmt: skip
    return rows


def stage_table(title: str, rows: list[dict]) -> str:
    if not rows:
        return f"{title}: none in the sample\n"
    names = STAGES + ["pickle", "other"]
    tot = {k: sum(r["stages"].get(k, 0.0) for r in rows) for k in names}
    all_ = sum(tot.values())
    n = len(rows)
    out = [[k, f"{tot[k]:.2f}", f"{tot[k] / n * 1e3:.1f}", f"{tot[k] / all_:.1%}"] for k in names]
    out.append(["total", f"{all_:.2f}", f"{all_ / n * 1e3:.1f}", "100%"])
    ok = sum(r["ok"] for r in rows)
    return table(
        f"{title}: {n} built ({ok} ok), {n / all_:.3f} per CPU s, mean degree "
        f"{np.mean([r['deg'] for r in rows]):.1f}, {np.mean([r['tris'] for r in rows]):,.0f} "
        f"triangles, {np.mean([r['bytes'] for r in rows]) / 1e3:.0f} kB pickled each "
        f"(load {os.getloadavg()[0]:.1f})",
        ["stage", "CPU s total", "ms per unit", "share"],
        out,
    )


def degree_table(title: str, rows: list[dict]) -> str:
    degs = sorted({r["deg"] for r in rows})
    out = []
    for d in degs:
        sel = [r for r in rows if r["deg"] == d]
        fuse = np.mean([r["stages"].get("fuse", 0.0) for r in sel])
        cpu = np.mean([r["cpu"] for r in sel])
        out.append([str(d), str(len(sel)), f"{fuse:.3f}", f"{cpu:.3f}", f"{1 / cpu:.2f}"])
    return table(title, ["degree", "n", "fuse CPU s", "total CPU s", "per CPU s"], out)


def use_main(on: bool) -> None:
    """Make this process build as main does (``on``): the sphere always fused, one general
    fuse first (no pairwise tree); ``on=False`` restores this branch."""
    from lattice_cad.occ_impl import cluster, truss

    if not hasattr(truss, "_branch"):
        truss._branch = (truss.sphere_is_covered, truss.ATTEMPTS, cluster.CLUSTER_ATTEMPTS)
    cov, att, catt = truss._branch
    if on:
        cov = lambda *a, **k: False  # noqa: E731
        att = tuple(x for x in att if x[0] != "tree")
        catt = tuple(x for x in catt if x[0] != "tree")
    truss.DIRECT = not on  # main builds every hub with booleans (no hub_direct)
    truss.sphere_is_covered = cluster.sphere_is_covered = cov
    truss.ATTEMPTS = cluster.ATTEMPTS = att
    cluster.CLUSTER_ATTEMPTS = catt


def ab(specs: list, tol: float, angular: float, rounds: int) -> dict[str, list[float]]:
    """Alternating A/B in this process: A = main's primitives (the sphere always fused), B =
    this branch (the covered sphere left out). Per unit, ABBA order; CPU seconds per build."""
    from reference_boolean.reference import _build_one

    cpu: dict[str, list[float]] = {"A": [], "B": []}
    for rnd in range(rounds):
        for s in specs:
            vols = {}
            for v in "AB" if rnd % 2 == 0 else "BA":
                use_main(v == "A")
                try:
                    c = time.process_time()
                    res = _build_one((s, tol, angular, False))
                    cpu[v].append(time.process_time() - c)
                finally:
                    use_main(False)
                vols[v] = res.volume
                if res.status != "ok":
                    print(f"  {v} failed: {res.status}")
            print(f"  {kind_of(s)} degree {degree(s)}: A {cpu['A'][-1]:.3f} s, B "
                  f"{cpu['B'][-1]:.3f} s, volume B/A - 1 = {vols['B'] / vols['A'] - 1:+.1e} "
                  f"(B: {res.attempts[-1]})",
                  flush=True)  # fmt: skip
    return cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lattice", choices=["tet", "voxel", "both"], default="both")
    ap.add_argument("--sample", type=int, default=24, help="units of each kind per lattice")
    ap.add_argument("--graphs", type=Path, default=None, help="cache directory of the graphs")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--ab",
        type=int,
        default=0,
        metavar="N",
        help="instead: alternating A/B (main vs branch construction) on N units",
    )
    ap.add_argument("--max-degree", type=int, default=99, help="with --ab: skip larger")
    ap.add_argument("--min-degree", type=int, default=0, help="with --ab: skip smaller")
    ap.add_argument("--rounds", type=int, default=1, help="with --ab")
    ap.add_argument(
        "--main-primitives",
        action="store_true",
        help="profile main's primitives (the sphere always fused): 'before'",
    )
    a = ap.parse_args()
    from lattice_cad.core import config
    from reference_boolean.reference import _unit_specs

    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}", flush=True)
    if a.main_primitives:
        use_main(True)
        print("main's construction: the sphere always fused, one general fuse (before)")
    kinds = ["tet", "voxel"] if a.lattice == "both" else [a.lattice]
    for kind in kinds:
        g = graph(kind, a.graphs)
        u = _unit_specs(g, True)
        tol = config.DEFAULT_TOLERANCE_REL * float(g.radii.min())
        by_kind: dict[str, list[int]] = {"hub": [], "cluster": [], "leaf": []}
        for i, s in enumerate(u.specs):
            by_kind[kind_of(s)].append(i)
        sizes = np.array([len(u.specs[i].hubs) for i in by_kind["cluster"]], dtype=int)
        sz, cnt = np.unique(sizes, return_counts=True)
        print(f"\nGE {kind}: {g.num_nodes:,} nodes, {g.num_edges:,} struts; distinct units: "
              f"{len(by_kind['hub']):,} hubs, {len(by_kind['cluster']):,} clusters, "
              f"{len(by_kind['leaf']):,} leaves; cluster sizes (nodes: count) "
              + ", ".join(f"{int(s)}: {int(c)}" for s, c in zip(sz, cnt, strict=True)),
              flush=True)  # fmt: skip
        rng = np.random.default_rng(a.seed)
        if a.ab:
            idx = [
                i
                for i in range(len(u.specs))
                if kind_of(u.specs[i]) != "leaf"
                and a.min_degree <= degree(u.specs[i]) <= a.max_degree
            ]
            pick = np.sort(rng.choice(idx, size=min(a.ab, len(idx)), replace=False))
            load0 = os.getloadavg()[0]
            cpu = ab([u.specs[int(i)] for i in pick], tol, config.DEFAULT_ANGULAR, a.rounds)
            rows = [[v, str(len(t)), f"{sum(t):.1f}", f"{sum(t) / len(t):.3f}",
                     f"{len(t) / sum(t):.3f}"] for v, t in cpu.items()]  # fmt: skip
            print(table(f"A/B GE {kind}, {len(pick)} hubs/clusters (degree "
                        f"{a.min_degree}-{a.max_degree}) x "
                        f"{a.rounds} round(s), alternating; A = main (sphere always fused, "
                        "one general fuse), B = branch (covered sphere left out, pairwise "
                        f"tree); load {load0:.1f} -> {os.getloadavg()[0]:.1f}",
                        ["variant", "builds", "CPU s", "CPU s per unit", "units per CPU s"],
                        rows), flush=True)  # fmt: skip
            continue
        all_rows = []
        for k, idx in by_kind.items():
            if not idx:
                continue
            pick = np.sort(rng.choice(idx, size=min(a.sample, len(idx)), replace=False))
            rows = profile([u.specs[int(i)] for i in pick], tol, config.DEFAULT_ANGULAR)
            all_rows += rows
            print(stage_table(f"GE {kind}, {k}s (sample of {len(idx):,})", rows), flush=True)
            bad = [r["status"] for r in rows if not r["ok"]]
            if bad:
                print(f"  failed: {bad[:3]}")
        print(degree_table(f"GE {kind}: per degree (hubs and clusters: stumps incl. inner x2)",
                           all_rows), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
