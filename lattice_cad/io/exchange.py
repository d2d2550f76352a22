"""Readers and writers of meshes, graphs and beam lattices (the suffix table is
:mod:`lattice_cad.core.formats`).

Every file is written atomically (:func:`lattice_cad.core.atomic.atomic_write`): a failed or
interrupted export never leaves a half-written file behind. Formats that cannot hold the
result are refused with :class:`ExportError` (binary STL counts triangles in 32 bits; lib3mf
indexes with signed 32-bit integers), and files estimated above ``config.WARN_BYTES`` (2 GB,
where many slicers fail) raise an :class:`ExportWarning`.

Every writer is deterministic: the same input gives the same bytes (3MF UUIDs are derived
from the content; graph ``.npz`` archives carry a fixed timestamp).

===========  ===========================================================  ==============
format       content                                                      written with
===========  ===========================================================  ==============
STL          binary STL of the mesh                                       numpy (core)
3MF          3MF core mesh, or the 3MF Beam Lattice extension (beams      lib3mf
             with per-end radii, balls at the nodes, the part as clipping
             mesh) with the printable mesh as the triangles for readers
             without the extension (or beam-only: tiny, few readers)
PLY, OBJ     binary PLY, Wavefront OBJ                                    trimesh
JSON, NPZ    the lattice graph (exact)                                    LatticeGraph
STEP         exact B-rep solids                                           OpenCascade
===========  ===========================================================  ==============
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import tempfile
import uuid
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.atomic import atomic_write, check_target, output_error
from lattice_cad.core.errors import (
    BeamOnlyWarning,
    ExportError,
    ExportWarning,
    InputFileError,
    LatticeWarning,
    MissingFileError,
    OutputError,
)
from lattice_cad.core.formats import Kind, format_for, suffixes
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.core.mesh import Mesh, mesh_arrays, stl_size, weld
from lattice_cad.core.resources import require_disk, require_memory

__all__ = [
    "ExportError",
    "ExportWarning",
    "BeamOnlyWarning",
    "BEAM_UNAWARE_READERS",
    "MESH_SUFFIXES",
    "GRAPH_SUFFIXES",
    "estimate_bytes",
    "check_limits",
    "save_mesh",
    "save_graph",
    "save_beam_lattice",
    "read_mesh",
    "check_mesh_file",
    "read_beam_lattice",
    "single_precision",
    "collapse_faces",
]

#: Mesh formats written by :func:`save_mesh`.
MESH_SUFFIXES = suffixes(Kind.MESH)
#: Graph formats written by :func:`save_graph`.
GRAPH_SUFFIXES = suffixes(Kind.GRAPH)


# ------------------------------------------------------------------ precision
def single_precision(mesh: Any, *, name: str = "mesh") -> tuple[Mesh, int]:
    """The mesh as STL and 3MF store it: vertices rounded to float32, still a closed solid.

    Rounding can merge vertices (they are welded) and flatten triangles; each flattened
    one loses its shortest edge (the two vertices merged), so a mesh the product built is
    never refused at write time. Nothing changes for a mesh that survives the
    rounding as it is (the usual case), except the rounding itself.

    Returns
    -------
    mesh : Mesh
        Float32-exact vertices (stored as float64).
    repaired : int
        How many triangles lost a vertex or became flat in the rounding (0 usually);
        when nonzero the caller should run the full validity check, self-intersections
        included, before writing.

    Raises
    ------
    ExportError
        The geometry cannot be represented in single precision at all (struts far thinner
        than the float32 spacing at their coordinates); the message says where.
    """
    v, f = _arrays(mesh)
    require_memory(
        160 * len(v) + 120 * len(f),
        f"rounding {name} ({len(f):,} triangles) to single precision for STL/3MF",
        advice="use fewer or larger cells or fewer segments, or write a 3MF beam lattice",
    )
    v32 = v.astype(np.float32).astype(np.float64)
    v2, f2 = weld(v32, f)
    merged = len(f) - len(f2)  # triangles that lost a vertex to rounding
    from lattice_cad.io.rounding import cancel_opposite_faces, pinched_vertices, repair_rounded

    if len(v2) < len(v):  # fins thinner than a float32 step: two faces back to back
        v2, f2, cancelled = cancel_opposite_faces(v2, f2)
        merged += cancelled
    bad = _flat_triangles(v2, f2)

    if bad.any():
        v3, f3 = v2, f2
        v2, f2 = _collapse_flat(v2, f2)
        if _flat_triangles(v2, f2).any() or not _closed_manifold(f2) or len(f2) == 0:
            # caps flip their longest edge instead, pinched vertices are separated
            v2, f2 = repair_rounded(v3, f3)
    pinched = np.zeros(0, dtype=np.int64)
    if bad.any() or len(v2) < len(v):
        # vertices of two sheets less than a float32 step apart became one: separate them
        pinched = pinched_vertices(f2, len(v2))
        if len(pinched):
            where_pinch = v2[pinched[0]]
            v2, f2 = repair_rounded(v2, f2)
    if bad.any() or len(pinched):
        if _flat_triangles(v2, f2).any() or not _closed_manifold(f2) or len(f2) == 0:
            where = v32[f[np.flatnonzero(bad)[0]]].mean(axis=0) if bad.any() else where_pinch
            lo, hi = v.min(axis=0), v.max(axis=0)
            if np.abs(v).max() > 2.0 * float((hi - lo).max()):
                # moved to the origin, its coordinates (and their steps) would be smaller
                why = (
                    "the struts are too thin for coordinates this far from the origin: move "
                    "the lattice closer to the origin or use thicker struts"
                )
            else:  # (a coffee mug's skin at the origin was told to move, s34)
                step = float(np.spacing(np.float32(np.abs(where).max())))
                why = (
                    f"two of its surfaces lie closer there than a float32 step ({step:.2g} "
                    "mm), a fin or sliver too thin to be stored (it is near the origin "
                    "already: moving it would not help); use thicker struts, or other cell "
                    "sizes or skin thicknesses"
                )
            raise ExportError(
                f"{name}: {int(bad.sum())} triangle(s) collapse and {len(pinched)} vertex(es) "
                f"are pinched when coordinates are rounded to "
                f"single precision (as STL and 3MF store them), e.g. near "
                f"({where[0]:.6g}, {where[1]:.6g}, {where[2]:.6g}); {why}"
            )
    return Mesh(vertices=v2, faces=f2), merged + int(bad.sum()) + len(pinched)


def _collapse_flat(
    v: NDArray[np.float64], f: NDArray[np.int64], rounds: int = 20
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Collapse the shortest edge of every flat triangle until none is flat."""
    for _ in range(rounds):
        bad = np.flatnonzero(_flat_triangles(v, f))
        if not len(bad):
            break
        v, f = collapse_faces(v, f, bad)
    return v, f


