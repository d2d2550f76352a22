"""End-to-end speed of ``lattice-cad fill ... --skin`` on the GE bracket, with a stage table.

Each run is a fresh process (``--child``) that wraps the main stages (functions of the
package, looked up by name; a stage a tree does not have is skipped) with a timer of wall
and process CPU seconds, then runs the CLI command. Trees are compared by alternating
A/B runs; the load average is printed with every run, since the machine is shared. The
run's CPU includes its worker processes (this process becomes their subreaper).

Usage::

    PYTHONPATH=$PWD python benchmarks/bench_skin.py --trees ../main-before $PWD --repeat 3 \
        --out benchmarks/results/bench_skin.txt
    # one tree with and without an environment variable
    python benchmarks/bench_skin.py --trees "$PWD::NUMPY_MADVISE_HUGEPAGE=1" $PWD
    # the same fill without the skin (the lattice trimmed to the part instead)
    PYTHONPATH=$PWD python benchmarks/bench_skin.py --no-skin --trees ../main-before $PWD
    # the floor of the computation: each run fills twice in one process and times the
    # second (imports done, numba's kernels and OpenCascade loaded; OCCT's offsets still
    # start a new child process, whose start-up then comes after the lattice is built)
    PYTHONPATH=$PWD python benchmarks/bench_skin.py --warm --repeat 2

Times of nested stages are inclusive (``booleans`` is ``build_skin`` minus its surfaces,
lattice conversion, island check and wall measurement).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

#: the repository root; shared data lies beside it (../shared), as in CI
ROOT = Path(__file__).resolve().parents[1]
PART = str(ROOT.parent / "shared" / "data" / "step" / "dolfiny_ge_bracket_rotated_nonds.step")
ARGS = ["--cell", "octet", "--cell-size", "6", "--radius", "0.5", "--skin", "1.5"]

#: (label, module, attribute path): the stages timed (inclusive).
STAGES = [
    ("load part", "lattice_cad.lattice", "_load_part"),
    ("lattice graph", "lattice_cad.lattice", "_fill_graph"),
    ("stitch", "fast_stitch", "stitch"),
    ("cutting part (here)", "conformal.trim", "cutting_part"),
    ("cutting part (child wait)", "conformal.trim", "PendingCut.result"),
    ("skin: build_skin", "conformal.skin", "build_skin"),
    ("skin: OCCT surfaces", "conformal.skin", "_occt_surfaces"),
    ("skin: OCCT offset", "lattice_cad.occ_impl.shapes", "offset_solid_isolated"),
    ("skin: OCCT offset (wait)", "lattice_cad.occ_impl.shapes", "fused_offsets_result"),
    ("skin: split lattice", "conformal.skin", "_split"),
    ("skin: surfaces (all)", "conformal.skin", "_surfaces"),
    ("skin: voxel surfaces", "conformal.skin", "_voxel_surfaces"),
    ("skin: distance field", "conformal.skin", "_distance_field"),
    ("skin: marching tets", "conformal.skin", "marching_tets"),
    ("skin: part_solid", "conformal.skin", "part_solid"),
    ("skin: islands", "conformal.skin", "_keep_attached"),
    ("skin: wall measure", "conformal.skin", "wall_thickness"),
    ("trim: trim_to_part", "conformal.trim", "trim_to_part"),
    ("trim: near struts", "conformal.trim", "_trim_near"),
    ("split_lattice (any)", "conformal.skin_split", "split_lattice"),
    ("escape drill", "lattice_cad.lattice", "Lattice._drill"),
    ("escape verify", "lattice_cad.lattice", "Lattice._verify_escape"),
    ("printability report", "lattice_cad.cli", "_say_printability"),
    ("float32 check (all)", "lattice_cad.lattice", "_checked_single_precision"),
    ("  fast_stitch.check", "fast_stitch", "check"),
    ("  single_precision", "lattice_cad.io", "single_precision"),
    ("write", "lattice_cad.io", "save_mesh"),
    ("mesh volume", "lattice_cad.core.mesh", "signed_volume"),
]


def _wrap(acc: dict, label: str, fn):
    @functools.wraps(fn)
    def timed(*a, **k):
        w0, c0 = time.perf_counter(), time.process_time()
        try:
            return fn(*a, **k)
        finally:
            rec = acc.setdefault(label, [0.0, 0.0, 0])
            rec[0] += time.perf_counter() - w0
            rec[1] += time.process_time() - c0
            rec[2] += 1

    return timed


def _args(no_skin: bool) -> list[str]:
    """The fill's options: ``ARGS``, without ``--skin`` when ``no_skin``."""
    if not no_skin:
        return ARGS
    i = ARGS.index("--skin")
    return ARGS[:i] + ARGS[i + 2 :]


def child(out: str, no_skin: bool = False, warm: bool = False) -> None:
    """Run the CLI command in this process with the stages timed; write JSON to ``out``.
    ``warm``: run it once untimed first (see ``--warm``)."""
    w0, c0 = time.perf_counter(), time.process_time()
    acc: dict = {}
    import lattice_cad.cli as cli

    target = "/tmp/bench_skin_out.stl"
    if warm:
        cli.main(["--quiet", "fill", PART, *_args(no_skin), "-o", target])
        _reap()  # the first run's workers, before the clock starts again
        w0, c0 = time.perf_counter(), time.process_time()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)

    for label, mod, attr in STAGES:
        try:
            m = importlib.import_module(mod)
        except ImportError:
            continue
        owner, name = m, attr
        if "." in attr:
            cls, name = attr.split(".")
            owner = getattr(m, cls, None)
        fn = getattr(owner, name, None) if owner is not None else None
        if fn is None:
            continue
        setattr(owner, name, _wrap(acc, label, fn))
    rc = cli.main(["--quiet", "fill", PART, *_args(no_skin), "-o", target])
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    children = (ru.ru_utime - r0.ru_utime) + (ru.ru_stime - r0.ru_stime)
    acc["TOTAL (in process)"] = [wall, cpu + children, 1]
    Path(out).write_text(json.dumps({"rc": rc, "stages": acc}))


