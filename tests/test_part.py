"""conformal.load_part / Part: file formats, bad inputs, units, inside and distance queries."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from conformal.part import Part, PartError, load_part
from lattice_cad.core.errors import LatticeError, LatticeWarning
from tests.conftest import DATA


@pytest.fixture(scope="module")
def sphere() -> Part:
    import cadquery as cq

    return load_part(cq.Workplane().sphere(10.0))


@pytest.fixture(scope="module")
def box() -> Part:
    import cadquery as cq

    return load_part(cq.Workplane().box(10.0, 20.0, 30.0, centered=False))


def test_parterror_is_valueerror_and_latticeerror():
    assert issubclass(PartError, ValueError) and issubclass(PartError, LatticeError)


# ------------------------------------------------------------ bad inputs
BROKEN = {
    "pythonocc_splinecage_surfaces_only.stp": (
        r"no closed solid, only 4 open face\(s\), which do not close into a solid even when "
        r"sewn: face 1 \(free edge \("
    ),
    "trimesh_teapot_open.stl": r"not a closed solid: \d+ open",
    "newell_teapot_open.obj": r"not a closed solid: \d+ open",
    # a missing face: one hole, named by its first edges' end points
    "cube_no_bottom.obj": (
        r"not a closed solid: 8 open \(boundary\) edge\(s\) around 1 hole\(s\): it has holes, "
        r"e\.g\. the edge \(-1, -1, -1\) - \(-1, -1, 0\); .* and 5 more"
    ),
    "plane_holes.obj": r"not a closed solid: 341 open \(boundary\) edge\(s\) around 27 hole",
    "stanford-bunny_original_with_holes.obj": r"not a closed solid: \d+ open",
    "trimesh_soup.stl": r"not a closed solid: 300 open",
    "trimesh_stl_empty_ascii.stl": r"no triangles",
    "trimesh_stl_empty_bin.stl": r"no triangles",
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_files_raise_clear_error(name):
    path = DATA / "broken" / name
    with pytest.raises(PartError, match=BROKEN[name]) as info:
        load_part(path)
    assert name in str(info.value)


def test_bodies_sharing_an_edge_are_split_with_a_warning():
    """trimesh's two unit cubes sharing an edge were refused ("1 non-manifold edge(s) shared
    by more than two triangles"); each cube now keeps its own copy of the edge
    (``conformal.touching``), said with where, and the two are one part of volume 2."""
    path = DATA / "broken" / "trimesh_shared_nonmanifold_edge.STL"
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always", LatticeWarning)
        part = load_part(path)
    said = " | ".join(str(w.message) for w in rec)
    assert "1 edge(s) shared by more than two triangles" in said
    assert "e.g. at (0.5, 0.5, 0)" in said
    assert "2 bodies, none overlapping another, make one part" in said
    assert part.volume == pytest.approx(2.0, rel=1e-12)
    assert part.contains(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])).all()
    assert not part.contains(np.array([[1.0, 0.0, 0.0]]))[0]


def test_overlapping_solids_are_united_with_warning():
    path = DATA / "broken" / "kcl_food-service-spatula_overlapping_solids.step"
    with pytest.warns(LatticeWarning, match=r"3 solids were united .*overlapping by 9000"):
        part = load_part(path)
    assert part.volume > 0
    assert Part.__name__ in repr(type(part))


def test_bodies_touching_at_a_corner_are_two_solids_each_filled(tmp_path):
    """Regression (s39's two blocks touching at one corner, made outside shared/data): the
    bodies of a mesh were found by shared vertices, so the blocks were one solid, and the
    fill of the smaller one (376 of 752 struts) was removed as a loose piece. Bodies are
    edge-connected: two solids, one body each."""
    from lattice_cad import Lattice

    a = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    a.apply_translation((20.0, 15.0, 10.0))  # corner at (40, 30, 20)
    b = trimesh.creation.box(extents=(30.0, 30.0, 25.0))
    b.apply_translation((55.0, 45.0, 32.5))  # corner at (40, 30, 20)
    both = trimesh.util.concatenate([a, b])
    both.merge_vertices()
    assert len(both.vertices) == 15  # the corner is one vertex
    path = tmp_path / "corner.stl"
    both.export(path)
    with pytest.warns(LatticeWarning, match="2 bodies, none overlapping another, make one part"):
        part = load_part(path)
    assert len(part.solid_parts) == 2
    assert part.volume == pytest.approx(40 * 30 * 20 + 30 * 30 * 25, rel=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no loose piece removed
        lat = Lattice.fill(part, cell="bcc", cell_size=5.0, radius=0.4)
    assert lat.build_report.removed_islands == 0 and lat.build_report.bodies == 2
    inside = [float(p.contains(lat.graph.nodes).sum()) for p in part.solid_parts]
    assert min(inside) > 0.3 * max(inside)  # both blocks filled


def test_flipped_body_is_reoriented_with_warning():
    path = DATA / "broken" / "trimesh_multibody_flipped_body.stl"
    with pytest.warns(LatticeWarning) as rec:
        part = load_part(path)
    msgs = " | ".join(str(w.message) for w in rec)
    assert "re-oriented outward" in msgs
    assert "2 bodies, none overlapping another, make one part" in msgs
    # regression: each body was counted twice ("4 of 2 bodies"); each is named by a point;
    # regression (s38's bracket with 9 flipped triangles: "1 of 1 bodies had flipped
    # triangles"): the triangles are counted, per body (10 of the first box's 12 and 16 of
    # the second's 20 face inward, by the centroid test of these near-convex boxes)
    assert "26 flipped (inward-facing) triangle(s) in 2 of 2 bodies" in msgs
    assert "body 0 at (-0.4758, -0.6225, 0.009326): 10 of 12" in msgs
    assert "body 1 at (0.07422, 3.508e-08, 0.2281): 16 of 20" in msgs
    assert part.volume > 0
    # both bodies count as inside
    assert part.contains(part.vertices.mean(axis=0, keepdims=True)).dtype == bool


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_part(tmp_path / "nope.step")


@pytest.mark.parametrize("suffix", [".step", ".stl"])
def test_empty_and_garbage_files(tmp_path, suffix):
    empty = tmp_path / f"empty{suffix}"
    empty.write_bytes(b"")
    with pytest.raises(PartError, match="empty"):
        load_part(empty)


def test_garbage_step(tmp_path):
    bad = tmp_path / "bad.step"
    bad.write_text("this is not a STEP file\n")
    with pytest.raises(PartError, match="bad.step"):
        load_part(bad)


def test_unsupported_suffix(tmp_path):
    f = tmp_path / "x.iges"
    f.write_text("x")
    with pytest.raises(PartError, match="unsupported file type"):
        load_part(f)


def test_bad_source_type():
    with pytest.raises(TypeError):
        load_part(42)


# ----------------------------------------------------------------- units
def test_step_in_inches_comes_out_in_mm(tmp_path):
    import cadquery as cq

    from lattice_cad.occ_impl import step as _occ

    shape = cq.Workplane().box(25.4, 50.8, 12.7, centered=False).val().wrapped
    path = tmp_path / "inch.step"
    _occ.write_step(shape, path, unit="IN")
    text = path.read_text(errors="ignore").upper()
    assert "INCH" in text
    part = load_part(path)
    np.testing.assert_allclose(part.size, [25.4, 50.8, 12.7], rtol=1e-6)
    np.testing.assert_allclose(part.volume, 25.4 * 50.8 * 12.7, rtol=1e-6)


def test_inch_step_file_from_the_wild():
    part = load_part(DATA / "step" / "trimesh_featuretype.STEP")
    # a 5 x 2.5 x 1.375 inch block
    np.testing.assert_allclose(part.size, [127.0, 63.5, 34.925], atol=0.02)


def test_mesh_units_override():
    path = DATA / "meshes" / "bunny_closed_odedstein.obj"
    a = load_part(path)
    b = load_part(path, units="cm")
    np.testing.assert_allclose(b.size, 10 * a.size)
    with pytest.raises(ValueError, match="unknown unit"):
        load_part(path, units="furlong")
    with pytest.raises(ValueError, match="STEP files declare"):
        load_part(DATA / "step" / "kcl_bracket.step", units="mm")


def test_mesh_units_are_refused_for_3mf(tmp_path):
    import trimesh

    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh

    box = trimesh.creation.box((2.0, 3.0, 4.0))
    path = tmp_path / "box.3mf"
    io.save_mesh(Mesh(vertices=np.asarray(box.vertices), faces=np.asarray(box.faces)), path)
    np.testing.assert_allclose(load_part(path).size, [2.0, 3.0, 4.0], atol=1e-6)
    with pytest.raises(ValueError, match="3MF files declare their own unit"):
        load_part(path, units="in")


# ------------------------------------------------------------ in memory
def test_cadquery_and_build123d_shapes(box):
    import build123d as bd
    import cadquery as cq

    np.testing.assert_allclose(box.size, [10, 20, 30], atol=1e-9)
    np.testing.assert_allclose(box.volume, 6000.0, rtol=1e-9)
    p = load_part(cq.Workplane().box(4, 5, 6).val())
    np.testing.assert_allclose(p.volume, 120.0, rtol=1e-9)
    q = load_part(bd.Box(4, 5, 6))
    np.testing.assert_allclose(q.volume, 120.0, rtol=1e-9)


def test_two_solids_in_memory_united(recwarn):
    import cadquery as cq

    wp = cq.Workplane().box(2, 2, 2).add(cq.Workplane().box(2, 2, 2).translate((1, 0, 0)))
    with pytest.warns(LatticeWarning, match="2 solids were united.*overlapping by 4"):
        p = load_part(wp)
    np.testing.assert_allclose(p.volume, 12.0, rtol=1e-6)


# -------------------------------------------------------------- queries
def test_contains_box_exact(box, rng):
    pts = rng.uniform(-5, 35, size=(20000, 3))
    inside = (pts > 0).all(axis=1) & (pts < [10, 20, 30]).all(axis=1)
    np.testing.assert_array_equal(box.contains(pts), inside)


def test_contains_on_vertices_and_edges_of_grid(box):
    # grid points through mesh vertices and edges: simulation of simplicity counts once
    g = np.stack(np.meshgrid(*[np.linspace(-1, 31, 33)] * 3, indexing="ij"), -1).reshape(-1, 3)
    off = g + [0.0, 0.0, 0.5]  # z off the faces; x/y on the diagonals of the top/bottom faces
    on_side = np.isin(off[:, 0], [0.0, 10.0]) | np.isin(off[:, 1], [0.0, 20.0])
    off = off[~on_side]
    assert np.any(np.isclose(off[:, 1], 2 * off[:, 0]))  # rays through mesh edges
    inside = (off > 0).all(axis=1) & (off < [10, 20, 30]).all(axis=1)
    np.testing.assert_array_equal(box.contains(off), inside)


def test_sphere_contains_and_distance(sphere, rng):
    pts = rng.uniform(-12, 12, size=(20000, 3))
    r = np.linalg.norm(pts, axis=1)
    tol = sphere.deflection * 1.01
    far = np.abs(r - 10) > tol
    np.testing.assert_array_equal(sphere.contains(pts)[far], (r < 10)[far])
    d = sphere.distance(pts)
    assert np.all(np.abs(d - np.abs(r - 10)) <= tol)
    sd = sphere.signed_distance(pts[far])
    assert np.all(np.sign(sd) == np.sign(r[far] - 10))


def test_signed_distance_within_max_distance_equals_full():
    # the protrusion bench measures only vertices near the surface of a fine mesh; points
    # within the band get the full value, the others +-inf by side
    part = load_part(DATA / "step" / "trimesh_featuretype.STEP")
    rng = np.random.default_rng(7)
    lo, hi = part.bounds
    pts = rng.uniform(lo - 2.0, hi + 2.0, size=(3000, 3))
    band = 0.05 * float(part.size.max())
    full = part.signed_distance(pts)
    banded = part.signed_distance(pts, max_distance=band)
    near = np.abs(full) <= band
    assert 100 < near.sum() < len(pts) - 100
    np.testing.assert_array_equal(banded[near], full[near])
    np.testing.assert_array_equal(banded[~near], np.where(full[~near] < 0, -np.inf, np.inf))


def test_distance_matches_brute_force(box, rng):
    import trimesh

    pts = rng.uniform(-3, 33, size=(300, 3))
    d, cp = box.closest(pts)
    tm = trimesh.Trimesh(box.vertices, box.faces, process=False)
    _, ref, _ = trimesh.proximity.closest_point(tm, pts)
    np.testing.assert_allclose(d, ref, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(cp - pts, axis=1), d, atol=1e-9)


def test_grid_contains_matches_points(sphere):
    origin = np.array([-11.3, -10.7, -12.1])
    step = np.array([0.9, 1.1, 0.7])
    dims = np.array([25, 21, 35])
    grid = sphere.grid_contains(origin, step, dims)
    idx = np.indices(dims).reshape(3, -1).T
    pts = origin + idx * step
    np.testing.assert_array_equal(grid.reshape(-1), sphere.contains(pts))


def test_real_mesh_contains_agrees_with_trimesh(rng):
    import trimesh

    part = load_part(DATA / "meshes" / "bunny_closed_odedstein.obj")
    b = part.bounds
    pts = rng.uniform(b[0], b[1], size=(3000, 3))
    tm = trimesh.Trimesh(part.vertices, part.faces, process=False)
    d = part.distance(pts)
    ok = d > 1e-6
    np.testing.assert_array_equal(part.contains(pts)[ok], tm.contains(pts)[ok])


def test_declared_length_unit_is_read_from_the_step_text():
    from lattice_cad.occ_impl import step as _occ

    si = "#5=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );"
    metre = "#5=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT($,.METRE.) );"
    inch = (
        "#4=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT($,.METRE.) );"
        "#6=( CONVERSION_BASED_UNIT('INCH',#7) LENGTH_UNIT() NAMED_UNIT(#8) );"
        "#9=( CONVERSION_BASED_UNIT('DEGREE',#10) NAMED_UNIT(#8) PLANE_ANGLE_UNIT() );"
    )
    assert _occ.declared_length_unit(si) == ("MILLIMETRE", 1.0)
    assert _occ.declared_length_unit(metre) == ("METRE", 1000.0)
    assert _occ.declared_length_unit(inch) == ("INCH", 25.4)
    assert _occ.declared_length_unit("#1=CARTESIAN_POINT('',(0.,0.,0.));") is None


def _inch_box_step(tmp_path):
    import cadquery as cq

    from lattice_cad.occ_impl import step as _occ

    shape = cq.Workplane().box(25.4, 50.8, 12.7, centered=False).val()
    path = tmp_path / "inch.step"
    _occ.write_step(shape.wrapped, path, unit="IN")
    return path, shape


def test_step_units_check_refuses_a_part_loaded_at_the_wrong_scale(tmp_path):
    from lattice_cad.core.errors import StepUnitsError
    from lattice_cad.occ_impl import step as _occ

    path, box = _inch_box_step(tmp_path)
    _occ.check_step_units(path, ["INCH"], box.wrapped)  # the right size passes
    # what an OCP install that converts twice produced: 25.4 times too large
    with pytest.raises(
        StepUnitsError,
        match=r"inch\.step: declared unit INCH .* edges 25\.4 times as long as the file's own",
    ):
        _occ.check_step_units(path, ["INCH"], box.scale(25.4).wrapped)
    for wrong in (1 / 25.4, 10.0, 1000.0, 1e-3):
        with pytest.raises(StepUnitsError, match="inch.step"):
            _occ.check_step_units(path, ["INCH"], box.scale(wrong).wrapped)
    # OCCT naming another unit than the file declares is refused too
    with pytest.raises(StepUnitsError, match="declares its lengths in INCH, but OCCT reads"):
        _occ.check_step_units(path, ["millimetre"], box.wrapped)


@pytest.mark.parametrize("where", ["far", "sphere"])
def test_step_units_check_passes_parts_the_span_of_their_points_misjudged(tmp_path, where):
    """Regression: the size check compared the loaded shape with the span of the file's
    CARTESIAN_POINTs, which takes in placement origins (a filleted box at (8000, 2000,
    500) "spanned" 8290 mm against 61.6 mm loaded) and misses a sphere's extent (its points
    are its centre and a pole: 25 mm against 86.6 mm): both valid files were refused as
    loaded at the wrong scale. Edge lengths do not depend on either."""
    import cadquery as cq

    if where == "far":
        wp = cq.Workplane().box(50, 30, 20).edges().fillet(3).translate((8000, 2000, 500))
        size, volume = [50, 30, 20], None
    else:
        wp = cq.Workplane().sphere(25)
        size, volume = [50, 50, 50], 4 / 3 * np.pi * 25**3
    path = tmp_path / f"{where}.step"
    cq.exporters.export(wp, str(path))
    part = load_part(path)
    np.testing.assert_allclose(part.size, size, rtol=5e-3)  # (a tessellation's size)
    if volume is not None:
        np.testing.assert_allclose(part.volume, volume, rtol=1e-2)
    # and the writer, whose file is checked the same way, writes it back
    from lattice_cad.occ_impl import step as _occ

    out = tmp_path / f"{where}_again.step"
    _occ.write_step(wp.val().wrapped, out)
    assert load_part(out).size == pytest.approx(part.size, rel=1e-6)


def test_a_closed_shell_without_a_solid_loads_as_a_solid(tmp_path):
    """Regression: a STEP surface model (SHELL_BASED_SURFACE_MODEL holding a CLOSED_SHELL,
    what CadQuery writes for a shelled box) was refused as "no closed solid, only 1 open
    shell"; it is now made a solid, with a warning."""
    import cadquery as cq

    from lattice_cad.occ_impl import shapes as _occ

    solid = cq.Workplane().box(60, 40, 30).faces(">Z").shell(-2).val()
    shell = solid.Shells()[0]
    path = tmp_path / "shell.step"
    cq.exporters.export(cq.Workplane().add(shell), str(path))
    text = path.read_text(errors="ignore")
    assert "SHELL_BASED_SURFACE_MODEL" in text and "MANIFOLD_SOLID_BREP" not in text
    with pytest.warns(LatticeWarning, match=r"holds surfaces, not a solid: 11 face\(s\) were sewn"):
        part = load_part(path)
    assert part.volume == pytest.approx(60 * 40 * 30 - 56 * 36 * 28, rel=1e-4)
    assert len(_occ.solids(part.shape[0])) == 1


