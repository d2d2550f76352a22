"""Sharded beam lattices (3MF Beam Lattice extension): every strut as one beam and every
ball once (seam nodes too), for fill_sharded and for stitch_sharded of a user graph;
compared ball by ball (position, radius) with the single-process beam lattice; and the
hub scales that a shard computes from part of the lattice are the whole lattice's."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from tests.conftest import DATA

distributed = pytest.importorskip("distributed")

import conformal  # noqa: E402
import fast_stitch  # noqa: E402
from lattice_cad.distributed import fill_sharded, stitch_sharded, write_graph_shards  # noqa: E402
from lattice_cad.io.exchange import read_beam_lattice, save_beam_lattice  # noqa: E402
from lattice_cad.io.sharded_3mf import read_parts  # noqa: E402
from tests.test_distributed import canonical, tapered_graph, two_worker_client  # noqa: E402
from tests.test_distributed_3mf import assert_one_closed_solid, merged, reference  # noqa: E402

PART = DATA / "meshes" / "bunny_closed_odedstein.obj"


@pytest.fixture(scope="module")
def client():
    with two_worker_client(sys.modules[__name__]) as c:
        yield c


def balls_and_beams(path):
    """(B, 4) float64 balls (x, y, z, radius) and (M, 8) beams (both ends' x, y, z sorted
    by end, then the two radii), each sorted, over all mesh objects of a 3MF (lib3mf)."""
    from lattice_cad.io.exchange import _mesh_objects, _read_3mf_model

    _, model = _read_3mf_model(path)
    balls, beams = [], []
    for obj in _mesh_objects(model):
        bl = obj.BeamLattice()
        if not bl.GetBeamCount():
            continue
        v = np.array([list(p.Coordinates) for p in obj.GetVertices()])
        for b in bl.GetBalls():
            balls.append([*v[b.Index], b.Radius])
        for b in bl.GetBeams():
            (i, j), (ri, rj) = list(b.Indices), list(b.Radii)
            ends = sorted([(*v[i], ri), (*v[j], rj)])
            beams.append([*ends[0][:3], *ends[1][:3], ends[0][3], ends[1][3]])
    balls_a, beams_a = np.array(balls), np.array(beams)
    return balls_a[np.lexsort(balls_a.T[::-1])], beams_a[np.lexsort(beams_a.T[::-1])]


def test_fill_beam_lattice_each_ball_once(client, tmp_path):
    part = conformal.load_part(PART)
    h = float((part.bounds[1] - part.bounds[0]).max()) / 12
    graph = conformal.voxel_lattice(part, "bcc", h, 0.08 * h, fill="inside")
    one = tmp_path / "one.3mf"
    save_beam_lattice(graph, one, mesh=fast_stitch.stitch(graph, 6))
    out = tmp_path / "sharded.3mf"
    res = fill_sharded(PART, out, "bcc", h, 0.08 * h, shards=4, scheduler=client,
                       beam_lattice=True)  # fmt: skip
    assert len(res.shards) >= 3
    info, info1 = read_beam_lattice(out), read_beam_lattice(one)
    n_balls = int((graph.degree >= 2).sum())
    assert info1["balls"] == n_balls
    assert info["balls"] == n_balls and info["beams"] == graph.num_edges
    (b, e), (b1, e1) = balls_and_beams(out), balls_and_beams(one)
    np.testing.assert_array_equal(b, b1)  # same places and radii, seam balls once
    np.testing.assert_array_equal(e, e1)


def test_stitch_sharded_beam_lattice(client, tmp_path):
    graph = tapered_graph()
    shards = write_graph_shards(graph, tmp_path / "g", chunks=3)
    out = tmp_path / "g.3mf"
    res = stitch_sharded(shards, out, 7, seed=5, blocks=4, scheduler=client, beam_lattice=True)
    assert len(res.shards) == 4
    got = read_parts(out)
    assert got["components"] == 4 == len(got["meshes"]) and got["build_items"] == 1
    # the triangles: those of the single-process mesh, one closed solid across the seams
    corners, v, f = merged(got["meshes"])
    np.testing.assert_array_equal(canonical(corners), reference(tmp_path,
                                  fast_stitch.stitch(graph, 7, seed=5)))  # fmt: skip
    assert_one_closed_solid(v, f)
    # the beams and balls: those of the single-process beam lattice, each once
    one = tmp_path / "one.3mf"
    save_beam_lattice(graph, one, mesh=fast_stitch.stitch(graph, 7, seed=5))
    info = read_beam_lattice(out)
    assert info["beams"] == graph.num_edges
    assert info["balls"] == int((graph.degree >= 2).sum()) == read_beam_lattice(one)["balls"]
    (b, e), (b1, e1) = balls_and_beams(out), balls_and_beams(one)
    # a ball whose radius is the object's default ball radius is stored without one, read
    # back as that default in single precision: radii agree to float32
    np.testing.assert_array_equal(b[:, :3], b1[:, :3])
    np.testing.assert_allclose(b[:, 3], b1[:, 3], rtol=1e-7, atol=0)
    np.testing.assert_array_equal(e, e1)
    with pytest.raises(Exception, match="beam lattice is written as .3mf"):
        stitch_sharded(shards, tmp_path / "g.stl", 7, scheduler=client, beam_lattice=True)


def test_hub_scales_do_not_depend_on_the_representative():
    """Translated hubs share one representative, whose volumes give the hub scale of all
    of them; a shard holds only part of the lattice and picks other representatives. The
    volumes come from the stitch's canonical frames, so the scales are bit-identical
    (they differed in the last bits when taken from absolute positions: one vertex of the
    GE bracket's conform fill at r = 0.08 cell differed sharded)."""
    from lattice_cad import LatticeGraph

    ijk = np.argwhere(np.ones((6, 5, 4), dtype=bool))
    nodes, edges, _ = conformal.tile_arrays("bcc", ijk, cell_size=1.37, origin=(-31.3, 7.9, 2.1))
    full = LatticeGraph(nodes, edges, np.full((len(edges), 2), 0.11))
    rep_full: dict = {}
    fast_stitch.stitch(full, 6, _report=rep_full)
    # drop the cells' struts near the low corner: every hub class gets another first member
    keep = (nodes[edges].min(axis=1) > nodes.min(axis=0) + 1.5).any(axis=1)
    used = np.zeros(len(nodes), dtype=bool)
    used[edges[keep].ravel()] = True
    sub = LatticeGraph(nodes[used], (np.cumsum(used) - 1)[edges[keep]],
                       np.full((int(keep.sum()), 2), 0.11))  # fmt: skip
    rep_sub: dict = {}
    fast_stitch.stitch(sub, 6, _report=rep_sub)
    # nodes whose stars two struts out are whole in the sub-lattice
    whole = np.zeros(len(nodes), dtype=bool)
    whole[used] = np.bincount(sub.edges.ravel(), minlength=sub.num_nodes) == full.degree[used]
    for _ in range(2):
        whole &= ~np.bincount(edges[~whole[edges].all(axis=1)].ravel(),
                              minlength=len(nodes)).astype(bool)  # fmt: skip
    assert whole.sum() > 20
    got = rep_sub["scale0"][(np.cumsum(used) - 1)[whole]]
    want = rep_full["scale0"][whole]
    assert np.ptp(want) > 0  # boundary and inner hubs: several classes
    np.testing.assert_array_equal(got, want)
