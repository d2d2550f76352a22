"""The worst places of an accuracy report, and a close-up picture of each.

:func:`worst_places` ranks the hubs by the largest two-sided surface deviation
sampled near them (:attr:`ValidationReport.node_deviation`: samples of the whole
surfaces, mesh to exact and exact to mesh, each given to its nearest node; hub
zones and struts alike), one per place: a hub next to an already ranked one
(sharing a strut) is the same place and is skipped; hubs next to a failed hub of
an incomplete reference are not ranked (there is no exact solid there to compare
with). Each place says where its worst sample lies: in the node's hub zone
(where the fast mesh's convex hub and the exact ball differ by design) or along
a strut, and on which surface.

:func:`closeup` renders the compared mesh near one hub (the triangles whose
centroid is within about half the longest incident strut), flat-shaded per
triangle and coloured by its **signed** deviation from the exact solid: for
each triangle, of its centroid, vertices and edge midpoints the point farthest
from the exact surface (positive: the mesh is outside the exact solid, extra
material; negative: inside, missing material). The hub is ringed in
:data:`HIGHLIGHT` green, and the exact solid's tessellation over the same
region is drawn as a translucent ghost. The distances are computed in closed
form (:func:`design_distance`) from the primitives the reference models (a ball
per hub, a cylinder or cone per strut), so they do not depend on the
tessellation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from reference_boolean.compare import ValidationReport

__all__ = [
    "WorstPlace",
    "worst_places",
    "closeup",
    "closeup_data",
    "clip_to_ball",
    "design_distance",
    "HIGHLIGHT",
    "zone_ball",
]

#: Ring colour of the worst hub in its close-up (absent from the diverging colour map).
HIGHLIGHT = "#00c853"

#: Marker colour of the worst sample in a close-up.
WORST_POINT = "#ff6f00"

#: Diverging colour map of the signed deviation (blue: material missing, red: extra).
SIGNED_COLORMAP = "RdBu_r"


@dataclass(frozen=True)
class WorstPlace:
    """One of the worst places of a report.

    Attributes
    ----------
    rank : int
        1 for the worst.
    node : int
    position : (float, float, float)
        The node, mm.
    deviation : float
        Largest two-sided surface deviation sampled near the node, mm.
    radius : float
        Largest strut radius at the node, mm.
    point : (float, float, float) or None
        Where the worst sample lies, mm (None if not recorded).
    region : {"hub zone", "strut"} or None
        Whether that sample lies in a hub zone (:mod:`reference_boolean.regions`) or
        along a strut; None without hub zones.
    side : {"mesh", "exact"} or None
        The surface the sample lies on: ``"mesh"`` (a mesh point that far from the exact
        surface) or ``"exact"`` (an exact surface point that far from the mesh).
    """

    rank: int
    node: int
    position: tuple[float, float, float]
    deviation: float
    radius: float
    point: tuple[float, float, float] | None = None
    region: str | None = None
    side: str | None = None

    @property
    def where(self) -> str:
        """``"hub zone, on the exact surface"`` and the like ("-" if unknown)."""
        parts = []
        if self.region is not None:
            parts.append(self.region)
        if self.side is not None:
            parts.append("on the mesh" if self.side == "mesh" else "on the exact surface")
        return ", ".join(parts) or "-"

    @property
    def percent_of_radius(self) -> float:
        """``deviation`` in % of ``radius``."""
        return 100.0 * self.deviation / self.radius if self.radius > 0 else float("nan")


def zone_ball(
    rep: ValidationReport, place: WorstPlace, *, n: int = 12
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A UV sphere showing a worst place's hub zone on the overview (its radius from
    :attr:`ValidationReport.hub_zone`, else 3 x the strut radius).

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Outward triangles.
    """
    zr = 0.0
    if rep.hub_zone is not None:
        zr = float(rep.hub_zone[place.node])
    if not zr > 0.0:
        zr = 3.0 * place.radius
    th = np.linspace(0.0, np.pi, n + 1)[1:-1]
    ph = np.linspace(0.0, 2.0 * np.pi, 2 * n, endpoint=False)
    st, ct = np.sin(th)[:, None], np.cos(th)[:, None]
    ring = np.stack([st * np.cos(ph), st * np.sin(ph), ct * np.ones_like(ph)], axis=-1)
    ring = ring.reshape(-1, 3)
    v = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    m = 2 * n
    faces = []
    for j in range(m):  # caps
        faces.append([0, 1 + j, 1 + (j + 1) % m])
        last = 1 + (n - 2) * m
        faces.append([len(v) - 1, last + (j + 1) % m, last + j])
    for i in range(n - 2):
        a, b = 1 + i * m, 1 + (i + 1) * m
        for j in range(m):
            j1 = (j + 1) % m
            faces.append([a + j, b + j, b + j1])
            faces.append([a + j, b + j1, a + j1])
    return np.asarray(place.position) + zr * v, np.asarray(faces, dtype=np.int64)


