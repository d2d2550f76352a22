"""lattice_cad.io: formats by suffix, limits, beam-lattice 3MF re-read with lib3mf."""

from __future__ import annotations

import numpy as np
import pytest

import fast_stitch
from conformal import block
from fast_stitch.check import check
from lattice_cad import io as export
from lattice_cad.core.errors import (
    BeamOnlyWarning,
    ExportError,
    ExportWarning,
    InputFileError,
    InvalidGraphError,
    LatticeWarning,
)


@pytest.fixture(scope="module")
def graph():
    return block("bcc", 2, cell_size=5.0, radius=0.4)


@pytest.fixture(scope="module")
def mesh(graph):
    return fast_stitch.stitch(graph, 6)


@pytest.mark.parametrize("suffix", [".stl", ".3mf", ".ply", ".obj"])
def test_mesh_round_trip(tmp_path, mesh, suffix):
    p = export.save_mesh(mesh, tmp_path / f"m{suffix}")
    assert p.exists() and p.stat().st_size > 0
    v, f = export.read_mesh(p)
    assert len(f) == len(mesh.faces)
    assert len(v) == len(mesh.vertices)
    rep = check((v, f), self_intersections=False)
    assert rep.valid, rep
    assert rep.volume == pytest.approx(mesh.volume, rel=1e-5)
    assert not list(tmp_path.glob(".*")), "temp files left behind"


def test_stl_size_is_exact(tmp_path, mesh):
    p = export.save_mesh(mesh, tmp_path / "m.STL")
    assert p.stat().st_size == export.estimate_bytes(".stl", 0, len(mesh.faces))
    assert not p.read_bytes().startswith(b"solid")


def test_mesh_like_inputs(tmp_path, mesh):
    import manifold3d
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    export.save_mesh(tm, tmp_path / "a.ply")
    export.save_mesh((mesh.vertices, mesh.faces), tmp_path / "b.obj")
    export.save_mesh(manifold3d.Manifold.cube([1, 2, 3]), tmp_path / "c.3mf")
    v, f = export.read_mesh(tmp_path / "c.3mf")
    assert check((v, f)).volume == pytest.approx(6.0)
    with pytest.raises(TypeError, match="cannot export a int"):
        export.save_mesh(3, tmp_path / "d.stl")


def test_bad_suffix_and_empty(tmp_path, mesh):
    with pytest.raises(
        ValueError,
        match=r"cannot save a mesh as \.step \(m\.step\): use \.stl, \.3mf, \.ply",
    ):
        export.save_mesh(mesh, tmp_path / "m.step")
    with pytest.raises(ValueError, match="without suffix"):
        export.save_mesh(mesh, tmp_path / "m")
    with pytest.raises(ExportError, match="e.stl: the mesh is empty"):
        export.save_mesh((np.zeros((0, 3)), np.zeros((0, 3), int)), tmp_path / "e.stl")
    with pytest.raises(
        ValueError, match=r"cannot save a graph as \.txt \(g\.txt\): use \.json, \.npz"
    ):
        export.save_graph(block("bcc", 1), tmp_path / "g.txt")
    assert not list(tmp_path.iterdir())


def test_limits(tmp_path):
    with pytest.raises(ExportError, match=r"big\.stl: 4,294,967,296 triangles do not fit"):
        export.check_limits(tmp_path / "big.stl", 3, 2**32)
    with pytest.raises(ExportError, match=r"big\.3mf: 2,147,483,648 triangles do not fit"):
        export.check_limits(tmp_path / "big.3mf", 3, 2**31)
    with pytest.raises(ExportError, match="beams do not fit"):
        export.check_limits(tmp_path / "big.3mf", 3, 0, n_beams=2**31)
    with pytest.warns(ExportWarning, match=r"big\.stl: the file will be about 2\.3 GiB"):
        size = export.check_limits(tmp_path / "big.stl", 3, 50_000_000)
    assert size == 84 + 50 * 50_000_000
    assert export.check_limits(tmp_path / "small.stl", 3, 1000) == 50_084
    assert issubclass(ExportWarning, LatticeWarning)
    assert ExportError is fast_stitch.ExportError


def test_failed_export_leaves_nothing(tmp_path):
    # struts far from the origin: float32 STL rounding makes triangles degenerate
    g = block("cubic", 1, cell_size=1e-3, origin=(1e4, 1e4, 1e4), radius=1e-4)
    m = fast_stitch.stitch(g, 6)
    target = tmp_path / "far.stl"
    with pytest.raises(ExportError, match="far.stl"):
        export.save_mesh(m, target)
    assert not list(tmp_path.iterdir())


