"""Sharded fill and stitch on a Dask LocalCluster: the same triangles as one process,
watertight across seams (trimesh, manifold3d), faults retried, output complete or absent."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import DATA

distributed = pytest.importorskip("distributed")

import conformal  # noqa: E402
import fast_stitch  # noqa: E402
from lattice_cad import LatticeGraph  # noqa: E402
from lattice_cad.core.errors import (  # noqa: E402
    DistributedUnavailableError,
    ShardingError,
)
from lattice_cad.core.mesh import stl_records  # noqa: E402
from lattice_cad.distributed import (  # noqa: E402
    fill_sharded,
    stitch_sharded,
    write_graph_shards,
)

PART = DATA / "meshes" / "bunny_closed_odedstein.obj"
REC = np.dtype([("n", "<f4", 3), ("v", "<f4", 9), ("attr", "<u2")])


@contextlib.contextmanager
def two_worker_client(module):
    """A Dask client on a LocalCluster of two worker processes with one thread each, as in
    CI; the test ``module`` travels to the workers by value (tests is no package there)."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(module)
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,  # and the HTTP server on a free port: 8787 may be taken
        scheduler_kwargs={"dashboard_address": ":0"},
    )
    c = distributed.Client(cluster)
    try:
        yield c
    finally:
        c.close()
        cluster.close()
        cloudpickle.unregister_pickle_by_value(module)


@pytest.fixture(scope="module")
def client():
    with two_worker_client(sys.modules[__name__]) as c:
        yield c


def canonical(corners: np.ndarray) -> np.ndarray:
    """(F, 9) float32 triangles, each rotated to start at its smallest corner (orientation
    kept), rows sorted: equal arrays mean equal oriented triangle sets."""
    t = corners.reshape(-1, 3, 3)
    best = np.zeros(len(t), dtype=np.int64)
    rows = np.arange(len(t))
    for k in (1, 2):
        a, b = t[:, k], t[rows, best]
        tie_y = (a[:, 1] == b[:, 1]) & (a[:, 2] < b[:, 2])
        less = (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & ((a[:, 1] < b[:, 1]) | tie_y))
        best = np.where(less, k, best)
    out = np.stack([t[rows, (best + j) % 3] for j in range(3)], axis=1).reshape(-1, 9)
    return out[np.lexsort(out.T[::-1])]


def single_triangles(mesh) -> np.ndarray:
    out = np.empty((len(mesh.faces), 12), dtype=np.float32)
    assert stl_records(mesh.vertices, mesh.faces, out) == 0
    return canonical(out[:, 3:])


def read_stl(path: Path) -> np.ndarray:
    raw = path.read_bytes()
    count = int(np.frombuffer(raw[80:84], dtype="<u4")[0])
    rec = np.frombuffer(raw[84:], dtype=REC)
    assert count == len(rec)  # header count written last, matches the records
    return rec


