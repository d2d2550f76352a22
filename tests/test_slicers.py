"""Real slicers open what lattice-cad writes (issue 13 item 8): PrusaSlicer and CuraEngine
slice STL, 3MF and the default beam-lattice 3MF, and the G-code covers the whole part.

These programs are part of the test suite, as ``../shared/data`` is: a missing one is a
failure, never a skip (``.ci/run`` installs them). CuraEngine needs Cura's printer
definitions (``fdmprinter.def.json``), found in ``$LATTICE_CAD_CURA_DEFINITIONS`` or where
Debian's ``cura`` package puts them (``/usr/share/cura/resources/definitions``).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conformal import block
from lattice_cad.core.errors import BeamOnlyWarning
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

CURA_DEFINITIONS_ENV = "LATTICE_CAD_CURA_DEFINITIONS"
CURA_DEFINITIONS_DEFAULT = Path("/usr/share/cura/resources/definitions")


def _program(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        pytest.fail(
            f"{name} is not installed; the slicer tests need it "
            "(Debian: apt-get install prusa-slicer cura-engine; .ci/run does this)"
        )
    return path


@pytest.fixture(scope="module")
def prusa() -> str:
    return _program("prusa-slicer")


@pytest.fixture(scope="module")
def cura() -> tuple[str, Path]:
    exe = _program("CuraEngine")
    d = Path(os.environ.get(CURA_DEFINITIONS_ENV, CURA_DEFINITIONS_DEFAULT))
    if not (d / "fdmprinter.def.json").is_file():
        pytest.fail(
            f"Cura's printer definitions are missing: no fdmprinter.def.json in {d} "
            f"(Debian package `cura`, or set {CURA_DEFINITIONS_ENV} to a directory holding "
            "the definitions of its .deb; .ci/run does this)"
        )
    return exe, d / "fdmprinter.def.json"


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A 2 x 2 x 2 BCC block (5 mm cells, radius 0.5) in every mesh format."""
    d = tmp_path_factory.mktemp("small")
    lat = Lattice(block("bcc", 2, cell_size=5.0, radius=0.5))
    files = {s: lat.save(d / f"small.{s}") for s in ("stl", "3mf", "obj", "ply")}
    files["beam.3mf"] = lat.save(d / "small.beam.3mf", beam_lattice=True)
    with pytest.warns(BeamOnlyWarning):
        files["only.3mf"] = lat.save(d / "small.only.3mf", beam_lattice="only")
    return lat.mesh(), files


@pytest.fixture(scope="module")
def screw(tmp_path_factory):
    """A real part: the socket-head cap screw (kcl) filled with 3 mm BCC cells."""
    d = tmp_path_factory.mktemp("screw")
    lat = Lattice.fill(DATA / "step" / "kcl_socket-head-cap-screw.step", "bcc", 3.0, 0.4)
    return lat.mesh(), {
        "stl": lat.save(d / "screw.stl"),
        "beam.3mf": lat.save(d / "screw.beam.3mf", beam_lattice=True),
    }


def _height(mesh) -> float:
    return float(mesh.vertices[:, 2].max() - mesh.vertices[:, 2].min())


