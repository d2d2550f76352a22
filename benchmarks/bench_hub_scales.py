"""Why the GE tet window's strut deviation p95 is 0.109 r at P = 6 (issue 14, item 3).

The default mesh (``profile="volume"``) removes each hub's excess volume by scaling the
profiles at that node by ``s_n`` (:func:`fast_stitch.hubvolume.hub_scales`); a strut then
runs between the scaled polygons of its two ends, a frustum along its whole length, where
the reference is a cylinder. Prints the scales and the circumradius / r of the strut-end
polygons of the stitched windows (the area-preserving hexagon alone: 1.0996).

Usage::

    python benchmarks/bench_hub_scales.py [--graphs DIR]   # GE lattice cache (.npz)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from bench_hub_profile import graph
    from bench_reference import WINDOW_HUBS, WINDOW_SEED, window

    from fast_stitch.hubvolume import area_factor
    from fast_stitch.stitch import stitch

    cache = Path(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[1] == "--graphs" else None
    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}", flush=True)
    P = 6
    for kind in ("tet", "voxel"):
        g = window(graph(kind, cache), WINDOW_HUBS, WINDOW_SEED)
        rep: dict = {}
        m = stitch(g, P, _report=rep)
        s0 = rep["scale0"][g.degree >= 2]
        M = g.num_edges
        # the strut between the hub zones: its band rings (profile="volume", after the hub
        # rings) where the mesh has them, else its hub rings
        V = np.asarray(m.vertices)[-2 * M * P :].reshape(M, 2, P, 3)
        a = g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]]
        a /= np.linalg.norm(a, axis=1)[:, None]
        rel = V - g.nodes[g.edges[:, 0]][:, None, None, :]
        along = np.einsum("mspk,mk->msp", rel, a)
        rad = np.linalg.norm(rel - along[..., None] * a[:, None, None, :], axis=-1)
        ratio = rad / g.radii[:, :, None]
        # a strut's two ends differ by its two hubs' scales: the taper along the strut region
        taper = np.abs(ratio[:, 0, 0] - ratio[:, 1, 0])
        print(
            f"{kind} window: hubs {len(s0)}, struts {M}; hub scale s_n min {s0.min():.3f} "
            f"p5 {np.percentile(s0, 5):.3f} median {np.median(s0):.3f} max {s0.max():.3f}"
        )
        print(
            f"  strut-end polygon circumradius / r: min {ratio.min():.4f} p5 "
            f"{np.percentile(ratio, 5):.4f} median {np.median(ratio):.4f} p95 "
            f"{np.percentile(ratio, 95):.4f} max {ratio.max():.4f} (no hub scale: "
            f"{area_factor(P):.4f}); |end - end| / r median {np.median(taper):.4f} "
            f"p95 {np.percentile(taper, 95):.4f}"
        )


if __name__ == "__main__":
    main()
