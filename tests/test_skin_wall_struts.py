"""Struts wholly inside a skin's wall are left out before the radii are fitted (s37).

The GE bracket's skin case of issue 11 (octet 6 mm, r 0.5, skin 1.5) reported 6,386
struts thinned, 2,481 of them below 0.7 x the radius asked; most lay inside the wall,
where the skin swallows them, and the struts beside them were thinned for them. They are
now left out (``voxel_lattice(wall=)``): 882 below 0.7 x.
"""

from __future__ import annotations

import warnings

import manifold3d
import numpy as np
import trimesh

from conformal import Part, load_part, voxel_lattice
from conformal.voxel import WALL_SHARE, struts_in_wall
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import DATA

PLATE = DATA / "step" / "kcl_mounting-plate.step"


def _box(lo: np.ndarray, hi: np.ndarray) -> Part:
    box = manifold3d.Manifold.cube(list(hi - lo)).translate(list(lo))
    mesh = box.to_mesh()
    return Part(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name="box")


def test_struts_in_wall_against_the_exact_distance_in_a_box(rng):
    """A box's distance to its surface, inside it, is the smallest distance to a face:
    exact along each strut (sampled at 4,001 points, where it is piecewise linear and
    concave). No strut is called inside the wall whose capsule reaches deeper than
    WALL_SHARE x the wall; every strut that lies in it with the samples' slack to spare
    (a quarter of the wall between samples) is found."""
    lo, hi = np.zeros(3), np.array([40.0, 30.0, 20.0])
    part = _box(lo, hi)
    wall, n = 2.0, 4000
    a = rng.uniform(lo, hi, (n, 3))
    # half of them near a face: ends pulled within the wall of the nearest face
    near = rng.random(n) < 0.5
    axis = rng.integers(0, 3, n)
    side = rng.random(n) < 0.5
    depth = rng.uniform(0.0, wall, n)
    a[near, axis[near]] = np.where(
        side[near], lo[axis[near]] + depth[near], hi[axis[near]] - depth[near]
    )
    b = a + rng.normal(0.0, 1.5, (n, 3))
    b[near, axis[near]] = np.where(
        side[near],
        lo[axis[near]] + rng.uniform(0, wall, near.sum()),
        hi[axis[near]] - rng.uniform(0, wall, near.sum()),
    )
    b = np.clip(b, lo + 1e-6, hi - 1e-6)
    nodes = np.concatenate([a, b])
    edges = np.column_stack([np.arange(n), np.arange(n) + n])
    radii = rng.uniform(0.05, 1.2, n)
    got = struts_in_wall(part, nodes, edges, radii, wall)

    t = np.linspace(0.0, 1.0, 4001)
    pts = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    exact = np.minimum(pts - lo, hi - pts).min(axis=2).max(axis=1)  # (n,) deepest point
    reach = exact + radii
    limit = WALL_SHARE * wall
    assert not (got & (reach > limit + 1e-9)).any()  # never a strut that reaches deeper
    sure = reach + 0.125 * wall <= limit
    assert sure.sum() > 200 and got[sure].all()
    assert got.sum() >= sure.sum()


def _capsules(nodes: np.ndarray, edges: np.ndarray, r: float) -> manifold3d.Manifold:
    """The struts' capsules (polygonal, inside the true ones), united."""
    pieces = []
    for i, j in edges:
        s0 = manifold3d.Manifold.sphere(r, 16).translate(list(nodes[i]))
        s1 = manifold3d.Manifold.sphere(r, 16).translate(list(nodes[j]))
        pieces.append(manifold3d.Manifold.batch_hull([s0, s1]))
    return manifold3d.Manifold.batch_boolean(pieces, manifold3d.OpType.Add)


def test_the_struts_left_out_lie_in_the_printed_wall():
    """The shared mounting plate with a skin of 3 x the radius: the struts left out would
    have been swallowed by the skin (their capsules inside the part lie inside the solid
    written, by manifold3d's booleans), and no more struts are thinned than with them."""
    from lattice_cad import Lattice

    part = load_part(PLATE)
    cell = float(part.size.max()) / 15
    r, skin = cell / 12, cell / 4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        g0, rep0 = voxel_lattice(part, "octet", cell, r, fill="clip", return_report=True)
        g1, rep1 = voxel_lattice(part, "octet", cell, r, fill="clip", return_report=True, wall=skin)
        lat = Lattice.fill(PLATE, cell="octet", cell_size=cell, radius=r, skin=skin)
        mesh = lat.mesh()
    assert lat.build_report.removed_in_wall == rep1.removed_in_wall
    assert rep1.removed_in_wall > 100
    assert g1.num_edges == g0.num_edges - rep1.removed_in_wall
    assert rep1.radii_reduced < rep0.radii_reduced
    assert rep1.thinned_beyond_tolerance <= rep0.thinned_beyond_tolerance

    out = struts_in_wall(part, g0.nodes, g0.edges, np.full(g0.num_edges, r), skin)
    assert int(out.sum()) == rep1.removed_in_wall
    caps = _capsules(g0.nodes, g0.edges[out], r)
    solid = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )
    assert solid.status() == manifold3d.Error.NoError
    # the cavity: the solid's shells that face inward (trimesh's split), turned outward
    shells = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).split(only_watertight=False)
    cavities = [s for s in shells if s.volume < 0]
    assert cavities
    cavity = manifold3d.Manifold.batch_boolean(
        [
            manifold3d.Manifold(
                manifold3d.Mesh(
                    vert_properties=np.asarray(c.vertices, dtype=np.float32),
                    tri_verts=np.asarray(c.faces[:, ::-1], dtype=np.uint32),
                )
            )
            for c in cavities
        ],
        manifold3d.OpType.Add,
    )
    assert cavity.volume() > 0.1 * part.volume
    # the struts left out: none of them reaches into the cavity (a strut that did would be
    # missing from the lattice printed there)
    assert (caps ^ cavity).volume() == 0.0
    assert (_capsules(g0.nodes, g0.edges[~out][:300], r) ^ cavity).volume() > 0  # (the test)
