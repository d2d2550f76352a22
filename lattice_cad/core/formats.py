"""The one table of file formats: which suffix holds what, and which programs read it.

Every save and load in lattice-cad (graphs, meshes, beam lattices, exact solids, parts,
reports) resolves its path here with :func:`format_for`, so a suffix means the same
everywhere and an unsupported one gets the same clear error, naming the file and the
suffixes that would work. The readers and writers themselves live in
:mod:`lattice_cad.io` (and :class:`~lattice_cad.core.graph.LatticeGraph` for its own two
formats).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

__all__ = ["Kind", "Format", "FORMATS", "format_for", "resolve", "suffixes"]


class Kind(str, Enum):
    """What a file holds."""

    MESH = "mesh"
    GRAPH = "graph"
    BEAM_LATTICE = "beam lattice"
    SOLIDS = "exact solids"
    PART = "part"
    REPORT = "report"
    FE_MODEL = "beam FE model"


@dataclass(frozen=True)
class Format:
    """One file format.

    Attributes
    ----------
    name : str
        Short name (``"stl"``), used by the readers and writers to dispatch.
    suffixes : tuple of str
        Lower-case suffixes, the first one canonical.
    writes, reads : frozenset of Kind
        What lattice-cad writes to / reads from this format.
    description : str
        What the file holds.
    opened_by : str
        Which programs open it (for the docs and the CLI's help).
    """

    name: str
    suffixes: tuple[str, ...]
    writes: frozenset[Kind]
    reads: frozenset[Kind]
    description: str
    opened_by: str


def _k(*kinds: Kind) -> frozenset[Kind]:
    return frozenset(kinds)


M, G, B, S, P, R = Kind.MESH, Kind.GRAPH, Kind.BEAM_LATTICE, Kind.SOLIDS, Kind.PART, Kind.REPORT
FE = Kind.FE_MODEL

#: Every format lattice-cad reads or writes.
FORMATS: tuple[Format, ...] = (
    Format("stl", (".stl",), _k(M), _k(M, P), "binary STL triangle mesh (mm)",
           "every slicer (PrusaSlicer, Cura, Bambu Studio), MeshLab, CAD tools"),
    Format("3mf", (".3mf",), _k(M, B), _k(M, B, P),
           "3MF core mesh (mm); or 3MF Beam Lattice: beams with per-end radii and balls, plus "
           "the mesh for other readers (or beams only)",
           "PrusaSlicer, Cura, Bambu Studio, Windows 3D Viewer (not CuraEngine's command "
           "line); beam-only files: beam-aware readers only (lib3mf)"),
    Format("ply", (".ply",), _k(M), _k(M, P), "binary PLY triangle mesh",
           "MeshLab, Blender, trimesh (not PrusaSlicer)"),
    Format("obj", (".obj",), _k(M), _k(M, P), "Wavefront OBJ triangle mesh",
           "PrusaSlicer, Blender, MeshLab (not CuraEngine's command line)"),
    Format("off", (".off",), _k(), _k(M, P), "OFF triangle mesh", "MeshLab, CGAL, trimesh"),
    Format("step", (".step", ".stp"), _k(S), _k(P, S), "STEP AP214 B-rep solids (mm)",
           "every CAD tool (FreeCAD, CadQuery, SolidWorks, Fusion)"),
    Format("json", (".json",), _k(G, R), _k(G), "lattice graph (exact, text) or report data",
           "lattice-cad, any JSON reader"),
    Format("npz", (".npz",), _k(G), _k(G), "lattice graph (exact, compressed numpy)",
           "lattice-cad, numpy"),
    Format("inp", (".inp",), _k(FE), _k(),
           "CalculiX/Abaqus beam model: B32 beams, circular sections per radius, node sets",
           "CalculiX (ccx), Abaqus (dialect='abaqus'), PrePoMax, FreeCAD FEM"),
    Format("md", (".md",), _k(R), _k(), "accuracy report (Markdown)", "any text viewer"),
    Format("html", (".html", ".htm"), _k(R), _k(), "accuracy report (self-contained HTML)",
           "any web browser"),
)  # fmt: skip

_BY_SUFFIX = {s: f for f in FORMATS for s in f.suffixes}


def suffixes(kind: Kind, *, action: str = "write") -> tuple[str, ...]:
    """The suffixes that can ``action`` ("write" or "read") a ``kind``."""
    attr = "writes" if action == "write" else "reads"
    return tuple(s for f in FORMATS if kind in getattr(f, attr) for s in f.suffixes)


def format_for(
    path: str | os.PathLike[str],
    kind: Kind | tuple[Kind, ...],
    *,
    action: str = "write",
    what: str | None = None,
) -> Format:
    """The format of ``path`` for writing (or reading) a ``kind`` (or any of several).

    Raises
    ------
    ValueError
        The suffix is unknown or cannot hold the kind; the message names the file and lists
        the suffixes that can.
    """
    return resolve(path, kind, action=action, what=what)[0]


def resolve(
    path: str | os.PathLike[str],
    kind: Kind | tuple[Kind, ...],
    *,
    action: str = "write",
    what: str | None = None,
) -> tuple[Format, Kind]:
    """Like :func:`format_for`, and which of the ``kind`` s (tried in order) the file holds.

    ``what`` names the object in the error message (default: the kinds).
    """
    kinds = (kind,) if isinstance(kind, Kind) else kind
    p = Path(path)
    suffix = p.suffix.lower()
    fmt = _BY_SUFFIX.get(suffix)
    attr = "writes" if action == "write" else "reads"
    for k in kinds:
        if fmt is not None and k in getattr(fmt, attr):
            return fmt, k
    verb = "save" if action == "write" else "load"
    given = suffix or "a file without suffix"
    names = what or " or ".join(k.value for k in kinds)
    ok = list(dict.fromkeys(s for k in kinds for s in suffixes(k, action=action)))
    raise ValueError(f"cannot {verb} a {names} as {given} ({p.name}): use " + ", ".join(ok))
