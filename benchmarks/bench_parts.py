"""Real-parts benchmark: run ``lattice-cad fill`` on every shared test part with five settings.

What it measures
----------------
Every file in ``<repo>/../shared/data/step`` and ``<repo>/../shared/data/meshes`` is filled
by the command-line tool, once per setting, in a fresh subprocess (so each time includes the
interpreter start-up, imports, loading the numba cache, reading the part, building the
lattice, meshing it and writing the STL: what a user waits for). The cell size is the
largest extent of the part / 15 (the extent comes from ``conformal.load_part``, called once
per part in this process) and the strut radius is cell / 12. The settings are

=========  ============================================
bcc        ``--cell bcc``
skin       ``--cell octet --skin CELL/6``
tet        ``--method tet``
conform    ``--cell kelvin --fill conform``
clip       ``--cell bcc --fill clip``
=========  ============================================

and, when asked with ``--settings``, ``conform-octet``, ``conform-fcc`` and ``clip-octet``
(the same with other cells).

each added to ``lattice-cad fill PART -o OUT.stl --cell-size CELL --radius R``.

A run is ``ok`` only when the command exits with 0, the STL exists, ``lattice-cad check``
accepts it, and an independent check passes: trimesh (vertices merged) finds it watertight,
winding-consistent and with a positive volume, and manifold3d builds a ``Manifold`` from it
with status ``NoError``. Outcomes: ``ok``, ``fail`` (non-zero exit, no file, or the part
could not be loaded here), ``invalid`` (a file was written but a check rejects it),
``timeout``. For every run the table gives the wall time of the fill command, the number
of struts (parsed from the "N struts, M nodes" line the CLI prints; ``--quiet`` would
suppress it, so it is not passed) and how many of them had to be made thinner than 0.7 x
the radius asked ("thin", from the CLI's "N below 0.7 x the radius asked"), the
triangles of the written file, the bodies
(connected components over shared edges that enclose positive volume: a cavity's wall is
not a body), the protrusion (the largest distance of a vertex of the file outside the
part, exact winding numbers against the part's tessellation (for B-rep parts one with a
chord error of 0.1 % of the strut radius, or coarser where that would need more than
``REFERENCE_MAX_TRIANGLES``: then "~" and its chord in % r follow), in % of the strut radius;
issue 13 asks for at most 1 %) and the error: the CLI's ``error:`` line (or the
problems ``lattice-cad check`` lists, or what the independent check found), cut to 90
characters in the table and complete in the JSON.

Before the measurements every setting is run once on a small box so that numba kernels
are compiled and cached (``--no-warmup`` skips this); the first run after a code change
would otherwise include minutes of compilation.

How to run
----------
::

    python benchmarks/bench_parts.py                       # all parts, all settings
    python benchmarks/bench_parts.py --parts kcl_ bunny --settings bcc tet
    python benchmarks/bench_parts.py --jobs 2 --timeout 300 --json results.json
    python benchmarks/bench_parts.py --out out/lattices    # keep the STL files

Rows are printed as the runs complete; at the end the whole table is printed again,
sorted by part and setting, followed by one summary line per setting. Ctrl-C (or SIGTERM)
kills the running subprocesses and prints the partial table.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
PART_DIRS = ("step", "meshes")

CELLS_PER_EXTENT = 15.0
RADIUS_PER_CELL = 12.0
SKIN_PER_CELL = 6.0

ERROR_WIDTH = 90
CHECK_TIMEOUT_MIN = 120.0
#: The protrusion's reference tessellation holds about this many triangles at most (its
#: chord error is then coarser than 0.1 % r, and the table shows it after a "~").
REFERENCE_MAX_TRIANGLES = 2_000_000


def _fmt_mm(value: float) -> str:
    return f"{value:.6g}"


# setting name -> extra ``lattice-cad fill`` arguments; SKIN stands for CELL / SKIN_PER_CELL
SETTINGS: dict[str, str] = {
    "bcc": "--cell bcc",
    "skin": "--cell octet --skin SKIN",
    "tet": "--method tet",
    "conform": "--cell kelvin --fill conform",
    "clip": "--cell bcc --fill clip",
    # more cells in the modes that pull struts onto the surface (run with --settings)
    "conform-octet": "--cell octet --fill conform",
    "conform-fcc": "--cell fcc --fill conform",
    "clip-octet": "--cell octet --fill clip",
}
#: the settings run when --settings is not given (the issue's four and clip)
DEFAULT_SETTINGS = ("bcc", "skin", "tet", "conform", "clip")


def setting_args(setting: str, cell: float) -> list[str]:
    """The extra ``lattice-cad fill`` arguments of ``setting`` for cells of ``cell`` mm."""
    skin = _fmt_mm(cell / SKIN_PER_CELL)
    return [skin if a == "SKIN" else a for a in SETTINGS[setting].split()]


STRUTS_RE = re.compile(r"^\s*([\d,]+) struts\b", re.MULTILINE)
THIN_RE = re.compile(r"\b([\d,]+) below [\d.]+ x the radius asked")
ANSI_RE = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _lattice_cad() -> str:
    """The ``lattice-cad`` script next to this interpreter, else the one on PATH."""
    exe = Path(sys.executable).with_name("lattice-cad")
    if exe.exists():
        return str(exe)
    found = shutil.which("lattice-cad")
    if found is None:
        sys.exit("error: the lattice-cad command is not installed (pip install -e .)")
    return found


LATTICE_CAD = _lattice_cad()


# ------------------------------------------------------------------ data types
@dataclass
class Part:
    """A part file with the lattice dimensions derived from its extent."""

    path: Path
    size: tuple[float, float, float] | None = None
    load_error: str = ""
    shape: Any = None  # the conformal.Part, for the protrusion of the written lattice

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def cell(self) -> float:
        assert self.size is not None
        return max(self.size) / CELLS_PER_EXTENT

    @property
    def radius(self) -> float:
        return self.cell / RADIUS_PER_CELL


@dataclass
class Row:
    """The result of one (part, setting) run."""

    part: str
    setting: str
    outcome: str  # ok / fail / invalid / timeout
    seconds: float | None = None
    struts: int | None = None
    thin: int | None = None  # struts the CLI says are below 0.7 x the radius asked
    triangles: int | None = None
    bodies: int | None = None
    protrusion: float | None = None  # % of the strut radius outside the part
    reference_chord: float | None = None  # its reference tessellation's chord, % of r
    error: str = ""
    cell: float | None = None
    radius: float | None = None
    command: str = ""


# ------------------------------------------------------------------ helpers
@contextlib.contextmanager
def _silence_fds() -> Iterator[None]:
    """Send file descriptors 1 and 2 to /dev/null (OpenCascade prints from C++)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


