"""Solids that touch are united by OpenCascade's fuse before they are tessellated (s37).

A golf club head made outside shared/data (``regression_golf_head.step.gz``, by CadQuery: a
hollow 2.5 mm ellipsoid shell with a hosel, and a separate face insert whose rim faces
coincide with the shell's opening) was tessellated solid by solid and the meshes united:
the rim, meshed twice and differently, left slivers between the two meshes. The bcc fill's
cut by the part then had surfaces a float32 step apart there and was not applied (the
lattice written uncut, 1.66 mm out of the part); the skin was refused after 75 s
("119 vertex(es) are pinched when coordinates are rounded to single precision").
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from conformal import load_part
from conformal.trim import protrusion
from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import assert_valid, gunzipped


@pytest.fixture(scope="module")
def golf(tmp_path_factory):
    return gunzipped("regression_golf_head.step.gz", tmp_path_factory)


def test_touching_solids_are_one_solid_with_their_volumes(golf):
    with pytest.warns(LatticeWarning, match=r"2 solids were united into one part$"):
        part = load_part(golf)
    # tessellated as one solid; the solids as given stay the part's shape (keep selectors)
    assert len(part.united) == 1 and len(part.shape) == 2
    # the shell (65,813 mm^3) and the insert (5,329.8 mm^3) do not overlap: their sum
    assert part.volume == pytest.approx(65813.03 + 5329.80, rel=1e-2)  # (chords: -0.44 %)
    from lattice_cad.occ_impl import shapes as occ

    assert occ.volume(part.united[0], eps=1e-6) == pytest.approx(71142.83, rel=1e-5)
    # a finer tessellation is of the united solid, on the same grid
    fine = part.refined(part.deflection / 4)
    assert fine.united is part.united and fine.shape is part.shape
    assert_valid(fine)


@pytest.mark.slow
def test_the_cut_and_the_skin_of_a_shell_with_an_insert(golf):
    with pytest.warns(LatticeWarning, match="united"):
        part = load_part(golf)
    cell = float(part.size.max()) / 15
    r = cell / 12
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(golf, cell="bcc", cell_size=cell, radius=r)
        mesh = lat.mesh()
    rep = lat.trim_report
    assert not rep.failed and rep.trimmed and rep.within_tolerance, rep.summary()
    assert protrusion(part, mesh.vertices) <= max(rep.tolerance, part.deflection)
    assert_valid(mesh)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(golf, cell="octet", cell_size=cell, radius=r, skin=cell / 6)
        mesh = lat.mesh()
    assert lat.skin_report is not None
    assert_valid(mesh)
    assert mesh.volume == pytest.approx(part.volume, rel=0.02)  # 2.5 mm walls: nearly solid
    assert np.isfinite(mesh.volume)


def test_solids_apart_are_said_to_stay_apart(tmp_path):
    """Regression (s38's print-in-place hinge, two leaves 0.3 mm apart): the load said "2
    solids were united into one part", and every fill then gave 2 bodies. Solids that touch
    nothing are not united: the warning says the part has as many bodies as solids; with a
    pair that touches, it says how many bodies the fused part has."""
    import cadquery as cq

    apart = tmp_path / "apart.step"
    a = cq.Workplane().box(10, 10, 4)
    b = cq.Workplane().box(10, 10, 4).translate((10.3, 0, 0))
    cq.exporters.export(cq.Workplane().add(a.val()).add(b.val()), str(apart))
    with pytest.warns(LatticeWarning) as rec:
        part = load_part(apart)
    said = [str(w.message) for w in rec]
    assert said == [f"{apart}: 2 solids, none touching another, make one part of 2 bodies"]
    assert part.united is None  # nothing fused: tessellated one by one
    assert part.volume == pytest.approx(800.0, rel=1e-9)

    three = tmp_path / "three.step"
    c = cq.Workplane().box(10, 10, 4).translate((0, 10, 0))  # shares a face with a
    cq.exporters.export(cq.Workplane().add(a.val()).add(b.val()).add(c.val()), str(three))
    with pytest.warns(LatticeWarning) as rec:
        part = load_part(three)
    said = [str(w.message) for w in rec]
    assert said == [
        f"{three}: 3 solids were united into one part of 2 bodies "
        "(those touching or overlapping were fused)"
    ]
    assert len(part.united) == 2
