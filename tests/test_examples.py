"""Every script in examples/ runs, in a subprocess, writing into a temp directory."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))
#: Command-line arguments per script (relative paths land in the temp directory).
ARGS = {
    "make_example_part.py": ["bracket.step"],
    "stitch_bcc_block.py": ["bcc_block.stl"],
}
#: Files each script must have written.
OUTPUTS = {
    "make_example_part.py": ["bracket.step"],
    "stitch_bcc_block.py": ["bcc_block.stl"],
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


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=[s.name for s in SCRIPTS])
def test_example_runs(script, tmp_path):
    args = ARGS.get(script.name, [str(tmp_path)])
    r = subprocess.run(
        [sys.executable, str(script), *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    for name in OUTPUTS.get(script.name, []):
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
