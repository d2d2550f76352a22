"""A slow, plain numpy/scipy reference of fast_stitch.stitch, for comparison in tests.

Written from the description in fast_stitch.stitch (not from the kernels):
Python integers for the hash, explicit loops for the offsets, qhull (scipy)
for the hub hulls.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull

from lattice_cad import LatticeGraph

M64 = (1 << 64) - 1
QSCALE = 2.0**30


def mix64(x: int) -> int:
    x = (x + 0x9E3779B97F4A7C15) & M64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & M64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & M64
    return x ^ (x >> 31)


def combine(h: int, v: int) -> int:
    return mix64(h ^ ((v + 0x632BE59BD9B4E019) & M64))


def edge_frame(p0, p1, P: int, seed: int):
    """Canonical axis, sign, frame (u, v) of a strut from p0 to p1."""
    d = np.asarray(p1, float) - np.asarray(p0, float)
    q = [int(np.rint(c / np.linalg.norm(d) * QSCALE)) for c in d]
    s = 1
    if q[0] < 0 or (q[0] == 0 and (q[1] < 0 or (q[1] == 0 and q[2] < 0))):
        s = -1
    q = [s * c for c in q]
    c = np.array(q, float)
    c /= np.linalg.norm(c)
    sg = 1.0 if q[2] >= 0 else -1.0
    a = -1.0 / (sg + c[2])
    b = c[0] * c[1] * a
    b1 = np.array([1.0 + sg * c[0] ** 2 * a, sg * b, -sg * c[0]])
    b2 = np.array([b, sg + c[1] ** 2 * a, -c[1]])
    h = mix64(seed)
    for comp in q:
        h = combine(h, comp)
    phase = (h >> 11) * 2.0**-53 * 2 * math.pi / P
    u = math.cos(phase) * b1 + math.sin(phase) * b2
    v = -math.sin(phase) * b1 + math.cos(phase) * b2
    return c, s, u, v


def offsets(dirs, rad, *, shrink: bool, margin: float = 1e-2, floor_deg: float = 10.0):
    d = len(dirs)
    cos = np.clip(dirs @ dirs.T, -1, 1)
    sin = np.sqrt(1 - cos**2)
    alpha_max = math.radians(90 - floor_deg)  # widest cone a profile may have

    def pair_offset(i, j):
        # split the angle so the two cones touch; if j's share would be wider
        # than alpha_max, j is floored anyway and i gets theta - alpha_max
        dij = (rad[j] + rad[i] * cos[i, j]) / sin[i, j]
        dji = (rad[i] + rad[j] * cos[i, j]) / sin[i, j]
        if math.atan2(rad[j], dji) > alpha_max or dji <= 0:
            rest = math.acos(cos[i, j]) - alpha_max
            if rest >= math.pi / 2:
                return 0.0
            dij = rad[i] / math.tan(rest)
        return dij * (1 + margin)

    ideal = np.array(
        [
            max(
                [rad[i] / math.tan(alpha_max)]
                + [pair_offset(i, j) for j in range(d) if j != i and sin[i, j] > 1e-12]
            )
            for i in range(d)
        ]
    )
    rho2 = max(ideal**2 + rad**2)
    sphere = np.sqrt(rho2 - rad**2)
    if not shrink:
        return sphere
    delta = margin * math.sqrt(rho2)
    out = ideal.copy()
    for _ in range(200):  # Jacobi sweeps: order independent
        prev = out.copy()
        need = np.array(
            [
                max(
                    (
                        (prev[j] if cos[i, j] > 0 else ideal[j]) * cos[i, j]
                        + rad[j] * sin[i, j]
                        + delta
                        for j in range(d)
                        if j != i
                    ),
                    default=-np.inf,
                )
                for i in range(d)
            ]
        )
        raised = need > prev * (1 + 1e-9)
        if not raised.any():
            return np.minimum(out, sphere)
        out = np.where(raised, np.maximum(out, need + 0.1 * delta), out)
    return sphere


def reference_stitch(graph: LatticeGraph, P: int, *, seed: int = 0, shrink: bool = True):
    """(vertices (2MP, 3) float64, faces (F, 3) int64) built the slow way."""
    nodes, edges, radii = graph.nodes, graph.edges, graph.radii
    m = len(edges)
    frames = [edge_frame(nodes[a], nodes[b], P, seed) for a, b in edges]
    incident: dict[int, list[tuple[int, int]]] = {}
    for e, (a, b) in enumerate(edges):
        incident.setdefault(int(a), []).append((e, 0))
        incident.setdefault(int(b), []).append((e, 1))
    end_offset = np.zeros((m, 2))
    faces = []
    ang = 2 * math.pi * np.arange(P) / P
    for inc in incident.values():
        if len(inc) < 2:
            continue
        outward = np.array(
            [frames[e][0] * frames[e][1] * (1 if side == 0 else -1) for e, side in inc]
        )
        rad = np.array([radii[e, side] for e, side in inc])
        off = offsets(outward, rad, shrink=shrink)
        pts = []
        ids = []
        for t, (e, side) in enumerate(inc):
            end_offset[e, side] = off[t]
            _, _, u, v = frames[e]
            for k in range(P):
                pts.append(
                    off[t] * outward[t] + rad[t] * (math.cos(ang[k]) * u + math.sin(ang[k]) * v)
                )
                ids.append((2 * e + side) * P + k)
        pts = np.array(pts)
        ids = np.array(ids)
        hull = ConvexHull(pts)
        centre = pts.mean(axis=0)
        for simplex in hull.simplices:
            group = ids[simplex] // P
            if group[0] == group[1] == group[2]:
                continue
            a, b, c = pts[simplex]
            if np.dot(np.cross(b - a, c - a), a - centre) < 0:
                simplex = simplex[[0, 2, 1]]
            faces.append(ids[simplex])
    vertices = np.zeros((2 * m * P, 3))
    for e, (a, b) in enumerate(edges):
        c, s, u, v = frames[e]
        for side, n in ((0, a), (1, b)):
            direction = s * c * (1 if side == 0 else -1)
            for k in range(P):
                vertices[(2 * e + side) * P + k] = (
                    nodes[n] + end_offset[e, side] * direction
                    + radii[e, side] * (math.cos(ang[k]) * u + math.sin(ang[k]) * v)
                )  # fmt: skip
        a0, a1 = 2 * e * P, (2 * e + 1) * P
        for k in range(P):
            k1 = (k + 1) % P
            quad = [(a0 + k, a0 + k1, a1 + k1), (a0 + k, a1 + k1, a1 + k)]
            faces += quad if s == 1 else [(t[0], t[2], t[1]) for t in quad]
    for inc in incident.values():
        if len(inc) != 1:
            continue
        e, side = inc[0]
        base = (2 * e + side) * P
        ccw = (frames[e][1] == 1) == (side == 0)
        for k in range(1, P - 1):
            faces.append((base, base + k + 1, base + k) if ccw else (base, base + k, base + k + 1))
    return vertices, np.array(faces, dtype=np.int64)


def canonical_faces(faces) -> set[tuple[int, int, int]]:
    """Faces as a set of tuples, each rotated to start at its smallest index."""
    out = set()
    for f in np.asarray(faces):
        i = int(np.argmin(f))
        out.add(tuple(int(x) for x in np.roll(f, -i)))
    return out
