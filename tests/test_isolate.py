"""run_isolated: a crash or a hang of a C++ library in a child is an ExternalCrash here."""

from __future__ import annotations

import os
import time

import pytest

from lattice_cad.core.errors import ExternalCrash
from lattice_cad.core.isolate import run_isolated


def test_result_comes_back():
    assert run_isolated(divmod, 17, 5, timeout=60, what="divmod") == (3, 2)


def test_exceptions_are_reraised():
    with pytest.raises(ZeroDivisionError):
        run_isolated(divmod, 1, 0, timeout=60, what="divmod")


def test_a_crash_is_an_external_crash():
    with pytest.raises(ExternalCrash, match="abort crashed"):
        run_isolated(os.abort, timeout=60, what="abort")


def test_a_hang_is_killed():
    t0 = time.perf_counter()
    with pytest.raises(ExternalCrash, match="sleep did not finish within 1 s"):
        run_isolated(time.sleep, 30, timeout=1.0, what="sleep")
    assert time.perf_counter() - t0 < 15
