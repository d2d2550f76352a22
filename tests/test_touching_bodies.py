"""Mesh parts whose bodies touch (an assembly saved as one STL): they were refused.

Two 10 mm cubes face to face or along an edge, saved as one STL, were refused with "the
mesh is not a closed solid: N non-manifold edge(s) shared by more than two triangles",
which named the edge but left the user nothing to do. ``conformal.touching`` removes
the walls stored twice (once each way) and gives each body its own copy of the edges it
shares; the loader then unites the bodies as it unites any others.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from conformal.part import load_part
from conformal.touching import split_touching
from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import assert_valid

#: a 10 mm cube's corners and its squares, each counter-clockwise seen from outside
_CORNERS = 5.0 * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
_SQUARES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def _cube(at, flip_diagonals=False):
    """A 10 mm cube centred at ``at``; each square split along one diagonal or the other."""
    f = []
    for p, q, r, s in _SQUARES:
        f += [[q, r, s], [q, s, p]] if flip_diagonals else [[p, q, r], [p, r, s]]
    m = trimesh.Trimesh(_CORNERS + np.asarray(at, dtype=float), np.asarray(f), process=False)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0
    return m


def _welded(meshes):
    m = trimesh.util.concatenate(meshes)
    v, inv = np.unique(np.asarray(m.vertices), axis=0, return_inverse=True)
    return v, inv.reshape(-1)[np.asarray(m.faces)]


def _stl(tmp_path, meshes, name):
    path = tmp_path / name
    trimesh.util.concatenate(meshes).export(path)
    return path


def test_the_shared_edge_is_split_between_the_two_cubes():
    v, f = _welded([_cube((0, 0, 0)), _cube((10, 10, 0))])
    got = split_touching(v, f)
    assert got is not None
    v2, f2, report = got
    assert report.edges == 1 and np.allclose(report.at, (5.0, 5.0, 0.0))
    assert len(v2) == len(v) + 2 and len(f2) == len(f)  # the edge's two ends, copied
    out = trimesh.Trimesh(v2, f2, process=False)
    assert out.is_watertight and out.is_winding_consistent
    assert out.volume == pytest.approx(2000.0)
    assert sorted(b.volume for b in out.split()) == pytest.approx([1000.0, 1000.0])


@pytest.mark.parametrize("offset", [(10, 0, 0), (10, 10, 0)], ids=["face", "edge"])
@pytest.mark.parametrize("flip", [False, True], ids=["same", "other-diagonals"])
def test_touching_cubes_load_as_the_two_cubes(tmp_path, offset, flip):
    path = _stl(tmp_path, [_cube((0, 0, 0)), _cube(offset, flip)], "two_cubes.stl")
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", LatticeWarning)
        part = load_part(path)
    said_ = " ".join(str(w.message) for w in said)
    # (the same triangles face to face: a wall the loader's seams step removes)
    assert "shared by more than two triangles" in said_ or "coincident triangles" in said_
    assert abs(part.volume) == pytest.approx(2000.0, rel=1e-9)
    t = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert t.is_watertight and t.is_winding_consistent
    inside = part.contains(np.array([[0.0, 0.0, 0.0], np.asarray(offset, dtype=float)]))
    assert inside.all()
    assert not part.contains(np.array([[0.0, 10.0, 0.0]]))[0]


@pytest.mark.parametrize("offset", [(10, 0, 0), (10, 10, 0)], ids=["face", "edge"])
def test_touching_cubes_are_filled(tmp_path, offset):
    path = _stl(tmp_path, [_cube((0, 0, 0)), _cube(offset)], "two_cubes.stl")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(path, "bcc", 3.0, 0.3)
        mesh = lat.mesh()
    assert_valid(mesh)
    # both cubes hold struts
    nodes = lat.graph.nodes
    assert (nodes[:, 0] < 5).any() and (nodes[:, 0] > 5).any()


def test_a_mesh_without_shared_edges_is_left_alone():
    v, f = _welded([_cube((0, 0, 0))])
    assert split_touching(v, f) is None
