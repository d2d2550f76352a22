"""The trim's boolean on the struts near the part's surface only (``trim_to_part(graph=)``):
the deep struts left out and glued back after the float32 check give the same solid, the
same report and the same removed pieces as the boolean on the whole lattice (real parts),
and every way the split can fail falls back to the whole cut."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import fast_stitch
from conformal import load_part, skin_split, trim
from lattice_cad import Lattice, LatticeGraph
from lattice_cad.core.errors import ExportError, LatticeWarning
from tests.conftest import DATA, assert_valid
from tests.test_skin_split import _triangles

STEP = DATA / "step"
pytestmark = pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")


def _spy_near(monkeypatch) -> list:
    """Record what each ``_trim_near`` call returned (None: the whole cut ran)."""
    calls: list = []
    real = trim._trim_near

    def spy(*a, **k):
        out = real(*a, **k)
        calls.append(out)
        return out

    monkeypatch.setattr(trim, "_trim_near", spy)
    return calls


def _box():
    import cadquery as cq

    return load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))


def _grid(lo: float, hi: float, step: float, r: float) -> LatticeGraph:
    """A cubic grid graph (nodes ``lo .. hi`` by ``step`` on each axis, axis struts)."""
    ax = np.arange(lo, hi + 1e-9, step)
    n = len(ax)
    idx = np.arange(n**3).reshape(n, n, n)
    nodes = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), axis=-1).reshape(-1, 3)
    edges = np.vstack(
        [
            np.stack([idx[:-1].ravel(), idx[1:].ravel()], 1),
            np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
            np.stack([idx[:, :, :-1].ravel(), idx[:, :, 1:].ravel()], 1),
        ]
    )
    return LatticeGraph(nodes, edges, r)


def _compare(make, monkeypatch) -> tuple[Lattice, Lattice]:
    """``make()``'s lattice with the split and without it: the same triangles and report."""
    calls = _spy_near(monkeypatch)
    lat = make()
    mesh = lat.mesh()
    assert calls and calls[0] is not None, "the split did not apply"
    assert calls[0].split is not None or not lat.trim_report.trimmed
    monkeypatch.setattr(trim, "_trim_near", lambda *a, **k: None)
    whole = make()
    ref = whole.mesh()
    a, b = lat.trim_report, whole.trim_report
    assert (a.trimmed, a.bodies, a.pieces_removed) == (b.trimmed, b.bodies, b.pieces_removed)
    # the whole cut measures the protrusion before on manifold3d's float32 vertices, the
    # split on the lattice's own (float64), and after on float32-rounded ones
    ulp = float(np.spacing(np.float32(np.abs(lat.part.bounds).max())))
    assert a.protrusion_before == pytest.approx(b.protrusion_before, abs=2 * ulp)
    assert a.volume_removed == pytest.approx(b.volume_removed, rel=1e-6, abs=1e-6)
    assert a.protrusion_after == pytest.approx(b.protrusion_after, abs=2 * ulp)
    assert len(mesh.faces) == len(ref.faces)
    np.testing.assert_array_equal(_triangles(mesh), _triangles(ref))
    assert fast_stitch.check(mesh).valid
    return lat, whole


def _real_fill(name: str, **kw):
    def make():
        part = load_part(STEP / name)
        cell = float(np.max(part.size)) / 15
        return Lattice.fill(part, cell_size=cell, radius=cell / 12, **kw)

    return make


@pytest.mark.parametrize(
    ("name", "kw", "loose"),
    [
        ("kcl_bracket.step", {"fill": "clip"}, False),
        # struts joined only outside the part leave loose pieces in each solid
        ("trimesh_box_sides.STEP", {"cell": "bcc"}, True),
        # 12 solids (its tet lattice left loose pieces until gmsh put fewer nodes on the
        # B-rep's small arcs; none now: box_sides keeps the loose pieces' case)
        ("kcl_enclosure.step", {"method": "tet"}, False),
    ],
)
def test_split_trim_equals_the_whole_cut_on_real_parts(name, kw, loose, monkeypatch):
    lat, _ = _compare(_real_fill(name, **kw), monkeypatch)
    rep = lat.trim_report
    assert rep.trimmed and rep.within_tolerance
    assert (rep.pieces_removed > 0) == loose
    assert_valid(lat.mesh(), self_intersections=False)


def test_struts_outside_the_part_are_dropped(monkeypatch):
    """A grid larger than the box: the struts clear outside never enter the boolean."""
    part = _box()
    lat, _ = _compare(lambda: Lattice(_grid(-3.0, 13.0, 2.0, 0.3), part=part), monkeypatch)
    rep = lat.trim_report
    assert rep.trimmed and rep.bodies == 1 and rep.within_tolerance
    # closed form: the grid's struts inside the box are whole; the volume kept is that of
    # the (independent) boolean of the lattice with the box
    kept = lat.mesh().volume
    whole = fast_stitch.stitch(lat.graph, lat.segments)
    # (the written mesh has float32 coordinates)
    assert rep.volume_removed == pytest.approx(whole.volume - kept, rel=1e-5)


