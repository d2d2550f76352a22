"""Hubs equal up to a rotation (or a reflection): build one, place turned copies (issue 14).

A single hub (:class:`lattice_cad.occ_impl.truss.HubSpec`) is its sphere radius and its
stumps: per stump the node -> midpoint vector ``v`` and the radii ``r_node``, ``r_mid``.
Two hubs are *congruent* when an orthogonal matrix ``Q`` (``det Q = +1`` or ``-1``) maps
the stump vectors of one onto the stump vectors of the other, stump by stump with equal
radii, within a tolerance. The solid of the second is then ``Q`` applied to the solid of
the first: the reference builds it once and places turned copies
(:func:`reference_boolean.reference.build_reference`, ``reuse="rotation"``).

How a match is found: hubs are grouped by a rotation-invariant key (the sorted stump
lengths and radii, the sorted Gram matrix of the stump vectors, the sphere radius, all
rounded to a coarse quantum: equal hubs may still fall into different groups when a value
lies on a rounding boundary, which only costs a missed reuse). Within a group every
candidate is verified: two non-parallel stumps ``a1, a2`` of the first hub (the two with
the largest ``|a1 x a2|`` among its first stumps) are mapped onto every pair ``b1, b2`` of
the second hub with the same lengths, radii and angle, in both handednesses; ``Q`` is the
orthogonal polar factor of the map of the frames ``(a1, a2, a1 x a2)``, and it is accepted
only if every stump of the first hub lands on a distinct stump of the second within
``tol`` with equal radii. So a reused hub is always congruent to its template to ``tol``,
whatever the key.

Nothing here is OCCT: plain numpy on the specs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Congruence", "invariant_key", "match", "RotationCache"]


@dataclass(frozen=True)
class Congruence:
    """How a hub is a turned copy of its template.

    Attributes
    ----------
    rotation : (3, 3) float64
        Orthogonal matrix ``Q``: template stump vector ``a_k`` maps to ``Q @ a_k``.
    perm : (d,) int64
        ``Q @ a_k`` is stump ``perm[k]`` of the copy.
    """

    rotation: NDArray[np.float64]
    perm: NDArray[np.int64]

    @property
    def proper(self) -> bool:
        """True for a rotation (``det Q = +1``), False for a reflection."""
        return bool(np.linalg.det(self.rotation) > 0.0)


def invariant_key(
    radius: float,
    vecs: NDArray[np.float64],
    radii: NDArray[np.float64],
    quantum: float,
) -> bytes:
    """A rotation-invariant key of a hub (equal for congruent hubs, up to rounding).

    Parameters
    ----------
    radius : float
        Sphere radius.
    vecs : (d, 3) float64
        Stump vectors.
    radii : (d, 2) float64
        ``r_node``, ``r_mid`` of each stump.
    quantum : float
        Rounding quantum (mm) of the lengths and radii; Gram entries use ``quantum`` times
        the longest stump.
    """
    L = np.linalg.norm(vecs, axis=1)
    rows = np.rint(np.column_stack([L, radii]) / quantum).astype(np.int64)
    rows = rows[np.lexsort(rows.T[::-1])]
    gram = np.sort(np.rint((vecs @ vecs.T).ravel() / (quantum * float(L.max()))).astype(np.int64))
    head = np.array([len(vecs), int(np.rint(radius / quantum))], dtype=np.int64)
    return head.tobytes() + rows.tobytes() + gram.tobytes()


def _polar(m: NDArray[np.float64]) -> NDArray[np.float64]:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def match(
    a_vecs: NDArray[np.float64],
    a_radii: NDArray[np.float64],
    b_vecs: NDArray[np.float64],
    b_radii: NDArray[np.float64],
    tol: float,
) -> Congruence | None:
    """An orthogonal map of hub ``a``'s stumps onto hub ``b``'s, or None.

    Parameters
    ----------
    a_vecs, b_vecs : (d, 3) float64
        Stump vectors of the two hubs.
    a_radii, b_radii : (d, 2) float64
        ``r_node``, ``r_mid`` of each stump.
    tol : float
        Largest distance (mm) between a mapped stump vector and its image, and largest
        radius difference.

    Returns
    -------
    Congruence or None
        ``Q`` and the stump permutation (see :class:`Congruence`); None when no orthogonal
        map within ``tol`` exists (or the hubs have different degrees).
    """
    d = len(a_vecs)
    if d != len(b_vecs) or d < 2:
        return None
    La = np.linalg.norm(a_vecs, axis=1)
    Lb = np.linalg.norm(b_vecs, axis=1)
    # a stump of b may be the image of a stump of a: same length and radii
    ok = (np.abs(La[:, None] - Lb[None, :]) <= tol) & np.all(
        np.abs(a_radii[:, None, :] - b_radii[None, :, :]) <= tol, axis=2
    )
    if not ok.any(axis=1).all():
        return None
    # two stumps of a spanning a plane as well as possible
    cr = np.linalg.norm(np.cross(a_vecs[:, None, :], a_vecs[None, :, :]), axis=2)
    i1, i2 = np.unravel_index(int(np.argmax(cr)), cr.shape)
    if cr[i1, i2] <= 1e3 * tol * max(float(La.max()), 1.0):
        return None  # all stumps on one line (degree 2 straight through): not worth it
    a1, a2 = a_vecs[i1], a_vecs[i2]
    A = np.column_stack([a1, a2, np.cross(a1, a2)])
    Ainv = np.linalg.inv(A)
    dot12 = float(a1 @ a2)
    Gb = b_vecs @ b_vecs.T
    for j1 in np.flatnonzero(ok[i1]):
        cands = np.flatnonzero(ok[i2] & (np.abs(Gb[j1] - dot12) <= tol * float(La.max()) * 4))
        for j2 in cands:
            if j2 == j1:
                continue
            b1, b2 = b_vecs[j1], b_vecs[j2]
            c = np.cross(b1, b2)
            for sign in (1.0, -1.0):
                Q = _polar(np.column_stack([b1, b2, sign * c]) @ Ainv)
                img = a_vecs @ Q.T  # (d, 3)
                dist = np.linalg.norm(img[:, None, :] - b_vecs[None, :, :], axis=2)
                dist[~ok] = np.inf
                perm = np.argmin(dist, axis=1)
                if dist[np.arange(d), perm].max() <= tol and len(np.unique(perm)) == d:
                    return Congruence(rotation=Q, perm=perm.astype(np.int64))
    return None


class RotationCache:
    """Templates grouped by :func:`invariant_key`; :meth:`find` returns a congruent one.

    Parameters
    ----------
    quantum : float
        Rounding quantum of the keys (mm).
    tol : float
        Verification tolerance of :func:`match` (mm).
    """

    def __init__(self, quantum: float, tol: float) -> None:
        self.quantum = float(quantum)
        self.tol = float(tol)
        self._groups: dict[bytes, list[tuple[int, NDArray[np.float64], NDArray[np.float64]]]]
        self._groups = {}
        self.tries = 0

    def find(
        self, radius: float, vecs: NDArray[np.float64], radii: NDArray[np.float64]
    ) -> tuple[int, Congruence] | tuple[None, bytes]:
        """``(template, congruence)`` of a known congruent hub, else ``(None, key)``.

        The congruence maps the template's stumps onto these (``vecs``, ``radii``).
        """
        key = invariant_key(radius, vecs, radii, self.quantum)
        for t, av, ar in self._groups.get(key, []):
            self.tries += 1
            m = match(av, ar, vecs, radii, self.tol)
            if m is not None:
                return t, m
        return None, key

    def add(
        self, key: bytes, template: int, vecs: NDArray[np.float64], radii: NDArray[np.float64]
    ) -> None:
        """Register ``template`` (with the key :meth:`find` returned for it)."""
        self._groups.setdefault(key, []).append((template, vecs, radii))
