"""A 3MF written in shards: one model part per shard, joined by the 3MF Production extension.

A lattice too large for one 3MF mesh object (or for one process's memory) is written as:

- one *model part* per shard, ``/3D/shard_K.model``, holding one mesh object: the
  shard's triangles (welded by exact single-precision coordinates inside the shard) and,
  for a beam lattice, the shard's beams (3MF Beam Lattice extension). Each part is made
  by lib3mf in the worker that stitched the shard (:func:`write_part`);
- a small root model ``/3D/3dmodel.model`` with one *components* object whose components
  reference the shard objects by ``p:path`` (Production extension), and one build item;
- the parts are streamed into the zip by :func:`assemble_parts` (never held whole in
  memory; ZIP64 for parts beyond 2 GiB), atomically (complete or absent), and
  deterministically (content-derived UUIDs, fixed zip timestamps: the same input gives
  the same bytes).

The shard objects are open where the lattice crosses a shard boundary (a strut's cylinder
belongs to one shard, the hub at its other end may belong to the next); the union of the
components -- the one object in the build -- is the closed lattice: merged by coordinates
the triangles are one closed, oriented solid (every seam vertex is the same float32 in
both shards). A consumer that checks each mesh object for closedness on its own will
report the seams; the 3MF core specification asks closed meshes per object of type
``model``, so a single merged mesh (``save_mesh``) remains the choice for small lattices.
"""

from __future__ import annotations

import hashlib
import uuid
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lattice_cad.core.atomic import atomic_write, check_target
from lattice_cad.core.errors import ExportError

__all__ = ["write_part", "assemble_parts", "read_parts", "PART_NAME"]

#: The model-part path of shard ``k`` inside the package.
PART_NAME = "3D/shard_{k}.model"
_CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
_PROD = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06"
_REL_MODEL = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def write_part(
    path: str | Path,
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    name: str,
    beams: dict[str, NDArray[Any]] | None = None,
    balls: bool = True,
) -> dict[str, Any]:
    """Write one shard as a one-object 3MF (lib3mf); its model becomes a part later.

    Parameters
    ----------
    path : path
        A work file (``.3mf``), shared with the client.
    vertices : (V, 3) float64
        The shard's vertices (exactly representable in float32 for seams to match).
    faces : (F, 3) int64
        Triangles into ``vertices`` (may be empty for a beam-only part).
    name : str
        The object's name.
    beams : dict, optional
        ``nodes`` (N, 3) float64, ``edges`` (M, 2) int64 into ``nodes``, ``radii`` (M, 2)
        float64 and ``degree`` (N,) int64 (the node's degree in the *whole* lattice: caps
        and balls follow it, not the shard's share); optionally ``ball`` (N,) bool, the
        nodes whose ball this part holds (each ball in one part only), and ``ball_radius``
        (N,) float64, the ball radii (the largest strut radius at the node in the whole
        lattice).
    balls : bool
        A ball at every node of degree >= 2 (with ``beams``).

    Returns
    -------
    dict
        ``object_id`` (int, the object's id inside its part), ``uuid`` (str),
        ``triangles``, ``beams`` (int).
    """
    from lattice_cad.core.graph import LatticeGraph
    from lattice_cad.io.exchange import (
        _lib3mf,
        _set_beams,
        _set_geometry,
        _stable_uuid,
    )

    lib3mf, wrapper = _lib3mf()
    model = wrapper.CreateModel()
    model.SetUnit(lib3mf.ModelUnit.MilliMeter)
    digest = hashlib.sha256(f"shard part {name}".encode())
    obj = model.AddMeshObject()
    obj.SetName(name)
    n_beams = 0
    try:
        if beams is None:
            _set_geometry(lib3mf, obj, vertices, faces, digest)
        else:
            nodes = np.asarray(beams["nodes"], dtype=np.float64)
            edges = np.asarray(beams["edges"], dtype=np.int64)
            g = LatticeGraph(nodes, edges, np.asarray(beams["radii"], dtype=np.float64))
            used = np.arange(len(nodes))
            _set_geometry(lib3mf, obj, np.vstack([vertices, nodes]), faces, digest)
            if len(edges):
                _set_beams(lib3mf, obj, g, used, edges, len(vertices), balls, digest,
                           degree=np.asarray(beams["degree"], dtype=np.int64),
                           ball_at=beams.get("ball"),
                           ball_radius=beams.get("ball_radius"))  # fmt: skip
            n_beams = len(edges)
        uid = _stable_uuid(digest.digest(), "object")
        obj.SetUUID(uid)
        model.SetBuildUUID(_stable_uuid(digest.digest(), "build"))
        writer = model.QueryWriter("3mf")
        from lattice_cad.io.exchange import THREEMF_DECIMALS

        writer.SetDecimalPrecision(THREEMF_DECIMALS)
        writer.WriteToFile(str(path))
    except lib3mf.ELib3MFException as exc:
        raise ExportError(f"{name}: lib3mf refused the shard part: {exc}") from None
    return {
        "object_id": int(obj.GetModelResourceID()),
        "uuid": uid,
        "triangles": int(len(faces)),
        "beams": int(n_beams),
    }


