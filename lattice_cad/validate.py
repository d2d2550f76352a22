"""One call: stitch a lattice, build its exact reference, compare, write the report."""

from __future__ import annotations

import inspect
import os
from typing import Any

from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph

__all__ = ["validate"]


def validate(
    graph: LatticeGraph,
    segments: int = config.DEFAULT_SEGMENTS,
    report: str | os.PathLike[str] | None = "report.html",
    *,
    volume_preserving: bool | str = "both",
    union_segments: tuple[int, ...] = (16, 32, 64, 128),
    samples: int = 50_000,
    union_hubs: int | None = config.DEFAULT_UNION_HUBS,
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
    volume_preserving : bool or "both"
        ``"both"`` (default): compare the plain and the volume-preserving
        :func:`fast_stitch.stitch` meshes side by side in one report (the first
        row, and the report's single-mesh attributes, are the plain mesh; the
        volume-preserving one is skipped, with a note in ``extra``, when this
        fast_stitch has no ``volume_preserving``). True: only the
        volume-preserving mesh. False: only the plain mesh.
    union_segments : tuple of int
        Resolutions of the manifold3d unions in the report.
    samples : int
        Surface samples per direction of the deviation measure.
    union_hubs : int or None
        The manifold3d unions cover a seeded sample of this many hubs (None: the whole
        lattice; see :func:`reference_boolean.compare`).
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

    if volume_preserving not in (True, False, "both"):
        raise ValueError(
            f"volume_preserving must be True, False or 'both', got {volume_preserving!r}"
        )
    opts = dict(stitch_options or {})
    opts.pop("volume_preserving", None)
    has_vp = "volume_preserving" in inspect.signature(fast_stitch.stitch).parameters
    base = f"fast_stitch P={segments}"
    meshes: dict[str, Any] = {}
    notes: dict[str, Any] = {}
    if volume_preserving in (False, "both"):
        meshes[base] = fast_stitch.stitch(graph, segments, **opts)
    if volume_preserving is True or (volume_preserving == "both" and has_vp):
        meshes[f"{base} volume_preserving"] = fast_stitch.stitch(
            graph, segments, volume_preserving=True, **opts
        )
    elif volume_preserving == "both":
        notes["note"] = "fast_stitch.stitch has no volume_preserving: only the plain mesh"
    rep = compare(
        graph,
        meshes=meshes,
        union_segments=union_segments,
        samples=samples,
        union_hubs=union_hubs,
        **reference_options,
    )
    if notes:
        rep.extra.update(notes)
    if report is not None:
        rep.save(report)
    return rep
