"""Volumes of the GE tet 5 mm hubs with thinned/tapered stumps: direct+fuse, the tree fuse and
one general fuse against each other, and a Monte Carlo estimate for one hub (issue 14).

Usage::

    python benchmarks/check_hub_fuse_mc.py [--graphs DIR] [--mc INDEX]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from bench_hub_profile import graph

    from lattice_cad.core import config
    from lattice_cad.occ_impl import hub_direct, truss
    from lattice_cad.occ_impl.shapes import volume
    from reference_boolean.frame import frame_scale, scale_spec
    from reference_boolean.reference import _unit_specs

    ap = argparse.ArgumentParser()
    ap.add_argument("--graphs", type=Path, default=None)
    ap.add_argument("--mc", type=int, default=None)
    a = ap.parse_args()
    g = graph("tet", a.graphs)
    why = "stumps of different radii or tapered"
    hubs = [s for s in _unit_specs(g, True).specs
            if isinstance(s, truss.HubSpec) and hub_direct.direct_applies(s) == why]  # fmt: skip
    for i, s in enumerate(hubs):
        if a.mc is not None and i != a.mc:
            continue
        s = scale_spec(s, 1 / frame_scale(s))  # as a worker builds it
        if not truss._direct_plan(s)[0]:
            continue
        _, vb = truss.direct_hub_shape(s)
        vt = volume(truss.make_hub_shape(s, construction="tree"), eps=config.VOLUME_EPS)
        vf = volume(truss.make_hub_shape(s, construction="fuse"), eps=config.VOLUME_EPS)
        print(f"hub {i} degree {len(s.vecs)}: direct+fuse {vb:.9g}, tree {vt:.9g}, one general "
              f"fuse {vf:.9g}; direct+fuse/fuse - 1 = {vb / vf - 1:.1e}", flush=True)  # fmt: skip
        if a.mc is None:
            continue
        rng = np.random.default_rng(0)
        h = np.linalg.norm(s.vecs, axis=1)
        u = s.vecs / h[:, None]
        ext = float((h + s.r_mid.max()).max())
        n, hit = 4_000_000, 0
        for _ in range(5):
            p = rng.uniform(-ext, ext, size=(n, 3))
            ins = np.linalg.norm(p, axis=1) <= s.radius
            t = p @ u.T
            d2 = (p * p).sum(1)[:, None] - t * t
            rr = s.r_node[None] + (s.r_mid - s.r_node)[None] * t / h[None]
            ins |= ((t >= 0) & (t <= h[None]) & (d2 <= rr * rr)).any(axis=1)
            hit += int(ins.sum())
        box = (2 * ext) ** 3
        print(f"  Monte Carlo (2e7 points): {hit / (5 * n) * box:.2f} +- "
              f"{box * np.sqrt(hit) / (5 * n):.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
