"""Tetrahedral lattices: the vertices and edges of a tet mesh of the part.

As in Verma, Rankouhi & Suresh (2019), Fig. 6.

The part is meshed with gmsh (target edge length ``size``): a CAD part
through its exact B-rep (OCCT kernel; several solids are fused first), a mesh
part by re-meshing its surface (``classifySurfaces`` / ``createGeometry``).
Every tetrahedron vertex becomes a node and every distinct tetrahedron edge a
strut, so surface nodes lie on the part's surface and the lattice conforms to
it.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from conformal.part import Part, PartError
from conformal.radius import RadiusSpec
from conformal.voxel import BuildReport, FitMode, _finish
from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph

__all__ = ["tet_lattice", "tet_mesh"]

Algorithm = Literal["delaunay", "hxt"]
_ALGO = {"delaunay": 1, "hxt": 10}


def tet_mesh(
    part: Part,
    size: float = config.DEFAULT_CELL_SIZE,
    *,
    algorithm: Algorithm = "hxt",
    surface_angle: float = 40.0,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A tetrahedral mesh of ``part`` with gmsh.

    Parameters
    ----------
    part : Part
    size : float
        Target edge length (mm).
    algorithm : {"hxt", "delaunay"}
        gmsh's 3-D algorithm (HXT is parallel and fast).
    surface_angle : float
        For mesh parts: dihedral angle (degrees) above which a mesh edge is a
        feature edge that the re-meshed surface keeps.

    Returns
    -------
    nodes : (N, 3) float64
        Vertices used by the tetrahedra.
    tets : (T, 4) int64
        Node indices of each tetrahedron.

    Raises
    ------
    PartError
        gmsh failed; the message has gmsh's error and the volume entity tags.
    """
    import gmsh

    if not (isinstance(size, (int, float)) and math.isfinite(size) and size > 0):
        raise ValueError(f"size must be a finite number > 0, got {size!r}")
    if algorithm not in _ALGO:
        raise ValueError(f"algorithm must be one of {sorted(_ALGO)}, got {algorithm!r}")
    if gmsh.isInitialized():
        raise RuntimeError("gmsh is already initialised in this process; finalise it first")
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    vols: list[int] = []
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.logger.start()
        gmsh.model.add("part")
        with tempfile.TemporaryDirectory(prefix="conformal_tet_") as tmp:
            brep = _brep_file(part, Path(tmp))
            if brep is not None:
                gmsh.model.occ.importShapes(str(brep))
                gmsh.model.occ.synchronize()
            else:
                stl = Path(tmp) / "part.stl"
                _write_stl(part, stl)
                gmsh.merge(str(stl))
                gmsh.model.mesh.classifySurfaces(math.radians(surface_angle), True, True, math.pi)
                gmsh.model.mesh.createGeometry()
                surfaces = [t for _, t in gmsh.model.getEntities(2)]
                loop = gmsh.model.geo.addSurfaceLoop(surfaces)
                gmsh.model.geo.addVolume([loop])
                gmsh.model.geo.synchronize()
        vols = [t for _, t in gmsh.model.getEntities(3)]
        if not vols:
            raise PartError(f"{part.name}: gmsh found no volume to mesh")
        gmsh.option.setNumber("Mesh.MeshSizeMax", float(size))
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * float(size))
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
        gmsh.option.setNumber("Mesh.Algorithm3D", _ALGO[algorithm])
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        etypes, _, enodes = gmsh.model.mesh.getElements(3)
        tets = [
            np.asarray(n, dtype=np.int64) for t, n in zip(etypes, enodes, strict=True) if t == 4
        ]
        if not tets or not sum(len(t) for t in tets):
            raise PartError(
                f"{part.name}: gmsh produced no tetrahedra (volumes {vols}); "
                "the part may be thinner than the mesh size allows"
            )
        tet_tags = np.concatenate(tets).reshape(-1, 4)
        tags = np.asarray(tags, dtype=np.int64)
        xyz = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    except PartError:
        raise
    except Exception as exc:  # gmsh raises plain Exceptions with its message
        log = [m for m in gmsh.logger.get() if "Error" in m][-3:]
        detail = "; ".join(log) if log else ""
        raise PartError(
            f"{part.name}: gmsh failed to mesh volume(s) {vols or '(none)'}: {exc}"
            f"{'; ' + detail if detail and detail not in str(exc) else ''}"
        ) from None
    finally:
        try:
            gmsh.logger.stop()
        finally:
            gmsh.finalize()
    lookup = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    lookup[tags] = np.arange(len(tags))
    tet = lookup[tet_tags]
    used, inv = np.unique(tet, return_inverse=True)
    return xyz[used], inv.reshape(-1, 4).astype(np.int64)


def _brep_file(part: Part, tmp: Path) -> Path | None:
    """The part's exact B-rep as a .brep file (None for mesh parts or a failed fuse)."""
    if part.shape is None:
        return None
    from lattice_cad.core.errors import OCCTFailure
    from lattice_cad.occ_impl import shapes as _occ

    solids = list(part.shape)
    try:
        shape = solids[0] if len(solids) == 1 else _occ.fuse(solids, simplify=True)
    except OCCTFailure:
        return None
    path = tmp / "part.brep"
    _occ.write_brep(shape, path)
    return path


def _write_stl(part: Part, path: Path) -> None:
    import trimesh

    trimesh.Trimesh(part.vertices, part.faces, process=False).export(str(path))


def tet_edges(tets: NDArray[np.int64]) -> NDArray[np.int64]:
    """(M, 2) int64: the distinct edges of (T, 4) tetrahedra, ``[:, 0] < [:, 1]``, sorted."""
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    e = np.sort(tets[:, pairs].reshape(-1, 2), axis=1)
    return np.unique(e, axis=0)


def tet_lattice(
    part: Part,
    size: float = config.DEFAULT_CELL_SIZE,
    radius: RadiusSpec = config.DEFAULT_RADIUS,
    *,
    algorithm: Algorithm = "hxt",
    min_radius: float | None = None,
    fit: FitMode = "shrink",
    return_report: bool = False,
) -> LatticeGraph | tuple[LatticeGraph, BuildReport]:
    """A lattice whose nodes and struts are the vertices and edges of a tet mesh of ``part``.

    Parameters
    ----------
    part : Part
    size : float
        Target tetrahedron edge length (mm).
    radius : float, (M,), (M, 2) or callable
        See :mod:`conformal.radius`.
    algorithm : {"hxt", "delaunay"}
        gmsh's 3-D algorithm.
    min_radius, fit
        As in :func:`conformal.voxel_lattice`: struts whose end profiles would
        meet (small angles between tet edges) are thinned, or reported.
    return_report : bool
        Also return a :class:`~conformal.voxel.BuildReport`.

    Returns
    -------
    LatticeGraph, or (LatticeGraph, BuildReport)

    Raises
    ------
    PartError
        gmsh failed (its message and the volume tags are included).
    """
    if not isinstance(part, Part):
        raise TypeError(f"part must be a conformal.Part (see load_part), got {type(part).__name__}")
    rep = BuildReport()
    t0 = time.perf_counter()
    nodes, tets = tet_mesh(part, size, algorithm=algorithm)
    rep.seconds["mesh"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    edges = tet_edges(tets)
    graph = _finish(nodes, edges, radius, min_radius, fit, rep)
    rep.seconds["fit"] = time.perf_counter() - t0
    return (graph, rep) if return_report else graph
