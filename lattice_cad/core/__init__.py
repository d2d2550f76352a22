"""The core floor of lattice-cad: the shared types, errors and settings (numpy only).

Everything else stands on this package, and it imports nothing of lattice-cad above it and
no library but numpy. Importing it has no side effects.

- :class:`LatticeGraph` (``graph``): nodes, struts and per-end radii, validated and
  immutable, with its own ``.json``/``.npz`` format.
- :class:`Mesh` (``mesh``): the triangle mesh type of every engine, with its binary STL
  writer.
- ``errors``: every exception and warning, in one hierarchy under :class:`LatticeError`.
- ``config``: every shared tolerance, limit and default.
- ``checks``: the argument checks the engines share (segments, seed, workers, progress).
- ``atomic``: :func:`atomic_write`, so that no file is ever left half-written.
- ``arrays``: :func:`unique_rows` (``np.unique(axis=0)`` of integer rows, fast).
"""

from lattice_cad.core import config
from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.checks import ProgressCallback
from lattice_cad.core.errors import (
    BeamOnlyWarning,
    CADStackWarning,
    DirtyLatticeError,
    ExportError,
    ExportWarning,
    ExternalCrash,
    FillError,
    FitError,
    InvalidGraphError,
    LatticeError,
    LatticeWarning,
    OCCTFailure,
    PartError,
    ReferenceBuildError,
    SimilarityError,
    SkinError,
    SteadyLatticeError,
    StepUnitsError,
    StitchError,
)
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.mesh import Mesh, stl_size

__all__ = [
    "config",
    "atomic_write",
    "ProgressCallback",
    "LatticeGraph",
    "Mesh",
    "stl_size",
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "FitError",
    "FillError",
    "PartError",
    "StepUnitsError",
    "SkinError",
    "SimilarityError",
    "SteadyLatticeError",
    "ExportError",
    "OCCTFailure",
    "ExternalCrash",
    "ReferenceBuildError",
    "DirtyLatticeError",
    "LatticeWarning",
    "ExportWarning",
    "BeamOnlyWarning",
    "CADStackWarning",
]
