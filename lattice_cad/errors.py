"""Exception and warning hierarchy shared by every lattice-cad package.

This module sits at the bottom of the layering (beside :mod:`lattice_cad.graph`)
so that the engines (``fast_stitch``, ``conformal``, ``reference_boolean``) can
raise the same types that users catch.
"""

from __future__ import annotations

__all__ = [
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "LatticeWarning",
    "CADStackWarning",
]


class LatticeError(Exception):
    """Base class of every error raised on purpose by lattice-cad."""


class InvalidGraphError(LatticeError, ValueError):
    """A lattice graph violates an input rule; the message names the node or edge."""


class StitchError(LatticeError, ValueError):
    """A valid graph cannot be stitched (struts meet too closely, or overlap)."""


class LatticeWarning(UserWarning):
    """Something was accepted but deserves the user's attention (e.g. isolated nodes)."""


class CADStackWarning(LatticeWarning):
    """The installed cadquery/build123d/OCP set is not the supported one (see ``_stack``)."""
