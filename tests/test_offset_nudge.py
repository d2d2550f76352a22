"""Regression: OCCT's offset of the README's example bracket fails at exactly 1 mm (null
shape; 0.9999 and 1.001 mm give one valid solid), so the README's own first command got the
voxel fallback's wall (0.959 .. 1.127 mm, "NOT within"). ``offset_solid`` now nudges the depth
(``OFFSET_NUDGES``) before it gives up, and the skin's wall is exact."""

from __future__ import annotations

import manifold3d
import pytest

from conformal import load_part
from conformal import skin as S
from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl import shapes as occ
from tests.conftest import ROOT

BRACKET = ROOT / "examples" / "bracket.step"


def test_occt_fails_at_exactly_one_mm_as_it_is():
    """The premise: without the nudge (no factors) OCCT gives no solid at -1 mm."""
    part = load_part(BRACKET)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(occ, "OFFSET_NUDGES", ())
        with pytest.raises(OCCTFailure, match="null shape"):
            occ.offset_solid(part.shape[0], -1.0)


def test_the_nudged_offset_is_one_valid_solid_one_mm_in():
    part = load_part(BRACKET)
    solid = occ.offset_solid(part.shape[0], -1.0)
    assert occ.is_valid(solid)
    # inside the part, thinner by about (area x 1 mm)
    assert 0.0 < occ.volume(solid) < occ.volume(part.shape[0])


def test_readme_example_skin_takes_the_exact_path():
    part = load_part(BRACKET)
    rep = S.build_skin(manifold3d.Manifold(), part, 1.0).report
    assert rep.method == "occt", rep.fallback
    assert rep.accurate, rep.wall
    assert abs(rep.wall["min"] - 1.0) <= 0.02 and abs(rep.wall["max"] - 1.0) <= 0.02
