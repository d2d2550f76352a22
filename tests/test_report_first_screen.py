"""The accuracy report's first screen: verdict against a tolerance, key figures, worst places
with pictures (issue 14 item 4, issue 16 item 3).

The lattice is a real one: the shipped example bracket filled with BCC cells of 5 mm,
radius 0.5 mm (whole cells inside), its exact reference built by OCCT.
"""

from __future__ import annotations

import dataclasses
import io
import re
import warnings

import numpy as np
import pytest
from PIL import Image

from lattice_cad.core.errors import ToleranceError
from lattice_cad.render.raster import BACKGROUND
from reference_boolean.pictures import HIGHLIGHT
from reference_boolean.report import first_screen, first_screen_pictures, to_markdown, to_text
from tests.conftest import ROOT, star_graph


@pytest.fixture(scope="module")
def bracket_report():
    from lattice_cad.core.errors import LatticeWarning
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(ROOT / "examples" / "bracket.step", "bcc", 5.0, 0.5, fill="inside")
    return lat.validate(profiles=("inscribed",), union_segments=(), samples=4000)


def _pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float64) / 255.0


def _object_fraction(img: np.ndarray) -> float:
    return float((np.abs(img - np.array(BACKGROUND)).max(axis=-1) > 0.03).mean())


def _colour_pixels(img: np.ndarray, hex_colour: str, tol: float = 0.12) -> int:
    rgb = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)]) / 255.0
    return int((np.abs(img - rgb).max(axis=-1) < tol).sum())


def _first_screen_md(md: str) -> str:
    return md.split("# Details")[0]


def test_first_screen_has_verdict_figures_and_pictures(bracket_report, tmp_path):
    rep = bracket_report
    assert rep.reference.complete and len(rep.comparisons) == 1
    comp = next(iter(rep.comparisons.values()))
    md_path = rep.save(tmp_path / "r.md")
    md = md_path.read_text(encoding="utf-8")
    top = _first_screen_md(md)
    lines = [ln for ln in top.splitlines() if ln.strip()]
    # the verdict is the first line after the title
    assert lines[0] == "# Lattice accuracy report"
    assert re.match(r"\*\*(PASS|FAIL): ", lines[1])
    assert "of the exact solid" in lines[1]
    # the figures are the report's own numbers
    assert f"{100 * comp.relative_volume_error:+.2f} %" in top
    assert f"{rep.reference.volume:.10g} mm^3" in top
    sym = comp.hausdorff["symmetric"]
    assert f"p95 {sym['p95']:.3g} mm" in top and f"max {sym['max']:.3g} mm" in top
    assert f"p95 {100 * sym['p95'] / 0.5:.0f} %" in top  # % of the 0.5 mm strut radius
    # ... and split: along struts (judged, where both model the same design) and at hubs
    for region, label in (("struts", "along struts"), ("hubs", "at hubs")):
        st = comp.regions[region]["symmetric"]
        assert st["samples"] > 100
        row = next(ln for ln in top.splitlines() if f"surface deviation {label}" in ln)
        assert f"p95 {st['p95']:.3g} mm" in row and f"max {st['max']:.3g} mm" in row
    reg = comp.regions
    assert reg["struts"]["symmetric"]["p95"] < 0.5 * reg["hubs"]["symmetric"]["p95"]
    assert "| hub zone |" in top
    # the worst places, worst first, each with its close-up picture beside the .md
    screen = first_screen(rep)
    assert 1 <= len(screen.places) <= 4
    devs = [p.deviation for p in screen.places]
    assert devs == sorted(devs, reverse=True)
    assert devs[0] == pytest.approx(np.nanmax(rep.node_deviation))
    assert "## Worst places" in top
    for p in screen.places:
        assert f"| #{p.rank} | {p.node} |" in top
        assert (tmp_path / "r_pictures" / f"worst{p.rank}.png").exists()
        assert f"(r_pictures/worst{p.rank}.png)" in top
    assert "(r_pictures/overview.png)" in top
    # the long tables come after the first screen
    rest = md.split("# Details")[1]
    assert "## Reference" in rest and "| quantity | value |" in rest
    # HTML: the same first screen on top of the page
    page = rep.save(tmp_path / "r.html").read_text(encoding="utf-8")
    assert page.index("id='verdict'") < page.index("id='figures'") < page.index("Details")
    assert page.index("alt='overview'") < page.index("id='worst'") < page.index("Details")


def test_first_screen_pictures_are_not_blank_and_mark_the_worst_hub(bracket_report):
    rep = bracket_report
    pics = first_screen_pictures(rep)
    places = first_screen(rep).places
    assert set(pics) == {"overview"} | {f"worst{p.rank}" for p in places}
    over = _pixels(pics["overview"])
    assert 0.08 < _object_fraction(over[40:-110]) < 0.95
    assert _colour_pixels(over, HIGHLIGHT) > 50  # the numbered rings of the worst places
    assert len(np.unique((over * 255).astype(np.uint8).reshape(-1, 3), axis=0)) > 40  # shaded
    for p in places:
        img = _pixels(pics[f"worst{p.rank}"])
        assert 0.05 < _object_fraction(img[40:-110]) < 0.95, p
        assert _colour_pixels(img, HIGHLIGHT) > 30, p  # the worst hub, ringed
        assert img.std() > 0.05


