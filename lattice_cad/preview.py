"""Offscreen pictures (PNG) of lattices, meshes and parts.

Two styles:

* ``"shaded"`` (default): lit, shaded renders from :mod:`lattice_cad.render`
  (a software rasteriser: no display, no GPU, no extra package). A graph is
  drawn as tubes (one per strut, a ball per node), a mesh as its surface, a
  part as a translucent ghost around the lattice; the picture is framed on the
  object, can be cut away (``section="z"`` or ``"z=12.5"``) and coloured by
  strut radius or by the struts' angle to the build plate, with a colour bar.
* ``"wireframe"``: the former matplotlib 3D line drawing (one line per strut,
  flat-shaded triangles), kept as a fallback.

Large meshes are simplified for display only (vertex clustering above
``max_triangles``; the caption says so); the saved files are never touched.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.graph import LatticeGraph

__all__ = ["render", "render_png", "save_png", "load_for_preview", "parse_section"]

#: Default caps on what the wireframe style draws (keeps a 1M-triangle mesh under a few
#: seconds). Meshes with more triangles are simplified by vertex clustering (never by dropping
#: faces).
MAX_TRIANGLES = 300_000
MAX_STRUTS = 60_000
#: The shaded style draws meshes up to this many triangles as they are, larger ones are
#: simplified for display (vertex clustering) to about this many.
MAX_SHADED_TRIANGLES = 40_000_000
#: Graphs with more struts are drawn as 6-sided tubes without balls at the nodes.
MAX_TUBE_STRUTS = 400_000

Style = Literal["shaded", "wireframe"]
ColorBy = Literal["auto", "radius", "overhang", "none"]


def _subset(n: int, k: int) -> NDArray[np.int64]:
    """Evenly spread indices of ``k`` of ``n`` items (all of them when ``n <= k``)."""
    if n <= k:
        return np.arange(n, dtype=np.int64)
    return np.unique(np.linspace(0, n - 1, k).astype(np.int64))


def _cluster(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], max_triangles: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Simplify a mesh to about ``max_triangles`` by vertex clustering (numpy only).

    Vertices are snapped to the cells of a uniform grid (each cell's vertices
    merge into their mean), faces that collapse are dropped, and so are the
    coincident faces left where a thin slab collapsed (in pairs). The surface
    stays closed, unlike dropping faces; the grid is coarsened until the count
    fits.
    """
    lo = vertices.min(axis=0)
    ext = np.maximum(vertices.max(axis=0) - lo, 1e-12)
    # triangles scale like 1/cell^2: start from the area-based estimate, coarsen as needed
    cell = (
        0.4
        * float(np.cbrt(np.prod(ext) / max(len(vertices), 1)))
        * np.sqrt(len(faces) / max_triangles)
    )
    for _ in range(40):
        ijk = np.floor((vertices - lo) / cell).astype(np.int64)
        dims = ijk.max(axis=0) + 1
        key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
        uniq, inv = np.unique(key, return_inverse=True)
        f = inv.reshape(-1)[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        # triangles on the same vertex set come from collapsed slabs (a pair of opposite
        # faces): drop them in pairs, which keeps every edge on an even number of faces,
        # so the surface stays closed (dropping all of an odd set, e.g. three where a
        # strut's band and hub rings collapse together, would open it)
        _, first, inv_f, cnt = np.unique(
            np.sort(f, axis=1), axis=0, return_index=True, return_inverse=True, return_counts=True
        )
        inv_f = inv_f.reshape(-1)
        f = f[(cnt[inv_f] % 2 == 1) & (first[inv_f] == np.arange(len(f)))]
        if len(f) <= max_triangles:
            count = np.bincount(inv, minlength=len(uniq)).astype(np.float64)
            v = np.stack(
                [np.bincount(inv, weights=vertices[:, k], minlength=len(uniq)) for k in range(3)],
                axis=1,
            )
            return v / count[:, None], f
        cell *= 1.2
    raise AssertionError("unreachable: a coarse enough grid always fits")  # pragma: no cover


def _axes_limits(ax: Any, lo: NDArray[np.float64], hi: NDArray[np.float64]) -> None:
    centre = 0.5 * (lo + hi)
    half = 0.5 * float(max(np.max(hi - lo), 1e-9))
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")


def _draw_graph(ax: Any, fig: Any, graph: LatticeGraph, max_struts: int) -> str:
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    idx = _subset(graph.num_edges, max_struts)
    segs = graph.nodes[graph.edges[idx]]
    r = graph.radii[idx].mean(axis=1)
    lo, hi = (float(r.min()), float(r.max())) if len(r) else (0.0, 1.0)
    norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1e-9)
    cmap = colormaps["viridis"]
    width = 0.4 + 1.6 * (r - lo) / (hi - lo) if hi > lo else np.full(len(r), 1.0)
    ax.add_collection3d(Line3DCollection(segs, colors=cmap(norm(r)), linewidths=width))
    if hi > lo:
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.6, label="radius (mm)")
    b = graph.bounds
    _axes_limits(ax, b[0], b[1])
    shown = "" if len(idx) == graph.num_edges else f" ({len(idx):,} shown)"
    return f"{graph.num_edges:,} struts{shown}"


