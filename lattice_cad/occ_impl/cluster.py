"""One *cluster* of the exact reference as a single OCCT solid (several nodes, fused once).

:mod:`reference_boolean.clusters` groups nodes whose unit trusses (hubs) would overlap
(short struts, struts at small angles, clipped ends) and describes each group in plain
numpy (:class:`ClusterSpec`); :func:`build_cluster` turns it into a
:class:`~lattice_cad.occ_impl.truss.HubResult`, exactly as :func:`truss.build_hub` does for
one hub:

* primitives: the sphere of every member of degree >= 2 (radius ``R_n``, its axis from
  :func:`truss.sphere_axis` so that its poles lie inside the member's stumps; left out of
  the fuse where the member's own stumps cover it, :func:`truss.sphere_is_covered`), every
  strut joining two members as one cylinder/cone frustum from node to node (a strut
  ending at a leaf ends there with a flat disc), and every strut leaving the cluster as a
  stump from its member node to its midpoint, built in the strut's canonical frame so that
  the midpoint circle is the one the neighbouring hub (or cluster) builds;
* one general fuse of all of them (retried with a fuzzy value, then one primitive at a
  time, as for hubs), BRepCheck, exact volume (GProp);
* a tessellation without the midpoint discs of the leaving struts, whose circle vertices
  are verified to sit at the angles ``2 pi k / K`` of the strut's frame and come first,
  in the order of the leaving struts.

A cluster of one leaf (a node of degree 1) is its half-strut alone, with a flat disc at
the node (no sphere, no fuse). Nothing OCCT-typed crosses this module's boundary (worker
processes).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepPrimAPI import BRepPrimAPI_MakeCone, BRepPrimAPI_MakeCylinder
from OCP.GeomAbs import GeomAbs_Plane
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.TopAbs import TopAbs_SOLID
from OCP.TopoDS import TopoDS_Shape

from lattice_cad.core import config
from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.shapes import (
    check_done,
    check_valid,
    count,
    face_area,
    face_triangulations,
    fuse,
    merge_close,
    to_bytes,
    translated,
    volume,
)
from lattice_cad.occ_impl.truss import (
    ATTEMPTS,
    HubResult,
    HubSpec,
    StageClock,
    _lap,
    circle_loops,
    circles_first,
    make_sphere,
    sphere_is_covered,
    stump_start,
    tree_fuse,
)

__all__ = ["ClusterSpec", "build_cluster", "make_cluster_shape"]

_SAME_RADIUS = 1e-6

#: Retry plan of a cluster: the hub's (:data:`truss.ATTEMPTS`), with larger fuzzy values
#: before the sequential fuse (a ball nearly tangent to a stump as thick as its node, as
#: conforming fills make, left unclosed tessellations at 0 and 1e-7 but not at 1e-6).
CLUSTER_ATTEMPTS: tuple[tuple[str, float, bool], ...] = (
    *ATTEMPTS[:-1],
    ("fuse", 1e-6, True),
    ("fuse", 1e-4, True),
    ATTEMPTS[-1],
)


@dataclass(frozen=True)
class ClusterSpec:
    """One cluster in local coordinates (its first member at the origin).

    Attributes
    ----------
    offsets : (c, 3) float64
        Position of each member node (``offsets[0] == 0``).
    hubs : list of HubSpec
        Per member: its sphere radius (0 for a leaf) and all its stumps (node -> strut
        midpoint), used to place the sphere's poles inside stumps.
    inner : (k, 2) int64
        Struts joining two members, as member indices.
    inner_radii : (k, 2) float64
        Their radii at those two ends.
    inner_xdirs : (k, 3) float64
        A frame vector perpendicular to each (deterministic seam).
    member : (b,) int64
        For each strut leaving the cluster (in the caller's order), its member.
    vecs : (b, 3) float64
        Member node -> midpoint vector of each leaving strut.
    r_node, r_mid : (b,) float64
        Radius of each leaving stump at its node and at the midpoint.
    xdirs, ydirs : (b, 3) float64
        Canonical frame of each leaving strut's midpoint circle (shared with the neighbour).
    """

    offsets: NDArray[np.float64]
    hubs: list[HubSpec]
    inner: NDArray[np.int64]
    inner_radii: NDArray[np.float64]
    inner_xdirs: NDArray[np.float64]
    member: NDArray[np.int64]
    vecs: NDArray[np.float64]
    r_node: NDArray[np.float64]
    r_mid: NDArray[np.float64]
    xdirs: NDArray[np.float64]
    ydirs: NDArray[np.float64]

    @property
    def centres(self) -> NDArray[np.float64]:
        """(b, 3) float64: midpoint (disc centre) of each leaving strut."""
        return self.offsets[self.member] + self.vecs

    @property
    def axes(self) -> NDArray[np.float64]:
        """(b, 3) float64: unit axis of each leaving strut, pointing out of the cluster."""
        return self.vecs / np.linalg.norm(self.vecs, axis=1)[:, None]

    @property
    def scale(self) -> float:
        """Size of the cluster (for relative tolerances)."""
        ext = [np.abs(self.offsets).max() if len(self.offsets) else 0.0]
        if len(self.vecs):
            ext.append(float(np.abs(self.centres).max()))
        rmax = max((h.radius for h in self.hubs), default=0.0)
        return float(max(ext) + max(rmax, float(np.max(self.r_mid, initial=0.0))) + 1e-12)


def _pnt(v: NDArray[np.float64]) -> gp_Pnt:
    return gp_Pnt(float(v[0]), float(v[1]), float(v[2]))


def _dir(v: NDArray[np.float64]) -> gp_Dir:
    return gp_Dir(float(v[0]), float(v[1]), float(v[2]))


def _frustum(
    start: NDArray[np.float64],
    axis: NDArray[np.float64],
    xdir: NDArray[np.float64],
    r0: float,
    r1: float,
    h: float,
    what: str,
) -> TopoDS_Shape:
    ax = gp_Ax2(_pnt(start), _dir(axis), _dir(xdir))
    if abs(r0 - r1) <= _SAME_RADIUS:
        mk = BRepPrimAPI_MakeCylinder(ax, r1, h)
    else:
        mk = BRepPrimAPI_MakeCone(ax, r0, r1, h)
    mk.Build()
    check_done(mk, what)
    s = mk.Shape()
    check_valid(s, what)
    return s


def _primitives(spec: ClusterSpec, trim: bool) -> list[TopoDS_Shape]:
    """Spheres, inner struts and leaving stumps of the cluster, each checked."""
    out: list[TopoDS_Shape] = []
    # a member's sphere inside its own stumps (node to midpoint, contained in the cluster's
    # struts when they start at that node) is left out, as for a hub (truss.make_primitives)
    covered = [
        trim and hub.radius > 0.0 and sphere_is_covered(hub.radius, hub.vecs, hub.r_node, hub.r_mid)
        for hub in spec.hubs
    ]
    for i, hub in enumerate(spec.hubs):
        if hub.radius > 0.0 and not covered[i]:
            (s,) = make_sphere(hub)
            out.append(translated(s, spec.offsets[i]) if np.any(spec.offsets[i]) else s)
    for k, (a, b) in enumerate(spec.inner):
        pa, pb = spec.offsets[a], spec.offsets[b]
        v = pb - pa
        L = float(np.linalg.norm(v))
        u = v / L
        ra, rb = (float(x) for x in spec.inner_radii[k])
        rm = 0.5 * (ra + rb)
        h0 = stump_start(spec.hubs[a].radius, ra, rm, 0.5 * L) if trim and not covered[a] else 0.0
        h1 = stump_start(spec.hubs[b].radius, rb, rm, 0.5 * L) if trim and not covered[b] else 0.0
        r0 = ra + (rb - ra) * h0 / L
        r1 = rb + (ra - rb) * h1 / L
        out.append(_frustum(pa + h0 * u, u, spec.inner_xdirs[k], r0, r1, L - h0 - h1, f"strut {k}"))
    for j, v in enumerate(spec.vecs):
        m = int(spec.member[j])
        h = float(np.linalg.norm(v))
        u = v / h
        r0, r1 = float(spec.r_node[j]), float(spec.r_mid[j])
        h0 = stump_start(spec.hubs[m].radius, r0, r1, h) if trim and not covered[m] else 0.0
        r_start = r0 + (r1 - r0) * (h0 / h)
        out.append(
            _frustum(spec.offsets[m] + h0 * u, u, spec.xdirs[j], r_start, r1, h - h0, f"stump {j}")
        )
    return out


def make_cluster_shape(
    spec: ClusterSpec,
    *,
    construction: str = "fuse",
    fuzzy: float = 0.0,
    trim: bool = True,
    clock: StageClock | None = None,
) -> TopoDS_Shape:
    """The cluster solid: the union of its primitives (one general fuse, or one at a time).

    Raises
    ------
    OCCTFailure
        A builder is not done, or a shape is invalid.
    """
    prims = _primitives(spec, trim)
    _lap(clock, "primitives")
    if len(prims) == 1:
        shape = prims[0]
    elif construction == "tree":
        shape = tree_fuse(prims, fuzzy=fuzzy)
    elif construction == "fuse":
        shape = fuse(prims[:1], prims[1:], fuzzy=fuzzy, parallel=False, check=False)
    elif construction == "sequential":
        shape = prims[0]
        for j, s in enumerate(prims[1:]):
            shape = fuse([shape], [s], fuzzy=fuzzy, parallel=False, check=False)
            check_valid(shape, f"sequential fuse after primitive {j + 1}")
    else:  # pragma: no cover - guarded by the caller
        raise ValueError(f"unknown construction {construction!r}")
    _lap(clock, "fuse")
    check_valid(shape, "cluster")
    _lap(clock, "check")
    if count(shape, TopAbs_SOLID) < 1:
        raise OCCTFailure("cluster: the fuse gave no solid")
    return shape


# ------------------------------------------------------------- tessellation
def tessellate_open(
    shape: TopoDS_Shape,
    centres: NDArray[np.float64],
    axes: NDArray[np.float64],
    r_mid: NDArray[np.float64],
    xdirs: NDArray[np.float64],
    ydirs: NDArray[np.float64],
    *,
    scale: float,
    deflection: float,
    angular: float,
    clock: StageClock | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], list[NDArray[np.int64]]]:
    """Tessellate a solid without its midpoint discs; circle vertices first, in order.

    The general form of the hub tessellation (:mod:`truss`): disc ``j`` is the planar face
    through ``centres[j]`` perpendicular to ``axes[j]``, of radius ``r_mid[j]``; it must be
    intact (its area that of the full disc), and its rim's vertices must sit at the angles
    ``2 pi k / K_j`` of the frame ``xdirs[j], ydirs[j]``.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Outward, without the discs.
    circles : list of (K_j,) int64
        Vertex of angle ``2 pi k / K_j`` of disc ``j`` (``circles[j][k]``).
    """
    tol = config.GEOM_RTOL * scale
    plane_off = np.einsum("ij,ij->i", centres, axes)
    verts: list[NDArray[np.float64]] = []
    tris: list[NDArray[np.int64]] = []
    cap_found = np.zeros(len(centres), dtype=bool)
    base = 0
    on_meshed = None if clock is None else (lambda: clock.lap("mesh"))
    for face, pts, t in face_triangulations(
        shape, deflection, angular, parallel=False, on_meshed=on_meshed, tiny=deflection
    ):
        if len(centres) and BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane:
            proj = pts @ axes.T - plane_off  # (nn, b)
            near = np.linalg.norm(pts[:, None, :] - centres[None, :, :], axis=2)
            on = np.all(np.abs(proj) < tol, axis=0) & np.all(
                near <= r_mid[None, :] * (1 + 1e-6) + tol, axis=0
            )
            if on.any():
                j = int(np.flatnonzero(on)[0])
                if cap_found[j]:
                    raise OCCTFailure(f"the midpoint disc of leaving strut {j} is split")
                area = face_area(face)
                expect = math.pi * float(r_mid[j]) ** 2
                if abs(area - expect) > 1e-6 * expect:
                    raise OCCTFailure(
                        f"the midpoint disc of leaving strut {j} is not intact (area "
                        f"{area:.9g}, expected {expect:.9g}): another primitive reaches the cut"
                    )
                cap_found[j] = True
                continue
        verts.append(pts)
        tris.append(t + base)
        base += len(pts)
    if not cap_found.all():
        missing = ", ".join(str(int(j)) for j in np.flatnonzero(~cap_found))
        raise OCCTFailure(f"no midpoint disc found for leaving strut(s) {missing}")
    v = np.concatenate(verts)
    f = np.concatenate(tris)
    _lap(clock, "extract")
    v, f, _ = merge_close(v, f, config.MERGE_RTOL * scale)
    circles = circle_loops(v, f, centres, axes, r_mid, xdirs, ydirs, tol, what="leaving strut")
    out = circles_first(v, f, circles)
    _lap(clock, "circles")
    return out


# ------------------------------------------------------------------- driver
def build_cluster(
    spec: ClusterSpec, *, deflection: float, angular: float, keep_brep: bool = True
) -> HubResult:
    """Build, check, measure and tessellate one cluster; never raises for OCCT failures.

    ``deflection <= 0`` builds the solid only (no tessellation; the midpoint discs are not
    checked), as :func:`truss.build_hub_solid` does.

    Returns
    -------
    HubResult
        As for a hub; ``circles[j]`` belongs to leaving strut ``j``.
    """
    t0 = time.perf_counter()
    clock = StageClock()
    scale = spec.scale
    attempts: list[str] = []
    plan = CLUSTER_ATTEMPTS if len(spec.hubs) > 1 or spec.hubs[0].radius > 0 else ATTEMPTS[:1]
    for construction, fuzzy_rel, trim in plan:
        name = (
            f"cluster {construction}"
            + (f" (fuzzy {fuzzy_rel:g})" if fuzzy_rel else "")
            + ("" if trim else " (untrimmed stumps)")
        )
        try:
            shape = make_cluster_shape(
                spec, construction=construction, fuzzy=fuzzy_rel * scale, trim=trim, clock=clock
            )
            vol = volume(shape, eps=config.VOLUME_EPS)
            clock.lap("volume")
            if not (vol > 0.0 and math.isfinite(vol)):
                raise OCCTFailure(f"cluster volume {vol!r} is not positive")
            if deflection > 0.0:
                v, f, circles = tessellate_open(
                    shape, spec.centres, spec.axes, spec.r_mid, spec.xdirs, spec.ydirs,
                    scale=scale, deflection=deflection, angular=angular, clock=clock,
                )  # fmt: skip
            else:
                v, f, circles = np.zeros((0, 3)), np.zeros((0, 3), np.int64), []
        except Exception as exc:  # OCCTFailure, or an OCCT exception class
            attempts.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        attempts.append(f"{name}: ok")
        return HubResult(
            status="ok",
            attempts=attempts,
            volume=vol,
            vertices=v,
            faces=f,
            circles=circles,
            brep=to_bytes(shape) if keep_brep or deflection <= 0.0 else b"",
            seconds=time.perf_counter() - t0,
            stages=_brep_lap(clock),
        )
    return HubResult(
        status=attempts[-1] if attempts else "not attempted",
        attempts=attempts,
        seconds=time.perf_counter() - t0,
        stages=clock.stages,
    )


def _brep_lap(clock: StageClock) -> dict[str, float]:
    clock.lap("brep")
    return clock.stages
