"""Every script in examples/ runs, in a subprocess, writing into a temp directory."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))
#: Files each script must have written (besides the one its ``[OUT.xxx]`` argument names).
OUTPUTS = {
    "cadquery_lattice.py": [
        "block_skin.stl",
        "block_lattice.3mf",
        "block_graph.json",
        "plate_lattice.step",
    ],
    "build123d_lattice.py": ["ring_lattice.stl", "ring_lattice.3mf"],
}


def test_examples_exist():
    names = {s.name for s in SCRIPTS}
    assert {"make_example_part.py", "cadquery_lattice.py", "build123d_lattice.py"} <= names
    assert (EXAMPLES / "bracket.step").stat().st_size < 200_000


def _args(script: Path, tmp_path: Path) -> list[str]:
    """The output argument the script's docstring advertises (``Run: ... [OUT.stl]``).

    ``[OUT_DIR]`` gets the temp directory, ``[OUT.xxx]`` gets ``out.xxx`` inside it.
    """
    m = re.search(r"\[(OUT[^\]]*)\]", script.read_text(encoding="utf-8"))
    if m is None:
        return []
    name = m.group(1).split()[0]
    if "." in name:
        return [str(tmp_path / ("out" + name[name.index(".") :].lower()))]
    return [str(tmp_path)]


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=[s.name for s in SCRIPTS])
def test_example_runs(script, tmp_path):
    args = _args(script, tmp_path)
    r = subprocess.run(
        [sys.executable, str(script), *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    expected = list(OUTPUTS.get(script.name, []))
    expected += [Path(a).name for a in args if Path(a) != tmp_path]
    for name in expected:
        assert (tmp_path / name).stat().st_size > 0, name


@pytest.mark.slow
def test_shipped_bracket_is_what_the_script_makes(tmp_path):
    """examples/bracket.step is up to date: same volume as a fresh build."""
    from conformal.part import load_part

    r = subprocess.run(
        [sys.executable, str(EXAMPLES / "make_example_part.py"), str(tmp_path / "b.step")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    fresh = load_part(tmp_path / "b.step")
    shipped = load_part(EXAMPLES / "bracket.step")
    assert shipped.volume == pytest.approx(fresh.volume, rel=1e-6)
