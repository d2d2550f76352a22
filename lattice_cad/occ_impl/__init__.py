"""Every OpenCascade call of lattice-cad goes through this package (as CadQuery's ``occ_impl``).

No other module imports OCP, cadquery or build123d at module level; the engines and the
front call these functions, which take and return OCCT shapes or plain numpy arrays.

- :mod:`~lattice_cad.occ_impl.stack`: is the installed cadquery/build123d/OCP set the
  supported one? (checked once, before OCP is first imported)
- :mod:`~lattice_cad.occ_impl.shapes`: conversion from CadQuery/build123d objects,
  exploration, BRepCheck and builder checks, the one fuse, volume, bounds, tessellation
  with shared edge nodes, binary BREP.
- :mod:`~lattice_cad.occ_impl.step`: STEP read/write with unit cross-checks.
- :mod:`~lattice_cad.occ_impl.merge`: merging vertices within a distance (OCCT's copies of
  edge nodes, a mesh file's triangle soup); numpy and scipy only, no OCP.
- :mod:`~lattice_cad.occ_impl.truss`: the exact unit truss of one node (Wang, Chen & Rosen:
  a sphere plus half-struts), built, checked, measured and tessellated.

Importing this package is cheap; its submodules but ``merge`` import OCP (about a second).
"""

from lattice_cad.occ_impl import stack

stack.warn_once()  # before the first OCP import: a broken stack is named, with its fix