# ------------------------------------------------------------------------- PrusaSlicer
def _prusa(exe: str, src: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    out = tmp_path / (src.name + ".gcode")
    return subprocess.run(
        [exe, "--datadir", str(tmp_path / "prusa-datadir"), "--export-gcode", str(src),
         "-o", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip


def _prusa_gcode(exe: str, src: Path, tmp_path: Path) -> dict:
    """Slice with PrusaSlicer's defaults; what the G-code says about the part."""
    run = _prusa(exe, src, tmp_path)
    assert run.returncode == 0, run.stderr[-2000:] + run.stdout[-2000:]
    text = (tmp_path / (src.name + ".gcode")).read_text(encoding="utf-8")
    setting = {
        k: float(v)
        for k, v in re.findall(r"^; (layer_height|first_layer_height|filament_diameter) = ([\d.]+)",
                               text, re.M)
    }  # fmt: skip
    filament = float(re.search(r"^; filament used \[mm\] = ([\d.]+)", text, re.M).group(1))
    return {
        "layers": text.count(";LAYER_CHANGE"),
        "top": max(float(z) for z in re.findall(r"^;Z:([\d.]+)", text, re.M)),
        "extrusions": len(re.findall(r"^G1 [^;\n]*E[\d.]", text, re.M)),
        "volume": filament * math.pi * setting["filament_diameter"] ** 2 / 4,
        **setting,
    }


MESH_FORMATS = ("stl", "3mf", "beam.3mf", "obj")


@pytest.fixture(scope="module")
def prusa_small(prusa, small, tmp_path_factory) -> dict:
    """PrusaSlicer's G-code of the small block in each format PrusaSlicer reads."""
    d = tmp_path_factory.mktemp("prusa")
    return {fmt: _prusa_gcode(prusa, small[1][fmt], d) for fmt in MESH_FORMATS}


@pytest.mark.parametrize("fmt", MESH_FORMATS)
def test_prusaslicer_slices_the_whole_lattice(prusa_small, small, fmt):
    mesh, _ = small
    g = prusa_small[fmt]
    height = _height(mesh)  # 10.79 mm
    # every layer up to the top of the part, and not beyond
    assert abs(g["top"] - height) <= g["layer_height"]
    assert g["layers"] >= (height - g["first_layer_height"]) / g["layer_height"]
    assert g["extrusions"] > 50 * g["layers"]
    # it extrudes about the volume of the lattice (thin struts: mostly perimeters)
    assert g["volume"] == pytest.approx(mesh.volume, rel=0.25)


def test_prusaslicer_sees_the_same_solid_in_every_mesh_format(prusa_small):
    """STL, 3MF, the default beam-lattice 3MF (its triangles) and OBJ give the same print."""
    stl = prusa_small["stl"]
    for fmt in MESH_FORMATS:
        assert prusa_small[fmt]["layers"] == stl["layers"], fmt
        assert prusa_small[fmt]["volume"] == pytest.approx(stl["volume"], rel=1e-3), fmt


def test_prusaslicer_refuses_beam_only_and_ply(prusa, small, tmp_path):
    """Why ``beam_lattice="only"`` warns, and why the docs send PLY elsewhere."""
    _, files = small
    run = _prusa(prusa, files["only.3mf"], tmp_path)
    assert run.returncode != 0
    assert "invalid object id" in run.stderr + run.stdout
    run = _prusa(prusa, files["ply"], tmp_path)
    assert run.returncode != 0
    assert "Unknown file format" in run.stderr + run.stdout


def test_prusaslicer_slices_a_real_part(prusa, screw, tmp_path):
    mesh, files = screw
    g = _prusa_gcode(prusa, files["beam.3mf"], tmp_path)
    assert abs(g["top"] - _height(mesh)) <= g["layer_height"]
    assert g["volume"] == pytest.approx(mesh.volume, rel=0.35)


# -------------------------------------------------------------------------- CuraEngine
def _cura(cura: tuple[str, Path], src: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    exe, definitions = cura
    out = tmp_path / (src.name + ".gcode")
    # center_object: on the build plate, as Cura's front end places it
    return subprocess.run(
        [exe, "slice", "-j", str(definitions), "-s", "center_object=true", "-l", str(src),
         "-o", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip


def _cura_gcode(cura: tuple[str, Path], src: Path, tmp_path: Path) -> dict:
    run = _cura(cura, src, tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    text = (tmp_path / (src.name + ".gcode")).read_text(encoding="utf-8")
    # the moves of the print: from the first layer to the last (not the start/end G-code)
    body = text[text.index(";LAYER:0") : text.rindex(";TIME_ELAPSED:")]
    zs = [float(z) for z in re.findall(r"^G[01] [^;\n]*Z([\d.]+)", body, re.M)]
    return {
        "layer_count": int(re.search(r"^;LAYER_COUNT:(\d+)", text, re.M).group(1)),
        "layers": len(re.findall(r"^;LAYER:\d+", text, re.M)),
        "top": max(zs),
        "extrusions": len(re.findall(r"^G1 [^;\n]*E[\d.]", text, re.M)),
    }


def test_curaengine_slices_the_whole_lattice(cura, small, tmp_path):
    mesh, files = small
    g = _cura_gcode(cura, files["stl"], tmp_path)
    height = _height(mesh)
    # fdmprinter defaults: first layer 0.3 mm, then 0.1 mm
    assert abs(g["top"] - height) <= 0.35
    assert g["layers"] >= (height - 0.3) / 0.1 - 3
    assert g["extrusions"] > 50 * g["layers"]


def test_curaengine_slices_a_real_part(cura, screw, tmp_path):
    mesh, files = screw
    g = _cura_gcode(cura, files["stl"], tmp_path)
    assert abs(g["top"] - _height(mesh)) <= 0.35
    assert g["extrusions"] > 10 * g["layers"]


def test_curaengine_reads_stl_only(cura, small, tmp_path):
    """CuraEngine's command line loads STL only (Cura's 3MF reader is in its front end)."""
    _, files = small
    for fmt in ("3mf", "beam.3mf", "obj"):
        run = _cura(cura, files[fmt], tmp_path)
        assert "only .stl and .STL are supported" in run.stderr + run.stdout, fmt
