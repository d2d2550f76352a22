"""Folds of a skin's inner wall removed before the booleans (issue 11 item 1).

manifold3d's ``simplify`` of the voxel method's inner wall (marching tetrahedra, valid as
they come) can fold it: on the Ventilator (octet, skin 0.889 mm) 66 face pairs of the
simplified wall intersect each other, in float64 already, and the booleans carry them
into the skinned solid. No rounding to float32, shift of the lattice or mid-wall surface
removes them, so the float32 check failed four times before a retry on the part's own
tessellation happened to give an unfolded wall (~7 min). A fold is a few faces: collapsing
the smaller face of each intersecting pair (as the final check does with the booleans'
needles) removes it, the surface stays closed, and the wall moves by at most the length
of the collapsed edges (a fraction of the simplification's tolerance there).
"""

from __future__ import annotations

from typing import Any

__all__ = ["untangle", "unfolded"]

#: Passes of collapses (each followed by a local check) before the surface is left as it is.
UNTANGLE_ROUNDS = 8


def _collapse_folds(mesh: Any, report: Any) -> Any:
    """The zero-area faces and the smaller face of each intersecting pair collapsed."""
    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh

    v, f = io.collapse_folds(
        mesh.vertices, mesh.faces, report.self_intersection_pairs, report.zero_area_faces
    )
    return Mesh(vertices=v, faces=f)


def untangle(surface: Any, name: str = "the inner surface") -> tuple[Any, int]:
    """``surface`` (a ``manifold3d.Manifold``) without self-intersections or zero-area faces.

    Returns the surface and the number of triangles the collapses removed (0: returned as
    it came, also when it is not a closed oriented 2-manifold or the collapses do not make
    it valid: the caller's final check then decides).
    """
    done = unfolded(surface, name)
    return (surface, 0) if done is None else done


def unfolded(surface: Any, name: str = "the inner surface") -> tuple[Any, int] | None:
    """:func:`untangle`, or None when ``surface`` is not valid and the collapses do not make
    it valid (a fold across sheets of the wall, not a few faces: ``conformal.skin`` then
    simplifies the wall less)."""
    import fast_stitch
    from conformal.skin import _manifold, to_arrays
    from fast_stitch.recheck import recheck
    from lattice_cad.core.mesh import Mesh

    if surface.is_empty():
        return surface, 0
    v, f = to_arrays(surface)
    mesh = Mesh(vertices=v, faces=f)
    report = fast_stitch.check(mesh)
    if report.valid:
        return surface, 0
    if not (report.watertight and report.manifold and report.oriented):
        return None
    for _ in range(UNTANGLE_ROUNDS):
        before, mesh = mesh, _collapse_folds(mesh, report)
        report = recheck(before, report, mesh)  # self-intersections near the collapses
        if report.valid:  # (a round can pinch an edge that the next one collapses)
            return _manifold(mesh.vertices, mesh.faces, name), len(f) - len(mesh.faces)
    return None
