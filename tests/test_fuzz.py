"""A seeded, bounded fuzzer: graphs of every family and magnitude, and bad inputs.

Every generated input must end in exactly one of two ways:

* a valid mesh: ``fast_stitch.check`` (self-intersections included) passes and the counts
  equal ``fast_stitch.estimate`` (and, for the printable float32 mesh, the check passes);
* a :class:`~lattice_cad.core.errors.LatticeError` (the product's own, named error).

Anything else (a bare numpy or Python exception, a warning such as an overflow, an
invalid mesh) fails the test. The families are stars (uniform and tapered radii, 1 to 8
struts, near-parallel pairs included), chains, random graphs (crossing struts) and
jittered blocks of every built-in cell, at scales from 1e-80 to 1e80, moved up to 1e17
from the origin, with 3 to 16 segments; the bad inputs replace elements of the arrays
with strings, booleans, complex numbers, None, NaN, huge or negative indices, or give
wrong shapes.

Profiles
--------
The normal test run uses the short profile (100 derandomized examples per test, about
10 s). The long profile (3000 per test by default) took 14 minutes on 2 shared cores.
The long profile is run with::

    LATTICE_CAD_FUZZ=long [LATTICE_CAD_FUZZ_EXAMPLES=3000] [LATTICE_CAD_FUZZ_SEED=1] \\
        [LATTICE_CAD_FUZZ_REPORT=fuzz.json] python -m pytest tests/test_fuzz.py -p no:cacheprovider

``LATTICE_CAD_FUZZ_REPORT`` writes the outcome counts (valid, and each error class) of
the run to a JSON file.
"""

from __future__ import annotations

import json
import os
import warnings
from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

import fast_stitch
from conformal import CELLS, block
from lattice_cad import LatticeGraph
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeError, LatticeWarning

LONG = os.environ.get("LATTICE_CAD_FUZZ", "") == "long"
EXAMPLES = int(os.environ.get("LATTICE_CAD_FUZZ_EXAMPLES", "3000" if LONG else "100"))
SEED = int(os.environ.get("LATTICE_CAD_FUZZ_SEED", "20261121"))

settings.register_profile(
    "lattice_cad_fuzz",
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=not LONG,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
FUZZ = settings.get_profile("lattice_cad_fuzz")

OUTCOMES: Counter[str] = Counter()

# the long profile runs for minutes: no per-test timeout (bound it from outside if needed)
pytestmark = [pytest.mark.timeout(0)] if LONG else []


def seeded(f):
    return seed(SEED)(f) if LONG else f


@pytest.fixture(scope="module", autouse=True)
def _report():
    yield
    path = os.environ.get("LATTICE_CAD_FUZZ_REPORT")
    if path:
        with open(path, "w", encoding="utf-8") as fh:
            json.dump({"examples_per_test": EXAMPLES, "outcomes": dict(OUTCOMES)}, fh, indent=1)


# ---------------------------------------------------------------------------- families
def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


def star_family(rng: np.random.Generator, tapered: bool) -> tuple:
    d = int(rng.integers(1, 9))
    dirs = _unit(rng, d)
    if d >= 2 and rng.random() < 0.2:  # a near-parallel pair
        dirs[1] = dirs[0] + rng.normal(scale=10.0 ** rng.uniform(-9, -1), size=3)
        dirs[1] /= np.linalg.norm(dirs[1])
    lengths = rng.uniform(0.3, 2.0, d)
    nodes = np.vstack([np.zeros(3), dirs * lengths[:, None]])
    edges = np.column_stack([np.zeros(d, dtype=np.int64), np.arange(1, d + 1)])
    r = rng.uniform(0.01, 0.12, (d, 2) if tapered else d)
    return nodes, edges, r


def chain_family(rng: np.random.Generator) -> tuple:
    n = int(rng.integers(2, 10))
    steps = _unit(rng, n - 1) * rng.uniform(0.5, 1.5, (n - 1, 1))
    nodes = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])
    edges = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    return nodes, edges, rng.uniform(0.02, 0.1)


def random_family(rng: np.random.Generator) -> tuple:
    n = int(rng.integers(3, 12))
    nodes = rng.uniform(-1, 1, (n, 3))
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    pick = rng.choice(len(pairs), size=min(len(pairs), int(rng.integers(1, 2 * n))), replace=False)
    return nodes, pairs[pick], rng.uniform(0.005, 0.05)


def block_family(rng: np.random.Generator) -> tuple:
    cell = sorted(CELLS)[int(rng.integers(len(CELLS)))]
    g = block(cell, int(rng.integers(1, 3)), cell_size=1.0, radius=0.03)
    nodes = g.nodes + rng.uniform(-1, 1, g.nodes.shape) * 10.0 ** rng.uniform(-9, -1.5)
    return nodes, np.asarray(g.edges), 0.03 * 10.0 ** rng.uniform(-1, 0.5)


FAMILIES = ["star", "tapered", "chain", "random", "block"]


def make(family: str, rng: np.random.Generator) -> tuple:
    if family in ("star", "tapered"):
        return star_family(rng, family == "tapered")
    return {"chain": chain_family, "random": random_family, "block": block_family}[family](rng)


