"""fast_stitch: the combinatorial lattice stitcher (Verma, Rankouhi & Suresh 2019).

A lattice graph becomes a watertight, 2-manifold, outward-oriented triangle mesh without any
boolean: each node gets a convex hub, each strut a prism between two profiles, stitched by
index. :func:`stitch` (also ``method="lslt"``: Chougrani et al. 2017), :func:`estimate`
(exact counts before building), and :func:`check`, the validity checker (see its module for
what it shares with the stitcher). The :class:`Mesh` type is the core's, re-exported.

>>> import fast_stitch
>>> from lattice_cad import LatticeGraph
>>> g = LatticeGraph([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1], [0, 2]], 0.1)
>>> mesh = fast_stitch.stitch(g, segments=6)
>>> fast_stitch.estimate(g, 6).triangles == len(mesh.faces)
True
"""

from fast_stitch.check import CheckReport, check
from fast_stitch.stitch import Estimate, estimate, stitch
from lattice_cad.core.errors import ExportError, StitchError
from lattice_cad.core.mesh import Mesh

__all__ = [
    "stitch",
    "estimate",
    "Estimate",
    "check",
    "CheckReport",
    "Mesh",
    "StitchError",
    "ExportError",
]

from lattice_cad.core import config as _config  # noqa: E402

_config.prefer_numba_threading()  # before any parallel kernel runs (see there)
