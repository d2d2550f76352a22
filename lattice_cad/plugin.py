"""The CadQuery plugin: ``cq.Workplane.lattice``.

Importing this module registers :func:`lattice` as a method of
``cadquery.Workplane`` without importing cadquery itself (which takes seconds):
if cadquery is already imported the method is added at once, otherwise a
one-shot import hook adds it right after ``import cadquery`` runs. So
``import lattice_cad`` stays light and ``cq.Workplane.lattice`` is always there.
CadQuery's plugin contract: the function takes the workplane as ``self`` and
works in global coordinates.

>>> import cadquery as cq
>>> import lattice_cad.plugin  # noqa: F401  (done by ``import lattice_cad``)
>>> lat = cq.Workplane().box(20, 20, 20).lattice("bcc", 5.0, 0.4)  # doctest: +SKIP
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import cadquery as cq

    from lattice_cad.lattice import Fill, Lattice, Method

__all__ = ["lattice", "register", "install"]


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


def register(module: Any = None) -> None:
    """Add :func:`lattice` to ``cadquery.Workplane`` (idempotent; imports cadquery)."""
    if module is None:
        import cadquery as module
    module.Workplane.lattice = lattice


class _CadQueryHook(importlib.abc.MetaPathFinder):
    """Registers the plugin right after ``cadquery`` is first imported, then removes itself."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "cadquery":
            return None
        uninstall()
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        loader = spec.loader
        original = loader.exec_module

        def exec_module(module: Any) -> None:
            original(module)
            register(module)

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


_HOOK = _CadQueryHook()


def uninstall() -> None:
    """Remove the import hook (if still waiting for cadquery)."""
    if _HOOK in sys.meta_path:
        sys.meta_path.remove(_HOOK)


def install() -> bool:
    """Register now if cadquery is imported, else when it is; False if it is not installed."""
    if "cadquery" in sys.modules:
        register(sys.modules["cadquery"])
        return True
    if importlib.util.find_spec("cadquery") is None:
        return False
    if _HOOK not in sys.meta_path:
        sys.meta_path.insert(0, _HOOK)
    return True


install()
