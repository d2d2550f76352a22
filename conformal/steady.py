"""Steady lattices (Gupta, Kurzeja, Rossignac et al., *Designing and processing
parametric models of steady lattices*).

A steady lattice is a base *cluster* of balls ``C_0``, three similarities
``U, V, W`` and repetition counts ``(ni, nj, nk)``: cluster ``(i, j, k)`` is
``C[i, j, k] = W^k V^j U^i C_0`` (ball radii scale with ``m_w^k m_v^j m_u^i``,
Eq. 7). *Racks* ``(s, e, di, dj, dk)`` join ball ``s`` of every cluster
``(i, j, k)`` to ball ``e`` of cluster ``(i + di, j + dj, k + dk)`` whenever both
exist, by a *beam*: the truncated cone tangent to both balls (their convex hull).

Every cluster is evaluated directly through real powers of similarities (no
iteration); :meth:`SteadyLattice.graph` exports any index box without
building the rest; :meth:`SteadyLattice.integral_properties` gives volume,
area, centroid and spherical inertia from the first ij-slab in closed form
(paper Sec. 6), or by brute force over all hubs.

What the integral properties measure
------------------------------------
The paper decomposes the lattice into *hubs* (a ball and its half-beams) and
assumes a *clean* lattice (hubs with disjoint interiors, Sec. 2), so that
properties add up hub by hub. Its own per-hub values come from a sampled
approximation (Sec. 6.1); here every hub quantity is exact for a clean
lattice whose stumps do not overlap each other outside their ball:

* each ball counts fully (volume ``4/3 pi r^3``, area ``4 pi r^2``);
* each beam counts as its *connector*: the convex hull of its two balls minus
  the two balls (so a ball and its beams are never counted twice). Its area is
  the cone's lateral area minus the two ball caps it covers.

Summing hub by hub or element by element is the same sum (the two stumps of a
beam partition its connector). Overlaps between connectors at a node, between
beams of different racks, or between balls of different clusters are *not*
subtracted, exactly as in the paper's hub sums: for lattices that are not
clean, ``volume`` is the sum of the element volumes (an upper bound of the
union's) and ``area`` counts hidden surface. Beams whose balls overlap
(``L <= r1 + r2``) have no connector and are rejected.

Closed form
-----------
Every k-row of balls and of each rack's beams is steady under ``W`` (Sec. 4):
the element started at cluster ``(i, j, k)`` is ``W^k`` of the one started at
``(i, j, 0)``. The paper writes the lattice as ``nk`` images of the first
ij-slab; at the k-boundary this is not exact (beams of a rack with ``dk != 0``
exist only for ``max(0, -dk) <= k < nk - max(0, dk)``), so we apply the same
formulas per family (balls; each rack) with that family's own k-range, the
"first slab" of a rack being its beams started at ``k = 0`` (whose end may lie
at the virtual cluster ``k = dk < 0``). With ``m = m_w``, angle ``alpha``,
axis ``N`` and fixed point / axis point ``F`` of ``W`` (Sec. 5.1), and slab
moments about ``F``:

* swirl (``m != 1``): area ``a0 sum m^(2k)`` (Eq. 8), volume ``v0 sum m^(3k)``
  (Eq. 9), first moment ``sum m^(4k) R^k Y0`` (Eqs. 11-15: axial part times
  ``sum m^(4k)``, perpendicular part times ``sum m^(4k) c_k`` and
  ``sum m^(4k) s_k``), second moment ``J0 sum m^(5k)`` (Eq. 20);
* screw (``m == 1``): ``nk a0``, ``nk v0``, ``sum R^k Y0 + d v0 (sum k) N``
  (Eq. 18), ``nk J0 + 2 d (sum k) N.Y0 + d^2 (sum k^2) v0`` (Eq. 21);

then the centroid and the inertia about it follow by the transfer formula
(Eq. 19); this is Eqs. 20-21 with the terms regrouped about ``F``. Geometric
and trigonometric sums (Eq. 15) are evaluated as complex geometric series
``sum (m^p e^(i alpha))^k`` with ``expm1``, exactly ``count`` at the identity;
``sum k`` and ``sum k^2`` are exact integers. When ``W`` is close to a
translation the fixed point or axis lies far away and the transfer to the
centroid would cancel digits; when more than 4 digits would be lost, the sums
are evaluated instead by binary splitting (``sum_{k<2n} = sum_{k<n} +
W^n sum_{k<n}``, ``O(log nk)`` exact moment transforms about a nearby point),
reported as ``method == "closed-split"``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from conformal import _steady_kernels as _k
from conformal.similarity import Similarity, _ratio, as_similarity, powers
from lattice_cad.core.errors import SteadyLatticeError
from lattice_cad.core.graph import LatticeGraph

__all__ = ["SteadyLattice", "SteadyLatticeError"]

RegionLike = Sequence[Sequence[int] | slice | int] | None
#: When the transfer to the centroid would amplify rounding more than this, use splitting.
_MAX_AMPLIFICATION = 1e4


# Moments of a set of solids about a common reference point P:
# (volume, area, first moment integral (x - P) dV (3,), integral |x - P|^2 dV).
_Moments = tuple[float, float, NDArray[np.float64], float]


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _transform_moments(mo: _Moments, s: Similarity, ref: NDArray[np.float64]) -> _Moments:
    """Moments (about ``ref``) of the image of a set of solids under ``s``."""
    v, a, y, j = mo
    m = s.scale
    d = s(ref) - ref
    ry = s.rotation @ y
    m3 = m**3
    return (
        m3 * v,
        m * m * a,
        m3 * (m * ry + v * d),
        m3 * (m * m * j + 2.0 * m * float(d @ ry) + v * float(d @ d)),
    )


def _add(a: _Moments, b: _Moments) -> _Moments:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


def _split_sum(mo: _Moments, w: Similarity, n: int, ref: NDArray[np.float64]) -> _Moments:
    """``sum_{k=0}^{n-1} W^k mo`` by binary splitting (``O(log n)`` transforms)."""
    if n == 1:
        return mo
    h = n // 2
    half = _split_sum(mo, w, h, ref)
    out = _add(half, _transform_moments(half, w.power(h), ref))
    if n % 2:
        out = _add(out, _transform_moments(mo, w.power(n - 1), ref))
    return out


def _geo(mu: complex, k0: int, n: int) -> complex:
    """``sum_{k=k0}^{k0+n-1} exp(mu k)`` (exactly ``n`` when ``mu == 0``)."""
    r = _ratio(mu, float(n))
    if k0 == 0:
        return r
    x = mu * k0
    return complex(math.exp(x.real) * math.cos(x.imag), math.exp(x.real) * math.sin(x.imag)) * r


def _rot_apply(c: complex, y: NDArray[np.float64], n: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Re(c) y + Im(c) N x y`` (complex scalar acting on the plane normal to ``N``)."""
    return c.real * y + c.imag * np.cross(n, y)


