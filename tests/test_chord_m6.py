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


def test_quarter_octave_rounds_down_to_a_power_of_the_fourth_root_of_two():
    from lattice_cad.occ_impl import chord

    assert chord._quarter_octave(0.5) == 0.5
    assert chord._quarter_octave(1.0) == 1.0
    assert chord._quarter_octave(0.4) == pytest.approx(2**-1.5)  # 0.354 <= 0.4 < 0.42
    assert chord._quarter_octave(0.3) == pytest.approx(2**-1.75)  # 0.297
    for x in (0.9, 0.61, 0.123, 0.0071):
        q = chord._quarter_octave(x)
        assert q <= x < q * 2**0.25


def _volume(shape):
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    # with a relative precision: the default integration is 1.3 % off on the M6 as it is
    # loaded (332.28 against 336.74 mm^3, its fine mesh 336.60)
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props, 1e-7)
    return props.Mass()


@pytest.mark.slow
def test_dense_faces_are_split_into_patches_of_the_same_surfaces(solid):
    """The thread and head faces of the M6 at its cut's chord error (0.5 % r): split into
    patches that map back to them, the same solid (volume, validity), and a closed mesh
    within the chord control, the same as the faces meshed whole."""
    import numpy as np
    from OCP.BRepCheck import BRepCheck_Analyzer

    from conformal.part import _closed_problem
    from lattice_cad.core import config
    from lattice_cad.occ_impl import chord, shapes

    defl = 0.005 * R
    shape = shapes.copied(solid)
    got = chord.split_dense_faces(shape, defl, config.CUT_ANGULAR_DEFLECTION)
    assert got is not None
    patches, face_of = got
    n = len(chord._faces(shape))
    assert len(face_of) == len(chord._faces(patches)) > n
    assert sorted(set(face_of.tolist())) == list(range(n))  # every face, none lost
    split = np.flatnonzero(np.bincount(face_of, minlength=n) > 1)
    assert {1, 8, 11, 12} <= set(split.tolist()), split  # the thread flanks, the head
    assert BRepCheck_Analyzer(patches).IsValid()
    assert _volume(patches) == pytest.approx(_volume(solid), rel=1e-7)
    v, f, report = shapes.tessellate(
        patches, defl, config.CUT_ANGULAR_DEFLECTION, control=config.CHORD_CONTROL,
        patches_of=face_of,
    )  # fmt: skip
    assert _closed_problem(f) == ""
    assert report.unresolved == [], report
    # within the control, or over it by no more than those faces' B-rep tolerance
    tol = max(chord._tolerance(face) for face in chord._faces(patches))
    assert report.max_deviation <= config.CHORD_CONTROL * defl + tol, report.max_deviation / defl


@pytest.mark.slow
def test_patches_of_one_face_are_meshed_finer_together(solid):
    """Regression: the head's surface of revolution (face 11), split into patches, had
    11 patches left 1.8 x the chord error: the finer stage gave some patches a finer
    deflection than their siblings, and BRepMesh's triangles along the edges between them
    deviate more (0.48 -> 1.64 x). Each patch of a face now gets the finest step any of
    them needs, and every face resolves (the refined part, as cutting_part makes it)."""
    from conformal import load_part
    from lattice_cad.core import config

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = load_part(M6)
        defl = 0.0052 * 0.0833  # bench_parts: cell 12 / 15, r = cell / 12, 0.52 % r
        cut = part.refined(defl, angular=config.CUT_ANGULAR_DEFLECTION)
    assert cut.chord_unresolved == 0
    assert cut.chord_error <= config.CHORD_CONTROL * defl * 1.02, cut.chord_error / defl
    assert part.__dict__["_split"], "the faces were not split: the case is not tested"
