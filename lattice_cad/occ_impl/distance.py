"""Exact distances from points to B-rep solids (OCCT), for checking tessellation-based cuts.

:func:`signed_distance` evaluates, point by point, OpenCascade's exact distance to the
solids' boundaries (``BRepExtrema_DistShapeShape`` on the B-rep faces, not on a mesh) and
the classification of the point (``BRepClass3d_SolidClassifier``). It costs about a
millisecond per point and face set, so callers evaluate it only where a cheaper test (a
fine tessellation) leaves doubt.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from OCP.BRep import BRep_Builder
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
from OCP.BRepClass3d import BRepClass3d_SolidClassifier
from OCP.BRepExtrema import BRepExtrema_DistShapeShape
from OCP.gp import gp_Pnt
from OCP.TopAbs import TopAbs_FACE, TopAbs_IN, TopAbs_ON
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS_Compound

from lattice_cad.core.errors import OCCTFailure
from lattice_cad.occ_impl.shapes import max_tolerance

__all__ = ["signed_distance"]


def _boundary(solid: Any) -> TopoDS_Compound:
    """The faces of ``solid`` as a compound (BRepExtrema measures 0 from a point inside a
    solid: the distance to its boundary needs the faces)."""
    comp = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(comp)
    exp = TopExp_Explorer(solid, TopAbs_FACE)
    while exp.More():
        builder.Add(comp, exp.Current())
        exp.Next()
    return comp


def signed_distance(
    solids: Sequence[Any],
    points: ArrayLike,
    *,
    tol: float = 1e-7,
    beyond_tolerance: bool = False,
) -> NDArray[np.float64]:
    """Signed distance of points to the union of B-rep solids, positive outside.

    Parameters
    ----------
    solids : sequence of TopoDS_Solid
        E.g. ``conformal.Part.shape``.
    points : (P, 3) float64
    tol : float
        Classification tolerance (mm): points closer to the boundary count as on it
        (distance 0 or their exact distance, signed positive only when outside).
    beyond_tolerance : bool
        Count a point outside as far outside as it is *beyond the B-rep's own tolerance*
        there: its distance less the largest tolerance of the nearest face (with its edges
        and vertices, or of the nearest edge or vertex), 0 if within it. A STEP file's
        edges may lie off their faces' surfaces by up to their tolerance (the
        Ventilator's plane face 19: 0.014 mm), and any tessellation that follows the
        edges lies that far off the surface inside the face: that is the file's accuracy,
        not the tessellation's.

    Returns
    -------
    (P,) float64
        Outside all solids: the distance to the nearest solid's boundary (exact for the
        union); inside one: minus the distance to that solid's boundary (the largest depth
        over the solids holding the point; for solids that touch, a point near a shared
        face is deeper in their union than this says).

    Raises
    ------
    OCCTFailure
        BRepExtrema finds no distance for a point.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(p), dtype=np.float64)
    tools = []
    for solid in solids:
        dist = BRepExtrema_DistShapeShape()
        dist.LoadS1(_boundary(solid))
        # loaded once: building the classifier per point was most of the time
        tools.append((BRepClass3d_SolidClassifier(solid), dist))
    for i, (x, y, z) in enumerate(p):
        pnt = gp_Pnt(float(x), float(y), float(z))
        vertex = BRepBuilderAPI_MakeVertex(pnt).Vertex()
        best_out, best_in = np.inf, -np.inf
        for classifier, dist in tools:
            dist.LoadS2(vertex)
            if not dist.Perform() or dist.NbSolution() == 0:
                raise OCCTFailure(f"BRepExtrema found no distance from ({x:g}, {y:g}, {z:g})")
            d = float(dist.Value())
            classifier.Perform(pnt, tol)
            state = classifier.State()
            if state == TopAbs_IN:
                best_in = max(best_in, d)
            elif state == TopAbs_ON:
                best_in = max(best_in, 0.0)
            else:
                if beyond_tolerance:
                    d = max(0.0, d - max_tolerance(dist.SupportOnShape1(1)))
                best_out = min(best_out, d)
        out[i] = -best_in if np.isfinite(best_in) else best_out
    return out
