"""The ``lattice-cad`` command line.

::

    lattice-cad fill PART -o OUT [--cell --cell-size --radius --method --fill --skin
                                  --segments --beam-lattice[=only] --report DIR
                                  --build-direction X,Y,Z --critical-angle DEG
                                  --min-diameter MM --remove-overhangs --self-supporting
                                  --escape-holes D --escape-at X,Y,Z --keep SELECTOR:MM ...
                                  --max-brep-struts N]
    lattice-cad stitch GRAPH -o OUT [--segments --beam-lattice[=only]]
    lattice-cad reference GRAPH -o OUT
    lattice-cad validate GRAPH_OR_PART --report DIR [--tolerance MM --tolerance-volume PCT]
    lattice-cad cells
    lattice-cad check MESH
    lattice-cad preview FILE -o PNG [--section z[=MM]] [--part PART] [--color-by radius|overhang]

Exit codes: 0 success, 1 error (one readable line on stderr; ``--debug`` shows
the traceback), an invalid mesh for ``check``, or a FAIL verdict of ``validate``
when ``--tolerance`` or ``--tolerance-volume`` is given, 2 wrong usage, 130 interrupted.
"""

from __future__ import annotations

import argparse
import functools
import math
import re
import sys
import time
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from lattice_cad.core import config
from lattice_cad.core.formats import Kind, resolve, suffixes

__all__ = ["main", "build_parser"]

_OUTPUT_HELP = (
    "output file; the format follows the suffix: .stl .3mf .ply .obj (mesh), "
    ".json .npz (graph), .step (exact B-rep: one solid per body, trimmed to a STEP part), "
    ".inp (CalculiX/Abaqus beam model)"
)


