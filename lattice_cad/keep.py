"""Keep-solid zones of ``Lattice.fill(part, keep=...)``: what the user names, resolved to faces.

The front resolves CadQuery selector strings on the part's B-rep faces (only the front
imports cadquery) and hands :class:`conformal.keep.KeepZone` objects to the engine, which
builds the solid zones (:mod:`conformal.keep`).

``keep`` takes one zone or a list of zones; a zone is

* ``(faces, thickness)``: ``faces`` a CadQuery selector string (``">Z"``, ``"%CYLINDER"``,
  ``">Z or <Z"``), a build123d or cadquery ``Face``, a list of faces, or a cadquery
  ``Workplane`` holding faces (``part.faces(">Z")``); the part stays solid within
  ``thickness`` mm of those faces;
* ``(box, margin)``: ``box = ((xmin, ymin, zmin), (xmax, ymax, zmax))``, the part inside
  the box grown by ``margin`` (``0``: the box itself); works for mesh parts too;
* ``"SELECTOR:THICKNESS"``: the command-line form (``">Z:2"``, ``"%CYLINDER:1.5"``, or a
  box as ``"xmin,ymin,zmin,xmax,ymax,zmax:MARGIN"``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from lattice_cad.core.errors import KeepError
from lattice_cad.selectors import brep_faces, face_inventory, pick_faces

__all__ = ["resolve_keep", "parse_keep"]


def parse_keep(text: str) -> tuple[Any, float]:
    """``"SELECTOR:THICKNESS"`` as ``(selector or box, thickness)``.

    A selector of six comma-separated numbers is a box ``xmin,ymin,zmin,xmax,ymax,zmax``.

    Raises
    ------
    KeepError
        No ``:THICKNESS``, or a thickness that is not a number.
    """
    if not isinstance(text, str):
        raise KeepError(f"a keep zone string is 'SELECTOR:THICKNESS', got {text!r}")
    sel, sep, thick = text.rpartition(":")
    sel = sel.strip()
    if not sep or not sel:
        raise KeepError(
            f"keep zone {text!r}: expected SELECTOR:THICKNESS (e.g. '>Z:2' or '%CYLINDER:1.5')"
        )
    try:
        t = float(thick)
    except ValueError:
        raise KeepError(f"keep zone {text!r}: thickness {thick!r} is not a number") from None
    numbers = sel.split(",")
    if len(numbers) == 6:
        try:
            box = np.array([float(x) for x in numbers]).reshape(2, 3)
        except ValueError:
            pass
        else:
            return box, t
    return sel, t


def _is_box(obj: Any) -> bool:
    if isinstance(obj, (str, bytes)):
        return False
    try:
        arr = np.asarray(obj, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return arr.shape == (2, 3)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.number)) and not isinstance(x, bool)


def _zone_specs(keep: Any) -> list[Any]:
    """The list of zone specs in ``keep`` (one zone or several)."""
    if isinstance(keep, str):
        return [keep]
    if isinstance(keep, (tuple, list)) and len(keep) == 2 and _is_number(keep[1]):
        return [keep]
    if isinstance(keep, (list, tuple)):
        return list(keep)
    raise KeepError(
        "keep must be (faces, thickness), 'SELECTOR:THICKNESS' or a list of them; "
        f"got {type(keep).__name__}"
    )


def _select(part: Any, selector: str, label: str) -> list[Any]:
    faces = brep_faces(part)
    if not faces:
        raise KeepError(
            f"keep zone {label!r}: a face selector needs a B-rep part (STEP, CadQuery, "
            f"build123d); {part.name} is a mesh: give a box ((xmin, ymin, zmin), "
            "(xmax, ymax, zmax)) instead"
        )
    try:
        chosen = pick_faces(faces, selector)
    except ValueError as exc:
        raise KeepError(
            f"keep zone {label!r}: {selector!r} is not a CadQuery selector ({exc})"
        ) from None
    if not chosen:
        raise KeepError(
            f"keep zone {label!r}: selector {selector!r} matches no face of the part; "
            f"it has {face_inventory(faces)}"
        )
    return chosen


def _as_faces(obj: Any, label: str) -> list[Any]:
    """cadquery Faces of a Face, a list of faces or a Workplane (build123d or cadquery)."""
    import cadquery as cq

    items = obj.vals() if isinstance(obj, cq.Workplane) else obj
    if not isinstance(items, (list, tuple)):
        items = [items]
    out = []
    for k, item in enumerate(items):
        wrapped = getattr(item, "wrapped", None)
        face = cq.Shape.cast(wrapped) if wrapped is not None else None
        if not isinstance(face, cq.Face):
            raise KeepError(
                f"keep zone {label!r}: item {k} is a {type(item).__name__}, not a face; give "
                "faces, a selector string or a box ((xmin, ymin, zmin), (xmax, ymax, zmax))"
            )
        out.append(face)
    if not out:
        raise KeepError(f"keep zone {label!r}: the list of faces is empty")
    return out


def resolve_keep(part: Any, keep: Any) -> tuple[Any, ...]:
    """The keep-solid zones named by ``keep``, on ``part`` (see the module docstring).

    Parameters
    ----------
    part : conformal.Part
        The filled part; selectors are resolved on its B-rep faces (``part.shape``).
    keep : zone or list of zones

    Returns
    -------
    tuple of conformal.keep.KeepZone

    Raises
    ------
    KeepError
        A selector that matches no face (the message lists the part's faces by type), a
        selector on a mesh part, something that is not a face, a bad thickness or box.
    """
    from conformal.keep import KeepZone

    zones = []
    for k, spec in enumerate(_zone_specs(keep)):
        if isinstance(spec, str):
            what, t = parse_keep(spec)
        elif isinstance(spec, (tuple, list)) and len(spec) == 2:
            what, t = spec
        else:
            raise KeepError(
                f"keep zone {k}: expected (faces, thickness) or 'SELECTOR:THICKNESS', got {spec!r}"
            )
        if not _is_number(t) or not math.isfinite(float(t)):
            raise KeepError(f"keep zone {k}: thickness must be a number, got {t!r}")
        t = float(t)
        if _is_box(what):
            box = np.asarray(what, dtype=np.float64)
            label = "box " + ",".join(f"{x:g}" for x in box.ravel()) + f":{t:g}"
            zones.append(KeepZone(label, t, box=box))
            continue
        on_part = isinstance(what, str)
        if on_part:
            label = f"{what}:{t:g}"
            faces = _select(part, what, label)
        else:
            label = f"zone {k}:{t:g}"
            faces = _as_faces(what, label)
            label = f"{len(faces)} face(s):{t:g}"
        if not t > 0:
            raise KeepError(f"keep zone {label!r}: the thickness must be > 0, got {t:g}")
        zones.append(
            KeepZone(
                label,
                t,
                faces=tuple(f.wrapped for f in faces),
                face_types=tuple(f.geomType() for f in faces),
                on_part=on_part,
            )
        )
    if not zones:
        raise KeepError("keep is an empty list: give at least one zone or leave keep out")
    return tuple(zones)