def _one_line(text: str) -> str:
    """``text`` on one line, without the data directory."""
    return " ".join(text.split()).replace(f"{DATA}{os.sep}", "")


def _truncate(text: str, width: int = ERROR_WIDTH) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def _lines(text: str) -> list[str]:
    """Non-empty lines of captured output, without ANSI escapes (tqdm redraws with \\r)."""
    text = ANSI_RE.sub("", text)
    return [ln.strip() for chunk in text.splitlines() for ln in chunk.split("\r") if ln.strip()]


def _is_progress(line: str) -> bool:
    return "|" in line and ("it/s" in line or "/s]" in line or "%" in line)


def _error_line(code: int | None, stderr: str, stdout: str = "") -> str:
    """The line that explains a failure.

    The CLI's ``error: ...`` line if there is one; else the last line of stderr that is
    neither a progress bar nor a warning (a traceback's exception), else the first line of
    stdout, else the first warning. A death by a signal is named first.
    """
    err, out = _lines(stderr), _lines(stdout)
    text = next((ln[ln.index("error:") :] for ln in err + out if "error:" in ln), "")
    if not text:
        rest = [ln for ln in err if not _is_progress(ln) and not ln.startswith("warning:")]
        warns = [ln for ln in err if ln.startswith("warning:")]
        text = (rest[-1:] or out[:1] or warns[:1] or [""])[0]
    if code is not None and code < 0:
        with contextlib.suppress(ValueError):
            text = f"killed by {signal.Signals(-code).name}; {text}".rstrip("; ")
    if not text and code:
        text = f"exit code {code}"
    return _one_line(text)


