"""Volume-preserving profiles: the strut factor and the per-node hub correction.

With ``profile="volume"`` (the default of :func:`fast_stitch.stitch`) the stitched mesh has
the volume of the exact solid it approximates: the union of the strut cylinders (radius
``r``) and a ball of radius ``R_n = max r`` at every node of degree >= 2 (flat ends at
leaves), which is what :func:`reference_boolean.build_reference` builds. Two steps:

1. **Struts.** Every profile is the regular P-gon of circumradius
   ``rho = r * sqrt(2 pi / (P sin(2 pi / P)))`` (:func:`area_factor`), whose area is
   ``pi r^2``: between its two profile planes a strut prism has exactly the cylinder's
   volume. The hubs are built for these profiles (offsets from the node, convex hulls),
   exactly as for inscribed ones.

2. **Hubs.** Cut the exact solid and the mesh by every profile plane: both split into
   the same strut bodies (cylinder / prism between the two profile planes of a strut,
   equal volumes by step 1) and one *hub region* per node. The offsets guarantee that a
   strut beyond its profile plane meets no other strut of the node, and the part of
   the ball beyond a profile plane lies inside that strut, so the exact hub region is
   ``H_n = (ball U C_1 U ... U C_d) n {x . a_i <= d_i}`` (``C_i``: cylinder i from the
   node to its plane) and ``vol(mesh) - vol(exact) = sum_n (V_hull(n) - vol(H_n))``:
   the whole error sits in the hubs, where the convex hull fills the concave corners
   between struts (+0.6 % on a BCC 8 mm / r 0.6 lattice, +1.6 % on a cubic lattice of
   r / L = 1/6). ``H_n`` is star-shaped about the node, so
   ``vol(H_n) = int_{S^2} rho(w)^3 / 3 dw`` with the radial function
   ``rho = min(max(R, max_i rho_Ci(w)), min_i d_i / (w . a_i))`` (closed form per
   direction), integrated on ``config.HUB_QUADRATURE`` (1,024) Fibonacci directions (relative
   error below 4e-4 of the hub's volume on closed-form hubs; about 20 us per distinct
   hub). ``V_hull`` is the hull's
   exact volume (its triangles and profile polygons, cones from the node).

   The correction scales every profile at node n (radius and offset) by one factor
   ``s_n <= 1``. Offsets are homogeneous of degree 1 in the radii, so the scaled hub is
   the hub of the scaled radii, exactly ``s_n`` times the original about the node
   (same triangles, volume ``s_n^3 V_hull``). The strut keeps its unscaled profile: each
   strut end gets a second ring, the *band ring* (:func:`band_rings`), at
   ``x = s d + sqrt(((1 - s) d)^2 + g^2)`` (``g``: :func:`band_gaps`, about 0.05 rho), that
   is at the unscaled offset ``d`` (up to ``g^2 / (2 (1 - s) d)``) where ``s < 1``, of the
   unscaled strut's radius there; a short *band* (frustum) joins the hub ring to it, and
   the strut between its two band rings is the unscaled prism (frustum when tapered). So
   the correction stays inside the hub zone and the strut region keeps the design's
   radius (before, the strut ran between the two scaled hub rings: a frustum along its
   whole length, 0.95-1.18 r on tet lattices). Where a hub grows (``s > 1``) the band ring
   is ``s`` times wider too, so that the strut carries the missing volume (as before: the
   strut is a frustum towards that end). The exact solid does not change, so ``s_n``
   solves, per node (each strut end counted with its far end unscaled; the cross terms
   are ``O(eps_0 eps_1)``, ~1e-4 of a strut):

       s^3 V_hull - vol(H_n) + sum_i delta_i(s) = 0,

   ``delta_i(s)``: the band and the strut to the far band ring minus the unscaled strut
   there (closed-form frustum volumes, ``_hub_kernels._band_end``; for a cylinder and ``s < 1``
   about ``A_i d_i (1 - s^3) / 3``, the cone shell between the scaled and unscaled
   profile), by Newton's method from ``s = 1``, clamped to ``[config.MIN_HUB_SCALE,
   config.MAX_HUB_SCALE]``. Where ``s_n <= 1`` (hubs fuller than the exact solid: every
   node with struts around it) the scaled mesh lies inside the unscaled one (hubs shrink
   about their node, frusta stay within their hub's cone and the prism), so the
   clearance and fit guarantees of the unscaled profiles hold, and
   :mod:`fast_stitch.fit` checks the unscaled ones. Hubs lighter than the exact solid
   (boundary nodes whose struts all lie on one side: the hull misses the back of the
   ball) grow, ``s_n > 1``, bounded so that every strut keeps ``config.FIT_SLACK`` of its
   length as open cylinder, and by what their clearance allows
   (:func:`fast_stitch.stitch.cap_growth`: the clearance check's capsules with the scaled
   profiles may not overlap an element sharing no node); :func:`fast_stitch.stitch`'s
   clearance check runs on the final mesh. Typical ``|1 - s_n|`` is a few percent (the
   surface moves by that fraction of ``r``).

   ``s_n`` depends on the struts at node n and at its neighbours (the offsets at the far
   ends give the frustum lengths ``l_i`` and the bound on growth), nothing else: every
   node's Newton iteration stops on its own step, so a subgraph holding those struts gives
   the same bits (the sharded pipeline, :mod:`lattice_cad.distributed`).

Tapered struts: the strut prisms run between the end radii, the exact struts are
frustums along the whole strut; that (small) difference is not corrected.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from fast_stitch import _hub_kernels
from lattice_cad.core import config
from lattice_cad.core.arrays import read_only

__all__ = [
    "Profile",
    "PROFILES",
    "area_factor",
    "profile_factor",
    "hub_scales",
    "band_rings",
    "taper_cone_pairs",
]

Profile = Literal["volume", "area", "inscribed", "circumscribed"]
PROFILES: tuple[str, ...] = ("volume", "area", "inscribed", "circumscribed")


def area_factor(P: int) -> float:
    """Circumradius / radius of the regular P-gon whose area is the circle's."""
    return math.sqrt(2.0 * math.pi / (P * math.sin(2.0 * math.pi / P)))