def _info(name: str) -> zipfile.ZipInfo:
    zi = zipfile.ZipInfo(name, date_time=_ZIP_TIME)
    zi.compress_type = zipfile.ZIP_DEFLATED
    zi.external_attr = 0o644 << 16
    return zi


def assemble_parts(
    path: str | Path,
    parts: Sequence[str | Path],
    metas: Sequence[dict[str, Any]],
    *,
    name: str = "lattice",
    compresslevel: int = 1,
) -> Path:
    """Join shard 3MFs (:func:`write_part`) into one 3MF: a components object over them.

    Parameters
    ----------
    path : path
        The ``.3mf`` to write (atomically).
    parts : sequence of path
        The shard files, in shard order.
    metas : sequence of dict
        :func:`write_part`'s return values, same order.
    name : str
        The name of the built (components) object.
    compresslevel : int
        Deflate level of the streamed parts (1: fast; the parts are XML).

    Returns
    -------
    Path
    """
    out = check_target(path)
    if not parts or len(parts) != len(metas):
        raise ExportError(f"{out.name}: no shard parts to write")
    digest = hashlib.sha256(f"sharded 3mf {name}".encode())
    for m in metas:
        digest.update(f"{m['uuid']}/{m['object_id']}".encode())
    key = digest.hexdigest()

    def uid(role: str) -> str:
        return str(uuid.uuid5(uuid.NAMESPACE_URL, f"lattice-cad/{key}/{role}"))

    comps = "\n".join(
        f'      <component objectid="{m["object_id"]}" p:path="/{PART_NAME.format(k=k)}" '
        f'p:UUID="{uid(f"component/{k}")}"/>'
        for k, m in enumerate(metas)
    )
    root = (
        '<?xml version="1.0" encoding="utf-8"?>\n'
        f'<model xmlns="{_CORE}" xmlns:p="{_PROD}" unit="millimeter" xml:lang="en-US" '
        'requiredextensions="p">\n'
        f' <metadata name="Application">lattice-cad (sharded)</metadata>\n'
        " <resources>\n"
        f'  <object id="1" name="{_xml(name)}" type="model" p:UUID="{uid("object")}">\n'
        f"   <components>\n{comps}\n   </components>\n"
        "  </object>\n"
        " </resources>\n"
        f' <build p:UUID="{uid("build")}">\n'
        f'  <item objectid="1" p:UUID="{uid("item")}"/>\n'
        " </build>\n"
        "</model>\n"
    )
    rels = (
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">\n'
        + "".join(
            f'  <Relationship Type="{_REL_MODEL}" Target="/{PART_NAME.format(k=k)}" Id="rel{k}"/>\n'
            for k in range(len(parts))
        )
        + "</Relationships>\n"
    )
    pkg_rels = (
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">\n'
        f'  <Relationship Type="{_REL_MODEL}" Target="/3D/3dmodel.model" Id="rel0"/>\n'
        "</Relationships>\n"
    )
    types = (
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">\n'
        '  <Default Extension="model" '
        'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>\n'
        '  <Default Extension="rels" '
        'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>\n'
        "</Types>\n"
    )
    with (
        atomic_write(out, "wb") as fh,
        zipfile.ZipFile(
            fh, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=compresslevel
        ) as z,
    ):
        z.writestr(_info("[Content_Types].xml"), types)
        z.writestr(_info("_rels/.rels"), pkg_rels)
        z.writestr(_info("3D/3dmodel.model"), root)
        z.writestr(_info("3D/_rels/3dmodel.model.rels"), rels)
        for k, p in enumerate(parts):
            with zipfile.ZipFile(p) as src:
                try:
                    info = src.getinfo("3D/3dmodel.model")
                except KeyError:
                    raise ExportError(f"{p}: not a shard part (no 3D/3dmodel.model)") from None
                big = info.file_size >= 2**31
                with (
                    src.open(info) as r,
                    z.open(_info(PART_NAME.format(k=k)), "w", force_zip64=big) as w,
                ):
                    while chunk := r.read(1 << 22):
                        w.write(chunk)
    return out


def _xml(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def read_parts(path: str | Path) -> dict[str, Any]:
    """Read a 3MF back with lib3mf: its mesh objects, components and build (for checks).

    Returns
    -------
    dict
        ``meshes``: list of (vertices (V, 3) float64, faces (F, 3) int64), one per mesh
        object; ``beams``: beams over all objects; ``components``: components of the built
        object(s); ``build_items``: int.
    """
    from lattice_cad.io.exchange import _get_geometry, _mesh_objects, _read_3mf_model

    lib3mf, model = _read_3mf_model(Path(path))
    meshes = []
    n_beams = 0
    for obj in _mesh_objects(model):
        meshes.append(_get_geometry(lib3mf, obj))
        n_beams += obj.BeamLattice().GetBeamCount()
    items = model.GetBuildItems()
    n_items = 0
    n_comp = 0
    while items.MoveNext():
        n_items += 1
        res = items.GetCurrent().GetObjectResource()
        if res.IsComponentsObject():
            co = model.GetComponentsObjectByID(res.GetResourceID())
            n_comp += co.GetComponentCount()
    return {"meshes": meshes, "beams": n_beams, "components": n_comp, "build_items": n_items}
