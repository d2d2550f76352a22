"""Every distinct single hub with stumps of different radii or tapered (issue 14): A/B.

On the GE bracket lattices (``tet`` = tet 5 mm r 0.25, ``voxel`` = Box-BCC 5.5 mm clip r
0.25; graphs cached as .npz in ``--graphs``), builds each hub that
``hub_direct.direct_applies`` declines with "stumps of different radii or tapered" twice in
this process, alternating the order (AB, BA, ...): A = the boolean chain (``truss.DIRECT``
off), B = as a worker builds it now (direct+fuse where a group of equal cylinder stumps
exists, else the booleans). Prints CPU seconds, hubs per CPU s, B's paths, the volume
agreement and the midpoint circles' point counts.

Usage::

    python benchmarks/bench_hub_unequal.py voxel|tet [N] [--graphs=DIR]
"""

from __future__ import annotations

import collections
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_hub_profile import graph

from lattice_cad.core import config
from lattice_cad.occ_impl import hub_direct, truss
from reference_boolean.reference import _build_one, _unit_specs

if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--graphs")]
    cache = next(
        (Path(a.split("=", 1)[1]) for a in sys.argv[1:] if a.startswith("--graphs=")), None
    )
    kind = args[0]
    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}", flush=True)
    g = graph(kind, cache)
    u = _unit_specs(g, True)
    hubs = [
        s
        for s in u.specs
        if isinstance(s, truss.HubSpec)
        and hub_direct.direct_applies(s) == "stumps of different radii or tapered"
    ]
    tol = config.DEFAULT_TOLERANCE_REL * float(g.radii.min())
    cpu = {"A": 0.0, "B": 0.0}
    paths = collections.Counter()
    worst = 0
    kd = 0
    fails = []
    n = int(args[1]) if len(args) > 1 else len(hubs)
    for i, s in enumerate(hubs[:n]):
        res = {}
        for v in "AB" if i % 2 == 0 else "BA":
            truss.DIRECT = v == "B"
            c = time.process_time()
            res[v] = _build_one((s, tol, config.DEFAULT_ANGULAR, False))
            cpu[v] += time.process_time() - c
        truss.DIRECT = True
        rb = res["B"]
        ra = res["A"]
        paths[rb.attempts[-1].split(":")[0]] += 1
        if len(rb.attempts) > 1:
            paths["declined: " + rb.attempts[0][:90]] += 1
        if ra.status != "ok" or rb.status != "ok":
            fails.append((i, ra.status, rb.status))
            continue
        worst = max(worst, abs(rb.volume / ra.volume - 1))
        kd += [len(c) for c in ra.circles] != [len(c) for c in rb.circles]
    print(
        kind,
        n,
        "hubs (all with different radii or tapered)",
        {k: f"{v:.2f}" for k, v in cpu.items()},
        "hubs/CPU s A",
        n / cpu["A"],
        "B",
        n / cpu["B"],
    )
    for k, v in paths.most_common():
        print(f"  {v:4d} {k}")
    print("max |B/A-1|", worst, "circle count diffs", kd, "fails", fails)
