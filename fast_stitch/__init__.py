"""fast_stitch: the combinatorial lattice stitcher (Verma, Rankouhi & Suresh 2019).

>>> import fast_stitch
>>> from lattice_cad import LatticeGraph
>>> g = LatticeGraph([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1], [0, 2]], 0.1)
>>> mesh = fast_stitch.stitch(g, segments=6)
>>> fast_stitch.estimate(g, 6).triangles == len(mesh.faces)
True
"""

from fast_stitch.check import CheckReport, check
from fast_stitch.mesh import ExportError, Mesh
from fast_stitch.stitch import Estimate, estimate, stitch
from lattice_cad.errors import StitchError

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
