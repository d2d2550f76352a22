"""Run a call in a child process, so that a crash or a hang of a C++ library (OpenCascade's
offsets, gmsh) is an exception the caller can handle, not the end of the user's process.
"""

from __future__ import annotations

import multiprocessing as mp
import sys
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from lattice_cad.core.errors import ExternalCrash

__all__ = ["run_isolated"]

T = TypeVar("T")


_PENDING: tuple[Callable[..., Any], tuple[Any, ...]] | None = None


def _call_pending() -> Any:
    assert _PENDING is not None
    fn, args = _PENDING
    return fn(*args)


def run_isolated(fn: Callable[..., T], *args: Any, timeout: float, what: str) -> T:
    """``fn(*args)`` in a forked child process; its result is pickled back.

    The call is inherited through ``fork`` (the arguments need not be picklable: OCCT
    shapes are not). Where ``fork`` is not available the call runs in this process.

    Raises
    ------
    ExternalCrash
        The child died (e.g. a segmentation fault) or did not finish within ``timeout``
        seconds (it is killed); ``what`` names the operation in the message.
    Exception
        Whatever ``fn`` raised, re-raised here.
    """
    global _PENDING
    if not sys.platform.startswith("linux"):
        return fn(*args)
    ctx = mp.get_context("fork")
    _PENDING = (fn, args)
    pool = ProcessPoolExecutor(max_workers=1, mp_context=ctx)
    try:
        future = pool.submit(_call_pending)
        try:
            return future.result(timeout=timeout)
        except FutureTimeout:
            raise ExternalCrash(f"{what} did not finish within {timeout:g} s") from None
        except BrokenProcessPool:
            raise ExternalCrash(f"{what} crashed (the child process died)") from None
    finally:
        _PENDING = None
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.kill()
        pool.shutdown(wait=False, cancel_futures=True)
