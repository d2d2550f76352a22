"""Writers of :class:`~reference_boolean.compare.ValidationReport`: JSON, Markdown, HTML.

Every format opens with the same **first screen** (:func:`first_screen`): one
verdict line (PASS / FAIL against the user's tolerance, see
:mod:`reference_boolean.verdict`), the key figures (volume error, exact volume,
two-sided surface deviation in mm and in % of the strut radius, the
tolerances), a shaded render of the lattice coloured by local deviation with the
worst places numbered and a colour bar in mm, and the worst places
(:func:`reference_boolean.pictures.worst_places`) as a table with a close-up
picture of each (the mesh near the hub coloured by signed deviation, the exact
solid as a ghost, the hub ringed). The long tables (reference, unions, one
table per mesh, failed hubs, timings) and the plots (volume convergence,
deviation histogram) follow under "Details".

The HTML file is self-contained (every picture embedded as base64). A Markdown
report ``NAME.md`` is written with its pictures beside it in ``NAME_pictures/``.
The pictures are rendered offscreen (:mod:`lattice_cad.render`) once per report
and shared by every format written from it.
"""

from __future__ import annotations

import base64
import html
import io
import json
import os
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lattice_cad.core import config
from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.formats import Kind, format_for

if TYPE_CHECKING:
    from reference_boolean.compare import ValidationReport
    from reference_boolean.pictures import WorstPlace
    from reference_boolean.verdict import Verdict

__all__ = [
    "save",
    "to_markdown",
    "to_html",
    "to_text",
    "plots",
    "lattice_render",
    "first_screen",
    "first_screen_pictures",
    "FirstScreen",
]


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def save(rep: ValidationReport, path: str | os.PathLike[str]) -> Path:
    """Write ``rep`` by suffix: ``.json``, ``.md`` or ``.html`` (atomically).

    A Markdown report also writes its first-screen pictures into ``<stem>_pictures/``
    beside it (PNG), linked relatively from the text.
    """
    p = Path(path)
    fmt = format_for(p, Kind.REPORT)
    if fmt.name == "json":
        text = json.dumps(rep.to_dict(), indent=2, default=_json_default)
    elif fmt.name == "md":
        from lattice_cad.core.atomic import check_target

        check_target(p)
        folder = p.parent / f"{p.stem}_pictures"
        folder.mkdir(exist_ok=True)
        links = {}
        for name, data in first_screen_pictures(rep).items():
            with atomic_write(folder / f"{name}.png") as fh:
                fh.write(data)
            links[name] = f"{folder.name}/{name}.png"
        text = to_markdown(rep, pictures=links)
    else:
        text = to_html(rep)
    with atomic_write(p, "w") as fh:
        fh.write(text)
    return p


def _g(x: float | None, fmt: str = ".6g") -> str:
    return "-" if x is None else format(x, fmt)


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{x:+.4%}"


_Table = tuple[str, list[str], list[list[str]]]


