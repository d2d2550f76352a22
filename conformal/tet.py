"""Tetrahedral lattices: the vertices and edges of a tet mesh of the part.

As in Verma, Rankouhi & Suresh (2019), Fig. 6.

The part is meshed with gmsh (target edge length ``size``): a CAD part
through its exact B-rep (OCCT kernel; several solids are fused first), a mesh
part by re-meshing its surface (``classifySurfaces`` / ``createGeometry``). When gmsh
cannot mesh a B-rep (NIST CTC-02: overlapping surface meshes of close faces), the
part's closed triangulation is meshed as a mesh part's, with a warning; so it is first
when the edges of the B-rep's faces would crowd the tetrahedra's nodes (a gear of
hundreds of narrow faces), and also when the B-rep's lattice has struts thinned where
the part is thick for the size (a thread), the better of the two then kept
(:func:`tet_lattice`).
Every tetrahedron vertex becomes a node and every distinct tetrahedron edge a
strut, so surface nodes lie on the part's surface and the lattice conforms to
it.
"""

from __future__ import annotations

import math
import signal
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from conformal.part import Part, PartError
from conformal.radius import (
    Profile,
    RadiusSpec,
    check_stitch_profile,
    repair_graph,
    resolve_radii,
)
from conformal.voxel import BuildReport, FitMode, _finish, refuse_too_thick
from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.errors import ExternalCrash, ExternalTimeout, LatticeWarning
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.isolate import run_isolated
from lattice_cad.core.mesh import signed_volume

__all__ = ["tet_lattice", "tet_mesh", "tet_edges", "boundary_nodes"]

Algorithm = Literal["hxt", "delaunay", "frontal"]
_ALGO = {"hxt": 10, "delaunay": 1, "frontal": 4}

#: A part at most this many times the tetrahedra's size thick has no tet nodes inside it
#: (a node inside needs a tetrahedron's height, about 0.8 x size, to either face): its
#: tetrahedra lie flat between its faces (the thinned-struts warning, :func:`_thin_advice`).
THIN_FOR_TETS = 1.5

#: The feature angle (degrees) that marks no edge as a feature: a mesh surface is then
#: re-parametrised in the patches gmsh cuts it into itself.
NO_FEATURES = 180.0