def profile_factor(P: int, profile: str) -> float:
    """Circumradius / strut radius of the P-gon profiles of ``profile``.

    ``"volume"`` and ``"area"``: :func:`area_factor` (same area as the circle);
    ``"inscribed"``: 1 (vertices on the circle); ``"circumscribed"``: ``1 / cos(pi / P)``
    (edges tangent to the circle: the prism contains the cylinder).
    """
    if profile in ("volume", "area"):
        return area_factor(P)
    if profile == "inscribed":
        return 1.0
    if profile == "circumscribed":
        return 1.0 / math.cos(math.pi / P)
    raise ValueError(f"profile must be one of {', '.join(map(repr, PROFILES))}, got {profile!r}")


def band_gaps(
    prad: NDArray[np.float64], end_offset: NDArray[np.float64], length: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(M, 2) smallest band length ``g`` of every strut end (:func:`band_rings`).

    ``config.HUB_BAND_GAP`` times the end's profile radius, at most a quarter of the body
    between the unscaled profiles and 2 % of the strut (so that the two band rings of a
    strut never meet: ``s_a d_a + s_b d_b <= 0.95 L`` by the growth bound)."""
    body = length - end_offset.sum(axis=1)
    cap = np.minimum(0.25 * body, 0.02 * length)[:, None]
    return np.minimum(float(config.HUB_BAND_GAP) * prad, cap)


def band_rings(
    scale: NDArray[np.float64],
    edges: NDArray[np.int64],
    prad: NDArray[np.float64],
    end_offset: NDArray[np.float64],
    length: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(M, 2) offset and radius of every strut end's band ring (``profile="volume"``).

    The hub at node n is its unscaled hub scaled by ``s_n`` (profiles at ``s d`` of radius
    ``s rho``); the strut between the two band rings is the unscaled prism (frustum when
    tapered), so the strut region keeps the design's radius, and a short band (frustum)
    joins each band ring to its hub ring: the hub correction stays inside the hub zone.
    The band ring sits at ``x = s d + sqrt(((1 - s) d)^2 + g^2)`` (``g``:
    :func:`band_gaps`): at the unscaled offset ``d`` (the band then lies on the cone from
    the node through the unscaled profile, inside the unscaled hub) up to ``g^2 / (2 (1 -
    s) d)``, and ``g`` beyond the hub ring where ``s >= 1`` (leaves: a split of the prism).
    Its radius is the unscaled strut's there, times ``s`` where the hub grows (``s > 1``:
    the strut carries the volume the hub lacks)."""
    x = np.empty_like(end_offset)
    b = np.empty_like(end_offset)
    gap0 = band_gaps(prad, end_offset, length)
    _hub_kernels.band_rings(edges, scale, prad, end_offset, length, gap0, x, b)
    return x, b


def taper_cone_pairs(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    incidence: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]],
    length: NDArray[np.float64],
    base: NDArray[np.float64],
    hub: tuple[NDArray[np.float64], NDArray[np.float64]],
    band: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    far: tuple[
        tuple[NDArray[np.float64], NDArray[np.float64]],
        tuple[NDArray[np.float64], NDArray[np.float64]],
    ]
    | None = None,
) -> NDArray[np.int64]:
    """Pairs of struts at a node that a tapered strut may bring into contact.

    The hubs keep the struts of a node apart beyond their profiles for the radius each
    hub was built for (``base``). A strut that is wider somewhere beyond its near profile
    (a strut that widens away from the node, or a band ring grown with a far hub) is
    *loose*; a pair at node n with a loose strut is listed unless the cones from n that
    hold the two struts (half-angle: the largest ``atan(radius / distance)`` of the
    strut's rings) are apart. The listed pairs are those to test exactly.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    incidence : tuple
        ``LatticeGraph.incidence`` (offsets, inc_edge, inc_side).
    length : (M,) float64
    base : (M, 2) float64
        Radius at each strut end that its hub was built for.
    hub : ((M, 2) float64, (M, 2) float64)
        Offset and radius of the hub ring at each strut end.
    band : ((M, 2) float64, (M, 2) float64), optional
        Offset and radius of the band ring at each strut end (``profile="volume"``).
    far : (hub, band), optional
        The rings to take for a strut's far end (seen from the pair's node), in the same
        form; default ``hub`` and ``band``.

    Returns
    -------
    (K, 3) int64
        ``(node, strut_a, strut_b)``, by node.
    """
    off_a, rad_a = (np.ascontiguousarray(x, dtype=np.float64) for x in hub)
    off_b, rad_b = (off_a, rad_a) if band is None else (
        np.ascontiguousarray(x, dtype=np.float64) for x in band)  # fmt: skip
    far_off_a, far_rad_a, far_off_b, far_rad_b = off_a, rad_a, off_b, rad_b
    if far is not None:
        (far_off_a, far_rad_a), (far_off_b, far_rad_b) = (
            (np.ascontiguousarray(x, dtype=np.float64) for x in ring) for ring in far
        )
    offsets, inc_edge, inc_side = incidence
    n = len(offsets) - 1
    args = (
        np.ascontiguousarray(nodes, dtype=np.float64), edges, offsets, inc_edge, inc_side,
        read_only(np.ascontiguousarray(length, dtype=np.float64)),
        np.ascontiguousarray(base, dtype=np.float64), off_a, rad_a, off_b, rad_b,
        far_off_a, far_rad_a, far_off_b, far_rad_b,
    )  # fmt: skip
    count = np.zeros(n, dtype=np.int64)
    start = np.zeros(n + 1, dtype=np.int64)
    out = np.zeros((0, 3), dtype=np.int64)
    _hub_kernels.taper_cone_pairs(*args, count, start, out, False)
    np.cumsum(count, out=start[1:])
    out = np.empty((int(start[-1]), 3), dtype=np.int64)
    if len(out):
        _hub_kernels.taper_cone_pairs(*args, count, start, out, True)
    return out


