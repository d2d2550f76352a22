"""The :class:`Lattice`: a part filled with a lattice, ready to mesh, save, validate.

>>> from lattice_cad.lattice import Lattice
>>> from conformal import block
>>> lat = Lattice(block("bcc", 1, cell_size=5.0, radius=0.4))
>>> lat.info()["struts"]
8

``Lattice.fill(part, ...)`` takes a build123d Part/Solid, a cadquery
Workplane/Shape, an OCCT shape, a ``conformal.Part`` or a path (STEP or mesh),
builds the lattice graph with :mod:`conformal` and keeps the part, so that a
skin can be added and a beam-lattice 3MF can carry the part as clipping mesh.
Everything heavy (the mesh, the skin, the exact reference) is built lazily, once.
"""

from __future__ import annotations

import math
import os
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, cast

import numpy as np

from lattice_cad.core import config
from lattice_cad.core.errors import ExportError, LatticeError, OCCTFailure
from lattice_cad.core.formats import Kind, resolve
from lattice_cad.core.graph import LatticeGraph

if TYPE_CHECKING:
    import cadquery as cq

    from lattice_cad.core.mesh import Mesh

__all__ = ["Lattice", "Method", "Fill", "load_graph"]

Method = Literal["voxel", "tet"]
Fill = Literal["auto", "inside", "clip", "conform"]


def _check_choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")
    return str(value)