def _draw_mesh(
    ax: Any, vertices: NDArray[np.float64], faces: NDArray[np.int64], max_triangles: int
) -> str:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    drawn = faces
    if len(faces) > max_triangles:
        v_s, drawn = _cluster(vertices, faces, max_triangles // 2)
        tri = v_s[drawn]
    else:
        tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(n, axis=1)
    unit = n / np.maximum(area, 1e-300)[:, None]
    light = np.array([0.4, -0.5, 0.75])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.clip(unit @ light, 0.0, 1.0)
    base = np.array([0.30, 0.55, 0.85])
    colors = np.clip(shade[:, None] * base[None, :], 0, 1)
    ax.add_collection3d(Poly3DCollection(tri, facecolors=colors, edgecolors="none"))
    _axes_limits(ax, vertices.min(axis=0), vertices.max(axis=0))
    shown = "" if drawn is faces else f" (simplified to {len(tri):,})"
    return f"{len(faces):,} triangles{shown}"


def load_for_preview(path: str | os.PathLike[str]) -> Any:
    """What ``lattice-cad preview`` draws for a file: a graph or ``(vertices, faces)``.

    ``.json``/``.npz`` are graphs; ``.step``/``.stp`` parts are tessellated
    (``conformal.load_part``); other suffixes are read as meshes.
    """
    p = Path(path)
    s = p.suffix.lower()
    if s in (".json", ".npz"):
        return LatticeGraph.load(p)
    if s in (".step", ".stp"):
        from conformal.part import load_part

        part = load_part(p)
        return (np.asarray(part.vertices), np.asarray(part.faces))
    from lattice_cad.io import read_mesh

    return read_mesh(p)


def _wireframe_png(
    obj: Any,
    *,
    size: tuple[int, int] = (900, 700),
    view: tuple[float, float] = (25.0, -60.0),
    title: str | None = None,
    max_triangles: int = MAX_TRIANGLES,
    max_struts: int = MAX_STRUTS,
) -> bytes:
    """A matplotlib wireframe PNG of ``obj`` (the ``"wireframe"`` style).

    Parameters
    ----------
    obj : LatticeGraph, Lattice, mesh-like, conformal.Part or path
        A ``Lattice`` is drawn as its graph; a path is read with :func:`load_for_preview`.
    size : (int, int)
        Width and height in pixels.
    view : (float, float)
        Elevation and azimuth of the camera (degrees).
    title : str, optional
        Defaults to a count of what is drawn.
    max_triangles, max_struts : int
        Caps on what is drawn.

    Returns
    -------
    bytes
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if isinstance(obj, (str, os.PathLike)):
        obj = load_for_preview(obj)
    if hasattr(obj, "graph") and isinstance(obj.graph, LatticeGraph):
        obj = obj.graph
    dpi = 100
    fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    ax.view_init(elev=view[0], azim=view[1])
    if isinstance(obj, LatticeGraph):
        if obj.num_edges == 0:
            raise ValueError("cannot draw an empty graph (no struts)")
        what = _draw_graph(ax, fig, obj, max_struts)
    else:
        from lattice_cad.core.mesh import mesh_arrays

        arrays = mesh_arrays(obj)
        if arrays is None:
            raise TypeError(f"cannot draw a {type(obj).__name__}")
        v, f = arrays
        if len(f) == 0:
            raise ValueError("cannot draw an empty mesh (no triangles)")
        what = _draw_mesh(ax, v, f, max_triangles)
    ax.set_title(title if title is not None else what)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def save_png(obj: Any, path: str | os.PathLike[str], **options: Any) -> Path:
    """Render ``obj`` (see :func:`render_png`) to a PNG file, atomically."""
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise ValueError(f"preview pictures are PNG files; got {p.name!r}")
    data = render_png(obj, **options)
    with atomic_write(p, "wb") as fh:
        fh.write(data)
    return p


render = save_png


# ------------------------------------------------------------------------ shaded
def parse_section(text: str) -> tuple[int, float | None]:
    """``"x"``, ``"y"``, ``"z"`` or ``"z=12.5"`` -> (axis, value or None for the middle)."""
    t = str(text).strip().lower().replace(" ", "")
    axis, _, value = t.partition("=")
    if axis not in ("x", "y", "z"):
        raise ValueError(f"section must be x, y or z, optionally with =VALUE (mm); got {text!r}")
    if not value:
        return "xyz".index(axis), None
    try:
        return "xyz".index(axis), float(value)
    except ValueError:
        raise ValueError(f"section value must be a number of mm; got {text!r}") from None


def _graph_layer(graph: LatticeGraph, color_by: str, colorbar: list[Any]) -> tuple[Any, str]:
    from lattice_cad.render import ColorBar, Layer, node_values, strut_angles, tubes

    radii = graph.radii
    if color_by == "auto":
        graded = float(radii.max() - radii.min()) > 1e-9 * max(float(radii.max()), 1e-300)
        color_by = "radius" if graded else "none"
    end_values = node_scalars = None
    if color_by == "radius":
        end_values = radii
        colorbar.append(
            ColorBar("strut radius (mm)", (float(radii.min()), float(radii.max())), "viridis")
        )
    elif color_by == "overhang":
        ang = strut_angles(graph.nodes, graph.edges)
        end_values = np.repeat(ang[:, None], 2, axis=1)
        # a ball takes the flattest (worst) strut angle at its node
        node_scalars = -node_values(graph.num_nodes, graph.edges, -end_values)
        colorbar.append(
            ColorBar(
                "strut angle to the build plate (°; below 45° overhangs)",
                (0.0, 90.0),
                "RdYlBu",
                threshold=45.0,
            )
        )
    elif color_by != "none":
        raise ValueError(f"color_by must be auto, radius, overhang or none; got {color_by!r}")
    small = graph.num_edges <= MAX_TUBE_STRUTS
    v, f, n, sc = tubes(
        graph.nodes,
        graph.edges,
        radii,
        sides=8 if small else 6,
        end_values=end_values,
        node_scalars=node_scalars,
        balls=small,
    )
    return Layer(v, f, n, sc, color=(0.80, 0.62, 0.25), closed=True), (
        f"{graph.num_edges:,} struts"
    )


def _mesh_layer(v: Any, f: Any, max_triangles: int, notes: list[str], closed: bool) -> Any:
    from lattice_cad.render import Layer

    if len(f) > max_triangles:
        n0 = len(f)
        v, f = _cluster(np.asarray(v, dtype=np.float64), np.asarray(f), max_triangles)
        notes.append(
            f"{n0:,} triangles, simplified to {len(f):,} for display only (the file is unchanged)"
        )
    else:
        notes.append(f"{len(f):,} triangles")
    return Layer(v, f, color=(0.80, 0.62, 0.25), closed=closed)


def render_png(
    obj: Any,
    *,
    size: tuple[int, int] = (1200, 900),
    view: str | tuple[float, float] = "iso",
    section: str | None = None,
    views: list[str] | tuple[str, ...] | None = None,
    part: Any = None,
    color_by: ColorBy = "auto",
    title: str | None = None,
    caption: str | None = None,
    style: Style = "shaded",
    max_triangles: int | None = None,
    max_struts: int = MAX_STRUTS,
) -> bytes:
    """A PNG picture of ``obj`` as bytes.

    Parameters
    ----------
    obj : LatticeGraph, Lattice, mesh-like, conformal.Part or path
        A ``Lattice`` is drawn as its graph with its part as a ghost; a path is
        read with :func:`load_for_preview`.
    size : (int, int)
        Width and height in pixels.
    view : str or (float, float)
        A named view (``"iso"``, ``"top"``, ``"front"``, ``"right"``, ...); the
        wireframe style takes (elevation, azimuth) in degrees.
    section : str, optional
        ``"x"``, ``"y"``, ``"z"`` (through the middle) or ``"z=12.5"`` (mm): a
        second panel cut away at that plane, showing the lattice inside the part.
    views : sequence of str, optional
        Several named views side by side (the section, if any, comes last).
    part : mesh-like, conformal.Part or path, optional
        Drawn as a translucent ghost around ``obj``.
    color_by : "auto", "radius", "overhang" or "none"
        For graphs: strut radius (``"auto"``: when the radii vary), or each
        strut's angle to the build plate (xy), with a colour bar.
    title, caption : str, optional
        The caption defaults to what is drawn (and whether it was simplified).
    style : "shaded" or "wireframe"
        ``"wireframe"`` is the former matplotlib drawing (``view`` is then
        (elevation, azimuth); ``section``, ``part`` and ``color_by`` are ignored).
    max_triangles : int, optional
        Meshes with more triangles are simplified for display (default
        :data:`MAX_SHADED_TRIANGLES`, :data:`MAX_TRIANGLES` for wireframes).
    max_struts : int
        Wireframe style only: at most this many struts are drawn.

    Returns
    -------
    bytes
    """
    if style == "wireframe":
        wf_view = view if isinstance(view, tuple) else (25.0, -60.0)
        return _wireframe_png(
            obj,
            size=size,
            view=wf_view,
            title=title,
            max_triangles=max_triangles or MAX_TRIANGLES,
            max_struts=max_struts,
        )
    if style != "shaded":
        raise ValueError(f"style must be 'shaded' or 'wireframe'; got {style!r}")
    return _shaded_png(
        obj,
        size=size,
        views=list(views) if views else [view if isinstance(view, str) else "iso"],
        section=section,
        part=part,
        color_by=color_by,
        title=title,
        caption=caption,
        max_triangles=max_triangles or MAX_SHADED_TRIANGLES,
    )


def _shaded_png(
    obj: Any,
    *,
    size: tuple[int, int],
    views: list[str],
    section: str | None,
    part: Any,
    color_by: str,
    title: str | None,
    caption: str | None,
    max_triangles: int,
) -> bytes:
    from lattice_cad.core.mesh import mesh_arrays
    from lattice_cad.render import Layer, Panel, Section, picture

    if isinstance(obj, (str, os.PathLike)):
        obj = load_for_preview(obj)
    if hasattr(obj, "graph") and isinstance(obj.graph, LatticeGraph):
        if part is None:
            part = getattr(obj, "part", None)
        obj = obj.graph
    if isinstance(part, (str, os.PathLike)):
        part = load_for_preview(part)
    layers: list[Any] = []
    colorbar: list[Any] = []
    notes: list[str] = []
    if isinstance(obj, LatticeGraph):
        if obj.num_edges == 0:
            raise ValueError("cannot draw an empty graph (no struts)")
        layer, what = _graph_layer(obj, color_by, colorbar)
        layers.append(layer)
        notes.append(what)
    else:
        arrays = mesh_arrays(obj)
        if arrays is None:
            raise TypeError(f"cannot draw a {type(obj).__name__}")
        v, f = arrays
        if len(f) == 0:
            raise ValueError("cannot draw an empty mesh (no triangles)")
        if color_by not in ("auto", "none"):
            raise ValueError(f"color_by={color_by!r} needs a lattice graph, not a mesh")
        # lattice-cad's own meshes are closed and outward (their back faces need no drawing)
        from lattice_cad.core.mesh import Mesh

        layers.append(_mesh_layer(v, f, max_triangles, notes, closed=isinstance(obj, Mesh)))
    if part is not None:
        arrays = mesh_arrays(part)
        if arrays is None:
            raise TypeError(f"cannot draw a part given as {type(part).__name__}")
        layers.append(
            Layer(arrays[0], arrays[1], style="ghost", color=(0.50, 0.58, 0.70), closed=True)
        )
        notes.append("part shown as a ghost")
    panels = [Panel(v) for v in views]
    if section is not None:
        axis, value = parse_section(section)
        if value is None:
            lo = min(float(layer.vertices[:, axis].min()) for layer in layers)
            hi = max(float(layer.vertices[:, axis].max()) for layer in layers)
            value = 0.5 * (lo + hi)
        panels.append(Panel(views[0] if len(views) == 1 else "iso", Section(axis, value)))
    png, _ = picture(
        layers,
        panels=panels,
        size=size,
        colorbar=colorbar[0] if colorbar else None,
        title=title,
        caption=caption if caption is not None else "; ".join(notes),
    )
    return png
