"""numba kernels of the software rasteriser (see :mod:`lattice_cad.render.raster`).

Every function here works on arrays already projected to the screen: ``sx``,
``sy`` are pixel coordinates (x to the right, y down, pixel centres at
``i + 0.5``) and ``sz`` is the depth (larger is farther). The projection is
orthographic, so barycentric interpolation in screen space is exact for depth,
normals and scalars.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def vertex_normals(vertices, faces):  # pragma: no cover - compiled
    """Area-weighted vertex normals, (V, 3) float32 (zero for unused vertices)."""
    n = np.zeros((vertices.shape[0], 3), dtype=np.float64)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ux = vertices[b, 0] - vertices[a, 0]
        uy = vertices[b, 1] - vertices[a, 1]
        uz = vertices[b, 2] - vertices[a, 2]
        vx = vertices[c, 0] - vertices[a, 0]
        vy = vertices[c, 1] - vertices[a, 1]
        vz = vertices[c, 2] - vertices[a, 2]
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        for k in (a, b, c):
            n[k, 0] += nx
            n[k, 1] += ny
            n[k, 2] += nz
    out = np.zeros((vertices.shape[0], 3), dtype=np.float32)
    for i in range(n.shape[0]):
        s = np.sqrt(n[i, 0] ** 2 + n[i, 1] ** 2 + n[i, 2] ** 2)
        if s > 0.0:
            out[i, 0] = n[i, 0] / s
            out[i, 1] = n[i, 1] / s
            out[i, 2] = n[i, 2] / s
    return out


@numba.njit(cache=True, error_model="numpy")
def _span(c, k, lo, hi):  # pragma: no cover - compiled
    """Narrow ``[lo, hi]`` to the x where ``c - k * x >= 0``."""
    if k > 0.0:
        hi = min(hi, c / k)
    elif k < 0.0:
        lo = max(lo, c / k)
    elif c < 0.0:
        hi = lo - 1.0
    return lo, hi


@numba.njit(cache=True)
def _near(nx, ny, nz, fx, fy, fz):  # pragma: no cover - compiled
    """The vertex normal, or the face normal where they differ by more than ~37 degrees."""
    if nx * fx + ny * fy + nz * fz < 0.8:
        return fx, fy, fz
    return nx, ny, nz


@numba.njit(cache=True, parallel=True)
def rasterise(
    sx, sy, sz, faces, normals, scalars, cut, layer, cull, depth, nbuf, sbuf, ids, bands, zscale
):  # pragma: no cover - compiled
    """Z-buffer the triangles ``faces`` into the G-buffer, in place.

    The image is split into horizontal bands drawn in parallel (each band
    owns its rows, so no two threads write the same pixel).

    Parameters
    ----------
    sx, sy, sz : (V,) float32
        Screen x, y (pixels) and depth of every vertex.
    faces : (F, 3) int64
    normals : (V, 3) float32
        Unit vertex normals in camera coordinates (z towards the viewer).
    scalars : (V,) float32
        The quantity to colour by (NaN: none).
    cut : (V,) float32
        Signed distance to the section plane; fragments where the
        interpolated value is positive are dropped (all zeros: no section).
    layer : int
        Written to ``ids`` where this layer wins the depth test; ``-layer``
        for back faces (seen through a cut).
    cull : bool
        Skip back faces (closed surfaces without a section: they are hidden).
    depth : (H, W) float32
    nbuf : (H, W, 3) float32
    sbuf : (H, W) float32
    ids : (H, W) int16
    bands : int
        Number of horizontal bands (2 x the threads is a good choice).
    zscale : float
        Pixels per depth unit (the face normals are computed in pixels). A vertex
        normal more than ~37 degrees from its face's normal is replaced by the face
        normal there (sharp edges of CAD parts stay sharp).

    Returns
    -------
    int
        The number of fragments written (a measure of the work done).
    """
    h = depth.shape[0]
    bands = max(1, min(bands, h))
    counts = np.zeros(bands, dtype=np.int64)
    for k in numba.prange(bands):
        counts[k] = _rasterise_rows(
            sx, sy, sz, faces, normals, scalars, cut, layer, cull, depth, nbuf, sbuf, ids,
            (h * k) // bands, (h * (k + 1)) // bands, zscale,
        )  # fmt: skip
    return counts.sum()


@numba.njit(cache=True, error_model="numpy")
def _rasterise_rows(
    sx, sy, sz, faces, normals, scalars, cut, layer, cull, depth, nbuf, sbuf, ids, row0, row1, zs
):  # pragma: no cover - compiled
    """:func:`rasterise` on the rows ``row0 <= y < row1`` only."""
    w = depth.shape[1]
    written = 0
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        x0, y0, x1, y1, x2, y2 = sx[a], sy[a], sx[b], sy[b], sx[c], sy[c]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0:
            continue
        # screen y points down: a positive area is a back face seen from the camera
        back = area > 0.0
        if back and cull:
            continue
        ymin = max(int(np.floor(min(y0, y1, y2))), row0)
        ymax = min(int(np.ceil(max(y0, y1, y2))), row1)
        xlo = max(min(x0, x1, x2), 0.0)
        xhi = min(max(x0, x1, x2), w - 0.5)
        if ymin >= ymax or xlo > xhi:
            continue
        inv = 1.0 / area
        k0 = (y2 - y1) * inv
        k1 = (y0 - y2) * inv
        za, zb, zc = sz[a], sz[b], sz[c]
        ca, cb, cc = cut[a], cut[b], cut[c]
        # the face normal in camera axes (x right, y up, z to the viewer)
        ux, uy, uz = x1 - x0, y0 - y1, (za - zb) * zs
        vx, vy, vz = x2 - x0, y0 - y2, (za - zc) * zs
        fx, fy, fz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        fl = np.sqrt(fx * fx + fy * fy + fz * fz)
        if fl > 0.0:
            fx, fy, fz = fx / fl, fy / fl, fz / fl
        ax_, ay_, az_ = _near(normals[a, 0], normals[a, 1], normals[a, 2], fx, fy, fz)
        bx_, by_, bz_ = _near(normals[b, 0], normals[b, 1], normals[b, 2], fx, fy, fz)
        cx_, cy_, cz_ = _near(normals[c, 0], normals[c, 1], normals[c, 2], fx, fy, fz)
        for py in range(ymin, ymax):
            cy = py + 0.5
            # barycentrics along the row: w0 = c0 - k0 x, w1 = c1 - k1 x, w2 = 1 - w0 - w1
            c0 = (x1 * (y2 - cy) - x2 * (y1 - cy)) * inv
            c1 = (x2 * (y0 - cy) - x0 * (y2 - cy)) * inv
            lo, hi = _span(c0, k0, xlo, xhi)
            lo, hi = _span(c1, k1, lo, hi)
            lo, hi = _span(1.0 - c0 - c1, -(k0 + k1), lo, hi)
            # pixel centres px + 0.5 in [lo, hi]
            pstart = int(np.ceil(lo - 0.5))
            pend = int(np.floor(hi - 0.5))
            for px in range(max(pstart, 0), min(pend, w - 1) + 1):
                cx = px + 0.5
                w0 = c0 - k0 * cx
                w1 = c1 - k1 * cx
                w2 = 1.0 - w0 - w1
                z = w0 * za + w1 * zb + w2 * zc
                if z >= depth[py, px]:
                    continue
                if w0 * ca + w1 * cb + w2 * cc > 0.0:
                    continue
                depth[py, px] = z
                nx = w0 * ax_ + w1 * bx_ + w2 * cx_
                ny = w0 * ay_ + w1 * by_ + w2 * cy_
                nz = w0 * az_ + w1 * bz_ + w2 * cz_
                if back:
                    nx, ny, nz = -nx, -ny, -nz
                nbuf[py, px, 0] = nx
                nbuf[py, px, 1] = ny
                nbuf[py, px, 2] = nz
                sbuf[py, px] = w0 * scalars[a] + w1 * scalars[b] + w2 * scalars[c]
                ids[py, px] = -layer if back else layer
                written += 1
    return written


@numba.njit(cache=True)
def _jump(depth, y, x, limit):  # pragma: no cover - compiled
    """True at a depth discontinuity: the second difference across (y, x) exceeds ``limit``.

    A steep but smooth surface (a wall seen at a grazing angle) has a large
    first difference and a small second one, so it is not outlined.
    """
    h, w = depth.shape
    d = depth[y, x]
    for dy, dx in ((1, 0), (0, 1)):
        y0, x0, y1, x1 = y - dy, x - dx, y + dy, x + dx
        if y0 < 0 or x0 < 0 or y1 >= h or x1 >= w:
            continue
        a, b = depth[y0, x0], depth[y1, x1]
        if not (np.isfinite(a) and np.isfinite(b)):
            return True
        if abs(a + b - 2.0 * d) > limit:
            return True
    return False


@numba.njit(cache=True)
def _light(nx, ny, nz):  # pragma: no cover - compiled
    """Diffuse and specular terms of a camera-space normal (two lights, z to the viewer)."""
    s = np.sqrt(nx * nx + ny * ny + nz * nz)
    if s > 0.0:
        nx, ny, nz = nx / s, ny / s, nz / s
    # key light from the upper left, fill light from the lower right
    kx, ky, kz = -0.4836, 0.5911, 0.6523
    fx, fy, fz = 0.7399, -0.2846, 0.6097
    diffuse = 0.72 * max(nx * kx + ny * ky + nz * kz, 0.0)
    diffuse += 0.28 * max(nx * fx + ny * fy + nz * fz, 0.0)
    # Blinn-Phong half vector of the key light and the viewer
    hx, hy, hz = kx, ky, kz + 1.0
    hn = np.sqrt(hx * hx + hy * hy + hz * hz)
    spec = max((nx * hx + ny * hy + nz * hz) / hn, 0.0)
    return diffuse, 0.22 * spec**40, abs(nz)


@numba.njit(cache=True)
def composite(
    image, depth, normal, scalar, ids, occl, gdepth, gnormal, gids, colors, lut, lo, hi, jump, gjump
):  # pragma: no cover - compiled
    """Shade the G-buffers into ``image`` (H, W, 3) float32, in place.

    Solid pixels: the layer colour (or the colour map at the scalar), ambient
    darkened by ``occl``, two lights, a specular highlight, a dark outline where
    the depth jumps by more than ``jump``; back faces (negative ids) darker.
    Ghost pixels in front of the solid: a translucent tint, more opaque at
    grazing angles, outlined at its silhouette and creases (``gjump``).
    """
    h, w = depth.shape
    span = hi - lo
    for y in range(h):
        for x in range(w):
            i = ids[y, x]
            if i != 0:
                layer = abs(i)
                s = scalar[y, x]
                if np.isfinite(s):
                    u = (s - lo) / span if span > 0.0 else 0.5
                    k = int(min(max(u, 0.0), 1.0) * 255.0 + 0.5)
                    r, g, b = lut[k, 0], lut[k, 1], lut[k, 2]
                else:
                    r, g, b = colors[layer, 0], colors[layer, 1], colors[layer, 2]
                if i < 0:
                    r, g, b = 0.55 * r, 0.55 * g, 0.55 * b
                diffuse, spec, _ = _light(normal[y, x, 0], normal[y, x, 1], normal[y, x, 2])
                light = 0.30 * (1.0 - 0.6 * occl[y, x]) + 0.78 * diffuse
                r, g, b = r * light + spec, g * light + spec, b * light + spec
                if _jump(depth, y, x, jump):
                    r, g, b = 0.45 * r, 0.45 * g, 0.45 * b
                image[y, x, 0], image[y, x, 1], image[y, x, 2] = r, g, b
            j = gids[y, x]
            if j != 0 and gdepth[y, x] < depth[y, x]:
                diffuse, spec, facing = _light(gnormal[y, x, 0], gnormal[y, x, 1], gnormal[y, x, 2])
                a = 0.10 + 0.38 * (1.0 - facing) ** 2
                t = 0.55 + 0.45 * diffuse
                for c in range(3):
                    image[y, x, c] = (1 - a) * image[y, x, c] + a * (colors[j, c] * t + spec)
            if j != 0:
                line = _jump(gdepth, y, x, gjump)
                if not line:
                    n0, n1, n2 = gnormal[y, x, 0], gnormal[y, x, 1], gnormal[y, x, 2]
                    for dy, dx in ((1, 0), (0, 1)):
                        yy, xx = y + dy, x + dx
                        if yy < h and xx < w and gids[yy, xx] != 0:
                            dn = abs(gnormal[yy, xx, 0] - n0) + abs(gnormal[yy, xx, 1] - n1)
                            dn += abs(gnormal[yy, xx, 2] - n2)
                            if dn > 0.5:
                                line = True
                if line:
                    for c in range(3):
                        image[y, x, c] = 0.35 * image[y, x, c] + 0.65 * (0.30 + 0.04 * c)


@numba.njit(cache=True)
def tube_vertices(nodes, edges, radii, sides, verts, normals):  # pragma: no cover - compiled
    """Ring vertices and radial normals of tapered tubes, in place.

    ``verts`` and ``normals`` are (M * 2 * sides, 3): strut ``e`` owns rows
    ``2 * sides * e`` .. ``2 * sides * (e + 1) - 1``, first the ring at its first
    node, then the ring at its second node.
    """
    for e in range(edges.shape[0]):
        a, b = edges[e, 0], edges[e, 1]
        dx = nodes[b, 0] - nodes[a, 0]
        dy = nodes[b, 1] - nodes[a, 1]
        dz = nodes[b, 2] - nodes[a, 2]
        length = max(np.sqrt(dx * dx + dy * dy + dz * dz), 1e-300)
        ux, uy, uz = dx / length, dy / length, dz / length
        # a unit vector across the strut: u x (1, 0, 0), or u x (0, 1, 0) when u is near x
        if abs(ux) < 0.9:
            px, py, pz = 0.0, uz, -uy
        else:
            px, py, pz = -uz, 0.0, ux
        pl = np.sqrt(px * px + py * py + pz * pz)
        px, py, pz = px / pl, py / pl, pz / pl
        qx, qy, qz = uy * pz - uz * py, uz * px - ux * pz, ux * py - uy * px
        r0, r1 = radii[e, 0], radii[e, 1]
        slope = (r0 - r1) / length
        base = 2 * sides * e
        for k in range(sides):
            t = 2.0 * np.pi * k / sides
            cx = np.cos(t) * px + np.sin(t) * qx
            cy = np.cos(t) * py + np.sin(t) * qy
            cz = np.cos(t) * pz + np.sin(t) * qz
            nx, ny, nz = cx + slope * ux, cy + slope * uy, cz + slope * uz
            nl = np.sqrt(nx * nx + ny * ny + nz * nz)
            for j in range(2):
                i = base + j * sides + k
                r = r0 if j == 0 else r1
                n = a if j == 0 else b
                verts[i, 0] = nodes[n, 0] + r * cx
                verts[i, 1] = nodes[n, 1] + r * cy
                verts[i, 2] = nodes[n, 2] + r * cz
                normals[i, 0] = nx / nl
                normals[i, 1] = ny / nl
                normals[i, 2] = nz / nl
