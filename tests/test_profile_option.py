"""The stitched strut profile is a user option (issue 14 item 3: "keep the inscribed profile
as an option"): ``Lattice(profile=...)``, ``Lattice.fill(profile=...)``, ``--profile``.

The default ``"volume"`` gives the exact design's volume by scaling each hub, which on
irregular nodes leaves a neck where struts meet their hub; ``"area"`` has no neck and is
heavier, ``"inscribed"`` is lighter. Checked on a real part (kcl_bracket, tet) with trimesh.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import trimesh

import fast_stitch
from conformal import load_part
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

pytestmark = pytest.mark.filterwarnings("ignore::lattice_cad.core.errors.LatticeWarning")
PART = DATA / "step" / "kcl_bracket.step"


@pytest.fixture(scope="module")
def tet_graph():
    part = load_part(PART)
    cell = float(np.max(part.size)) / 8
    return Lattice.fill(part, cell_size=cell, radius=cell / 12, method="tet", trim=False).graph


def test_profiles_order_the_volume_and_match_the_estimate(tet_graph):
    vol, tri = {}, {}
    for prof in ("inscribed", "volume", "area", "circumscribed"):
        lat = Lattice(tet_graph, profile=prof)
        m = lat.mesh()
        tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
        assert tm.is_watertight and tm.is_winding_consistent
        vol[prof], tri[prof] = tm.volume, len(m.faces)
        assert tri[prof] == fast_stitch.estimate(tet_graph, 6, prof).triangles
        assert lat.info()["profile"] == prof
        assert (prof == "volume") != (f"profile={prof!r}" in repr(lat))
    # the default's hubs are scaled down to the exact node volume: area (unscaled) is heavier;
    # inscribed struts are thinner than area's (its unscaled hubs may outweigh "volume")
    assert vol["volume"] < vol["area"] < vol["circumscribed"]
    assert vol["inscribed"] < vol["area"]
    # only the default has band rings (twice the strut vertices)
    assert tri["volume"] > tri["area"] == tri["inscribed"]


def test_profile_is_checked():
    with pytest.raises(ValueError, match="profile"):
        Lattice.fill(PART, cell_size=10, radius=1, profile="round")


def test_cli_profile_option(tmp_path):
    out = {}
    for prof in ("volume", "area"):
        path = tmp_path / f"{prof}.stl"
        r = subprocess.run(
            [sys.executable, "-m", "lattice_cad.cli", "fill", str(PART), "--method", "tet",
             "--cell-size", "12", "--radius", "1", "--profile", prof, "-o", str(path)],
            capture_output=True, text=True, cwd=tmp_path,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        out[prof] = trimesh.load(path)
        assert out[prof].is_watertight
    assert out["area"].volume > out["volume"].volume
