"""Beam FE export (.inp): the model's structure, node sets by selector, and CalculiX (ccx)
results against closed-form beam theory.

ccx is a real client here: a missing ``ccx`` is a failure, never a skip (CI installs
calculix-ccx). Each analysis writes a small deck that ``*INCLUDE``s the exported model and
loads it with forces (``*CLOAD``), and reads ccx's ``.dat`` tables back.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from conformal import block
from lattice_cad import LatticeGraph
from lattice_cad.core import config
from lattice_cad.core.errors import ExportError, SelectionError
from lattice_cad.core.formats import Kind, format_for
from lattice_cad.io import fe
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

E_PLA = config.FE_YOUNGS_MODULUS


# ------------------------------------------------------------------ helpers
@pytest.fixture(scope="module")
def ccx() -> str:
    exe = shutil.which("ccx")
    if exe is None:
        pytest.fail("ccx (CalculiX) is not installed: apt-get install calculix-ccx")
    return exe


def run_ccx(ccx: str, workdir: Path, model: Path, step: str) -> tuple[list[fe.DatBlock], float]:
    """Run ``step`` (boundary conditions and a *STEP) on ``model``; the .dat tables, seconds."""
    deck = workdir / "job.inp"
    deck.write_text(f"*INCLUDE, INPUT={model.name}\n{step.strip()}\n")
    t0 = time.perf_counter()
    proc = subprocess.run(
        [ccx, "job"], cwd=workdir, capture_output=True, text=True, timeout=900, check=False
    )
    seconds = time.perf_counter() - t0
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-2000:]
    assert "*ERROR" not in log, log[-2000:]
    assert "Job finished" in log, log[-2000:]
    return fe.read_dat(workdir / "job.dat"), seconds


def block_of(blocks: list[fe.DatBlock], quantity: str, set_name: str, *, total: bool = False):
    found = [b for b in blocks if b.quantity == quantity and b.set == set_name.upper()]
    found = [b for b in found if b.total == total]
    assert len(found) == 1, [(b.quantity, b.set, b.total) for b in blocks]
    return found[0]


def parse_inp(path: Path) -> dict:
    """An independent reader of the written file: nodes, elements by set, sections, sets."""
    nodes: dict[int, np.ndarray] = {}
    elements: dict[int, tuple[str, tuple[int, int, int]]] = {}
    sections: dict[str, tuple[float, np.ndarray]] = {}
    nsets: dict[str, list[int]] = {}
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if not ln.startswith("**")]
    i = 0
    while i < len(lines):
        head = lines[i].upper()
        i += 1
        opts = dict((kv.split("=") + [""])[:2] for kv in (s.strip() for s in head.split(",")[1:]))
        data = []
        while i < len(lines) and not lines[i].startswith("*"):
            data.append([x.strip() for x in lines[i].split(",") if x.strip()])
            i += 1
        if head.startswith("*NODE,") or head == "*NODE":
            for row in data:
                nodes[int(row[0])] = np.array([float(x) for x in row[1:4]])
            if "NSET" in opts:
                nsets[opts["NSET"]] = [int(row[0]) for row in data]
        elif head.startswith("*ELEMENT"):
            assert opts["TYPE"] in ("B32", "B32R")
            for row in data:
                elements[int(row[0])] = (opts["ELSET"], tuple(int(x) for x in row[1:4]))
        elif head.startswith("*BEAM SECTION"):
            assert opts["SECTION"] == "CIRC"
            sections[opts["ELSET"]] = (float(data[0][0]), np.array([float(x) for x in data[1]]))
        elif head.startswith("*NSET"):
            nsets[opts["NSET"]] = [int(x) for row in data for x in row]
    return {"nodes": nodes, "elements": elements, "sections": sections, "nsets": nsets}


def chain(direction, n: int, length: float, r0: float, r1: float | None = None) -> LatticeGraph:
    """``n`` struts in a straight line from the origin; radius linear from r0 to r1."""
    t = np.asarray(direction, dtype=np.float64)
    t /= np.linalg.norm(t)
    s = np.linspace(0.0, length, n + 1)
    r = np.linspace(r0, r0 if r1 is None else r1, n + 1)
    edges = np.column_stack([np.arange(n), np.arange(1, n + 1)])
    return LatticeGraph(s[:, None] * t, edges, np.column_stack([r[:-1], r[1:]]))


# --------------------------------------------------------------- the file
def test_inp_in_the_suffix_table(tmp_path):
    assert format_for("x.inp", Kind.FE_MODEL).name == "inp"
    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh

    g = block("bcc", 1, cell_size=5.0, radius=0.4)
    tetra = Mesh(
        vertices=np.eye(4, 3), faces=np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    )
    with pytest.raises(ValueError, match=r"\.inp"):
        io.save_mesh(tetra, tmp_path / "x.inp")  # a mesh is not a beam model
    with pytest.raises(ValueError, match="cannot save a beam FE model as .stl"):
        fe.save_inp(g, tmp_path / "x.stl")


def test_model_structure(tmp_path):
    g = block("bcc", 2, cell_size=5.0, radius=0.4)
    out = tmp_path / "m.inp"
    model = Lattice(g).save_inp(out, node_sets={"bottom": "<Z", "top": ">Z"})
    f = parse_inp(out)
    k = config.FE_ELEMENTS_PER_STRUT
    assert len(f["elements"]) == k * g.num_edges == model.num_elements
    # graph node i is node i + 1 at the same place
    for i in range(g.num_nodes):
        np.testing.assert_array_equal(f["nodes"][i + 1], g.nodes[i])
    # each element: mid-node in the middle, section direction far from the strut axis
    for _eid, (elset, (a, m, b)) in f["elements"].items():
        pa, pm, pb = f["nodes"][a], f["nodes"][m], f["nodes"][b]
        np.testing.assert_allclose(pm, 0.5 * (pa + pb), atol=1e-9)
        t = (pb - pa) / np.linalg.norm(pb - pa)
        d, n1 = f["sections"][elset]
        assert abs(t @ n1) / np.linalg.norm(n1) <= 1 / math.sqrt(3) + 1e-9
        assert d == pytest.approx(2 * 0.4 * fe.CCX_CIRC_SCALE, rel=1e-8)
    # every strut is a chain of k elements from one of its nodes to the other
    for m_idx, (a, b) in enumerate(g.edges):
        els = [f["elements"][e + 1][1] for e in np.flatnonzero(model.element_strut == m_idx)]
        assert len(els) == k and els[0][0] == a + 1 and els[-1][2] == b + 1
        assert all(els[j][2] == els[j + 1][0] for j in range(k - 1))
    # node sets: every node within one radius of z = 0 / z = 10, and none else
    z = g.nodes[:, 2]
    assert sorted(f["nsets"]["BOTTOM"]) == list(np.flatnonzero(z <= 0.4) + 1)
    assert sorted(f["nsets"]["TOP"]) == list(np.flatnonzero(z >= 10 - 0.4) + 1)
    assert len(f["nsets"]["NJOINT"]) == g.num_nodes
    assert len(f["nsets"]["NALL"]) == len(f["nodes"]) == model.num_nodes


def test_radius_groups_and_tapered_steps(tmp_path):
    nodes = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0], [0, 0, 10]], float)
    edges = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 4]]
    radii = [[0.4, 0.4], [0.4002, 0.4002], [0.41, 0.41], [0.5, 0.5], [0.4, 0.6]]
    g = LatticeGraph(nodes, edges, radii)
    model = fe.beam_model(g, elements_per_strut=1)
    # the tapered strut: 5 steps (0.83 (0.04 / 0.4)^2 < 1 % needs dr <= 0.0438)
    k = np.bincount(model.element_strut)
    assert list(k) == [1, 1, 1, 1, 5]
    taper = model.element_strut == 4
    np.testing.assert_allclose(
        model.element_radius[taper], [0.42, 0.46, 0.5, 0.54, 0.58], rtol=config.FE_RADIUS_STEP
    )
    # each element's section radius within half a step of its own (midpoint) radius
    mid = g.radii[model.element_strut].mean(axis=1)
    mid[taper] = [0.42, 0.46, 0.5, 0.54, 0.58]
    assert np.all(np.abs(model.element_radius / mid - 1) <= config.FE_RADIUS_STEP / 2 + 1e-12)
    # equal radii stay exact; 0.4 and 0.4002 share a group, 0.41 does not
    assert model.element_radius[0] == model.element_radius[1]
    assert model.element_group[0] != model.element_group[2]
    assert float(model.radii[model.element_group[3]]) == 0.5
    # the estimate: the steps' bending error below the tolerance, and not far below it
    step_dr = 0.2 / 5
    assert 20 / 24 * (step_dr / 0.4) ** 2 <= config.FE_TAPER_TOL
    assert 20 / 24 * (0.2 / 4 / 0.4) ** 2 > config.FE_TAPER_TOL


def test_material_and_dialect(tmp_path):
    g = block("bcc", 1, cell_size=5.0, radius=0.4)
    out = tmp_path / "a.inp"
    fe.save_inp(g, out, dialect="abaqus", material={"E": 1700, "nu": 0.4, "density": 0.93e-9,
                                                    "name": "PA12"})  # fmt: skip
    text = out.read_text(encoding="utf-8")
    assert "*MATERIAL, NAME=PA12\n*ELASTIC\n1700, 0.4\n*DENSITY\n9.3e-10\n" in text
    assert all(v[0] == 0.4 for v in parse_inp(out)["sections"].values())  # Abaqus: radius
    fe.save_inp(g, out)
    text = out.read_text(encoding="utf-8")
    assert f"*ELASTIC\n{config.FE_YOUNGS_MODULUS:g}, {config.FE_POISSON:g}\n" in text
    with pytest.raises(ValueError, match="poisson"):
        fe.save_inp(g, out, material={"nu": 0.5})
    with pytest.raises(ValueError, match="unknown material option 'G'"):
        fe.save_inp(g, out, material={"G": 1.0})


def test_bad_node_sets_are_named_and_write_nothing(tmp_path):
    g = block("bcc", 1, cell_size=5.0, radius=0.4)
    out = tmp_path / "x.inp"
    with pytest.raises(ExportError, match="'1bad'"):
        fe.save_inp(g, out, node_sets={"1bad": "<Z"})
    with pytest.raises(ExportError, match="given twice"):
        fe.save_inp(g, out, node_sets={"load": "<Z", "LOAD": ">Z"})
    with pytest.raises(ExportError, match="reserved"):
        fe.save_inp(g, out, node_sets={"NALL": "<Z"})
    with pytest.raises(SelectionError, match=r"node set 'mid'.*nearest node \(4\) is 0\.5 mm"):
        fe.save_inp(g, out, node_sets={"mid": "plane:0,0,2,0,0,1"})
    with pytest.raises(SelectionError, match="node index 99 is out of range"):
        fe.save_inp(g, out, node_sets={"x": [99]})
    with pytest.raises(SelectionError, match="needs the part's B-rep"):
        fe.save_inp(g, out, node_sets={"x": "%CYLINDER"})
    assert not out.exists() and list(tmp_path.iterdir()) == []
    # boxes and index lists
    model = fe.save_inp(g, out, node_sets={"b": "box:-1,-1,-1,1,1,1", "i": [4]})
    assert list(model.node_sets["b"]) == [1] and list(model.node_sets["i"]) == [5]


def test_cad_selectors_on_a_part(tmp_path):
    import cadquery as cq

    box = cq.Workplane("XY").box(20, 16, 12, centered=(True, True, False))
    lat = Lattice.fill(box, "bcc", 4.0, 0.4, fill="clip")
    z = lat.graph.nodes[:, 2]
    used = lat.graph.degree > 0
    out = tmp_path / "box.inp"
    sets = {"fixed": "<Z", "load": ">Z", "side": box.faces(">X"), "pl": "plane:0,0,0,0,0,1"}
    model = lat.save_inp(out, node_sets=sets)
    r = 0.4 + lat.part.deflection
    assert set(model.node_sets["fixed"] - 1) == set(np.flatnonzero(used & (z <= r)))
    assert set(model.node_sets["load"] - 1) == set(np.flatnonzero(used & (z >= 12 - r)))
    x = lat.graph.nodes[:, 0]
    assert set(model.node_sets["side"] - 1) == set(np.flatnonzero(used & (x >= 10 - r)))
    assert len(model.node_sets["fixed"]) > 10
    with pytest.raises(SelectionError, match="'%CYLINDER' selects no face"):
        lat.save_inp(out, node_sets={"c": "%CYLINDER"})
    with pytest.raises(SelectionError, match="not a CadQuery face selector"):
        lat.save_inp(out, node_sets={"c": ">>Q!"})
    # a lattice inside the part touches no face: the error says how far the nearest node is
    inner = Lattice.fill(box, "bcc", 4.0, 0.4, fill="inside")
    with pytest.raises(SelectionError, match=r"nearest node .* mm from|is [0-9.]+ mm away"):
        inner.save_inp(out, node_sets={"top": ">Z"})
    # the suffix dispatches: save() writes the same model
    lat.save(tmp_path / "b.inp", node_sets={"fixed": "<Z"})
    assert "*NSET, NSET=fixed" in (tmp_path / "b.inp").read_text(encoding="utf-8")
    with pytest.raises(ValueError, match="apply to .inp"):
        lat.save(tmp_path / "b.json", node_sets={"fixed": "<Z"})


# ----------------------------------------------------- ccx vs beam theory
def cantilever(ccx, tmp_path, graph, *, nu, direction_load, elements_per_strut=None):
    model = tmp_path / "model.inp"
    kw = {} if elements_per_strut is None else {"elements_per_strut": elements_per_strut}
    fe.save_inp(graph, model, node_sets={"root": [0], "tip": [graph.num_nodes - 1]},
                material={"E": E_PLA, "nu": nu}, **kw)  # fmt: skip
    p = np.asarray(direction_load, dtype=np.float64)
    step = f"""
