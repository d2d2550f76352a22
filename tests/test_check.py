"""Tests of the independent mesh checker :func:`fast_stitch.check.check`."""

from __future__ import annotations

import json

import manifold3d
import numpy as np
import pytest
import trimesh

from fast_stitch.check import CheckReport, check
from tests.conftest import DATA

BROKEN = DATA / "broken"


# ----------------------------------------------------------------------------- helpers


def cube(lo=(0.0, 0.0, 0.0), size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Outward axis-aligned cube: (8, 3) float64 vertices, (12, 3) int64 faces."""
    lo = np.asarray(lo, dtype=np.float64)
    box = trimesh.creation.box(bounds=[lo, lo + size])
    return np.asarray(box.vertices, dtype=np.float64), np.asarray(box.faces, dtype=np.int64)


def join(*meshes) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate (vertices, faces) pairs without merging anything."""
    vs, fs, off = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.vstack(vs), np.vstack(fs)


def pymeshlab_faces(v: np.ndarray, f: np.ndarray) -> set[int]:
    """Faces that pymeshlab selects as self-intersecting."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return set(np.flatnonzero(ms.current_mesh().face_selection_array()).tolist())


def our_faces(rep: CheckReport) -> set[int]:
    assert len(rep.self_intersection_pairs) == rep.n_self_intersections  # all reported
    return set(np.unique(rep.self_intersection_pairs).tolist())


def manifold3d_ok(v: np.ndarray, f: np.ndarray) -> bool:
    mesh = manifold3d.Mesh(vert_properties=v.astype(np.float32), tri_verts=f.astype(np.uint32))
    return manifold3d.Manifold(mesh).status() == manifold3d.Error.NoError


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# ------------------------------------------------------------------- closed-form cases


def test_unit_cube_is_valid():
    v, f = cube()
    rep = check((v, f))
    assert rep.valid and rep.watertight and rep.manifold and rep.oriented and rep.outward
    assert rep.volume == pytest.approx(1.0, abs=1e-14)
    assert rep.euler_characteristic == 2
    assert (rep.n_vertices, rep.n_faces, rep.n_edges, rep.n_components) == (8, 12, 18, 1)
    assert rep.n_self_intersections == 0 and rep.n_self_intersecting_faces == 0
    assert rep.n_zero_area == 0 and rep.n_unused_vertices == 0
    assert str(rep).startswith("12 faces") and "valid" in str(rep)
    assert rep.problems() == []


def test_accepts_trimesh_objects_and_any_integer_dtype():
    box = trimesh.creation.box()
    assert check(box).valid
    from lattice_cad.core.mesh import Mesh

    assert check(Mesh(np.asarray(box.vertices), np.asarray(box.faces))).valid
    v, f = cube()
    assert check((v.astype(np.float32), f.astype(np.uint32))).valid
    assert check([v.tolist(), f.tolist()]).valid


def test_missing_face_gives_three_boundary_edges():
    v, f = cube()
    rep = check((v, f[1:]))
    assert rep.n_boundary_edges == 3
    assert not rep.watertight and not rep.valid
    assert rep.oriented and rep.manifold
    assert rep.euler_characteristic == 1
    # every reported boundary edge is an edge of the removed face, used by one face
    removed = {tuple(sorted(e)) for e in [f[0, [0, 1]], f[0, [1, 2]], f[0, [2, 0]]]}
    assert {(a, b) for a, b, _ in rep.boundary_edges.tolist()} == removed
    for a, b, face in rep.boundary_edges.tolist():
        assert {a, b} <= set(f[1:][face].tolist())
    assert "3 boundary edges" in str(rep)


def test_one_flipped_face_gives_inconsistent_edges():
    v, f = cube()
    f = f.copy()
    f[5] = f[5, ::-1]
    rep = check((v, f))
    assert rep.n_inconsistent_edges == 3
    assert rep.watertight and not rep.oriented and not rep.valid
    edges5 = {tuple(sorted(e)) for e in [f[5, [0, 1]], f[5, [1, 2]], f[5, [2, 0]]]}
    assert {(a, b) for a, b, _ in rep.inconsistent_edges.tolist()} == edges5
    assert "inconsistently oriented" in str(rep)


def test_all_faces_flipped_is_inward():
    v, f = cube()
    rep = check((v, f[:, ::-1]))
    assert rep.oriented and rep.watertight and rep.manifold
    assert rep.volume == pytest.approx(-1.0)
    assert not rep.outward and not rep.valid
    assert rep.n_inverted_components == 1
    assert rep.inverted_component_faces.tolist() == [0]


def test_duplicated_face_gives_nonmanifold_edges_and_an_intersection():
    v, f = cube()
    rep = check((v, np.vstack([f, f[3:4]])))
    assert rep.n_nonmanifold_edges == 3
    assert not rep.watertight and not rep.manifold and not rep.valid
    # the copy coincides with the original face and with nothing else
    assert rep.n_self_intersections == 1
    assert rep.self_intersection_pairs.tolist() == [[3, 12]]
    assert "non-manifold edges" in str(rep)


def test_two_cubes_sharing_one_vertex_is_a_nonmanifold_vertex():
    v0, f0 = cube()
    v1, f1 = cube(lo=(1.0, 1.0, 1.0))
    shared0 = int(np.flatnonzero((v0 == 1.0).all(axis=1))[0])
    shared1 = int(np.flatnonzero((v1 == 1.0).all(axis=1))[0])
    # second cube: drop its copy of the corner, use the first cube's one
    keep = np.delete(np.arange(8), shared1)
    remap = np.full(8, -1)
    remap[keep] = 8 + np.arange(7)
    remap[shared1] = shared0
    v = np.vstack([v0, v1[keep]])
    f = np.vstack([f0, remap[f1]])
    rep = check((v, f))
    assert rep.n_nonmanifold_vertices == 1
    assert rep.nonmanifold_vertices.tolist() == [shared0]
    assert rep.watertight and rep.oriented and rep.outward and not rep.manifold
    assert rep.n_components == 2 and rep.volume == pytest.approx(2.0)
    assert rep.n_self_intersections == 0  # the faces only meet at the shared vertex
    assert not rep.valid
    assert manifold3d_ok(v, f)  # manifold3d accepts pinched vertices; we do not


def test_two_overlapping_cubes_self_intersect():
    v, f = join(cube(), cube(lo=(0.5, 0.4, 0.3)))
    rep = check((v, f), max_report=10_000)
    assert rep.watertight and rep.manifold and rep.oriented and rep.outward
    assert rep.n_self_intersections > 0 and not rep.valid
    assert our_faces(rep) == pymeshlab_faces(v, f)
    pairs = rep.self_intersection_pairs
    assert (pairs[:, 0] < 12).all() and (pairs[:, 1] >= 12).all()


def test_cubes_touching_through_distinct_vertices_count_as_intersecting():
    """Decision: topology is by vertex index, and touching closed triangles intersect.

    Two unit cubes side by side, each with its own vertices: every cube is a perfect
    closed shell, but the two coincident square faces (and the faces meeting them along
    edges) touch, so the pair is reported as self-intersecting and the mesh is not a
    valid solid (a printer would see a zero-thickness double wall). pymeshlab does not
    count touching faces and reports nothing here.
    """
    v, f = join(cube(), cube(lo=(1.0, 0.0, 0.0)))
    rep = check((v, f), max_report=10_000)
    assert rep.watertight and rep.manifold and rep.oriented and rep.outward
    assert rep.n_components == 2 and rep.volume == pytest.approx(2.0)
    assert rep.n_self_intersections > 0 and not rep.valid
    # exactly the faces with a vertex on the contact plane x = 1
    assert our_faces(rep) == {i for i in range(len(f)) if (v[f[i], 0] == 1.0).any()}
    # a gap of one ulp is enough to separate them
    v2 = v.copy()
    v2[8:, 0] = np.nextafter(v2[8:, 0], 10.0)
    assert check((v2, f)).valid


def test_zero_area_faces():
    v, f = cube()
    # a vertex in the middle of the cube edge a-b, and a collinear face through it
    a = int(np.flatnonzero((v == [0.0, 0.0, 0.0]).all(axis=1))[0])
    b = int(np.flatnonzero((v == [1.0, 0.0, 0.0]).all(axis=1))[0])
    mid = 0.5 * (v[a] + v[b])
    v2 = np.vstack([v, mid])
    f2 = np.vstack([f, [[a, 8, b]], [[a, a, b]]])
    rep = check((v2, f2))
    assert rep.n_zero_area == 2
    assert rep.zero_area_faces.tolist() == [12, 13]
    assert not rep.valid
    assert "2 zero-area faces" in str(rep)
    # area_tol: a sliver of area 1e-9 only counts with a tolerance
    v3 = np.vstack([v, mid + [0.0, 2e-9, 0.0]])
    f3 = np.vstack([f, [[a, 8, b]]])
    assert check((v3, f3)).n_zero_area == 0
    assert check((v3, f3), area_tol=1e-8).zero_area_faces.tolist() == [12]


def test_unused_vertices_are_reported_but_do_not_invalidate():
    v, f = cube()
    v2 = np.vstack([v, [[5.0, 5.0, 5.0]]])
    rep = check((v2, f))
    assert rep.valid and rep.n_unused_vertices == 1 and rep.unused_vertices.tolist() == [8]
    assert rep.euler_characteristic == 2


def test_cavity_with_inward_shell_is_outward():
    outer = cube(lo=(-2.0, -2.0, -2.0), size=4.0)
    inner_v, inner_f = cube(lo=(-1.0, -1.0, -1.0), size=2.0)
    v, f = join(outer, (inner_v, inner_f[:, ::-1]))
    rep = check((v, f))
    assert rep.n_components == 2
    assert rep.volume == pytest.approx(64.0 - 8.0)
    assert rep.outward and rep.n_inverted_components == 0 and rep.valid
    # a separate inside-out cube next to it is inverted
    far_v, far_f = cube(lo=(10.0, 0.0, 0.0))
    v, f = join(outer, (far_v, far_f[:, ::-1]))
    rep = check((v, f))
    assert rep.volume > 0 and rep.n_inverted_components == 1 and not rep.outward
    assert rep.inverted_component_faces.tolist() == [12]


def test_self_intersections_can_be_skipped():
    v, f = join(cube(), cube(lo=(0.5, 0.4, 0.3)))
    rep = check((v, f), self_intersections=False)
    assert rep.n_self_intersections is None and rep.n_self_intersecting_faces is None
    assert rep.valid  # the intersection is not looked for
    assert "not checked" in str(rep)


def test_max_report_truncates_examples_not_counts():
    rng = np.random.default_rng(7)
    v = rng.random((300, 3))
    f = np.arange(300).reshape(100, 3)
    rep = check((v, f), max_report=5)
    assert rep.n_boundary_edges == 300 and rep.boundary_edges.shape == (5, 3)
    assert rep.n_components == 100
    assert rep.self_intersection_pairs.shape[0] == min(5, rep.n_self_intersections)
    full = check((v, f), max_report=10**6)
    assert full.self_intersection_pairs[:5].tolist() == rep.self_intersection_pairs.tolist()
    assert (np.diff(full.self_intersection_pairs[:, 0]) >= 0).all()
    empty = check((v, f), max_report=0)
    assert empty.boundary_edges.shape == (0, 3) and empty.n_boundary_edges == 300


def test_report_is_json_ready_and_frozen():
    v, f = cube()
    rep = check((v, f[1:]))
    d = rep.to_dict()
    json.dumps(d)
    assert d["n_boundary_edges"] == 3 and d["watertight"] is False and d["valid"] is False
    assert len(d["boundary_edges"]) == 3
    with pytest.raises(AttributeError):
        rep.volume = 2.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        rep.boundary_edges[0, 0] = 1


def test_empty_mesh():
    rep = check((np.zeros((0, 3)), np.zeros((0, 3), np.int64)))
    assert rep.n_faces == 0 and rep.volume == 0.0 and not rep.outward and not rep.valid
    assert rep.n_self_intersections == 0


# ------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "v, f, match",
    [
        (np.zeros((4, 2)), np.zeros((1, 3), int), r"vertices must have shape"),
        (np.zeros((4, 3)), np.zeros((1, 4), int), r"faces must have shape"),
        (np.zeros((4, 3)), np.array([[0, 1, 2], [0, 1, 4]]), r"face 1 "),
        (np.zeros((4, 3)), np.array([[0, 1, 2], [-1, 1, 2]]), r"face 1 "),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]), r"vertex 2 "),
        (np.array([[0, 0, 0], [np.inf, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), r"vertex 1 "),
        (np.zeros((4, 3)), np.array([[0.0, 1.5, 2.0]]), r"face 0 "),
    ],
)
def test_bad_input_raises_value_error(v, f, match):
    with pytest.raises(ValueError, match=match):
        check((v, f))


def test_bad_options_and_objects():
    v, f = cube()
    with pytest.raises(ValueError):
        check((v, f), area_tol=-1.0)
    with pytest.raises(ValueError):
        check((v, f), max_report=-1)
    with pytest.raises(TypeError):
        check(42)
    with pytest.raises(ValueError):
        check((v, f, f))


# ------------------------------------------------------- comparison with other checkers


def test_icosphere_is_valid_and_matches_trimesh():
    m = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    rep = check(m)
    assert rep.valid, str(rep)
    assert rep.euler_characteristic == 2
    assert rep.volume == pytest.approx(m.volume, rel=1e-12)


def _reference_meshes():
    rng = np.random.default_rng(11)
    v, f = cube()
    flipped = f.copy()
    flipped[2] = flipped[2, ::-1]
    yield "cube", v, f
    yield "cube-open", v, f[2:]
    yield "cube-flip-one", v, flipped
    yield "cube-inward", v, f[:, ::-1]
    yield "two-cubes", *join(cube(), cube(lo=(3.0, 0.0, 0.0)))
    m = trimesh.creation.icosphere(subdivisions=2)
    yield "icosphere", np.asarray(m.vertices), np.asarray(m.faces)
    t = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    yield "torus", np.asarray(t.vertices), np.asarray(t.faces)
    soup_v = rng.random((60, 3))
    yield "soup", soup_v, np.arange(60).reshape(20, 3)
    for path in sorted(BROKEN.glob("*")):
        if path.suffix.lower() in (".step", ".stp"):
            continue
        for process in (False, True):
            mesh = trimesh.load(path, process=process, force="mesh")
            yield f"{path.name}-{process}", np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_agrees_with_trimesh_and_manifold3d():
    seen = 0
    for name, v, f in _reference_meshes():
        v = np.asarray(v, dtype=np.float64)
        f = np.asarray(f, dtype=np.int64)
        rep = check((v, f), self_intersections=False)
        tm = trimesh.Trimesh(vertices=v, faces=f, process=False)
        if len(f):
            assert rep.watertight == tm.is_watertight, name
            assert rep.oriented == tm.is_winding_consistent, name
            assert (rep.watertight and rep.oriented and rep.outward) == tm.is_volume, name
        if len(f) and rep.watertight and rep.oriented:  # else the volume is ill-defined
            assert rep.volume == pytest.approx(tm.volume, rel=1e-9, abs=1e-12), name
        # manifold3d also accepts an edge shared by 4 faces (paired up) and pinched vertices
        closed = rep.watertight and rep.oriented
        if rep.n_nonmanifold_edges == 0:
            assert closed == manifold3d_ok(v, f), name
        else:
            assert not closed
        seen += 1
    assert seen > 20


def test_broken_files_expected_defects():
    def load(name, process=False):
        return trimesh.load(BROKEN / name, process=process, force="mesh")

    rep = check(load("cube_no_bottom.obj", process=True))
    assert not rep.watertight and rep.n_boundary_edges > 0
    rep = check(load("trimesh_multibody_flipped_body.stl"))
    assert rep.watertight and not rep.oriented and rep.n_inconsistent_edges == 12
    rep = check(load("trimesh_shared_nonmanifold_edge.STL", process=True))
    assert rep.n_nonmanifold_edges > 0 and not rep.manifold
    rep = check(load("trimesh_soup.stl"))
    assert rep.n_boundary_edges == 300 and rep.n_components == 100 and not rep.valid


@pytest.mark.parametrize("name", ["newell_teapot_open.obj", "trimesh_teapot_open.stl"])
def test_self_intersections_of_merged_files_match_pymeshlab(name):
    mesh = trimesh.load(BROKEN / name, process=True, force="mesh")
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    rep = check((v, f), max_report=10**6)
    assert rep.n_self_intersections > 0
    assert our_faces(rep) == pymeshlab_faces(v, f)


@pytest.mark.parametrize("seed", range(4))
def test_two_random_icospheres_match_pymeshlab(seed):
    rng = np.random.default_rng(seed)
    a = trimesh.creation.icosphere(subdivisions=3)
    b = trimesh.creation.icosphere(subdivisions=3, radius=rng.uniform(0.4, 1.2))
    b.apply_translation(rng.normal(size=3) * 1.2)
    v, f = join(
        (np.asarray(a.vertices), np.asarray(a.faces)), (np.asarray(b.vertices), np.asarray(b.faces))
    )
    rep = check((v, f), max_report=10**6)
    assert our_faces(rep) == pymeshlab_faces(v, f)
    assert rep.n_self_intersecting_faces == len(our_faces(rep))
    assert rep.watertight and rep.manifold and rep.oriented and rep.outward


def test_far_apart_icospheres_do_not_intersect():
    a = trimesh.creation.icosphere(subdivisions=3)
    v, f = join((a.vertices, a.faces), (a.vertices + [2.5, 0.0, 0.0], a.faces))
    rep = check((v, f))
    assert rep.valid and rep.n_components == 2


@pytest.mark.parametrize("seed", range(3))
def test_random_triangle_soup_matches_pymeshlab(seed):
    rng = np.random.default_rng(100 + seed)
    n = 400
    centres = rng.random((n, 3))
    v = (centres[:, None, :] + 0.12 * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    f = np.arange(3 * n).reshape(n, 3)
    rep = check((v, f), max_report=10**6)
    assert rep.n_self_intersections > 0
    assert our_faces(rep) == pymeshlab_faces(v, f)
    # pairs are canonical, unique and sorted
    pairs = rep.self_intersection_pairs
    assert (pairs[:, 0] < pairs[:, 1]).all()
    assert len({tuple(p) for p in pairs.tolist()}) == len(pairs)
    assert np.array_equal(pairs, pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))])


def test_result_does_not_depend_on_face_order():
    rng = np.random.default_rng(5)
    n = 300
    centres = rng.random((n, 3))
    v = (centres[:, None, :] + 0.1 * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    f = np.arange(3 * n).reshape(n, 3)
    rep = check((v, f), max_report=10**6)
    perm = rng.permutation(n)
    rep2 = check((v, f[perm]), max_report=10**6)
    assert rep2.n_self_intersections == rep.n_self_intersections
    back = np.sort(perm[rep2.self_intersection_pairs], axis=1)
    assert {tuple(p) for p in back.tolist()} == {
        tuple(p) for p in rep.self_intersection_pairs.tolist()
    }
    # deterministic
    rep3 = check((v, f[perm]), max_report=10**6)
    assert np.array_equal(rep3.self_intersection_pairs, rep2.self_intersection_pairs)


# ---------------------------------------------------------- no false positives


def test_fine_icosphere_at_large_coordinates_is_valid():
    m = trimesh.creation.icosphere(subdivisions=6)
    v = np.asarray(m.vertices) + [1e6, 0.0, 0.0]
    rep = check((v, m.faces))
    assert rep.valid, str(rep)
    assert rep.n_self_intersections == 0
    assert rep.volume == pytest.approx(m.volume, rel=1e-9)


def test_rotated_prism_with_sliver_fans_is_valid():
    """Fan-triangulated caps: long slivers sharing one vertex, coplanar neighbours."""
    rng = np.random.default_rng(2)
    n = 1000
    t = np.sort(rng.random(n)) * 2 * np.pi
    ring = np.column_stack([np.cos(t), np.sin(t)])
    bottom = np.column_stack([ring, np.zeros(n)])
    top = np.column_stack([ring, np.full(n, 3.0)])
    v = np.vstack([bottom, top])
    i = np.arange(n)
    j = (i + 1) % n
    sides = np.vstack([np.column_stack([i, j, j + n]), np.column_stack([i, j + n, i + n])])
    k = np.arange(1, n - 1)
    cap_bottom = np.column_stack([np.zeros(n - 2, int), k + 1, k])
    cap_top = np.column_stack([np.full(n - 2, n), k + n, k + 1 + n])
    f = np.vstack([sides, cap_bottom, cap_top])
    assert check((v, f)).valid
    v2 = v @ random_rotation(rng).T + [1234.5, -987.25, 4321.0]
    rep = check((v2, f))
    assert rep.valid, str(rep)


def test_lattice_hub_from_manifold3d_is_valid():
    """Boolean union of struts and a ball: slivers along the intersection curves."""
    rng = np.random.default_rng(3)
    hub = manifold3d.Manifold.sphere(0.16, 48)
    for d in rng.normal(size=(6, 3)):
        d = d / np.linalg.norm(d)
        r = float(rng.uniform(0.05, 0.15))
        cyl = manifold3d.Manifold.cylinder(1.0, r, r, int(rng.integers(8, 48)))
        # rotation taking z to d (Rodrigues)
        z = np.array([0.0, 0.0, 1.0])
        ax = np.cross(z, d)
        s, c = np.linalg.norm(ax), float(d @ z)
        kx = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]]) / s
        rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
        hub = hub + cyl.transform(np.hstack([rot, np.zeros((3, 1))]))
    mesh = hub.to_mesh()
    v = np.asarray(mesh.vert_properties[:, :3], np.float64) + [1000.0, -500.0, 2000.0]
    f = np.asarray(mesh.tri_verts, np.int64)
    rep = check((v, f))
    assert rep.valid, str(rep)
    assert rep.n_self_intersections == 0 and pymeshlab_faces(v, f) == set()


def test_folded_neighbours_are_detected():
    """Two faces sharing an edge, folded onto each other, and a near-flat hinge."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0.3, 1, 0], [0.6, 0.8, 0.0]])
    folded = check((v, np.array([[0, 1, 2], [1, 0, 3]])), max_report=10)
    assert folded.n_self_intersections == 1
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [0.3, 1, 0], [0.6, -0.8, 0.0]])
    assert check((flat, np.array([[0, 1, 2], [1, 0, 3]]))).n_self_intersections == 0
    # a hinge folded to a 1e-3 rad opening is not an intersection
    v2 = v.copy()
    v2[3, 2] = 1e-3
    assert check((v2, np.array([[0, 1, 2], [1, 0, 3]]))).n_self_intersections == 0
    # ... but a fold far below the coordinate precision is
    v2[3, 2] = 1e-15
    assert check((v2, np.array([[0, 1, 2], [1, 0, 3]]))).n_self_intersections == 1