def collapse_faces(
    v: NDArray[np.float64], f: NDArray[np.int64], which: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Collapse an edge of each face in ``which``: its shortest edge whose collapse keeps
    the surface 2-manifold, of an independent subset of them.

    The two vertices of the edge become one (the lower index, in place), which removes the
    face and its neighbour across that edge; unused vertices are dropped. An edge is
    collapsed only when its two vertices have no common neighbour but the two opposite
    corners of its faces (the link condition); otherwise the collapse would join two
    sheets of the surface in an edge or a vertex (a pinch no later collapse removes), and
    the face's next shorter edge is tried. No two collapses of one call touch each
    other's ring of neighbours, so each sees the mesh its condition was tested on; a
    face skipped is left for the caller's next round.
    vertices : (V, 3) float64, faces : (F, 3) int64, which : (K,) int64.
    """
    which = np.asarray(which, dtype=np.int64).reshape(-1)
    if not len(which):
        return v, f
    t = v[f[which]]
    lengths = np.stack([np.linalg.norm(t[:, (k + 1) % 3] - t[:, k], axis=1) for k in range(3)])
    order = np.argsort(lengths, axis=0, kind="stable")  # (3, K): edges shortest first
    # vertex -> faces (CSR) for the rings of the candidates only
    from lattice_cad.io._rounding_kernels import corners_by_vertex

    # a counting sort: np.argsort(corner_v, kind="stable") and its group offsets
    by_vertex, start = corners_by_vertex(np.ascontiguousarray(f.ravel(), dtype=np.int64), len(v))

    def ring_faces(x: int) -> NDArray[np.int64]:
        return by_vertex[start[x] : start[x + 1]] // 3

    def ring(x: int) -> set[int]:
        return set(f[ring_faces(x)].ravel().tolist()) - {x}

    target = np.arange(len(v))
    busy = np.zeros(len(v), dtype=bool)
    for i, face in enumerate(which.tolist()):
        for k in order[:, i].tolist():
            a, b = int(f[face, k]), int(f[face, (k + 1) % 3])
            if a == b or busy[a] or busy[b]:
                continue
            shared = ring_faces(a)
            shared = shared[(f[shared] == b).any(axis=1)]  # the faces on edge (a, b)
            if len(shared) != 2:
                continue
            opposite = set(f[shared].ravel().tolist()) - {a, b}
            ra, rb = ring(a), ring(b)
            if len(opposite) != 2 or (ra & rb) != opposite:
                continue
            busy[a] = busy[b] = True
            busy[list(ra | rb)] = True
            target[max(a, b)] = min(a, b)
            break
    f = target[f]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[keep]
    used = np.zeros(len(v), dtype=bool)
    used[f.ravel()] = True
    new_id = np.cumsum(used) - 1
    return v[used], new_id[f]


def collapse_folds(
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    pairs: NDArray[np.int64],
    zero_area: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Collapse (:func:`collapse_faces`) the zero-area faces and the smaller face of each
    self-intersecting pair: removes the needles booleans leave and the folds a
    simplification makes (a fold is a few faces), keeping the surface closed.

    vertices : (V, 3) float64, faces : (F, 3) int64, pairs : (P, 2) int64 face indices
    (e.g. ``fast_stitch.check(...).self_intersection_pairs``), zero_area : (Z,) int64.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    t = v[f[pairs]]  # (P, 2, 3, 3): only the faces of the pairs
    e1, e2 = t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :]
    area = np.linalg.norm(np.cross(e1, e2), axis=-1)
    smaller = np.where(area[:, 0] <= area[:, 1], pairs[:, 0], pairs[:, 1])
    which = np.union1d(np.asarray(zero_area, dtype=np.int64), smaller)
    return collapse_faces(v, f, which)


def _closed_manifold(f: NDArray[np.int64]) -> bool:
    """Every edge used exactly twice, once in each direction."""
    from lattice_cad.io._rounding_kernels import closed_oriented

    if len(f) == 0:
        return True
    f = np.ascontiguousarray(f, dtype=np.int64)
    return bool(closed_oriented(f, int(f.max()) + 1))


def _flat_triangles(v: NDArray[np.float64], f: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(F,) bool: triangles of zero area (exactly, in the coordinates given)."""
    from lattice_cad.io._rounding_kernels import flat_mask

    v = np.ascontiguousarray(v, dtype=np.float64)
    return flat_mask(v, np.ascontiguousarray(f, dtype=np.int64))


# ---------------------------------------------------------------- utilities
def _arrays(mesh: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices (V, 3) float64 and faces (F, 3) int64 of any mesh-like object."""
    arrays = mesh_arrays(mesh)
    if arrays is None:
        raise TypeError(
            f"cannot export a {type(mesh).__name__}: expected a mesh (vertices and faces), "
            "a manifold3d.Manifold or a (vertices, faces) tuple"
        )
    v, f = arrays
    v = np.ascontiguousarray(v, dtype=np.float64).reshape(-1, 3)
    f = np.ascontiguousarray(f, dtype=np.int64).reshape(-1, 3)
    return v, f


def estimate_bytes(fmt: str, n_vertices: int, n_faces: int, *, n_beams: int = 0) -> int:
    """Approximate size in bytes of a file of the given format.

    Exact for binary STL (``84 + 50 F``) and binary PLY; 3MF and OBJ are estimates
    (3MF is zip-compressed XML, about 12 bytes per vertex and 10 per triangle or beam).
    """
    s = fmt.lower().lstrip(".")
    if s == "stl":
        return stl_size(n_faces)
    if s == "ply":
        return 200 + 12 * n_vertices + 13 * n_faces
    if s == "obj":
        return 34 * n_vertices + 22 * n_faces
    if s == "3mf":
        return 1200 + 12 * n_vertices + 10 * n_faces + 14 * n_beams
    raise ValueError(f"no size estimate for {fmt!r}")


def check_limits(
    path: str | os.PathLike[str], n_vertices: int, n_faces: int, *, n_beams: int = 0
) -> int:
    """Refuse what a format cannot hold; warn above :data:`config.WARN_BYTES`.

    Returns
    -------
    int
        The estimated file size in bytes.

    Raises
    ------
    ExportError
        More than 2**32 - 1 triangles for STL, or more than 2**31 - 1 vertices,
        triangles or beams for 3MF (the message names the file and the counts).
    """
    p = Path(path)
    s = p.suffix.lower()
    if s == ".stl" and n_faces > config.STL_MAX_TRIANGLES:
        raise ExportError(
            f"{p.name}: {n_faces:,} triangles do not fit in a binary STL "
            f"(at most {config.STL_MAX_TRIANGLES:,}); save as a 3MF beam lattice or split the part"
        )
    if s == ".3mf":
        for what, n in (("vertices", n_vertices), ("triangles", n_faces), ("beams", n_beams)):
            if n > config.THREEMF_MAX:
                raise ExportError(
                    f"{p.name}: {n:,} {what} do not fit in a 3MF file "
                    f"(at most {config.THREEMF_MAX:,}); "
                    "use beam_lattice=True or split the part"
                )
    size = estimate_bytes(s, n_vertices, n_faces, n_beams=n_beams)
    if size > config.WARN_BYTES:
        warnings.warn(
            f"{p.name}: the file will be about {size / 1024**3:.1f} GiB; many slicers fail "
            "above 2 GB (consider a 3MF beam lattice, fewer segments or a coarser lattice)",
            ExportWarning,
            stacklevel=3,
        )
    return size


def writer_memory(fmt: str, n_vertices: int, n_faces: int) -> int:
    """Estimated peak memory (bytes) of :func:`save_mesh` beyond the mesh itself.

    STL is written in chunks of 2**20 triangles (about 200 bytes each while in flight);
    3MF copies the arrays to float32/uint32 and lib3mf holds its own model (about 60 bytes
    per vertex and per triangle); PLY and OBJ are built in memory by trimesh (twice the
    file for PLY, five times for OBJ's text).
    """
    s = fmt.lower().lstrip(".")
    if s == "stl":
        return 200 * min(n_faces, 1 << 20)
    if s == "3mf":
        return 60 * (n_vertices + n_faces)
    if s == "ply":
        return 2 * estimate_bytes("ply", n_vertices, n_faces) + 24 * (n_vertices + n_faces)
    return 5 * estimate_bytes("obj", n_vertices, n_faces) + 24 * (n_vertices + n_faces)


def _write_via_temp(path: Path, write: Any) -> None:
    """Let ``write(tmp_path)`` produce the file, then copy it atomically onto ``path``.

    Errors name ``path``, never the temp file (:class:`OutputError`).
    """
    check_target(path)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise output_error(path, exc) from None
    os.close(fd)
    try:
        try:
            write(tmp)
        except OSError as exc:
            raise output_error(path, exc) from None
        except Exception as exc:  # lib3mf's own exception type
            if type(exc).__name__ != "ELib3MFException":
                raise
            raise OutputError(
                f"cannot write {path}: lib3mf failed: {_strip_temp(str(exc), tmp, path)}"
            ) from None
        with atomic_write(path, "wb") as fh, open(tmp, "rb") as src:
            shutil.copyfileobj(src, fh, 1 << 22)
    finally:
        Path(tmp).unlink(missing_ok=True)


def _strip_temp(message: str, tmp: str, path: Path) -> str:
    return message.replace(tmp, str(path)).replace(Path(tmp).name, path.name)


# ------------------------------------------------------------------- lib3mf
def _lib3mf() -> tuple[Any, Any]:
    try:
        import lib3mf
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise ExportError(f"3MF export needs lib3mf (pip install lib3mf): {exc}") from None
    wrapper = lib3mf.get_wrapper()
    return lib3mf, wrapper


def _set_geometry(
    lib3mf: Any,
    mesh_obj: Any,
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    digest: Any = None,
) -> None:
    """``MeshObject.SetGeometry`` from numpy arrays without per-element Python objects.

    ``digest`` (a hashlib object), if given, is updated with the bytes written.
    """
    pos = np.ascontiguousarray(v, dtype=np.float32)
    tri = np.ascontiguousarray(f, dtype=np.uint32)
    if digest is not None:
        digest.update(np.array([len(pos), len(tri)], dtype=np.uint64).tobytes())
        digest.update(pos.tobytes())
        digest.update(tri.tobytes())
    pbuf = (lib3mf.Position * len(pos)).from_buffer(pos) if len(pos) else None
    tbuf = (lib3mf.Triangle * len(tri)).from_buffer(tri) if len(tri) else None
    w = mesh_obj._wrapper
    w.checkError(
        mesh_obj,
        w.lib.lib3mf_meshobject_setgeometry(
            mesh_obj._handle, ctypes.c_uint64(len(pos)), pbuf, ctypes.c_uint64(len(tri)), tbuf
        ),
    )


#: Namespace of the content-derived UUIDs in 3MF files (fixed: part of the file format).
_UUID_NAMESPACE = uuid.UUID("6f0b7c52-9d1e-4b7a-a3c8-4c1f0e2d9b35")

#: Readers reported not to open a 3MF whose built objects are beam lattices without
#: triangles (PrusaSlicer 2.5 measured: "Found item with invalid object id").
BEAM_UNAWARE_READERS = ("PrusaSlicer", "Bambu Studio", "Cura", "Windows 3D Viewer", "Netfabb")

_NO_FACES = np.zeros((0, 3), dtype=np.int64)


def _stable_uuid(digest: bytes, role: str) -> str:
    """A UUID derived from the file's content and the element's role (name-based, v5)."""
    return str(uuid.uuid5(_UUID_NAMESPACE, f"{digest.hex()}/{role}"))


def _set_uuids(model: Any, objects: list[tuple[Any, str]], items: list[Any], digest: bytes) -> None:
    """Replace lib3mf's random UUIDs (objects, build, build items) by content-derived ones,
    so that the same model gives the same file."""
    model.SetBuildUUID(_stable_uuid(digest, "build"))
    for obj, role in objects:
        obj.SetUUID(_stable_uuid(digest, f"object/{role}"))
    for k, item in enumerate(items):
        item.SetUUID(_stable_uuid(digest, f"item/{k}"))


#: Decimals lib3mf writes per coordinate. Its default (6) moves coordinates below 1 mm by up
#: to thousands of float32 steps (1e-6 mm); from 10 on, every coordinate is within one step
#: of the float32 value (lib3mf's formatter is not exact at any setting; measured, lib3mf 2.5).
THREEMF_DECIMALS = 10


def _write_model(lib3mf: Any, model: Any, path: Path) -> None:
    writer = model.QueryWriter("3mf")
    writer.SetDecimalPrecision(THREEMF_DECIMALS)

    def write(tmp: str) -> None:
        writer.WriteToFile(tmp)

    _write_via_temp(path, write)


def _save_3mf(path: Path, v: NDArray[np.float64], f: NDArray[np.int64], name: str) -> None:
    lib3mf, wrapper = _lib3mf()
    model = wrapper.CreateModel()
    model.SetUnit(lib3mf.ModelUnit.MilliMeter)
    mesh_obj = model.AddMeshObject()
    mesh_obj.SetName(name)
    digest = hashlib.sha256(f"mesh {name}".encode())
    _set_geometry(lib3mf, mesh_obj, v, f, digest)
    item = model.AddBuildItem(mesh_obj, wrapper.GetIdentityTransform())
    _set_uuids(model, [(mesh_obj, "mesh")], [item], digest.digest())
    _write_model(lib3mf, model, path)


# ---------------------------------------------------------------------- API
def save_mesh(mesh: Any, path: str | os.PathLike[str], *, name: str = "lattice") -> Path:
    """Write a triangle mesh; the format is chosen by the suffix.

    Parameters
    ----------
    mesh : fast_stitch.Mesh, manifold3d.Manifold, trimesh.Trimesh or (vertices, faces)
    path : path-like
        ``.stl`` (binary), ``.3mf`` (core mesh), ``.ply`` (binary) or ``.obj``.
    name : str
        Object name stored in 3MF files.

    Returns
    -------
    Path

    Raises
    ------
    ExportError
        Too many triangles for the format, or an STL whose triangles degenerate in
        single precision.
    ValueError
        For an unknown suffix.

    Warns
    -----
    ExportWarning
        When the file will be larger than 2 GB.
    """
    p = Path(path)
    fmt = format_for(p, Kind.MESH)
    v, f = _arrays(mesh)
    if len(f) == 0:
        raise ExportError(f"{p.name}: the mesh is empty (no triangles)")
    size = check_limits(p, len(v), len(f))
    check_target(p)
    require_memory(
        writer_memory(fmt.name, len(v), len(f)),
        f"writing {p.name} ({len(f):,} triangles)",
        advice="write STL (streamed in chunks) or a 3MF beam lattice instead",
    )
    require_disk(p, size, temp_copies=2 if fmt.name == "3mf" else 1)
    if fmt.name == "stl":
        m = mesh if isinstance(mesh, Mesh) else Mesh(vertices=v, faces=f)
        m.save(p)
    elif fmt.name == "3mf":
        _save_3mf(p, v, f, name)
    else:
        import trimesh

        tm = trimesh.Trimesh(vertices=v, faces=f, process=False)
        if fmt.name == "ply":
            data: bytes | str = trimesh.exchange.ply.export_ply(tm, encoding="binary")
        else:
            data = trimesh.exchange.obj.export_obj(tm, include_normals=False)
        if isinstance(data, str):
            with atomic_write(p, "w") as fh:
                fh.write(data)
        else:
            with atomic_write(p, "wb") as fh:
                fh.write(data)
    return p


def save_graph(graph: LatticeGraph, path: str | os.PathLike[str]) -> Path:
    """Write a graph as ``.json`` or ``.npz`` (see :meth:`LatticeGraph.save`)."""
    return graph.save(path)


def save_beam_lattice(
    graph: LatticeGraph,
    path: str | os.PathLike[str],
    *,
    mesh: Any = None,
    skin: Any = None,
    clip: Any = None,
    balls: bool = True,
    name: str = "lattice",
) -> Path:
    """Write a graph as a 3MF Beam Lattice, with or without triangles for other readers.

    The beam-lattice object always holds the beams (per-end radii, caps, balls). The Beam
    Lattice specification makes the extension *required* in the file and defines the
    object's solid as the union of its triangles and its beams, so the printable mesh of
    the lattice goes into the same object (``mesh=``): readers without the extension
    (PrusaSlicer 2.5 measured; Bambu Studio shares its reader) ignore the beams and slice
    the triangles, a beam-aware reader gets the triangles united with the round beams (the
    default stitched mesh has polygons of the circle's area, whose corners reach
    10 % of ``r`` beyond the beams at P = 6; a mesh stitched with
    ``profile="inscribed"`` lies inside them). Without ``mesh`` the file holds
    beams only: tiny, but most readers cannot open it (:class:`BeamOnlyWarning`).

    Parameters
    ----------
    graph : LatticeGraph
        Beams take the graph's per-end radii; nodes with a single strut get flat
        (butt) caps, the others spherical caps.
    path : path-like
        Must end in ``.3mf``.
    mesh : mesh-like, optional
        The printable triangle mesh of the lattice (``fast_stitch.Mesh``, Manifold,
        trimesh or ``(vertices, faces)``; with a skin, skin and lattice united), written
        as the triangles of the beam-lattice object. ``None`` writes a beam-only file.
    skin : mesh-like, optional
        A closed mesh written as a separate object of the build (the part's skin beside
        a beam-only lattice).
    clip : mesh-like, optional
        Closed mesh of the part: written as a separate mesh object (not in the build) and
        referenced as the lattice's clipping mesh (clip mode ``inside``), so a beam-aware
        printer trims the beams to the part. PrusaSlicer 2.5 and its forks refuse any
        3MF with an object outside the build ("Unable to find object"), so a file meant
        for them (``mesh=``) should not have one.
    balls : bool
        Put a ball at every node of degree >= 2, with the largest radius of the
        struts there (smooth joints).
    name : str
        Object name.

    Returns
    -------
    Path

    Raises
    ------
    ExportError
        An empty graph, too many vertices, triangles or beams for 3MF, or lib3mf refusing
        the model.

    Warns
    -----
    BeamOnlyWarning
        Without ``mesh``: the readers that cannot open a beam-only file.

    Notes
    -----
    The file is deterministic: every UUID lib3mf stores is derived from the content, so
    the same input gives the same bytes.
    """
    p = Path(path)
    format_for(p, Kind.BEAM_LATTICE)
    if graph.num_edges == 0:
        raise ExportError(f"{p.name}: the graph has no struts: nothing to write")
    graph.check_precision("float32")  # 3MF stores positions in single precision
    used = np.flatnonzero(graph.degree > 0)
    remap = np.full(graph.num_nodes, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    nodes = graph.nodes[used]
    edges = remap[graph.edges]
    tri_v, tri_f = _arrays(mesh) if mesh is not None else (np.zeros((0, 3)), _NO_FACES)
    skin_v, skin_f = _arrays(skin) if skin is not None else (np.zeros((0, 3)), _NO_FACES)
    clip_v, clip_f = _arrays(clip) if clip is not None else (np.zeros((0, 3)), _NO_FACES)
    if mesh is not None and len(tri_f) == 0:
        raise ExportError(f"{p.name}: the triangle mesh of the lattice is empty")
    if skin is not None and len(skin_f) == 0:
        raise ExportError(f"{p.name}: the skin mesh is empty")
    size = check_limits(
        p,
        len(nodes) + len(tri_v) + len(skin_v) + len(clip_v),
        len(tri_f) + len(skin_f) + len(clip_f),
        n_beams=len(edges),
    )
    check_target(p)
    require_memory(
        200 * len(edges) + 100 * len(nodes) + 100 * (len(tri_f) + len(skin_f) + len(clip_f)),
        f"writing the beam lattice {p.name} ({len(edges):,} beams)",
        advice="use fewer or larger cells",
    )
    require_disk(p, size, temp_copies=2)
    if mesh is None:
        warnings.warn(
            f"{p.name} holds beams only (3MF Beam Lattice, no triangles): readers without "
            f"the extension cannot open it ({', '.join(BEAM_UNAWARE_READERS)}); "
            "save with beam_lattice=True (CLI: --beam-lattice) to add the triangle mesh "
            "they read",
            BeamOnlyWarning,
            stacklevel=2,
        )
    lib3mf, wrapper = _lib3mf()
    model = wrapper.CreateModel()
    model.SetUnit(lib3mf.ModelUnit.MilliMeter)
    digest = hashlib.sha256(f"beam lattice {name} balls={balls}".encode())
    try:
        objects: list[tuple[Any, str]] = []
        clip_obj = None
        if clip is not None:
            clip_obj = model.AddMeshObject()
            clip_obj.SetName(f"{name} clipping mesh")
            _set_geometry(lib3mf, clip_obj, clip_v, clip_f, digest)
            objects.append((clip_obj, "clip"))
        skin_obj = None
        if skin is not None:
            skin_obj = model.AddMeshObject()
            skin_obj.SetName(f"{name} skin")
            _set_geometry(lib3mf, skin_obj, skin_v, skin_f, digest)
            objects.append((skin_obj, "skin"))
        obj = model.AddMeshObject()
        obj.SetName(name)
        # the triangles' vertices first, then the lattice nodes the beams refer to
        _set_geometry(lib3mf, obj, np.vstack([tri_v, nodes]), tri_f, digest)
        objects.append((obj, "lattice"))
        _set_beams(lib3mf, obj, graph, used, edges, len(tri_v), balls, digest)
        if clip_obj is not None:
            obj.BeamLattice().SetClipping(
                lib3mf.BeamLatticeClipMode.Inside, clip_obj.GetUniqueResourceID()
            )
        built = [o for o in (skin_obj, obj) if o is not None]
        items = [model.AddBuildItem(o, wrapper.GetIdentityTransform()) for o in built]
        _set_uuids(model, objects, items, digest.digest())
        _write_model(lib3mf, model, p)
    except lib3mf.ELib3MFException as exc:
        raise ExportError(f"{p.name}: lib3mf refused the beam lattice: {exc}") from None
    return p


def _set_beams(
    lib3mf: Any,
    obj: Any,
    graph: LatticeGraph,
    used: NDArray[np.int64],
    edges: NDArray[np.int64],
    offset: int,
    balls: bool,
    digest: Any,
    *,
    degree: NDArray[np.int64] | None = None,
    ball_at: NDArray[np.bool_] | None = None,
    ball_radius: NDArray[np.float64] | None = None,
) -> None:
    """The beams (and balls) of ``graph`` on ``obj``, whose vertex ``offset + i`` is the
    ``i``-th used node. used : (U,) int64 node ids, edges : (M, 2) int64 into ``used``;
    degree : (U,) int64, optional: the nodes' degrees in a larger lattice (a shard's part
    of it: caps and balls follow the whole lattice), default the graph's own.
    ball_at : (U,) bool, optional: which of the nodes of degree >= 2 get a ball here (a
    shard writes only the balls it owns, so that a seam node has one ball); ball_radius :
    (U,) float64, optional: their radii (the largest strut radius at the node in the
    whole lattice), default the largest of ``edges`` at the node."""
    bl = obj.BeamLattice()
    bl.SetMinLength(float(min(1e-4, 0.5 * graph.edge_lengths.min())))
    degree = graph.degree[used] if degree is None else np.asarray(degree)
    caps = np.where(
        degree[edges] >= 2,
        int(lib3mf.BeamLatticeCapMode.Sphere),
        int(lib3mf.BeamLatticeCapMode.Butt),
    ).astype(np.int32)
    beams = np.zeros(
        len(edges),
        dtype=np.dtype(
            {
                "names": ["idx", "rad", "cap"],
                "formats": [("<u4", (2,)), ("<f8", (2,)), ("<i4", (2,))],
                "offsets": [
                    lib3mf.Beam.Indices.offset,
                    lib3mf.Beam.Radii.offset,
                    lib3mf.Beam.CapModes.offset,
                ],
                "itemsize": ctypes.sizeof(lib3mf.Beam),
            }
        ),
    )
    beams["idx"] = edges + offset
    beams["rad"] = graph.radii
    beams["cap"] = caps
    for field in ("idx", "rad", "cap"):
        digest.update(np.ascontiguousarray(beams[field]).tobytes())
    bbuf = (lib3mf.Beam * len(beams)).from_buffer(beams)
    w = bl._wrapper
    w.checkError(
        bl, w.lib.lib3mf_beamlattice_setbeams(bl._handle, ctypes.c_uint64(len(beams)), bbuf)
    )
    if not balls:
        return
    inner = np.flatnonzero((degree >= 2) if ball_at is None else (degree >= 2) & ball_at)
    if not len(inner):
        return
    if ball_radius is None:
        rmax = np.zeros(len(used))
        np.maximum.at(rmax, edges.ravel(), graph.radii.ravel())
    else:
        rmax = np.asarray(ball_radius, dtype=np.float64)
    ball_arr = np.zeros(
        len(inner),
        dtype=np.dtype(
            {
                "names": ["idx", "rad"],
                "formats": ["<u4", "<f8"],
                "offsets": [lib3mf.Ball.Index.offset, lib3mf.Ball.Radius.offset],
                "itemsize": ctypes.sizeof(lib3mf.Ball),
            }
        ),
    )
    ball_arr["idx"] = inner + offset
    ball_arr["rad"] = rmax[inner]
    digest.update(ball_arr["idx"].tobytes() + ball_arr["rad"].tobytes())
    bl.SetBallOptions(lib3mf.BeamLatticeBallMode.Mixed, float(rmax[inner].min()))
    abuf = (lib3mf.Ball * len(ball_arr)).from_buffer(ball_arr)
    w.checkError(
        bl, w.lib.lib3mf_beamlattice_setballs(bl._handle, ctypes.c_uint64(len(ball_arr)), abuf)
    )


# ------------------------------------------------------------------ reading
def _read_3mf_model(path: Path) -> tuple[Any, Any]:
    lib3mf, wrapper = _lib3mf()
    model = wrapper.CreateModel()
    reader = model.QueryReader("3mf")
    try:
        reader.ReadFromFile(str(path))
    except lib3mf.ELib3MFException as exc:
        raise InputFileError(f"{path}: not a readable 3MF file: {exc}") from None
    return lib3mf, model


def _mesh_objects(model: Any) -> list[Any]:
    out = []
    it = model.GetMeshObjects()
    while it.MoveNext():
        out.append(it.GetCurrentMeshObject())
    return out


def _get_geometry(lib3mf: Any, obj: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    nv, nt = obj.GetVertexCount(), obj.GetTriangleCount()
    pos = np.zeros((nv, 3), dtype=np.float32)
    tri = np.zeros((nt, 3), dtype=np.uint32)
    w = obj._wrapper
    need = ctypes.c_uint64(0)
    if nv:
        buf = (lib3mf.Position * nv).from_buffer(pos)
        w.checkError(
            obj, w.lib.lib3mf_meshobject_getvertices(obj._handle, ctypes.c_uint64(nv), need, buf)
        )
    if nt:
        buf2 = (lib3mf.Triangle * nt).from_buffer(tri)
        w.checkError(
            obj,
            w.lib.lib3mf_meshobject_gettriangleindices(
                obj._handle, ctypes.c_uint64(nt), need, buf2
            ),
        )
    return pos.astype(np.float64), tri.astype(np.int64)


#: Millimetres per 3MF model unit (``lib3mf.ModelUnit``), by name.
_3MF_UNIT_MM = {"MicroMeter": 1e-3, "MilliMeter": 1.0, "CentiMeter": 10.0, "Inch": 25.4,
                "Foot": 304.8, "Meter": 1000.0}  # fmt: skip
#: Deepest nesting of 3MF components followed (a deeper one is taken for a cycle).
_3MF_MAX_DEPTH = 32


def _3mf_matrix(t: Any) -> NDArray[np.float64]:
    """(4, 4) float64: a ``lib3mf.Transform`` (row vectors: ``[x y z 1] @ M``)."""
    m = np.eye(4)
    m[:, :3] = [[float(t.Fields[i][j]) for j in range(3)] for i in range(4)]
    return m


def _3mf_built(
    lib3mf: Any, model: Any, path: Path
) -> list[tuple[NDArray[np.float64], NDArray[np.int64]]]:
    """The triangles a 3MF builds, in mm: each build item's object with the item's
    transform, components followed with theirs (a part placed on a slicer's bed, an
    assembly of instances), scaled by the model's unit. Support objects, the clipping
    meshes of beam lattices and the beams themselves are left out (the triangles of a
    beam-lattice object are its representation for readers without the extension). A
    mirroring transform (negative determinant) reverses the triangles' order too, so the
    mirrored object stays outward. A file without build items gives its mesh objects as
    they are."""
    objs = _mesh_objects(model)
    skip = set()
    for obj in objs:
        mode, rid = obj.BeamLattice().GetClipping()
        if mode != lib3mf.BeamLatticeClipMode.NoClipMode:
            skip.add(rid)
    supports = (lib3mf.ObjectType.Support, lib3mf.ObjectType.SolidSupport)
    unit = model.GetUnit()
    names = {getattr(lib3mf.ModelUnit, k): k for k in _3MF_UNIT_MM}
    mm = _3MF_UNIT_MM.get(names.get(unit, "MilliMeter"), 1.0)
    out: list[tuple[NDArray[np.float64], NDArray[np.int64]]] = []

    def mesh_of(obj: Any, m: NDArray[np.float64] | None) -> None:
        if obj.GetUniqueResourceID() in skip or obj.GetTriangleCount() == 0:
            return
        if obj.GetType() in supports:
            return
        v, f = _get_geometry(lib3mf, obj)
        if obj.BeamLattice().GetBeamCount():  # the beams' nodes are not on the surface
            keep = np.zeros(len(v), dtype=bool)
            keep[f.ravel()] = True
            v, f = v[keep], (np.cumsum(keep) - 1)[f]
        if m is not None:
            v = v @ m[:3, :3] + m[3, :3]
            if np.linalg.det(m[:3, :3]) < 0:  # a mirror (a slicer's): the winding too
                f = f[:, ::-1]
        out.append((v * mm if mm != 1.0 else v, f))

    def visit(obj: Any, m: NDArray[np.float64] | None, depth: int) -> None:
        if depth > _3MF_MAX_DEPTH:
            raise InputFileError(
                f"{path}: components nested more than {_3MF_MAX_DEPTH} deep (a cycle?)"
            )
        if obj.IsMeshObject():
            if not hasattr(obj, "GetTriangleCount"):
                obj = model.GetMeshObjectByID(obj.GetResourceID())
            mesh_of(obj, m)
        elif obj.IsComponentsObject():
            if not hasattr(obj, "GetComponentCount"):
                obj = model.GetComponentsObjectByID(obj.GetResourceID())
            for i in range(obj.GetComponentCount()):
                comp = obj.GetComponent(i)
                mc = _3mf_matrix(comp.GetTransform()) if comp.HasTransform() else None
                both = mc if m is None else (m if mc is None else mc @ m)
                visit(comp.GetObjectResource(), both, depth + 1)

    items = model.GetBuildItems()
    built = False
    while items.MoveNext():
        item = items.GetCurrent()
        built = True
        m = _3mf_matrix(item.GetObjectTransform()) if item.HasObjectTransform() else None
        if m is not None and np.array_equal(m, np.eye(4)):
            m = None  # (the identity: the file's float32 coordinates exactly)
        visit(item.GetObjectResource(), m, 0)
    if not built:
        for obj in objs:
            mesh_of(obj, None)
    return out


def read_beam_lattice(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary of the beam lattices in a 3MF file (for checks and tests).

    Returns
    -------
    dict
        ``objects`` (mesh objects), ``build_items``, and over the objects with a beam
        lattice: ``beams``, ``balls``, ``vertices``, ``triangles`` (the triangle
        representation readers without the extension use; 0 in a beam-only file) and
        ``clipped`` (whether one uses a clipping mesh); ``skin_triangles``: triangles of
        the other built objects (a skin beside a beam-only lattice).
    """
    p = check_mesh_file(path)
    lib3mf, model = _read_3mf_model(p)
    objs = _mesh_objects(model)
    built = set()
    items = model.GetBuildItems()
    while items.MoveNext():
        built.add(items.GetCurrent().GetObjectResourceID())
    out = {
        "objects": len(objs),
        "build_items": len(built),
        "beams": 0,
        "balls": 0,
        "vertices": 0,
        "triangles": 0,
        "clipped": False,
        "skin_triangles": 0,
    }
    for obj in objs:
        bl = obj.BeamLattice()
        nb = bl.GetBeamCount()
        if nb:
            out["beams"] += nb
            out["balls"] += bl.GetBallCount()
            out["vertices"] += obj.GetVertexCount()
            out["triangles"] += obj.GetTriangleCount()
            mode, _ = bl.GetClipping()
            out["clipped"] |= mode != lib3mf.BeamLatticeClipMode.NoClipMode
        elif obj.GetResourceID() in built:
            out["skin_triangles"] += obj.GetTriangleCount()
    return out


_MAGIC = {"3mf": (b"PK\x03\x04",), "ply": (b"ply",), "off": (b"OFF", b"COFF", b"NOFF", b"4OFF")}


def check_mesh_file(path: str | os.PathLike[str]) -> Path:
    """Refuse a mesh file that is missing, a directory, empty or not the format of its suffix.

    Cheap (reads the first bytes): binary STL must be exactly ``84 + 50 n`` bytes for the
    ``n`` triangles its header counts, ASCII STL must start with ``solid``; 3MF is a zip
    archive; PLY and OFF start with their keyword.

    Returns
    -------
    Path

    Raises
    ------
    MissingFileError
        The file does not exist.
    InputFileError
        A directory, an empty file, or not the format its suffix says (names the file).
    """
    p = Path(path)
    fmt = format_for(p, Kind.MESH, action="read")
    if p.is_dir():
        raise InputFileError(f"{p}: is a directory, not a mesh file")
    if not p.exists():
        raise MissingFileError(f"mesh file not found: {p}")
    size = p.stat().st_size
    what = fmt.name.upper()
    what = ("an " if what[0] in "AEIOFHLMNRSX" else "a ") + what  # an STL, a PLY
    if size == 0:
        raise InputFileError(f"{p}: the file is empty (0 bytes), not {what} file")
    try:
        with open(p, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read the file: {exc.strerror or exc}") from None
    if fmt.name == "stl":
        n = int(np.frombuffer(head[80:84], dtype="<u4")[0]) if len(head) >= 84 else -1
        if n >= 0 and 84 + 50 * n == size:
            return p
        text = head.lstrip()
        if text[:5].lower() == b"solid" and (b"facet" in head or b"endsolid" in head):
            return p
        binary = (
            f"a binary STL of {n:,} triangles (as its header says) would be "
            f"{84 + 50 * n:,} bytes, the file has {size:,}"
            if n >= 0
            else f"the file has only {size} bytes, less than a binary STL header (84)"
        )
        raise InputFileError(
            f"{p}: not an STL file (truncated or another format): {binary}, and it does not "
            "start with 'solid ... facet' as an ASCII STL does"
        )
    magic = _MAGIC.get(fmt.name)
    if magic and not any(head.lstrip().startswith(m) for m in magic):
        raise InputFileError(
            f"{p}: not {what} file (it does not start with "
            f"{' or '.join(repr(m.decode('latin-1')) for m in magic)})"
        )
    return p


def read_mesh(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read the triangles of a mesh file (``.stl``, ``.3mf``, ``.ply``, ``.obj``, ``.off``...).

    STL vertices are merged by position (STL stores each triangle separately);
    the other formats keep their indexing. A 3MF gives what it builds, in mm
    (:func:`_3mf_built`: build items and components with their transforms, the model's
    unit; no supports, no clipping meshes, no beams).

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64

    Raises
    ------
    MissingFileError, InputFileError
        A missing, empty or unreadable file, or one that is not the format of its suffix
        (named in the message; see :func:`check_mesh_file`).
    """
    p = check_mesh_file(path)
    fmt = format_for(p, Kind.MESH, action="read")
    if fmt.name == "3mf":
        lib3mf, model = _read_3mf_model(p)
        pieces = _3mf_built(lib3mf, model, p)
        if not pieces:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        base = np.cumsum([0] + [len(v) for v, _ in pieces[:-1]])
        return (
            np.vstack([v for v, _ in pieces]),
            np.vstack([f + b for (_, f), b in zip(pieces, base, strict=True)]),
        )
    v, f = read_mesh_faces(p, fmt.name)
    if fmt.name == "stl" and len(v):
        v, f = weld(v, f, tol=1e-12, drop_degenerate=False)
    return v, f


def read_mesh_faces(path: Path, fmt: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The vertices (V, 3) float64 and triangles (F, 3) int64 of a mesh file (not 3MF) as
    it stores them: trimesh's reading, except that faces of more than three vertices
    (OBJ, OFF, PLY) are split as the polygons they are (:mod:`lattice_cad.io.polygons`;
    trimesh fans them from their first vertex, which overlaps for a concave polygon).

    Raises
    ------
    InputFileError
        trimesh cannot read it, or a face names a vertex the file does not have.
    """
    import trimesh

    from lattice_cad.io.polygons import mesh_polygons, triangulate

    p = Path(path)
    polygons = None
    try:
        if fmt in ("obj", "off"):  # faces of 4+ vertices: split as polygons, not fans
            polygons = mesh_polygons(p, fmt)
        if polygons is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                loaded: Any = trimesh.load(str(p), force="mesh", process=False)
            if fmt == "ply":
                polygons = mesh_polygons(p, fmt, loaded)
    except Exception as exc:  # trimesh raises many types for bad files
        raise InputFileError(f"{p}: cannot read the mesh: {exc}") from None
    if polygons is not None:
        v, polys = polygons
        for which, idx in polys[0]:
            wrong = np.flatnonzero((idx < 0).any(axis=1) | (idx >= len(v)).any(axis=1))
            if len(wrong):
                k = int(wrong[0])
                raise InputFileError(
                    f"{p}: face {int(which[k])} ({', '.join(map(str, idx[k][:8]))}) names a "
                    f"vertex the file does not have ({len(v)} vertices)"
                )
        try:
            f, crossing = triangulate(v, polys)
        except ValueError as exc:  # a face of fewer than three vertices
            raise InputFileError(f"{p}: {exc}") from None
        if crossing:
            warnings.warn(
                f"{p}: {crossing} polygon face(s) cross themselves; they were split as fans "
                "from their first vertex",
                LatticeWarning,
                stacklevel=3,
            )
        return v, f
    v = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    f = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    return v.reshape(-1, 3), f.reshape(-1, 3)
