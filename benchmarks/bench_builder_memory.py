#!/usr/bin/env python
"""Peak memory per strut and time of the graph builder (``conformal.voxel_lattice``).

Run from the repository root::

    python benchmarks/bench_builder_memory.py                  # 1M and 5M struts, all cases
    python benchmarks/bench_builder_memory.py --sizes 20       # the 20M cases (~2-3 GB each)
    python benchmarks/bench_builder_memory.py --stages         # where the peak is, per stage

Each case runs in a fresh interpreter (one subprocess per case): it loads the part, warms
the numba kernels up on a small fill, then resets the peak RSS (``echo 5 >
/proc/self/clear_refs``) and builds the lattice with ``voxel_lattice(part, cell, h, r,
fill="inside")``. ``peak B/strut`` is (VmHWM after the build - VmRSS just before it) /
struts: the whole process's resident memory, numpy and numba allocations alike (not
tracemalloc, which misses numba's). ``ru_maxrss`` is not used: in a subprocess Linux folds
the parent's RSS at fork into it. ``graph B/strut`` is what the result itself holds
(``nodes``, ``edges``, ``radii`` bytes): the floor of any builder that returns it.

Cases: a box filled with BCC and with octet cells, and the Stanford bunny
(``../shared/data/meshes/bunny_closed_odedstein.obj``, bbox min at the origin, scaled by
56.487 as in ``bench_stitch.py``) filled with BCC and octet cells; the cell size is chosen
for about 1M / 5M / 20M struts, the radius is a fixed fraction of the cell size.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BUNNY_PATH = DATA / "meshes" / "bunny_closed_odedstein.obj"
BUNNY_SCALE = 56.48725264197303  # bench_stitch.py: ~135k 1 mm cells with their centre inside

#: radius as a fraction of the cell size (the fit then leaves every strut as asked)
RADIUS_FRACTION = {"bcc": 0.2, "octet": 0.08}
#: struts per cell deep inside a block (BCC: 8, none shared; octet: 24)
STRUTS_PER_CELL = {"bcc": 8, "octet": 24}
#: for the bunny: cells of size h fully inside ~ BUNNY_CELLS_1MM / h^3 (1 mm: measured)
BUNNY_CELLS_1MM = 122_400


def _status_kb(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return -1


def _reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")


def _box_part(n: int, h: float) -> Any:
    """An axis-aligned box whose centred grid of cells ``h`` has exactly ``n^3`` inside cells."""
    from conformal.part import Part

    s = (n + 1.5) * h  # the grid has n + 2 cells, the outer layer sticks out by h / 4: cut
    v = np.array([[x, y, z] for x in (0, s) for y in (0, s) for z in (0, s)], dtype=np.float64)
    f = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
        dtype=np.int64,
    )  # fmt: skip
    return Part(v, f, name=f"box {s:g} mm")


def _bunny_part() -> Any:
    from conformal.part import load_part

    p = load_part(BUNNY_PATH)
    lo = p.bounds[0]
    m = np.eye(4) * BUNNY_SCALE
    m[3, 3] = 1.0
    m[:3, 3] = -lo * BUNNY_SCALE
    return p.transformed(m)


def case_setup(spec: dict[str, Any]) -> tuple[Any, float]:
    cell, target = spec["cell"], spec["struts"]
    cells = target / STRUTS_PER_CELL[cell]
    if spec["part"] == "box":
        n = max(2, round(cells ** (1 / 3)))
        return _box_part(n, 1.0), 1.0
    h = (BUNNY_CELLS_1MM / cells) ** (1 / 3)
    return _bunny_part(), float(f"{h:.4g}")


def child(spec: dict[str, Any]) -> dict[str, Any]:
    import conformal
    from conformal import voxel

    part, h = case_setup(spec)
    cell = spec["cell"]
    r = RADIUS_FRACTION[cell] * h
    # warm-up: numba JIT/cache load and lazy imports, on a small fill of the same part
    big = float(part.size.max()) / 8
    conformal.voxel_lattice(part, cell, big, RADIUS_FRACTION[cell] * big)
    stages: dict[str, float] = {}
    if spec.get("stages"):
        graph_cls = voxel.LatticeGraph
        for name in ("voxelize", "tile_arrays", "_cleanup", "keep_main_components",
                     "resolve_radii", "fit_radii", "LatticeGraph"):  # fmt: skip
            owner: Any = voxel
            if name == "LatticeGraph" and hasattr(graph_cls, "_from_owned"):
                owner, name = graph_cls, "_from_owned"  # noqa: PLW2901
            orig = getattr(owner, name)

            def wrapped(*a: Any, _orig: Any = orig, _name: str = name, **k: Any) -> Any:
                base = _status_kb("VmRSS")
                _reset_peak()
                out = _orig(*a, **k)
                stages[_name] = max(stages.get(_name, 0), _status_kb("VmHWM") - base)
                stages[_name + " (kept)"] = _status_kb("VmRSS") - base
                return out

            setattr(owner, name, wrapped if owner is voxel else staticmethod(wrapped))
    gc.collect()
    _reset_peak()
    before = _status_kb("VmRSS")
    c0 = time.process_time()
    t0 = time.perf_counter()
    g = conformal.voxel_lattice(part, cell, h, r, fill="inside")
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    peak = _status_kb("VmHWM")
    after = _status_kb("VmRSS")
    m = g.num_edges
    return {
        "spec": spec,
        "h": h,
        "radius": r,
        "struts": m,
        "nodes": g.num_nodes,
        "rss_before_kb": before,
        "peak_kb": peak,
        "rss_after_kb": after,
        "peak_bytes_per_strut": (peak - before) * 1024 / m,
        "graph_bytes_per_strut": (g.nodes.nbytes + g.edges.nbytes + g.radii.nbytes) / m,
        "wall_s": wall,
        "cpu_s": cpu,
        "loadavg": os.getloadavg()[0],
        "stages_kb": stages,
    }


def run_child(spec: dict[str, Any]) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps(spec)]
    p = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if p.returncode != 0:
        return {"spec": spec, "error": (p.stderr or p.stdout)[-800:]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1,5", help="millions of struts, comma-separated")
    ap.add_argument("--cases", default="box-bcc,box-octet,bunny-bcc,bunny-octet")
    ap.add_argument("--stages", action="store_true", help="peak per builder stage")
    ap.add_argument("--out", default=None, help="append the table to this file")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(json.loads(args.child))))
        return
    import conformal

    code = Path(conformal.__file__).resolve().parents[1]
    lines = [
        f"# bench_builder_memory  code: {code}  "
        f"git: {_git(code)}  {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}",
        f"# python {sys.version.split()[0]}, numpy {np.__version__}, "
        f"loadavg at start {os.getloadavg()[0]:.2f}",
        "case               h mm     struts      nodes  before MB  peak MB  peak B/strut  "
        "graph B/strut  wall s  cpu s  load",
    ]
    print("\n".join(lines), flush=True)
    for size in (float(s) for s in args.sizes.split(",")):
        for case in args.cases.split(","):
            part, cell = case.split("-")
            spec = {"part": part, "cell": cell, "struts": int(size * 1e6), "stages": args.stages}
            r = run_child(spec)
            label = f"{case} {size:g}M"
            if "error" in r:
                line = f"{label:<16} ERROR {r['error'].strip().splitlines()[-1]}"
            else:
                line = (
                    f"{label:<16} {r['h']:6.4g} {r['struts']:>10,} {r['nodes']:>10,} "
                    f"{r['rss_before_kb'] / 1024:>10.0f} {r['peak_kb'] / 1024:>8.0f} "
                    f"{r['peak_bytes_per_strut']:>13.1f} {r['graph_bytes_per_strut']:>14.1f} "
                    f"{r['wall_s']:>7.2f} {r['cpu_s']:>6.2f} {r['loadavg']:>5.2f}"
                )
                if r["stages_kb"]:  # the stage wrappers reset the peak: no overall figure
                    m = r["struts"]
                    line = f"{label:<16} {r['h']:6.4g} {m:>10,} {r['nodes']:>10,}  (stages)"
                    line += "\n    stages B/strut (peak above the stage's start; kept): "
                    line += ", ".join(f"{k} {v * 1024 / m:.0f}" for k, v in r["stages_kb"].items())
            print(line, flush=True)
            lines.append(line)
    if args.out:
        with open(args.out, "a", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n\n")


def _git(path: Path) -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(path), "log", "-1", "--format=%h %s"],
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        return out.stdout.strip()[:60]
    except OSError:
        return "?"


if __name__ == "__main__":
    main()
