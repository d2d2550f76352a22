"""Orientation-preserving similarities of 3-space and their real powers.

A :class:`Similarity` is ``x -> scale * R x + translation`` with ``scale > 0``
and ``R`` a rotation. It is the building block of steady lattices
(Gupta, Kurzeja, Rossignac et al., *Designing and processing parametric models
of steady lattices*, Sec. 5 and Appendix A): a cluster of balls is moved along
steady patterns ``U^i``, so we need integer, negative and fractional powers.

Powers
------
Every similarity is ``exp`` of an affine generator ``x -> A x + b`` with
``A = ln(scale) I + angle [N]_x`` (principal logarithm, ``0 <= angle <= pi``).
The paper's *canonical decomposition* (Sec. 5.1) into a commuting rotation and
a translation along the axis (*screw*, ``scale == 1``) or a dilation about a
fixed point on the axis (*swirl*, ``scale != 1``) is exactly this one-parameter
group: ``S^t = exp(t log S)``. We evaluate it without going through the fixed
point (which runs off to infinity as ``S`` approaches a translation):

* scale ``scale**t``, rotation ``angle * t`` about the same axis ``N``;
* translation: the axial part of ``translation`` times
  ``expm1(t l) / expm1(l)`` and the part perpendicular to ``N`` times the
  complex number ``expm1(t z) / expm1(z)`` (``l = ln scale``,
  ``z = l + i angle``; a complex number ``a + ib`` acts on a vector ``v``
  perpendicular to ``N`` as ``a v + b N x v``).

Both factors tend to ``t`` at the identity, which is used exactly when
``z == 0``; nothing is divided by a small number otherwise, so powers are
accurate for scales near 1 and angles near 0 or ``pi``. At ``angle == pi``
the axis sign is a convention (the one stored in the quaternion); fractional
powers of a half-turn are therefore one of the two valid roots.

:meth:`Similarity.decompose` also returns the paper's explicit parameters
(fixed point or axis point, axis, angle, scale, axial shift).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lattice_cad.core.errors import SimilarityError

__all__ = ["Similarity", "Canonical", "SimilarityError"]

#: Below this |log| the generator is treated as exactly zero (identity limits).
_TINY = 1e-150


# ----------------------------------------------------------------- helpers
def _cexpm1(z: complex) -> complex:
    """``exp(z) - 1`` for complex ``z``, accurate for small ``|z|``."""
    x, y = z.real, z.imag
    s = math.sin(0.5 * y)
    return complex(math.expm1(x) * math.cos(y) - 2.0 * s * s, math.exp(x) * math.sin(y))


def _ratio(z: complex, t: float) -> complex:
    """``(exp(t z) - 1) / (exp(z) - 1)``; exactly ``t`` at ``z == 0``."""
    if abs(z) < _TINY:
        return complex(t, 0.0)
    return _cexpm1(t * z) / _cexpm1(z)


def _qmul(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def _qcanon(q: NDArray[np.float64]) -> NDArray[np.float64]:
    q = q / math.sqrt(float(q @ q))
    if q[0] < 0.0:
        q = -q
    return q


def _qmatrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _qfrom_matrix(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Shepperd's method: robust for every rotation angle."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    diag = (tr, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(diag))
    if k == 0:
        w = 0.5 * math.sqrt(1.0 + tr)
        f = 0.25 / w
        q = [w, (m[2, 1] - m[1, 2]) * f, (m[0, 2] - m[2, 0]) * f, (m[1, 0] - m[0, 1]) * f]
    elif k == 1:
        x = 0.5 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        f = 0.25 / x
        q = [(m[2, 1] - m[1, 2]) * f, x, (m[0, 1] + m[1, 0]) * f, (m[0, 2] + m[2, 0]) * f]
    elif k == 2:
        y = 0.5 * math.sqrt(1.0 - m[0, 0] + m[1, 1] - m[2, 2])
        f = 0.25 / y
        q = [(m[0, 2] - m[2, 0]) * f, (m[0, 1] + m[1, 0]) * f, y, (m[1, 2] + m[2, 1]) * f]
    else:
        z = 0.5 * math.sqrt(1.0 - m[0, 0] - m[1, 1] + m[2, 2])
        f = 0.25 / z
        q = [(m[1, 0] - m[0, 1]) * f, (m[0, 2] + m[2, 0]) * f, (m[1, 2] + m[2, 1]) * f, z]
    return _qcanon(np.array(q, dtype=np.float64))


def _vec3(value: ArrayLike, what: str) -> NDArray[np.float64]:
    try:
        a = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SimilarityError(f"{what} must be 3 numbers: {exc}") from None
    if a.shape != (3,):
        raise SimilarityError(f"{what} must have 3 components, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise SimilarityError(f"{what} has a non-finite component {a.tolist()}")
    return a


def _scalar(value: float, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise SimilarityError(f"{what} must be a number: {exc}") from None
    if not math.isfinite(x):
        raise SimilarityError(f"{what} must be finite, got {x!r}")
    return x


@dataclass(frozen=True)
class Canonical:
    """Canonical (screw or swirl) parameters of a similarity (paper Sec. 5.1, App. A).

    ``S^t x = F + t d N + R(t angle, N)(x - F)`` (screw) or
    ``S^t x = F + scale^t R(t angle, N)(x - F)`` (swirl), Eqs. (5) and (6).

    Attributes
    ----------
    kind : {"screw", "swirl"}
        ``"screw"`` when ``scale == 1`` (rigid motion), else ``"swirl"``.
    scale : float
        ``m > 0``.
    axis : (3,) float64
        Unit rotation axis ``N`` (``(0, 0, 1)`` when there is no rotation and, for
        a screw, the translation direction if it is a pure translation).
    angle : float
        Rotation angle ``alpha`` in ``[0, pi]``.
    point : (3,) float64
        ``F``: the fixed point (swirl), or the point of the screw axis nearest to
        the ``near`` point given to :meth:`Similarity.decompose` (screw).
    shift : float
        ``d``: translation along the axis (screw); 0 for a swirl.
    """

    kind: Literal["screw", "swirl"]
    scale: float
    axis: NDArray[np.float64]
    angle: float
    point: NDArray[np.float64]
    shift: float

    def evaluate(self, points: ArrayLike, t: float) -> NDArray[np.float64]:
        """``S^t`` applied to ``points`` ((..., 3) float64) by Eq. (5) or (6)."""
        p = np.asarray(points, dtype=np.float64)
        rot = Similarity(axis=self.axis, angle=t * self.angle)
        y = (p - self.point) @ rot.rotation.T
        if self.kind == "screw":
            return self.point + t * self.shift * self.axis + y
        return self.point + self.scale**t * y


class Similarity:
    """An orientation-preserving similarity ``x -> scale * R(axis, angle) x + translation``.

    Parameters
    ----------
    scale : float
        Positive scale factor ``m``.
    axis : (3,) float
        Rotation axis (any non-zero length; normalised).
    angle : float
        Rotation angle in radians (right-handed about ``axis``).
    translation : (3,) float
        Translation applied after the scaled rotation.

    Raises
    ------
    SimilarityError
        For a non-positive or non-finite scale, a zero or non-finite axis, a
        non-finite angle or translation.

    Notes
    -----
    ``S @ T`` is the composition "``T`` first, then ``S``"; ``S(points)``
    applies ``S`` to ``(..., 3)`` arrays; ``S ** t`` is :meth:`power`.
    Instances are immutable.
    """

    __slots__ = ("_scale", "_q", "_t", "_R")

    def __init__(
        self,
        scale: float = 1.0,
        axis: ArrayLike = (0.0, 0.0, 1.0),
        angle: float = 0.0,
        translation: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        m = _scalar(scale, "scale")
        if m <= 0.0:
            raise SimilarityError(f"scale must be > 0, got {m!r}")
        n = _vec3(axis, "axis")
        norm = math.sqrt(float(n @ n))
        if norm == 0.0:
            raise SimilarityError("axis must be a non-zero vector, got (0, 0, 0)")
        a = _scalar(angle, "angle")
        t = _vec3(translation, "translation")
        h = 0.5 * math.remainder(a, 2.0 * math.pi)
        q = np.concatenate([[math.cos(h)], math.sin(h) * n / norm])
        self._set(m, _qcanon(q), t)

    def _set(self, m: float, q: NDArray[np.float64], t: NDArray[np.float64]) -> None:
        self._scale = float(m)
        self._q = q
        self._t = np.array(t, dtype=np.float64)
        self._R = _qmatrix(q)
        for a in (self._q, self._t, self._R):
            a.flags.writeable = False

    @classmethod
    def _raw(cls, m: float, q: NDArray[np.float64], t: NDArray[np.float64]) -> Similarity:
        s = cls.__new__(cls)
        s._set(m, _qcanon(np.asarray(q, dtype=np.float64)), t)
        return s

    # ------------------------------------------------------------ builders
    @classmethod
    def identity(cls) -> Similarity:
        """The identity similarity."""
        return cls()

    @classmethod
    def from_rotation(
        cls,
        rotation: ArrayLike,
        *,
        scale: float = 1.0,
        translation: ArrayLike = (0.0, 0.0, 0.0),
    ) -> Similarity:
        """``x -> scale * rotation @ x + translation``.

        Parameters
        ----------
        rotation : (3, 3) float
            A proper rotation matrix (orthonormal to 1e-6, determinant +1).
        """
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.isfinite(r).all():
            raise SimilarityError(f"rotation must be a finite (3, 3) matrix, got shape {r.shape}")
        if np.abs(r @ r.T - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
            raise SimilarityError(
                "rotation is not a proper rotation matrix (R R^T != I or det < 0)"
            )
        m = _scalar(scale, "scale")
        if m <= 0.0:
            raise SimilarityError(f"scale must be > 0, got {m!r}")
        return cls._raw(m, _qfrom_matrix(r), _vec3(translation, "translation"))

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> Similarity:
        """From a (4, 4) homogeneous or (3, 4) matrix whose linear part is ``scale * R``."""
        a = np.asarray(matrix, dtype=np.float64)
        if a.shape not in ((4, 4), (3, 4)) or not np.isfinite(a).all():
            raise SimilarityError(f"matrix must be finite (4, 4) or (3, 4), got shape {a.shape}")
        lin = a[:3, :3]
        det = float(np.linalg.det(lin))
        if det <= 0.0:
            raise SimilarityError(f"linear part has determinant {det:g}; must be > 0")
        m = det ** (1.0 / 3.0)
        return cls.from_rotation(lin / m, scale=m, translation=a[:3, 3])

    @classmethod
    def from_frame(
        cls,
        origin: ArrayLike,
        x_axis: ArrayLike = (1.0, 0.0, 0.0),
        y_axis: ArrayLike = (0.0, 1.0, 0.0),
        *,
        scale: float = 1.0,
    ) -> Similarity:
        """The similarity mapping the world frame to the frame ``F(O, I, J, K, s)``.

        ``x_axis`` is normalised to ``I``; ``y_axis`` is orthogonalised against it
        to give ``J``; ``K = I x J``. Maps ``x`` to ``O + s (x0 I + x1 J + x2 K)``.
        """
        o = _vec3(origin, "origin")
        i = _vec3(x_axis, "x_axis")
        j0 = _vec3(y_axis, "y_axis")
        ni = math.sqrt(float(i @ i))
        if ni == 0.0:
            raise SimilarityError("x_axis must be non-zero")
        i = i / ni
        j = j0 - (j0 @ i) * i
        nj = math.sqrt(float(j @ j))
        if nj <= 1e-12 * math.sqrt(float(j0 @ j0)):
            raise SimilarityError("y_axis must not be parallel to x_axis")
        j = j / nj
        return cls.from_rotation(
            np.column_stack([i, j, np.cross(i, j)]), scale=scale, translation=o
        )

    # ---------------------------------------------------------- properties
    @property
    def scale(self) -> float:
        """Scale factor ``m > 0``."""
        return self._scale

    @property
    def quaternion(self) -> NDArray[np.float64]:
        """(4,) float64 unit quaternion ``(w, x, y, z)`` of the rotation, ``w >= 0``."""
        return self._q

    @property
    def rotation(self) -> NDArray[np.float64]:
        """(3, 3) float64 rotation matrix ``R``."""
        return self._R

    @property
    def translation(self) -> NDArray[np.float64]:
        """(3,) float64 translation."""
        return self._t

    @property
    def angle(self) -> float:
        """Rotation angle in ``[0, pi]``."""
        v = self._q[1:]
        return 2.0 * math.atan2(math.sqrt(float(v @ v)), float(self._q[0]))

    @property
    def axis(self) -> NDArray[np.float64]:
        """(3,) float64 unit rotation axis (``(0, 0, 1)`` when the angle is 0)."""
        v = self._q[1:]
        n = math.sqrt(float(v @ v))
        if n == 0.0:
            return np.array([0.0, 0.0, 1.0])
        return v / n

    @property
    def matrix(self) -> NDArray[np.float64]:
        """(4, 4) float64 homogeneous matrix."""
        out = np.eye(4)
        out[:3, :3] = self._scale * self._R
        out[:3, 3] = self._t
        return out

    @property
    def is_identity(self) -> bool:
        """Exactly the identity (scale 1, no rotation, no translation)."""
        return self._scale == 1.0 and self._q[0] == 1.0 and not self._t.any()

    # ----------------------------------------------------------- algebra
    def __call__(self, points: ArrayLike) -> NDArray[np.float64]:
        """Apply to ``points``: (..., 3) float -> (..., 3) float64."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise SimilarityError(f"points must have shape (..., 3), got {p.shape}")
        return self._scale * (p @ self._R.T) + self._t

    apply = __call__

    def apply_vectors(self, vectors: ArrayLike) -> NDArray[np.float64]:
        """Linear part only (no translation): (..., 3) -> (..., 3) float64."""
        return self._scale * (np.asarray(vectors, dtype=np.float64) @ self._R.T)

    def __matmul__(self, other: Similarity) -> Similarity:
        if not isinstance(other, Similarity):
            return NotImplemented
        return self.compose(other)

    def compose(self, other: Similarity) -> Similarity:
        """``self @ other``: apply ``other`` first, then ``self``."""
        m = self._scale * other._scale
        q = _qmul(self._q, other._q)
        t = self._scale * (self._R @ other._t) + self._t
        return Similarity._raw(m, q, t)

    def inverse(self) -> Similarity:
        """The inverse similarity ``x -> R^T (x - t) / scale``."""
        q = self._q * np.array([1.0, -1.0, -1.0, -1.0])
        m = 1.0 / self._scale
        t = -m * (self._R.T @ self._t)
        return Similarity._raw(m, q, t)

    def power(self, t: float) -> Similarity:
        """``S^t`` for any real ``t`` (principal branch; see the module notes).

        Integer ``t`` gives ``S @ S @ ... @ S`` (or powers of the inverse), ``t = 0``
        the identity exactly, and ``S.power(1/n)`` an ``n``-th root.
        """
        tt = _scalar(t, "exponent")
        if tt == 0.0:
            return Similarity()
        if tt == 1.0:
            return self
        lam = math.log(self._scale)
        alpha = self.angle
        n = self.axis
        half = 0.5 * tt * alpha
        q = np.concatenate([[math.cos(half)], math.sin(half) * n])
        m = math.exp(tt * lam)
        ax = float(self._t @ n)
        perp = self._t - ax * n
        f_ax = _ratio(complex(lam, 0.0), tt).real
        c = _ratio(complex(lam, alpha), tt)
        trans = f_ax * ax * n + c.real * perp + c.imag * np.cross(n, perp)
        return Similarity._raw(m, q, trans)

    def __pow__(self, t: float) -> Similarity:
        return self.power(t)

    def decompose(self, near: ArrayLike | None = None) -> Canonical:
        """Canonical screw/swirl parameters (paper Sec. 5.1 and Appendix A).

        Parameters
        ----------
        near : (3,) float, optional
            For a screw, the returned axis point is the one nearest to ``near``
            (default: the origin). A pure translation or the identity has no
            axis; ``near`` itself is returned as ``point``.

        Returns
        -------
        Canonical
            ``kind``, ``scale``, ``axis``, ``angle``, ``point`` and ``shift``. The
            swirl fixed point solves ``(I - m R) F = t``; it is ill-conditioned
            (far away) when ``S`` is close to a translation.
        """
        p0 = np.zeros(3) if near is None else _vec3(near, "near")
        m = self._scale
        alpha = self.angle
        n = self.axis
        t = self._t
        if m != 1.0:
            f = np.asarray(np.linalg.solve(np.eye(3) - m * self._R, t), dtype=np.float64)
            return Canonical("swirl", m, n, alpha, f, 0.0)
        if alpha == 0.0:
            d = math.sqrt(float(t @ t))
            axis = t / d if d > 0.0 else np.array([0.0, 0.0, 1.0])
            return Canonical("screw", 1.0, axis, 0.0, p0.copy(), d)
        d = float(t @ n)
        tp = t - d * n
        # axis point A (perpendicular to N through the origin): (I - R) A = tp
        c, s = math.cos(alpha), math.sin(alpha)
        # in the plane: (1 - e^{i a}) A = tp  =>  A = tp / (1 - e^{i a})
        z = complex(1.0 - c, -s)
        inv = 1.0 / z
        a = inv.real * tp + inv.imag * np.cross(n, tp)
        point = a + float((p0 - a) @ n) * n
        return Canonical("screw", 1.0, n, alpha, point, d)

    # ----------------------------------------------------------- utilities
    @staticmethod
    def interpolating(first: Similarity, last: Similarity, count: int) -> list[Similarity]:
        """``count`` similarities steadily interpolating ``first`` and ``last``.

        ``S_i = (last @ first^-1)^(i / (count - 1)) @ first``: consecutive ones
        differ by the same similarity (a steady pattern of frames, paper Sec. 5.3).
        ``S_0`` is ``first`` and ``S_{count-1}`` is ``last`` (the same objects).

        Raises
        ------
        SimilarityError
            When ``count < 2`` or is not an integer.
        """
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 2:
            raise SimilarityError(f"count must be an integer >= 2, got {count!r}")
        if not isinstance(first, Similarity) or not isinstance(last, Similarity):
            raise SimilarityError("first and last must be Similarity instances")
        rel = last @ first.inverse()
        out = [first]
        out += [rel.power(i / (count - 1)) @ first for i in range(1, count - 1)]
        out.append(last)
        return out

    def isclose(self, other: Similarity, *, atol: float = 1e-12, rtol: float = 1e-12) -> bool:
        """Same map up to tolerance: compares the (4, 4) matrices entry-wise."""
        return bool(np.allclose(self.matrix, other.matrix, atol=atol, rtol=rtol))

    def __repr__(self) -> str:
        ax = ", ".join(f"{v:.6g}" for v in self.axis)
        tr = ", ".join(f"{v:.6g}" for v in self._t)
        return (
            f"Similarity(scale={self._scale:.12g}, axis=({ax}), angle={self.angle:.12g}, "
            f"translation=({tr}))"
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Similarity):
            return NotImplemented
        return (
            self._scale == other._scale
            and np.array_equal(self._q, other._q)
            and np.array_equal(self._t, other._t)
        )

    __hash__ = None  # type: ignore[assignment]


def as_similarity(value: Similarity | None, what: str) -> Similarity:
    """``value`` itself, or the identity for ``None``; rejects other types."""
    if value is None:
        return Similarity()
    if not isinstance(value, Similarity):
        raise SimilarityError(f"{what} must be a Similarity, got {type(value).__name__}")
    return value


def powers(
    s: Similarity, exponents: Sequence[int] | NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Scales (K,), rotation matrices (K, 3, 3) and translations (K, 3) of ``s**e``."""
    ex = list(exponents)
    sc = np.empty(len(ex))
    rot = np.empty((len(ex), 3, 3))
    tr = np.empty((len(ex), 3))
    for i, e in enumerate(ex):
        p = s.power(float(e))
        sc[i], rot[i], tr[i] = p.scale, p.rotation, p.translation
    return sc, rot, tr
