"""Is the installed CAD stack the supported one? (standard library only, no OCP import).

cadquery and build123d both sit on ``OCP``, the Python binding of OpenCascade. Two
distributions on PyPI install a package named ``OCP`` (``cadquery-ocp`` and
``cadquery-ocp-novtk``); with both installed, one silently overwrites the other's files and
OCCT can misbehave (``import build123d`` fails, STEP units are converted twice). pip does
not notice. :func:`problems` finds such states from the installed metadata, and
:func:`warn_once` tells the user once, with the command that fixes it, before OCP is
imported for the first time.
"""

from __future__ import annotations

import importlib.metadata as md
import re
import warnings

from lattice_cad.core.errors import CADStackWarning

__all__ = ["SUPPORTED", "FIX", "ocp_distributions", "problems", "warn_once", "CADStackWarning"]

#: Supported versions: distribution -> (lowest, first unsupported). Keep in step with
#: ``pyproject.toml`` (a test checks that they agree).
SUPPORTED: dict[str, tuple[str, str]] = {
    "cadquery": ("2.7", "2.8"),
    "build123d": ("0.10", "0.11"),
    "cadquery-ocp": ("7.8.1", "7.9"),
}

#: The command that installs the supported stack into the current environment.
FIX = (
    "pip uninstall -y cadquery-ocp-novtk cadquery-ocp-proxy; "
    "pip install 'cadquery>=2.7,<2.8' 'build123d>=0.10,<0.11' 'ocp_gordon>=0.1.17,<0.2'; "
    "pip install --force-reinstall --no-deps 'cadquery-ocp>=7.8.1,<7.9'"
)


def _version_tuple(v: str) -> tuple[int, ...]:
    out = []
    for part in v.split("."):
        m = re.match(r"\d+", part)
        if not m:
            break
        out.append(int(m.group()))
    return tuple(out)


def ocp_distributions() -> list[str]:
    """Names of the installed distributions that provide the top-level package ``OCP``."""
    names = []
    for dist in md.distributions():
        top = dist.read_text("top_level.txt")
        if top is not None:
            provides = "OCP" in top.split()
        else:  # the RECORD's text searched: its parse (``dist.files``) took 0.1-0.2 s in all
            provides = re.search(r"^OCP/", dist.read_text("RECORD") or "", re.M) is not None
        if provides:
            names.append(dist.metadata["Name"])
    return sorted(set(names))


def problems() -> list[str]:
    """What is wrong with the installed CAD stack; empty when it is the supported one."""
    out = []
    ocp = ocp_distributions()
    if len(ocp) > 1:
        out.append(
            f"{len(ocp)} distributions install the same 'OCP' package ({', '.join(ocp)}); "
            "their files overwrite each other"
        )
    for name, (lo, hi) in SUPPORTED.items():
        try:
            v = md.version(name)
        except md.PackageNotFoundError:
            out.append(f"{name} is not installed")
            continue
        if not (_version_tuple(lo) <= _version_tuple(v) < _version_tuple(hi)):
            out.append(f"{name} {v} is installed; lattice-cad supports {name} >={lo},<{hi}")
    return out


_warned = False


def warn_once() -> None:
    """Warn (once per process) when :func:`problems` finds anything."""
    global _warned
    if _warned:
        return
    _warned = True
    found = problems()
    if found:
        warnings.warn(
            "unsupported CAD stack: " + "; ".join(found) + f". Fix it with: {FIX}",
            CADStackWarning,
            stacklevel=3,
        )
