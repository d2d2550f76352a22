"""The triangle mesh produced by :func:`fast_stitch.stitch`."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from fast_stitch import _kernels
from lattice_cad._atomic import atomic_write
from lattice_cad.errors import LatticeError

if TYPE_CHECKING:
    import trimesh

    from fast_stitch.check import CheckReport

__all__ = ["Mesh", "ExportError", "STL_HEADER", "stl_size"]

#: 80-byte binary STL header; must not start with "solid" (ASCII STL marker).
STL_HEADER = b"lattice-cad fast_stitch binary STL".ljust(80, b" ")
_STL_CHUNK = 1 << 20
_STL_MAX_TRIANGLES = 2**32 - 1


class ExportError(LatticeError, ValueError):
    """A mesh cannot be written faithfully in the requested format."""


def stl_size(n_triangles: int) -> int:
    """Size in bytes of a binary STL with ``n_triangles`` triangles."""
    return 84 + 50 * int(n_triangles)


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
        return float(_kernels.signed_volume(self.vertices, self.faces))

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: min and max vertex coordinates."""
        if len(self.vertices) == 0:
            return np.zeros((2, 3))
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def check(self, **kwargs: Any) -> CheckReport:
        """Validity report (see :func:`fast_stitch.check`)."""
        from fast_stitch.check import check

        return check(self, **kwargs)

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
        if n > _STL_MAX_TRIANGLES:
            raise ExportError(
                f"{p.name}: {n} triangles do not fit in a binary STL (at most {_STL_MAX_TRIANGLES})"
            )
        buf = np.empty((min(n, _STL_CHUNK), 12), dtype=np.float32)
        rec = np.zeros(min(n, _STL_CHUNK), dtype=[("data", "<f4", (12,)), ("attr", "<u2")])
        with atomic_write(p, "wb") as fh:
            fh.write(STL_HEADER)
            fh.write(np.uint32(n).tobytes())
            for start in range(0, n, _STL_CHUNK):
                stop = min(n, start + _STL_CHUNK)
                out = buf[: stop - start]
                bad = _kernels.stl_records(self.vertices, self.faces, start, stop, out)
                if bad:
                    raise ExportError(
                        f"{p.name}: {bad} triangle(s) (first in faces {start}..{stop - 1}) become "
                        "degenerate when coordinates are rounded to single precision for STL; "
                        "move the lattice closer to the origin or use thicker struts"
                    )
                r = rec[: stop - start]
                r["data"] = out
                fh.write(r.tobytes())
        return p