def _with_tip(r: float, depth: float) -> LatticeGraph:
    """A grid inside the box and one strut from it toward the face x = 10 whose mesh ends
    ``depth`` mm under that face (placed from its stitched mesh)."""
    g0 = _grid(1.0, 7.0, 2.0, r)
    i = int(np.flatnonzero(np.all(np.isclose(g0.nodes, [7.0, 5.0, 5.0]), axis=1))[0])
    edges = np.vstack([g0.edges, [[i, len(g0.nodes)]]])
    tip = 10.0 - r
    for _ in range(2):
        g = LatticeGraph(np.vstack([g0.nodes, [[tip, 5.0, 5.0]]]), edges, r)
        tip += 10.0 - depth - float(Lattice(g)._lattice_mesh.vertices[:, 0].max())
    return LatticeGraph(np.vstack([g0.nodes, [[tip, 5.0, 5.0]]]), edges, r)


@pytest.mark.parametrize("depth", [0.005, 0.5])
def test_a_lattice_inside_the_surface_is_not_cut(depth, monkeypatch):
    """A strut whose end lies 5 um (near) or 0.5 mm (clear) under the surface: reported
    untrimmed, the lattice as it was, and no boolean on the whole lattice (the clear one is
    proven inside on the box's own tessellation, the near one by the split)."""
    from conformal import skin

    real = skin.as_manifold

    def refuse(obj, *, name="part"):
        if name == "the lattice mesh":  # (trim_to_part's whole cut)
            raise AssertionError("the whole lattice went through manifold3d")
        return real(obj, name=name)

    calls = _spy_near(monkeypatch)
    monkeypatch.setattr(skin, "as_manifold", refuse)
    lat = Lattice(_with_tip(0.3, depth), part=_box())
    mesh = lat.mesh()
    if depth > 0.1:  # clear of the box's own tessellation: proven there (trim.clear_inside)
        assert not calls and lat.trim_report.clearance > 0
    else:
        assert calls and calls[0] is not None and lat.trim_report.clearance == 0
    assert float(lat.mesh(lattice_only=True).vertices[:, 0].max()) == pytest.approx(
        10.0 - depth, abs=1e-6
    )
    rep = lat.trim_report
    assert not rep.trimmed and rep.protrusion_before == 0.0 and rep.bodies == 1
    assert len(mesh.faces) == len(lat.mesh(lattice_only=True).faces)


def test_a_lost_cap_falls_back_to_the_whole_cut(monkeypatch):
    calls: list[bool] = []
    real = Lattice._cut

    def spy(self, *, shift=0.0, split=True):
        calls.append(split)
        return real(self, shift=shift, split=split)

    monkeypatch.setattr(Lattice, "_cut", spy)
    monkeypatch.setattr(skin_split.SplitLattice, "glue", lambda self, v, f: None)
    lat = Lattice(_grid(-3.0, 13.0, 2.0, 0.3), part=_box())
    mesh = lat.mesh()
    assert calls == [True, False]
    assert lat.trim_report.trimmed and fast_stitch.check(mesh).valid
    monkeypatch.undo()
    ref = Lattice(_grid(-3.0, 13.0, 2.0, 0.3), part=_box()).mesh()
    np.testing.assert_array_equal(_triangles(mesh), _triangles(ref))


def test_regression_the_coarse_skin_retry_keeps_the_deep_struts(monkeypatch):
    """The last skin retry (on the part's own tessellation) built the skin of the near
    struts only and never glued the deep ones back: the flange lost 18 % of its triangles
    (159 K of 195 K faces). Every earlier try is made to fail here."""
    import lattice_cad.lattice as L

    def make():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)
            part = load_part(STEP / "kcl_flange-with-patterns.step")
            cell = float(part.size.max()) / 10
            return Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6)

    ref = make()
    ref_mesh = ref.mesh()
    real = L._checked_single_precision
    seen = {"n": 0}

    def failing(mesh, name):
        seen["n"] += 1
        if seen["n"] <= 4:  # the first build and the three retries before the coarse one
            raise ExportError("forced for the test")
        return real(mesh, name)

    monkeypatch.setattr(L, "_checked_single_precision", failing)
    lat = make()
    mesh = lat.mesh()
    assert lat.skin_retry == "coarse"
    assert lat.skin_report.split, "the coarse retry did not use the split"
    assert fast_stitch.check(mesh).valid and lat.skin_report.bodies == 1
    # the same lattice in a skin on a slightly coarser wall: about the same solid
    assert mesh.volume == pytest.approx(ref_mesh.volume, rel=0.01)
    assert len(mesh.faces) > 0.9 * len(ref_mesh.faces)
