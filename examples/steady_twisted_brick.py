"""A twisted, graded octahedral brick (paper Fig. 20) from three cumulative similarities.

The base cluster holds the three face-centre balls of a unit cube; twelve
racks join them into octahedra that share their vertices. The first and last
clusters of each row are placed by cumulative similarities (``U'``, ``V'``:
translations across the brick; ``W'``: a quarter twist about the brick's
central axis with a 0.6 shrink and a lift), and the incremental similarities
are their fractional powers (paper Sec. 5.3), so the brick interpolates its
end frames while it twists and grades steadily.

Run from the repository root: python examples/steady_twisted_brick.py [OUT.stl]
"""

from __future__ import annotations

import math
import sys
import time

import fast_stitch
from conformal.similarity import Similarity
from conformal.steady import SteadyLattice

COUNTS = (6, 6, 10)
RADIUS = 0.07

# ball 0: z-face centre, 1: y-face centre, 2: x-face centre of cell (i, j, k)
OCTAHEDRAL_RACKS = [
    (0, 1, 0, 0, 0), (0, 1, 0, 1, 0), (0, 2, 0, 0, 0), (0, 2, 1, 0, 0),
    (1, 0, 0, 0, 1), (1, 0, 0, -1, 1), (2, 0, 0, 0, 1), (2, 0, -1, 0, 1),
    (1, 2, 0, 0, 0), (1, 2, 1, 0, 0), (2, 1, 0, 1, 0), (2, 1, -1, 1, 0),
]  # fmt: skip


def twisted_brick() -> SteadyLattice:
    ni, nj, nk = COUNTS
    cluster = [((0.5, 0.5, 0.0), RADIUS), ((0.5, 0.0, 0.5), RADIUS), ((0.0, 0.5, 0.5), RADIUS)]
    centre = Similarity(translation=(ni / 2.0, nj / 2.0, 0.0))
    twist = Similarity(scale=0.6, axis=(0, 0, 1), angle=math.pi / 2, translation=(0, 0, nk - 1))
    w_total = centre @ twist @ centre.inverse()
    u_total = Similarity(translation=(ni - 1, 0, 0))
    v_total = Similarity(translation=(0, nj - 1, 0))
    return SteadyLattice(
        cluster, OCTAHEDRAL_RACKS, u=u_total, v=v_total, w=w_total, counts=COUNTS, cumulative=True
    )


def main(out: str = "steady_twisted_brick.stl") -> None:
    lattice = twisted_brick()
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
