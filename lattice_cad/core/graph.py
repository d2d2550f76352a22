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
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.errors import InvalidGraphError, LatticeWarning
from lattice_cad.core.formats import Kind, format_for

__all__ = ["LatticeGraph"]

_FORMAT = "lattice-cad-graph"
_VERSION = 1


def _fmt_point(p: NDArray[np.float64]) -> str:
    return "(" + ", ".join(f"{float(c):.6g}" for c in p) + ")"


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
        With the offending node or edge index in the message, for: wrong array
        shapes, non-finite coordinates or radii, radius <= 0, node index out of
        range, self-loops, duplicate edges (in either direction), zero-length
        edges, a radius not strictly below half the edge length, and distinct
        nodes at the same position.

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
                stacklevel=2,
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
        try:
            nodes = np.asarray(data["nodes"], dtype=np.float64).reshape(-1, 3)
            edges = np.asarray(data["edges"]).reshape(-1, 2)
            radii = np.asarray(data["radii"], dtype=np.float64)
        except KeyError as exc:
            raise InvalidGraphError(f"graph data is missing the key {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise InvalidGraphError(f"graph data is malformed: {exc}") from None
        return cls(nodes, edges, radii)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the graph to ``.npz`` or ``.json`` (atomically). Returns the path."""
        p = Path(path)
        fmt = format_for(p, Kind.GRAPH)
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
        if not p.exists():
            raise FileNotFoundError(f"graph file not found: {p}")
        try:
            if fmt.name == "json":
                with open(p, encoding="utf-8") as fh:
                    data = json.load(fh)
                return cls.from_dict(data)
            with np.load(p, allow_pickle=False) as z:
                if str(z.get("format", "")) != _FORMAT:
                    raise InvalidGraphError(f"{p}: not a lattice-cad graph archive")
                return cls(z["nodes"], z["edges"], z["radii"])
        except InvalidGraphError as exc:
            raise InvalidGraphError(f"{p}: {exc}") from None
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise InvalidGraphError(f"{p}: cannot read graph: {exc}") from None


# ---------------------------------------------------------------- coercion
def _as_nodes(nodes: ArrayLike) -> NDArray[np.float64]:
    try:
        a = np.array(nodes, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise InvalidGraphError(f"nodes must be numbers: {exc}") from None
    if a.size == 0:
        return np.zeros((0, 3), dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InvalidGraphError(f"nodes must have shape (N, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def _as_edges(edges: ArrayLike, n_nodes: int) -> NDArray[np.int64]:
    raw = np.asarray(edges)
    if raw.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if raw.ndim != 2 or raw.shape[1] != 2:
        raise InvalidGraphError(f"edges must have shape (M, 2), got {raw.shape}")
    if raw.dtype.kind in "iu":
        a = raw.astype(np.int64)
    elif raw.dtype.kind == "f":
        bad = ~np.isfinite(raw) | (raw != np.round(raw))
        if bad.any():
            e = int(np.flatnonzero(bad.any(axis=1))[0])
            raise InvalidGraphError(f"edge {e} has a non-integer node index {raw[e].tolist()}")
        a = raw.astype(np.int64)
    else:
        raise InvalidGraphError(f"edges must be integer node indices, got dtype {raw.dtype}")
    out = (a < 0) | (a >= n_nodes)
    if out.any():
        e = int(np.flatnonzero(out.any(axis=1))[0])
        k = int(a[e][out[e]][0])
        raise InvalidGraphError(
            f"edge {e} references node {k}, but the graph has {n_nodes} nodes "
            f"(valid indices 0..{n_nodes - 1})"
        )
    return np.ascontiguousarray(a)


def _as_radii(radii: ArrayLike, n_edges: int) -> NDArray[np.float64]:
    try:
        r = np.asarray(radii, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidGraphError(f"radii must be numbers: {exc}") from None
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


def _validate(
    nodes: NDArray[np.float64], edges: NDArray[np.int64], radii: NDArray[np.float64]
) -> None:
    bad = ~np.isfinite(nodes).all(axis=1)
    if bad.any():
        n = int(np.flatnonzero(bad)[0])
        raise InvalidGraphError(f"node {n} has a non-finite coordinate {nodes[n].tolist()}")
    if len(edges) == 0:
        return
    loops = edges[:, 0] == edges[:, 1]
    if loops.any():
        e = int(np.flatnonzero(loops)[0])
        raise InvalidGraphError(f"edge {e} is a self-loop on node {int(edges[e, 0])}")
    key = np.sort(edges, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks = key[order]
    dup = np.flatnonzero((ks[1:] == ks[:-1]).all(axis=1))
    if len(dup):
        # report the later edge as the duplicate of the earlier one
        pairs = np.sort(np.stack([order[dup], order[dup + 1]], axis=1), axis=1)
        first, second = (int(v) for v in pairs[np.argmin(pairs[:, 1])])
        raise InvalidGraphError(
            f"edge {second} {tuple(edges[second].tolist())} duplicates edge {first} "
            f"{tuple(edges[first].tolist())}"
        )
    badr = ~np.isfinite(radii)
    if badr.any():
        e = int(np.flatnonzero(badr.any(axis=1))[0])
        raise InvalidGraphError(f"edge {e} has a non-finite radius {radii[e].tolist()}")
    nonpos = radii <= 0
    if nonpos.any():
        e, side = (int(v) for v in np.argwhere(nonpos)[0])
        raise InvalidGraphError(
            f"edge {e} has radius {radii[e, side]:g} at node {int(edges[e, side])}; "
            "radii must be > 0"
        )
    vec = nodes[edges[:, 1]] - nodes[edges[:, 0]]
    length = np.sqrt(np.einsum("ij,ij->i", vec, vec))
    zero = length == 0.0
    if zero.any():
        e = int(np.flatnonzero(zero)[0])
        a, b = (int(v) for v in edges[e])
        raise InvalidGraphError(
            f"edge {e} ({a}, {b}) has zero length: nodes {a} and {b} coincide at "
            f"{_fmt_point(nodes[a])}"
        )
    fat = radii.max(axis=1) >= 0.5 * length
    if fat.any():
        e = int(np.flatnonzero(fat)[0])
        raise InvalidGraphError(
            f"edge {e} ({int(edges[e, 0])}, {int(edges[e, 1])}): radius {radii[e].max():g} is not "
            f"strictly below half its length {length[e]:g} (must be < {0.5 * length[e]:g})"
        )
    # distinct nodes at the same position (only among nodes that carry struts)
    used = np.flatnonzero(np.bincount(edges.ravel(), minlength=len(nodes)) > 0)
    if len(used) > 1:
        pts = nodes[used]
        order = np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0]))
        same = np.flatnonzero((pts[order][1:] == pts[order][:-1]).all(axis=1))
        if len(same):
            a, b = sorted((int(used[order[same[0]]]), int(used[order[same[0] + 1]])))
            raise InvalidGraphError(f"nodes {a} and {b} coincide at {_fmt_point(nodes[a])}")
