"""Faces meshed finer on their own keep sharing their edge nodes (issue 13 item 2).

On ``build123d_M6-1x12-countersunk-screw.step`` BRepMesh leaves three neighbouring
analytic faces of the head and thread run-out (1 and 11: surfaces of revolution, 3: a
cone) 2.5-3.7 times over the chord error of the cutting tessellation. Meshed alone, each
at its own finer deflection, faces 1 and 3 (and 3 and 11) each put their own nodes on the
edge they share (285 vs 273 nodes), so the whole-shape run left the mesh open and
``occ_impl.chord`` threw that work away (~30 CPU s per fill, the faces unresolved).
Neighbours are now meshed together, finest first, so they share their edge nodes.
"""

from __future__ import annotations

import warnings

import pytest
from conftest import DATA

M6 = DATA / "step" / "build123d_M6-1x12-countersunk-screw.step"
#: ``Lattice.fill(M6, 'bcc', 0.8, R)``: the cut's chord error is 0.5 % r = 0.00033 mm.
R = 0.06667


@pytest.fixture(scope="module")
def solid():
    from conformal import load_part

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return list(load_part(M6).shape)[0]


def test_adjacent_faces_meshed_finer_share_their_edges(solid):
    from OCP.BRepTools import BRepTools

    from lattice_cad.occ_impl import chord, shapes

    shape = shapes.copied(solid)
    defl = 0.004
    faces = chord._faces(shape)
    groups = chord._adjacent_groups(shape, faces, [1, 3, 11, 27])
    assert sorted(map(sorted, groups)) == [[1, 3, 11], [27]]
    # each its own finer deflection, as on the cut at 0.00033 mm (0.5, 0.4, 0.32 times)
    asked = {1: 0.5 * defl, 3: 0.4 * defl, 11: 0.32 * defl}

    # meshed each alone (as before): neighbours put their own nodes on a common edge
    for i, d in asked.items():
        chord._mesh_alone(shape, {i: d}, defl, 0.3)
    chord._mesh(shape, defl, 0.3, False)
    assert not chord._edges_shared(shape, [faces[i] for i in asked])

    BRepTools.Clean_s(shape)
    chord._mesh_alone(shape, asked, defl, 0.3)
    chord._mesh(shape, defl, 0.3, False)
    faces = chord._faces(shape)
    assert chord._edges_shared(shape, faces)
    # and finer than the plain mesh there
    plain = shapes.copied(solid)
    chord._mesh(plain, defl, 0.3, False)
    nodes = [
        chord.BRep_Tool.Triangulation_s(f, chord.TopLoc_Location()).NbNodes()
        for s in (plain, shape)
        for f in (chord._faces(s)[i] for i in asked)
    ]
    assert all(b > a for a, b in zip(nodes[:3], nodes[3:], strict=True)), nodes


@pytest.mark.slow
def test_m6_cut_resolves_every_face(solid):
    """The cut's tessellation (the chord error ``cutting_part`` asks for this screw)."""
    from lattice_cad.core import config
    from lattice_cad.occ_impl import shapes

    defl = 0.005 * R  # 0.5 % r, the chord error cutting_part takes for this screw
    v, f, report = shapes.tessellate(
        shapes.copied(solid), defl, config.CUT_ANGULAR_DEFLECTION, control=config.CHORD_CONTROL
    )
    assert report.unresolved == [] and sorted(report.finer) == [1, 3, 11], report
    assert report.max_deviation <= config.CHORD_CONTROL * defl, report.max_deviation / defl
    # closed: every edge of the triangle mesh is shared by exactly two triangles
    import numpy as np

    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert (counts == 2).all(), np.bincount(counts)