class SteadyLattice:
    """A steady lattice: ``C[i, j, k] = W^k V^j U^i C_0`` with racks of tapered beams.

    Parameters
    ----------
    cluster : sequence of ((3,) float, float)
        Base cluster ``C_0``: ``n >= 1`` disjoint balls as ``(centre, radius)``.
    racks : sequence of 5 ints
        ``(start, end, di, dj, dk)``: a beam from ball ``start`` of cluster
        ``(i, j, k)`` to ball ``end`` of cluster ``(i + di, j + dj, k + dk)``,
        for every ``(i, j, k)`` for which both clusters exist. May be empty.
    u, v, w : Similarity, optional
        Incremental similarities ``U``, ``V``, ``W`` (default: identity), or
        cumulative ones with ``cumulative=True``.
    counts : (3,) int
        Repetition counts ``(ni, nj, nk)``, each >= 1.
    cumulative : bool, keyword-only
        When True, ``u``, ``v``, ``w`` are the cumulative similarities
        ``U' = U^(ni - 1)`` etc. relating the first and last clusters of a row
        (paper Sec. 5.3); the incremental ones are ``U = U'^(1 / (ni - 1))``
        (identity when the count is 1).

    Raises
    ------
    SteadyLatticeError
        With the ball or rack index in the message, for: an empty cluster, a
        malformed ball, a non-finite centre, a radius <= 0, two base balls that
        intersect, a malformed rack, a ball index out of range, a rack joining a
        ball to itself, two racks defining the same beams (in either direction),
        or counts that are not three integers >= 1.

    Attributes
    ----------
    centres : (n, 3) float64, read-only
    radii : (n,) float64, read-only
    racks : (P, 5) int64, read-only
    u, v, w : Similarity
        Incremental similarities.
    counts : tuple[int, int, int]
    """

    def __init__(
        self,
        cluster: Sequence[tuple[ArrayLike, float]],
        racks: Sequence[Sequence[int]] = (),
        u: Similarity | None = None,
        v: Similarity | None = None,
        w: Similarity | None = None,
        counts: Sequence[int] = (1, 1, 1),
        *,
        cumulative: bool = False,
    ) -> None:
        self.centres, self.radii = _parse_cluster(cluster)
        self.racks = _parse_racks(racks, len(self.radii))
        self.counts = _parse_counts(counts)
        sims = [as_similarity(s, name) for s, name in ((u, "u"), (v, "v"), (w, "w"))]
        if cumulative:
            sims = [
                s.power(1.0 / (c - 1)) if c > 1 else Similarity()
                for s, c in zip(sims, self.counts, strict=True)
            ]
        self.u, self.v, self.w = sims
        for a in (self.centres, self.radii, self.racks):
            a.flags.writeable = False

    # ---------------------------------------------------------------- sizes
    @property
    def num_clusters(self) -> int:
        """``ni * nj * nk``."""
        ni, nj, nk = self.counts
        return ni * nj * nk

    @property
    def num_balls(self) -> int:
        """Number of balls, ``n * ni * nj * nk``."""
        return len(self.radii) * self.num_clusters

    def rack_beam_counts(self) -> NDArray[np.int64]:
        """(P,) int64: beams in each rack, ``prod_a max(0, n_a - |d_a|)``."""
        c = np.asarray(self.counts, dtype=np.int64)
        return np.prod(np.maximum(0, c - np.abs(self.racks[:, 2:5])), axis=1).astype(np.int64)

    @property
    def num_beams(self) -> int:
        """Total number of beams (exact integer, may exceed 2**53)."""
        ni, nj, nk = self.counts
        return sum(
            max(0, ni - abs(int(r[2]))) * max(0, nj - abs(int(r[3]))) * max(0, nk - abs(int(r[4])))
            for r in self.racks
        )

    def __repr__(self) -> str:
        ni, nj, nk = self.counts
        return (
            f"SteadyLattice({len(self.radii)} balls/cluster, {len(self.racks)} racks, "
            f"{ni} x {nj} x {nk} clusters, {self.num_beams:,} beams)"
        )

    # ----------------------------------------------------------- evaluation
    def cluster_transform(self, i: int, j: int, k: int) -> Similarity:
        """``W^k V^j U^i`` (any integers, also outside the counts)."""
        return self.w.power(k) @ self.v.power(j) @ self.u.power(i)

    def cluster(self, i: int, j: int, k: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Balls of cluster ``(i, j, k)`` by Eq. (7): centres (n, 3) and radii (n,) float64."""
        s = self.cluster_transform(i, j, k)
        return s(self.centres), s.scale * self.radii

    def _box(self, region: RegionLike) -> list[tuple[int, int]]:
        if region is None:
            return [(0, c) for c in self.counts]
        if not isinstance(region, (list, tuple)) or len(region) != 3:
            raise SteadyLatticeError(
                "region must be three index ranges ((i0, i1), (j0, j1), (k0, k1)) or slices"
            )
        out = []
        for axis, (item, c) in enumerate(zip(region, self.counts, strict=True)):
            name = "ijk"[axis]
            if isinstance(item, slice):
                if item.step not in (None, 1):
                    raise SteadyLatticeError(f"region {name}: slice step must be 1")
                lo, hi, _ = item.indices(c)
            elif _is_int(item):
                lo, hi = int(item), int(item) + 1
            else:
                try:
                    lo, hi = (int(x) for x in item)
                except (TypeError, ValueError):
                    raise SteadyLatticeError(
                        f"region {name}: expected (start, stop), a slice or an index, got {item!r}"
                    ) from None
            if not 0 <= lo < hi <= c:
                raise SteadyLatticeError(
                    f"region {name}: range [{lo}, {hi}) is empty or outside 0..{c} "
                    f"(count {name} = {c})"
                )
            out.append((lo, hi))
        return out

    def balls(self, region: RegionLike = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Centres ``(ni', nj', nk', n, 3)`` and radii ``(ni', nj', nk', n)`` in a region.

        ``region``: ``((i0, i1), (j0, j1), (k0, k1))`` half-open index ranges (or
        slices, or single indices); ``None`` is the whole lattice.
        """
        (i0, i1), (j0, j1), (k0, k1) = self._box(region)
        us, ur, ut = powers(self.u, range(i0, i1))
        vs, vr, vt = powers(self.v, range(j0, j1))
        ws, wr, wt = powers(self.w, range(k0, k1))
        p = us[:, None, None] * np.einsum("iab,nb->ina", ur, self.centres) + ut[:, None, :]
        q = vs[:, None, None, None] * np.einsum("jab,inb->jina", vr, p) + vt[:, None, None, :]
        x = (
            ws[:, None, None, None, None] * np.einsum("kab,jinb->kjina", wr, q)
            + wt[:, None, None, None, :]
        )
        centres = np.ascontiguousarray(x.transpose(2, 1, 0, 3, 4))
        radii = (
            us[:, None, None, None]
            * vs[None, :, None, None]
            * ws[None, None, :, None]
            * self.radii[None, None, None, :]
        )
        return centres, radii

    def graph(
        self, region: RegionLike = None, *, return_index: bool = False
    ) -> LatticeGraph | tuple[LatticeGraph, NDArray[np.int64]]:
        """Export the balls and beams of an index box as a :class:`LatticeGraph`.

        Nodes are ball centres; each beam whose two balls are in the region is a
        tapered strut with the radii of its two balls. Balls without a beam in
        the region are left out (a graph has no isolated balls). Only the region
        is evaluated, so a small window of a huge lattice is cheap.

        Parameters
        ----------
        region : ((i0, i1), (j0, j1), (k0, k1)), optional
            Half-open cluster index ranges (slices or single indices also work);
            default: the whole lattice.
        return_index : bool, keyword-only
            Also return the (N, 4) int64 array ``(i, j, k, ball)`` of every node.

        Raises
        ------
        SteadyLatticeError
            For a malformed or empty region, or when the region has no beam.
        InvalidGraphError
            When beams are not valid struts (e.g. a radius not below half the
            beam length), with the graph's edge index.
        """
        box = self._box(region)
        centres, radii = self.balls(region)
        ni, nj, nk, nb = radii.shape
        ids = np.arange(radii.size, dtype=np.int64).reshape(ni, nj, nk, nb)
        edges, rads = [], []
        for r in self.racks:
            s, e, di, dj, dk = (int(x) for x in r)
            sl_a, sl_b = [], []
            for d, n in zip((di, dj, dk), (ni, nj, nk), strict=True):
                lo, hi = max(0, -d), min(n, n - d)
                if hi <= lo:
                    break
                sl_a.append(slice(lo, hi))
                sl_b.append(slice(lo + d, hi + d))
            else:
                a = ids[sl_a[0], sl_a[1], sl_a[2], s].ravel()
                b = ids[sl_b[0], sl_b[1], sl_b[2], e].ravel()
                edges.append(np.column_stack([a, b]))
                rads.append(
                    np.column_stack(
                        [
                            radii[sl_a[0], sl_a[1], sl_a[2], s].ravel(),
                            radii[sl_b[0], sl_b[1], sl_b[2], e].ravel(),
                        ]
                    )
                )
        if not edges:
            raise SteadyLatticeError(f"region {box} contains no beam")
        ed = np.vstack(edges)
        used, inv = np.unique(ed, return_inverse=True)
        graph = LatticeGraph(centres.reshape(-1, 3)[used], inv.reshape(-1, 2), np.vstack(rads))
        if not return_index:
            return graph
        ii, jj, kk, bb = np.unravel_index(used, (ni, nj, nk, nb))
        index = np.column_stack([ii + box[0][0], jj + box[1][0], kk + box[2][0], bb]).astype(
            np.int64
        )
        return graph, index

    # --------------------------------------------------- integral properties
    def _family_ranges(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """lo, hi (1 + P, 3): start-cluster index ranges of balls and of each rack."""
        c = np.asarray(self.counts, dtype=np.int64)
        d = self.racks[:, 2:5]
        lo = np.vstack([np.zeros((1, 3), np.int64), np.maximum(0, -d)])
        hi = np.vstack([c[None, :], np.minimum(c, c - d)])
        return lo.astype(np.int64), hi.astype(np.int64)

    def _run_kernel(
        self, k0: int, k1: int, lo: NDArray[np.int64], hi: NDArray[np.int64], ref: NDArray
    ) -> NDArray[np.float64]:
        """(1 + P, 6) family sums for start clusters with k in [k0, k1)."""
        ni, nj, _ = self.counts
        us, ur, ut = powers(self.u, range(ni))
        pts = us[:, None, None] * np.einsum("iab,nb->ina", ur, self.centres) + ut[:, None, :]
        vs, vr, vt = powers(self.v, range(nj))
        dk = self.racks[:, 4] if len(self.racks) else np.zeros(1, np.int64)
        kmin = min(0, int(dk.min())) + k0
        kmax = max(0, int(dk.max())) + k1
        ws, wr, wt = powers(self.w, range(kmin, kmax))
        racks = np.ascontiguousarray(self.racks, dtype=np.int64).reshape(-1, 5)
        out, err = _k.empty_outputs((k1 - k0) * nj, 1 + len(racks))
        # dynamic scheduling of rows: robust to busy cores
        chunk = numba.set_parallel_chunksize(4)
        try:
            _k.family_moments(
                np.ascontiguousarray(pts), us, np.ascontiguousarray(self.radii), vs, vr, vt,
                ws, wr, wt, -kmin, racks, lo, hi, ref, k0, k1, out, err,
            )  # fmt: skip
        finally:
            numba.set_parallel_chunksize(chunk)
        bad = np.flatnonzero(err[:, 0] >= 0)
        if len(bad):
            q, i, j, k = (int(x) for x in err[bad[0]])
            s, e, di, dj, dkk = (int(x) for x in racks[q])
            raise SteadyLatticeError(
                f"rack {q} ({s}, {e}, {di}, {dj}, {dkk}): the beam from cluster ({i}, {j}, {k}) "
                f"joins balls that overlap (length <= sum of radii); beams need disjoint balls"
            )
        return out.sum(axis=0)

    def integral_properties(self, method: Literal["closed", "brute"] = "closed") -> dict[str, Any]:
        """Volume, area, centroid and spherical inertia of the lattice (paper Sec. 6).

        See the module notes for exactly what is summed (balls plus beam
        connectors, overlaps between different elements not subtracted).

        Parameters
        ----------
        method : {"closed", "brute"}
            ``"closed"``: the first ij-slab is summed element by element
            (``O(ni nj)``), then the k-direction in closed form (Eqs. 8-21).
            ``"brute"``: every hub of the lattice is evaluated directly and
            summed (``O(ni nj nk)``), for validation.

        Returns
        -------
        dict
            ``volume`` (float), ``area`` (float), ``centroid`` ((3,) float64),
            ``spherical_inertia`` (float; ``integral |x - centroid|^2 dV``, unit
            density), ``num_balls`` (int), ``num_beams`` (int) and ``method``
            (``"closed"``, ``"closed-split"`` or ``"brute"``).

        Raises
        ------
        SteadyLatticeError
            For an unknown method, or a beam whose balls overlap (rack and
            cluster indices named).
        """
        if method not in ("closed", "brute"):
            raise SteadyLatticeError(f"method must be 'closed' or 'brute', got {method!r}")
        ref = np.ascontiguousarray(self.centres.mean(axis=0))
        lo, hi = self._family_ranges()
        nk = self.counts[2]
        if method == "brute":
            fam = self._run_kernel(0, nk, lo, hi, ref)
            tot: _Moments = (
                float(fam[:, 0].sum()), float(fam[:, 1].sum()), fam[:, 2:5].sum(axis=0),
                float(fam[:, 5].sum()),
            )  # fmt: skip
            used = "brute"
        else:
            lo0, hi0 = lo.copy(), hi.copy()
            lo0[:, 2], hi0[:, 2] = 0, 1
            fam = self._run_kernel(0, 1, lo0, hi0, ref)
            ka = lo[:, 2]
            kb = hi[:, 2]
            tot, used = self._closed_sum(fam, ka, kb, ref)
        v, a, y, j = tot
        centroid = ref + y / v
        inertia = j - float(y @ y) / v
        return {
            "volume": v,
            "area": a,
            "centroid": centroid,
            "spherical_inertia": inertia,
            "num_balls": self.num_balls,
            "num_beams": self.num_beams,
            "method": used,
        }

    def _closed_sum(
        self,
        fam: NDArray[np.float64],
        ka: NDArray[np.int64],
        kb: NDArray[np.int64],
        ref: NDArray[np.float64],
    ) -> tuple[_Moments, str]:
        w = self.w
        can = w.decompose(near=ref)
        f = can.point
        n_ax = can.axis
        lam = math.log(can.scale)
        alpha = can.angle
        shift = f - ref  # F - P
        V = 0.0
        A = 0.0
        Y = np.zeros(3)  # about F
        J = 0.0  # about F
        fams = []
        for q in range(len(fam)):
            n = int(kb[q] - ka[q])
            if n <= 0 or fam[q, 0] == 0.0:
                continue
            v0, a0, yp, jp = float(fam[q, 0]), float(fam[q, 1]), fam[q, 2:5], float(fam[q, 5])
            fams.append(((v0, a0, yp.copy(), jp), int(ka[q]), n))
            # moments about F
            yf = yp - v0 * shift
            jf = jp - 2.0 * float(shift @ yp) + v0 * float(shift @ shift)
            y_ax = float(yf @ n_ax) * n_ax
            y_pp = yf - y_ax
            k0 = int(ka[q])
            if can.kind == "swirl":
                V += v0 * _geo(complex(3 * lam), k0, n).real
                A += a0 * _geo(complex(2 * lam), k0, n).real
                Y += _geo(complex(4 * lam), k0, n).real * y_ax
                Y += _rot_apply(_geo(complex(4 * lam, alpha), k0, n), y_pp, n_ax)
                J += jf * _geo(complex(5 * lam), k0, n).real
            else:
                d = can.shift
                k1 = k0 + n - 1
                s1 = (k0 + k1) * n / 2.0
                s2 = (k1 * (k1 + 1) * (2 * k1 + 1) - (k0 - 1) * k0 * (2 * k0 - 1)) / 6.0
                V += n * v0
                A += n * a0
                Y += n * y_ax + _rot_apply(_geo(complex(0.0, alpha), k0, n), y_pp, n_ax)
                Y += d * v0 * s1 * n_ax
                J += n * jf + 2.0 * d * s1 * float(n_ax @ yf) + d * d * s2 * v0
        if V == 0.0:
            raise SteadyLatticeError("the lattice has zero volume")
        # transfer: inertia about the centroid = J_F - |Y_F|^2 / V
        inertia = J - float(Y @ Y) / V
        if inertia > 0.0 and J <= _MAX_AMPLIFICATION * inertia:
            y_ref = Y + V * shift
            # J about ref, rebuilt from the inertia (avoids a second cancellation)
            j_ref = inertia + float(y_ref @ y_ref) / V
            return (V, A, y_ref, j_ref), "closed"
        # near-translation W: binary splitting about ref (well-conditioned)
        tot: _Moments = (0.0, 0.0, np.zeros(3), 0.0)
        for mo, k0, n in fams:
            part = _split_sum(mo, w, n, ref)
            if k0:
                part = _transform_moments(part, w.power(k0), ref)
            tot = _add(tot, part)
        return tot, "closed-split"


# --------------------------------------------------------------- parsing
def _parse_cluster(cluster: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    try:
        items = list(cluster)
    except TypeError:
        raise SteadyLatticeError("cluster must be a sequence of (centre, radius) pairs") from None
    if not items:
        raise SteadyLatticeError("cluster must have at least one ball")
    centres = np.empty((len(items), 3))
    radii = np.empty(len(items))
    for b, item in enumerate(items):
        try:
            c, r = item
            centres[b] = np.asarray(c, dtype=np.float64).reshape(3)
            radii[b] = float(r)
        except (TypeError, ValueError):
            raise SteadyLatticeError(
                f"ball {b}: expected ((x, y, z), radius), got {item!r}"
            ) from None
        if not np.isfinite(centres[b]).all():
            raise SteadyLatticeError(f"ball {b}: centre {centres[b].tolist()} is not finite")
        if not (math.isfinite(radii[b]) and radii[b] > 0.0):
            raise SteadyLatticeError(f"ball {b}: radius must be finite and > 0, got {radii[b]!r}")
    if len(items) > 1:
        d = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
        clash = d <= radii[:, None] + radii[None, :]
        np.fill_diagonal(clash, False)
        if clash.any():
            a, b = (int(x) for x in np.argwhere(clash)[0])
            raise SteadyLatticeError(
                f"balls {a} and {b} of the cluster intersect (distance {d[a, b]:g} <= "
                f"{radii[a]:g} + {radii[b]:g}); cluster balls must be disjoint"
            )
    return centres, radii


def _parse_racks(racks: Any, n: int) -> NDArray[np.int64]:
    try:
        items = list(racks)
    except TypeError:
        raise SteadyLatticeError("racks must be a sequence of (start, end, di, dj, dk)") from None
    out = np.zeros((len(items), 5), dtype=np.int64)
    seen: dict[tuple[int, ...], int] = {}
    for p, item in enumerate(items):
        try:
            vals = list(item)
        except TypeError:
            vals = []
        if len(vals) != 5 or not all(_is_int(x) for x in vals):
            raise SteadyLatticeError(
                f"rack {p}: expected 5 integers (start, end, di, dj, dk), got {item!r}"
            )
        s, e, di, dj, dk = (int(x) for x in vals)
        for what, b in (("start", s), ("end", e)):
            if not 0 <= b < n:
                raise SteadyLatticeError(
                    f"rack {p}: {what} ball {b} is out of range (cluster has {n} balls)"
                )
        if s == e and di == dj == dk == 0:
            raise SteadyLatticeError(f"rack {p}: joins ball {s} to itself (zero offsets)")
        key = min((s, e, di, dj, dk), (e, s, -di, -dj, -dk))
        if key in seen:
            raise SteadyLatticeError(
                f"rack {p} {(s, e, di, dj, dk)} defines the same beams as rack {seen[key]}"
            )
        seen[key] = p
        out[p] = (s, e, di, dj, dk)
    return out


def _parse_counts(counts: Any) -> tuple[int, int, int]:
    try:
        vals = list(counts)
    except TypeError:
        vals = []
    if len(vals) != 3 or not all(_is_int(c) and c >= 1 for c in vals):
        raise SteadyLatticeError(f"counts must be three integers >= 1, got {counts!r}")
    return (int(vals[0]), int(vals[1]), int(vals[2]))
