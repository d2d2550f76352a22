"""Protrusion of written fills against the exact B-rep, not the part mesh the fill cuts by.

The parts benchmark measures how far the written solid stands out of the part's mesh
(``conformal.load_part`` defaults: deflection 1e-3 of the diagonal, 0.3 rad). On concave faces
(holes) that mesh lies outside the exact surface by up to its deflection, so a lattice cut by it
stands out of the CAD surface. This script measures that against a fine tessellation of the
exact B-rep (deflection 1e-3 mm, 0.05 rad), with the parts benchmark's dimensions (cell =
largest extent / 15, r = cell / 12, 6 significant digits).

    python benchmarks/bench_protrusion_exact.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import trimesh

import conformal

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "step"
CASES = [
    ("kcl_flange-with-patterns.step", "clip"),
    ("kcl_flange-with-patterns.step", "conform"),
    ("dolfiny_ge_bracket_rotated_nonds.step", "clip"),
    ("kcl_bracket.step", "clip"),
    ("kcl_mounting-plate.step", "clip"),
]


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'part':40s} {'fill':8s} {'r mm':>8s} {'vs mesh %r':>11s} {'vs B-rep %r':>12s} "
          f"{'verts > 1% r':>13s}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for name, fill in CASES:
            src = DATA / name
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                coarse = conformal.load_part(src)
                fine = conformal.load_part(src, deflection=1e-3, angular_deflection=0.05)
            ext = float((coarse.bounds[1] - coarse.bounds[0]).max())
            cell = float(f"{ext / 15:.6g}")
            r = float(f"{cell / 12:.6g}")
            out = Path(tmp) / f"{src.stem}.{fill}.stl"
            cmd = [sys.executable, "-m", "lattice_cad.cli", "fill", str(src), "-o", str(out),
                   "--cell-size", str(cell), "--radius", str(r), "--fill", fill]  # fmt: skip
            subprocess.run(cmd, check=True, capture_output=True)
            v = trimesh.load(out).vertices
            d_mesh = coarse.signed_distance(v)
            d_brep = fine.signed_distance(v)
            print(f"{name:40s} {fill:8s} {r:8.4f} {100 * d_mesh.max() / r:11.2f} "
                  f"{100 * d_brep.max() / r:12.2f} {int((d_brep > 0.01 * r).sum()):7d} of "
                  f"{len(v)}")  # fmt: skip
    print("(% r: largest signed distance of a written vertex outside the surface, in % of r)")


if __name__ == "__main__":
    main()
