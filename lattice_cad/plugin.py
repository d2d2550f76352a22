"""The CadQuery plugin: ``cq.Workplane.lattice``.

Importing this module registers :func:`lattice` as a method of
``cadquery.Workplane`` (``lattice_cad/__init__.py`` imports it when cadquery is
installed). CadQuery's plugin contract: the function takes the workplane as
``self`` and works in global coordinates.

>>> import cadquery as cq
>>> import lattice_cad.plugin  # noqa: F401  (done by ``import lattice_cad``)
>>> lat = cq.Workplane().box(20, 20, 20).lattice("bcc", 5.0, 0.4)  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import cadquery as cq

    from lattice_cad.lattice import Fill, Lattice, Method

__all__ = ["lattice", "register"]


def lattice(
    self: cq.Workplane,
    cell: str = "bcc",
    cell_size: float = 5.0,
    radius: float = 0.4,
    *,
    method: Method = "voxel",
    fill: Fill | None = None,
    skin: float | None = None,
    segments: int = 6,
    origin: Any = None,
    rotation: Any = None,
) -> Lattice:
    """Fill the solids on the workplane's stack with a lattice.

    Parameters
    ----------
    cell, cell_size, radius, method, fill, skin, segments, origin, rotation
        See :meth:`lattice_cad.Lattice.fill`.

    Returns
    -------
    lattice_cad.Lattice
        Not a Workplane: call :meth:`~lattice_cad.Lattice.to_workplane` for the exact
        B-rep of a small lattice, or :meth:`~lattice_cad.Lattice.save` to write a file.

    Raises
    ------
    ValueError
        The stack holds no solid.
    """
    import cadquery as cq

    from lattice_cad.lattice import Lattice

    solids = [s for v in self.vals() if isinstance(v, cq.Shape) for s in v.Solids()]
    if not solids:
        # the usual CadQuery chain leaves faces or edges selected: use their solid
        try:
            solids = list(self.findSolid().Solids())
        except ValueError:
            solids = []
    if not solids:
        raise ValueError("Workplane.lattice: there is no solid on the stack to fill")
    shape = solids[0] if len(solids) == 1 else cq.Compound.makeCompound(solids)
    return Lattice.fill(
        shape,
        cell,
        cell_size,
        radius,
        method=method,
        fill=fill,
        skin=skin,
        segments=segments,
        origin=origin,
        rotation=rotation,
    )


def register() -> None:
    """Add :func:`lattice` to ``cadquery.Workplane`` (idempotent)."""
    import cadquery as cq

    cq.Workplane.lattice = lattice  # type: ignore[attr-defined]


register()
