"""Read the stored triangulations of many faces at once, as numpy arrays.

Reading a ``Poly_Triangulation`` node by node (``Node(i).Coord()``, ``Triangle(i).Get()``)
costs a few Python calls per node and per triangle: on a part meshed with 400,000 triangles
that is seconds, each time the mesh is read. Here OpenCascade writes all of them in one go
in its own binary format (``BinTools_ShapeSet.WriteTriangulation``: the doubles and
integers as they are in memory, so the values are bit for bit the same), and numpy reads
that buffer. Whenever the buffer is not what is expected (a triangulation shared by two
faces, another layout, another byte order), :func:`triangulation_arrays` returns None and
the caller reads node by node as before.
"""

from __future__ import annotations

import io
import sys

import numpy as np
from numpy.typing import NDArray
from OCP.BinTools import BinTools_FormatVersion_VERSION_4, BinTools_ShapeSet
from OCP.BRep import BRep_Builder
from OCP.Message import Message_ProgressRange
from OCP.Poly import Poly_Triangulation
from OCP.TopoDS import TopoDS_Compound, TopoDS_Face

__all__ = ["triangulation_arrays"]

Arrays = tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.int64]]


def triangulation_arrays(tris: list[Poly_Triangulation]) -> list[Arrays] | None:
    """Each triangulation's (nodes (n, 3) in its own coordinates, uv nodes (n, 2) or None,
    triangles (t, 3), 1-based as stored), in the order given; None when the bulk read does
    not apply (then read them node by node)."""
    if not tris or sys.byteorder != "little":
        return None
    builder = BRep_Builder()
    comp = TopoDS_Compound()
    builder.MakeCompound(comp)
    for tri in tris:
        face = TopoDS_Face()
        builder.MakeFace(face, tri)  # a face with only the triangulation: nothing else written
        builder.Add(comp, face)
    sset = BinTools_ShapeSet()
    sset.SetWithTriangles(True)
    sset.SetWithNormals(False)
    sset.Add(comp)
    buf = io.BytesIO()
    sset.WriteTriangulation(buf, Message_ProgressRange())
    head, _, body = buf.getvalue().partition(b"\n")
    if head.split() != [b"Triangulations", str(len(tris)).encode()]:
        return None  # a triangulation held twice, or another format
    v4 = int(sset.FormatNb()) >= int(BinTools_FormatVersion_VERSION_4.value)
    out: list[Arrays] = []
    pos, size = 0, len(body)
    for tri in tris:
        if pos + 9 + v4 + 8 > size:
            return None
        nn, nt = (int(x) for x in np.frombuffer(body, "<i4", 2, pos))
        has_uv, pos = body[pos + 8], pos + 9
        if v4:
            if body[pos] != 0:  # normals: not asked for
                return None
            pos += 1
        pos += 8  # the deflection
        if nn != tri.NbNodes() or nt != tri.NbTriangles() or has_uv != tri.HasUVNodes():
            return None
        need = 24 * nn + (16 * nn if has_uv else 0) + 12 * nt
        if pos + need > size:
            return None
        pts = np.frombuffer(body, "<f8", 3 * nn, pos).reshape(nn, 3)
        pos += 24 * nn
        uv = None
        if has_uv:
            uv = np.frombuffer(body, "<f8", 2 * nn, pos).reshape(nn, 2)
            pos += 16 * nn
        t = np.frombuffer(body, "<i4", 3 * nt, pos).reshape(nt, 3).astype(np.int64)
        pos += 12 * nt
        if nn and pts[0].tolist() != list(tri.Node(1).Coord()):
            return None
        if nt and t[-1].tolist() != list(tri.Triangle(nt).Get()):
            return None
        out.append((pts.astype(np.float64), None if uv is None else uv.astype(np.float64), t))
    return out if pos == size else None
