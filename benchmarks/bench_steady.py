#!/usr/bin/env python
"""Steady lattices: closed-form integral properties vs brute force, and scale.

Run from the repository root::

    python benchmarks/bench_steady.py           # full run (10000^3 brick: several minutes)
    python benchmarks/bench_steady.py --quick   # skips the 10000^3 brick

Table 1: relative differences between ``integral_properties("closed")`` (first
ij-slab + closed-form sums over k, paper Sec. 6) and ``method="brute"`` (every
hub evaluated directly) on screw and swirl lattices, plus degenerate ``W``.

Table 2: time of the closed-form properties of a bent, graded brick (26 racks:
cubic edges of both BCC sub-lattices, body diagonals and face diagonals; over
24e12 beams at 10000^3), reproducing the paper's Fig. 13 claim ("volume of a
10000 x 10000 x 10000 brick with more than 24 x 10^12 beams in under 10
minutes"). The closed form costs ``O(ni nj)`` (the first slab); the brute force
would cost ``O(ni nj nk)``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from steady_screw_tire import tire  # noqa: E402
from steady_swirl_slab import michell_slab  # noqa: E402
from steady_twisted_brick import twisted_brick  # noqa: E402

from conformal.similarity import Similarity  # noqa: E402
from conformal.steady import SteadyLattice  # noqa: E402

BCC_RACKS = (
    [(0, 0, 1, 0, 0), (0, 0, 0, 1, 0), (0, 0, 0, 0, 1)]
    + [(1, 1, 1, 0, 0), (1, 1, 0, 1, 0), (1, 1, 0, 0, 1)]
    + [(1, 0, a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)]
    + [(0, 0, 1, 1, 0), (0, 0, 1, -1, 0), (0, 0, 1, 0, 1)]
    + [(0, 0, 1, 0, -1), (0, 0, 0, 1, 1), (0, 0, 0, 1, -1)]
    + [(1, 1, 1, 1, 0), (1, 1, 1, -1, 0), (1, 1, 1, 0, 1)]
    + [(1, 1, 1, 0, -1), (1, 1, 0, 1, 1), (1, 1, 0, 1, -1)]
)


def bent_brick(n: int) -> SteadyLattice:
    """A bent (quarter turn along i), twisted and graded BCC brick of n^3 unit clusters."""
    c = float(n - 1)
    u_total = Similarity(scale=1.5, axis=(0, 0, 1), angle=math.pi / 2, translation=(c, 0, 0))
    v_total = Similarity(axis=(1, 0, 0), angle=0.3, translation=(0, c, 0))
    w_total = Similarity(scale=0.8, axis=(0, 1, 0), angle=0.5, translation=(0, 0, c))
    cluster = [((0.0, 0.0, 0.0), 0.08), ((0.5, 0.5, 0.5), 0.06)]
    return SteadyLattice(
        cluster,
        BCC_RACKS,
        u=u_total,
        v=v_total,
        w=w_total,
        counts=(n, n, n),
        cumulative=True,
    )


def screw_tire() -> SteadyLattice:
    """The example tire with a pitch: W is a true screw (rotation + axial shift)."""
    t = tire()
    w = Similarity(axis=(0, 0, 1), angle=t.w.angle, translation=(0, 0, 0.7))
    return SteadyLattice(
        [(c, r) for c, r in zip(t.centres, t.radii, strict=True)],
        t.racks.tolist(),
        u=t.u,
        v=t.v,
        w=w,
        counts=t.counts,
    )


def swirl_brick() -> SteadyLattice:
    cluster = [((0.0, 0.0, 0.0), 0.1), ((0.5, 0.5, 0.5), 0.08)]
    return SteadyLattice(
        cluster,
        BCC_RACKS,
        u=Similarity(scale=1.02, axis=(0, 0, 1), angle=0.05, translation=(1, 0, 0)),
        v=Similarity(scale=0.99, axis=(1, 0, 0), angle=0.04, translation=(0, 1, 0)),
        w=Similarity(scale=1.04, axis=(1, 1, 0), angle=0.15, translation=(0.1, 0, 1)),
        counts=(12, 10, 30),
    )


def near_translation_brick() -> SteadyLattice:
    b = swirl_brick()
    w = Similarity(scale=1 + 1e-9, axis=(1, 1, 0), angle=1e-8, translation=(0.1, 0, 1))
    return SteadyLattice(
        [(c, r) for c, r in zip(b.centres, b.radii, strict=True)],
        b.racks.tolist(),
        u=b.u,
        v=b.v,
        w=w,
        counts=b.counts,
    )


def rel(a: object, b: object) -> float:
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(x - y).max() / np.abs(y).max())


def table1() -> list[dict[str, object]]:
    cases = [
        ("screw tire (Fig. 19), W screw", screw_tire()),
        ("tire example, W rotation", tire()),
        ("Michell slab (Fig. 18), W swirl", michell_slab()),
        ("twisted brick (Fig. 20), W swirl", twisted_brick()),
        ("graded BCC brick, W swirl", swirl_brick()),
        ("BCC brick, W near translation", near_translation_brick()),
    ]
    print("\nTable 1: closed form vs brute force (relative differences)")
    hdr = (
        f"{'lattice':34s} {'kind':6s} {'method':13s} {'beams':>8s} {'volume':>9s} "
        f"{'area':>9s} {'centroid':>9s} {'inertia':>9s} {'closed s':>9s} {'brute s':>8s}"
    )
    print(hdr)
    print("-" * len(hdr))
    rows = []
    for name, lat in cases:
        t0 = time.perf_counter()
        c = lat.integral_properties()
        t1 = time.perf_counter()
        b = lat.integral_properties(method="brute")
        t2 = time.perf_counter()
        row = {
            "lattice": name,
            "kind": lat.w.decompose().kind,
            "method": c["method"],
            "beams": lat.num_beams,
            # centroid: max coordinate difference relative to the lattice's extent
            "volume": rel(c["volume"], b["volume"]),
            "area": rel(c["area"], b["area"]),
            "centroid": float(
                np.abs(c["centroid"] - b["centroid"]).max()
                / np.ptp(lat.graph().nodes, axis=0).max()
            ),
            "inertia": rel(c["spherical_inertia"], b["spherical_inertia"]),
            "closed_s": t1 - t0,
            "brute_s": t2 - t1,
        }
        rows.append(row)
        print(
            f"{name:34s} {row['kind']:6s} {row['method']:13s} {row['beams']:8d} "
            f"{row['volume']:9.1e} {row['area']:9.1e} {row['centroid']:9.1e} "
            f"{row['inertia']:9.1e} {row['closed_s']:9.3f} {row['brute_s']:8.3f}"
        )
    worst = max(max(r[k] for k in ("volume", "area", "centroid", "inertia")) for r in rows)
    print(f"worst relative difference: {worst:.1e} (target 1e-9)")
    return rows


def table2(sizes: list[int]) -> None:
    print(f"\nTable 2: closed-form integral properties of a bent, graded brick "
          f"({numba.get_num_threads()} threads, {os.cpu_count()} CPUs)")  # fmt: skip
    hdr = f"{'size':>18s} {'beams':>20s} {'volume':>22s} {'time s':>9s} {'method':>8s}"
    print(hdr)
    print("-" * len(hdr))
    bent_brick(40).integral_properties()  # compile / load the kernels
    for n in sizes:
        lat = bent_brick(n)
        t0 = time.perf_counter()
        props = lat.integral_properties()
        dt = time.perf_counter() - t0
        size = f"{n} x {n} x {n}"
        print(f"{size:>18s} {lat.num_beams:20,d} {props['volume']:22.10g} {dt:9.2f} "
              f"{props['method']:>8s}", flush=True)  # fmt: skip
    small = bent_brick(40)
    c, b = small.integral_properties(), small.integral_properties(method="brute")
    print(f"check at 40^3: closed vs brute volume rel. diff {rel(c['volume'], b['volume']):.1e}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the 10000^3 brick")
    args = ap.parse_args()
    table1()
    table2([100, 1000] if args.quick else [100, 1000, 10000])


if __name__ == "__main__":
    main()
