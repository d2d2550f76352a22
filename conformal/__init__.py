"""conformal: lattice graphs from unit cells and from real parts, skins, steady lattices.

Everything that turns geometry into a lattice graph lives here: the unit-cell library and
its exact tiling, parts (STEP, meshes, CAD shapes) with exact inside and distance queries,
voxel and tetrahedral fills, radius specifications and the fit check, skins (hollowing a
part), and also the *steady* (programmed) lattices of Gupta et al., which are graphs too:
balls and racks placed by a similarity transformation, with closed-form integral
properties.

- :mod:`conformal.cells`: the unit-cell library and exact tiling.
- :func:`load_part`: STEP/STP, STL/OBJ/PLY/3MF or CAD shapes -> :class:`Part`.
- :func:`voxel_lattice`, :func:`tet_lattice`: parts -> :class:`lattice_cad.LatticeGraph`.
- :mod:`conformal.radius`: radius specifications and the stitch-fit check.
- :mod:`conformal.skin`: hollow a part to a wall and unite it with a lattice.
- :mod:`conformal.printability`: overhanging and thin struts for a build direction
  (``conformal.printability.printability``), overhang removal, self-supporting cells
  and orientations.
- :mod:`conformal.escape`: escape holes for the cavities of a skin, verified by a flood fill.
- :class:`Similarity`, :class:`SteadyLattice`: steady (programmed) lattices with
  closed-form integral properties (Gupta et al.).
"""

from conformal.cells import CELLS, UnitCell, block, cell_counts, tile, tile_arrays
from conformal.part import Part, load_part
from conformal.printability import (
    PrintabilityReport,
    best_orientation,
    remove_overhangs,
    self_supporting_cells,
)
from conformal.radius import check_fit, fit_radii, graded_by_distance
from conformal.similarity import Canonical, Similarity
from conformal.steady import SteadyLattice
from conformal.tet import tet_lattice, tet_mesh
from conformal.voxel import BuildReport, grid_of, inside_cells, voxel_lattice, voxelize
from lattice_cad.core.errors import (
    FitError,
    PartError,
    PrintabilityError,
    SimilarityError,
    SteadyLatticeError,
    StepUnitsError,
)

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
    "grid_of",
    "inside_cells",
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
    "PrintabilityReport",
    "PrintabilityError",
    "remove_overhangs",
    "self_supporting_cells",
    "best_orientation",
]

from lattice_cad.core import config as _config  # noqa: E402

_config.prefer_numba_threading()  # before any parallel kernel runs (see there)
