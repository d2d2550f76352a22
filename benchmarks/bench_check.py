"""Alternating A/B timing of the float32 export check (``_checked_single_precision_once``).

Every boolean result the product writes (skins, clip/conform/tet trims) is rounded to
float32, welded and checked in full by ``lattice_cad.lattice._checked_single_precision_once``.
This times that call on real meshes, each run a fresh subprocess with ``PYTHONPATH`` set to
the checkout (numba's cache warmed first on a small sphere, then one timed call), in the
order A B A B ...; wall and CPU seconds (process-wide, all threads) and the 1-minute load
average are printed per run, then a table: the median and best of each side, B/A, and
whether every run of both sides gave the same result (a digest of the output mesh's bytes
and of the full ``fast_stitch.check`` report of it, or of the error raised).

The meshes are the ones the CLI passes to the check, captured once into ``--meshes`` (by
running ``lattice-cad fill`` with the B checkout on the parts in ``<repo>/../shared/data``)::

    python benchmarks/bench_check.py --a /work/main --b . --rounds 3

Cases: ``ge_skin`` (the GE bracket with an octet lattice and a 1.5 mm skin, ~950 K
triangles), ``gear_clip`` (the cycloidal gear, clip fill, ~820 K), ``vent_conform`` (the
ventilator, conform fill, ~275 K), ``ge_tet5`` (the seed's Table 5 case: the GE bracket's
tet lattice at 5 mm, r 0.25, trimmed, ~930 K, about 80 folds after rounding, 10 rounds of
collapses).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"

CASES = {
    "ge_skin": ["step/dolfiny_ge_bracket_rotated_nonds.step", "--cell", "octet",
                "--cell-size", "6", "--radius", "0.5", "--skin", "1.5"],
    "gear_clip": ["step/kcl_cycloidal-gear.step", "--fill", "clip", "--cell-size", "2.576",
                  "--radius", "0.2147"],
    "vent_conform": ["step/pythonocc_Ventilator.stp", "--fill", "conform", "--cell-size",
                     "5.333", "--radius", "0.4444"],
    "ge_tet5": ["step/dolfiny_ge_bracket_rotated_nonds.step", "--method", "tet",
                "--cell-size", "5", "--radius", "0.25"],
}  # fmt: skip

CAPTURE = r"""
import sys
import numpy as np
import lattice_cad.lattice as L

target = sys.argv[1]
orig = L._checked_single_precision_once
saved = []

def capture(mesh, name):
    if not saved:  # the first mesh the check gets (the boolean result itself)
        np.savez(target, vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces))
        saved.append(1)
    return orig(mesh, name)

L._checked_single_precision_once = capture
from lattice_cad.cli import main

if __name__ == "__main__":
    rc = main(sys.argv[2:])
    sys.exit(rc if saved else 3)
"""

CHILD = r"""
import dataclasses, hashlib, json, os, sys, time
import numpy as np
import trimesh
import fast_stitch
from lattice_cad.core.errors import ExportError
from lattice_cad.core.mesh import Mesh
from lattice_cad.lattice import _checked_single_precision_once

z = np.load(sys.argv[1])
mesh = Mesh(vertices=z["vertices"], faces=z["faces"])
s = trimesh.creation.icosphere(subdivisions=3)  # numba cache warm-up
_checked_single_precision_once(Mesh(vertices=s.vertices, faces=s.faces), "warm-up")
t0, c0 = time.perf_counter(), time.process_time()
try:
    out = _checked_single_precision_once(mesh, "the mesh")
except ExportError as e:
    out, err = None, str(e)
t, c = time.perf_counter() - t0, time.process_time() - c0
load = os.getloadavg()[0]
h = hashlib.sha1()
if out is None:
    h.update(err.encode())
else:
    h.update(out.vertices.tobytes())
    h.update(out.faces.tobytes())
    rep = fast_stitch.check(out)
    for f in dataclasses.fields(rep):
        x = getattr(rep, f.name)
        b = np.ascontiguousarray(x).tobytes() if isinstance(x, np.ndarray) else repr(x).encode()
        h.update(b)
    h.update(str(rep).encode())
print(json.dumps({"wall": t, "cpu": c, "load": load, "triangles": len(mesh.faces),
                  "digest": h.hexdigest()[:12], "valid": out is not None}))
"""


def capture(case: str, target: Path, tree: Path) -> None:
    """Run the fill of ``case`` with checkout ``tree`` and save the mesh the check gets."""
    args = CASES[case]
    part = DATA / args[0]
    target.parent.mkdir(parents=True, exist_ok=True)
    out_stl = target.with_suffix(".stl")
    env = dict(os.environ, PYTHONPATH=str(tree.resolve()))
    cmd = [sys.executable, "-c", CAPTURE, str(target), "fill", str(part), *args[1:], "-q"]
    subprocess.run([*cmd, "-o", str(out_stl)], env=env, check=True, cwd="/tmp", timeout=3600)
    out_stl.unlink(missing_ok=True)


def run(tree: str, mesh: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(Path(tree).resolve()))
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(mesh)], env=env, capture_output=True, text=True,
        check=True, cwd="/tmp", timeout=1800,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="checkout A (before)")
    ap.add_argument("--b", required=True, help="checkout B (after)")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--meshes", default="/tmp/bench_check_meshes", help="mesh cache (npz)")
    ns = ap.parse_args()

    paths = {}
    for case in ns.cases:
        paths[case] = Path(ns.meshes) / f"{case}.npz"
        if not paths[case].exists():
            print(f"capturing {case} (lattice-cad fill with {ns.b}) ...", flush=True)
            capture(case, paths[case], Path(ns.b))

    results: dict[tuple[str, str], list[dict]] = {}
    print(f"{'round':>5}  {'case':<13} {'side':<4} {'wall s':>7} {'cpu s':>7} {'load':>5}  digest")
    for r in range(ns.rounds):
        for case in ns.cases:
            for side, tree in (("A", ns.a), ("B", ns.b)):
                res = run(tree, paths[case])
                results.setdefault((case, side), []).append(res)
                print(
                    f"{r + 1:>5}  {case:<13} {side:<4} {res['wall']:7.2f} {res['cpu']:7.2f} "
                    f"{res['load']:5.2f}  {res['digest']}",
                    flush=True,
                )

    print()
    print(f"A = {Path(ns.a).resolve()}, B = {Path(ns.b).resolve()}, {ns.rounds} runs each")
    head = (
        f"{'case':<13} {'triangles':>10} {'A wall med/best':>16} {'B wall med/best':>16} "
        f"{'B/A':>5} {'A cpu med':>9} {'B cpu med':>9} {'B/A':>5} {'load':>10} {'identical':>9}"
    )
    print(head)
    print("-" * len(head))
    for case in ns.cases:
        a, b = results[(case, "A")], results[(case, "B")]
        aw = [x["wall"] for x in a]
        bw = [x["wall"] for x in b]
        ac = statistics.median(x["cpu"] for x in a)
        bc = statistics.median(x["cpu"] for x in b)
        loads = [x["load"] for x in a + b]
        same = len({x["digest"] for x in a + b}) == 1
        print(
            f"{case:<13} {a[0]['triangles']:>10,} "
            f"{statistics.median(aw):7.2f} /{min(aw):6.2f}  {statistics.median(bw):7.2f} /"
            f"{min(bw):6.2f}  {statistics.median(bw) / statistics.median(aw):5.2f} "
            f"{ac:9.2f} {bc:9.2f} {bc / ac:5.2f} {min(loads):4.1f}-{max(loads):4.1f} "
            f"{'yes' if same else 'NO':>9}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
