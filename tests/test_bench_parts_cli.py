"""``benchmarks/bench_parts.py``'s part folders: a wrong one is named, with what to give.

s34: ``--data DIR`` on a folder holding ``step/`` and ``meshes/`` (the layout of
../shared/data) failed with "no part matches --parts" though ``--parts`` was not given.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_parts.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(BENCH), *args], capture_output=True, text=True, timeout=120
    )


def test_a_folder_of_folders_is_named_with_its_folders(tmp_path):
    (tmp_path / "step").mkdir()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "step" / "a.step").write_text("x")
    done = _run("--data", str(tmp_path))
    assert done.returncode != 0
    assert f"{tmp_path} holds no part files (only the folders meshes, step" in done.stderr
    assert "--parts" not in done.stderr


def test_no_part_matching_parts_says_what_was_asked(tmp_path):
    (tmp_path / "a.step").write_text("x")
    done = _run("--data", str(tmp_path), "--parts", "zzz")
    assert done.returncode != 0
    assert "no part matches --parts zzz" in done.stderr
