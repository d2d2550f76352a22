#!/usr/bin/env python
"""Sharded fill on a Dask LocalCluster (lattice_cad.distributed) against one process.

Run from the repository root (the machine may be shared: load averages and CPU seconds are
printed with every timing)::

    python benchmarks/bench_distributed.py scaling --total 2e6 --shard 1e5,1e6
    python benchmarks/bench_distributed.py big --struts 2e7 --shard 1e6
    python benchmarks/bench_distributed.py single --struts 2e6

The part is the Stanford bunny of ../shared/data (a real, curved part), filled with BCC
cells ("inside" fill, 6-sided struts, radius 8 % of the cell) whose size is chosen for a
target number of struts. Output is one binary STL (streamed from the shard pieces).
``struts/s`` counts written struts per wall second; ``peak RSS`` is a worker process's
resident peak (VmHWM, reset when each task starts, so the build and the stitch phase are
measured apart; it includes the worker's ~0.6 GB of imports), the largest over the tasks the
worker ran; halo overhead is the struts stitched beyond the owned ones, in percent.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PART = ROOT.parent / "shared" / "data" / "meshes" / "bunny_closed_odedstein.obj"
STRUTS_PER_CELL = 8  # BCC: 8 half-diagonals per cell


def load() -> str:
    a = os.getloadavg()
    return f"load {a[0]:.2f} {a[1]:.2f} {a[2]:.2f}"


def cpu_self_children() -> float:
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def cell_for(struts: float) -> float:
    import conformal

    part = conformal.load_part(PART)
    return float((STRUTS_PER_CELL * abs(part.volume) / struts) ** (1 / 3))


def run_sharded(h: float, shards: int, workers: int, out: Path, client=None) -> dict:
    from lattice_cad.distributed import fill_sharded

    t0, c0 = time.perf_counter(), cpu_self_children()
    res = fill_sharded(PART, out, "bcc", h, 0.08 * h, shards=shards, workers=workers,
                       scheduler=client, tmpdir=out.parent)  # fmt: skip
    wall = time.perf_counter() - t0
    task_cpu = sum(s.cpu_seconds for s in res.shards)
    return {
        "struts": res.struts,
        "triangles": res.triangles,
        "shards": len(res.shards),
        "wall": wall,
        "client_cpu": cpu_self_children() - c0,
        "task_cpu": task_cpu,
        "rate": res.struts / wall,
        "rss": res.peak_rss_per_worker,
        "build_rss": res.build_peak_rss_per_worker,
        "halo": res.halo_overhead,
        "seconds": res.seconds,
        "bytes": out.stat().st_size,
        "client_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
        "load": load(),
    }


def run_single(h: float, out: Path) -> dict:
    """One process: conformal.voxel_lattice + fast_stitch.stitch + STL, in a child
    process so that its peak RSS is its own."""
    import subprocess

    code = (
        "import time,resource,sys,numpy as np;import conformal,fast_stitch;"
        "from lattice_cad.core.mesh import Mesh;"
        f"t=time.perf_counter();p=conformal.load_part({str(PART)!r});"
        f"g=conformal.voxel_lattice(p,'bcc',{h!r},{0.08 * h!r},fill='inside');"
        "m=fast_stitch.stitch(g,6);"
        "Mesh(vertices=m.vertices.astype(np.float32).astype(np.float64),faces=m.faces)"
        f".save({str(out)!r});w=time.perf_counter()-t;"
        "r=resource.getrusage(resource.RUSAGE_SELF);"
        "print(g.num_edges,len(m.faces),w,r.ru_utime+r.ru_stime,r.ru_maxrss*1024)"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if p.returncode:
        return {"error": p.stderr.strip().splitlines()[-1] if p.stderr else str(p.returncode)}
    m, f, w, cpu, rss = p.stdout.split()
    return {"struts": int(m), "triangles": int(f), "wall": float(w), "cpu": float(cpu),
            "rss": int(rss), "rate": int(m) / float(w), "load": load()}  # fmt: skip


def fmt_rss(rss: dict) -> str:
    return ", ".join(f"{v / 2**30:.2f}" for _, v in sorted(rss.items()))


def cmd_scaling(args: argparse.Namespace) -> None:
    h = cell_for(args.total)
    print(f"# scaling: bunny, BCC cell {h:.5g} mm (~{args.total:.3g} struts), {load()}")
    print(
        "| shard target | workers | shards | struts | wall s | struts/s | task CPU s | "
        "client CPU s | build peak RSS per worker GiB | stitch peak RSS per worker GiB | "
        "halo % | load |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(dir=args.tmp) as d:
        for shard in args.shard:
            shards = max(1, round(args.total / shard))
            for workers in (1, 2, 1, 2)[: 2 * args.repeat]:  # alternating A/B
                r = run_sharded(h, shards, workers, Path(d) / "s.stl")
                print(f"| {shard:.0e} | {workers} | {r['shards']} | {r['struts']:,} | "
                      f"{r['wall']:.1f} | {r['rate']:,.0f} | {r['task_cpu']:.1f} | "
                      f"{r['client_cpu']:.1f} | {fmt_rss(r['build_rss'])} | {fmt_rss(r['rss'])} | "
                      f"{100 * r['halo']:.1f} | "
                      f"{r['load']} |", flush=True)  # fmt: skip


def cmd_big(args: argparse.Namespace) -> None:
    h = cell_for(args.struts)
    shards = max(2, round(args.struts / args.shard[0]))
    print(f"# big: bunny, BCC cell {h:.5g} mm (~{args.struts:.3g} struts), {shards} shards, "
          f"2 workers, {load()}")  # fmt: skip
    with tempfile.TemporaryDirectory(dir=args.tmp) as d:
        r = run_sharded(h, shards, 2, Path(d) / "big.stl")
        phases = ", ".join(f"{k} {v:.1f}" for k, v in r["seconds"].items())
        print(
            f"struts {r['struts']:,}, triangles {r['triangles']:,}, STL {r['bytes'] / 1e9:.2f} GB"
        )
        print(f"wall {r['wall']:.1f} s ({phases})")
        print(
            f"{r['rate']:,.0f} struts/s; task CPU {r['task_cpu']:.1f} s, client CPU "
            f"{r['client_cpu']:.1f} s; halo {100 * r['halo']:.1f} %"
        )
        print(f"peak RSS per worker (GiB): build {fmt_rss(r['build_rss'])}; stitch "
              f"{fmt_rss(r['rss'])}; client peak RSS "
              f"{r['client_rss'] / 2**30:.2f} GiB; {r['load']}")  # fmt: skip
        project(r, args.struts / shards)


def project(r: dict, shard_struts: float, total: float = 1e9) -> None:
    """A 1B-strut job on N workers, projected from one measured run (same cell, same
    shard size): CPU per strut, peak RSS per worker, triangles per strut."""
    cpu_per_strut = r["task_cpu"] / r["struts"]
    tri_per_strut = r["triangles"] / r["struts"]
    rss = max(max(r["rss"].values()), max(r["build_rss"].values(), default=0))
    shards = total / shard_struts
    tris = total * tri_per_strut
    asm_rate = r["bytes"] / max(r["seconds"].get("assemble", 0.0), 1e-9)
    print(f"\n## PROJECTION (not a measurement) for a {total:.0e}-strut job, from the run above")
    print(
        f"measured: {1e6 * cpu_per_strut:.1f} us task CPU per strut (halo included), "
        f"{tri_per_strut:.1f} triangles per strut, peak RSS {rss / 2**30:.2f} GiB per worker "
        f"with ~{shard_struts:,.0f}-strut shards, assembly {asm_rate / 1e6:.0f} MB/s"
    )
    print(
        f"job: {shards:,.0f} shards of ~{shard_struts:,.0f} struts, {tris:.3g} triangles "
        f"({tris * 50 / 1e12:.2f} TB as binary STL: beyond STL's 2^32-triangle count, so the "
        "output must stay one file per shard or a beam-lattice 3MF)"
    )
    print(
        "| workers (1 core each) | stitch+build wall (h) | peak RSS per worker GiB | "
        "cluster RAM GiB |"
    )
    print("|---|---|---|---|")
    for n in (2, 16, 64, 256, 1024):
        wall = -(-shards // n) * shard_struts * cpu_per_strut / 3600  # rounds of shards
        print(f"| {n} | {wall:.2f} | {rss / 2**30:.2f} | {n * rss / 2**30:.0f} |")


def cmd_single(args: argparse.Namespace) -> None:
    h = cell_for(args.struts)
    print(f"# single process: bunny, BCC cell {h:.5g} mm (~{args.struts:.3g} struts), {load()}")
    with tempfile.TemporaryDirectory(dir=args.tmp) as d:
        r = run_single(h, Path(d) / "one.stl")
    if "error" in r:
        print(f"single process failed: {r['error']}")
        return
    print(f"struts {r['struts']:,}, triangles {r['triangles']:,}, wall {r['wall']:.1f} s, "
          f"{r['rate']:,.0f} struts/s, CPU {r['cpu']:.1f} s, peak RSS {r['rss'] / 2**30:.2f} GiB; "
          f"{r['load']}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("scaling", "big", "single"))
    ap.add_argument("--total", type=float, default=2e6)
    ap.add_argument("--struts", type=float, default=2e7)
    ap.add_argument("--shard", type=lambda s: [float(x) for x in s.split(",")], default=[1e6])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--tmp", default=None)
    args = ap.parse_args()
    print(f"$ {' '.join(sys.argv)}  (nproc {os.cpu_count()}, {load()})")
    {"scaling": cmd_scaling, "big": cmd_big, "single": cmd_single}[args.mode](args)


if __name__ == "__main__":
    main()
