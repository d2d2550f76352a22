"""Argument checks shared by the engines (segments, seed, workers, progress).

Each check raises ``TypeError`` or ``ValueError`` naming the argument and the value given,
and returns the value coerced to the type the kernels need.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "ProgressCallback",
    "Progress",
    "check_positive",
    "check_segments",
    "check_seed",
    "check_workers",
]

#: ``callback(stage, done, total)``: called as long operations advance.
ProgressCallback = Callable[[str, int, int], Any]


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def check_positive(name: str, value: Any) -> float:
    """``value`` as a finite positive float; a TypeError or ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(float(value)) and float(value) > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def check_segments(segments: Any) -> int:
    """Polygon segments per strut: an integer >= 3."""
    if not _is_int(segments):
        raise TypeError(f"segments must be an integer >= 3, got {segments!r}")
    if segments < 3:
        raise ValueError(f"segments must be >= 3, got {segments}")
    return int(segments)


def check_seed(seed: Any) -> int:
    """Random seed: a non-negative integer."""
    if not _is_int(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def check_workers(workers: Any, *, minimum: int = 1) -> int | None:
    """Worker (thread or process) count: None (all cores) or an integer >= ``minimum``."""
    if workers is None:
        return None
    if not _is_int(workers):
        raise TypeError(f"workers must be an integer or None, got {workers!r}")
    if workers < minimum:
        raise ValueError(f"workers must be >= {minimum}, got {workers}")
    return int(workers)


class Progress:
    """Progress reporting: a user callback, a tqdm bar (``progress=True``), or nothing.

    ``Progress(progress, total, desc=..., unit=...)(stage, done, total)`` forwards to the
    callback and moves the bar; :meth:`close` closes the bar.
    """

    def __init__(
        self,
        progress: bool | ProgressCallback | None,
        total: int,
        *,
        desc: str = "lattice-cad",
        unit: str = "it",
    ) -> None:
        self._cb: ProgressCallback | None = None
        self._bar: Any = None
        self._desc = desc
        if callable(progress):
            self._cb = progress
        elif progress:
            from tqdm.auto import tqdm

            self._bar = tqdm(total=total, desc=desc, unit=unit, leave=False)

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self._cb is not None:
            self._cb(stage, done, total)
        if self._bar is not None:
            self._bar.set_description(f"{self._desc}: {stage}")
            self._bar.n = done
            self._bar.total = total
            self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