# ------------------------------------------------------------------ first screen
@dataclass(frozen=True)
class FirstScreen:
    """What a user reads first: the verdict, the key figures, the worst places.

    Attributes
    ----------
    verdict : Verdict
        PASS / FAIL of the report's first mesh (:meth:`ValidationReport.verdict`).
    figures : list of (str, str)
        Quantity and value, in reading order (mesh, volume error, exact volume,
        deviation in mm and in % of the strut radius, tolerances, other meshes).
    places : list of WorstPlace
        The worst places, worst first (numbered ``#1``, ... on every picture).
    unranked : int
        Nodes next to failed hubs, left out of the ranking.
    """

    verdict: Verdict
    figures: list[tuple[str, str]]
    places: list[WorstPlace]
    unranked: int


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def first_screen(rep: ValidationReport, *, k: int = config.REPORT_WORST_HUBS) -> FirstScreen:
    """The verdict, the key figures and the ``k`` worst places of ``rep``."""
    from reference_boolean.pictures import worst_places
    from reference_boolean.verdict import DEFINITION

    v = rep.verdict()
    ref = rep.reference
    figs: list[tuple[str, str]] = []
    comp = rep.comparisons.get(v.label)
    if comp is not None:
        bad = [key for key, ok in comp.valid.items() if key != "valid" and not ok]
        figs.append(
            (
                "mesh",
                f"{comp.label}: {len(comp.mesh.faces):,} triangles, "
                + ("valid (watertight, manifold)" if not bad else "INVALID: not " + ", ".join(bad)),
            )
        )
        figs.append(
            (
                "volume error",
                f"{100 * comp.relative_volume_error:+.2f} % (mesh {comp.volume:.6g} mm^3)",
            )
        )
    state = (
        f"complete, {v.hubs:,} hubs"
        if ref.complete
        else f"INCOMPLETE: {v.failed_hubs} of {v.hubs:,} hubs failed, so this is a partial volume"
    )
    figs.append(("exact volume", f"{ref.volume:.10g} mm^3 (OCCT, reference {state})"))
    if comp is not None:
        figs += _deviation_figures(rep, v, comp)
    figs.append(
        (
            "tolerance",
            f"surface \u00b1{_fmt(v.tolerance)} mm on the deviation p95"
            + (
                f" (default: {100 * config.DEFAULT_DEVIATION_TOLERANCE_REL:g} % of the median "
                "strut radius)"
                if v.tolerance_default
                else ""
            )
            + f"; volume \u00b1{100 * v.tolerance_volume:.3g} %",
        )
    )
    figs.append(("verdict rule", DEFINITION))
    for label in list(rep.comparisons)[1:]:
        o = rep.verdict(label)
        assert o.volume_error is not None
        figs.append(
            (
                f"also compared: {label}",
                f"{o.status}: volume error {100 * o.volume_error:+.2f} %, deviation p95 "
                f"{_fmt(o.deviation['p95'])} mm, max {_fmt(o.deviation['max'])} mm"
                + (" along struts" if o.deviation_region == "struts" else "")
                + (f" (hubs: p95 {_fmt(o.deviation_hubs['p95'])} mm)" if o.deviation_hubs else ""),
            )
        )
    places, unranked = worst_places(rep, k) if comp is not None else ([], 0)
    return FirstScreen(verdict=v, figures=figs, places=places, unranked=unranked)


def _dev(d: dict[str, float], r: float) -> str:
    """``max .. mm, p95 .. mm, mean .. mm`` and the same in % of ``r``."""
    out = f"max {_fmt(d['max'])} mm, p95 {_fmt(d['p95'])} mm, mean {_fmt(d['mean'])} mm"
    if r > 0:
        out += (
            f" (max {100 * d['max'] / r:.0f} %, p95 {100 * d['p95'] / r:.0f} %, "
            f"mean {100 * d['mean'] / r:.0f} % of r)"
        )
    return out


def _deviation_figures(rep: ValidationReport, v: Verdict, comp: Any) -> list[tuple[str, str]]:
    """The deviation lines of the first screen: along struts (judged), at hubs, whole."""
    from reference_boolean.regions import RULE

    r = v.radius
    d = v.deviation
    figs: list[tuple[str, str]] = []
    struts = v.deviation_region == "struts"
    figs.append(
        (
            "surface deviation along struts (two-sided, judged)"
            if struts
            else "surface deviation (two-sided)",
            f"max {_fmt(d['max'])} mm, p95 {_fmt(d['p95'])} mm, mean {_fmt(d['mean'])} mm"
            + (
                f" on {100 * comp.regions['struts']['symmetric']['fraction']:.0f} % of the "
                "surface: outside the hub zones, where mesh and exact solid model the same "
                "design"
                if struts
                else ""
            ),
        )
    )
    if r > 0:
        figs.append(
            (
                f"... in % of the strut radius ({_fmt(r)} mm"
                + ("" if np.ptp(rep.graph.radii) == 0 else ", median")
                + ")",
                f"max {100 * d['max'] / r:.0f} %, p95 {100 * d['p95'] / r:.0f} %, "
                f"mean {100 * d['mean'] / r:.0f} %",
            )
        )
    if comp.regions:
        h = v.deviation_hubs
        if comp.regions["hubs"]["symmetric"]["samples"]:
            figs.append(
                (
                    "surface deviation at hubs (not judged)",
                    _dev(h, r) + "; the designs differ there: the mesh's convex hub fills the "
                    "crevices between struts where the exact solid shows its node ball "
                    "(the volume error covers the hubs)",
                )
            )
        else:
            figs.append(("surface deviation at hubs (not judged)", "no samples in hub zones"))
        if not struts:
            figs.append(
                (
                    "note",
                    "too few samples along struts (below "
                    f"{100 * config.MIN_STRUT_FRACTION:g} %): the whole surface is judged",
                )
            )
        figs.append(("surface deviation, whole surface", _dev(v.deviation_all, r)))
        figs.append(("hub zone", RULE.format(f=rep.hub_zone_factor or 0.0)))
    return figs