def test_a_surface_model_of_a_hollow_solid_keeps_its_cavity(tmp_path):
    """Regression: a closed hollow vessel (CadQuery's ``shell()`` with no face open) is
    written as a surface model of two closed shells, the cavity's facing inward; each was
    made a solid on its own and their union filled the cavity (69,344 mm^3 read for
    28,636; made outside shared/data). Nested as a solid's shells are, they make one solid
    with a void; two disjoint shells stay two solids."""
    import cadquery as cq

    from lattice_cad.occ_impl import shapes as _occ

    hollow = cq.Workplane().box(60, 40, 30).edges().fillet(5).shell(-3.4)
    path = tmp_path / "vessel.step"
    cq.exporters.export(hollow, str(path))
    text = path.read_text(errors="ignore")
    assert "SHELL_BASED_SURFACE_MODEL" in text and "MANIFOLD_SOLID_BREP" not in text
    with pytest.warns(
        LatticeWarning,
        match=r"sewn into 2 closed shell\(s\) and made 1 solid\(s\) \(1 of the shells facing in",
    ):
        part = load_part(path)
    exact = hollow.val().Volume()
    assert part.volume == pytest.approx(exact, rel=2e-3)
    assert len(part.shape) == 1 and _occ.shell_count(part.shape[0]) == 2
    assert _occ.is_valid(part.shape[0])
    assert bool(part.contains(np.array([[0.0, 0.0, 0.0]]))[0]) is False  # the cavity
    assert bool(part.contains(np.array([[0.0, 0.0, 13.3]]))[0])  # the wall
    # two boxes apart, written as surfaces: two solids, each facing out
    a = cq.Workplane().box(10, 10, 10).val()
    b = cq.Workplane().box(10, 10, 10).translate((20, 0, 0)).val()
    path2 = tmp_path / "two.step"
    cq.exporters.export(cq.Workplane().add(a.Shells()[0]).add(b.Shells()[0]), str(path2))
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        two = load_part(path2)
    assert two.volume == pytest.approx(2000.0, rel=1e-6) and len(two.shape) == 2


