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
    mesh = fast_stitch.stitch(star, 8)
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
    json.loads((rep.save(tmp_path / "r.json")).read_text())
    md = rep.save(tmp_path / "r.md").read_text()
    assert "| segments |" in md and "fast_stitch P=8" in md
    page = rep.save(tmp_path / "r.html").read_text()
    pngs = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page)
    assert len(pngs) == 3
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
    out = tmp_path / "report.html"
    rep = validate(g, 6, out, union_segments=(16, 32), samples=2000)
    assert out.exists() and out.stat().st_size > 1000
    assert rep.label == "fast_stitch P=6"
    assert rep.reference.complete
    vp = validate(g, 6, None, volume_preserving=True, union_segments=(), samples=2000)
    # the area-preserving polygons bring the volume closer to the reference
    assert abs(vp.volume_mesh - vp.reference.volume) < abs(rep.volume_mesh - rep.reference.volume)


def test_reference_for_other_graph_rejected(star_ref):
    g = LatticeGraph([[0, 0, 0], [1, 0, 0]], [[0, 1]], 0.1)
    with pytest.raises(ValueError, match="another graph"):
        compare(g, reference=star_ref)
    assert np.isnan(
        compare(star_ref.graph, reference=star_ref, union_segments=()).node_deviation
    ).all()
