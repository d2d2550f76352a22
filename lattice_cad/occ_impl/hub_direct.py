"""Unit trusses built face by face, without a boolean (issue 14, "Fast").

Where every stump of a hub has the same radius ``r`` (cylinders, ``r_node == r_mid``), the
union of the stumps has a closed-form boundary. A point ``x`` on the side of cylinder ``j``
(axis ``u_j`` through the node) lies inside the half-infinite cylinder ``k`` exactly when
``x . u_k > x . u_j``: equal radii turn "inside the other stump" into "on the other side of
the plane through the node with normal ``u_j - u_k``" (two cylinders of equal radius with
intersecting axes meet in planar ellipses in their bisector planes). So the side of stump
``j`` that stays on the hub's boundary is the part of cylinder ``j`` inside the polyhedral
cone ``{x : x . u_j >= x . u_k for all k}`` (a cell of the spherical Voronoi diagram of the
directions), above the sphere and below the midpoint disc. In the cylinder's coordinates
(angle ``theta`` from the strut frame's ``xdir``, height ``s``) that face is
``s_low(theta) <= s <= h_j`` with ``s_low(theta) = r * max_k g_k(theta)``,
``g_k = (a_k cos theta + b_k sin theta) / (1 - u_j . u_k)`` (``a_k, b_k`` the components of
``u_k`` along the frame): an upper envelope of sinusoids, computed exactly
(:func:`envelope`), together with the constant ``c = sqrt(R^2 - r^2)`` where the sphere of
radius ``R`` shows. Its pieces are arcs of the bisector ellipses and of the circle where the
stump meets the sphere; its breakpoints are the points where three (or, at symmetric nodes,
more) stumps meet, or two stumps and the sphere.

:func:`build_direct` builds that solid face by face: one face per stump on a
``Geom_CylindricalSurface`` (seam at ``xdir``, so the midpoint circle starts at ``xdir`` as
the contract of :mod:`lattice_cad.occ_impl.truss` asks), bounded below by the shared
ellipse arcs (exact ``Geom_Ellipse`` 3D curves; their parameter curves, ``theta`` linear
and ``s`` a cosine in the ellipse parameter, are B-spline fits to 1e-3 of the edge
tolerance) and sphere circle arcs (exact ``Geom_Circle``, parameter curve a line), and
above by the midpoint circle; one planar disc per stump; where the sphere shows, one face
on a ``Geom_SphericalSurface`` bounded by the circle arcs (its poles put inside stumps,
its seam turned away from the face; parameter curves fitted and checked). The edges and
vertices are shared between the faces (no sewing), the shell is closed, and the solid is
checked by ``BRepCheck_Analyzer`` like every other hub. Its volume comes from
:func:`analytic_volume` (closed form, divergence theorem on the same envelope) instead
of GProp.

:func:`direct_applies` says which hubs it covers: cylinder stumps of one radius below the
sphere's, every midpoint disc intact (``h_k >= r cot(alpha_jk / 2)`` with a margin: the
highest point of each bisector ellipse below both discs). Inside :func:`build_direct` it
declines (:class:`DirectNotApplicable`) what it does not build: an exposed sphere that is
not one disc-like face (a straight strut's band, several islands), nearly degenerate
vertices (pieces of the envelope narrower than 1e-5 rad), a stump that touches no other
one. The caller then falls back to the boolean chain.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
from OCP.Geom import Geom_Circle, Geom_CylindricalSurface, Geom_Ellipse, Geom_Line, Geom_Plane
from OCP.Geom2d import Geom2d_Circle, Geom2d_Line
from OCP.Geom2dAPI import Geom2dAPI_PointsToBSpline
from OCP.GeomAbs import GeomAbs_C2
from OCP.gp import (
    gp_Ax2,
    gp_Ax2d,
    gp_Ax3,
    gp_Circ,
    gp_Dir,
    gp_Dir2d,
    gp_Elips,
    gp_Lin,
    gp_Pnt,
    gp_Pnt2d,
)
from OCP.TColgp import TColgp_Array1OfPnt2d
from OCP.TColStd import TColStd_Array1OfReal
from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
from OCP.TopoDS import (
    TopoDS_Edge,
    TopoDS_Face,
    TopoDS_Shape,
    TopoDS_Shell,
    TopoDS_Solid,
    TopoDS_Wire,
)

from lattice_cad.core.errors import LatticeError

__all__ = [
    "DirectNotApplicable",
    "envelope",
    "analytic_volume",
    "direct_applies",
    "base_group",
    "build_direct",
]

_TWO_PI = 2.0 * math.pi
#: Envelope pieces narrower than this (rad) are rounding where four or more faces meet at
#: one point (symmetric nodes): merged into a single vertex.
_MERGE = 1e-9
#: Pieces between _MERGE and this (rad) would make edges shorter than the tolerance: the
#: direct path declines.
_NARROW = 1e-5
#: Vertices closer than this (relative to r) are one vertex.
_SAME_POINT = 1e-7
#: Discs must clear the bisector ellipses' highest points by this fraction of r.
_DISC_MARGIN = 1e-3
#: Points of each parameter-curve fit (B-spline through exact points of the pcurve).
_FIT_POINTS = 17

#: An arc on the sphere where it meets stump j: (j, theta0, theta1, key0, key1, edge).
_SphereArc = tuple[int, float, float, object, object, TopoDS_Edge]
#: An ellipse arc where the stumps of ``pair`` meet: (pair, key0, key1), vertex keys.
_EllipseArc = tuple[tuple[int, int], object, object]


class DirectNotApplicable(LatticeError):
    """The hub is outside what :func:`build_direct` covers (the caller uses the booleans)."""


def _frames(
    vecs: NDArray[np.float64], xdirs: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    h = np.linalg.norm(vecs, axis=1)
    u = vecs / h[:, None]
    x = np.asarray(xdirs, dtype=np.float64)
    y = np.cross(u, x)
    return u, x, y, h


def envelope(
    u: NDArray[np.float64],
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    j: int,
    floor: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Upper envelope of the sinusoids ``g_k(theta)`` of stump ``j`` (see the module doc).

    Parameters
    ----------
    u, x, y : (d, 3) float64
        Unit axes and the frames' x and y directions (``y = u x x``).
    j : int
        The stump.
    floor : float, optional
        A constant taking part in the envelope (``c / r``, the sphere), owner ``-1``.

    Returns
    -------
    breaks : (m + 1,) float64
        Angles ``0 = b_0 < ... < b_m = 2 pi``; the envelope is one sinusoid on each piece.
    owner : (m,) int64
        The stump ``k`` (or ``-1`` for the floor) on top on each piece.
    A, B : (d,) float64
        ``g_k = A_k cos theta + B_k sin theta`` (0 for ``k = j``).

    Raises
    ------
    DirectNotApplicable
        Two axes nearly parallel, or a degenerate breakpoint (three sinusoids tie).
    """
    d = len(u)
    others = np.array([k for k in range(d) if k != j], dtype=np.int64)
    den = 1.0 - u[others] @ u[j]
    if np.any(den < 1e-9):
        raise DirectNotApplicable(f"stump {j} is parallel to another stump")
    A = np.zeros(d)
    B = np.zeros(d)
    A[others] = (u[others] @ x[j]) / den
    B[others] = (u[others] @ y[j]) / den
    # candidate breakpoints: where two sinusoids (or one and the floor) are equal
    ia, ib = np.triu_indices(len(others), 1)
    ka, kb = others[ia], others[ib]
    da, db = A[ka] - A[kb], B[ka] - B[kb]
    t0 = np.arctan2(-da, db)
    cand = [np.zeros(1), t0, t0 + math.pi]
    if floor is not None:
        amp = np.hypot(A[others], B[others])
        ok = amp > abs(floor)
        phi = np.arctan2(B[others][ok], A[others][ok])
        ac = np.arccos(np.clip(floor / amp[ok], -1.0, 1.0))
        cand += [phi + ac, phi - ac]
    t = np.unique(np.mod(np.concatenate(cand), _TWO_PI))
    t = np.concatenate([t, [_TWO_PI]])
    t = t[np.concatenate([[True], np.diff(t) > 1e-13])]
    if t[-1] != _TWO_PI:
        t[-1] = _TWO_PI
    mid = 0.5 * (t[:-1] + t[1:])
    vals = np.cos(mid)[:, None] * A[others] + np.sin(mid)[:, None] * B[others]
    if floor is not None:
        vals = np.column_stack([vals, np.full(len(mid), floor)])
        labels = np.concatenate([others, [-1]])
    else:
        labels = others
    own = labels[np.argmax(vals, axis=1)]
    # pieces narrower than _MERGE are rounding at a point where four or more functions
    # meet (symmetric nodes): dropped, their ends joined; a real piece narrower than
    # _NARROW would give an edge below the tolerance: declined
    wide = np.diff(t) >= _MERGE
    if not wide.any():  # pragma: no cover - the pieces span 2 pi
        raise DirectNotApplicable(f"stump {j}: no envelope")
    lo, hi, own = t[:-1][wide], t[1:][wide], own[wide]
    cut = 0.5 * (hi[:-1] + lo[1:])
    keep = np.concatenate([[True], own[1:] != own[:-1]])
    breaks = np.concatenate([[0.0], cut[keep[1:]], [_TWO_PI]])
    owner = own[keep]
    if np.diff(breaks).min() < _NARROW:
        raise DirectNotApplicable(f"stump {j}: nearly degenerate (a piece of "
                                  f"{np.diff(breaks).min():.1e} rad)")  # fmt: skip
    return breaks, owner.astype(np.int64), A, B