class _Console:
    """Messages and progress bars that respect ``--quiet``."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet

    @property
    def bars(self) -> bool:
        """Whether library calls draw their own tqdm bars: only on a terminal (in a log the
        redraws of a bar nested in a step's bar pile up with cursor-up codes)."""
        return not self.quiet and sys.stderr.isatty()

    def say(self, msg: str) -> None:
        if not self.quiet:
            print(_cli_words(msg), flush=True)

    @contextmanager
    def step(self, desc: str) -> Iterator[Callable[[str, int, int], None]]:
        """A tqdm bar for one step; yields a ``progress(stage, done, total)`` callback."""
        t0 = time.perf_counter()
        bar = None
        if not self.quiet:
            from tqdm.auto import tqdm

            # disable=None: no bar when stderr is not a terminal (a log file would get every
            # redraw and its cursor-up codes); the "  step: N s" lines still say where it is
            bar = tqdm(total=1, desc=desc, leave=False, file=sys.stderr, delay=1.0, disable=None)

        def progress(stage: str, done: int, total: int) -> None:
            if bar is not None:
                bar.set_description(f"{desc}: {stage}", refresh=False)
                bar.total = max(int(total), 1)
                bar.n = int(done)
                bar.refresh()

        try:
            yield progress
        finally:
            if bar is not None:
                bar.close()
        self.say(f"  {desc}: {time.perf_counter() - t0:.2f} s")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _percent(text: str) -> float:
    try:
        value = float(text.strip().rstrip("%"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a percentage, got {text!r}") from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a percentage >= 0, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def _keep_zone(text: str) -> str:
    from lattice_cad.core.errors import KeepError
    from lattice_cad.keep import parse_keep

    try:
        parse_keep(text)
    except KeepError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _segments(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 3:
        raise argparse.ArgumentTypeError(f"segments must be >= 3, got {value}")
    return value


def _direction(text: str) -> tuple[float, float, float]:
    values = _point(text)
    if not any(values):
        raise argparse.ArgumentTypeError("the build direction must not be 0,0,0")
    return values


def _angle(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None
    if not 0.0 <= value <= 90.0:
        raise argparse.ArgumentTypeError(f"expected an angle in 0..90 degrees, got {text!r}")
    return value


def _nonnegative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _print_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The printability options of ``fill`` / ``validate`` as ``Lattice.fill`` keywords."""
    return {
        "build_direction": args.build_direction,
        "critical_angle": args.critical_angle,
        "min_diameter": args.min_diameter,
        "remove_overhangs": args.remove_overhangs,
        "self_supporting": args.self_supporting,
    }


def _graph_print_options(lat: Any, args: argparse.Namespace) -> None:
    """Apply the printability options to a lattice read from a graph file (no part)."""
    from conformal import printability as pr
    from lattice_cad.core.errors import PrintabilityError

    if args.self_supporting:
        raise PrintabilityError("--self-supporting orients the cells of a fill, not a graph")
    for name in ("build_direction", "critical_angle", "min_diameter"):
        if getattr(args, name) is not None:
            setattr(lat, name, getattr(args, name))
    if args.remove_overhangs:
        lat.graph, lat.overhang_removal = pr.remove_overhangs(
            lat.graph, build_direction=lat.build_direction, critical_angle=lat.critical_angle
        )


def _say_printability(con: _Console, lat: Any) -> None:
    """The printability summary of the ``fill`` output."""
    if lat.overhang_removal is not None:
        con.say(str(lat.overhang_removal))
    rep = lat.printability()
    for line in rep.lines():
        con.say(line)
    if rep.overhang_count:
        from conformal.printability import self_supporting_cells

        cells = self_supporting_cells(rep.build_direction, rep.critical_angle)
        con.say(
            f"  self-supporting cells along {rep.direction_label} at {rep.critical_angle:g} "
            f"deg: {', '.join(cells) or 'none'} (or --remove-overhangs, --self-supporting)"
        )


def _point(text: str) -> tuple[float, float, float]:
    parts = text.replace(" ", "").split(",")
    try:
        xyz = tuple(float(p) for p in parts)
    except ValueError:
        xyz = ()
    if len(xyz) != 3 or not all(abs(c) < float("inf") for c in xyz):
        raise argparse.ArgumentTypeError(f"expected three numbers X,Y,Z, got {text!r}")
    return (xyz[0], xyz[1], xyz[2])


# ------------------------------------------------------------------ commands
def _load_graph(path: str) -> Any:
    from lattice_cad.core.graph import LatticeGraph

    return LatticeGraph.load(path)


def _check_output(out: Path) -> None:
    """Refuse a missing directory or a directory in the way before any work."""
    from lattice_cad.core.atomic import check_target

    check_target(out)


def _write_report(
    con: _Console, lat: Any, directory: str, args: argparse.Namespace | None = None
) -> Any:
    """Preview, validate, write ``report.html`` and ``report.md`` (+ pictures) into
    ``directory``, print the report's first screen; return the report."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    from lattice_cad.preview import save_png
    from reference_boolean.report import to_text

    tol = getattr(args, "tolerance", None)
    tol_v = getattr(args, "tolerance_volume", None)
    with con.step("preview"):
        save_png(lat, d / "lattice.png", section="z" if lat.part is not None else None)
    # the reference prints its estimate and its own bar over the hubs (progress=True)
    opts: dict[str, Any] = {"progress": True} if not con.quiet else {}
    if getattr(args, "full_union_study", False):
        opts["union_hubs"] = None
    with con.step("validate"):
        rep = lat.validate(
            tolerance=tol, tolerance_volume=None if tol_v is None else tol_v / 100.0, **opts
        )
    with con.step("report"):
        rep.save(d / "report.html")
        rep.save(d / "report.md")
    text = to_text(rep).splitlines()
    print(text[0], flush=True)  # the verdict, even with --quiet
    for line in text[1:]:
        con.say(line)
    con.say(f"report: {d / 'report.html'} (and report.md)")
    return rep


def _fe_options(args: argparse.Namespace, out: Path) -> dict[str, Any] | None:
    """The beam-model options of ``fill`` (None unless the output is ``.inp``); refuses FE
    options with another output before any work."""
    given = [f for f, v in (("--node-set", args.node_set), ("--material", args.material)) if v]
    if out.suffix.lower() not in suffixes(Kind.FE_MODEL):
        if given:
            raise ValueError(f"{' and '.join(given)} apply to .inp output, not {out.name}")
        return None
    sets: dict[str, str] = {}
    for item in args.node_set:
        name, sep, selector = item.partition("=")
        if not sep or not name.strip() or not selector.strip():
            raise ValueError(f"--node-set {item!r}: expected NAME=SELECTOR, e.g. fixed='<Z'")
        if name.strip() in sets:
            raise ValueError(f"--node-set {name.strip()!r} is given twice")
        sets[name.strip()] = selector.strip()
    material: dict[str, str | float] = {}
    for item in (args.material or "").split(","):
        if not item.strip():
            continue
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--material {item!r}: expected KEY=VALUE (E, nu, density, name)")
        k = key.strip()
        try:
            material[k] = value.strip() if k.lower() == "name" else float(value)
        except ValueError:
            raise ValueError(f"--material {item!r}: {value.strip()!r} is not a number") from None
    return {
        "node_sets": sets,
        "material": material or None,
        "dialect": args.fe_dialect,
        "elements_per_strut": args.elements_per_strut,
    }


def _cmd_fill(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.lattice import Lattice

    if args.shards is not None:
        return _cmd_fill_sharded(args, con)
    out = Path(args.output)
    fe_options = _fe_options(args, out)
    if args.beam_lattice:  # refuse a wrong suffix before the work
        resolve(out, Kind.BEAM_LATTICE)
    _check_output(out)
    _first_run_note(con)
    with con.step("load + lattice") as progress:
        lat = Lattice.fill(
            args.part,
            args.cell,
            args.cell_size,
            args.radius,
            method=args.method,
            fill=args.fill,
            skin=args.skin,
            segments=args.segments,
            profile=args.profile,
            min_radius=args.min_radius,
            **_print_kwargs(args),
            escape_holes=args.escape_holes,
            escape_at=args.escape_at,
            keep=args.keep,
            units=args.units,
            close_holes=args.close_holes,
            move_to_origin=args.move_to_origin,
            progress=progress,
        )
    lat.progress = con.bars
    _say_part(con, lat)
    _say_moved(con, lat)
    con.say(f"{lat.graph.num_edges:,} struts, {lat.graph.num_nodes:,} nodes")
    rep = lat.build_report
    if rep is not None:
        notes = [f"fill {rep.fill}"] if rep.fill else []
        if rep.fill != "inside" and not math.isnan(rep.inside_share):  # auto's choice
            notes[0] += (
                f" (whole cells would fill {100 * rep.inside_share:.2g} % of the part)"
                if rep.inside_share
                else " (no whole cell fits)"
            )
        if rep.origin_moved:
            notes.append("grid moved to put a node at the part's deepest point")
        if rep.removed_islands:
            notes.append(f"{rep.removed_islands} strut(s) in loose pieces removed")
        if rep.removed_in_wall:
            notes.append(f"{rep.removed_in_wall} strut(s) wholly inside the skin's wall left out")
        if rep.merged_nodes or rep.removed_short:
            notes.append(f"{rep.merged_nodes} merged, {rep.removed_short} removed")
        if rep.radii_reduced:
            notes.append(f"{rep.radii_reduced} strut(s) thinned (min radius {rep.min_radius:.4g})")
        if rep.thinned_beyond_tolerance:
            notes.append(
                f"{rep.thinned_beyond_tolerance} below {config.THIN_TOLERANCE:g} x the radius asked"
            )
        if notes:
            con.say("; ".join(notes))
    _say_printability(con, lat)
    if out.suffix.lower() in suffixes(Kind.MESH) and args.beam_lattice != "only":
        with con.step("mesh" + (" + skin" if args.skin else "")):
            mesh = lat.mesh()
        density = ""
        volume = mesh.volume  # once: a sum over every triangle
        if lat.part is not None and lat.part.volume > 0:
            density = f", relative density {volume / lat.part.volume:.3f}"
        con.say(f"{len(mesh.faces):,} triangles, volume {volume:.6g} mm^3{density}")
        if lat.skin_report is not None:
            con.say(lat.skin_report.summary())
        if lat.keep_report is not None:
            con.say(lat.keep_report.summary())
        if lat.trim_report is not None:
            con.say(lat.trim_report.summary())
        if (short := lat.cut_shortfall()) is not None:
            con.say(
                f"cut by a tessellation with chord error {short:.2f} % of r (the triangle "
                "budget binds; config.CUT_MAX_TRIANGLES)"
            )
        if lat.escape_report is not None:
            con.say(lat.escape_report.summary())
    if out.suffix.lower() in suffixes(Kind.SOLIDS):
        _save_step(con, lat, out, args.max_brep_struts)
    else:
        with con.step(f"write {out.suffix.lstrip('.')}"):
            if fe_options is not None:
                lat.save_inp(out, **fe_options)
            else:
                lat.save(out, beam_lattice=_beam_lattice_mode(args))
    if getattr(lat, "beam_clip_report", None) is not None:
        con.say(lat.beam_clip_report.summary())
    con.say(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)")
    if fe_options is not None:
        con.say(lat.fe_model.summary())
    if args.report:
        _write_report(con, lat, args.report, args)
    return 0


def _say_part(con: _Console, lat: Any) -> None:
    """The part's size and volume as read; for a mesh file that stores no unit, that its
    numbers were taken as millimetres (a part drawn in inches reads 25.4 times too small,
    and is filled at that size without any other sign of it)."""
    part = lat.part
    if part is None:
        return
    size = " x ".join(f"{float(s):.4g}" for s in part.size)
    line = f"part {size} mm, volume {part.volume:.6g} mm^3"
    if getattr(part, "unit_assumed", False):
        line += (
            f" ({Path(part.name).suffix.lstrip('.').upper()} stores no unit: read as "
            "millimetres; --units in, --units m, ... if it is in another)"
        )
    con.say(line)


def _say_moved(con: _Console, lat: Any) -> None:
    """The translation ``--move-to-origin`` applied to the part, if any."""
    moved = getattr(lat.part, "moved_by", None)
    if moved is not None and moved.any():
        shift = ", ".join(f"{float(c):.6g}" for c in moved)
        con.say(f"part moved by ({shift}) to centre it on the origin")


def _save_step(con: _Console, lat: Any, out: Path, max_struts: int | None) -> None:
    """The exact B-rep to STEP: refused before any work when too large (with the estimate)."""
    from lattice_cad.brep import save_step

    with con.step("B-rep + write step") as progress:
        _, rep = save_step(
            lat, out, max_struts=max_struts, option="--max-brep-struts ", progress=progress
        )
    con.say(
        f"{rep.solids} solid(s) (BRepCheck valid), volume {rep.volume:.6g} mm^3"
        + (", trimmed to the part" if rep.estimate.trim else "")
    )


def _cmd_stitch(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.lattice import Lattice

    graph = _load_graph(args.graph)
    lat = Lattice(graph, segments=args.segments, profile=args.profile)
    lat.progress = con.bars
    out = Path(args.output)
    _check_output(out)
    with con.step("stitch"):
        mesh = lat.mesh()
    with con.step(f"write {out.suffix.lstrip('.')}"):
        lat.save(out, beam_lattice=_beam_lattice_mode(args))
    con.say(f"wrote {out}: {len(mesh.faces):,} triangles ({out.stat().st_size / 1e6:.2f} MB)")
    return 0


def _cmd_reference(args: argparse.Namespace, con: _Console) -> int:
    from reference_boolean import build_reference

    graph = _load_graph(args.graph)
    out = Path(args.output)
    resolve(out, (Kind.SOLIDS, Kind.MESH), what="reference")  # refuse before the build
    with con.step("reference") as progress:
        ref = build_reference(graph, progress=progress)
    with con.step(f"write {out.suffix.lstrip('.')}"):
        ref.save(out)
    con.say(f"wrote {out}: {ref!r}")
    if ref.failed:
        node, why = next(iter(ref.failed.items()))
        print(f"error: {len(ref.failed)} hub(s) failed, e.g. node {node}: {why}", file=sys.stderr)
        return 1
    return 0


def _cmd_validate(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.lattice import Lattice

    src = Path(args.input)
    _first_run_note(con)
    if src.suffix.lower() in suffixes(Kind.GRAPH, action="read"):
        if args.units is not None or args.close_holes or args.move_to_origin:
            raise ValueError(
                "--units, --close-holes and --move-to-origin apply to part files, not to a graph"
            )
        lat = Lattice(_load_graph(args.input), segments=args.segments, profile=args.profile)
        _graph_print_options(lat, args)
    else:
        with con.step("load + lattice"):
            lat = Lattice.fill(
                src,
                args.cell,
                args.cell_size,
                args.radius,
                method=args.method,
                fill=args.fill,
                segments=args.segments,
                profile=args.profile,
                **_print_kwargs(args),
                units=args.units,
                close_holes=args.close_holes,
                move_to_origin=args.move_to_origin,
            )
        _say_moved(con, lat)
    rep = _write_report(con, lat, args.report, args)
    strict = args.tolerance is not None or args.tolerance_volume is not None
    return 1 if strict and not rep.verdict().passed else 0


def _cmd_cells(args: argparse.Namespace, con: _Console) -> int:
    from conformal.cells import CELLS

    width = max(len(n) for n in CELLS)
    for name in sorted(CELLS):
        print(f"{name:<{width}}  {CELLS[name].description}")
    return 0


def _cmd_check(args: argparse.Namespace, con: _Console) -> int:
    from fast_stitch.check import check
    from lattice_cad.io import read_mesh

    _refuse_non_mesh(args.mesh)
    with con.step("read"):
        v, f = read_mesh(args.mesh)
    if len(f) == 0:
        print(f"{args.mesh}: INVALID: the file holds no triangles")
        return 1
    with con.step("check"):
        rep = check((v, f), self_intersections=not args.no_self_intersections)
    print(f"{args.mesh}: {rep}")
    return 0 if rep.valid else 1


def _refuse_non_mesh(path: str) -> None:
    """``check`` takes meshes: say what a part or graph file is instead of a suffix error."""
    from lattice_cad.core.errors import InputFileError

    s = Path(path).suffix.lower()
    if s in (".step", ".stp"):
        raise InputFileError(
            f"{path}: is a STEP part, not a mesh; `lattice-cad check` checks mesh files "
            f"({' '.join(suffixes(Kind.MESH, action='read'))})"
        )
    if s in suffixes(Kind.GRAPH, action="read"):
        raise InputFileError(
            f"{path}: is a lattice graph, not a mesh; stitch it first "
            f"(`lattice-cad stitch {path} -o out.stl`)"
        )


def _first_run_note(con: _Console) -> None:
    """Say why a first run on a new install is slow (numba compiling, once)."""
    from lattice_cad.warmup import kernels_cached

    if not kernels_cached():
        con.say(
            "first run on this install: numba compiles the kernels for this machine "
            "(a few minutes, once); `lattice-cad warmup` does it ahead, on all cores"
        )


def _cmd_warmup(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.warmup import warmup

    con.say(
        f"compiling lattice-cad's numerical kernels for this machine in {args.jobs} "
        "process(es) (once per install: later runs load them from numba's cache)"
    )
    t0 = time.perf_counter()

    def progress(r: Any) -> None:
        state = "ok" if r.code == 0 else f"FAILED (exit {r.code})"
        con.say(
            f"  {r.name:<10} {state:<6} {r.seconds:6.1f} s  "
            f"({r.compiled} compiled, {r.loaded} loaded from the cache)"
        )
        for e in r.errors:
            print(f"  {e}", file=sys.stderr)

    results = warmup(tasks=args.tasks, jobs=args.jobs, progress=progress)
    compiled = sum(r.compiled for r in results)
    failed = [r.name for r in results if r.code != 0]
    con.say(f"{compiled} kernel signature(s) compiled in {time.perf_counter() - t0:.1f} s")
    if failed:
        print(f"error: warm-up task(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _cmd_preview(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.preview import save_png

    out = Path(args.output)
    options = {
        "size": (args.width, args.height),
        "style": args.style,
        "section": args.section,
        "part": args.part,
        "color_by": args.color_by,
    }
    if args.views:
        options["views"] = [v.strip() for v in args.views.split(",") if v.strip()]
    with con.step("render"):
        save_png(args.file, out, **options)
    con.say(f"wrote {out}")
    return 0


# -------------------------------------------------------------------- parser
def _units(text: str) -> str | float:
    """``--units``: a unit name of ``conformal.UNITS`` or millimetres per file unit."""
    from conformal.part import UNITS

    if text.lower() in UNITS:
        return text.lower()
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(
            f"unknown unit {text!r}: use {', '.join(UNITS)} or millimetres per unit (> 0)"
        )
    return value


def _add_part_file_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--units",
        type=_units,
        default=None,
        metavar="UNIT",
        help="unit of a mesh part file: mm (default), cm, m, in, ft, um, or millimetres per "
        "unit (STL, OBJ and PLY store none; STEP files declare theirs)",
    )
    p.add_argument(
        "--close-holes",
        action="store_true",
        help="close the holes of an open mesh part with least-area patches (a warning says "
        "how many and where) instead of refusing it",
    )
    p.add_argument(
        "--move-to-origin",
        action="store_true",
        help="move the part so that its bounding box is centred on the origin before filling "
        "it (for parts in plant coordinates, far from the origin, whose struts single "
        "precision cannot resolve); the files written are in the moved coordinates",
    )


def _add_lattice_options(p: argparse.ArgumentParser, *, skin: bool = True) -> None:
    g = p.add_argument_group("lattice")
    g.add_argument(
        "--cell",
        default=config.DEFAULT_CELL,
        help="unit cell (see `lattice-cad cells`; default bcc)",
    )
    g.add_argument(
        "--cell-size",
        type=_positive_float,
        default=config.DEFAULT_CELL_SIZE,
        metavar="MM",
        help="cell edge length, or tet element size (default 5)",
    )
    g.add_argument(
        "--radius",
        type=_positive_float,
        default=config.DEFAULT_RADIUS,
        metavar="MM",
        help="strut radius (default 0.4)",
    )
    g.add_argument(
        "--method",
        choices=("voxel", "tet"),
        default="voxel",
        help="periodic cells on a grid, or struts along a tet mesh (default voxel)",
    )
    g.add_argument(
        "--fill",
        choices=("auto", "inside", "clip", "conform"),
        default=None,
        help="how cells meet the boundary (default: clip with --skin or --keep, else auto: "
        "inside, or "
        "conform when no whole cell fits, as in thin parts); "
        "voxel only: an error with --method tet, whose lattice always conforms",
    )
    if skin:
        g.add_argument(
            "--skin",
            type=_positive_float,
            default=None,
            metavar="MM",
            help="hollow the part to this wall thickness and unite it with the lattice",
        )
        g.add_argument(
            "--escape-holes",
            type=_positive_float,
            default=None,
            metavar="MM",
            help="with --skin: drill a hole of this diameter into every enclosed cavity (at "
            "its lowest point) and verify by a flood fill that all cavities reach the outside",
        )
        g.add_argument(
            "--escape-at",
            type=_point,
            action="append",
            default=None,
            metavar="X,Y,Z",
            help="with --skin: drill an escape hole at this point of the outer surface, along "
            f"the wall normal (repeatable; diameter --escape-holes, default "
            f"{config.ESCAPE_DIAMETER:g})",
        )
    g.add_argument(
        "--segments",
        type=_segments,
        default=config.DEFAULT_SEGMENTS,
        metavar="P",
        help="sides of each strut's polygon profile (default 6)",
    )
    _add_profile_option(g)
    g.add_argument(
        "--min-radius",
        type=float,
        default=None,
        metavar="MM",
        help="thinnest a strut may be made so that it stitches (default radius / 10)",
    )


def _add_print_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("printability")
    g.add_argument(
        "--build-direction",
        type=_direction,
        default=None,
        metavar="X,Y,Z",
        help="direction the layers grow in (any non-zero vector; default 0,0,1): overhangs "
        "are measured against it, escape holes go at the lowest points",
    )
    g.add_argument(
        "--critical-angle",
        type=_angle,
        default=None,
        metavar="DEG",
        help=f"struts below this angle to the build plate are overhangs "
        f"(default {config.OVERHANG_ANGLE_DEG:g})",
    )
    g.add_argument(
        "--min-diameter",
        type=_nonnegative_float,
        default=None,
        metavar="MM",
        help=f"struts thinner than this are reported (default {config.MIN_STRUT_DIAMETER:g})",
    )
    g.add_argument(
        "--remove-overhangs",
        action="store_true",
        help="remove the overhanging struts and the loose pieces that leaves",
    )
    g.add_argument(
        "--self-supporting",
        action="store_true",
        help="voxel: rotate the cell grid so that the cell's struts are as steep as "
        "possible (refused when the cell cannot reach the critical angle)",
    )


def _add_fe_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("beam FE model (-o NAME.inp, CalculiX/Abaqus)")
    g.add_argument(
        "--node-set",
        action="append",
        default=[],
        metavar="NAME=SELECTOR",
        help="a named node set for supports and loads (repeatable): a CadQuery face selector "
        "on a STEP part ('<Z', '>Z', '%%CYLINDER'), 'plane:x,y,z,nx,ny,nz' or "
        "'box:x0,y0,z0,x1,y1,z1'; nodes within one strut radius of the faces",
    )
    g.add_argument(
        "--material",
        metavar="E=MPA,nu=NU,density=T/MM3",
        help=f"material (keys E, nu, density, name; default {config.FE_MATERIAL}: "
        f"E={config.FE_YOUNGS_MODULUS:g} MPa, nu={config.FE_POISSON:g}, "
        f"density={config.FE_DENSITY:g} t/mm^3)",
    )
    g.add_argument(
        "--fe-dialect",
        choices=("calculix", "abaqus"),
        default="calculix",
        help="circular sections as CalculiX (diameter) or Abaqus (radius) read them",
    )
    g.add_argument(
        "--elements-per-strut",
        type=_positive_int,
        default=config.FE_ELEMENTS_PER_STRUT,
        metavar="K",
        help=f"quadratic beam elements per strut (default {config.FE_ELEMENTS_PER_STRUT})",
    )


def _add_profile_option(g: Any) -> None:
    g.add_argument(
        "--profile",
        choices=("volume", "area", "inscribed", "circumscribed"),
        default="volume",
        help="stitched strut profile: volume (default: the design's exact volume; hubs of "
        "irregular nodes are scaled down, so struts meet them in a neck, down to ~0.75 r "
        "on tet lattices), area (no neck, heavier: +1-11 %%), inscribed (never wider than "
        "the design), circumscribed (never thinner)",
    )


def _add_beam_lattice_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--beam-lattice",
        nargs="?",
        const="with-mesh",
        choices=("with-mesh", "only"),
        default=None,
        metavar="only",
        help="with a .3mf output: write the 3MF Beam Lattice extension; the beam-lattice "
        "object also holds the printable mesh, so slicers without the extension (PrusaSlicer, "
        "Cura) open it; --beam-lattice=only: beams only, a tiny file few programs open",
    )


def _beam_lattice_mode(args: argparse.Namespace) -> Any:
    """``Lattice.save``'s ``beam_lattice`` for the CLI option: False, True or "only"."""
    mode = getattr(args, "beam_lattice", None)
    return False if mode is None else ("only" if mode == "only" else True)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``lattice-cad`` (one sub-parser per command)."""
    # SUPPRESS: a sub-command's parser must not reset -q/--debug given before the command
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
        help="print nothing but errors",
    )  # fmt: skip
    common.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks of errors"
    )

    parser = argparse.ArgumentParser(
        prog="lattice-cad",
        description="Fill parts with lattices and write watertight, printable files.",
        parents=[common],
    )
    from lattice_cad import __version__

    parser.add_argument("--version", action="version", version=f"lattice-cad {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "fill",
        parents=[common],
        help="fill a part (STEP or mesh) with a lattice and save it",
        description="Fill a part (STEP or closed mesh) with a lattice and write a printable file.",
    )
    p.add_argument("part", help="part file: .step/.stp, or a closed mesh .stl/.obj/.ply/.3mf/.off")
    p.add_argument("-o", "--output", required=True, help=_OUTPUT_HELP)
    _add_part_file_options(p)
    _add_lattice_options(p)
    p.add_argument(
        "--keep",
        action="append",
        type=_keep_zone,
        default=None,
        metavar="SELECTOR:MM",
        help="keep the part solid within MM of the faces a CadQuery selector picks (e.g. "
        "'>Z:2', '%%CYLINDER:1.5'; a box as 'x0,y0,z0,x1,y1,z1:MARGIN'); repeatable",
    )
    _add_beam_lattice_option(p)
    p.add_argument("--report", metavar="DIR", help="also write a validation report and pictures")
    _add_print_options(p)
    _add_fe_options(p)
    p.add_argument(
        "--max-brep-struts",
        type=_positive_int,
        default=None,
        metavar="N",
        help=f"with a .step output: build the exact B-rep for up to N struts (default "
        f"{config.MAX_BREP_STRUTS:,}; larger lattices are refused with an estimate of the "
        "time and size)",
    )
    g = p.add_argument_group("sharded (Dask distributed; pip install 'lattice-cad[distributed]')")
    g.add_argument(
        "--shards",
        type=_positive_int,
        default=None,
        metavar="N",
        help="fill in N blocks of cells on a Dask cluster and stream one STL (fill inside; "
        "the stitched lattice, not trimmed)",
    )
    g.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="with --shards: an existing Dask scheduler (tcp://host:8786); default a local "
        "cluster of --workers processes",
    )
    g.add_argument(
        "--workers", type=_positive_int, default=None, metavar="N",
        help="with --shards and no --scheduler: local worker processes (default 2)",
    )  # fmt: skip
    p.set_defaults(func=_cmd_fill)

    p = sub.add_parser(
        "stitch",
        parents=[common],
        help="stitch a graph (.json/.npz) into a watertight mesh",
        description="Stitch a lattice graph into a watertight mesh (fast_stitch).",
    )
    p.add_argument("graph", help="graph file (.json or .npz)")
    p.add_argument("-o", "--output", required=True, help=_OUTPUT_HELP)
    p.add_argument(
        "--segments",
        type=_segments,
        default=config.DEFAULT_SEGMENTS,
        metavar="P",
        help="sides of each strut's polygon profile (default 6)",
    )
    _add_profile_option(p)
    _add_beam_lattice_option(p)
    p.set_defaults(func=_cmd_stitch)

    p = sub.add_parser(
        "reference",
        parents=[common],
        help="build the exact B-rep reference of a graph",
        description="Build the exact per-hub B-rep reference of a graph (.step or .stl).",
    )
    p.add_argument("graph", help="graph file (.json or .npz)")
    p.add_argument("-o", "--output", required=True, help="output .step/.stp (solids) or .stl")
    p.set_defaults(func=_cmd_reference)

    p = sub.add_parser(
        "validate",
        parents=[common],
        help="accuracy report: fast mesh vs exact reference",
        description="Stitch, build the exact reference, compare, print the verdict (PASS / FAIL "
        "against --tolerance) and write report.html and report.md with pictures.",
    )
    p.add_argument("input", metavar="GRAPH_OR_PART", help="graph (.json/.npz) or part file")
    p.add_argument("--report", required=True, metavar="DIR", help="directory for the report")
    _add_part_file_options(p)
    p.add_argument(
        "--full-union-study",
        action="store_true",
        help="manifold3d convergence study over the whole lattice (default: a sample of "
        "200 hubs, which shows the same trend in seconds)",
    )
    p.add_argument(
        "--tolerance",
        type=_positive_float,
        default=None,
        metavar="MM",
        help="surface tolerance of the verdict: PASS needs 95 %% of the two-sided surface "
        "deviation from the exact solid within +-MM (default: 10 %% of the median strut "
        "radius); with this option a FAIL exits with code 1",
    )
    p.add_argument(
        "--tolerance-volume",
        type=_percent,
        default=None,
        metavar="PCT",
        help="volume tolerance of the verdict in percent: PASS needs |V_mesh - V_exact| / "
        "V_exact <= PCT %% (default 1); with this option a FAIL exits with code 1",
    )
    _add_lattice_options(p, skin=False)
    _add_print_options(p)
    p.set_defaults(func=_cmd_validate)

    p = sub.add_parser(
        "cells",
        parents=[common],
        help="list the unit cells",
        description="List the built-in unit cells with a one-line description each.",
    )
    p.set_defaults(func=_cmd_cells)

    p = sub.add_parser(
        "check",
        parents=[common],
        help="check that a mesh file is a valid solid (exit 0/1)",
        description="Check a mesh file: watertight, manifold, oriented, outward, no "
        "zero-area or self-intersecting triangles. Exit code 0 if valid, 1 if not.",
    )
    p.add_argument("mesh", help="mesh file (.stl, .3mf, .ply, .obj, .off)")
    p.add_argument(
        "--no-self-intersections",
        action="store_true",
        help="skip the (slower) self-intersection test",
    )
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser(
        "preview",
        parents=[common],
        help="render a lattice, mesh or part to PNG",
        description="Render a graph (.json/.npz), mesh or part (.step) to a PNG picture "
        "(offscreen).",
    )
    p.add_argument("file", help="graph, mesh or part file")
    p.add_argument("-o", "--output", required=True, help="output .png")
    p.add_argument("--width", type=int, default=1200, help="pixels (default 1200)")
    p.add_argument("--height", type=int, default=900, help="pixels (default 900)")
    p.add_argument(
        "--section",
        metavar="x|y|z[=MM]",
        help="add a cut-away view at that plane (default: through the middle)",
    )
    p.add_argument("--part", metavar="PART", help="draw this part (.step or mesh) as a ghost")
    p.add_argument(
        "--color-by",
        choices=["auto", "radius", "overhang", "none"],
        default="auto",
        help="colour struts by radius (auto: when graded) or by angle to the build plate",
    )
    p.add_argument(
        "--views", metavar="V1,V2", help="several views side by side: iso, top, front, right"
    )
    p.add_argument(
        "--style",
        choices=["shaded", "wireframe"],
        default="shaded",
        help="shaded render (default) or the matplotlib wireframe",
    )
    p.set_defaults(func=_cmd_preview)

    from lattice_cad.warmup import TASKS

    p = sub.add_parser(
        "warmup",
        parents=[common],
        help="compile the numerical kernels once, after installing (a few minutes)",
        description="Compile (and cache) lattice-cad's numba kernels by running every "
        "mode on a small part, in several processes at once. Run it once after installing: "
        "otherwise the first real run compiles them (about 3 minutes for a skin on a "
        "2-core machine).",
    )
    p.add_argument("--jobs", type=int, default=2, metavar="N", help="worker processes (default 2)")
    p.add_argument(
        "--tasks", nargs="+", choices=list(TASKS), metavar="TASK",
        help=f"only these ({', '.join(TASKS)})",
    )  # fmt: skip
    p.set_defaults(func=_cmd_warmup)
    return parser


def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, FileNotFoundError) and exc.filename and str(exc.filename) not in msg:
        msg = f"{msg}: {exc.filename}"
    return f"error: {_cli_words(msg)}"


@functools.lru_cache(maxsize=1)
def _options() -> frozenset[str]:
    """Every ``--option`` of every command (``--fill``, ``--close-holes``, ...)."""
    found: set[str] = set()
    parser = build_parser()
    todo = [parser]
    while todo:
        p = todo.pop()
        for action in p._actions:
            found.update(o for o in action.option_strings if o.startswith("--"))
            if isinstance(action, argparse._SubParsersAction):
                todo.extend(action.choices.values())
    return frozenset(found)


_KEYWORD = re.compile(r"\b([a-z][a-z0-9_]*)=(?:'([^']*)'|\"([^\"]*)\"|(True)\b)")


def _cli_words(msg: str) -> str:
    """``msg`` with the library's keyword syntax put as the command line's options.

    The library's messages name its keywords (``fill='conform'``, ``close_holes=True``,
    ``units='m'``); where a keyword is an option of the command line, the command line
    says the option instead (``--fill conform``, ``--close-holes``, ``--units m``), once
    (a message that already adds it in brackets or after "or" keeps one)."""
    options = _options()

    def option(m: re.Match[str]) -> str:
        name = "--" + m.group(1).replace("_", "-")
        if name not in options:
            return m.group(0)
        value = m.group(2) if m.group(2) is not None else m.group(3)
        return name if value is None else f"{name} {value}"

    def bare(m: re.Match[str]) -> str:  # self_supporting, close_holes: as names
        name = "--" + m.group(1).replace("_", "-")
        return name if name in options else m.group(0)

    out = _KEYWORD.sub(option, msg)
    out = re.sub(r"(?<![\w/.=-])([a-z]+(?:_[a-z]+)+)(?![\w/.=-])", bare, out)
    # "--close-holes (--close-holes)", "--units m, or --units m": said twice now
    return re.sub(r"(--[a-z][a-z0-9-]*(?: [\w.]+)?)(?: \(\1\)|, or \1)", r"\1", out)


#: numpy's environment variable for its huge-page advice (read when numpy is imported).
_HUGEPAGE_ENV = "NUMPY_MADVISE_HUGEPAGE"


def _no_hugepage_advice() -> bool:
    """Stop numpy advising the kernel to back its large arrays with transparent huge pages
    (``madvise(MADV_HUGEPAGE)`` on every array of 4 MiB or more), in this process and in
    the processes it starts (the OCCT offset worker, Dask workers), unless the user set
    ``NUMPY_MADVISE_HUGEPAGE``; returns whether it did.

    The first touch of a huge page costs the zeroing of 2 MiB at once, and far more where
    the kernel must first compact memory for it (numpy issue 31590) or, in a virtual
    machine, the host must back it: on the 2-core KVM guest of the benchmarks, copying a
    fresh 67 MB array took 0.46 s with the advice and 0.03 s without, and the GE bracket's
    skin spent 3-4 s of system time in such faults (0.8-1.1 s without; see CHANGES).
    A fill allocates many fresh arrays of that size (a lattice of millions of triangles)
    and uses each briefly, which is what huge pages do not pay off for. The library does
    not change numpy's global state when imported; ``NUMPY_MADVISE_HUGEPAGE=1`` keeps the
    advice for the command line too.
    """
    import os

    if _HUGEPAGE_ENV in os.environ:
        return False
    os.environ[_HUGEPAGE_ENV] = "0"  # the child processes import numpy with it
    import numpy as np

    core = getattr(np, "_core", None) or getattr(np, "core", None)
    setter = getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)
    if setter is None:  # pragma: no cover - a numpy without the switch
        return False
    setter(False)
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``lattice-cad``; returns the exit code (also the console-script entry point)."""
    _no_hugepage_advice()
    parser = build_parser()
    args = parser.parse_args(argv)
    args.quiet = getattr(args, "quiet", False)  # given before or after the command
    args.debug = getattr(args, "debug", False)
    con = _Console(args.quiet)
    _SHOWN.clear()
    try:
        with warnings.catch_warnings():
            if args.quiet:
                warnings.simplefilter("ignore")
            else:
                warnings.simplefilter("default")
                warnings.showwarning = _show_warning  # type: ignore[assignment]
            return int(args.func(args, con))
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if args.debug:
            traceback.print_exc()
        print(_one_line(exc), file=sys.stderr)
        return 1


#: The warnings the command line has printed (each text once: the library's retries
#: repeat theirs, and its own ``catch_warnings`` blocks reset Python's "default" registry;
#: a golf head's skin printed the same wall warning four times, s37).
_SHOWN: set[str] = set()


def _show_warning(message: Any, category: Any, filename: str, lineno: int, *a: Any) -> None:
    text = _cli_words(str(message))
    if text in _SHOWN:
        return
    _SHOWN.add(text)
    print(f"warning: {text}", file=sys.stderr)


def _entry() -> None:  # pragma: no cover - console script
    sys.exit(main())


def _cmd_fill_sharded(args: argparse.Namespace, con: _Console) -> int:
    """``fill --shards N``: lattice_cad.distributed.fill_sharded, refusing what it cannot do."""
    from lattice_cad.core.errors import ShardingError
    from lattice_cad.distributed import fill_sharded

    refused = [
        flag
        for flag, on in (
            ("--method tet", args.method != "voxel"),
            ("--skin", args.skin is not None),
            ("--keep", args.keep is not None),
            ("--escape-holes/--escape-at", args.escape_holes is not None or args.escape_at),
            ("--beam-lattice=only", args.beam_lattice == "only"),
            ("--report", args.report is not None),
            ("--remove-overhangs", args.remove_overhangs),
            ("--self-supporting", args.self_supporting),
            ("--node-set/--material", bool(args.node_set or args.material)),
            ("--close-holes", args.close_holes),
            ("--move-to-origin", args.move_to_origin),
        )
        if on
    ]
    if refused:
        raise ShardingError(
            f"{', '.join(refused)} cannot be combined with --shards (the sharded path writes "
            "the stitched lattice of fill inside, clip or conform as .stl or .3mf, with "
            "--beam-lattice one object per shard, of a closed part)"
        )
    with con.step(f"sharded fill ({args.shards} shards)"):
        res = fill_sharded(
            args.part,
            args.output,
            args.cell,
            args.cell_size,
            args.radius,
            shards=args.shards,
            scheduler=args.scheduler,
            workers=args.workers,
            fill=args.fill or "inside",
            segments=args.segments,
            profile=args.profile,
            progress=not con.quiet,
            beam_lattice=bool(args.beam_lattice),
            units=args.units,
        )
    con.say(res.summary())
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
