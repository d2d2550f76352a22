"""One call: stitch a lattice, build its exact reference, compare, write the report."""

from __future__ import annotations

import os
from typing import Any

from lattice_cad.graph import LatticeGraph

__all__ = ["validate"]


def validate(
    graph: LatticeGraph,
    segments: int = 6,
    report: str | os.PathLike[str] | None = "report.html",
    *,
    volume_preserving: bool = False,
    union_segments: tuple[int, ...] = (16, 32, 64, 128),
    samples: int = 50_000,
    stitch_options: dict[str, Any] | None = None,
    **reference_options: Any,
) -> Any:
    """Stitch ``graph`` with fast_stitch, compare it with the exact reference, write a report.

    Parameters
    ----------
    graph : LatticeGraph
    segments : int
        P, the profile polygon sides of :func:`fast_stitch.stitch`.
    report : path-like or None
        Where to write the report (``.html``, ``.md`` or ``.json``); None: do not write.
    volume_preserving : bool
        Passed to :func:`fast_stitch.stitch` when true (needs a fast_stitch that has it).
    union_segments : tuple of int
        Resolutions of the manifold3d unions in the report.
    samples : int
        Surface samples per direction of the deviation measure.
    stitch_options : dict, optional
        More keyword arguments of :func:`fast_stitch.stitch`.
    **reference_options
        Keyword arguments of :func:`reference_boolean.build_reference`.

    Returns
    -------
    reference_boolean.ValidationReport
    """
    import fast_stitch
    from reference_boolean import compare

    opts = dict(stitch_options or {})
    if volume_preserving:
        opts["volume_preserving"] = True
    mesh = fast_stitch.stitch(graph, segments, **opts)
    label = f"fast_stitch P={segments}" + (" volume_preserving" if volume_preserving else "")
    rep = compare(
        graph,
        mesh=mesh,
        union_segments=union_segments,
        samples=samples,
        label=label,
        **reference_options,
    )
    if report is not None:
        rep.save(report)
    return rep
