"""The part's surface a skin is built on: tessellated for the wall's tolerance, not for the
strut radius (the struts are cut by the inner wall), and OCCT's offsets are checked
against it; the voxel field's exact band distances come in chunks."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from conformal import skin as S
from conformal.part import Part
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import DATA


def test_outer_chord_is_a_quarter_of_the_wall_tolerance():
    # the tolerance is max(2 % t, 0.02 mm): 0.03 mm for t = 1.5, 0.02 mm below t = 1
    assert S.outer_chord(1.5) == pytest.approx(0.0075, rel=1e-12)
    assert S.outer_chord(4.0) == pytest.approx(0.02, rel=1e-12)
    assert S.outer_chord(0.5) == pytest.approx(0.005, rel=1e-12)
    assert S.outer_chord(1.0) == pytest.approx(0.005, rel=1e-12)


@pytest.mark.slow
def test_skinned_real_part_is_cut_by_the_walls_chord_and_exact_against_the_brep():
    """At the parts benchmark's setting (cell = extent / 15, r = cell / 12, t = cell / 6)
    the skin is built on the part tessellated with ``outer_chord(t)`` (twice the chord
    error the radius would ask), and measured against the *exact* B-rep (OpenCascade's
    distance): the outside of the written solid stands out of the part by at most that
    chord error (and the float32 rounding), and the inner wall lies t deep within the
    wall's tolerance."""
    from lattice_cad.lattice import Lattice
    from lattice_cad.occ_impl.distance import signed_distance

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(DATA / "step" / "kcl_mounting-plate.step", "octet", 6.0, 0.5, skin=1.0)
        mesh = lat.mesh()
    t = 1.0
    chord = S.outer_chord(t)
    assert lat.skin_report.method == "occt" and lat.skin_report.accurate, lat.skin_report
    assert lat.skin_report.bodies == 1
    cut = lat._cutting_part
    assert cut.deflection == pytest.approx(chord, rel=1e-12)
    assert cut.deflection > 0.005 * 0.5  # coarser than the radius's 0.5 % r: the point
    solids = list(lat.part.shape)
    # outside: the vertices the part's default mesh finds farthest out, exactly
    v = mesh.vertices
    worst = np.argsort(lat.part.signed_distance(v))[::-1][:300]
    exact = signed_distance(solids, v[worst])
    rounding = 2.0 * float(np.spacing(np.float32(np.abs(v).max())))
    assert exact.max() <= chord + rounding, exact.max()
    assert exact.max() > -1e-3  # the candidates lie on the surface: the test can fail
    # inside: random points of the inner wall, t deep in the exact B-rep
    inner = S._occt_surfaces(cut, t)[1]
    vi, fi = S.to_arrays(inner)
    pts = trimesh.Trimesh(vi, fi, process=False).sample(3000, seed=11)
    depth = -signed_distance(solids, pts)
    tol = S.wall_tolerance(t)
    assert np.all(np.abs(depth - t) <= tol), (depth.min(), depth.max())


def test_voxel_field_in_chunks_equals_the_field_in_one_piece(monkeypatch):
    """The band's exact distances computed in chunks (a caller waiting for OCCT looks
    again between them) give exactly the field computed in one piece."""
    mesh = trimesh.creation.annulus(r_min=2.0, r_max=6.0, height=5.0, sections=40)
    part = Part(mesh.vertices, mesh.faces, name="ring")
    t, h = 1.0, 0.25
    whole, origin = S._distance_field(part, t, h)
    monkeypatch.setattr(S, "DISTANCE_CHUNK", 97)
    steps = S._distance_field_steps(part, t, h)
    stages = 0
    try:
        while True:
            next(steps)
            stages += 1
    except StopIteration as stop:
        chunked, origin2 = stop.value
    assert stages > 10  # yielded between the chunks (one stage before them)
    np.testing.assert_array_equal(chunked, whole)
    np.testing.assert_array_equal(origin2, origin)
