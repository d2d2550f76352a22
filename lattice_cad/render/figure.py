"""Pictures: rendered panels, colour bar, markers and caption in one PNG.

The panels come from :func:`lattice_cad.render.raster.shade`; matplotlib's Agg
canvas (no pyplot, no display) lays them out 1:1 in pixels and adds the text.
The PNG is reduced to an adaptive 256-colour palette (Pillow), which keeps a
1200 x 900 picture around 100-200 KB.
"""

from __future__ import annotations

import io
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.render.raster import BACKGROUND, Camera, Layer, Section, camera_for, shade

__all__ = ["ColorBar", "Marker", "Panel", "picture"]

_VIEW_TITLES = {"iso": "isometric", "top": "top", "front": "front", "right": "right"}


@dataclass(frozen=True)
class ColorBar:
    """What the layers' scalars mean: a label with units, the range and the colour map.

    ``threshold`` draws a mark on the bar (e.g. 45 degrees for overhangs).
    """

    label: str
    limits: tuple[float, float]
    colormap: str = "viridis"
    threshold: float | None = None


@dataclass(frozen=True)
class Marker:
    """A numbered mark at a world point (e.g. a worst place), drawn on every panel.

    ``color`` is the ring's and the label's colour (default red).
    """

    point: tuple[float, float, float]
    label: str
    color: str = "#d62728"


@dataclass(frozen=True)
class Panel:
    """One view of the picture: a named view (see ``raster.VIEWS``) and an optional section."""

    view: str = "iso"
    section: Section | None = None

    @property
    def title(self) -> str:
        name = _VIEW_TITLES.get(self.view, self.view)
        return f"{name}, section {self.section.name}" if self.section else name


