"""Sharded ``fill="conform"`` and ``"clip"`` on a LocalCluster: the same oriented triangles as
``conformal.voxel_lattice(fill=...)`` + ``fast_stitch.stitch`` in one process, on real
parts, and one closed solid across the seams (trimesh, manifold3d)."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

from tests.conftest import DATA

distributed = pytest.importorskip("distributed")

import conformal  # noqa: E402
import fast_stitch  # noqa: E402
from lattice_cad.core.errors import ShardingError  # noqa: E402
from lattice_cad.distributed import fill_sharded  # noqa: E402
from tests.test_distributed import (  # noqa: E402
    assert_closed,
    canonical,
    read_stl,
    single_triangles,
    two_worker_client,
)

MESHES = DATA / "meshes"


@pytest.fixture(scope="module")
def client():
    with two_worker_client(sys.modules[__name__]) as c:
        yield c


@pytest.mark.parametrize(
    ("fill", "name", "cells", "merged"),
    [
        ("conform", "bunny_closed_odedstein.obj", 12, 1),
        ("conform", "wingnut.obj", 16, 4),
        ("clip", "wingnut.obj", 14, 120),
        pytest.param("clip", "bunny_closed_odedstein.obj", 14, 387, marks=pytest.mark.slow),
    ],
)
def test_boundary_fill_same_triangles_as_one_process(client, tmp_path, fill, name, cells, merged):
    src = MESHES / name
    with warnings.catch_warnings(record=True) as w0:  # wingnut: 3 pairs of its faces cross
        warnings.simplefilter("always")
        part = conformal.load_part(src)
    said_at_load = [str(x.message) for x in w0]
    assert all("surface crosses itself" in m for m in said_at_load)
    assert len(said_at_load) == (name == "wingnut.obj")
    h = float((part.bounds[1] - part.bounds[0]).max()) / cells
    r = 0.012 * h  # thin enough that no strut is thinned (radius fitting is global)
    with warnings.catch_warnings(record=True) as w1:  # loose pieces removed: warned
        warnings.simplefilter("always")
        graph, rep = conformal.voxel_lattice(part, "bcc", h, r, fill=fill,
                                             return_report=True)  # fmt: skip
    assert rep.fill == fill and rep.radii_reduced == 0
    assert (rep.moved_nodes if fill == "conform" else rep.clipped_struts) > 0
    assert rep.merged_nodes == merged  # surface nodes merged: the cross-block case is real
    ref = single_triangles(fast_stitch.stitch(graph, 6))
    out = tmp_path / "c.stl"
    with warnings.catch_warnings(record=True) as w2:
        warnings.simplefilter("always")
        res = fill_sharded(src, out, "bcc", h, r, shards=4, scheduler=client, fill=fill)
    loaded = [m for m in (str(x.message) for x in w2) if m in said_at_load]
    assert [str(x.message) for x in w2 if str(x.message) not in loaded] == [
        str(x.message) for x in w1
    ]
    assert len(res.shards) == 4
    assert res.struts == graph.num_edges
    assert res.removed_islands == rep.removed_islands
    assert res.removed_fragments == rep.removed_fragments
    rec = read_stl(out)
    assert len(rec) == res.triangles == len(ref)
    np.testing.assert_array_equal(canonical(rec["v"]), ref)
    assert_closed(rec)


def test_conform_halo_too_small_is_refused(client, tmp_path):
    src = MESHES / "bunny_closed_odedstein.obj"
    part = conformal.load_part(src)
    h = float((part.bounds[1] - part.bounds[0]).max()) / 12
    with pytest.raises(ShardingError, match="merging close surface nodes.*larger halo"):
        fill_sharded(src, tmp_path / "x.stl", "bcc", h, 0.012 * h, shards=4,
                     scheduler=client, fill="conform", halo=2)  # fmt: skip
    assert not (tmp_path / "x.stl").exists()


@pytest.mark.parametrize(
    ("fill", "cells"),
    # conform: a 6-cell halo on a 12-cell part (~20 s under load)
    [pytest.param("conform", 12, marks=pytest.mark.slow), ("clip", 14)],
)
def test_usual_radius_fit_and_capping_sharded(client, tmp_path, fill, cells):
    """At the CLI's radius (0.08 of the cell) the one-process fit thins hundreds of struts
    near the surface (misfit and clearance rounds) and, for clip, hub growth is capped by
    clearance: the sharded rounds give the same triangles and the same warnings."""
    import importlib

    src = MESHES / "bunny_closed_odedstein.obj"
    part = conformal.load_part(src)
    h = float((part.bounds[1] - part.bounds[0]).max()) / cells
    r = 0.08 * h
    with warnings.catch_warnings(record=True) as w1:
        warnings.simplefilter("always")
        graph, rep = conformal.voxel_lattice(part, "bcc", h, r, fill=fill,
                                             return_report=True)  # fmt: skip
    assert rep.radii_reduced > 100  # the fit really thins, near every seam
    report: dict = {}
    ref = single_triangles(fast_stitch.stitch(graph, 6, _report=report))
    capped = len(report["capped"])
    assert capped == (2 if fill == "clip" else 0)  # clip: hubs capped in one process
    out = tmp_path / "u.stl"
    st = importlib.import_module("lattice_cad.distributed")
    with warnings.catch_warnings(record=True) as w2:
        warnings.simplefilter("always")
        res = st.fill_sharded(src, out, "bcc", h, r, shards=4, scheduler=client, fill=fill)
    assert [str(x.message) for x in w2] == [str(x.message) for x in w1]
    assert len(res.shards) == 4 and res.struts == graph.num_edges
    assert res.radii_reduced == rep.radii_reduced
    assert ("cap" in res.seconds) == bool(capped)  # the capping rounds ran sharded
    rec = read_stl(out)
    assert len(rec) == res.triangles == len(ref)
    np.testing.assert_array_equal(canonical(rec["v"]), ref)
    assert_closed(rec)
    if capped:  # every shard stitched again with the capped scales given: the same
        # _always_changed travels by value: the client fixture registers this module
        with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mp.setattr(st, "_cap_changed", _always_changed)
            res2 = st.fill_sharded(src, out, "bcc", h, r, shards=4, scheduler=client,
                                   fill=fill)  # fmt: skip
        assert "restitch" in res2.seconds
        np.testing.assert_array_equal(canonical(read_stl(out)["v"]), ref)


def _always_changed(spec, shard, rnd):
    """Stands in for lattice_cad.distributed._cap_changed: restitch every shard."""
    return True


def test_fit_reach_checked(client, tmp_path):
    """A halo given too small for the fit's reach is refused by name (no file); the
    default halo grows until it is enough (the test above)."""
    from lattice_cad.core.errors import LatticeWarning, ShardHaloError

    src = MESHES / "bunny_closed_odedstein.obj"
    part = conformal.load_part(src)
    h = float((part.bounds[1] - part.bounds[0]).max()) / 12
    with (
        pytest.raises(ShardHaloError, match="fitting the radii reads struts within"),
        pytest.warns(LatticeWarning, match="loose piece"),
    ):
        fill_sharded(src, tmp_path / "x.stl", "bcc", h, 0.08 * h, shards=4,
                     scheduler=client, fill="conform", halo=4)  # fmt: skip
    assert not (tmp_path / "x.stl").exists()
