"""The compiled parts of the skin path against plain references: marching tetrahedra, the
distance transform, the vertex weld, and the local re-check of the float32 export."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.ndimage import distance_transform_edt

from conformal import skin
from conformal._skin_kernels import edt_squared
from fast_stitch.check import check
from fast_stitch.recheck import recheck
from lattice_cad.core.mesh import weld
from tests.reference_marching_tets import reference_marching_tets


def _field(rng, n=(23, 19, 17), h=0.3):
    x, y, z = (np.arange(k) * h for k in n)
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
    c = np.array([k * h / 2 for k in n])
    r = np.sqrt((X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2)
    f = 2.0 - r + 0.4 * np.sin(3 * X) * np.cos(2 * Y) + 0.05 * rng.standard_normal(r.shape)
    f[0], f[-1], f[:, 0], f[:, -1], f[:, :, 0], f[:, :, -1] = (-1.0,) * 6
    return f, np.array([0.1, -0.2, 0.3]), h


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_marching_tets_kernel_reproduces_the_numpy_version(seed):
    f, origin, h = _field(np.random.default_rng(seed))
    v, t = skin.marching_tets(f, origin, h)
    v0, t0 = reference_marching_tets(f, origin, h)
    assert len(t) > 100
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(t, t0)
    assert check((v, t), self_intersections=False).valid


def test_marching_tets_of_an_empty_field():
    v, t = skin.marching_tets(-np.ones((4, 5, 6)), np.zeros(3), 1.0)
    assert v.shape == (0, 3) and t.shape == (0, 3)


@pytest.mark.parametrize("seed", range(6))
def test_edt_equals_scipy(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(int(k) for k in rng.integers(1, 14, 3))
    inside = rng.random(shape) < rng.uniform(0.3, 0.95)
    inside.flat[rng.integers(inside.size)] = False
    h = float(rng.uniform(0.05, 3.0))
    d = np.sqrt(edt_squared(inside, h))
    ref = distance_transform_edt(inside, sampling=h)
    np.testing.assert_allclose(d, ref, rtol=1e-12, atol=1e-12)


def _weld_reference(v, f, tol=0.0):
    key = v if tol == 0 else np.round(v / tol)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    first = np.full(len(uniq), len(v), dtype=np.int64)
    np.minimum.at(first, inv, np.arange(len(v)))
    f2 = inv[f]
    keep = (f2[:, 0] != f2[:, 1]) & (f2[:, 1] != f2[:, 2]) & (f2[:, 0] != f2[:, 2])
    return v[first], f2[keep]


@pytest.mark.parametrize("tol", [0.0, 0.5])
def test_weld_equals_the_np_unique_version(tol):
    rng = np.random.default_rng(3)
    v = rng.integers(-3, 3, (300, 3)).astype(float)
    v[rng.random(v.shape) < 0.1] *= -0.0  # -0.0 and 0.0 are one coordinate
    v += rng.choice([0.0, 0.1], v.shape)
    f = rng.integers(0, len(v), (400, 3))
    got, ref = weld(v, f, tol=tol), _weld_reference(v, f, tol)
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])


def _sphere_through_box():
    a = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    b = trimesh.creation.box(extents=[0.3, 0.3, 0.3])
    b.apply_translation([0.0, 0.0, 1.0])  # crosses the sphere's surface
    v = np.vstack([a.vertices, b.vertices])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    return v, f.astype(np.int64)


@pytest.mark.parametrize("max_report", [100, 2])
def test_recheck_after_a_collapse_equals_the_full_check(max_report):
    from lattice_cad.core.mesh import Mesh
    from lattice_cad.lattice import _collapse_folds

    v, f = _sphere_through_box()
    before = Mesh(vertices=v, faces=f)
    rep = check(before, max_report=max_report)
    assert rep.n_self_intersections > 0
    after = _collapse_folds(before, rep)
    full = check(after, max_report=max_report)
    local = recheck(before, rep, after, max_report=max_report)
    # the box still crosses the sphere: the local check must fail as the full one does
    assert not full.valid and not local.valid
    assert local.n_self_intersections == full.n_self_intersections > 0
    np.testing.assert_array_equal(local.self_intersection_pairs, full.self_intersection_pairs)
    assert local.n_boundary_edges == full.n_boundary_edges
    assert local.n_faces == full.n_faces


@pytest.mark.parametrize("seed", range(3))
def test_fold_rounds_without_topology_end_as_the_full_check(seed, monkeypatch):
    """Rounds of collapses rechecked with ``topology=False`` (self-intersections and
    zero-area faces only) give, completed by ``with_topology``, the full check's report;
    and each round's zero-area faces and self-intersections are the full check's."""
    import fast_stitch.recheck as rc
    from fast_stitch.recheck import with_topology
    from lattice_cad.core.mesh import Mesh
    from lattice_cad.lattice import _collapse_folds

    checked = []  # the faces each check inside recheck looked at

    def counted(mesh, **kw):
        checked.append(len(mesh[1]))
        return check(mesh, **kw)

    monkeypatch.setattr(rc, "check", counted)

    rng = np.random.default_rng(seed)
    v, f = _sphere_through_box()
    # needles: a corner of some faces moved onto another (zero area)
    flat = rng.choice(len(f), 5, replace=False)
    v = v.copy()
    for face in f[flat]:
        v[face[2]] = v[face[0]]
    mesh = Mesh(vertices=v, faces=f)
    rep = check(mesh, max_report=10_000)
    assert rep.n_self_intersections > 0 and rep.n_zero_area > 0
    for _ in range(4):
        after = _collapse_folds(mesh, rep)
        local = recheck(mesh, rep, after, max_report=10_000, topology=False)
        full = check(after, max_report=10_000)
        assert local.n_faces == full.n_faces and local.n_vertices == full.n_vertices
        assert local.n_zero_area == full.n_zero_area
        np.testing.assert_array_equal(local.zero_area_faces, full.zero_area_faces)
        assert local.n_self_intersections == full.n_self_intersections
        np.testing.assert_array_equal(local.self_intersection_pairs, full.self_intersection_pairs)
        done = with_topology(after, local, max_report=10_000)
        for field in (
            "n_boundary_edges",
            "n_nonmanifold_edges",
            "n_components",
            "volume",
            "n_inverted_components",
            "n_zero_area",
            "n_self_intersections",
        ):
            assert getattr(done, field) == getattr(full, field), field
        assert done.valid == full.valid
        mesh, rep = after, local
    # the rounds after the first were local: a check of far fewer faces than the mesh's
    assert min(checked) < len(f) // 3
