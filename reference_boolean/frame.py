"""Build every hub and cluster in a frame where its radius is about 1.

OCCT's tolerances are absolute (``Precision::Confusion`` = 1e-7, the fuzzy values of the
retries, the midpoint-disc checks of :mod:`lattice_cad.occ_impl.truss`): on a unitless mesh
with struts of radius 0.005-0.02 they are a sizeable fraction of the geometry and hubs fail
("no midpoint disc found for stump(s)"). So each spec is scaled by ``1 / s`` before it is
built, ``s`` the power of two nearest to its largest sphere or strut radius, and the result
is scaled back: vertices by ``s``, volume by ``s^3``, the solid (binary BREP) by ``s``. The
linear deflection of the tessellation is scaled by ``1 / s`` with the spec, so the mesh is
the one the caller asked for.

A power of two scales every coordinate exactly (only the exponent of each float changes),
so the spec in the frame is an exact copy of the geometry and scaling back loses nothing;
hubs whose radius is already within a factor sqrt(2) of 1 are built as they are
(``s = 1``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

__all__ = ["frame_scale", "scale_spec", "unscale_result"]


def frame_scale(spec: Any) -> float:
    """The power of two nearest to the largest radius of a hub or cluster spec.

    Parameters
    ----------
    spec : HubSpec or ClusterSpec

    Returns
    -------
    float
        ``s = 2 ** k``: the spec is built scaled by ``1 / s``; 1.0 if no radius is positive.
    """
    if hasattr(spec, "hubs"):  # ClusterSpec
        radii = [h.radius for h in spec.hubs]
        radii += [float(np.max(spec.r_mid, initial=0.0)), float(np.max(spec.r_node, initial=0.0))]
        radii += [float(np.max(spec.inner_radii, initial=0.0))]
    else:
        radii = [spec.radius, float(np.max(spec.r_mid, initial=0.0))]
    r = max(radii)
    if not (r > 0.0 and math.isfinite(r)):
        return 1.0
    return float(2.0 ** round(math.log2(r)))


def _hub(spec: Any, f: float) -> Any:
    return replace(
        spec,
        radius=spec.radius * f,
        vecs=spec.vecs * f,
        r_node=spec.r_node * f,
        r_mid=spec.r_mid * f,
    )


def scale_spec(spec: Any, f: float) -> Any:
    """A copy of a HubSpec or ClusterSpec with every length multiplied by ``f``.

    Directions (the midpoint circles' frames, the inner struts' seams) are unchanged.
    """
    if f == 1.0:
        return spec
    if hasattr(spec, "hubs"):
        return replace(
            spec,
            offsets=spec.offsets * f,
            hubs=[_hub(h, f) for h in spec.hubs],
            inner_radii=spec.inner_radii * f,
            vecs=spec.vecs * f,
            r_node=spec.r_node * f,
            r_mid=spec.r_mid * f,
        )
    return _hub(spec, f)


def unscale_result(res: Any, s: float) -> Any:
    """A build result of the frame brought back to the lattice's units (scale ``s``).

    ``vertices`` (V, 3) float64 times ``s``, ``volume`` times ``s ** 3``, ``brep`` scaled
    by ``s`` (OCCT); faces, circles, status and attempts as they are.
    """
    if s == 1.0 or res.status != "ok":
        return res
    brep = res.brep
    if brep:
        from lattice_cad.occ_impl.shapes import scaled_brep

        brep = scaled_brep(brep, s)
    return replace(res, vertices=res.vertices * s, volume=res.volume * s**3, brep=brep)
