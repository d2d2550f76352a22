"""How long do the shaded pictures take? (issue 16)

Renders, with ``lattice_cad.preview.render_png`` (software rasteriser, offscreen,
1200 x 900 per picture unless said otherwise), and prints one row per picture:
what is drawn, triangles drawn, wall-clock seconds to render and the process's CPU
seconds (all threads; building the lattice and mesh are not timed, they are printed
apart), the PNG size, and the load average (on a shared machine the wall clock grows
with the load; the CPU time much less).

Cases:

* ``bracket``: the shipped example bracket, 4 mm BCC, 0.4 mm struts, 1 mm skin: the
  lattice as tubes with the part as a ghost, isometric + section z = 5 (the README picture);
* ``ge-clip``: the GE bracket (``../shared/data/step/dolfiny_ge_bracket_rotated_nonds.step``),
  BCC clipped at the walls (cell = largest extent / 15, radius = cell / 12): the printable
  mesh, and the graph as tubes coloured by angle to the build plate with the part as ghost;
* ``ge-skin``: the same with a skin of cell / 6, the printable mesh (skin + lattice) with a
  section through the middle;
* ``bunny``: the 1 mm bunny BCC of ``bench_stitch.py`` (1.08 M struts; 29 M triangles at
  P = 6): the stitched mesh, and the graph as tubes.

Pictures are written to ``--out`` (default: a temporary directory) so they can be looked at.

Run::

    python benchmarks/bench_preview.py                    # every case
    python benchmarks/bench_preview.py --cases bracket ge-clip
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
GE = DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step"
CASES = ("bracket", "ge-clip", "ge-skin", "bunny")


def _load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def timed(rows: list[list[str]], out: Path, name: str, what: str, obj: Any, **opts: Any) -> None:
    from lattice_cad import preview

    t0, c0 = time.perf_counter(), time.process_time()
    png = preview.render_png(obj, **opts)
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    path = out / f"{name}.png"
    path.write_bytes(png)
    tri = _triangles(obj, opts)
    rows.append(
        [name, what, f"{tri:,}", f"{dt:.2f}", f"{cpu:.2f}", f"{len(png) / 1e3:.0f}", _load()]
    )
    print(f"  {name}: {dt:.2f} s -> {path}", flush=True)


def _triangles(obj: Any, opts: dict[str, Any]) -> int:
    from lattice_cad.core.graph import LatticeGraph

    g = getattr(obj, "graph", obj)
    if isinstance(g, LatticeGraph):
        sides = 8 if g.num_edges <= 400_000 else 6
        balls = 0 if g.num_edges > 400_000 else 80 * len(np.unique(g.edges))
        return 2 * sides * g.num_edges + balls
    return len(obj.faces)


def fill(part: Path, **kw: Any) -> Any:
    from lattice_cad.core.errors import LatticeWarning
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        return Lattice.fill(part, **kw)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    ap.add_argument("--out", help="directory for the pictures (default: a temporary one)")
    args = ap.parse_args(argv)
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_preview_"))
    out.mkdir(parents=True, exist_ok=True)
    rows: list[list[str]] = []

    # warm-up: numba kernels (compiled once, cached) and matplotlib
    from lattice_cad import preview
    from lattice_cad.core.graph import LatticeGraph

    t0 = time.perf_counter()
    preview.render_png(LatticeGraph([[0, 0, 0], [1, 1, 1]], [[0, 1]], [[0.1, 0.1]]))
    print(f"warm-up (kernels, matplotlib): {time.perf_counter() - t0:.1f} s")

    if "bracket" in args.cases:
        t0 = time.perf_counter()
        lat = fill(ROOT / "examples" / "bracket.step", cell="bcc", cell_size=4.0, radius=0.4,
                   skin=1.0)  # fmt: skip
        print(f"bracket: fill {time.perf_counter() - t0:.1f} s")
        timed(rows, out, "bracket", "tubes + ghost, iso + section z=5, by radius", lat,
              size=(1400, 680), section="z=5", color_by="radius")  # fmt: skip
    if "ge-clip" in args.cases or "ge-skin" in args.cases:
        from conformal.part import load_part

        part = load_part(GE)
        cell = float(np.ptp(part.vertices, axis=0).max()) / 15
        if "ge-clip" in args.cases:
            t0 = time.perf_counter()
            lat = fill(GE, cell="bcc", cell_size=cell, radius=cell / 12, fill="clip")
            mesh = lat.mesh()
            print(f"ge-clip: fill + mesh {time.perf_counter() - t0:.1f} s")
            timed(rows, out, "ge-clip-mesh", "printable mesh (clip)", mesh)
            timed(rows, out, "ge-clip-tubes", "tubes + ghost, by angle to plate", lat,
                  color_by="overhang")  # fmt: skip
        if "ge-skin" in args.cases:
            t0 = time.perf_counter()
            lat = fill(GE, cell="bcc", cell_size=cell, radius=cell / 12, skin=cell / 6)
            mesh = lat.mesh()
            print(f"ge-skin: fill + mesh {time.perf_counter() - t0:.1f} s")
            timed(rows, out, "ge-skin-section", "printable mesh (skin), iso + section z", mesh,
                  section="z", size=(1400, 680))  # fmt: skip
    if "bunny" in args.cases:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        import bench_stitch

        import fast_stitch

        t0 = time.perf_counter()
        v, f, s, _ = bench_stitch.scaled_bunny()
        g, _, _ = bench_stitch.bunny_graph(v, f, 1.0)
        mesh = fast_stitch.stitch(g, 6)
        print(f"bunny: graph + stitch {time.perf_counter() - t0:.1f} s, {len(mesh.faces):,} tri")
        timed(rows, out, "bunny-mesh", "1 mm bunny BCC, stitched mesh", mesh)
        del mesh
        timed(rows, out, "bunny-tubes", "1 mm bunny BCC, graph as tubes", g)

    head = ["picture", "what", "triangles", "render s", "cpu s", "PNG kB", "load 1/5/15"]
    width = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    print()
    for r in [head, ["-" * w for w in width], *rows]:
        print("  ".join(c.ljust(w) for c, w in zip(r, width, strict=True)))
    print(f"\npictures in {out}")


if __name__ == "__main__":
    main()
