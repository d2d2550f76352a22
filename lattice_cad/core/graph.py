"""The core lattice graph type: nodes, struts (edges) and strut radii.

Everything else in lattice-cad is built on :class:`LatticeGraph`. It is
immutable (its arrays are read-only) and validated at construction, so an
engine that receives one can rely on the invariants listed in
:meth:`LatticeGraph.__init__`.
"""

from __future__ import annotations

import json
import os
import warnings
import zipfile
import zlib
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core import config
from lattice_cad.core.arrays import point_text
from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.errors import (
    InputFileError,
    InvalidGraphError,
    LatticeWarning,
    MissingFileError,
)
from lattice_cad.core.formats import Kind, format_for
from lattice_cad.core.resources import require_memory

__all__ = ["LatticeGraph", "precision_problem"]

_FORMAT = "lattice-cad-graph"
_VERSION = 1


class LatticeGraph:
    """A lattice: nodes in space joined by cylindrical (or tapered) struts.

    Parameters
    ----------
    nodes : (N, 3) float64
        Node coordinates (any length unit; lattice-cad uses millimetres).
    edges : (M, 2) int
        Node indices of each strut. Direction does not matter.
    radii : float, (M,) float64 or (M, 2) float64
        Strut radius: one for all struts, one per strut, or one per strut end
        (tapered struts: ``radii[:, 0]`` at node ``edges[:, 0]`` and
        ``radii[:, 1]`` at node ``edges[:, 1]``).

    Raises
    ------
    InvalidGraphError
        With the offending node or edge index in the message, for: anything but
        real numbers (one rule for nodes, edges and radii: strings, even numeric
        ones, booleans, complex numbers and None are refused), wrong array
        shapes, non-finite coordinates or radii, radius <= 0, node index out of
        range (reported as given), self-loops, duplicate edges (in either
        direction), zero-length edges, a radius not strictly below half the edge
        length, distinct nodes at the same position, and the precision contract
        (:func:`precision_problem`): coordinates beyond ``config.MAX_COORDINATE``,
        radii below ``config.MIN_RADIUS``, and struts whose ``|x| / r`` exceeds
        ``config.PRECISION_RATIO_F64``.

    Warns
    -----
    LatticeWarning
        When some nodes have no strut; they are kept but ignored by the engines.

    Attributes
    ----------
    nodes : (N, 3) float64, read-only
    edges : (M, 2) int64, read-only
    radii : (M, 2) float64, read-only
        Always per strut end, whatever form was passed in.
    """

    nodes: NDArray[np.float64]
    edges: NDArray[np.int64]
    radii: NDArray[np.float64]

    def __init__(self, nodes: ArrayLike, edges: ArrayLike, radii: ArrayLike) -> None:
        nodes_a = _as_nodes(nodes)
        edges_a = _as_edges(edges, len(nodes_a))
        radii_a = _as_radii(radii, len(edges_a))
        self._adopt(nodes_a, edges_a, radii_a)

    @classmethod
    def _from_owned(
        cls,
        nodes: NDArray[np.float64],
        edges: NDArray[np.int64],
        radii: NDArray[np.float64],
    ) -> LatticeGraph:
        """A graph that takes the arrays over without copying them (the builders' path).

        ``nodes`` (N, 3) float64, ``edges`` (M, 2) int64 and ``radii`` (M, 2) float64 must
        be C-contiguous arrays that nobody else writes to: they are validated as by the
        constructor and made read-only in place. Other arrays go through the constructor.
        """
        ok = (
            isinstance(nodes, np.ndarray) and nodes.dtype == np.float64 and nodes.ndim == 2
            and nodes.shape[1] == 3 and nodes.flags.c_contiguous and len(nodes) > 0
            and isinstance(edges, np.ndarray) and edges.dtype == np.int64 and edges.ndim == 2
            and edges.shape[1] == 2 and edges.flags.c_contiguous
            and isinstance(radii, np.ndarray) and radii.dtype == np.float64
            and radii.shape == (len(edges), 2) and radii.flags.c_contiguous
        )  # fmt: skip
        if not ok:
            return cls(nodes, edges, radii)
        if len(edges) and (int(edges.min()) < 0 or int(edges.max()) >= len(nodes)):
            return cls(nodes, edges, radii)  # the constructor names the bad index
        g = cls.__new__(cls)
        g._adopt(nodes, edges, radii)
        return g

    def _adopt(
        self, nodes_a: NDArray[np.float64], edges_a: NDArray[np.int64], radii_a: NDArray[np.float64]
    ) -> None:
        _validate(nodes_a, edges_a, radii_a)
        for a in (nodes_a, edges_a, radii_a):
            a.flags.writeable = False
        self.nodes = nodes_a
        self.edges = edges_a
        self.radii = radii_a
        isolated = self.isolated_nodes
        if len(isolated):
            shown = ", ".join(str(int(i)) for i in isolated[:8])
            more = ", ..." if len(isolated) > 8 else ""
            warnings.warn(
                f"{len(isolated)} isolated node(s) without struts will be ignored "
                f"(node {shown}{more})",
                LatticeWarning,
                stacklevel=3,
            )

    # ------------------------------------------------------------------ sizes
    @property
    def num_nodes(self) -> int:
        """Number of nodes N (including isolated ones)."""
        return int(self.nodes.shape[0])

    @property
    def num_edges(self) -> int:
        """Number of struts M."""
        return int(self.edges.shape[0])

    def __len__(self) -> int:
        return self.num_edges

    def __repr__(self) -> str:
        taper = ", tapered" if self.is_tapered else ""
        return f"LatticeGraph({self.num_nodes} nodes, {self.num_edges} edges{taper})"

    # ---------------------------------------------------------- derived data
    @property
    def is_tapered(self) -> bool:
        """True when some strut has different radii at its two ends."""
        return bool(np.any(self.radii[:, 0] != self.radii[:, 1]))

    @cached_property
    def edge_vectors(self) -> NDArray[np.float64]:
        """(M, 3) float64: ``nodes[edges[:, 1]] - nodes[edges[:, 0]]``."""
        v = self.nodes[self.edges[:, 1]] - self.nodes[self.edges[:, 0]]
        v.flags.writeable = False
        return v

    @cached_property
    def edge_lengths(self) -> NDArray[np.float64]:
        """(M,) float64: strut lengths."""
        L = np.sqrt(np.einsum("ij,ij->i", self.edge_vectors, self.edge_vectors))
        L.flags.writeable = False
        return L

    @cached_property
    def degree(self) -> NDArray[np.int64]:
        """(N,) int64: number of struts at each node."""
        d = np.bincount(self.edges.ravel(), minlength=self.num_nodes).astype(np.int64)
        d.flags.writeable = False
        return d

    @cached_property
    def isolated_nodes(self) -> NDArray[np.int64]:
        """(K,) int64: indices of nodes with no strut."""
        iso = np.flatnonzero(self.degree == 0).astype(np.int64)
        iso.flags.writeable = False
        return iso

    @cached_property
    def incidence(self) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
        """Node-to-strut incidence in CSR form.

        Returns
        -------
        offsets : (N + 1,) int64
            Struts of node ``n`` are entries ``offsets[n]:offsets[n + 1]``.
        edge_ids : (2M,) int64
            Strut index of each entry, ascending within a node.
        sides : (2M,) int64
            0 if the node is ``edges[e, 0]``, 1 if it is ``edges[e, 1]``.
        """
        m = self.num_edges
        flat_nodes = self.edges.ravel()  # entry k -> edge k // 2, side k % 2
        order = np.argsort(flat_nodes, kind="stable")
        edge_ids = (order // 2).astype(np.int64)
        sides = (order % 2).astype(np.int64)
        offsets = np.zeros(self.num_nodes + 1, dtype=np.int64)
        np.cumsum(self.degree, out=offsets[1:])
        for a in (offsets, edge_ids, sides):
            a.flags.writeable = False
        assert len(edge_ids) == 2 * m
        return offsets, edge_ids, sides

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: min and max node coordinates (zeros for an empty graph)."""
        if self.num_nodes == 0:
            return np.zeros((2, 3))
        return np.stack([self.nodes.min(axis=0), self.nodes.max(axis=0)])

    def check_precision(self, dtype: Literal["float64", "float32"] = "float64") -> None:
        """Refuse struts too thin for their coordinates' magnitude in ``dtype``.

        The constructor checks float64 (``config.PRECISION_RATIO_F64``); writers of
        single-precision files (STL, 3MF, beam-lattice 3MF) check float32
        (``config.PRECISION_RATIO_F32``) before any work. See :func:`precision_problem`.

        Raises
        ------
        InvalidGraphError
            Naming the worst strut, the radius it needs and the offset that centres the
            lattice on the origin (when that helps).
        """
        if dtype not in ("float64", "float32"):
            raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
        msg = precision_problem(self.nodes, self.edges, self.radii, dtype)
        if msg:
            raise InvalidGraphError(msg)

    # ------------------------------------------------------------- equality
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LatticeGraph):
            return NotImplemented
        return (
            np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.edges, other.edges)
            and np.array_equal(self.radii, other.radii)
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------- I/O
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (floats round-trip exactly)."""
        return {
            "format": _FORMAT,
            "version": _VERSION,
            "nodes": self.nodes.tolist(),
            "edges": self.edges.tolist(),
            "radii": self.radii.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LatticeGraph:
        """Inverse of :meth:`to_dict`; validates like the constructor."""
        if not isinstance(data, dict) or data.get("format") != _FORMAT:
            raise InvalidGraphError(f"not a lattice-cad graph (expected format {_FORMAT!r})")
        if int(data.get("version", 0)) > _VERSION:
            raise InvalidGraphError(
                f"graph format version {data['version']} is newer than supported"
            )
        missing = [k for k in ("nodes", "edges", "radii") if k not in data]
        if missing:
            raise InvalidGraphError(f"graph data is missing the key {missing[0]!r}")
        nodes, edges = data["nodes"], data["edges"]
        # an empty list stands for an empty (0, 3) or (0, 2) array
        return cls(
            np.zeros((0, 3)) if _is_empty_list(nodes) else nodes,
            np.zeros((0, 2), dtype=np.int64) if _is_empty_list(edges) else edges,
            data["radii"],
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the graph to ``.npz`` or ``.json`` (atomically). Returns the path."""
        p = Path(path)
        fmt = format_for(p, Kind.GRAPH)
        numbers = 3 * self.num_nodes + 4 * self.num_edges
        # JSON goes through Python lists (about 120 bytes per number, text included);
        # npz compresses copies of the arrays (about 16)
        require_memory(
            (120 if fmt.name == "json" else 16) * numbers,
            f"writing {p.name} ({self.num_edges:,} struts)",
            advice="save the graph as .npz (compact) rather than .json",
        )
        if fmt.name == "json":
            with atomic_write(p, "w") as fh:
                json.dump(self.to_dict(), fh)
        else:
            with atomic_write(p, "wb") as fh:
                np.savez_compressed(
                    fh,
                    format=np.array(_FORMAT),
                    version=np.array(_VERSION),
                    nodes=self.nodes,
                    edges=self.edges,
                    radii=self.radii,
                )
        return p

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> LatticeGraph:
        """Read a graph written by :meth:`save` (``.npz`` or ``.json``)."""
        p = Path(path)
        fmt = format_for(p, Kind.GRAPH, action="read")
        if p.is_dir():
            raise InputFileError(f"{p}: is a directory, not a graph file")
        if not p.exists():
            raise MissingFileError(f"graph file not found: {p}")
        if p.stat().st_size == 0:
            raise InputFileError(f"{p}: the file is empty (0 bytes), not a .{fmt.name} graph")
        try:
            if fmt.name == "json":
                with open(p, encoding="utf-8") as fh:
                    data = json.load(fh)
                return cls.from_dict(data)
            with open(p, "rb") as fh:  # ours to close, whatever np.load raises
                z = np.load(fh, allow_pickle=False)
                if not isinstance(z, np.lib.npyio.NpzFile):
                    raise InputFileError(f"{p}: not an .npz archive (a single numpy array)")
                with z:
                    if str(z.get("format", "")) != _FORMAT:
                        raise InvalidGraphError(f"{p}: not a lattice-cad graph archive")
                    return cls(z["nodes"], z["edges"], z["radii"])
        except InputFileError:
            raise
        except InvalidGraphError as exc:
            msg = str(exc)
            raise InvalidGraphError(msg if msg.startswith(f"{p}:") else f"{p}: {msg}") from None
        except json.JSONDecodeError as exc:
            raise InputFileError(f"{p}: not a JSON file (truncated or corrupt: {exc})") from None
        except UnicodeDecodeError:
            raise InputFileError(f"{p}: not a JSON file (not UTF-8 text)") from None
        except (EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise InputFileError(
                f"{p}: not a readable .npz archive (truncated or corrupt: {exc})"
            ) from None
        except KeyError as exc:
            raise InvalidGraphError(f"{p}: the archive has no array {exc}") from None
        except (OSError, ValueError) as exc:
            raise InputFileError(f"{p}: cannot read the graph: {exc}") from None


# ---------------------------------------------------------------- coercion
def _is_empty_list(x: Any) -> bool:
    return isinstance(x, list) and len(x) == 0


def _find_non_number(value: Any, path: tuple[int, ...] = ()) -> tuple[tuple[int, ...], Any] | None:
    """The first element of a nested sequence that is not a real number (bool, str, ...)."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "iuf":
            return None
        if value.dtype.kind != "O":
            return (path, value.flat[0].item()) if value.size else None
        for i, x in enumerate(value):
            found = _find_non_number(x, (*path, i))
            if found is not None:
                return found
        return None
    if isinstance(value, (list, tuple)):
        for i, x in enumerate(value):
            found = _find_non_number(x, (*path, i))
            if found is not None:
                return found
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        return path, value
    if isinstance(value, (complex, np.complexfloating)):
        return path, value
    return None


def _describe(x: Any) -> str:
    """``a boolean (True)``, ``a string ('0.1')``, ``None``: what a non-number is."""
    if x is None:
        return "None"
    if isinstance(x, (bool, np.bool_)):
        kind = "a boolean"
    elif isinstance(x, (str, bytes, np.str_, np.bytes_)):
        kind = "a string"
    elif isinstance(x, (complex, np.complexfloating)):
        kind = "a complex number"
    else:
        kind = f"a {type(x).__name__}"
    return f"{kind} ({x!r})"


def _as_number_array(value: Any, what: str) -> NDArray[Any]:
    """``value`` as an int, uint, float or (for huge Python ints) object array of real numbers.

    The one input rule of :class:`LatticeGraph`, the same for nodes, edges and radii: real
    numbers only. Strings (even numeric ones), booleans, complex numbers, None and other
    objects are refused with :class:`InvalidGraphError` naming the array and the element.
    """
    if isinstance(value, (str, bytes)):
        raise InvalidGraphError(f"{what} must be real numbers, got {_describe(value)}")
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InvalidGraphError(f"{what} must be an array of numbers: {exc}") from None
    kind = a.dtype.kind
    # a list may mix bools into numbers (numpy then casts them silently): look at the elements
    if kind == "O" or (kind in "iuf" and not isinstance(value, np.ndarray) and a.ndim > 0):
        found = _find_non_number(value)
        if found is not None:
            where, x = found
            at = f" at index {list(where)}" if where else ""
            raise InvalidGraphError(f"{what} must be real numbers, got {_describe(x)}{at}")
        if kind == "O" and what != "edges":  # e.g. Python ints beyond 64 bits
            try:
                a = np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError, OverflowError) as exc:
                raise InvalidGraphError(f"{what} must be an array of numbers: {exc}") from None
        return a  # edges keep exact Python ints for the range check
    elif kind not in "iuf":
        x = a.flat[0].item() if a.size else a.dtype
        names = {"b": "booleans", "U": "strings", "S": "strings", "c": "complex numbers",
                 "M": "dates", "m": "time spans", "V": "records"}  # fmt: skip
        if a.size == 0 and kind in "bUSc":
            return a.astype(np.float64)
        raise InvalidGraphError(
            f"{what} must be real numbers, got {names.get(kind, str(a.dtype))} "
            f"(dtype {a.dtype}, e.g. {x!r})"
        )
    return a


def _as_nodes(nodes: ArrayLike) -> NDArray[np.float64]:
    raw = _as_number_array(nodes, "nodes")
    if raw.size == 0:
        return np.zeros((0, 3), dtype=np.float64)
    if raw.ndim != 2 or raw.shape[1] != 3:
        raise InvalidGraphError(f"nodes must have shape (N, 3), got {raw.shape}")
    with np.errstate(over="ignore"):
        a = np.array(raw, dtype=np.float64, copy=True)
    return np.ascontiguousarray(a)


def _fmt_index(x: Any) -> str:
    if isinstance(x, (float, np.floating)):
        return f"{float(x):g}"
    return str(int(x))


def _as_edges(edges: ArrayLike, n_nodes: int) -> NDArray[np.int64]:
    raw = _as_number_array(edges, "edges")
    if raw.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if raw.ndim != 2 or raw.shape[1] != 2:
        raise InvalidGraphError(f"edges must have shape (M, 2), got {raw.shape}")
    if raw.dtype.kind == "f":
        bad = ~np.isfinite(raw) | (raw != np.round(raw))
        if bad.any():
            e = int(np.flatnonzero(bad.any(axis=1))[0])
            raise InvalidGraphError(f"edge {e} has a non-integer node index {raw[e].tolist()}")
    elif raw.dtype.kind == "O":  # Python ints beyond 64 bits, or integral floats among them
        flat = raw.ravel()
        for k, x in enumerate(flat):
            if isinstance(x, (float, np.floating)) and not float(x).is_integer():
                raise InvalidGraphError(
                    f"edge {k // 2} has a non-integer node index {raw[k // 2].tolist()}"
                )
    if raw.dtype.kind in "iu" and raw.min() >= 0 and raw.max() < n_nodes:
        return np.ascontiguousarray(raw.astype(np.int64))
    # range check in the given type: a uint64 2**64 - 1 or a float 1e20 must not wrap
    out = (raw < 0) | (raw >= n_nodes)
    if out.any():
        e = int(np.flatnonzero(out.any(axis=1))[0])
        node = _fmt_index(raw[e][np.asarray(out[e], dtype=bool)][0])
        has = f"{n_nodes} nodes (valid indices 0..{n_nodes - 1})" if n_nodes else "no nodes"
        raise InvalidGraphError(f"edge {e} references node {node}, but the graph has {has}")
    return np.ascontiguousarray(raw.astype(np.int64))


def _as_radii(radii: ArrayLike, n_edges: int) -> NDArray[np.float64]:
    raw = _as_number_array(radii, "radii")
    with np.errstate(over="ignore"):
        r = np.asarray(raw, dtype=np.float64)
    if r.ndim == 0:
        out = np.full((n_edges, 2), float(r))
    elif r.shape == (n_edges,):
        out = np.repeat(r[:, None], 2, axis=1)
    elif r.shape == (n_edges, 2):
        out = r.copy()
    else:
        raise InvalidGraphError(
            f"radii must be a number, shape ({n_edges},) or ({n_edges}, 2); got shape {r.shape}"
        )
    return np.ascontiguousarray(out, dtype=np.float64)


#: Rows per block in the checks of :func:`_validate` (bounds their temporaries).
_BLOCK = 1 << 16


def _blocks(n: int) -> range:
    return range(0, n, _BLOCK)


def _first_row(n: int, bad_rows: Any) -> int | None:
    """The first row ``i < n`` for which ``bad_rows(start, stop)`` (a bool block) is True."""
    for s in _blocks(n):
        bad = bad_rows(s, min(n, s + _BLOCK))
        if bad.any():
            return s + int(np.flatnonzero(bad)[0])
    return None


def _first_cell(n: int, bad_cells: Any) -> tuple[int, int] | None:
    """The first (row, column) of an (n, k) test evaluated by blocks of rows."""
    for s in _blocks(n):
        bad = bad_cells(s, min(n, s + _BLOCK))
        if bad.any():
            r, c = (int(v) for v in np.argwhere(bad)[0])
            return s + r, c
    return None


def _lengths(nodes: NDArray[np.float64], edges: NDArray[np.int64], s: int, t: int) -> Any:
    vec = nodes[edges[s:t, 1]] - nodes[edges[s:t, 0]]
    return np.sqrt(np.einsum("ij,ij->i", vec, vec))


def _is_sorted_rows(a: NDArray[Any], strict: bool) -> bool:
    """Are the rows of the (n, k) array in (strictly) increasing lexicographic order?"""
    n, k = a.shape
    for s in _blocks(max(n - 1, 0)):
        t = min(n - 1, s + _BLOCK)
        x, y = a[s:t], a[s + 1 : t + 1]
        # lexicographic x < y (or <=) over the k columns, from the last column back
        ok = (x[:, k - 1] < y[:, k - 1]) if strict else (x[:, k - 1] <= y[:, k - 1])
        for c in range(k - 2, -1, -1):
            ok = (x[:, c] < y[:, c]) | ((x[:, c] == y[:, c]) & ok)
        if not ok.all():
            return False
    return True


def _validate(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], radii: NDArray[np.float64]
) -> None:
    """The invariants of :class:`LatticeGraph`, checked by blocks of rows (temporaries stay
    small whatever the size); raises :class:`InvalidGraphError` for the first problem."""
    n_nodes, m = len(nodes), len(edges)
    bad = _first_row(n_nodes, lambda s, t: ~np.isfinite(nodes[s:t]).all(axis=1))
    if bad is not None:
        raise InvalidGraphError(f"node {bad} has a non-finite coordinate {nodes[bad].tolist()}")
    if m == 0:
        return
    huge = _first_row(n_nodes, lambda s, t: np.abs(nodes[s:t]).max(axis=1) > config.MAX_COORDINATE)
    if huge is not None:
        n = huge
        raise InvalidGraphError(
            f"node {n} at {point_text(nodes[n], digits=6)} is beyond the largest supported "
            f"coordinate {config.MAX_COORDINATE:g} (lengths' squares and the exact predicates' "
            "products would overflow); use a larger length unit (smaller numbers) or move the "
            "lattice to the origin"
        )
    loop = _first_row(m, lambda s, t: edges[s:t, 0] == edges[s:t, 1])
    if loop is not None:
        raise InvalidGraphError(f"edge {loop} is a self-loop on node {int(edges[loop, 0])}")
    _check_duplicates(edges)
    badr = _first_row(m, lambda s, t: ~np.isfinite(radii[s:t]).all(axis=1))
    if badr is not None:
        e = badr
        raise InvalidGraphError(f"edge {e} has a non-finite radius {radii[e].tolist()}")
    nonpos = _first_cell(m, lambda s, t: radii[s:t] <= 0)
    if nonpos is not None:
        e, side = nonpos
        raise InvalidGraphError(
            f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}; "
            "radii must be > 0"
        )
    tiny = _first_cell(m, lambda s, t: radii[s:t] < config.MIN_RADIUS)
    if tiny is not None:
        e, side = tiny
        raise InvalidGraphError(
            f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}, below the "
            f"smallest supported radius {config.MIN_RADIUS:g} (products of such lengths "
            "underflow in floating point); use a smaller length unit"
        )
    zero: int | None = None
    fat: int | None = None
    for s in _blocks(m):
        t = min(m, s + _BLOCK)
        length = _lengths(nodes, edges, s, t)
        z = np.flatnonzero(length == 0.0)
        if len(z):
            zero = s + int(z[0])
            break
        if fat is None:
            f = np.flatnonzero(radii[s:t].max(axis=1) >= 0.5 * length)
            if len(f):
                fat = s + int(f[0])
    if zero is not None:
        e = zero
        a, b = (int(v) for v in edges[e])
        raise InvalidGraphError(
            f"edge {e} ({a}, {b}) has zero length: nodes {a} and {b} coincide at "
            f"{point_text(nodes[a], digits=6)}"
        )
    if fat is not None:
        e = fat
        length_e = float(_lengths(nodes, edges, e, e + 1)[0])
        raise InvalidGraphError(
            f"edge {e} ({int(edges[e, 0])}, {int(edges[e, 1])}): radius {radii[e].max():g} is not "
            f"strictly below half its length {length_e:g} (must be < {0.5 * length_e:g})"
        )
    if config.PRECISION_CONTRACT and _precision_ratio(nodes, edges, radii) > (
        config.PRECISION_RATIO_F64
    ):
        msg = precision_problem(nodes, edges, radii, "float64")
        if msg:
            raise InvalidGraphError(msg)
    _check_coincident(nodes, edges)


