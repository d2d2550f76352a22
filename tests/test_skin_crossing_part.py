"""A skin on a mesh whose surface crosses itself in a few places (regression, s38).

A knee implant's femoral component made outside shared/data
(``regression_knee_selfx.off.gz``: an OFF mesh, 8.5 mm J-shaped shell; a sculpt brush
pushed a dimple through its 5.5 mm wall, whose tip pokes about 1 mm out of the inner face)
crosses itself in 16 pairs of triangles, fewer than ``config.SKIN_FOLD_PAIRS``: the skin is
built on that surface as it is, and its outer wall crossed itself with it. Every retry (the
mid-wall surface, the lattice shifted, both) kept the same outer wall; after four tries of
68 crossing pairs each the skin was refused ("the lattice cannot be written in single
precision"), 216 s for the benchmark's setting. The retries now begin with the part's
surface rebuilt from the region it encloses (``conformal.unfold``), said in a warning with
how far it stands out of the part.
"""

from __future__ import annotations

import re
import warnings

import pytest

from conformal import load_part
from conformal.trim import protrusion
from lattice_cad import Lattice
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import assert_valid, gunzipped


@pytest.fixture(scope="module")
def knee(tmp_path_factory):
    return gunzipped("regression_knee_selfx.off.gz", tmp_path_factory)


@pytest.mark.slow
def test_a_skin_on_a_surface_that_crosses_itself_a_little_is_written(knee, tmp_path):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        part = load_part(knee)
        pairs = part.self_crossings[0]
        # fewer pairs than make a folded wall (which goes to the rebuild at once)
        assert 0 < pairs < config.SKIN_FOLD_PAIRS
        lat = Lattice.fill(part, cell="octet", cell_size=9.2, radius=0.7667, skin=0.7667)
        mesh = lat.mesh()
        path = tmp_path / "knee.stl"
        lat.save(path)
    texts = [str(w.message) for w in said if issubclass(w.category, LatticeWarning)]
    assert any(f"crosses itself ({pairs} pair" in t for t in texts)
    assert lat.skin_retry == "rebuilt"
    # the wall of the skin written, once: not also that of the first skin, thrown away
    walls = [t for t in texts if t.startswith("the skin's wall")]
    w = lat.skin_report.wall
    assert len(walls) == 1 and f"is {w['min']:.4g} .. {w['max']:.4g} mm thick" in walls[0]
    h = lat.skin_report.rebuilt
    assert 0 < h < 0.5
    # said, with how far the skin stands out of the part; and it does no farther
    out = [re.search(r"the skin stands up to ([\d.e-]+) mm out", t) for t in texts]
    said_out = [float(m.group(1)) for m in out if m]
    assert len(said_out) == 1
    assert protrusion(part, mesh.vertices) <= said_out[0] * 1.01 + 1e-6
    assert said_out[0] <= 0.7 * h * 1.5  # the rebuild's concave creases: about 0.7 x grid
    assert_valid(mesh)  # crossing faces none (pymeshlab, confirmed exactly), manifold3d
    import trimesh

    back = trimesh.load(path)  # the file written: the same closed solid
    assert back.is_watertight and back.is_winding_consistent
    made = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).volume
    assert back.volume == pytest.approx(made, rel=1e-5) and made > 0
