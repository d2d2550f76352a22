"""STEP output a CAD user can use: one BRepCheck-valid solid per body, read back, sized.

Independent checks: the file is read back by OCCT's STEP reader and by cadquery, its
volume is compared with a fine stitched mesh intersected with the part by manifold3d, the
solid count with the mesh's connected bodies (trimesh), and PrusaSlicer's own report.
"""

from __future__ import annotations

import io
import shutil
import subprocess
import time

import numpy as np
import pytest

from conformal import block
from lattice_cad import LatticeGraph
from lattice_cad.core.errors import ExportError, LatticeError, OCCTFailure
from lattice_cad.lattice import Lattice
from tests.conftest import ROOT, star_graph

BRACKET = ROOT / "examples" / "bracket.step"


def _bodies(mesh) -> int:
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    return len(tm.split(only_watertight=False))


def _trimmed_mesh_volume(graph, part, segments: int = 64) -> float:
    """Volume of a fine mesh of the same solid (manifold3d union of the hub spheres and the
    struts, ``reference_boolean.union_mesh``) intersected with the part's mesh.

    The stitched mesh (``fast_stitch``) joins struts by hulls, not spheres, so it is a
    slightly different solid at the nodes; the union mesh converges to the exact one.
    """
    import manifold3d as m3

    from reference_boolean import union_mesh

    m = union_mesh(graph, segments)

    def man(v, f):
        return m3.Manifold(
            m3.Mesh(vert_properties=np.asarray(v, np.float32), tri_verts=np.asarray(f, np.uint32))
        )

    return float((man(m.vertices, m.faces) ^ man(part.vertices, part.faces)).volume())


def _prusa_info(path) -> dict[str, str]:
    out = subprocess.run(
        ["prusa-slicer", "--info", str(path)], capture_output=True, text=True, timeout=600
    ).stdout
    pairs = (ln.split("=", 1) for ln in out.splitlines() if "=" in ln)
    return {k.strip(): v.strip() for k, v in pairs}


