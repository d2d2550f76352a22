"""Benchmarks of reference_boolean and the accuracy report (printed tables; issue 14's
"Measured" section).

The script is a list of **sections**, each one function printing one table, selected by
flags (:data:`SECTIONS`; no flag: the first three, as before):

``--periodic``
    1. A periodic lattice of ~10k hubs (cubic block, 21^3 cells): build time with the cache.
``--irregular``
    2. An irregular lattice (jittered cubic grid, every hub distinct): hubs per second.
    Seed anchor (Wang, Chen & Rosen, Table 1): 4,662 struts in 1,361 s on 2005 hardware.
``--table2``
    3. The seed's Table 2 box lattice (13 x 13 x 7 cubic cells of 1.5 mm, R = 0.25 mm):
    fast_stitch's volume error against the exact reference at P = 3, 4, 6, 10, 18, 24,
    of the default mesh (``profile="volume"``) and of ``profile="area"``.
``--report``
    4. The whole accuracy report (``Lattice.validate`` with its defaults, then the
    first-screen pictures and the HTML/Markdown files) on the seed's GE bracket lattices
    (:func:`ge_lattice`: Box-BCC 5.5 mm clip, tet 5 mm): time per stage, hubs/s, and the
    verdict line at the default tolerance. With ``--quick``, a small smoke lattice.

Issue 14's other tables come as their own sections (one function each, one flag each,
registered in :data:`SECTIONS`): the reference speed on the GE lattices (``--ge``), the
volume error of each mesh option at P = 4, 6, 8, 12 (``--volume-table``) and the lattices
refused over every fill mode on the shared parts (``--refused``). ``--all`` runs every
section. Every timing prints the load average and CPU seconds next to wall seconds.

Usage: ``python benchmarks/bench_reference.py [--quick] [--all | SECTION FLAGS ...]``
"""

from __future__ import annotations

import argparse
import inspect
import math
import os
import resource
import signal
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import fast_stitch
from conformal.cells import block
from lattice_cad import LatticeGraph
from reference_boolean import build_reference


def table(title: str, cols: list[str], rows: list[list[str]]) -> str:
    w = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(cols)]
    line = "  ".join(c.rjust(w[i]) for i, c in enumerate(cols))
    out = [title, line, "-" * len(line)]
    out += ["  ".join(x.rjust(w[i]) for i, x in enumerate(r)) for r in rows]
    return "\n".join(out) + "\n"


def bench_periodic(quick: bool) -> None:
    n = 6 if quick else 21
    g = block("cubic", (n, n, n), cell_size=1.0, radius=0.1)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    rows = [
        [
            f"{g.num_nodes:,}",
            f"{g.num_edges:,}",
            str(ref.unique_hubs),
            f"{ref.cache_hits:,}",
            f"{len(ref.mesh.faces):,}",
            f"{dt:.1f}",
            f"{ref.timings['build']:.1f}",
            f"{ref.timings['stack']:.1f}",
            "PASS" if dt < 60 else "MISS",
            "yes" if ref.complete else "NO",
        ]
    ]
    print(
        table(
            f"1. Periodic cubic lattice {n}^3 cells, r = 0.1, cache on (goal: < 60 s for 10k hubs)",
            [
                "hubs",
                "struts",
                "built",
                "reused",
                "triangles",
                "total s",
                "build s",
                "stack s",
                "goal",
                "complete",
            ],
            rows,
        )
    )


def bench_irregular(quick: bool, size: int | None = None) -> None:
    n = size or (3 if quick else 5)
    g0 = block("cubic", (n, n, n), cell_size=1.0, radius=0.08)
    rng = np.random.default_rng(1)
    nodes = g0.nodes + rng.uniform(-0.12, 0.12, g0.nodes.shape)
    radii = rng.uniform(0.05, 0.09, (g0.num_edges, 2))
    g = LatticeGraph(nodes, g0.edges, radii)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    hubs = int((g.degree > 0).sum())
    deg6 = int((g.degree == 6).sum())
    rows = [
        [
            f"{hubs:,}",
            str(deg6),
            f"{g.num_edges:,}",
            str(ref.unique_hubs),
            f"{dt:.1f}",
            f"{hubs / dt:.2f}",
            f"{g.num_edges / dt:.2f}",
            f"{4662 / 1361:.2f}",
            "yes" if ref.complete else f"NO ({len(ref.failed)} failed)",
        ]
    ]
    print(
        table(
            f"2. Irregular lattice (jittered {n}^3 cubic grid, tapered random radii), "
            f"{min(2, os.cpu_count() or 1)} workers, load {os.getloadavg()[0]:.1f}",
            [
                "hubs",
                "degree 6",
                "struts",
                "built",
                "time s",
                "hubs/s",
                "struts/s",
                "seed struts/s (2005)",
                "complete",
            ],
            rows,
        )
    )


