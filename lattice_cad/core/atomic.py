"""Atomic file writing: a temp file beside the target, then ``os.replace``.

Nothing half-written is ever left at the target path: if the writer raises
(including ``KeyboardInterrupt``), the temp file is removed and any existing
file at the target is untouched. Failures of the file system (no such directory,
a directory in the way, no permission, a full disk) raise :class:`OutputError`
naming the target, never the temp file.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Literal

from lattice_cad.core.errors import OutputError

__all__ = ["atomic_write", "check_target", "output_error"]


def output_error(target: Path, exc: OSError) -> OutputError:
    """An :class:`OutputError` for ``target`` from an OS error about it or its temp file."""
    why = exc.strerror or str(exc)
    if isinstance(exc, IsADirectoryError) or target.is_dir():
        why = "it is a directory"
    elif isinstance(exc, PermissionError):
        why = f"permission denied ({why})"
    return OutputError(f"cannot write {target}: {why}")


def check_target(path: str | os.PathLike[str]) -> Path:
    """The target as a Path, after refusing a missing directory or a directory in the way."""
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise OutputError(f"cannot write {target}: directory {directory} does not exist")
    if target.is_dir():
        raise OutputError(f"cannot write {target}: it is a directory")
    return target


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: Literal["wb", "w"] = "wb") -> Iterator[IO]:
    """Open a temp file for writing; on success rename it onto ``path``.

    Parameters
    ----------
    path : path-like
        Destination. Its directory must exist.
    mode : {"wb", "w"}
        Binary or text mode (text is UTF-8).

    Raises
    ------
    OutputError
        The directory does not exist, the target is a directory, or the file system
        refuses the write (permissions, disk full); the message names ``path``.
    """
    target = check_target(path)
    directory = target.parent if str(target.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=directory)
    except OSError as exc:
        raise output_error(target, exc) from None
    try:
        encoding = None if "b" in mode else "utf-8"
        try:
            fh = os.fdopen(fd, mode, encoding=encoding)
        except OSError as exc:  # pragma: no cover - fdopen of a fresh fd
            os.close(fd)
            raise output_error(target, exc) from None
        with fh:
            try:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
            except OSError as exc:
                if isinstance(exc, OutputError):
                    raise
                raise output_error(target, exc) from None
        umask = os.umask(0)
        os.umask(umask)
        try:
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600 files; honour the umask instead
            os.replace(tmp, target)
        except OSError as exc:
            raise output_error(target, exc) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
