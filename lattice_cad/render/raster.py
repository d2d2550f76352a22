"""A software rasteriser: shaded, lit images of triangle meshes, with no display and no GPU.

Every layer is projected orthographically, z-buffered by a numba kernel into a
G-buffer (depth, normal, scalar, layer id) at twice the output resolution, then
shaded in numpy: two lights plus ambient, a little specular, a depth-based
ambient-occlusion term and dark outlines where depth jumps (so overlapping
struts stay apart). Ghost layers (the part around a lattice) are drawn as a
translucent shell over the solid layers, more opaque at grazing angles, with
their silhouette outlined. A section plane removes everything on the camera's
side of it; surfaces seen from inside through the cut are darker.

The result is an ``(H, W, 3)`` float image in [0, 1]; :mod:`lattice_cad.render.figure`
adds the colour bar, captions and markers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["Layer", "Camera", "Section", "VIEWS", "camera_for", "shade"]

#: Named views: (azimuth, elevation) of the camera in degrees, z up (the build direction).
VIEWS: dict[str, tuple[float, float]] = {
    "iso": (-60.0, 30.0),
    "front": (-90.0, 0.0),
    "back": (90.0, 0.0),
    "right": (0.0, 0.0),
    "left": (180.0, 0.0),
    "top": (-90.0, 90.0),
    "bottom": (-90.0, -90.0),
}

#: Supersampling factor per axis (2: four samples per output pixel).
SUPERSAMPLE = 2

#: Flat background (a gradient would band in the 256-colour PNG).
BACKGROUND = (0.955, 0.962, 0.972)


@dataclass
class Layer:
    """One triangle surface of a picture.

    Attributes
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    normals : (V, 3) float32, optional
        Unit vertex normals; area-weighted from the faces when None.
    scalars : (V,) float64, optional
        A quantity per vertex, coloured through the picture's colour map
        (NaN: the layer's colour).
    color : (3,) float
        RGB in [0, 1] where there is no scalar.
    style : "solid" or "ghost"
        A ghost is a translucent shell drawn over the solid layers.
    closed : bool
        A closed, outward-oriented surface: its back faces are skipped when
        no section cuts it (twice as fast, same picture).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    normals: NDArray[np.float32] | None = None
    scalars: NDArray[np.float64] | None = None
    color: tuple[float, float, float] = (0.62, 0.66, 0.72)
    style: Literal["solid", "ghost"] = "solid"
    closed: bool = False

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if self.scalars is not None:
            self.scalars = np.asarray(self.scalars, dtype=np.float64).reshape(-1)
            if len(self.scalars) != len(self.vertices):
                raise ValueError(
                    f"scalars has {len(self.scalars)} values for {len(self.vertices)} vertices"
                )

    def vertex_normals(self) -> NDArray[np.float32]:
        """(V, 3) float32 unit normals (the given ones, or area-weighted from the faces)."""
        if self.normals is None:
            from lattice_cad.render import _kernels

            self.normals = _kernels.vertex_normals(self.vertices, self.faces)
        return np.ascontiguousarray(self.normals, dtype=np.float32)


@dataclass(frozen=True)
class Section:
    """A cut-away: everything on the camera's side of ``x[axis] = value`` is removed."""

    axis: int
    value: float

    @property
    def name(self) -> str:
        return f"{'xyz'[self.axis]} = {self.value:.4g} mm"


@dataclass
class Camera:
    """An orthographic camera framed on a box.

    ``right``, ``up`` and ``back`` are orthonormal world vectors (``back``
    points from the scene to the camera); a world point ``p`` lands on pixel
    ``(W / 2 + (p . right - cx) * scale, H / 2 - (p . up - cy) * scale)``.
    """

    right: NDArray[np.float64]
    up: NDArray[np.float64]
    back: NDArray[np.float64]
    centre: tuple[float, float] = (0.0, 0.0)
    scale: float = 1.0
    size: tuple[int, int] = (800, 600)
    view: str = "iso"
    extra: dict[str, float] = field(default_factory=dict)

    def project(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 3) world points to (N, 3) pixel x, pixel y (down) and depth (far is larger)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        w, h = self.size
        x = (p @ self.right - self.centre[0]) * self.scale + 0.5 * w
        y = 0.5 * h - (p @ self.up - self.centre[1]) * self.scale
        return np.stack([x, y, -(p @ self.back)], axis=1)


def _basis(azimuth: float, elevation: float) -> tuple[NDArray[np.float64], ...]:
    az, el = np.radians(azimuth), np.radians(elevation)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    ref = np.array([0.0, 0.0, 1.0]) if abs(back[2]) < 0.999 else np.array([0.0, 1.0, 0.0])
    right = np.cross(ref, back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return right, up, back


def camera_for(
    layers: list[Layer],
    *,
    view: str | tuple[float, float] = "iso",
    size: tuple[int, int] = (800, 600),
    margin: float = 0.04,
    section: Section | None = None,
) -> Camera:
    """A camera looking at every vertex of ``layers`` from ``view``, filling the frame.

    Parameters
    ----------
    layers : list of Layer
    view : str or (float, float)
        A name of :data:`VIEWS` or (azimuth, elevation) in degrees.
    size : (int, int)
        Width and height of the image in pixels.
    margin : float
        Free border on each side, as a fraction of the image.
    section : Section, optional
        Frame only what the section keeps (the far side of the plane).
    """
    if isinstance(view, str):
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}: use one of {', '.join(VIEWS)}")
        az, el = VIEWS[view]
        name = view
    else:
        az, el = float(view[0]), float(view[1])
        name = f"azimuth {az:g}, elevation {el:g}"
    right, up, back = _basis(az, el)
    pts = [layer.vertices for layer in layers if len(layer.faces)]
    if section is not None:
        sign = 1.0 if back[section.axis] >= 0 else -1.0
        kept = [v[sign * (v[:, section.axis] - section.value) <= 0] for v in pts]
        if any(len(v) for v in kept):
            pts = [v for v in kept if len(v)]
    if not pts:
        raise ValueError("nothing to draw: every layer is empty")
    # the frame follows the 8 corners of each layer's box in camera axes (exact for x and y)
    lo_x, hi_x, lo_y, hi_y = np.inf, -np.inf, np.inf, -np.inf
    for v in pts:
        x = v @ right
        y = v @ up
        lo_x, hi_x = min(lo_x, float(x.min())), max(hi_x, float(x.max()))
        lo_y, hi_y = min(lo_y, float(y.min())), max(hi_y, float(y.max()))
    w, h = size
    span_x = max(hi_x - lo_x, 1e-9)
    span_y = max(hi_y - lo_y, 1e-9)
    scale = min(w * (1 - 2 * margin) / span_x, h * (1 - 2 * margin) / span_y)
    centre = (0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y))
    return Camera(right, up, back, centre, float(scale), (int(w), int(h)), name)


