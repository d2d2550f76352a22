"""The checker shares only :mod:`fast_stitch._predicates` with the stitchers.

``fast_stitch.check`` is used to test the stitchers, so the code it shares with
them is kept to the predicates (see the docstring of ``fast_stitch._predicates``).
A bug there could hide in both; the independent checkers of ``conftest.py``
(trimesh, manifold3d, pymeshlab) guard against that. These tests keep the
sharing from growing unnoticed.
"""

from __future__ import annotations

import ast
import importlib

import pytest

from tests.conftest import ROOT

STITCHER = ["_kernels", "_lslt_kernels", "stitch", "lslt"]
CHECKER = ["check", "_check_kernels"]


def _fast_stitch_imports(module: str) -> set[str]:
    """Modules of the fast_stitch package that ``fast_stitch/<module>.py`` imports."""
    tree = ast.parse((ROOT / "fast_stitch" / f"{module}.py").read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("fast_stitch."))
        elif isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "fast_stitch":  # from fast_stitch import _k
                out.update(f"fast_stitch.{a.name}" for a in node.names)
            elif node.module.startswith("fast_stitch."):
                out.add(node.module)
    return out


@pytest.mark.parametrize("module", STITCHER)
def test_stitchers_do_not_import_the_checker(module):
    forbidden = {f"fast_stitch.{m}" for m in CHECKER}
    assert not _fast_stitch_imports(module) & forbidden


@pytest.mark.parametrize("module", CHECKER)
def test_checker_does_not_import_the_stitchers(module):
    forbidden = {f"fast_stitch.{m}" for m in STITCHER}
    assert not _fast_stitch_imports(module) & forbidden


def test_both_use_the_one_shared_predicate():
    from fast_stitch import _check_kernels, _kernels, _lslt_kernels, _predicates

    # (fast_stitch.check and fast_stitch.stitch are also the names of the functions)
    check_module = importlib.import_module("fast_stitch.check")
    stitch_module = importlib.import_module("fast_stitch.stitch")
    assert _kernels.tri_tri is _predicates.tri_tri
    assert _lslt_kernels.tri_tri is _predicates.tri_tri
    assert _check_kernels.tri_tri is _predicates.tri_tri
    assert stitch_module.box_stats is _predicates.box_stats
    assert check_module.box_stats is _predicates.box_stats
