"""Issue 12 item 8: every public operation that returns a boolean result checks it in full.

A solid of two overlapping bodies is 2-manifold for manifold3d (status NoError) but not a
valid printable solid: its faces cross. ``conformal.skin.checked`` must refuse it and say
where; valid results pass unchanged.
"""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest

from conformal import skin
from lattice_cad.core.errors import SkinError


def test_overlapping_bodies_are_refused_with_a_place():
    v, f = skin.to_arrays(manifold3d.Manifold.cube((1.0, 1.0, 1.0)))
    both = manifold3d.Mesh(
        vert_properties=np.vstack([v, v + [0.5, 0.25, 0.125]]).astype(np.float32),
        tri_verts=np.vstack([f, f + len(v)]).astype(np.uint32),
    )
    bad = manifold3d.Manifold(both)
    assert bad.status() == manifold3d.Error.NoError  # manifold3d alone does not see it
    with pytest.raises(
        SkinError, match=r"(?s)the test solid is not a valid solid.*self-intersecting.*near \("
    ):
        skin.checked(bad, "the test solid")


def test_a_valid_solid_passes_unchanged():
    cube = manifold3d.Manifold.cube((2.0, 2.0, 2.0))
    assert skin.checked(cube, "a cube") is cube


def test_hollow_and_inset_results_are_checked_and_valid():
    import cadquery as cq

    from conformal import load_part

    part = load_part(cq.Workplane("XY").box(20, 16, 12))
    shell = skin.hollow(part, 2.0)
    cavity = skin.inset(part, 2.0)
    # closed forms (the voxel method's surfaces lie within the wall tolerance)
    assert cavity.volume() == pytest.approx(16 * 12 * 8, rel=0.03)
    assert shell.volume() == pytest.approx(20 * 16 * 12 - 16 * 12 * 8, rel=0.03)
    v, f = skin.to_arrays(shell)
    assert np.all(np.isfinite(v)) and len(f) > 0