def _near_failed(rep: ValidationReport) -> NDArray[np.bool_]:
    """(N,) bool: failed hubs and their neighbours."""
    g = rep.graph
    bad = np.zeros(g.num_nodes, dtype=bool)
    failed = np.fromiter((int(i) for i in rep.reference.failed), dtype=np.int64)
    if len(failed):
        bad[failed] = True
        e = g.edges
        touch = bad[e[:, 0]] | bad[e[:, 1]]
        bad[e[touch].reshape(-1)] = True
    return bad


def worst_places(rep: ValidationReport, k: int) -> tuple[list[WorstPlace], int]:
    """The ``k`` worst places: hubs by local deviation, neighbours of a ranked hub skipped.

    Returns
    -------
    places : list of WorstPlace
        Worst first (fewer than ``k`` when the lattice is small).
    unranked : int
        Nodes with a deviation that were not ranked because they are, or are next to,
        a failed hub.
    """
    g = rep.graph
    dev = np.asarray(rep.node_deviation, dtype=np.float64)
    ok = np.isfinite(dev)
    near = _near_failed(rep)
    unranked = int((ok & near).sum())
    cand = np.flatnonzero(ok & ~near)
    order = cand[np.argsort(-dev[cand], kind="stable")]
    rmax = np.zeros(g.num_nodes)
    np.maximum.at(rmax, g.edges[:, 0], g.radii[:, 0])
    np.maximum.at(rmax, g.edges[:, 1], g.radii[:, 1])
    adj: dict[int, set[int]] = {}
    taken: set[int] = set()
    out: list[WorstPlace] = []
    if k > 0 and len(order):
        for a, b in g.edges:
            adj.setdefault(int(a), set()).add(int(b))
            adj.setdefault(int(b), set()).add(int(a))
    comp = rep.comparisons.get(rep.label)
    wpt = None if comp is None else comp.node_worst_point
    wside = None if comp is None else comp.node_worst_side
    for i in order:
        if len(out) >= k:
            break
        i = int(i)
        if i in taken:
            continue
        taken.add(i)
        taken.update(adj.get(i, ()))
        point = region = side = None
        if wpt is not None and bool(np.isfinite(wpt[i]).all()):
            point = (float(wpt[i, 0]), float(wpt[i, 1]), float(wpt[i, 2]))
            if rep.hub_zone is not None:
                from reference_boolean.regions import in_hub_zone

                inside = bool(in_hub_zone(wpt[i : i + 1], g, rep.hub_zone)[0])
                region = "hub zone" if inside else "strut"
        if wside is not None and wside[i] >= 0:
            side = ("mesh", "exact")[int(wside[i])]
        out.append(
            WorstPlace(
                rank=len(out) + 1,
                node=i,
                position=(float(g.nodes[i, 0]), float(g.nodes[i, 1]), float(g.nodes[i, 2])),
                deviation=float(dev[i]),
                radius=float(rmax[i]),
                point=point,
                region=region,
                side=side,
            )
        )
    return out, unranked


def crop_radius(rep: ValidationReport, node: int) -> float:
    """Radius (mm) of the close-up around ``node``: 0.55 x its longest strut + its radius,
    between 3 and 7 times its largest strut radius (the hub and the start of its struts)."""
    g = rep.graph
    inc = np.flatnonzero((g.edges[:, 0] == node) | (g.edges[:, 1] == node))
    if not len(inc):
        return 1.0
    e = g.edges[inc]
    length = float(np.linalg.norm(g.nodes[e[:, 1]] - g.nodes[e[:, 0]], axis=1).max())
    r = float(g.radii[inc].max())
    return max(min(0.55 * length + r, 7.0 * r), 3.0 * r)


