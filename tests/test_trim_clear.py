"""A lattice clear inside a B-rep part is reported untrimmed on the part's own tessellation
(``conformal.trim.clear_inside``), without the finer cutting tessellation: the M6 screw's
inside fill took 80-90 s for that tessellation and now takes none. The proof must be sound:
checked against OpenCascade's exact distances (``lattice_cad.occ_impl.distance``), also
where the coarse tessellation stands off the exact surface (a spherical cavity, meshed
with a large chord error)."""

from __future__ import annotations

import numpy as np
import pytest

import fast_stitch
from conformal import load_part, trim
from lattice_cad import Lattice, LatticeGraph
from lattice_cad.occ_impl.distance import signed_distance
from tests.conftest import DATA
from tests.test_skin_split import _triangles

STEP = DATA / "step"
pytestmark = pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")


def _exact_depth(part, vertices: np.ndarray, k: int = 200) -> float:
    """Smallest exact depth (mm, > 0 inside) of the ``k`` vertices nearest the part's
    tessellation: OCCT's signed distance to the B-rep."""
    v = np.asarray(vertices, dtype=np.float64)
    d = part.distance(v)
    near = v[np.argsort(d)[:k]]
    return float(-signed_distance(part.shape, near).max())


def _cavity_part():
    """A 20 mm cube with a ball of radius 6 cut out of its middle, tessellated with a
    0.4 mm chord error: the facets of the cavity stand up to 0.4 mm out of the material."""
    import cadquery as cq

    shape = cq.Workplane("XY").box(20, 20, 20).cut(cq.Workplane("XY").sphere(6.0))
    return load_part(shape, deflection=0.4)


def test_the_part_as_loaded_bounds_its_chord_error():
    part = _cavity_part()
    assert part.chord_bound is not None
    # the sphere's facets: the largest sag of a chord is what BRepMesh was asked, about
    assert 0.05 < part.chord_bound < 1.0
    # a refined part is measured by its own check, not by this bound
    assert part.refined(0.1, checked=False).chord_bound is None
    # a mesh part has none
    assert load_part(DATA / "meshes" / "fandisk.obj").chord_bound is None


def test_clear_inside_is_sound_against_the_exact_surface():
    """Seeded short struts all over the cube with the cavity: whenever ``clear_inside``
    says a lattice is clear inside, OCCT finds every vertex inside the exact solid, at
    least as deep as the clearance reported; struts on the cavity's facets (inside the
    coarse mesh, outside the exact solid) are never passed."""
    part = _cavity_part()
    rng = np.random.default_rng(20261204)
    r = 0.25
    passed = refused = 0
    grazing = 0
    for _ in range(40):
        a = rng.uniform(-9.0, 9.0, 3)
        if rng.random() < 0.5:  # near the cavity: just under its facets, or beyond
            u = a / np.linalg.norm(a)
            a = u * rng.uniform(6.0, 6.0 + 3 * r)
        d = rng.normal(size=3)
        b = a + 1.5 * d / np.linalg.norm(d)
        g = LatticeGraph(np.array([a, b]), np.array([[0, 1]]), r)
        mesh = fast_stitch.stitch(g)
        got = trim.clear_inside(mesh, part, g, radius=r)
        depth = float(-signed_distance(part.shape, mesh.vertices).max())
        if depth < 2 * r:
            grazing += 1
        if got is None:
            refused += 1
            continue
        passed += 1
        assert not got.report.trimmed
        assert got.report.clearance > 0
        assert depth >= got.report.clearance, (a, b, depth, got.report.clearance)
    assert passed >= 5 and refused >= 5 and grazing >= 5, (passed, refused, grazing)


def test_a_strut_under_the_cavitys_facets_is_not_clear():
    """Inside the coarse mesh (between a facet and the exact sphere), outside the solid."""
    part = _cavity_part()
    # the middle of a facet of the cavity: a point of the mesh, off the sphere by its sag
    tri = part.vertices[part.faces]
    c = tri.mean(axis=1)
    on_ball = np.abs(np.linalg.norm(tri, axis=2) - 6.0).max(axis=1) < 1e-6
    k = int(np.argmax(np.where(on_ball, 6.0 - np.linalg.norm(c, axis=1), -1)))
    sag = 6.0 - float(np.linalg.norm(c[k]))
    assert sag > 0.05  # the facet stands that far into the cavity
    u = c[k] / np.linalg.norm(c[k])
    r = 0.02
    a = u * (6.0 - 0.5 * sag)  # in the cavity (outside the material) ...
    assert part.contains(a[None])[0]  # ... yet inside the coarse mesh
    g = LatticeGraph(np.array([a - 0.05 * u, a + 0.05 * np.cross(u, [0, 0, 1.0])]),
                     np.array([[0, 1]]), r)  # fmt: skip
    assert trim.clear_inside(fast_stitch.stitch(g), part, g, radius=r) is None


