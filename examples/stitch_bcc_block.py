"""Stitch a BCC lattice block into a watertight STL and check it.

Run: python examples/stitch_bcc_block.py [OUT.stl]
"""

from __future__ import annotations

import sys
import time

import fast_stitch
from conformal import block


def main(out: str = "bcc_block.stl") -> None:
    graph = block("bcc", (20, 20, 10), cell_size=5.0, radius=0.4)  # millimetres
    est = fast_stitch.estimate(graph, segments=6)
    print(f"{graph}: will write {est.triangles:,} triangles ({est.stl_bytes / 1e6:.1f} MB)")
    t0 = time.perf_counter()
    mesh = fast_stitch.stitch(graph, segments=6)
    print(f"stitched in {time.perf_counter() - t0:.2f} s, volume {mesh.volume:.1f} mm^3")
    report = fast_stitch.check(mesh)
    print(report)
    mesh.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
