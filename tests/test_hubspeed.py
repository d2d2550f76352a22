"""Issue 14, item 2 (a fast report): the hub's general fuse, the sampled convergence
study, the up-front estimate with its progress bar, Ctrl-C."""

from __future__ import annotations

import math
import multiprocessing as mp

import numpy as np
import pytest

from conformal.cells import block
from lattice_cad import LatticeGraph
from lattice_cad.cli import build_parser
from lattice_cad.core import config
from reference_boolean import build_reference, compare
from reference_boolean.compare import hub_union
from reference_boolean.reference import _hub_specs, _run
from tests.conftest import star_graph


def half_capped_cylinder(r: float, half: float) -> float:
    """Exact volume of one hub of a straight strut: sphere R = 1.00001 r, stump to ``half``."""
    R = config.SPHERE_FACTOR * r
    a = math.sqrt(R * R - r * r)
    inside = math.pi * r * r * a + math.pi * (R * R * (R - a) - (R**3 - a**3) / 3)
    return 4 / 3 * math.pi * R**3 + math.pi * r * r * half - inside


@pytest.fixture(scope="module")
def bcc():
    g = block("bcc", (2, 2, 1), cell_size=1.0, radius=0.08)
    return g, build_reference(g, keep_solids=False)


def test_general_fuse_matches_closed_form_and_the_plain_fuse():
    from lattice_cad.occ_impl import truss
    from lattice_cad.occ_impl.shapes import check_valid, fuse, volume

    # one stump: closed form
    g = LatticeGraph([[0, 0, 0], [2.0, 0.3, -0.2]], [[0, 1]], 0.25)
    specs, _, _, _ = _hub_specs(g, True)
    half = 0.5 * float(g.edge_lengths[0])
    sh = truss.general_fuse(truss.make_primitives(specs[0]))
    check_valid(sh, "hub")
    assert volume(sh, eps=1e-10) == pytest.approx(half_capped_cylinder(0.25, half), rel=1e-8)
    # a degree-6 jittered hub: the same solid as the plain BRepAlgoAPI_Fuse (independent path)
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(6, 3))
    g6 = star_graph(dirs, lengths=1.0, radii=0.08)
    spec = max(_hub_specs(g6, True)[0], key=lambda s: len(s.vecs))
    assert len(spec.vecs) == 6
    a = truss.general_fuse(truss.make_primitives(spec))
    b = fuse(*(lambda p: (p[:1], p[1:]))(truss.make_primitives(spec)), parallel=False)
    check_valid(a, "hub")
    assert volume(a, eps=1e-10) == pytest.approx(volume(b, eps=1e-10), rel=1e-9)


def test_hub_union_of_one_hub_converges_to_the_closed_form():
    # a leaf ends flat (as the reference models it): the half strut is a plain cylinder
    g = LatticeGraph([[0, 0, 0], [2.0, 0.3, -0.2]], [[0, 1]], 0.25)
    exact = math.pi * 0.25**2 * 0.5 * float(g.edge_lengths[0])
    errs = [abs(hub_union(g, np.array([0]), n)[0] - exact) / exact for n in (16, 64, 256)]
    assert errs[0] > errs[1] > errs[2] and errs[2] < 2e-4
    with pytest.raises(ValueError, match="segments"):
        hub_union(g, np.array([0]), 2)


def test_sampled_union_study_converges_to_the_sampled_hubs(bcc):
    g, ref = bcc
    rep = compare(g, reference=ref, union_segments=(16, 32, 64), union_hubs=5)
    assert rep.union_scope.startswith("5 of ")
    vu = rep.union_reference_volume
    assert vu is not None and 0 < vu < ref.volume
    err = {n: abs(v - vu) / vu for n, v in rep.volume_union.items()}
    assert err[16] > err[32] > err[64]
    assert rep.convergence_order == pytest.approx(2.0, abs=0.3)
    assert all(rep.union_valid.values())
    d = rep.to_dict()
    assert d["volume_union_reference"] == vu and d["union_scope"] == rep.union_scope
    rel64 = (rep.volume_union[64] - vu) / vu
    assert d["relative_volume_error"]["union"][64] == pytest.approx(rel64)
    # the full study is still there and is measured against the whole reference
    full = compare(g, reference=ref, union_segments=(16,), union_hubs=None)
    assert full.union_scope == "lattice" and full.union_reference_volume is None
    assert full.to_dict()["volume_union_reference"] == ref.volume
    with pytest.raises(ValueError, match="union_hubs"):
        compare(g, reference=ref, union_segments=(16,), union_hubs=0)


def test_progress_true_prints_an_estimate_first_and_builds_the_same(bcc, capsys):
    g, ref = bcc
    capsys.readouterr()
    again = build_reference(g, keep_solids=False, progress=True)
    err = capsys.readouterr().err
    first = err.index("distinct to build")
    assert first < err.index("estimate") < err.index("reference hubs")
    assert f"{ref.unique_hubs:,} distinct to build" in err
    assert again.timings["estimate"] > 0 and again.timings["calibration_cpu"] > 0
    assert again.volume == pytest.approx(ref.volume, rel=1e-12)
    assert len(again.mesh.faces) == len(ref.mesh.faces) and again.complete


def test_ctrl_c_stops_the_workers(bcc):
    g, _ = bcc
    specs, _, _, _ = _hub_specs(g, True)

    def interrupt(stage: str, done: int, total: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(specs, 0.001, 0.25, False, 2, 300.0, interrupt)
    assert mp.active_children() == []


def test_validate_has_the_full_union_study_switch():
    parser = build_parser()
    a = parser.parse_args(["validate", "g.json", "--report", "r", "--full-union-study"])
    assert a.full_union_study is True
    assert parser.parse_args(["validate", "g.json", "--report", "r"]).full_union_study is False


def test_union_sample_is_bounded_by_stumps(bcc):
    from reference_boolean.compare import union_sample

    g, ref = bcc
    deg = g.degree
    free = union_sample(ref, 10_000, max_stumps=None)
    assert len(free) == int(np.isfinite(ref.hub_volume).sum())
    for cap in (1, 9, 25):
        s = union_sample(ref, 10_000, seed=4, max_stumps=cap)
        assert len(s) >= 1 and len(np.unique(s)) == len(s)
        assert int(deg[s].sum()) <= cap or len(s) == 1
        # the cap cuts the same seeded order: a larger cap keeps a superset
        assert set(s) <= set(union_sample(ref, 10_000, seed=4, max_stumps=cap + 20))
    # hubs still bound it, and the default cap (config) is applied by compare
    assert len(union_sample(ref, 3, max_stumps=10**6)) == 3


def test_run_keeps_a_few_hubs_in_flight_and_builds_them_all(bcc, monkeypatch):
    import reference_boolean.reference as rb

    g, ref = bcc
    specs, _, _, _ = _hub_specs(g, True)
    assert len(specs) > 2
    monkeypatch.setattr(rb, "_IN_FLIGHT_PER_WORKER", 1)  # fewer in flight than hubs
    seen: list[int] = []
    out = _run(specs, 0.0, 0.25, False, 2, 300.0, lambda s, d, t: seen.append(d))
    assert all(r is not None and r.status == "ok" and r.volume > 0 for r in out)
    assert seen == list(range(1, len(specs) + 1))
