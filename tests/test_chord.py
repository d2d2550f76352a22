"""The cutting tessellation follows the exact surface face by face (issue 13 item 2).

BRepMesh does not honour the chord error on face 78 of ``trimesh_featuretype.STEP`` (a
twisted ruled B-spline, degree 3 x 1): its triangles span the face diagonally, 0.08 mm
(25 times the 0.0035 mm asked) from the surface, and a clip fill cut by that mesh stood
11 % r out of the part. ``occ_impl.chord`` measures every face against its exact surface
and refines such faces; checked here by OpenCascade's exact point-to-B-rep distance, which
does not use the check's own measure.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import DATA

FEATURETYPE = DATA / "step" / "trimesh_featuretype.STEP"
#: The parts benchmark's dimensions for this part (cell = extent / 15, r = cell / 12).
CELL, R = 8.46667, 0.705556


@pytest.fixture(scope="module")
def part():
    from conformal import load_part

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_part(FEATURETYPE)


def test_plain_brepmesh_misses_the_chord_error_and_the_check_refines_it(part):
    from lattice_cad.core import config
    from lattice_cad.occ_impl import chord, shapes
    from lattice_cad.occ_impl.distance import signed_distance

    solid = part.shape[0]
    defl = 0.005 * R
    # plain BRepMesh: face 78 is 20+ times coarser than asked (so the test can fail)
    plain = shapes.copied(solid)
    list(shapes.face_triangulations(plain, defl, 0.3))
    dev = chord.face_deviations(plain, defl)
    assert int(np.argmax(dev)) == 78 and dev[78] > 20 * defl, dev.max() / defl

    v, f, report = shapes.tessellate(solid, defl, 0.3, control=config.CHORD_CONTROL)
    assert report.refined == [78] and report.unresolved == [], report
    assert report.max_deviation <= config.CHORD_CONTROL * defl, report.max_deviation / defl
    # the caller's shape keeps its own surface (the knots went into a copy)
    surface = chord._bspline(chord._faces(solid)[78])
    assert (surface.NbUKnots(), surface.NbVKnots()) == (8, 2)

    # independent: OCCT's exact distance of triangle centroids and edge midpoints to the
    # B-rep, where the plain mesh deviated (face 78's box) and over the whole mesh
    lo, hi = _bounds(solid, 78)
    t = v[f]
    pts = np.concatenate([t.mean(axis=1), 0.5 * (t + np.roll(t, -1, axis=1)).reshape(-1, 3)])
    inside = np.all((pts >= lo) & (pts <= hi), axis=1)
    rng = np.random.default_rng(1)
    on78 = rng.choice(np.flatnonzero(inside), size=250, replace=False)
    anywhere = rng.choice(len(pts), size=100, replace=False)
    d = np.abs(signed_distance(part.shape, pts[np.concatenate([on78, anywhere])]))
    assert d.max() <= config.CHORD_CONTROL * defl, d.max() / defl


def _bounds(solid, index):
    from lattice_cad.occ_impl import chord, shapes

    box = shapes.bounds(chord._faces(solid)[index])
    return box[0] - 1e-6, box[1] + 1e-6


def test_cutting_part_reports_its_measured_chord_error(part):
    from conformal.trim import cutting_part
    from lattice_cad.core import config

    cut = cutting_part(part, R)
    assert cut.deflection <= config.CUT_DEFLECTION_RTOL * R * (1 + 1e-9)
    assert cut.chord_unresolved == 0
    assert 0 < cut.chord_error <= config.CHORD_CONTROL * cut.deflection
    assert part.chord_error is None  # the default tessellation is not measured


@pytest.mark.slow
def test_featuretype_clip_within_one_percent_of_r_of_the_exact_brep(part):
    from lattice_cad import Lattice
    from lattice_cad.occ_impl.distance import signed_distance

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lat = Lattice.fill(str(FEATURETYPE), cell="bcc", cell_size=CELL, radius=R, fill="clip")
        mesh = lat.mesh()
    v = np.asarray(mesh.vertices, dtype=np.float64)
    fine = lat.part.refined(1e-3 * R, angular=0.05)
    d = fine.signed_distance(v)
    # the worst by the fine mesh, and a random sample of the vertices on the cut
    rng = np.random.default_rng(0)
    on_cut = np.flatnonzero(np.abs(d) <= 0.02 * R)
    pick = np.unique(np.concatenate([np.argsort(d)[::-1][:200], rng.choice(on_cut, 150)]))
    exact = signed_distance(lat.part.shape, v[pick])
    assert d.max() <= 0.01 * R, d.max() / R
    assert exact.max() <= 0.01 * R, exact.max() / R


def test_checked_tessellation_after_an_unchecked_one_reuses_it_and_is_the_same(monkeypatch):
    """cutting_part counts triangles on unchecked trials and checks only the chosen one;
    the check then reuses that trial's BRepMesh run (the M6 screw's cut meshed 4 times
    and checked twice, 75 CPU s; now 2 meshings and 1 check). The reused result must be
    the one a fresh part gives."""
    from conformal import load_part
    from lattice_cad.occ_impl import chord

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fresh = load_part(FEATURETYPE).refined(0.005 * R)
        p = load_part(FEATURETYPE)
        plain = p.refined(0.005 * R, checked=False)
        cleaned = []
        real_clean = chord.BRepTools.Clean_s
        monkeypatch.setattr(
            chord.BRepTools, "Clean_s", lambda s: (cleaned.append(s), real_clean(s))[1]
        )
        again = p.refined(0.005 * R)
    assert plain.chord_error is None and again.chord_error is not None
    # the unchecked run's triangulation was kept, not meshed again (only the refined
    # copy of the check is cleaned)
    assert cleaned and not any(s.IsSame(p.shape[0]) for s in cleaned)
    np.testing.assert_array_equal(again.vertices, fresh.vertices)
    np.testing.assert_array_equal(again.faces, fresh.faces)
    assert again.chord_error == fresh.chord_error
    assert len(again.faces) != len(plain.faces)  # face 78 was refined


def test_chord_control_off_gives_brepmesh_as_it_is(monkeypatch):
    from conformal import load_part
    from lattice_cad.core import config

    monkeypatch.setattr(config, "CHORD_CONTROL", 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cut = load_part(FEATURETYPE).refined(0.005 * R)
    assert cut.chord_error is None and len(cut.faces) > 0


VENTILATOR = DATA / "step" / "pythonocc_Ventilator.stp"
#: The parts benchmark's strut radius for this part (cell = extent / 15, r = cell / 12).
R_VENT = 0.444444


@pytest.mark.slow
def test_ventilator_faces_brepmesh_left_coarse_come_down():
    """BRepMesh meshes a face with the largest deflection of its edges, which edges with a
    large B-rep tolerance raise (face 26, a B-spline with tolerance 4.25e-3 mm: 1.9 x the
    chord asked), unless ``ForceFaceDeflection``; and its torus faces 11 and 12 come out
    4.5 x coarser than asked whatever the parameters: they are meshed alone, finer."""
    from conformal import load_part
    from conformal.part import _closed_problem
    from lattice_cad.core import config
    from lattice_cad.occ_impl import chord, shapes
    from lattice_cad.occ_impl.distance import signed_distance

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = load_part(VENTILATOR)
    solid = part.shape[0]
    defl = 0.01 * R_VENT
    limit = config.CHORD_CONTROL * defl
    # plain BRepMesh, as before: face 26 and the tori over the limit (so the test can fail)
    plain = shapes.copied(solid)
    list(shapes.face_triangulations(plain, defl, 0.3))
    dev = chord.face_deviations(plain, limit)
    assert dev[26] > 1.7 * defl and dev[11] > 4 * defl and dev[12] > 4 * defl

    v, f, owner, report = shapes.tessellate(
        solid, defl, 0.3, face_ids=True, control=config.CHORD_CONTROL
    )
    assert report.unresolved == [] and {11, 12} <= set(report.finer), report
    assert _closed_problem(f) == ""
    # independent: OCCT's exact distance of triangle centroids on faces 26, 11 and 12
    rng = np.random.default_rng(2)
    t = v[f]
    for face in (26, 11, 12):
        on = rng.choice(np.flatnonzero(owner == face), size=150, replace=False)
        d = np.abs(signed_distance(part.shape, t[on].mean(axis=1)))
        assert d.max() <= limit, (face, d.max() / defl)


@pytest.mark.slow
def test_ventilator_clip_within_one_percent_of_r_of_the_exact_brep():
    """Issue 13 item 2 on the Ventilator: the clip fill's written vertices stand out of the
    exact B-rep by at most 1 % r (2.86 % r before the chord check's ForceFaceDeflection and
    the larger cut budget), by OpenCascade's exact distance of the vertices the cutting
    tessellation puts furthest out and of a sample of those on the cut."""
    from conformal.trim import cutting_part
    from lattice_cad import Lattice
    from lattice_cad.occ_impl.distance import signed_distance

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lat = Lattice.fill(
            str(VENTILATOR), cell="bcc", cell_size=12 * R_VENT, radius=R_VENT, fill="clip"
        )
        mesh = lat.mesh()
        cut = cutting_part(lat.part, R_VENT)  # cached: the tessellation the fill was cut by
    v = np.asarray(mesh.vertices, dtype=np.float64)
    d_cut = cut.signed_distance(v, max_distance=R_VENT)
    rng = np.random.default_rng(0)
    on_cut = np.flatnonzero(np.abs(d_cut) <= 0.02 * R_VENT)
    pick = np.unique(np.concatenate([np.argsort(d_cut)[::-1][:250], rng.choice(on_cut, 150)]))
    exact = signed_distance(lat.part.shape, v[pick], beyond_tolerance=True)
    assert exact.max() <= 0.01 * R_VENT, exact.max() / R_VENT


def test_ventilator_plane_face_19_is_off_its_plane_by_its_tolerance():
    """Regression: the test above failed on another machine (3.14 % r) by one vertex on the
    cut, in the interior of plane face 19, whose edges lie 0.0140 mm off its plane (the
    STEP file's tolerance there, 3.1 % r): BRepMesh's two triangles follow the edges, so a
    vertex on them stands out of the exact plane by up to that tolerance. The vertex
    sampled depends on the lattice's floating point; the exact distance beyond the B-rep
    tolerance does not."""
    from conformal import load_part
    from lattice_cad.occ_impl.distance import signed_distance

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = load_part(VENTILATOR)
    p = [[3.44694853, -8.41106415, 6.81988859]]  # the vertex that stood out
    plain = signed_distance(part.shape, p)[0]
    beyond = signed_distance(part.shape, p, beyond_tolerance=True)[0]
    assert 0.03 * R_VENT < plain < 0.032 * R_VENT and beyond == 0.0


def test_knots_that_make_a_face_far_worse_are_given_up(part, monkeypatch):
    """A face that knots leave more than KNOT_GIVE_UP times over the limit, worse than before,
    gets no more knots, and when that is so of every knotted face the plain mesh is kept
    (the exhaust manifold's faces, simulated here on face 78: its measure after knots is
    made 30 times the limit; see test_chord_bounded for the real part)."""
    from lattice_cad.core import config
    from lattice_cad.occ_impl import chord, shapes

    defl = 0.005 * R
    limit = config.CHORD_CONTROL * defl
    measured = chord._measured
    rounds = []

    def worse_after_knots(faces, which, lim, cache):
        got = measured(faces, which, lim, cache)
        if isinstance(which, dict) and 78 in got and got[78] is not None:  # a knot round
            rounds.append(sorted(which))
            d, uv, t = got[78]
            got[78] = (np.maximum(d, 30.0 * limit), uv, t)
        return got

    monkeypatch.setattr(chord, "_measured", worse_after_knots)
    plain = shapes.copied(part.shape[0])
    meshed, report = chord.mesh_checked(
        plain, defl, 0.3, factor=config.CHORD_CONTROL, finer_rounds=0
    )
    assert rounds == [[78]]  # one knot round, then no more knots for it
    assert report.refined == [] and report.unresolved == [78]
    assert meshed is plain  # the plain mesh, not the copy with the knots
    assert report.max_deviation > 20 * defl  # face 78 as BRepMesh meshed it (so measured)
    # a face knots leave over the limit but not far over goes on getting them
    monkeypatch.setattr(chord, "KNOT_GIVE_UP", 40.0)
    rounds.clear()
    _, report = chord.mesh_checked(
        shapes.copied(part.shape[0]),
        defl,
        0.3,
        factor=config.CHORD_CONTROL,
        finer_rounds=0,
        rounds=3,
    )
    assert len(rounds) == 3 and report.refined == [78] and report.unresolved == [78]


def test_an_offset_face_over_the_limit_gets_knots_in_its_basis_not_a_finer_mesh():
    """A shelled loft's inner wall is an offset of a B-spline surface, parametrised as its
    basis, which BRepMesh splits at the basis's knots: knots inserted there bring the face
    under the limit as they do a B-spline face. It went to the finer meshing instead, which
    meshes every patch of that surface at half the deflection: the shelled bottle made
    outside shared/data (s29) had 488 K triangles, 321 K with the knots, the same chord
    error, 30 -> 23 CPU s."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_OffsetSurface

    from lattice_cad.occ_impl import chord
    from tests.test_surface_eval import _shelled_loft

    deflection = 0.01
    meshed, report = chord.mesh_checked(_shelled_loft(), deflection, 0.5)
    faces = chord._faces(meshed)
    offsets = [
        i for i, f in enumerate(faces) if BRepAdaptor_Surface(f).GetType() == GeomAbs_OffsetSurface
    ]
    assert offsets and set(offsets) <= set(report.refined)
    assert not report.finer and not report.unresolved
    for i in offsets:  # under the limit, measured again on the faces as meshed
        dev = chord._triangle_deviation(faces[i], 1.5 * deflection)
        assert dev is not None
        assert not chord._over(faces[i], float(dev[0].max()), 1.5 * deflection)
