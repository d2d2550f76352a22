"""Does the printable solid keep the part's size? Protrusion of every fill mode.

For each part and fill mode, ``Lattice.fill(...).mesh()`` is built in this process and
every vertex of the printable mesh is tested against the part (exact winding numbers,
``conformal.Part.contains``); the table gives the largest distance of a vertex outside the
part's surface, in mm and in % of the strut radius, the time to build the mesh (stitch,
trim, float32 rounding, check), triangles, and whether ``fast_stitch.check`` accepts it.
The goal (issue 13): at most 1 % of the strut radius in every mode.

Modes: ``auto`` (the default fill), ``clip``, ``conform`` (kelvin), ``tet`` and ``skin``
(octet, skin = cell / 6). Cell = largest extent / 15 (as bench_parts.py), radius = cell / 12.

Run::

    python benchmarks/bench_protrusion.py                      # example bracket + GE bracket
    python benchmarks/bench_protrusion.py --parts kcl_bracket --modes clip tet
"""

from __future__ import annotations

import argparse
import time
import traceback
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
DEFAULT_PARTS = [ROOT / "examples" / "bracket.step",
                 DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step"]  # fmt: skip
MODES = ("auto", "clip", "conform", "tet", "skin")


def options(mode: str, cell: float) -> dict:
    r = cell / 12
    base = {"cell_size": cell, "radius": r}
    if mode == "auto":
        return {**base, "cell": "bcc"}
    if mode == "clip":
        return {**base, "cell": "bcc", "fill": "clip"}
    if mode == "conform":
        return {**base, "cell": "kelvin", "fill": "conform"}
    if mode == "tet":
        return {**base, "method": "tet"}
    return {**base, "cell": "octet", "skin": cell / 6}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", nargs="*", help="substrings of part file names in shared/data")
    ap.add_argument("--modes", nargs="*", default=list(MODES), choices=MODES)
    args = ap.parse_args()
    import fast_stitch
    from conformal import load_part
    from conformal.trim import protrusion
    from lattice_cad import Lattice

    if args.parts:
        files = sorted(p for d in ("step", "meshes") for p in (DATA / d).iterdir()
                       if any(s in p.name for s in args.parts))  # fmt: skip
    else:
        files = DEFAULT_PARTS
    print(f"{'part':34s} {'mode':8s} {'r mm':>7s} {'protrude mm':>12s} {'% of r':>8s} "
          f"{'mesh s':>7s} {'triangles':>10s} {'check':>6s}")  # fmt: skip
    for f in files:
        part = load_part(f)
        cell = float(np.max(part.size)) / 15
        for mode in args.modes:
            opts = options(mode, cell)
            r = opts["radius"]
            try:
                t0 = time.perf_counter()
                lat = Lattice.fill(part, **opts)
                m = lat.mesh()
                dt = time.perf_counter() - t0
                d = protrusion(part, m.vertices)
                ok = "ok" if fast_stitch.check(m).valid else "FAIL"
                print(f"{f.stem[:34]:34s} {mode:8s} {r:7.3f} {d:12.4g} {100 * d / r:8.2f} "
                      f"{dt:7.1f} {len(m.faces):10d} {ok:>6s}", flush=True)  # fmt: skip
            except Exception as exc:  # a table row, not a crash
                print(f"{f.stem[:34]:34s} {mode:8s} {r:7.3f} error: {type(exc).__name__}: "
                      f"{str(exc)[:80]}", flush=True)  # fmt: skip
                if "--debug" in traceback.format_exc():
                    raise


if __name__ == "__main__":
    main()