def assert_closed(rec: np.ndarray) -> None:
    """Weld by exact float32 coordinates; trimesh and manifold3d must see one closed solid."""
    import manifold3d
    import trimesh

    corners = rec["v"].reshape(-1, 3)
    v, inv = np.unique(corners, axis=0, return_inverse=True)
    f = inv.reshape(-1, 3)
    tm = trimesh.Trimesh(vertices=v.astype(np.float64), faces=f, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    man = manifold3d.Manifold(
        manifold3d.Mesh(vert_properties=v.astype(np.float32), tri_verts=f.astype(np.uint32))
    )
    assert man.status() == manifold3d.Error.NoError


def _cell() -> float:
    part = conformal.load_part(PART)
    return float((part.bounds[1] - part.bounds[0]).max()) / 12


def test_fill_same_triangles_as_one_process(client, tmp_path):
    h = _cell()
    part = conformal.load_part(PART)
    graph = conformal.voxel_lattice(part, "bcc", h, 0.08 * h, fill="inside")
    # the default profile="volume" in both: hub scales reach two struts from a hub
    ref = single_triangles(fast_stitch.stitch(graph, 6))
    out = tmp_path / "bunny.stl"
    res = fill_sharded(PART, out, "bcc", h, 0.08 * h, shards=4, scheduler=client)
    assert len(res.shards) >= 3  # seams in every direction the grid was cut
    assert res.struts == graph.num_edges
    assert res.halo_overhead > 0
    rec = read_stl(out)
    assert len(rec) == res.triangles == len(ref)
    np.testing.assert_array_equal(canonical(rec["v"]), ref)
    assert_closed(rec)
    assert set(res.peak_rss_per_worker) and min(res.peak_rss_per_worker.values()) > 0


def test_fill_graded_radius_3mf(client, tmp_path):
    h = _cell()
    part = conformal.load_part(PART)

    def radius(mid):
        return h * (0.05 + 0.04 * (mid[:, 0] + 1.0) / 2.0)

    graph = conformal.voxel_lattice(part, "bcc", h, radius, fill="inside")
    assert np.ptp(graph.radii) > 0
    ref = fast_stitch.stitch(graph, 6)
    out = tmp_path / "bunny.3mf"
    res = fill_sharded(PART, out, "bcc", h, radius, shards=3, scheduler=client)
    assert res.triangles == len(ref.faces)
    from lattice_cad.core.mesh import Mesh
    from lattice_cad.io import read_mesh, save_mesh

    # 3MF stores decimal text: compare with the one-process mesh written the same way
    one = tmp_path / "one.3mf"
    save_mesh(Mesh(vertices=ref.vertices.astype(np.float32).astype(np.float64),
                   faces=ref.faces), one)  # fmt: skip
    (v, f), (v1, f1) = read_mesh(out), read_mesh(one)
    assert len(f) == len(f1) == len(ref.faces)
    np.testing.assert_array_equal(
        canonical(v[f].reshape(-1, 9).astype(np.float32)),
        canonical(v1[f1].reshape(-1, 9).astype(np.float32)),
    )


def tapered_graph() -> LatticeGraph:
    """A BCC block with radii graded along x and z and tapered (ends differ)."""
    ijk = np.argwhere(np.ones((5, 4, 3), dtype=bool))
    nodes, edges, _ = conformal.tile_arrays("bcc", ijk, cell_size=1.0, origin=(0.3, -1.1, 2.0))
    node_r = 0.05 + 0.01 * (nodes[:, 0] - 0.3) + 0.008 * (nodes[:, 2] - 2.0)
    radii = node_r[edges]
    # some struts reversed: the orientation of the given edges must be kept
    flip = np.arange(len(edges)) % 3 == 0
    edges[flip] = edges[flip][:, ::-1]
    radii[flip] = radii[flip][:, ::-1]
    return LatticeGraph(nodes, edges, radii)


@pytest.mark.parametrize("profile", ["volume", "area"])
def test_stitch_sharded_tapered_graded(client, tmp_path, profile):
    graph = tapered_graph()
    assert graph.is_tapered
    ref = fast_stitch.stitch(graph, 7, seed=5, profile=profile)
    shards = write_graph_shards(graph, tmp_path / "g", chunks=3)
    out = tmp_path / "g.stl"
    kw = {} if profile == "volume" else {"profile": profile}  # volume: the default
    res = stitch_sharded(shards, out, 7, seed=5, blocks=4, scheduler=client, **kw)
    assert len(res.shards) == 4
    assert res.struts == graph.num_edges
    rec = read_stl(out)
    np.testing.assert_array_equal(canonical(rec["v"]), single_triangles(ref))
    assert_closed(rec)


class DieOnce:
    """A radius that kills its worker process the first time it is evaluated."""

    def __init__(self, marker: str, r: float) -> None:
        self.marker, self.r = marker, r

    def __call__(self, mid: np.ndarray) -> np.ndarray:
        if not os.path.exists(self.marker):
            Path(self.marker).touch()
            os._exit(1)  # the worker dies mid-task
        return np.full(len(mid), self.r)


class AlwaysFails:
    def __call__(self, mid: np.ndarray) -> np.ndarray:
        raise ValueError("radius callable failed on purpose")


@pytest.mark.slow  # a worker process is killed and restarted (~10 s)
def test_worker_death_retried_same_bytes(client, tmp_path):
    h = _cell()
    good = tmp_path / "good.stl"
    fill_sharded(PART, good, "bcc", h, 0.08 * h, shards=2, scheduler=client)
    marker = tmp_path / "died"
    crashed = tmp_path / "crashed.stl"
    fill_sharded(PART, crashed, "bcc", h, DieOnce(str(marker), 0.08 * h), shards=2,
                 scheduler=client)  # fmt: skip
    assert marker.exists()  # a worker really died
    assert crashed.read_bytes() == good.read_bytes()  # a rerun (after a crash) gives the same bytes
    client.wait_for_workers(2, timeout=60)


@pytest.mark.slow  # both phases run before the failing radius (~10 s under load)
def test_failure_leaves_no_file(client, tmp_path):
    out = tmp_path / "never.stl"
    with pytest.raises(ValueError, match="on purpose"):
        fill_sharded(PART, out, "bcc", _cell(), AlwaysFails(), shards=2, scheduler=client,
                     retries=0, tmpdir=tmp_path)  # fmt: skip
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_cli_shards(client, tmp_path, capsys):
    from lattice_cad.cli import main

    out = tmp_path / "cli.stl"
    code = main(["-q", "fill", str(PART), "-o", str(out), "--cell-size", str(_cell()),
                 "--radius", str(0.08 * _cell()), "--shards", "2",
                 "--scheduler", client.scheduler.address])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert_closed(read_stl(out))


def test_refusals(tmp_path, monkeypatch, capsys):
    from lattice_cad.cli import main

    with pytest.raises(ShardingError, match="'tet'.*not supported sharded"):
        fill_sharded(PART, tmp_path / "a.stl", fill="tet")  # type: ignore[arg-type]
    with pytest.raises(ShardingError, match=r"\.stl or \.3mf"):
        fill_sharded(PART, tmp_path / "a.ply")
    code = main(["fill", str(PART), "-o", str(tmp_path / "b.stl"), "--shards", "2",
                 "--skin", "1"])  # fmt: skip
    assert code == 1 and "--skin" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(DistributedUnavailableError, match=r"lattice-cad\[distributed\]"):
        fill_sharded(PART, tmp_path / "c.stl")
    assert not any(tmp_path.iterdir())


def test_ctrl_c_cancels_cluster_work(client, monkeypatch):
    """Ctrl-C while waiting: every future of the run is cancelled, and the error propagates."""
    import time

    import lattice_cad.distributed as dist

    seen = []

    def interrupted(futures):
        seen.extend(futures)
        raise KeyboardInterrupt

    monkeypatch.setattr(distributed, "as_completed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        dist._run(client, time.sleep, [(30,), (30,)], retries=0, progress=False, desc="sleep")
    assert len(seen) == 2
    deadline = time.monotonic() + 10
    while any(f.status != "cancelled" for f in seen) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [f.status for f in seen] == ["cancelled", "cancelled"]


def test_volume_hub_scales_need_two_struts_of_halo():
    """A hub scale depends on the offsets at the far ends of the node's struts (the
    frustum lengths), i.e. on its neighbours' struts: the node's own struts alone give
    another scale, those and its neighbours' the same bits. An owned strut's far end is
    such a neighbour, hence two struts of complete stars beyond the owned nodes (_hops)."""
    import importlib

    from lattice_cad.distributed import _hops, _within

    st = importlib.import_module("fast_stitch.stitch")
    from fast_stitch.hubvolume import area_factor
    from lattice_cad.core.checks import Progress

    graph = tapered_graph()
    assert _hops("volume") == 2 and _hops("area") == 1

    def scales(g):
        r = g.radii * area_factor(6)
        _, _, _, rr = st._stitch(g, r, 6, True, 0, Progress(None, 1), correct_hubs=True)
        return rr / r  # (M, 2): the scale of each strut end's node

    full = scales(graph)
    n0 = int(np.argmax(graph.degree))  # an inner node
    seed = np.zeros(graph.num_nodes, dtype=bool)
    seed[n0] = True
    for hops, same in ((0, False), (1, True)):
        keep = _within(seed, graph.edges, hops)
        sub = np.flatnonzero(keep[graph.edges].any(axis=1))
        used = np.zeros(graph.num_nodes, dtype=bool)
        used[graph.edges[sub].ravel()] = True
        new_id = np.cumsum(used) - 1
        g = LatticeGraph(graph.nodes[used], new_id[graph.edges[sub]], graph.radii[sub])
        at_n0 = graph.edges[sub] == n0
        assert at_n0.any()
        got, want = scales(g)[at_n0], full[sub][at_n0]
        assert np.array_equal(got, want) == same, (hops, np.abs(got - want).max())


def test_capped_hub_growth_is_refused_sharded(client, tmp_path):
    """A hub whose growth the clearance caps (issue 11) depends on struts that need not be
    in the shard: refused by name, no output; the same graph sharded with "area" works."""
    from tests.test_stitch import _grown_v_and_a_strut_above

    graph, P = _grown_v_and_a_strut_above()
    shards = write_graph_shards(graph, tmp_path / "g", chunks=2)
    out = tmp_path / "v.stl"
    with pytest.raises(ShardingError, match="may not grow"):
        stitch_sharded(shards, out, P, blocks=2, scheduler=client)
    assert not out.exists()
    stitch_sharded(shards, out, P, blocks=2, scheduler=client, profile="area")
    rec = read_stl(out)
    ref = fast_stitch.stitch(graph, P, profile="area")
    np.testing.assert_array_equal(canonical(rec["v"]), single_triangles(ref))
