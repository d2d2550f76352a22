"""Where a mesh and the exact reference model the same design: strut and hub regions.

The exact reference (docs/REFERENCE.md) puts a ball of radius ``R_n = 1.00001 max r`` at
every node of degree >= 2 and unites it with the struts' cylinders; the fast mesh
(:func:`fast_stitch.stitch`) closes each such node with the **convex hull** of its strut
profiles. Near a node the two are different designs: the hull fills the concave
crevices between struts where the reference shows its ball, so their surfaces are up to
about one radius apart there whatever the number of polygon sides. Along the struts both
are the same cylinder (the mesh a prism), and their distance is the polygon's chord error.

The report therefore measures the surface deviation twice, on a mask that is the same
rule for both surfaces and depends on the design (the graph) only:

**Hub zone of a node** (degree >= 2): the ball about the node of radius
``h_n = HUB_ZONE_FACTOR * E_n`` with

    E_n = max(R_n, max_i sqrt(t_i^2 + r_i^2)),
    t_i = min(L_i, max(0, max_{j != i} (r_j + r_i cos a_ij) / sin a_ij)),

where ``r_i`` is strut i's radius at the node, ``L_i`` its length and ``a_ij`` the angle
between struts i and j. ``t_i`` is the distance along strut i beyond which its cylinder
meets no other cylinder of the node (for equal radii ``r cot(a / 2)``: the smallest angle
decides; a strut ends at its length), so ``E_n`` is the radius of the smallest ball about
the node holding the ball, every intersection of the node's cylinders and the exposed ball
between them: beyond it the exact solid is a set of separate cylinders. fast_stitch places
its profiles at the same offsets computed for the *profile* radius (circumradius ``rho = f
r``, ``f`` up to ``1 / cos(pi / 4) = 1.41`` for circumscribed squares, ``1.25 * 1.1`` for
the P = 4 volume profile with its hub scale), so its hull reaches ``f E_n``;
``HUB_ZONE_FACTOR`` = 1.5 covers every profile at P >= 4 (checked on real lattices in
tests/test_regions.py). A leaf (degree 1) has no hub zone: both designs end the strut flat there.

**Strut region**: every sampled surface point (on the mesh or on the reference) farther
than ``h_n`` from every node ``n``; the **hub region** is the rest. The deviation of each
sample is still its distance to the *whole* other surface; only which samples are
counted changes. Where the strut region is the same design, its deviation is the
polygon's error: for inscribed P-gons exactly the chord error ``r (1 - cos(pi / P))``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph

__all__ = ["hub_zones", "in_hub_zone", "region_stats", "RULE"]

#: One sentence stating the mask (printed in the report).
RULE = (
    "hub zone = ball about each node of degree >= 2 of radius {f:g} x (the largest of the "
    "node's ball radius and sqrt(t^2 + r^2), t = where a strut clears every other strut of "
    "the node, r cot(a/2) for the smallest angle a); strut region = the rest"
)


def hub_zones(
    graph: LatticeGraph, *, factor: float = config.HUB_ZONE_FACTOR
) -> NDArray[np.float64]:
    """Radius of every node's hub zone (module docstring).

    Parameters
    ----------
    graph : LatticeGraph
    factor : float
        ``HUB_ZONE_FACTOR``: margin for the mesh's larger profiles (>= 1).

    Returns
    -------
    (N,) float64
        ``h_n`` in mm; 0 at nodes of degree < 2 (leaves end flat in both designs).
    """
    if not (math.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"factor must be a number >= 1, got {factor!r}")
    nodes = np.asarray(graph.nodes, dtype=np.float64)
    edges = np.asarray(graph.edges, dtype=np.int64)
    radii = np.asarray(graph.radii, dtype=np.float64)
    offsets, inc_edge, inc_side = graph.incidence
    degree = np.asarray(graph.degree)
    out = np.zeros(len(nodes))
    for d in np.unique(degree[degree >= 2]):
        ns = np.flatnonzero(degree == d)
        idx = offsets[ns][:, None] + np.arange(d)[None, :]  # (k, d)
        e = inc_edge[idx]
        side = inc_side[idx]
        other = edges[e, 1 - side]
        u = nodes[other] - nodes[ns][:, None, :]  # (k, d, 3) out of the node
        length = np.linalg.norm(u, axis=-1)
        u = u / np.where(length > 0, length, 1.0)[..., None]
        r = radii[e, side]  # (k, d) radius at the node
        c = np.clip(np.einsum("kid,kjd->kij", u, u), -1.0, 1.0)  # (k, d, d) cosines
        s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (r[:, None, :] + r[:, :, None] * c) / s  # t[k, i, j]: strut i clears j
        # parallel struts leaving the same way overlap all along: the zone is the strut
        t = np.where(s > 1e-12, t, np.where(c > 0, length[:, :, None], 0.0))
        eye = np.eye(d, dtype=bool)[None]
        t = np.where(eye, 0.0, t)
        # strut i ends at its other node: nothing of it to clear beyond (nearly parallel
        # struts, as clipped lattices have, gave zones of 1e7 r that swallowed the lattice)
        ti = np.minimum(np.maximum(0.0, t.max(axis=2)), length)  # (k, d)
        ball = config.SPHERE_FACTOR * r.max(axis=1)
        ext = np.sqrt(ti * ti + r * r).max(axis=1)
        out[ns] = factor * np.maximum(ball, ext)
    return out


def in_hub_zone(
    points: NDArray[np.float64], graph: LatticeGraph, zones: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """(S,) bool: which of ``points`` (S, 3) lie within ``zones[n]`` of some node ``n``."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=np.float64)
    mask = np.zeros(len(pts), dtype=bool)
    has = np.flatnonzero(zones > 0)
    if not len(has) or not len(pts):
        return mask
    tree = cKDTree(pts)
    step = 4096  # bounded memory: the hit lists of a chunk of nodes at a time
    for lo in range(0, len(has), step):
        sel = has[lo : lo + step]
        hits = tree.query_ball_point(graph.nodes[sel], r=zones[sel], return_sorted=False)
        for h in hits:
            if h:
                mask[np.asarray(h, dtype=np.int64)] = True
    return mask


