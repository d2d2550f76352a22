"""Skins: hollow a part to a wall thickness and unite the wall with a lattice.

The printable result of ``Lattice.fill(part, skin=t)`` is one watertight mesh:
the part minus its inset by ``t`` (the skin), united with the lattice clipped
to the part, so that the struts that reach the boundary end inside the wall.
All booleans are done by manifold3d, whose results are guaranteed manifold.

The inset (the cavity) is computed on a voxel grid: the inside of the part is
rasterised slice by slice (manifold3d slices, even-odd polygon fill), an
exact Euclidean distance transform gives the distance to the boundary, and a
marching-tetrahedra pass (a Freudenthal split of every voxel, so the surface
is closed and 2-manifold by construction) extracts the level ``d = t``. The
wall thickness is therefore exact up to about half a voxel; the voxel size is
``thickness / 3`` unless the grid would exceed :data:`config.MAX_VOXELS`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.errors import SkinError
from lattice_cad.core.mesh import mesh_arrays, weld

__all__ = ["SkinError", "as_manifold", "inset", "hollow", "add_skin"]


def shape_mesh(
    shape: Any, tolerance: float = 0.01, angular: float = 0.2
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Tessellate a cadquery/build123d/OCCT shape into a welded triangle mesh.

    Parameters
    ----------
    shape : cadquery.Workplane, cadquery.Shape, build123d shape or TopoDS_Shape
    tolerance, angular : float
        Linear (mm) and angular (rad) deflection of the tessellation.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    """
    from lattice_cad.occ_impl import shapes as occ

    topo = occ.as_topods(shape)
    if topo is None:
        raise TypeError(f"cannot tessellate a {type(shape).__name__}")
    if not occ.solids(topo):
        raise SkinError("the shape holds no solid to tessellate")
    v, f = occ.tessellate(topo, tolerance, angular)
    return weld(v, f, tol=1e-9)


def as_manifold(obj: Any, *, name: str = "part") -> Any:
    """A ``manifold3d.Manifold`` of a part or mesh.

    Parameters
    ----------
    obj : Manifold, fast_stitch.Mesh, trimesh.Trimesh, (vertices, faces), CAD shape, or Part
        A ``conformal.Part`` is used through its ``mesh`` / ``shape`` attribute.
    name : str
        What to call the object in error messages.

    Raises
    ------
    SkinError
        When the mesh is not a closed 2-manifold (manifold3d's status is named).
    """
    import manifold3d

    if isinstance(obj, manifold3d.Manifold):
        return obj
    arrays = mesh_arrays(obj)
    if arrays is None:
        for attr in ("mesh", "shape", "solid", "wrapped"):
            inner = getattr(obj, attr, None)
            if inner is not None and not callable(inner):
                if attr in ("mesh",):
                    arrays = mesh_arrays(inner)
                if arrays is None:
                    try:
                        arrays = shape_mesh(inner if attr != "wrapped" else obj)
                    except TypeError:
                        arrays = None
                if arrays is not None:
                    break
        if arrays is None:
            arrays = shape_mesh(obj)
    v, f = arrays
    if len(f) == 0:
        raise SkinError(f"{name} has no triangles")
    v, f = weld(v, f, tol=1e-9)
    man = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(v, dtype=np.float32),
            tri_verts=np.ascontiguousarray(f, dtype=np.uint32),
        )
    )
    status = man.status()
    if status != manifold3d.Error.NoError:
        raise SkinError(f"{name} is not a closed 2-manifold solid (manifold3d: {status.name})")
    return man


