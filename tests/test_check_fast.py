"""The faster float32 export check gives the same results as the plain formulation.

:func:`lattice_cad.lattice._checked_single_precision_once` asks
:func:`lattice_cad.io.rounding.weld_merges` (a hashing pass) whether the
``config.NEAR_VERTEX`` weld would merge anything, instead of running the weld (a sort)
and comparing vertex counts. Seeded random meshes, valid and broken (self-intersecting,
open, flipped, duplicated faces, vertices split by less than the weld tolerance), must
get the same mesh or the same error as the plain formulation, kept here as the reference.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import fast_stitch
from lattice_cad import io
from lattice_cad.core import config
from lattice_cad.core.errors import ExportError
from lattice_cad.core.mesh import Mesh, weld
from lattice_cad.io.rounding import pinched_vertices, repair_rounded, weld_merges
from lattice_cad.lattice import _checked_single_precision_once, _collapse_folds


def _reference_once(mesh: Mesh, name: str) -> Mesh:
    """``_checked_single_precision_once`` in plain terms: the weld itself decides, and
    every round of collapses is followed by the full check."""
    out, _ = io.single_precision(mesh, name=name)
    v2, f2 = weld(out.vertices, out.faces, tol=config.NEAR_VERTEX)
    if len(v2) != len(out.vertices):
        if len(pinched_vertices(f2, len(v2))):
            v2, f2 = repair_rounded(v2, f2)
        out = Mesh(vertices=v2, faces=f2)
    listed = config.COLLAPSE_MAX_REPORT  # every problem listed, so every one collapsed
    for attempt in range(2):
        report = fast_stitch.check(out, max_report=listed)
        for _ in range(20):
            if report.valid:
                break
            out = _collapse_folds(out, report)
            report = fast_stitch.check(out, max_report=listed)  # the whole mesh, each round
        if not report.valid:
            raise ExportError(
                f"{name} cannot be written in single precision (STL, 3MF): rounding its "
                f"coordinates to float32 breaks it ({report})"
            )
        v2, f2 = weld(out.vertices, out.faces, tol=config.NEAR_VERTEX)
        if len(v2) == len(out.vertices) or attempt == 1:
            break
        out = Mesh(vertices=v2, faces=f2)
    return out


def _outcome(fn, mesh: Mesh) -> tuple[str, bytes, bytes]:
    try:
        out = fn(mesh, "the part")
    except ExportError as e:
        return ("error " + str(e), b"", b"")
    return ("ok", out.vertices.tobytes(), out.faces.tobytes())


def _sphere(rng: np.random.Generator, subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=rng.uniform(0.5, 20.0))
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    q = q if np.linalg.det(q) > 0 else -q  # a rotation: the sphere stays outward
    v = np.asarray(s.vertices, dtype=np.float64) @ q.T + rng.uniform(-50, 50, 3)
    return v, np.asarray(s.faces, dtype=np.int64)


def _broken(rng: np.random.Generator, kind: str) -> Mesh:
    v, f = _sphere(rng, int(rng.integers(1, 4)))
    if kind == "open":
        f = np.delete(f, rng.choice(len(f), int(rng.integers(1, 4)), replace=False), axis=0)
    elif kind == "flipped":
        k = rng.choice(len(f), int(rng.integers(1, 4)), replace=False)
        f = f.copy()
        f[k] = f[k][:, ::-1]
    elif kind == "duplicate":
        f = np.vstack([f, f[rng.choice(len(f), int(rng.integers(1, 3)), replace=False)]])
    elif kind == "intersecting":  # a second sphere overlapping the first
        v2, f2 = _sphere(rng, 1)
        r1 = np.linalg.norm(v - v.mean(axis=0), axis=1).max()
        r2 = np.linalg.norm(v2 - v2.mean(axis=0), axis=1).max()
        v2 = (v2 - v2.mean(axis=0)) * (0.5 * r1 / r2) + v[0]  # across the first's surface
        f = np.vstack([f, f2 + len(v)])
        v = np.vstack([v, v2])
    elif kind == "split":  # faces of a vertex use a copy less than NEAR_VERTEX away
        f = f.copy()
        for x in rng.choice(len(v), int(rng.integers(1, 6)), replace=False):
            ring = np.flatnonzero((f == x).any(axis=1))
            copy = len(v)
            v = np.vstack([v, v[x] + rng.uniform(-0.3, 0.3, 3) * config.NEAR_VERTEX])
            for face in ring[: len(ring) // 2]:
                f[face][f[face] == x] = copy
    elif kind == "split_far":  # the same, but the copy too far away to be welded
        f = f.copy()
        x = int(rng.integers(len(v)))
        ring = np.flatnonzero((f == x).any(axis=1))
        v = np.vstack([v, v[x] + 1e-3])
        for face in ring[: len(ring) // 2]:
            f[face][f[face] == x] = len(v) - 1
    perm = rng.permutation(len(f))  # face order is arbitrary
    return Mesh(vertices=v, faces=f[perm])


KINDS = ["valid", "open", "flipped", "duplicate", "intersecting", "split", "split_far"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(4))
def test_checked_single_precision_matches_the_plain_formulation(kind, seed):
    rng = np.random.default_rng(1000 * seed + KINDS.index(kind))
    mesh = _broken(rng, kind)
    expected = _outcome(_reference_once, mesh)
    assert _outcome(_checked_single_precision_once, mesh) == expected
    if kind in ("valid", "split"):
        assert expected[0] == "ok"
    if kind in ("open", "flipped", "duplicate", "split_far"):
        assert expected[0].startswith("error")
    # "intersecting": the fold collapse may shrink the smaller sphere out of the larger


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("tol", [0.0, config.NEAR_VERTEX, 0.25])
def test_weld_merges_is_what_weld_does(seed, tol):
    """Points on a coarse lattice (many equal or same-cell rows), half-way cases of the
    rounding, signed zeros: weld_merges agrees with the weld's vertex count."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    step = tol if tol else 1.0
    v = rng.integers(-6, 7, size=(n, 3)).astype(np.float64) * step
    if seed % 2:
        v += rng.choice([0.0, 0.5, 0.49999999, 0.5000001, -0.5], size=(n, 3)) * step
    if seed % 4 == 3:
        v = np.unique(v, axis=0)  # no equal rows left (cells may still be shared)
    v[rng.random((len(v), 3)) < 0.1] = -0.0
    f = rng.integers(0, len(v), size=(max(1, len(v) // 3), 3))
    assert weld_merges(v, tol) == (len(weld(v, f, tol=tol)[0]) != len(v))


def test_weld_merges_edge_cases():
    assert not weld_merges(np.zeros((0, 3)), config.NEAR_VERTEX)
    assert not weld_merges(np.zeros((1, 3)), 0.0)
    assert weld_merges(np.array([[0.0, 1.0, 2.0], [-0.0, 1.0, 2.0]]), 0.0)
    assert not weld_merges(np.array([[np.nan, 1.0, 2.0], [np.nan, 1.0, 2.0]]), 0.0)
    assert weld_merges(np.array([[1.0, 1.0, 1.0], [1.0 + 4e-9, 1.0, 1.0]]), 1e-8)
    assert not weld_merges(np.array([[1.0, 1.0, 1.0], [1.0 + 1e-7, 1.0, 1.0]]), 1e-8)


# ------------------------------------------------- recheck and collapse_faces kernels


def _near_reference(lo, hi, which, eps):
    """Plain numpy: the faces whose box meets an enlarged box of ``which``, and ``which``."""
    qlo, qhi = lo[which] - eps, hi[which] + eps
    hit = np.zeros(len(lo), dtype=bool)
    for k in range(len(which)):
        hit |= np.all(lo <= qhi[k], axis=1) & np.all(hi >= qlo[k], axis=1)
    hit[which] = True
    return np.flatnonzero(hit)


@pytest.mark.parametrize("seed", range(6))
def test_recheck_near_faces_and_scale_match_numpy(seed):
    from fast_stitch import _recheck_kernels as rk
    from fast_stitch.recheck import _near, _scale

    rng = np.random.default_rng(seed)
    n_v = int(rng.integers(3, 3000))
    v = rng.normal(size=(n_v, 3)) * rng.choice([1e-3, 1.0, 1e4])
    if seed % 2:  # snapped to a coarse lattice: many touching and equal boxes
        v = np.round(v * 4) / 4
    f = rng.integers(0, n_v, size=(int(rng.integers(1, 5000)), 3))
    if seed % 3 == 0:  # a few long faces (longer than most cells)
        f[: len(f) // 50, 1] = int(np.argmax(v[:, 0]))
    t = v[f]
    lo, hi = t.min(axis=1), t.max(axis=1)
    boxes = rk.face_boxes(v, f)
    np.testing.assert_array_equal(boxes[0], lo)
    np.testing.assert_array_equal(boxes[1], hi)
    np.testing.assert_array_equal(boxes[2], (hi - lo).max(axis=1))
    np.testing.assert_array_equal(boxes[3], lo.min(axis=0))
    np.testing.assert_array_equal(boxes[4], hi.max(axis=0))
    which = np.unique(rng.choice(len(f), int(rng.integers(1, min(len(f), 200) + 1))))
    for eps in (0.0, 1e-9, 0.1):
        np.testing.assert_array_equal(_near(boxes, which, eps), _near_reference(lo, hi, which, eps))
    used = np.zeros(n_v, dtype=bool)
    used[f.ravel()] = True
    u = v[used]
    expected = max(float(np.abs(u).max()), float(np.linalg.norm(u.max(axis=0) - u.min(axis=0))))
    assert _scale(v, f) == expected
    assert _scale(v, f[:0]) == 0.0


@pytest.mark.parametrize("seed", range(4))
def test_corners_by_vertex_is_the_stable_argsort(seed):
    from lattice_cad.io._rounding_kernels import corners_by_vertex

    rng = np.random.default_rng(seed)
    nv = int(rng.integers(1, 500))
    corner_v = rng.integers(0, nv, size=int(rng.integers(0, 3000)))
    order, start = corners_by_vertex(corner_v, nv)
    expected = np.argsort(corner_v, kind="stable")
    np.testing.assert_array_equal(order, expected)
    np.testing.assert_array_equal(start, np.searchsorted(corner_v[expected], np.arange(nv + 1)))
