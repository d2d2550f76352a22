"""lattice-cad: lattice structures for additive manufacturing.

The project stands on three floors (see docs/ARCHITECTURE.md):

- the core, :mod:`lattice_cad.core`: :class:`LatticeGraph`, :class:`Mesh`, the errors, the
  shared settings (numpy only); :mod:`lattice_cad.occ_impl` (every OpenCascade call) and
  :mod:`lattice_cad.io` (every file format) beside it;
- the engines, separate top-level packages: :mod:`fast_stitch` (graph -> watertight mesh),
  :mod:`conformal` (parts and unit cells -> graphs; skins; steady lattices) and
  :mod:`reference_boolean` (the exact B-rep reference and the comparisons);
- the front, here: :class:`Lattice`, :func:`validate`, the reports, the CLI
  (:mod:`lattice_cad.cli`), previews, and the CadQuery plugin (``import lattice_cad.plugin``
  adds ``cadquery.Workplane.lattice``).

``import lattice_cad`` loads the core only; the front loads on first use and importing it
has no side effects.
"""

from typing import Any

from lattice_cad.core.errors import (
    ExportError,
    ExportWarning,
    InvalidGraphError,
    LatticeError,
    LatticeWarning,
    StitchError,
)
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.mesh import Mesh

__all__ = [
    "LatticeGraph",
    "Mesh",
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "LatticeWarning",
    "ExportError",
    "ExportWarning",
    "Lattice",
    "validate",
]

__version__ = "0.1.0"


def __getattr__(name: str) -> Any:  # PEP 562: the front loads on first use
    if name == "Lattice":
        from lattice_cad.lattice import Lattice

        return Lattice
    if name == "validate":
        from lattice_cad.validate import validate

        return validate
    raise AttributeError(f"module 'lattice_cad' has no attribute {name!r}")
