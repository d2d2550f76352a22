"""A tire-like steady lattice of woven springs (paper Fig. 19): screw, rotation, rotation.

A base cluster of two balls on opposite sides of a helix axis, ``U`` a screw
about that axis (one spring segment per k-slab), ``V`` a quarter turn about the
same axis (two more springs, woven between the first two), ``W`` a rotation
about the tire axis. Racks continue each spring from slab to slab and close
the tire.

Run from the repository root: python examples/steady_screw_tire.py [OUT.stl]
"""

from __future__ import annotations

import math
import sys
import time

import fast_stitch
from conformal.similarity import Similarity
from conformal.steady import SteadyLattice

NI, NJ, NK = 8, 2, 24  # balls per spring turn, spring pairs, slabs around the tire
RHO, STEP, RADIUS = 1.0, 0.25, 0.08  # spring radius, axial step, wire radius


def tire() -> SteadyLattice:
    r0 = NI * STEP / 2.0 / math.sin(math.pi / NK)  # tire radius: slabs form a closed polygon
    y0 = -NI * STEP / 2.0
    cluster = [((r0 + RHO, y0, 0.0), RADIUS), ((r0 - RHO, y0, 0.0), RADIUS)]
    axis_point = (r0, 0.0, 0.0)
    # screw about the line (axis_point, y): conjugate a screw about the y axis
    to_axis = Similarity(translation=axis_point)
    screw = Similarity(axis=(0, 1, 0), angle=2 * math.pi / NI, translation=(0, STEP, 0))
    u = to_axis @ screw @ to_axis.inverse()
    v = to_axis @ Similarity(axis=(0, 1, 0), angle=math.pi / 2) @ to_axis.inverse()
    w = Similarity(axis=(0, 0, 1), angle=2 * math.pi / NK)
    racks = [
        (0, 0, 1, 0, 0),  # spring A
        (1, 1, 1, 0, 0),  # spring B (half a turn out of phase)
        (0, 0, -(NI - 1), 0, 1),  # spring A continues into the next slab
        (1, 1, -(NI - 1), 0, 1),
        (0, 0, -(NI - 1), 0, -(NK - 1)),  # close the tire: last slab -> first slab
        (1, 1, -(NI - 1), 0, -(NK - 1)),
    ]
    return SteadyLattice(cluster, racks, u=u, v=v, w=w, counts=(NI, NJ, NK))


def main(out: str = "steady_screw_tire.stl") -> None:
    lattice = tire()
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
