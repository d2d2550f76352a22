"""The triangle mesh type every package uses, and its binary STL writer (numpy only).

:func:`fast_stitch.stitch` returns a :class:`Mesh`; the reference, the skins and the file
readers produce one too. Its validity checker is :func:`fast_stitch.check`, an engine above
this floor.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core import config
from lattice_cad.core.atomic import atomic_write, check_target
from lattice_cad.core.errors import ExportError
from lattice_cad.core.resources import require_disk

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "Mesh",
    "STL_HEADER",
    "stl_size",
    "signed_volume",
    "stl_records",
    "mesh_arrays",
    "weld",
    "without_unused_vertices",
]

#: 80-byte binary STL header; must not start with "solid" (ASCII STL marker).
STL_HEADER = b"lattice-cad binary STL".ljust(80, b" ")
#: Triangles per chunk of the volume sum and the STL records: small enough that the
#: temporaries stay in cache and are reused (1 << 20 took 0.9 s for the volume of a
#: 700 K-triangle skin, most of it first-touch page faults of fresh arrays; 1 << 16: 0.05 s).
_STL_CHUNK = 1 << 16


def stl_size(n_triangles: int) -> int:
    """Size in bytes of a binary STL with ``n_triangles`` triangles."""
    return 84 + 50 * int(n_triangles)


def mesh_arrays(obj: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """Vertices (V, 3) float64 and faces (F, 3) int64 of anything mesh-like, else None.

    Accepts a :class:`Mesh`, a ``(vertices, faces)`` pair, any object with array
    ``vertices`` and ``faces`` (trimesh.Trimesh), and a ``manifold3d.Manifold`` (by its
    ``to_mesh`` method). Nothing is copied when the dtypes already match.
    """
    if isinstance(obj, Mesh):
        return obj.vertices, obj.faces
    if isinstance(obj, tuple) and len(obj) == 2:
        return np.asarray(obj[0], dtype=np.float64), np.asarray(obj[1], dtype=np.int64)
    to_mesh = getattr(obj, "to_mesh64", None) or getattr(obj, "to_mesh", None)
    if callable(to_mesh) and hasattr(obj, "status"):  # manifold3d.Manifold
        m = to_mesh()
        return (
            np.asarray(m.vert_properties, dtype=np.float64)[:, :3],
            np.asarray(m.tri_verts, dtype=np.int64),
        )
    v = getattr(obj, "vertices", None)
    f = getattr(obj, "faces", None)
    if v is not None and f is not None and not callable(v) and not callable(f):
        return np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)
    return None


def without_unused_vertices(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The vertices some face uses, in their order, and the faces renumbered into them.

    vertices : (V, 3) float64, faces : (F, 3) int64; returns (V', 3), (F, 3).
    """
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    new_id = np.cumsum(used) - 1
    return vertices[used], new_id[faces]


