"""Tests of reference_boolean.compare, the reports and lattice_cad.validate."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest

import fast_stitch
from lattice_cad import LatticeGraph
from reference_boolean import build_reference, compare, union_mesh
from tests.conftest import star_graph


@pytest.fixture(scope="module")
def star():
    return star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1]], lengths=1.0, radii=0.1)


@pytest.fixture(scope="module")
def star_ref(star):
    return build_reference(star)


def test_union_converges_like_n_squared(star, star_ref):
    rep = compare(star, reference=star_ref, union_segments=(16, 32, 64, 128))
    vref = star_ref.volume
    err = {n: abs(v - vref) / vref for n, v in rep.volume_union.items()}
    assert err[128] < 1e-3
    assert err[16] > err[32] > err[64] > err[128]
    assert rep.convergence_order == pytest.approx(2.0, abs=0.3)
    assert all(rep.union_valid.values())
    d = rep.to_dict()
    for key in (
        "volume_reference",
        "volume_union",
        "volume_mesh",
        "relative_volume_error",
        "hausdorff",
        "valid",
        "triangles",
        "timings",
    ):
        assert key in d
    assert d["volume_mesh"] is None


def test_mesh_deviation_and_reports(star, star_ref, tmp_path):
    mesh = fast_stitch.stitch(star, 8, profile="inscribed")
    rep = compare(
        star,
        mesh=mesh,
        reference=star_ref,
        union_segments=(16, 32),
        samples=3000,
        label="fast_stitch P=8",
    )
    d = rep.to_dict()
    h = d["hausdorff"]
    for k in ("mesh_to_reference", "reference_to_mesh", "symmetric"):
        assert 0 <= h[k]["mean"] <= h[k]["p95"] <= h[k]["max"]
    # a P=8 polygon inscribed in r=0.1 misses the circle by r (1 - cos(pi/8)) = 0.0076,
    # and the leaves have flat caps where the reference has spheres (up to r)
    assert 0.005 < h["reference_to_mesh"]["max"] < 0.2
    assert d["valid"]["mesh"]["valid"] and d["valid"]["reference"]["valid"]
    assert d["relative_volume_error"]["mesh"] < 0
    assert d["triangles"]["mesh"] == len(mesh.faces)
    assert len(d["worst_nodes"]) == 5  # every node with struts
    json.loads((rep.save(tmp_path / "r.json")).read_text(encoding="utf-8"))
    md = rep.save(tmp_path / "r.md").read_text(encoding="utf-8")
    assert "| segments |" in md and "fast_stitch P=8" in md
    page = rep.save(tmp_path / "r.html").read_text(encoding="utf-8")
    pngs = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page)
    from reference_boolean.report import first_screen

    places = first_screen(rep).places
    # the star's worst place is a leaf (flat cap vs sphere); its centre and the other
    # leaves are its neighbours or distinct places: at least one, at most 4 close-ups
    assert 1 <= len(places) <= 4
    assert len(pngs) == 3 + len(places)  # overview, close-ups, convergence, histogram
    assert all(base64.b64decode(p)[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    with pytest.raises(ValueError, match="use .json"):
        rep.save(tmp_path / "r.txt")


def test_exact_mesh_has_no_deviation(star, star_ref):
    rep = compare(star, mesh=star_ref.mesh, reference=star_ref, union_segments=(), samples=2000)
    assert rep.hausdorff["symmetric"]["max"] < 1e-9
    assert rep.volume_union == {}


def test_union_mesh_single_strut():
    g = LatticeGraph([[0, 0, 0], [0.3, 1.0, -0.2]], [[0, 1]], 0.1)
    m = union_mesh(g, 64)
    ref = build_reference(g)
    assert abs(m.volume - ref.volume) / ref.volume < 5e-3
    with pytest.raises(ValueError):
        union_mesh(g, 2)


def test_validate_one_call(tmp_path):
    from lattice_cad.validate import validate

    g = star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1]], lengths=1.0, radii=0.1)
    out = tmp_path / "report.md"
    rep = validate(g, 6, out, union_segments=(16, 32), samples=2000)
    assert out.exists() and out.stat().st_size > 500
    # the default (volume) and the inscribed meshes side by side; the single-mesh
    # attributes are the default one's
    vp, plain = "fast_stitch P=6", "fast_stitch P=6 inscribed"
    assert list(rep.comparisons) == [vp, plain]
    assert rep.label == vp
    assert rep.volume_mesh == rep.comparisons[vp].volume
    assert rep.reference.complete
    vref = rep.reference.volume
    # the default mesh has the exact volume (up to the leaf ends' design, balls in the
    # reference, flat in the mesh); the inscribed one is far lighter
    assert abs(rep.comparisons[vp].volume - vref) < abs(rep.comparisons[plain].volume - vref)
    d = rep.to_dict()
    assert set(d["volume_mesh"]) == {plain, vp}
    assert d["relative_volume_error"]["mesh"][vp] == pytest.approx(
        (rep.comparisons[vp].volume - vref) / vref
    )
    assert set(d["hausdorff"][vp]["symmetric"]) == {"max", "mean", "p95"}
    assert [m["label"] for m in d["meshes"]] == [vp, plain]
    md = out.read_text(encoding="utf-8")
    rows = [ln for ln in md.splitlines() if ln.startswith("| fast_stitch P=6")]
    assert len(rows) == 2  # one comparison row per mesh
    only_vp = validate(g, 6, None, profiles=("volume",), union_segments=(), samples=2000)
    assert list(only_vp.comparisons) == [vp]
    assert isinstance(only_vp.to_dict()["volume_mesh"], float)
    assert only_vp.volume_mesh == pytest.approx(rep.comparisons[vp].volume)
    with pytest.warns(DeprecationWarning, match="volume_preserving"):
        old = validate(g, 6, None, volume_preserving=True, union_segments=(), samples=2000)
    assert list(old.comparisons) == ["fast_stitch P=6 area"]
    with pytest.raises(ValueError, match="volume_preserving"):
        validate(g, 6, None, volume_preserving="sometimes", union_segments=())
    with pytest.raises(ValueError, match="profiles"):
        validate(g, 6, None, profiles=("exact",), union_segments=())


def test_compare_several_meshes(star, star_ref, tmp_path):
    m6 = fast_stitch.stitch(star, 6, profile="inscribed")
    m12 = fast_stitch.stitch(star, 12, profile="inscribed")
    rep = compare(
        star,
        mesh=m6,
        label="P=6",
        meshes={"P=12": m12, "exact": star_ref.mesh},
        reference=star_ref,
        union_segments=(),
        samples=1500,
    )
    assert list(rep.comparisons) == ["P=6", "P=12", "exact"]
    c = rep.comparisons
    # same reference, same samples: finer polygons deviate less, the reference's own mesh not at all
    assert c["exact"].hausdorff["symmetric"]["max"] < 1e-9
    assert c["P=12"].hausdorff["symmetric"]["mean"] < c["P=6"].hausdorff["symmetric"]["mean"]
    assert abs(c["P=12"].relative_volume_error) < abs(c["P=6"].relative_volume_error)
    assert rep.volume_mesh == c["P=6"].volume and rep.hausdorff is c["P=6"].hausdorff
    d = json.loads(rep.save(tmp_path / "r.json").read_text(encoding="utf-8"))
    assert set(d["volume_mesh"]) == {"P=6", "P=12", "exact"}
    assert d["triangles"]["mesh"]["P=12"] == len(m12.faces)
    assert d["valid"]["mesh"]["exact"]["valid"]
    page = rep.save(tmp_path / "r.html").read_text(encoding="utf-8")
    assert page.count("<td>P=12</td>") == 1 and "Mesh under test: exact" in page
    from reference_boolean.report import first_screen

    closeups = len(first_screen(rep).places)
    # overview, close-ups, histogram; no unions: no convergence plot
    assert len(re.findall(r"data:image/png;base64,", page)) == 2 + closeups
    # meshes= alone, and label clashes
    only = compare(star, meshes={"a": m6}, reference=star_ref, union_segments=(), samples=500)
    assert only.label == "a" and isinstance(only.to_dict()["volume_mesh"], float)
    with pytest.raises(ValueError, match="twice"):
        compare(star, mesh=m6, label="a", meshes={"a": m12}, reference=star_ref)


def test_reference_for_other_graph_rejected(star_ref):
    g = LatticeGraph([[0, 0, 0], [1, 0, 0]], [[0, 1]], 0.1)
    with pytest.raises(ValueError, match="another graph"):
        compare(g, reference=star_ref)
    assert np.isnan(
        compare(star_ref.graph, reference=star_ref, union_segments=()).node_deviation
    ).all()


def test_surface_deviation_is_the_exact_distance_to_a_box_in_bounded_memory(monkeypatch):
    """Closed form: the distance from a point to the surface of an axis-aligned box, for
    points spread inside and outside; queried in small chunks (the bounded-memory path)."""
    import trimesh

    from lattice_cad.core import config
    from lattice_cad.core.mesh import Mesh
    from reference_boolean.compare import surface_deviation

    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    target = Mesh(vertices=np.asarray(box.vertices), faces=np.asarray(box.faces, dtype=np.int64))
    blob = trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    source = Mesh(vertices=np.asarray(blob.vertices), faces=np.asarray(blob.faces, dtype=np.int64))
    monkeypatch.setattr(config, "DEVIATION_CHUNK", 997)
    pts, d = surface_deviation(source, target, samples=5000, seed=3)
    h = np.array([1.0, 1.5, 2.0])
    q = np.abs(pts) - h
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = -np.minimum(q.max(axis=1), 0.0)
    expected = np.where(q.max(axis=1) > 0, outside, inside)
    assert len(pts) == 5000 + len(source.vertices)
    np.testing.assert_allclose(d, expected, atol=1e-9)


def test_mesh_validity_agrees_with_trimesh_on_valid_inverted_open_and_flipped_meshes():
    """mesh_validity reads a valid mesh from manifold3d alone (trimesh only for refused
    ones); on each kind of mesh its answers must be trimesh's."""
    import trimesh

    from lattice_cad.core.mesh import Mesh
    from reference_boolean.compare import mesh_validity

    s = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    flipped_one = f.copy()
    flipped_one[0] = flipped_one[0, ::-1]
    cases = {
        "valid": f,
        "inverted": f[:, ::-1],
        "open": f[1:],
        "one flipped": flipped_one,
    }
    expect_valid = {"valid": True, "inverted": False, "open": False, "one flipped": False}
    for name, faces in cases.items():
        got = mesh_validity(Mesh(vertices=v, faces=faces))
        tm = trimesh.Trimesh(vertices=v, faces=faces, process=False)
        assert got["watertight"] == tm.is_watertight, name
        assert got["winding_consistent"] == tm.is_winding_consistent, name
        assert got["outward"] == (tm.volume > 0), name
        assert got["valid"] == expect_valid[name], (name, got)


