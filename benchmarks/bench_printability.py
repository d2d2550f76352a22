"""Printability of real parts: overhangs, thin struts, and overhang removal per cell.

What it measures
----------------
For one part (default: the GE bracket of ``../shared/data``) and each cell (default bcc,
octet, kelvin, cubic) at one cell size (default 6 mm, radius 0.4 mm, fill "auto"), with
build direction +Z, critical angle 35 degrees and minimum diameter 0.4 mm (the defaults of
``conformal.printability``):

- the struts, the overhanging struts (count and fraction), the smallest strut angle,
  the thin struts and the unsupported nodes of the lattice as built;
- ``Lattice.fill(..., remove_overhangs=True)``: the overhanging struts removed, the struts
  removed afterwards in loose pieces, the pieces removed, the struts left, and the number
  of connected pieces of the result counted independently (scipy);
- ``Lattice.fill(..., self_supporting=True)``: the smallest strut angle reached, or the
  reason it is refused.

How to run
----------
::

    PYTHONPATH=. python benchmarks/bench_printability.py [--part PATH] [--cell-size 6]
        [--cells bcc,octet,kelvin,cubic]
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_PART = ROOT.parent / "shared" / "data" / "step" / "dolfiny_ge_bracket_rotated_nonds.step"


def _pieces(g) -> int:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = g.num_nodes
    m = coo_matrix((np.ones(g.num_edges), (g.edges[:, 0], g.edges[:, 1])), shape=(n, n))
    _, lab = connected_components(m, directed=False)
    return len(np.unique(lab[g.edges[:, 0]]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--part", default=str(DEFAULT_PART))
    ap.add_argument("--cell-size", type=float, default=6.0)
    ap.add_argument("--radius", type=float, default=0.4)
    ap.add_argument("--cells", default="bcc,octet,kelvin,cubic")
    args = ap.parse_args()

    from conformal import load_part
    from conformal.printability import self_supporting_cells
    from lattice_cad.core.errors import PrintabilityError
    from lattice_cad.lattice import Lattice

    warnings.simplefilter("ignore")
    part = load_part(args.part)
    print(f"part {Path(args.part).name}, cell size {args.cell_size:g} mm, radius {args.radius:g}")
    print(f"self-supporting cells along +Z at 35 deg: {', '.join(self_supporting_cells())}")
    head = (
        f"{'cell':<8} {'struts':>7} {'overhang':>9} {'frac':>6} {'min deg':>7} {'thin':>5} "
        f"{'unsup':>5} | {'removed':>7} {'island':>6} {'pieces':>6} {'left':>6} {'bodies':>6} "
        f"| self-supporting"
    )
    print(head)
    print("-" * len(head))
    for cell in args.cells.split(","):
        t0 = time.perf_counter()
        lat = Lattice.fill(part, cell, args.cell_size, args.radius)
        rep = lat.printability()
        rem = Lattice.fill(part, cell, args.cell_size, args.radius, remove_overhangs=True)
        rm = rem.overhang_removal
        try:
            ss = Lattice.fill(part, cell, args.cell_size, args.radius, self_supporting=True)
            sr = ss.printability()
            ss_text = (
                f"min {sr.min_angle:.2f} deg, {sr.overhang_count} overhangs, "
                f"{ss.graph.num_edges} struts"
            )
        except PrintabilityError as exc:
            ss_text = "refused: " + str(exc).split(";")[0].split(": ", 1)[-1]
        print(
            f"{cell:<8} {rep.num_struts:>7} {rep.overhang_count:>9} "
            f"{rep.overhang_fraction:>6.1%} {rep.min_angle:>7.2f} {rep.thin_count:>5} "
            f"{len(rep.unsupported):>5} | {rm.removed_overhangs:>7} {rm.removed_islands:>6} "
            f"{rm.islands:>6} {rm.struts_after:>6} {_pieces(rem.graph):>6} | {ss_text}"
            f"   ({time.perf_counter() - t0:.1f} s)"
        )


if __name__ == "__main__":
    main()
