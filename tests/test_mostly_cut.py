"""A cut that removes most of the lattice is said (regression, s28's parts made outside
shared/data): a 3 m machine bed with 200 mm cells kept 252 of its 456 conforming struts
across its pockets, outside the part; the cut removed 94 % of the lattice's volume and the
fill was written (relative density 0.008) with one report line of mm^3 removed."""

from __future__ import annotations

import warnings

import pytest

from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning


def _channel(tmp_path):
    """A U-channel 120 x 120 x 60 mm with 5 mm walls and floor."""
    import cadquery as cq

    u = cq.Workplane("XY").box(120, 120, 60)
    u = u.cut(cq.Workplane("XY").box(110, 130, 60).translate((0, 0, 5)))
    path = tmp_path / "channel.step"
    cq.exporters.export(u, str(path))
    return path


def test_a_cut_that_removes_most_of_the_lattice_warns(tmp_path):
    path = _channel(tmp_path)
    lat = Lattice.fill(path, "bcc", 40.0, 2.0, fill="conform")
    with pytest.warns(LatticeWarning, match=r"removed (\d+) % of the lattice's volume") as said:
        lat.mesh()
    rep = lat.trim_report
    assert rep.share_removed > 0.5, rep.summary()
    assert f"{100 * rep.share_removed:.0f} %" in str(said[-1].message)
    assert rep.volume_before == pytest.approx(lat.mesh(lattice_only=True).volume, rel=1e-6)


def test_a_cut_that_removes_little_does_not_warn(tmp_path):
    path = _channel(tmp_path)
    lat = Lattice.fill(path, "bcc", 8.0, 0.8, fill="conform")
    with warnings.catch_warnings():
        warnings.simplefilter("error", LatticeWarning)
        lat.mesh()
    assert lat.trim_report.share_removed < 0.5
