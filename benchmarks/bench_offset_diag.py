"""Why OCCT's offset fails on a STEP part: each way tried, in a child process, with OCCT's
``BRepOffset_Error`` code, validity, solid count, and the wall of a result (inner vertices
and face centres to a fine mesh of the part, % of t). t = largest extent / 90 (bench_wall).

Run::

    python benchmarks/bench_offset_diag.py spanner M6       # substrings of STEP names
    STRATS=arc,inter TMO=90 python benchmarks/bench_offset_diag.py ge_bracket
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def strategies() -> list[str]:
    return ["arc", "unify+arc", "inter", "unify+inter", "unify+arc+fix", "c1+arc", "simple"]


def run_one(brep, dist, strat, q):
    try:
        from OCP.BRepOffset import BRepOffset_Skin
        from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeOffsetShape
        from OCP.GeomAbs import GeomAbs_Arc, GeomAbs_Intersection
        from OCP.ShapeFix import ShapeFix_Shape
        from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
        from OCP.TopAbs import TopAbs_FACE

        from lattice_cad.occ_impl import shapes as occ

        s = occ.from_bytes(brep)
        info = {}
        t0 = time.process_time()
        if strat.startswith("c1"):
            s = occ._split_to_c1(s) or s
        if strat.startswith("unify"):
            u = ShapeUpgrade_UnifySameDomain(s, True, True, True)
            u.Build()
            s2 = u.Shape()
            info["faces"] = (occ.count(s, TopAbs_FACE), occ.count(s2, TopAbs_FACE))
            s = s2
        mk = BRepOffsetAPI_MakeOffsetShape()
        if "simple" in strat:
            mk.PerformBySimple(s, dist)
        else:
            join = GeomAbs_Intersection if "inter" in strat else GeomAbs_Arc
            mk.PerformByJoin(s, dist, 1e-6, BRepOffset_Skin, False, False, join)
        info["done"] = mk.IsDone()
        try:
            info["err"] = mk.MakeOffset().Error().name
        except Exception as e:
            info["err"] = "?" + str(e)[:40]
        if not mk.IsDone():
            q.put(info)
            return
        out = mk.Shape()
        info["valid"] = occ.is_valid(out)
        if "fix" in strat and not info["valid"]:
            fx = ShapeFix_Shape(out)
            fx.Perform()
            out = fx.Shape()
            info["valid_fixed"] = occ.is_valid(out)
        sol = occ.solids(out)
        info["nsol"] = len(sol)
        info["cpu"] = time.process_time() - t0
        if len(sol) == 1:
            vol0 = occ.volume(occ.from_bytes(brep))
            vol = occ.volume(sol[0])
            info["volfrac"] = vol / vol0
            t = -dist
            vo, fo = occ.tessellate(occ.from_bytes(brep), 0.002 * t, 0.1)
            vi, fi = occ.tessellate(sol[0], 0.01 * t, 0.1)
            from conformal.part import Part

            P = Part(vo, fo, name="o")
            d = P.distance(np.vstack([vi, vi[fi].mean(axis=1)]))
            info["wall%"] = (round(100 * (d.min() - t) / t, 2), round(100 * (d.max() - t) / t, 2))
        q.put(info)
    except Exception as e:
        q.put({"exc": f"{type(e).__name__}: {str(e)[:80]}"})


def main():
    from conformal import load_part
    from lattice_cad.occ_impl import shapes as occ

    names = sys.argv[1:]
    strats = os.environ.get("STRATS", ",".join(strategies())).split(",")
    files = [f for f in sorted((DATA / "step").iterdir()) if any(n in f.name for n in names)]
    for f in files:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            part = load_part(f)
        cell = float(np.max(part.size)) / 15
        t = float(f"{cell / 6:.6g}")
        sl = list(part.shape)
        if len(sl) > 1:
            try:
                fused = occ.solids(occ.fuse(sl, simplify=True)) or sl
            except Exception:
                fused = sl
        else:
            fused = sl
        print(f"== {f.name} t={t} solids={len(sl)} fused={len(fused)}", flush=True)
        for k, s in enumerate(fused):
            b = occ.to_bytes(s)
            for st in strats:
                q = mp.Queue()
                p = mp.Process(target=run_one, args=(b, -t, st, q))
                w0 = time.time()
                p.start()
                p.join(int(os.environ.get("TMO", "60")))
                if p.is_alive():
                    p.kill()
                    p.join()
                    res = "TIMEOUT"
                else:
                    res = q.get() if not q.empty() else f"crash rc={p.exitcode}"
                print(f"  solid {k} {st:14s} {time.time() - w0:5.1f}s {res}", flush=True)


if __name__ == "__main__":
    mp.set_start_method("fork")
    main()
