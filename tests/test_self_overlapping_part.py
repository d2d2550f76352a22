"""A part whose surface crosses itself (regression, s22's parts made outside shared/data).

A pipe elbow swept by CadQuery along a path whose arc bent the wrong way (kinks at both
ends; ``regression_folded_pipe_elbow.step``, made by a helper in s22) is a solid
BRepCheck accepts, but its surface folds over itself. ``load_part`` said
nothing; a fill's cut to it failed, and the lattice was written uncut with a "NOT cut"
line blaming float32 rounding. Now the load warns where the surface crosses itself, and
the trim's reason names the part; a cut that crosses itself is given up at once.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from conformal import load_part
from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning

FOLDED = Path(__file__).parent / "regression_folded_pipe_elbow.step"  # made by CadQuery


def _elbow():
    """A tube (OD 20, wall 2) swept along a leg, a 40 mm arc tangent to it and a leg, with
    a flange at each end: its surface does not cross itself."""
    import cadquery as cq

    path = cq.Workplane("XZ").moveTo(0, 0).lineTo(0, 30).radiusArc((40, 70), 40).lineTo(70, 70)
    tube = cq.Workplane("XY").circle(10).circle(8).sweep(path, transition="round")
    flange1 = cq.Workplane("XY").circle(16).circle(8).extrude(4)
    flange2 = cq.Workplane("YZ").workplane(offset=66).center(0, 70).circle(16).circle(8).extrude(4)
    return tube.union(flange1).union(flange2).val()


def _pymeshlab_crossing_faces(part) -> int:
    """Faces pymeshlab flags as self-intersecting that the exact arbiter confirms (it also
    flags coplanar neighbours sharing a vertex: ``tests/exact_intersect.py``)."""
    import pymeshlab

    from tests.exact_intersect import confirmed_faces

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(part.vertices, part.faces.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    flagged = np.flatnonzero(ms.current_mesh().face_selection_array())
    return len(confirmed_faces(part.vertices, part.faces, flagged[:300]))


@pytest.mark.slow
def test_a_folded_sweep_is_said_at_load_and_named_when_its_cut_fails(monkeypatch):
    """... and its cut, which crosses itself before any rounding, is given up at once:
    no collapse of float32 folds and no second cut off the surface (they took 73 of the
    CLI's 87 s, for the same uncut lattice)."""
    from OCP.BRepCheck import BRepCheck_Analyzer

    import lattice_cad.lattice as lattice_module
    from lattice_cad.occ_impl.step import read_step

    assert BRepCheck_Analyzer(read_step(FOLDED)).IsValid()  # "valid" to OCCT
    with pytest.warns(LatticeWarning, match=r"surface crosses itself \((\d+) pair") as said:
        part = load_part(FOLDED)
    pairs, at = part.self_crossings
    assert pairs > 100 and str(pairs) in str(said[0].message)
    assert np.isfinite(at).all() and part.contains(at[None]).size == 1
    assert _pymeshlab_crossing_faces(part) > 100  # independent: the surface does cross

    with pytest.warns(LatticeWarning, match="thinned"):
        lat = Lattice.fill(part, cell="bcc", cell_size=8.0, radius=0.6)

    def futile(*args, **kwargs):
        raise AssertionError("a cut that crosses itself was rounded, collapsed or cut again")

    monkeypatch.setattr(lattice_module, "_checked_single_precision", futile)
    monkeypatch.setattr(Lattice, "_retrim", futile)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        mesh = lat.mesh()
    rep = lat.trim_report
    assert rep is not None and rep.failed, rep.summary()
    assert rep.failed.startswith("the part's surface crosses itself")
    assert "single precision" not in rep.summary() and "NOT cut" in rep.summary()
    assert len(mesh.faces) > 0  # the lattice is written uncut, as the summary says


def test_a_sweep_that_does_not_fold_loads_without_a_word():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        part = load_part(_elbow())
    assert part.self_crossings[0] == 0 and np.isnan(part.self_crossings[1]).all()
    assert part.crossing_note() == ""
    assert _pymeshlab_crossing_faces(part) == 0


@pytest.mark.slow
def test_a_skin_of_a_folded_sweep_is_refused_with_the_reason():
    """Regression: a skin of the folded elbow (the parts benchmark's setting: octet, cell
    extent / 15, skin cell / 6) ran the booleans on the whole lattice (the tube is too
    thin for the split) with an outer wall that crosses itself: more than 10 minutes, then
    the benchmark's timeout. That wall bounds no solid, so the skin now stops there with
    the reason and what to do."""
    from conformal import skin as _skin
    from conformal import voxel_lattice
    from lattice_cad.core.errors import SkinError

    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        graph = voxel_lattice(part, "octet", cell, cell / 12, fill="clip")
    import fast_stitch

    lattice = fast_stitch.stitch(graph)
    with pytest.raises(SkinError, match=r"surface crosses itself \(\d+ pair.*repair"):
        _skin.build_skin(lattice, part, cell / 6, method="voxel", check=False)


def test_a_skin_of_a_folded_part_is_refused_before_its_walls_are_built(monkeypatch):
    """Regression (s26): ``Lattice.fill(skin=)`` of the folded elbow waited for OCCT's
    offset attempts and the voxel walls (21 of the run's 30 s) before ``build_skin``
    refused it. Both tessellations a skin can be built on (the load's: 557 pairs; the
    cutting one: about 2,378) cross themselves, so the skinned mesh could never be written:
    it is refused before any wall is built, OCCT's child closed."""
    from conformal import skin as _skin
    from lattice_cad.core.errors import SkinError

    def no_walls(*args, **kwargs):
        raise AssertionError("the walls were built for a skin that cannot be written")

    monkeypatch.setattr(_skin, "_surfaces", no_walls)
    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="octet", cell_size=cell, radius=cell / 12, skin=cell / 6)
        pending = lat._pending_offsets  # OCCT's offsets, started in a child at the fill
        assert pending is not None and pending.worker.submitted
        with pytest.raises(SkinError, match=r"surface crosses itself \(\d+ pair.*repair"):
            lat.mesh()
    assert pending.worker._pool is None  # closed, not left to finish its attempts


