"""``lattice_cad.occ_impl.surface_eval.surface_points``: a face's surface on arrays (s30),
for the chord check's screen; compared with OCCT's own ``Value``, point by point."""

from __future__ import annotations

import numpy as np
import pytest

from lattice_cad.occ_impl import surface_eval
from lattice_cad.occ_impl.chord import _faces
from lattice_cad.occ_impl.surface_eval import surface_points
from tests.conftest import DATA


def _compare(face, rng, n=500):
    """(array points, OCCT's points) at ``n`` random parameters of the face's domain (and a
    little beyond it: a triangle's edge midpoint can be)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    surf = BRepAdaptor_Surface(face)
    u0, u1 = surf.FirstUParameter(), surf.LastUParameter()
    v0, v1 = surf.FirstVParameter(), surf.LastVParameter()
    du, dv = 0.01 * (u1 - u0), 0.01 * (v1 - v0)
    u = rng.uniform(u0 - du, u1 + du, n)
    v = rng.uniform(v0 - dv, v1 + dv, n)
    got = surface_points(surf, u, v)
    exact = np.array([surf.Value(a, b).Coord() for a, b in zip(u, v, strict=True)])
    return surf.GetType(), got, exact


def _moved(shape):
    """``shape`` with a location (rotated and moved), as in an assembly."""
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
    from OCP.TopLoc import TopLoc_Location

    t = gp_Trsf()
    t.SetRotation(gp_Ax1(gp_Pnt(1, 2, 3), gp_Dir(1, 1, 0.3)), 0.7)
    m = gp_Trsf()
    m.SetTranslation(gp_Vec(40, -7, 12))
    return shape.Moved(TopLoc_Location(m.Multiplied(t)))


@pytest.fixture(scope="module")
def shapes():
    import cadquery as cq
    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert

    loft = (
        cq.Workplane("XY")
        .spline([(0, 0), (10, 4), (20, -3), (30, 2)])
        .close()
        .workplane(offset=15)
        .spline([(0, 1), (12, 6), (22, -1), (31, 3)])
        .close()
        .loft()
    )
    solids = {
        "cylinder": cq.Workplane().cylinder(10, 3).val().wrapped,
        "cone": cq.Solid.makeCone(4, 1, 6).wrapped,
        "sphere": cq.Workplane().sphere(5).val().wrapped,
        "torus": cq.Solid.makeTorus(8, 2).wrapped,
        "loft": loft.val().wrapped,
        # a rational B-spline surface (a cylinder's NURBS form)
        "nurbs": BRepBuilderAPI_NurbsConvert(cq.Workplane().cylinder(10, 3).val().wrapped).Shape(),
    }
    solids.update({f"moved {k}": _moved(s) for k, s in list(solids.items())})
    return solids


@pytest.mark.parametrize(
    "name",
    [
        f"{m}{k}"
        for m in ("", "moved ")
        for k in ("cylinder", "cone", "sphere", "torus", "loft", "nurbs")
    ],
)
def test_the_surfaces_of_a_cad_part_on_arrays_are_occts(shapes, name):
    from OCP.GeomAbs import GeomAbs_Plane

    rng = np.random.default_rng(7)
    curved = 0
    for face in _faces(shapes[name]):
        kind, got, exact = _compare(face, rng)
        if kind == GeomAbs_Plane:
            continue
        curved += 1
        assert got is not None, (name, kind)
        scale = float(np.abs(exact).max())
        assert np.abs(got - exact).max() <= 1e-10 * max(1.0, scale), (name, kind)
    assert curved


def test_a_rational_periodic_surface_is_made_non_periodic_not_refused(shapes):
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_BSplineSurface

    kinds = [BRepAdaptor_Surface(f) for f in _faces(shapes["nurbs"])]
    bs = [s.BSpline() for s in kinds if s.GetType() == GeomAbs_BSplineSurface]
    assert any(b.IsURational() or b.IsVRational() for b in bs)


def test_an_evaluation_that_does_not_match_occt_is_refused(shapes, monkeypatch):
    """The check against OCCT's ``Value`` decides: with no difference allowed below zero,
    every surface is refused (None), and the caller evaluates point by point."""
    monkeypatch.setattr(surface_eval, "CHECK_RTOL", -1.0)
    rng = np.random.default_rng(3)
    for name in ("cylinder", "loft"):
        for face in _faces(shapes[name]):
            _, got, _ = _compare(face, rng, n=20)
            assert got is None


def test_the_chord_check_measures_the_same_on_arrays(monkeypatch):
    """``chord._triangle_deviation`` on the cycloidal gear's B-spline faces and a
    cylinder: the same deviations as with OCCT's ``Value`` point by point."""
    from lattice_cad.occ_impl import chord
    from lattice_cad.occ_impl.step import read_step

    shape = read_step(DATA / "step" / "kcl_cycloidal-gear.step")
    chord._mesh(shape, 0.01, 0.5, True)
    faces = [f for f in _faces(shape) if chord._uv_triangulation(f) is not None]
    fast = [chord._triangle_deviation(f, 0.01) for f in faces]
    monkeypatch.setattr(chord, "surface_points", lambda *a: None)
    slow = [chord._triangle_deviation(f, 0.01) for f in faces]
    measured = 0
    for a, b in zip(fast, slow, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            measured += len(a[0])
            assert np.allclose(a[0], b[0], rtol=0, atol=1e-10)
    assert measured > 1000
