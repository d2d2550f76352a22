"""``lattice_cad.occ_impl.surface_eval.surface_points``: a face's surface on arrays (s30;
offset surfaces s31), for the chord check's screen; compared with OCCT's own ``Value``,
point by point. And the chord check's global search, built once per face (s31)."""

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
    # offsets of B-spline surfaces: a shelled loft (as CadQuery's shell makes them: the
    # bottle of s29's new parts), and offset faces of a plain loft, of a rational periodic
    # surface (a NURBS cylinder) and of one with poles (a NURBS sphere: the basis's normal
    # is undefined there, and OCCT's own evaluation is taken)
    solids["shelled loft"] = _shelled_loft()
    solids["offset loft"] = _offset_faces(loft.val().wrapped, 1.5)
    solids["offset nurbs"] = _offset_faces(solids["nurbs"], -0.75)
    solids["offset sphere"] = _offset_faces(
        BRepBuilderAPI_NurbsConvert(cq.Workplane().sphere(5).val().wrapped).Shape(), 1.0
    )
    solids["moved offset loft"] = _moved(solids["offset loft"])
    return solids


def _shelled_loft():
    import cadquery as cq

    body = (
        cq.Workplane("XY").circle(15)
        .workplane(offset=20).ellipse(19, 12)
        .workplane(offset=20).circle(8)
        .loft(ruled=False, combine=True)
    )  # fmt: skip
    return body.faces(">Z").shell(-1.0).val().wrapped


def _offset_faces(shape, distance):
    """A compound of faces on ``Geom_OffsetSurface``s of ``shape``'s curved surfaces."""
    from OCP.BRep import BRep_Builder, BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_OffsetSurface
    from OCP.GeomAbs import GeomAbs_Plane
    from OCP.TopoDS import TopoDS_Compound

    out = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(out)
    for face in _faces(shape):
        if BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane:
            continue
        surface = Geom_OffsetSurface(BRep_Tool.Surface_s(face), distance)
        made = BRepBuilderAPI_MakeFace(surface, 1e-7)
        assert made.IsDone()
        builder.Add(out, made.Face())
    return out


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


@pytest.mark.parametrize(
    "name", ["shelled loft", "offset loft", "offset nurbs", "offset sphere", "moved offset loft"]
)
def test_offset_surfaces_on_arrays_are_occts(shapes, name):
    """Every offset face is evaluated on arrays (not refused), as OCCT evaluates it: at
    random parameters, and on the domain's edges (the sphere's poles among them)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_OffsetSurface

    rng = np.random.default_rng(11)
    offsets = 0
    for face in _faces(shapes[name]):
        surf = BRepAdaptor_Surface(face)
        if surf.GetType() != GeomAbs_OffsetSurface:
            continue
        offsets += 1
        u0, u1 = surf.FirstUParameter(), surf.LastUParameter()
        v0, v1 = surf.FirstVParameter(), surf.LastVParameter()
        u, v = rng.uniform(u0, u1, 600), rng.uniform(v0, v1, 600)
        u[:50], u[50:100], v[100:150], v[150:200] = u0, u1, v0, v1
        got = surface_points(surf, u, v)
        assert got is not None, name
        exact = np.array([surf.Value(a, b).Coord() for a, b in zip(u, v, strict=True)])
        assert np.abs(got - exact).max() <= 1e-10 * max(1.0, float(np.abs(exact).max())), name
    assert offsets


def test_the_offset_of_a_sphere_takes_occts_values_at_its_poles(shapes, monkeypatch):
    """Where the basis's derivatives are rounding noise (a NURBS sphere's poles), the
    normal from them would be wrong by up to the offset (0.9 mm here): those points are
    OCCT's. With that guard off, the check against OCCT refuses the evaluation."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    surf = BRepAdaptor_Surface(_faces(shapes["offset sphere"])[0])
    v0, v1 = surf.FirstVParameter(), surf.LastVParameter()
    u = np.linspace(surf.FirstUParameter(), surf.LastUParameter(), 40)
    v = np.where(np.arange(40) % 2 == 0, v0, v1)
    assert surface_points(surf, u, v) is not None
    monkeypatch.setattr(surface_eval, "SINGULAR_SINE", 0.0)
    monkeypatch.setattr(surface_eval, "OCCT_SINGULAR", 0.0)
    assert surface_points(surf, u, v) is None


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


class _PerPoint:
    """The chord check's global search as it was before s31: a new ``Extrema_ExtPS`` (grid
    of samples and all) for every point."""

    def __init__(self, surf):
        self.surf = surf

    def Perform(self, p):  # noqa: N802 - OCCT's name
        from OCP.Extrema import Extrema_ExtPS

        self.ext = Extrema_ExtPS(p, self.surf, 1e-9, 1e-9)

    def IsDone(self):  # noqa: N802
        return self.ext.IsDone()

    def NbExt(self):  # noqa: N802
        return self.ext.NbExt()

    def SquareDistance(self, i):  # noqa: N802
        return self.ext.SquareDistance(i)


def test_the_global_search_built_once_per_face_measures_as_one_per_point(shapes, monkeypatch):
    """``chord._global_search`` (one ``Extrema_ExtPS`` per face, ``Perform`` per point)
    gives the deviations that a search built for each point gave, on the shelled loft's
    faces meshed coarsely (many points for the global search: the screen's limit is 0)."""
    from lattice_cad.occ_impl import chord

    shape = _shelled_loft()
    chord._mesh(shape, 1.0, 0.8, True)
    faces = [f for f in _faces(shape) if chord._uv_triangulation(f) is not None]
    searched = []

    class Counted(_PerPoint):
        def Perform(self, p):  # noqa: N802
            searched.append(p)
            super().Perform(p)

    monkeypatch.setattr(chord, "_global_search", Counted)
    each = [chord._triangle_deviation(f, 0.0) for f in faces]
    monkeypatch.undo()
    once = [chord._triangle_deviation(f, 0.0) for f in faces]
    assert len(searched) > 50  # the global search ran, for many points
    measured = 0
    for a, b in zip(once, each, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            measured += len(a[0])
            assert np.array_equal(a[0], b[0])
    assert measured > 50
