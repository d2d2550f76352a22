"""The check's test of inside-out shells: a cavity (an inward shell enclosed by the rest of
the mesh) is valid, a shell inside out on its own is not.

Found on a dome shelled to 1.8 mm (made outside shared/data) under a skin of 0.8 mm (s32):
the 0.2 mm cavity, cut by the 0.8 mm struts, fell into 2,295 closed voids in a
1.08 M-triangle solid. The check tested voids by solid angles within a budget of 200 M
(query, face) evaluations, i.e. the 184 largest, and counted the other 2,111 as inside
out: the valid solid was refused after every retry (more than 10 minutes, then an error).
Every cavity is now decided by the exact crossings of a ray along +z
(``fast_stitch._check_kernels.ray_winding_numbers``); the solid angles decide only the
shells whose rays meet an edge, a vertex or a face's plane.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import trimesh

from fast_stitch import _check_kernels as K
from fast_stitch import check
from tests.test_check import join, manifold3d_ok

check_module = importlib.import_module("fast_stitch.check")


def _cube(lo, size, *, inward=False):
    m = trimesh.creation.box(extents=(size, size, size))
    v = np.asarray(m.vertices) + np.asarray(lo, dtype=float) + size / 2.0
    f = np.asarray(m.faces, dtype=np.int64)
    return v, (f[:, ::-1] if inward else f)


def _sphere(center, radius, *, inward=False, subdivisions=3, rng=None):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v = np.asarray(m.vertices)
    if rng is not None:  # a generic shape: no symmetry for the rays to line up with
        v = v * (1.0 + 0.02 * rng.standard_normal((len(v), 1)))
        q = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        v = v @ q
    f = np.asarray(m.faces, dtype=np.int64)
    return v + np.asarray(center, dtype=float), (f[:, ::-1] if inward else f)


def test_a_thousand_cavities_in_a_fine_shell_are_all_cavities():
    # 327,680 faces and 1,000 cavities: the solid angles' budget covered the 610 largest,
    # the other 390 were counted inside out (a valid solid refused)
    outer = _sphere((0, 0, 0), 10.0, subdivisions=7)
    voids = [_cube((i - 4.7, j - 4.7, k - 4.7), 0.4, inward=True)
             for i in range(10) for j in range(10) for k in range(10)]  # fmt: skip
    stray = _cube((20.0, 0.0, 0.0), 1.0, inward=True)  # inside out, enclosed by nothing
    v, f = join(outer, *voids, stray)
    assert len(f) * len(voids) > check_module._WINDING_BUDGET  # the case the budget lost
    rep = check((v, f))
    assert rep.n_components == 1002
    assert rep.n_inverted_components == 1
    assert rep.inverted_component_faces.tolist() == [len(f) - 12]  # the stray cube only
    assert not rep.valid
    # without the stray cube: valid, as the independent checker says
    v2, f2 = join(outer, *voids)
    rep2 = check((v2, f2))
    assert rep2.valid and rep2.n_inverted_components == 0
    assert manifold3d_ok(v2, f2)


def test_cavities_on_axis_aligned_grids_are_decided_without_solid_angles(monkeypatch):
    # boxes in boxes: many rays from face centroids run along edges and through vertices;
    # the other points of the face decide them (no solid angle may be spent here)
    monkeypatch.setattr(check_module, "_WINDING_BUDGET", 0)
    voids = [_cube((1 + 2 * i, 1 + 2 * j, 1 + 2 * k), 1.0, inward=True)
             for i in range(12) for j in range(12) for k in range(12)]  # fmt: skip
    island = _cube((3.25, 3.25, 3.25), 0.5)  # in the cavity (3, 3, 3)-(4, 4, 4): valid
    v, f = join(_cube((0, 0, 0), 26.0), *voids, island)
    rep = check((v, f))
    assert rep.n_inverted_components == 0 and rep.valid
    # the same cavities with one of them turned outward and one stray shell: 1 inverted
    v3, f3 = join(_cube((0, 0, 0), 26.0), *voids, _cube((40, 0, 0), 1.0, inward=True))
    rep3 = check((v3, f3))
    assert rep3.n_inverted_components == 1
    assert rep3.inverted_component_faces.tolist() == [len(f3) - 12]


@pytest.mark.parametrize("seed", range(4))
def test_ray_winding_equals_the_solid_angles(seed):
    rng = np.random.default_rng(seed)
    shells = [
        _sphere((0, 0, 0), 10.0, rng=rng),
        _sphere((3, 0, 0), 2.0, inward=True, rng=rng),
        _sphere((-4, 1, 0), 3.0, inward=True, rng=rng),
        _sphere((-4, 1, 0), 1.5, rng=rng),  # an island in that cavity
        _sphere((-4, 1, 0), 0.7, inward=True, rng=rng),  # a cavity in the island
        _sphere((0, -5, 2), 1.0, inward=True, rng=rng),
        _sphere((30, 0, 0), 1.0, inward=True, rng=rng),  # a cavity of the next one
        _sphere((30, 0, 0), 3.0, rng=rng),  # a second body
    ]
    v, f = join(*shells)
    labels = np.concatenate([np.full(len(s[1]), i, np.int64) for i, s in enumerate(shells)])
    queries = v[f].mean(axis=1)
    w, unsure = check_module._ray_winding(v, f, labels, queries, labels)
    exact = K.winding_numbers(v, f, labels, queries, labels)
    assert np.abs(exact - np.round(exact)).max() < 1e-6  # closed shells: integers
    assert np.array_equal(w[~unsure], np.round(exact[~unsure]).astype(np.int64))
    assert unsure.mean() < 0.01
    # per shell, the winding number of the others at it (the island's cavity: 1 - 1 + 1)
    inside = [0, 1, 1, 0, 1, 1, 1, 0]
    for i in range(len(shells)):
        got = w[(labels == i) & ~unsure]
        assert got.size and np.all(got == inside[i]), i


def test_a_ray_along_an_edge_or_in_a_face_is_unsure():
    # one square of two triangles at z = 1, shared diagonal (0,0)-(1,1), normal up
    v = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    labels = np.zeros(2, np.int64)
    queries = np.array(
        [
            [0.7, 0.2, 0.0],  # below one triangle: crosses it going up
            [0.5, 0.5, 0.0],  # below the diagonal: unsure
            [0.2, 0.7, 1.0],  # in the face: unsure
            [0.2, 0.7, 2.0],  # above: nothing
            [1.0, 0.5, 0.0],  # below the boundary edge: unsure
            [3.0, 3.0, 0.0],  # beside it: nothing
        ]
    )
    w, unsure = check_module._ray_winding(v, f, labels, queries, np.ones(6, np.int64))
    assert unsure.tolist() == [False, True, True, False, True, False]
    assert w[~unsure].tolist() == [1, 0, 0]
    # turned over, the crossing counts -1; its own faces are not counted
    w2, u2 = check_module._ray_winding(v, f[:, ::-1], labels, queries[:1], np.ones(1, np.int64))
    assert w2.tolist() == [-1] and not u2[0]
    w3, u3 = check_module._ray_winding(v, f, labels, queries[:1], np.zeros(1, np.int64))
    assert w3.tolist() == [0] and not u3[0]


def test_queries_along_a_line_get_few_cells():
    # 5 queries 2 m apart along x, 1e-13 apart in y: square cells of their box would
    # number 1e16; the grid is capped at 4 Q cells and the answers are the same
    v = np.array([[0, 0, 1], [2000, 0, 1], [2000, 1, 1], [0, 1, 1]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    q = np.c_[np.linspace(1, 1999, 5), 0.5 + 1e-13 * np.arange(5), np.zeros(5)]
    w, unsure = check_module._ray_winding(v, f, np.zeros(2, np.int64), q, np.ones(5, np.int64))
    assert w.tolist() == [1] * 5 and not unsure.any()
