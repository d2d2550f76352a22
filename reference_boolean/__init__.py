"""reference_boolean: exact per-hub B-rep reference of a lattice (see issue: reference)."""
