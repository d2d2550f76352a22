"""Fill a build123d part with an octet lattice and write STL and 3MF.

Run: python examples/build123d_lattice.py [OUT_DIR]   (default: the current directory)
"""

from __future__ import annotations

import sys
from pathlib import Path

import build123d as bd

from lattice_cad.lattice import Lattice


def main(out_dir: str = ".") -> None:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with bd.BuildPart() as builder:
        bd.Cylinder(radius=15, height=20)
        bd.Box(12, 12, 30, mode=bd.Mode.SUBTRACT)
    part = builder.part  # a build123d Part: a ring 30 mm across with a square hole

    lat = Lattice.fill(part, "octet", cell_size=5.0, radius=0.35, fill="clip", segments=8)
    print(lat, lat.info()["triangles"], "triangles")
    lat.save(out / "ring_lattice.stl")
    lat.save(out / "ring_lattice.3mf")
    print(f"wrote {out / 'ring_lattice.stl'} and {out / 'ring_lattice.3mf'}")


if __name__ == "__main__":
    main(*sys.argv[1:])
