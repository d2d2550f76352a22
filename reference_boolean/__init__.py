"""reference_boolean: exact per-hub B-rep reference of a lattice, and accuracy reports.

The reference follows Wang, Chen & Rosen's unit trusses: one OCCT solid per
node (a sphere fused with the half-struts up to the strut midpoints; a leaf is its
half-strut, flat at the node), or per cluster of nodes whose hubs would overlap (fused
once), tessellated so that neighbouring solids share their midpoint circles exactly,
and stacked without any boolean between them (docs/REFERENCE.md).

The name: the reference is "boolean" in the sense of exact solid modelling (each hub is an
OCCT boolean union of a sphere and half-struts), not because hubs are fused with each other;
they are not, which is what makes it fast and exactly watertight. The OCCT side of a hub
lives in :mod:`lattice_cad.occ_impl.truss`; this package describes hubs in numpy, runs them
in worker processes, stacks the results and compares meshes with them.

- :func:`build_reference` -> :class:`Reference` (exact volume, watertight mesh,
  STL / STEP export, failed hubs by node index).
- :func:`hub_solids` -> :class:`HubSolids`: the distinct hub solids of any lattice
  (clean or not), which :mod:`lattice_cad.occ_impl.lattice_brep` sews or fuses into one
  solid per body for STEP output.
- :func:`compare` -> :class:`ValidationReport` (manifold3d unions at several
  resolutions, a mesh's deviation from the reference; JSON / Markdown / HTML).

OCCT (OCP) is only imported when a reference is built.
"""

from lattice_cad.core.errors import DirtyLatticeError, ReferenceBuildError
from reference_boolean.clusters import find_clusters
from reference_boolean.compare import MeshComparison, ValidationReport, compare, union_mesh
from reference_boolean.reference import (
    HubSolids,
    Reference,
    build_reference,
    count_hubs,
    find_overlaps,
    hub_solids,
    strut_frames,
)

__all__ = [
    "build_reference",
    "Reference",
    "ReferenceBuildError",
    "DirtyLatticeError",
    "find_overlaps",
    "find_clusters",
    "strut_frames",
    "compare",
    "ValidationReport",
    "MeshComparison",
    "union_mesh",
    "hub_solids",
    "HubSolids",
    "count_hubs",
]

from lattice_cad.core import config as _config  # noqa: E402

_config.prefer_numba_threading()  # before any parallel kernel runs (see there)