def analytic_volume(
    radius: float,
    vecs: NDArray[np.float64],
    r: float,
    xdirs: NDArray[np.float64],
) -> float:
    """Exact volume of the unit truss of equal-radius cylinder stumps (mm^3), closed form.

    The hub is the ball ``|x| <= R`` plus, per stump ``j``, the part ``W_j`` of cylinder
    ``j`` outside the ball, inside its Voronoi cone and below its disc (the ``W_j`` do not
    overlap, see the module doc; valid when every disc is intact, which
    :func:`direct_applies` checks). By the divergence theorem with the field ``x / 3``
    (zero flux through the bisector planes, which pass through the node):
    ``vol(W_j) = (r A_cyl + h_j pi r^2 - R A_sph) / 3`` with the cylinder area
    ``A_cyl = r int (h_j - max(c, r g(theta))) dtheta`` and the sphere patch under it
    ``A_sph = R^2 int (1 - max(c / R, g / sqrt(1 + g^2))) dtheta`` (``c = sqrt(R^2 - r^2)``,
    ``g`` the envelope of :func:`envelope`); both integrals are sums of closed forms over
    the envelope's pieces (``int A cos t / sqrt(1 + A^2 cos^2 t) dt =
    arcsin(A sin t / sqrt(1 + A^2))``).

    Parameters
    ----------
    radius : float
        Sphere radius ``R > r``.
    vecs : (d, 3) float64
        Node -> midpoint vector of each stump.
    r : float
        The common stump radius.
    xdirs : (d, 3) float64
        Frame x directions (any unit vectors perpendicular to the axes).
    """
    R = float(radius)
    c = math.sqrt(max(R * R - r * r, 0.0))
    u, x, y, h = _frames(np.asarray(vecs, dtype=np.float64), xdirs)
    total = 4.0 / 3.0 * math.pi * R**3
    for j in range(len(u)):
        breaks, owner, A, B = envelope(u, x, y, j, floor=c / r)
        a0, a1 = breaks[:-1], breaks[1:]
        fl = owner < 0
        k = np.where(fl, 0, owner)
        amp = np.hypot(A[k], B[k])
        phi = np.arctan2(B[k], A[k])
        # int g = amp [sin(t - phi)]
        int_g = amp * (np.sin(a1 - phi) - np.sin(a0 - phi))
        s = amp / np.sqrt(1.0 + amp * amp)
        int_q = np.arcsin(np.clip(s * np.sin(a1 - phi), -1, 1)) - np.arcsin(
            np.clip(s * np.sin(a0 - phi), -1, 1)
        )
        width = a1 - a0
        low_cyl = np.where(fl, c * width, r * int_g).sum()
        low_sph = np.where(fl, c / R * width, int_q).sum()
        a_cyl = r * (_TWO_PI * h[j] - low_cyl)
        a_sph = R * R * (_TWO_PI - low_sph)
        total += (r * a_cyl + h[j] * math.pi * r * r - R * a_sph) / 3.0
    return float(total)


