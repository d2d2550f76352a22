"""conformal: lattice graphs from unit cells and from real parts.

- :mod:`conformal.cells`: the unit-cell library and exact tiling.
- :func:`load_part`: STEP/STP, STL/OBJ/PLY/3MF or CAD shapes -> :class:`Part`.
- :func:`voxel_lattice`, :func:`tet_lattice`: parts -> :class:`lattice_cad.LatticeGraph`.
- :mod:`conformal.radius`: radius specifications and the stitch-fit check.
- :class:`Similarity`, :class:`SteadyLattice`: steady (programmed) lattices with
  closed-form integral properties (Gupta et al.).
"""

from conformal.cells import CELLS, UnitCell, block, cell_counts, tile, tile_arrays
from conformal.part import Part, PartError, StepUnitsError, load_part
from conformal.radius import FitError, check_fit, fit_radii, graded_by_distance
from conformal.similarity import Canonical, Similarity, SimilarityError
from conformal.steady import SteadyLattice, SteadyLatticeError
from conformal.tet import tet_lattice, tet_mesh
from conformal.voxel import BuildReport, voxel_lattice, voxelize

__all__ = [
    "CELLS",
    "UnitCell",
    "tile",
    "tile_arrays",
    "block",
    "cell_counts",
    "Part",
    "PartError",
    "StepUnitsError",
    "load_part",
    "voxel_lattice",
    "voxelize",
    "BuildReport",
    "tet_lattice",
    "tet_mesh",
    "FitError",
    "check_fit",
    "fit_radii",
    "graded_by_distance",
    "Similarity",
    "SimilarityError",
    "Canonical",
    "SteadyLattice",
    "SteadyLatticeError",
]
