"""Beam-lattice 3MF for every reader (beams + the printable mesh, or beams only), the skin in
beam-lattice files, and byte-identical output of every format (issue 13 item 1, issue 12
item 5). The real slicers open these files in tests/test_slicers.py."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
import uuid
import zipfile

import numpy as np
import pytest

import fast_stitch
from conformal import block
from lattice_cad import io
from lattice_cad.core.errors import BeamOnlyWarning
from lattice_cad.lattice import Lattice
from tests.conftest import ROOT


@pytest.fixture(scope="module")
def lat() -> Lattice:
    return Lattice(block("bcc", 2, cell_size=5.0, radius=0.5))


@pytest.fixture(scope="module")
def skinned():
    """A 20 x 16 x 12 mm box, BCC 4 mm cells, skin 1 mm: the wall alone is 20*16*12 - 18*14*10."""
    import cadquery as cq

    return Lattice.fill(cq.Workplane("XY").box(20, 16, 12), "bcc", 4.0, 0.4, skin=1.0)


def _lib3mf_objects(path):
    """(name, vertices, triangles, beams (M, 2) int, radii (M, 2)) of each mesh object, and the
    resource ids of the build items, read with lib3mf's own API (strict mode)."""
    import lib3mf

    model = lib3mf.get_wrapper().CreateModel()
    reader = model.QueryReader("3mf")
    reader.SetStrictModeActive(True)
    reader.ReadFromFile(str(path))
    assert reader.GetWarningCount() == 0
    out = []
    it = model.GetMeshObjects()
    while it.MoveNext():
        obj = it.GetCurrentMeshObject()
        bl = obj.BeamLattice()
        beams = [bl.GetBeam(i) for i in range(bl.GetBeamCount())]
        idx = np.array([[b.Indices[0], b.Indices[1]] for b in beams], dtype=np.int64)
        rad = np.array([[b.Radii[0], b.Radii[1]] for b in beams])
        pos = np.array([[p.Coordinates[k] for k in range(3)] for p in obj.GetVertices()])
        out.append((obj.GetName(), pos.reshape(-1, 3), obj.GetTriangleCount(), idx, rad))
    built = []
    items = model.GetBuildItems()
    while items.MoveNext():
        built.append(items.GetCurrent().GetObjectResource().GetName())
    return out, built


# ------------------------------------------------------------ default: beams + triangles
def test_default_beam_lattice_holds_beams_and_the_printable_mesh(tmp_path, lat):
    p = lat.save(tmp_path / "b.3mf", beam_lattice=True)
    objects, built = _lib3mf_objects(p)
    # one object, in the build: the mesh (for readers without the extension) and the beams
    assert [o[0] for o in objects] == ["lattice"] and built == ["lattice"]
    _, pos, n_tri, idx, rad = objects[0]
    mesh = lat.mesh()
    assert n_tri == len(mesh.faces)
    assert len(idx) == lat.graph.num_edges
    np.testing.assert_allclose(rad, lat.graph.radii)
    # every beam joins the graph's nodes (float32 in 3MF), in the graph's order
    np.testing.assert_allclose(pos[idx[:, 0]], lat.graph.nodes[lat.graph.edges[:, 0]], atol=1e-5)
    np.testing.assert_allclose(pos[idx[:, 1]], lat.graph.nodes[lat.graph.edges[:, 1]], atol=1e-5)
    # the triangles are the checked mesh (lib3mf's decimal writer is within one float32 step)
    v, f = io.read_mesh(p)
    np.testing.assert_allclose(v, mesh.vertices, rtol=2.0**-23, atol=1e-12)
    np.testing.assert_array_equal(f, mesh.faces)
    assert fast_stitch.check((v, f)).valid
    # the extension is still marked required, as the Beam Lattice specification demands
    with zipfile.ZipFile(p) as z:
        head = z.read("3D/3dmodel.model")[:2000].decode()
    assert re.search(r'requiredextensions="[^"]*\bb\b', head)
    info = io.read_beam_lattice(p)
    assert info["triangles"] == len(mesh.faces) and info["clipped"] is False


def test_beam_only_warns_and_is_tiny(tmp_path, lat):
    with pytest.warns(BeamOnlyWarning) as rec:
        p = lat.save(tmp_path / "only.3mf", beam_lattice="only")
    msg = str(rec[0].message)
    for reader in ("PrusaSlicer", "Bambu Studio", "Cura", "Windows 3D Viewer", "Netfabb"):
        assert reader in msg
    assert "only.3mf" in msg and "beam_lattice=True" in msg
    info = io.read_beam_lattice(p)
    assert info["triangles"] == 0 and info["beams"] == lat.graph.num_edges
    full = lat.save(tmp_path / "full.3mf", beam_lattice=True)
    assert p.stat().st_size * 5 < full.stat().st_size


