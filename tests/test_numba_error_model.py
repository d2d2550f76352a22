"""Every compiled helper that runs inside a ``prange`` loop uses numba's "numpy" error model.

Under numba's default "python" error model a division by zero raises ZeroDivisionError.
Raised in a helper called from a ``prange`` loop (not inlined), it does not reach the
caller: the worker thread stops its chunk and the kernel returns with the rest of that
chunk unwritten (found in ``conformal._kernels.soups_within``, session 9: the result was
silently False there). The loop body itself and ``inline='always'`` helpers are compiled
into the parallel region and follow its semantics (inf / nan), so only called helpers can
hit this; and only a division (or a ``raise``) raises there. This test reads the kernel
modules and asserts the rule for all of them.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("conformal", "fast_stitch", "lattice_cad", "reference_boolean")


def _compiled_functions() -> dict[str, list[tuple[str, ast.FunctionDef, str]]]:
    """name -> [(file, def, decorator source)] of every numba-compiled module function."""
    found: dict[str, list[tuple[str, ast.FunctionDef, str]]] = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            source = path.read_text(encoding="utf-8")
            if "numba" not in source:
                continue
            for node in ast.parse(source).body:
                if not isinstance(node, ast.FunctionDef):
                    continue
                decorators = [ast.unparse(d) for d in node.decorator_list]
                jit = [d for d in decorators if "jit" in d]
                if jit:
                    rel = str(path.relative_to(ROOT))
                    found.setdefault(node.name, []).append((rel, node, jit[0]))
    return found


def _called(node: ast.AST) -> set[str]:
    names = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Call):
            if isinstance(n.func, ast.Name):
                names.add(n.func.id)
            elif isinstance(n.func, ast.Attribute):
                names.add(n.func.attr)
    return names


def _divides_or_raises(fdef: ast.FunctionDef) -> bool:
    """The function has a ``/``, ``//`` or ``%`` (a ZeroDivisionError under the python
    error model) or a ``raise``."""
    for n in ast.walk(fdef):
        if isinstance(n, (ast.BinOp, ast.AugAssign)) and isinstance(
            n.op, (ast.Div, ast.FloorDiv, ast.Mod)
        ):
            return True
        if isinstance(n, ast.Raise):
            return True
    return False


def test_helpers_called_in_prange_loops_use_the_numpy_error_model() -> None:
    functions = _compiled_functions()
    assert len(functions) > 50  # the scan found the kernel modules
    offenders = set()
    n_loops = 0
    for entries in functions.values():
        for _, fdef, _ in entries:
            for loop in ast.walk(fdef):
                if not (isinstance(loop, ast.For) and "prange" in ast.unparse(loop.iter)):
                    continue
                n_loops += 1
                stack, seen = list(_called(loop)), set()
                while stack:
                    name = stack.pop()
                    if name in seen or name not in functions:
                        continue
                    seen.add(name)
                    for rel, helper, decorator in functions[name]:
                        inlined = "inline='always'" in decorator or 'inline="always"' in decorator
                        numpy_model = "error_model='numpy'" in decorator or (
                            'error_model="numpy"' in decorator
                        )
                        if not inlined and not numpy_model and _divides_or_raises(helper):
                            offenders.add(f"{rel}:{helper.lineno} {name} (from {fdef.name})")
                        stack.extend(_called(helper))
    assert n_loops > 20
    assert not offenders, "\n".join(sorted(offenders))
