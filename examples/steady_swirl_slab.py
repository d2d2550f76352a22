"""A Michell-like steady slab (paper Fig. 18): two swirls with a common fixed point.

``U`` and ``W`` are swirls about the same point and axis, turning by ``+theta``
and ``-theta`` with the same scale ``e^theta``: the beams follow two families of
logarithmic spirals crossing at right angles, as in Michell's optimal
cantilever, and the balls and beams grow steadily away from the fixed point.
The slab has two layers (``V`` a translation across the slab) joined by
vertical beams.

Run from the repository root: python examples/steady_swirl_slab.py [OUT.stl]
"""

from __future__ import annotations

import math
import sys
import time

import fast_stitch
from conformal.similarity import Similarity
from conformal.steady import SteadyLattice

THETA = 0.1
COUNTS = (14, 2, 14)


def michell_slab() -> SteadyLattice:
    m = math.exp(THETA)  # equiangular spirals at 45 degrees: orthogonal families
    u = Similarity(scale=m, axis=(0, 0, 1), angle=THETA)
    w = Similarity(scale=m, axis=(0, 0, 1), angle=-THETA)
    v = Similarity(translation=(0, 0, 0.3))
    cluster = [((2.0, 0.0, 0.0), 0.035)]
    racks = [(0, 0, 1, 0, 0), (0, 0, 0, 0, 1), (0, 0, 0, 1, 0)]
    return SteadyLattice(cluster, racks, u=u, v=v, w=w, counts=COUNTS)


def main(out: str = "steady_swirl_slab.stl") -> None:
    lattice = michell_slab()
    print(lattice)
    props = lattice.integral_properties()
    for key in ("volume", "area", "centroid", "spherical_inertia"):
        print(f"  {key:18s} {props[key]}")
    graph = lattice.graph()
    t0 = time.perf_counter()
    mesh = fast_stitch.stitch(graph, segments=8)
    print(f"{graph}: stitched in {time.perf_counter() - t0:.2f} s, mesh volume {mesh.volume:.3f}")
    mesh.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
