"""Benchmark of conformal: voxel classification, GE bracket voxel and tet lattices vs the seed.

Run: ``python benchmarks/bench_conformal.py`` (prints a table). Numba kernels are
warmed up first so that times exclude compilation.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

import fast_stitch
from conformal.part import load_part
from conformal.tet import tet_lattice
from conformal.voxel import voxel_lattice, voxelize

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
BRACKET = DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step"
SEED = {"voxel": (7145, 35_400, 964_000, 0.172), "tet": (5853, 35_200, 979_000, 0.185)}


def main() -> None:
    warnings.simplefilter("ignore")
    part = load_part(BRACKET)
    # warm-up (numba compilation)
    g = voxel_lattice(part, "box-bcc", 20.0, 0.25, fill="conform")
    fast_stitch.stitch(g)
    h = float(np.prod(part.size) / 1e6) ** (1 / 3)
    t = time.perf_counter()
    vox = voxelize(part, h)
    t_vox = time.perf_counter() - t
    n_cells = vox.inside.size
    print(f"voxel classification: {n_cells:,} cells in {t_vox:.3f} s (target < 3 s)")
    print()
    hdr = (
        f"{'GE bracket':34s} {'nodes':>7s} {'edges':>8s} {'build s':>8s} {'e2e s':>7s} "
        f"{'triangles':>10s} {'stitch s':>8s} | seed: nodes edges triangles time"
    )
    print(hdr)
    print("-" * len(hdr))
    rows = []
    for fill in ("inside", "clip", "conform"):
        rows.append((f"box-bcc 5.5 mm {fill}", "voxel", fill))
    rows.append(("tet 5 mm (gmsh hxt)", "tet", None))
    for label, kind, fill in rows:
        t0 = time.perf_counter()
        p = load_part(BRACKET)
        t1 = time.perf_counter()
        if kind == "voxel":
            g = voxel_lattice(p, "box-bcc", 5.5, 0.25, fill=fill)
        else:
            g = tet_lattice(p, 5.0, 0.25)
        t2 = time.perf_counter()
        mesh = fast_stitch.stitch(g, 6)
        t3 = time.perf_counter()
        s = SEED[kind]
        print(
            f"{label:34s} {g.num_nodes:7d} {g.num_edges:8d} {t2 - t1:8.2f} {t3 - t0:7.2f} "
            f"{len(mesh.faces):10d} {t3 - t2:8.2f} | {s[0]} {s[1]} {s[2]} {s[3]}"
        )
    print("\nbuild s = lattice graph from the loaded part; e2e s = STEP file -> stitched mesh")


if __name__ == "__main__":
    main()
