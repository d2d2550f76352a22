"""Skin speed (issue 11 item 2): the compiled float32 checks and marching-tets helpers
against plain numpy/scipy references and trimesh, the voxel surfaces begun while OCCT's
offsets compute, and the early OCCT offsets reused for the part Lattice cuts by."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from conformal import skin
from conformal._skin_kernels import max_step_x, unique_inverse
from conformal.part import Part, load_part
from lattice_cad.core.errors import OCCTFailure
from lattice_cad.io import _rounding_kernels as K
from tests.conftest import DATA


# ----------------------------------------------------------------- references
def _fans_reference(f: np.ndarray, nv: int) -> np.ndarray:
    """The fans of every corner with a sparse graph (the numpy/scipy formulation the
    kernel replaced): corners joined across edges with exactly two opposite faces."""
    nf = len(f)
    corner = np.arange(3 * nf).reshape(nf, 3)
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    ca, cb = corner.ravel(), corner[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * np.int64(nv) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[start, len(ks)])
    two = start[count == 2]
    h1, h2 = order[two], order[two + 1]
    opp = a[h1] == b[h2]
    h1, h2 = h1[opp], h2[opp]
    rows = np.concatenate([ca[h1], cb[h1]])
    cols = np.concatenate([cb[h2], ca[h2]])
    g = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(3 * nf,) * 2)
    return connected_components(g, directed=False)[1].reshape(nf, 3)


def _pinched_reference(f: np.ndarray, nv: int) -> np.ndarray:
    fans = _fans_reference(f, nv)
    pairs = np.unique(np.stack([f.ravel(), fans.ravel()], axis=1), axis=0)
    return np.flatnonzero(np.bincount(pairs[:, 0], minlength=nv) > 1)


def _same_partition(x: np.ndarray, y: np.ndarray) -> bool:
    pairs = np.unique(np.stack([x.ravel(), y.ravel()], axis=1), axis=0)
    return len(pairs) == len(np.unique(x)) == len(np.unique(y))


def _meshes():
    """Closed meshes, broken ones and pinched ones (name, v, f)."""
    s = trimesh.creation.icosphere(subdivisions=3)
    v, f = np.asarray(s.vertices), np.asarray(s.faces, dtype=np.int64)
    yield "sphere", v, f
    yield "open", v, f[1:]
    flipped = f.copy()
    flipped[5] = flipped[5, ::-1]
    yield "one face flipped", v, flipped
    # two spheres sharing one vertex (a pinch), and sharing a vertex through a weld
    w = v + np.array([2.0, 0, 0])
    w = w - (w[0] - v[np.argmax(v[:, 0])])  # vertex 0 of the second on the first's +x pole
    vv = np.vstack([v, w])
    ff = np.vstack([f, f + len(v)])
    ff[ff == len(v)] = int(np.argmax(v[:, 0]))
    yield "pinched pair", vv, ff
    # an edge with four faces (two cubes sharing an edge)
    box = trimesh.creation.box()
    bv, bf = np.asarray(box.vertices), np.asarray(box.faces, dtype=np.int64)
    yield "box", bv, bf
    yield "duplicated face", bv, np.vstack([bf, bf[:1]])


@pytest.mark.parametrize("case", list(_meshes()), ids=lambda c: c[0])
def test_rounding_kernels_match_references(case):
    _, v, f = case
    nv = len(v)
    tm = trimesh.Trimesh(v, f, process=False)
    expect_closed = bool(tm.is_watertight and tm.is_winding_consistent)
    # trimesh's watertight allows a consistently flipped face pair? our definition is
    # stricter (each directed edge once): compare with a direct count as well
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    und, cnt = np.unique(np.sort(he, axis=1), axis=0, return_counts=True)
    direct = bool((cnt == 2).all() and len(np.unique(he, axis=0)) == len(he))
    assert K.closed_oriented(f, nv) == direct
    if direct:
        assert expect_closed
    assert _same_partition(K.corner_fans(f, nv), _fans_reference(f, nv))
    np.testing.assert_array_equal(K.pinched(f, nv), _pinched_reference(f, nv))
    t = v[f]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    np.testing.assert_array_equal(K.flat_mask(v, f), ~np.any(n != 0.0, axis=1))


def test_pinched_pair_is_found():
    name, v, f = [c for c in _meshes() if c[0] == "pinched pair"][0]
    assert len(K.pinched(f, len(v))) == 1


def test_flat_mask_finds_needles_and_caps():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 0, 0]], dtype=float)
    f = np.array([[0, 1, 3], [0, 1, 2], [1, 4, 3]])  # fine; a cap (collinear); a needle
    np.testing.assert_array_equal(K.flat_mask(v, f), [False, True, True])


@pytest.mark.parametrize("seed", range(4))
def test_unique_inverse_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 10 ** int(rng.integers(1, 12)), int(rng.integers(1, 5000)))
    u, inv = unique_inverse(a.astype(np.int64))
    u0, inv0 = np.unique(a, return_inverse=True)
    np.testing.assert_array_equal(u, u0)
    np.testing.assert_array_equal(inv, inv0.ravel())
    np.testing.assert_array_equal(u[inv], a)


def test_max_step_x_equals_numpy_diff():
    rng = np.random.default_rng(3)
    f = rng.standard_normal((7, 5, 6))
    assert max_step_x(f) == np.abs(np.diff(f, axis=0)).max()
    assert max_step_x(f[:1].copy()) == 0.0


# ------------------------------------------------------ speculative voxel surfaces
class _SlowFailingWorker:
    """An IsolatedWorker stand-in: running for ``n`` polls, then its offset has failed."""

    def __init__(self, n: int) -> None:
        self.polls = n
        self.closed = False

    @property
    def running(self) -> bool:
        self.polls -= 1
        return self.polls >= 0

    def result(self, **_):
        raise OCCTFailure("offset by -1: BRepCheck_Analyzer reports an invalid shape (test)")

    def close(self) -> None:
        self.closed = True


@pytest.mark.parametrize("polls", [0, 1, 2, 50])
def test_voxel_surfaces_begun_while_occt_computes_are_the_same(polls, monkeypatch):
    """The voxel surfaces computed stage by stage while the offsets run (any number of
    stages before the child reports its failure) are exactly the plain voxel surfaces."""
    from lattice_cad.occ_impl import shapes as occ

    monkeypatch.setattr(occ, "fused_offsets_result", lambda w, **k: w.result())
    mesh = trimesh.creation.box(extents=(12.0, 9.0, 7.0))
    part = Part(mesh.vertices, mesh.faces, name="box", shape=["not used"])
    t, h = 1.5, 0.5
    worker = _SlowFailingWorker(polls)
    pending = skin.PendingOffsets(worker, part, t, False)
    surfaces, used, fallback, h_used, _ = skin._surfaces(part, t, "auto", h, False, pending)
    assert used == "voxel" and "invalid shape" in fallback and h_used == h
    assert worker.closed
    ref = skin._voxel_surfaces(part, t, h)[0]
    for a, b in zip(surfaces, ref, strict=True):
        va, fa = skin.to_arrays(a)
        vb, fb = skin.to_arrays(b)
        np.testing.assert_array_equal(va, vb)
        np.testing.assert_array_equal(fa, fb)
    # the inner box of a box is the box shrunk by t on every side
    lo, hi = skin.to_arrays(ref[1])[0].min(axis=0), skin.to_arrays(ref[1])[0].max(axis=0)
    np.testing.assert_allclose(hi - lo, np.array([12.0, 9.0, 7.0]) - 2 * t, atol=0.02 * t)


def test_offsets_get_their_time_from_their_start_not_from_when_they_are_waited_for(
    monkeypatch,
):
    """OCCT's offsets run beside the lattice build: their budget (config.OFFSET_TIMEOUT)
    counts from their start, so a lattice that took long to build does not add its own
    time to the wait (a threaded bolt's offset ran past 120 s after a 50 s build: 181 s)."""
    import time

    from lattice_cad.core import config
    from lattice_cad.core.isolate import IsolatedWorker
    from lattice_cad.occ_impl import shapes as occ

    monkeypatch.setattr(config, "OFFSET_TIMEOUT", 3.0)
    asked = []
    result = occ.fused_offsets_result

    def timed(worker, **kw):  # the wait for the child alone (not the voxel work)
        t0 = time.monotonic()
        try:
            return result(worker, **kw)
        finally:
            asked.append((kw["timeout"], time.monotonic() - t0))

    monkeypatch.setattr(occ, "fused_offsets_result", timed)
    mesh = trimesh.creation.box(extents=(12.0, 9.0, 7.0))
    part = Part(mesh.vertices, mesh.faces, name="box", shape=["not used"])
    worker = IsolatedWorker()
    try:
        worker.submit(time.sleep, 60.0)  # an offset that never ends
        pending = skin.PendingOffsets(worker, part, 1.5, False)
        time.sleep(2.5)  # the lattice build, meanwhile
        _, used, fallback, _, _ = skin._surfaces(part, 1.5, "auto", 0.5, False, pending)
    finally:
        worker.close()
    assert used == "voxel" and "did not finish within 3 s of its start" in fallback, fallback
    [(timeout, waited)] = asked
    assert timeout == 1.0  # at most 0.5 s of the 3 s left: the floor of 1 s, not 3 s more
    assert waited < 2.0, waited
    assert pending.remaining() == 1.0


def test_an_offset_of_a_piece_of_the_part_is_refused():
    """Regression (a 3 mm clip made for bench_parts --data outside shared/data): OCCT's
    offset of a box with filleted edges united with a block is a valid solid, the block's
    inset alone (702 of ~7,100 mm^3), every vertex at the right depth: it was taken, and
    the skinned part stayed solid (relative density 0.93). The inset's volume is now
    checked against the part's distance field; the skin falls back to the voxel surfaces."""
    import cadquery as cq

    box = cq.Workplane("XY").box(30, 20, 12).edges("|Z").fillet(1.5)
    ear = cq.Workplane("XY").box(4, 20, 12).translate((17, 0, 6))
    part = load_part(box.union(ear))
    said = r"holds 702\.\d mm\^3, where the part's distance field has about 7\d{3} mm\^3 "
    with pytest.raises(OCCTFailure, match=said + r".* OCCT offset a piece of the part only"):
        skin._occt_surfaces(part, 0.377778)
    # a whole offset passes: the same box without the block
    surfaces = skin._occt_surfaces(load_part(box), 0.377778)
    assert len(surfaces) == 2 and surfaces[1].volume() > 0.8 * (27 * 17 * 11.2)


def _pulley():
    """A V-belt pulley (OD 100, 18 mm wide, a 14 mm deep groove, a web with 5 windows, a
    keyed hub bore), made for bench_parts --data outside shared/data (s22)."""
    import cadquery as cq

    ro, w, depth = 50.0, 18.0, 14.0
    half = np.tan(np.radians(20.0))
    rim_in = ro - depth - 5.0
    prof = [(6.0, -15.0), (16.0, -15.0), (16.0, -3.0), (rim_in, -3.0), (rim_in, -w / 2),
            (ro, -w / 2), (ro, -depth * half - 1.5), (ro - depth, -1.5), (ro - depth, 1.5),
            (ro, depth * half + 1.5), (ro, w / 2), (rim_in, w / 2), (rim_in, 3.0),
            (16.0, 3.0), (16.0, 15.0), (6.0, 15.0)]  # fmt: skip
    body = cq.Workplane("XZ").polyline(prof).close().revolve(360, (0, 0, 0), (0, 1, 0))
    for i in range(5):
        win = cq.Workplane("XY").center(25.5, 0).slot2D(12, 10).extrude(20)
        body = body.cut(win.translate((0, 0, -10)).rotate((0, 0, 0), (0, 0, 1), i * 72 + 36))
    key = cq.Workplane("XY").center(7, 0).rect(3, 4).extrude(40).translate((0, 0, -20))
    return load_part(body.cut(key))


def test_an_offset_missing_a_piece_the_volume_check_cannot_see_is_refused():
    """Regression (s22, a pulley made outside shared/data): OCCT's offset by 1.11 mm is a
    valid solid of 14 of the part's 47 faces, 11,895 of ~53,000 mm^3, every vertex at the
    right depth; the volume check's allowance (twice the area times its grid step, 66,220
    mm^3) exceeds the volume itself, so it passed, and the skin came out in 5 bodies that
    no retry could write (exit 1 after 194 s). Points of the part deeper than the thickness
    must now lie inside the offset; the skin falls back to the voxel surfaces."""
    part = _pulley()
    with pytest.raises(OCCTFailure, match=r"leaves out \d+ of \d+ points of the part deeper"):
        skin._occt_surfaces(part, 1.11072)


@pytest.mark.filterwarnings("ignore:.*solids were united")
def test_early_offsets_serve_the_refined_part():
    """Lattice starts OCCT's offsets for the loaded part and cuts by its finer
    tessellation (Part.refined): the pending offsets are those of the refined part too."""
    part = load_part(DATA / "step" / "kcl_flange-with-patterns.step")
    fine = part.refined(0.25 * part.deflection)
    assert fine is not part and fine.unrefined is part and part.unrefined is None
    pending = skin.PendingOffsets(None, part, 1.0, False)
    assert skin._pending_for(pending, fine, 1.0, False)
    assert skin._pending_for(pending, part, 1.0, False)
    assert not skin._pending_for(pending, fine, 2.0, False)
    assert not skin._pending_for(pending, fine, 1.0, True)
    other = load_part(DATA / "step" / "kcl_flange-with-patterns.step")
    assert not skin._pending_for(pending, other, 1.0, False)


def test_any_flat_triangle_equals_the_np_cross_test():
    """conformal._skin_kernels.any_flat_triangle (skin_split's float32 test of the deep
    triangles) answers as ``np.cross`` did: a real part's triangles in float32 have no
    zero normal; one made of three points on a line, or with a repeated corner, has."""
    from conformal._skin_kernels import any_flat_triangle

    part = load_part(DATA / "meshes" / "fandisk.obj")
    v = part.vertices.astype(np.float32).astype(np.float64)
    f = np.ascontiguousarray(part.faces, dtype=np.int64)

    def reference(v, f):
        t = v[f]
        return not np.all(np.any(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]) != 0, axis=1))

    assert any_flat_triangle(v, f) == reference(v, f) is False
    a, b = v[f[0, 0]], v[f[0, 1]]
    line = np.vstack([v, a + 0.25 * (b - a)])  # a point on the edge a-b (exact in binary)
    for bad in ([f[0, 0], f[0, 1], len(v)], [f[5, 0], f[5, 1], f[5, 1]]):
        g = np.vstack([f, [bad]])
        assert any_flat_triangle(line, g) == reference(line, g) is True