def tet_mesh(
    part: Part,
    size: float = config.DEFAULT_CELL_SIZE,
    *,
    algorithm: Algorithm = "hxt",
    surface_angle: float = 40.0,
    timeout: float | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A tetrahedral mesh of ``part`` with gmsh.

    Parameters
    ----------
    part : Part
    size : float
        Target edge length (mm).
    algorithm : {"hxt", "delaunay"}
        gmsh's 3-D algorithm tried first (HXT is parallel and fast); when it fails, the
        others are tried.
    surface_angle : float
        For mesh parts (and B-rep parts whose B-rep gmsh cannot mesh): dihedral angle
        (degrees) above which a mesh edge is a feature edge that the re-meshed surface
        keeps. When the surface cannot be re-parametrised at that angle, it is tried with
        no feature edges (:data:`NO_FEATURES`); then a resampled surface (the zero level
        of the signed distance, spacing ``size / 1.5``), re-parametrised at the same two
        angles, then as it is; then 20 and 10 degrees, then the part's own triangles as
        the boundary. A surface of several closed shells is meshed one solid
        (an outer shell with its cavities) at a time.
    timeout : float, optional
        Seconds one gmsh attempt may take (default ``config.TET_ATTEMPT_SECONDS`` plus one
        second per ``config.TET_ATTEMPT_RATE`` tetrahedra expected of the part's volume).
        Each runs in a child process: a crash or a hang of gmsh moves on to the next
        attempt instead of ending the caller; after a hang, the next surface (a hang is
        most often in the surface mesh, which the other 3-D algorithms would mesh again).
        All attempts together stop after ``config.TET_TOTAL_ATTEMPTS`` times it.
    progress : callable, optional
        ``progress(stage, done, total)`` is called before each gmsh attempt: ``stage``
        names it (the surface strategy, the piece, the 3-D algorithm), ``done`` counts
        the strategies tried of ``total`` (a CLI bar shows which attempt runs).

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
    nodes, tets, _ = _tet_mesh(
        part, size, algorithm=algorithm, surface_angle=surface_angle, timeout=timeout,
        progress=progress,
    )  # fmt: skip
    return nodes, tets


#: How a B-rep part's tet mesh is sought (:func:`_tet_mesh`): its B-rep first; its
#: triangulated surface first, then its B-rep; its triangulated surface only.
BrepOrder = Literal["brep", "surface", "no-brep"]


def _tet_mesh(
    part: Part,
    size: float,
    *,
    algorithm: Algorithm = "hxt",
    surface_angle: float = 40.0,
    timeout: float | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    brep: BrepOrder = "brep",
) -> tuple[NDArray[np.float64], NDArray[np.int64], str]:
    """:func:`tet_mesh`, and which input gave it (``"brep"``, ``"surface"`` or
    ``"resampled"``); ``brep`` places a B-rep part's B-rep among the ways tried."""
    import gmsh

    if not (isinstance(size, (int, float)) and math.isfinite(size) and size > 0):
        raise ValueError(f"size must be a finite number > 0, got {size!r}")
    if algorithm not in _ALGO:
        raise ValueError(f"algorithm must be one of {sorted(_ALGO)}, got {algorithm!r}")
    if gmsh.isInitialized():
        raise RuntimeError("gmsh is already initialised in this process; finalise it first")
    order = [algorithm] + [a for a in _ALGO if a != algorithm]
    # (input, gmsh's surface handling, feature angle): the resampled surface is first
    # re-parametrised (gmsh re-meshes it at ``size``), then taken as it is (its triangles,
    # a fraction of ``size`` and some slivers, then bound the tetrahedra: the teapot gave
    # 46,527 tetrahedra where 1,911 of the size asked fill it)
    # each surface is re-parametrised with feature edges at ``surface_angle``, then with
    # none (NO_FEATURES: gmsh cuts the surface into patches it can parametrise where it
    # needs to): the creases a scan's noise marks at 40 deg bound patches gmsh cannot
    # parametrise ("Wrong topology of boundary mesh"), and the resampled surface taken as
    # it is bounds tetrahedra with edges a tenth of the size (the dragon: median 0.48 x
    # size, 10 % under 0.08 x size; 3,858 of 3,901 struts thinned)
    angles = list(dict.fromkeys((float(surface_angle), NO_FEATURES)))
    surfaces = [("surface", "reparametrized", a) for a in angles]
    surfaces += [("resampled", "reparametrized", a) for a in angles]
    surfaces += [("resampled", "discrete", 0.0)]
    surfaces += [("surface", "reparametrized", a) for a in (20.0, 10.0)]
    surfaces += [("surface", "discrete", 0.0)]
    if (
        len(part.faces) > config.TET_DENSE_TRIANGLES
        and len(part.faces) > config.TET_DENSE_PER_SQUARE * part.area / size**2
    ):
        # far more triangles than the size needs: gmsh spends a minute and more on each
        # attempt at the surface as it is; its resampled surface first
        surfaces.sort(key=lambda s: s[0] == "surface")  # (stable: the B-rep still first)
    if part.shape is not None and brep == "brep":
        # the exact B-rep first; when gmsh cannot mesh it (e.g. overlapping surface meshes of
        # close faces, NIST CTC-02), the part's own closed triangulation as for a mesh part
        surfaces = [("brep", "brep", 0.0), *surfaces]
    elif part.shape is not None and brep == "surface":
        # (the B-rep's faces would crowd the nodes: see tet_lattice) its surface
        # re-parametrised at the angles first
        k = len(angles)
        surfaces = [*surfaces[:k], ("brep", "brep", 0.0), *surfaces[k:]]
    if timeout is None:
        expected = 2.0 * abs(part.volume) / (size**3 / (6.0 * math.sqrt(2.0)))
        timeout = config.TET_ATTEMPT_SECONDS + expected / config.TET_ATTEMPT_RATE
    failures: list[str] = []
    brep_failure = ""  # the first reason the B-rep failed, if it was tried and did
    tried = 0  # failures before the B-rep's attempt
    deadline = time.monotonic() + config.TET_TOTAL_ATTEMPTS * timeout
    inputs = _GmshInputs(part, size)
    label = {"brep": "B-rep", "surface": "surface", "resampled": "resampled surface"}
    with tempfile.TemporaryDirectory(prefix="conformal_tet_") as tmp:
        for step, (source, how, angle) in enumerate(surfaces):
            if source == "brep":
                tried = len(failures)
            if time.monotonic() >= deadline:
                failures.append(
                    f"the other ways not tried: the attempts took "
                    f"{config.TET_TOTAL_ATTEMPTS:g} x {timeout:.0f} s, their budget"
                )
                break
            sources = inputs.files(source, Path(tmp))
            if sources is None:
                failures.append("the solids could not be fused into one B-rep")
                brep_failure = brep_failure or (failures[-1] if source == "brep" else "")
                continue
            what = f"{label[source]}{', ' + how if source != 'brep' else ''}"
            what += f" {angle:g} deg" if angle else ""
            if source == "surface" and how == "reparametrized" and angle < NO_FEATURES:
                patches, squares = _feature_patches(part, size, angle)
                if patches > config.TET_FEATURE_PATCH_SHARE * squares:
                    failures.append(
                        f"{what}: not tried, its feature edges cut it into {patches:,} "
                        f"patches, more than {config.TET_FEATURE_PATCH_SHARE:g} x its area in "
                        f"squares of the size ({squares:,.0f}): noise at this size"
                    )
                    continue
            got = []
            for k, file in enumerate(sources):
                piece = f" piece {k + 1} of {len(sources)}" if len(sources) > 1 else ""
                for algo in order:
                    if time.monotonic() >= deadline:
                        break
                    if progress is not None:
                        progress(f"gmsh, {what}{piece}, {algo}", step, len(surfaces))
                    try:
                        got.append(
                            run_isolated(
                                _gmsh_tets,
                                str(file),
                                size,
                                how,
                                angle,
                                algo,
                                timeout=max(1e-3, min(timeout, deadline - time.monotonic())),
                                what=f"gmsh ({what}{piece}, {algo})",
                            )
                        )
                        break
                    except ExternalTimeout as exc:  # hung: the next surface, not algorithm
                        failures.append(str(exc))
                        break
                    except ExternalCrash as exc:  # gmsh itself died: the next way
                        failures.append(str(exc))
                    except _GmshFailure as exc:
                        failures.append(f"{what}{piece}, {algo}: {exc}")
                        if exc.stage == "surface":
                            break  # the next surface strategy, not the next 3-D algorithm
                if len(got) <= k:
                    break  # a piece failed: the next strategy
            if len(got) < len(sources):
                if source == "brep" and len(failures) > tried:
                    brep_failure = failures[tried]
                continue
            if source != "brep" and brep_failure:
                warnings.warn(
                    f"{part.name}: gmsh could not mesh the B-rep ({brep_failure}); the "
                    f"tetrahedra come from its triangulated surface ({what}, {algo})",
                    LatticeWarning,
                    stacklevel=2,
                )
            n, vol = inputs.dropped
            if source == "resampled" and n:
                warnings.warn(
                    f"{part.name}: the tetrahedra come from its surface resampled at "
                    f"{inputs.spacing:.3g} mm; {n} piece(s) of it with {vol:.3g} mm^3 in all "
                    f"({100 * vol / max(part.volume, 1e-300):.2g} % of the part), each smaller "
                    f"than one tetrahedron of edge {size:.3g} mm, were left out",
                    LatticeWarning,
                    stacklevel=2,
                )
            return (*_joined([_compact(*g) for g in got]), source)
    raise PartError(
        f"{part.name}: gmsh could not mesh the part: "
        + "; ".join(failures)
        + "; a lattice of cells fills it without tetrahedra (--method voxel, the default: "
        "--fill conform follows its walls as a tet lattice does)"
    )


def _feature_patches(part: Part, size: float, angle: float) -> tuple[int, float]:
    """(patches, squares): how many pieces the edges of ``part``'s surface whose faces meet
    at more than ``angle`` degrees cut it into, and its area over ``size`` squared.

    gmsh's ``classifySurfaces`` makes those pieces the surfaces it re-parametrises: on a
    noisy scan thousands, far below the size (it then fails after tens of seconds, "Wrong
    topology of boundary mesh"); on a CAD mesh a few, each many squares of the size.
    """
    import trimesh

    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    smooth = mesh.face_adjacency[mesh.face_adjacency_angles <= math.radians(angle)]
    labels = trimesh.graph.connected_component_labels(smooth, node_count=len(mesh.faces))
    return int(labels.max()) + 1, float(mesh.area / size**2)


class _GmshFailure(Exception):
    """gmsh failed at ``stage`` ("surface" or "volume"). Raised in the child process of
    :func:`run_isolated` and pickled back: its ``args`` are both (an exception whose
    ``__init__`` takes more than its ``args`` cannot be unpickled, and the pool then reports
    the child as crashed, losing the message and the stage)."""

    def __init__(self, message: str, stage: str) -> None:
        super().__init__(message, stage)
        self.message = message
        self.stage = stage

    def __str__(self) -> str:
        return self.message


class _GmshInputs:
    """The files gmsh meshes for :func:`tet_mesh`'s strategies, made once each: the fused
    B-rep, the part's surface, or its resampled surface; a surface is written one file per
    outer shell (with the cavities it holds), since gmsh meshes one volume per surface loop.

    Pieces of the resampled surface smaller than one regular tetrahedron of edge ``size``
    (where the part is thinner than the spacing, e.g. the teapot's handle breaks into
    bubbles) are left out and counted in ``dropped`` (count, volume mm^3): meshed with
    the rest, gmsh found no tetrahedra in the volume at all.
    """

    def __init__(self, part: Part, size: float) -> None:
        self.part = part
        self.size = size
        self.spacing = size / 1.5
        self.dropped: tuple[int, float] = (0, 0.0)
        self._made: dict[str, list[Path] | None] = {}

    def files(self, source: str, tmp: Path) -> list[Path] | None:
        if source not in self._made:
            if source == "brep":
                brep = _brep_file(self.part, tmp)
                self._made[source] = None if brep is None else [brep]
            else:
                surf = self.part
                if source == "resampled":
                    surf = _resampled(self.part, self.spacing)
                small = self.size**3 / (6 * math.sqrt(2)) if source == "resampled" else 0.0
                groups, dropped = _shell_groups(surf, min_volume=small)
                if source == "resampled":
                    self.dropped = dropped
                paths = []
                for k, g in enumerate(groups):
                    paths.append(tmp / f"{source}_{k}.stl")
                    _write_stl(g, paths[-1])
                self._made[source] = paths
        return self._made[source]


def _shell_groups(part: Part, *, min_volume: float = 0.0) -> tuple[list[Part], tuple[int, float]]:
    """The part's closed shells grouped into solids: each outer shell (positive volume) with
    the cavity shells (negative volume) it holds, as one Part; shells whose volume is under
    ``min_volume`` (mm^3, in absolute value) are left out. Returns the groups (the part
    itself when it is one shell) and (shells left out, their volume)."""
    from conformal.part import _components

    v, f = part.vertices, part.faces
    comps = _components(f, len(v))
    if len(comps) == 1:
        return [part], (0, 0.0)
    vols = np.array([signed_volume(v, f[c]) for c in comps])
    keep = np.abs(vols) >= min_volume
    dropped = (int((~keep).sum()), float(np.abs(vols[~keep]).sum()))
    outer = [i for i in np.flatnonzero(keep).tolist() if vols[i] > 0]
    inner = [i for i in np.flatnonzero(keep).tolist() if vols[i] < 0]
    faces: dict[int, list[NDArray[np.int64]]] = {i: [f[comps[i]]] for i in outer}
    for i in inner:  # a cavity goes with the smallest outer shell holding a vertex of it
        p = v[f[comps[i][0], 0]][None]
        holders = [j for j in outer if Part(v, f[comps[j]]).contains(p)[0]]
        if holders:
            faces[min(holders, key=lambda j: vols[j])].append(f[comps[i]])
    groups = [Part(v, np.concatenate(faces[i]), name=part.name) for i in outer]
    return groups or [part], dropped


def _joined(
    meshes: list[tuple[NDArray[np.float64], NDArray[np.int64]]],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The (nodes, tets) of separately meshed solids as one mesh (no nodes shared)."""
    if len(meshes) == 1:
        return meshes[0]
    offsets = np.cumsum([0] + [len(n) for n, _ in meshes[:-1]])
    nodes = np.concatenate([n for n, _ in meshes])
    tets = np.concatenate([t + o for (_, t), o in zip(meshes, offsets, strict=True)])
    return nodes, tets


def _gmsh_tets(
    source: str, size: float, how: str, angle: float, algorithm: str
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """One gmsh run on a file (run in a child process): node tags (N,), coordinates (N, 3),
    tetrahedra (T, 4) as node tags.

    gmsh's boundary recovery prints its debugging (``Found two duplicated facets``, ``el1 =
    np = ...``: 856 lines on kcl_enclosure) with C ``printf``, past ``General.Terminal``;
    standard output is captured for the run, so none of it reaches the user's terminal.
    """
    from lattice_cad.occ_impl.quiet import c_stdout_captured

    with c_stdout_captured():
        return _gmsh_tets_run(source, size, how, angle, algorithm)


def _gmsh_tets_run(
    source: str, size: float, how: str, angle: float, algorithm: str
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    import gmsh

    if gmsh.isInitialized():
        raise RuntimeError("gmsh is already initialised in this process; finalise it first")
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    # gmsh's initialize resets SIGPIPE to the default action (terminate): Python ignores it
    # and reports EPIPE instead, and a process that later writes to a closed pipe or socket
    # (a Dask client, a pool's pipe) would die silently with status 141
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    stage = "surface"
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.logger.start()
        gmsh.model.add("part")
        if how == "brep":
            gmsh.model.occ.importShapes(source)
            gmsh.model.occ.synchronize()
        else:
            gmsh.merge(source)
            if how == "reparametrized":
                gmsh.model.mesh.classifySurfaces(math.radians(angle), True, True, math.pi)
                gmsh.model.mesh.createGeometry()
            else:  # the triangles as they are (resampled or the part's), as the boundary
                gmsh.model.mesh.createTopology()
            loop = gmsh.model.geo.addSurfaceLoop([t for _, t in gmsh.model.getEntities(2)])
            gmsh.model.geo.addVolume([loop])
            gmsh.model.geo.synchronize()
        vols = [t for _, t in gmsh.model.getEntities(3)]
        if not vols:
            raise _GmshFailure("no volume to mesh", stage)
        gmsh.option.setNumber("Mesh.MeshSizeMax", float(size))
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * float(size))
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        # the size asked, not the input's: a mesh part's re-parametrised points carry the
        # spacing of its triangles (a fine scan would give struts a fifth of ``size``, most
        # of them too short for the radius), and extending boundary sizes into the volume
        # would carry it inside. A B-rep's points carry no size, but with sizes from points
        # gmsh meshed a cone with a sharp apex at 0.68 of the size asked (3,686 nodes
        # against 789; HXT failed on it, the frontal algorithm took 8.6 s); on 28 of 30
        # other STEP parts the tetrahedra are the same without (CTC-02: 4,356 -> 4,252
        # nodes; the spanner: the same 261 nodes, edges 0.48 -> 0.51 of the size, median)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1 if how == "brep" else 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        if how == "brep":
            # the size asked on small round and curved features too: gmsh's defaults put at
            # least 7 nodes on a circle (in proportion on an arc) and 3 on any other curve,
            # so a 1 mm fillet's edges carry nodes a fraction of the size apart, and the
            # struts between them must be thinned (a block with 96 fillets, size 4 mm: 6,450
            # of 11,703 struts below 0.7 r, 41 of 8,934 with these; GE Table 5: 24 -> 0)
            gmsh.option.setNumber("Mesh.MinimumCirclePoints", config.TET_MIN_CIRCLE_POINTS)
            gmsh.option.setNumber("Mesh.MinimumCurvePoints", config.TET_MIN_CURVE_POINTS)
        gmsh.option.setNumber("Mesh.Algorithm3D", _ALGO[algorithm])
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(2)
        stage = "volume"
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        etypes, _, enodes = gmsh.model.mesh.getElements(3)
        tets = [
            np.asarray(n, dtype=np.int64) for t, n in zip(etypes, enodes, strict=True) if t == 4
        ]
        if not tets or not sum(len(t) for t in tets):
            raise _GmshFailure(f"no tetrahedra in volume(s) {vols}", stage)
        tags = np.asarray(tags, dtype=np.int64)
        tet = np.concatenate(tets).reshape(-1, 4)
        stray = ~np.isin(tet, tags)
        if stray.any():
            # a tetrahedron on a node gmsh does not list (delaunay on a tapered wing's
            # surface re-parametrised at 40 deg, made outside shared/data: 38 corners on
            # node 7688 of 315 listed): the mesh is broken; the next way is tried
            rows = np.flatnonzero(stray.any(axis=1))
            raise _GmshFailure(
                f"{len(rows)} tetrahedra use nodes gmsh does not list (e.g. node "
                f"{int(tet[stray][0])} of tetrahedron {int(rows[0])}; {len(tags)} nodes listed)",
                stage,
            )
        return tags, np.asarray(coords, dtype=np.float64).reshape(-1, 3), tet
    except _GmshFailure:
        raise
    except Exception as exc:  # gmsh raises plain Exceptions with its message
        log = [m for m in gmsh.logger.get() if "Error" in m][-2:]
        detail = "; ".join(m for m in log if m.split(": ", 1)[-1] not in str(exc))
        raise _GmshFailure(f"{exc}{'; ' + detail if detail else ''}", stage) from None
    finally:
        try:
            gmsh.logger.stop()
        finally:
            gmsh.finalize()


def _compact(
    tags: NDArray[np.int64], xyz: NDArray[np.float64], tet_tags: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Nodes used by the tetrahedra and the tetrahedra as 0-based indices into them."""
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


def _resampled(part: Part, h: float) -> Part:
    """The part's surface re-triangulated at spacing ``h``: the zero level of its signed
    distance on a grid (exact near the surface), by marching tetrahedra. A clean, even
    boundary for gmsh when a scanned or dense mesh cannot be re-parametrised."""
    from scipy.ndimage import binary_dilation, binary_erosion

    from conformal.skin import _GRID_SHIFT, marching_tets

    pad = 2 * h
    # off the round positions a CAD part's faces sit on: a vertical ray of the inside test
    # along a face would be ambiguous
    origin = part.bounds[0] - pad + _GRID_SHIFT * h
    dims = np.ceil((part.size + 2 * pad) / h).astype(np.int64) + 1
    inside = part.grid_contains(origin, np.full(3, h), dims)
    field = np.where(inside, 2.0 * h, -2.0 * h)
    near = np.argwhere(
        binary_dilation(inside, iterations=2) & ~binary_erosion(inside, iterations=2)
    )
    d = part.distance(origin + near * h, max_distance=4 * h)
    sign = np.where(inside[tuple(near.T)], 1.0, -1.0)
    field[tuple(near.T)] = sign * np.where(np.isfinite(d), d, 2 * h)
    v, f = marching_tets(field, origin, h)
    return Part(v, f, name=part.name)


def _write_stl(part: Part, path: Path) -> None:
    import trimesh

    trimesh.Trimesh(part.vertices, part.faces, process=False).export(str(path))


def tet_edges(tets: NDArray[np.int64]) -> NDArray[np.int64]:
    """(M, 2) int64: the distinct edges of (T, 4) tetrahedra, ``[:, 0] < [:, 1]``, sorted."""
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    e = np.sort(tets[:, pairs].reshape(-1, 2), axis=1)
    return unique_rows(e)


def tet_lattice(
    part: Part,
    size: float = config.DEFAULT_CELL_SIZE,
    radius: RadiusSpec = config.DEFAULT_RADIUS,
    *,
    algorithm: Algorithm = "hxt",
    min_radius: float | None = None,
    fit: FitMode = "shrink",
    repair: bool = True,
    tolerance: float = config.THIN_TOLERANCE,
    return_report: bool = False,
    segments: int = config.DEFAULT_SEGMENTS,
    profile: Profile = config.DEFAULT_PROFILE,
    progress: Callable[[str, int, int], None] | None = None,
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
    repair : bool
        First change the graph where struts meet at angles too small for the radius
        (:func:`conformal.radius.repair_graph`: short struts collapsed, others dropped,
        the graph kept connected and its surface nodes in place), so that no strut is
        thinner than ``tolerance`` times the radius asked; the report counts what
        changed (``merged_nodes``, ``removed_short`` = dropped struts, ``radii_reduced``).
    tolerance : float
        Smallest fraction of the asked radius a strut may be thinned to.
    return_report : bool
        Also return a :class:`~conformal.voxel.BuildReport`.
    segments, profile
        The profile polygons the graph will be stitched with (as in
        :func:`conformal.voxel_lattice`): the repair and the fit are for them (P = 3 or 4
        needs thinner struts, or more repair, than the default P = 6).
    progress : callable, optional
        ``progress(stage, done, total)``: which gmsh attempt runs (:func:`tet_mesh`), then
        the graph repair.

    Returns
    -------
    LatticeGraph, or (LatticeGraph, BuildReport)

    Raises
    ------
    PartError
        gmsh failed (its message and the volume tags are included).
    FitError
        Some struts cannot be stitched even at a tenth of the radius.
    FillError
        The radius asked is too thick for the part, and the fit would thin most struts
        beyond ``tolerance`` (:func:`conformal.voxel.refuse_too_thick`; the message says
        what radius fits).

    Warns
    -----
    LatticeWarning
        Some struts had to be made thinner than ``tolerance`` times the radius even after
        the repair (how many and where; ``report.thinned_beyond_tolerance``).
    """
    if not isinstance(part, Part):
        raise TypeError(f"part must be a conformal.Part (see load_part), got {type(part).__name__}")
    segments, profile = check_stitch_profile(segments, profile)
    rep = BuildReport()
    asked = radius
    t0 = time.perf_counter()
    first: BrepOrder = "brep"
    crowd = _brep_crowding(part, size)
    if crowd is not None and crowd[0] > config.TET_BREP_CROWDING * crowd[1]:
        first = "surface"
    nodes, tets, used = _tet_mesh(part, size, algorithm=algorithm, progress=progress, brep=first)
    if crowd is not None and first == used == "surface":
        warnings.warn(
            f"{part.name}: the edges of its B-rep's faces would crowd the tetrahedra's nodes "
            f"({crowd[0]:,} nodes on them, where about {crowd[1]:,.0f} cover its surface at "
            f"size {size:.3g}): the tetrahedra come from its triangulated surface, re-meshed "
            "at the size",
            LatticeWarning,
            stacklevel=2,
        )
    rep.seconds["mesh"] = time.perf_counter() - t0
    if progress is not None:
        progress("graph repair and radii", 0, 1)
    t0 = time.perf_counter()
    if not repair:
        edges = tet_edges(tets)
    else:
        nodes, edges, fitted, fix, r = _repaired(nodes, tets, radius, tolerance, segments, profile)
        if used == "brep" and fix.unfit > config.TET_RETRY_THIN_SHARE * len(edges):
            # struts thinned where the part is thick for the size: the B-rep's small faces
            # crowd the nodes (an M6 screw's thread: 1,047 of 6,296 struts beyond the
            # tolerance; from its triangulated surface 47 of 5,759); the surface is tried,
            # and the lattice with the smaller share of such struts kept
            thin = fitted.min(axis=1) < tolerance * float(np.max(r)) * (1 - 1e-9)
            _, local = _thin_ends(part, nodes, edges, thin, size)
            other = (
                _surface_try(part, size, algorithm, radius, tolerance, segments, profile)
                if np.mean(local < THIN_FOR_TETS * size) < 0.5
                else None
            )
            if other is not None and other[3].unfit * len(edges) < fix.unfit * len(other[1]):
                warnings.warn(
                    f"{part.name}: the tetrahedra of its B-rep left {fix.unfit:,} of "
                    f"{len(edges):,} struts thinner than {tolerance:g} x the radius asked, "
                    f"those of its triangulated surface (re-meshed at the size) "
                    f"{other[3].unfit:,} of {len(other[1]):,}: the latter are used",
                    LatticeWarning,
                    stacklevel=2,
                )
                nodes, edges, fitted, fix, r = other
                used = "surface"
        rep.merged_nodes, rep.removed_short = fix.merged, fix.dropped
        rep.radii_reduced = fix.thinned
        if fix.unfit:
            where = ", ".join("(" + ", ".join(f"{c:.4g}" for c in p) + ")" for p in fix.where[:3])
            warnings.warn(
                f"{fix.unfit} strut(s) of the tet lattice of {part.name} had to be made thinner "
                f"than {tolerance:g} x the radius asked even after the graph repair "
                f"({fix.merged} struts collapsed, {fix.dropped} dropped), e.g. at {where}"
                + _thin_advice(
                    part, nodes, edges, fitted, r, size, tolerance, from_brep=used == "brep"
                ),
                LatticeWarning,
                stacklevel=2,
            )
        rep.thinned_beyond_tolerance = fix.unfit
        radius = fitted
        if min_radius is None:  # the floor is relative to the radius asked, not the fitted one
            min_radius = 0.1 * float(np.min(r))
    graph = _finish(nodes, edges, radius, min_radius, fit, rep, segments=segments, profile=profile)
    if repair:
        rep.radii_reduced = max(rep.radii_reduced, fix.thinned)
    # the radius asked too thick for the part, and most struts thinned far below it:
    # refused, as the voxel method's fills refuse it
    refuse_too_thick(
        part, graph.nodes, graph, asked, rep, h=np.full(3, size), fill="conform", fitted=False
    )
    rep.seconds["fit"] = time.perf_counter() - t0
    return (graph, rep) if return_report else graph


def _brep_crowding(part: Part, size: float) -> tuple[int, float] | None:
    """(nodes on the edges of the B-rep's faces at ``size``, nodes of its surface meshed
    at ``size``) for a B-rep part, or None (a mesh part, or OCCT could not measure it).

    gmsh meshing a B-rep puts a node on every vertex and every ``size`` along every edge
    of its faces (:func:`lattice_cad.occ_impl.shapes.edge_nodes`); a surface meshed at
    ``size`` has about one node per two equilateral triangles of that edge. A helical
    gear whose flanks are 744 narrow B-spline faces (made outside shared/data): 4,583
    against 1,001 at size 3.47; the shared STEP parts at the benchmark's size: 0.25-2.5.
    """
    if part.shape is None:
        return None
    from lattice_cad.core.errors import OCCTFailure
    from lattice_cad.occ_impl import shapes as _occ

    try:
        forced = sum(_occ.edge_nodes(s, size) for s in part.shape)
    except OCCTFailure:
        return None
    return forced, float(abs(part.area) / (size * size * math.sqrt(3.0) / 4.0) / 2.0)


def _surface_try(
    part: Part,
    size: float,
    algorithm: Algorithm,
    radius: RadiusSpec,
    tolerance: float,
    segments: int,
    profile: Profile,
) -> tuple[Any, ...] | None:
    """(nodes, edges, fitted radii, repair, radii asked) of the tet lattice of a B-rep
    part's triangulated surface (its B-rep not tried), or None when gmsh fails on it."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)
            nodes, tets, _ = _tet_mesh(part, size, algorithm=algorithm, brep="no-brep")
    except PartError:
        return None
    return _repaired(nodes, tets, radius, tolerance, segments, profile)


def _repaired(
    nodes: NDArray[np.float64],
    tets: NDArray[np.int64],
    radius: RadiusSpec,
    tolerance: float,
    segments: int,
    profile: Profile,
) -> tuple[Any, ...]:
    """(nodes, edges, fitted radii, repair report, radii asked per tet edge): the graph of
    a tet mesh repaired by :func:`conformal.radius.repair_graph`."""
    edges = tet_edges(tets)
    r = resolve_radii(radius, nodes, edges)
    nodes, edges, fitted, fix = repair_graph(
        nodes, edges, r, surface=boundary_nodes(tets, len(nodes)), tolerance=tolerance,
        segments=segments, profile=profile,
    )  # fmt: skip
    return nodes, edges, fitted, fix, r


def _thin_ends(
    part: Part, nodes: NDArray[np.float64], edges: NDArray[np.int64], thin: Any, size: float
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The ends of the struts ``thin`` ((M,) bool) and the part's local thickness about each
    (:func:`_local_thickness`): where it is at most ``THIN_FOR_TETS`` times ``size``, the
    part is thin for tetrahedra of that size, whatever their input."""
    ends = np.unique(edges[thin])
    return ends, _local_thickness(part, nodes[ends], size)


def _thin_advice(
    part: Part,
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    fitted: NDArray[np.float64],
    asked: NDArray[np.float64],
    size: float,
    tolerance: float,
    *,
    from_brep: bool = True,
) -> str:
    """The end of the warning about struts thinned beyond ``tolerance``: how thin (for one
    radius asked), and what helps (``from_brep``: the tetrahedra came from the part's
    B-rep, not from a surface gmsh re-meshed):

    - where the part is at most ``THIN_FOR_TETS`` times ``size`` thick about most of
      their ends (its greatest thickness within ``size`` of the end,
      :func:`_local_thickness`), it is thin for tetrahedra of that size: they have no nodes
      inside it, lie flat between its faces, their struts meet at small angles, and a
      larger size makes that worse, not better (the spanner, the sheet-metal bracket,
      box_sides; the hammer scan, 0.64 mm thick at size 0.55);
    - else, where most of their ends lie on the part's surface, its small features
      (thread teeth, chamfers, fillets, small faces, smaller than ``size``) are the cause:
      the tetrahedra follow the edges of its faces, and their nodes crowd there (a STEP M10
      bolt's thread and 0.8 mm chamfer: 1,068 of 2,053 struts, said to be "thin for
      tetrahedra" before); for a mesh part (no faces), the surface gmsh re-meshed, whose
      triangles come out shorter than the size where it curves or is rough.
    """
    r = np.asarray(asked, dtype=np.float64)
    if not r.size or float(np.ptp(r)) > 1e-9 * float(r.max()):
        return "; a larger size or a thinner radius avoids it"
    r0 = float(r.max())
    ratio = fitted.min(axis=1) / r0
    thin = ratio < tolerance * (1 - 1e-9)
    if not thin.any():
        return "; a larger size or a thinner radius avoids it"
    ends, local = _thin_ends(part, nodes, edges, thin, size)
    near = 0.05 * size
    on = float(np.mean(part.distance(nodes[ends], max_distance=near) <= near))
    out = (
        f" (median {float(np.median(ratio[thin])):.2g} x, thinnest {float(ratio.min()):.2g} x); "
        f"{100 * on:.0f} % of their ends lie on the part's surface"
    )
    flat = float(np.mean(local < THIN_FOR_TETS * size))
    if flat < 0.5 and on < 0.8:
        # neither cause dominates (the hammer and the dragon scans came here, when their
        # tetrahedra were bounded by a resampled surface's triangles: 1,380 of 1,382 and
        # 3,858 of 3,901 struts; the conform fill thinned 57 of 663 and 57 of 3,128)
        return out + (
            "; a larger size or a thinner radius avoids it, and the voxel method's conform "
            "fill (--fill conform) often thins far fewer struts"
        )
    if flat >= 0.5:
        return out + (
            f", where it is at most {THIN_FOR_TETS:g} x the size thick (median "
            f"{float(np.median(local)):.3g} mm): the part is thin for tetrahedra of size "
            f"{size:.3g}, which have no nodes inside it there and lie flat between "
            "its faces with struts meeting at small angles (a larger size makes that worse, a "
            "thinner radius helps less than it seems); the voxel method's conform fill "
            "(--fill conform) thins far fewer struts there"
        )
    length = np.linalg.norm(nodes[edges[thin, 1]] - nodes[edges[thin, 0]], axis=1)
    # a mesh part has no faces whose edges the nodes follow: its surface is re-meshed (a
    # noisy capsule scan: surface edges median 0.68 x size on its end cap, 0.85 elsewhere,
    # inside 1.46; every strut under 0.3 x size on the surface)
    cause = (
        "the part's small features (teeth, chamfers, fillets, small faces) crowd the "
        "tetrahedra's nodes, which follow the edges of its faces (a smaller size helps little)"
        if part.shape is not None and from_brep
        else "the surface gmsh re-meshed for the tetrahedra crowds their nodes there (where "
        "the surface curves or is rough, or has features smaller than the size, its new "
        "triangles are shorter than the size)"
    )
    return out + (
        f", {100 * (1 - flat):.0f} % of them where the part is thicker than the size {size:.3g} "
        f"(median strut {float(np.median(length)):.2g} mm long): {cause}; the voxel method's "
        "conform fill (--fill conform) thins far fewer struts there"
    )


def _local_thickness(part: Part, points: NDArray[np.float64], size: float) -> NDArray[np.float64]:
    """(P,) float64: the part's greatest thickness (twice the greatest depth on its depth
    grid, :meth:`Part._depth_grid`) within a cube of half-width ``size`` about each of the
    (P, 3) points; 0 where the grid has no point inside."""
    from scipy.ndimage import maximum_filter

    grid = part._depth_grid(96)
    if grid is None:
        return np.zeros(len(points))
    origin, h, depth = grid
    k = max(1, int(np.ceil(size / h)))
    widest = maximum_filter(depth, size=2 * k + 1, mode="constant", cval=0.0)
    idx = np.rint((np.asarray(points, dtype=np.float64) - origin) / h).astype(np.int64)
    idx = np.clip(idx, 0, np.array(depth.shape) - 1)
    return 2.0 * widest[idx[:, 0], idx[:, 1], idx[:, 2]]


def boundary_nodes(tets: NDArray[np.int64], n_nodes: int) -> NDArray[np.bool_]:
    """(N,) bool: nodes on the boundary of a tet mesh (on a face used by one tet only)."""
    faces = np.sort(tets[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3), axis=1)
    uniq, count = unique_rows(faces, return_counts=True)
    out = np.zeros(n_nodes, dtype=bool)
    out[uniq[count == 1].ravel()] = True
    return out
