"""The cutting tessellation's triangle budget (issue 13 item 2): a named warning with the
chord error reached, reported by info() and the CLI; the budget is used, not guessed."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lattice_cad.core.errors import CutBudgetWarning


def _plate():
    import cadquery as cq

    return cq.Workplane().box(30, 30, 10).faces(">Z").workplane().hole(8)


def _part():
    from conformal.part import load_part

    return load_part(_plate())


def test_no_warning_within_budget():
    from conformal.trim import cut_shortfall, cutting_part

    part, r = _part(), 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error", CutBudgetWarning)
        cut = cutting_part(part, r)
    assert cut.deflection == pytest.approx(0.005 * r)
    assert cut_shortfall(part, cut, r) is None


def test_budget_binds(monkeypatch):
    from conformal.trim import cut_shortfall, cutting_part
    from lattice_cad.core import config
    from lattice_cad.occ_impl.distance import signed_distance

    part, r = _part(), 0.5
    monkeypatch.setattr(config, "CUT_MAX_TRIANGLES", 200)
    with pytest.warns(CutBudgetWarning, match=r"% of the strut radius.*budget") as rec:
        cut = cutting_part(part, r)
    assert part.name in str(rec[0].message)
    short = cut_shortfall(part, cut, r)
    assert short is not None and short > 0.5
    assert short == pytest.approx(100 * cut.deflection / r)
    assert f"{short:.2f} %" in str(rec[0].message)
    # the budget is used (measured counts, not the 1 / chord guess) but not exceeded much
    assert 0.3 * 200 < len(cut.faces) <= 1.5 * 200
    # the chord error reported is what the mesh has against the exact B-rep: the hole's
    # polygon lies outside the exact cylinder by up to about that much
    c = cut.vertices[cut.faces].mean(axis=1)
    near_hole = c[np.hypot(c[:, 0], c[:, 1]) < 4.5]
    d = signed_distance(list(part.shape), near_hole)
    assert 0.2 * cut.deflection < d.max() <= 1.05 * cut.deflection


@pytest.mark.filterwarnings("ignore:.*struts were thinned")
def test_lattice_reports_the_budget(monkeypatch):
    from lattice_cad.core import config
    from lattice_cad.lattice import Lattice

    monkeypatch.setattr(config, "CUT_MAX_TRIANGLES", 200)
    lat = Lattice.fill(_plate(), "bcc", 5.0, 0.5, fill="clip")
    assert lat.cut_shortfall() is None  # nothing cut yet
    with pytest.warns(CutBudgetWarning):
        lat.mesh()
    short = lat.cut_shortfall()
    assert short is not None and short > 0.5
    assert lat.info()["cut_budget"] == short
