"""An open bug, kept as a strict xfail until it is fixed (session 18).

The graph (``regression_hammer_tet_graph.npz``: 489 nodes, 1,359 struts, fitted radii) is
the tet lattice of ``meshes/hammer.obj`` at the parts benchmark's setting (cell 0.54971,
r 0.0458092) built by the clash-aware graph repair of branch ``tet-clash-repair``. The
stitcher makes a mesh with 10 self-intersecting face pairs from it (``fast_stitch.check``
says so) without raising; through the CLI the trim glued those struts back after its
float32 check, and ``lattice-cad fill`` wrote a file ``lattice-cad check`` rejects.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fast_stitch
from lattice_cad import LatticeGraph

GRAPH = Path(__file__).with_name("regression_hammer_tet_graph.npz")


def _graph() -> LatticeGraph:
    z = np.load(GRAPH)
    return LatticeGraph(z["nodes"], z["edges"], z["radii"])


def test_the_graph_is_the_one_recorded():
    g = _graph()
    assert (g.num_nodes, g.num_edges) == (489, 1359)


@pytest.mark.xfail(strict=True, reason="open bug: the stitch self-intersects (10 pairs)")
def test_stitch_of_the_hammer_tet_graph_is_valid_or_refused():
    try:
        mesh = fast_stitch.stitch(_graph())
    except fast_stitch.StitchError:
        return  # refusing is acceptable; writing an invalid mesh is not
    assert fast_stitch.check(mesh).valid
