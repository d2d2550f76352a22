"""Tests of reference_boolean.build_reference (exact per-hub B-rep reference)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conformal.cells import block
from lattice_cad import LatticeError, LatticeGraph
from lattice_cad.core import config
from reference_boolean import (
    DirtyLatticeError,
    ReferenceBuildError,
    build_reference,
    find_overlaps,
)
from tests.conftest import star_graph


def sphere_outside_cylinder(r: float) -> float:
    """Exact volume of the sphere R = 1.00001 r outside a cylinder of radius r through it."""
    R = config.SPHERE_FACTOR * r
    a = math.sqrt(R * R - r * r)  # where the sphere crosses the cylinder
    inside = 2 * (math.pi * r * r * a + math.pi * (R * R * (R - a) - (R**3 - a**3) / 3))
    return 4 / 3 * math.pi * R**3 - inside


def check_watertight(mesh) -> None:
    import manifold3d
    import trimesh

    tm = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
    assert tm.is_watertight
    assert tm.is_winding_consistent
    assert tm.volume > 0
    man = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=mesh.vertices.astype(np.float32),
            tri_verts=mesh.faces.astype(np.uint32),
        )
    )
    assert man.status() == manifold3d.Error.NoError


@pytest.mark.parametrize("r,length", [(0.25, 2.0), (0.05, 1.0)])
def test_single_strut_exact_volume(r, length):
    g = LatticeGraph([[0, 0, 0], [length, 0.3, -0.2]], [[0, 1]], r)
    L = float(g.edge_lengths[0])
    ref = build_reference(g, workers=1)
    assert ref.complete and not ref.failed
    # both ends are leaves: flat, as in the fast mesh -> exactly a cylinder
    assert ref.volume == pytest.approx(math.pi * r * r * L, rel=1e-9)
    check_watertight(ref.mesh)
    # the tessellation is inscribed: slightly smaller, within the chordal tolerance
    assert 0.98 * ref.volume < ref.mesh.volume < ref.volume
    # both hubs are translates (one reversed) -> the line's two ends are distinct hubs
    assert ref.unique_hubs == 2


@pytest.mark.parametrize("angle_deg", [30, 60, 90, 120, 150, 180])
def test_two_strut_joints(angle_deg):
    t = math.radians(angle_deg)
    g = star_graph([[1, 0, 0], [math.cos(t), math.sin(t), 0.0]], lengths=1.0, radii=0.08)
    ref = build_reference(g, workers=1)
    assert ref.complete, ref.failed
    check_watertight(ref.mesh)
    hv = ref.hub_volume
    assert np.isfinite(hv).all()
    assert ref.volume == pytest.approx(hv.sum(), rel=1e-12)
    # the centre hub is at most sphere + both stumps, at least one stump + the sphere
    r, R = 0.08, config.SPHERE_FACTOR * 0.08
    stump = math.pi * r * r * 0.5
    assert 4 / 3 * math.pi * R**3 < hv[0] < 4 / 3 * math.pi * R**3 + 2 * stump
    if angle_deg == 180:  # straight: sphere + cylinder through it, in closed form
        a = math.sqrt(R * R - r * r)
        inside = 2 * (math.pi * r * r * a + math.pi * (R * R * (R - a) - (R**3 - a**3) / 3))
        exact = 4 / 3 * math.pi * R**3 + 2 * stump - inside
        assert hv[0] == pytest.approx(exact, rel=1e-8)


def test_star_and_tapered():
    dirs = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1], [1, -1, 0.3]]
    radii = np.array([[0.1, 0.06], [0.08, 0.08], [0.12, 0.05], [0.07, 0.09], [0.1, 0.1]])
    g = star_graph(dirs, lengths=[1.0, 1.2, 0.9, 1.1, 1.0], radii=radii)
    ref = build_reference(g, workers=2)
    assert ref.complete, ref.failed
    check_watertight(ref.mesh)
    assert 0.97 * ref.volume < ref.mesh.volume < ref.volume


def test_tapered_strut_volume():
    # two tapered struts in line through a hub (sphere R_b); the leaves end flat
    ra, rb, L = 0.1, 0.2, 2.0
    g = LatticeGraph([[0, 0, 0], [0, 0, L], [0, 0, 2 * L]], [[0, 1], [1, 2]], [[ra, rb], [rb, ra]])
    ref = build_reference(g, workers=1)
    assert ref.complete
    check_watertight(ref.mesh)
    # volume of the union of the sphere and the two frustums, by numerical integration
    Rb = config.SPHERE_FACTOR * rb
    z = np.linspace(0.0, 2 * L, 800_001)
    rc = ra + (rb - ra) * (1.0 - np.abs(z - L) / L)
    rsb = np.sqrt(np.clip(Rb**2 - (z - L) ** 2, 0, None))
    rr = np.maximum(rc, rsb)
    y = np.pi * rr**2
    vol = float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(z)))
    assert ref.volume == pytest.approx(vol, rel=1e-6)


def test_bcc_block_cache_and_sum():
    g = block("bcc", (2, 2, 2), cell_size=2.0, radius=0.2)
    ref = build_reference(g, reuse="translation")  # turned copies get split triangles
    assert ref.complete, ref.failed
    check_watertight(ref.mesh)
    assert ref.unique_hubs + ref.cache_hits == int((g.degree > 0).sum())
    assert ref.cache_hits > 0
    nocache = build_reference(g, cache=False, keep_solids=False)
    assert nocache.cache_hits == 0
    assert nocache.volume == pytest.approx(ref.volume, rel=1e-9)
    # cached hubs are identical: same volume, same triangle count per node
    per_node = np.bincount(ref.face_node, minlength=g.num_nodes)
    tpl = ref.node_template
    for t in np.unique(tpl[tpl >= 0]):
        ns = np.flatnonzero(tpl == t)
        assert len(set(per_node[ns].tolist())) == 1
        assert len(set(ref.hub_volume[ns].tolist())) == 1


def test_stl_and_step_round_trip(tmp_path):
    import trimesh

    g = star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1]], lengths=1.0, radii=0.1)
    ref = build_reference(g)
    p = ref.save(tmp_path / "ref.stl")
    tm = trimesh.load(p)
    assert len(tm.faces) == len(ref.mesh.faces)
    s = ref.save(tmp_path / "ref.step")
    from lattice_cad.occ_impl.step import read_step_solids

    solids = read_step_solids(str(s))
    assert len(solids) == 1  # the four hubs sewn into one solid
    assert all(valid for valid, _ in solids)
    assert sum(v for _, v in solids) == pytest.approx(ref.volume, rel=1e-7)
    with pytest.raises(ValueError, match=r"cannot save a reference as \.txt \(ref\.txt\)"):
        ref.save(tmp_path / "ref.txt")


def test_overlapping_hubs_become_one_cluster():
    # a strut too short for the sphere of node 1: hub 1 and leaf 2 are one fused cluster
    g = LatticeGraph([[0, 0, 0], [1, 0, 0], [1.4, 0, 0]], [[0, 1], [1, 2]], [0.3, 0.05])
    probs = find_overlaps(g)
    assert probs and any("strut 1" in p for p in probs)  # the former per-hub check
    ref = build_reference(g, workers=0)
    assert ref.complete, ref.failed
    assert [c.tolist() for c in ref.clusters] == [[1, 2]]
    check_watertight(ref.mesh)
    # all primitives are coaxial: the volume is the integral of the largest section
    R = config.SPHERE_FACTOR * 0.3
    x = np.linspace(0.0, 1.4, 1_400_001)
    rr = np.maximum(
        np.where(x <= 1.0, 0.3, 0.05), np.sqrt(np.clip(R * R - (x - 1.0) ** 2, 0.0, None))
    )
    y = np.pi * rr**2
    assert ref.volume == pytest.approx(float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x))), rel=1e-7)
    # two struts at a small angle: a stump reaches the other strut's cut plane
    g = star_graph([[1, 0, 0], [1, 0.05, 0]], lengths=[1.0, 0.5], radii=0.05)
    assert find_overlaps(g)
    assert issubclass(DirtyLatticeError, LatticeError)
    assert issubclass(ReferenceBuildError, RuntimeError)


def test_forced_occt_failure_is_reported(monkeypatch):
    from lattice_cad.occ_impl import truss as _occ

    real = _occ.make_hub_shape
    calls = []

    def broken(spec, **kw):
        calls.append(kw)
        if len(spec.vecs) == 3:  # only the centre hub of the star
            raise _occ.OCCTFailure("forced failure for the test")
        return real(spec, **kw)

    monkeypatch.setattr(_occ, "make_hub_shape", broken)
    monkeypatch.setattr(_occ, "DIRECT", False)  # the boolean chain's retries, not hub_direct
    g = star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1]], lengths=1.0, radii=0.1)
    ref = build_reference(g, workers=0)
    assert not ref.complete
    assert list(ref.failed) == [0]
    assert "forced failure" in ref.failed[0]
    assert len(ref.attempts[0]) == len(_occ.ATTEMPTS)  # every retry was tried
    assert math.isnan(ref.hub_volume[0])
    assert "INCOMPLETE" in repr(ref)
    # the leaves were built; their open circles are not hidden: the mesh is not watertight
    assert np.isfinite(ref.hub_volume[1:]).all()
    assert ref.volume == pytest.approx(np.nansum(ref.hub_volume))
    import trimesh

    tm = trimesh.Trimesh(vertices=ref.mesh.vertices, faces=ref.mesh.faces, process=False)
    assert not tm.is_watertight


def test_invalid_shape_is_caught(monkeypatch):
    from lattice_cad.occ_impl import truss as _occ

    def invalid(spec, **kw):
        from OCP.TopoDS import TopoDS_Shape

        from lattice_cad.occ_impl.shapes import check_valid

        check_valid(TopoDS_Shape(), "hub")  # a null shape never passes
        raise AssertionError("unreachable")

    from lattice_cad.occ_impl import cluster as _cl

    monkeypatch.setattr(_occ, "make_hub_shape", invalid)
    monkeypatch.setattr(_cl, "make_cluster_shape", invalid)  # leaves are built as clusters
    g = LatticeGraph([[0, 0, 0], [1, 0, 0]], [[0, 1]], 0.1)
    ref = build_reference(g)  # in worker processes (fork keeps the patch)
    assert sorted(ref.failed) == [0, 1]
    assert all("null shape" in v for v in ref.failed.values())
    assert len(ref.mesh.faces) == 0


def test_bad_options():
    g = LatticeGraph([[0, 0, 0], [1, 0, 0]], [[0, 1]], 0.1)
    with pytest.raises(ValueError, match="tolerance"):
        build_reference(g, tolerance=-1.0)
    with pytest.raises(TypeError):
        build_reference("not a graph")  # type: ignore[arg-type]
    with pytest.raises(ReferenceBuildError, match="no struts"):
        build_reference(LatticeGraph(np.zeros((0, 3)), np.zeros((0, 2)), 0.1))


def test_trimmed_stumps_give_the_same_hub():
    """Stumps that start inside the sphere (the fast default) leave the hub unchanged."""
    from lattice_cad.occ_impl import truss as _occ
    from lattice_cad.occ_impl.shapes import volume
    from reference_boolean.reference import _hub_specs

    # thin struts beside a thick one: the thin stumps are trimmed, the thick one is not
    g = star_graph(
        [[1, 0, 0], [0, 1, 0.1], [0, 0.1, 1], [-1, -0.2, 0]],
        lengths=1.0,
        radii=[[0.1, 0.1], [0.06, 0.05], [0.07, 0.07], [0.05, 0.06]],
    )
    specs, *_ = _hub_specs(g, True)
    spec = max(specs, key=lambda s: len(s.vecs))
    starts = [
        _occ.stump_start(spec.radius, a, b, float(np.linalg.norm(v)))
        for v, a, b in zip(spec.vecs, spec.r_node, spec.r_mid, strict=True)
    ]
    assert sum(h > 0 for h in starts) == 3 and starts[int(np.argmax(spec.r_node))] == 0.0
    for h, a, b in zip(starts, spec.r_node, spec.r_mid, strict=True):
        assert h**2 + max(a, b) ** 2 < spec.radius**2  # the dropped part is inside the sphere
    vols = [volume(_occ.make_hub_shape(spec, trim=t), eps=1e-10) for t in (True, False)]
    assert vols[0] == pytest.approx(vols[1], rel=1e-8)
    res = _occ.build_hub(spec, deflection=1e-3, angular=0.25, keep_brep=False)
    assert res.status == "ok" and res.attempts == ["tree: ok"]
    assert res.volume == pytest.approx(vols[1], rel=1e-8)
