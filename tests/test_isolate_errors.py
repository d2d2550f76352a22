"""Exceptions raised in a child of ``run_isolated`` come back as themselves.

gmsh's failures in ``conformal.tet`` (``_GmshFailure(message, stage)``) could not be
unpickled (their ``__init__`` took more than their ``args``): the process pool then said
the child had crashed, so every failure of a tet mesh read "gmsh (...) crashed (the child
process died)" and a failure of the surface was taken for a crash of the 3-D algorithm (the
same failing surface was tried with every algorithm). Found on teapot_closed_rainbow.obj.
"""

from __future__ import annotations

import importlib
import inspect
import pickle
import pkgutil

import pytest

from conformal.tet import _GmshFailure
from lattice_cad.core.isolate import run_isolated


def _our_exceptions() -> list[type[BaseException]]:
    found: dict[str, type[BaseException]] = {}
    for pkg in ("lattice_cad", "conformal", "fast_stitch", "reference_boolean"):
        root = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(root.__path__, pkg + "."):
            mod = importlib.import_module(info.name)
            for obj in vars(mod).values():
                if (
                    inspect.isclass(obj)
                    and issubclass(obj, BaseException)
                    and obj.__module__.split(".")[0] == pkg
                ):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return [found[k] for k in sorted(found)]


EXCEPTIONS = _our_exceptions()


def _example(cls: type[BaseException]) -> BaseException:
    if cls is _GmshFailure:
        return cls("Wrong topology of boundary mesh for parametrization", "surface")
    return cls("what went wrong, at node 7")


def test_the_package_exceptions_are_found():
    names = {c.__name__ for c in EXCEPTIONS}
    assert {"LatticeError", "PartError", "ExternalCrash", "_GmshFailure"} <= names


@pytest.mark.parametrize("cls", EXCEPTIONS, ids=lambda c: c.__name__)
def test_every_exception_survives_pickling(cls):
    exc = _example(cls)
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is cls and str(back) == str(exc)
    assert getattr(back, "stage", None) == getattr(exc, "stage", None)


def _raise_gmsh_failure(stage: str) -> None:
    raise _GmshFailure("HXT 3D mesh failed", stage)


def test_a_gmsh_failure_in_the_child_comes_back_with_its_stage():
    with pytest.raises(_GmshFailure, match="HXT 3D mesh failed") as info:
        run_isolated(_raise_gmsh_failure, "volume", timeout=60, what="gmsh")
    assert info.value.stage == "volume"
