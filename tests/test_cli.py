"""The lattice-cad command line: every subcommand, every flag, exit codes, errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conformal import CELLS, block
from lattice_cad.cli import build_parser, main
from tests.conftest import DATA

COMMANDS = ["fill", "stitch", "reference", "validate", "cells", "check", "preview"]


@pytest.fixture(scope="module")
def box_step(tmp_path_factory):
    import cadquery as cq

    p = tmp_path_factory.mktemp("parts") / "box.step"
    cq.exporters.export(cq.Workplane("XY").box(20, 16, 12), str(p))
    return p


@pytest.fixture(scope="module")
def graph_json(tmp_path_factory):
    p = tmp_path_factory.mktemp("graphs") / "g.json"
    block("bcc", 2, cell_size=5.0, radius=0.4).save(p)
    return p


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------------- help
def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for cmd in COMMANDS:
        assert cmd in out


@pytest.mark.parametrize("cmd", COMMANDS)
def test_help_of_each_command(capsys, cmd):
    with pytest.raises(SystemExit) as e:
        main([cmd, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert f"lattice-cad {cmd}" in out
    assert "--quiet" in out and "--debug" in out


def test_every_flag_is_documented():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    flags = {
        "fill": [
            "--output",
            "--cell",
            "--cell-size",
            "--radius",
            "--method",
            "--fill",
            "--skin",
            "--keep",
            "--segments",
            "--beam-lattice",
            "--report",
            "--units",
        ],
        "stitch": ["--output", "--segments", "--beam-lattice"],
        "reference": ["--output"],
        "validate": [
            "--report",
            "--cell",
            "--cell-size",
            "--radius",
            "--method",
            "--fill",
            "--segments",
            "--units",
        ],
        "check": ["--no-self-intersections"],
        "preview": ["--output", "--width", "--height"],
        "cells": [],
    }
    for cmd, expected in flags.items():
        p = sub.choices[cmd]
        have = {o for a in p._actions for o in a.option_strings}
        assert set(expected) <= have, (cmd, set(expected) - have)
        for a in p._actions:
            assert a.help, (cmd, a.option_strings)


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.startswith("lattice-cad ")


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["frobnicate"],
        ["fill"],
        ["fill", "x.step"],  # -o is required
        ["fill", "x.step", "-o", "y.stl", "--radius", "-1"],
        ["fill", "x.step", "-o", "y.stl", "--cell-size", "abc"],
        ["fill", "x.step", "-o", "y.stl", "--segments", "2"],
        ["fill", "x.step", "-o", "y.stl", "--method", "octree"],
        ["fill", "x.step", "-o", "y.stl", "--fill", "outside"],
        ["fill", "x.step", "-o", "y.stl", "--skin", "0"],
        ["fill", "x.stl", "-o", "y.stl", "--units", "furlong"],
        ["fill", "x.stl", "-o", "y.stl", "--units", "-2"],
        ["validate", "g.json"],  # --report is required
    ],
)
def test_usage_errors_exit_2(capsys, argv):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "usage: lattice-cad" in capsys.readouterr().err


# ------------------------------------------------------------------ commands
def test_cells(capsys):
    code, out, _ = run(capsys, "cells")
    assert code == 0
    lines = out.strip().splitlines()
    assert len(lines) == len(CELLS)
    for name, cell in CELLS.items():
        assert any(ln.split()[0] == name and ln.endswith(cell.description) for ln in lines)


def test_fill_all_flags(capsys, box_step, tmp_path):
    out = tmp_path / "box.stl"
    code, stdout, err = run(
        capsys,
        "fill",
        box_step,
        "-o",
        out,
        "--cell",
        "bccz",
        "--cell-size",
        "4",
        "--radius",
        "0.35",
        "--method",
        "voxel",
        "--fill",
        "inside",
        "--segments",
        "8",
    )
    assert code == 0, err
    assert out.exists() and f"wrote {out}" in stdout and "struts" in stdout
    code, _, _ = run(capsys, "check", out, "--no-self-intersections")
    assert code == 0
    code, stdout, err = run(
        capsys, "fill", box_step, "-o", tmp_path / "q.3mf", "--quiet", "--cell-size", "4"
    )
    assert code == 0 and stdout == "" and err == ""


def test_fill_beam_lattice_and_skin(capsys, box_step, tmp_path):
    from lattice_cad.io import read_beam_lattice

    out = tmp_path / "box.3mf"
    code, _, err = run(
        capsys, "fill", box_step, "-o", out, "--beam-lattice=only", "--cell-size", "4"
    )
    assert code == 0, err
    assert "warning:" in err and "beams only" in err and "PrusaSlicer" in err
    info = read_beam_lattice(out)
    assert info["beams"] > 0 and info["clipped"] and info["triangles"] == 0
    code, _, err = run(capsys, "fill", box_step, "-o", out, "--beam-lattice", "--cell-size", "4")
    assert code == 0 and "warning" not in err, err
    info = read_beam_lattice(out)
    assert info["beams"] > 0 and info["triangles"] > 0 and info["objects"] == 1
    skinned = tmp_path / "skin.stl"
    code, stdout, err = run(
        capsys, "fill", box_step, "-o", skinned, "--skin", "1", "--cell-size", "4", "-q"
    )
    assert code == 0, err
    code, out_text, _ = run(capsys, "check", skinned, "--no-self-intersections")
    assert code == 0 and "valid" in out_text


def test_fill_tet_method(capsys, box_step, tmp_path):
    code, _, err = run(
        capsys,
        "fill",
        box_step,
        "-o",
        tmp_path / "t.stl",
        "--method",
        "tet",
        "--cell-size",
        "6",
        "-q",
    )
    # without conformal.tet_lattice this is a one-line error, not a traceback
    assert code == 0 or (code == 1 and err.count("\n") == 1 and err.startswith("error: ")), err


BRACKET = Path(__file__).parents[1] / "examples" / "bracket.step"


def test_fill_tet_bracket_end_to_end(capsys, tmp_path):
    out = tmp_path / "bracket_tet.stl"
    code, _, err = run(capsys, "fill", BRACKET, "-o", out, "--method", "tet", "-q")
    assert code == 0, err
    code, stdout, err = run(capsys, "check", out)
    assert code == 0 and stdout.rstrip().endswith(": valid"), stdout + err


def test_fill_tet_rejects_fill_mode(capsys, tmp_path):
    code, _, err = run(
        capsys, "fill", BRACKET, "-o", tmp_path / "x.stl", "--method", "tet", "--fill", "clip"
    )
    assert code == 1 and err.count("\n") == 1
    assert "fill only applies to --method voxel" in err  # the CLI's words
    assert not (tmp_path / "x.stl").exists()


def test_errors_are_one_line(capsys, tmp_path):
    code, out, err = run(capsys, "fill", tmp_path / "missing.step", "-o", tmp_path / "x.stl")
    assert code == 1
    assert err.startswith("error: ") and "missing.step" in err and err.count("\n") == 1
    assert "Traceback" not in err
    assert not (tmp_path / "x.stl").exists()
    code, _, err = run(capsys, "fill", tmp_path / "missing.step", "-o", "x.stl", "--debug")
    assert code == 1 and "Traceback" in err and err.rstrip().splitlines()[-1].startswith("error:")
    code, _, err = run(capsys, "stitch", tmp_path / "g.txt", "-o", tmp_path / "x.stl")
    assert code == 1 and "cannot load a graph as .txt (g.txt): use .json, .npz" in err


def test_fill_units_of_a_mesh_in_metres(capsys, tmp_path):
    """STL stores no unit: a real part exported in metres reads as 1000 times too small
    (a warning says so and what to pass), and ``--units m`` fills it at its size."""
    import trimesh

    tm = trimesh.load(DATA / "meshes" / "wingnut.obj", force="mesh")
    tm.apply_scale(1e-3)
    src = tmp_path / "wingnut_in_metres.stl"
    tm.export(src)
    out = tmp_path / "out.stl"
    code, _, err = run(capsys, "fill", src, "-o", out, "--cell-size", "1.5", "--radius", "0.12")
    assert code == 1 and not out.exists()
    assert "mm across, read as millimetres" in err and "--units m" in err
    code, out_text, err = run(
        capsys, "fill", src, "-o", out, "--cell-size", "1.5", "--radius", "0.12", "--units", "m"
    )
    assert code == 0, err
    assert "read as millimetres" not in err
    written = trimesh.load(out, force="mesh")
    np.testing.assert_allclose(
        written.extents, 1000 * tm.extents, rtol=0.1
    )  # the lattice spans the part (trimmed to it)
    assert written.is_watertight and written.volume > 0
    # a STEP file declares its unit
    code, _, err = run(
        capsys, "fill", DATA / "step" / "kcl_bracket.step", "-o", out, "--units", "in"
    )
    assert code == 1 and "STEP files declare their own unit" in err


def test_fill_says_the_part_size_and_an_assumed_unit(capsys, tmp_path, box_step):
    """The fill says the part's size as read; for a mesh file that stores no unit, that it
    was read as millimetres (a bracket drawn in inches, 3 x 2 x 1.5, above the tiny-part
    warning's 1 mm, was filled 25.4 times too small with no sign of it: s34's new parts)."""
    import trimesh

    src = tmp_path / "bracket_in_inches.stl"
    trimesh.creation.box(extents=(3.0, 2.0, 1.5)).export(src)
    out = tmp_path / "out.stl"
    code, text, err = run(capsys, "fill", src, "-o", out, "--cell-size", "0.5", "--radius", "0.04")
    assert code == 0, err
    assert "part 3 x 2 x 1.5 mm, volume 9 mm^3 (STL stores no unit: read as millimetres" in text
    code, text, err = run(
        capsys, "fill", src, "-o", out, "--units", "in", "--cell-size", "12", "--radius", "1"
    )
    assert code == 0, err
    assert "part 76.2 x 50.8 x 38.1 mm, volume 147484 mm^3\n" in text
    assert "stores no unit" not in text
    code, text, err = run(capsys, "fill", box_step, "-o", out, "--cell-size", "4")
    assert code == 0, err
    assert "part 20 x 16 x 12 mm, volume 3840 mm^3\n" in text


def test_stitch_check_preview(capsys, graph_json, tmp_path):
    stl = tmp_path / "g.stl"
    code, stdout, err = run(capsys, "stitch", graph_json, "-o", stl, "--segments", "8")
    assert code == 0, err
    assert "triangles" in stdout
    code, stdout, _ = run(capsys, "check", stl, "--no-self-intersections")
    assert code == 0 and "valid" in stdout
    code, _, err = run(capsys, "stitch", graph_json, "-o", tmp_path / "g.3mf", "--beam-lattice")
    assert code == 0, err
    png = tmp_path / "g.png"
    code, _, err = run(
        capsys, "preview", graph_json, "-o", png, "--width", "320", "--height", "240"
    )
    assert code == 0, err
    assert png.read_bytes()[:4] == b"\x89PNG"
    code, _, err = run(capsys, "preview", stl, "-o", tmp_path / "m.png", "-q")
    assert code == 0, err
    code, _, err = run(capsys, "preview", stl, "-o", tmp_path / "m.jpg")
    assert code == 1 and "PNG" in err


def test_check_invalid_mesh_exit_1(capsys, tmp_path):
    import trimesh

    box = trimesh.creation.box()
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    p = tmp_path / "open.stl"
    open_box.export(p)
    code, stdout, _ = run(capsys, "check", p, "--no-self-intersections")
    assert code == 1
    assert "INVALID" in stdout and "boundary edges" in stdout
    code, _, err = run(capsys, "check", tmp_path / "none.stl")
    assert code == 1 and "mesh file not found" in err


@pytest.mark.slow
def test_reference_and_validate(capsys, tmp_path):
    g = tmp_path / "small.npz"
    block("bcc", 1, cell_size=5.0, radius=0.5).save(g)
    step = tmp_path / "ref.step"
    code, stdout, err = run(capsys, "reference", g, "-o", step)
    assert code == 0, err
    assert step.exists() and "Reference(" in stdout
    code, _, err = run(capsys, "reference", g, "-o", tmp_path / "ref.txt")
    assert code == 1 and "cannot save a reference as .txt" in err and ".step, .stp" in err
    rep = tmp_path / "report"
    code, stdout, err = run(capsys, "validate", g, "--report", rep, "--segments", "8")
    assert code == 0, err
    assert (rep / "report.html").exists() and (rep / "lattice.png").exists()


@pytest.mark.slow
def test_fill_with_report(capsys, box_step, tmp_path):
    rep = tmp_path / "rep"
    code, _, err = run(
        capsys,
        "fill",
        box_step,
        "-o",
        tmp_path / "b.npz",
        "--cell-size",
        "5",
        "--radius",
        "0.5",
        "--report",
        rep,
    )
    assert code == 0, err
    assert (rep / "report.html").exists()


def test_module_entry_point(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "lattice_cad.cli", "cells"], capture_output=True, text=True
    )
    assert r.returncode == 0 and "bcc" in r.stdout
    r = subprocess.run(
        [sys.executable, "-m", "lattice_cad.cli", "check", str(tmp_path / "x.stl")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1 and r.stderr.count("\n") == 1


def test_graph_npz_input(capsys, tmp_path):
    g = tmp_path / "g.npz"
    block("cubic", 1, cell_size=5.0, radius=0.4).save(g)
    code, _, err = run(capsys, "stitch", g, "-o", tmp_path / "g.ply")
    assert code == 0, err
    from lattice_cad.io import read_mesh

    v, f = read_mesh(tmp_path / "g.ply")
    assert len(f) > 0 and np.isfinite(v).all()


@pytest.mark.slow
def test_check_with_self_intersections(capsys, graph_json, tmp_path):
    stl = tmp_path / "g.stl"
    assert run(capsys, "stitch", graph_json, "-o", stl, "-q")[0] == 0
    code, stdout, _ = run(capsys, "check", stl)
    assert code == 0 and "self-intersections checked" in stdout


def test_tet_fill_output_has_no_gmsh_debugging_or_cursor_codes(tmp_path):
    """Regression: on kcl_enclosure (the parts benchmark's tet setting) the CLI printed 856
    lines of gmsh's boundary-recovery debugging (``el1 = np = ...``) to stdout, and in a log
    the stitch's tqdm bar, nested in the step's bar, left cursor-up codes."""
    r = subprocess.run(
        [sys.executable, "-m", "lattice_cad.cli", "fill", str(DATA / "step" / "kcl_enclosure.step"),
         "--method", "tet", "--cell-size", "18.3333", "--radius", "1.5278",
         "-o", str(tmp_path / "t.stl")],
        capture_output=True, text=True, cwd=tmp_path,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    out = r.stdout + r.stderr
    assert "el1 = np" not in out and "duplicated facets" not in out, out[:2000]
    assert "\x1b[A" not in out and "hub/s" not in out
    assert "wrote" in r.stdout and len(out.splitlines()) < 40, out


def test_an_error_after_parallel_kernels_exits_at_once(tmp_path):
    """Regression (s24's parts made outside shared/data): ``--close-holes`` on a triangle
    soup runs numba's parallel kernels, then fails ("encloses no volume"). With numba on
    TBB (found wherever a system libtbb is installed, as CI's slicer packages bring one),
    the process then spun in TBB's finalize at interpreter exit: 64 s on this sphere, more
    than 300 s on a larger soup. The engines now ask numba for OpenMP first
    (``config.NUMBA_THREADING_PRIORITY``): it exits as soon as it has said the error."""
    import os
    import time

    import trimesh

    m = trimesh.creation.icosphere(subdivisions=3, radius=20.0)
    rng = np.random.default_rng(0)
    # every triangle its own vertices, 0.05 mm apart (far beyond the load's weld of open
    # edges, config.WELD_OPEN_RTOLS): 1,280 "holes", each closed to a sheet of no volume
    v = m.vertices[m.faces].reshape(-1, 3) + rng.normal(scale=0.05, size=(3 * len(m.faces), 3))
    soup = tmp_path / "soup.obj"
    trimesh.Trimesh(v, np.arange(len(v)).reshape(-1, 3), process=False).export(soup)
    env = {k: x for k, x in os.environ.items() if not k.startswith("NUMBA_THREADING")}
    out = str(tmp_path / "x.stl")
    argv = [sys.executable, "-m", "lattice_cad.cli", "fill", str(soup), "-o", out,
            "--cell-size", "3", "--radius", "0.25", "--close-holes"]  # fmt: skip
    # the time from the error to the end of the process (its first run may compile
    # kernels the warm-up does not: 40 s in a CI run, and not what is measured here)
    said, said_at = [], None
    with subprocess.Popen(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env
    ) as proc:
        assert proc.stderr is not None
        for line in proc.stderr:  # stderr is line-buffered: each line as it is printed
            said.append(line)
            if line.startswith("error:") and said_at is None:
                said_at = time.perf_counter()
        returncode = proc.wait(timeout=300)
        gone_at = time.perf_counter()
    assert returncode == 1 and said_at is not None, said
    assert "encloses no volume" in "".join(said), said
    assert gone_at - said_at < 15.0, gone_at - said_at
    assert not (tmp_path / "x.stl").exists()
    # how long TBB spun depends on the machine's load (64-148 s beside CI, a few seconds
    # when it is quiet): the layer itself, where OpenMP is there to be had
    probe = (
        "import numpy as np, numba, conformal\n"
        "@numba.njit(parallel=True)\n"
        "def f(a):\n"
        "    s = 0.0\n"
        "    for i in numba.prange(len(a)):\n"
        "        s += a[i]\n"
        "    return s\n"
        "f(np.ones(64))\n"
        "try:\n"
        "    import numba.np.ufunc.omppool\n"
        "    omp = 'omp there'\n"
        "except ImportError:\n"
        "    omp = 'no omp'\n"
        "print(numba.threading_layer(), omp)\n"
    )
    layer = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=300
    )
    assert layer.returncode == 0, layer.stderr
    used, there = layer.stdout.split(maxsplit=1)
    assert used == "omp" or there.strip() == "no omp", layer.stdout


def test_messages_name_the_command_lines_options(capsys, tmp_path):
    """The library's messages name its keywords (``close_holes=True``, ``units='m'``,
    ``fill='conform'``); the command line says its own options instead, once."""
    import trimesh

    from lattice_cad.cli import _cli_words

    out = str(tmp_path / "x.stl")
    assert main(["fill", str(DATA / "broken" / "cube_no_bottom.obj"), "-o", out]) == 1
    err = capsys.readouterr().err
    assert "--close-holes closes them" in err and "close_holes" not in err, err
    # a mesh 0.05 mm across (a part in metres read as mm)
    tiny = tmp_path / "tiny.stl"
    trimesh.creation.box((0.05, 0.04, 0.02)).export(tiny)
    main(["fill", str(tiny), "-o", out, "--cell-size", "0.01", "--radius", "0.001"])
    err = capsys.readouterr().err
    assert "pass it (--units m)" in err and "units=" not in err, err
    # each form the library uses, and what is not an option stays as it is
    assert _cli_words("fill='conform' joins them (fill='clip' too)") == (
        "--fill conform joins them (--fill clip too)"
    )
    assert _cli_words('self_supporting applies to method="voxel"') == (
        "--self-supporting applies to --method voxel"
    )
    kept = "/tmp/close_holes/a_b.stl: Lattice(..., skin=MM), inside_share, x='y'"
    assert _cli_words(kept) == kept


def test_a_warning_repeated_by_a_retry_is_printed_once(capsys, monkeypatch):
    """Regression (s37's new parts): a golf head's skin printed the same wall warning four
    times, once per retry (the library's own ``catch_warnings`` blocks reset Python's
    registry of warnings shown)."""
    import warnings

    import lattice_cad.cli as cli
    from lattice_cad.core.errors import LatticeWarning

    def noisy(args, con):
        for _ in range(3):
            with warnings.catch_warnings():  # as the library's retries do
                warnings.simplefilter("ignore", DeprecationWarning)
            warnings.warn("the skin's wall is 1.39 .. 1.71 mm thick", LatticeWarning, stacklevel=1)
        warnings.warn("another one", LatticeWarning, stacklevel=1)
        return 0

    parser = cli.build_parser()
    args = parser.parse_args(["cells"])
    args.func = noisy
    monkeypatch.setattr(parser, "parse_args", lambda argv=None: args)
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    assert cli.main(["cells"]) == 0
    err = capsys.readouterr().err
    assert err.count("the skin's wall is 1.39 .. 1.71 mm thick") == 1
    assert err.count("another one") == 1
