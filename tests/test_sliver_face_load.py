"""A valid solid with a sliver face BRepMesh leaves without triangles loads (s40).

A turbocharger volute made outside shared/data by CadQuery (``regression_volute_sliver
.step.gz``: a lofted spiral with an exit duct started 1 mm behind its last section) has a
valid planar face about 0.05 mm wide (face 12). At the load's chord error (0.26 mm) BRepMesh
left that face without triangles, and every fill of the part failed with "BRepMesh left a
face without triangulation", naming neither face nor file; at 0.2 mm the mesh had holes
bordering faces 9, 12 and 16. The tessellation is now tried again at a quarter of the chord
error (healed or not) before the solid is refused.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conformal import load_part
from lattice_cad.occ_impl import shapes as occ
from tests.conftest import gunzipped


def test_a_valid_solid_with_a_sliver_face_loads_closed(tmp_path_factory):
    import cadquery as cq

    path = gunzipped("regression_volute_sliver.step.gz", tmp_path_factory)
    shape = cq.importers.importStep(str(path)).val()
    assert shape.isValid() and len(shape.Solids()) == 1
    part = load_part(path)  # (before: OCCTFailure, a face without triangulation)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    # the mesh encloses the B-rep's volume (chords cut a little off the curved walls)
    assert mesh.volume == pytest.approx(occ.volume(shape.wrapped), rel=0.01)
    assert float(np.abs(part.vertices).max()) < 200.0
