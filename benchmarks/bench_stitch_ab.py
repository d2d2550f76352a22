"""Alternating A/B timing of the default ``fast_stitch.stitch`` between two checkouts.

Each run is a fresh subprocess (JIT warmed up on a small block first) with ``PYTHONPATH``
set to the checkout, in the order A B A B ...; wall and CPU seconds (process-wide, all
threads) and the load average are printed per run, then the best of each side and the
ratios. Run from anywhere::

    python benchmarks/bench_stitch_ab.py --a /work/main --b . --cases bcc51 --rounds 2

Cases: ``bccN`` (``conformal.cells.block("bcc", N)``, r 0.1: bcc51 has 1.06 M struts) or
the path of an ``.npz`` graph (``nodes``, ``edges``, ``radii``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, os, sys, time
import numpy as np
import fast_stitch
from conformal.cells import block
from lattice_cad.core.graph import LatticeGraph

case = sys.argv[1]
if case.startswith("bcc"):
    g = block("bcc", int(case[3:]), cell_size=1.0, radius=0.1)
else:
    z = np.load(case)
    g = LatticeGraph(z["nodes"], z["edges"], z["radii"])
g.incidence
fast_stitch.stitch(block("bcc", 2, cell_size=1.0, radius=0.1), 6)  # JIT warm-up
t0, c0 = time.perf_counter(), time.process_time()
m = fast_stitch.stitch(g, 6)
t, c = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({"struts": int(g.num_edges), "wall": t, "cpu": c, "triangles": len(m.faces),
                  "vertices": len(m.vertices), "volume": float(m.volume),
                  "load": os.getloadavg()[0], "src": fast_stitch.__file__}))
"""


def run(path: str, case: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(Path(path).resolve()))
    out = subprocess.run(
        [sys.executable, "-c", CHILD, case], env=env, capture_output=True, text=True,
        check=True, cwd="/tmp", timeout=1800,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="checkout A (before)")
    ap.add_argument("--b", required=True, help="checkout B (after)")
    ap.add_argument("--cases", nargs="+", default=["bcc51"])
    ap.add_argument("--rounds", type=int, default=2)
    a = ap.parse_args()
    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}")
    for case in a.cases:
        best: dict[str, dict] = {}
        for k in range(a.rounds):
            for side, path in (("A", a.a), ("B", a.b)):
                r = run(path, case)
                print(
                    f"{case} round {k + 1} {side}: {r['wall']:.2f} s wall, {r['cpu']:.2f} s CPU, "
                    f"{r['triangles']:,} triangles, volume {r['volume']:.4f}, load "
                    f"{r['load']:.1f} ({Path(r['src']).parent.parent})",
                    flush=True,
                )
                if side not in best or r["cpu"] < best[side]["cpu"]:
                    best[side] = r
        A, B = best["A"], best["B"]
        print(
            f"{case} ({A['struts']:,} struts) best of {a.rounds}: B/A wall "
            f"{B['wall'] / A['wall']:.2f}, CPU {B['cpu'] / A['cpu']:.2f}, triangles "
            f"{B['triangles'] / A['triangles']:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
