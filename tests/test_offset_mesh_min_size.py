"""OCCT's offsets are meshed with no triangle edge shorter than the chord error (s40).

The skin's inner wall is OpenCascade's offset of the part, meshed in a child process at a
chord error of 1 % of the wall. On a mould insert made outside shared/data (an 8 mm
cooling channel swept along a 3-D spline), the offset by 1.3333 mm is made in 0.7 s, but
BRepMesh, at its default smallest triangle (a tenth of the chord error), kept adding nodes
to one of the channel's offset faces: the child had not finished after 10 minutes, the
offsets timed out (``config.OFFSET_TIMEOUT``, 60 s), and the skin fell back to the voxel
surfaces (110 s in all, the wall 1.267 .. 1.561 mm for 1.3333, 7,278 points out of
tolerance). With BRepMesh's ``MinSize`` at the chord error the offset meshes in about 4 s.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from mould_insert import channel_block

from lattice_cad.core import config


@pytest.mark.slow
def test_the_offset_of_a_swept_channel_is_meshed_within_the_offsets_budget():
    from conformal import load_part
    from conformal.skin import start_solid_offsets, wall_tolerance
    from lattice_cad.occ_impl import shapes as occ
    from lattice_cad.occ_impl.distance import signed_distance

    shape = channel_block()
    assert shape.isValid()
    thickness = 1.3333
    pending = start_solid_offsets([shape.wrapped], thickness)
    try:
        # (before: OCCTFailure, "OCCT's offset did not finish within 60 s of its start")
        results = occ.fused_offsets_result(
            pending.worker, timeout=config.OFFSET_TIMEOUT, budget=config.OFFSET_TIMEOUT
        )
    finally:
        pending.worker.close()
    assert len(results) == 1
    (vols, meshes) = results[0]
    assert meshes is not None and 0.0 < vols[1] < vols[0]
    v, f = meshes[0]
    # a closed, consistently wound surface (trimesh), enclosing the offset's volume
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(vols[1], rel=2e-3)
    # its nodes lie on the offset: inside the part (its mesh), at the wall's depth below its
    # surface (OCCT's exact distance, unsigned: its classifier calls a few of these points,
    # inside by the mesh, outside; 100 nodes spread over the mesh, 0.1 s each)
    part = load_part(shape)
    assert bool(np.all(part.contains(v)))
    depth = np.abs(signed_distance([shape.wrapped], v[:: len(v) // 100]))
    assert float(np.abs(depth - thickness).max()) <= wall_tolerance(thickness)