_PICTURES: weakref.WeakKeyDictionary[Any, dict[str, bytes]] = weakref.WeakKeyDictionary()


def first_screen_pictures(
    rep: ValidationReport, *, k: int = config.REPORT_WORST_HUBS
) -> dict[str, bytes]:
    """PNG bytes of the first screen: ``"overview"`` (the lattice coloured by local deviation,
    worst places numbered) and ``"worst1"``, ``"worst2"``, ... (one close-up per worst place,
    all on one colour scale). Rendered once per report (cached)."""
    cached = _PICTURES.get(rep)
    if cached is not None:
        return cached
    from reference_boolean.pictures import closeup, closeup_data

    screen = first_screen(rep, k=k)
    out = {
        "overview": lattice_render(rep, places=screen.places, tolerance=screen.verdict.tolerance)
    }
    if rep.mesh is not None and screen.places:
        datas = [closeup_data(rep, p) for p in screen.places]
        devs = [np.abs(d.deviation[np.isfinite(d.deviation)]) for d in datas]
        limit = max((float(x.max()) for x in devs if len(x)), default=0.0)
        limit = max(limit, screen.verdict.tolerance)
        for d in datas:
            out[f"worst{d.place.rank}"] = closeup(rep, d, limit=limit)
    _PICTURES[rep] = out
    return out


def _place_rows(screen: FirstScreen) -> list[list[str]]:
    return [
        [
            f"#{p.rank}",
            str(p.node),
            "(" + ", ".join(f"{c:.4g}" for c in p.position) + ")",
            _fmt(p.deviation),
            f"{p.percent_of_radius:.0f} %",
            p.where,
        ]
        for p in screen.places
    ]


_PLACE_COLS = [
    "#", "node", "position (mm)", "deviation (mm)", "% of strut radius", "worst sample",
]  # fmt: skip


def _unranked_note(screen: FirstScreen) -> str:
    if not screen.unranked:
        return ""
    return (
        f"{screen.unranked} node(s) at or next to failed hubs are not ranked: the exact "
        "solid is missing there (marked 'failed' on the overview)."
    )


def to_text(rep: ValidationReport) -> str:
    """The first screen as plain text (what ``lattice-cad validate`` prints)."""
    screen = first_screen(rep)
    w = max(len(q) for q, _ in screen.figures)
    lines = [screen.verdict.line]
    lines += [f"  {q:<{w}}  {val}" for q, val in screen.figures if q != "verdict rule"]
    if screen.places:
        lines.append("  worst places (node, position mm, deviation):")
        for p in screen.places:
            pos = ", ".join(f"{c:.4g}" for c in p.position)
            lines.append(
                f"    #{p.rank} node {p.node} at ({pos}): {_fmt(p.deviation)} mm "
                f"({p.percent_of_radius:.0f} % of r)" + (f", {p.where}" if p.where != "-" else "")
            )
    note = _unranked_note(screen)
    if note:
        lines.append("  " + note)
    return "\n".join(lines)