def _bands(n_panels: int, size: tuple[int, int], colorbar: bool, title: bool) -> dict[str, Any]:
    w, h = size
    top = 34 if title else 8
    bottom = 26 + (78 if colorbar else 0)
    ph = max(h - top - bottom, 32)
    pw = max(w // n_panels, 32)
    return {"top": top, "bottom": bottom, "panel": (pw, ph)}


def picture(
    layers: list[Layer],
    *,
    panels: Sequence[Panel] = (Panel(),),
    size: tuple[int, int] = (1200, 900),
    colorbar: ColorBar | None = None,
    title: str | None = None,
    caption: str | None = None,
    markers: Sequence[Marker] = (),
) -> tuple[bytes, dict[str, Any]]:
    """Render ``layers`` in one or more panels and return the PNG bytes.

    Parameters
    ----------
    layers : list of Layer
    panels : sequence of Panel
        Side by side, left to right (e.g. isometric, then a section).
    size : (int, int)
        Width and height of the whole picture in pixels.
    colorbar : ColorBar, optional
        Colours the layers' scalars; without it, scalars are ignored.
    title, caption : str, optional
        A line above and a line below the panels.
    markers : sequence of Marker
        Numbered marks, projected into every panel.

    Returns
    -------
    png : bytes
    info : dict
        ``seconds`` (render + layout), ``fragments`` and ``triangles`` drawn,
        ``cameras`` (one :class:`Camera` per panel).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t0 = time.perf_counter()
    if not panels:
        raise ValueError("a picture needs at least one panel")
    w, h = int(size[0]), int(size[1])
    if w < 64 or h < 64:
        raise ValueError(f"picture size must be at least 64 x 64 pixels, got {w} x {h}")
    bands = _bands(len(panels), (w, h), colorbar is not None, bool(title))
    pw, ph = bands["panel"]
    if colorbar is None:
        layers = [_no_scalars(layer) for layer in layers]
    dpi = 100
    fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    fig.patch.set_facecolor(BACKGROUND)
    info: dict[str, Any] = {"fragments": 0, "triangles": 0, "cameras": []}
    for i, panel in enumerate(panels):
        cam = camera_for(layers, view=panel.view, size=(pw, ph), section=panel.section)
        img, stats = shade(
            layers,
            cam,
            section=panel.section,
            colormap=colorbar.colormap if colorbar else "viridis",
            limits=colorbar.limits if colorbar else None,
        )
        info["fragments"] += stats["fragments"]
        info["triangles"] = stats["triangles"]
        info["cameras"].append(cam)
        ax = fig.add_axes(
            (i * pw / w, bands["bottom"] / h, pw / w, ph / h), frameon=False, xticks=[], yticks=[]
        )
        ax.imshow(img, interpolation="nearest", extent=(0, pw, ph, 0))
        ax.set_xlim(0, pw)
        ax.set_ylim(ph, 0)
        if len(panels) > 1 or panel.section is not None:
            ax.text(8, 8, panel.title, va="top", ha="left", fontsize=10, color="0.25")
        _draw_markers(ax, cam, markers)
    if title:
        fig.text(0.5, 1 - 8 / h, title, ha="center", va="top", fontsize=13, color="0.1")
    if colorbar is not None:
        _draw_colorbar(fig, colorbar, (w, h), bands)
    if caption:
        fig.text(8 / w, 5 / h, caption, ha="left", va="bottom", fontsize=8.5, color="0.35")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    keep = None
    if colorbar is not None:
        from matplotlib import colormaps

        keep = colormaps[colorbar.colormap](np.linspace(0, 1, 64))[:, :3]
    png = _palette_png(buf.getvalue(), keep)
    info["seconds"] = time.perf_counter() - t0
    return png, info


def _no_scalars(layer: Layer) -> Layer:
    if layer.scalars is None:
        return layer
    return Layer(
        layer.vertices,
        layer.faces,
        layer.normals,
        None,
        layer.color,
        layer.style,
        layer.closed,
    )


def _draw_markers(ax: Any, cam: Camera, markers: Sequence[Marker]) -> None:
    if not markers:
        return
    p = cam.project(np.array([m.point for m in markers], dtype=np.float64))
    ax.scatter(
        p[:, 0],
        p[:, 1],
        s=150,
        facecolors="none",
        edgecolors=[m.color for m in markers],
        linewidths=2.0,
        zorder=3,
    )
    for (x, y, _), m in zip(p, markers, strict=True):
        ax.annotate(
            m.label,
            (x, y),
            xytext=(9, -9),
            textcoords="offset points",
            color="#b01010" if m.color == "#d62728" else m.color,
            fontsize=10,
            fontweight="bold",
            zorder=4,
        )


def _draw_colorbar(fig: Any, cb: ColorBar, size: tuple[int, int], bands: dict[str, Any]) -> None:
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    w, h = size
    lo, hi = cb.limits
    if not hi > lo:
        lo, hi = lo - 0.5 * max(abs(lo), 1e-9), hi + 0.5 * max(abs(hi), 1e-9)
    cax = fig.add_axes((0.25, (bands["bottom"] - 28) / h, 0.5, 16 / h))
    sm = ScalarMappable(norm=Normalize(lo, hi), cmap=colormaps[cb.colormap])
    bar = fig.colorbar(sm, cax=cax, orientation="horizontal")
    bar.set_label(cb.label, fontsize=10)
    bar.ax.tick_params(labelsize=9)
    if cb.threshold is not None and lo < cb.threshold < hi:
        cax.axvline(cb.threshold, color="black", lw=2)


def _palette_png(data: bytes, keep: NDArray[np.float64] | None = None) -> bytes:
    """The PNG reduced to a 256-colour palette (about a third of the size, same look).

    The palette is adaptive (Pillow's octree) for 256 - len(keep) colours, plus
    the colours ``keep`` (N, 3) in [0, 1] (a colour bar's, so that it stays smooth).
    """
    from PIL import Image

    img = Image.open(io.BytesIO(data)).convert("RGB")
    extra = np.zeros((0, 3), dtype=np.uint8)
    if keep is not None and len(keep):
        extra = np.clip(np.asarray(keep) * 255 + 0.5, 0, 255).astype(np.uint8).reshape(-1, 3)
    adaptive = img.quantize(
        colors=256 - len(extra), method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE
    )
    palette = adaptive.getpalette()
    if palette is None:  # quantize returns a "P" image, which has one
        raise RuntimeError("Pillow's quantize returned an image without a palette")
    pal = np.asarray(palette[: 3 * (256 - len(extra))], dtype=np.uint8)
    pal = np.concatenate([pal.reshape(-1, 3), extra]).reshape(-1)
    # exact nearest palette colour of every distinct colour of the picture (Pillow's own
    # mapping works on a coarse colour grid and would band the colour bar)
    from scipy.spatial import cKDTree

    rgb = np.asarray(img, dtype=np.uint8)
    r, g, b = (rgb[..., k].astype(np.int32) for k in range(3))
    packed = (r << 16) | (g << 8) | b
    uniq, inv = np.unique(packed.reshape(-1), return_inverse=True)
    cols = np.stack([(uniq >> 16) & 255, (uniq >> 8) & 255, uniq & 255], axis=1)
    _, nearest = cKDTree(pal.reshape(-1, 3).astype(np.float64)).query(cols.astype(np.float64))
    index = nearest.astype(np.uint8)[inv.reshape(-1)].reshape(rgb.shape[:2])
    q = Image.fromarray(index, mode="P")
    q.putpalette(pal.tolist())
    out = io.BytesIO()
    q.save(out, format="PNG", compress_level=9)
    return out.getvalue()


def as_points(points: ArrayLike) -> list[tuple[float, float, float]]:
    """(N, 3) points as a list of tuples (for :class:`Marker`)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return [(float(a), float(b), float(c)) for a, b, c in p]
