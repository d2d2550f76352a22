"""Wall-thickness accuracy of skins on every B-rep part in shared/data (issue 11 item 2).

For each STEP part, at the parts benchmark's setting (cell = largest extent / 15, skin
t = cell / 6), the skin is built (``conformal.skin.build_skin`` with an empty lattice: the
wall does not depend on the lattice) once with ``method="auto"`` (OpenCascade's offset,
voxel field if it fails) and once with ``method="voxel"``. The wall is measured from the
inner surface to the outer one (the definition of an offset) at every vertex *and face
centre* of the inner surface (``skin.wall_thickness``); ``raw`` is the same measure before
the inner vertices are projected onto the offset (``skin._project_to_offset``). The part is
tessellated as ``Lattice`` does before it skins (``conformal.trim.cutting_part`` for the
strut radius r = cell / 12 and the skin's chord error ``conformal.skin.outer_chord(t)``;
``--default-mesh``: the part's default tessellation). ``exact %``: the largest deviation
from t of the inner wall's depth in the exact B-rep (OpenCascade's distance) at
``--samples`` random points of its triangles. The goal
for the OCCT path: every sample within max(2 % of t, 0.02 mm) of t. Also printed: the
protrusion of the skin out of the part (largest distance of a vertex outside, in % of
the benchmark's strut radius cell / 12).

Run::

    python benchmarks/bench_wall.py                 # all STEP parts
    python benchmarks/bench_wall.py --parts kcl_ --methods auto
    python benchmarks/bench_wall.py --methods voxel --sharpen   # creases put back
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def _pct(x: float, t: float) -> str:
    return f"{100 * (x - t) / t:+6.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", nargs="*", help="substrings of STEP file names")
    ap.add_argument("--methods", nargs="*", default=["auto", "voxel"])
    ap.add_argument("--samples", type=int, default=2000, help="points for the exact column")
    ap.add_argument(
        "--default-mesh",
        action="store_true",
        help="skin the part's default tessellation, not the one Lattice cuts by",
    )
    ap.add_argument(
        "--sharpen",
        action="store_true",
        help="the voxel method puts its creases back (conformal.skin.SHARPEN_CREASES)",
    )
    args = ap.parse_args()
    import manifold3d
    import trimesh

    from conformal import load_part
    from conformal import skin as S
    from conformal.trim import cutting_part, protrusion
    from lattice_cad.occ_impl.distance import signed_distance

    S.SHARPEN_CREASES = bool(args.sharpen)
    files = sorted((DATA / "step").iterdir())
    if args.parts:
        files = [f for f in files if any(s in f.name for s in args.parts)]
    print(f"load average {os.getloadavg()[0]:.1f}")
    head = (
        f"{'part':34s} {'solids':>6s} {'asked':6s} {'used':6s} {'t mm':>7s} {'tol %':>6s} "
        f"{'raw min%':>8s} {'raw max%':>8s} {'min %':>7s} {'p01 %':>7s} {'p99 %':>7s} "
        f"{'max %':>7s} {'ok':>3s} {'exact %':>7s} {'prot %r':>8s} {'cpu s':>6s} "
        f"{'wall s':>6s}  fallback"
    )
    print(head)
    print("-" * len(head))
    for f in files:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                part = load_part(f)
            except Exception as exc:  # a part that does not load is a row
                print(f"{f.name[:34]:34s} load failed: {str(exc)[:80]}")
                continue
        cell = float(np.max(part.size)) / 15
        t, r = float(f"{cell / 6:.6g}"), cell / 12
        solids = list(part.shape or [])
        if len(solids) > 1:  # measured against the solids fused (touching faces inside)
            from lattice_cad.occ_impl import shapes as occ

            solids = occ.solids(occ.fuse(solids, simplify=True)) or solids
        if not args.default_mesh:  # the part as Lattice skins it (cutting_part, outer_chord)
            part = cutting_part(part, r, chord=S.outer_chord(t))
        tol = 100 * max(0.02 * t, 0.02) / t
        for method in args.methods:
            c0, w0 = time.process_time(), time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    surfaces, used, fallback, _, _ = S._surfaces(part, t, method, None)
                    outer = S._as_part(surfaces[0])
                    raw = S.wall_thickness(surfaces[1], outer) if not surfaces[1].is_empty() else []
                    res = S.build_skin(manifold3d.Manifold(), part, t, method=method, check=False)
            except Exception as exc:  # a failure is a row
                print(f"{f.name[:34]:34s} {len(part.shape or []):6d} {method:6s} failed: "
                      f"{' '.join(str(exc).split())[:100]}")  # fmt: skip
                continue
            cpu, wall_s = time.process_time() - c0, time.perf_counter() - w0
            rep = res.report
            w = rep.wall
            v, _ = S.to_arrays(res.solid)
            prot = 100 * protrusion(part, v) / r
            raw_min = _pct(float(np.min(raw)), t) if len(raw) else "   -"
            raw_max = _pct(float(np.max(raw)), t) if len(raw) else "   -"
            fb = " ".join(rep.fallback.split())[:70]
            exact = "      -"
            if solids and not surfaces[1].is_empty():  # the wall against the exact B-rep
                inner = surfaces[1]  # as build_skin makes it: OCCT's projected onto the offset
                if used == "occt":
                    inner = S._project_to_offset(inner, outer, t, refine=True)
                vi, fi = S.to_arrays(inner)
                pts = trimesh.Trimesh(vi, fi, process=False).sample(args.samples, seed=5)
                dev = np.abs(-signed_distance(solids, pts) - t).max()
                exact = f"{100 * dev / t:7.2f}"
            print(
                f"{f.name[:34]:34s} {len(part.shape or []):6d} {method:6s} {rep.method:6s} "
                f"{t:7.4g} {tol:6.2f} {raw_min:>8s} {raw_max:>8s} {_pct(w['min'], t):>7s} "
                f"{_pct(w['p01'], t):>7s} {_pct(w['p99'], t):>7s} {_pct(w['max'], t):>7s} "
                f"{'yes' if rep.accurate else 'no':>3s} {exact} {prot:8.3f} {cpu:6.1f} "
                f"{wall_s:6.1f}  {fb}",
                flush=True,
            )


if __name__ == "__main__":
    main()