def _reference_table(d: dict[str, Any]) -> _Table:
    """The reference itself: size, exact volume, status, hubs, tessellation, time."""
    status = (
        "complete"
        if d["reference_complete"]
        else (f"INCOMPLETE: {len(d['reference_failed'])} hub(s) failed, the volume is partial")
    )
    g = d["graph"]
    rows = [
        [
            "graph",
            f"{g['nodes']} nodes, {g['struts']} struts" + (", tapered" if g["tapered"] else ""),
        ],
        ["reference volume (exact, OCCT GProp)", _g(d["volume_reference"], ".10g")],
        ["reference status", status],
        [
            "reference hubs built / reused",
            f"{d['reference_hubs']['unique']} / {d['reference_hubs']['cache_hits']}",
        ],
        [
            "reference tessellation volume",
            f"{_g(d['volume_reference_mesh'], '.10g')} "
            f"({_pct(d['relative_volume_error']['reference_mesh'])})",
        ],
        ["reference triangles", str(d["triangles"]["reference"])],
        ["reference build time (s)", _g(d["timings"]["reference"]["total"], ".3g")],
    ]
    return ("Reference", ["quantity", "value"], rows)


def _union_table(d: dict[str, Any]) -> list[_Table]:
    """The manifold3d unions at each resolution (empty when none were built)."""
    rows = [
        [
            str(n),
            _g(v, ".10g"),
            _pct(d["relative_volume_error"]["union"][n]),
            str(d["triangles"]["union"][n]),
            str(d["valid"]["union"][n]),
            _g(d["timings"]["union"][n], ".3g"),
        ]
        for n, v in d["volume_union"].items()
    ]
    if not rows:
        return []
    title = (
        "manifold3d union of the same spheres and struts "
        f"(fitted convergence order {_g(d['convergence_order'], '.3g')}, 2 expected)"
    )
    if d.get("union_scope", "lattice") != "lattice":
        title += f"; over {d['union_scope']}"
    return [(title, ["segments", "volume", "rel. error", "triangles", "valid", "time (s)"], rows)]


def _region_cells(row: dict[str, Any]) -> list[str]:
    """p95 and max of the symmetric deviation along struts and at hubs ("-" if none)."""
    regs = row.get("deviation_regions") or {}
    out = []
    for reg in ("struts", "hubs"):
        st = regs.get(reg, {}).get("symmetric")
        ok = st is not None and st["samples"] > 0
        out += [_g(st["p95"]) if ok else "-", _g(st["max"]) if ok else "-"]
    return out


def _mesh_tables(d: dict[str, Any]) -> list[_Table]:
    """The meshes under test: one summary table, one table per mesh, the worst nodes."""
    meshes = d.get("meshes") or []
    if not meshes:
        return []
    summary = []
    for row in meshes:
        sym = row["hausdorff"]["symmetric"]
        summary.append(
            [
                row["label"],
                _g(row["volume"], ".10g"),
                _pct(row["relative_volume_error"]),
                _g(sym["max"]),
                _g(sym["mean"]),
                _g(sym["p95"]),
                *_region_cells(row),
                str(row["triangles"]),
                str(row["valid"]["valid"]),
            ]
        )
    cols = ["mesh", "volume", "rel. volume error", "Hausdorff max", "mean", "p95"]
    cols += ["struts p95", "struts max", "hubs p95", "hubs max"]
    out: list[_Table] = [
        (
            "Meshes under test against the reference (one row per mesh; "
            "symmetric surface deviation: whole surface, along struts, at hubs)",
            [*cols, "triangles", "valid"],
            summary,
        )
    ]
    for row in meshes:
        rows = [
            ["volume", _g(row["volume"], ".10g")],
            ["relative volume error", _pct(row["relative_volume_error"])],
            ["triangles", str(row["triangles"])],
            ["valid", ", ".join(f"{k}={v}" for k, v in row["valid"].items())],
        ]
        for k in ("mesh_to_reference", "reference_to_mesh", "symmetric"):
            st = row["hausdorff"][k]
            rows.append(
                [
                    f"deviation {k.replace('_', ' ')} (max / mean / p95)",
                    f"{_g(st['max'])} / {_g(st['mean'])} / {_g(st['p95'])}",
                ]
            )
        for reg, regions in (row.get("deviation_regions") or {}).items():
            for k in ("mesh_to_reference", "reference_to_mesh", "symmetric"):
                st = regions[k]
                rows.append(
                    [
                        f"deviation {'along struts' if reg == 'struts' else 'at hubs'}, "
                        f"{k.replace('_', ' ')} (max / mean / p95; share of samples)",
                        f"{_g(st['max'])} / {_g(st['mean'])} / {_g(st['p95'])}; "
                        f"{100 * st['fraction']:.1f} %",
                    ]
                )
        out.append((f"Mesh under test: {row['label']}", ["quantity", "value"], rows))
    worst = [[str(w["node"]), _g(w["deviation"])] for w in d["worst_nodes"]]
    out.append(
        (f"Worst nodes by local deviation ({meshes[0]['label']})", ["node", "deviation"], worst)
    )
    return out