def direct_applies(spec: object) -> str:
    """Why :func:`build_direct` does not cover ``spec`` (``""`` if it does).

    ``spec`` is a :class:`lattice_cad.occ_impl.truss.HubSpec`.
    """
    vecs = np.asarray(spec.vecs, dtype=np.float64)  # type: ignore[attr-defined]
    r_node = np.asarray(spec.r_node, dtype=np.float64)  # type: ignore[attr-defined]
    r_mid = np.asarray(spec.r_mid, dtype=np.float64)  # type: ignore[attr-defined]
    r = float(r_mid[0])
    if len(vecs) < 2:
        return "fewer than 2 stumps"
    if np.any(np.abs(r_node - r) > 1e-12 * r) or np.any(np.abs(r_mid - r) > 1e-12 * r):
        return "stumps of different radii or tapered"
    if not float(spec.radius) > r * (1.0 + 1e-9):  # type: ignore[attr-defined]
        return "the sphere is not larger than the stumps"
    h = np.linalg.norm(vecs, axis=1)
    u = vecs / h[:, None]
    ca = np.clip(u @ u.T, -1.0, 1.0)
    np.fill_diagonal(ca, -1.0)
    # highest point of the bisector ellipse of j, k: r cot(alpha / 2) = r sqrt((1+c)/(1-c))
    if np.any(ca > 1.0 - 1e-9):
        return "two stumps nearly parallel"
    peak = r * np.sqrt((1.0 + ca) / (1.0 - ca))
    hmin = np.minimum(h[:, None], h[None, :])
    if np.any(peak > hmin - _DISC_MARGIN * r):
        return "a stump reaches another stump's midpoint disc"
    return ""