*BOUNDARY
root, 1, 6
*STEP
*STATIC
*CLOAD
tip, 1, {p[0]:.12g}
tip, 2, {p[1]:.12g}
tip, 3, {p[2]:.12g}
*NODE PRINT, NSET=tip
U
*END STEP
"""
    blocks, _ = run_ccx(ccx, tmp_path, model, step)
    return block_of(blocks, "displacements", "tip").values[0]


SKEW = np.array([3.0, 1.0, 0.5]) / np.linalg.norm([3.0, 1.0, 0.5])
ACROSS = np.cross(SKEW, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(SKEW, [0.0, 0.0, 1.0]))


def test_ccx_cantilever_chain_matches_beam_theory(ccx, tmp_path):
    """10 struts in a line off the axes, clamped at one end, loaded across at the other:
    tip deflection P L^3 / (3 E I). Slender (L / r = 200): the Timoshenko shear term,
    3 E I / (kappa G A L^2) = 4e-5 of the bending term, is left out. nu = 0: Euler-Bernoulli
    has no Poisson effect, CalculiX's expanded bricks do (see the next test)."""
    length, r, force = 100.0, 0.5, 0.01
    g = chain(SKEW, 10, length, r)
    u = cantilever(ccx, tmp_path, g, nu=0.0, direction_load=force * ACROSS)
    theory = force * length**3 / (3 * E_PLA * math.pi * r**4 / 4)
    err = u @ ACROSS / theory - 1
    print(f"cantilever chain: ccx {u @ ACROSS:.6g} mm, beam theory {theory:.6g} mm, {err:+.2%}")
    assert abs(err) < 0.02
    assert abs(u @ SKEW) < 1e-3 * theory  # no axial motion to first order


