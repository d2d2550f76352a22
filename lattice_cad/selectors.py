"""Node sets of a lattice chosen by faces of its part: CadQuery selectors, CAD faces, planes.

The front's half of the beam FE export (:mod:`lattice_cad.io.fe` writes the file, numpy
only): a selector that needs the part's B-rep is resolved here, with cadquery's string
selectors and OpenCascade's tessellation (through :mod:`lattice_cad.occ_impl`), to the
triangles of the chosen faces; the nodes within the tolerance of them form the set.

Selectors
---------
* a CadQuery face selector string: ``">Z"``, ``"<Z"``, ``"%CYLINDER"``, ``">Z[-2]"``,
  ``"|Z and >X"``, ... (evaluated on the part's faces). A part without B-rep (a mesh file, a
  graph alone) takes the six axis selectors ``">X"`` .. ``"<Z"`` as the sides of its bounding
  box, and nothing else that needs faces;
* a CAD face or faces: a cadquery ``Workplane``/``Face``, a build123d ``Face`` or
  ``ShapeList``, a ``TopoDS_Shape``;
* ``"plane:x,y,z,nx,ny,nz"``, ``"box:x0,y0,z0,x1,y1,z1"``, :class:`~lattice_cad.io.fe.Plane`,
  :class:`~lattice_cad.io.fe.Box`;
* graph node indices or a boolean node mask.

A node is on a face when its distance to it is at most ``tol``; by default the node's
largest strut radius (its material touches the face) plus the tessellation deflection of
the face. Nodes of a lattice filled with ``fill="inside"`` lie a cell's depth inside the
part and touch no face: the error then gives the distance of the nearest node.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.errors import SelectionError
from lattice_cad.core.graph import LatticeGraph
from lattice_cad.io import fe

__all__ = [
    "select_nodes",
    "resolve_node_sets",
    "face_triangles",
    "brep_faces",
    "face_inventory",
    "pick_faces",
]


def _part_shape(part: Any) -> Any:
    """The B-rep of a ``conformal.Part`` (a compound of its solids), or None."""
    shape = getattr(part, "shape", None)
    if shape is None:
        return None
    if isinstance(shape, (list, tuple)):
        if not shape:
            return None
        from lattice_cad.occ_impl import shapes as occ

        return shape[0] if len(shape) == 1 else occ.compound(list(shape))
    return shape


def face_triangles(faces: Any, deflection: float) -> NDArray[np.float64]:
    """(T, 3, 3) float64: the triangles of CAD faces (anything with an OCCT shape)."""
    from lattice_cad.occ_impl import shapes as occ

    shape = occ.as_topods(faces)
    if shape is None:
        items = list(faces) if isinstance(faces, (list, tuple)) else []
        found = [occ.as_topods(f) for f in items]
        if not items or any(s is None for s in found):
            raise SelectionError(f"cannot select faces with {type(faces).__name__} {faces!r}")
        shape = occ.compound(found)
    v, f = occ.tessellate(shape, deflection)
    if len(f) == 0:
        raise SelectionError("the selected shape has no faces to select nodes by")
    return np.ascontiguousarray(v[f])


def brep_faces(part: Any) -> list[Any]:
    """The cadquery Faces of a part's B-rep solids (TopExp order, solid by solid); [] for a
    part read from a mesh."""
    import cadquery as cq

    shape = getattr(part, "shape", None)
    if shape is None:
        return []
    solids = shape if isinstance(shape, (list, tuple)) else [shape]
    return [f for s in solids for f in cq.Shape.cast(s).Faces()]


def face_inventory(faces: list[Any]) -> str:
    """E.g. ``"7 faces: 1 CYLINDER, 6 PLANE"``."""
    from collections import Counter

    counts = Counter(f.geomType() for f in faces)
    listed = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    return f"{len(faces)} faces: {listed}" if faces else "no faces"


def pick_faces(faces: list[Any], selector: str) -> list[Any]:
    """The faces a CadQuery string selector (``">Z"``, ``"%CYLINDER"``...) picks.

    Raises
    ------
    ValueError
        The selector is not CadQuery selector syntax (the parser's message, on one line).
    """
    import cadquery as cq

    try:
        return list(cq.selectors.StringSyntaxSelector(selector).filter(faces))
    except Exception as exc:  # pyparsing and cadquery raise several kinds
        raise ValueError(f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None


def _cadquery_faces(part: Any, selector: str) -> Any:
    """The faces of the part that a CadQuery string selector picks (a list of cq.Face)."""
    faces = brep_faces(part)
    try:
        chosen = pick_faces(faces, selector)
    except ValueError as exc:
        raise SelectionError(f"{selector!r} is not a CadQuery face selector: {exc}") from None
    if not chosen:
        raise SelectionError(
            f"{selector!r} selects no face of the part; it has {face_inventory(faces)}"
        )
    return chosen


def select_nodes(
    graph: LatticeGraph,
    selector: Any,
    *,
    part: Any = None,
    tol: float | None = None,
    name: str = "node set",
) -> NDArray[np.int64]:
    """The graph nodes (with struts) on the faces a selector picks (see the module notes).

    Parameters
    ----------
    graph : LatticeGraph
    selector : str, CAD face(s), Plane, Box, int array or bool mask
    part : conformal.Part, optional
        The filled part (its B-rep for CadQuery selectors; its bounds for axis selectors).
    tol : float, optional
        Distance tolerance (mm); default per node: its largest strut radius, plus the
        tessellation deflection for faces.
    name : str
        The set's name, for messages.

    Returns
    -------
    (K,) int64
        Sorted graph node indices, K >= 1.

    Raises
    ------
    SelectionError
        The selector is not understood, picks no face, or no node is near its faces.
    """
    bounds = getattr(part, "bounds", None)
    deflection = float(getattr(part, "deflection", 0.0) or 0.0)
    if isinstance(selector, str):
        parsed = fe.parse_selector(selector)
        if not isinstance(parsed, str) or _part_shape(part) is None:
            return fe.select_nodes(graph, parsed, tol=tol, bounds=bounds, name=name)
        faces = _cadquery_faces(part, parsed)
        tri = face_triangles(faces, deflection or 1e-3 * float(getattr(part, "diagonal", 1.0)))
        return _near(graph, tri, tol, deflection, name, parsed)
    if isinstance(selector, (fe.Plane, fe.Box, np.ndarray, list, tuple)) and not _is_faces(
        selector
    ):
        return fe.select_nodes(graph, selector, tol=tol, bounds=bounds, name=name)
    tri = face_triangles(selector, deflection or 1e-3 * _diagonal(graph))
    return _near(graph, tri, tol, deflection, name, selector)


def _diagonal(graph: LatticeGraph) -> float:
    b = graph.bounds
    return float(np.linalg.norm(b[1] - b[0])) or 1.0


def _is_faces(selector: Any) -> bool:
    """A list or tuple of CAD objects (rather than node indices)."""
    if not isinstance(selector, (list, tuple)) or not selector:
        return False
    return all(hasattr(s, "wrapped") or type(s).__name__.startswith("TopoDS") for s in selector)


def _near(
    graph: LatticeGraph, tri: Any, tol: float | None, deflection: float, name: str, what: Any
) -> NDArray[np.int64]:
    slack = deflection if tol is None else 0.0
    return fe.select_nodes(graph, what, tol=tol, triangles=tri, slack=slack, name=name)


def resolve_node_sets(
    graph: LatticeGraph,
    node_sets: Mapping[str, Any] | None,
    *,
    part: Any = None,
    tol: float | None = None,
) -> dict[str, NDArray[np.int64]]:
    """Every named selector resolved to graph node indices (see :func:`select_nodes`)."""
    out: dict[str, NDArray[np.int64]] = {}
    for key, sel in (node_sets or {}).items():
        out[key] = select_nodes(graph, sel, part=part, tol=tol, name=f"node set {key!r}")
    return out