def test_open_faces_are_named(tmp_path):
    """A box missing its top face does not close even when sewn: the error names the faces
    with a free edge and where that edge is."""
    import cadquery as cq

    box = cq.Workplane().box(10, 10, 10).val()
    faces = [f for f in box.Faces() if f.Center().z < 4.9]  # all but the top
    path = tmp_path / "open.step"
    cq.exporters.export(cq.Workplane().add(cq.Shell.makeShell(faces)), str(path))
    with pytest.raises(PartError, match=r"only 5 open face\(s\).*face \d \(free edge \(.*, 5\) - "):
        load_part(path)


def test_every_step_part_in_shared_data_passes_the_units_check():
    from lattice_cad.occ_impl import step as _occ

    seen = 0
    for path in sorted((DATA / "step").glob("*")):
        if _occ.read_step(path) is not None:  # read_step runs check_step_units
            seen += 1
    assert seen == len(list((DATA / "step").glob("*")))


def test_nist_ctc02_loads_closed():
    """Regression: an AP242 file with its own stored triangulation and edge nodes that differ
    within the B-rep's tolerance was refused as "not closed" (3 open edges)."""
    part = load_part(DATA / "step" / "nist_ctc_02_asme1_ap242-1.stp")
    np.testing.assert_allclose(part.size, [680.0, 860.0, 400.0], atol=0.5)
    tm = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0