def clip_to_ball(
    triangles: NDArray[np.float64], centre: NDArray[np.float64], radius: float, *, parts: int = 8
) -> NDArray[np.float64]:
    """The part of a triangle soup within ``radius`` of ``centre``, for display.

    Triangles longer than ``radius / parts`` are split in four at their edge midpoints
    (repeatedly) where they can reach the ball, then the pieces whose centroid lies in
    the ball are kept: long strut triangles end near the sphere instead of sticking out.

    Parameters
    ----------
    triangles : (T, 3, 3) float64
    centre : (3,) float64
    radius : float

    Returns
    -------
    (T', 3, 3) float64
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    target = radius / parts
    for _ in range(12):
        edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
        cen = tri.mean(axis=1)
        reach = np.linalg.norm(cen - centre, axis=1) <= radius + edge
        tri, edge = tri[reach], edge[reach]
        big = edge > target
        if not big.any():
            break
        t = tri[big]
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        four = np.concatenate(
            [
                np.stack([a, ab, ca], 1),
                np.stack([ab, b, bc], 1),
                np.stack([ca, bc, c], 1),
                np.stack([ab, bc, ca], 1),
            ]
        )
        tri = np.concatenate([tri[~big], four])
    cen = tri.mean(axis=1)
    return tri[np.einsum("ij,ij->i", cen - centre, cen - centre) < radius * radius]


def design_distance(
    points: NDArray[np.float64], graph: Any, centre: NDArray[np.float64], reach: float
) -> NDArray[np.float64]:
    """Signed distance (mm) of ``points`` (P, 3) to the solid the reference models, in closed
    form: the union of a ball at every node of degree >= 2 (radius ``SPHERE_FACTOR`` x its
    largest strut radius) and a flat-ended cylinder or cone frustum along every strut (leaves
    end flat, as in the reference).

    Only the primitives within ``reach`` of ``centre`` are used (the points must lie
    within ``reach`` of it). Exact outside the solid (the distance to a union is the
    smallest distance to its parts); inside, the depth in the deepest part (exact away
    from the junctions). Positive outside, negative inside.

    Returns
    -------
    (P,) float64
    """
    from lattice_cad.core import config

    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nodes = np.asarray(graph.nodes, dtype=np.float64)
    edges = np.asarray(graph.edges, dtype=np.int64)
    radii = np.asarray(graph.radii, dtype=np.float64)
    rmax = np.zeros(len(nodes))
    np.maximum.at(rmax, edges[:, 0], radii[:, 0])
    np.maximum.at(rmax, edges[:, 1], radii[:, 1])
    degree = np.bincount(edges.ravel(), minlength=len(nodes))
    out = np.full(len(p), np.inf)
    # no ball at a leaf (degree 1): the strut ends flat there (docs/REFERENCE.md)
    near_node = np.linalg.norm(nodes - centre, axis=1) < reach + rmax
    ball = np.flatnonzero((rmax > 0) & (degree >= 2) & near_node)
    if len(ball):
        d = np.linalg.norm(p[:, None, :] - nodes[ball][None], axis=2)
        out = np.minimum(out, (d - config.SPHERE_FACTOR * rmax[ball]).min(axis=1))
    a, b = nodes[edges[:, 0]], nodes[edges[:, 1]]
    v = b - a
    length = np.linalg.norm(v, axis=1)
    u = v / np.maximum(length, 1e-300)[:, None]
    s = np.clip(np.einsum("ij,ij->i", centre - a, u), 0.0, length)
    seg = np.linalg.norm(a + s[:, None] * u - centre, axis=1)
    near = np.flatnonzero(seg < reach + radii.max(axis=1))
    if len(near):
        a, u, length, ra, rb = a[near], u[near], length[near], radii[near, 0], radii[near, 1]
        w = p[:, None, :] - a[None]
        t = np.einsum("pej,ej->pe", w, u)
        rho = np.linalg.norm(w - t[..., None] * u[None], axis=2)
        r_t = ra + (rb - ra) * t / length
        d = (rho - r_t) * (length / np.hypot(length, rb - ra))
        # beyond an end: the distance to that end's flat disc (inside a ball unless a leaf)
        before, after = t < 0, t > length
        d = np.where(before, np.hypot(np.maximum(rho - ra, 0.0), -t), d)
        d = np.where(after, np.hypot(np.maximum(rho - rb, 0.0), t - length), d)
        out = np.minimum(out, d.min(axis=1))
    return out


def _near_triangles(
    v: NDArray[np.float64], f: NDArray[np.int64], c: NDArray[np.float64], radius: float
) -> NDArray[np.float64]:
    """(T, 3, 3) the triangles of (v, f) that can reach within ``radius`` of ``c``."""
    tri = v[f]
    cen = tri.mean(axis=1)
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    return tri[np.linalg.norm(cen - c, axis=1) <= radius + edge]


def _crop(
    rep: ValidationReport, node: int, radius: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The compared mesh clipped to the ball of ``radius`` around ``node`` (T, 3, 3), and
    the reference's triangles of every hub that can reach within ``radius`` of it."""
    g = rep.graph
    c = g.nodes[node]
    m = rep.mesh
    assert m is not None
    tri = clip_to_ball(
        _near_triangles(np.asarray(m.vertices), np.asarray(m.faces), c, radius), c, radius
    )
    ref = rep.reference
    lengths = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    reach = radius + 0.5 * float(lengths.max(initial=0.0)) + 2.0 * float(g.radii.max(initial=0))
    near = np.einsum("ij,ij->i", g.nodes - c, g.nodes - c) < reach * reach
    rf = np.asarray(ref.mesh.faces)[near[np.asarray(ref.face_node)]]
    return tri, np.asarray(ref.mesh.vertices), rf