def test_ccx_poisson_stiffening_is_calculix_s(ccx, tmp_path):
    """With PLA's nu = 0.36 the same chain is stiffer than beam theory by a few percent:
    CalculiX's 20-node bricks on the parabolic circle lock in bending with nu > 0 (a
    property of the solver's element, documented in lattice_cad.io.fe)."""
    length, r, force = 100.0, 0.5, 0.01
    g = chain(SKEW, 10, length, r)
    u = cantilever(ccx, tmp_path, g, nu=config.FE_POISSON, direction_load=force * ACROSS)
    theory = force * length**3 / (3 * E_PLA * math.pi * r**4 / 4)
    err = u @ ACROSS / theory - 1
    print(f"cantilever chain, nu = {config.FE_POISSON}: {err:+.2%} against beam theory")
    assert -0.06 < err < -0.01


def test_ccx_tapered_cantilever_matches_beam_theory(ccx, tmp_path):
    """A cone-shaped cantilever (radius 0.8 -> 0.4 mm over 100 mm in 5 tapered struts):
    tip deflection (P / E) int_0^L (L - x)^2 / I(x) dx, integrated by Gauss-Legendre."""
    length, force = 100.0, 0.002
    g = chain(SKEW, 5, length, 0.8, 0.4)
    u = cantilever(ccx, tmp_path, g, nu=0.0, direction_load=force * ACROSS)
    x, w = np.polynomial.legendre.leggauss(200)
    x = 0.5 * length * (x + 1)
    rx = 0.8 + (0.4 - 0.8) * x / length
    theory = force / E_PLA * np.sum(0.5 * length * w * (length - x) ** 2 / (math.pi * rx**4 / 4))
    err = u @ ACROSS / theory - 1
    print(f"tapered cantilever: ccx {u @ ACROSS:.6g} mm, theory {theory:.6g} mm, {err:+.2%}")
    assert abs(err) < 0.02


