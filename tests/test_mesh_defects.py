"""Mesh files with a crack and repeated triangles (s37).

A prosthetic foot's keel made outside shared/data (190 x 55 x 94 mm, as an STL with a
0.004 mm crack across it, its two sides exported apart, and 36 triangles stored twice)
was refused as "not a closed solid: 8 open edges around 2 holes ... --close-holes closes
them"; with --close-holes, "no holes" and the same refusal: the repeated triangles, whose
edges are used three and four times, hid the holes from the closing, and were only
dropped when no hole was named first. The repeated triangles are now dropped whenever the
mesh is not closed, and open rims are welded up to 1e-4 of the diagonal
(``config.WELD_OPEN_RTOLS``): the crack is closed, one body.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conformal import load_part
from lattice_cad.core.errors import LatticeWarning


def _box() -> trimesh.Trimesh:
    """A 2 mm cube centred on the origin, with vertices on the plane x = 0."""
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    v, f = trimesh.remesh.subdivide(box.vertices, box.faces)
    v, f = trimesh.remesh.subdivide(v, f)
    return trimesh.Trimesh(v, f, process=True)


def test_repeated_triangles_do_not_hide_a_hole(tmp_path):
    box = _box()
    f = np.asarray(box.faces)
    faces = np.vstack([f[1:], f[5:9]])  # one triangle missing, four stored twice
    path = tmp_path / "holed.stl"
    trimesh.Trimesh(box.vertices, faces, process=False).export(path)
    with pytest.warns(LatticeWarning) as rec:
        part = load_part(path, close_holes=True)
    said = " | ".join(str(w.message) for w in rec)
    assert "4 triangle(s) stored twice were kept once" in said
    assert "1 hole(s) closed with 1 triangle(s)" in said
    assert part.volume == pytest.approx(8.0, rel=1e-9)
    assert len(part.faces) == len(f)


def test_a_crack_between_two_halves_is_welded(tmp_path):
    box = _box()
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    right = v[f].mean(axis=1)[:, 0] > 0
    # the right half's triangles on copies of their vertices, moved 1.9e-5 x the diagonal
    crack = 1.9e-5 * float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    used = np.unique(f[right])
    copy = np.full(len(v), -1)
    copy[used] = len(v) + np.arange(len(used))
    v2 = np.vstack([v, v[used] + [crack, 0.0, 0.0]])
    f2 = f.copy()
    f2[right] = copy[f[right]]
    path = tmp_path / "cracked.stl"
    trimesh.Trimesh(v2, f2, process=False).export(path)
    with pytest.warns(LatticeWarning, match="were welded .* no after"):
        part = load_part(path)
    assert part.volume == pytest.approx(8.0, rel=1e-4)
    tm = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert tm.is_watertight and tm.body_count == 1
