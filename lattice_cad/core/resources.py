"""Memory and disk checks before heavy work (standard library only).

Every stage that allocates in proportion to the lattice (the graph builders, the stitcher,
the writers) first asks :func:`require_memory` for its estimated peak, and every writer asks
:func:`require_disk` for the file's estimated size, so a lattice too large for the machine
is refused at once with an :class:`InsufficientMemoryError` (or :class:`OutputError`) that
says how much is needed, how much there is, and what to do, instead of dying half way in a
numpy ``MemoryError`` or leaving a full disk.

Available memory is the smallest of: the kernel's ``MemAvailable`` (``/proc/meminfo``; on
other systems psutil's ``virtual_memory().available`` when psutil is installed), the cgroup
limit minus the cgroup's usage (containers), and the address-space limit
(``ulimit -v``) minus the process's current size. ``config.MEMORY_LIMIT`` (or the
environment variable ``LATTICE_CAD_MEMORY_LIMIT``, in bytes or with a K/M/G/T suffix)
caps it further.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from lattice_cad.core import config
from lattice_cad.core.errors import InsufficientMemoryError, OutputError

__all__ = ["available_memory", "require_memory", "require_disk", "format_bytes"]

_UNITS = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}


def format_bytes(n: float) -> str:
    """``1.5 GiB``-style size."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} TiB"  # pragma: no cover


def _parse_bytes(text: str) -> int | None:
    t = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = t[-1:] if t[-1:] in _UNITS and t[-1:] else ""
    try:
        value = float(t[: len(t) - len(unit)] if unit else t)
    except ValueError:
        return None
    return int(value * _UNITS[unit]) if value >= 0 else None


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:  # other systems: psutil when it is installed
        import psutil

        return int(psutil.virtual_memory().available)
    except Exception:  # noqa: BLE001 - psutil missing or unsupported here
        return None


def _cgroup_available() -> int | None:
    for limit_file, usage_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),  # cgroup v2
        (
            "/sys/fs/cgroup/memory/memory.limit_in_bytes",  # cgroup v1
            "/sys/fs/cgroup/memory/memory.usage_in_bytes",
        ),
    ):
        try:
            limit = Path(limit_file).read_text().strip()
            usage = int(Path(usage_file).read_text().strip())
        except (OSError, ValueError):
            continue
        if limit == "max" or not limit.isdigit() or int(limit) >= 1 << 60:
            return None
        return max(0, int(limit) - usage)
    return None


def _rlimit_available() -> int | None:
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    size = 0
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    size = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    return max(0, soft - size)


def available_memory() -> int | None:
    """Bytes this process can still allocate (see the module docstring), None if unknown."""
    values = [v for v in (_meminfo_available(), _cgroup_available(), _rlimit_available()) if
              v is not None]  # fmt: skip
    cap = config.MEMORY_LIMIT
    env = os.environ.get("LATTICE_CAD_MEMORY_LIMIT")
    if env:
        parsed = _parse_bytes(env)
        if parsed is not None:
            cap = parsed if cap is None else min(cap, parsed)
    if cap is not None:
        values.append(int(cap))
    return min(values) if values else None


def require_memory(needed: int, what: str, *, advice: str = "") -> None:
    """Raise :class:`InsufficientMemoryError` if ``needed`` bytes exceed what is available.

    Parameters
    ----------
    needed : int
        Estimated peak bytes of the operation.
    what : str
        The operation and its size, e.g. ``"stitching 10,000,000 struts (268,000,000
        triangles)"``.
    advice : str
        What the user can do instead (fewer cells, beam-lattice 3MF, ...).
    """
    avail = available_memory()
    if avail is None:
        return
    usable = int(avail * config.MEMORY_FRACTION)
    if needed > usable:
        msg = (
            f"{what} needs about {format_bytes(needed)} of memory, but only "
            f"{format_bytes(avail)} is available"
        )
        if usable < avail:
            msg += f" (at most {config.MEMORY_FRACTION:.0%} of it is used)"
        raise InsufficientMemoryError(msg + (f"; {advice}" if advice else ""))


def require_disk(path: str | os.PathLike[str], nbytes: int, *, temp_copies: int = 1) -> None:
    """Raise :class:`OutputError` if the disk holding ``path`` cannot take ``nbytes``.

    ``temp_copies`` counts the copies that exist at once while writing (2 when a library
    writes a temp file that is then copied into the atomic temp file).
    """
    p = Path(path)
    directory = p.parent if str(p.parent) else Path(".")
    try:
        free = shutil.disk_usage(directory).free
    except OSError:
        return  # the writer itself names a missing directory
    need = int(nbytes) * max(1, temp_copies)
    if need > free:
        raise OutputError(
            f"cannot write {p}: the file needs about {format_bytes(need)} of disk space while "
            f"writing, but {directory} has only {format_bytes(free)} free"
        )
