"""Rotation reuse of the exact reference on the GE bracket lattices (issue 14, item 2).

Prints, per lattice, the distinct units built up to translation and up to rotation (hubs
only; clusters and leaves stay translation-only), then builds the whole reference with
``reuse`` given (2 worker processes, the up-front estimate and the progress bar) and
prints wall and CPU seconds (this process and its workers), hubs placed per CPU second and
per wall second, and the load average.

Usage::

    python benchmarks/bench_rotation_reuse.py [--lattice voxel|tet] [--reuse rotation|translation]
        [--count-only] [--graphs DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _cpu() -> float:
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lattice", choices=["voxel", "tet"], default="voxel")
    ap.add_argument("--reuse", choices=["rotation", "translation"], default="rotation")
    ap.add_argument("--count-only", action="store_true")
    ap.add_argument("--graphs", type=Path, default=None, help="cache directory of the graphs")
    a = ap.parse_args()
    import trimesh
    from bench_hub_profile import graph

    from reference_boolean import build_reference
    from reference_boolean.reference import _unit_specs

    g = graph(a.lattice, a.graphs)
    t0 = time.perf_counter()
    tra = _unit_specs(g, True)
    rot = _unit_specs(g, True, rotations=True)
    print(f"GE {a.lattice}: {g.num_nodes:,} nodes, {g.num_edges:,} struts, "
          f"{len(tra.template):,} units placed; distinct up to translation {len(tra.specs):,}, "
          f"up to rotation {len(rot.specs):,} ({int(rot.turned().sum()):,} turned copies); "
          f"{time.perf_counter() - t0:.1f} s for both", flush=True)  # fmt: skip
    if a.count_only:
        return
    load0 = os.getloadavg()
    c0, w0 = _cpu(), time.perf_counter()
    ref = build_reference(g, keep_solids=False, progress=True, reuse=a.reuse)
    cpu, wall = _cpu() - c0, time.perf_counter() - w0
    tm = trimesh.Trimesh(ref.mesh.vertices, ref.mesh.faces, process=False)
    n = len(ref.units.template)
    print(f"reuse={a.reuse}: {ref!r}\n  built {ref.unique_hubs:,} distinct, reused "
          f"{ref.cache_hits:,}; wall {wall:.0f} s, CPU {cpu:.0f} s (incl. workers); "
          f"{n / cpu:.2f} units placed per CPU s, {n / wall:.2f} per wall s; "
          f"{ref.unique_hubs / cpu:.2f} built per CPU s; timings "
          f"{ {k: round(v, 1) for k, v in ref.timings.items()} }\n  watertight "
          f"{tm.is_watertight}, winding {tm.is_winding_consistent}, volume {ref.volume:.6f} "
          f"(mesh {tm.volume:.6f}), failed {len(ref.failed)}; load {load0[0]:.1f} -> "
          f"{os.getloadavg()[0]:.1f}", flush=True)  # fmt: skip
    if ref.failed:
        print("  e.g.", list(ref.failed.items())[:3])
    np.save(f"/tmp/hubfast_{a.lattice}_{a.reuse}_hubvol.npy", ref.hub_volume)


if __name__ == "__main__":
    main()