def test_beam_lattice_mode_is_checked(tmp_path, lat):
    with pytest.raises(ValueError, match="beam_lattice must be False, True or 'only'; got 'yes'"):
        lat.save(tmp_path / "b.3mf", beam_lattice="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"cannot save a beam lattice as \.stl"):
        lat.save(tmp_path / "b.stl", beam_lattice="only")


# ----------------------------------------------------------------------------- the skin
@pytest.mark.slow
def test_skin_is_written_in_both_modes(tmp_path, skinned):
    # default: the triangles are the printable mesh, skin included
    p = skinned.save(tmp_path / "s.3mf", beam_lattice=True)
    info = io.read_beam_lattice(p)
    assert info["triangles"] == len(skinned.mesh().faces) > 0
    assert info["beams"] == skinned.graph.num_edges
    v, f = io.read_mesh(p)
    vol = fast_stitch.Mesh(vertices=v, faces=f).volume
    assert vol == pytest.approx(skinned.mesh().volume, rel=1e-6)
    # beams only: the skin is its own object in the build, the part clips the beams
    with pytest.warns(BeamOnlyWarning):
        q = skinned.save(tmp_path / "o.3mf", beam_lattice="only")
    objects, built = _lib3mf_objects(q)
    names = [o[0] for o in objects]
    assert names == ["lattice clipping mesh", "lattice skin", "lattice"]
    assert built == ["lattice skin", "lattice"]
    info = io.read_beam_lattice(q)
    assert info["clipped"] and info["triangles"] == 0 and info["skin_triangles"] > 0
    # the skin object is the wall alone: a closed solid of the box's wall volume
    v, f = io.read_mesh(q)
    assert fast_stitch.check((v, f)).valid
    wall = fast_stitch.Mesh(vertices=v, faces=f).volume
    assert wall == pytest.approx(20 * 16 * 12 - 18 * 14 * 10, rel=0.02)


# ------------------------------------------------------------------ deterministic output
FORMATS = ["stl", "3mf", "ply", "obj", "json", "npz", "beam.3mf", "only.3mf"]


def _write(lat: Lattice, path):
    name = path.name
    if name.endswith("beam.3mf"):
        return lat.save(path, beam_lattice=True)
    if name.endswith("only.3mf"):
        with pytest.warns(BeamOnlyWarning):
            return lat.save(path, beam_lattice="only")
    return lat.save(path)


@pytest.mark.parametrize("fmt", FORMATS)
def test_same_input_same_bytes(tmp_path, lat, monkeypatch, fmt):
    a = _write(lat, tmp_path / f"a.{fmt}").read_bytes()
    # a day later (zip timestamps), in a fresh Lattice (no cached state)
    real = time.time
    monkeypatch.setattr(time, "time", lambda: real() + 86400.5)
    fresh = Lattice(lat.graph, segments=lat.segments)
    b = _write(fresh, tmp_path / f"b.{fmt}").read_bytes()
    assert a == b
    if fmt.endswith("3mf") or fmt == "npz":  # zip archives: no wall-clock time inside
        with zipfile.ZipFile(tmp_path / f"a.{fmt}") as z:
            assert all(i.date_time[0] <= 1980 for i in z.infolist())


def test_3mf_uuids_follow_the_content(tmp_path, lat):
    """UUIDs are valid, unique in a file, and change with the content."""

    def uuids(p):
        with zipfile.ZipFile(p) as z:
            xml = z.read("3D/3dmodel.model").decode()
        return re.findall(r'UUID="([0-9a-f-]+)"', xml)

    a = uuids(lat.save(tmp_path / "a.3mf"))
    other = Lattice(block("bcc", 2, cell_size=5.0, radius=0.45))
    b = uuids(other.save(tmp_path / "b.3mf"))
    c = uuids(lat.save(tmp_path / "c.3mf", beam_lattice=True))
    assert len(a) == 3 and len(set(a)) == 3  # build, object, item
    for u in a + b + c:
        assert str(uuid.UUID(u)) == u
    assert not set(a) & set(b) and not set(a) & set(c)


def test_bytes_do_not_depend_on_the_process(tmp_path, lat):
    """Written by another Python process (new hash seed, new lib3mf instance): same bytes."""
    here = tmp_path / "here"
    there = tmp_path / "there"
    here.mkdir()
    there.mkdir()
    code = (
        "import sys, warnings; warnings.simplefilter('ignore')\n"
        "from pathlib import Path\n"
        "from conformal import block\n"
        "from lattice_cad.lattice import Lattice\n"
        "lat = Lattice(block('bcc', 2, cell_size=5.0, radius=0.5))\n"
        "d = Path(sys.argv[1])\n"
        "for s in ('stl', '3mf', 'ply', 'obj', 'json', 'npz'):\n"
        "    lat.save(d / f'x.{s}')\n"
        "lat.save(d / 'x.beam.3mf', beam_lattice=True)\n"
        "lat.save(d / 'x.only.3mf', beam_lattice='only')\n"
    )
    env = {"PYTHONHASHSEED": "12345", "PYTHONPATH": str(ROOT)}
    subprocess.run([sys.executable, "-c", code, str(there)], check=True, env={**os.environ, **env})
    for fmt in FORMATS:
        mine = _write(lat, here / f"x.{fmt}").read_bytes()
        assert mine == (there / f"x.{fmt}").read_bytes(), fmt


def test_3mf_coordinates_within_one_float32_step(tmp_path, rng):
    """lib3mf's default of 6 decimals moved coordinates below 1 mm by up to ~8,600 float32
    steps; with ``THREEMF_DECIMALS`` every coordinate reads back within one step."""
    v = 10.0 ** rng.uniform(-3, 3, (3000, 3)) * rng.choice([-1.0, 1.0], (3000, 3))
    v = v.astype(np.float32).astype(np.float64)
    f = np.arange(len(v)).reshape(-1, 3)
    p = io.save_mesh((v, f), tmp_path / "c.3mf")
    back, _ = io.read_mesh(p)
    steps = np.abs(
        back.astype(np.float32).view(np.int32).astype(np.int64)
        - v.astype(np.float32).view(np.int32).astype(np.int64)
    )
    assert steps.max() <= 1
