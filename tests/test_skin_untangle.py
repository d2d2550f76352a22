"""conformal.skin_untangle: folds of an inner wall collapsed before the skin's booleans."""

from __future__ import annotations

import numpy as np
import trimesh

import fast_stitch
from conformal.skin import _manifold, to_arrays
from conformal.skin_untangle import untangle
from lattice_cad.core.mesh import Mesh


def _folded_box() -> tuple[np.ndarray, np.ndarray]:
    """A unit box whose top face is a fan around a vertex pulled out past its edge and
    a little down: the fan's faces fold over each other (3 intersecting pairs)."""
    box = trimesh.creation.box(extents=(1, 1, 1))
    v = np.asarray(box.vertices, dtype=np.float64)
    f = np.asarray(box.faces, dtype=np.int64)
    top = np.all(np.isclose(v[f][:, :, 2], 0.5), axis=1)
    square = ((-0.5, -0.5, 0.5), (0.5, -0.5, 0.5), (0.5, 0.5, 0.5), (-0.5, 0.5, 0.5))
    corners = [int(np.flatnonzero(np.all(np.isclose(v, p), axis=1))[0]) for p in square]
    c = len(v)
    fan = [[c, corners[k], corners[(k + 1) % 4]] for k in range(4)]
    return np.vstack([v, [[0.7, 0.0, 0.45]]]), np.vstack([f[~top], fan])


def test_untangle_collapses_a_fold_and_keeps_the_solid_closed():
    v, f = _folded_box()
    before = fast_stitch.check(Mesh(vertices=v, faces=f))
    assert before.watertight and before.oriented and before.n_self_intersections
    out, collapsed = untangle(_manifold(v, f, "the folded box"))
    assert collapsed > 0
    v2, f2 = to_arrays(out)
    assert fast_stitch.check(Mesh(vertices=v2, faces=f2)).valid
    assert abs(out.volume() - 1.0) < 0.2  # the fold went, not the box


def test_untangle_leaves_a_valid_surface_as_it_is():
    import manifold3d

    sphere = manifold3d.Manifold.sphere(2.0, 32)
    out, collapsed = untangle(sphere)
    assert out is sphere and collapsed == 0
    empty = manifold3d.Manifold()
    assert untangle(empty) == (empty, 0)
