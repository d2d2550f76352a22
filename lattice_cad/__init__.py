"""lattice-cad: lattice structures for additive manufacturing.

The core types live here; the engines are separate top-level packages:

- :mod:`fast_stitch`: graph -> watertight triangle mesh (Verma et al.).
- :mod:`conformal`: parts -> lattice graphs.
- :mod:`reference_boolean`: exact B-rep reference and accuracy reports.
"""

from lattice_cad.errors import InvalidGraphError, LatticeError, LatticeWarning, StitchError
from lattice_cad.graph import LatticeGraph

__all__ = [
    "LatticeGraph",
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "LatticeWarning",
]

__version__ = "0.1.0"
