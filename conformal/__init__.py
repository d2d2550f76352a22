"""conformal: lattice graphs from unit cells (and, later, from parts)."""

from conformal.cells import CELLS, UnitCell, block, cell_counts, tile, tile_arrays

__all__ = ["CELLS", "UnitCell", "tile", "tile_arrays", "block", "cell_counts"]