def test_a_scan_that_crosses_itself_in_a_few_places_is_still_cut(tmp_path):
    """The shared hi-res bunny with vertex noise of 0.2 of its edges crosses itself in 25
    triangle pairs; its clip's cut crosses itself in 4 of 140,520 triangles before any
    rounding, needles the fold collapses remove. s24's early give-up took any crossing in
    the cut as hopeless and wrote the lattice uncut (a noisy genus-2 scan made outside
    shared/data: 143 % of r out of the part); only a cut with more than
    ``config.TRIM_HOPELESS_SHARE`` of its triangles crossing is given up at once now."""
    import trimesh

    import fast_stitch
    from tests.conftest import DATA, independent_check

    clean = load_part(DATA / "meshes" / "bunny_closed_hr_odedstein.obj")
    v, f = clean.vertices, clean.faces
    edge = float(np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1).mean())
    noisy = v + np.random.default_rng(0).normal(scale=0.2 * edge, size=v.shape)
    path = tmp_path / "noisy_bunny.stl"
    trimesh.Trimesh(noisy, f, process=False).export(path)
    with pytest.warns(LatticeWarning, match=r"surface crosses itself \(\d+ pair"):
        part = load_part(path)
    assert part.self_crossings[0] > 0
    h = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # thinned struts
        lat = Lattice.fill(part, "bcc", h, h / 12, fill="clip")
        mesh = lat.mesh()
    rep = lat.trim_report
    assert not rep.failed, rep.failed
    assert rep.protrusion_after <= rep.tolerance, rep.summary()
    assert fast_stitch.check(mesh).valid
    independent_check(mesh)


def test_a_fill_of_a_folded_brep_is_not_cut_and_no_cutting_tessellation_is_made(monkeypatch):
    """Regression (s27): a cabinet handle swept along a looping path (made outside
    shared/data) crosses itself in 21 % of its triangles at load; each fill spent 88-237 s
    making the chord-checked cutting tessellation (411 K triangles, still crossing) before
    the cut was given up and the lattice written uncut. A B-rep whose tessellation crosses
    itself in more than ``config.TRIM_HOPELESS_SHARE`` of its triangles, and still does
    four times finer (``Part.folds``), is written uncut at once with the same reason; its
    skin is refused at once."""
    import fast_stitch
    from conformal import trim
    from lattice_cad.core.errors import SkinError

    def no_cutting_part(*args, **kwargs):
        raise AssertionError("a cutting tessellation was made for a folded B-rep")

    monkeypatch.setattr(trim, "cutting_part", no_cutting_part)
    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    assert part.folds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="bcc", cell_size=8.0, radius=0.6, fill="clip")
        mesh = lat.mesh()
    rep = lat.trim_report
    assert rep.failed.startswith("the part's surface crosses itself"), rep.summary()
    assert "bounds no solid" in rep.failed and "NOT cut" in rep.summary()
    assert rep.protrusion_before > 0 and rep.bodies >= 1
    assert fast_stitch.check(mesh).valid  # the stitched lattice, written as it is
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        skinned = Lattice.fill(part, cell="octet", cell_size=8.0, radius=0.6, skin=1.5)
        pending = skinned._pending_offsets
        with pytest.raises(SkinError, match=r"surface crosses itself \(\d+ pair.*repair"):
            skinned.mesh()
    assert pending is None or pending.worker._pool is None  # OCCT's child closed


def test_a_tessellation_that_crosses_itself_only_at_its_chords_is_not_a_fold():
    """``Part.folds`` looks again four times finer: crossings that go away there are the
    chords' (simulated: a clean B-rep said to cross itself in 5 % of its triangles), and a
    mesh part is never judged a fold without its cut."""
    from tests.conftest import DATA

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # 3 solids united
        part = load_part(DATA / "step" / "kcl_flange-with-patterns.step")
    part.__dict__["self_crossings"] = (int(0.05 * len(part.faces)), part.vertices[0])
    assert not part.folds
    mesh = load_part(DATA / "meshes" / "bunny_closed_odedstein.obj")
    mesh.__dict__["self_crossings"] = (int(0.05 * len(mesh.faces)), mesh.vertices[0])
    assert not mesh.folds