def test_two_sided_deviation_in_two_processes_gives_the_serial_numbers(monkeypatch, star, star_ref):
    """The report measures the two sides in two processes on big meshes (libigl holds the
    GIL); forced on a small one, the numbers must be the serial ones, bit for bit."""
    from lattice_cad.core import config
    from reference_boolean.compare import surface_deviation, two_sided_deviation

    mesh = fast_stitch.stitch(star, segments=6)
    ref = star_ref.mesh
    serial = (
        surface_deviation(mesh, ref, samples=3000, seed=5),
        surface_deviation(ref, mesh, samples=3000, seed=6),
    )
    monkeypatch.setattr(config, "DEVIATION_PARALLEL_MIN", 0)
    forked = two_sided_deviation(mesh, ref, samples=3000, seed=5)
    for (p, d), (q, e) in zip(serial, forked, strict=True):
        np.testing.assert_array_equal(p, q)
        np.testing.assert_array_equal(d, e)


@pytest.mark.slow  # the GE bracket lattice and its reference (~15 s)
def test_meshes_of_one_report_share_the_reference_side_with_the_same_numbers(monkeypatch):
    """The report compares two meshes with one reference: the reference's tree, its sample
    points, their hub-zone mask and nearest nodes are computed once for both (the GE tet
    report's deviation stage measured them twice). Each mesh must get, bit for bit, the
    numbers of a comparison of it alone - here on a real part, with the two sides forced
    into two processes as on the big GE lattices."""
    import warnings

    from conformal.part import load_part
    from conformal.voxel import voxel_lattice
    from lattice_cad.core import config
    from lattice_cad.core.errors import LatticeWarning
    from tests.conftest import DATA

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        part = load_part(DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step")
        g = voxel_lattice(part, "bcc", 16.0, 0.6, fill="inside")
    ref = build_reference(g, keep_solids=False)
    meshes = {
        "volume": fast_stitch.stitch(g, 6),
        "inscribed": fast_stitch.stitch(g, 6, profile="inscribed"),
    }
    alone = {
        lab: compare(g, reference=ref, meshes={lab: m}, union_segments=(), samples=5000)
        for lab, m in meshes.items()
    }
    monkeypatch.setattr(config, "DEVIATION_PARALLEL_MIN", 0)
    both = compare(g, reference=ref, meshes=meshes, union_segments=(), samples=5000)
    assert list(both.comparisons) == list(meshes)
    for lab in meshes:
        a, b = alone[lab].comparisons[lab], both.comparisons[lab]
        assert a.hausdorff == b.hausdorff
        assert a.regions == b.regions
        for side in ("mesh_to_reference", "reference_to_mesh"):
            np.testing.assert_array_equal(a.distances[side], b.distances[side])
        np.testing.assert_array_equal(a.node_deviation, b.node_deviation)
        np.testing.assert_array_equal(a.node_worst_point, b.node_worst_point)
        np.testing.assert_array_equal(a.node_worst_side, b.node_worst_side)
    # the reference's validity was checked while the child measured (cached for the report)
    from reference_boolean.compare import _REFERENCE_VALIDITY

    assert both.timings["reference_validity"] >= 0.0 and ref in _REFERENCE_VALIDITY
    # and the two meshes do differ (the test would be empty otherwise)
    assert both.comparisons["volume"].hausdorff != both.comparisons["inscribed"].hausdorff
