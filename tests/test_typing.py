"""mypy on the public API ([tool.mypy] in pyproject.toml): it must start and pass.

Before, ``mypy`` stopped at once: ``files`` named lattice_cad/graph.py and errors.py,
which had moved to lattice_cad/core/.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]


def _mypy_files() -> list[str]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]["files"]


def test_mypy_files_exist():
    files = _mypy_files()
    assert files
    missing = [f for f in files if not (ROOT / f).exists()]
    assert not missing, f"[tool.mypy] files names paths that do not exist: {missing}"


def test_mypy_covers_the_public_packages():
    assert {"lattice_cad", "fast_stitch", "conformal", "reference_boolean"} <= {
        f.rstrip("/") for f in _mypy_files()
    }


@pytest.mark.slow
def test_mypy_passes():  # mypy is in the test extras: a missing mypy is a failure
    run = subprocess.run(
        [sys.executable, "-m", "mypy"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
