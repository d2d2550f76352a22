"""The worst places of an accuracy report, and a close-up picture of each.

:func:`worst_places` ranks the hubs by the largest two-sided surface deviation
sampled near them (:attr:`ValidationReport.node_deviation`), one per place: a
hub next to an already ranked one (sharing a strut) is the same place and is
skipped; hubs next to a failed hub of an incomplete reference are not ranked
(there is no exact solid there to compare with).

:func:`closeup` renders the compared mesh near one hub (the triangles whose
centroid is within about half the longest incident strut), flat-shaded per
triangle and coloured by its **signed** deviation from the exact solid: for
each triangle, of its centroid, vertices and edge midpoints the point farthest
from the exact surface (positive: the mesh is outside the exact solid, extra
material; negative: inside, missing material). The hub is ringed in
:data:`HIGHLIGHT` green. Distances are exact point-to-triangle distances
(trimesh) to the reference's tessellation near the hub; their sign comes from
the outward normal of the closest reference triangle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from reference_boolean.compare import ValidationReport

__all__ = ["WorstPlace", "worst_places", "closeup", "signed_deviation", "HIGHLIGHT"]

#: Ring colour of the worst hub in its close-up (absent from the diverging colour map).
HIGHLIGHT = "#00c853"

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
    """

    rank: int
    node: int
    position: tuple[float, float, float]
    deviation: float
    radius: float

    @property
    def percent_of_radius(self) -> float:
        """``deviation`` in % of ``radius``."""
        return 100.0 * self.deviation / self.radius if self.radius > 0 else float("nan")


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
    for i in order:
        if len(out) >= k:
            break
        i = int(i)
        if i in taken:
            continue
        taken.add(i)
        taken.update(adj.get(i, ()))
        out.append(
            WorstPlace(
                rank=len(out) + 1,
                node=i,
                position=(float(g.nodes[i, 0]), float(g.nodes[i, 1]), float(g.nodes[i, 2])),
                deviation=float(dev[i]),
                radius=float(rmax[i]),
            )
        )
    return out, unranked


def crop_radius(rep: ValidationReport, node: int) -> float:
    """Radius (mm) of the close-up around ``node``: 0.55 x its longest strut + its radius,
    at least 3 radii."""
    g = rep.graph
    inc = np.flatnonzero((g.edges[:, 0] == node) | (g.edges[:, 1] == node))
    if not len(inc):
        return 1.0
    e = g.edges[inc]
    length = float(np.linalg.norm(g.nodes[e[:, 1]] - g.nodes[e[:, 0]], axis=1).max())
    r = float(g.radii[inc].max())
    return max(0.55 * length + r, 3.0 * r)


def signed_deviation(
    points: NDArray[np.float64],
    ref_vertices: NDArray[np.float64],
    ref_faces: NDArray[np.int64],
) -> NDArray[np.float64]:
    """Signed distance of ``points`` (P, 3) to the outward triangle surface ``ref``.

    Exact unsigned point-to-triangle distance (trimesh); the sign is that of
    ``(p - q) . n`` with ``q`` the closest point and ``n`` the outward normal of its
    triangle: positive outside the surface, negative inside.

    Returns
    -------
    (P,) float64
    """
    import trimesh

    tm = trimesh.Trimesh(vertices=ref_vertices, faces=ref_faces, process=False)
    q, dist, tri = trimesh.proximity.closest_point(tm, points)
    n = tm.face_normals[np.asarray(tri, dtype=np.int64)]
    side = np.einsum("ij,ij->i", points - q, n)
    return np.where(side < 0, -1.0, 1.0) * np.asarray(dist, dtype=np.float64)


def _crop(
    rep: ValidationReport, node: int, radius: float
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """The compared mesh's triangles with centroid within ``radius`` of ``node``, and the
    reference's triangles of every hub that can reach within ``radius`` of it."""
    g = rep.graph
    c = g.nodes[node]
    m = rep.mesh
    assert m is not None
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    cen = v[f].mean(axis=1)
    sel = f[np.einsum("ij,ij->i", cen - c, cen - c) < radius * radius]
    ref = rep.reference
    lengths = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    reach = radius + 0.5 * float(lengths.max(initial=0.0)) + 2.0 * float(g.radii.max(initial=0))
    near = np.einsum("ij,ij->i", g.nodes - c, g.nodes - c) < reach * reach
    rf = np.asarray(ref.mesh.faces)[near[np.asarray(ref.face_node)]]
    return v, sel, np.asarray(ref.mesh.vertices), rf


def face_deviation(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    ref_vertices: NDArray[np.float64],
    ref_faces: NDArray[np.int64],
) -> NDArray[np.float64]:
    """(F,) float64 signed deviation of each triangle: of its centroid, 3 vertices and 3
    edge midpoints, the value farthest from the reference surface."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    pts = np.stack([a, b, c, (a + b + c) / 3, (a + b) / 2, (b + c) / 2, (c + a) / 2], axis=1)
    d = signed_deviation(pts.reshape(-1, 3), ref_vertices, ref_faces).reshape(-1, 7)
    pick = np.argmax(np.abs(d), axis=1)
    return d[np.arange(len(d)), pick]


@dataclass(frozen=True)
class Closeup:
    """The data of one close-up: the cropped mesh, its per-triangle signed deviation, and
    the exact solid's triangles over the same region (drawn as a translucent ghost)."""

    place: WorstPlace
    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    deviation: NDArray[np.float64]
    crop: float
    ref_vertices: NDArray[np.float64]
    ref_faces: NDArray[np.int64]


def closeup_data(rep: ValidationReport, place: WorstPlace) -> Closeup:
    """Crop the compared mesh around ``place`` and measure each triangle's signed deviation."""
    rc = crop_radius(rep, place.node)
    v, f, rv, rf = _crop(rep, place.node, rc)
    dev = face_deviation(v, f, rv, rf) if len(f) and len(rf) else np.full(len(f), np.nan)
    c = np.asarray(place.position)
    cen = rv[rf].mean(axis=1)
    ghost = rf[np.einsum("ij,ij->i", cen - c, cen - c) < rc * rc]
    used, ghost = np.unique(ghost, return_inverse=True)
    rv, ghost = rv[used], ghost.reshape(-1, 3)
    return Closeup(
        place=place, vertices=v, faces=f, deviation=dev, crop=rc, ref_vertices=rv, ref_faces=ghost
    )


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
    f = data.faces
    # unshared vertices: one colour and one flat normal per triangle (facets stay visible)
    v = data.vertices[f].reshape(-1, 3)
    ff = np.arange(len(v), dtype=np.int64).reshape(-1, 3)
    sc = np.repeat(data.deviation, 3)
    lim = max(float(limit), 1e-12)
    layers = [Layer(v, ff, None, sc, color=(0.8, 0.8, 0.8), closed=False)]
    if len(data.ref_faces):
        layers.append(
            Layer(data.ref_vertices, data.ref_faces, color=(0.45, 0.5, 0.55), style="ghost")
        )
    png, _ = picture(
        layers,
        size=size,
        colorbar=ColorBar(
            "mesh inside (-) / outside (+) the exact solid, mm", (-lim, lim), SIGNED_COLORMAP
        ),
        title=f"#{p.rank}: node {p.node}, {p.deviation:.3g} mm ({p.percent_of_radius:.0f} % r)",
        caption=f"at ({p.position[0]:.4g}, {p.position[1]:.4g}, {p.position[2]:.4g}); "
        "ghost: exact solid",
        markers=[Marker(p.position, f"#{p.rank}", color=HIGHLIGHT)],
    )
    return png
