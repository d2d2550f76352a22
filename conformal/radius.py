"""Strut radii for the lattice builders, and the check that a graph will stitch.

A *radius spec* is one of

* a number: every strut end;
* an ``(M,)`` array (one per strut) or ``(M, 2)`` array (per strut end:
  tapered struts, ``[:, 0]`` at ``edges[:, 0]``);
* a callable ``f(midpoints) -> (M,) or (M, 2)`` of the ``(M, 3)`` strut
  midpoints (graded lattices; see :func:`graded_by_distance`).

:func:`check_fit` lists the struts that :func:`fast_stitch.stitch` would
reject because their end profiles (whose offsets from the node are set by the
angles and radii of all struts at that node) would meet; :func:`fit_radii`
thins the struts at the offending nodes until every strut fits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fast_stitch.fit import misfits
from lattice_cad.errors import LatticeError
from lattice_cad.graph import LatticeGraph

if TYPE_CHECKING:
    from conformal.part import Part

__all__ = [
    "RadiusSpec",
    "resolve_radii",
    "graded_by_distance",
    "StrutMisfit",
    "check_fit",
    "fit_radii",
    "FitError",
]

RadiusSpec = Union[float, ArrayLike, Callable[[NDArray[np.float64]], ArrayLike]]  # noqa: UP007

#: Fraction of its length every strut keeps as open cylinder after :func:`fit_radii`.
FIT_SLACK = 0.05


class FitError(LatticeError, ValueError):
    """Some struts cannot be made to fit (the message lists them)."""


def resolve_radii(
    radius: RadiusSpec, nodes: NDArray[np.float64], edges: NDArray[np.int64]
) -> NDArray[np.float64]:
    """Turn a radius spec into per-end radii.

    Parameters
    ----------
    radius : float, (M,), (M, 2) or callable
        See the module docstring.
    nodes : (N, 3) float64
    edges : (M, 2) int64

    Returns
    -------
    (M, 2) float64

    Raises
    ------
    ValueError
        Wrong shape, or a radius that is not finite and > 0 (the message names the strut).
    """
    m = len(edges)
    if callable(radius):
        mid = 0.5 * (nodes[edges[:, 0]] + nodes[edges[:, 1]])
        r = np.asarray(radius(mid), dtype=np.float64)
        what = "the radius callable's result"
    else:
        r = np.asarray(radius, dtype=np.float64)
        what = "radius"
    if r.ndim == 0:
        out = np.full((m, 2), float(r))
    elif r.shape == (m,):
        out = np.repeat(r[:, None], 2, axis=1)
    elif r.shape == (m, 2):
        out = r.astype(np.float64, copy=True)
    else:
        raise ValueError(
            f"{what} must be a number or have shape ({m},) or ({m}, 2) for {m} struts; "
            f"got shape {r.shape}"
        )
    bad = ~(np.isfinite(out) & (out > 0)).all(axis=1)
    if bad.any():
        e = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}: strut {e} has radius {out[e].tolist()}; radii must be > 0")
    return out


def graded_by_distance(
    part: Part, *, near: float, far: float, width: float
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """A radius callable: ``near`` at the part's surface, ``far`` at ``width`` and beyond.

    Linear in the distance ``d`` of the strut midpoint to the surface:
    ``far + (near - far) * max(0, 1 - d / width)``.
    """
    if not (near > 0 and far > 0 and width > 0):
        raise ValueError("near, far and width must be > 0")

    def f(mid: NDArray[np.float64]) -> NDArray[np.float64]:
        d = part.distance(mid, max_distance=width)
        t = np.where(np.isfinite(d), np.clip(1.0 - d / width, 0.0, 1.0), 0.0)
        return far + (near - far) * t

    return f


@dataclass(frozen=True)
class StrutMisfit:
    """A strut whose end profiles would meet: stitching would fail on it."""

    edge: int
    nodes: tuple[int, int]
    length: float
    needed: float  #: sum of the two end offsets; must stay below ``length``

    def __str__(self) -> str:
        return (
            f"strut {self.edge} (nodes {self.nodes[0]}, {self.nodes[1]}): length {self.length:.4g} "
            f"but its end profiles need {self.needed:.4g}; use thinner struts or a coarser lattice"
        )


def check_fit(graph: LatticeGraph, segments: int = 6, *, shrink: bool = True) -> list[StrutMisfit]:
    """The struts of ``graph`` that :func:`fast_stitch.stitch` would reject as too short.

    Uses the stitcher's own offset rule (:mod:`fast_stitch.fit`); the result
    does not depend on ``segments`` (kept for symmetry with ``stitch``). Does
    not check clearance between struts that share no node.

    Returns
    -------
    list of StrutMisfit
        Empty when every strut fits.
    """
    del segments  # offsets do not depend on the number of segments
    bad, need, length = misfits(graph.nodes, graph.edges, graph.radii, shrink=shrink)
    return [
        StrutMisfit(
            int(e),
            (int(graph.edges[e, 0]), int(graph.edges[e, 1])),
            float(length[e]),
            float(need[e]),
        )
        for e in bad
    ]


def fit_radii(
    nodes: NDArray[np.float64],
    edges: NDArray[np.int64],
    radii: NDArray[np.float64],
    *,
    min_radius: float = 0.0,
    shrink: bool = True,
    max_rounds: int = 60,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Thin the struts at crowded nodes until every strut fits.

    A strut fits when its end offsets leave ``FIT_SLACK`` of its length free
    and its radius is below 0.45 of its length. Offsets at a node scale
    linearly with the radii there, so the radii at both ends of a misfit
    strut's nodes are scaled down by the missing factor (which may taper
    neighbouring struts), and the check is repeated.

    Parameters
    ----------
    nodes : (N, 3) float64
    edges : (M, 2) int64
    radii : (M, 2) float64
    min_radius : float
        Radii are never reduced below this.

    Returns
    -------
    radii : (M, 2) float64
        The fitted radii.
    unfit : (K,) int64
        Struts that still do not fit (radius at ``min_radius``).
    """
    r = np.array(radii, dtype=np.float64, copy=True)
    length = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
    cap = 0.45 * length
    too_fat = r > cap[:, None]
    r[too_fat] = np.broadcast_to(cap[:, None], r.shape)[too_fat]
    bad = np.zeros(0, dtype=np.int64)
    n_nodes = len(nodes)
    for _ in range(max_rounds):
        bad, need, length = misfits(nodes, edges, r, shrink=shrink, slack=FIT_SLACK)
        if not len(bad):
            return r, bad
        factor = np.clip((1.0 - 1.5 * FIT_SLACK) * length[bad] / need[bad], 0.2, 0.97)
        node_f = np.ones(n_nodes)
        np.minimum.at(node_f, edges[bad, 0], factor)
        np.minimum.at(node_f, edges[bad, 1], factor)
        new = r * node_f[edges]
        new = np.maximum(new, min_radius)
        if np.array_equal(new, r):
            break
        r = new
    return r, bad
