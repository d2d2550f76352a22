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


def _prism(diagonals: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A closed triangular prism, each side quad split along one of its two diagonals."""
    v = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = [(0, 1, 2), (3, 5, 4)]
    for (a, b, c, d), k in zip(((0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)), diagonals, strict=True):
        f += [(a, d, c), (a, c, b)] if k == 0 else [(a, d, b), (b, d, c)]
    faces = np.array(f, dtype=np.int64)
    if trimesh.Trimesh(v, faces, process=False).volume < 0:
        faces = faces[:, ::-1].copy()
    return v, faces


def test_collapse_faces_keeps_the_surface_manifold():
    """Regression: collapsing the shortest edge of a face whatever its neighbourhood could
    join two sheets of the surface in a vertex (a pinch no later collapse removes); the
    untangling of the Ventilator's inner wall then never became valid. An edge whose
    vertices share a neighbour besides its two opposite corners is not collapsed: the
    face's next edge is."""
    from lattice_cad.io import collapse_faces
    from lattice_cad.io.rounding import pinched_vertices

    v, f = _prism((0, 0, 1))  # the top face's shortest edge (0, 1): 0 and 1 share 2, 4, 5
    assert fast_stitch.check(Mesh(vertices=v, faces=f)).valid
    v2, f2 = collapse_faces(v, f, np.array([0]))
    assert len(f2) == len(f) - 2  # one edge went
    report = fast_stitch.check(Mesh(vertices=v2, faces=f2), self_intersections=False)
    assert report.watertight and report.manifold and report.oriented, report
    assert len(pinched_vertices(f2, len(v2))) == 0


def test_simplified_wall_backs_off_where_folds_cannot_be_collapsed(monkeypatch):
    """conformal.skin._simplified: a simplification whose folds ``unfolded`` cannot repair
    is replaced by one with a smaller tolerance (more triangles)."""
    import manifold3d

    from conformal import skin

    sphere = manifold3d.Manifold.sphere(1.0, 96)
    seen: list[int] = []
    real = skin.unfolded

    def first_fails(surface, name="x"):
        seen.append(surface.num_tri())
        return None if len(seen) == 1 else real(surface, name)

    monkeypatch.setattr(skin, "unfolded", first_fails)
    out = skin._simplified(sphere, 0.01, "the sphere")
    assert len(seen) == 2 and seen[1] > seen[0]
    assert out.num_tri() == seen[1]
