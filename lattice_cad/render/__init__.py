"""Shaded pictures of meshes and lattices, rendered in software (no display, no GPU).

A floor module (beside :mod:`lattice_cad.io`): the front's ``preview`` and the
accuracy report of ``reference_boolean`` both draw through it. It needs only
numpy, numba (the rasteriser kernel), scipy (one blur) and matplotlib/Pillow
(the text and the PNG), all of them dependencies of lattice-cad already.

* :class:`Layer`: one triangle surface (solid or translucent ghost), optionally
  with a quantity per vertex.
* :func:`picture`: layers in one or more :class:`Panel` (views, sections), a
  :class:`ColorBar` with units, numbered :class:`Marker`, a caption -> PNG bytes.
* :func:`tubes`, :func:`strut_angles`: a graph's struts as display tubes; each
  strut's angle to the build plate.
"""

from lattice_cad.render.figure import ColorBar, Marker, Panel, picture
from lattice_cad.render.geometry import node_values, strut_angles, tubes
from lattice_cad.render.raster import VIEWS, Camera, Layer, Section, camera_for, shade

__all__ = [
    "VIEWS",
    "Camera",
    "ColorBar",
    "Layer",
    "Marker",
    "Panel",
    "Section",
    "camera_for",
    "node_values",
    "picture",
    "shade",
    "strut_angles",
    "tubes",
]
