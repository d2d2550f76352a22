"""lattice_cad.Lattice, the CadQuery plugin, skins and previews."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fast_stitch
from conformal import block, skin
from fast_stitch.check import check
from lattice_cad import LatticeGraph
from lattice_cad.lattice import Lattice


@pytest.fixture(scope="module")
def box():
    import cadquery as cq

    import lattice_cad.plugin  # noqa: F401  (adds Workplane.lattice, as users do)

    return cq.Workplane("XY").box(20, 16, 12)


@pytest.fixture(scope="module")
def box_lattice(box):
    import lattice_cad.plugin  # noqa: F401

    return box.lattice("bcc", 4.0, 0.4)


# ------------------------------------------------------------------- Lattice
def test_lattice_from_graph(tmp_path):
    g = block("bcc", 2, cell_size=5.0, radius=0.4)
    lat = Lattice(g, segments=8)
    info = lat.info()
    est = fast_stitch.estimate(g, 8)
    assert (info["struts"], info["nodes"]) == (64, 35)
    assert (info["triangles"], info["vertices"]) == (est.triangles, est.vertices)
    assert not info["volume_exact"]
    assert info["file_bytes"]["stl"] == est.stl_bytes
    assert info["file_bytes"]["3mf_beam"] < info["file_bytes"]["3mf"]
    assert "relative_density" not in info
    assert "_lattice_mesh" not in lat.__dict__  # lazy
    m = lat.mesh()
    assert lat.mesh() is m  # cached
    assert len(m.faces) == est.triangles
    info = lat.info()
    assert info["volume_exact"] and info["volume"] == pytest.approx(m.volume)
    # strut-volume estimate is an over-estimate of the same order
    assert m.volume < lat.strut_volume() < 2 * m.volume
    for suffix in (".json", ".npz"):
        assert LatticeGraph.load(lat.save(tmp_path / f"g{suffix}")) == g
    assert lat.save(tmp_path / "m.stl").stat().st_size == est.stl_bytes
    assert repr(lat) == "Lattice(35 nodes, 64 struts, segments=8)"


def test_lattice_options_checked(tmp_path):
    g = block("bcc", 1, cell_size=5.0, radius=0.4)
    with pytest.raises(ValueError, match="segments must be >= 3"):
        Lattice(g, segments=2)
    with pytest.raises(TypeError, match="segments must be an integer"):
        Lattice(g, segments=6.0)
    with pytest.raises(ValueError, match="a skin needs the part"):
        Lattice(g, skin=1.0)
    with pytest.raises(TypeError, match="graph must be a LatticeGraph"):
        Lattice([[0, 0, 0]])
    lat = Lattice(g)
    with pytest.raises(ValueError, match=r"cannot save a lattice as \.txt \(g\.txt\)"):
        lat.save(tmp_path / "g.txt")
    with pytest.raises(
        ValueError, match=r"cannot save a beam lattice as \.stl \(g\.stl\): use \.3mf"
    ):
        lat.save(tmp_path / "g.stl", beam_lattice=True)


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"method": "octree"}, ValueError, "method must be one of 'voxel', 'tet'"),
        ({"fill": "outside"}, ValueError, "fill must be one of"),
        ({"cell": "hexagon"}, ValueError, "unknown cell 'hexagon'"),
        ({"cell_size": -1.0}, ValueError, "cell_size must be a positive number"),
        ({"radius": float("nan")}, ValueError, "radius must be a positive number"),
        ({"radius": "0.4"}, TypeError, "radius must be a number"),
        ({"skin": 0.0}, ValueError, "skin must be a positive number"),
    ],
)
def test_fill_options_checked(box, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        Lattice.fill(box, **kwargs)


BRACKET = Path(__file__).parents[1] / "examples" / "bracket.step"


def test_fill_tet_bracket_is_valid(tmp_path):
    from lattice_cad.core.errors import LatticeWarning

    # crowded tet edges: the graph repair drops some, a few are still thinned (and said so)
    with pytest.warns(LatticeWarning, match="had to be made thinner than 0.7 x the radius"):
        lat = Lattice.fill(BRACKET, cell_size=5.0, radius=0.4, method="tet")
    rep = check(lat.mesh())
    assert rep.valid, str(rep)
    with pytest.raises(ValueError, match="fill only applies to method='voxel'"):
        Lattice.fill(BRACKET, method="tet", fill="conform")
    with pytest.raises(ValueError, match="origin and rotation only apply"):
        Lattice.fill(BRACKET, method="tet", origin=(0, 0, 0), rotation=np.eye(3))


def test_fill_bad_part(tmp_path):
    from conformal.part import PartError

    with pytest.raises(FileNotFoundError, match="nope.step"):
        Lattice.fill(tmp_path / "nope.step")
    bad = tmp_path / "bad.step"
    bad.write_text("garbage")
    with pytest.raises(PartError, match="bad.step"):
        Lattice.fill(bad)


def test_plugin_global_coordinates(box_lattice):
    import cadquery as cq

    assert callable(cq.Workplane.lattice)
    lo, hi = box_lattice.graph.bounds
    assert np.all(lo >= [-10, -8, -6]) and np.all(hi <= [10, 8, 6])
    moved = cq.Workplane("XY").box(20, 16, 12).translate((100, 0, 50)).faces(">Z")
    lat = moved.lattice("bcc", 4.0, 0.4)  # faces selected: their solid is used
    np.testing.assert_allclose(lat.graph.bounds, box_lattice.graph.bounds + [100, 0, 50])
    info = lat.info()
    assert info["part_volume"] == pytest.approx(20 * 16 * 12, rel=1e-6)
    assert 0 < info["relative_density"] < 1


def test_plugin_needs_a_solid():
    import cadquery as cq

    import lattice_cad.plugin  # noqa: F401

    with pytest.raises(ValueError, match="no solid on the stack"):
        cq.Workplane("XY").rect(5, 5).lattice()


def test_fill_build123d_and_path(tmp_path, box_lattice):
    import build123d as bd

    part = bd.Box(20, 16, 12)
    lat = Lattice.fill(part, "bcc", 4.0, 0.4)
    assert lat.graph == box_lattice.graph
    import cadquery as cq

    step = tmp_path / "box.step"
    cq.exporters.export(cq.Workplane("XY").box(20, 16, 12), str(step))
    assert Lattice.fill(step, "bcc", 4.0, 0.4).graph == box_lattice.graph


def test_beam_lattice_with_clip(tmp_path, box_lattice):
    from lattice_cad.core.errors import BeamOnlyWarning
    from lattice_cad.io import read_beam_lattice

    with pytest.warns(BeamOnlyWarning):
        p = box_lattice.save(tmp_path / "b.3mf", beam_lattice="only")
    info = read_beam_lattice(p)
    assert info["beams"] == box_lattice.graph.num_edges and info["clipped"]


# ---------------------------------------------------------------------- skin
def test_marching_tets_sphere():
    n, h = 40, 0.1
    x = (np.arange(n) - n / 2 + 0.5) * h
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    v, f = skin.marching_tets(1.5 - np.sqrt(X**2 + Y**2 + Z**2), np.full(3, x[0]), h)
    rep = check((v, f), self_intersections=False)
    assert rep.valid, rep
    assert rep.volume == pytest.approx(4 / 3 * np.pi * 1.5**3, rel=5e-3)


def test_inset_and_hollow_box():
    import manifold3d

    cube = manifold3d.Manifold.cube([20, 16, 12])
    cav = skin.inset(cube, 1.0)
    # the eroded box, exact up to the voxel size (1/3 mm)
    assert cav.volume() == pytest.approx(18 * 14 * 10, rel=0.04)
    lo, hi = np.asarray(cav.bounding_box()).reshape(2, 3)
    np.testing.assert_allclose(lo, [1, 1, 1], atol=0.2)
    np.testing.assert_allclose(hi, [19, 15, 11], atol=0.2)
    wall = skin.hollow(cube, 1.0)
    assert wall.volume() == pytest.approx(20 * 16 * 12 - cav.volume(), rel=1e-6)
    with pytest.raises(skin.SkinError, match="nowhere thicker than twice"):
        skin.hollow(cube, 6.5)
    with pytest.raises(ValueError, match="skin thickness must be a positive number"):
        skin.inset(cube, -1.0)


def test_as_manifold_refuses_open_mesh():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]])  # one face missing
    with pytest.raises(skin.SkinError, match="lid is not a closed 2-manifold"):
        skin.as_manifold((v, f), name="lid")


def test_skin_is_one_watertight_solid(box, tmp_path):
    lat = box.lattice("bcc", 4.0, 0.4, skin=1.0)
    assert lat.skin == 1.0
    m = lat.mesh()
    rep = check(m, self_intersections=False)
    assert rep.valid, rep
    lattice_only = lat.mesh(lattice_only=True)
    assert m.volume > 20 * 16 * 12 - 18 * 14 * 10 - 50  # at least the wall
    assert m.volume < 20 * 16 * 12
    assert len(lattice_only.faces) == lat.info()["triangles"]
    import manifold3d

    man = skin.as_manifold(m)
    bodies = [p for p in man.decompose() if p.volume() > 0]
    assert len(bodies) == 1  # struts are fused to the wall: nothing floats
    p = lat.save(tmp_path / "s.stl")
    from lattice_cad.io import read_mesh

    assert check(read_mesh(p), self_intersections=False).valid
    assert isinstance(man, manifold3d.Manifold)


# ------------------------------------------------------------------- preview
def test_preview_graph_mesh_and_part(tmp_path, box_lattice):
    from lattice_cad import preview

    for name, obj in [
        ("g.png", box_lattice.graph),
        ("l.png", box_lattice),
        ("m.png", box_lattice.mesh()),
        ("p.png", box_lattice.part),
    ]:
        p = preview.save_png(obj, tmp_path / name, size=(300, 200))
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="preview pictures are PNG files"):
        preview.save_png(box_lattice.graph, tmp_path / "x.jpg")
    with pytest.raises(TypeError, match="cannot draw a int"):
        preview.render_png(1)


@pytest.mark.slow
def test_preview_of_a_million_triangles(tmp_path):
    """A 1M-triangle mesh and its graph render to non-blank pictures (their speed is
    measured by benchmarks/bench_preview.py, not here)."""
    from PIL import Image

    from lattice_cad import preview

    g = block("bcc", (20, 20, 12), cell_size=5.0, radius=0.4)
    m = fast_stitch.stitch(g, 6)
    assert len(m.faces) > 1_000_000
    for what, name in ((m, "big.png"), (g, "graph.png")):
        preview.save_png(what, tmp_path / name)
        px = np.asarray(Image.open(tmp_path / name).convert("L"), dtype=np.float64)
        assert px.std() > 5.0 and (px < 250).mean() > 0.05, name


def test_preview_simplifies_without_holes(monkeypatch):
    from lattice_cad import preview

    m = fast_stitch.stitch(block("bcc", (4, 4, 3), cell_size=5.0, radius=0.4), 6)
    n = len(m.faces)
    v, f = preview._cluster(m.vertices, m.faces, n // 4)
    assert 0 < len(f) <= n // 4
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert np.all(count >= 2)  # closed: no boundary edges, i.e. no holes
    assert len(v) <= len(m.vertices)
    # all triangles are drawn up to the cap; the title says when it simplified
    import matplotlib.pyplot as plt

    for cap, expect in [(n, f"{n:,} triangles"), (n // 2, "simplified to")]:
        fig = plt.figure()
        ax = fig.add_subplot(projection="3d")
        try:
            what = preview._draw_mesh(ax, m.vertices, m.faces, cap)
        finally:
            plt.close(fig)
        assert expect in what and (cap < n or "simplified" not in what)


# ---------------------------------------------------------------------- B-rep
@pytest.mark.slow
def test_to_workplane_and_to_part():
    import cadquery as cq

    lat = Lattice(block("bcc", 1, cell_size=5.0, radius=0.6))
    wp = lat.to_workplane()
    solid = wp.val()
    assert solid.isValid()
    # the default mesh has the exact solid's volume (profile="volume", to the hub
    # quadrature's accuracy)
    assert lat.mesh().volume == pytest.approx(solid.Volume(), rel=2e-3)
    cut = cq.Workplane("XY").box(5, 5, 1).translate((2.5, 2.5, 0)).union(wp)
    assert cut.val().isValid()
    part = lat.to_part()
    assert part.volume == pytest.approx(solid.Volume(), rel=1e-9)
    with pytest.raises(Exception, match="B-rep solids are built for at most 4"):
        lat.to_workplane(max_struts=4)


def test_import_stays_light():
    code = (
        "import sys, lattice_cad.lattice, lattice_cad.cli, lattice_cad.io, "
        "conformal.skin, lattice_cad.preview\n"
        "heavy = [m for m in ('cadquery', 'OCP', 'build123d', 'manifold3d', 'trimesh', "
        "'matplotlib', 'lib3mf', 'reference_boolean') if m in sys.modules]\n"
        "print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_plugin_registers_the_cadquery_way_and_engines_never_touch_cadquery():
    code = (
        "import sys, lattice_cad, fast_stitch, conformal, reference_boolean, lattice_cad.io\n"
        "assert 'cadquery' not in sys.modules, 'an engine imported cadquery'\n"
        "hooks = [type(h).__module__ for h in sys.meta_path]\n"
        "assert not any(h.startswith('lattice_cad') for h in hooks), hooks\n"
        "import cadquery as cq\n"
        "assert not hasattr(cq.Workplane, 'lattice')\n"
        "import lattice_cad.plugin\n"
        "assert cq.Workplane.lattice is lattice_cad.plugin.lattice\n"
        "print('ok')"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