def weld(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    tol: float = 0.0,
    drop_degenerate: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Merge coincident vertices (per-face tessellations repeat their boundary points).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    tol : float
        Vertices in the same cell of a grid of this spacing are merged (0: only exactly
        equal coordinates). The first vertex of each group is kept.
    drop_degenerate : bool
        Remove faces that end up with a repeated vertex.

    Returns
    -------
    vertices : (V', 3) float64, faces : (F', 3) int64
    """
    if len(vertices) == 0:
        return vertices, faces
    key = vertices if tol == 0 else np.round(vertices / tol)
    # rows in lexicographic order (as np.unique(axis=0), several times faster): a stable
    # sort, so the first of each group of equal rows is the vertex of lowest index
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))
    ks = key[order]
    new = np.empty(len(order), dtype=bool)
    new[0] = True
    np.any(ks[1:] != ks[:-1], axis=1, out=new[1:])
    group = np.cumsum(new) - 1
    inv = np.empty(len(order), dtype=np.int64)
    inv[order] = group
    first = order[new]
    f2 = inv[faces]
    if drop_degenerate:
        keep = (f2[:, 0] != f2[:, 1]) & (f2[:, 1] != f2[:, 2]) & (f2[:, 0] != f2[:, 2])
        f2 = f2[keep]
    return vertices[first], f2


def signed_volume(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> float:
    """Signed enclosed volume of a triangle mesh (divergence theorem), in chunks.

    vertices : (V, 3) float64, faces : (F, 3) int64. Positive for a closed, outward mesh.
    """
    total = 0.0
    for start in range(0, len(faces), _STL_CHUNK):
        tri = vertices[faces[start : start + _STL_CHUNK]]
        total += float(np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])))
    return total / 6.0


def stl_records(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], out: NDArray[np.float32]
) -> int:
    """Fill binary-STL records for ``faces``; return how many are degenerate in float32.

    vertices : (V, 3) float64, faces : (n, 3) int64
    out : (n, 12) float32
        Unit normal (3) then the three vertices (9), in single precision. A triangle whose
        float32 corners have a zero cross product gets a zero normal and is counted.
    """
    corners = vertices[faces].astype(np.float32)  # (n, 3, 3)
    out[:, 3:] = corners.reshape(-1, 9)
    c = corners.astype(np.float64)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    bad = norm == 0.0
    out[:, :3] = n / np.where(bad, 1.0, norm)[:, None]
    return int(bad.sum())


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh.

    Attributes
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Counter-clockwise seen from outside.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]

    def __repr__(self) -> str:
        return f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces)"

    @property
    def volume(self) -> float:
        """Signed enclosed volume (positive for an outward-oriented closed mesh)."""
        if len(self.faces) == 0:
            return 0.0
        return signed_volume(self.vertices, self.faces)

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: min and max vertex coordinates."""
        if len(self.vertices) == 0:
            return np.zeros((2, 3))
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def to_trimesh(self) -> trimesh.Trimesh:
        """The same mesh as a ``trimesh.Trimesh`` (no merging or repair)."""
        import trimesh

        return trimesh.Trimesh(vertices=self.vertices, faces=self.faces, process=False)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write a binary STL (atomically: nothing is left behind on failure).

        The header never starts with ``solid``. Raises :class:`ExportError` if the
        mesh has more than 2**32 - 1 triangles, or if rounding the coordinates to
        single precision (as STL stores them) makes a triangle degenerate, as
        happens with tiny struts far from the origin.
        """
        p = Path(path)
        if p.suffix.lower() != ".stl":
            raise ValueError(f"Mesh.save writes binary STL; got {p.name!r} (use a .stl suffix)")
        n = len(self.faces)
        if n > config.STL_MAX_TRIANGLES:
            raise ExportError(
                f"{p.name}: {n} triangles do not fit in a binary STL "
                f"(at most {config.STL_MAX_TRIANGLES})"
            )
        check_target(p)
        require_disk(p, stl_size(n))
        buf = np.empty((min(n, _STL_CHUNK), 12), dtype=np.float32)
        rec = np.zeros(min(n, _STL_CHUNK), dtype=[("data", "<f4", (12,)), ("attr", "<u2")])
        with atomic_write(p, "wb") as fh:
            fh.write(STL_HEADER)
            fh.write(np.uint32(n).tobytes())
            for start in range(0, n, _STL_CHUNK):
                stop = min(n, start + _STL_CHUNK)
                out = buf[: stop - start]
                bad = stl_records(self.vertices, self.faces[start:stop], out)
                if bad:
                    k = int(np.flatnonzero(~out[:, :3].any(axis=1))[0])
                    where = ", ".join(f"{float(c):.6g}" for c in out[k, 3:6])
                    raise ExportError(
                        f"{p.name}: {bad} triangle(s) become degenerate when coordinates are "
                        f"rounded to single precision for STL, the first face {start + k} at "
                        f"({where}); move the lattice closer to the origin or use thicker struts"
                    )
                r = rec[: stop - start]
                r["data"] = out
                fh.write(r.tobytes())
        return p
