"""One call: stitch a lattice, build its exact reference, compare, write the report."""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from typing import Any

from lattice_cad.core import config
from lattice_cad.core.graph import LatticeGraph

__all__ = ["validate"]


def validate(
    graph: LatticeGraph,
    segments: int = config.DEFAULT_SEGMENTS,
    report: str | os.PathLike[str] | None = "report.html",
    *,
    profiles: Sequence[str] = ("volume", "inscribed"),
    volume_preserving: bool | str | None = None,
    union_segments: tuple[int, ...] = (16, 32, 64, 128),
    samples: int = 50_000,
    union_hubs: int | None = config.DEFAULT_UNION_HUBS,
    stitch_options: dict[str, Any] | None = None,
    tolerance: float | None = None,
    tolerance_volume: float | None = None,
    reference_tolerance: float | None = None,
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
    profiles : sequence of {"volume", "area", "inscribed", "circumscribed"}
        The :func:`fast_stitch.stitch` profiles to compare side by side in one report;
        the first is the report's main mesh (its first row and single-mesh attributes).
        Default: the default mesh (``"volume"``, labelled ``fast_stitch P=<segments>``)
        and the inscribed option (``fast_stitch P=<segments> inscribed``).
    volume_preserving : bool or "both", optional
        Deprecated: True is ``profiles=("area",)``, False ``("inscribed",)``, "both"
        ``("inscribed", "area")``.
    union_segments : tuple of int
        Resolutions of the manifold3d unions in the report.
    samples : int
        Surface samples per direction of the deviation measure.
    union_hubs : int or None
        The manifold3d unions cover a seeded sample of this many hubs (None: the whole
        lattice; see :func:`reference_boolean.compare`).
    stitch_options : dict, optional
        More keyword arguments of :func:`fast_stitch.stitch`.
    tolerance : float, optional
        Surface tolerance of the report's verdict, in mm: the mesh passes only if 95 % of
        its two-sided surface deviation from the exact solid is within +-``tolerance``
        (default: 10 % of the median strut radius). See :mod:`reference_boolean.verdict`.
    tolerance_volume : float, optional
        Volume tolerance of the verdict, a fraction: ``|V_mesh - V_exact| / V_exact``
        at most this (default 0.01, i.e. 1 %).
    reference_tolerance : float, optional
        Linear deflection (mm) of the reference's tessellation (``tolerance`` of
        :func:`reference_boolean.build_reference`; default 1 % of the smallest radius).
    **reference_options
        Keyword arguments of :func:`reference_boolean.build_reference`.

    Returns
    -------
    reference_boolean.ValidationReport
        Its :meth:`~reference_boolean.ValidationReport.verdict` is PASS / FAIL against
        ``tolerance`` and ``tolerance_volume`` (never PASS on an incomplete reference).

    Raises
    ------
    ToleranceError
        ``tolerance`` is not a positive number, or ``tolerance_volume`` not a fraction >= 0
        (checked before any work).
    """
    import dataclasses

    import fast_stitch
    from fast_stitch.hubvolume import PROFILES
    from reference_boolean import compare
    from reference_boolean.verdict import check_tolerances

    check_tolerances(tolerance, tolerance_volume)
    if reference_tolerance is not None:
        reference_options["tolerance"] = reference_tolerance

    if volume_preserving is not None:
        if volume_preserving not in (True, False, "both"):
            raise ValueError(
                f"volume_preserving must be True, False or 'both', got {volume_preserving!r}"
            )
        warnings.warn(
            "validate(volume_preserving=...) is deprecated: use profiles=(...)",
            DeprecationWarning,
            stacklevel=2,
        )
        profiles = {True: ("area",), False: ("inscribed",), "both": ("inscribed", "area")}[
            volume_preserving
        ]
    profiles = tuple(profiles) if not isinstance(profiles, str) else (profiles,)
    bad = [p for p in profiles if p not in PROFILES]
    if bad or not profiles or len(set(profiles)) != len(profiles):
        raise ValueError(
            f"profiles must be distinct names out of {', '.join(map(repr, PROFILES))}, "
            f"got {profiles!r}"
        )
    opts = dict(stitch_options or {})
    opts.pop("volume_preserving", None)
    opts.pop("profile", None)
    base = f"fast_stitch P={segments}"
    meshes: dict[str, Any] = {}
    notes: dict[str, Any] = {}
    for prof in profiles:
        label = base if prof == "volume" else f"{base} {prof}"
        meshes[label] = fast_stitch.stitch(graph, segments, profile=prof, **opts)  # type: ignore[arg-type]
    rep = compare(
        graph,
        meshes=meshes,
        union_segments=union_segments,
        samples=samples,
        union_hubs=union_hubs,
        **reference_options,
    )
    rep = dataclasses.replace(rep, tolerance=tolerance, tolerance_volume=tolerance_volume)
    if notes:
        rep.extra.update(notes)
    if report is not None:
        rep.save(report)
    return rep