# ------------------------------------------- exact narrowphase against a brute force


def _sat_intersect(p: list, q: list) -> bool:
    """Closed convex planar polygons (integer points) intersect: exact separating axes."""

    def sub(a, b):
        return (a[0] - b[0], a[1] - b[1], a[2] - b[2])

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    ep = [sub(p[(i + 1) % len(p)], p[i]) for i in range(len(p))]
    eq = [sub(q[(i + 1) % len(q)], q[i]) for i in range(len(q))]
    n_p, n_q = cross(ep[0], ep[1]), cross(eq[0], eq[1])
    axes = [n_p, n_q] + [cross(n_p, e) for e in ep] + [cross(n_q, e) for e in eq]
    axes += [cross(e, g) for e in ep for g in eq]
    for ax in axes:
        if ax == (0, 0, 0):
            continue
        pp = [dot(ax, x) for x in p]
        qq = [dot(ax, x) for x in q]
        if max(pp) < min(qq) or max(qq) < min(pp):
            return False
    return True


def _reference_pair(t1: list, t2: list, n_shared: int) -> bool:
    """Do the triangles meet outside their shared vertex / edge (by brute force)?

    The shared part is cut off ``t1`` by moving its end points 1e-6 of the way towards the
    other vertices: on a small integer grid every intersection point is much further away.
    """
    n = 10**6

    def lerp(a, b):  # (a + (b - a) / n) * n
        return tuple(a[i] * n + (b[i] - a[i]) for i in range(3))

    def scaled(x):
        return tuple(c * n for c in x)

    if n_shared == 0:
        return _sat_intersect(t1, t2)
    if n_shared == 1:
        p, a, b = t1
        return _sat_intersect(
            [lerp(p, a), scaled(a), scaled(b), lerp(p, b)], [scaled(x) for x in t2]
        )
    a, b, c = t1
    return _sat_intersect([lerp(a, c), lerp(b, c), scaled(c)], [scaled(x) for x in t2])


