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

__all__ = ["run_isolated", "IsolatedWorker"]

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


def _import(module: str) -> None:
    """Import ``module`` in the child (warms it up for the calls that follow)."""
    import importlib

    importlib.import_module(module)


class IsolatedWorker:
    """A child process started now, for calls whose results are needed later.

    :func:`run_isolated` starts its child when it is called and waits; a worker is started
    ahead of time (``warm`` imports a module in it meanwhile, e.g. OpenCascade's bindings),
    so the child's start-up and the call overlap with the caller's own work. Results
    come back with :meth:`result`; :meth:`close` (also on garbage collection) kills the
    child.

    Parameters
    ----------
    warm : str, optional
        A module the child imports at once.
    """

    def __init__(self, *, warm: str | None = None) -> None:
        import weakref

        method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        self._pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            max_workers=1, mp_context=mp.get_context(method)
        )
        self._future: Any = None
        self._finalizer = weakref.finalize(self, _shutdown, self._pool)
        if warm is not None:
            self._pool.submit(_import, warm)

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        """Start ``fn(*args)`` in the child (after the warm-up); one call per worker."""
        if self._pool is None or self._future is not None:
            raise RuntimeError("an IsolatedWorker runs one call")
        self._future = self._pool.submit(fn, *args)

    @property
    def submitted(self) -> bool:
        return self._future is not None

    @property
    def running(self) -> bool:
        """A call was submitted and has not finished yet (its result is not in)."""
        return self._future is not None and self._pool is not None and not self._future.done()

    def result(self, *, timeout: float, what: str) -> Any:
        """The call's result (its exception re-raised), then the child is ended.

        Raises
        ------
        ExternalCrash
            As :func:`run_isolated`.
        """
        if self._future is None:
            raise RuntimeError("nothing was submitted to this IsolatedWorker")
        try:
            return self._future.result(timeout=timeout)
        except FutureTimeout:
            raise ExternalCrash(f"{what} did not finish within {timeout:g} s") from None
        except BrokenProcessPool:
            raise ExternalCrash(f"{what} crashed (the child process died)") from None
        finally:
            self.close()

    def close(self) -> None:
        """Kill the child (idempotent)."""
        self._finalizer()
        self._pool = None


def _shutdown(pool: ProcessPoolExecutor) -> None:
    for proc in list(getattr(pool, "_processes", {}).values()):
        proc.kill()
    pool.shutdown(wait=False, cancel_futures=True)