def cap_taper_growth(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    incidence: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]],
    prad: NDArray[np.float64],
    end_offset: NDArray[np.float64],
    length: NDArray[np.float64],
    scale: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(N,) float64: ``scale`` with no growth (``s_n = 1``) at the nodes of tapered pairs.

    A hub that grows (``s_n > 1``) scales its band rings by ``s_n``; the hub offsets keep
    a node's struts apart for their profile radii, so a grown band ring on a strut that
    widens can reach the neighbouring strut (a tet lattice of ``meshes/hammer.obj``: struts
    0.005 -> 0.009 at 20.7 degrees, hub grown 1.23 times, ten self-intersecting face
    pairs). A grown node with a pair that :func:`taper_cone_pairs` lists (its own rings
    scaled by ``s_n``, the far ends' unscaled) keeps ``s_n = 1``. That depends on node n's
    struts, ``s_n`` and the offsets at their far ends only, as ``s_n`` itself does (the
    sharded stitch gets the same bits). A far hub's growth is not bounded here: the
    stitch's exact check of tapered neighbours has the last word.
    """
    grown = scale > 1.0
    if not grown.any():
        return scale
    x_off, x_rad = band_rings(scale, edges, prad, end_offset, length)
    unit = np.ones_like(scale)
    x_off1, x_rad1 = band_rings(unit, edges, prad, end_offset, length)
    s_end = scale[edges]
    pairs = taper_cone_pairs(
        nodes, edges, incidence, length, prad * np.maximum(s_end, 1.0),
        (end_offset * s_end, prad * s_end), (x_off, x_rad),
        far=((end_offset, prad), (x_off1, x_rad1)),
    )  # fmt: skip
    cap = np.zeros(len(scale), dtype=bool)
    cap[pairs[:, 0]] = True
    cap &= grown
    if not cap.any():
        return scale
    scale = scale.copy()
    scale[cap] = 1.0
    return scale


def hub_scales(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    incidence: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]],
    degree: NDArray[np.int64],
    radii: NDArray[np.float64],
    prad: NDArray[np.float64],
    end_offset: NDArray[np.float64],
    length: NDArray[np.float64],
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    face_start: NDArray[np.int64],
    node_rep: NDArray[np.int64],
    P: int,
    *,
    frames: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per-node scale ``s_n`` that gives each hub the exact solid's volume (module docstring).

    Parameters
    ----------
    radii : (M, 2) float64
        Design radii.
    prad : (M, 2) float64
        Profile circumradii the hubs were built for.
    end_offset : (M, 2) float64
        Their offsets.
    length : (M,) float64
        Strut lengths.
    vertices, faces : the mesh built with ``prad`` and ``end_offset``.
    face_start : (N,) int64
        First row of each node's hub triangles.
    node_rep : (N,) int64
        Distinct hub of each node of degree >= 2 (translates share one), -1 otherwise.
    frames : tuple
        The stitch's strut frames ``(axis (M, 3), sign (M,), frame_u (M, 3), frame_v
        (M, 3))`` (``_kernels.edge_frames``): the volumes are computed from them relative
        to the node, so that they do not depend on which translate represents a hub.

    Returns
    -------
    scale : (N,) float64
        ``s_n`` (1 at nodes of degree < 2).
    v_hull, v_exact : (N,) float64
        Hull and exact hub-region volumes before the correction (0 at degree < 2).
    """
    offsets, inc_edge, inc_side = incidence
    n_nodes = len(nodes)
    hubs = np.flatnonzero(degree >= 2)
    scale = np.ones(n_nodes)
    v_hull = np.zeros(n_nodes)
    v_exact = np.zeros(n_nodes)
    if not len(hubs):
        return scale, v_hull, v_exact
    # one representative node per distinct hub (translates have equal volumes)
    reps_of, first = np.unique(node_rep[hubs], return_index=True)
    rep_nodes = hubs[first]
    vh = np.empty(len(rep_nodes))
    vx = np.empty(len(rep_nodes))
    W = _hub_kernels.sphere_directions(int(config.HUB_QUADRATURE))
    axis, sign, frame_u, frame_v = frames
    _hub_kernels.hub_mesh_volumes(
        rep_nodes, axis, sign, frame_u, frame_v, faces, face_start, offsets, inc_edge,
        inc_side, prad, end_offset, P, vh,
    )  # fmt: skip
    _hub_kernels.exact_hub_volumes(
        rep_nodes, axis, sign, offsets, inc_edge, inc_side, radii, end_offset, W, vx
    )
    pos = np.searchsorted(reps_of, node_rep[hubs])
    v_hull[hubs] = vh[pos]
    v_exact[hubs] = vx[pos]

    # growth (hubs lighter than the exact solid: struts all on one side of a boundary
    # node) is bounded so that every strut keeps its open cylinder whatever both ends do
    need = end_offset.sum(axis=1)
    room = np.full(len(edges), np.inf)
    pos_need = need > 0.0
    room[pos_need] = (1.0 - config.FIT_SLACK) * length[pos_need] / need[pos_need]
    hi_s = np.full(n_nodes, float(config.MAX_HUB_SCALE))
    np.minimum.at(hi_s, edges[:, 0], room)
    np.minimum.at(hi_s, edges[:, 1], room)
    hi_s = np.maximum(hi_s, 1.0)
    # every node iterates on its own until its step is below 1e-13: a node's scale depends
    # on its own struts only (a shard of the graph gives the same bits; see
    # lattice_cad.distributed)
    poly = 0.5 * P * math.sin(2.0 * math.pi / P)
    gap0 = band_gaps(prad, end_offset, length)
    s = np.empty(n_nodes)
    _hub_kernels.band_scales(
        offsets, inc_edge, inc_side, prad, end_offset, length, gap0, v_hull, v_exact,
        float(config.MIN_HUB_SCALE), hi_s, poly, s,
    )  # fmt: skip
    return s, v_hull, v_exact
