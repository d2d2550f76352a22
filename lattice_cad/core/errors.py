"""Every exception and warning lattice-cad raises on purpose, in one hierarchy.

Catch :class:`LatticeError` for any refusal of the product; each subclass also derives from
the built-in exception a Python user would expect (``ValueError`` for bad input,
``RuntimeError`` for a build that failed). The engines re-export the ones they raise (for
example ``conformal.PartError``), but they are defined here only.

::

    LatticeError
    ├── InvalidGraphError        a graph breaks an input rule (names the node or edge)
    ├── StitchError              a valid graph cannot be stitched (fast_stitch)
    ├── FitError                 struts cannot be made to fit (conformal.radius)
    ├── FillError                no lattice fits the part (says what would)
    ├── PartError                a part file or shape cannot be used (conformal.part)
    │   └── StepUnitsError       a STEP file's unit disagrees with OCCT's reading of it
    ├── SkinError                a part cannot be hollowed (conformal.skin)
    ├── EscapeHoleError          a cavity cannot be opened, or stays closed (conformal.escape)
    ├── KeepError                a keep-solid zone cannot be used (conformal.keep)
    ├── SimilarityError          invalid similarity parameters (conformal.similarity)
    ├── SteadyLatticeError       invalid steady-lattice input (conformal.steady)
    ├── PrintabilityError        invalid build direction, angle or diameter (conformal.printability)
    ├── ExportError              a mesh cannot be written faithfully (lattice_cad.io)
    ├── ShardingError            an option the sharded (Dask) path refuses, a halo too small
    ├── DistributedUnavailableError  (ImportError) Dask distributed is not installed
    ├── SelectionError           a selector picks no face or node (names the selector)
    ├── ToleranceError           an accuracy-report tolerance is not a valid number
    ├── OCCTFailure              an OpenCascade step failed (lattice_cad.occ_impl)
    ├── ExternalCrash            a C++ library crashed or hung in a child process
    ├── InsufficientMemoryError  the estimated peak memory exceeds what is available
    ├── OutputError              a file cannot be written (names the target, never a temp)
    ├── InputFileError           a file cannot be read: a directory, empty, truncated, or
    │   │                        not the format its suffix says (names the file)
    │   └── MissingFileError     the file does not exist (also a FileNotFoundError)
    └── ReferenceBuildError      the exact reference cannot be built (reference_boolean)
        └── DirtyLatticeError    hubs would overlap, the stacked reference is not exact

    LatticeWarning               accepted, but deserves the user's attention
    ├── ExportWarning            a file may be too large for common slicers
    ├── BeamOnlyWarning          a beam-only 3MF that most slicers cannot open
    ├── CutBudgetWarning         the cut tessellation is coarser than asked (triangle budget)
    └── CADStackWarning          the installed cadquery/build123d/OCP set is unsupported
"""

from __future__ import annotations

__all__ = [
    "LatticeError",
    "InvalidGraphError",
    "StitchError",
    "FitError",
    "FillError",
    "PartError",
    "StepUnitsError",
    "SkinError",
    "EscapeHoleError",
    "KeepError",
    "SimilarityError",
    "SteadyLatticeError",
    "PrintabilityError",
    "ExportError",
    "SelectionError",
    "ShardingError",
    "DistributedUnavailableError",
    "ToleranceError",
    "OCCTFailure",
    "ExternalCrash",
    "ExternalTimeout",
    "ReferenceBuildError",
    "DirtyLatticeError",
    "InsufficientMemoryError",
    "OutputError",
    "InputFileError",
    "MissingFileError",
    "LatticeWarning",
    "ExportWarning",
    "BeamOnlyWarning",
    "CutBudgetWarning",
    "CADStackWarning",
]


class LatticeError(Exception):
    """Base class of every error raised on purpose by lattice-cad."""


class InvalidGraphError(LatticeError, ValueError):
    """A lattice graph violates an input rule; the message names the node or edge."""


class StitchError(LatticeError, ValueError):
    """A valid graph cannot be stitched (struts meet too closely, or overlap)."""


class FitError(LatticeError, ValueError):
    """Some struts cannot be made to fit (the message lists them)."""


class FillError(LatticeError, ValueError):
    """No lattice of the asked cell size and radius fits the part; the message says what
    would (the largest cell size that fits whole, the part's thickness, the largest radius).
    """


class PartError(LatticeError, ValueError):
    """A part cannot be used: unreadable, empty, not a closed solid (the message says which)."""