def face_deviation(
    triangles: NDArray[np.float64], graph: Any, centre: NDArray[np.float64], reach: float
) -> NDArray[np.float64]:
    """(T,) float64 signed deviation of each triangle of ``triangles`` (T, 3, 3) from the
    modelled solid (:func:`design_distance`): of its centroid, 3 vertices and 3 edge
    midpoints, the value farthest from the surface."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    pts = np.stack([a, b, c, (a + b + c) / 3, (a + b) / 2, (b + c) / 2, (c + a) / 2], axis=1)
    d = design_distance(pts.reshape(-1, 3), graph, centre, reach).reshape(-1, 7)
    pick = np.argmax(np.abs(d), axis=1)
    return d[np.arange(len(d)), pick]


@dataclass(frozen=True)
class Closeup:
    """The data of one close-up: the cropped mesh, its per-triangle signed deviation, and
    the exact solid's triangles over the same region (drawn as a translucent ghost)."""

    place: WorstPlace
    triangles: NDArray[np.float64]
    deviation: NDArray[np.float64]
    crop: float
    ghost: NDArray[np.float64]


def closeup_data(rep: ValidationReport, place: WorstPlace) -> Closeup:
    """Clip the compared mesh and the exact solid's tessellation to a ball around ``place``
    and measure each mesh triangle's signed deviation.

    Returns
    -------
    Closeup
        ``triangles`` (T, 3, 3) float64, ``deviation`` (T,) float64 (mm),
        ``ghost`` (G, 3, 3) float64.
    """
    rc = crop_radius(rep, place.node)
    tri, rv, rf = _crop(rep, place.node, rc)
    c = np.asarray(place.position)
    dev = face_deviation(tri, rep.graph, c, rc)
    ghost = clip_to_ball(_near_triangles(rv, rf, c, rc), c, rc)
    return Closeup(place=place, triangles=tri, deviation=dev, crop=rc, ghost=ghost)


def closeup(
    rep: ValidationReport,
    data: Closeup,
    *,
    limit: float,
    size: tuple[int, int] = (430, 400),
) -> bytes:
    """PNG of one close-up: the mesh near the hub, flat-shaded, coloured by signed deviation
    in ``[-limit, limit]`` mm, the hub ringed in :data:`HIGHLIGHT`.
    """
    from lattice_cad.render import ColorBar, Layer, Marker, picture

    p = data.place
    # unshared vertices: one colour and one flat normal per triangle (facets stay visible)
    v = data.triangles.reshape(-1, 3)
    ff = np.arange(len(v), dtype=np.int64).reshape(-1, 3)
    sc = np.repeat(data.deviation, 3)
    lim = max(float(limit), 1e-12)
    layers = [Layer(v, ff, None, sc, color=(0.8, 0.8, 0.8), closed=False)]
    if len(data.ghost):
        gv = data.ghost.reshape(-1, 3)
        gf = np.arange(len(gv), dtype=np.int64).reshape(-1, 3)
        layers.append(Layer(gv, gf, color=(0.45, 0.5, 0.55), style="ghost"))
    png, _ = picture(
        layers,
        size=size,
        colorbar=ColorBar(
            "mesh inside (-) / outside (+) the exact solid, mm", (-lim, lim), SIGNED_COLORMAP
        ),
        title=f"#{p.rank}: node {p.node}, {p.deviation:.3g} mm ({p.percent_of_radius:.0f} % r)",
        caption=f"at ({p.position[0]:.4g}, {p.position[1]:.4g}, {p.position[2]:.4g}); "
        + (f"worst sample ({p.where}) marked 'max'; " if p.point is not None else "")
        + "ghost: exact solid",
        markers=[Marker(p.position, f"#{p.rank}", color=HIGHLIGHT)]
        + ([Marker(p.point, "max", color=WORST_POINT)] if p.point is not None else []),
    )
    return png