def bench_table2(quick: bool) -> None:
    counts = (4, 4, 2) if quick else (13, 13, 7)
    g = block("cubic", counts, cell_size=1.5, radius=0.25)
    t = time.perf_counter()
    ref = build_reference(g, keep_solids=False)
    dt = time.perf_counter() - t
    vref = ref.volume
    has_vp = "profile" in inspect.signature(fast_stitch.stitch).parameters
    rows = []
    for P in (3, 4, 6, 10, 18, 24):
        v = fast_stitch.stitch(g, P).volume
        row = [str(P), f"{v:.2f}", f"{(v - vref) / vref:+.3%}"]
        if has_vp:
            vp = fast_stitch.stitch(g, P, profile="area").volume
            row += [f"{vp:.2f}", f"{(vp - vref) / vref:+.3%}"]
        else:
            row += ["n/a", "n/a"]
        rows.append(row)
    notes = (
        ""
        if has_vp
        else ("\n(profile is not in this fast_stitch.stitch yet: that column is skipped)")
    )
    print(
        table(
            f"3. Seed Table 2 box lattice {counts[0]}x{counts[1]}x{counts[2]} cubic cells "
            "of 1.5 mm, "
            f"R = 0.25 mm, {g.num_edges:,} struts: exact reference volume {vref:.3f} mm^3 "
            f"({'complete' if ref.complete else 'INCOMPLETE'}, built in {dt:.1f} s, "
            f"{ref.unique_hubs} distinct hubs){notes}",
            ["P", "default volume", "rel. error", "profile='area'", "rel. error"],
            rows,
        )
    )


# ------------------------------------------------------------- GE bracket lattices
#: The seed's GE bracket (shared data).
GE_BRACKET = (
    Path(__file__).resolve().parents[2]
    / "shared"
    / "data"
    / "step"
    / "dolfiny_ge_bracket_rotated_nonds.step"
)

#: The seed's two GE bracket lattices (as in bench_conformal.py), and a small smoke one.
GE_LATTICES = {
    "voxel": "GE bracket Box-BCC 5.5 mm clip, r 0.25",
    "tet": "GE bracket tet 5 mm, r 0.25",
    "smoke": "GE bracket BCC 16 mm inside, r 0.6 (smoke)",
}


def ge_lattice(kind: str) -> LatticeGraph:
    """One of :data:`GE_LATTICES` as a graph (``"voxel"``, ``"tet"`` or ``"smoke"``)."""
    from conformal.part import load_part
    from conformal.tet import tet_lattice
    from conformal.voxel import voxel_lattice

    part = load_part(GE_BRACKET)
    if kind == "voxel":
        return voxel_lattice(part, "box-bcc", 5.5, 0.25, fill="clip")
    if kind == "tet":
        return tet_lattice(part, 5.0, 0.25)
    if kind == "smoke":
        return voxel_lattice(part, "bcc", 16.0, 0.6, fill="inside")
    raise ValueError(f"unknown GE lattice {kind!r}: {', '.join(GE_LATTICES)}")