# ------------------------------------------------------------- binary BREP
def test_hub_bytes_round_trip_with_triangulation(monkeypatch):
    """A degree-6 BCC hub of the GE bracket, tessellated, did not read back from bytes
    (``NCollection_IndexedMap::FindKey``: OCP's stream wrapper and BREP format 4)."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeSphere
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    from lattice_cad.occ_impl import shapes as occ
    from lattice_cad.occ_impl import truss
    from reference_boolean.reference import _hub_specs

    d = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    d = d[~((d[:, 0] > 0) & (d[:, 1] > 0))]  # 6 of the 8 diagonals, as on the GE bracket
    g = star_graph(d, lengths=5.0 * np.sqrt(3.0), radii=0.4)
    specs, _, _, _ = _hub_specs(g, True)
    # the sphere as it was built then (axis +Z): the very shape that failed
    z_sphere = lambda spec: [  # noqa: E731
        BRepPrimAPI_MakeSphere(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1), gp_Dir(1, 0, 0)),
                               spec.radius).Shape()
    ]  # fmt: skip
    monkeypatch.setattr(truss, "make_sphere", z_sphere)
    shape = truss.make_hub_shape(specs[0])
    list(occ.face_triangulations(shape, 0.004, 0.25, parallel=False))  # as build_hub did
    back = occ.from_bytes(occ.to_bytes(shape))
    assert occ.is_valid(back)
    assert occ.volume(back, eps=1e-10) == pytest.approx(occ.volume(shape, eps=1e-10), rel=1e-9)


def test_occt_exceptions_are_wrapped(tmp_path):
    from OCP.BinTools import BinTools
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    from lattice_cad.occ_impl import shapes as occ

    assert not occ.is_occt_error(ValueError("x"))
    with pytest.raises(OCCTFailure, match="reading a shape back from binary BREP"):
        occ.from_bytes(b"not a brep at all" * 10)
    box = BRepPrimAPI_MakeBox(1.0, 2.0, 3.0).Shape()
    buf = io.BytesIO()
    BinTools.Write_s(box, buf)
    assert occ.volume(occ.from_bytes(buf.getvalue())) == pytest.approx(6.0)


# -------------------------------------------------------------- refusals
def test_too_large_is_refused_before_any_work(tmp_path):
    lat = Lattice(block("bcc", 3, cell_size=5.0, radius=0.4))
    out = tmp_path / "x.step"
    t0 = time.perf_counter()
    with pytest.raises(ExportError) as err:
        lat.save(out, max_struts=10)
    msg = str(err.value)
    assert time.perf_counter() - t0 < 5.0
    assert f"{lat.graph.num_edges:,} struts" in msg and "at most 10 struts" in msg
    assert " s and " in msg and "MB of STEP" in msg  # the estimate
    assert ".stl" in msg and ".3mf" in msg and f"max_struts={lat.graph.num_edges}" in msg
    assert str(out) in msg and not out.exists() and list(tmp_path.iterdir()) == []
    with pytest.raises(LatticeError, match="at most 4 struts"):
        lat.to_workplane(max_struts=4)


def test_skin_is_refused_not_dropped(tmp_path):
    from conformal.part import load_part

    part = load_part(BRACKET)
    lat = Lattice(block("bcc", 1, cell_size=5.0, radius=0.4), part=part, skin=1.0)
    with pytest.raises(ExportError, match="skin"):
        lat.save(tmp_path / "s.step")
    assert not (tmp_path / "s.step").exists()


def test_estimate_grows_with_the_lattice():
    from lattice_cad.brep import estimate

    small = estimate(block("bcc", 1, cell_size=5.0, radius=0.4))
    big = estimate(block("bcc", 3, cell_size=5.0, radius=0.4), trim=True)
    assert small.clean and big.clean and big.trim
    assert big.struts > small.struts and big.seconds > small.seconds and big.bytes > small.bytes


# -------------------------------------------------------------- solids
def test_block_is_one_valid_solid(tmp_path):
    """A clean lattice: the hubs sewn into one solid of exactly the reference's volume."""
    import cadquery as cq

    from lattice_cad.occ_impl.step import read_step_solids
    from reference_boolean import build_reference

    g = block("bcc", 2, cell_size=5.0, radius=0.5)
    lat = Lattice(g)
    out = lat.save(tmp_path / "b.step")
    solids = read_step_solids(out)
    assert len(solids) == 1 == _bodies(lat.mesh())
    assert solids[0][0]  # BRepCheck
    exact = build_reference(g).volume
    assert solids[0][1] == pytest.approx(exact, rel=1e-7)
    # the default 6-sided mesh has the exact solid's volume (profile="volume", hubs scaled
    # to it), to the hub quadrature's accuracy
    assert lat.mesh().volume == pytest.approx(exact, rel=2e-3)
    wp = cq.importers.importStep(str(out))
    assert len(wp.solids().vals()) == 1 and wp.val().isValid()
    assert wp.val().Volume() == pytest.approx(exact, rel=1e-6)
    assert [p.name for p in tmp_path.iterdir()] == ["b.step"]  # no temp file left


def test_step_output_is_byte_identical(tmp_path, monkeypatch):
    """Issue 12: the same lattice gives the same STEP bytes (no clock, no session counter),
    and the header names the file written, not the temp file."""
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    g = block("bcc", 1, cell_size=5.0, radius=0.5)
    first = Lattice(g).save(tmp_path / "a.step").read_bytes()
    time.sleep(1.1)  # the header's time stamp had a one-second resolution
    (tmp_path / "a.step").unlink()
    second = Lattice(g).save(tmp_path / "a.step").read_bytes()
    assert first == second
    assert b"FILE_NAME('a.step','2000-01-01T00:00:00'" in first
    assert b"PRODUCT('a','a'" in first
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    third = Lattice(g).save(tmp_path / "a.step").read_bytes()
    assert b"'2023-11-14T22:13:20'" in third