def _subreaper() -> None:
    """Become the subreaper of this process's descendants (Linux): the child processes the
    run starts (the forkserver's workers: OCCT's offsets, the cutting tessellation) are
    then reaped here, so their CPU time is in ``RUSAGE_CHILDREN``; without it, the
    orphaned forkserver and its workers are never counted."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):
        pass


def _reap(seconds: float = 10.0) -> None:
    """Reap the orphaned descendants of a finished run (see :func:`_subreaper`)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            time.sleep(0.05)


def run_once(tree: str, no_skin: bool = False, warm: bool = False) -> dict:
    """One fresh-process run of ``tree``: a repository path, optionally followed by
    ``::VAR=VALUE[,VAR=VALUE]``, environment variables set for that run only (an A/B of
    one tree with and without a setting)."""
    _subreaper()
    path, _, spec = tree.partition("::")
    env = dict(os.environ, PYTHONPATH=path)
    for item in filter(None, spec.split(",")):
        key, _, value = item.partition("=")
        env[key] = value
    out = f"/tmp/bench_skin_{os.getpid()}.json"
    load = os.getloadavg()[0]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.perf_counter()
    subprocess.run(
        [sys.executable, __file__, "--child", out, *(["--no-skin"] if no_skin else []),
         *(["--warm"] if warm else [])],
        env=env, check=True, cwd="/tmp",
        stdout=subprocess.DEVNULL,
    )  # fmt: skip
    wall = time.perf_counter() - w0
    _reap()  # the workers' CPU too
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    data = json.loads(Path(out).read_text())
    data["wall"], data["cpu"], data["load"] = wall, cpu, load
    if warm:  # the timed (second) fill only
        data["wall"], data["cpu"] = data["stages"]["TOTAL (in process)"][:2]
    data["load_after"] = os.getloadavg()[0]
    return data


def _label(tree: str) -> str:
    """A short column name: the tree's folder name, and its environment variables."""
    path, _, spec = tree.partition("::")
    return Path(path).name + (f" {spec}" if spec else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trees", nargs="+", default=[str(Path(__file__).resolve().parents[1])])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=None, help="also write the tables to this file")
    ap.add_argument("--no-skin", action="store_true", help="the same fill without --skin")
    ap.add_argument(
        "--warm",
        action="store_true",
        help="fill twice in each run's process and time the second (the computation's floor)",
    )
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if not Path(PART).is_file():
        sys.exit(f"bench_skin: {PART} is missing: the shared data must lie beside the repository")
    if args.child:
        child(args.child, args.no_skin, args.warm)
        return
    lines: list[str] = []

    def say(s: str = "") -> None:
        print(s, flush=True)
        lines.append(s)

    say(f"bench_skin: lattice-cad fill {Path(PART).name} {' '.join(_args(args.no_skin))} -o x.stl")
    if args.warm:
        say("warm: each process fills twice; the second fill is timed (its wall below too)")
    say(f"machine: {os.cpu_count()} cores; {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}")
    runs: dict[str, list[dict]] = {t: [] for t in args.trees}
    for i in range(args.repeat):
        for t in args.trees:  # alternating A/B
            d = run_once(t, args.no_skin, args.warm)
            runs[t].append(d)
            say(
                f"run {i + 1} {t}: wall {d['wall']:.2f} s, CPU {d['cpu']:.2f} s "
                f"(load avg {d['load']:.2f} -> {d['load_after']:.2f})"
            )
    say()
    labels = [s[0] for s in STAGES] + ["TOTAL (in process)"]
    width = max([18] + [len(_label(t)) for t in args.trees])
    names = "".join(f" | {_label(t):>{width}s}" for t in args.trees)
    head = f"{'stage (median wall / CPU s)':28s}" + names
    say(head)
    say("-" * len(head))

    def med(xs: list[float]) -> float:
        xs = sorted(xs)
        return xs[len(xs) // 2]

    for lab in labels:
        cells = []
        for t in args.trees:
            vals = [d["stages"].get(lab) for d in runs[t]]
            if any(v is None for v in vals):
                cells.append(f"{'-':>{width}s}")
            else:
                w = med([v[0] for v in vals])
                c = med([v[1] for v in vals])
                n = vals[0][2]
                cells.append(f"{f'{w:7.2f} / {c:6.2f} x{n:<2d}':>{width}s}")
        say(f"{lab:28s}" + "".join(f" | {c}" for c in cells))
    for t in args.trees:
        ws = [d["wall"] for d in runs[t]]
        cs = [d["cpu"] for d in runs[t]]
        say(
            f"{_label(t)}: process wall median {med(ws):.2f} s (min {min(ws):.2f}), "
            f"CPU median {med(cs):.2f} s (min {min(cs):.2f})"
        )
    if args.out:
        Path(args.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