def _stats(d: NDArray[np.float64], area: NDArray[np.bool_], total: int) -> dict[str, float]:
    """max over every point of the region; mean, p95 and the fraction over its area samples
    (``area``), of ``total`` area samples on that side."""
    da = d[area]
    if not len(da):
        nan = float("nan")
        top = float(d.max()) if len(d) else nan
        return {"max": top, "mean": nan, "p95": nan, "samples": 0, "fraction": 0.0}
    return {
        "max": float(d.max()),
        "mean": float(da.mean()),
        "p95": float(np.percentile(da, 95)),
        "samples": int(len(da)),
        "fraction": float(len(da) / max(total, 1)),
    }


def region_stats(
    hub1: NDArray[np.bool_],
    d1: NDArray[np.float64],
    hub2: NDArray[np.bool_],
    d2: NDArray[np.float64],
    *,
    area1: NDArray[np.bool_] | None = None,
    area2: NDArray[np.bool_] | None = None,
) -> dict[str, dict[str, Any]]:
    """Deviation statistics of the strut and hub regions.

    Parameters
    ----------
    hub1, d1 : (S1,) bool, (S1,) float64
        Mesh samples in a hub zone, and their distances to the reference.
    hub2, d2 : (S2,) bool, (S2,) float64
        Reference samples in a hub zone, and their distances to the mesh.
    area1, area2 : (S1,) bool, (S2,) bool, optional
        Which samples are area-weighted random points (the others are mesh vertices,
        :func:`reference_boolean.compare.surface_deviation`): the mean, the p95 and the
        fraction are statistics of the *surface*, so they are taken over those only; the
        max over every point. None: every sample is an area sample.

    Returns
    -------
    dict
        ``{"struts": {...}, "hubs": {...}}``, each with ``"mesh_to_reference"`` and
        ``"reference_to_mesh"`` (max, mean, p95, samples, fraction of that side's samples)
        and ``"symmetric"`` (the larger of each of max, mean, p95; samples: the smaller
        count, NaN when a side has none).
    """
    out: dict[str, dict[str, Any]] = {}
    a1 = np.ones(len(d1), dtype=bool) if area1 is None else np.asarray(area1, dtype=bool)
    a2 = np.ones(len(d2), dtype=bool) if area2 is None else np.asarray(area2, dtype=bool)
    for name, sel1, sel2 in (("struts", ~hub1, ~hub2), ("hubs", hub1, hub2)):
        a = _stats(d1[sel1], a1[sel1], int(a1.sum()))
        b = _stats(d2[sel2], a2[sel2], int(a2.sum()))
        sym: dict[str, float] = {
            k: float(np.fmax(a[k], b[k])) if a["samples"] and b["samples"] else float("nan")
            for k in ("max", "mean", "p95")
        }
        sym["samples"] = int(min(a["samples"], b["samples"]))
        sym["fraction"] = float(min(a["fraction"], b["fraction"]))
        out[name] = {"mesh_to_reference": a, "reference_to_mesh": b, "symmetric": sym}
    return out
