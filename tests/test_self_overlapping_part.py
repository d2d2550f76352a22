"""A part whose surface crosses itself (regression, s22's parts made outside shared/data).

A pipe elbow swept by CadQuery along a path whose arc bent the wrong way (kinks at both
ends; ``regression_folded_pipe_elbow.step``, made by a helper in s22) is a solid
BRepCheck accepts, but its surface folds over itself. ``load_part`` said
nothing; a fill's cut to it failed, and the lattice was written uncut with a "NOT cut"
line blaming float32 rounding. Now the load warns where the surface crosses itself, and
the trim's reason names the part; a cut that crosses itself is given up at once.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from conformal import load_part
from conformal.trim import protrusion
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
def test_a_folded_sweep_is_said_at_load_and_its_fill_is_cut_by_its_rebuild():
    """The load says where the surface crosses itself (pymeshlab agrees, independently);
    a fill of it (conform: a tube too thin for whole cells) is cut by the surface rebuilt
    from the region it encloses (``conformal.unfold``; before s28 it was written uncut,
    more than three radii out of the part), and the report says so."""
    from OCP.BRepCheck import BRepCheck_Analyzer

    from lattice_cad.occ_impl.step import read_step
    from tests.conftest import assert_valid

    assert BRepCheck_Analyzer(read_step(FOLDED)).IsValid()  # "valid" to OCCT
    with pytest.warns(LatticeWarning, match=r"surface crosses itself \((\d+) pair") as said:
        part = load_part(FOLDED)
    pairs, at = part.self_crossings
    assert pairs > 100 and str(pairs) in str(said[0].message)
    assert np.isfinite(at).all() and part.contains(at[None]).size == 1
    assert _pymeshlab_crossing_faces(part) > 100  # independent: the surface does cross

    with pytest.warns(LatticeWarning, match="thinned"):
        lat = Lattice.fill(part, cell="bcc", cell_size=8.0, radius=0.6)
    # (s30) out of the part by more than the tolerance: said in a warning, not only in the
    # trim's line, with how far
    with pytest.warns(LatticeWarning, match=r"the lattice stands up to ([\d.]+) mm out") as out:
        mesh = lat.mesh()
    rep = lat.trim_report
    said = re.search(r"stands up to ([\d.]+) mm", str(out[0].message))
    assert said and float(said.group(1)) == pytest.approx(rep.protrusion_after, rel=1e-2)
    assert rep.protrusion_after > rep.tolerance
    assert not rep.failed and rep.trimmed and rep.rebuilt > 0, rep.summary()
    assert "rebuilt on a" in rep.summary() and "NOT cut" not in rep.summary()
    # against the part as loaded: out by less than the grid's spacing (at concave creases:
    # 0.22 mm at 0.32), where the uncut lattice stood out by more than three radii
    assert rep.protrusion_before > 3 * 0.6
    assert rep.protrusion_after < rep.rebuilt, rep.summary()
    assert rep.bodies == 1
    assert_valid(mesh)


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


HANDLE = Path(__file__).parent / "regression_swept_handle.step"  # made by CadQuery (s26)


@pytest.mark.slow
def test_a_skin_of_a_folded_part_is_built_on_its_rebuild():
    """Regression (s26-s28): ``Lattice.fill(skin=)`` of a folded B-rep (the cabinet handle
    swept along a looping path, made outside shared/data) waited for OCCT's offsets and
    the walls, then was refused (s27: refused at once): both tessellations a skin could be
    built on cross themselves. Its outside is now the surface rebuilt from the region the
    part encloses, the skin the voxel method's on it; OCCT's child is closed; one body,
    valid to the independent checkers, and the report says so."""
    from tests.conftest import assert_valid

    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(HANDLE)
    assert part.folds
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="octet", cell_size=cell, radius=cell / 12, skin=cell / 6)
        pending = lat._pending_offsets  # OCCT's offsets, started in a child at the fill
        assert pending is not None and pending.worker.submitted
        mesh = lat.mesh()
    assert pending.worker._pool is None  # closed, not left to finish its attempts
    rep = lat.skin_report
    assert rep.method == "voxel" and rep.rebuilt > 0 and rep.bodies == 1, rep.summary()
    assert "folds over itself" in rep.summary()
    assert abs(rep.wall["median"] - cell / 6) < 0.02 * cell / 6, rep.summary()
    assert_valid(mesh)


@pytest.mark.slow
def test_a_skin_of_a_thin_walled_folded_part_is_refused_without_the_whole_booleans(
    monkeypatch,
):
    """The folded elbow (a 2 mm tube wall) with the benchmark's skin (0.96 mm) leaves a
    0.1 mm cavity on its rebuild, and the lattice near the wall cannot be split off: the
    booleans on the whole lattice then fell into 3,043 pieces that float32 could not hold,
    refused after 201 s. Refused before those booleans now, saying why and what to do."""
    from conformal import skin as _skin
    from lattice_cad.core.errors import SkinError

    def no_whole_booleans(*args, **kwargs):
        raise AssertionError("the booleans on the whole lattice ran")

    monkeypatch.setattr(_skin, "_keep_attached", no_whole_booleans)
    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="octet", cell_size=cell, radius=cell / 12, skin=cell / 6)
        with pytest.raises(SkinError, match=r"folds over itself.*rebuilt on a .* too thin"):
            lat.mesh()


def test_a_scan_that_crosses_itself_in_a_few_places_is_still_cut(tmp_path):
    """The shared hi-res bunny with vertex noise of 0.2 of its edges crosses itself in 25
    triangle pairs; its clip's cut crosses itself in 4 of 140,520 triangles before any
    rounding, needles the fold collapses remove. s24's early give-up took any crossing in
    the cut as hopeless and wrote the lattice uncut (a noisy genus-2 scan made outside
    shared/data: 143 % of r out of the part); only a cut with more than
    ``config.TRIM_HOPELESS_SHARE`` of its triangles crossing is given up at once now."""
    import trimesh

    import fast_stitch
    from tests.conftest import DATA, assert_valid

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
    assert_valid(mesh)


def test_a_fill_of_a_folded_brep_is_cut_by_its_rebuild_without_a_cutting_tessellation(
    monkeypatch,
):
    """Regression (s27, s28): a cabinet handle swept along a looping path (made outside
    shared/data) crosses itself in 21 % of its triangles at load; each fill spent 88-237 s
    making the chord-checked cutting tessellation (411 K triangles, still crossing) before
    the cut was given up and the lattice written uncut. A B-rep that folds (``Part.folds``)
    gets no such tessellation: the lattice is cut by the surface rebuilt from the region it
    encloses (``conformal.unfold.rebuilt_part``), which does not cross itself."""
    import fast_stitch
    from conformal.part import Part

    refined = Part.refined

    def unchecked_only(self, *args, **kwargs):
        if kwargs.get("checked", True):
            raise AssertionError("a chord-checked tessellation was made for a folded B-rep")
        return refined(self, *args, **kwargs)

    monkeypatch.setattr(Part, "refined", unchecked_only)
    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    assert part.folds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="bcc", cell_size=8.0, radius=0.6, fill="clip")
        mesh = lat.mesh()
    cut = lat._cutting_part
    assert cut.rebuilt > 0 and cut.shape is None
    assert cut.self_crossings[0] == 0  # the rebuild does not cross itself
    rep = lat.trim_report
    assert not rep.failed and rep.rebuilt == cut.rebuilt, rep.summary()
    assert rep.protrusion_after < 0.2 * rep.protrusion_before, rep.summary()
    assert fast_stitch.check(mesh).valid


def test_a_rebuild_keeps_the_cavity_of_a_part_and_drops_the_pockets_of_its_folds():
    """``conformal.unfold.rebuilt_part`` of a hollow ball (an inner shell: a cavity the part
    has) keeps the cavity, its volume the shell's within the grid's accuracy. A void of a
    rebuild where the part has no inner shell is a pocket of winding number 0 that a fold
    encloses (the swept handle: two of 0.1 mm, which a skin walled and measured at
    0.085 mm): dropped."""
    import trimesh

    from conformal.part import Part
    from conformal.skin_split import pieces
    from conformal.unfold import _without_fold_pockets, rebuilt_part

    def ball_with_void(void_radius):
        outer = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
        void = trimesh.creation.icosphere(subdivisions=4, radius=void_radius)
        v = np.vstack([outer.vertices, void.vertices])
        f = np.vstack([outer.faces, void.faces[:, ::-1] + len(outer.vertices)])
        return Part(v, f, name="hollow ball"), Part(outer.vertices, outer.faces, name="ball")

    hollow, ball = ball_with_void(6.0)
    rebuilt = rebuilt_part(hollow, spacing=0.4)
    n, _, vols = pieces(rebuilt.vertices, rebuilt.faces)
    exact = 4.0 / 3.0 * np.pi * (10.0**3 - 6.0**3)
    assert n == 2 and (vols < 0).sum() == 1  # the cavity kept
    assert abs(vols.sum() - exact) < 0.02 * exact
    assert rebuilt.self_crossings[0] == 0 and rebuilt.rebuilt == 0.4

    # the same void in a rebuild of a part without it (no inner shell there): a pocket
    v, f = _without_fold_pockets(hollow.vertices, hollow.faces, ball, 0.4)
    n, _, vols = pieces(v, f)
    assert n == 1 and vols[0] > 0 and len(f) == len(ball.faces)
    v, f = _without_fold_pockets(hollow.vertices, hollow.faces, hollow, 0.4)
    assert len(f) == len(hollow.faces)  # at the part's inner shell: kept


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


@pytest.mark.slow
def test_a_mesh_part_that_folds_is_cut_and_skinned_by_its_rebuild(tmp_path):
    """The swept handle's tessellation as an STL (a mesh part: no finer tessellation to look
    at, 4,022 crossing pairs): its conform fill's cut crossed itself and the lattice was
    written uncut; its skin was refused (``skin.folded_wall``). Both are now made on the
    surface rebuilt from the region it encloses (``Lattice._rebuilt_part``), valid to the
    independent checkers, one body each."""
    import trimesh

    from tests.conftest import assert_valid

    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        brep = load_part(HANDLE)
    path = tmp_path / "folded_handle.stl"
    trimesh.Trimesh(brep.vertices, brep.faces, process=False).export(path)
    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(path)
    assert part.shape is None and part.self_crossings[0] > 100 and not part.folds
    cell = float(part.size.max()) / 15
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", LatticeWarning)
        lat = Lattice.fill(part, "bcc", cell, cell / 12, fill="conform")
        mesh = lat.mesh()
    rep = lat.trim_report
    assert not rep.failed and rep.rebuilt > 0 and rep.bodies == 1, rep.summary()
    assert rep.protrusion_after < rep.rebuilt < rep.protrusion_before, rep.summary()
    out = protrusion(part, mesh.vertices)  # (the file's, against the part as loaded)
    assert out == pytest.approx(rep.protrusion_after, rel=1e-3, abs=1e-6)
    assert out > rep.tolerance and _said_out(said, "the lattice") == pytest.approx(out, rel=1e-2)
    assert_valid(mesh)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", LatticeWarning)
        skinned = Lattice.fill(part, "octet", cell, cell / 12, skin=cell / 6)
        mesh = skinned.mesh()
    rep = skinned.skin_report
    assert rep.rebuilt > 0 and rep.bodies == 1 and "folds over itself" in rep.summary()
    out = protrusion(part, mesh.vertices)
    assert out > 0.01 * cell / 12 and _said_out(said, "the skin") == pytest.approx(out, rel=1e-2)
    assert_valid(mesh)


def _said_out(said: list, what: str) -> float:
    """How far the warning about ``what`` cut on a rebuild says it stands out (mm)."""
    found = [re.search(rf"{what} stands up to ([\d.]+) mm out", str(w.message)) for w in said]
    hits = [float(m.group(1)) for m in found if m]
    assert len(hits) == 1, [str(w.message)[:200] for w in said]
    return hits[0]


def test_a_fold_is_found_by_occts_check_without_a_finer_tessellation(monkeypatch):
    """Regression (s38's CV-joint bellows, made outside shared/data: convolutions curving
    tighter than the 1.6 mm wall): ``Part.folds`` tessellated the B-rep four times finer to
    see its crossings stay, 33 s of each fill's 40-49 s. OCCT's check finds the faces that
    intersect at once (``BRepAlgoAPI_Check``, in a child); no finer tessellation is made.
    When the check does not answer in time, the finer tessellation decides, as before."""
    from conformal.part import Part
    from lattice_cad.core import config
    from lattice_cad.occ_impl import shapes as occ

    with pytest.warns(LatticeWarning, match="surface crosses itself"):
        part = load_part(FOLDED)
    assert occ.self_interfering(list(part.shape)) == [0]
    refined = Part.refined
    calls = []

    def counted(self, *args, **kwargs):
        calls.append(args)
        return refined(self, *args, **kwargs)

    monkeypatch.setattr(Part, "refined", counted)
    assert part.folds and not calls
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        again = load_part(FOLDED)  # (a fresh part: folds is cached)
    monkeypatch.setattr(config, "FOLD_CHECK_SECONDS", 1e-3)  # the check times out
    assert again.folds and len(calls) == 1
    # a B-rep whose faces do not intersect: none found
    assert occ.self_interfering([load_part(_elbow()).shape[0]]) == []
