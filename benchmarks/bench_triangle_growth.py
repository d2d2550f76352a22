"""How well ``Part.triangles_at`` predicts BRepMesh's triangle counts at a finer chord error.

For each STEP part, the part is loaded (its own tessellation, per-face counts in
``Part.face_triangles``) and tessellated again, unchecked, at the parts benchmark's cutting
chord error (``conformal.trim._wanted`` for r = largest extent / 15 / 12) and at 4 x it; the
table gives the predicted and actual totals and their ratio (``conformal.trim`` takes the
prediction as its first guess of the chord error the triangle budget allows, and
``occ_impl.chord.split_dense_faces`` skips its coarse pass from it), then, per surface
type, the face whose count exceeded its own prediction the most.

Usage::

    python benchmarks/bench_triangle_growth.py [--data DIR ...]

Parts: ``../shared/data/step`` (relative to the repository root), and the ``step/`` of
each ``--data`` directory.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "data"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", nargs="*", default=[], help="more folders holding step/")
    args = ap.parse_args()
    from conformal import trim
    from conformal.part import load_part
    from lattice_cad.core.errors import LatticeWarning
    from lattice_cad.occ_impl.shapes import surface_kinds

    paths = sorted((SHARED / "step").iterdir())
    for d in args.data:
        paths += sorted((Path(d) / "step").glob("*.st*p"))
    worst: dict[str, tuple[float, str, int, float]] = {}
    print(f"{'part':40s} {'chord mm':>9s} {'predicted':>10s} {'actual':>10s} {'ratio':>6s}")
    for path in paths:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)
            try:
                part = load_part(path)
            except Exception as exc:  # a part that does not load: said, not timed
                print(f"{path.name[:40]:40s} not loaded: {str(exc)[:60]}")
                continue
            if part.face_triangles is None or part.folds:
                continue
            r = float(np.max(part.size)) / 15 / 12
            for want in (trim._wanted(part, r, None), 4 * trim._wanted(part, r, None)):
                if want >= part.deflection:
                    continue
                fine = part.refined(want, angular=0.3, checked=False)
                if fine.face_triangles is None:
                    continue
                predicted, actual = part.triangles_at(want), len(fine.faces)
                print(
                    f"{path.name[:40]:40s} {want:9.3g} {predicted:10,.0f} {actual:10,} "
                    f"{actual / predicted:6.2f}"
                )
                ratio = max(1.0, part.deflection / want)
                for k, solid in enumerate(part.shape):
                    n0, g = part.face_triangles[k]
                    n1 = fine.face_triangles[k][0]
                    if len(n1) != len(n0):
                        continue
                    for kind, a, b in zip(surface_kinds(solid), n1, n0 * ratio**g, strict=True):
                        if a >= 50 and a / b > worst.get(kind, (0.0,))[0]:
                            worst[kind] = (float(a / b), path.name, int(a), float(b))
    print("\nper surface type, the face most over its prediction (faces of 50+ triangles):")
    for kind, (x, name, a, b) in sorted(worst.items(), key=lambda kv: -kv[1][0]):
        print(f"  {kind:20s} {x:5.2f} x  {name} ({a:,} triangles, predicted {b:,.0f})")


if __name__ == "__main__":
    main()
