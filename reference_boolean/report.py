"""Writers of :class:`~reference_boolean.compare.ValidationReport`: JSON, Markdown, HTML.

The HTML file is self-contained: its first screen is a shaded render of the
lattice coloured by local deviation from the exact reference, with the worst
nodes numbered (:mod:`lattice_cad.render`, offscreen); the plots below the
tables (volume convergence, deviation histogram) are matplotlib PNGs rendered
with the Agg backend. Every picture is embedded as base64.
"""

from __future__ import annotations

import base64
import html
import io
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lattice_cad.core.atomic import atomic_write
from lattice_cad.core.formats import Kind, format_for

if TYPE_CHECKING:
    from reference_boolean.compare import ValidationReport

__all__ = ["save", "to_markdown", "to_html", "plots", "lattice_render"]


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def save(rep: ValidationReport, path: str | os.PathLike[str]) -> Path:
    """Write ``rep`` by suffix: ``.json``, ``.md`` or ``.html`` (atomically)."""
    p = Path(path)
    fmt = format_for(p, Kind.REPORT)
    if fmt.name == "json":
        text = json.dumps(rep.to_dict(), indent=2, default=_json_default)
    elif fmt.name == "md":
        text = to_markdown(rep)
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
                str(row["triangles"]),
                str(row["valid"]["valid"]),
            ]
        )
    cols = ["mesh", "volume", "rel. volume error", "Hausdorff max", "mean", "p95"]
    out: list[_Table] = [
        (
            "Meshes under test against the reference (one row per mesh; "
            "symmetric surface deviation)",
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


def to_markdown(rep: ValidationReport) -> str:
    """The report as Markdown tables."""
    out = ["# Lattice accuracy report", ""]
    for title, cols, rows in _tables(rep):
        out += [f"## {title}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        out += ["| " + " | ".join(r) + " |" for r in rows]
        out.append("")
    return "\n".join(out)


def plots(rep: ValidationReport) -> dict[str, bytes]:
    """PNG bytes of the pictures: ``lattice`` (the render), ``convergence``, ``histogram``."""
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
    return {"lattice": lattice_render(rep), **out}


#: Worst nodes numbered on the report's render.
WORST_MARKED = 5


def lattice_render(rep: ValidationReport, *, size: tuple[int, int] = (1100, 780)) -> bytes:
    """PNG of the lattice as shaded tubes coloured by local deviation, worst nodes numbered.

    Failed hubs (if any) are marked ``failed``.
    """
    from lattice_cad.render import ColorBar, Layer, Marker, picture, tubes

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
    worst = rep.worst_nodes(WORST_MARKED)
    markers = [Marker(tuple(map(float, g.nodes[i])), str(k)) for k, (i, _) in enumerate(worst, 1)]
    markers += [Marker(tuple(map(float, g.nodes[int(i)])), "failed") for i in rep.reference.failed]
    colorbar = None
    if has:
        lo, hi = float(np.nanmin(dev)), float(np.nanmax(dev))
        colorbar = ColorBar("local deviation from the exact reference (mm)", (lo, hi), "plasma")
    caption = f"{g.num_edges:,} struts ({rep.label})"
    if worst:
        caption += "; worst nodes: " + ", ".join(
            f"{k}: node {i} ({d:.3g} mm)" for k, (i, d) in enumerate(worst, 1)
        )
    png, _ = picture(
        [Layer(v, f, n, sc, color=(0.80, 0.62, 0.25), closed=True)],
        size=size,
        colorbar=colorbar,
        title="local deviation from the exact reference" if has else "lattice",
        caption=caption,
        markers=markers,
    )
    return png


def to_html(rep: ValidationReport) -> str:
    """One self-contained HTML page (tables and base64 PNG plots)."""
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Lattice accuracy report</title>",
        "<style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
        "table{border-collapse:collapse;margin-bottom:1em}td,th{border:1px solid #999;"
        "padding:2px 8px;text-align:left}</style></head><body>",
        "<h1>Lattice accuracy report</h1>",
    ]
    figures = plots(rep)

    def figure(name: str, data: bytes) -> str:
        b64 = base64.b64encode(data).decode("ascii")
        return (
            f"<figure><img alt='{name}' src='data:image/png;base64,{b64}' style='max-width:100%'>"
            f"<figcaption>{name}</figcaption></figure>"
        )

    parts.append(figure("lattice", figures.pop("lattice")))
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