def _check_duplicates(edges: NDArray[np.int64]) -> None:
    """Duplicate edges (in either direction): the later one is named as a duplicate of the
    earlier one. Sorted edges (``a < b``, rows ascending, as the builders make them) are
    checked by neighbours; others by a sort of all the rows."""
    m = len(edges)
    normal = _first_row(m, lambda s, t: edges[s:t, 0] >= edges[s:t, 1]) is None
    if normal and _is_sorted_rows(edges, strict=False):
        dup = _first_row(m - 1, lambda s, t: (edges[s:t] == edges[s + 1 : t + 1]).all(axis=1))
        if dup is None:
            return
        first, second = dup, dup + 1
    else:
        key = np.sort(edges, axis=1)
        order = np.lexsort((key[:, 1], key[:, 0]))
        ks = key[order]
        dups = np.flatnonzero((ks[1:] == ks[:-1]).all(axis=1))
        if not len(dups):
            return
        # report the later edge as the duplicate of the earlier one
        pairs = np.sort(np.stack([order[dups], order[dups + 1]], axis=1), axis=1)
        first, second = (int(v) for v in pairs[np.argmin(pairs[:, 1])])
    raise InvalidGraphError(
        f"edge {second} {tuple(edges[second].tolist())} duplicates edge {first} "
        f"{tuple(edges[first].tolist())}"
    )


