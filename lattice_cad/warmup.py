"""Compile the numerical kernels once, ahead of the first real run.

lattice-cad's kernels are numba functions compiled for the machine on their first call and
cached on disk (numba's ``cache=True``: beside the sources, or in ``NUMBA_CACHE_DIR``). On a
new install the first ``lattice-cad fill`` pays for that compilation: the GE bracket with a
skin takes about 3 minutes the first time on a 2-core machine against 15 s later. Compilation
is single-threaded per process, so :func:`warmup` runs every mode on a small part in
``jobs`` processes at once: each compiles (and caches) a share of the kernels, and every
later process loads them.

The tasks go through the command line (:func:`lattice_cad.cli.main`) as a user's runs do,
so they reach the kernels with the same argument types: a 24 x 16 x 10 mm B-rep block with a
hole (written as STEP) and its tessellation (STL), filled in each mode, checked, previewed,
and validated against the exact reference.
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["TASKS", "TaskResult", "kernels_cached", "warmup"]

#: name -> command lines (``PART`` is the STEP block, ``MESH`` its STL, ``OUT`` a file stem
#: in the task's directory); in the order a single process would run them.
TASKS: dict[str, list[list[str]]] = {
    "skin": [  # first: it reaches the most kernels (run alone, then the rest in parallel)
        ["fill", "PART", "--cell", "octet", "--cell-size", "5", "--radius", "0.4",
         "--skin", "1", "-o", "OUT.stl"],
        ["check", "OUT.stl"],
    ],
    "tet": [["fill", "PART", "--method", "tet", "--cell-size", "5", "--radius", "0.4",
             "-o", "OUT.stl"]],
    "bcc": [
        ["fill", "PART", "--cell", "bcc", "--cell-size", "4", "--radius", "0.3",
         "-o", "OUT.3mf"],
        ["preview", "OUT.3mf", "-o", "OUT.png"],
    ],
    "conform": [["fill", "PART", "--cell", "kelvin", "--fill", "conform", "--cell-size", "5",
                 "--radius", "0.4", "-o", "OUT.stl"]],
    "clip": [["fill", "PART", "--cell", "bcc", "--fill", "clip", "--cell-size", "5",
              "--radius", "0.4", "-o", "OUT.stl"]],
    "mesh-skin": [["fill", "MESH", "--cell", "octet", "--cell-size", "5", "--radius", "0.4",
                   "--skin", "1", "-o", "OUT.stl"]],
    "mesh-tet": [["fill", "MESH", "--method", "tet", "--cell-size", "5", "--radius", "0.4",
                  "-o", "OUT.stl"]],
    "validate": [["validate", "PART", "--cell", "bcc", "--cell-size", "8", "--radius", "0.6",
                  "--report", "OUT_report"]],
}  # fmt: skip


@dataclass
class TaskResult:
    """One warm-up task: its exit code, seconds, and the kernels its process compiled
    (``compiled``) or loaded from the cache (``loaded``) while running it."""

    name: str
    code: int
    seconds: float
    compiled: int
    loaded: int
    errors: list[str] = field(default_factory=list)


def _kernel_counts() -> tuple[int, int]:
    """(compiled, loaded from the cache) signatures of every numba function of the
    package's modules loaded in this process so far."""
    compiled = loaded = 0
    roots = ("lattice_cad", "conformal", "fast_stitch", "reference_boolean")
    for name, mod in list(sys.modules.items()):
        if mod is None or name.split(".")[0] not in roots:
            continue
        for obj in list(vars(mod).values()):
            stats = getattr(obj, "stats", None)
            if stats is not None and hasattr(obj, "py_func") and hasattr(stats, "cache_misses"):
                compiled += sum(stats.cache_misses.values())
                loaded += sum(stats.cache_hits.values())
    return compiled, loaded


def _run_task(name: str, part: str, mesh: str, folder: str) -> TaskResult:
    """Run one task's command lines in this process (a pool worker)."""
    import contextlib
    import io

    from lattice_cad.cli import main

    before = _kernel_counts()
    t0 = time.perf_counter()
    code = 0
    errors: list[str] = []
    out = str(Path(folder) / name)
    for argv in TASKS[name]:
        args = [part if a == "PART" else mesh if a == "MESH" else a for a in argv]
        args = [a.replace("OUT", out) if a.startswith("OUT") else a for a in args]
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            rc = main(["-q", *args])
        if rc != 0:
            code = rc
            errors.append(f"lattice-cad {' '.join(args)}: exit {rc}: {err.getvalue().strip()}")
            break
    after = _kernel_counts()
    return TaskResult(
        name=name,
        code=code,
        seconds=time.perf_counter() - t0,
        compiled=after[0] - before[0],
        loaded=after[1] - before[1],
        errors=errors,
    )


def _make_parts(folder: Path) -> tuple[str, str]:
    """The warm-up block as STEP (B-rep) and STL (mesh) in ``folder``."""
    import cadquery as cq

    block = cq.Workplane("XY").box(24.0, 16.0, 10.0).faces(">Z").workplane().hole(6.0)
    step, stl = folder / "block.step", folder / "block.stl"
    cq.exporters.export(block, str(step))
    cq.exporters.export(block, str(stl), tolerance=0.01, angularTolerance=0.1)
    return str(step), str(stl)


def warmup(
    *,
    tasks: Sequence[str] | None = None,
    jobs: int = 2,
    progress: Callable[[TaskResult], None] | None = None,
) -> list[TaskResult]:
    """Compile (and cache) the kernels by running ``tasks`` (default: all of
    :data:`TASKS`) on a small part, in ``jobs`` processes.

    Parameters
    ----------
    tasks : sequence of str, optional
        Names from :data:`TASKS`.
    jobs : int
        Worker processes (each compiles what its tasks reach first; 2 on a 2-core machine).
    progress : callable, optional
        Called with each :class:`TaskResult` as it finishes.

    Returns
    -------
    list of TaskResult
        In the order they finished. A task that fails does not stop the others; its
        ``errors`` say why.
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    names = list(TASKS) if tasks is None else list(tasks)
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        raise ValueError(f"unknown warm-up task(s) {unknown}; known: {', '.join(TASKS)}")
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    results: list[TaskResult] = []

    def done(r: TaskResult) -> None:
        results.append(r)
        if progress is not None:
            progress(r)

    with tempfile.TemporaryDirectory(prefix="lattice-cad-warmup-") as tmp:
        part, mesh = _make_parts(Path(tmp))
        calls = [(n, part, mesh, tmp) for n in names]
        # the first task alone: it compiles what every mode shares (fill, stitch, check,
        # writers), which parallel processes would each compile again
        first, rest = calls[:1], calls[1:]
        for call in first if jobs > 1 else calls:
            done(_run_task(*call))
        if jobs == 1 or not rest:
            return results
        # not a multiprocessing.Pool: its daemonic workers cannot start the child processes
        # the skin (OCCT's offsets), tet (gmsh) and validate tasks use
        with ProcessPoolExecutor(
            max_workers=min(jobs, len(rest)), mp_context=mp.get_context("spawn")
        ) as pool:
            futures = [pool.submit(_run_task, *call) for call in rest]
            for fut in as_completed(futures):
                done(fut.result())
    return results


def kernels_cached() -> bool:
    """Whether numba's cache holds the stitcher's kernels (False on a new install, before
    :func:`warmup` or a first run)."""
    from fast_stitch import _kernels

    kernel: Any = _kernels.build_hubs  # numba's cache internals are not typed
    try:
        index = kernel._cache._cache_file._index_path
    except AttributeError:  # another numba: assume cached, say nothing
        return True
    return Path(index).is_file()
