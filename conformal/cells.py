"""Unit-cell library and exact tiling.

A :class:`UnitCell` is a small strut graph inside the unit cube ``[0, 1]^3``
whose node coordinates are stored *exactly*, as integers in units of
``1 / denominator``. Tiling a set of occupied cells (:func:`tile`,
:func:`block`) places a copy of the cell in every cell ``(i, j, k)`` and merges
nodes by their *global integer coordinates* ``(i, j, k) * denominator + node``:
nodes shared by neighbouring cells (on a common face, cube edge or corner) are
the same integer point, so they merge exactly, without any distance tolerance;
struts lying on a common face are then the same node pair and are deduplicated.

Built-in cells (:data:`CELLS`) are all *periodic*: the nodes and struts on each
face of the cube are the translated copies of those on the opposite face, so
the tiling of a block is seamless and the interior of a block is the infinite
lattice. Node and strut counts of an ``n x n x n`` block are given in closed
form by :func:`cell_counts`.

=====================  ===  =====  =====  ===================================
name                   den  nodes  edges  interior node degrees
=====================  ===  =====  =====  ===================================
cubic                  1    8      12     6
bcc                    2    9      8      8
bccz                   2    9      12     8 (centres), 10 (corners)
fcc                    2    14     24     4 (face centres), 12 (corners)
fccz                   2    14     28     4 (face centres), 14 (corners)
box-bcc                2    9      20     8 (centres), 14 (corners)
octet                  2    14     36     12
kelvin                 4    24     36     4
diamond                4    14     16     4
rhombic-dodecahedron   4    22     32     4 (tetrahedral), 8 (corners, faces)
reentrant              8    28     38     5 (rib ends), 2 (rib split points)
=====================  ===  =====  =====  ===================================
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from itertools import combinations, permutations, product

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core import config
from lattice_cad.core.arrays import unique_rows
from lattice_cad.core.graph import LatticeGraph

__all__ = ["UnitCell", "CELLS", "tile", "tile_arrays", "block", "cell_counts"]

_INT64_MAX = np.iinfo(np.int64).max
# Largest allowed |global integer coordinate|: keeps every intermediate in int64.
_COORD_LIMIT = 2**52


# =================================================================== UnitCell
@dataclass(frozen=True, eq=False)
class UnitCell:
    """A strut graph in the unit cube with exact (integer) node coordinates.

    Parameters
    ----------
    name : str
        Short identifier (e.g. ``"bcc"``).
    description : str
        One-line description.
    nodes : (K, 3) int
        Node positions in units of ``1 / denominator``: every coordinate is an
        integer in ``0 .. denominator`` (``denominator`` is the far face).
    denominator : int
        Number of integer units per cell edge (>= 1).
    edges : (E, 2) int
        Strut node-index pairs (direction does not matter).

    Raises
    ------
    ValueError
        With the node or edge index in the message, for: wrong shapes or
        dtypes, a coordinate outside ``0 .. denominator``, duplicate nodes,
        edge indices out of range, self-loops, duplicate edges (in either
        direction), a node without any edge, and a node lying strictly inside
        an edge (that edge must be split at the node instead).

    Notes
    -----
    The arrays are stored as read-only int64 arrays. Two cells compare equal
    when all five fields are equal. A cell does not have to be periodic (see
    :meth:`is_periodic`), but only a periodic cell tiles seamlessly; nor is it
    checked that struts do not cross each other.
    """

    name: str
    description: str
    nodes: NDArray[np.int64]
    denominator: int
    edges: NDArray[np.int64]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"cell name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.description, str) or "\n" in self.description:
            raise ValueError(f"cell {self.name!r}: description must be a one-line string")
        d = self.denominator
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 1:
            raise ValueError(f"cell {self.name!r}: denominator must be an integer >= 1, got {d!r}")
        d = int(d)
        nodes = _int_array(self.nodes, 3, f"cell {self.name!r}: nodes", "node")
        edges = _int_array(self.edges, 2, f"cell {self.name!r}: edges", "edge")
        _validate_cell(self.name, nodes, d, edges)
        nodes.flags.writeable = False
        edges.flags.writeable = False
        object.__setattr__(self, "denominator", d)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "edges", edges)

    # ------------------------------------------------------------ creation
    @classmethod
    def from_fractions(
        cls,
        name: str,
        nodes_frac: ArrayLike,
        edges: ArrayLike,
        *,
        description: str = "",
        max_denominator: int = 1000,
    ) -> UnitCell:
        """A cell from fractional (float) coordinates in ``[0, 1]``.

        Each coordinate is converted to the nearest fraction with denominator
        at most ``max_denominator`` (:meth:`fractions.Fraction.limit_denominator`);
        the cell's denominator is the least common multiple of those.

        Raises
        ------
        ValueError
            If a coordinate is not finite, lies outside ``[0, 1]``, or is not
            within 1e-9 of such a fraction (the message names the node), plus
            every error of the constructor.
        """
        if isinstance(max_denominator, bool) or int(max_denominator) != max_denominator:
            raise ValueError(f"max_denominator must be an integer, got {max_denominator!r}")
        if max_denominator < 1:
            raise ValueError(f"max_denominator must be >= 1, got {max_denominator}")
        try:
            frac = np.asarray(nodes_frac, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"cell {name!r}: node coordinates must be numbers: {exc}") from None
        if frac.size == 0:
            frac = frac.reshape(0, 3)
        if frac.ndim != 2 or frac.shape[1] != 3:
            raise ValueError(f"cell {name!r}: nodes must have shape (K, 3), got {frac.shape}")
        fractions: list[list[Fraction]] = []
        for k, row in enumerate(frac):
            out_row = []
            for axis, x in enumerate(row.tolist()):
                if not math.isfinite(x):
                    raise ValueError(f"cell {name!r}: node {k} has a non-finite coordinate {x}")
                if not -1e-9 <= x <= 1 + 1e-9:
                    raise ValueError(
                        f"cell {name!r}: node {k} coordinate {'xyz'[axis]}={x!r} is outside [0, 1]"
                    )
                f = Fraction(x).limit_denominator(int(max_denominator))
                if abs(float(f) - x) > 1e-9:
                    raise ValueError(
                        f"cell {name!r}: node {k} coordinate {'xyz'[axis]}={x!r} is not a "
                        f"fraction with denominator <= {max_denominator} (nearest {f}, "
                        f"error {abs(float(f) - x):.3g} > 1e-9)"
                    )
                out_row.append(f)
            fractions.append(out_row)
        den = math.lcm(1, *(f.denominator for row in fractions for f in row))
        ints = np.array([[int(f * den) for f in row] for row in fractions], dtype=np.int64).reshape(
            -1, 3
        )
        return cls(name, description, ints, den, np.asarray(edges))

    # ------------------------------------------------------------- queries
    @property
    def num_nodes(self) -> int:
        """Number of nodes K of one cell (boundary nodes included)."""
        return int(self.nodes.shape[0])

    @property
    def num_edges(self) -> int:
        """Number of struts E of one cell (boundary struts included)."""
        return int(self.edges.shape[0])

    @property
    def fractions(self) -> NDArray[np.float64]:
        """(K, 3) float64: node coordinates as fractions of the cell, in ``[0, 1]``."""
        return self.nodes / self.denominator

    def is_periodic(self) -> bool:
        """True when the struts on opposite faces of the cube match.

        That is, for each axis, the struts lying in the face ``0``, translated
        by one cell, are exactly the struts lying in the face ``denominator``,
        so that neighbouring copies share their boundary struts. (Nodes on a
        face need not have a partner on the opposite face: e.g. ``diamond``
        bonds only 4 of its 8 corner atoms in each cell.)
        """
        d = self.denominator
        pts = [tuple(p) for p in self.nodes.tolist()]
        for a in range(3):
            low: set[frozenset[tuple[int, ...]]] = set()
            high: set[frozenset[tuple[int, ...]]] = set()
            for i, j in self.edges.tolist():
                p, q = pts[i], pts[j]
                if p[a] == q[a] == 0:
                    low.add(
                        frozenset(tuple(x + d * (k == a) for k, x in enumerate(r)) for r in (p, q))
                    )
                elif p[a] == q[a] == d:
                    high.add(frozenset((p, q)))
            if low != high:
                return False
        return True

    # ------------------------------------------------------------ equality
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, UnitCell):
            return NotImplemented
        return (
            self.name == other.name
            and self.description == other.description
            and self.denominator == other.denominator
            and np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.edges, other.edges)
        )

    def __hash__(self) -> int:
        return hash(
            (
                self.name,
                self.description,
                self.denominator,
                self.nodes.tobytes(),
                self.edges.tobytes(),
            )
        )

    def __repr__(self) -> str:
        return (
            f"UnitCell({self.name!r}, {self.num_nodes} nodes, {self.num_edges} edges, "
            f"denominator {self.denominator})"
        )


def _int_array(a: ArrayLike, width: int, what: str, item: str) -> NDArray[np.int64]:
    raw = np.asarray(a)
    if raw.size == 0:
        return np.zeros((0, width), dtype=np.int64)
    if raw.ndim != 2 or raw.shape[1] != width:
        raise ValueError(f"{what} must have shape (N, {width}), got {raw.shape}")
    if raw.dtype.kind in "iu":
        return np.array(raw, dtype=np.int64)
    if raw.dtype.kind == "f":
        bad = ~np.isfinite(raw) | (raw != np.round(raw))
        if bad.any():
            k = int(np.flatnonzero(bad.any(axis=1))[0])
            raise ValueError(f"{what}: {item} {k} has a non-integer value {raw[k].tolist()}")
        return raw.astype(np.int64)
    raise ValueError(f"{what} must be integers, got dtype {raw.dtype}")


def _validate_cell(name: str, nodes: NDArray[np.int64], d: int, edges: NDArray[np.int64]) -> None:
    pre = f"cell {name!r}"
    k_nodes = len(nodes)
    if k_nodes == 0 or len(edges) == 0:
        raise ValueError(f"{pre}: a cell needs at least one node and one edge")
    out = (nodes < 0) | (nodes > d)
    if out.any():
        k, a = (int(v) for v in np.argwhere(out)[0])
        raise ValueError(
            f"{pre}: node {k} {tuple(nodes[k].tolist())} has coordinate {'xyz'[a]}="
            f"{int(nodes[k, a])} outside 0..{d} (denominator {d})"
        )
    order = np.lexsort(nodes.T[::-1])
    same = np.flatnonzero((nodes[order][1:] == nodes[order][:-1]).all(axis=1))
    if len(same):
        i, j = sorted((int(order[same[0]]), int(order[same[0] + 1])))
        raise ValueError(f"{pre}: node {j} duplicates node {i} at {tuple(nodes[i].tolist())}")
    bad = (edges < 0) | (edges >= k_nodes)
    if bad.any():
        e = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValueError(
            f"{pre}: edge {e} {tuple(edges[e].tolist())} references a node outside 0..{k_nodes - 1}"
        )
    loops = np.flatnonzero(edges[:, 0] == edges[:, 1])
    if len(loops):
        e = int(loops[0])
        raise ValueError(f"{pre}: edge {e} is a self-loop on node {int(edges[e, 0])}")
    seen: dict[tuple[int, int], int] = {}
    for e, (i, j) in enumerate(edges.tolist()):
        key = (min(i, j), max(i, j))
        if key in seen:
            raise ValueError(
                f"{pre}: edge {e} {(i, j)} duplicates edge {seen[key]} "
                f"{tuple(edges[seen[key]].tolist())}"
            )
        seen[key] = e
    deg = np.bincount(edges.ravel(), minlength=k_nodes)
    iso = np.flatnonzero(deg == 0)
    if len(iso):
        k = int(iso[0])
        raise ValueError(f"{pre}: node {k} {tuple(nodes[k].tolist())} has no edge")
    # a node strictly inside an edge: collinear (zero cross product) and between the ends
    p = nodes[edges[:, 0]][:, None, :]  # (E, 1, 3)
    v = (nodes[edges[:, 1]] - nodes[edges[:, 0]])[:, None, :]
    w = nodes[None, :, :] - p  # (E, K, 3)
    cross = np.cross(v, w)
    t = np.einsum("ekj,ekj->ek", np.broadcast_to(v, w.shape), w)
    vv = np.einsum("ekj,ekj->ek", v, v)
    inside = (cross == 0).all(axis=2) & (t > 0) & (t < vv)
    if inside.any():
        e, k = (int(x) for x in np.argwhere(inside)[0])
        raise ValueError(
            f"{pre}: node {k} {tuple(nodes[k].tolist())} lies inside edge {e} "
            f"{tuple(edges[e].tolist())}; split the edge at that node"
        )


# ============================================================ built-in cells
Point = tuple[int, int, int]


def _from_segments(
    name: str, description: str, denominator: int, segments: Iterable[tuple[Point, Point]]
) -> UnitCell:
    """A cell from strut end points (integer coordinates); nodes sorted, edges sorted."""
    segs = {tuple(sorted((tuple(a), tuple(b)))) for a, b in segments}
    pts = sorted({p for s in segs for p in s})
    index = {p: i for i, p in enumerate(pts)}
    edges = sorted((index[a], index[b]) for a, b in segs)
    return UnitCell(
        name,
        description,
        np.array(pts, dtype=np.int64),
        denominator,
        np.array(edges, dtype=np.int64).reshape(-1, 2),
    )


def _sq(a: Sequence[int], b: Sequence[int]) -> int:
    return sum((x - y) ** 2 for x, y in zip(a, b, strict=True))


def _corners(d: int) -> list[Point]:
    return [(x, y, z) for x, y, z in product((0, d), repeat=3)]


def _cube_edges(d: int, axes: Sequence[int] = (0, 1, 2)) -> list[tuple[Point, Point]]:
    out = []
    for a, b in combinations(_corners(d), 2):
        diff = [i for i in range(3) if a[i] != b[i]]
        if len(diff) == 1 and diff[0] in axes:
            out.append((a, b))
    return out


def _face_centres(d: int) -> list[Point]:
    h = d // 2
    out = []
    for a in range(3):
        for s in (0, d):
            p = [h, h, h]
            p[a] = s
            out.append((p[0], p[1], p[2]))
    return out


def _face_diagonals(d: int) -> list[tuple[Point, Point]]:
    """Each face centre joined to the four corners of its face (d even)."""
    out = []
    for c in _face_centres(d):
        a = next(i for i in range(3) if c[i] in (0, d))
        out += [(c, q) for q in _corners(d) if q[a] == c[a]]
    return out


def _centre_to_corners(d: int) -> list[tuple[Point, Point]]:
    h = d // 2
    return [((h, h, h), q) for q in _corners(d)]


def _cubic() -> UnitCell:
    return _from_segments("cubic", "simple cubic: the 12 edges of the cube", 1, _cube_edges(1))


def _bcc() -> UnitCell:
    return _from_segments(
        "bcc",
        "body-centred cubic: 8 struts from the body centre to the corners",
        2,
        _centre_to_corners(2),
    )


def _bccz() -> UnitCell:
    return _from_segments(
        "bccz",
        "bcc plus the 4 vertical (z) cube edges",
        2,
        _centre_to_corners(2) + _cube_edges(2, axes=(2,)),
    )


def _box_bcc() -> UnitCell:
    return _from_segments(
        "box-bcc",
        "bcc plus all 12 cube edges (Box-BCC, Verma et al.)",
        2,
        _centre_to_corners(2) + _cube_edges(2),
    )


def _fcc() -> UnitCell:
    return _from_segments(
        "fcc",
        "face-centred cubic: both diagonals of every face, split at the face centre",
        2,
        _face_diagonals(2),
    )


def _fccz() -> UnitCell:
    return _from_segments(
        "fccz",
        "fcc plus the 4 vertical (z) cube edges",
        2,
        _face_diagonals(2) + _cube_edges(2, axes=(2,)),
    )


def _octet() -> UnitCell:
    fc = _face_centres(2)
    octahedron = [(a, b) for a, b in combinations(fc, 2) if _sq(a, b) == 2]  # adjacent faces
    return _from_segments(
        "octet",
        "octet truss: fcc face diagonals plus an octahedron joining adjacent face centres",
        2,
        _face_diagonals(2) + octahedron,
    )


def _kelvin() -> UnitCell:
    # Truncated octahedron centred at (2,2,2)/4 with vertices (2,2,2) + permutations of
    # (0, +-1, +-2): every vertex lies on a cube face (4 per face, a square face of the
    # polyhedron, shared with the neighbour's), the 8 hexagons lie inside the cube.
    verts = set()
    for perm in permutations((0, 1, 2)):
        for s1, s2 in product((-1, 1), repeat=2):
            v = [0, 0, 0]
            v[perm[1]] = s1
            v[perm[2]] = 2 * s2
            verts.add((2 + v[0], 2 + v[1], 2 + v[2]))
    segs = [(a, b) for a, b in combinations(sorted(verts), 2) if _sq(a, b) == 2]
    assert len(verts) == 24 and len(segs) == 36
    return _from_segments(
        "kelvin",
        "Kelvin cell: truncated octahedron with its square faces on the cube faces",
        4,
        segs,
    )


def _fcc_sites(d: int) -> list[Point]:
    return _corners(d) + _face_centres(d)


def _diamond() -> UnitCell:
    tetra = [(1, 1, 1), (1, 3, 3), (3, 1, 3), (3, 3, 1)]
    segs = [(t, s) for t in tetra for s in _fcc_sites(4) if _sq(t, s) == 3]
    assert len(segs) == 16
    return _from_segments(
        "diamond",
        "diamond cubic: 4 inner atoms each bonded to 4 corner/face-centre atoms",
        4,
        segs,
    )


def _rhombic_dodecahedron() -> UnitCell:
    inner = [(x, y, z) for x, y, z in product((1, 3), repeat=3)]
    segs = [(t, s) for t in inner for s in _fcc_sites(4) if _sq(t, s) == 3]
    assert len(segs) == 32
    return _from_segments(
        "rhombic-dodecahedron",
        "rhombic dodecahedron centred in the cube plus 8 struts to the corners (FCC Voronoi foam)",
        4,
        segs,
    )


def _reentrant() -> UnitCell:
    # Units of 1/8. Vertical (z) ribs of length 6/8 on three column families: the side
    # face centres (x or y in {0, 8}, the other 4), spanning z = 1..7; the vertical cube
    # edges and the cell axis (4, 4), spanning z = 5..11 (cut by the cell's top and bottom
    # faces, hence split at z = 0 and z = 8). Each face-rib end joins the nearest ends of
    # the two edge ribs of its face and of the axis rib: inclined struts 4/8 across and
    # 2/8 down, which makes every vertical section (xz, yz) a re-entrant honeycomb.
    segs: list[tuple[Point, Point]] = []
    edge_cols = [(x, y) for x, y in product((0, 8), repeat=2)]
    axis = (4, 4)
    face_cols = [(0, 4), (8, 4), (4, 0), (4, 8)]
    for x, y in [*edge_cols, axis]:
        segs += [((x, y, 0), (x, y, 3)), ((x, y, 5), (x, y, 8))]
    for x, y in face_cols:
        segs.append(((x, y, 1), (x, y, 7)))
        for zf, zo in ((7, 5), (1, 3)):
            others = [axis] + [c for c in edge_cols if (c[0] == x if x in (0, 8) else c[1] == y)]
            assert len(others) == 3
            segs += [((x, y, zf), (ox, oy, zo)) for ox, oy in others]
    return _from_segments(
        "reentrant",
        "3D re-entrant auxetic: vertical ribs joined by inward-sloping struts (bow-tie sections)",
        8,
        segs,
    )


CELLS: dict[str, UnitCell] = {
    c.name: c
    for c in (
        _cubic(),
        _bcc(),
        _bccz(),
        _fcc(),
        _fccz(),
        _box_bcc(),
        _octet(),
        _kelvin(),
        _diamond(),
        _rhombic_dodecahedron(),
        _reentrant(),
    )
}
"""The built-in cells by name. See the module docstring for the table.

