"""Time ``conformal.trim.cutting_part`` in fresh processes, two trees alternating.

Each run is a fresh ``python`` process with ``PYTHONPATH`` set to one tree (A, then B,
then A, ...): it loads the part, takes the strut radius (the parts benchmark's: largest
extent / 15 / 12, 6 significant digits, unless given), and times ``cutting_part(part,
radius)`` alone (CPU and wall seconds), then hashes the vertices and faces of the result
(sha256 of their float64 / int64 bytes), so the table says whether both trees give the
same tessellation bit for bit. The load average is read before each run.

Usage::

    python benchmarks/bench_cut_speed.py --a ../main --b . --runs 3 [PART[:RADIUS] ...]

Parts are file names under ``../shared/data/step`` (relative to the repository root) or
paths; without any, the GE bracket (r 0.5), the M6 screw (r 0.06667) and three more.
One-shot mode (``--one PART RADIUS``) prints a JSON line for one run in this process.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STEP = ROOT.parent / "shared" / "data" / "step"
DEFAULT = [
    "dolfiny_ge_bracket_rotated_nonds.step:0.5",
    "build123d_M6-1x12-countersunk-screw.step:0.06667",
    "kcl_cycloidal-gear.step",
    "nist_ctc_02_asme1_ap242-1.stp",
    "trimesh_featuretype.STEP",
    "kcl_flange-with-patterns.step",
]


def bench_radius(part: object) -> float:
    """The parts benchmark's strut radius: largest extent / 15 / 12, to 6 digits."""
    size = [float(x) for x in part.size]  # type: ignore[attr-defined]
    return float(f"{max(size) / 15.0 / 12.0:.6g}")


def one(path: str, radius: float | None) -> dict[str, object]:
    """Load ``path``, time ``cutting_part`` on it; the numbers as a dict."""
    import numpy as np

    from conformal import load_part
    from conformal.trim import cutting_part

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = load_part(path)
        r = bench_radius(part) if radius is None else radius
        c0, w0 = time.process_time(), time.perf_counter()
        cut = cutting_part(part, r)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    v = np.ascontiguousarray(cut.vertices, dtype=np.float64)
    f = np.ascontiguousarray(cut.faces, dtype=np.int64)
    h = hashlib.sha256(v.tobytes() + b"|" + f.tobytes()).hexdigest()[:16]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"radius": r, "cpu": cpu, "wall": wall, "tris": len(f), "hash": h, "rss_mb": rss}


def run(tree: Path, path: str, radius: float | None) -> dict[str, object]:
    """One fresh process with ``tree`` first on the path."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", path]
    cmd += [] if radius is None else [repr(radius)]
    out = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=False)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return dict(json.loads(lines[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("parts", nargs="*", help="PART[:RADIUS]")
    ap.add_argument("--a", default=str(ROOT.parent / "main"), help="tree A (default ../main)")
    ap.add_argument("--b", default=str(ROOT), help="tree B (default this tree)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--one", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        radius = float(args.one[1]) if len(args.one) > 1 else None
        print(json.dumps(one(args.one[0], radius)), flush=True)
        return
    trees = {"A": Path(args.a).resolve(), "B": Path(args.b).resolve()}
    for k, t in trees.items():
        rev = subprocess.run(
            ["git", "-C", str(t), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        print(f"# {k} = {t} ({rev})", flush=True)
    print(
        f"# {time.strftime('%Y-%m-%d %H:%M:%SZ', time.gmtime())}, {args.runs} runs each,"
        " alternating A B A B in fresh processes",
        flush=True,
    )
    summary = []
    for spec in args.parts or DEFAULT:
        name, _, rad = spec.partition(":")
        path = name if os.sep in name else str(STEP / name)
        radius = float(rad) if rad else None
        got: dict[str, list[dict[str, object]]] = {"A": [], "B": []}
        for _ in range(args.runs):
            for k in ("A", "B"):
                load = os.getloadavg()[0]
                res = run(trees[k], path, radius)
                res["load"] = load
                got[k].append(res)
                print(f"#   {k} {Path(path).name[:40]:<40} {json.dumps(res)}", flush=True)
        summary.append((Path(path).name, got))
    print()
    head = (
        f"{'part':<42} {'r':>8}  {'A cpu s':>8} {'B cpu s':>8} {'B/A':>5}  "
        f"{'A wall s':>8} {'B wall s':>8}  {'load':>9}  {'tris':>8}  identical"
    )
    print(head)
    for name, got in summary:
        ok = all("error" not in r for k in got for r in got[k])
        if not ok:
            errs = [str(r.get("error")) for k in got for r in got[k] if "error" in r]
            print(f"{name[:42]:<42} error: {errs[0][:80]}")
            continue

        def med(k: str, key: str, g: dict[str, list[dict[str, object]]] = got) -> float:
            return statistics.median(float(r[key]) for r in g[k])  # type: ignore[arg-type]

        loads = [float(r["load"]) for k in got for r in got[k]]  # type: ignore[arg-type]
        hashes = {str(r["hash"]) for k in got for r in got[k]}
        radius = float(got["A"][0]["radius"])  # type: ignore[arg-type]
        print(
            f"{name[:42]:<42} {radius:>8.6g}  {med('A', 'cpu'):>8.2f} {med('B', 'cpu'):>8.2f} "
            f"{med('B', 'cpu') / med('A', 'cpu'):>5.2f}  {med('A', 'wall'):>8.2f} "
            f"{med('B', 'wall'):>8.2f}  {min(loads):>4.1f}-{max(loads):<4.1f}  "
            f"{int(got['B'][0]['tris']):>8}  {'yes' if len(hashes) == 1 else 'NO ' + str(hashes)}"  # type: ignore[call-overload]
        )
    print("# medians of the runs; load = 1-minute load average before each run (min-max)")


if __name__ == "__main__":
    main()
