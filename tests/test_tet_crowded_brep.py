"""Tet lattices of a B-rep whose faces' edges crowd the tetrahedra (s41).

A helical gear made outside shared/data (module 2, 24 teeth, its tooth outline a polyline
twisted into 744 narrow B-spline faces) gave, at the parts benchmark's setting (size 3.47,
r 0.289), 29,438 of 35,070 struts thinned beyond 0.7 r in 129 s: gmsh put a node on every
one of its 4,500 edges' ends and every size along them, 4,583 nodes where about 1,000
cover its surface. Such a part's tetrahedra now come from its triangulated surface first
(re-meshed at the size; ``conformal.tet._brep_crowding``).
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

from conformal import load_part
from conformal.tet import _brep_crowding, tet_lattice
from lattice_cad.core import config
from lattice_cad.core.errors import LatticeWarning
from tests.conftest import DATA

pytestmark = pytest.mark.slow


def _gear_outline(m: float, z: int, pa: float = math.radians(20)) -> list[tuple[float, float]]:
    """An involute spur gear's outline as a polyline (10 points per flank, 4 on the tip,
    5 on the root arc): how a gear exported from a sketch of points often comes."""
    r = m * z / 2
    rb, ra, rf = r * math.cos(pa), r + m, r - 1.25 * m

    def inv(a: float) -> float:
        return math.tan(a) - a

    half = math.pi / (2 * z) + inv(pa)

    def phi(radius: float) -> float:
        return half - inv(math.acos(min(1.0, rb / radius)))

    side = [(rf, phi(rb))] + [(q, phi(q)) for q in np.linspace(rb, ra, 10)]
    pitch, pts = 2 * math.pi / z, []
    for k in range(z):
        c = k * pitch
        pts += [(q * math.cos(c - p), q * math.sin(c - p)) for q, p in side]
        pts += [
            (ra * math.cos(c + t), ra * math.sin(c + t))
            for t in np.linspace(-phi(ra), phi(ra), 6)[1:-1]
        ]
        pts += [(q * math.cos(c + p), q * math.sin(c + p)) for q, p in reversed(side)]
        a0, a1 = c + phi(rb), c + pitch - phi(rb)
        pts += [(rf * math.cos(t), rf * math.sin(t)) for t in np.linspace(a0, a1, 7)[1:-1]]
    return pts


@pytest.fixture(scope="module")
def gear(tmp_path_factory):
    cq = pytest.importorskip("cadquery")
    face, beta, m, z = 16.0, math.radians(20), 2.0, 24
    twist = math.degrees(face * math.tan(beta) / (m * z / 2))
    g = cq.Workplane("XY").polyline(_gear_outline(m, z)).close().twistExtrude(face, twist)
    g = g.union(cq.Workplane("XY").circle(15).extrude(8).translate((0, 0, face)))
    g = g.cut(cq.Workplane("XY").circle(6).extrude(40).translate((0, 0, -5)))
    path = tmp_path_factory.mktemp("gear") / "helical_gear.step"
    cq.exporters.export(g, str(path), exportType="STEP")
    return load_part(path)


def test_a_crowded_b_rep_is_meshed_from_its_surface(gear):
    size = float(gear.size.max()) / 15  # the parts benchmark's: 3.47
    forced, iso = _brep_crowding(gear, size)
    assert forced > config.TET_BREP_CROWDING * iso  # 4,5xx against ~1,000
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LatticeWarning)
        g, rep = tet_lattice(gear, size=size, radius=size / 12, return_report=True)
    said = [str(w.message) for w in caught]
    crowd = [w for w in said if "would crowd the tetrahedra's nodes" in w]
    assert len(crowd) == 1 and f"{forced:,} nodes on them" in crowd[0], said
    # from the B-rep: 84 % of the struts beyond the tolerance, strut median 0.68 mm long;
    # from the surface: 28 %, 1.6 mm (the teeth, 3 mm thick at the pitch circle, 1.4 mm
    # at the tip, still crowd 2 mm struts of radius 0.29)
    assert rep.thinned_beyond_tolerance < 0.4 * g.num_edges
    lengths = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    assert float(np.median(lengths)) > 0.35 * size
    thin = [w for w in said if "had to be made thinner" in w]
    assert all("follow the edges of its faces" not in w for w in thin)  # (not its B-rep's)
    assert all(re.search(r"the surface gmsh re-meshed", w) for w in thin)


def test_the_shared_b_reps_are_not_crowded():
    """Every shared STEP part at the benchmark's tet size keeps its B-rep first (their
    ratios are 0.25-2.5): the pre-check changes none of their tet lattices."""
    for path in sorted((DATA / "step").iterdir()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LatticeWarning)  # (solids united, ...)
            part = load_part(path)
        size = float(part.size.max()) / 15
        forced, iso = _brep_crowding(part, size)
        assert forced <= config.TET_BREP_CROWDING * iso, (path.name, forced, iso)