@pytest.mark.parametrize("grid, offset", [(3, 0.0), (4, 2.0**30)])
def test_pair_predicate_matches_brute_force_on_degenerate_configurations(grid, offset):
    """Triangles on a tiny integer grid: coplanar, collinear and touching cases galore."""
    from fast_stitch._check_kernels import faces_intersect, triangles_intersect_exact

    rng = np.random.default_rng(grid)
    expected_true = 0
    for t in range(1500):
        n_shared = t % 3
        while True:
            pts = [tuple(int(x) for x in rng.integers(0, grid, 3)) for _ in range(6)]
            pts[3:3 + n_shared] = pts[:n_shared]  # fmt: skip
            ok = len(set(pts)) == 6 - n_shared
            for tri in (pts[:3], pts[3:]):
                e1 = np.subtract(tri[1], tri[0])
                e2 = np.subtract(tri[2], tri[0])
                ok = ok and bool(np.cross(e1, e2).any())
            if ok:
                break
        uniq = list(dict.fromkeys(pts))
        idx = [uniq.index(p) for p in pts]
        f1, f2 = idx[:3], idx[3:]
        r1, r2 = int(rng.integers(3)), int(rng.integers(3))
        f1 = (f1[r1:] + f1[:r1])[:: int(rng.choice([-1, 1]))]
        f2 = (f2[r2:] + f2[:r2])[:: int(rng.choice([-1, 1]))]
        v = np.array(uniq, dtype=np.float64) + offset
        f = np.array([f1, f2], dtype=np.int64)
        expected = _reference_pair(pts[:3], pts[3:], n_shared)
        expected_true += expected
        tol = 1e-12 * max(1.0, offset)
        assert faces_intersect(v, f, 0, 1, tol) == expected, (pts, n_shared)
        assert faces_intersect(v, f, 1, 0, tol) == expected, (pts, n_shared)
        if n_shared == 0:  # the exact Guigue-Devillers test alone, without shortcuts
            assert triangles_intersect_exact(v, *f1, *f2) == expected, pts
    assert 200 < expected_true < 1300


