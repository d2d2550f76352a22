"""Sharded 3MF (lattice_cad.io.sharded_3mf): one object per shard in its own model part
(3MF Production extension), with or without beams; read back with lib3mf, the union of
the shard objects merged by coordinates is one closed solid (trimesh, manifold3d) with the
triangles of the single-process mesh."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from tests.conftest import DATA

distributed = pytest.importorskip("distributed")

import conformal  # noqa: E402
import fast_stitch  # noqa: E402
from lattice_cad.core.mesh import Mesh  # noqa: E402
from lattice_cad.distributed import fill_sharded, stitch_sharded, write_graph_shards  # noqa: E402
from lattice_cad.io import read_mesh, save_mesh  # noqa: E402
from lattice_cad.io.sharded_3mf import read_parts  # noqa: E402
from tests.test_distributed import canonical, tapered_graph, two_worker_client  # noqa: E402

PART = DATA / "meshes" / "bunny_closed_odedstein.obj"


@pytest.fixture(scope="module")
def client():
    with two_worker_client(sys.modules[__name__]) as c:
        yield c


def merged(meshes):
    """Weld the objects' triangles by exact coordinates: (corners (F, 9) float32, v, f)."""
    corners = np.concatenate([v[f].reshape(-1, 9) for v, f in meshes]).astype(np.float32)
    v, inv = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    return corners, v, inv.reshape(-1, 3)


