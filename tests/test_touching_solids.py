"""Solids that touch are not a surface that crosses itself (s32).

Found on three 20 mm blocks in one STEP file, made outside shared/data: A and B touch
along an edge, B and C at a corner. ``Part.self_crossings`` counted the 71 pairs of
triangles that meet at the contact as crossings, so the skin, tet and clip fills took the
path of a folded surface (its rebuild on a grid): they stood 27 % r out of the part at the
contact, as one body for three solids, with advice to unite overlapping bodies that do not
overlap. Only pairs that pass through each other count now
(``fast_stitch.check.crossing_pairs``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fast_stitch.check import check, crossing_pairs


def _blocks():
    import cadquery as cq

    return cq.Compound.makeCompound(
        [
            cq.Solid.makeBox(20, 20, 20, cq.Vector(0, 0, 0)),
            cq.Solid.makeBox(20, 20, 20, cq.Vector(20, 20, 0)),
            cq.Solid.makeBox(20, 20, 20, cq.Vector(40, 40, 20)),
        ]
    )


def test_crossing_and_touching_pairs():
    v = np.array(
        [
            [0, 0, 0], [2, 0, 0], [0, 2, 0],  # 0: in z = 0
            [0.5, 0.5, -1], [0.5, 0.5, 1], [1.5, -1, 0.2],  # 1: through 0
            [0, 0, 0], [2, 0, 0], [0, 0, 2],  # 2: on 0's edge, upright (touches)
            [0.5, 0.5, 0], [3, 3, 3], [3, 0, 3],  # 3: a corner in 0's interior (touches)
            [0.2, 0.2, 0], [1.2, 0.2, 0], [0.2, 1.2, 0],  # 4: coplanar inside 0 (touches)
        ],
        np.float64,
    )  # fmt: skip
    f = np.arange(15, dtype=np.int64).reshape(5, 3)
    pairs = np.array([[0, 1], [1, 0], [0, 2], [0, 3], [0, 4]])
    assert crossing_pairs((v, f), pairs).tolist() == [True, True, False, False, False]
    # the check finds every one of these pairs: they all meet
    found = {tuple(p) for p in check((v, f), max_report=100).self_intersection_pairs.tolist()}
    assert {(0, 1), (0, 2), (0, 3), (0, 4)} <= found
    with pytest.raises(ValueError, match="pairs name faces"):
        crossing_pairs((v, f), [[0, 5]])


def test_blocks_touching_at_an_edge_and_a_corner_are_not_folded():
    from conformal import load_part

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the three solids are united into one part
        part = load_part(_blocks())
    rep = check((part.vertices, part.faces), max_report=1000)
    assert rep.n_self_intersections > 0  # the contact's triangles meet ...
    assert part.self_crossings[0] == 0  # ... but none crosses another
    assert not part.folds


@pytest.mark.slow
def test_a_clip_fill_of_touching_blocks_is_cut_to_them_one_body_each():
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lat = Lattice.fill(_blocks(), "bcc", 4.0, 1.0 / 3.0, fill="clip")
        mesh = lat.mesh()
    rep = lat.trim_report
    assert rep.trimmed and not rep.failed, rep.summary()
    assert rep.protrusion_after <= rep.tolerance, rep.summary()  # was 27 % r (0.089 mm)
    assert rep.bodies == 3, rep.summary()  # was 1
    assert check(mesh).valid