- ``cubic``: the 12 cube edges.
- ``bcc``: 8 struts from the body centre (1/2, 1/2, 1/2) to the corners.
- ``bccz``: ``bcc`` plus the 4 cube edges parallel to z.
- ``fcc``: every face carries its two diagonals, split at a face-centre node
  (face centre joined to the 4 corners of its face).
- ``fccz``: ``fcc`` plus the 4 cube edges parallel to z.
- ``box-bcc``: ``bcc`` plus the 12 cube edges (Box-BCC of Verma et al.).
- ``octet``: ``fcc`` plus the 12 edges of the octahedron whose vertices are the
  6 face centres (adjacent face centres joined); every node of the infinite
  lattice has degree 12.
- ``kelvin``: the truncated octahedron with vertices (1/2, 1/2, 1/2) +
  permutations of (0, +-1/4, +-1/2): 24 vertices, all on the cube faces (each
  face holds one square face of the polyhedron: vertices (1/4, 1/2), (3/4, 1/2),
  (1/2, 1/4), (1/2, 3/4) in the face's coordinates), 36 edges of length
  sqrt(2)/4 (24 in the cube faces, 12 inside). Tiled, it is exactly Kelvin's
  foam, the Voronoi diagram of the BCC lattice (the corner cells' edges that
  fall in the cube are edges of the central polyhedron); every vertex has
  degree 4.
- ``diamond``: diamond cubic, coordinates in quarters: the FCC atoms (corners
  and face centres) and the 4 inner atoms (1,1,1), (1,3,3), (3,1,3), (3,3,1)/4,
  each bonded to its 4 nearest FCC atoms (16 bonds of length sqrt(3)/4). Only
  the 4 corners (0,0,0), (0,1,1), (1,0,1), (1,1,0) are bonded inside this cell;
  the other 4 corner atoms bond only in neighbouring cells, so they are not
  nodes of this cell (14 nodes). In a block they appear wherever a neighbour
  bonds them; only 4 of the block's 8 corners are atoms.
- ``rhombic-dodecahedron``: the Voronoi foam of the FCC lattice, placed so that
  one rhombic dodecahedron is centred in the cube: its 6 four-fold vertices
  are the face centres and its 8 three-fold vertices are the points
  (1/4 | 3/4)^3; its 24 edges join each of the latter to the 3 nearest face
  centres, and 8 more struts join each of them to the nearest cube corner
  (edges of the neighbouring dodecahedra). All 32 struts have length
  sqrt(3)/4; vertices have degree 4 ((1/4 | 3/4)^3 points) or 8 (corners and
  face centres) in the infinite lattice.
- ``reentrant``: 3D re-entrant honeycomb (the topology of Yang et al.'s
  3D re-entrant structure: 2D re-entrant honeycombs in the xz and yz
  sections), coordinates in eighths: vertical ribs of
  length 3/4 at the 4 side-face centres (z from 1/8 to 7/8) and, offset by
  half a period, on the vertical cube edges and the cell axis (z from 5/8 to
  11/8, split by the top/bottom faces into halves of length 3/8); every face
  rib end is joined by an inclined strut (1/2 across, 1/4 down towards the
  cell's mid-height) to the facing ends of the two edge ribs of its face and of
  the axis rib. Each xz or yz section is a re-entrant (bow-tie) honeycomb, so
  the lattice is auxetic under z loading. Rib ends have degree 5; the nodes
  where the cube faces split a rib have degree 2.
"""


# ================================================================== counting
def _cube(n: int) -> int:
    return (n + 1) ** 3


def _faces(n: int) -> int:
    """Distinct faces of an n^3 block (all three orientations)."""
    return 3 * n * n * (n + 1)


def _cube_edge_count(n: int) -> int:
    """Distinct cube edges of an n^3 block parallel to one axis."""
    return n * (n + 1) ** 2


_COUNTS: dict[str, Callable[[int], tuple[int, int]]] = {
    # corners are shared by 8 cells, cube edges by 4, faces by 2; interior items by 1
    "cubic": lambda n: (_cube(n), 3 * _cube_edge_count(n)),
    "bcc": lambda n: (_cube(n) + n**3, 8 * n**3),
    "bccz": lambda n: (_cube(n) + n**3, 8 * n**3 + _cube_edge_count(n)),
    "box-bcc": lambda n: (_cube(n) + n**3, 8 * n**3 + 3 * _cube_edge_count(n)),
    # 4 half-diagonals per distinct face
    "fcc": lambda n: (_cube(n) + _faces(n), 4 * _faces(n)),
    "fccz": lambda n: (_cube(n) + _faces(n), 4 * _faces(n) + _cube_edge_count(n)),
    # + 12 octahedron edges strictly inside each cell
    "octet": lambda n: (_cube(n) + _faces(n), 4 * _faces(n) + 12 * n**3),
    # 4 vertices and 4 square edges per distinct face, 12 inner edges per cell
    "kelvin": lambda n: (4 * _faces(n), 4 * _faces(n) + 12 * n**3),
    # lattice points: corners + face centres; 4 of the block's 8 corners carry no bond;
    # 4 inner atoms and 16 bonds per cell
    "diamond": lambda n: (_cube(n) - 4 + _faces(n) + 4 * n**3, 16 * n**3),
    "rhombic-dodecahedron": lambda n: (_cube(n) + _faces(n) + 8 * n**3, 32 * n**3),
    # nodes: corners; 2 rib ends per vertical cube edge; 2 rib ends per side face
    # (2/3 of the faces); 2 axis rib ends per cell; top/bottom face centres (1/3 of faces).
    # edges: 2 half-ribs per vertical cube edge; per side face 1 rib + 4 inclined struts;
    # per cell 2 axis half-ribs + 8 inner inclined struts.
    "reentrant": lambda n: (
        _cube(n) + 2 * _cube_edge_count(n) + 2 * (2 * _faces(n) // 3) + 2 * n**3 + _faces(n) // 3,
        2 * _cube_edge_count(n) + 5 * (2 * _faces(n) // 3) + 10 * n**3,
    ),
}


def cell_counts(cell: UnitCell | str, n: int) -> tuple[int, int]:
    """Closed-form (number of nodes, number of edges) of an ``n x n x n`` block.

    Only for the built-in cells (a cell equal to ``CELLS[cell.name]``): the
    formulas count the cell's corner, cube-edge, face and interior items and
    how many cells share each.

    Raises
    ------
    ValueError
        For ``n < 1`` or a cell without a formula (user-defined cells).
    """
    c = _resolve(cell)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    builtin = CELLS.get(c.name)
    if builtin is None or builtin != c or c.name not in _COUNTS:
        raise ValueError(f"no closed-form counts for the user-defined cell {c.name!r}")
    return _COUNTS[c.name](int(n))


# ==================================================================== tiling
def _resolve(cell: UnitCell | str) -> UnitCell:
    if isinstance(cell, UnitCell):
        return cell
    if isinstance(cell, str):
        try:
            return CELLS[cell]
        except KeyError:
            raise ValueError(
                f"unknown cell {cell!r}; built-in cells: {', '.join(sorted(CELLS))}"
            ) from None
    raise TypeError(f"cell must be a UnitCell or a built-in cell name, got {type(cell).__name__}")


def _as_cells(cells_ijk: ArrayLike) -> NDArray[np.int64]:
    raw = np.asarray(cells_ijk)
    if raw.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if raw.ndim != 2 or raw.shape[1] != 3:
        raise ValueError(f"cells_ijk must have shape (C, 3), got {raw.shape}")
    if raw.dtype.kind not in "iu":
        raise ValueError(f"cells_ijk must be integer cell indices, got dtype {raw.dtype}")
    return raw.astype(np.int64, copy=False)


def _as_vec3(value: ArrayLike, what: str, positive: bool) -> NDArray[np.float64]:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be a number or 3 numbers: {exc}") from None
    if v.ndim == 0:
        v = np.full(3, float(v))
    if v.shape != (3,):
        raise ValueError(f"{what} must be a number or 3 numbers, got shape {v.shape}")
    if not np.isfinite(v).all() or (positive and (v <= 0).any()):
        need = "finite and > 0" if positive else "finite"
        raise ValueError(f"{what} must be {need}, got {v.tolist()}")
    return v


def _unique_sorted(s: NDArray[np.int64]) -> NDArray[np.int64]:
    """Distinct values of the sorted 1-d array ``s``."""
    if len(s) == 0:
        return s
    first = np.empty(len(s), dtype=bool)
    first[0] = True
    np.not_equal(s[1:], s[:-1], out=first[1:])
    return s[first]


#: Keys per block in :func:`_tile_int` (2**18 int64: 2 MB): bounds its temporaries.
_TILE_BLOCK = 1 << 18


def _tile_int(
    cell: UnitCell, cells: NDArray[np.int64], *, block: int = _TILE_BLOCK
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(node_ijk (N, 3), edges (M, 2)) of the union of the cell copies, sorted.

    Works on blocks of about ``block`` (cell, node) keys: the distinct node keys of every
    block, then their union; then the edge keys of every block (node ids by binary search
    in the sorted node keys), then their union. Temporaries stay O(block) besides the
    results' own size (about 8 bytes per node and per strut).
    """
    if len(cells) == 0:
        return np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2), dtype=np.int64)
    d = cell.denominator
    c_lo = [int(v) for v in cells.min(axis=0)]
    c_hi = [int(v) for v in cells.max(axis=0)]
    if max(abs(v) for v in c_lo + c_hi) * d + d > _COORD_LIMIT:
        raise ValueError(
            f"cell indices up to {max(abs(v) for v in c_lo + c_hi)} are too large "
            f"(global integer coordinates must stay below 2**52)"
        )
    k_nodes = cell.num_nodes
    g_lo = [v * d for v in c_lo]
    span = [(hi - lo + 1) * d + 1 for lo, hi in zip(c_lo, c_hi, strict=True)]
    if span[0] * span[1] * span[2] > _INT64_MAX:  # a huge, sparse extent: rows instead
        return _tile_int_rows(cell, cells)
    # One int64 key per (cell, node), linear in the coordinates, so that
    # key(cell, node) = key(cell origin) + key(node offset) and key order is
    # lexicographic (x, y, z) order.
    sy, sz = span[1], span[2]
    loc = cell.nodes
    off = (loc[:, 0] * sy + loc[:, 1]) * sz + loc[:, 2]
    step = max(1, block // k_nodes)
    starts = range(0, len(cells), step)

    def base(s: int) -> NDArray[np.int64]:
        c = cells[s : s + step]
        return ((c[:, 0] * d - g_lo[0]) * sy + (c[:, 1] * d - g_lo[1])) * sz + (
            c[:, 2] * d - g_lo[2]
        )

    parts = []
    for s in starts:
        k = (base(s)[:, None] + off[None, :]).ravel()
        k.sort()
        parts.append(_unique_sorted(k))
        del k
    uniq = _sorted_union(parts)
    n_nodes = len(uniq)
    node_ijk = np.empty((n_nodes, 3), dtype=np.int64)
    rest, node_ijk[:, 2] = np.divmod(uniq, sz)
    node_ijk[:, 0], node_ijk[:, 1] = np.divmod(rest, sy)
    del rest
    node_ijk += np.asarray(g_lo, dtype=np.int64)
    off_a, off_b = off[cell.edges[:, 0]], off[cell.edges[:, 1]]
    if n_nodes > 3_000_000_000:  # pragma: no cover - n_nodes**2 would overflow int64
        return node_ijk, _tile_edges_rows(uniq, base, starts, off_a, off_b)
    step = max(1, block // max(1, cell.num_edges))
    starts = range(0, len(cells), step)
    parts = []
    for s in starts:
        b0 = base(s)[:, None]
        a = np.searchsorted(uniq, (b0 + off_a[None, :]).ravel())
        b = np.searchsorted(uniq, (b0 + off_b[None, :]).ravel())
        lo = np.minimum(a, b)
        np.maximum(a, b, out=b)
        lo *= n_nodes
        lo += b
        del a, b
        lo.sort()
        parts.append(_unique_sorted(lo))
        del lo
    del uniq
    ekeys = _sorted_union(parts)
    edges = np.empty((len(ekeys), 2), dtype=np.int64)
    np.divmod(ekeys, n_nodes, out=(edges[:, 0], edges[:, 1]))
    return node_ijk, edges


def _sorted_union(parts: list[NDArray[np.int64]]) -> NDArray[np.int64]:
    """Distinct values of the sorted int64 arrays in ``parts`` (emptied), sorted."""
    if len(parts) == 1:
        return parts.pop()
    allk = np.concatenate(parts)
    parts.clear()
    allk.sort()
    return _unique_sorted(allk)


def _tile_int_rows(
    cell: UnitCell, cells: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """:func:`_tile_int` for a huge, sparse extent: unique on coordinate rows."""
    d, k_nodes = cell.denominator, cell.num_nodes
    g = (cells[:, None, :] * d + cell.nodes[None, :, :]).reshape(-1, 3)
    node_ijk, inv = unique_rows(g, return_inverse=True)
    del g
    inv = inv.reshape(len(cells), k_nodes)
    a = inv[:, cell.edges[:, 0]]
    b = inv[:, cell.edges[:, 1]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    edges = unique_rows(np.stack([lo.ravel(), hi.ravel()], axis=1))
    return node_ijk, edges.astype(np.int64, copy=False)


def _tile_edges_rows(
    uniq: NDArray[np.int64],
    base: Callable[[int], NDArray[np.int64]],
    starts: range,
    off_a: NDArray[np.int64],
    off_b: NDArray[np.int64],
) -> NDArray[np.int64]:  # pragma: no cover - more than 3e9 nodes
    rows = []
    for s in starts:
        b0 = base(s)[:, None]
        a = np.searchsorted(uniq, (b0 + off_a[None, :]).ravel())
        b = np.searchsorted(uniq, (b0 + off_b[None, :]).ravel())
        rows.append(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1))
    return unique_rows(np.concatenate(rows))


def tile_arrays(
    cell: UnitCell | str,
    cells_ijk: ArrayLike,
    *,
    cell_size: float | ArrayLike = 1.0,
    origin: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Tile ``cell`` over the occupied cells; return the raw arrays.

    Parameters
    ----------
    cell : UnitCell or str
        The cell, or the name of a built-in cell.
    cells_ijk : (C, 3) int
        Integer indices of the occupied cells (any subset of the grid, in any
        order; repeats are harmless). Cell ``(i, j, k)`` occupies
        ``origin + [i, i+1] x [j, j+1] x [k, k+1] * cell_size``.
    cell_size : float or (hx, hy, hz)
        Cell edge length(s), > 0.
    origin : (3,) float
        Position of the corner of cell ``(0, 0, 0)``.

    Returns
    -------
    nodes : (N, 3) float64
        ``origin + node_ijk / denominator * cell_size``.
    edges : (M, 2) int64
        Unique struts, ``edges[:, 0] < edges[:, 1]``, sorted lexicographically
        (hence by the global integer coordinates of their end nodes).
    node_ijk : (N, 3) int64
        Global integer coordinates of the nodes, ``cell_index * denominator +
        local``; sorted lexicographically and unique. A node lies in cell
        ``node_ijk // denominator`` (and, when a coordinate is a multiple of
        the denominator, also in the neighbour below along that axis).

    Nodes of different copies are merged when their global integer
    coordinates are equal, never by a distance tolerance. The work is
    vectorised (sorting int64 keys); time is O(C log C) and memory O(C).
    """
    c = _resolve(cell)
    cells = _as_cells(cells_ijk)
    h = _as_vec3(cell_size, "cell_size", positive=True)
    o = _as_vec3(origin, "origin", positive=False)
    node_ijk, edges = _tile_int(c, cells)
    nodes = o + (node_ijk / c.denominator) * h
    return nodes, edges, node_ijk


def tile(
    cell: UnitCell | str,
    cells_ijk: ArrayLike,
    *,
    cell_size: float | ArrayLike = 1.0,
    origin: ArrayLike = (0.0, 0.0, 0.0),
    radius: float | ArrayLike = config.DEFAULT_RADIUS,
) -> LatticeGraph:
    """Tile ``cell`` over the occupied cells as a :class:`LatticeGraph`.

    See :func:`tile_arrays` for the parameters and the (deterministic) node
    and edge order. ``radius`` (a number, (M,) or (M, 2)) is passed unchanged
    to :class:`LatticeGraph`, whose :class:`~lattice_cad.InvalidGraphError`
    propagates (e.g. a radius not below half of the shortest strut: note that
    with ``cell_size=1`` the shortest struts of several cells are shorter than
    0.8, the length the default radius 0.4 needs).
    """
    nodes, edges, _ = tile_arrays(cell, cells_ijk, cell_size=cell_size, origin=origin)
    return LatticeGraph(nodes, edges, radius)


def _block_cells(counts: int | Sequence[int]) -> NDArray[np.int64]:
    cnt = np.asarray(counts)
    if cnt.ndim == 0:
        cnt = np.full(3, cnt)
    if cnt.shape != (3,) or cnt.dtype.kind not in "iu" or (cnt < 1).any():
        raise ValueError(
            f"counts must be a positive integer or 3 positive integers, got {counts!r}"
        )
    nx, ny, nz = (int(v) for v in cnt)
    return np.indices((nx, ny, nz), dtype=np.int64).reshape(3, -1).T


def block(
    cell: UnitCell | str,
    counts: int | Sequence[int] = (1, 1, 1),
    *,
    cell_size: float | ArrayLike = 1.0,
    origin: ArrayLike = (0.0, 0.0, 0.0),
    radius: float | ArrayLike = config.DEFAULT_RADIUS,
) -> LatticeGraph:
    """A full ``nx x ny x nz`` block of cells (cells ``0..nx-1`` etc.); see :func:`tile`."""
    return tile(cell, _block_cells(counts), cell_size=cell_size, origin=origin, radius=radius)
