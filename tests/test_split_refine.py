"""The skin split's exact clearance test (``conformal._kernels.triangles_within`` and
``soups_within``) and the near elements it reclassifies (``conformal.skin_split``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import minimize

from conformal import skin_split
from conformal._kernels import bin_triangles_3d, soups_within, triangle_boxes, triangles_within
from lattice_cad.core.errors import LatticeWarning
from tests.test_skin_split import _fill, _triangles


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between triangles a and b ((3, 3) each) by a convex program (SLSQP on the
    two barycentric pairs), from several starts: an independent reference."""

    def sq(x: np.ndarray) -> float:
        p = a[0] + x[0] * (a[1] - a[0]) + x[1] * (a[2] - a[0])
        q = b[0] + x[2] * (b[1] - b[0]) + x[3] * (b[2] - b[0])
        return float((p - q) @ (p - q))

    cons = [
        {"type": "ineq", "fun": lambda x: 1 - x[0] - x[1]},
        {"type": "ineq", "fun": lambda x: 1 - x[2] - x[3]},
    ]
    best = np.inf
    for x0 in ([1 / 3] * 4, [0, 0, 0, 0], [1, 0, 0, 1], [0, 1, 1, 0]):
        r = minimize(sq, x0, bounds=[(0, 1)] * 4, constraints=cons, method="SLSQP",
                     options={"ftol": 1e-15, "maxiter": 500})  # fmt: skip
        best = min(best, float(r.fun))
    return float(np.sqrt(max(best, 0.0)))


def test_triangles_within_agrees_with_a_convex_program():
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(300):
        a = rng.normal(size=(1, 3, 3))
        b = rng.normal(size=(1, 3, 3)) * rng.uniform(0.2, 1.5) + rng.normal(size=3) * 2.0
        d = _distance(a[0], b[0])
        if d < 1e-6:  # crossing (the program stops a little above 0): within any eps
            assert triangles_within(a, 0, b, 0, 0.0) or triangles_within(a, 0, b, 0, 1e-6)
            continue
        assert triangles_within(a, 0, b, 0, 1.01 * d), d
        assert not triangles_within(a, 0, b, 0, 0.99 * d), d
        assert triangles_within(b, 0, a, 0, 1.01 * d) and not triangles_within(b, 0, a, 0, 0.99 * d)
        checked += 1
    assert checked > 150


def test_triangles_within_sees_an_edge_through_a_face_far_from_its_edges():
    big = np.array([[[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [0.0, 10.0, 0.0]]])
    needle = np.array([[[0.0, 0.0, -1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.0]]])
    assert triangles_within(big, 0, needle, 0, 0.0)
    assert triangles_within(needle, 0, big, 0, 0.0)
    lifted = needle + np.array([0.0, 0.0, 1.5])  # now 0.5 above the face
    assert not triangles_within(big, 0, lifted, 0, 0.49)
    assert triangles_within(big, 0, lifted, 0, 0.51)


def test_soups_within_equals_testing_every_pair():
    """The binned, box- and plane-culled kernel against all pairs, uncull'd."""
    rng = np.random.default_rng(5)
    mesh = rng.uniform(-5, 5, size=(300, 1, 3)) + rng.normal(scale=0.6, size=(300, 3, 3))
    mesh = np.ascontiguousarray(mesh)
    lo = mesh.reshape(-1, 3).min(axis=0)
    h = 0.9
    dims = np.ceil((mesh.reshape(-1, 3).max(axis=0) - lo) / h).astype(np.int64) + 1
    origin = lo - 0.5 * h
    start, items = bin_triangles_3d(mesh, origin, h, dims)
    box = triangle_boxes(mesh)
    # small triangles about random centres (soups of 1..9), one of them degenerate
    centres = rng.uniform(-8, 8, size=(240, 1, 3))
    v = (centres + rng.normal(scale=0.25, size=(240, 3, 3))).reshape(-1, 3)
    soup = np.arange(720).reshape(240, 3)
    soup[7, 2] = soup[7, 1]
    sizes = rng.integers(1, 10, size=60)
    sizes = sizes[np.cumsum(sizes) <= len(soup)]
    soup_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    tri = v[soup]
    for eps in (0.0, 0.05, 0.3):
        got = soups_within(mesh, box, start, items, origin, h, dims, v, soup, soup_start, eps)
        want = [
            any(
                triangles_within(tri, k, mesh, t, eps)
                for k in range(soup_start[s], soup_start[s + 1])
                for t in range(len(mesh))
            )
            for s in range(len(sizes))
        ]
        np.testing.assert_array_equal(got, want)
        assert 0 < sum(want) < len(want)  # both answers occur


@pytest.mark.slow
def test_exact_clearance_leaves_the_skin_unchanged_with_fewer_near_triangles(monkeypatch):
    """Flange: the near elements found clear are deep or wall, the booleans see fewer
    triangles, and the written solid is the same triangles as with the bounds alone."""
    name, per = "step/kcl_flange-with-patterns.step", 10
    lat = _fill(name, per)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        mesh = lat.mesh()
    monkeypatch.setattr(skin_split, "_refine_near", lambda *a, **k: None)
    bounds = _fill(name, per)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        ref = bounds.mesh()
    exact, loose = lat.skin_report.split, bounds.skin_report.split
    assert exact["near"] < 0.8 * loose["near"], (exact, loose)
    assert exact["deep"] > loose["deep"] and exact["wall"] > loose["wall"]
    np.testing.assert_array_equal(_triangles(mesh), _triangles(ref))
