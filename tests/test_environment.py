"""The installed CAD stack is one consistent OpenCascade build (issue: fresh install).

These fail loudly in an environment where two distributions write the same ``OCP`` package
(``cadquery-ocp`` and ``cadquery-ocp-novtk``), which made ``import build123d`` fail and
loaded inch STEP files 25.4 times too large.
"""

from __future__ import annotations

import importlib.metadata as md
import re
import subprocess
import sys
from pathlib import Path

import tomllib
from packaging.requirements import Requirement
from packaging.version import Version

from lattice_cad.occ_impl import stack as _stack

ROOT = Path(__file__).resolve().parents[1]


def test_exactly_one_distribution_provides_ocp():
    assert _stack.ocp_distributions() == ["cadquery-ocp"]


def test_installed_stack_has_no_problems():
    assert _stack.problems() == []


def test_cadquery_and_build123d_use_the_same_opencascade():
    # a fresh interpreter: import order and earlier imports cannot hide a broken install
    code = (
        "import warnings; warnings.simplefilter('ignore', DeprecationWarning)\n"
        "import cadquery as cq, build123d as bd, OCP\n"
        "from OCP.TopoDS import TopoDS_Shape\n"
        "a = cq.Workplane().box(1, 2, 3).val()\n"
        "b = bd.Box(1, 2, 3)\n"
        "assert isinstance(a.wrapped, TopoDS_Shape) and isinstance(b.wrapped, TopoDS_Shape)\n"
        "print(OCP.__version__, round(a.Volume(), 9), round(b.volume, 9))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    ocp_version, cq_volume, bd_volume = out.stdout.split()
    assert float(cq_volume) == float(bd_volume) == 6.0
    installed = Version(md.version("cadquery-ocp"))
    assert Version(ocp_version).release[:3] == installed.release[:3]
    # both libraries declare the OCP distribution they need; the installed one satisfies both
    for lib in ("cadquery", "build123d"):
        reqs = [Requirement(r) for r in md.requires(lib) or []]
        ocp = [r for r in reqs if r.name.startswith("cadquery-ocp") and not r.marker]
        assert [r.name for r in ocp] == ["cadquery-ocp"], (lib, ocp)
        assert ocp[0].specifier.contains(installed, prereleases=True), (lib, ocp[0], installed)


def test_supported_ranges_match_pyproject():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    spec = {Requirement(d).name: str(Requirement(d).specifier) for d in deps}
    for name, (lo, hi) in _stack.SUPPORTED.items():
        assert set(spec[name].split(",")) == {f">={lo}", f"<{hi}"}, name


def test_constraints_pin_the_supported_stack():
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        m = re.match(r"^([A-Za-z0-9_.\-]+)==(\S+)", line)
        if m:
            pins[m.group(1).lower().replace("_", "-")] = Version(m.group(2))
    assert "cadquery-ocp-novtk" not in pins and "cadquery-ocp-proxy" not in pins
    for name, (lo, hi) in _stack.SUPPORTED.items():
        assert Version(lo) <= pins[name] < Version(hi), name
