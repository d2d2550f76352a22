"""The fast paths of the cutting tessellation give what the slow ones gave, bit for bit.

``occ_impl.triangulation`` reads every face's nodes, uv nodes and triangles from one
OpenCascade binary buffer instead of node by node; ``occ_impl.chord`` makes the edges of
the triangles unique by one integer key instead of ``np.unique(axis=0)``, and measures a
face again only when BRepMesh gave it another triangulation. Each is compared here with
the plain reference on a real part's faces (B-spline, cylinder, cone, torus and planes).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import DATA

FEATURETYPE = DATA / "step" / "trimesh_featuretype.STEP"
DEFL = 0.0035  # 0.5 % of the parts benchmark's strut radius for this part


@pytest.fixture(scope="module")
def solid():
    from conformal import load_part

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_part(FEATURETYPE).shape[0]


@pytest.fixture(scope="module")
def meshed(solid):
    from lattice_cad.occ_impl import chord, shapes

    shape = shapes.copied(solid)
    chord._mesh(shape, DEFL, 0.3, False)
    return shape


def _slow(tri):
    """The node-by-node reading (the reference)."""
    nn, nt = tri.NbNodes(), tri.NbTriangles()
    pts = np.array([tri.Node(i).Coord() for i in range(1, nn + 1)], dtype=np.float64)
    uv = np.array([tri.UVNode(i).Coord() for i in range(1, nn + 1)], dtype=np.float64)
    t = np.array([tri.Triangle(i).Get() for i in range(1, nt + 1)], dtype=np.int64)
    return pts.reshape(nn, 3), uv.reshape(nn, 2), t.reshape(nt, 3)


def test_bulk_read_is_the_node_by_node_read(meshed):
    from OCP.BRep import BRep_Tool
    from OCP.TopLoc import TopLoc_Location

    from lattice_cad.occ_impl import chord
    from lattice_cad.occ_impl.triangulation import triangulation_arrays

    tris = [BRep_Tool.Triangulation_s(f, TopLoc_Location()) for f in chord._faces(meshed)]
    assert len(tris) > 90 and all(t is not None for t in tris)
    got = triangulation_arrays(tris)
    assert got is not None
    assert sum(len(t) for _p, _uv, t in got) > 10_000
    for tri, (pts, uv, t) in zip(tris, got, strict=True):
        ref = _slow(tri)
        assert uv is not None
        for a, b in zip((pts, uv, t), ref, strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape
            assert a.tobytes() == b.tobytes()
    # a triangulation held by two faces: not read in bulk (the caller reads node by node)
    assert triangulation_arrays([tris[0], tris[0]]) is None
    assert triangulation_arrays([]) is None


def test_stored_triangulations_same_with_and_without_bulk(meshed, monkeypatch):
    from lattice_cad.occ_impl import shapes, triangulation

    fast = [(v.tobytes(), t.tobytes()) for _f, v, t in shapes.stored_triangulations(meshed)]
    monkeypatch.setattr(triangulation, "triangulation_arrays", lambda tris: None)
    slow = [(v.tobytes(), t.tobytes()) for _f, v, t in shapes.stored_triangulations(meshed)]
    assert fast == slow


def test_unique_edges_is_numpy_unique_rows(meshed):
    from lattice_cad.occ_impl import chord

    for got in chord._uv_triangulations(chord._faces(meshed)):
        if got is None:
            continue
        _pts, _uv, t = got
        edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mine, mine_inv = chord._unique_edges(t)
        assert np.array_equal(mine, uniq) and np.array_equal(mine_inv, inv.reshape(-1))


def test_measurements_reused_only_for_the_same_triangulation(solid, meshed):
    """A face meshed the same again (here: the whole shape cleaned and meshed again, and a
    deep copy meshed alike) gets the cached measurement, equal to measuring it afresh; a
    face meshed otherwise is measured again."""
    from OCP.BRepTools import BRepTools

    from lattice_cad.occ_impl import chord, shapes

    limit = 1.5 * DEFL
    faces = chord._faces(meshed)
    cache: chord._Cache = {}
    first = chord._measured(faces, range(len(faces)), limit, cache)
    assert sum(got is not None for got in first.values()) > 20

    def fresh(shape):
        out = {}
        for i, face in enumerate(chord._faces(shape)):
            out[i] = chord._triangle_deviation(face, limit + chord._tolerance(face))
        return out

    def same(a, b):
        return a.keys() == b.keys() and all(
            (a[i] is None and b[i] is None)
            or all(x.tobytes() == y.tobytes() for x, y in zip(a[i], b[i], strict=True))
            for i in a
        )

    assert same(first, fresh(meshed))
    copy = shapes.copied(solid)
    chord._mesh(copy, DEFL, 0.3, False)
    again = chord._measured(chord._faces(copy), range(len(faces)), limit, cache)
    assert same(again, fresh(copy))
    hits = sum(a is not None and a is first[i] for i, a in again.items())
    assert hits == sum(got is not None for got in first.values())  # all reused
    # meshed finer: every curved face measured again
    BRepTools.Clean_s(copy)
    chord._mesh(copy, 0.5 * DEFL, 0.3, False)
    finer = chord._measured(chord._faces(copy), range(len(faces)), limit, cache)
    assert same(finer, fresh(copy))
    assert not any(a is not None and a is first[i] for i, a in finer.items())
