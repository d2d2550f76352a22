"""``np.unique(axis=0)`` against ``lattice_cad.core.arrays.unique_rows`` on real edge arrays.

The half-edges of each STEP part's tessellation in ../shared/data (sorted vertex pairs, the
rows ``conformal.part._closed_problem`` deduplicates on every tessellation trial) are
deduplicated both ways, alternating A B A B; the results are checked equal and the best of
each side printed with the ratio. Run from anywhere::

    python benchmarks/bench_unique_rows.py [--rounds 3] [--parts NAME ...] [--cut]

``--cut``: the cutting tessellation (``conformal.trim.cutting_part`` at the parts benchmark's
radius, largest extent / 180) instead of the load tessellation: up to
``config.CUT_MAX_TRIANGLES`` triangles, the size the trials deduplicate.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def main() -> None:
    from conformal.part import load_part
    from lattice_cad.core.arrays import unique_rows

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--parts", nargs="*", help="substrings of part file names in shared/data/step")
    ap.add_argument("--cut", action="store_true", help="the cutting tessellation")
    args = ap.parse_args()
    paths = sorted((DATA / "step").iterdir())
    if args.parts:
        paths = [p for p in paths if any(s in p.name for s in args.parts)]
    load = os.getloadavg()[0]
    print(f"load average {load:.1f}; {args.rounds} rounds A (np.unique axis=0) B (unique_rows)")
    print(f"{'part':44s} {'half-edges':>11s} {'numpy s':>8s} {'rows s':>8s} {'ratio':>6s}")
    for path in paths:
        part = load_part(path)
        if args.cut:
            from conformal.trim import cutting_part

            part = cutting_part(part, float(np.max(part.size)) / 180.0)
        f = np.asarray(part.faces, dtype=np.int64)
        und = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        best = {"a": float("inf"), "b": float("inf")}
        for _ in range(args.rounds):
            t = time.perf_counter()
            ua, ia, ca = np.unique(und, axis=0, return_inverse=True, return_counts=True)
            best["a"] = min(best["a"], time.perf_counter() - t)
            t = time.perf_counter()
            ub, ib, cb = unique_rows(und, return_inverse=True, return_counts=True)
            best["b"] = min(best["b"], time.perf_counter() - t)
            same = np.array_equal(ua, ub) and np.array_equal(ia.reshape(-1), ib)
            if not (same and np.array_equal(ca, cb)):
                raise SystemExit(f"{path.name}: results differ")
        print(
            f"{path.name:44s} {len(und):>11,d} {best['a']:8.3f} {best['b']:8.3f} "
            f"{best['a'] / best['b']:6.1f}"
        )


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore")
    main()
