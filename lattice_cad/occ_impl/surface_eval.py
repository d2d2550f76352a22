"""Points of a face's surface at many parameters at once, for the chord check.

:func:`lattice_cad.occ_impl.chord._triangle_deviation` evaluates the surface at each
triangle's centroid and edge midpoints (about 2.5 points per triangle). One
``BRepAdaptor_Surface.Value`` call per point from Python was 20-30 % of a cutting
tessellation's time on the curved parts (the cycloidal gear: 4.8 of 16.8 s, 1 M points).
Here the surfaces a CAD part is mostly made of are evaluated on arrays: planes are not
measured; cylinders, cones, spheres and tori by their closed forms (OCCT's ``ElSLib``), and
B-spline surfaces (rational or not; periodic ones made non-periodic, the same surface) by
``scipy.interpolate.NdBSpline`` on their poles and knots, and offsets of B-spline surfaces
(a shelled loft's inner wall: ``S + d N``, ``N`` the unit normal ``Su x Sv`` from the
spline's derivatives, as OCCT's ``GeomEvaluator_OffsetSurface`` computes it; where
``Su x Sv`` nearly vanishes, OCCT's special handling of such points is used, point by
point). Any other surface type returns None (the caller evaluates point by point).

Nothing is assumed: every evaluation is compared with OCCT's own ``Value`` at up to
``CHECK_POINTS`` of the parameters spread over them and at each parameter's least and
greatest, and None is returned unless they agree within
``CHECK_RTOL`` of the surface's size (a transformation or a parametrisation read wrongly
cannot pass).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.GeomAbs import (
    GeomAbs_BSplineSurface,
    GeomAbs_Cone,
    GeomAbs_Cylinder,
    GeomAbs_OffsetSurface,
    GeomAbs_Sphere,
    GeomAbs_Torus,
)

__all__ = ["surface_points"]

#: Parameters at which an array evaluation is compared with OCCT's ``Value``.
CHECK_POINTS = 16
#: Largest difference allowed there, relative to the points' extent (at least 1 mm).
CHECK_RTOL = 1e-9
#: An offset surface's points where ``|Su x Sv|`` is at most this fraction of its median
#: ``|Su|`` times its median ``|Sv|`` (the basis surface's normal nearly undefined: a pole,
#: a degenerate edge, where the derivatives are rounding noise), or at most
#: ``OCCT_SINGULAR`` (below which OCCT's ``GeomEvaluator_OffsetSurface`` takes the normal
#: from higher derivatives), are evaluated by OCCT, point by point.
SINGULAR_SINE = 1e-6
OCCT_SINGULAR = 1e-9


def surface_points(
    surf: BRepAdaptor_Surface, u: NDArray[np.float64], v: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """``surf`` at the parameters ``(u[i], v[i])``, or None for a surface type it does not
    evaluate on arrays (or whose evaluation does not match OCCT's at the check points).

    Parameters
    ----------
    surf : BRepAdaptor_Surface
        A face's surface, with the face's location (``BRepAdaptor_Surface(face)``).
    u, v : (n,) float64

    Returns
    -------
    (n, 3) float64, or None
    """
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    if u.shape != v.shape or u.ndim != 1:
        raise ValueError(f"u and v must be 1-D of one length, got {u.shape} and {v.shape}")
    kind = surf.GetType()
    pts: NDArray[np.float64] | None
    try:
        if kind in _ELEMENTARY:
            pts = _ELEMENTARY[kind](surf, u, v)
        elif kind == GeomAbs_BSplineSurface:
            pts = _bspline(surf, u, v)
        elif kind == GeomAbs_OffsetSurface:
            pts = _offset(surf, u, v)
        else:
            return None
    except Exception:  # an OCCT accessor raised (Standard_Failure), scipy refused the knots
        return None
    if pts is None or not _agrees(surf, u, v, pts):
        return None
    return pts


def _axes(position: Any) -> tuple[NDArray[np.float64], ...]:
    """Origin, X, Y and Z directions of a ``gp_Ax3`` (a left-handed one included)."""
    return (
        np.array(position.Location().Coord()),
        np.array(position.XDirection().Coord()),
        np.array(position.YDirection().Coord()),
        np.array(position.Direction().Coord()),
    )


def _on_axes(
    position: Any, radial: NDArray[np.float64], u: NDArray[np.float64], z: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``O + radial (cos u X + sin u Y) + z Z`` for the axes of ``position``."""
    o, x, y, d = _axes(position)
    cu, su = np.cos(u), np.sin(u)
    return (
        o
        + (radial * cu)[:, None] * x
        + (radial * su)[:, None] * y
        + z[:, None] * d
    )  # fmt: skip


def _cylinder(surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    c = surf.Cylinder()
    return _on_axes(c.Position(), np.full_like(u, c.Radius()), u, v)


def _cone(surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    c = surf.Cone()
    a = c.SemiAngle()
    return _on_axes(c.Position(), c.RefRadius() + v * np.sin(a), u, v * np.cos(a))


def _sphere(surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    s = surf.Sphere()
    r = s.Radius()
    return _on_axes(s.Position(), r * np.cos(v), u, r * np.sin(v))


def _torus(surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    t = surf.Torus()
    r = t.MinorRadius()
    return _on_axes(t.Position(), t.MajorRadius() + r * np.cos(v), u, r * np.sin(v))


_ELEMENTARY = {
    GeomAbs_Cylinder: _cylinder,
    GeomAbs_Cone: _cone,
    GeomAbs_Sphere: _sphere,
    GeomAbs_Torus: _torus,
}


def _bspline(
    surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """A B-spline surface by ``NdBSpline`` on its poles (homogeneous when rational)."""
    got = _bspline_points(surf.BSpline(), u, v, derivatives=False)  # (with the location)
    return None if got is None else got[0]


def _offset(
    surf: Any, u: NDArray[np.float64], v: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """An offset of a B-spline surface: ``S + d (Su x Sv) / |Su x Sv|``; the points where
    the basis's normal is nearly undefined (``SINGULAR_SINE``, ``OCCT_SINGULAR``) by
    OCCT's ``Value``."""
    basis = surf.BasisSurface()  # (with the face's location)
    if basis.GetType() != GeomAbs_BSplineSurface:
        return None
    got = _bspline_points(basis.BSpline(), u, v, derivatives=True)
    if got is None:
        return None
    p, pu, pv = got
    n = np.cross(pu, pv)
    norm = np.linalg.norm(n, axis=1)
    typical = float(np.median(np.linalg.norm(pu, axis=1)) * np.median(np.linalg.norm(pv, axis=1)))
    weak = ~(norm > max(OCCT_SINGULAR, SINGULAR_SINE * typical))  # (NaN included)
    pts = p + float(surf.OffsetValue()) * n / np.where(weak, 1.0, norm)[:, None]
    for i in np.flatnonzero(weak).tolist():
        pts[i] = surf.Value(float(u[i]), float(v[i])).Coord()
    return pts


def _bspline_points(
    bs: Any, u: NDArray[np.float64], v: NDArray[np.float64], *, derivatives: bool
) -> tuple[NDArray[np.float64], ...] | None:
    """Points of a ``Geom_BSplineSurface`` at ``(u, v)``, (n, 3) float64, and with
    ``derivatives`` also its first derivatives in u and in v; None when its knots do not
    make a spline of its poles (scipy's view of them)."""
    from scipy.interpolate import NdBSpline

    if bs.IsUPeriodic() or bs.IsVPeriodic():
        # parameters into the first period (as OCCT evaluates a periodic surface), then
        # the same surface made non-periodic (the adaptor's own stays as it is)
        if bs.IsUPeriodic():
            u = bs.UKnot(1) + np.mod(u - bs.UKnot(1), bs.UPeriod())
        if bs.IsVPeriodic():
            v = bs.VKnot(1) + np.mod(v - bs.VKnot(1), bs.VPeriod())
        bs = bs.Copy()
        if bs.IsUPeriodic():
            bs.SetUNotPeriodic()
        if bs.IsVPeriodic():
            bs.SetVNotPeriodic()
    nu, nv = bs.NbUPoles(), bs.NbVPoles()
    poles = np.array(
        [bs.Pole(i, j).Coord() for i in range(1, nu + 1) for j in range(1, nv + 1)]
    ).reshape(nu, nv, 3)
    tu = _flat(bs.NbUKnots(), bs.UKnot, bs.UMultiplicity)
    tv = _flat(bs.NbVKnots(), bs.VKnot, bs.VMultiplicity)
    if len(tu) != nu + bs.UDegree() + 1 or len(tv) != nv + bs.VDegree() + 1:
        return None
    k = (bs.UDegree(), bs.VDegree())
    uv = np.column_stack([u, v])
    rational = bs.IsURational() or bs.IsVRational()
    if rational:
        w = np.array([bs.Weight(i, j) for i in range(1, nu + 1) for j in range(1, nv + 1)]).reshape(
            nu, nv, 1
        )
        poles = np.concatenate([poles * w, w], axis=2)
    spline = NdBSpline((tu, tv), poles, k)
    value = np.asarray(spline(uv), dtype=np.float64)
    orders = [(1, 0), (0, 1)] if derivatives else []
    slopes = [np.asarray(spline(uv, nu=np.array(o)), dtype=np.float64) for o in orders]
    if not rational:
        return (value, *slopes)
    # P = H / w; dP = (dH - P dw) / w
    w_at = value[:, 3:]
    p = value[:, :3] / w_at
    return (p, *[(d[:, :3] - p * d[:, 3:]) / w_at for d in slopes])


def _flat(n: int, knot: Any, multiplicity: Any) -> NDArray[np.float64]:
    """The knot sequence, each of the ``n`` knots repeated by its multiplicity."""
    return np.repeat(
        np.array([knot(i) for i in range(1, n + 1)], dtype=np.float64),
        np.array([multiplicity(i) for i in range(1, n + 1)], dtype=np.int64),
    )


def _agrees(
    surf: Any, u: NDArray[np.float64], v: NDArray[np.float64], pts: NDArray[np.float64]
) -> bool:
    """Whether ``pts`` match OCCT's ``Value`` at up to ``CHECK_POINTS`` spread parameters."""
    if not len(u):
        return True
    if pts.shape != (len(u), 3) or not np.isfinite(pts).all():
        return False
    # spread over the points, and the extremes of each parameter (beyond a periodic
    # surface's first period, or a face's domain, a slip shows there first)
    spread = np.linspace(0, len(u) - 1, min(CHECK_POINTS, len(u))).astype(np.int64)
    ends = [np.argmin(u), np.argmax(u), np.argmin(v), np.argmax(v)]
    at = np.unique(np.concatenate([spread, np.array(ends, dtype=np.int64)]))
    exact = np.array([surf.Value(float(u[i]), float(v[i])).Coord() for i in at])
    scale = max(1.0, float(np.ptp(pts, axis=0).max()), float(np.abs(exact).max()))
    return bool(np.abs(exact - pts[at]).max() <= CHECK_RTOL * scale)
