"""The ``lattice-cad`` command line.

::

    lattice-cad fill PART -o OUT [--cell --cell-size --radius --method --fill --skin
                                  --segments --beam-lattice --report DIR]
    lattice-cad stitch GRAPH -o OUT [--segments]
    lattice-cad reference GRAPH -o OUT
    lattice-cad validate GRAPH_OR_PART --report DIR
    lattice-cad cells
    lattice-cad check MESH
    lattice-cad preview FILE -o PNG

Exit codes: 0 success, 1 error (one readable line on stderr; ``--debug`` shows
the traceback) or an invalid mesh for ``check``, 2 wrong usage, 130 interrupted.
"""

from __future__ import annotations

import argparse
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
    ".json .npz (graph), .step (exact B-rep)"
)


class _Console:
    """Messages and progress bars that respect ``--quiet``."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet

    def say(self, msg: str) -> None:
        if not self.quiet:
            print(msg, flush=True)

    @contextmanager
    def step(self, desc: str) -> Iterator[Callable[[str, int, int], None]]:
        """A tqdm bar for one step; yields a ``progress(stage, done, total)`` callback."""
        t0 = time.perf_counter()
        bar = None
        if not self.quiet:
            from tqdm.auto import tqdm

            bar = tqdm(total=1, desc=desc, leave=False, file=sys.stderr, delay=1.0)

        def progress(stage: str, done: int, total: int) -> None:
            if bar is not None:
                bar.set_description(f"{desc}: {stage}")
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


def _segments(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 3:
        raise argparse.ArgumentTypeError(f"segments must be >= 3, got {value}")
    return value


# ------------------------------------------------------------------ commands
def _load_graph(path: str) -> Any:
    from lattice_cad.core.graph import LatticeGraph

    return LatticeGraph.load(path)


def _check_output(out: Path) -> None:
    """Refuse a missing directory or a directory in the way before any work."""
    from lattice_cad.core.atomic import check_target

    check_target(out)


def _write_report(con: _Console, lat: Any, directory: str) -> None:
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    from lattice_cad.preview import save_png

    with con.step("preview"):
        save_png(lat.graph, d / "lattice.png")
    with con.step("validate"):
        lat.validate(report=d / "report.html")
    con.say(f"report: {d / 'report.html'}")


def _cmd_fill(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.lattice import Lattice

    out = Path(args.output)
    _check_output(out)
    with con.step("load + lattice"):
        lat = Lattice.fill(
            args.part,
            args.cell,
            args.cell_size,
            args.radius,
            method=args.method,
            fill=args.fill,
            skin=args.skin,
            segments=args.segments,
        )
    lat.progress = not con.quiet
    info = lat.info()
    con.say(
        f"{info['struts']:,} struts, {info['nodes']:,} nodes"
        + (
            f", relative density {info['relative_density']:.3f}"
            if "relative_density" in info
            else ""
        )
    )
    rep = lat.build_report
    if rep is not None:
        notes = [f"fill {rep.fill}"] if rep.fill else []
        if rep.removed_islands:
            notes.append(f"{rep.removed_islands} strut(s) in loose pieces removed")
        if rep.merged_nodes or rep.removed_short:
            notes.append(f"{rep.merged_nodes} merged, {rep.removed_short} removed")
        if rep.radii_reduced:
            notes.append(f"{rep.radii_reduced} strut(s) thinned (min radius {rep.min_radius:.4g})")
        if rep.thinned_beyond_tolerance:
            notes.append(f"{rep.thinned_beyond_tolerance} below 0.7 x the radius asked")
        if notes:
            con.say("; ".join(notes))
    if out.suffix.lower() in suffixes(Kind.MESH) and not args.beam_lattice:
        with con.step("mesh" + (" + skin" if args.skin else "")):
            mesh = lat.mesh()
        con.say(f"{len(mesh.faces):,} triangles, volume {mesh.volume:.6g} mm^3")
        if lat.skin_report is not None:
            con.say(lat.skin_report.summary())
    with con.step(f"write {out.suffix.lstrip('.')}"):
        lat.save(out, beam_lattice=args.beam_lattice)
    con.say(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)")
    if args.report:
        _write_report(con, lat, args.report)
    return 0


def _cmd_stitch(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.lattice import Lattice

    graph = _load_graph(args.graph)
    lat = Lattice(graph, segments=args.segments)
    lat.progress = not con.quiet
    out = Path(args.output)
    _check_output(out)
    with con.step("stitch"):
        mesh = lat.mesh()
    with con.step(f"write {out.suffix.lstrip('.')}"):
        lat.save(out, beam_lattice=args.beam_lattice)
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
    if src.suffix.lower() in suffixes(Kind.GRAPH, action="read"):
        lat = Lattice(_load_graph(args.input), segments=args.segments)
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
            )
    _write_report(con, lat, args.report)
    return 0


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


def _cmd_preview(args: argparse.Namespace, con: _Console) -> int:
    from lattice_cad.preview import save_png

    out = Path(args.output)
    with con.step("render"):
        save_png(args.file, out, size=(args.width, args.height))
    con.say(f"wrote {out}")
    return 0


# -------------------------------------------------------------------- parser
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
        help="how cells meet the boundary (default: clip with --skin, else auto: inside, or "
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
        "--segments",
        type=_segments,
        default=config.DEFAULT_SEGMENTS,
        metavar="P",
        help="sides of each strut's polygon profile (default 6)",
    )


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
    _add_lattice_options(p)
    p.add_argument(
        "--beam-lattice",
        action="store_true",
        help="with a .3mf output: write the 3MF Beam Lattice extension (tiny file)",
    )
    p.add_argument("--report", metavar="DIR", help="also write a validation report and pictures")
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
    p.add_argument(
        "--beam-lattice",
        action="store_true",
        help="with a .3mf output: write the 3MF Beam Lattice extension",
    )
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
        description="Stitch, build the exact reference, compare, and write an HTML report.",
    )
    p.add_argument("input", metavar="GRAPH_OR_PART", help="graph (.json/.npz) or part file")
    p.add_argument("--report", required=True, metavar="DIR", help="directory for the report")
    _add_lattice_options(p, skin=False)
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
    p.add_argument("--width", type=int, default=900, help="pixels (default 900)")
    p.add_argument("--height", type=int, default=700, help="pixels (default 700)")
    p.set_defaults(func=_cmd_preview)
    return parser


def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, FileNotFoundError) and exc.filename and str(exc.filename) not in msg:
        msg = f"{msg}: {exc.filename}"
    return f"error: {msg}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``lattice-cad``; returns the exit code (also the console-script entry point)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.quiet = getattr(args, "quiet", False)  # given before or after the command
    args.debug = getattr(args, "debug", False)
    con = _Console(args.quiet)
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


def _show_warning(message: Any, category: Any, filename: str, lineno: int, *a: Any) -> None:
    print(f"warning: {message}", file=sys.stderr)


def _entry() -> None:  # pragma: no cover - console script
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
