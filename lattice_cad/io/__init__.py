"""The I/O room: every reader and writer of lattice-cad, dispatched by one suffix table.

The table is :data:`lattice_cad.core.formats.FORMATS` (a suffix means the same everywhere,
and an unsupported one gets one clear error). Meshes, graphs and beam lattices are read and
written by :mod:`lattice_cad.io.exchange`; beam FE models (``.inp``) by
:mod:`lattice_cad.io.fe`; exact solids (STEP) by
:mod:`lattice_cad.occ_impl.step`; parts are loaded by :func:`conformal.load_part`.
"""

from lattice_cad.core.formats import FORMATS, Format, Kind, format_for, suffixes
from lattice_cad.io.exchange import (
    GRAPH_SUFFIXES,
    MESH_SUFFIXES,
    check_limits,
    check_mesh_file,
    collapse_faces,
    collapse_folds,
    estimate_bytes,
    read_beam_lattice,
    read_mesh,
    save_beam_lattice,
    save_graph,
    save_mesh,
    single_precision,
)
from lattice_cad.io.fe import BeamModel, Box, Material, Plane, read_dat, save_inp

__all__ = [
    "FORMATS",
    "Format",
    "Kind",
    "format_for",
    "suffixes",
    "MESH_SUFFIXES",
    "GRAPH_SUFFIXES",
    "check_limits",
    "check_mesh_file",
    "collapse_faces",
    "collapse_folds",
    "estimate_bytes",
    "read_beam_lattice",
    "read_mesh",
    "save_beam_lattice",
    "save_graph",
    "save_mesh",
    "single_precision",
    "BeamModel",
    "Box",
    "Material",
    "Plane",
    "read_dat",
    "save_inp",
]
