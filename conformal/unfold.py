"""The surface of a part whose B-rep folds over itself, rebuilt from the region it encloses.

A sweep along a path that loops or turns back (a cabinet handle, a pipe elbow whose arc
bends the wrong way) gives a solid BRepCheck accepts but whose surface crosses itself:
sheets of it lie inside the solid (``conformal.Part.folds``). A boolean by such a surface
bounds no solid at any chord error, so a lattice could be neither cut to it nor skinned.

:func:`rebuilt_part` rebuilds the boundary of the region the surface encloses (the points
of nonzero winding number: where bodies of a sweep overlap the winding is 2, where it
turns back -1; all of it is the part) on a grid of spacing ``h``:

1. the grid's points are classified by winding numbers (``Part.grid_contains``, exact for
   the tessellation);
2. at the points with a neighbour on the other side (26-neighbourhood: the tetrahedra
   of the Freudenthal split join diagonal neighbours too), the exact distance to the
   surface, signed by that side. An inside point's nearest surface may be a folded sheet
   within the solid, nearer than the boundary: the crossing then moves inward, never out;
   an outside point's distance is to the boundary itself;
3. marching tetrahedra of that field (``conformal.skin.marching_tets``: watertight,
   2-manifold, no crossing), simplified within 2 % of ``h`` by manifold3d without folds;
4. the voids a folded sheet encloses inside the solid (pockets of winding number 0) are
   removed, and so are specks smaller than a grid cell; a void at an inner shell of the
   part (a cavity it has) is kept.

Away from creases the surface lies within a small fraction of ``h`` of the exact one; the
triangles across a concave crease (the floor of a blind hole, a tube meeting its flange)
stand out of it by up to about ``0.7 h`` (the lattice cut by it: the handle 0.10-0.13 mm
at ``h`` = 0.38 mm, the folded elbow 0.22 mm at 0.32 mm), a convex crease is chamfered
inward. The cut and the skin say so in their reports (``TrimReport.rebuilt``,
``SkinReport.rebuilt``), the cut's protrusion measured against the part as loaded.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config

__all__ = ["rebuilt_part", "rebuild_spacing"]

#: Grid spacing of the rebuild in strut radii (the cut's protrusion at concave creases is
#: about half of it).
REBUILD_RTOL = 0.5

#: manifold3d's simplification of the marching tetrahedra, in grid spacings (the handle's
#: 460 K triangles become 96 K; the protrusion does not change).
SIMPLIFY_SPACINGS = 0.02


def rebuild_spacing(part: Any, radius: float) -> float:
    """The rebuild's grid spacing (mm) for struts of ``radius``: ``REBUILD_RTOL`` radii, or
    coarser where the part's box would hold more than ``config.MAX_VOXELS`` points."""
    h = REBUILD_RTOL * float(radius)
    box = float(np.prod(np.asarray(part.size, dtype=np.float64) + 4.0 * h))
    if box / h**3 > config.MAX_VOXELS:
        h = (box / config.MAX_VOXELS) ** (1.0 / 3.0)
    return h


def rebuilt_part(part: Any, *, spacing: float) -> Any:
    """The boundary of the region ``part``'s surface encloses, rebuilt on a grid.

    Parameters
    ----------
    part : conformal.Part
        A closed surface that may cross itself (``Part.folds``).
    spacing : float
        Grid spacing (mm), e.g. :func:`rebuild_spacing`.

    Returns
    -------
    conformal.Part
        A closed, 2-manifold surface that does not cross itself, without a B-rep; its
        ``rebuilt`` is ``spacing`` and its ``deflection`` half of it.

    Raises
    ------
    PartError
        Nothing of the part is left on the grid (a part thinner than the spacing).
    """
    from scipy import ndimage

    from conformal.part import Part
    from conformal.skin import _GRID_SHIFT, _manifold, _simplified, marching_tets, to_arrays
    from lattice_cad.core.errors import PartError

    h = float(spacing)
    if not h > 0:
        raise ValueError(f"spacing must be positive, got {spacing!r}")
    lo = np.asarray(part.bounds[0], dtype=np.float64)
    pad = 2.0 * h
    # off the round positions a CAD part's faces sit on (as the skin's grid)
    origin = lo - pad + _GRID_SHIFT * h
    dims = tuple(int(n) for n in np.ceil((np.asarray(part.size) + 2 * pad) / h) + 1)
    inside = part.grid_contains(origin, np.full(3, h), dims)
    if not inside.any():
        raise PartError(
            f"{part.name}: no point of a {h:.3g} mm grid lies inside the part, so its folded "
            "surface cannot be rebuilt on it"
        )
    rim = ndimage.maximum_filter(inside, size=3) != ndimage.minimum_filter(inside, size=3)
    field = np.where(inside, 2.0 * h, -2.0 * h)
    at = np.nonzero(rim)
    dist = part.distance(origin + np.stack(at, axis=1) * h, max_distance=4.0 * h)
    dist = np.where(np.isfinite(dist), dist, 2.0 * h)
    field[at] = np.where(inside[at], dist, -dist)
    v, f = marching_tets(field, origin, h)
    del field, inside, rim
    name = f"{part.name} (rebuilt on a {h:.3g} mm grid)"
    solid = _simplified(_manifold(v, f, name), SIMPLIFY_SPACINGS * h, name)
    v, f = _without_fold_pockets(*to_arrays(solid), part, h)
    out = Part(v, f, name=part.name, deflection=0.5 * h)
    out.rebuilt = h
    return out


def _without_fold_pockets(
    v: NDArray[np.float64], f: NDArray[np.int64], part: Any, h: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The rebuilt surface ``v, f`` without the voids its folds enclose and its specks.

    Where a folded sheet turns back inside the solid it can enclose a pocket of winding
    number 0 (the swept handle: two of 0.1 mm): the rebuild holds it as a void, which a
    skin would wall and measure. A void of the rebuild is kept only when it lies at an
    inner shell of the part (a cavity the part has: one of its pieces with a negative
    volume, within ``2 h``); the others are removed.
    """
    from conformal.skin_split import pieces

    n, vlabel, vols = pieces(v, f)
    # specks: pieces smaller than a grid cell, which the grid cannot resolve (the elbow's
    # rebuild held one of 8 vertices and 1e-5 mm^3)
    specks = np.flatnonzero((vols > 0) & (vols < h**3) & (vols < vols.max()))
    voids = np.flatnonzero(vols < 0)
    if n <= 1 or not (len(voids) or len(specks)):
        return v, f
    pn, plabel, pvols = pieces(part.vertices, part.faces)
    inner = np.flatnonzero(pvols < 0)
    shells = None
    if len(inner):
        from conformal.part import Part

        at = np.isin(plabel[part.faces[:, 0]], inner)
        shells = Part(part.vertices, part.faces[at], name="inner shells")
    drop = list(specks)
    for k in voids:
        pts = v[vlabel == k]
        pts = pts[:: max(1, len(pts) // 64)]
        if shells is None or not float(shells.distance(pts, max_distance=4 * h).min()) <= 2 * h:
            drop.append(k)
    if not drop:
        return v, f
    keep = ~np.isin(vlabel[f[:, 0]], drop)
    f = f[keep]
    used = np.zeros(len(v), dtype=bool)
    used[f.ravel()] = True
    renum = np.cumsum(used) - 1
    return v[used], renum[f]
