"""The chord-checked tessellation stays bounded on faces BRepMesh cannot follow.

kcl_exhaust-manifold_overlapping_solids.step (shared/data/broken, five overlapping
solids): BRepMesh meshes two B-spline faces of each solid 10-20 times coarser than asked.
Knot insertion made them worse round after round (11.8 -> 14.9 -> 19.3 x the limit) and
meshing them alone finer and finer took 290 K, then 610 K triangles for one face: a
default ``lattice-cad fill`` of the part spent over 8 minutes in the cutting tessellation.
Now a face is meshed alone finer only while the whole mesh stays under
``FINER_MAX_TRIANGLES`` (the cutting budget with its
1.5 margin); what is left is reported unresolved (``ChordReport.unresolved``). And knots
stop once they leave a face far worse than before (``chord.KNOT_GIVE_UP``): the first
solid took 8 knot rounds and 231 s, ending 0.49 mm off; now 2 rounds, 39 s, and the plain
mesh (0.38 mm off).
"""

from __future__ import annotations

import pytest

from conformal.part import load_part
from lattice_cad.core import config
from lattice_cad.occ_impl import chord
from lattice_cad.occ_impl.shapes import copied
from tests.conftest import DATA

EXHAUST = DATA / "broken" / "kcl_exhaust-manifold_overlapping_solids.step"
pytestmark = pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")


def _first_solid():
    part = load_part(EXHAUST)
    return copied(list(part.shape)[0])


@pytest.mark.slow
def test_finer_meshing_keeps_the_triangle_budget(monkeypatch):
    alone = []
    mesh_alone = chord._mesh_alone

    def recorded(shape, asked, deflection, angular):
        alone.append(dict(asked))
        mesh_alone(shape, asked, deflection, angular)

    monkeypatch.setattr(chord, "_mesh_alone", recorded)
    solid = _first_solid()
    meshed, report = chord.mesh_checked(solid, 0.0216, 0.3, factor=config.CHORD_CONTROL)
    total = int(chord._triangle_counts(chord._faces(meshed)).sum())
    # the finer stage may run once within the budget; it never meshes a face alone to
    # more than the budget allows, and the faces it cannot bring down are reported
    assert len(alone) <= 1
    assert total <= 1.2 * chord.FINER_MAX_TRIANGLES
    assert set(report.unresolved) >= {0, 3} - set(report.finer)
    # knots made both faces far worse in the second round: given up, the plain mesh kept
    assert report.rounds == 2 and report.refined == []
    assert meshed is solid
