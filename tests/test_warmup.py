"""lattice_cad.warmup: the kernels compiled ahead of the first real run."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from lattice_cad import cli
from lattice_cad.warmup import TASKS, warmup


def test_unknown_task_and_bad_jobs_are_refused():
    with pytest.raises(ValueError, match="unknown warm-up task"):
        warmup(tasks=["nope"])
    with pytest.raises(ValueError, match="jobs must be at least 1"):
        warmup(tasks=["clip"], jobs=0)


def test_warmup_command_runs_a_task_through_the_cli(capsys):
    rc = cli.main(["warmup", "--tasks", "clip", "--jobs", "1"])
    out = capsys.readouterr().out
    assert rc == 0, out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("clip"))
    assert " ok " in line and "compiled" in line and "loaded from the cache" in line
    assert "kernel signature(s) compiled in" in out


def test_every_task_names_a_part_and_a_command():
    commands = {"fill", "check", "preview", "validate"}
    for name, lines in TASKS.items():
        assert lines, name
        for argv in lines:
            assert argv[0] in commands, (name, argv)
            assert any(a in ("PART", "MESH") or a.startswith("OUT") for a in argv), (name, argv)
        # every file a later line reads was written by an earlier one
        written = {a for argv in lines for a in argv if a.startswith("OUT")}
        assert written, name


def test_kernels_cached_is_false_for_an_empty_numba_cache(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    code = "from lattice_cad.warmup import kernels_cached; print(kernels_cached())"
    got = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert got.stdout.strip() == "False"
    # and True once the stitcher has built a hub in this session's cache
    import numpy as np

    import fast_stitch
    from lattice_cad import LatticeGraph
    from lattice_cad.warmup import kernels_cached

    nodes = np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    g = LatticeGraph(nodes=nodes, edges=np.array([[0, 1], [0, 2], [0, 3]]), radii=0.1)
    fast_stitch.stitch(g)
    assert kernels_cached()


def test_first_run_note_only_on_a_cold_cache(monkeypatch, capsys):
    import lattice_cad.warmup as w

    monkeypatch.setattr(w, "kernels_cached", lambda: False)
    cli._first_run_note(cli._Console(False))
    assert "first run on this install" in capsys.readouterr().out
    cli._first_run_note(cli._Console(True))  # --quiet
    assert capsys.readouterr().out == ""
    monkeypatch.setattr(w, "kernels_cached", lambda: True)
    cli._first_run_note(cli._Console(False))
    assert capsys.readouterr().out == ""
