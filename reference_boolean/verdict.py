"""The verdict of an accuracy report: is the mesh within a user tolerance of the exact solid?

A mesh **passes** when all of these hold:

1. the exact reference is complete (every hub was built; an incomplete reference
   never passes: the mesh cannot be verified where the reference is missing);
2. the mesh is valid (watertight, consistently wound, outward, manifold);
3. the 95th percentile of its two-sided surface deviation from the exact solid
   (mesh to reference and reference to mesh, sampled densely on both) **along the
   struts** is at most ``tolerance`` mm: 95 % of both surfaces outside the hub zones lie
   within +-``tolerance`` mm of the other. Inside a node's hub zone
   (:mod:`reference_boolean.regions`) the mesh's convex hub and the reference's ball and
   cylinders are different designs (about one radius apart in the crevices between
   struts at any resolution), so the hubs are judged by the volume error (4), and their
   deviation is reported beside it. Where fewer than
   :data:`~lattice_cad.core.config.MIN_STRUT_FRACTION` of the samples lie along struts
   (or the report has no zones), the whole surface is judged;
4. its relative volume error ``|V_mesh - V_exact| / V_exact`` is at most
   ``tolerance_volume``.

Defaults: ``tolerance`` = 10 % of the median strut radius
(:data:`~lattice_cad.core.config.DEFAULT_DEVIATION_TOLERANCE_REL`), ``tolerance_volume``
= 1 % (:data:`~lattice_cad.core.config.DEFAULT_VOLUME_TOLERANCE`), the accuracy goals of
issue 14. The verdict is about the report's first mesh (the one the product writes by
default); every other compared mesh gets its own verdict under the same tolerances.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from lattice_cad.core import config
from lattice_cad.core.errors import ToleranceError

if TYPE_CHECKING:
    from reference_boolean.compare import ValidationReport

__all__ = [
    "Verdict",
    "judge",
    "check_tolerances",
    "median_radius",
    "default_tolerance",
    "DEFINITION",
]

#: One sentence that defines the verdict (printed under it in every report).
DEFINITION = (
    "PASS when the exact reference is complete, the mesh is valid (watertight, "
    "consistently wound, outward, manifold), 95 % of its two-sided surface deviation "
    "from the exact solid along the struts (outside the hub zones, where both model the "
    "same design) is within the surface tolerance, and its volume error is "
    "within the volume tolerance."
)


def median_radius(graph: Any) -> float:
    """Median strut radius (mm) over both ends of every strut (0 for a graph without struts)."""
    r = np.asarray(graph.radii, dtype=np.float64).reshape(-1)
    return float(np.median(r)) if len(r) else 0.0


def default_tolerance(graph: Any) -> float:
    """The default surface tolerance (mm): 10 % of the median strut radius."""
    return config.DEFAULT_DEVIATION_TOLERANCE_REL * median_radius(graph)


def check_tolerances(tolerance: float | None, tolerance_volume: float | None) -> None:
    """Refuse a surface tolerance that is not a positive number of mm, or a volume
    tolerance that is not a fraction >= 0.

    Raises
    ------
    ToleranceError
        Naming the option and the value.
    """
    if tolerance is not None:
        try:
            t = float(tolerance)
        except (TypeError, ValueError):
            t = math.nan
        if not (math.isfinite(t) and t > 0):
            raise ToleranceError(f"tolerance must be a positive number of mm, got {tolerance!r}")
    if tolerance_volume is not None:
        try:
            tv = float(tolerance_volume)
        except (TypeError, ValueError):
            tv = math.nan
        if not (math.isfinite(tv) and tv >= 0):
            raise ToleranceError(
                f"tolerance_volume must be a fraction >= 0 (0.01 = 1 %), got {tolerance_volume!r}"
            )


def _pct(x: float) -> str:
    return f"{100 * x:+.2f} %"


def _mm(x: float) -> str:
    return f"{x:.3g} mm"


@dataclass(frozen=True)
class Verdict:
    """The verdict on one mesh of a report.

    Attributes
    ----------
    passed : bool
    line : str
        ``"PASS: mesh within +-X mm of the exact solid ..."`` or ``"FAIL: ..."``.
    label : str
        The mesh judged.
    tolerance : float
        Surface tolerance, mm (on the 95th percentile of the two-sided deviation).
    tolerance_default : bool
        True when ``tolerance`` is the default (10 % of the median strut radius).
    tolerance_volume : float
        Volume tolerance, a fraction (0.01 = 1 %).
    radius : float
        Median strut radius, mm (the "% of radius" figures divide by it).
    reference_complete : bool
    failed_hubs : int
    hubs : int
        Nodes with struts.
    valid : bool or None
        The mesh's validity (None without a mesh).
    volume_error : float or None
        ``(V_mesh - V_exact) / V_exact``.
    deviation : dict[str, float]
        ``"max"``, ``"p95"``, ``"mean"`` of the two-sided deviation that is judged, mm
        (empty without a mesh): along the struts, or the whole surface (``deviation_region``).
    reasons : tuple of str
        Why it failed (empty when it passed).
    deviation_region : str
        ``"struts"`` or ``"whole surface"``: where ``deviation`` was measured.
    deviation_hubs : dict[str, float]
        The same inside the hub zones (not judged; empty without zones).
    deviation_all : dict[str, float]
        The same over the whole surfaces.
    """

    passed: bool
    line: str
    label: str
    tolerance: float
    tolerance_default: bool
    tolerance_volume: float
    radius: float
    reference_complete: bool
    failed_hubs: int
    hubs: int
    valid: bool | None
    volume_error: float | None
    deviation: dict[str, float]
    reasons: tuple[str, ...]
    deviation_region: str = "whole surface"
    deviation_hubs: dict[str, float] = field(default_factory=dict)
    deviation_all: dict[str, float] = field(default_factory=dict)

    @property
    def status(self) -> str:
        """``"PASS"`` or ``"FAIL"``."""
        return "PASS" if self.passed else "FAIL"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        out = asdict(self)
        out["reasons"] = list(self.reasons)
        out["status"] = self.status
        out["definition"] = DEFINITION
        return out


def judge(
    rep: ValidationReport,
    *,
    tolerance: float | None = None,
    tolerance_volume: float | None = None,
    label: str | None = None,
) -> Verdict:
    """The verdict on one mesh of ``rep`` (default: its first).

    Parameters
    ----------
    rep : ValidationReport
    tolerance : float, optional
        Surface tolerance in mm, > 0 (default: 10 % of the median strut radius).
    tolerance_volume : float, optional
        Relative volume tolerance, >= 0 (default 0.01, i.e. 1 %).
    label : str, optional
        Which compared mesh (default: the first).

    Raises
    ------
    ToleranceError
        A tolerance is negative, zero (surface) or not finite.
    ValueError
        ``label`` is not one of the compared meshes.
    """
    check_tolerances(tolerance, tolerance_volume)
    g = rep.graph
    radius = median_radius(g)
    is_default = tolerance is None
    tol = default_tolerance(g) if tolerance is None else float(tolerance)
    tol_v = config.DEFAULT_VOLUME_TOLERANCE if tolerance_volume is None else float(tolerance_volume)
    comps = rep.comparisons
    if label is not None and label not in comps:
        raise ValueError(f"no mesh {label!r} in the report (meshes: {', '.join(comps) or 'none'})")
    comp = comps[label] if label is not None else next(iter(comps.values()), None)
    ref = rep.reference
    hubs = int((g.degree > 0).sum())
    failed = len(ref.failed)
    common: dict[str, Any] = {
        "tolerance": tol,
        "tolerance_default": is_default,
        "tolerance_volume": tol_v,
        "radius": radius,
        "reference_complete": bool(ref.complete),
        "failed_hubs": failed,
        "hubs": hubs,
    }
    within = f"within \u00b1{_mm(tol)} of the exact solid"
    if comp is None:
        return Verdict(
            passed=False,
            line=f"FAIL: no mesh was compared with the exact solid, so none is shown {within}",
            label="",
            valid=None,
            volume_error=None,
            deviation={},
            reasons=("no mesh compared",),
            **common,
        )
    keys = ("max", "p95", "mean")
    sym = comp.hausdorff["symmetric"]
    dev_all = {k: float(sym[k]) for k in keys}
    dev, region, dev_hubs = dev_all, "whole surface", {}
    regs = comp.regions
    if regs:
        dev_hubs = {k: float(regs["hubs"]["symmetric"][k]) for k in keys}
        if regs["struts"]["symmetric"]["fraction"] >= config.MIN_STRUT_FRACTION:
            dev = {k: float(regs["struts"]["symmetric"][k]) for k in keys}
            region = "struts"
    where = " along struts" if region == "struts" else ""
    verr = float(comp.relative_volume_error)
    valid = bool(comp.valid.get("valid", False))
    reasons: list[str] = []
    if not ref.complete:
        reasons.append(
            f"the exact reference is incomplete ({failed} of {hubs} hubs failed), so the mesh "
            "cannot be verified where it is missing"
        )
    if not valid:
        bad = [k for k, v in comp.valid.items() if k != "valid" and not v]
        reasons.append("the mesh is not valid (" + ", ".join(f"not {k}" for k in bad) + ")")
    if not dev["p95"] <= tol:
        reasons.append(f"deviation p95{where} {_mm(dev['p95'])} > {_mm(tol)}")
    if not abs(verr) <= tol_v:
        reasons.append(f"volume error {_pct(verr)} outside \u00b1{100 * tol_v:.3g} %")
    passed = not reasons
    if passed:
        line = (
            f"PASS: mesh {within} (deviation p95{where} {_mm(dev['p95'])}, "
            f"volume error {_pct(verr)} within \u00b1{100 * tol_v:.3g} %)"
        )
    elif not ref.complete:
        line = f"FAIL: not verified {within}: " + "; ".join(reasons)
    else:
        line = f"FAIL: mesh not {within}: " + "; ".join(reasons)
    return Verdict(
        passed=passed,
        line=line,
        label=comp.label,
        valid=valid,
        volume_error=verr,
        deviation=dev,
        reasons=tuple(reasons),
        deviation_region=region,
        deviation_hubs=dev_hubs,
        deviation_all=dev_all,
        **common,
    )
