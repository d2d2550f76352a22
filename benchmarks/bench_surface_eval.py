"""The chord check's surface points on arrays (``occ_impl.surface_eval``) against OCCT's
``Value`` point by point: the cutting tessellation's CPU time per part, A/B alternating.

Each run is a fresh process (``--child``) that loads the part and times
``conformal.trim.cutting_part(part, r)`` (the parts benchmark's radius: the largest extent
/ 15 / 12) by process CPU seconds (BRepMesh runs in threads: wall time on a loaded
machine says little), with ``surface_points`` switched off in the "point by point" runs.
The md5 of the tessellation's vertices is printed: the two must give the same triangles.

Usage::

    PYTHONPATH=$PWD python benchmarks/bench_surface_eval.py --repeat 3 \
        [PART ...] --out benchmarks/results/bench_surface_eval.txt
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STEP = ROOT.parent / "shared" / "data" / "step"
PARTS = [
    STEP / "kcl_cycloidal-gear.step",
    STEP / "build123d_M6-1x12-countersunk-screw.step",
    STEP / "nist_ctc_02_asme1_ap242-1.stp",
]


def child(path: str, arrays: bool) -> None:
    import warnings

    warnings.simplefilter("ignore")
    import lattice_cad.occ_impl.chord as chord
    from conformal import load_part
    from conformal.trim import cutting_part

    if not arrays:
        chord.surface_points = lambda *a: None  # type: ignore[assignment]
    part = load_part(path)
    r = float(max(part.size)) / 15 / 12
    t0 = time.process_time()
    cut = cutting_part(part, r)
    cpu = time.process_time() - t0
    digest = hashlib.md5(cut.vertices.tobytes()).hexdigest()[:12]
    print(json.dumps({"cpu": cpu, "triangles": len(cut.faces), "md5": digest}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", type=Path, default=PARTS)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--child", nargs=2, metavar=("PART", "ARRAYS"))
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1] == "1")
        return
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    lines = [
        "bench_surface_eval: cutting_part CPU s, point by point (OCCT Value) vs on arrays, "
        f"alternating, {args.repeat} x; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"load avg {os.getloadavg()[0]:.2f}"
    ]
    print(lines[0], flush=True)
    rows = []
    for part in args.parts:
        got: dict[str, list[dict]] = {"0": [], "1": []}
        for _ in range(args.repeat):
            for mode in ("0", "1"):
                out = subprocess.run(
                    [sys.executable, __file__, "--child", str(part), mode],
                    env=env, capture_output=True, text=True, check=True,
                )  # fmt: skip
                got[mode].append(json.loads(out.stdout.strip().splitlines()[-1]))
        same = len({r["md5"] for r in got["0"] + got["1"]}) == 1
        a = [r["cpu"] for r in got["0"]]
        b = [r["cpu"] for r in got["1"]]
        row = (
            f"{part.name:45s} {got['1'][0]['triangles']:>9,}  point by point "
            f"{' '.join(f'{x:6.2f}' for x in a)}  arrays {' '.join(f'{x:6.2f}' for x in b)}  "
            f"median ratio {sorted(b)[len(b) // 2] / sorted(a)[len(a) // 2]:.2f}  "
            f"{'same triangles' if same else 'DIFFERENT TRIANGLES'}"
        )
        rows.append(row)
        print(row, flush=True)
    if args.out:
        args.out.write_text("\n".join(lines + rows) + "\n")


if __name__ == "__main__":
    main()