def _positive(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(float(value)) and float(value) > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def load_graph(path: str | os.PathLike[str]) -> LatticeGraph:
    """Read a lattice graph (``.json`` / ``.npz``), see :meth:`LatticeGraph.load`."""
    return LatticeGraph.load(path)


def _load_part(source: Any) -> Any:
    """A ``conformal.Part`` from anything :func:`conformal.load_part` accepts."""
    from conformal.part import Part, load_part

    if isinstance(source, Part):
        return source
    return load_part(source)


def _fill_graph(
    part: Any,
    *,
    method: str,
    cell: str,
    cell_size: float,
    radius: float,
    fill: str,
    origin: Any,
    rotation: Any,
) -> tuple[LatticeGraph, Any]:
    """Call the conformal engine (imported lazily) for ``method``: the graph and its report."""
    import conformal

    built: Any
    if method == "voxel":
        built = conformal.voxel_lattice(
            part,
            cell=cell,
            cell_size=cell_size,
            radius=radius,
            fill=cast(Any, fill),
            origin=origin,
            rotation=rotation,
            return_report=True,
        )
    else:
        built = conformal.tet_lattice(part, size=cell_size, radius=radius, return_report=True)
    graph, report = built
    if not isinstance(graph, LatticeGraph):
        raise TypeError(f"the {method} engine returned {type(graph).__name__}, not a graph")
    return graph, report


def _collapse_folds(mesh: Mesh, report: Any) -> Mesh:
    """Collapse the zero-area faces and the smaller face of each self-intersecting pair
    (manifold3d's booleans leave needles that rounding to float32 can fold)."""
    from lattice_cad import io
    from lattice_cad.core.mesh import Mesh

    v, f = mesh.vertices, mesh.faces
    pairs = np.asarray(report.self_intersection_pairs, dtype=np.int64).reshape(-1, 2)
    t = v[f]
    area = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    smaller = np.where(area[pairs[:, 0]] <= area[pairs[:, 1]], pairs[:, 0], pairs[:, 1])
    which = np.union1d(np.asarray(report.zero_area_faces, dtype=np.int64), smaller)
    v2, f2 = io.collapse_faces(v, f, which)
    return Mesh(vertices=v2, faces=f2)


class Lattice:
    """A lattice graph, optionally with the part it fills and a skin.

    Parameters
    ----------
    graph : LatticeGraph
    part : conformal.Part, optional
        The filled part (needed for ``skin`` and for a beam lattice's clipping mesh).
    skin : float, optional
        Wall thickness of the part's skin; the printable solid is then the skin
        united with the lattice (see :mod:`conformal.skin`).
    segments : int
        Sides of every strut's polygonal profile in the stitched mesh (>= 3).

    Attributes
    ----------
    graph : LatticeGraph
    part : conformal.Part or None
    skin : float or None
    segments : int
    """

    def __init__(
        self,
        graph: LatticeGraph,
        *,
        part: Any = None,
        skin: float | None = None,
        segments: int = config.DEFAULT_SEGMENTS,
    ) -> None:
        if not isinstance(graph, LatticeGraph):
            raise TypeError(f"graph must be a LatticeGraph, got {type(graph).__name__}")
        if skin is not None:
            skin = _positive("skin", skin)
            if part is None:
                raise ValueError("a skin needs the part: use Lattice.fill(part, skin=...)")
        if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)):
            raise TypeError(f"segments must be an integer >= 3, got {segments!r}")
        if segments < 3:
            raise ValueError(f"segments must be >= 3, got {segments}")
        self.graph = graph
        self.part = part
        self.skin = skin
        #: How the skin was made and its measured wall (set when the mesh is built).
        self.skin_report: Any = None
        #: What the lattice builder did (``conformal.BuildReport``; set by :meth:`fill`).
        self.build_report: Any = None
        self.segments = int(segments)
        self.progress: bool = False

    # ---------------------------------------------------------------- build
    @classmethod
    def fill(
        cls,
        part: Any,
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
    ) -> Lattice:
        """Fill a part with a lattice.

        Parameters
        ----------
        part : build123d Part/Solid, cadquery Workplane/Shape, TopoDS_Shape, conformal.Part or path
            A path may name a STEP file or a closed mesh (STL, OBJ, PLY, 3MF, OFF).
            Coordinates are global (a cadquery Workplane's solids where they are).
        cell : str
            Unit cell name (see ``conformal.CELLS`` or ``lattice-cad cells``).
        cell_size : float
            Cell edge length (mm) for ``method="voxel"``; target element size for ``"tet"``.
        radius : float
            Strut radius (mm).
        method : {"voxel", "tet"}
            Periodic cells on a grid, or struts along the edges of a tetrahedral mesh.
        fill : {"auto", "inside", "clip", "conform"}, optional
            How the voxel lattice meets the boundary (see ``conformal.voxel_lattice``);
            default ``"clip"`` with a skin (struts reach into the wall), else ``"auto"``
            (``"inside"``, or ``"conform"`` when no whole cell fits, as in thin parts).
            Voxel only: a tet lattice always conforms (its surface nodes lie on the
            part's surface), so passing ``fill`` with ``method="tet"`` is an error.
        skin : float, optional
            Hollow the part to this wall thickness and unite the wall with the lattice.
        segments : int
            Profile sides of the stitched struts.
        origin, rotation : optional
            Placement of the cell grid (passed to ``conformal.voxel_lattice``; voxel only).
            ``cell`` is ignored by ``method="tet"``.

        Returns
        -------
        Lattice

        Raises
        ------
        conformal.PartError
            The part cannot be read or is not a closed solid.
        ValueError, TypeError
            An option out of range (named in the message).
        """
        _check_choice("method", method, ("voxel", "tet"))
        if method == "tet":
            given = [k for k, v in (("fill", fill), ("origin", origin), ("rotation", rotation))
                     if v is not None]  # fmt: skip
            if given:
                verb = "applies" if len(given) == 1 else "apply"
                raise ValueError(
                    f"{' and '.join(given)} only {verb} to method='voxel'; a tet lattice "
                    "follows the part's surface by construction (leave them out)"
                )
        if fill is None:
            fill = "clip" if skin is not None else "auto"
        _check_choice("fill", fill, ("auto", "inside", "clip", "conform"))
        if not isinstance(cell, str):
            raise TypeError(f"cell must be a cell name, got {type(cell).__name__}")
        from conformal import CELLS

        if method == "voxel" and cell not in CELLS:
            raise ValueError(f"unknown cell {cell!r}; choose from {', '.join(sorted(CELLS))}")
        cell_size = _positive("cell_size", cell_size)
        radius = _positive("radius", radius)
        if skin is not None:
            skin = _positive("skin", skin)
        the_part = _load_part(part)
        graph, report = _fill_graph(
            the_part,
            method=method,
            cell=cell,
            cell_size=cell_size,
            radius=radius,
            fill=fill,
            origin=origin,
            rotation=rotation,
        )
        lat = cls(graph, part=the_part, skin=skin, segments=segments)
        lat.build_report = report
        return lat

    def __repr__(self) -> str:
        part = f", part={getattr(self.part, 'name', 'part')!r}" if self.part is not None else ""
        skin = f", skin={self.skin:g}" if self.skin is not None else ""
        return (
            f"Lattice({self.graph.num_nodes} nodes, {self.graph.num_edges} struts, "
            f"segments={self.segments}{part}{skin})"
        )

    # ----------------------------------------------------------------- mesh
    @cached_property
    def _lattice_mesh(self) -> Mesh:
        import fast_stitch

        return fast_stitch.stitch(self.graph, self.segments, progress=self.progress)

    @cached_property
    def _solid_mesh(self) -> Mesh:
        if self.skin is None:
            return self._lattice_mesh
        from conformal import skin as _skin
        from lattice_cad.core.mesh import Mesh

        result = _skin.build_skin(self._lattice_mesh, self.part, self.skin)
        self.skin_report = result.report
        v, f = _skin.to_arrays(result.solid)
        return Mesh(vertices=v, faces=f)

    @cached_property
    def _printable_mesh(self) -> Mesh:
        import fast_stitch
        from lattice_cad import io

        self.graph.check_precision("float32")  # before stitching: STL/3MF store float32
        mesh, repaired = io.single_precision(self._solid_mesh, name="the lattice")
        # a stitched lattice keeps its clearances through the rounding; a skin (manifold3d
        # booleans) can have surfaces a float32 step apart, so it is checked in full
        if repaired or self.skin is not None:
            report = fast_stitch.check(mesh)
            for _ in range(20):  # tiny folds where the booleans left needles: collapse them
                if report.valid or self.skin is None:
                    break
                mesh = _collapse_folds(mesh, report)
                report = fast_stitch.check(mesh)
            if not report.valid:
                raise ExportError(
                    f"the lattice cannot be written in single precision (STL, 3MF): rounding "
                    f"its coordinates to float32 breaks it ({report}); move it closer to the "
                    "origin or use thicker struts"
                )
        return mesh

    def mesh(self, *, lattice_only: bool = False) -> Mesh:
        """The printable watertight mesh (built on first use, then cached).

        Its vertices are exactly representable in single precision (as STL and 3MF store
        them), so every file written from it is the mesh that was checked.

        Parameters
        ----------
        lattice_only : bool
            Without the skin even if the lattice has one.

        Returns
        -------
        fast_stitch.Mesh
            The stitched lattice, or (with a skin) the union of skin and lattice.
        """
        return self._lattice_mesh if lattice_only else self._printable_mesh

    # ---------------------------------------------------------------- files
    def save(self, path: str | os.PathLike[str], *, beam_lattice: bool = False) -> Path:
        """Write the lattice; the format is chosen by the suffix.

        Parameters
        ----------
        path : path-like
            ``.stl``, ``.3mf``, ``.ply``, ``.obj``: the printable mesh;
            ``.json``, ``.npz``: the graph; ``.step``/``.stp``: the exact B-rep reference.
        beam_lattice : bool
            With ``.3mf``: write the 3MF Beam Lattice extension (beams, balls and the
            part as clipping mesh) instead of triangles. A skin is then written as
            a separate mesh object.

        Returns
        -------
        Path
        """
        from lattice_cad import io

        p = Path(path)
        if beam_lattice:
            io.format_for(p, Kind.BEAM_LATTICE)
            clip = None
            if self.part is not None:
                clip = (self.part.vertices, self.part.faces)
            return io.save_beam_lattice(self.graph, p, clip=clip)
        _, kind = resolve(p, (Kind.MESH, Kind.GRAPH, Kind.SOLIDS), what="lattice")
        if kind is Kind.GRAPH:
            return io.save_graph(self.graph, p)
        if kind is Kind.SOLIDS:
            return self.reference().save(p)
        return io.save_mesh(self.mesh(), p)

    # ------------------------------------------------------------ reference
    def reference(self, **options: Any) -> Any:
        """The exact B-rep reference (``reference_boolean.build_reference``), cached."""
        cached = self.__dict__.get("_reference")
        if cached is None or options:
            from reference_boolean import build_reference

            cached = build_reference(self.graph, **options)
            if not options:
                self.__dict__["_reference"] = cached
        return cached

    def validate(self, report: str | os.PathLike[str] | None = None, **options: Any) -> Any:
        """Compare the stitched mesh with the exact reference (see ``lattice_cad.validate``).

        Parameters
        ----------
        report : path-like, optional
            Write the report there (``.html``, ``.md`` or ``.json``).
        **options
            More keyword arguments of :func:`lattice_cad.validate.validate`.

        Returns
        -------
        reference_boolean.ValidationReport
        """
        from lattice_cad.validate import validate

        return validate(self.graph, self.segments, report=report, **options)

    def _brep_compound(self, max_struts: int) -> Any:
        if self.graph.num_edges > max_struts:
            raise LatticeError(
                f"the lattice has {self.graph.num_edges} struts; B-rep solids are built for at "
                f"most {max_struts} (pass max_struts= to go further, or use mesh())"
            )
        from lattice_cad.occ_impl import shapes as occ

        ref = self.reference()
        if ref.failed:
            node, why = next(iter(ref.failed.items()))
            raise LatticeError(f"the B-rep of node {node} could not be built: {why}")
        cache: dict[int, Any] = {}
        shapes = []
        for n in range(self.graph.num_nodes):
            t = int(ref.node_template[n])
            if t < 0:
                continue
            if t not in cache:
                cache[t] = occ.from_bytes(ref.breps[t])
            shapes.append(occ.translated(cache[t], self.graph.nodes[n]))
        if len(shapes) == 1:
            return shapes[0]
        try:
            return occ.fuse(shapes, simplify=True)
        except OCCTFailure as exc:
            raise LatticeError(f"OCCT could not fuse the hub solids of the lattice: {exc}") from exc

    def to_workplane(self, *, max_struts: int = config.MAX_BREP_STRUTS) -> cq.Workplane:
        """The exact lattice solid as a CadQuery Workplane (small lattices only).

        The hub solids of the exact reference are fused into one B-rep, usable
        in further CadQuery booleans (e.g. ``part.cut(...)``, ``.union(...)``).

        Raises
        ------
        LatticeError
            More than ``max_struts`` struts, or a hub that OCCT could not build.
        """
        import cadquery as cq

        return cq.Workplane("XY").newObject([cq.Shape.cast(self._brep_compound(max_struts))])

    def to_part(self, *, max_struts: int = config.MAX_BREP_STRUTS) -> Any:
        """The exact lattice solid as a build123d shape (small lattices only).

        See :meth:`to_workplane`.
        """
        import build123d as bd

        shape = self._brep_compound(max_struts)
        from lattice_cad.occ_impl.shapes import is_compound

        # build123d 0.10's Shape.cast gives None for a plain TopoDS_Shape: wrap by type
        if is_compound(shape):
            return bd.Compound(shape)
        return bd.Solid(shape)

    # ----------------------------------------------------------------- info
    def strut_volume(self) -> float:
        """Sum of the struts' frustum volumes (overlaps at nodes counted twice)."""
        g = self.graph
        r0, r1 = g.radii[:, 0], g.radii[:, 1]
        return float(np.sum(math.pi * g.edge_lengths * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0))

    def info(self) -> dict[str, Any]:
        """Counts, volume, relative density and estimated file sizes.

        Returns
        -------
        dict
            ``nodes``, ``struts``, ``vertices`` and ``triangles`` (of the stitched
            lattice, exact before building it), ``volume`` (mm^3: of the mesh if built,
            else the strut-volume estimate), ``volume_exact`` (whether it is the mesh's),
            ``part_volume`` and ``relative_density`` (when the part is known), ``skin``,
            and ``file_bytes``: estimated sizes of ``stl``, ``3mf``, ``ply``, ``obj``
            and ``3mf_beam`` files of the lattice (without skin).
        """
        import fast_stitch
        from lattice_cad import io as export

        g = self.graph
        est = fast_stitch.estimate(g, self.segments)
        built = "_solid_mesh" in self.__dict__ or (
            self.skin is None and "_lattice_mesh" in self.__dict__
        )
        volume = self.mesh().volume if built else self.strut_volume()
        out: dict[str, Any] = {
            "nodes": g.num_nodes,
            "struts": g.num_edges,
            "segments": self.segments,
            "vertices": est.vertices,
            "triangles": est.triangles,
            "volume": volume,
            "volume_exact": built,
            "skin": self.skin,
        }
        if self.part is not None:
            pv = float(self.part.volume)
            out["part_volume"] = pv
            out["relative_density"] = volume / pv if pv > 0 else None
        n_used = int(np.count_nonzero(g.degree))
        out["file_bytes"] = {
            s.lstrip("."): export.estimate_bytes(s, est.vertices, est.triangles)
            for s in export.MESH_SUFFIXES
        }
        out["file_bytes"]["3mf_beam"] = export.estimate_bytes(
            ".3mf", n_used, 0, n_beams=g.num_edges
        )
        return out