def _load_parts(paths: Sequence[Path]) -> list[Part]:
    """Load every part once (in this process) to get its extent."""
    from conformal import load_part

    parts = []
    for path in paths:
        part = Part(path)
        try:
            with warnings.catch_warnings(), _silence_fds():
                warnings.simplefilter("ignore")
                part.shape = load_part(path)
                size = np.asarray(part.shape.size, dtype=float)
            if size.shape != (3,) or not np.all(np.isfinite(size)) or size.max() <= 0:
                raise ValueError(f"bad part size {size}")
            part.size = (float(size[0]), float(size[1]), float(size[2]))
        except Exception as exc:  # any load error is a reported result
            part.load_error = _one_line(f"load_part: {str(exc) or type(exc).__name__}")
        parts.append(part)
    return parts


class Runner:
    """Runs subprocesses in their own process groups so that they can all be killed."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._procs: set[subprocess.Popen[bytes]] = set()
        self.stopping = threading.Event()

    def run(self, cmd: list[str], timeout: float) -> tuple[int | None, str, str, float]:
        """Like ``subprocess.run(cmd, capture_output=True, timeout=timeout)``.

        Returns (exit code or None on timeout, stdout, stderr, wall seconds). A separate
        session keeps the terminal's Ctrl-C away from the child; :meth:`kill_all` ends it.
        """
        if self.stopping.is_set():
            raise KeyboardInterrupt
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True
        )
        with self._lock:
            self._procs.add(proc)
        try:
            try:
                out, err = proc.communicate(timeout=timeout)
                code: int | None = proc.returncode
            except subprocess.TimeoutExpired:
                self._kill(proc)
                out, err = proc.communicate()
                code = None
        except BaseException:  # Ctrl-C in this thread: do not leave the child running
            self._kill(proc)
            proc.wait()
            raise
        finally:
            with self._lock:
                self._procs.discard(proc)
        seconds = time.perf_counter() - t0
        if self.stopping.is_set():
            raise KeyboardInterrupt
        return code, out.decode(errors="replace"), err.decode(errors="replace"), seconds

    @staticmethod
    def _kill(proc: subprocess.Popen[bytes]) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)

    def kill_all(self) -> None:
        self.stopping.set()
        with self._lock:
            procs = list(self._procs)
        for proc in procs:
            self._kill(proc)


# ------------------------------------------------------------------ checks
def independent_check(path: Path) -> tuple[str, int, int, Any]:
    """Check a mesh file with trimesh and manifold3d.

    Returns (problem or "", triangles in the file, bodies, vertices (V, 3) float64).
    """
    import manifold3d
    import trimesh
    import trimesh.graph

    raw = trimesh.load(path, force="mesh", process=False)
    if not isinstance(raw, trimesh.Trimesh):
        return f"trimesh: loaded a {type(raw).__name__}, not a mesh", 0, 0, None
    triangles = len(raw.faces)
    if triangles == 0:
        return "empty mesh", 0, 0, None
    mesh = trimesh.Trimesh(vertices=raw.vertices, faces=raw.faces, process=True)  # merges
    del raw
    # bodies: connected surface pieces that enclose positive volume (a cavity's wall is a
    # piece of its own, with negative volume, and belongs to the body around it)
    pieces = trimesh.graph.connected_components(
        mesh.face_adjacency, nodes=np.arange(len(mesh.faces))
    )
    tri = mesh.vertices[mesh.faces]
    signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    bodies = sum(1 for p in pieces if signed[p].sum() > 0)
    problems = []
    if not mesh.is_watertight:
        problems.append("not watertight")
    if not mesh.is_winding_consistent:
        problems.append("winding inconsistent")
    volume = float(mesh.volume)
    if not volume > 0:
        problems.append(f"volume {volume:.4g} <= 0")
    man = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.ascontiguousarray(mesh.faces, dtype=np.uint32),
        )
    )
    status = man.status()
    if status != manifold3d.Error.NoError:
        problems.append(f"manifold3d {status.name}")
    problem = ("trimesh/manifold3d: " + ", ".join(problems)) if problems else ""
    return problem, triangles, bodies, np.asarray(mesh.vertices, dtype=np.float64)


def _check_error(out: Path, code: int, stdout: str, stderr: str) -> str:
    """Why ``lattice-cad check`` rejected ``out``: its problem list, else its report line."""
    lines = _lines(stdout)
    head = next((i for i, ln in enumerate(lines) if ln.startswith(f"{out}: ")), None)
    if head is None:
        detail = _error_line(code, stderr, stdout)
    else:
        problems = [ln[2:] for ln in lines[head + 1 :] if ln.startswith("- ")]
        detail = "; ".join(problems) or lines[head][len(f"{out}: ") :]
    return _one_line(f"lattice-cad check: {detail}")


def run_one(
    runner: Runner, part: Part, setting: str, out_dir: Path, timeout: float, keep: bool
) -> Row:
    """Fill ``part`` with ``setting`` and check the result."""
    if part.size is None:
        return Row(part.name, setting, "fail", error=part.load_error)
    cell, radius = part.cell, part.radius
    out = out_dir / f"{part.path.stem}__{setting}.stl"
    out.unlink(missing_ok=True)
    cmd = [
        LATTICE_CAD,
        "fill",
        str(part.path),
        "-o",
        str(out),
        "--cell-size",
        _fmt_mm(cell),
        "--radius",
        _fmt_mm(radius),
        *setting_args(setting, cell),
    ]
    row = Row(part.name, setting, "fail", cell=cell, radius=radius)
    row.command = shlex.join(["lattice-cad", *cmd[1:]])
    try:
        code, stdout, stderr, row.seconds = runner.run(cmd, timeout)
        if m := STRUTS_RE.search(stdout):
            row.struts = int(m.group(1).replace(",", ""))
            t = THIN_RE.search(stdout)
            row.thin = int(t.group(1).replace(",", "")) if t else 0
        if code is None:
            row.outcome, row.error = "timeout", f"timed out after {timeout:g} s"
            return row
        if code != 0:
            row.error = _error_line(code, stderr, stdout).replace(f"{out.name}: ", "")
            return row
        if not out.is_file():
            row.error = "exit code 0 but no output file"
            return row
        row.outcome = "invalid"
        ccode, cout, cerr, _ = runner.run(
            [LATTICE_CAD, "check", str(out)], max(timeout, CHECK_TIMEOUT_MIN)
        )
        problem, row.triangles, row.bodies, vertices = independent_check(out)
        if vertices is not None and part.shape is not None:
            from conformal.trim import protrusion

            # against a tessellation of a B-rep part 5x finer than the one the lattice is
            # cut by (conformal.trim.cutting_part), so within 0.1 % r of the exact surface,
            # unless that needs more than REFERENCE_MAX_TRIANGLES (the Ventilator's 22,736
            # faces: millions, minutes): then as fine as that allows (the row says so)
            shape = part.shape
            defl = max(
                1e-3 * radius,
                shape.deflection * len(shape.faces) / REFERENCE_MAX_TRIANGLES,
            )
            reference = shape.refined(defl, angular=0.1)
            row.protrusion = 100.0 * protrusion(reference, vertices) / radius
            row.reference_chord = 100.0 * defl / radius
        if ccode is None:
            row.error = f"lattice-cad check timed out after {max(timeout, CHECK_TIMEOUT_MIN):g} s"
        elif ccode != 0:
            row.error = _check_error(out, ccode, cout, cerr)
            if problem:
                row.error += f"; {problem}"
        elif problem:
            row.error = _one_line(problem)
        else:
            row.outcome = "ok"
        return row
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # report, keep benchmarking
        row.error = _one_line(f"benchmark: {type(exc).__name__}: {exc}")
        return row
    finally:
        if not keep:
            out.unlink(missing_ok=True)


def warm_up(runner: Runner, settings: Sequence[str], out_dir: Path, timeout: float) -> None:
    """Run every setting once on a 20 mm box so that numba compiles (and caches) its kernels."""
    import trimesh

    box = out_dir / "_warmup_box.stl"
    trimesh.creation.box(extents=(20.0, 20.0, 20.0)).export(box)
    part = Part(box, size=(20.0, 20.0, 20.0))
    for setting in settings:
        t0 = time.perf_counter()
        row = run_one(runner, part, setting, out_dir, timeout, keep=False)
        note = f"  ({_truncate(row.error)})" if row.outcome != "ok" else ""
        print(f"warm-up {setting:<8} {row.outcome:<8} {time.perf_counter() - t0:7.1f} s{note}")
    box.unlink(missing_ok=True)


# ------------------------------------------------------------------ output
COLUMNS = (
    ("part", "<", 42),
    ("setting", "<", 7),
    ("outcome", "<", 7),
    ("seconds", ">", 8),
    ("struts", ">", 9),
    ("thin", ">", 6),
    ("triangles", ">", 10),
    ("bodies", ">", 6),
    ("protrusion", ">", 14),
    ("error", "<", 0),
)


def _cell(row: Row, name: str) -> str:
    value = getattr(row, name)
    if value is None:
        return ""
    if name == "error":
        return _truncate(value)
    if name == "seconds":
        return f"{value:.1f}"
    if name == "protrusion":  # "~": measured against a coarser reference (its chord)
        ref = row.reference_chord
        coarse = ref is not None and ref > 0.1 * (1 + 1e-6)
        return f"{value:.2f}%" + (f"~{ref:.2g}" if coarse else "")
    if isinstance(value, int):
        return f"{value:,}" if name != "bodies" else str(value)
    return str(value)


def format_header() -> str:
    head = "  ".join(f"{n:{a}{w}}" if w else n for n, a, w in COLUMNS)
    return head + "\n" + "-" * (len(head) + ERROR_WIDTH - len("error"))


def format_row(row: Row) -> str:
    return "  ".join(f"{_cell(row, n):{a}{w}}" if w else _cell(row, n) for n, a, w in COLUMNS)


def format_summary(rows: Sequence[Row], settings: Sequence[str], n_parts: int) -> str:
    lines = []
    for setting in settings:
        done = [r for r in rows if r.setting == setting]
        ok = sum(r.outcome == "ok" for r in done)
        counts = {o: sum(r.outcome == o for r in done) for o in ("fail", "invalid", "timeout")}
        extra = ", ".join(f"{v} {k}" for k, v in counts.items() if v)
        missing = n_parts - len(done)
        if missing:
            extra = ", ".join(filter(None, [extra, f"{missing} not run"]))
        lines.append(f"{setting}: {ok}/{n_parts} ok" + (f"  ({extra})" if extra else ""))
    return "\n".join(lines)


# ------------------------------------------------------------------ main
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        description="Fill every shared test part with five lattice settings and check the files.",
    )
    p.add_argument(
        "--parts", nargs="+", metavar="SUBSTR", help="only parts whose file name contains one"
    )
    p.add_argument(
        "--settings", nargs="+", metavar="NAME", choices=list(SETTINGS), help="only these"
    )
    p.add_argument(
        "--timeout", type=float, default=600.0, metavar="SECONDS", help="per run (default 600)"
    )
    p.add_argument("--jobs", type=int, default=1, metavar="N", help="parallel runs (default 1)")
    p.add_argument(
        "--out", type=Path, metavar="DIR", help="keep the STL files here (default: a temp dir)"
    )
    p.add_argument("--json", type=Path, metavar="PATH", help="also save the rows as JSON")
    p.add_argument("--no-warmup", action="store_true", help="skip the numba warm-up runs")
    p.add_argument(
        "--data",
        type=Path,
        metavar="DIR",
        action="append",
        help="fill the parts in DIR instead (every file in it; repeatable); default: "
        "../shared/data/step and ../shared/data/meshes",
    )
    return p


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    # the fills run in their own sessions: a SIGTERM must end them too, as Ctrl-C does
    signal.signal(signal.SIGTERM, _interrupt)
    if args.jobs < 1 or not args.timeout > 0:
        sys.exit("error: --jobs must be >= 1 and --timeout > 0")
    dirs = args.data or [DATA / d for d in PART_DIRS]
    missing = [d for d in dirs if not d.is_dir()]
    if missing:
        what = "part folder" if args.data else "shared data"
        sys.exit(f"error: {what} not found: {', '.join(map(str, missing))}")
    paths = sorted((f for d in dirs for f in d.iterdir() if f.is_file()), key=lambda f: f.name)
    empty = [d for d in dirs if not any(f.is_file() for f in d.iterdir())]
    if empty:
        # (a folder of folders, as ../shared/data is: each is given with its own --data)
        d = empty[0]
        inside = sorted(f.name for f in d.iterdir() if f.is_dir())
        sys.exit(
            f"error: {d} holds no part files"
            + (f" (only the folders {', '.join(inside)}: give each with --data)" if inside else "")
        )
    if args.parts:
        paths = [f for f in paths if any(s in f.name for s in args.parts)]
        if not paths:
            sys.exit(f"error: no part matches --parts {' '.join(args.parts)}")
    settings = [s for s in SETTINGS if s in (args.settings or DEFAULT_SETTINGS)]

    keep = args.out is not None
    out_dir = args.out or Path(tempfile.mkdtemp(prefix="bench_parts_"))
    out_dir.mkdir(parents=True, exist_ok=True)

    print(f"lattice-cad: {LATTICE_CAD}")
    where = ", ".join(map(str, args.data)) if args.data else DATA
    print(f"data: {where}  ({len(paths)} parts)  settings: {' '.join(settings)}")
    print(f"timeout {args.timeout:g} s, jobs {args.jobs}, output: {out_dir}", flush=True)
    t0 = time.perf_counter()
    runner = Runner()
    parts: list[Part] = []
    rows: list[Row] = []
    interrupted = False
    futures: list[Future[Row]] = []
    reported: set[Future[Row]] = set()
    pool = ThreadPoolExecutor(max_workers=args.jobs)
    try:
        parts = _load_parts(paths)
        print(f"parts loaded in {time.perf_counter() - t0:.1f} s:")
        for part in parts:
            if part.size is None:
                print(f"  {part.name:<42}  {_truncate(part.load_error)}")
            else:
                dims = " x ".join(f"{s:.4g}" for s in part.size)
                print(f"  {part.name:<42}  {dims} mm, cell {part.cell:.4g}, r {part.radius:.4g}")
        print(flush=True)
        if not args.no_warmup:
            warm_up(runner, settings, out_dir, args.timeout)
            print(flush=True)
        print(format_header(), flush=True)
        tasks = [(part, s) for part in parts for s in settings]
        futures = [
            pool.submit(run_one, runner, part, s, out_dir, args.timeout, keep) for part, s in tasks
        ]
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            for fut in done:
                rows.append(fut.result())
                reported.add(fut)
                print(format_row(rows[-1]), flush=True)
    except KeyboardInterrupt:
        interrupted = True
        runner.kill_all()
        pool.shutdown(wait=True, cancel_futures=True)
        # runs that were being checked when the subprocesses were killed still count
        rows += [
            f.result()
            for f in futures
            if f not in reported and f.done() and not f.cancelled() and not f.exception()
        ]
        print("\ninterrupted: running subprocesses killed; partial results", flush=True)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        if not keep:
            shutil.rmtree(out_dir, ignore_errors=True)

    order = {s: i for i, s in enumerate(settings)}
    rows.sort(key=lambda r: (r.part, order[r.setting]))
    print()
    print(f"results ({len(rows)} runs, {time.perf_counter() - t0:.0f} s in total)")
    print(format_header())
    for row in rows:
        print(format_row(row))
    print()
    print(format_summary(rows, settings, len(paths)), flush=True)

    if args.json:
        payload = {
            "data": [str(d) for d in dirs],
            "timeout": args.timeout,
            "jobs": args.jobs,
            "interrupted": interrupted,
            "settings": {s: SETTINGS[s] for s in settings},
            "skin": f"SKIN = cell / {SKIN_PER_CELL:g}",
            "cell": f"largest extent / {CELLS_PER_EXTENT:g}",
            "radius": f"cell / {RADIUS_PER_CELL:g}",
            "parts": [{"part": p.name, "size": p.size, "load_error": p.load_error} for p in parts],
            "rows": [asdict(r) for r in rows],
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(payload, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 130 if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
