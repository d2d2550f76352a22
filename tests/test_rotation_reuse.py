"""Hubs equal up to a rotation or reflection are built once (issue 14, item 2)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conformal.cells import block
from reference_boolean import build_reference
from reference_boolean.rotations import RotationCache, invariant_key, match
from tests.conftest import DATA
from tests.test_reference import check_watertight


def _hub(rng: np.random.Generator, d: int = 7) -> tuple[np.ndarray, np.ndarray]:
    v = rng.normal(size=(d, 3))
    v *= rng.uniform(1.0, 2.0, size=(d, 1)) / np.linalg.norm(v, axis=1)[:, None]
    radii = np.column_stack([rng.uniform(0.1, 0.2, d), rng.uniform(0.1, 0.2, d)])
    return v, radii


@pytest.mark.parametrize("reflect", [False, True])
def test_match_finds_the_rotation_and_the_order(rng, reflect):
    v, radii = _hub(rng)
    q = Rotation.random(random_state=1).as_matrix()
    if reflect:
        q = q @ np.diag([1.0, 1.0, -1.0])
    perm = rng.permutation(len(v))
    b = np.empty_like(v)
    b[perm] = v @ q.T
    br = np.empty_like(radii)
    br[perm] = radii
    m = match(v, radii, b, br, 1e-9)
    assert m is not None
    np.testing.assert_array_equal(m.perm, perm)
    np.testing.assert_allclose(m.rotation, q, atol=1e-12)
    assert m.proper is not reflect
    assert invariant_key(0.3, v, radii, 1e-6) == invariant_key(0.3, b, br, 1e-6)


def test_match_refuses_what_is_not_congruent(rng):
    v, radii = _hub(rng)
    q = Rotation.random(random_state=2).as_matrix()
    b = v @ q.T
    bent = b.copy()
    bent[3] += 1e-6  # one stump moved by more than the tolerance
    assert match(v, radii, bent, radii, 1e-8) is None
    thick = radii.copy()
    thick[2, 1] += 1e-6  # one radius differs
    assert match(v, radii, b, thick, 1e-8) is None
    assert match(v, radii, b[:-1], radii[:-1], 1e-8) is None  # another degree
    cache = RotationCache(1e-6, 1e-8)
    t, key = cache.find(0.3, v, radii)
    assert t is None
    cache.add(key, 0, v, radii)
    assert cache.find(0.3, b, radii)[0] == 0
    assert cache.find(0.3, bent, radii)[0] is None


def test_turned_copies_stack_watertight_with_the_same_volume():
    # an FCC block: its face and corner hubs are the same up to the cube's rotations
    g = block("fcc", (1, 2, 2), cell_size=2.0, radius=0.2)
    rot = build_reference(g, workers=0, keep_solids=False)
    tra = build_reference(g, workers=0, keep_solids=False, reuse="translation")
    assert rot.complete and tra.complete
    assert rot.units.turned().sum() > 0
    assert rot.unique_hubs < tra.unique_hubs
    assert rot.unique_hubs + rot.cache_hits == tra.unique_hubs + tra.cache_hits
    # GProp's volume of one hub turned in space varies by ~5e-7 (the translation-built
    # copies of one rotation class differ among themselves by as much)
    assert rot.volume == pytest.approx(tra.volume, rel=1e-6)
    np.testing.assert_allclose(rot.hub_volume, tra.hub_volume, rtol=1e-6)
    check_watertight(rot.mesh)
    # every node keeps its triangles; a turned copy has its template's plus the split ones
    per_rot = np.bincount(rot.face_node, minlength=g.num_nodes)
    per_tra = np.bincount(tra.face_node, minlength=g.num_nodes)
    assert np.all(per_rot[g.degree > 0] >= per_tra[g.degree > 0])
    assert np.all(per_rot[g.degree > 0] > 0)
    # the split boundary triangles only add points on the exact surface: the mesh volume
    # gets closer to the exact one, never farther
    import trimesh

    vt = trimesh.Trimesh(tra.mesh.vertices, tra.mesh.faces, process=False).volume
    vr = trimesh.Trimesh(rot.mesh.vertices, rot.mesh.faces, process=False).volume
    assert vt < vr < rot.volume


def test_step_of_turned_copies_is_one_valid_solid(tmp_path):
    from lattice_cad.occ_impl.step import read_step_solids

    g = block("fcc", (1, 1, 2), cell_size=2.0, radius=0.2)
    ref = build_reference(g, workers=0)
    assert ref.units.turned().any()
    solids = read_step_solids(str(ref.save(tmp_path / "fcc.step")))
    assert len(solids) == 1 and solids[0][0]
    assert solids[0][1] == pytest.approx(ref.volume, rel=1e-6)


@pytest.mark.slow
def test_real_part_box_bcc_rotation_reuse_matches_the_unreused_build():
    import conformal
    from lattice_cad import LatticeGraph

    part = conformal.load_part(DATA / "meshes" / "bunny_closed_odedstein.obj")
    h = float((part.bounds[1] - part.bounds[0]).max()) / 6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = conformal.voxel_lattice(part, "box-bcc", h, 0.06 * h, fill="inside")
    # the bunny file is 1.55 units across: read as mm, OCCT's absolute tolerances (1e-7 mm)
    # are 5e-6 of a 0.02 mm strut radius (one hub then fails, and GProp volumes of one hub in
    # different orientations spread by 1e-4); as a 155 mm print they agree to 1e-9
    g = LatticeGraph(g.nodes * 100.0, g.edges, g.radii * 100.0)
    rot = build_reference(g, keep_solids=False, workers=0)
    tra = build_reference(g, keep_solids=False, workers=0, reuse="translation")
    assert rot.complete and tra.complete, (rot.failed, tra.failed)
    assert rot.units.turned().sum() >= 10
    assert rot.unique_hubs < tra.unique_hubs
    assert rot.volume == pytest.approx(tra.volume, rel=1e-7)
    np.testing.assert_allclose(rot.hub_volume, tra.hub_volume, rtol=1e-7)
    check_watertight(rot.mesh)
    check_watertight(tra.mesh)


def test_bad_reuse_option():
    g = block("bcc", (1, 1, 1), cell_size=2.0, radius=0.2)
    with pytest.raises(ValueError, match="reuse must be"):
        build_reference(g, reuse="mirror")  # type: ignore[arg-type]
