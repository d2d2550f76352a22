"""Fill a CadQuery part with a lattice, inside a 1 mm skin, and write printable files.

Run: python examples/cadquery_lattice.py [OUT_DIR]   (default: the current directory)

``import lattice_cad.plugin`` adds ``Workplane.lattice`` to CadQuery (its plugin convention).
"""

from __future__ import annotations

import sys
from pathlib import Path

import cadquery as cq

import fast_stitch
import lattice_cad.plugin  # noqa: F401  (adds cq.Workplane.lattice)


def main(out_dir: str = ".") -> None:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # a 40 x 30 x 16 mm block with a through hole, in global coordinates
    part = cq.Workplane("XY").box(40, 30, 16).faces(">Z").workplane().hole(8)

    lat = part.lattice("bcc", cell_size=4.0, radius=0.4, skin=1.0)
    print(lat)
    info = lat.info()
    print(f"{info['struts']} struts, relative density {info['relative_density']:.3f}")
    lat.save(out / "block_skin.stl")  # skin + lattice, one watertight solid
    lat.save(out / "block_lattice.3mf", beam_lattice=True)  # beams + the mesh, opens everywhere
    lat.save(out / "block_graph.json")  # the graph, exactly
    print(fast_stitch.check(lat.mesh(), self_intersections=False))

    # a small lattice as an exact B-rep, used in a further CadQuery boolean
    small = cq.Workplane("XY").box(10, 10, 10).lattice("bcc", 5.0, 0.6, fill="clip")
    solid = small.to_workplane()
    plate = cq.Workplane("XY").box(10, 10, 2).translate((0, 0, -6)).union(solid)
    print(f"plate + lattice B-rep: volume {plate.val().Volume():.1f} mm^3")
    cq.exporters.export(plate, str(out / "plate_lattice.step"))
    print(
        f"wrote {out / 'block_skin.stl'}, block_lattice.3mf, block_graph.json, plate_lattice.step"
    )


if __name__ == "__main__":
    main(*sys.argv[1:])