def assert_one_closed_solid(v, f):
    import manifold3d
    import trimesh

    tm = trimesh.Trimesh(vertices=v.astype(np.float64), faces=f, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    assert len(tm.split(only_watertight=False)) == 1
    man = manifold3d.Manifold(
        manifold3d.Mesh(vert_properties=v.astype(np.float32), tri_verts=f.astype(np.uint32))
    )
    assert man.status() == manifold3d.Error.NoError
    assert man.num_tri() == len(f)


def reference(tmp_path, mesh):
    """The single-process mesh through the same 3MF writer (3MF stores decimal text)."""
    one = tmp_path / "one.3mf"
    save_mesh(Mesh(vertices=mesh.vertices.astype(np.float32).astype(np.float64),
                   faces=mesh.faces), one)  # fmt: skip
    v1, f1 = read_mesh(one)
    return canonical(v1[f1].reshape(-1, 9).astype(np.float32))


def _cell() -> float:
    part = conformal.load_part(PART)
    return float((part.bounds[1] - part.bounds[0]).max()) / 12


@pytest.mark.slow  # two sharded runs on the bunny (~30 s under load)
def test_fill_3mf_one_object_per_shard_and_beams(client, tmp_path):
    h = _cell()
    part = conformal.load_part(PART)
    graph = conformal.voxel_lattice(part, "bcc", h, 0.08 * h, fill="inside")
    ref = reference(tmp_path, fast_stitch.stitch(graph, 6))

    out = tmp_path / "shards.3mf"
    res = fill_sharded(PART, out, "bcc", h, 0.08 * h, shards=4, scheduler=client,
                       threemf="shards")  # fmt: skip
    got = read_parts(out)
    n = len(res.shards)
    assert n >= 3 and got["build_items"] == 1 and got["components"] == n
    assert len(got["meshes"]) == n and got["beams"] == 0
    build, stitch = res.build_peak_rss_per_worker, res.peak_rss_per_worker
    assert set(build) & set(stitch) and min(build.values()) > 0 and min(stitch.values()) > 0
    assert sum(len(f) for _, f in got["meshes"]) == res.triangles == len(ref)
    corners, v, f = merged(got["meshes"])
    np.testing.assert_array_equal(canonical(corners), ref)
    assert_one_closed_solid(v, f)
    # every shard object is open at its seams: the shards really split the lattice
    import trimesh

    assert not any(trimesh.Trimesh(a, b, process=False).is_watertight for a, b in got["meshes"])

    beams = tmp_path / "beams.3mf"
    res_b = fill_sharded(PART, beams, "bcc", h, 0.08 * h, shards=4, scheduler=client,
                         beam_lattice=True)  # fmt: skip
    got_b = read_parts(beams)
    assert got_b["components"] == len(res_b.shards) == n
    assert got_b["beams"] == graph.num_edges == res_b.struts  # each strut once
    corners_b, _, _ = merged(got_b["meshes"])
    np.testing.assert_array_equal(canonical(corners_b), ref)
    from lattice_cad.io.exchange import read_beam_lattice

    info = read_beam_lattice(beams)
    assert info["beams"] == graph.num_edges and info["balls"] >= graph.num_nodes // 2


def test_stitch_sharded_3mf_parts_deterministic(client, tmp_path):
    graph = tapered_graph()
    ref = reference(tmp_path, fast_stitch.stitch(graph, 7, seed=5))
    shards = write_graph_shards(graph, tmp_path / "g", chunks=3)
    a, b = tmp_path / "a.3mf", tmp_path / "b.3mf"
    res = stitch_sharded(shards, a, 7, seed=5, blocks=4, scheduler=client, threemf="shards")
    stitch_sharded(shards, b, 7, seed=5, blocks=4, scheduler=client, threemf="shards")
    assert a.read_bytes() == b.read_bytes()  # content-derived UUIDs, fixed zip times
    got = read_parts(a)
    assert got["components"] == len(res.shards) == 4 == len(got["meshes"])
    corners, v, f = merged(got["meshes"])
    np.testing.assert_array_equal(canonical(corners), ref)
    assert_one_closed_solid(v, f)
    # small and "auto": one merged mesh object, no components
    c = tmp_path / "c.3mf"
    stitch_sharded(shards, c, 7, seed=5, blocks=4, scheduler=client)
    got_c = read_parts(c)
    assert len(got_c["meshes"]) == 1 and got_c["components"] == 0
    np.testing.assert_array_equal(canonical(merged(got_c["meshes"])[0]), ref)


def test_threemf_option_checked(tmp_path):
    with pytest.raises(ValueError, match="threemf"):
        fill_sharded(PART, tmp_path / "x.3mf", threemf="many")  # type: ignore[arg-type]
    from lattice_cad.core.errors import ShardingError

    with pytest.raises(ShardingError, match="beam lattice"):
        fill_sharded(PART, tmp_path / "x.stl", beam_lattice=True)


_PEAK_PROBE = """
import numpy as np
from lattice_cad.distributed import _peak_rss, _reset_peak
big = np.ones(300 * 2**20 // 8)
before = _peak_rss()
del big
if not _reset_peak():
    print("noreset")
    raise SystemExit(0)
after = _peak_rss()
small = np.ones(50 * 2**20 // 8)
print(before, after, _peak_rss())
"""


def test_peak_rss_reset_measures_one_phase():
    """The per-task peak (build and stitch phases are printed apart): after a reset the
    peak no longer holds an earlier 300 MB allocation, and a later 50 MB allocation shows.

    Run in a fresh interpreter (as a Dask worker runs one task at a time): in the test
    process, other threads may free memory after the reset, so that the resident size
    drops below the reset high-water mark and a new allocation does not raise it."""
    import subprocess

    out = subprocess.run(
        [sys.executable, "-c", _PEAK_PROBE], capture_output=True, text=True, check=True
    ).stdout.split()
    if out == ["noreset"]:
        pytest.skip("this kernel cannot reset the peak RSS (/proc/self/clear_refs)")
    before, after, later = map(int, out)
    assert before - after > 200 * 2**20
    assert later >= after + 40 * 2**20


def test_cli_shards_beam_lattice(client, tmp_path, capsys):
    from lattice_cad.cli import main

    h = 2 * _cell()
    out = tmp_path / "cli.3mf"
    code = main(["-q", "fill", str(PART), "-o", str(out), "--cell-size", str(h),
                 "--radius", str(0.05 * h), "--shards", "2", "--beam-lattice",
                 "--scheduler", client.scheduler.address])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    got = read_parts(out)
    assert got["build_items"] == 1 and got["components"] == len(got["meshes"]) >= 1
    part = conformal.load_part(PART)
    graph = conformal.voxel_lattice(part, "bcc", h, 0.05 * h, fill="inside")
    assert got["beams"] == graph.num_edges
    code = main(["fill", str(PART), "-o", str(tmp_path / "x.3mf"), "--cell-size", str(h),
                 "--shards", "2", "--beam-lattice=only"])  # fmt: skip
    assert code == 1 and "--beam-lattice=only" in capsys.readouterr().err