def base_group(spec: object) -> tuple[NDArray[np.int64], str]:
    """The stumps of a hub :func:`direct_applies` declines that it can still build face by face.

    Where the stumps differ (thinned or tapered struts, e.g. 157 of the 1,369 distinct hubs of
    the GE bracket Box-BCC 5.5 mm clip lattice), two stumps of different radii always meet
    outside the sphere (their solid intersection holds a point at distance
    ``sqrt(r_j^2 + r_k^2) > R`` from the node, as ``R`` is 1.00001 x the largest radius), in
    a quartic curve that has no closed form. The hub is then built in two steps (see
    :func:`lattice_cad.occ_impl.truss.direct_hub_shape`): the sphere with the largest group
    of cylinder stumps of one radius face by face (a sub-hub :func:`direct_applies` covers),
    then one general fuse of that solid with the remaining stumps.

    Returns
    -------
    idx : (m,) int64
        The group (at least 2 stumps; ties go to the larger radius), empty if none.
    why : str
        Why there is none, or why the sub-hub is not covered (``""`` if it is).
    """
    r_node = np.asarray(spec.r_node, dtype=np.float64)  # type: ignore[attr-defined]
    r_mid = np.asarray(spec.r_mid, dtype=np.float64)  # type: ignore[attr-defined]
    cyl = np.abs(r_node - r_mid) <= 1e-12 * r_mid
    best = np.zeros(0, dtype=np.int64)
    for r in sorted(set(r_mid[cyl].tolist()), reverse=True):
        idx = np.flatnonzero(cyl & (np.abs(r_mid - r) <= 1e-12 * r))
        if len(idx) > len(best):
            best = idx
    if len(best) < 2:
        return np.zeros(0, dtype=np.int64), "fewer than 2 cylinder stumps of one radius"
    if len(best) == len(r_mid):
        return np.zeros(0, dtype=np.int64), "every stump is in the group (direct_applies)"
    why = direct_applies(sub_spec(spec, best))
    return (best, "") if not why else (np.zeros(0, dtype=np.int64), f"base group: {why}")


def sub_spec(spec: object, idx: NDArray[np.int64]) -> object:
    """The :class:`~lattice_cad.occ_impl.truss.HubSpec` of the stumps ``idx`` (same sphere)."""
    return dataclasses.replace(
        spec,  # type: ignore[type-var]
        **{
            k: np.asarray(getattr(spec, k))[idx]
            for k in ("vecs", "r_node", "r_mid", "xdirs", "ydirs")
        },
    )


# --------------------------------------------------------------- construction
def _pnt(v: NDArray[np.float64]) -> gp_Pnt:
    return gp_Pnt(float(v[0]), float(v[1]), float(v[2]))


def _dir(v: NDArray[np.float64]) -> gp_Dir:
    return gp_Dir(float(v[0]), float(v[1]), float(v[2]))


