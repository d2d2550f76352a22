"""A cut that float32 cannot hold is made again by a finer cutting tessellation (s37).

A model-rocket fin can made outside shared/data (``regression_rocket_fins.step.gz``, by
CadQuery: body and motor tubes, centring rings, fins through the wall whose edge at the
root's top is flush with the body tube, r = 33 mm): the bcc fill's cut by the part's
cutting tessellation had surfaces a float32 step apart at that edge, and again with the
part moved off its surface (the retry), so the lattice was written uncut, 2.32 mm out of
the part. The cut is now made again by a tessellation with 0.8 x the chord error
(``config.RETRIM_FINER``), within the trim's tolerance.
"""

from __future__ import annotations

import warnings

import pytest

from conformal.trim import protrusion
from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import assert_valid, gunzipped


@pytest.fixture(scope="module")
def rocket(tmp_path_factory):
    return gunzipped("regression_rocket_fins.step.gz", tmp_path_factory)


@pytest.mark.slow
def test_a_fin_flush_with_its_tube_is_cut_within_the_tolerance(rocket):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(rocket, cell="bcc", cell_size=10.0, radius=0.8333)
        mesh = lat.mesh()
    rep = lat.trim_report
    assert not rep.failed and rep.trimmed and rep.within_tolerance, rep.summary()
    # against the cutting tessellation the first cut used (independent of the retry's)
    assert protrusion(lat._cutting_part, mesh.vertices) <= rep.tolerance
    assert_valid(mesh)
