"""Polygon faces of mesh files (OBJ, OFF, PLY), triangulated as the polygons they are.

trimesh triangulates every face of more than three vertices as a fan from its first vertex
(``trimesh.geometry.triangulate_quads``; a quad along its 0-2 diagonal). That is right for
convex polygons only: the fan of a concave one leaves the polygon, so its triangles
overlap and the surface crosses itself (a Blender OBJ of an extrusion whose end caps are
concave 20-gons loaded as a solid 3.6 strut radii larger than the part, and its skin was
refused). :func:`mesh_polygons` reads the polygons of a file that has any (the vertices as
the file stores them) and :func:`triangulate` splits each one: a convex polygon as the
fan trimesh makes, a concave one by ear clipping in its plane (``mapbox_earcut``).
Files of triangles only are left to trimesh.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["mesh_polygons", "triangulate"]

#: A face line of an OBJ file with four or more vertex references.
_OBJ_POLYGON = re.compile(rb"^[ \t]*f[ \t]+\S+[ \t]+\S+[ \t]+\S+[ \t]+\S+", re.M)
#: A face line of an OBJ file with a relative (negative) vertex reference.
_OBJ_RELATIVE = re.compile(rb"^[ \t]*f[ \t]+(?:[^\r\n]*[ \t])?-[0-9]", re.M)
_OBJ_V = re.compile(rb"^[ \t]*v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.M)
_OBJ_F = re.compile(rb"^[ \t]*f[ \t]+([^\r\n]*)", re.M)
_REFS = re.compile(rb"/\S*")
_SPACES = re.compile(rb"[ \t]+")
_EDGES = re.compile(rb" ?\n ?")


#: Polygons grouped by their number of vertices k: (rows (n,) int64, the polygons' places
#: in the file; indices (n, k) int64), and the number of polygons in all.
Groups = tuple[list[tuple[NDArray[np.int64], NDArray[np.int64]]], int]


def mesh_polygons(
    path: Path, fmt: str, loaded: Any = None
) -> tuple[NDArray[np.float64], Groups] | None:
    """The vertices (V, 3) float64 and the faces (:data:`Groups`) of a mesh file with at
    least one face of more than three vertices, or None (triangles only, or a format
    without polygons). Also an OBJ file of triangles with relative (negative) vertex
    references: trimesh counts them back from the vertices of the face's object, not of the
    file, so every object after the first is read onto the first one's vertices (an OBJ
    of 6 groups, made outside shared/data, loaded with 91 open edges).

    ``fmt``: the format's name (``"obj"``, ``"off"``, ``"ply"``); ``loaded``: the mesh
    trimesh read from a PLY file (its raw elements hold the polygons).
    """
    if fmt == "obj":
        data = path.read_bytes()
        wanted = _OBJ_POLYGON.search(data) or _OBJ_RELATIVE.search(data)
        return _obj_polygons(data) if wanted else None
    if fmt == "off":
        return _off_polygons(path.read_text(errors="replace"))
    if fmt == "ply" and loaded is not None:
        return _ply_polygons(getattr(loaded, "metadata", {}).get("_ply_raw"))
    return None


def _grouped(rows: list[Any], convert: Any) -> Groups:
    """:data:`Groups` of ``rows`` (one sequence per face), each group's (n, k) array made
    by ``convert``."""
    lens = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    groups = []
    for k in np.unique(lens):
        which = np.flatnonzero(lens == k)
        groups.append((which, convert([rows[i] for i in which]).reshape(len(which), int(k))))
    return groups, len(rows)


def _obj_polygons(data: bytes) -> tuple[NDArray[np.float64], Groups]:
    """Vertices and faces of an OBJ file (``v`` and ``f`` lines; texture and normal
    references and every other statement ignored; negative indices count back)."""
    data = data.replace(b"\\\r\n", b" ").replace(b"\\\n", b" ")  # continued lines
    vs = _OBJ_V.findall(data)
    v = np.array(vs, dtype=np.bytes_).astype(np.float64) if vs else np.zeros((0, 3))
    lines = _OBJ_F.findall(data)
    block = b"\n".join(lines)
    if b"/" in block:
        block = _REFS.sub(b"", block)  # "7/3/7" -> "7"
    if b"\t" in block or b"  " in block:  # (most exporters write single spaces)
        block = _SPACES.sub(b" ", block)
    if b" \n" in block or b"\n " in block:
        block = _EDGES.sub(b"\n", block)
    block = block.strip()
    counts = np.fromiter(
        (ln.count(b" ") + 1 for ln in block.split(b"\n")), dtype=np.int64, count=len(lines)
    )
    toks = np.array(block.split(), dtype=np.bytes_).astype(np.int64)
    if len(toks) != counts.sum():  # (an empty face line)
        raise ValueError("a face line of the OBJ file names no vertex")
    if (toks < 0).any():  # counted back from the face: the vertices defined before it
        starts = [m.start() for m in _OBJ_V.finditer(data)]
        at = [m.start() for m in _OBJ_F.finditer(data)]
        seen = np.searchsorted(np.asarray(starts), np.asarray(at))
        toks = np.where(toks > 0, toks - 1, np.repeat(seen, counts) + toks)
    else:
        toks = toks - 1
    offset = np.concatenate([[0], np.cumsum(counts)[:-1]])
    groups = []
    for k in np.unique(counts):
        which = np.flatnonzero(counts == k)
        groups.append((which, toks[offset[which][:, None] + np.arange(k)[None, :]]))
    return v.reshape(-1, 3), (groups, len(lines))


def _off_polygons(text: str) -> tuple[NDArray[np.float64], Groups] | None:
    """Vertices and faces of an OFF (or COFF) file with a face of more than three vertices,
    else None."""
    tokens = [ln.split("#", 1)[0].split() for ln in text.splitlines()]
    lines = [t for t in tokens if t]
    if not lines or not lines[0][0].upper().endswith("OFF"):
        return None
    head = lines[0][1:] if len(lines[0]) > 1 else lines[1]
    body = lines[1:] if len(lines[0]) > 1 else lines[2:]
    n_v, n_f = int(head[0]), int(head[1])
    rows = [r[1 : 1 + int(r[0])] for r in body[n_v : n_v + n_f]]
    if not any(len(r) > 3 for r in rows):
        return None
    v = np.array([r[:3] for r in body[:n_v]], dtype=np.float64).reshape(-1, 3)
    return v, _grouped(rows, lambda g: np.array(g, dtype=np.int64))


def _ply_polygons(raw: Any) -> tuple[NDArray[np.float64], Groups] | None:
    """Vertices and faces of a PLY file's raw elements (as trimesh keeps them) with a face
    of more than three vertices, else None."""
    if not raw or "face" not in raw or "vertex" not in raw:
        return None
    data = raw["face"].get("data")
    faces: Any = None
    if isinstance(data, dict):
        faces = next((data[k] for k in ("vertex_indices", "vertex_index") if k in data), None)
    elif isinstance(data, np.ndarray) and data.dtype.names:
        names = data.dtype.names
        name = next((k for k in ("vertex_indices", "vertex_index") if k in names), names[0])
        faces = data[name]
        if faces.dtype.names and "f1" in faces.dtype.names:
            faces = faces["f1"]
    if faces is None:
        return None
    arr = np.asarray(faces)
    if arr.dtype != object and arr.ndim == 2 and arr.shape[1] <= 3:
        return None
    rows = [np.asarray(p, dtype=np.int64).reshape(-1) for p in faces]
    if not any(len(p) > 3 for p in rows):
        return None
    vd = raw["vertex"]["data"]
    v = np.column_stack([np.asarray(vd[c], dtype=np.float64) for c in "xyz"])
    return v, _grouped(rows, lambda g: np.array(g, dtype=np.int64))


def triangulate(
    vertices: NDArray[np.float64], polygons: list[NDArray[np.int64]] | Groups
) -> tuple[NDArray[np.int64], int]:
    """Triangles (F, 3) int64 of ``polygons`` (each (k,) int64 indices into ``vertices``
    (V, 3) float64, k >= 3; or :data:`Groups`), in their order, and how many concave
    polygons could not be split without overlaps (a polygon that crosses itself: fanned
    as trimesh does).

    A convex polygon (or a degenerate one) becomes the fan from its first vertex; a concave
    one is projected on its plane (the Newell normal) and split by ear clipping
    (``mapbox_earcut``), every triangle turned as the polygon is.
    """
    v = np.asarray(vertices, dtype=np.float64)
    if isinstance(polygons, tuple):
        groups, n_polys = polygons
    else:
        groups, n_polys = _grouped(list(polygons), lambda g: np.array(g, dtype=np.int64))
    lengths = np.zeros(n_polys, dtype=np.int64)
    for which, idx in groups:
        lengths[which] = idx.shape[1]
        if idx.shape[1] < 3:
            raise ValueError(
                f"face {int(which[0])} has {idx.shape[1]} vertices; a face needs 3 or more"
            )
    failed = 0
    pieces: list[tuple[NDArray[np.int64], NDArray[np.int64]]] = []
    for which, idx in groups:
        k = idx.shape[1]
        if k == 3:
            pieces.append((which, idx[:, None, :]))
            continue
        p = v[idx]  # (n, k, 3)
        normal = np.cross(p, np.roll(p, -1, axis=1)).sum(axis=1)  # (n, 3): 2 x area normal
        edge = np.roll(p, -1, axis=1) - p
        turn = np.einsum("nkc,nc->nk", np.cross(edge, np.roll(edge, -1, axis=1)), normal)
        scale = np.einsum("nkc,nkc->nk", edge, edge).max(axis=1) * np.linalg.norm(normal, axis=1)
        concave = (turn < -1e-12 * scale[:, None]).any(axis=1)
        fan = np.stack(
            [np.stack([idx[:, 0], idx[:, j], idx[:, j + 1]], axis=1) for j in range(1, k - 1)],
            axis=1,
        )  # (n, k - 2, 3)
        for row in np.flatnonzero(concave):
            tri = _ear_clipped(p[row], normal[row])
            if tri is None:
                failed += 1
            else:
                fan[row] = idx[row][tri]
        pieces.append((which, fan))
    # each polygon's triangles where it stands in the file
    start = np.concatenate([[0], np.cumsum(lengths - 2)])
    f = np.empty((int(start[-1]), 3), dtype=np.int64)
    for which, tris in pieces:
        rows = start[which][:, None] + np.arange(tris.shape[1])[None, :]
        f[rows.ravel()] = tris.reshape(-1, 3)
    return f, failed


def _ear_clipped(p: NDArray[np.float64], normal: NDArray[np.float64]) -> NDArray[np.int64] | None:
    """(k - 2, 3) int64: local indices of the triangles of the polygon ``p`` (k, 3) by ear
    clipping in its plane, turned along ``normal``; None when the polygon cannot be split
    into k - 2 triangles of its own (it crosses itself)."""
    import mapbox_earcut

    n = normal / np.linalg.norm(normal)
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    q = np.ascontiguousarray(np.stack([p @ u, p @ w], axis=1))
    tri = np.asarray(
        mapbox_earcut.triangulate_float64(q, np.array([len(p)], dtype=np.uint32)), dtype=np.int64
    ).reshape(-1, 3)
    if len(tri) != len(p) - 2:
        return None
    x = q[tri]  # (t, 3, 2): the triangles' signed areas in the plane (u, w, n is right-handed)
    area = (x[:, 1, 0] - x[:, 0, 0]) * (x[:, 2, 1] - x[:, 0, 1]) - (x[:, 1, 1] - x[:, 0, 1]) * (
        x[:, 2, 0] - x[:, 0, 0]
    )
    tri[area < 0] = tri[area < 0][:, ::-1]
    # the polygon's own area, split without overlap: the triangles' areas add up to it
    ring = (q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]).sum()
    if not np.isclose(np.abs(area).sum(), abs(ring), rtol=1e-9, atol=0.0):
        return None
    return tri
