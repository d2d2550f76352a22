"""The CadQuery plugin: ``cq.Workplane.lattice``, registered as CadQuery documents plugins.

A CadQuery plugin is a module that adds a method to ``cadquery.Workplane`` when it is
imported; the method takes the workplane as ``self`` and works in global coordinates. So:

>>> import cadquery as cq
>>> import lattice_cad.plugin  # adds Workplane.lattice
>>> lat = cq.Workplane().box(20, 20, 20).lattice("bcc", 5.0, 0.4)  # doctest: +SKIP

Importing this module imports cadquery; nothing else in lattice-cad does (``import
lattice_cad`` and the engines stay light and free of side effects).
"""

from __future__ import annotations

from typing import Any

import cadquery as cq

from lattice_cad.core import config
from lattice_cad.lattice import Fill, Lattice, Method

__all__ = ["lattice", "register"]


def lattice(
    self: cq.Workplane,
    cell: str = config.DEFAULT_CELL,
    cell_size: float = config.DEFAULT_CELL_SIZE,
    radius: float = config.DEFAULT_RADIUS,
    *,
    method: Method = "voxel",
    fill: Fill | None = None,
    skin: float | None = None,
    segments: int = config.DEFAULT_SEGMENTS,
    origin: Any = None,
    rotation: Any = None,
    keep: Any = None,
    **options: Any,
) -> Lattice:
    """Fill the solids on the workplane's stack with a lattice.

    Parameters
    ----------
    cell, cell_size, radius, method, fill, skin, segments, origin, rotation, keep
        See :meth:`lattice_cad.Lattice.fill`.
    **options
        Every other keyword of :meth:`lattice_cad.Lattice.fill` (``trim``,
        ``build_direction``, ``remove_overhangs``, ...).

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
        keep=keep,
        **options,
    )


def register() -> None:
    """Add :func:`lattice` to ``cadquery.Workplane`` (idempotent; done on import)."""
    setattr(cq.Workplane, "lattice", lattice)  # noqa: B010 (mypy: Workplane declares no lattice)


register()
