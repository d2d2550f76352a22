"""Tests of reference_boolean.frame: every hub is built where its radius is ~1, so the
reference of a lattice does not depend on its units (OCCT's tolerances are absolute)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import fast_stitch
from conformal.cells import block
from lattice_cad import LatticeGraph
from reference_boolean import build_reference, compare
from reference_boolean.frame import frame_scale, scale_spec, unscale_result
from reference_boolean.reference import _unit_specs
from tests.conftest import DATA


def scaled(g: LatticeGraph, s: float) -> LatticeGraph:
    return LatticeGraph(g.nodes * s, g.edges, g.radii * s)


def test_frame_scale_is_the_power_of_two_nearest_the_radius():
    g = block("bcc", (2, 2, 1), cell_size=1.0, radius=0.08)
    for s in (1.0, 1e-3, 7.3, 0.02):
        units = _unit_specs(scaled(g, s), True)
        for spec in units.specs:
            f = frame_scale(spec)
            assert math.log2(f) == int(math.log2(f))  # exact: only exponents change
            hubs = spec.hubs if hasattr(spec, "hubs") else [spec]
            r = max(max(h.radius for h in hubs), float(spec.r_mid.max()))
            assert 2**-0.5 <= r / f <= 2**0.5 + 1e-12
            # scaling by a power of two and back is exact
            back = scale_spec(scale_spec(spec, 1.0 / f), f)
            assert np.array_equal(back.vecs, spec.vecs)
            assert np.array_equal(back.r_mid, spec.r_mid)


def test_unscale_result_scales_vertices_and_volume():
    from lattice_cad.occ_impl.truss import HubResult

    res = HubResult(status="ok", volume=2.0, vertices=np.ones((4, 3)))
    out = unscale_result(res, 0.25)
    assert out.volume == 2.0 * 0.25**3
    assert np.array_equal(out.vertices, np.full((4, 3), 0.25))
    failed = HubResult(status="no midpoint disc")
    assert unscale_result(failed, 0.25) is failed


@pytest.mark.parametrize("s", [1e-3, 7.3])
def test_scaled_lattice_volume_scales_by_s_cubed_and_verdict_is_unchanged(s):
    """Closed form: a lattice scaled by s has s^3 times the volume (the frame makes the
    build the same up to a power of two; before it, s = 1e-3 was off by 1e-6) and the same
    verdict, volume error and deviation / r against its own fast mesh."""
    g = block("bcc", (2, 2, 1), cell_size=1.0, radius=0.08)
    gs = scaled(g, s)
    ref = build_reference(g, keep_solids=False, workers=0)
    refs = build_reference(gs, keep_solids=False, workers=0)
    assert ref.complete and refs.complete
    assert refs.volume / s**3 == pytest.approx(ref.volume, rel=1e-9)
    assert refs.mesh.volume / s**3 == pytest.approx(ref.mesh.volume, rel=1e-6)
    rep = compare(g, mesh=fast_stitch.stitch(g, 6), reference=ref, union_segments=())
    reps = compare(gs, mesh=fast_stitch.stitch(gs, 6), reference=refs, union_segments=())
    assert reps.comparisons["mesh"].relative_volume_error == pytest.approx(
        rep.comparisons["mesh"].relative_volume_error, rel=1e-5, abs=1e-9
    )
    v, vs = rep.verdict(), reps.verdict()
    assert vs.status == v.status
    assert vs.deviation["p95"] / s == pytest.approx(v.deviation["p95"], rel=0.05)


def test_tiny_unitless_mesh_part_gets_a_complete_reference():
    """The Stanford bunny (closed, 1.55 units wide), BCC inside, r = 0.0215: hub 7 failed
    ("no midpoint disc found for stump(s)") after every retry before the frame (even with a
    600 s time bound); now complete, watertight, and its volume is that of the same lattice
    built x 100, divided by 100^3."""
    from conformal import load_part
    from lattice_cad import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = load_part(DATA / "meshes" / "bunny_closed_hr_odedstein.obj")
        cell = float(np.max(part.size)) / 6
        g = Lattice.fill(part, cell="bcc", cell_size=cell, radius=cell / 12, fill="inside").graph
    assert float(g.radii.max()) < 0.03
    ref = build_reference(g, keep_solids=False, hub_timeout=300.0)
    assert ref.complete, ref.failed
    from tests.test_reference import check_watertight

    check_watertight(ref.mesh)
    big = build_reference(scaled(g, 100.0), keep_solids=False, hub_timeout=300.0)
    assert big.complete
    assert ref.volume * 100.0**3 == pytest.approx(big.volume, rel=1e-8)