def _precision_ratio(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], radii: NDArray[np.float64]
) -> float:
    """The largest ``|x| / r`` of the struts (see :func:`precision_problem`), by blocks."""
    big = np.empty(len(nodes))
    for s in _blocks(len(nodes)):
        np.abs(nodes[s : s + _BLOCK]).max(axis=1, out=big[s : s + _BLOCK])
    worst = 0.0
    for s in _blocks(len(edges)):
        e = edges[s : s + _BLOCK]
        scale = np.maximum(big[e[:, 0]], big[e[:, 1]])
        scale /= radii[s : s + _BLOCK].min(axis=1)
        worst = max(worst, float(scale.max()))
    return worst


def _check_coincident(nodes: NDArray[np.float64], edges: NDArray[np.int64]) -> None:
    """Distinct nodes at the same position (only among nodes that carry struts)."""
    used = np.flatnonzero(np.bincount(edges.ravel(), minlength=len(nodes)) > 0)
    if len(used) <= 1:
        return
    pts = nodes if len(used) == len(nodes) else nodes[used]
    if _is_sorted_rows(pts, strict=True):  # the builders' nodes: sorted, distinct
        return
    order = np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0]))
    same = np.flatnonzero((pts[order][1:] == pts[order][:-1]).all(axis=1))
    if len(same):
        a, b = sorted((int(used[order[same[0]]]), int(used[order[same[0] + 1]])))
        raise InvalidGraphError(f"nodes {a} and {b} coincide at {point_text(nodes[a], digits=6)}")


