"""Polygon faces of mesh files split as polygons (regression, s26's parts made outside
shared/data: a Blender-style OBJ of a T-slot extrusion whose end caps are concave 20-gons).

trimesh fans every face of more than three vertices from its first vertex; the fan of a
concave polygon leaves it, so the loaded surface crossed itself in 139 triangle pairs, a
bcc fill stood 2 mm out of the part after its trim and the skin was refused.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from conformal import load_part
from lattice_cad.core.errors import LatticeWarning
from lattice_cad.io.exchange import read_mesh
from lattice_cad.io.polygons import triangulate

#: a T-slot profile (mm): concave, 20 vertices, counter-clockwise seen from +z
T_SLOT = np.array(
    [
        (-15, -15), (-4, -15), (-4, -12), (-9, -12), (-9, -9), (9, -9), (9, -12), (4, -12),
        (4, -15), (15, -15), (15, 15), (4, 15), (4, 12), (9, 12), (9, 9), (-9, 9), (-9, 12),
        (-4, 12), (-4, 15), (-15, 15),
    ],
    dtype=np.float64,
)  # fmt: skip


def _area(q: np.ndarray) -> float:
    return 0.5 * float((q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]).sum())


def _prism(profile: np.ndarray, height: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """Vertices and polygon faces (two n-gon caps, n quads) of an extruded profile."""
    n = len(profile)
    v = np.vstack([np.c_[profile, np.zeros(n)], np.c_[profile, np.full(n, height)]])
    bottom = np.arange(n)[::-1]  # facing -z
    top = n + np.arange(n)
    sides = [np.array([k, (k + 1) % n, n + (k + 1) % n, n + k]) for k in range(n)]
    return v, [bottom, top, *sides]


def _write_obj(path, v, faces) -> None:
    lines = ["# Blender-style", "o TSlot"] + [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    lines += ["vn 0 0 1", "usemtl None", "s 0"]
    lines += ["f " + " ".join(f"{i + 1}//1" for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n")


def _write_off(path, v, faces) -> None:
    lines = ["OFF", f"{len(v)} {len(faces)} 0"] + [f"{x} {y} {z}" for x, y, z in v]
    lines += [f"{len(face)} " + " ".join(map(str, face)) for face in faces]
    path.write_text("\n".join(lines) + "\n")


def _write_ply(path, v, faces) -> None:
    head = [
        "ply", "format ascii 1.0", f"element vertex {len(v)}", "property float x",
        "property float y", "property float z", f"element face {len(faces)}",
        "property list uchar int vertex_indices", "end_header",
    ]  # fmt: skip
    body = [f"{x} {y} {z}" for x, y, z in v] + [
        f"{len(face)} " + " ".join(map(str, face)) for face in faces
    ]
    path.write_text("\n".join(head + body) + "\n")


def test_a_concave_polygon_is_split_inside_itself():
    v = np.c_[T_SLOT, np.zeros(len(T_SLOT))]
    f, crossing = triangulate(v, [np.arange(len(T_SLOT))])
    assert crossing == 0 and len(f) == len(T_SLOT) - 2
    q = T_SLOT[f]  # (t, 3, 2)
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    signed = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert (signed > 0).all()  # every triangle turned as the polygon is
    assert signed.sum() == pytest.approx(_area(T_SLOT), rel=1e-12)  # no overlap, no gap


def test_random_concave_polygons_in_any_plane(seed_count: int = 60):
    rng = np.random.default_rng(7)
    for _ in range(seed_count):
        k = int(rng.integers(4, 30))
        angle = 2 * np.pi * (np.arange(k) + rng.uniform(0, 1, k)) / k  # gaps below pi
        radius = rng.uniform(0.2, 1.0, k)  # star-shaped about the origin: simple, concave
        q = np.c_[radius * np.cos(angle), radius * np.sin(angle)]
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        v = np.c_[q, np.zeros(k)] @ rot.T + rng.normal(size=3) * 100
        normal = np.cross(rot[:, 0], rot[:, 1])  # (rot may be a reflection)
        f, crossing = triangulate(v, [np.arange(k)])
        assert crossing == 0 and len(f) == k - 2
        t = v[f]
        n = 0.5 * np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        along = n @ normal
        assert (along > -1e-12).all()
        assert along.sum() == pytest.approx(_area(q), rel=1e-9)


def test_a_fan_is_kept_for_convex_polygons_and_triangles_keep_their_order():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 2, 2]], dtype=np.float64)
    f, _ = triangulate(v, [np.array([0, 1, 4]), np.array([0, 1, 2, 3]), np.array([1, 2, 4])])
    assert f.tolist() == [[0, 1, 4], [0, 1, 2], [0, 2, 3], [1, 2, 4]]


@pytest.mark.parametrize("suffix", ["obj", "off", "ply"])
def test_a_part_with_concave_ngon_caps_loads_as_the_solid(tmp_path, suffix):
    import trimesh

    v, faces = _prism(T_SLOT, 100.0)
    path = tmp_path / f"tslot.{suffix}"
    {"obj": _write_obj, "off": _write_off, "ply": _write_ply}[suffix](path, v, faces)
    with warnings.catch_warnings():
        warnings.simplefilter("error", LatticeWarning)  # no "surface crosses itself"
        part = load_part(path)
    assert part.self_crossings[0] == 0
    assert part.volume == pytest.approx(_area(T_SLOT) * 100.0, rel=1e-9)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    vr, fr = read_mesh(path)
    assert len(fr) == 2 * (len(T_SLOT) - 2) + 2 * len(T_SLOT)


def test_a_bcc_fill_of_the_concave_part_is_cut_to_it(tmp_path):
    """The fill was trimmed to 2 mm out of the part (its fanned surface crossed itself)."""
    from lattice_cad import Lattice
    from tests.conftest import assert_valid

    v, faces = _prism(T_SLOT, 100.0)
    path = tmp_path / "tslot.obj"
    _write_obj(path, v, faces)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(path, cell="bcc", cell_size=6.667, radius=0.5556)
        mesh = lat.mesh()
    assert lat.trim_report is not None and lat.trim_report.failed in (None, "")
    assert lat.trim_report.protrusion_after <= 0.01 * 0.5556
    assert_valid(mesh)


def test_a_face_naming_a_missing_vertex_is_named(tmp_path):
    from lattice_cad.core.errors import InputFileError

    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 9\n")
    with pytest.raises(InputFileError, match=r"face 0 \(0, 1, 2, 8\) names a vertex"):
        read_mesh(path)


def _tetra_obj(header: str, refs: str, offset: tuple[float, float, float]) -> str:
    x, y, z = offset
    corners = [(x, y, z), (x + 1, y, z), (x, y + 1, z), (x, y, z + 1)]
    lines = [header] + [f"v {a:g} {b:g} {c:g}" for a, b, c in corners]
    for tri in ((1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)):
        lines.append("f " + " ".join(refs.format(i - 5) for i in tri))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("header", ["o", "g"])
@pytest.mark.parametrize("refs", ["{}", "{0}/{0}/{0}", "{0}//{0}"])
def test_relative_indices_count_back_from_the_file_not_the_object(tmp_path, header, refs):
    # regression (s32, an OBJ of 6 groups with relative indices made outside shared/data):
    # trimesh counted "f -4 -2 -3" back from the vertices of the face's object, so every
    # object after the first was read onto the first one's vertices (91 open edges)
    import trimesh

    path = tmp_path / "two.obj"
    path.write_text(
        "# relative indices\n"
        + _tetra_obj(f"{header} first", refs, (0, 0, 0))
        + _tetra_obj(f"{header} second", refs, (5, 0, 0))
    )
    v, f = read_mesh(path)
    assert len(v) == 8 and f.max() == 7 and set(f[4:].ravel()) == {4, 5, 6, 7}
    tm = trimesh.Trimesh(v, f, process=False)
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume == pytest.approx(2.0 / 6.0)
    assert len(tm.split()) == 2
