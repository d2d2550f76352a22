"""Keep OpenCascade's console messages off stdout, and hand them to the caller instead.

OCCT's STEP reader prints banners such as ``**** ERR StepFile : ...`` straight to the C-level
standard output (file descriptor 1), past Python's ``sys.stdout``. :func:`c_stdout_captured`
points descriptor 1 at a temp file for the duration of a call and returns the messages
(ANSI colours and the ``****`` frames removed), so they can become the text of an error.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator

__all__ = ["c_stdout_captured", "clean_messages"]

_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
_LOCK = threading.Lock()


def _flush_c_stdio() -> None:
    with contextlib.suppress(Exception):
        ctypes.CDLL(None).fflush(None)


def clean_messages(text: str) -> list[str]:
    """The non-empty lines of ``text`` without colour codes and ``****`` frames."""
    out = []
    for line in _ANSI.sub("", text).splitlines():
        line = line.strip().strip("*").strip()
        if line:
            out.append(" ".join(line.split()))
    return out


@contextlib.contextmanager
def c_stdout_captured() -> Iterator[list[str]]:
    """Capture what C/C++ code writes to file descriptor 1 inside the block.

    Yields a list that is filled with the captured message lines when the block ends
    (also when it raises). Process-wide (descriptor 1 is shared), so calls are serialised.
    """
    lines: list[str] = []
    with _LOCK:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        _flush_c_stdio()
        try:
            saved = os.dup(1)
        except OSError:  # no descriptor 1 at all: nothing can reach a terminal
            yield lines
            return
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 1)
            try:
                yield lines
            finally:
                _flush_c_stdio()
                os.dup2(saved, 1)
                os.close(saved)
                tmp.seek(0)
                lines.extend(clean_messages(tmp.read().decode("utf-8", errors="replace")))
