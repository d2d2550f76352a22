"""Protrusion of written fills against the exact B-rep, not the part mesh the fill cuts by.

For every STEP part in ../shared/data/step (``--parts`` filters by substring) and every
setting (clip, conform, tet, skin; ``--settings``), ``lattice-cad fill`` is run in a fresh
subprocess of *this* tree (``python -m lattice_cad.cli`` with PYTHONPATH set to the
repository) with the parts benchmark's dimensions (cell = largest extent / 15, r = cell /
12, skin = cell / 6, 6 significant digits; ``benchmarks/bench_parts.py``), and every vertex
of the written STL is measured:

``vs mesh``
    signed distance to the part's default tessellation (``conformal.load_part``: chord
    error 1e-3 of the diagonal), the surface the fill was cut by before the cut used a
    finer tessellation (``conformal.trim.cutting_part``);
``vs fine``
    signed distance to an independent fine tessellation of the exact B-rep (chord error
    ``--fine`` times r, default 1e-3, angular 0.05 rad), for every vertex;
``exact``
    OpenCascade's exact signed distance to the B-rep faces
    (``lattice_cad.occ_impl.distance.signed_distance``) of the ``--exact`` vertices
    (default 300) that stand out most by ``vs fine``, the 100 by ``vs mesh``, and, so that
    a fine mesh wrong somewhere cannot hide a protrusion, a random sample of ``--exact`` / 3
    of the vertices the fine mesh puts within 2 % r (or twice its measured chord error) of
    the surface, i.e. on the cut.

Only the vertices within one strut radius of a surface (and those outside it) are
measured to the meshes (:func:`banded_signed_distance`): a vertex deeper inside cannot
protrude, and the nearest-triangle search for it in a fine mesh is what made a GE bracket
row take ~10 min; the band widens until ``--exact`` vertices are measured, so the printed
maxima and the vertices checked exactly are those of the full measurement (``--full``).
``--meshes`` adds the mesh parts of ../shared/data/meshes (their mesh is the exact surface).

The fine tessellation is checked face by face against the exact surface
(``Part.refined``: ``occ_impl.chord``; BRepMesh left a B-spline face of
trimesh_featuretype.STEP 25 times coarser than asked, and the fine check missed a
protrusion of 11 % r there); its measured chord error (``fine err``, % r, an upper bound by
exact surface evaluation) is printed in the note.

All in % of r: the largest signed distance of a written vertex outside the surface. The
goal (issue 13 item 2): at most 1 % of r. Also printed: the fill's wall and CPU seconds
(children included) and the triangles written.

    python benchmarks/bench_protrusion_exact.py
    python benchmarks/bench_protrusion_exact.py --parts flange ge_bracket --settings clip skin
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import trimesh

import conformal
from lattice_cad.occ_impl.distance import signed_distance

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "step"
MESHES = ROOT.parent / "shared" / "data" / "meshes"
SETTINGS: dict[str, list[str]] = {
    "bcc": ["--cell", "bcc"],  # fill auto, as benchmarks/bench_parts.py
    "clip": ["--cell", "bcc", "--fill", "clip"],
    "conform": ["--cell", "kelvin", "--fill", "conform"],
    "tet": ["--method", "tet"],
    "skin": ["--cell", "octet", "--skin", "SKIN"],
    "keep": ["--cell", "bcc", "--fill", "clip", "--keep", ">Z:SKIN"],  # not by default
}


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def banded_signed_distance(
    surface: conformal.Part, vertices: np.ndarray, band: float, keep: int
) -> np.ndarray:
    """Signed distance of every vertex, exact within ``band`` of the surface and outside.

    Vertices deeper inside than ``band`` get ``-inf`` (they cannot protrude: the search for
    their nearest triangle of a fine mesh is what took ~10 min per GE bracket row). The
    band grows (x4) until ``keep`` vertices are measured, so the largest value (and the
    ``keep`` largest) equal those of the full signed distance.
    """
    d = surface.signed_distance(vertices, max_distance=band)
    far_out = np.flatnonzero(d == np.inf)  # outside by more than band: measured fully
    if len(far_out):
        d[far_out] = surface.distance(vertices[far_out])
    keep = min(keep, len(d))
    while np.isfinite(d).sum() < keep and band < surface.diagonal:
        band *= 4
        deep = np.flatnonzero(~np.isfinite(d))
        d[deep] = surface.signed_distance(vertices[deep], max_distance=band)
    if np.isfinite(d).sum() < keep:
        deep = np.flatnonzero(~np.isfinite(d))
        d[deep] = surface.signed_distance(vertices[deep])
    return d


def measure(
    vertices: np.ndarray,
    part: conformal.Part,
    fine: conformal.Part,
    r: float,
    n_exact: int,
    *,
    full: bool = False,
) -> dict[str, float]:
    """Largest protrusion (% r) against the part mesh, the fine mesh and the exact B-rep.

    ``full``: the signed distance of every vertex (slow for vertices deep inside a fine
    mesh); by default :func:`banded_signed_distance` within one strut radius.
    """
    if full:
        d_mesh = part.signed_distance(vertices)
        d_fine = fine.signed_distance(vertices)
    else:
        d_mesh = banded_signed_distance(part, vertices, r, n_exact)
        d_fine = banded_signed_distance(fine, vertices, r, n_exact)
    # candidates: the worst by the fine mesh, the worst by the part's mesh, and a random
    # sample of the vertices on the cut (near the surface by the fine mesh)
    near = max(0.02 * r, 2 * (fine.chord_error or 0.0))
    on_cut = np.flatnonzero(np.abs(d_fine) <= near)
    rng = np.random.default_rng(0)
    sample = rng.choice(on_cut, size=min(len(on_cut), n_exact // 3), replace=False)
    worst = np.unique(
        np.concatenate(
            [
                np.argsort(d_fine)[::-1][:n_exact],
                np.argsort(d_mesh)[::-1][: n_exact // 3],
                sample,
            ]
        )
    )
    if part.shape is not None:
        d_exact = signed_distance(part.shape, vertices[worst])
    else:  # a mesh part: its mesh is the exact surface
        d_exact = d_mesh[worst]
    return {
        "mesh": 100 * float(d_mesh.max()) / r,
        "fine": 100 * float(d_fine.max()) / r,
        "exact": 100 * float(d_exact.max()) / r,
        "over": int((d_fine > 0.01 * r).sum() + 0),
        "exact_over": int((d_exact > 0.01 * r).sum()),
        "checked": len(worst),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", nargs="*", help="substrings of STEP file names")
    ap.add_argument(
        "--settings",
        nargs="*",
        choices=list(SETTINGS),
        default=[s for s in SETTINGS if s != "keep"],
    )
    ap.add_argument(
        "--fine", type=float, default=1e-3, help="chord error of the check, fraction of r"
    )
    ap.add_argument("--exact", type=int, default=300, help="vertices checked exactly")
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument(
        "--full",
        action="store_true",
        help="signed distance of every vertex (slow; default: within one strut radius)",
    )
    ap.add_argument(
        "--meshes", action="store_true", help="also the mesh parts (../shared/data/meshes)"
    )
    args = ap.parse_args()
    files = sorted(DATA.iterdir()) + (sorted(MESHES.iterdir()) if args.meshes else [])
    if args.parts:
        files = [f for f in files if any(s in f.name for s in args.parts)]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    print(f"load average {os.getloadavg()[0]:.1f}; tree {ROOT}")
    head = (
        f"{'part':36s} {'setting':8s} {'r mm':>7s} {'wall s':>6s} {'cpu s':>6s} {'tris':>8s} "
        f"{'mesh %r':>8s} {'fine %r':>8s} {'exact %r':>8s} {'>1% r':>7s}  note"
    )
    print(head)
    print("-" * len(head), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for src in files:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    part = conformal.load_part(src)
                    ext = float(part.size.max())
                    r = float(f"{float(f'{ext / 15:.6g}') / 12:.6g}")
                    # a mesh part is its own exact surface (refined returns it)
                    fine = part.refined(max(args.fine * r, 1e-6 * part.diagonal), angular=0.05)
                except Exception as exc:  # a part that does not load is a row
                    print(f"{src.name[:36]:36s} load failed: {str(exc)[:80]}")
                    continue
            ext = float(part.size.max())
            cell = float(f"{ext / 15:.6g}")
            r = float(f"{cell / 12:.6g}")
            skin = f"{cell / 6:.6g}"
            for setting in args.settings:
                out = Path(tmp) / f"{src.stem}.{setting}.stl"
                extra = [a.replace("SKIN", skin) for a in SETTINGS[setting]]
                cmd = [sys.executable, "-m", "lattice_cad.cli", "fill", str(src), "-o", str(out),
                       "--cell-size", str(cell), "--radius", str(r), *extra]  # fmt: skip
                c0, w0 = _children_cpu(), time.perf_counter()
                try:
                    proc = subprocess.run(
                        cmd, capture_output=True, text=True, env=env, timeout=args.timeout
                    )
                    # the CLI's "error:" line (progress bars share stderr), else its last line
                    lines = [ln.strip() for ln in proc.stderr.replace("\r", "\n").splitlines()]
                    lines = [ln for ln in lines if ln] or ["?"]
                    errors = [ln[ln.index("error:") :] for ln in lines if "error:" in ln]
                    failed = proc.returncode != 0 and (errors or lines)
                except subprocess.TimeoutExpired:
                    failed = [f"timeout {args.timeout:g} s"]
                wall, cpu = time.perf_counter() - w0, _children_cpu() - c0
                load = os.getloadavg()[0]
                if failed:
                    print(f"{src.name[:36]:36s} {setting:8s} {r:7.4f} {wall:6.1f} {cpu:6.1f} "
                          f"failed: {failed[-1][:90]}  (load {load:.1f})", flush=True)  # fmt: skip
                    continue
                mesh = trimesh.load(out, process=False)
                t0 = time.process_time()
                vertices = np.asarray(mesh.vertices, dtype=np.float64)
                m = measure(vertices, part, fine, r, args.exact, full=args.full)
                t_measure = time.process_time() - t0
                err = 100 * (fine.chord_error or 0.0) / r
                exact = "exact" if part.shape is not None else "mesh = exact"
                note = (
                    f"{exact} on {m['checked']}: {m['exact_over']} > 1% r; fine err {err:.2f}"
                    f"{f' ({fine.chord_unresolved} faces over)' if fine.chord_unresolved else ''}"
                    f"; measure {t_measure:.1f} cpu s{' (full)' if args.full else ''}"
                    f"; load {load:.1f}"
                )
                print(
                    f"{src.name[:36]:36s} {setting:8s} {r:7.4f} {wall:6.1f} {cpu:6.1f} "
                    f"{len(mesh.faces):8d} {m['mesh']:8.2f} {m['fine']:8.2f} {m['exact']:8.2f} "
                    f"{m['over']:7d}  {note}",
                    flush=True,
                )
    print(
        "(% r: largest signed distance of a written vertex outside the surface, in % of r; "
        ">1% r: vertices over 1 % r by the fine mesh)"
    )


if __name__ == "__main__":
    main()