def test_two_bodies_give_two_solids(tmp_path):
    from lattice_cad.occ_impl.step import read_step_solids

    a = block("bcc", 1, cell_size=5.0, radius=0.5)
    nodes = np.vstack([a.nodes, a.nodes + [20.0, 0.0, 0.0]])
    g = LatticeGraph(nodes, np.vstack([a.edges, a.edges + a.num_nodes]), np.vstack([a.radii] * 2))
    lat = Lattice(g)
    solids = read_step_solids(lat.save(tmp_path / "two.step"))
    assert len(solids) == 2 == _bodies(lat.mesh())
    assert all(v for v, _ in solids)
    assert solids[0][1] == pytest.approx(solids[1][1], rel=1e-9)


def test_overlapping_hubs_are_fused(tmp_path):
    """A lattice that is not clean (hubs overlap): fused, still one valid solid."""
    from lattice_cad.brep import estimate
    from lattice_cad.occ_impl.step import read_step_solids
    from reference_boolean import find_overlaps, union_mesh

    g = LatticeGraph([[0, 0, 0], [1, 0, 0], [1.4, 0, 0], [1, 1, 0]],
                     [[0, 1], [1, 2], [1, 3]], [0.3, 0.05, 0.1])  # fmt: skip
    assert find_overlaps(g) and not estimate(g).clean
    solids = read_step_solids(Lattice(g).save(tmp_path / "d.step"))
    assert len(solids) == 1 and solids[0][0]
    fine = union_mesh(g, 96).volume  # manifold3d union of spheres and struts
    assert solids[0][1] == pytest.approx(fine, rel=2e-3)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:24 of 48 strut:lattice_cad.core.errors.LatticeWarning")
def test_example_bracket_step(tmp_path):
    """The README's bracket: one solid, trimmed to the part, PrusaSlicer: manifold."""
    import cadquery as cq

    from lattice_cad.occ_impl.step import read_step_solids

    lat = Lattice.fill(BRACKET, "bcc", 5.0, 0.4, fill="inside")
    out = lat.save(tmp_path / "bracket.step")
    rep = lat.brep_report
    assert rep.estimate.trim and rep.valid
    solids = read_step_solids(out)
    assert len(solids) == rep.solids == _bodies(lat.mesh()) == 1
    assert all(v for v, _ in solids)
    ref = _trimmed_mesh_volume(lat.graph, lat.part)
    assert solids[0][1] == pytest.approx(ref, rel=5e-3)
    box = cq.importers.importStep(str(out)).val().BoundingBox()
    pb = lat.part.bounds
    tol = 1e-3
    assert box.xmin >= pb[0, 0] - tol and box.zmin >= pb[0, 2] - tol
    assert box.xmax <= pb[1, 0] + tol and box.zmax <= pb[1, 2] + tol
    if shutil.which("prusa-slicer") is None:
        pytest.skip("prusa-slicer is not installed")
    info = _prusa_info(out)
    assert info.get("manifold") == "yes" and "open_edges" not in info
    assert info.get("number_of_parts") == "1"
    assert float(info["volume"]) == pytest.approx(solids[0][1], rel=2e-2)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:24 of 48 strut:lattice_cad.core.errors.LatticeWarning")
def test_cli_step(tmp_path, capsys):
    from lattice_cad.cli import main

    out = tmp_path / "c.step"
    args = ["fill", str(BRACKET), "-o", str(out), "--fill", "inside"]
    code = main([*args, "--max-brep-struts", "5"])
    err = capsys.readouterr().err
    errors = [ln for ln in err.splitlines() if ln.startswith("error: ")]
    assert code == 1 and len(errors) == 1 and "--max-brep-struts 24" in errors[0]
    assert not out.exists()
    code = main([*args, "-q"])
    assert code == 0 and out.exists()


def test_writing_step_prints_nothing(tmp_path, capfd):
    """Issue 12: OCCT's transfer statistics went to the C stdout on every STEP write."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    from lattice_cad.occ_impl.step import write_step

    write_step(BRepPrimAPI_MakeBox(1.0, 2.0, 3.0).Shape(), tmp_path / "box.step")
    out, _ = capfd.readouterr()
    assert out == ""
    assert (tmp_path / "box.step").stat().st_size > 0