def to_arrays(man: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices (V, 3) float64 and faces (F, 3) int64 of a manifold3d.Manifold."""
    arrays = mesh_arrays(man)
    assert arrays is not None
    return arrays


# ------------------------------------------------------------- distance field
def _inside_grid(
    man: Any, origin: NDArray[np.float64], h: float, shape: tuple[int, int, int]
) -> NDArray[np.bool_]:
    """Inside mask at voxel centres ``origin + (i + 0.5) * h`` (exact winding numbers)."""
    from conformal.part import Part

    v, f = to_arrays(man)
    part = Part(v, f, name="skin")
    return part.grid_contains(origin + 0.5 * h, np.full(3, h), shape)


def _grid_spacing(extent: NDArray[np.float64], thickness: float) -> float:
    h = thickness / config.VOXELS_PER_THICKNESS
    vol = float(np.prod(extent + 4 * h))
    if vol / h**3 > config.MAX_VOXELS:
        h = (vol / config.MAX_VOXELS) ** (1.0 / 3.0)
    return h


# ---------------------------------------------------------- marching tetrahedra
# Freudenthal split of the unit cube: 6 tets along the main diagonal, corner codes
# are bit masks (x=1, y=2, z=4); every tet runs 0 -> a -> a|b -> 7.
_TETS = np.array(
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]],
    dtype=np.int64,
)
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def marching_tets(
    field: NDArray[np.float64], origin: NDArray[np.float64], h: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Closed, outward-oriented surface ``field = 0`` of a grid sampled field.

    Parameters
    ----------
    field : (nx, ny, nz) float64
        Positive inside, negative outside; must be negative on the whole grid boundary.
    origin : (3,) float64
        Position of sample ``[0, 0, 0]``.
    h : float
        Grid spacing.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Each vertex lies on a grid edge or Freudenthal diagonal, shared by all the
        triangles that cross that edge, so the surface is watertight and 2-manifold.
    """
    f = np.where(field == 0.0, -1e-12, field)  # no sample exactly on the surface
    nx, ny, nz = f.shape
    inside = f > 0
    # cubes that the surface crosses
    c = inside[:-1, :-1, :-1]
    corners = [
        inside[dx : nx - 1 + dx, dy : ny - 1 + dy, dz : nz - 1 + dz]
        for dz in (0, 1)
        for dy in (0, 1)
        for dx in (0, 1)
    ]
    any_in = np.zeros_like(c)
    all_in = np.ones_like(c)
    for cc in corners:
        any_in |= cc
        all_in &= cc
    cubes = np.argwhere(any_in & ~all_in)  # (C, 3)
    if len(cubes) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    bits = np.array([[(b >> 0) & 1, (b >> 1) & 1, (b >> 2) & 1] for b in range(8)], dtype=np.int64)
    stride = np.array([ny * nz, nz, 1], dtype=np.int64)
    # tet corner grid indices (T, 4, 3)
    tet_ijk = cubes[:, None, None, :] + bits[_TETS][None, :, :, :]
    tet_ijk = tet_ijk.reshape(-1, 4, 3)
    lin = tet_ijk @ stride  # (T, 4)
    val = f.ravel()[lin]
    ins = val > 0
    n_in = ins.sum(axis=1)
    keep = (n_in > 0) & (n_in < 4)
    lin, val, ins, tet_ijk, n_in = lin[keep], val[keep], ins[keep], tet_ijk[keep], n_in[keep]
    # crossing points on the 6 tet edges, keyed by their grid vertex pair
    a, b = _TET_EDGES[:, 0], _TET_EDGES[:, 1]
    va, vb = val[:, a], val[:, b]  # (T, 6)
    crosses = ins[:, a] != ins[:, b]
    la, lb = lin[:, a], lin[:, b]
    key_lo = np.minimum(la, lb)
    key_hi = np.maximum(la, lb)
    keys = key_lo * (nx * ny * nz) + key_hi  # unique id of a grid segment
    flat_keys = keys[crosses]
    _, first, inv = np.unique(flat_keys, return_index=True, return_inverse=True)
    rows, cols = np.nonzero(crosses)
    rows, cols = rows[first], cols[first]
    pa = origin + tet_ijk[rows, a[cols], :] * h
    pb = origin + tet_ijk[rows, b[cols], :] * h
    ta, tb = va[rows, cols], vb[rows, cols]
    vertices = pa + (ta / (ta - tb))[:, None] * (pb - pa)
    vid = np.full(keys.shape, -1, dtype=np.int64)
    vid[crosses] = inv.reshape(-1)
    # triangles: 1 or 3 inside -> one triangle; 2 inside -> a quad (two triangles)
    tris = []
    odd = np.flatnonzero(n_in != 2)
    if len(odd):
        # the lone vertex (inside when n_in == 1, outside when n_in == 3)
        lone_is_in = n_in[odd] == 1
        lone = np.argmax(ins[odd] == lone_is_in[:, None], axis=1)
        # the 3 edges at the lone vertex
        edge_of = np.array([[0, 1, 2], [0, 3, 4], [1, 3, 5], [2, 4, 5]], dtype=np.int64)
        e3 = edge_of[lone]
        tris.append(np.take_along_axis(vid[odd], e3, axis=1))
    quad = np.flatnonzero(n_in == 2)
    if len(quad):
        # inside pair (p, q), outside pair (r, s): crossing edges p-r, p-s, q-s, q-r form a cycle
        pair_edge = {(0, 1): 0, (0, 2): 1, (0, 3): 2, (1, 2): 3, (1, 3): 4, (2, 3): 5}
        e_idx = np.zeros((16, 4), dtype=np.int64)
        for mask in range(16):
            inn = [i for i in range(4) if (mask >> i) & 1]
            out = [i for i in range(4) if not (mask >> i) & 1]
            if len(inn) != 2:
                continue
            p, q = inn
            r, s = out

            def e(i: int, j: int) -> int:
                return pair_edge[(min(i, j), max(i, j))]

            e_idx[mask] = [e(p, r), e(p, s), e(q, s), e(q, r)]
        masks = (ins[quad] * np.array([1, 2, 4, 8])).sum(axis=1)
        cyc = np.take_along_axis(vid[quad], e_idx[masks], axis=1)
        tris.append(cyc[:, [0, 1, 2]])
        tris.append(cyc[:, [0, 2, 3]])
    faces = np.vstack(tris)
    # orientation: the normal must point from inside to outside (along -grad f)
    inside_pt = np.zeros((len(faces), 3))
    src = np.concatenate([odd, quad, quad]) if len(quad) else odd
    wsum = np.where(ins[src], 1.0, 0.0)
    corner_pos = origin + tet_ijk[src] * h
    inside_pt = (corner_pos * wsum[..., None]).sum(axis=1) / wsum.sum(axis=1)[:, None]
    tri_pts = vertices[faces]
    normal = np.cross(tri_pts[:, 1] - tri_pts[:, 0], tri_pts[:, 2] - tri_pts[:, 0])
    centre = tri_pts.mean(axis=1)
    flip = np.einsum("ij,ij->i", normal, centre - inside_pt) < 0
    faces[flip] = faces[flip][:, ::-1]
    return vertices, faces


# ------------------------------------------------------------------- hollowing
def inset(part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """The part shrunk by ``thickness`` (its cavity when hollowed), as a Manifold.

    Parameters
    ----------
    part : Manifold, mesh or CAD shape
        A closed solid (see :func:`as_manifold`).
    thickness : float
        Wall thickness (> 0, same unit as the part).
    voxel : float, optional
        Grid spacing of the distance field (default ``thickness / 3``, coarser
        if the grid would exceed :data:`config.MAX_VOXELS`).

    Returns
    -------
    manifold3d.Manifold
        Empty when the part is nowhere thicker than ``2 * thickness``.
    """
    import manifold3d
    from scipy.ndimage import distance_transform_edt

    if not (isinstance(thickness, (int, float)) and math.isfinite(thickness) and thickness > 0):
        raise ValueError(f"skin thickness must be a positive number, got {thickness!r}")
    man = as_manifold(part)
    bb = np.asarray(man.bounding_box(), dtype=np.float64).reshape(2, 3)
    extent = bb[1] - bb[0]
    h = float(voxel) if voxel is not None else _grid_spacing(extent, thickness)
    pad = 2 * h
    origin = bb[0] - pad
    sx, sy, sz = (int(n) for n in np.ceil((extent + 2 * pad) / h).astype(np.int64) + 1)
    shape = (sx, sy, sz)
    inside = _inside_grid(man, origin, h, shape)  # (nx, ny, nz) at voxel centres
    # signed distance to the boundary, which lies half a voxel beyond the last centre
    d_in = distance_transform_edt(inside, sampling=h)
    field = d_in - 0.5 * h - thickness
    field[~inside] = -thickness
    v, f = marching_tets(field, origin + 0.5 * h, h)
    if len(f) == 0:
        return manifold3d.Manifold()
    out = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(v, dtype=np.float32),
            tri_verts=np.ascontiguousarray(f, dtype=np.uint32),
        )
    )
    if out.status() != manifold3d.Error.NoError:  # pragma: no cover - construction guarantee
        raise SkinError(f"the inset surface is not manifold ({out.status().name})")
    # merge the many small coplanar triangles, then stay strictly inside the part
    return out.simplify(0.05 * h) ^ man