def _colormap(name: str) -> NDArray[np.float64]:
    from matplotlib import colormaps

    return np.asarray(colormaps[name](np.linspace(0.0, 1.0, 256))[:, :3], dtype=np.float64)


def _blur(a: NDArray[np.float32], sigma: float) -> NDArray[np.float32]:
    """Gaussian blur of ``a`` (H, W), computed at a quarter of the resolution."""
    from scipy.ndimage import gaussian_filter

    h, w = a.shape
    k = 4 if min(h, w) >= 64 else 1
    hh, ww = h // k * k, w // k * k
    small = a[:hh, :ww].reshape(hh // k, k, ww // k, k).mean(axis=(1, 3))
    small = gaussian_filter(small, sigma / k, mode="nearest")
    out = np.empty_like(a)
    out[:hh, :ww] = np.repeat(np.repeat(small, k, axis=0), k, axis=1)
    out[hh:, :] = out[hh - 1 : hh, :] if hh < h else out[hh:, :]
    out[:, ww:] = out[:, ww - 1 : ww] if ww < w else out[:, ww:]
    return out.astype(np.float32)


class _GBuffer:
    def __init__(self, w: int, h: int) -> None:
        self.depth = np.full((h, w), np.inf, dtype=np.float32)
        self.normal = np.zeros((h, w, 3), dtype=np.float32)
        self.scalar = np.full((h, w), np.nan, dtype=np.float32)
        self.ids = np.zeros((h, w), dtype=np.int16)

    def draw(
        self,
        cam: Camera,
        layer: Layer,
        layer_id: int,
        section: Section | None,
    ) -> int:
        import numba

        from lattice_cad.render import _kernels

        if len(layer.faces) == 0:
            return 0
        s = cam.project(layer.vertices).astype(np.float32)
        n = layer.vertex_normals()
        basis = np.stack([cam.right, cam.up, cam.back], axis=1).astype(np.float32)
        ncam = np.ascontiguousarray(n @ basis)
        if layer.scalars is None:
            sc = np.full(len(layer.vertices), np.nan, dtype=np.float32)
        else:
            sc = layer.scalars.astype(np.float32)
        if section is None:
            cut = np.zeros(len(layer.vertices), dtype=np.float32)
        else:
            side = float(cam.back[section.axis])
            sign = 1.0 if side >= 0 else -1.0
            cut = (sign * (layer.vertices[:, section.axis] - section.value)).astype(np.float32)
        return int(
            _kernels.rasterise(
                np.ascontiguousarray(s[:, 0]),
                np.ascontiguousarray(s[:, 1]),
                np.ascontiguousarray(s[:, 2]),
                layer.faces,
                ncam,
                sc,
                cut,
                layer_id,
                bool(layer.closed and section is None),
                self.depth,
                self.normal,
                self.scalar,
                self.ids,
                2 * numba.get_num_threads(),
                float(cam.scale),
            )
        )


def shade(
    layers: list[Layer],
    cam: Camera,
    *,
    section: Section | None = None,
    colormap: str = "viridis",
    limits: tuple[float, float] | None = None,
) -> tuple[NDArray[np.float64], dict[str, int]]:
    """Render ``layers`` through ``cam``.

    Parameters
    ----------
    layers : list of Layer
    cam : Camera
        From :func:`camera_for`; ``cam.size`` is the output size.
    section : Section, optional
        Cut away the camera's side of this plane (every layer).
    colormap : str
        A matplotlib colour map name for the layers' scalars.
    limits : (float, float), optional
        Scalar values at the two ends of the colour map; the range of the
        scalars when None.

    Returns
    -------
    image : (H, W, 3) float64
        RGB in [0, 1].
    stats : dict
        ``fragments`` written by the rasteriser (solid and ghost) and
        ``triangles`` drawn.
    """
    from lattice_cad.render import _kernels

    w, h = cam.size
    ss = SUPERSAMPLE
    big = Camera(
        cam.right, cam.up, cam.back, cam.centre, cam.scale * ss, (w * ss, h * ss), cam.view
    )
    solid, ghost = _GBuffer(w * ss, h * ss), _GBuffer(w * ss, h * ss)
    fragments, triangles = 0, 0
    colors = np.zeros((len(layers) + 1, 3), dtype=np.float32)
    for i, layer in enumerate(layers, start=1):
        colors[i] = layer.color
        is_ghost = layer.style == "ghost" and section is None
        if layer.style == "ghost" and section is not None:
            # a cut-away shows the part opaque (lighter, so that the lattice stands out)
            colors[i] = 0.6 + 0.4 * np.asarray(layer.color)
        fragments += (ghost if is_ghost else solid).draw(big, layer, i, section)
        triangles += len(layer.faces)

    image = np.empty((h * ss, w * ss, 3), dtype=np.float32)
    image[:] = BACKGROUND
    hit = solid.ids != 0
    px_mm = 1.0 / big.scale  # millimetres per (supersampled) pixel
    lo, hi = 0.0, 1.0
    if hit.any():
        s = solid.scalar[hit]
        s = s[np.isfinite(s)]
        if limits is not None:
            lo, hi = float(limits[0]), float(limits[1])
        elif len(s):
            lo, hi = float(s.min()), float(s.max())
        # ambient occlusion from the depth buffer: darker where a pixel lies behind its
        # neighbourhood (inner struts, corners)
        far = np.float32(solid.depth[hit].max() + 4 * px_mm)
        d = np.where(hit, solid.depth, far)
        occl = np.clip((d - _blur(d, 6.0 * ss)) / np.float32(20 * px_mm), 0.0, 1.0)
    else:
        occl = np.zeros(solid.depth.shape, dtype=np.float32)
    _kernels.composite(
        image,
        solid.depth,
        solid.normal,
        solid.scalar,
        solid.ids,
        occl.astype(np.float32),
        ghost.depth,
        ghost.normal,
        ghost.ids,
        colors,
        _colormap(colormap).astype(np.float32),
        lo,
        hi,
        3.0 * px_mm * ss,
        6.0 * px_mm * ss,
    )
    out = image.reshape(h, ss, w, ss, 3).mean(axis=(1, 3))
    return np.clip(out, 0.0, 1.0).astype(np.float64), {
        "fragments": fragments,
        "triangles": triangles,
    }