def test_a_mesh_part_or_a_lattice_on_the_surface_is_left_to_the_cut():
    import cadquery as cq

    box = load_part(cq.Workplane("XY").box(10, 10, 10, centered=False))
    g = LatticeGraph(np.array([[0.0, 5, 5], [5, 5, 5]]), np.array([[0, 1]]), 0.3)
    assert trim.clear_inside(fast_stitch.stitch(g), box, g, radius=0.3) is None
    deep = LatticeGraph(np.array([[3.0, 5, 5], [7, 5, 5]]), np.array([[0, 1]]), 0.3)
    got = trim.clear_inside(fast_stitch.stitch(deep), box, deep, radius=0.3)
    assert got is not None and not got.report.trimmed and got.report.bodies == 1
    from conformal.part import Part

    plain = Part(box.vertices, box.faces, name="box mesh")
    assert trim.clear_inside(fast_stitch.stitch(deep), plain, deep, radius=0.3) is None


def test_regression_the_m6_inside_fill_builds_no_cutting_tessellation(monkeypatch):
    """The M6 screw at the parts benchmark's bcc setting (cell 0.8, r 0.8 / 12): the lattice
    lies inside the part, so the cutting tessellation (77 s) is never made; the file is the
    stitched lattice as before, and OCCT finds it inside the exact screw."""
    called = []
    real = trim.cutting_part
    monkeypatch.setattr(trim, "cutting_part", lambda *a, **k: called.append(1) or real(*a, **k))
    lat = Lattice.fill(
        STEP / "build123d_M6-1x12-countersunk-screw.step", cell="bcc", cell_size=0.8,
        radius=0.8 / 12,
    )  # fmt: skip
    mesh = lat.mesh()
    assert not called and "_cutting_part" not in lat.__dict__
    rep = lat.trim_report
    assert not rep.trimmed and rep.protrusion_before == 0.0 and rep.clearance > 0
    assert "clear of its surface" in rep.summary()
    # the file holds the stitched lattice itself (in float32), uncut
    stitched = lat._lattice_mesh
    rounded = type(stitched)(
        vertices=stitched.vertices.astype(np.float32).astype(np.float64), faces=stitched.faces
    )
    np.testing.assert_array_equal(_triangles(mesh), _triangles(rounded))
    assert _exact_depth(lat.part, mesh.vertices) >= rep.clearance


def _chain(reach: float, r: float) -> LatticeGraph:
    """Struts along x from the cylinder's axis, the last node ``reach`` from it (mm)."""
    x = np.array([0.0, 3.0, 6.0, reach])
    nodes = np.stack([x, np.zeros(4), np.full(4, 5.0)], axis=1)
    return LatticeGraph(nodes, np.array([[0, 1], [1, 2], [2, 3]]), r)


def test_a_lattice_close_to_a_curved_wall_is_proven_on_a_finer_tessellation(monkeypatch):
    """Struts reaching 0.55 mm under a cylinder of radius 10 meshed with a 0.3 mm chord error: too
    close for the part's own tessellation, proven on one just fine enough (far coarser than
    the cutting tessellation's 0.5 % r), and OCCT agrees."""
    import cadquery as cq

    from conformal.part import Part

    part = load_part(cq.Workplane("XY").circle(10.0).extrude(10.0), deflection=0.3)
    asked: list[float] = []
    real = Part.refined

    def spy(self, deflection, **k):
        asked.append(deflection)
        return real(self, deflection, **k)

    monkeypatch.setattr(Part, "refined", spy)
    r = 0.2
    g = _chain(9.45, r)
    mesh = fast_stitch.stitch(g)
    got = trim.clear_inside(mesh, part, g, radius=r)
    assert got is not None and not got.report.trimmed
    assert len(asked) == 1 and asked[0] >= trim.CLEAR_FINER_RATIO * trim._wanted(part, r, None)
    depth = float(-signed_distance(part.shape, mesh.vertices).max())
    assert 0.4 < depth and depth >= got.report.clearance > 0
    # 0.01 mm under the wall: no tessellation much coarser than the cutting one proves it,
    # and none is tried
    asked.clear()
    g = _chain(9.99, r)
    assert trim.clear_inside(fast_stitch.stitch(g), part, g, radius=r) is None
    assert not asked
