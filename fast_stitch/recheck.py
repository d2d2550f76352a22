"""Re-check a mesh after a few of its faces were collapsed, self-intersections near them only.

The float32 export of a boolean result (``lattice_cad.lattice._checked_single_precision``)
checks the rounded mesh in full, collapses the faces of the problems found (zero-area
faces, the smaller face of each self-intersecting pair) and checks again, until valid.
The checks after a collapse need not look for self-intersections everywhere: a pair of
faces that intersects after the collapse and did not before has a face that changed, and
when the previous report listed *all* its problems, every pair of unchanged faces is as
the previous check found it. :func:`recheck` checks the topology of the whole mesh (cheap)
and the self-intersections of the faces near the changes, and returns a report equivalent
to :func:`fast_stitch.check` of the whole mesh (the counts of self-intersections are of
that region); otherwise (an incomplete previous report, or a large changed region) it is
the full check. The export lists every problem (``config.COLLAPSE_MAX_REPORT``), so that
each round collapses them all and the next check stays local; its rounds recheck only the
self-intersections and zero-area faces (``topology=False``: what the next collapse is
decided by), and :func:`with_topology` checks the topology once, after the last round.

Changed faces: the faces that use a vertex at the position of a vertex of a face the
previous report named (a collapse keeps one vertex of an edge in place and moves every
face of the other to it; the faces that keep all their vertices elsewhere keep their
geometry and their neighbours).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fast_stitch import _recheck_kernels as _rk
from fast_stitch.check import CheckReport, check

__all__ = ["recheck", "with_topology"]

#: Above this fraction of the faces near the changes, the full check is run instead.
MAX_LOCAL_FRACTION = 0.25
#: At most this many changed faces for the local check.
MAX_CHANGED = 5000


def _arrays(mesh: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    if isinstance(mesh, tuple):
        v, f = mesh
    else:
        v, f = mesh.vertices, mesh.faces
    return (
        np.ascontiguousarray(v, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(f, dtype=np.int64).reshape(-1, 3),
    )


def _row_hash(v: NDArray[np.float64]) -> NDArray[np.uint64]:
    """(V,) uint64: a hash of the exact bits of each row of (V, 3) float64 (collisions only
    make the changed region larger)."""
    b = np.ascontiguousarray(v, dtype=np.float64).view(np.uint64).reshape(-1, 3)
    with np.errstate(over="ignore"):
        h = b[:, 0] * np.uint64(0x9E3779B97F4A7C15)
        h ^= b[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F) + (h >> np.uint64(29))
        h ^= b[:, 2] * np.uint64(0x165667B19E3779F9) + (h >> np.uint64(31))
    return h


def _scale(v: NDArray[np.float64], f: NDArray[np.int64]) -> float:
    """The coordinate scale :func:`fast_stitch.check` uses (over the vertices faces use)."""
    if len(f) == 0:
        return 0.0
    lo, hi, amax = _rk.used_extremes(v, f)
    return max(float(amax), float(np.linalg.norm(hi - lo)))


def _near(
    boxes: tuple[NDArray[np.float64], ...], which: NDArray[np.int64], eps: float
) -> NDArray[np.int64]:
    """(N,) int64, sorted: the faces whose box meets a box of ``which``.

    ``boxes``: :func:`_recheck_kernels.face_boxes` of the faces (``lo, hi : (F, 3)``, the
    largest extents ``ext : (F,)``, the lower and upper corners ``g0, top : (3,)`` of all).

    The changed boxes mark the cells of a coarse grid (cells as large as 99 % of the faces);
    a face that fits in a cell overlaps at most 2 cells per axis, so it can meet a changed
    box only if one of the 8 cells at its box corners is marked; the longer faces and those
    candidates are then tested box against box (:func:`_recheck_kernels.near_faces`).
    """
    lo, hi, ext, g0, top = boxes
    span = float((top - g0).max())
    cell = max(float(np.quantile(ext, 0.99)), span / 256.0, 1e-300)
    dims = np.floor((top - g0) / cell).astype(np.int64) + 1
    return _rk.near_faces(lo, hi, ext, which, float(eps), cell, g0, dims)


def recheck(
    before: Any,
    report: CheckReport,
    after: Any,
    *,
    max_report: int = 100,
    coplanar_rtol: float = 1e-12,
    topology: bool = True,
) -> CheckReport:
    """The :func:`fast_stitch.check` report of ``after``, made from ``before`` (whose check
    was ``report``) by collapsing faces that ``report`` names.

    Parameters
    ----------
    before, after : Mesh or (vertices, faces)
        ``vertices : (V, 3) float64``, ``faces : (F, 3) int64``.
    report : CheckReport
        The check of ``before`` (self-intersections included): :func:`fast_stitch.check`,
        or a :func:`recheck`, also one with ``topology=False``.
    max_report, coplanar_rtol
        As :func:`fast_stitch.check` (the fold tolerance is relative to the scale of the
        whole of ``after``, also in the local check).
    topology : bool
        False: only the zero-area faces and the self-intersections are ``after``'s (both
        local: a face with no vertex where a named face had one keeps its geometry); the
        rest of the report (edges, components, volume) is ``report``'s, not checked again.
        For rounds of collapses that look only at those two (a collapse is decided by them
        alone); :func:`with_topology` completes the last round's report.

    Returns
    -------
    CheckReport
        The topology of the whole of ``after``; the self-intersections of the faces near
        the changed ones (all of ``after``'s, see the module docstring), face indices of
        ``after``.
    """
    vb, fb = _arrays(before)
    va, fa = _arrays(after)
    zero = np.asarray(report.zero_area_faces, dtype=np.int64).ravel()
    pairs = np.asarray(report.self_intersection_pairs, dtype=np.int64).reshape(-1, 2)
    complete = (
        report.n_self_intersections is not None
        and len(pairs) == report.n_self_intersections
        and len(zero) == report.n_zero_area
    )

    def whole(self_intersections: bool = True) -> CheckReport:
        return check(
            (va, fa),
            self_intersections=self_intersections,
            max_report=max_report,
            coplanar_rtol=coplanar_rtol,
        )

    if not complete or len(fa) == 0:
        return whole()
    named = np.union1d(zero, pairs.ravel())
    marked = np.isin(_row_hash(va), _row_hash(vb[fb[named]].reshape(-1, 3)))
    changed = np.flatnonzero(marked[fa].any(axis=1))
    if len(changed) > MAX_CHANGED:
        return whole()
    if topology:
        topo = whole(self_intersections=False)
    else:  # the zero-area faces are among the changed ones (found by the local check)
        topo = dataclasses.replace(
            report,
            n_vertices=len(va),
            n_faces=len(fa),
            n_zero_area=0,
            zero_area_faces=np.zeros(0, np.int64),
        )
    if len(changed) == 0:
        return dataclasses.replace(
            topo,
            n_self_intersections=0,
            n_self_intersecting_faces=0,
            self_intersection_pairs=np.zeros((0, 2), np.int64),
        )
    scale = _scale(va, fa)
    near = _near(_rk.face_boxes(va, fa), changed, 1e-9 * max(scale, 1.0))
    if len(near) > MAX_LOCAL_FRACTION * len(fa):
        return whole()
    sub = fa[near]
    sub_scale = _scale(va, sub)
    rtol = coplanar_rtol * scale / sub_scale if sub_scale > 0 else coplanar_rtol
    local = check((va, sub), max_report=max_report, coplanar_rtol=rtol)
    found = near[np.asarray(local.self_intersection_pairs, dtype=np.int64).reshape(-1, 2)]
    if not topology:  # (``near`` is sorted: the zero-area faces keep their order)
        zero_after = near[np.asarray(local.zero_area_faces, dtype=np.int64)]
        topo = dataclasses.replace(topo, n_zero_area=local.n_zero_area, zero_area_faces=zero_after)
    return dataclasses.replace(
        topo,
        n_self_intersections=local.n_self_intersections,
        n_self_intersecting_faces=local.n_self_intersecting_faces,
        self_intersection_pairs=np.sort(found, axis=1),
    )


def with_topology(
    after: Any, folds: CheckReport, *, max_report: int = 100, coplanar_rtol: float = 1e-12
) -> CheckReport:
    """The full report of ``after`` from a :func:`recheck` of it with ``topology=False``
    (``folds``): its topology checked in full, its self-intersections ``folds``'."""
    full = check(
        _arrays(after),
        self_intersections=False,
        max_report=max_report,
        coplanar_rtol=coplanar_rtol,
    )
    return dataclasses.replace(
        full,
        n_self_intersections=folds.n_self_intersections,
        n_self_intersecting_faces=folds.n_self_intersecting_faces,
        self_intersection_pairs=folds.self_intersection_pairs,
    )