def test_ccx_runs_the_example_step_of_the_file(ccx, tmp_path):
    g = block("bcc", (2, 2, 1), cell_size=5.0, radius=0.4)
    model = tmp_path / "ex.inp"
    fe.save_inp(g, model, node_sets={"fixed": "<Z", "load": ">Z"})
    text = model.read_text(encoding="utf-8")
    head, example = text.split("** Example analysis", 1)
    step = "\n".join(ln[3:] for ln in example.splitlines()[3:])
    assert step.startswith("*BOUNDARY\nfixed, 1, 6\n*STEP")
    blocks, _ = run_ccx(ccx, tmp_path, model, step)
    u = block_of(blocks, "displacements", "NJOINT").values
    top = g.nodes[:, 2] == 5.0
    assert np.isfinite(u).all() and np.all(u[top, 2] < 0)


def bcc_stiffness(ccx, tmp_path, a, r, **kw) -> float:
    """A BCC cell between a clamped base and a top held in x, y and rotation, pushed down
    with 1 N: its stiffness (N/mm)."""
    g = block("bcc", 1, cell_size=a, radius=r)
    model = tmp_path / "bcc.inp"
    fe.save_inp(g, model, node_sets={"bottom": "<Z", "top": ">Z"}, **kw)
    step = """
*BOUNDARY
bottom, 1, 6
top, 1, 2
top, 4, 6
*STEP
*STATIC
*CLOAD
top, 3, -0.25
*NODE PRINT, NSET=top
U
*END STEP
"""
    blocks, _ = run_ccx(ccx, tmp_path, model, step)
    uz = block_of(blocks, "displacements", "top").values[:, 2]
    assert np.ptp(uz) < 1e-9 * abs(uz.mean())  # the four corners move together
    return -1.0 / uz.mean()