def precision_problem(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    dtype: Literal["float64", "float32"] = "float64",
) -> str | None:
    """Why ``dtype`` coordinates cannot represent these struts, or None when they can.

    The precision contract: every strut's ``|x| / r`` (the largest absolute coordinate of
    its two nodes over its smaller end radius) must be at most
    ``config.PRECISION_RATIO_F64`` (``PRECISION_RATIO_F32`` for single-precision files).

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
    dtype : {"float64", "float32"}

    Returns
    -------
    str or None
        The message naming the worst strut, the radius it would need, and (when that
        helps) the offset that centres the lattice on the origin.
    """
    if len(edges) == 0:
        return None
    if dtype == "float32":
        used = np.unique(edges)
        big = np.abs(nodes[used]).max(axis=1)
        if big.max() > config.MAX_COORDINATE_F32:
            n = int(used[np.argmax(big)])
            return (
                f"node {n} at {point_text(nodes[n], digits=6)} is beyond the largest coordinate of "
                f"single-precision files (STL, 3MF: {config.MAX_COORDINATE_F32:g}); use a "
                "larger length unit or move the lattice to the origin"
            )
        if radii.min() < config.MIN_RADIUS_F32:
            e, side = (int(v) for v in np.argwhere(radii == radii.min())[0])
            return (
                f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}, below "
                f"the smallest radius of single-precision files (STL, 3MF: "
                f"{config.MIN_RADIUS_F32:g}); use a smaller length unit"
            )
    limit = config.PRECISION_RATIO_F64 if dtype == "float64" else config.PRECISION_RATIO_F32
    a = np.abs(nodes).max(axis=1)
    scale = np.maximum(a[edges[:, 0]], a[edges[:, 1]])
    rmin = radii.min(axis=1)
    ratio = scale / rmin
    e = int(np.argmax(ratio))
    if not ratio[e] > limit:
        return None
    ulp = float(np.spacing(np.float64(scale[e]) if dtype == "float64" else np.float32(scale[e])))
    n0, n1 = (int(v) for v in edges[e])
    used = np.unique(edges)
    lo, hi = nodes[used].min(axis=0), nodes[used].max(axis=0)
    centre = 0.5 * (lo + hi)
    centred = np.abs(nodes - centre).max(axis=1)
    ratio_c = np.maximum(centred[edges[:, 0]], centred[edges[:, 1]]) / rmin
    where = "STL and 3MF files store coordinates in single precision (float32)"
    if dtype == "float64":
        where = "float64"
    msg = (
        f"edge {e} ({n0}, {n1}): radius {rmin[e]:.4g} is too small for its position: its "
        f"coordinates reach {scale[e]:.4g}, where {where} resolves only {ulp:.3g}, so the "
        f"mesh would be degenerate (|x| / r = {ratio[e]:.3g}; at most {limit:g} is "
        f"supported for {dtype}); give it a radius of at least {scale[e] / limit:.4g}"
    )
    shift = "(" + ", ".join(f"{-float(c):.6g}" for c in centre) + ")"
    move = (
        f"move the lattice by {shift} (centre it on the origin; a fill does that with "
        "move_to_origin=True)"
    )
    if ratio_c.max() <= limit:
        msg += f", or {move}: it then fits as is"
    elif ratio_c.max() < 0.5 * ratio.max():
        ec = int(np.argmax(ratio_c))
        need = float(np.max(np.maximum(centred[edges[:, 0]], centred[edges[:, 1]]))) / limit
        msg += (
            f", or {move}, after which radii of at least {need:.4g} suffice "
            f"(edge {ec} is then the worst)"
        )
    return msg
