"""lattice-cad: lattice structures for additive manufacturing.

The core types live here; the engines are separate top-level packages:

- :mod:`fast_stitch`: graph -> watertight triangle mesh (Verma et al.; LSLT).
- :mod:`conformal`: parts and unit cells -> lattice graphs; steady lattices.
- :mod:`reference_boolean`: exact B-rep reference and accuracy reports.

The user-facing layer (:class:`Lattice`, :func:`validate`, file export, the
CLI) is loaded on first use, so ``import lattice_cad`` stays light. Importing
it also arranges for ``cadquery.Workplane.lattice`` to exist as soon as
cadquery is imported (without importing cadquery itself).
"""

from typing import Any

from lattice_cad.errors import InvalidGraphError, LatticeError, LatticeWarning, StitchError
from lattice_cad.graph import LatticeGraph

__all__ = [
    "LatticeGraph",
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "LatticeWarning",
    "Lattice",
    "validate",
    "ExportError",
    "ExportWarning",
]

__version__ = "0.1.0"


def __getattr__(name: str) -> Any:  # PEP 562: the upper layers load on first use
    if name == "Lattice":
        from lattice_cad.lattice import Lattice

        return Lattice
    if name == "validate":
        from lattice_cad.validate import validate

        return validate
    if name in ("ExportError", "ExportWarning"):
        from lattice_cad import export

        return getattr(export, name)
    raise AttributeError(f"module 'lattice_cad' has no attribute {name!r}")


try:  # adds cq.Workplane.lattice when cadquery is imported; does not import cadquery here
    from lattice_cad import plugin as _plugin  # noqa: F401
except ImportError:  # pragma: no cover
    pass