# ------------------------------------------------------------------------------ oracle
def outcome_of(run, kind: str) -> str:
    """``"valid"`` or the name of the LatticeError ``run()`` raised; anything else fails.

    Counted in ``OUTCOMES`` as ``"<kind>: <outcome>"``.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            warnings.simplefilter("ignore", LatticeWarning)  # isolated nodes: accepted
            run()
    except LatticeError as exc:
        assert str(exc), f"{type(exc).__name__} without a message"
        name = type(exc).__name__
        OUTCOMES[f"{kind}: {name}"] += 1
        return name
    OUTCOMES[f"{kind}: valid"] += 1
    return "valid"


def stitch_and_verify(g: LatticeGraph, segments: int, *, printable: bool) -> None:
    est = fast_stitch.estimate(g, segments)
    mesh = fast_stitch.stitch(g, segments)
    assert len(mesh.vertices) == est.vertices and len(mesh.faces) == est.triangles
    rep = fast_stitch.check(mesh)
    assert rep.valid, f"silent bad output: {rep}"
    if printable:  # what STL/3MF hold: the float32 printable mesh, checked in full
        from lattice_cad.lattice import Lattice

        m32 = Lattice(g, segments=segments).mesh()
        np.testing.assert_array_equal(m32.vertices, m32.vertices.astype(np.float32))
        rep32 = fast_stitch.check(m32)
        assert rep32.valid, f"silent bad float32 output: {rep32}"


# ------------------------------------------------------------------------------- tests
@seeded
@FUZZ
@given(
    family=st.sampled_from(FAMILIES),
    graph_seed=st.integers(0, 2**32 - 1),
    log_scale=st.one_of(st.just(0.0), st.floats(-80, 80)),
    log_offset=st.one_of(st.none(), st.floats(-3, 17)),
    segments=st.integers(3, 16),
    printable=st.booleans(),
)
def test_fuzz_graphs(family, graph_seed, log_scale, log_offset, segments, printable):
    rng = np.random.default_rng(graph_seed)
    nodes, edges, radii = make(family, rng)
    scale = 10.0**log_scale
    nodes = nodes * scale
    radii = np.asarray(radii) * scale
    if log_offset is not None:
        nodes = nodes + _unit(rng, 1)[0] * 10.0**log_offset

    def run() -> None:
        g = LatticeGraph(nodes, edges, radii)
        stitch_and_verify(g, segments, printable=printable and g.num_edges <= 120)

    outcome_of(run, f"graphs/{family}")


BAD_VALUES = [
    "1.0", "x", True, False, np.True_, 1 + 2j, np.complex128(1), None, float("nan"),
    float("inf"), -1, 2**63, 2**64 - 1, 2**64 + 5, 1e20, 0.5, -0.0, [1, 2], b"1",
]  # fmt: skip


@seeded
@FUZZ
@given(
    which=st.sampled_from(["nodes", "edges", "radii"]),
    bad=st.sampled_from(range(len(BAD_VALUES))),
    as_array=st.booleans(),
    position=st.integers(0, 10**6),
    shape_change=st.sampled_from([None, "transpose", "flatten", "empty", "extra"]),
)
def test_fuzz_bad_inputs(which, bad, as_array, position, shape_change):
    """Wrong types, values and shapes anywhere: a named error or a valid graph, the same
    rule for nodes, edges and radii."""
    star = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    arrays = {"nodes": star, "edges": [[0, 1], [0, 2], [0, 3]], "radii": [0.1, 0.1, 0.1]}
    target = [list(row) if isinstance(row, list) else row for row in arrays[which]]
    flat_rows = len(target)
    row = position % flat_rows
    value = BAD_VALUES[bad]
    if isinstance(target[row], list):
        target[row][position % len(target[row])] = value
    else:
        target[row] = value
    rows = all(isinstance(r, list) for r in target)
    if shape_change == "transpose" and rows:
        target = [list(c) for c in zip(*target, strict=False)]
    elif shape_change == "flatten" and rows:
        target = [x for r in target for x in r]
    elif shape_change == "empty":
        target = []
    elif shape_change == "extra" and rows:
        target = [[*r, 0] for r in target]
    if as_array:
        try:
            target = np.array(target)
        except (ValueError, TypeError):
            pass  # ragged: pass the list
    arrays[which] = target

    def run() -> None:
        g = LatticeGraph(arrays["nodes"], arrays["edges"], arrays["radii"])
        if g.num_edges:
            stitch_and_verify(g, 6, printable=False)

    outcome = outcome_of(run, "bad inputs")
    # strings, booleans, complex numbers and None are never coerced, wherever they are
    kind = value.__class__
    numeric_array = isinstance(target, np.ndarray) and target.dtype.kind in "iuf"
    if kind in (str, bytes, bool, np.bool_, complex, np.complex128, type(None)):
        if shape_change != "empty" and not numeric_array:  # (np.array made True a 1)
            assert outcome == "InvalidGraphError", (which, value, outcome)


def test_short_profile_is_bounded():
    """The normal run stays short; the long one is opt-in (see the module docstring)."""
    if not LONG:
        assert EXAMPLES <= 100
    assert config.PRECISION_CONTRACT