def _cpu() -> float:
    """CPU seconds of this process and its (finished) children."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


#: The GE lattices ``--report`` measures (``--report-lattices``).
REPORT_LATTICES: tuple[str, ...] = ("voxel", "tet")


def bench_report(quick: bool) -> None:
    """4. The accuracy report as a user runs it: time per stage, hubs/s, the verdict."""
    from lattice_cad.core.errors import LatticeError, LatticeWarning
    from lattice_cad.validate import validate
    from reference_boolean.report import first_screen_pictures

    kinds = ["smoke"] if quick else list(REPORT_LATTICES)
    rows, verdicts = [], []
    for kind in kinds:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)
            g = ge_lattice(kind)
        hubs = int((g.degree > 0).sum())
        w0, c0 = time.perf_counter(), _cpu()
        try:
            # quick: one union resolution only (a smoke run); else the user's defaults
            rep = validate(g, 6, None, **({"union_segments": (16,)} if quick else {}))
        except LatticeError as exc:
            rows.append([GE_LATTICES[kind], f"{hubs:,}", f"{g.num_edges:,}"] + ["-"] * 9)
            verdicts.append(f"{GE_LATTICES[kind]}: refused: {exc}")
            continue
        t = time.perf_counter()
        first_screen_pictures(rep)
        pictures = time.perf_counter() - t
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            rep.save(Path(d) / "report.html")
            rep.save(Path(d) / "report.md")
            files = time.perf_counter() - t
        wall, cpu = time.perf_counter() - w0, _cpu() - c0
        ref_s = rep.reference.timings.get("total", rep.timings["reference"])
        v = rep.verdict()
        rows.append(
            [
                GE_LATTICES[kind],
                f"{hubs:,}",
                f"{g.num_edges:,}",
                f"{rep.reference.unique_hubs:,}",
                f"{ref_s:.1f}",
                f"{hubs / ref_s:.1f}" if ref_s > 0 else "-",
                f"{rep.timings.get('unions', 0.0):.1f}",
                f"{rep.timings.get('deviation', 0.0):.1f}",
                f"{pictures + files:.1f}",
                f"{wall:.1f}",
                f"{cpu:.1f}",
                v.status,
            ]
        )
        verdicts.append(f"{GE_LATTICES[kind]}: {v.line}")
    print(
        table(
            "4. Accuracy report (validate defaults + first-screen pictures + HTML/Markdown), "
            f"{os.cpu_count()} cpus, load {os.getloadavg()[0]:.1f} "
            "(goal: < 300 s per GE lattice)",
            [
                "lattice",
                "hubs",
                "struts",
                "built",
                "reference s",
                "hubs/s",
                "unions s",
                "deviation s",
                "pictures+files s",
                "total s",
                "CPU s",
                "verdict",
            ],
            rows,
        )
    )
    print("\n".join(verdicts) + "\n")


#: The sections: flag name -> (function of ``quick``, one line of help). The default run
#: (no flag) is the first three; ``--all`` runs every one.
# ------------------------------------------------- GE bracket (issue 14, item 2: speed)
GE = (
    Path(__file__).resolve().parents[2]
    / "shared"
    / "data"
    / "step"
    / ("dolfiny_ge_bracket_rotated_nonds.step")
)


def _ge_lattices(which: str) -> list[tuple[str, LatticeGraph]]:
    import warnings

    from conformal.part import load_part
    from conformal.tet import tet_lattice
    from conformal.voxel import voxel_lattice

    warnings.simplefilter("ignore")
    part = load_part(GE)
    out = []
    if which in ("all", "bcc"):
        out.append(("box-bcc 5.5 mm inside, r 0.25", voxel_lattice(part, "box-bcc", 5.5, 0.25,
                                                                    fill="inside")))  # fmt: skip
    if which in ("all", "tet"):
        out.append(("tet 5 mm, r 0.25", tet_lattice(part, 5.0, 0.25)))
    return out


def bench_ge(which: str, sample: int, union_hubs: int | None) -> None:
    """The GE bracket lattices: the whole report where the reference accepts the lattice,
    else the hub build on a seeded sample of the distinct hubs (extrapolated)."""
    from reference_boolean.compare import compare
    from reference_boolean.reference import _hub_specs, _run, find_overlaps

    rows = []
    for name, g in _ge_lattices(which):
        specs, template, _, _ = _hub_specs(g, True)
        hubs = int((template >= 0).sum())
        overlaps = find_overlaps(g)
        print(f"\n{name}: {g.num_nodes:,} nodes, {g.num_edges:,} struts, {hubs:,} hubs, "
              f"{len(specs):,} distinct; overlap places {len(overlaps)}", flush=True)  # fmt: skip
        load0 = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), _cpu()
        if not overlaps:
            mesh = fast_stitch.stitch(g, 6)
            rep = compare(g, meshes={"fast_stitch P=6": mesh}, union_hubs=union_hubs,
                          keep_solids=False, progress=True)  # fmt: skip
            wall, cpu = time.perf_counter() - t0, _cpu() - c0
            ref = rep.reference
            tb = ref.timings["build"]
            rows.append([
                name, "full report", f"{wall:.1f}", f"{cpu:.1f}", str(ref.unique_hubs),
                f"{ref.cache_hits:,}", f"{ref.unique_hubs / tb:.2f}",
                f"{ref.timings.get('estimate', float('nan')):.0f} / {tb:.0f}",
                "yes" if ref.complete else f"NO ({len(ref.failed)})",
                f"{rep.timings['unions']:.1f}", f"{load0:.1f}/{os.getloadavg()[0]:.1f}",
            ])  # fmt: skip
            err = rep.comparisons["fast_stitch P=6"].relative_volume_error
            print(f"  reference {ref.timings['total']:.1f} s, unions {rep.timings['unions']:.1f} s"
                  f" ({rep.union_scope}), deviation {rep.timings.get('deviation', 0):.1f} s, "
                  f"volume error P=6 {err:+.3%}", flush=True)  # fmt: skip
        else:
            rng = np.random.default_rng(0)
            idx = np.sort(rng.choice(len(specs), size=min(sample, len(specs)), replace=False))
            sub = [specs[i] for i in idx]
            tol = 0.01 * float(g.radii.min())
            res = _run(sub, tol, 0.25, False, 2, 300.0, None)
            wall, cpu = time.perf_counter() - t0, _cpu() - c0
            ok = sum(r.status == "ok" for r in res)
            per_cpu = cpu / len(sub)
            rows.append([
                name, f"hub build, sample {len(sub)}", f"{wall:.1f}", f"{cpu:.1f}",
                str(len(specs)), f"{hubs - len(specs):,}", f"{len(sub) / wall:.2f}",
                f"all {len(specs)}: {per_cpu * len(specs) / 2:,.0f} s wall on 2 free cores",
                f"{ok}/{len(sub)} ok", "-", f"{load0:.1f}/{os.getloadavg()[0]:.1f}",
            ])  # fmt: skip
            print(f"  {len(sub) / cpu:.3f} hubs per CPU second (goal 10); mean degree "
                  f"{np.mean([len(s.vecs) for s in sub]):.1f}; refused as a whole "
                  "(overlapping hubs: clusters come from the 'cluster' work)",
                  flush=True)  # fmt: skip
    print()
    print(table(
        "GE bracket lattices (../shared/data/step/dolfiny_ge_bracket_rotated_nonds.step), "
        "2 workers; CPU = this process + hub workers",
        ["lattice", "measured", "wall s", "CPU s", "distinct", "reused", "hubs/s wall",
         "estimate / build s", "complete", "unions s", "load before/after"],
        rows,
    ))  # fmt: skip


def bench_fuse_ab(sample: int, rounds: int) -> None:
    """Alternating A/B, in this process, on the same tet hubs: the plain BRepAlgoAPI_Fuse
    (A, before) against truss.general_fuse (B: OBB, no history, no inverted check)."""
    from lattice_cad.occ_impl import truss
    from lattice_cad.occ_impl.shapes import fuse, volume
    from reference_boolean.reference import _hub_specs

    (_, g), = _ge_lattices("tet")  # fmt: skip
    specs, _, _, _ = _hub_specs(g, True)
    rng = np.random.default_rng(1)
    idx = rng.choice(len(specs), size=sample, replace=False)
    variants = {
        "A fuse (before)": lambda p: fuse(p[:1], p[1:], parallel=False, check=False),
        "B general_fuse": lambda p: truss.general_fuse(p),
    }
    cpu = {k: 0.0 for k in variants}
    n = 0
    skipped: set[int] = set()
    for _ in range(rounds):
        for i in idx:
            if i in skipped:
                continue
            vols, spent = [], {}
            try:
                for k, fn in variants.items():
                    prims = truss.make_primitives(specs[i])
                    c = time.process_time()
                    sh = fn(prims)
                    spent[k] = time.process_time() - c
                    vols.append(volume(sh, eps=1e-10))
            except MemoryError:  # run under ulimit -v: some degree-15+ tet hubs take GBs
                skipped.add(int(i))
                print(f"  hub {int(i)} (degree {len(specs[i].vecs)}): out of memory, skipped")
                continue
            for k, v in spent.items():
                cpu[k] += v
            n += 1
            print(
                f"  hub {int(i)} degree {len(specs[i].vecs)}: "
                + ", ".join(f"{k} {v:.3f} s" for k, v in spent.items()),
                flush=True,
            )
            assert abs(vols[0] - vols[1]) < 1e-7 * vols[0], vols
    print(table(
        f"Hub fuse A/B, tet 5 mm GE bracket, {sample} hubs x {rounds} rounds alternating "
        f"(load {os.getloadavg()[0]:.1f})",
        ["variant", "CPU s per hub", "hubs per CPU s"],
        [[k, f"{v / n:.3f}", f"{n / v:.3f}"] for k, v in cpu.items()],
    ))  # fmt: skip


REFUSED_SETTINGS: dict[str, dict[str, object]] = {
    "bcc": {"cell": "bcc", "fill": "inside"},
    "clip": {"cell": "bcc", "fill": "clip"},
    "conform": {"cell": "kelvin", "fill": "conform"},
    "tet": {"method": "tet"},
}


def bench_refused(
    max_struts: int = 1500,
    parts: list[str] | None = None,
    settings: list[str] | None = None,
    budget: float = 3600.0,
    build_max_struts: int = 600,
    cell_divisor: float = 8.0,
    out_path: Path | None = None,
    cache: Path | None = None,
    suffixes: tuple[str, ...] | None = None,
) -> list[list[str]]:
    """Issue 14: count the lattices the exact reference refuses, over every fill mode.

    Every part of ``../shared/data`` (STEP and meshes) is filled with every setting of
    :data:`REFUSED_SETTINGS` (cell = largest extent / ``cell_divisor``, r = cell / 12);
    each lattice of at most ``max_struts`` struts is clustered (cheap); then the lattices
    of at most ``build_max_struts`` struts are built **smallest first** until ``budget``
    seconds are spent, so that the cap, not the order of the files, decides what is built.
    A lattice is *refused* when ``build_reference`` raises, *incomplete* when some hub or
    cluster failed, *built* when complete (and its mesh is checked watertight).
    """
    from pathlib import Path

    data = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    files = sorted((data / "step").glob("*")) + sorted((data / "meshes").glob("*"))
    if parts:
        files = [f for f in files if any(p in f.name for p in parts)]
    if suffixes:
        files = [f for f in files if f.parent.name in suffixes]
    rows: list[list[str]] = []
    t_start = time.perf_counter()
    counts = {
        "lattices": 0, "refused": 0, "incomplete": 0, "complete": 0, "refused before": 0,
        "skipped": 0, "no lattice": 0,
    }  # fmt: skip
    try:
        _refused_rows(
            files, settings, max_struts, build_max_struts, budget, t_start, rows, counts,
            cell_divisor, cache,
        )  # fmt: skip
    except KeyboardInterrupt:  # Ctrl-C: print the partial table
        print("interrupted: partial table", flush=True)
    text = table(
        "5. Lattices refused by the exact reference (issue 14; cell = extent / "
        f"{cell_divisor:g}, r = cell / 12, clustered up to {max_struts:,} struts, built "
        f"smallest first up to {build_max_struts:,} struts within {budget:.0f} s of builds; load "
        f"{os.getloadavg()[0]:.1f})",
        ["part", "fill", "struts", "leaves", "former check", "clusters, solids", "reference"],
        [r + [""] * (7 - len(r)) if len(r) < 7 else r for r in rows],
    )
    built = (
        counts["refused"] + counts["incomplete"] + counts["complete"]
        + counts.get("case timeout", 0)
    )  # fmt: skip
    text += (
        f"\nlattices {counts['lattices']} ({counts['no lattice']} fills gave no lattice); "
        f"built {built}: complete {counts['complete']}, incomplete {counts['incomplete']}, "
        f"refused {counts['refused']}; stopped by the case timeout "
        f"{counts.get('case timeout', 0)}; not built (cap or budget) {counts['skipped']}; "
        f"refused by the former per-hub check: {counts['refused before']} of "
        f"{counts['lattices']}; {time.perf_counter() - t_start:.0f} s wall\n"
    )
    print(text, flush=True)
    if out_path is not None:
        out_path.parent.mkdir(parents=True, exist_ok=True)
        out_path.write_text(text)
    return rows


#: Wall seconds after which one lattice's reference build is stopped (``--case-timeout``;
#: 0: none). Counted apart from refusals: the build was not finished, not refused.
CASE_TIMEOUT = 0.0


class _CaseTimeout(BaseException):
    """Raised by SIGALRM in the middle of a build (a BaseException, so that the reference's
    worker pool is ended on the way out, as for Ctrl-C)."""


def _case_alarm(signum: int, frame: Any) -> None:
    raise _CaseTimeout()


def _refused_rows(
    files: list[Any],
    settings: list[str] | None,
    max_struts: int,
    build_max_struts: int,
    budget: float,
    t_start: float,
    rows: list[list[str]],
    counts: dict[str, int],
    cell_divisor: float = 8.0,
    cache: Path | None = None,
) -> None:
    import resource
    import warnings

    from conformal import load_part
    from lattice_cad import Lattice
    from reference_boolean import find_overlaps
    from reference_boolean.compare import mesh_validity
    from reference_boolean.reference import _unit_specs

    todo: list[tuple[int, list[str], Any]] = []  # (struts, row, graph) to build
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    for f in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                part = load_part(f)
        except Exception as exc:  # noqa: BLE001 - report and go on
            rows.append([f.name[:34], "-", "-", "-", "-", "-", f"part not loaded: {exc!s:.50}"])
            print("  ".join(rows[-1]), flush=True)
            continue
        for name, opts in REFUSED_SETTINGS.items():
            if settings and name not in settings:
                continue
            row = [f.name[:34], name]
            cached = None
            if cache is not None:
                cached = cache / f"{f.name}.{name}.{cell_divisor:g}.npz"
            try:
                if cached is not None and cached.exists():
                    z = np.load(cached)
                    if "error" in z:
                        raise RuntimeError(str(z["error"]))
                    g = LatticeGraph(z["nodes"], z["edges"], z["radii"])
                else:
                    try:
                        with warnings.catch_warnings():
                            warnings.simplefilter("ignore")
                            cell = float(np.max(part.size)) / cell_divisor
                            lat = Lattice.fill(part, cell_size=cell, radius=cell / 12.0, **opts)
                        g = lat.graph
                    except Exception as exc:
                        if cached is not None:
                            np.savez(cached, error=np.array(type(exc).__name__))
                        raise
                    if cached is not None:
                        np.savez(cached, nodes=g.nodes, edges=g.edges, radii=g.radii)
            except Exception as exc:  # noqa: BLE001 - report and go on
                counts["no lattice"] += 1
                rows.append(row + ["-", "-", "-", "-", f"no lattice: {type(exc).__name__}"])
                print("  ".join(rows[-1]), flush=True)
                continue
            counts["lattices"] += 1
            old = find_overlaps(g)
            counts["refused before"] += bool(old)
            row += [f"{g.num_edges:,}", str(int((g.degree == 1).sum()))]
            row.append(f"refused ({len(old)})" if old else "clean")
            if g.num_edges > max_struts:
                counts["skipped"] += 1
                rows.append(row + ["-", f"skipped: {g.num_edges:,} > {max_struts:,} struts"])
                print("  ".join(rows[-1]), flush=True)
                continue
            units = _unit_specs(g, True)  # the clustering alone (cheap): never refuses
            multi = [len(m) for m in units.members if len(m) > 1]
            row.append(f"{len(multi)} (max {max(multi, default=1)}), {len(units.specs)} solids")
            if g.num_edges > build_max_struts:
                counts["skipped"] += 1
                rows.append(row + [f"not built: {g.num_edges:,} > {build_max_struts:,} struts"])
                print("  ".join(rows[-1]), flush=True)
                continue
            rows.append(row)
            todo.append((g.num_edges, row, g))
    print(f"\n{len(todo)} lattices to build, smallest first\n", flush=True)
    t_build = time.perf_counter()  # the budget is for the builds (the fills come first)
    for _, row, g in sorted(todo, key=lambda t: t[0]):
        if time.perf_counter() - t_build > budget:
            counts["skipped"] += 1
            row.append("not built: time budget spent")
            continue
        t = time.perf_counter()
        c0 = time.process_time()
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        before = signal.signal(signal.SIGALRM, _case_alarm)
        if CASE_TIMEOUT > 0:
            signal.alarm(int(math.ceil(CASE_TIMEOUT)))
        try:
            ref = build_reference(g, keep_solids=False, hub_timeout=120.0)
        except _CaseTimeout:  # the hub workers are ended by build_reference itself
            counts["case timeout"] = counts.get("case timeout", 0) + 1
            row.append(
                f"TIMEOUT: stopped after {CASE_TIMEOUT:.0f} s wall (not refused; "
                f"{time.process_time() - c0:.0f} s cpu here), load {os.getloadavg()[0]:.1f}"
            )
            print("  ".join(row), flush=True)
            continue
        except Exception as exc:  # noqa: BLE001 - that is what is counted
            counts["refused"] += 1
            row.append(f"REFUSED: {type(exc).__name__}: {str(exc)[:60]}")
            print("  ".join(row), flush=True)
            continue
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, before)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = time.process_time() - c0 + (r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
        wall = time.perf_counter() - t
        if not ref.complete:
            counts["incomplete"] += 1
            n, why = next(iter(ref.failed.items()))
            verdict = f"INCOMPLETE {len(ref.failed)} nodes, e.g. {n}: {why[:50]}"
        else:
            counts["complete"] += 1
            v = mesh_validity(ref.mesh)
            verdict = "ok, watertight" if v["valid"] else f"ok, mesh {v}"
        load = os.getloadavg()[0]
        row.append(f"{verdict}; {wall:.0f} s wall, {cpu:.0f} s cpu, load {load:.1f}")
        print("  ".join(row), flush=True)


SECTIONS: dict[str, tuple[Callable[[bool], None], str]] = {
    "periodic": (bench_periodic, "1. periodic cubic lattice, hub cache"),
    "irregular": (bench_irregular, "2. irregular lattice, hubs per second"),
    "table2": (bench_table2, "3. seed Table 2 box lattice, volume error by P"),
    "report": (bench_report, "4. the whole accuracy report on the GE bracket lattices"),
}
DEFAULT_SECTIONS = ("periodic", "irregular", "table2")
VOLUME_PROFILES = ("volume", "area", "inscribed", "circumscribed")


#: The lattices of the volume table (``--volume-table``; ``--volume-lattices`` picks some).
#: ``-win``: a window of the lattice (:func:`window`), where the whole one takes too long.
VOLUME_LATTICES = (
    "table2", "ge-bcc", "ge-voxel", "ge-tet", "ge-voxel-10", "ge-tet-10", "ge-voxel-win",
    "ge-tet-win",
)  # fmt: skip

#: Hubs in a window of the ``-win`` lattices (``--window``), and the seed of its centre.
WINDOW_HUBS = 150
WINDOW_SEED = 0


#: Where a window is centred (``--window-at``): a random node, or a random leaf (a strut
#: end at the part's surface, where clipped lattices have their clusters).
WINDOW_AT = "random"


def window(g: LatticeGraph, hubs: int, seed: int = 0, at: str | None = None) -> LatticeGraph:
    """A sample of a lattice too big for the reference: the ``hubs`` nodes with struts nearest
    to a seeded random one, and the struts between them (struts leaving the window are
    dropped, so nodes at its border have a lower degree; unused nodes are removed).

    Parameters
    ----------
    g : LatticeGraph
    hubs : int
    seed : int
    at : {"random", "leaf"}, optional
        The centre: any node with struts, or a leaf (default :data:`WINDOW_AT`).

    Returns
    -------
    LatticeGraph
        Nodes ``(n, 3) float64``, edges ``(m, 2) int64``, radii ``(m, 2) float64``.
    """
    used = np.flatnonzero(g.degree > 0)
    leaves = np.flatnonzero(g.degree == 1)
    pool = leaves if (at or WINDOW_AT) == "leaf" and len(leaves) else used
    if (at or WINDOW_AT) == "leaf" and not len(leaves):
        print("window: the lattice has no leaves; centred at a random node", flush=True)
    c = g.nodes[np.random.default_rng(seed).choice(pool)]
    d = np.linalg.norm(g.nodes[used] - c, axis=1)
    take = np.zeros(g.num_nodes, dtype=bool)
    take[used[np.argsort(d, kind="stable")[:hubs]]] = True
    keep = take[g.edges].all(axis=1)
    e = g.edges[keep]
    live = np.unique(e)
    new = np.full(g.num_nodes, -1, dtype=np.int64)
    new[live] = np.arange(len(live))
    return LatticeGraph(g.nodes[live], new[e], g.radii[keep])


def _volume_lattices(quick: bool, which: tuple[str, ...] | None = None) -> list[tuple[str, Any]]:
    """(name, builder) of the lattices of the volume table; builders return a graph.

    ``table2``: the seed's Table 2 box lattice (13 x 13 x 7 cubic cells of 1.5 mm, R 0.25;
    4 x 4 x 2 with ``quick``); ``ge-bcc``: GE bracket BCC 8 mm r 0.6 inside; ``ge-voxel``
    and ``ge-tet``: the seed's GE bracket lattices (Box-BCC 5.5 mm clip and tet 5 mm, r
    0.25); ``ge-voxel-10`` and ``ge-tet-10``: the same kinds at 10 mm cells, r 0.6 (smaller,
    for a loaded machine).
    """
    from lattice_cad import Lattice

    def ge(cell: str, size: float, radius: float, **kw: Any) -> Any:
        return lambda: Lattice.fill(GE_BRACKET, cell, size, radius, **kw).graph

    counts = (4, 4, 2) if quick else (13, 13, 7)
    table = {
        "table2": (
            f"Table 2 box lattice {counts[0]}x{counts[1]}x{counts[2]} cubic 1.5 mm, R 0.25",
            lambda: block("cubic", counts, cell_size=1.5, radius=0.25),
        ),
        "ge-bcc": ("GE bracket BCC 8 mm r 0.6 inside", ge("bcc", 8.0, 0.6, fill="inside")),
        "ge-voxel": ("GE bracket Box-BCC 5.5 mm r 0.25 clip",
                     ge("box-bcc", 5.5, 0.25, fill="clip")),
        "ge-tet": ("GE bracket tet 5 mm r 0.25", ge("bcc", 5.0, 0.25, method="tet")),
        "ge-voxel-10": ("GE bracket Box-BCC 10 mm r 0.6 clip",
                        ge("box-bcc", 10.0, 0.6, fill="clip")),
        "ge-tet-10": ("GE bracket tet 10 mm r 0.6", ge("bcc", 10.0, 0.6, method="tet")),
        "ge-voxel-win": (
            f"GE bracket Box-BCC 5.5 mm r 0.25 clip, WINDOW of {WINDOW_HUBS} hubs "
            f"(seed {WINDOW_SEED}, centred at a {WINDOW_AT} node)",
            lambda: window(ge("box-bcc", 5.5, 0.25, fill="clip")(), WINDOW_HUBS, WINDOW_SEED),
        ),
        "ge-tet-win": (
            f"GE bracket tet 5 mm r 0.25, WINDOW of {WINDOW_HUBS} hubs (seed {WINDOW_SEED}, "
            f"centred at a {WINDOW_AT} node)",
            lambda: window(ge("bcc", 5.0, 0.25, method="tet")(), WINDOW_HUBS, WINDOW_SEED),
        ),
    }  # fmt: skip
    if which is None:
        which = ("table2", "ge-bcc") if quick else ("table2", "ge-bcc", "ge-voxel", "ge-tet")
    return [table[k] for k in which]


def bench_volume_table(
    quick: bool,
    out_path: Path | None = None,
    which: tuple[str, ...] | None = None,
    samples: int = 20_000,
) -> str:
    """Volume error and surface deviation / r of each profile option against the exact
    reference, at P = 4, 6, 8, 12: the deviation along struts (outside the hub zones, where
    mesh and reference model the same design) and at hubs (inside them), see
    :mod:`reference_boolean.regions`."""
    import warnings

    from reference_boolean import compare

    text: list[str] = []

    def emit(s: str) -> None:
        print(s, flush=True)
        if out_path is not None:  # written as it goes: a partial run keeps its tables
            out_path.parent.mkdir(parents=True, exist_ok=True)
            with open(out_path, "a") as fh:
                fh.write(s + "\n")
        text.append(s)

    if out_path is not None and out_path.exists():
        out_path.unlink()
    emit(
        f"Volume and surface deviation of the fast mesh against the exact reference (cpus "
        f"{os.cpu_count()}, load {os.getloadavg()[0]:.1f}); error = (V_mesh - V_exact) / "
        "V_exact; struts / hubs = symmetric surface deviation p95 / r along struts (outside "
        "the hub zones: same design in both) / at hubs (inside: convex hub against ball and "
        f"cylinders), {samples:,} area samples per direction (p95 over these; the "
        "vertices add to the max only); goals: default error within 1 % and struts p95 < "
        "0.10 at P = 6\n"
    )
    for name, build in _volume_lattices(quick, which):
        t = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                g = build()
        except Exception as exc:  # noqa: BLE001 - report and go on
            emit(f"{name}: lattice not built: {type(exc).__name__}: {exc}\n")
            continue
        tg = time.perf_counter() - t
        print(f"{name}: {g.num_edges:,} struts; building the reference", flush=True)
        t, c0 = time.perf_counter(), _cpu()
        try:
            ref = build_reference(g, keep_solids=False)
        except Exception as exc:  # noqa: BLE001 - the reference refuses some lattices
            emit(
                f"{name}: {g.num_nodes:,} nodes, {g.num_edges:,} struts (built in {tg:.0f} s): "
                f"NO REFERENCE: {type(exc).__name__}: {str(exc)[:300]}\n"
            )
            continue
        tr, cr = time.perf_counter() - t, _cpu() - c0
        if not ref.complete:
            emit(f"{name}: reference incomplete ({len(ref.failed)} hubs failed): skipped\n")
            continue
        vref = ref.volume
        r = float(np.median(g.radii))
        leaves = int((g.degree == 1).sum())
        rows = []
        t, c0 = time.perf_counter(), _cpu()
        for P in (4, 6, 8, 12):
            row = [str(P)]
            meshes = {}
            failed: dict[str, str] = {}
            cpu = float("nan")
            for prof in VOLUME_PROFILES:
                ts = time.process_time()
                try:
                    meshes[prof] = fast_stitch.stitch(g, P, profile=prof)
                except Exception as exc:  # noqa: BLE001 - a profile that does not fit
                    failed[prof] = type(exc).__name__
                if prof == "volume":
                    cpu = time.process_time() - ts
            rep = compare(g, meshes=meshes, reference=ref, union_segments=(), samples=samples)
            for prof in VOLUME_PROFILES:
                if prof in failed:
                    row += [failed[prof], "-", "-"]
                    continue
                c = rep.comparisons[prof]
                reg = c.regions
                row += [
                    f"{c.relative_volume_error:+.3%}",
                    f"{reg['struts']['symmetric']['p95'] / r:.3f}",
                    f"{reg['hubs']['symmetric']['p95'] / r:.3f}",
                ]
            frac = next(iter(rep.comparisons.values())).regions["struts"]["symmetric"]["fraction"]
            row += [f"{frac:.2f}", f"{cpu:.2f}"]
            rows.append(row)
            print("  ".join(row), flush=True)
        cols = ["P"]
        for prof in VOLUME_PROFILES:
            label = "default" if prof == "volume" else prof
            cols += [f"{label} error", "struts", "hubs"]
        cols += ["strut share", "default stitch cpu s"]
        zones = rep.hub_zone
        z = zones[zones > 0] if zones is not None else np.zeros(0)
        emit(
            table(
                f"{name}: {g.num_nodes:,} nodes, {g.num_edges:,} struts, {leaves} leaves, "
                f"r {r:g}; exact volume {vref:.4f} mm^3 (reference {tr:.0f} s wall, {cr:.0f} s "
                f"CPU, {ref.unique_hubs} distinct hubs, {len(ref.clusters)} clusters; lattice "
                f"{tg:.0f} s; meshes and deviations {time.perf_counter() - t:.0f} s wall, "
                f"{_cpu() - c0:.0f} s CPU; load {os.getloadavg()[0]:.1f}); hub zone radius "
                + (f"{np.median(z) / r:.2f} r median, {z.max() / r:.2f} r max" if len(z) else "-"),
                cols,
                rows,
            )
        )
    return "\n".join(text) + "\n"


def main() -> None:
    global WINDOW_HUBS, WINDOW_SEED, WINDOW_AT
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="small versions, < 1 min each")
    ap.add_argument("--all", action="store_true", help="every section")
    for name, (_, what) in SECTIONS.items():
        ap.add_argument(f"--{name.replace('_', '-')}", action="store_true", help=what)
    ap.add_argument(
        "--only", choices=list(SECTIONS), default=None, help="one section (same as its flag)"
    )
    ap.add_argument(
        "--volume-table",
        action="store_true",
        help="only the volume/deviation table of the profile options (section 4)",
    )
    ap.add_argument(
        "--volume-lattices", nargs="+", choices=list(VOLUME_LATTICES), default=None,
        help="with --volume-table: which lattices",
    )  # fmt: skip
    ap.add_argument("--volume-out", default=None, help="with --volume-table: file name in results/")
    ap.add_argument("--window", type=int, default=WINDOW_HUBS,
                    help="with --volume-table: hubs in a -win lattice's window")  # fmt: skip
    ap.add_argument("--window-seed", type=int, default=WINDOW_SEED,
                    help="with --volume-table: seed of the window's centre")  # fmt: skip
    ap.add_argument("--window-at", choices=["random", "leaf"], default=WINDOW_AT,
                    help="with --volume-table: window centre")  # fmt: skip
    ap.add_argument(
        "--irregular-size", type=int, default=None, help="cells per side of the irregular grid"
    )
    ap.add_argument(
        "--no-trim",
        action="store_true",
        help="stumps start at the node (the construction before trimming, for comparison)",
    )
    ap.add_argument(
        "--report-lattices",
        nargs="+",
        choices=["voxel", "tet"],
        default=["voxel", "tet"],
        help="the GE lattices --report measures",
    )
    ap.add_argument(
        "--ge",
        choices=["all", "bcc", "tet"],
        default=None,
        help="the GE bracket lattices (report time, hubs/s) instead of the rest",
    )
    ap.add_argument(
        "--ge-sample",
        type=int,
        default=24,
        help="distinct hubs built where the lattice is refused (tet)",
    )
    ap.add_argument(
        "--full-union-study",
        action="store_true",
        help="with --ge: manifold3d unions of the whole lattice",
    )
    ap.add_argument(
        "--fuse-ab",
        type=int,
        default=0,
        metavar="HUBS",
        help="A/B of the hub fuse on this many tet hubs (2 rounds)",
    )
    ap.add_argument("--refused", action="store_true", help="issue 14: lattices refused (only)")
    ap.add_argument("--max-struts", type=int, default=1500, help="with --refused")
    ap.add_argument("--parts", nargs="+", default=None, help="with --refused: name filters")
    ap.add_argument("--settings", nargs="+", default=None, choices=list(REFUSED_SETTINGS))
    ap.add_argument("--budget", type=float, default=3600.0, help="with --refused: seconds")
    ap.add_argument(
        "--build-max-struts", type=int, default=600, help="with --refused: build up to this"
    )
    ap.add_argument(
        "--cell-divisor", type=float, default=8.0, help="with --refused: cell = extent / this"
    )
    ap.add_argument("--out", type=Path, default=None, help="with --refused: save the table")
    ap.add_argument("--case-timeout", type=float, default=0.0,
                    help="with --refused: wall seconds per lattice build (0: none)")  # fmt: skip
    ap.add_argument("--cache", type=Path, default=None, help="with --refused: graphs cache")
    ap.add_argument(
        "--folders",
        nargs="+",
        default=None,
        choices=["step", "meshes"],
        help="with --refused: only these folders of ../shared/data",
    )
    a = ap.parse_args()
    global REPORT_LATTICES
    REPORT_LATTICES = tuple(a.report_lattices)
    if a.refused:
        global CASE_TIMEOUT
        CASE_TIMEOUT = a.case_timeout
        print(f"cpus {os.cpu_count()}, load {os.getloadavg()}\n")
        bench_refused(
            a.max_struts,
            a.parts,
            a.settings,
            a.budget,
            a.build_max_struts,
            a.cell_divisor,
            a.out,
            a.cache,
            tuple(a.folders) if a.folders else None,
        )
        return
    if a.ge or a.fuse_ab:
        print(f"cpus {os.cpu_count()}, load {os.getloadavg()}\n")
        if a.fuse_ab:
            bench_fuse_ab(a.fuse_ab, 2)
        if a.ge:
            bench_ge(a.ge, a.ge_sample, None if a.full_union_study else 200)
        return
    if a.no_trim:
        from lattice_cad.core import config

        config.TRIM_FRACTION = 0.0  # stump_start() then returns 0 for every stump (forked workers)
    print(f"cpus {os.cpu_count()}, load {os.getloadavg()}\n")
    if a.volume_table:
        WINDOW_HUBS, WINDOW_SEED, WINDOW_AT = a.window, a.window_seed, a.window_at
        name = a.volume_out or ("bench_reference_volume" + ("_quick" if a.quick else "") + ".txt")
        which = tuple(a.volume_lattices) if a.volume_lattices else None
        bench_volume_table(a.quick, Path(__file__).resolve().parent / "results" / name, which)
        return
    chosen = [n for n in SECTIONS if getattr(a, n) or a.only == n]
    if a.all:
        chosen = list(SECTIONS)
    for name in chosen or DEFAULT_SECTIONS:
        if name == "irregular":
            bench_irregular(a.quick, a.irregular_size)
        else:
            SECTIONS[name][0](a.quick)


if __name__ == "__main__":
    main()
