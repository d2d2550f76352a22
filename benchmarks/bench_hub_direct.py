"""Hubs built face by face vs the boolean chain (issue 14, "Fast"; hub_direct.py).

On a seeded sample of the distinct single hubs of the GE bracket lattices (tet 5 mm, Box-BCC
5.5 mm clip), builds every hub twice in this process, alternating the order (ABBA):
A = the boolean chain (``truss.DIRECT = False``), B = the direct construction first
(``truss.DIRECT = True``, the booleans as its fallback), exactly as a worker does
(:func:`reference_boolean.reference._build_one`, no BREP bytes). Prints CPU seconds and hubs
per CPU second of each, which path B took, the volume agreement B/A and the midpoint
circles' point counts, and B's stage table (:class:`lattice_cad.occ_impl.truss.StageClock`).

Usage::

    python benchmarks/bench_hub_direct.py [--lattice tet|voxel|both] [--sample N]
        [--graphs DIR]   # cache of the lattice graphs (.npz), built once (~50 s each)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_hub_profile import STAGES, graph, table  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lattice", choices=["tet", "voxel", "both"], default="both")
    ap.add_argument("--sample", type=int, default=40)
    ap.add_argument("--graphs", type=Path, default=None)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    from lattice_cad.core import config
    from lattice_cad.occ_impl import truss
    from reference_boolean.reference import _build_one, _unit_specs

    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}", flush=True)
    for kind in ["tet", "voxel"] if a.lattice == "both" else [a.lattice]:
        g = graph(kind, a.graphs)
        u = _unit_specs(g, True)
        hubs = [s for s in u.specs if isinstance(s, truss.HubSpec)]
        tol = config.DEFAULT_TOLERANCE_REL * float(g.radii.min())
        rng = np.random.default_rng(a.seed)
        pick = np.sort(rng.choice(len(hubs), size=min(a.sample, len(hubs)), replace=False))
        cpu = {"A": 0.0, "B": 0.0}
        paths: Counter[str] = Counter()
        stages: dict[str, float] = {}
        worst, kdiff, fails = 0.0, 0, []
        load0 = os.getloadavg()[0]
        for n, i in enumerate(pick):
            s = hubs[int(i)]
            res = {}
            for v in "AB" if n % 2 == 0 else "BA":
                truss.DIRECT = v == "B"
                c = time.process_time()
                res[v] = _build_one((s, tol, config.DEFAULT_ANGULAR, False))
                cpu[v] += time.process_time() - c
            truss.DIRECT = True
            ra, rb = res["A"], res["B"]
            paths[rb.attempts[-1].split(":")[0] + ("" if rb.status == "ok" else " (failed)")] += 1
            if len(rb.attempts) > 1 and rb.attempts[0].startswith("direct"):
                paths["  of which direct declined, then booleans"] += 1
            for k, t in rb.stages.items():
                stages[k] = stages.get(k, 0.0) + t
            if ra.status != "ok" or rb.status != "ok":
                fails.append((int(i), ra.status, rb.status))
                continue
            worst = max(worst, abs(rb.volume / ra.volume - 1.0))
            kdiff += [len(c) for c in ra.circles] != [len(c) for c in rb.circles]
        m = len(pick)
        rows = [[v, str(m), f"{t:.2f}", f"{t / m * 1e3:.0f}", f"{m / t:.2f}"]
                for v, t in cpu.items()]  # fmt: skip
        print(
            table(
                f"GE {kind}: {m} of {len(hubs):,} distinct single hubs, alternating A/B; "
                f"A = boolean chain, B = direct first; load {load0:.1f} -> "
                f"{os.getloadavg()[0]:.1f}",
                ["variant", "hubs", "CPU s", "ms per hub", "hubs per CPU s"],
                rows,
            ),
            flush=True,
        )
        print(f"B's path: {dict(paths)}")
        print(
            f"volume |B/A - 1| max {worst:.1e}; hubs whose circle point counts differ: "
            f"{kdiff}; failures (A or B): {fails[:5]}"
        )
        tot = sum(stages.values())
        print(table(f"B per stage (CPU s over the {m} hubs)",
                    ["stage", "CPU s", "ms per hub", "share"],
                    [[k, f"{stages.get(k, 0.0):.2f}", f"{stages.get(k, 0.0) / m * 1e3:.1f}",
                      f"{stages.get(k, 0.0) / tot:.0%}"] for k in STAGES]),
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