def test_verdict_fails_a_tiny_tolerance_and_passes_a_large_one(bracket_report, tmp_path):
    rep = bracket_report
    comp = next(iter(rep.comparisons.values()))
    p95 = comp.regions["struts"]["symmetric"]["p95"]  # the verdict judges the struts
    assert rep.verdict().deviation_region == "struts" and rep.verdict().deviation["p95"] == p95
    err = abs(comp.relative_volume_error)
    tiny = dataclasses.replace(rep, tolerance=1e-6, tolerance_volume=1e-9)
    assert not tiny.verdict().passed and tiny.verdict().line.startswith("FAIL: mesh not within")
    large = dataclasses.replace(rep, tolerance=100.0, tolerance_volume=10.0)
    assert large.verdict().passed
    assert large.verdict().line.startswith("PASS: mesh within \u00b1100 mm of the exact solid")
    # the boundary: p95 and the volume error decide, each on its own
    just = dataclasses.replace(rep, tolerance=p95 * 1.001, tolerance_volume=err * 1.001)
    assert just.verdict().passed
    surf = dataclasses.replace(rep, tolerance=p95 * 0.999, tolerance_volume=err * 1.001)
    assert not surf.verdict().passed and surf.verdict().reasons[0].startswith("deviation p95")
    vol = dataclasses.replace(rep, tolerance=p95 * 1.001, tolerance_volume=err * 0.999)
    assert not vol.verdict().passed and vol.verdict().reasons[0].startswith("volume error")
    # the verdict reaches every format
    assert to_text(large).splitlines()[0].startswith("PASS: ")
    assert to_markdown(tiny).splitlines()[2].startswith("**FAIL: ")
    assert "class='verdict pass'" in large.save(tmp_path / "p.html").read_text(encoding="utf-8")
    assert large.to_dict()["verdict"]["status"] == "PASS"
    assert tiny.to_dict()["verdict"]["status"] == "FAIL"


def test_incomplete_reference_never_passes(bracket_report):
    rep = bracket_report
    worst = first_screen(rep).places[0].node
    # a reference that lost the hub of the worst node (as when OCCT fails on it)
    ref = dataclasses.replace(rep.reference, failed={worst: "simulated failure"})
    bad = dataclasses.replace(rep, reference=ref, tolerance=100.0, tolerance_volume=10.0)
    v = bad.verdict()
    assert not v.passed
    assert v.line.startswith("FAIL: not verified") and "incomplete (1 of" in v.line
    screen = first_screen(bad)
    assert all(p.node != worst for p in screen.places)  # no exact solid there to rank
    assert screen.unranked >= 1
    assert "INCOMPLETE" in to_markdown(bad)


def test_default_tolerance_is_ten_percent_of_the_radius():
    from lattice_cad.validate import validate

    g = star_graph([[1, 0, 0], [0, 1, 0], [0, 0, 1]], lengths=1.0, radii=0.1)
    rep = validate(g, 24, None, profiles=("inscribed",), union_segments=(), samples=2000)
    v = rep.verdict()
    assert v.tolerance == pytest.approx(0.01) and v.tolerance_default
    assert v.tolerance_volume == pytest.approx(0.01)
    given = validate(
        g, 24, None, profiles=("inscribed",), union_segments=(), samples=2000, tolerance=0.5
    )
    assert given.verdict().tolerance == 0.5 and not given.verdict().tolerance_default
    for bad in ({"tolerance": 0.0}, {"tolerance": -1.0}, {"tolerance_volume": float("nan")}):
        with pytest.raises(ToleranceError, match="tolerance"):
            validate(g, 6, None, union_segments=(), **bad)


@pytest.mark.slow
def test_cli_validate_prints_the_verdict_and_fails_on_a_tiny_tolerance(
    capsys, tmp_path, monkeypatch
):
    from conformal import block
    from lattice_cad.cli import main
    from lattice_cad.lattice import Lattice

    validate = Lattice.validate

    def light(self, report=None, **options):  # one union resolution, fewer samples: faster
        return validate(self, report, union_segments=(16,), samples=3000, **options)

    monkeypatch.setattr(Lattice, "validate", light)
    g = tmp_path / "g.json"
    block("bcc", 1, cell_size=5.0, radius=0.5).save(g)
    code = main(["validate", str(g), "--report", str(tmp_path / "a"), "--tolerance", "50",
                 "--tolerance-volume", "100", "--segments", "8"])  # fmt: skip
    out = capsys.readouterr().out
    verdicts = [ln for ln in out.splitlines() if ln.startswith(("PASS", "FAIL"))]
    assert code == 0 and verdicts == [verdicts[0]]
    assert verdicts[0].startswith("PASS: mesh within \u00b150 mm")
    assert (tmp_path / "a" / "report.md").exists() and (tmp_path / "a" / "report.html").exists()
    assert (tmp_path / "a" / "report_pictures" / "worst1.png").exists()
    code = main(["validate", str(g), "--report", str(tmp_path / "b"), "--tolerance", "1e-6"])
    out = capsys.readouterr().out
    verdicts = [ln for ln in out.splitlines() if ln.startswith(("PASS", "FAIL"))]
    assert code == 1 and verdicts[0].startswith("FAIL: mesh not within")
    assert "worst places" in out and "exact volume" in out
    with pytest.raises(SystemExit) as e:
        main(["validate", str(g), "--report", str(tmp_path / "c"), "--tolerance", "0"])
    assert e.value.code == 2
