"""Run a call in a child process, so that a crash or a hang of a C++ library (OpenCascade's
offsets, gmsh) is an exception the caller can handle, not the end of the user's process.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from lattice_cad.core.errors import ExternalCrash

__all__ = ["run_isolated"]

T = TypeVar("T")


def run_isolated(fn: Callable[..., T], *args: Any, timeout: float, what: str) -> T:
    """``fn(*args)`` in a child process; its result is pickled back.

    ``fn`` must be a module-level function and ``args`` picklable. Children come from a
    fork server (a fresh interpreter, so a child never inherits the OpenMP runtime that
    numba or a library already started here: libgomp refuses to run after ``fork``).

    Raises
    ------
    ExternalCrash
        The child died (e.g. a segmentation fault) or did not finish within ``timeout``
        seconds (it is killed); ``what`` names the operation in the message.
    Exception
        Whatever ``fn`` raised, re-raised here.
    """
    method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
    ctx = mp.get_context(method)
    pool = ProcessPoolExecutor(max_workers=1, mp_context=ctx)
    try:
        future = pool.submit(fn, *args)
        try:
            return future.result(timeout=timeout)
        except FutureTimeout:
            raise ExternalCrash(f"{what} did not finish within {timeout:g} s") from None
        except BrokenProcessPool:
            raise ExternalCrash(f"{what} crashed (the child process died)") from None
    finally:
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.kill()
        pool.shutdown(wait=False, cancel_futures=True)
