"""Regression tests of the bad-input campaign (issue 12): every case gives a named error
(the product's own class, naming the element or the file) or a valid result.

The random side of the campaign is ``tests/test_fuzz.py``; this file keeps each reported
case as it was reported.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import fast_stitch
from lattice_cad import LatticeGraph
from lattice_cad.cli import main
from lattice_cad.core import config
from lattice_cad.core.errors import (
    InputFileError,
    InsufficientMemoryError,
    InvalidGraphError,
    LatticeError,
    MissingFileError,
    OutputError,
    StitchError,
)
from tests.conftest import DATA, ROOT, independent_check


def star(offset=0.0, r=0.1, length=1.0):
    nodes = np.vstack([np.zeros(3), np.eye(3) * length]) + offset
    return nodes, [[0, 1], [0, 2], [0, 3]], r


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ precision contract
@pytest.mark.parametrize(
    ("offset", "r", "length", "message"),
    [
        # campaign: 68/68 zero-area faces, volume 0
        (1e15, 0.01, 1.0, r"edge 0 \(0, 1\): radius 0.01 is too small.*reach 1e\+15.*0.125"),
        # campaign: 28 zero-area faces, 110 self-intersecting pairs, volume -4.2e14
        (1e15, 0.1, 1.0, r"radius 0.1 is too small.*at least 1e\+06.*move the lattice by \(-1e"),
        # campaign: volume 0 at the origin
        (0.0, 1e-16, 1.0, r"radius 1e-16 is too small.*at least 1e-09"),
        # campaign: "could not build a valid hub (status 1) ... this is a bug"
        (0.0, 1e-300, 1.0, r"edge 0 has radius 1e-300 at node 0, below the smallest supported"),
        # campaign: perpendicular struts called "parallel"
        (0.0, 1.0, 1e155, r"node 1 at \(1e\+155, 0, 0\) is beyond the largest supported"),
    ],
)
def test_extreme_magnitudes_are_refused_by_name(offset, r, length, message):
    with pytest.raises(InvalidGraphError, match=message):
        LatticeGraph(*star(offset, r, length))


def test_huge_coordinates_where_the_clearance_check_overflows():
    """Found by the fuzzer: crossing struts are refused at every scale up to 1e70, but at
    1e77 the clearance test overflowed and a self-intersecting mesh came out."""
    from tests.test_fuzz import make

    nodes, edges, radii = make("random", np.random.default_rng(1))
    with pytest.raises(StitchError, match="overlap although they share no node"):
        fast_stitch.stitch(LatticeGraph(nodes * 1e50, edges, np.asarray(radii) * 1e50), 3)
    with pytest.raises(InvalidGraphError, match="beyond the largest supported coordinate"):
        LatticeGraph(nodes * 1e77, edges, np.asarray(radii) * 1e77)


def test_the_contract_threshold_is_where_the_sweep_put_it():
    """Just inside the float64 limit a star stitches valid; just outside it is refused."""
    r = 0.01
    inside = 0.9 * config.PRECISION_RATIO_F64 * r
    g = LatticeGraph(*star(inside, r, 1.0))
    mesh = fast_stitch.stitch(g, 6)
    assert fast_stitch.check(mesh).valid
    with pytest.raises(InvalidGraphError, match="edge 0"):
        LatticeGraph(*star(2 * config.PRECISION_RATIO_F64 * r, r, 1.0))


def test_float32_contract_before_writing(tmp_path):
    """Fine in float64, too thin for STL/3MF: refused before stitching, naming the strut
    and the radius that would do, for every single-precision writer."""
    from lattice_cad import io
    from lattice_cad.lattice import Lattice

    g = LatticeGraph(*star(1e6, 0.05, 1.0))  # |x| / r = 2e7: float64 fine, float32 not
    lat = Lattice(g)
    for out in ("a.stl", "a.3mf"):
        with pytest.raises(InvalidGraphError, match=r"edge 0 \(0, 1\).*single precision"):
            lat.save(tmp_path / out)
    need = 1e6 / config.PRECISION_RATIO_F32
    with pytest.raises(InvalidGraphError, match=f"at least {need:.4g}"):
        io.save_beam_lattice(g, tmp_path / "b.3mf")
    assert not list(tmp_path.iterdir())
    lat.save(tmp_path / "g.npz")  # a graph file is exact: allowed


def test_tiny_star_is_not_called_inside_out():
    """Campaign: radius 1e-9 called "inside-out, volume -3.25e-14" (float cancellation)."""
    nodes, edges, _ = star()
    g = LatticeGraph(nodes, edges, 1e-9)
    mesh = fast_stitch.stitch(g, 6, profile="inscribed")
    rep = fast_stitch.check(mesh)
    assert rep.valid, str(rep)
    exact = 3 * 6 / 2 * np.sin(2 * np.pi / 6) * 1e-18  # prisms: area of the hexagon x length
    assert rep.volume > 0 and abs(rep.volume - exact) < 0.05 * exact
    assert rep.n_inverted_components == 0


def test_tapered_struts_widening_into_a_neighbour_are_refused():
    """Found by the fuzzer: a strut 0.02 -> 0.07 at 14 degrees from another overlaps it
    beyond the joint; it used to give a self-intersecting mesh silently."""
    d1 = np.array([1.0, 0, 0])
    d2 = np.array([np.cos(np.radians(14)), np.sin(np.radians(14)), 0])
    nodes = np.vstack([np.zeros(3), 1.8 * d1, 0.32 * d2, [0, 0, -1.0], [0, -1.0, 0]])
    radii = [[0.05, 0.01], [0.02, 0.07], [0.05, 0.05], [0.05, 0.05]]
    g = LatticeGraph(nodes, [[0, 1], [0, 2], [0, 3], [0, 4]], radii)
    assert (
        independent_check(fast_stitch.stitch(g, 6, check_clearance=False))[
            "self_intersecting_faces"
        ]
        > 0
    )  # the overlap is real
    with pytest.raises(StitchError, match="node 0: struts 0 and 1 meet at 14 degrees"):
        fast_stitch.stitch(g, 6)


# ------------------------------------------------------------------------ input types
@pytest.mark.parametrize(
    ("nodes", "edges", "message"),
    [
        (np.eye(3), np.array([[0, 2**64 - 1]], dtype=np.uint64), "node 18446744073709551615,"),
        (np.eye(3), np.array([[0, 1e20]]), "references node 1e+20,"),
        (np.zeros((0, 3)), [[0, 1]], "edge 0 references node 0, but the graph has no nodes"),
        (np.eye(3), [[0, 2**65]], "edge 0 references node 36893488147419103232"),
    ],
)
def test_indices_are_reported_as_given(nodes, edges, message):
    with pytest.raises(InvalidGraphError, match=message.replace("+", r"\+")):
        LatticeGraph(nodes, edges, 0.1)


GOOD_NODES = [[0.0, 0, 0], [1, 0, 0]]


@pytest.mark.parametrize(
    ("nodes", "edges", "radii", "message"),
    [
        ([["0", "0", "0"], ["1", "0", "0"]], [[0, 1]], 0.1, "nodes must be real numbers, got str"),
        ([[0, 0, 0], [1, 0, "0"]], [[0, 1]], 0.1, "nodes must be real numbers, got strings"),
        ([[False] * 3, [True, False, False]], [[0, 1]], 0.1, "nodes must be real numbers, got b"),
        ([[0, 0, 0], [1, 0, True]], [[0, 1]], 0.1, r"got a boolean \(True\) at index \[1, 2\]"),
        (np.array(GOOD_NODES, complex), [[0, 1]], 0.1, "nodes must be real numbers, got complex"),
        (GOOD_NODES, [["0", "1"]], 0.1, "edges must be real numbers, got strings"),
        (GOOD_NODES, np.array([[False, True]]), 0.1, "edges must be real numbers, got booleans"),
        (GOOD_NODES, [[0, 1 + 0j]], 0.1, "edges must be real numbers, got complex"),
        (GOOD_NODES, [[0, 1]], "0.1", r"radii must be real numbers, got a string \('0.1'\)"),
        (GOOD_NODES, [[0, 1]], True, "radii must be real numbers, got booleans"),
        (GOOD_NODES, [[0, 1]], [0.1, True], r"radii must be real numbers, got a boolean"),
        (GOOD_NODES, [[0, 1]], 0.1 + 0j, "radii must be real numbers, got complex"),
        (GOOD_NODES, [[0, 1]], None, "radii must be real numbers, got None"),
    ],
)
def test_one_type_rule_for_nodes_edges_and_radii(nodes, edges, radii, message):
    """Campaign: numeric strings, bools and complex were coerced for some arrays only."""
    with pytest.raises(InvalidGraphError, match=message):
        LatticeGraph(nodes, edges, radii)


def test_numbers_of_any_real_dtype_are_accepted():
    for dt in (np.float32, np.float64, np.int32, np.int64, np.uint8):
        g = LatticeGraph(np.array(GOOD_NODES).astype(dt), np.array([[0, 1]], dtype=dt), 0.1)
        assert g.nodes.dtype == np.float64 and g.edges.dtype == np.int64
    assert LatticeGraph(GOOD_NODES, [[0.0, 1.0]], np.float32(0.1)).num_edges == 1


# ------------------------------------------------------------------------------- files
def test_empty_and_truncated_graph_files_name_the_file(tmp_path, capsys):
    """Campaign: EOFError / BadZipFile, and the CLI printed no file name."""
    good = LatticeGraph(*star()).save(tmp_path / "good.npz")
    data = good.read_bytes()
    (tmp_path / "zero.npz").write_bytes(b"")
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "cut.json").write_text('{"format": "lattice-cad-gr')
    cases = {
        "zero.npz": "the file is empty",
        "cut.npz": "not a readable .npz archive",
        "cut.json": "not a JSON file",
    }
    for name, why in cases.items():
        with pytest.raises(InputFileError, match=f"{name}: {why}"):
            LatticeGraph.load(tmp_path / name)
        code, out, err = run(capsys, "stitch", tmp_path / name, "-o", tmp_path / "o.stl")
        assert code == 1 and name in err and why in err and "Traceback" not in err
    with pytest.raises(MissingFileError, match="nope.npz") as e:
        LatticeGraph.load(tmp_path / "nope.npz")
    assert isinstance(e.value, FileNotFoundError)
    assert not zipfile.is_zipfile(tmp_path / "cut.npz")


def test_check_names_what_the_file_is(tmp_path, capsys):
    (tmp_path / "adir.stl").mkdir()
    (tmp_path / "zero.stl").write_bytes(b"")
    (tmp_path / "garbage.stl").write_bytes(b"garbage " * 40)
    rng = np.random.default_rng(0)
    (tmp_path / "random.stl").write_bytes(rng.bytes(300))
    LatticeGraph(*star()).save(tmp_path / "g.json")
    cases = {
        tmp_path / "adir.stl": "is a directory, not a mesh file",  # was "mesh file not found"
        DATA / "step" / "kcl_bracket.step": "is a STEP part, not a mesh",  # was "cascadio"
        tmp_path / "zero.stl": "the file is empty (0 bytes), not an STL file",
        tmp_path / "garbage.stl": "not an STL file",  # was "INVALID: no triangles"
        tmp_path / "random.stl": "not an STL file",  # was "No module named charset_normalizer"
        tmp_path / "g.json": "is a lattice graph, not a mesh",
    }
    for path, message in cases.items():
        code, out, err = run(capsys, "check", path)
        assert code == 1, path
        assert message in err and path.name in err, err
        assert "INVALID" not in out


def test_a_valid_stl_still_checks(tmp_path, capsys):
    from lattice_cad import io

    io.save_mesh(fast_stitch.stitch(LatticeGraph(*star()), 6), tmp_path / "ok.stl")
    code, out, _ = run(capsys, "check", tmp_path / "ok.stl")
    assert code == 0 and "ok.stl" in out


def test_occt_banners_never_reach_stdout(tmp_path):
    """Campaign: ``**** ERR StepFile`` on stdout; now the error text carries the message."""
    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21; garbage\n")
    proc = subprocess.run(
        [sys.executable, "-m", "lattice_cad.cli", "fill", str(bad), "-o", str(tmp_path / "o.stl")],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=300,
    )
    assert proc.returncode == 1
    assert proc.stdout == ""
    assert "bad.step: not a readable STEP file" in proc.stderr
    assert "StepFile" in proc.stderr and "****" not in proc.stderr


@pytest.mark.parametrize("suffix", [".stl", ".3mf", ".ply", ".npz", ".json"])
def test_write_errors_name_the_target_not_the_temp_file(tmp_path, capsys, suffix):
    """Campaign: 3MF and read-only errors named ``.x.stl.XXXX.part``."""
    g = LatticeGraph(*star())
    graph = g.save(tmp_path / "g.json")
    target = tmp_path / f"x{suffix}"
    target.mkdir()  # a directory in the way
    code, _, err = run(capsys, "stitch", graph, "-o", target)
    assert code == 1
    assert f"cannot write {target}: it is a directory" in err
    assert ".part" not in err and ".tmp" not in err
    code, _, err = run(capsys, "stitch", graph, "-o", tmp_path / "no" / f"x{suffix}")
    assert code == 1 and "directory" in err and "does not exist" in err and ".tmp" not in err


@pytest.mark.parametrize("suffix", [".stl", ".3mf", ".npz"])
def test_permission_errors_name_the_target(tmp_path, monkeypatch, suffix):
    """Read-only targets (simulated: the tests may run as root, who may write anywhere)."""
    from lattice_cad import io

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", str(src))

    monkeypatch.setattr(os, "replace", refuse)
    target = tmp_path / f"ro{suffix}"
    g = LatticeGraph(*star())
    with pytest.raises(OutputError, match=rf"cannot write {target}: permission denied") as e:
        if suffix == ".npz":
            g.save(target)
        else:
            io.save_mesh(fast_stitch.stitch(g, 6), target)
    assert ".part" not in str(e.value) and isinstance(e.value, OSError)
    assert list(tmp_path.iterdir()) == []  # no temp file left behind


def test_quiet_before_the_command(tmp_path, capsys):
    """Campaign: ``lattice-cad -q preview ...`` ignored -q."""
    graph = LatticeGraph(*star()).save(tmp_path / "g.json")
    for argv in (["-q", "preview", graph, "-o", tmp_path / "a.png"],
                 ["preview", graph, "-o", tmp_path / "b.png", "-q"]):  # fmt: skip
        code, out, err = run(capsys, *argv)
        assert code == 0 and out == "" and err == ""
    code, out, _ = run(capsys, "preview", graph, "-o", tmp_path / "c.png")
    assert code == 0 and "wrote" in out


# ----------------------------------------------------------------------------- memory
def test_stitch_checks_memory_before_work(monkeypatch):
    """Campaign: a 10M-edge graph died in stitch with numpy's MemoryError (5.99 GiB). The
    estimate is compared with the available memory first (here capped at 1 MiB)."""
    from conformal import block

    g = block("bcc", 3, cell_size=1.0, radius=0.05)
    est = fast_stitch.estimate(g, 6)
    assert est.memory_bytes > 24 * (est.vertices + est.triangles)
    monkeypatch.setattr(config, "MEMORY_LIMIT", 100 * 1024)
    with pytest.raises(InsufficientMemoryError) as e:
        fast_stitch.stitch(g, 6)
    msg = str(e.value)
    assert f"stitching {g.num_edges:,} struts ({est.triangles:,} triangles)" in msg
    assert f"needs about {est.memory_bytes / 1024:.3g} KiB of memory" in msg
    assert "but only 100 KiB is available" in msg and "beam lattice" in msg
    assert isinstance(e.value, MemoryError) and isinstance(e.value, LatticeError)
    monkeypatch.setattr(config, "MEMORY_LIMIT", None)
    assert fast_stitch.check(fast_stitch.stitch(g, 6)).valid


def test_memory_limit_from_the_environment(monkeypatch):
    from lattice_cad.core.resources import available_memory

    monkeypatch.setenv("LATTICE_CAD_MEMORY_LIMIT", "3M")
    assert available_memory() == 3 * 1024**2
    monkeypatch.setenv("LATTICE_CAD_MEMORY_LIMIT", "2G")
    assert available_memory() <= 2 * 1024**3


def test_writers_and_fill_check_memory(tmp_path, monkeypatch):
    from conformal import block
    from lattice_cad import io
    from lattice_cad.lattice import Lattice

    g = block("bcc", 2, cell_size=1.0, radius=0.05)
    mesh = fast_stitch.stitch(g, 6)
    monkeypatch.setattr(config, "MEMORY_LIMIT", 10_000)
    for name in ("a.3mf", "a.ply", "a.obj"):
        with pytest.raises(InsufficientMemoryError, match=f"writing {name}"):
            io.save_mesh(mesh, tmp_path / name)
    with pytest.raises(InsufficientMemoryError, match="single precision"):
        io.single_precision(mesh)
    with pytest.raises(InsufficientMemoryError, match=r"writing g.json .*save the graph as .npz"):
        g.save(tmp_path / "g.json")
    with pytest.raises(InsufficientMemoryError, match="classifying a grid of"):
        Lattice.fill(DATA / "step" / "kcl_mounting-plate.step", cell_size=4.0, radius=0.4)
    monkeypatch.setattr(config, "MEMORY_LIMIT", 400_000)  # the grid fits, the lattice not
    with pytest.raises(InsufficientMemoryError, match=r"a lattice of [\d,]+ bcc cells"):
        Lattice.fill(DATA / "step" / "kcl_mounting-plate.step", cell_size=4.0, radius=0.4)
    assert not list(tmp_path.iterdir())


def test_memory_estimate_bounds_the_measured_peak(tmp_path):
    """The estimate is an upper bound of stitch's measured peak (numpy allocations, traced
    by tracemalloc), and not a gross overestimate."""
    code = (
        "import tracemalloc, fast_stitch\n"
        "from conformal import block\n"
        "g = block('bcc', 12, cell_size=1.0, radius=0.05)\n"
        "fast_stitch.stitch(block('bcc', 1, cell_size=1.0, radius=0.05), 8)\n"
        "tracemalloc.start()\n"
        "m = fast_stitch.stitch(g, 8)\n"
        "print(tracemalloc.get_traced_memory()[1], fast_stitch.estimate(g, 8).memory_bytes)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True,
    ).stdout  # fmt: skip
    peak, estimate = (int(x) for x in out.split())
    assert 0 < peak <= estimate < 3 * peak, (peak, estimate)