def _extra_tables(d: dict[str, Any]) -> list[_Table]:
    """Failed hubs (at most 50) and any extra list-of-records tables."""
    out: list[_Table] = []
    if d["reference_failed"]:
        failed = [[k, v] for k, v in list(d["reference_failed"].items())[:50]]
        out.append(("Failed hubs", ["node", "reason"], failed))
    for key, val in (d.get("extra") or {}).items():
        if isinstance(val, list) and val and isinstance(val[0], dict):
            cols = list(val[0])
            rows = [[_g(r[c]) if isinstance(r[c], float) else str(r[c]) for c in cols] for r in val]
            out.append((key, cols, rows))
    return out


def _tables(rep: ValidationReport) -> list[_Table]:
    """Every table of the report, in order: (title, column names, rows of strings)."""
    d = rep.to_dict()
    return [_reference_table(d), *_union_table(d), *_mesh_tables(d), *_extra_tables(d)]


def _md_table(cols: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    return out + ["| " + " | ".join(x.replace("|", "\\|") for x in r) + " |" for r in rows]


def to_markdown(rep: ValidationReport, *, pictures: dict[str, str] | None = None) -> str:
    """The report as Markdown: the first screen, then the tables.

    Parameters
    ----------
    pictures : dict[str, str], optional
        Links to the first-screen pictures by name (``"overview"``, ``"worst1"``, ...),
        as :func:`save` writes them; without it the text has no pictures.
    """
    screen = first_screen(rep)
    links = pictures or {}
    out = ["# Lattice accuracy report", "", f"**{screen.verdict.line}**", ""]
    out += _md_table(["quantity", "value"], [[q, v] for q, v in screen.figures])
    out.append("")
    if "overview" in links:
        out += [
            f"![local deviation from the exact solid, worst places numbered]({links['overview']})",
            "",
        ]
    if screen.places:
        out += ["## Worst places", ""]
        out += _md_table(_PLACE_COLS, _place_rows(screen))
        out.append("")
        pics = [
            f"![#{p.rank}: node {p.node}]({links[f'worst{p.rank}']})"
            for p in screen.places
            if f"worst{p.rank}" in links
        ]
        if pics:
            out += [" ".join(pics), ""]
    note = _unranked_note(screen)
    if note:
        out += [note, ""]
    out += ["---", "", "# Details", ""]
    for title, cols, rows in _tables(rep):
        out += [f"## {title}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        out += ["| " + " | ".join(r) + " |" for r in rows]
        out.append("")
    return "\n".join(out)


def plots(rep: ValidationReport, *, render: bool = True) -> dict[str, bytes]:
    """PNG bytes of the pictures: ``lattice`` (the render; not with ``render=False``),
    ``convergence``, ``histogram``."""
    # Figure + FigureCanvasAgg directly: no pyplot, no global backend switch, no window
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    def png(fig: Figure) -> bytes:
        FigureCanvasAgg(fig)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
        return buf.getvalue()

    out: dict[str, bytes] = {}
    vref = rep.reference.volume
    if rep.volume_union:
        fig = Figure(figsize=(5.5, 4))
        ax = fig.add_subplot()
        ns = np.array(sorted(rep.volume_union))
        vu = vref if rep.union_reference_volume is None else rep.union_reference_volume
        err = np.array([abs(rep.volume_union[int(n)] - vu) / vu for n in ns])
        ax.loglog(ns, np.maximum(err, 1e-17), "o-", label="manifold3d union")
        ax.loglog(ns, err[0] * (ns[0] / ns) ** 2, "k--", lw=0.8, label="1/n^2")
        for i, c in enumerate(rep.comparisons.values()):
            ax.axhline(
                max(abs(c.volume - vref) / vref, 1e-17),
                color=f"C{3 + i}",
                ls=("-", "--", ":", "-.")[i % 4],
                label=c.label,
            )
        ax.set_xlabel("segments per circle")
        ax.set_ylabel("|V - V_ref| / V_ref")
        ax.set_title("volume convergence to the exact reference")
        ax.legend()
        out["convergence"] = png(fig)
    if rep.comparisons:
        fig = Figure(figsize=(5.5, 4))
        ax = fig.add_subplot()
        many = len(rep.comparisons) > 1
        for c in rep.comparisons.values():
            for k, d in c.distances.items():
                name = k.replace("_", " ")
                ax.hist(d, bins=60, histtype="step", label=f"{c.label}: {name}" if many else name)
        ax.set_yscale("log")
        ax.set_xlabel("distance")
        ax.set_ylabel("samples")
        ax.set_title("surface deviation" + ("" if many else f": {rep.label}"))
        ax.legend()
        out["histogram"] = png(fig)
    if not render:
        return out
    return {"lattice": first_screen_pictures(rep)["overview"], **out}


#: Worst places numbered on the report's render.
WORST_MARKED = config.REPORT_WORST_HUBS


def lattice_render(
    rep: ValidationReport,
    *,
    size: tuple[int, int] = (1100, 780),
    places: list[WorstPlace] | None = None,
    tolerance: float | None = None,
) -> bytes:
    """PNG of the lattice as shaded tubes coloured by local deviation, worst places numbered.

    Parameters
    ----------
    rep : ValidationReport
    size : (int, int)
    places : list of WorstPlace, optional
        The numbered places (default: :func:`~reference_boolean.pictures.worst_places`).
    tolerance : float, optional
        Marked on the colour bar (mm).

    Failed hubs (if any) are marked ``failed``.
    """
    from lattice_cad.render import ColorBar, Layer, Marker, picture, tubes
    from reference_boolean.pictures import worst_places

    g = rep.graph
    dev = np.asarray(rep.node_deviation, dtype=np.float64)
    has = bool(np.isfinite(dev).any())
    small = g.num_edges <= 400_000
    v, f, n, sc = tubes(
        g.nodes,
        g.edges,
        g.radii,
        sides=8 if small else 6,
        end_values=dev[g.edges] if has else None,
        node_scalars=dev if has else None,
        balls=small,
    )
    if places is None:
        places = worst_places(rep, WORST_MARKED)[0] if has else []
    from reference_boolean.pictures import HIGHLIGHT

    # the worst hubs highlighted: a ring in the close-ups' colour and their hub zone (below)
    markers = [Marker(p.position, f"#{p.rank}", color=HIGHLIGHT) for p in places]
    for i in rep.reference.failed:
        x, y, z = map(float, g.nodes[int(i)])
        markers.append(Marker((x, y, z), "failed"))
    colorbar = None
    if has:
        lo, hi = float(np.nanmin(dev)), float(np.nanmax(dev))
        colorbar = ColorBar(
            "local deviation from the exact solid (mm)"
            + ("; | = tolerance" if tolerance is not None and lo < tolerance < hi else ""),
            (lo, hi),
            "plasma",
            threshold=tolerance,
        )
    caption = f"{g.num_edges:,} struts ({rep.label})"
    if places:
        caption += "; worst places: " + ", ".join(
            f"#{p.rank} node {p.node} ({p.deviation:.3g} mm)" for p in places
        )
    layers = [Layer(v, f, n, sc, color=(0.80, 0.62, 0.25), closed=True)]
    if places:  # each worst hub's zone as a translucent highlight-green ball
        from reference_boolean.pictures import zone_ball

        green = tuple(int(HIGHLIGHT[i : i + 2], 16) / 255.0 for i in (1, 3, 5))
        for p in places:
            bv, bf = zone_ball(rep, p)
            layers.append(Layer(bv, bf, color=green, style="ghost", closed=True))  # type: ignore[arg-type]
        caption += "; green balls: the worst places' hub zones"
    png, _ = picture(
        layers,
        size=size,
        colorbar=colorbar,
        title="local deviation from the exact reference" if has else "lattice",
        caption=caption,
        markers=markers,
    )
    return png


def to_html(rep: ValidationReport) -> str:
    """One self-contained HTML page: the first screen, then the tables and plots (base64 PNG)."""
    screen = first_screen(rep)
    ok = screen.verdict.passed
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Lattice accuracy report</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
        "table{border-collapse:collapse;margin-bottom:1em}td,th{border:1px solid #999;"
        "padding:2px 8px;text-align:left}"
        ".verdict{font-size:1.25em;font-weight:bold;padding:10px 14px;border-radius:4px}"
        ".pass{background:#e3f4e6;color:#14532d;border:2px solid #2e7d32}"
        ".fail{background:#fde8e8;color:#7f1d1d;border:2px solid #c62828}"
        ".closeups{display:flex;flex-wrap:wrap;gap:6px}"
        ".closeups figure{margin:0}</style></head><body>",
        "<h1>Lattice accuracy report</h1>",
        f"<p class='verdict {'pass' if ok else 'fail'}' id='verdict'>"
        f"{html.escape(screen.verdict.line)}</p>",
        "<table id='figures'>",
    ]
    parts += [
        f"<tr><th>{html.escape(q)}</th><td>{html.escape(v)}</td></tr>" for q, v in screen.figures
    ]
    parts.append("</table>")
    first = first_screen_pictures(rep)
    figures = plots(rep, render=False)

    def figure(name: str, data: bytes, caption: str | None = None) -> str:
        b64 = base64.b64encode(data).decode("ascii")
        return (
            f"<figure><img alt='{html.escape(name)}' src='data:image/png;base64,{b64}' "
            f"style='max-width:100%'><figcaption>{html.escape(caption or name)}"
            "</figcaption></figure>"
        )

    parts.append(
        figure(
            "overview",
            first["overview"],
            "local deviation from the exact solid (mm), worst places numbered",
        )
    )
    if screen.places:
        parts.append("<h2>Worst places</h2><table id='worst'><tr>")
        parts += [f"<th>{html.escape(c)}</th>" for c in _PLACE_COLS]
        parts.append("</tr>")
        for r in _place_rows(screen):
            parts.append("<tr>" + "".join(f"<td>{html.escape(x)}</td>" for x in r) + "</tr>")
        parts.append("</table><div class='closeups'>")
        parts += [
            figure(f"worst{p.rank}", first[f"worst{p.rank}"], f"#{p.rank}: node {p.node}")
            for p in screen.places
            if f"worst{p.rank}" in first
        ]
        parts.append("</div>")
    note = _unranked_note(screen)
    if note:
        parts.append(f"<p>{html.escape(note)}</p>")
    parts.append("<hr><h1>Details</h1>")
    for title, cols, rows in _tables(rep):
        parts.append(f"<h2>{html.escape(title)}</h2><table><tr>")
        parts += [f"<th>{html.escape(c)}</th>" for c in cols]
        parts.append("</tr>")
        for r in rows:
            parts.append("<tr>" + "".join(f"<td>{html.escape(x)}</td>" for x in r) + "</tr>")
        parts.append("</table>")
    parts.append("<h2>Plots</h2>")
    parts += [figure(name, data) for name, data in figures.items()]
    parts.append("</body></html>")
    return "\n".join(parts)