def test_every_valid_step_solid_in_shared_data_loads():
    """A STEP solid that BRepCheck accepts must load (healing and tolerant welding)."""
    from lattice_cad.occ_impl import shapes, step

    for path in sorted((DATA / "step").glob("*")):
        shape = step.read_step(path)
        if all(shapes.is_valid(s) for s in shapes.solids(shape)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", LatticeWarning)  # solids united
                load_part(path)


@pytest.mark.parametrize("max_distance", [0.5, 3.0, np.inf])
def test_closest_points_equal_trimesh_on_a_real_part(max_distance):
    """Part.closest (grid rings, triangles skipped by their boxes) against trimesh's
    closest points, on a real part and points from on the surface to far outside."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        part = load_part(DATA / "step" / "kcl_bracket.step")
    rng = np.random.default_rng(3)
    lo, hi = part.bounds
    pts = rng.uniform(lo - 5.0, hi + 5.0, size=(1500, 3))
    surf = part.vertices[rng.integers(0, len(part.vertices), 200)]  # on it
    pts = np.vstack([pts, surf, surf + rng.normal(scale=0.3, size=surf.shape)])
    d, c = part.closest(pts, max_distance=max_distance)
    _, ref, _ = trimesh.proximity.closest_point(
        trimesh.Trimesh(part.vertices, part.faces, process=False), pts
    )
    near = ref <= max_distance
    np.testing.assert_allclose(d[near], ref[near], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(c[near] - pts[near], axis=1), ref[near], atol=1e-9)
    assert np.all(np.isinf(d[ref > max_distance * (1 + 1e-9)]))


def test_3mf_part_is_read_as_built_in_its_unit(tmp_path):
    """Regression: a .3mf part went through trimesh, whose 3MF reader needs networkx (not a
    dependency): "cannot read the mesh: No module named 'networkx'". It is read with lib3mf
    as the file builds it: the build item's transform, components with theirs, the model's
    unit (here inches: a part 25.4 times too small otherwise)."""
    import lib3mf
    import trimesh

    from lattice_cad.io.exchange import _set_geometry

    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    model.SetUnit(lib3mf.ModelUnit.Inch)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))  # centred on the origin
    mesh = model.AddMeshObject()
    _set_geometry(lib3mf, mesh, box.vertices, box.faces)
    pair = model.AddComponentsObject()
    pair.AddComponent(mesh, wrapper.GetIdentityTransform())
    pair.AddComponent(mesh, wrapper.GetTranslationTransform(4.0, 0.0, 0.0))
    model.AddBuildItem(pair, wrapper.GetTranslationTransform(10.0, 20.0, 30.0))
    path = tmp_path / "pair.3mf"
    model.QueryWriter("3mf").WriteToFile(str(path))

    with pytest.warns(LatticeWarning, match="2 bodies"):
        part = load_part(path)
    inch = 25.4
    np.testing.assert_allclose(part.bounds[0], np.array([9.5, 19.0, 28.5]) * inch, rtol=1e-6)
    np.testing.assert_allclose(part.bounds[1], np.array([14.5, 21.0, 31.5]) * inch, rtol=1e-6)
    assert part.volume == pytest.approx(2 * 6.0 * inch**3, rel=1e-6)


def test_a_mesh_in_micrometres_gets_a_hint(tmp_path):
    """Regression (s33's micro gear made outside shared/data): a 5 mm part written in
    micrometres read as 5 m and was filled with 332 mm cells without a word; a mesh over
    ``config.LARGE_MESH_MM`` across now says so, and ``units='um'`` reads it right."""
    import trimesh

    tm = trimesh.creation.cylinder(radius=2.5, height=0.8, sections=48)
    tm.apply_scale(1000.0)  # micrometres
    path = tmp_path / "gear_in_um.stl"
    tm.export(path)
    with pytest.warns(LatticeWarning, match=r"5000 mm across.*micrometres \(5 mm across\)"):
        part = load_part(path)
    assert part.size.max() == pytest.approx(5000.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        part = load_part(path, units="um")
    assert part.size.max() == pytest.approx(5.0)


def test_3mf_mirrored_build_item_stays_outward(tmp_path):
    """Regression (s33's bed plate made outside shared/data): a slicer's mirror is a build
    transform with a negative determinant, which reverses the triangles' winding; the part
    loaded right, but with a warning that blamed the file ("1 of 4 bodies had flipped
    (inward-facing) triangles"). The mirrored object's triangles are reversed with it."""
    import lib3mf
    import trimesh

    from lattice_cad.io.exchange import _set_geometry

    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    box = trimesh.creation.box(extents=(10.0, 20.0, 5.0))
    box.apply_translation((5.0, 10.0, 2.5))  # in the positive octant
    mesh = model.AddMeshObject()
    _set_geometry(lib3mf, mesh, box.vertices, box.faces)
    mirror = wrapper.GetIdentityTransform()
    mirror.Fields[0][0] = -1.0  # x -> -x
    mirror.Fields[3][0] = 100.0  # then moved to x = 90 .. 100
    model.AddBuildItem(mesh, mirror)
    path = tmp_path / "mirrored.3mf"
    model.QueryWriter("3mf").WriteToFile(str(path))

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing flipped
        part = load_part(path)
    np.testing.assert_allclose(part.bounds, [[90.0, 0.0, 0.0], [100.0, 20.0, 5.0]], atol=1e-5)
    assert part.volume == pytest.approx(1000.0, rel=1e-6)
    assert part.contains(np.array([[95.0, 10.0, 2.5]])).all()


def test_a_closed_cavity_in_a_mesh_stays_a_cavity(tmp_path):
    """Regression (s24's parts made outside shared/data): a hollow box saved as one STL, its
    outer shell facing out and its closed inner shell facing in (a valid void), loaded as
    the full box: each shell was oriented on its own by the sign of its volume, so the
    cavity's wall was "flipped" outward (a warning said so) and the union filled it; every
    fill then lay in the cavity and none in the 1 mm walls. A shell facing inward inside an
    odd number of others is now a cavity."""
    from conformal import voxel_lattice

    outer = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    inner = trimesh.creation.box(extents=(38.0, 28.0, 18.0))
    inner.invert()  # the cavity's wall faces into the cavity
    path = tmp_path / "hollow_box.stl"
    trimesh.util.concatenate([outer, inner]).export(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing flipped, nothing united
        part = load_part(path)
    assert part.volume == pytest.approx(40 * 30 * 20 - 38 * 28 * 18)  # 4,848 mm^3
    assert not part.contains(np.array([[0.0, 0.0, 0.0], [15.0, 10.0, 5.0]])).any()
    assert part.contains(np.array([[19.5, 0.0, 0.0], [0.0, 0.0, -9.5]])).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        graph = voxel_lattice(part, "bcc", 2.66667, 0.222222, fill="conform")
    deep = np.all(np.abs(graph.nodes) < np.array([19.0, 14.0, 9.0]) - 0.5, axis=1)
    assert graph.num_edges > 1000 and not deep.any()  # the walls hold it, the void does not

    # a mirrored body (all faces inward, nothing around it) is still turned outward, and
    # two overlapping bodies still united
    flipped = trimesh.creation.box(extents=(10.0, 10.0, 10.0))
    flipped.invert()
    flipped.export(tmp_path / "mirrored.stl")
    with pytest.warns(LatticeWarning, match="re-oriented outward"):
        assert load_part(tmp_path / "mirrored.stl").volume == pytest.approx(1000.0)
    other = trimesh.creation.box(extents=(10.0, 10.0, 10.0))
    other.apply_translation((5.0, 0.0, 0.0))
    trimesh.util.concatenate([trimesh.creation.box(extents=(10.0, 10.0, 10.0)), other]).export(
        tmp_path / "overlap.stl"
    )
    with pytest.warns(LatticeWarning, match="2 bodies were united"):
        assert load_part(tmp_path / "overlap.stl").volume == pytest.approx(1500.0)


def _soup_obj(path, v, f, jitter, seed=0):
    """Write ``f`` as an OBJ triangle soup: each triangle its own three vertices, moved by
    up to ``jitter`` mm per coordinate (an exporter that rounds each triangle's own)."""
    rng = np.random.default_rng(seed)
    corners = v[f.ravel()] + rng.uniform(-jitter, jitter, size=(3 * len(f), 3))
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in corners.tolist()]
    lines += [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(len(f))]
    path.write_text("\n".join(lines) + "\n")


def test_a_triangle_soup_with_jittered_copies_loads_welded(tmp_path):
    """A soup whose copies of a vertex differ in the last digits was '3156 open edges
    around 1052 holes', and --close-holes made it 1052 sheets (s24's helper part)."""
    whole = load_part(DATA / "meshes" / "fandisk.obj")
    v, f = np.asarray(whole.vertices), np.asarray(whole.faces)
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    soup = tmp_path / "fandisk_soup.obj"
    _soup_obj(soup, v, f, jitter=1e-8 * diag)
    with pytest.warns(
        LatticeWarning,
        match=r"end point\(s\) of open edges lay within .* mm of "
        r"another and were welded \(\d+ open edge\(s\) before, no after\)",
    ):
        part = load_part(soup)
    assert len(part.faces) == len(f) and len(part.vertices) == len(v)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(whole.volume, rel=1e-6)
    # copies farther apart than the weld goes stay holes: refused, saying how far apart
    # they are, and not advising --close-holes (it would make each triangle a sheet)
    _soup_obj(soup, v, f, jitter=1e-3 * diag)
    with pytest.raises(PartError, match=r"the mesh is not a closed solid: \d+ open") as info:
        load_part(soup)
    said = str(info.value)
    assert "a triangle soup whose copies of a vertex lie" in said and "close_holes" not in said
    assert "hole(s)" not in said  # not "12908 holes" for 12,946 triangles (s26)


def test_welding_moves_only_the_end_points_of_open_edges(tmp_path):
    """A closed cube with an open one (no bottom) standing on it, 1e-8 of the size above:
    the open cube's rim is closer to the closed cube's top corners than any weld step, but
    only open edges' end points are welded (among themselves), so it stays one hole."""
    cube = trimesh.creation.box((10, 10, 10))
    v, f = np.asarray(cube.vertices), np.asarray(cube.faces)
    bottom = np.all(v[f][:, :, 2] < 0, axis=1)
    v2 = np.vstack([v, v + [0, 0, 10 + 1e-7]])
    f2 = np.vstack([f, f[~bottom] + len(v)])
    path = tmp_path / "open_cube_on_a_cube.obj"
    trimesh.Trimesh(v2, f2, process=False).export(path)
    with pytest.raises(PartError, match=r"4 open \(boundary\) edge\(s\) around 1 hole"):
        load_part(path)


def test_the_depth_of_bodies_stacked_face_to_face_is_finite(tmp_path):
    """Regression (s30, a helper's part: two boxes stacked face to face, triangulated
    differently, so the shared face stays as two sheets inside the solid):
    ``inscribed_radius`` was inf. The grid's depth passes through the inner sheets, so its
    deepest points lay at them; the climb's move straight off that plane landed at exactly
    the bound of its distance query, read as "farther" (inf), and taken. Now the climb
    never takes an unmeasured point, and starts from points spread over the part too."""
    a = trimesh.creation.box((40, 40, 15))
    b = a.copy().subdivide()  # the same face, other triangles
    b.apply_translation((0, 0, 15))
    both = trimesh.util.concatenate([a, b])
    both.merge_vertices()  # (the corners of the shared face)
    # a file loads as 2 bodies united (since s39: bodies are edge-connected), without the
    # sheets; the part with them, as a file gave it before
    path = tmp_path / "stacked.stl"
    both.export(path)
    with pytest.warns(LatticeWarning, match="^[^:]*: 2 bodies were united into one part$"):
        united = load_part(path)
    assert united.volume == pytest.approx(40 * 40 * 30) and len(united.solid_parts) == 1
    assert united.inscribed_radius() == pytest.approx(15.0, abs=0.1)
    part = Part(np.asarray(both.vertices), np.asarray(both.faces), name="stacked")
    # the two sheets touch without crossing: no "crosses itself" warning since s32 (the
    # suite turns any warning into an error)
    assert part.self_crossings[0] == 0
    point, depth = part.deepest_point()
    # each box is 15 mm thick and its face to the other is a sheet of the surface
    assert 7.4 < depth <= 7.5
    assert part.inscribed_radius() == depth
    assert part.distance(point[None])[0] == pytest.approx(depth) and part.contains(point[None])[0]
