"""Regression (session 18): a stitched mesh with self-intersecting faces, made silently.

The graph (``regression_hammer_tet_graph.npz``: 489 nodes, 1,359 struts, fitted radii) is
the tet lattice of ``meshes/hammer.obj`` at the parts benchmark's setting (cell 0.54971,
r 0.0458092) built by the clash-aware graph repair. At node 312 struts 951 and 953 meet at
20.7 degrees and widen away from it (0.0046 -> 0.0091 and -> 0.0087); the node's hub grew
1.23 times (``profile="volume"``), its band rings with it, and the two struts overlapped
beyond the joint: ten self-intersecting face pairs, which the stitch's check of tapered
neighbours let through (it skipped struts whose radius over distance from the node does
not grow, which does not keep them apart), and ``lattice-cad fill`` wrote a file
``lattice-cad check`` rejects.

Fixed in two places: hubs do not grow at the nodes of such pairs
(``fast_stitch.hubvolume.cap_taper_growth``), and the check tests every pair whose cones
from the node are not apart (``fast_stitch.hubvolume.taper_cone_pairs``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import fast_stitch
from lattice_cad import LatticeGraph
from tests.conftest import assert_valid, independent_check

GRAPH = Path(__file__).with_name("regression_hammer_tet_graph.npz")


def _graph() -> LatticeGraph:
    z = np.load(GRAPH)
    return LatticeGraph(z["nodes"], z["edges"], z["radii"])


def test_the_graph_is_the_one_recorded():
    g = _graph()
    assert (g.num_nodes, g.num_edges) == (489, 1359)
    assert g.is_tapered


def test_stitch_of_the_hammer_tet_graph_is_valid():
    assert_valid(fast_stitch.stitch(_graph()))  # ours, trimesh, manifold3d, pymeshlab


def test_the_check_refuses_the_grown_hub(monkeypatch):
    """With the growth cap off, the mesh is the invalid one; the check must refuse it."""
    stitch_module = sys.modules["fast_stitch.stitch"]
    monkeypatch.setattr(stitch_module, "cap_taper_growth", lambda *args: args[-1])
    with pytest.raises(fast_stitch.StitchError, match="node 312: struts 951 and 953"):
        fast_stitch.stitch(_graph())
    mesh = fast_stitch.stitch(_graph(), check_clearance=False)
    # what the check refused is really invalid, by ours and by an independent checker
    assert not fast_stitch.check(mesh).valid
    assert independent_check(mesh)["self_intersecting_faces"] > 0
