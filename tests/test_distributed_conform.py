"""Sharded ``fill="conform"`` on a LocalCluster: the same oriented triangles as
``conformal.voxel_lattice(fill="conform")`` + ``fast_stitch.stitch`` in one process, on real
parts, and one closed solid across the seams (trimesh, manifold3d)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tests.conftest import DATA

distributed = pytest.importorskip("distributed")

import conformal  # noqa: E402
import fast_stitch  # noqa: E402
from lattice_cad.core.errors import ShardingError  # noqa: E402
from lattice_cad.distributed import fill_sharded  # noqa: E402
from tests.test_distributed import assert_closed, canonical, read_stl, single_triangles  # noqa: E402
from tests.test_distributed_3mf import client  # noqa: E402, F401  (the module's cluster)

MESHES = DATA / "meshes"


@pytest.mark.parametrize(
    ("name", "cells", "merged"),
    [("bunny_closed_odedstein.obj", 12, 1), ("wingnut.obj", 16, 4)],
)
def test_conform_same_triangles_as_one_process(client, tmp_path, name, cells, merged):  # noqa: F811
    src = MESHES / name
    part = conformal.load_part(src)
    h = float((part.bounds[1] - part.bounds[0]).max()) / cells
    r = 0.012 * h  # thin enough that no strut is thinned (radius fitting is global)
    with warnings.catch_warnings(record=True) as w1:  # loose pieces removed: warned
        warnings.simplefilter("always")
        graph, rep = conformal.voxel_lattice(part, "bcc", h, r, fill="conform",
                                             return_report=True)  # fmt: skip
    assert rep.fill == "conform" and rep.moved_nodes > 0 and rep.radii_reduced == 0
    assert rep.merged_nodes == merged  # surface nodes merged: the cross-block case is real
    ref = single_triangles(fast_stitch.stitch(graph, 6, profile="area"))
    out = tmp_path / "c.stl"
    with warnings.catch_warnings(record=True) as w2:
        warnings.simplefilter("always")
        res = fill_sharded(src, out, "bcc", h, r, shards=4, scheduler=client, fill="conform")
    assert [str(x.message) for x in w2] == [str(x.message) for x in w1]
    assert len(res.shards) == 4
    assert res.struts == graph.num_edges
    assert res.removed_islands == rep.removed_islands
    rec = read_stl(out)
    assert len(rec) == res.triangles == len(ref)
    np.testing.assert_array_equal(canonical(rec["v"]), ref)
    assert_closed(rec)


def test_conform_halo_too_small_is_refused(client, tmp_path):  # noqa: F811
    src = MESHES / "bunny_closed_odedstein.obj"
    part = conformal.load_part(src)
    h = float((part.bounds[1] - part.bounds[0]).max()) / 12
    with pytest.raises(ShardingError, match="merging close surface nodes.*larger halo"):
        fill_sharded(src, tmp_path / "x.stl", "bcc", h, 0.012 * h, shards=4,
                     scheduler=client, fill="conform", halo=2)  # fmt: skip
    assert not (tmp_path / "x.stl").exists()


def test_clip_still_refused(tmp_path):
    with pytest.raises(ShardingError, match="'clip'.*crossings"):
        fill_sharded(MESHES / "wingnut.obj", tmp_path / "x.stl", fill="clip")  # type: ignore[arg-type]
