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

from lattice_cad.core.errors import ExternalCrash, ExternalTimeout

__all__ = ["run_isolated", "IsolatedWorker", "die_with_parent"]

#: Linux's ``prctl`` option that sends the calling process a signal when its parent ends.
_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """In a child process (a pool's ``initializer``): be killed when its parent ends.

    A child computing OpenCascade's offsets kept running, at full CPU, for minutes after
    the process that started it died of a segmentation fault (a trefoil knot made outside
    shared/data), and held the pipes of the command's output open: whoever ran the
    command waited for it. On Linux the child asks the kernel for ``SIGKILL`` when its
    parent exits (``prctl(PR_SET_PDEATHSIG)``); elsewhere nothing.

    The parent of a fork server's child is the fork server, which exits when no process
    holds its "alive" pipe any more; each child gets a copy of that pipe's write end
    (``multiprocessing.forkserver``), which kept the fork server, and so the child, alive
    after the process that asked for the child died. The child closes its copy here: the
    fork server then ends with that process, and the kernel ends the child.
    """
    import os
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return
    import ctypes
    from multiprocessing import forkserver

    server = getattr(forkserver, "_forkserver", None)
    alive = getattr(server, "_forkserver_alive_fd", None)
    if isinstance(alive, int) and mp.parent_process() is not None:
        try:
            os.close(alive)
        except OSError:  # pragma: no cover - already closed
            pass
        server._forkserver_alive_fd = None  # type: ignore[union-attr]

    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - no prctl in this libc
        return
    if os.getppid() != parent:  # the parent ended before the request: end now
        os._exit(1)


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
    pool = ProcessPoolExecutor(max_workers=1, mp_context=ctx, initializer=die_with_parent)
    try:
        future = pool.submit(fn, *args)
        try:
            return future.result(timeout=timeout)
        except FutureTimeout:
            raise ExternalTimeout(f"{what} did not finish within {timeout:g} s") from None
        except BrokenProcessPool:
            raise ExternalCrash(f"{what} crashed ({_death(pool)})") from None
    finally:
        kill_pool(pool, wait=False)


def _death(pool: ProcessPoolExecutor) -> str:
    """How the pool's child ended, for a crash's message: "the child process died of
    SIGSEGV" (a signal), "... exited with code 3", or "the child process died" when its
    exit status is unknown. gmsh's crashes on a NACA wing (made outside shared/data) were
    a glibc abort ("double free or corruption"), which its message did not say."""
    import signal

    codes: list[int] = []
    for p in list((getattr(pool, "_processes", None) or {}).values()):
        if p.exitcode is None:  # the fork server reports the status a moment after
            p.join(timeout=2.0)
        if p.exitcode is not None:
            codes.append(p.exitcode)
    if not codes or codes[0] == 0:
        return "the child process died"
    code = codes[0]
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"the child process died of {name}"
    return f"the child process exited with code {code}"


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
            max_workers=1, mp_context=mp.get_context(method), initializer=die_with_parent
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
            raise ExternalTimeout(f"{what} did not finish within {timeout:g} s") from None
        except BrokenProcessPool:
            raise ExternalCrash(
                f"{what} crashed ({_death(self._pool) if self._pool else 'the child process died'})"
            ) from None
        finally:
            self.close()

    def close(self) -> None:
        """Kill the child (idempotent)."""
        self._finalizer()
        self._pool = None


def _shutdown(pool: ProcessPoolExecutor) -> None:
    kill_pool(pool, wait=False)


def kill_pool(pool: ProcessPoolExecutor, *, wait: bool) -> None:
    """Kill the pool's worker processes, then shut the pool down (``wait``: join its
    threads and the workers).

    ``concurrent.futures`` offers no way to stop a running task, so the workers are killed;
    two of the pool's threads could then wait for good (each seen in CI as a 600 s hang of
    ``tests/test_hubspeed.py::test_ctrl_c_stops_the_workers``; ``shutdown(wait=True)`` joins
    them, and without it the interpreter joins them at exit):

    - the call queue's feeder thread, blocked writing tasks to a pipe no worker reads any
      more (CPython gh-94777): it is not joined (``cancel_join_thread``);
    - the manager thread, in ``recv()`` of a result a worker was killed while writing: this
      process holds the result pipe's other writing end (only this thread touches it);
      closed, and the workers dead, the read ends (EOF) and the thread finds the pool
      broken. 400 interrupts of the reference's hub build (``/tmp/ctrlc_loop.py``): a hang
      within the first 50 before (twice), none after.
    """
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        if p.is_alive():
            p.kill()
    # the call queue's pipes are the manager thread's to close (terminate_broken closes its
    # reader): closed here too, the two closes race, and a descriptor number closed twice
    # may by then belong to another pool's pipe (a later isolated call "crashed" in CI).
    # Not joining its feeder is enough: a daemon thread, it cannot hold up the exit.
    queue = getattr(pool, "_call_queue", None)
    if queue is not None:
        queue.cancel_join_thread()
    writer = getattr(getattr(pool, "_result_queue", None), "_writer", None)
    if writer is not None:
        writer.close()
    pool.shutdown(wait=wait, cancel_futures=True)
    if wait:
        for p in procs:
            p.join(timeout=10.0)
