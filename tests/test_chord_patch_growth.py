"""A face split into patches is meshed finer only when all its patches fit (s39).

A mould insert made outside shared/data has an 8 mm cooling channel: a circle swept along a
3-D spline (a B-spline face that ``split_dense_faces`` cuts into 334 patches). Its cutting
tessellation (chord error 0.5 % of a 0.667 mm strut radius) left one patch of 1,254
triangles 6.7 x over the limit. ``_mesh_faces_finer`` checked that patch's growth against
the triangle cap, then meshed every patch of the face at a tenth of the chord error (their
0.37 M triangles would make the mesh 3.6 M, for a cap of 1.05 M): BRepMesh was still running
6 minutes later (about 15 at the 3.5 K triangles a second measured on that face), and the
tet, conform and clip fills of the part timed out (400 s). The growth of all the patches is
now what is checked; the face stays as it is, said in the chord warning.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from mould_insert import channel_block

from lattice_cad.core.errors import LatticeWarning


@pytest.mark.slow
def test_the_patches_of_a_face_are_meshed_finer_only_when_they_all_fit(monkeypatch):
    from conformal import load_part
    from conformal.trim import cutting_part
    from lattice_cad.occ_impl import chord

    shape = channel_block()
    assert shape.isValid()
    part = load_part(shape)
    clean_around = chord._clean_around
    asked: list[float] = []

    def predicted(shape, scale):
        # the first round: every face at the cutting chord error; those in ``scale`` at
        # ``s`` times it grow about as 1 / s
        if isinstance(scale, dict) and not asked:  # (a list: the knot rounds before)
            counts = chord._triangle_counts(chord._faces(shape)).astype(np.float64)
            idx = np.array(sorted(scale))
            s = np.array([scale[i] for i in idx])
            total = counts.sum() + float((counts[idx] * (1.0 / s - 1.0)).sum())
            cap = max(float(chord.FINER_MAX_TRIANGLES), 2.0 * float(counts.sum()))
            asked.append(total)
            assert total <= cap, f"{len(idx)} faces meshed finer: {total:.3g} triangles > {cap:.3g}"
        return clean_around(shape, scale)

    monkeypatch.setattr(chord, "_clean_around", predicted)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always", LatticeWarning)
        cut = cutting_part(part, 0.666667)
    said = " | ".join(str(w.message) for w in rec)
    assert cut is not part and len(cut.faces) > len(part.faces)
    # the channel's face is left over the chord error asked, and the warning says so
    assert "could not be tessellated within the chord error asked" in said, said