def bcc_theory(a: float, r: float, e: float = E_PLA) -> float:
    """Each strut (length L = a sqrt(3) / 2, at 35.3 deg to the load's normal plane) is held
    in rotation at both ends (the centre by symmetry): along z it gives
    (EA / L) sin^2 + (12 EI / L^3) cos^2, sin^2 = 1/3; two layers of four in series."""
    length = a * math.sqrt(3) / 2
    area, inertia = math.pi * r**2, math.pi * r**4 / 4
    strut = e * area / length / 3 + 12 * e * inertia / length**3 * 2 / 3
    return 2 * strut


@pytest.mark.parametrize("a,r", [(10.0, 0.5), (10.0, 1.0)])
def test_ccx_bcc_cell_compression_matches_frame_theory(ccx, tmp_path, a, r):
    k = bcc_stiffness(ccx, tmp_path, a, r)  # default material (PLA, nu = 0.36)
    theory = bcc_theory(a, r)
    err = k / theory - 1
    print(f"BCC a={a} r={r}: ccx {k:.5g} N/mm, frame theory {theory:.5g} N/mm, {err:+.2%}")
    assert abs(err) < 0.02


def test_one_element_per_strut_locks(ccx, tmp_path):
    """Why three elements per strut: one quadratic element cannot bend in double curvature."""
    k1 = bcc_stiffness(ccx, tmp_path, 10.0, 0.5, elements_per_strut=1)
    err = k1 / bcc_theory(10.0, 0.5) - 1
    print(f"BCC with one element per strut: {err:+.2%}")
    assert err > 0.10


