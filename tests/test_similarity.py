"""Tests of conformal.similarity: algebra, real powers (screw/swirl), interpolation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conformal.similarity import Similarity, SimilarityError
from lattice_cad.core.errors import LatticeError


def rodrigues(axis, angle):
    n = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def random_similarity(rng, *, scale=None, angle=None, translation=None) -> Similarity:
    return Similarity(
        scale=float(np.exp(rng.normal(0, 0.3))) if scale is None else scale,
        axis=rng.normal(size=3),
        angle=float(rng.uniform(-math.pi, math.pi)) if angle is None else angle,
        translation=rng.normal(size=3) * 2 if translation is None else translation,
    )


# Hard cases: near-identity, near-half-turn, scale near 1, pure translation, identity.
EDGE_CASES = [
    dict(scale=1.0, angle=0.0, translation=(0.0, 0.0, 0.0)),
    dict(scale=1.0, angle=0.0, translation=(1.0, -2.0, 0.5)),
    dict(scale=1.0 + 1e-12, angle=1e-10, translation=(1.0, 2.0, 3.0)),
    dict(scale=1.0 - 1e-9, angle=0.0, translation=(0.3, 0.0, 1.0)),
    dict(scale=1.0, angle=1e-9, translation=(5.0, 1.0, 0.0)),
    dict(scale=1.0, angle=math.pi, translation=(1.0, 1.0, 1.0)),
    dict(scale=1.0, angle=math.pi - 1e-9, translation=(1.0, -1.0, 2.0)),
    dict(scale=1.7, angle=math.pi - 1e-12, translation=(0.0, 1.0, 0.0)),
    dict(scale=0.5, angle=2.0, translation=(3.0, 0.0, -1.0)),
    dict(scale=2.0, angle=0.0, translation=(0.0, 0.0, 0.0)),
]


def test_apply_matches_rodrigues(rng):
    axis, angle, t = rng.normal(size=3), 1.234, rng.normal(size=3)
    s = Similarity(scale=1.5, axis=axis, angle=angle, translation=t)
    p = rng.normal(size=(10, 3))
    np.testing.assert_allclose(s(p), 1.5 * p @ rodrigues(axis, angle).T + t, atol=1e-14)
    np.testing.assert_allclose(s.rotation, rodrigues(axis, angle), atol=1e-15)
    assert s.scale == 1.5
    assert 0 <= s.angle <= math.pi


def test_compose_and_inverse(rng):
    a, b = random_similarity(rng), random_similarity(rng)
    p = rng.normal(size=(7, 3))
    np.testing.assert_allclose((a @ b)(p), a(b(p)), atol=1e-13)
    np.testing.assert_allclose((a @ a.inverse())(p), p, atol=1e-13)
    assert (a @ a.inverse()).isclose(Similarity.identity())
    np.testing.assert_allclose(a.matrix @ b.matrix, (a @ b).matrix, atol=1e-13)


@pytest.mark.parametrize("case", EDGE_CASES + [None] * 5)
def test_integer_powers_are_repeated_composition(rng, case):
    s = random_similarity(rng) if case is None else Similarity(axis=(1, 2, 2), **case)
    acc = Similarity.identity()
    for k in range(1, 7):
        acc = acc @ s
        assert s.power(k).isclose(acc, atol=1e-12, rtol=1e-12), k
    inv = s.inverse()
    assert s.power(-3).isclose(inv @ inv @ inv, atol=1e-12, rtol=1e-12)
    assert s.power(0) == Similarity.identity()
    assert s.power(1) is s


@pytest.mark.parametrize("case", EDGE_CASES + [None] * 5)
def test_fractional_power_roots(rng, case):
    s = random_similarity(rng) if case is None else Similarity(axis=(0, 1, 3), **case)
    r = s.power(1 / 3)
    assert (r @ r @ r).isclose(s, atol=1e-12, rtol=1e-12)
    h = s**0.5
    assert (h @ h).isclose(s, atol=1e-12, rtol=1e-12)
    # one-parameter group: S^a S^b = S^(a + b)
    assert (s.power(0.3) @ s.power(1.45)).isclose(s.power(1.75), atol=1e-12, rtol=1e-12)


def test_near_identity_is_continuous():
    """Powers of S(eps) converge to those of the exact degenerate limit."""
    t = (1.0, 2.0, -1.0)
    exact = Similarity(translation=t).power(2.5)
    np.testing.assert_array_equal(exact.translation, 2.5 * np.array(t))
    for eps in (1e-6, 1e-9, 1e-12):
        near = Similarity(scale=1 + eps, axis=(1, 1, 0), angle=eps, translation=t).power(2.5)
        assert near.isclose(exact, atol=10 * eps, rtol=10 * eps)


def test_decompose_swirl(rng):
    s = random_similarity(rng, scale=1.3)
    c = s.decompose()
    assert c.kind == "swirl"
    np.testing.assert_allclose(s(c.point), c.point, atol=1e-12)
    p = rng.normal(size=(5, 3))
    for t in (-1.0, 0.5, 2.0, 3.7):
        np.testing.assert_allclose(c.evaluate(p, t), s.power(t)(p), atol=1e-12)


def test_decompose_screw(rng):
    s = random_similarity(rng, scale=1.0)
    near = np.array([3.0, -1.0, 2.0])
    c = s.decompose(near=near)
    assert c.kind == "screw"
    np.testing.assert_allclose(s(c.point), c.point + c.shift * c.axis, atol=1e-12)
    assert abs((near - c.point) @ c.axis) < 1e-12  # nearest axis point
    p = rng.normal(size=(5, 3))
    for t in (-2.0, 0.25, 1.5):
        np.testing.assert_allclose(c.evaluate(p, t), s.power(t)(p), atol=1e-12)
    tr = Similarity(translation=(0, 3, 4)).decompose(near=near)
    assert tr.kind == "screw" and tr.shift == 5.0 and tr.angle == 0.0
    np.testing.assert_allclose(tr.axis, [0, 0.6, 0.8])


def test_interpolating(rng):
    first, last = random_similarity(rng), random_similarity(rng)
    frames = Similarity.interpolating(first, last, 7)
    assert len(frames) == 7
    assert frames[0] is first and frames[-1] is last
    steps = [b @ a.inverse() for a, b in zip(frames[:-1], frames[1:], strict=True)]
    for st in steps[1:]:
        assert st.isclose(steps[0], atol=1e-12, rtol=1e-12)
    assert steps[0].power(6).isclose(last @ first.inverse(), atol=1e-12, rtol=1e-12)
    assert len(Similarity.interpolating(first, last, 2)) == 2
    with pytest.raises(SimilarityError, match="count"):
        Similarity.interpolating(first, last, 1)


def test_builders_round_trip(rng):
    s = random_similarity(rng)
    assert Similarity.from_matrix(s.matrix).isclose(s, atol=1e-13)
    assert Similarity.from_rotation(s.rotation, scale=s.scale, translation=s.translation).isclose(
        s, atol=1e-13
    )
    f = Similarity.from_frame((1, 2, 3), (0, 2, 0), (1, 1, 0), scale=2.0)
    np.testing.assert_allclose(f([1, 0, 0]), [1, 4, 3], atol=1e-15)
    np.testing.assert_allclose(f([0, 1, 0]), [3, 2, 3], atol=1e-15)
    np.testing.assert_allclose(f([0, 0, 1]), [1, 2, 1], atol=1e-15)
    # half-turn matrices (trace -1) convert exactly
    h = Similarity(axis=(1, -2, 0.5), angle=math.pi)
    assert Similarity.from_rotation(h.rotation).isclose(h, atol=1e-15)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(scale=0.0), "scale"),
        (dict(scale=-1.0), "scale"),
        (dict(scale=float("nan")), "scale"),
        (dict(axis=(0, 0, 0)), "axis"),
        (dict(axis=(1, 0)), "axis"),
        (dict(angle=float("inf")), "angle"),
        (dict(translation=(0, float("nan"), 0)), "translation"),
    ],
)
def test_errors(kwargs, match):
    with pytest.raises(SimilarityError, match=match) as info:
        Similarity(**kwargs)
    assert isinstance(info.value, LatticeError) and isinstance(info.value, ValueError)


def test_rejects_reflections():
    with pytest.raises(SimilarityError, match="rotation"):
        Similarity.from_rotation(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(SimilarityError, match="determinant"):
        Similarity.from_matrix(np.diag([1.0, 1.0, -1.0, 1.0]))