class StepUnitsError(PartError):
    """A STEP file's declared length unit disagrees with OCCT's reading of it."""


class SkinError(LatticeError, ValueError):
    """A part cannot be hollowed (not a closed solid, or the wall is too thick)."""


class EscapeHoleError(LatticeError, ValueError):
    """An enclosed cavity of a skinned part gets no escape hole (none fits, or a user point
    has no cavity behind it), or stays enclosed after drilling (the message says which)."""


class KeepError(LatticeError, ValueError):
    """A keep-solid zone cannot be used: a selector that matches no face (the message lists
    the part's faces), a face not on the part, a bad thickness or box."""


class SimilarityError(LatticeError, ValueError):
    """Invalid similarity parameters (non-positive scale, zero axis, non-finite values)."""


class SteadyLatticeError(LatticeError, ValueError):
    """Invalid steady-lattice input; the message names the ball, rack or index at fault."""


class PrintabilityError(LatticeError, ValueError):
    """Invalid printability options: a zero or non-finite build direction, a critical angle
    outside 0..90 degrees, a negative minimum diameter (the message names the option)."""


class ExportError(LatticeError, ValueError):
    """A mesh cannot be written faithfully in the requested format."""


class SelectionError(LatticeError, ValueError):
    """A selector (face, plane, box or node list) cannot be resolved or picks nothing; the
    message names the selector and says what is near (for example the closest node)."""


class ShardingError(LatticeError, ValueError):
    """An option the sharded (Dask) path does not support, or a shard whose halo is too
    small for the lattice (the message says which)."""


class ShardHaloError(ShardingError):
    """A shard's halo is too small for what it must know exactly (its struts' neighbours,
    the radius fit's or hub capping's reach): ``fill_sharded`` with the default halo
    retries with a larger one."""


class DistributedUnavailableError(LatticeError, ImportError):
    """The sharded path needs Dask distributed: ``pip install 'lattice-cad[distributed]'``."""


class ToleranceError(LatticeError, ValueError):
    """An accuracy-report tolerance is not a valid number (the message names the option)."""


class OCCTFailure(LatticeError, RuntimeError):
    """An OpenCascade operation failed (not done, errors, or an invalid result).

    Inside the reference builder it becomes a per-hub status, never an uncaught error.
    """


class ExternalCrash(LatticeError, RuntimeError):
    """OpenCascade or gmsh crashed or hung in a child process (the caller's process lives)."""


class ExternalTimeout(ExternalCrash):
    """OpenCascade or gmsh did not finish within its time in a child process (killed)."""


class InsufficientMemoryError(LatticeError, MemoryError):
    """The work's estimated peak memory exceeds the available memory, checked before any
    allocation; the message gives both amounts and what to do instead."""


class OutputError(LatticeError, OSError):
    """A file cannot be written (no such directory, a directory in the way, permissions, a
    full disk); the message names the target path, never the temp file beside it."""


class InputFileError(LatticeError, ValueError):
    """A file cannot be read: it is empty, truncated, a directory, or not the format its
    suffix says. The message names the file."""


class MissingFileError(InputFileError, FileNotFoundError):
    """An input file does not exist (the message names it)."""


class ReferenceBuildError(LatticeError, RuntimeError):
    """The reference cannot be built (bad input, or a failure that is not per hub)."""


class DirtyLatticeError(ReferenceBuildError, ValueError):
    """Hubs of the lattice would overlap, so the stacked reference would not be exact."""


class LatticeWarning(UserWarning):
    """Something was accepted but deserves the user's attention (e.g. isolated nodes)."""


class ExportWarning(LatticeWarning):
    """An export succeeded but the file may be too large for common slicers."""


class CutBudgetWarning(LatticeWarning):
    """The tessellation a lattice is cut by is coarser than asked (its triangle budget,
    ``config.CUT_MAX_TRIANGLES``, binds, or faces OpenCascade's mesher does not follow stay
    over the chord error): the message names the part and the chord error reached (measured
    on those faces) in % of the strut radius (``conformal.trim.cutting_part``)."""


class BeamOnlyWarning(LatticeWarning):
    """A 3MF beam lattice was written without triangles (``beam_lattice="only"``): readers
    without the Beam Lattice extension cannot open it (the message names them)."""


class CADStackWarning(LatticeWarning):
    """The installed cadquery/build123d/OCP set is not the supported one."""
