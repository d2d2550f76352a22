"""run_isolated: a crash or a hang of a C++ library in a child is an ExternalCrash here."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from lattice_cad.core.errors import ExternalCrash
from lattice_cad.core.isolate import IsolatedWorker, run_isolated


def test_result_comes_back():
    assert run_isolated(divmod, 17, 5, timeout=60, what="divmod") == (3, 2)


def test_exceptions_are_reraised():
    with pytest.raises(ZeroDivisionError):
        run_isolated(divmod, 1, 0, timeout=60, what="divmod")


def test_a_crash_is_an_external_crash():
    with pytest.raises(ExternalCrash, match="abort crashed"):
        run_isolated(os.abort, timeout=60, what="abort")


def test_a_crash_names_the_signal_or_the_exit_code():
    """gmsh's crash on a NACA wing (made outside shared/data) was a glibc abort, "double
    free or corruption"; the message said only that the child had died."""
    died = r"crashed \(the child process died of {}\)"
    with pytest.raises(ExternalCrash, match="abort " + died.format("SIGABRT")):
        run_isolated(os.abort, timeout=60, what="abort")
    with pytest.raises(ExternalCrash, match=r"exit crashed \(the child process exited with code 3"):
        run_isolated(os._exit, 3, timeout=60, what="exit")
    worker = IsolatedWorker()
    worker.submit(_segfault)
    with pytest.raises(ExternalCrash, match="segv " + died.format("SIGSEGV")):
        worker.result(timeout=60, what="segv")


def _segfault() -> None:
    import ctypes

    ctypes.string_at(0)


def test_a_hang_is_killed():
    t0 = time.perf_counter()
    with pytest.raises(ExternalCrash, match="sleep did not finish within 1 s"):
        run_isolated(time.sleep, 30, timeout=1.0, what="sleep")
    assert time.perf_counter() - t0 < 15


#: A parent that starts a worker on a long call, says the worker's pid, then dies as a
#: segmentation fault kills it (SIGKILL: no clean-up of its own runs).
_DYING_PARENT = """
import os, signal, sys, time
from lattice_cad.core.isolate import IsolatedWorker

if __name__ == "__main__":
    w = IsolatedWorker()
    w.submit(time.sleep, 120)
    pids = set()
    for _ in range(600):
        pids = {p.pid for p in w._pool._processes.values()} if w._pool._processes else set()
        if pids:
            break
        time.sleep(0.05)
    print(" ".join(map(str, pids)), flush=True)
    time.sleep(1.0)  # the worker is in its call
    os.kill(os.getpid(), signal.SIGKILL)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl is Linux's")
def test_a_worker_dies_with_its_parent(tmp_path):
    """Found on a trefoil knot (session 33): the fill died of a segmentation fault, and the
    child computing OCCT's offsets ran on at full CPU for minutes, holding the command's
    output pipes open (a benchmark waited 400 s for it)."""
    script = tmp_path / "dying_parent.py"
    script.write_text(_DYING_PARENT)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert run.returncode == -signal.SIGKILL, run.stderr
    pids = [int(p) for p in run.stdout.split()]
    assert pids, run.stdout + run.stderr
    deadline = time.monotonic() + 20
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(p) for p in pids), f"worker(s) {pids} outlived their parent"
