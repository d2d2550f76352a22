"""Where does float64 (and float32 output) stop representing a stitched lattice?

Sweeps ``|x| / r`` (largest absolute coordinate over the smallest strut radius) for random
stars and jittered bcc blocks moved away from the origin, stitches each with the precision
contract switched off, and counts invalid results (``fast_stitch.check`` with
self-intersections, and counts equal to ``fast_stitch.estimate``). The float32 column rounds
the valid float64 meshes as STL/3MF store them (``lattice_cad.io.single_precision``) and
checks again. The thresholds ``config.PRECISION_RATIO_F64`` / ``PRECISION_RATIO_F32`` are
chosen from this table with a safety factor.

    PYTHONPATH=. python benchmarks/precision_sweep.py [--trials 40] [--absolute | --fuzz-families]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import fast_stitch
from lattice_cad import LatticeGraph
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeError


def star(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = int(rng.integers(2, 7))
    while True:
        dirs = rng.normal(size=(d, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        cos = dirs @ dirs.T - 2 * np.eye(d)
        if cos.max() < np.cos(np.radians(35)):
            break
    lengths = rng.uniform(0.6, 1.4, d)
    nodes = np.vstack([np.zeros(3), dirs * lengths[:, None]])
    edges = np.column_stack([np.zeros(d, int), np.arange(1, d + 1)])
    radii = rng.uniform(0.5, 1.0, (d, 2))
    return nodes, edges, radii


def bcc(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from conformal import block

    g = block("bcc", 2, cell_size=1.0, radius=0.05)
    nodes = g.nodes + rng.uniform(-0.03, 0.03, g.nodes.shape)
    return nodes, np.asarray(g.edges), np.ones((g.num_edges, 2))


def trial(nodes, edges, radii, r_min, offset_mag, rng, segments=6):
    """Outcome for one graph scaled to smallest radius r_min, moved to |x| ~ offset_mag."""
    radii = radii / radii.min() * r_min
    scale = r_min / 0.05 if nodes.shape[0] > 10 else r_min / 0.02
    direction = rng.normal(size=3)
    direction /= np.abs(direction).max()
    nodes = nodes * scale + direction * offset_mag
    try:
        g = LatticeGraph(nodes, edges, radii)
        m = fast_stitch.stitch(g, segments)
    except LatticeError as exc:
        return "error", None, type(exc).__name__
    est = fast_stitch.estimate(g, segments)
    rep = fast_stitch.check(m)
    ok = rep.valid and len(m.faces) == est.triangles and len(m.vertices) == est.vertices
    if not ok:
        return "invalid", None, str(rep)[:80]
    from lattice_cad.io import single_precision

    try:
        m32, _ = single_precision(m)
        ok32 = fast_stitch.check(m32).valid
    except LatticeError:
        ok32 = False
    return "valid", ok32, ""


def absolute(trials: int, rng: np.random.Generator) -> None:
    """Whole graphs scaled by 10**k at the origin: where do over/underflow start?"""
    saved = config.MIN_RADIUS, config.MAX_COORDINATE
    config.MIN_RADIUS, config.MAX_COORDINATE = 0.0, float("inf")
    try:
        print(f"{'log10 scale':>12} {'valid':>6} {'invalid':>8} {'error':>6}")
        for k in range(-200, 201, 10):
            counts = {"valid": 0, "invalid": 0, "error": 0}
            for _ in range(trials):
                nodes, edges, radii = star(rng)
                radii = radii / radii.max() * 0.02
                try:
                    g = LatticeGraph(nodes * 10.0**k, edges, radii * 10.0**k)
                    m = fast_stitch.stitch(g, 6)
                except LatticeError:
                    counts["error"] += 1
                    continue
                ok = fast_stitch.check(m).valid
                counts["valid" if ok else "invalid"] += 1
            print(
                f"{k:>12} {counts['valid']:>6} {counts['invalid']:>8} {counts['error']:>6}",
                flush=True,
            )
    finally:
        config.MIN_RADIUS, config.MAX_COORDINATE = saved


def fuzz_families(trials: int) -> None:
    """The fuzzer's chains, random graphs and stars (``tests/test_fuzz.py``), P = 3 and 8:
    float64 validity against ``|x| / r`` (run from the repository root)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.test_fuzz import _unit, make

    saved = config.PRECISION_CONTRACT
    config.PRECISION_CONTRACT = False
    try:
        for fam in ("chain", "random", "star"):
            for exp in (8, 9, 10, 10.5, 11, 11.5, 12):
                bad = tot = 0
                for sd in range(trials):
                    rng = np.random.default_rng(sd)
                    nodes, edges, radii = make(fam, rng)
                    nodes = nodes + _unit(rng, 1)[0] * np.min(radii) * 10**exp
                    for P in (3, 8):
                        try:
                            m = fast_stitch.stitch(LatticeGraph(nodes, edges, radii), P)
                        except LatticeError:
                            continue
                        tot += 1
                        bad += not fast_stitch.check(m).valid
                print(f"{fam:>7} log10 |x|/r {exp:>5}: {bad}/{tot} invalid", flush=True)
    finally:
        config.PRECISION_CONTRACT = saved


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--absolute", action="store_true", help="sweep the absolute scale instead")
    ap.add_argument("--fuzz-families", action="store_true", help="chains and random graphs")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(args.seed)
    if args.absolute:
        absolute(args.trials, rng)
        return
    if args.fuzz_families:
        fuzz_families(args.trials)
        return
    saved = config.PRECISION_CONTRACT
    config.PRECISION_CONTRACT = False
    try:
        print(
            f"{'log10 |x|/r':>12} {'family':>6} {'valid':>6} {'invalid':>8} {'error':>6} "
            f"{'f32 ok':>7} {'f32 bad':>8}"
        )
        for exp in np.arange(4.0, 16.5, 0.5):
            for fam, make in (("star", star), ("bcc", bcc)):
                counts = {"valid": 0, "invalid": 0, "error": 0, "f32ok": 0, "f32bad": 0}
                for _ in range(args.trials):
                    nodes, edges, radii = make(rng)
                    r_min = 1.0
                    out, ok32, _ = trial(nodes, edges, radii, r_min, r_min * 10**exp, rng)
                    counts[out] += 1
                    if ok32 is not None:
                        counts["f32ok" if ok32 else "f32bad"] += 1
                print(
                    f"{exp:>12.1f} {fam:>6} {counts['valid']:>6} {counts['invalid']:>8} "
                    f"{counts['error']:>6} {counts['f32ok']:>7} {counts['f32bad']:>8}",
                    flush=True,
                )
    finally:
        config.PRECISION_CONTRACT = saved


if __name__ == "__main__":
    main()