def test_orientation_predicates_are_exact():
    """Nearly coplanar / collinear points, also far from the origin, against fractions."""
    from fractions import Fraction

    from fast_stitch._check_kernels import orient2d_sign, orient3d_sign

    def sign(x) -> int:
        return (x > 0) - (x < 0)

    rng = np.random.default_rng(1)
    zeros = 0
    for t in range(1500):
        p = rng.normal(size=(4, 3)) * 10.0 ** rng.integers(-4, 7)
        u, w = rng.random(2)
        p[3] = p[0] + u * (p[1] - p[0]) + w * (p[2] - p[0])  # on the plane, up to rounding
        if t % 3 == 1:
            p += 1e6
        if t % 3 == 2:  # exactly coplanar points on a coarse grid
            p = rng.integers(-3, 3, size=(4, 3)) * 0.125
            p[:, 2] = 0.5
            p[:, :2] += 2.0**20
        q = [[Fraction(float(x)) for x in row] for row in p]
        a, b, c = ([q[i][k] - q[3][k] for k in range(3)] for i in range(3))
        det = (
            a[0] * (b[1] * c[2] - b[2] * c[1])
            + a[1] * (b[2] * c[0] - b[0] * c[2])
            + a[2] * (b[0] * c[1] - b[1] * c[0])
        )
        zeros += det == 0
        assert orient3d_sign(np.ascontiguousarray(p), 0, 1, 2, 3) == sign(det)
        # 2D: c on the line ab, up to rounding
        p2 = p[:3].copy()
        p2[2] = p2[0] + rng.random() * (p2[1] - p2[0])
        r = [[Fraction(float(x)) for x in row] for row in p2]
        det2 = (r[0][0] - r[2][0]) * (r[1][1] - r[2][1]) - (r[0][1] - r[2][1]) * (r[1][0] - r[2][0])
        assert orient2d_sign(np.ascontiguousarray(p2), 0, 1, 2, 0, 1) == sign(det2)
    assert zeros >= 500


def test_bow_tie_vertex_is_nonmanifold():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]])
    rep = check((v, np.array([[0, 1, 2], [0, 3, 4]])))
    assert rep.nonmanifold_vertices.tolist() == [0]
    assert rep.n_boundary_edges == 6 and rep.n_self_intersections == 0
    fan = check((v, np.array([[0, 1, 2], [0, 2, 3]])))
    assert fan.n_nonmanifold_vertices == 0
