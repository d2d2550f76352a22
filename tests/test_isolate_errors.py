"""Exceptions raised in a child of ``run_isolated`` come back as themselves.

gmsh's failures in ``conformal.tet`` (``_GmshFailure(message, stage)``) could not be
unpickled (their ``__init__`` took more than their ``args``): the process pool then said
the child had crashed, so every failure of a tet mesh read "gmsh (...) crashed (the child
process died)" and a failure of the surface was taken for a crash of the 3-D algorithm (the
same failing surface was tried with every algorithm). Found on teapot_closed_rainbow.obj.
"""

from __future__ import annotations

import pickle

import pytest

from conformal.tet import _GmshFailure
from lattice_cad.core.isolate import run_isolated

_PICKLE_ALL = r"""
import importlib, inspect, pickle, pkgutil, sys
from conformal.tet import _GmshFailure
bad, n = [], 0
for pkg in ("lattice_cad", "conformal", "fast_stitch", "reference_boolean"):
    root = importlib.import_module(pkg)
    for info in pkgutil.walk_packages(root.__path__, pkg + "."):
        mod = importlib.import_module(info.name)
        for obj in vars(mod).values():
            if (inspect.isclass(obj) and issubclass(obj, BaseException)
                    and obj.__module__.split(".")[0] == pkg):
                n += 1
                exc = obj("gmsh failed", "surface") if obj is _GmshFailure else obj("node 7")
                back = pickle.loads(pickle.dumps(exc))
                if type(back) is not obj or str(back) != str(exc):
                    bad.append(obj.__name__)
print(n, bad)
"""


def test_every_exception_of_the_packages_survives_pickling():
    # in a fresh interpreter: a library another test imported (dask's tblib support)
    # changes how exceptions pickle in this one
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-c", _PICKLE_ALL], capture_output=True, text=True, check=True
    ).stdout.split(maxsplit=1)
    assert int(out[0]) >= 30 and out[1].strip() == "[]", out


def test_a_gmsh_failure_survives_pickling():
    exc = _GmshFailure("Wrong topology of boundary mesh for parametrization", "surface")
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is _GmshFailure and str(back) == str(exc) and back.stage == "surface"


def _raise_gmsh_failure(stage: str) -> None:
    raise _GmshFailure("HXT 3D mesh failed", stage)


def test_a_gmsh_failure_in_the_child_comes_back_with_its_stage():
    with pytest.raises(_GmshFailure, match="HXT 3D mesh failed") as info:
        run_isolated(_raise_gmsh_failure, "volume", timeout=60, what="gmsh")
    assert info.value.stage == "volume"