# --------------------------------------------------------- a real part
@pytest.mark.slow
def test_ccx_on_a_real_part_from_the_cli(ccx, tmp_path, capsys):
    """``lattice-cad fill`` of a real STEP part to .inp with supports at <Z and loads at >Z;
    ccx solves it without errors and the part has a finite, positive stiffness."""
    from lattice_cad.cli import main

    part = DATA / "step" / "dolfiny_spanner25_lo.step"  # 55 x 280 x 10 mm, flat in z
    out = tmp_path / "spanner.inp"
    argv = ["fill", str(part), "-o", str(out), "--cell-size", "10", "--radius", "0.8",
            "--fill", "conform", "--node-set", "fixed=<Z", "--node-set", "load=>Z"]  # fmt: skip
    code = main(argv)
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert re.search(r"node sets: fixed \d+, load \d+", printed)
    f = parse_inp(out)
    n_load = len(f["nsets"]["LOAD"])
    step = """
*BOUNDARY
fixed, 1, 6
*STEP
*STATIC
*CLOAD
load, 3, -1.0
*NODE PRINT, NSET=load
U
*NODE PRINT, NSET=fixed, TOTALS=ONLY
RF
*END STEP
"""
    blocks, seconds = run_ccx(ccx, tmp_path, out, step)
    u = block_of(blocks, "displacements", "load").values
    rf = block_of(blocks, "forces", "fixed", total=True).values[0]
    assert np.isfinite(u).all()
    stiffness = n_load / -u[:, 2].mean()
    print(
        f"spanner: {len(f['nodes'])} nodes, {len(f['elements'])} elements, load set {n_load} "
        f"nodes, ccx {seconds:.1f} s, stiffness {stiffness:.4g} N/mm, reaction {rf}"
    )
    assert 0 < stiffness < np.inf
    assert np.isfinite(rf).all()  # (ccx's RF of skew beam nodes is unreliable: not compared)


def test_cli_refuses_fe_options_without_inp(tmp_path, capsys):
    from lattice_cad.cli import main

    g = tmp_path / "g.json"
    block("bcc", 1, cell_size=5.0, radius=0.4).save(g)
    code = main(["fill", str(g), "-o", str(tmp_path / "x.stl"), "--node-set", "a=<Z"])
    assert code == 1
    assert "--node-set apply to .inp output" in capsys.readouterr().err
