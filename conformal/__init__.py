"""conformal: lattice graphs from unit cells and parts."""