def hollow(part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """The skin: ``part`` minus its inset by ``thickness`` (a Manifold).

    Raises
    ------
    SkinError
        When the part has no room for a cavity (it is thinner than ``2 * thickness``).
    """
    man = as_manifold(part)
    cavity = inset(man, thickness, voxel=voxel)
    if cavity.is_empty():
        raise SkinError(
            f"the part is nowhere thicker than twice the skin thickness {thickness:g}: "
            "no room for a lattice (use a thinner skin)"
        )
    return man - cavity


def add_skin(lattice: Any, part: Any, thickness: float, *, voxel: float | None = None) -> Any:
    """One solid: the skin of ``part`` united with ``lattice`` clipped to the part.

    Parameters
    ----------
    lattice : fast_stitch.Mesh, Manifold or mesh-like
        The stitched lattice (struts may cross the part's boundary: they are cut
        by it, so that every strut reaching the boundary ends inside the wall).
    part : Manifold, mesh or CAD shape
    thickness : float
        Wall thickness.

    Returns
    -------
    manifold3d.Manifold
        Watertight and 2-manifold (manifold3d guarantees it).
    """
    man = as_manifold(part)
    skin = hollow(man, thickness, voxel=voxel)
    lat = as_manifold(lattice, name="lattice mesh")
    out = (skin + (lat ^ man)).simplify(config.SLIVER)
    # negative-volume shells are the walls of the (lattice-filled) cavity, not bodies
    pieces = sum(1 for p in out.decompose() if p.volume() > 0)
    if pieces > 1:
        import warnings

        from lattice_cad.core.errors import LatticeWarning

        warnings.warn(
            f"the skinned part has {pieces} separate pieces: some lattice struts do not reach "
            "the skin (use fill='clip' so that struts run into the wall)",
            LatticeWarning,
            stacklevel=2,
        )
    return out