class _Ellipse:
    """The bisector ellipse of stumps ``j < k``: ``P(t) = a cos t w + r sin t m``."""

    def __init__(self, u: NDArray[np.float64], j: int, k: int, r: float) -> None:
        m = np.cross(u[j], u[k])
        sm = float(np.linalg.norm(m))
        if sm < 1e-9:
            raise DirectNotApplicable(f"stumps {j} and {k} are opposite")
        m /= sm
        w = u[j] + u[k]
        w /= np.linalg.norm(w)
        cos_a = float(np.clip(u[j] @ u[k], -1.0, 1.0))
        half = math.sqrt(max(0.5 * (1.0 - cos_a), 0.0))  # sin(alpha / 2)
        self.a = max(r / half, r)
        self.r = r
        self.w, self.m = w, m
        n = np.cross(w, m)
        self.curve = Geom_Ellipse(gp_Elips(gp_Ax2(gp_Pnt(0, 0, 0), _dir(n), _dir(w)), self.a, r))

    def param(self, p: NDArray[np.float64]) -> float:
        return math.atan2(float(p @ self.m) / self.r, float(p @ self.w) / self.a)

    def point(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.a * np.cos(t)[:, None] * self.w + self.r * np.sin(t)[:, None] * self.m


def build_direct(
    radius: float,
    vecs: NDArray[np.float64],
    r: float,
    xdirs: NDArray[np.float64],
    *,
    tol: float,
) -> TopoDS_Shape:
    """The hub solid of equal-radius stumps whose sphere is covered, face by face.

    Parameters
    ----------
    radius : float
        Sphere radius (not part of the boundary here; unused except for checks).
    vecs : (d, 3) float64
        Node -> midpoint vector of each stump.
    r : float
        The common stump radius.
    xdirs : (d, 3) float64
        Canonical frame x direction of each strut (the seam and circle start).
    tol : float
        Edge and vertex tolerance (mm), e.g. ``1e-7`` of the hub's size.

    Returns
    -------
    TopoDS_Solid
        Not yet checked (the caller runs BRepCheck).

    Raises
    ------
    DirectNotApplicable
        A degenerate configuration (the caller falls back to the booleans).
    """
    u, x, y, h = _frames(np.asarray(vecs, dtype=np.float64), xdirs)
    d = len(u)
    bb = BRep_Builder()
    origin = gp_Pnt(0.0, 0.0, 0.0)

    R = float(radius)
    c = math.sqrt(max(R * R - r * r, 0.0))
    if not c > 1e-9 * r:
        raise DirectNotApplicable("the sphere is not larger than the stumps")
    # 1. the envelope of every face (owner -1: the sphere), its vertices (where three
    # stumps meet, where two stumps meet the sphere, and the seam points)
    loops = []  # per face: list of (k, theta0, theta1, key0, key1)
    points: dict[object, NDArray[np.float64]] = {}
    where: list[NDArray[np.float64]] = []

    def vertex_key(p: NDArray[np.float64]) -> int:
        """The vertex at ``p``: one index per point (the faces compute each vertex of theirs,
        up to rounding; four or more faces may meet at one)."""
        if where:
            dist = np.linalg.norm(np.asarray(where) - p, axis=1)
            i = int(np.argmin(dist))
            if dist[i] < _SAME_POINT * r:
                return i
        where.append(p)
        points[len(where) - 1] = p
        return len(where) - 1

    for j in range(d):
        breaks, owner, A, B = envelope(u, x, y, j, floor=c / r)
        segs = []
        m = len(owner)
        if m < 2:
            raise DirectNotApplicable(f"stump {j}: one neighbour all around")
        keys = []
        for i in range(m + 1):  # the vertex at breaks[i], between pieces i - 1 and i
            th = float(breaks[i])
            k = int(owner[min(i, m - 1)])
            s = c if k < 0 else r * (A[k] * math.cos(th) + B[k] * math.sin(th))
            if s <= 0.0:  # pragma: no cover - the floor c > 0 is in the envelope
                raise DirectNotApplicable(f"stump {j}: its side reaches the node")
            p = s * u[j] + r * (math.cos(th) * x[j] + math.sin(th) * y[j])
            keys.append(vertex_key(p))
        for i in range(m):
            segs.append((int(owner[i]), float(breaks[i]), float(breaks[i + 1]), keys[i],
                         keys[i + 1]))  # fmt: skip
        loops.append(segs)
    verts = {key: _vertex(bb, p, tol) for key, p in points.items()}

    # 2. ellipses and their vertices' parameters; split arcs at every vertex on them
    ells: dict[tuple[int, int], _Ellipse] = {}
    on_ell: dict[tuple[int, int], dict[object, float]] = {}
    for j, segs in enumerate(loops):
        for k, _, _, k0, k1 in segs:
            if k < 0:
                continue
            pair = (min(j, k), max(j, k))
            if pair not in ells:
                ells[pair] = _Ellipse(u, pair[0], pair[1], r)
                on_ell[pair] = {}
            for key in (k0, k1):
                if key not in on_ell[pair]:
                    on_ell[pair][key] = ells[pair].param(points[key])
    edges: dict[_EllipseArc, tuple[TopoDS_Edge, float, float]] = {}

    def arc_edges(pair: tuple[int, int], ka: object, kb: object) -> list[tuple[_EllipseArc, bool]]:
        """Edges from vertex ka to kb along the ellipse, each with 'forward' (t increases)."""
        ta, tb = on_ell[pair][ka], on_ell[pair][kb]
        fwd = tb > ta
        lo, hi = (ta, tb) if fwd else (tb, ta)
        inner = sorted((t, key) for key, t in on_ell[pair].items() if lo < t < hi)
        chain = [(lo, ka if fwd else kb)] + inner + [(hi, kb if fwd else ka)]
        out = []
        for (t0, q0), (t1, q1) in zip(chain[:-1], chain[1:], strict=True):
            ekey = (pair, q0, q1)
            if ekey not in edges:
                if t1 - t0 < 1e-12:
                    raise DirectNotApplicable("a zero-length arc between two triple points")
                mk = BRepBuilderAPI_MakeEdge(ells[pair].curve, verts[q0], verts[q1], t0, t1)
                if not mk.IsDone():
                    raise DirectNotApplicable(f"ellipse arc {pair}: MakeEdge failed")
                edge = mk.Edge()
                # OCCT moves the range of a periodic curve into its first period
                r0, r1 = BRep_Tool.Range_s(edge)
                if abs((r1 - r0) - (t1 - t0)) > 1e-9:
                    raise DirectNotApplicable(f"ellipse arc {pair}: unexpected range")
                edges[ekey] = (edge, r0, r1)
            out.append((ekey, fwd))
        return out if fwd else out[::-1]

    # 3. faces
    floor_arcs: list[_SphereArc] = []
    shell = TopoDS_Shell()
    bb.MakeShell(shell)
    for j in range(d):
        ax3 = gp_Ax3(origin, _dir(u[j]), _dir(x[j]))
        surf = Geom_CylindricalSurface(ax3, r)
        face = TopoDS_Face()
        bb.MakeFace(face, surf, tol)
        wire = TopoDS_Wire()
        bb.MakeWire(wire)
        segs = loops[j]
        # bottom: ellipse arcs and sphere circle arcs in increasing theta
        for k, th0, th1, k0, k1 in segs:
            if k < 0:  # on the circle where the sphere meets this stump (parameter theta)
                circle = Geom_Circle(gp_Circ(gp_Ax2(_pnt(c * u[j]), _dir(u[j]), _dir(x[j])), r))
                mk = BRepBuilderAPI_MakeEdge(circle, verts[k0], verts[k1], th0, th1)
                if not mk.IsDone():
                    raise DirectNotApplicable(f"stump {j}: sphere circle arc failed")
                edge = mk.Edge()
                bb.UpdateEdge(edge, Geom2d_Line(gp_Pnt2d(0.0, c), gp_Dir2d(1.0, 0.0)), face, tol)
                bb.Add(wire, edge.Oriented(TopAbs_FORWARD))
                floor_arcs.append((j, th0, th1, k0, k1, edge))
                continue
            pair = (min(j, k), max(j, k))
            for ekey, fwd in arc_edges(pair, k0, k1):
                edge, t0, t1 = edges[ekey]
                _pcurve_on_cylinder(bb, edge, face, ells[pair], t0, t1, u[j], x[j], y[j],
                                    th0, th1, tol)  # fmt: skip
                bb.Add(wire, edge.Oriented(TopAbs_FORWARD if fwd else TopAbs_REVERSED))
        # seam (u = 2 pi going up: FORWARD; u = 0 going down: REVERSED) and top circle
        p_top = h[j] * u[j] + r * x[j]
        v_top = _vertex(bb, p_top, tol)
        seam_key = segs[0][3]
        s0 = float(points[seam_key] @ u[j])
        seam = BRepBuilderAPI_MakeEdge(
            Geom_Line(gp_Lin(_pnt(r * x[j]), _dir(u[j]))), verts[seam_key], v_top, s0, float(h[j])
        )
        if not seam.IsDone():
            raise DirectNotApplicable(f"stump {j}: seam edge failed")
        seam_e = seam.Edge()
        bb.UpdateEdge(
            seam_e,
            Geom2d_Line(gp_Pnt2d(_TWO_PI, 0.0), gp_Dir2d(0.0, 1.0)),
            Geom2d_Line(gp_Pnt2d(0.0, 0.0), gp_Dir2d(0.0, 1.0)),
            face,
            tol,
        )
        circle = Geom_Circle(gp_Circ(gp_Ax2(_pnt(h[j] * u[j]), _dir(u[j]), _dir(x[j])), r))
        circ = BRepBuilderAPI_MakeEdge(circle, v_top, v_top, 0.0, _TWO_PI)
        if not circ.IsDone():
            raise DirectNotApplicable(f"stump {j}: midpoint circle failed")
        circ_e = circ.Edge()
        top = Geom2d_Line(gp_Pnt2d(0.0, float(h[j])), gp_Dir2d(1.0, 0.0))
        bb.UpdateEdge(circ_e, top, face, tol)
        bb.Add(wire, seam_e.Oriented(TopAbs_FORWARD))
        bb.Add(wire, circ_e.Oriented(TopAbs_REVERSED))
        bb.Add(wire, seam_e.Oriented(TopAbs_REVERSED))
        bb.Add(face, wire)
        bb.Add(shell, face)
        # the midpoint disc
        disc = TopoDS_Face()
        pl = Geom_Plane(gp_Ax3(_pnt(h[j] * u[j]), _dir(u[j]), _dir(x[j])))
        bb.MakeFace(disc, pl, tol)
        bb.UpdateEdge(circ_e, Geom2d_Circle(gp_Ax2d(gp_Pnt2d(0, 0), gp_Dir2d(1, 0)), r), disc, tol)
        dw = TopoDS_Wire()
        bb.MakeWire(dw)
        bb.Add(dw, circ_e.Oriented(TopAbs_FORWARD))
        bb.Add(disc, dw)
        bb.Add(shell, disc)
    if floor_arcs:
        bb.Add(shell, _sphere_face(bb, floor_arcs, u, x, y, R, c, tol))
    shell.Closed(True)
    solid = TopoDS_Solid()
    bb.MakeSolid(solid)
    bb.Add(solid, shell)
    return solid


def _vertex(bb: BRep_Builder, p: NDArray[np.float64], tol: float) -> object:
    from OCP.TopoDS import TopoDS_Vertex

    v = TopoDS_Vertex()
    bb.MakeVertex(v, _pnt(p), tol)
    return v


def _sphere_axis(
    u: NDArray[np.float64], f: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Axis and x direction of the sphere surface with both poles well inside stumps' caps
    (``p . u_k > f`` for some ``k``), so that no pole lies on the exposed sphere face."""
    i = np.arange(64) + 0.5
    zc = 1.0 - i / 64.0  # a half sphere of candidates (a and -a give the same poles)
    phi = math.pi * (1.0 + 5**0.5) * i
    rho = np.sqrt(1 - zc * zc)
    fib = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), zc])
    cands = np.vstack([u, fib])
    proj = cands @ u.T  # (n, d)
    score = np.minimum(proj.max(axis=1), (-proj).max(axis=1)) - f
    best = int(np.argmax(score))
    if score[best] < 0.2:
        raise DirectNotApplicable("no sphere axis with both poles inside stumps")
    z = cands[best] / np.linalg.norm(cands[best])
    xd = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    return z, xd / np.linalg.norm(xd)


def _sphere_face(
    bb: BRep_Builder,
    arcs: list[_SphereArc],
    u: NDArray[np.float64],
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    R: float,
    c: float,
    tol: float,
) -> TopoDS_Face:
    """The exposed part of the sphere: one face bounded by the circle arcs (used reversed).

    Declines (:class:`DirectNotApplicable`) unless the arcs form one loop that does not
    wind round the sphere's axis and runs counter-clockwise in the surface's parameters
    (one disc-like face, both poles covered)."""
    from OCP.Geom import Geom_SphericalSurface

    r = math.sqrt(R * R - c * c)
    start = {}
    for arc in arcs:
        if arc[4] in start:
            raise DirectNotApplicable("the exposed sphere has a degenerate boundary")
        start[arc[4]] = arc  # in the sphere face the arc runs from key1 back to key0
    # one loop through every arc
    loop = [arcs[0]]
    while True:
        nxt = start.get(loop[-1][3])
        if nxt is None:
            raise DirectNotApplicable("the exposed sphere's boundary is not closed")
        if nxt is loop[0]:
            break
        loop.append(nxt)
        if len(loop) > len(arcs):
            raise DirectNotApplicable("the exposed sphere's boundary does not close")
    if len(loop) != len(arcs):
        raise DirectNotApplicable("the exposed sphere has more than one boundary loop")
    z, xs = _sphere_axis(u, c / R)
    ys = np.cross(z, xs)
    prev_u = None
    first_u = None
    area = 0.0
    samples = []
    for j, th0, th1, _, _, edge in loop:
        n = max(_FIT_POINTS, int(24 * (th1 - th0) / math.pi) + 1)
        t = np.linspace(th0, th1, n)
        p = c * u[j] + r * (np.cos(t)[:, None] * x[j] + np.sin(t)[:, None] * y[j])
        uu = np.unwrap(np.arctan2(p @ ys, p @ xs))
        vv = np.arcsin(np.clip(p @ z / R, -1.0, 1.0))
        if prev_u is None:
            first_u = uu[-1]
        else:  # the arc runs from th1 to th0 in this face: its th1 end meets prev_u
            uu += _TWO_PI * round((prev_u - uu[-1]) / _TWO_PI)
        prev_u = uu[0]
        # shoelace over the reversed arc (from th1 to th0)
        area += 0.5 * float(np.sum(uu[1:] * vv[:-1] - uu[:-1] * vv[1:]))
        samples.append((t, uu, vv, edge))
    assert prev_u is not None and first_u is not None  # the loop holds arcs[0]
    if abs(prev_u - first_u) > 1e-6:
        raise DirectNotApplicable("the exposed sphere winds round the sphere's axis")
    if area <= 0.0:
        raise DirectNotApplicable("the exposed sphere is not a disc in the surface parameters")
    # turn the seam (u = 0) away from the face: its u range inside (0, 2 pi)
    umin = min(float(sm[1].min()) for sm in samples)
    umax = max(float(sm[1].max()) for sm in samples)
    gap = _TWO_PI - (umax - umin)
    if gap < 1e-3:
        raise DirectNotApplicable("the exposed sphere spans every longitude")
    a = umin - 0.5 * gap
    xs, ys = math.cos(a) * xs + math.sin(a) * ys, -math.sin(a) * xs + math.cos(a) * ys
    surf = Geom_SphericalSurface(gp_Ax3(gp_Pnt(0.0, 0.0, 0.0), _dir(z), _dir(xs)), R)
    face = TopoDS_Face()
    bb.MakeFace(face, surf, tol)
    wire = TopoDS_Wire()
    bb.MakeWire(wire)
    for (t, uu, _, edge), (j, *_rest) in zip(samples, loop, strict=True):
        _fit_pcurve(bb, edge, face, float(t[0]), float(t[-1]),
                    _sphere_uv(c, r, R, u[j], x[j], y[j], z, xs, ys, float(uu[0] - a)),
                    (R, R), tol)  # fmt: skip
        bb.Add(wire, edge.Oriented(TopAbs_REVERSED))
    bb.Add(face, wire)
    return face


def _sphere_uv(
    c: float,
    r: float,
    R: float,
    uj: NDArray[np.float64],
    xj: NDArray[np.float64],
    yj: NDArray[np.float64],
    z: NDArray[np.float64],
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    ref: float,
) -> Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Sphere parameters of the circle ``c uj + r (cos t xj + sin t yj)``, longitude
    unwrapped from ``ref`` at the first ``t``."""

    def exact(t: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        p = c * uj + r * (np.cos(t)[:, None] * xj + np.sin(t)[:, None] * yj)
        lon = np.unwrap(np.arctan2(p @ ys, p @ xs))
        lon += _TWO_PI * round((ref - lon[0]) / _TWO_PI)
        return lon, np.arcsin(np.clip(p @ z / R, -1.0, 1.0))

    return exact


def _fit_pcurve(
    bb: BRep_Builder,
    edge: object,
    face: TopoDS_Face,
    t0: float,
    t1: float,
    exact: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]],
    scale: tuple[float, float],
    tol: float,
    *,
    check: bool = True,
) -> None:
    """Attach the parameter curve ``exact(t) -> (pu, pv)`` of ``edge`` on ``face`` for the
    edge parameters ``t0 <= t <= t1``: a B-spline fit through exact points, its parameter
    mapped onto ``[t0, t1]``. Checked at the midpoints between the fitted points (error
    times ``scale``, mm per unit of u and of v, below ``tol / 10``), with twice the points
    until it is (else :class:`DirectNotApplicable`); without ``check`` (the smooth
    cylinder curves) that is left to BRepCheck, which checks every curve against its 3D
    edge."""
    n = max(_FIT_POINTS, int(24 * abs(t1 - t0) / math.pi) + 1)
    for _ in range(4):
        t = np.linspace(t0, t1, 2 * n - 1)
        pu, pv = exact(t)
        pts = TColgp_Array1OfPnt2d(1, n)
        par = TColStd_Array1OfReal(1, n)
        for i in range(n):
            pts.SetValue(i + 1, gp_Pnt2d(float(pu[2 * i]), float(pv[2 * i])))
            par.SetValue(i + 1, float(t[2 * i]))
        fit = Geom2dAPI_PointsToBSpline(pts, par, 3, 8, GeomAbs_C2, 1e-3 * tol)
        if not fit.IsDone():
            raise DirectNotApplicable("parameter curve fit failed")
        curve = fit.Curve()
        if not check:
            break
        # the fit's parameter is (t - t0) / (t1 - t0)
        err = 0.0
        for i in range(1, 2 * n - 1, 2):
            q = curve.Value((float(t[i]) - t0) / (t1 - t0))
            err = max(err, abs(q.X() - pu[i]) * scale[0] + abs(q.Y() - pv[i]) * scale[1])
        if err < 0.1 * tol:
            break
        n *= 2
    else:
        raise DirectNotApplicable(f"parameter curve fit error {err:.2g} mm")
    # give it the edge's range
    nk = curve.NbKnots()
    knots = TColStd_Array1OfReal(1, nk)
    curve.Knots(knots)
    for i in range(1, nk + 1):
        knots.SetValue(i, t0 + (t1 - t0) * knots(i))
    curve.SetKnots(knots)
    bb.UpdateEdge(edge, curve, face, tol)


def _pcurve_on_cylinder(
    bb: BRep_Builder,
    edge: object,
    face: TopoDS_Face,
    ell: _Ellipse,
    t0: float,
    t1: float,
    uj: NDArray[np.float64],
    xj: NDArray[np.float64],
    yj: NDArray[np.float64],
    th0: float,
    th1: float,
    tol: float,
) -> None:
    """The parameter curve of an ellipse arc on cylinder ``j`` (B-spline in the ellipse
    parameter: ``theta`` linear, ``s`` a cosine), ``theta`` unwrapped into the face's
    piece ``[th0, th1]``."""
    t = np.array([t0, t1])
    p = ell.point(t)
    th = np.unwrap(np.arctan2(p @ yj, p @ xj))
    lo, hi = min(th0, th1), max(th0, th1)
    shift = _TWO_PI * round((0.5 * (lo + hi) - 0.5 * (th[0] + th[-1])) / _TWO_PI)
    ref = th[0] + shift

    def exact(tt: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        q = ell.point(tt)
        a = np.unwrap(np.arctan2(q @ yj, q @ xj))
        return a + _TWO_PI * round((ref - a[0]) / _TWO_PI), q @ uj

    _fit_pcurve(bb, edge, face, t0, t1, exact, (ell.r, 1.0), tol, check=False)
