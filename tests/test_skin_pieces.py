"""``conformal.skin._keep_attached`` on the arrays (s31): the islands the whole-lattice
booleans leave are found by ``conformal.skin_split.pieces``, not ``Manifold.decompose``.

Found on a dome shelled to 1.8 mm (made outside shared/data) under a skin of 0.8 mm: the
0.2 mm cavity, cut by 0.8 mm struts, fell into 2,295 closed voids, and ``decompose`` of the
1.08 M-triangle result ran for more than 5 minutes (its pieces on the arrays: 1.2 s). Here
the answer is known in closed form: a block (on the outer surface: the one body) with
1,728 small cubic cavities (each kept: negative pieces are cavity walls) and five islands
clear of it (removed).
"""

from __future__ import annotations

import numpy as np

from conformal import skin
from tests.test_check import join


def _cube(lo, size, *, inward=False):
    import trimesh

    m = trimesh.creation.box(extents=(size, size, size))
    v = np.asarray(m.vertices) + np.asarray(lo, dtype=float) + size / 2.0
    f = np.asarray(m.faces, dtype=np.int64)
    return v, (f[:, ::-1] if inward else f)


def test_many_cavities_are_kept_and_islands_dropped():
    cavities = [_cube((1 + 2 * i, 1 + 2 * j, 1 + 2 * k), 1.0, inward=True)
                for i in range(12) for j in range(12) for k in range(12)]  # fmt: skip
    islands = [_cube((40 + 3 * i, 0, 0), 1.0) for i in range(5)]
    block = _cube((0, 0, 0), 26.0)
    # the block with its 1,728 voids and five islands clear of it
    v, f = join(block, *cavities, *islands)
    solid = skin._manifold(v, f, "test solid")
    outer = skin._manifold(*block, "outer")
    kept, bodies, removed, voids = skin._keep_attached(solid, outer)
    assert (bodies, removed, len(voids)) == (1, 5, 1728)
    np.testing.assert_allclose(voids, 1.0)  # each cavity's volume
    assert abs(kept.volume() - (26.0**3 - 1728 * 1.0)) < 1e-6 * 26.0**3
    assert len(kept.decompose()) == 1 + 1728

    # nothing to remove: the solid as it is
    v2, f2 = join(block, *cavities[:10])
    solid2 = skin._manifold(v2, f2, "test solid")
    same, bodies2, removed2, voids2 = skin._keep_attached(solid2, outer)
    assert (bodies2, removed2, len(voids2)) == (1, 0, 10) and same is solid2