def test_beam_lattice_3mf(tmp_path, graph, mesh):
    import lib3mf
    import manifold3d

    radii = np.column_stack([np.full(graph.num_edges, 0.3), np.full(graph.num_edges, 0.5)])
    from lattice_cad import LatticeGraph

    tapered = LatticeGraph(graph.nodes, graph.edges, radii)
    clip = manifold3d.Manifold.cube([10, 10, 10])
    with pytest.warns(BeamOnlyWarning, match="PrusaSlicer, Bambu Studio, Cura"):
        p = export.save_beam_lattice(tapered, tmp_path / "b.3mf", clip=clip)
    info = export.read_beam_lattice(p)
    assert info["beams"] == graph.num_edges
    assert info["vertices"] == graph.num_nodes
    assert info["balls"] == int(np.count_nonzero(graph.degree >= 2))
    assert info["clipped"] is True
    assert info["objects"] == 2
    # per-end radii and indices survive, read back with lib3mf's own API
    model = lib3mf.get_wrapper().CreateModel()
    model.QueryReader("3mf").ReadFromFile(str(p))
    it = model.GetMeshObjects()
    beams = []
    while it.MoveNext():
        obj = it.GetCurrentMeshObject()
        bl = obj.BeamLattice()
        if bl.GetBeamCount():
            beams = [bl.GetBeam(i) for i in range(bl.GetBeamCount())]
    got = np.array([[b.Radii[0], b.Radii[1]] for b in beams])
    np.testing.assert_allclose(got, radii)
    got_idx = np.array([[b.Indices[0], b.Indices[1]] for b in beams])
    np.testing.assert_array_equal(got_idx, graph.edges)
    # the file is tiny compared with the mesh
    stl = export.save_mesh(mesh, tmp_path / "m.stl")
    assert p.stat().st_size * 10 < stl.stat().st_size
    # reading it as a mesh skips the clipping mesh and finds no triangles
    v, f = export.read_mesh(p)
    assert len(f) == 0


def test_beam_lattice_errors(tmp_path, graph):
    with pytest.raises(ValueError, match=r"cannot save a beam lattice as .* use \.3mf"):
        export.save_beam_lattice(graph, tmp_path / "b.stl")
    from lattice_cad import LatticeGraph

    empty = LatticeGraph(np.zeros((0, 3)), np.zeros((0, 2), int), 0.1)
    with pytest.raises(ExportError, match="b.3mf: the graph has no struts"):
        export.save_beam_lattice(empty, tmp_path / "b.3mf")


def test_read_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="mesh file not found"):
        export.read_mesh(tmp_path / "nope.stl")
    bad = tmp_path / "bad.3mf"
    bad.write_bytes(b"not a zip")
    with pytest.raises(InputFileError, match="bad.3mf: not a 3MF file"):
        export.read_mesh(bad)


def test_single_precision_output_is_what_gets_written(tmp_path):
    """The printable mesh is float32-exact, so the STL holds exactly the checked mesh."""
    g = block("octet", 2, cell_size=3.0, radius=0.3)
    m, repaired = export.single_precision(fast_stitch.stitch(g, segments=6))
    assert repaired == 0
    np.testing.assert_array_equal(m.vertices, m.vertices.astype(np.float32))
    assert check(m).valid
    p = export.save_mesh(m, tmp_path / "o.stl")
    v, f = export.read_mesh(p)
    assert len(f) == len(m.faces)
    assert check((v, f)).valid


def test_single_precision_refuses_what_float32_cannot_hold():
    """Regression (issue: extreme magnitudes): thin struts 1e6 mm from the origin flatten
    in single precision; the error says so and where, before any file is written."""
    from lattice_cad import LatticeGraph

    o = 1e6
    g = LatticeGraph(
        [[o, o, o], [o + 1, o, o], [o, o + 1, o], [o, o, o + 1]], [[0, 1], [0, 2], [0, 3]], 0.1
    )
    from lattice_cad.lattice import Lattice

    lat = Lattice(g, segments=8)
    # the precision contract refuses it before stitching (|x| / r = 1e7 > 3e4 for float32)
    with pytest.raises(InvalidGraphError, match=r"edge 0 \(0, 1\).*single precision"):
        lat.mesh()
    _, repaired = export.single_precision(lat.mesh(lattice_only=True))
    assert repaired > 0  # triangles collapse in float32; the rest still self-intersects
    # there, which the full check finds
