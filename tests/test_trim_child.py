"""The cutting tessellation made in a child process while the lattice is built
(``conformal.trim.start_cut``, started by ``Lattice.fill`` for trimmed fills of STEP files):
the same tessellation, the same lattice, the same warnings as made in this process."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from conformal.part import load_part
from conformal.trim import PendingCut, cutting_part, start_cut
from lattice_cad.core.errors import CutBudgetWarning
from lattice_cad.core.isolate import IsolatedWorker
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

GE = DATA / "step" / "dolfiny_ge_bracket_rotated_nonds.step"
PLATE = DATA / "step" / "kcl_mounting-plate.step"


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the GE bracket's union of solids is announced
        return load_part(path)


@pytest.mark.parametrize("chord", [None, 0.01])
def test_the_child_tessellates_as_this_process_does(chord):
    part = _load(GE)
    radius = float(part.size.max()) / 15 / 12
    pending = start_cut(str(GE), radius, chord=chord, worker=IsolatedWorker())
    got = pending.result(part, radius, chord=chord)
    here = cutting_part(part, radius, chord=chord)
    assert got is not None and got is not part
    assert len(here.faces) > 2 * len(part.faces)  # really finer than the part as loaded
    np.testing.assert_array_equal(got.vertices, here.vertices)
    np.testing.assert_array_equal(got.faces, here.faces)
    assert got.deflection == here.deflection
    assert got.chord_error == here.chord_error
    assert got.chord_unresolved == here.chord_unresolved
    assert got.unrefined is part and got.shape is part.shape and got.name == part.name


def test_a_cut_for_another_radius_is_not_used():
    part = _load(PLATE)
    worker = IsolatedWorker()
    pending = start_cut(str(PLATE), 0.5, worker=worker)
    assert pending.result(part, 0.4) is None  # the caller cuts for 0.4 itself
    assert not worker.running  # and the child was ended
    worker2 = IsolatedWorker()
    pending = start_cut(str(PLATE), 0.5, worker=worker2)
    assert pending.result(part, 0.5, chord=0.01) is None  # nor for another chord


class _Done:
    """A worker whose call is done (its result given), for the collecting side alone."""

    submitted = True

    def __init__(self, value):
        self.value, self.closed = value, False

    def result(self, *, timeout, what):
        return self.value

    def close(self):
        self.closed = True


def test_the_childs_warnings_are_warned_here_with_their_category():
    part = _load(PLATE)
    v = np.asarray(part.vertices) * 1.0
    attrs = {"deflection": 0.002, "chord_error": 0.0015, "chord_unresolved": 0}
    said = [
        ("CutBudgetWarning", "the budget binds"),
        ("RuntimeWarning", "a numpy note"),
        ("NoSuchWarning", "unknown kind"),
    ]
    pending = PendingCut(_Done((False, (v, part.faces), attrs, said)), str(PLATE), 0.5, None)
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        cut = pending.result(part, 0.5)
    assert [(type(w.message).__name__, str(w.message)) for w in got] == [
        ("CutBudgetWarning", "the budget binds"),
        ("RuntimeWarning", "a numpy note"),
        ("LatticeWarning", "unknown kind"),
    ]
    assert isinstance(got[0].message, CutBudgetWarning)
    assert cut.deflection == 0.002 and cut.chord_error == 0.0015 and cut.unrefined is part
    # the part as loaded was fine enough: the part itself
    same = PendingCut(_Done((True, None, {}, [])), str(PLATE), 0.5, None)
    assert same.result(part, 0.5) is part


def _fill(path, monkeypatch=None):
    kw = dict(method="voxel", fill="clip")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lat = Lattice.fill(str(path), "bcc", 12.0, 1.0, **kw)
        return lat, lat.mesh()


def test_a_clip_fill_of_a_step_file_cuts_in_the_child_and_writes_the_same_mesh(monkeypatch):
    import lattice_cad.lattice as lattice_mod

    collected = []
    result = PendingCut.result

    def spy(self, part, radius, *, chord=None):
        collected.append(result(self, part, radius, chord=chord))
        return collected[-1]

    monkeypatch.setattr(PendingCut, "result", spy)
    lat, mesh = _fill(PLATE)
    assert lat.trim_report is not None and lat.trim_report.trimmed
    # the child's tessellation was the one cut by (finer than the part as loaded)
    assert len(collected) == 1 and collected[0] is not None
    assert len(collected[0].faces) > len(lat.part.faces)

    started = []

    def no_child(*args, **kwargs):
        started.append(args)
        return None

    monkeypatch.setattr(lattice_mod, "_start_cut", no_child)
    lat2, mesh2 = _fill(PLATE)
    assert started  # the fill asked for a child (and got none: cut here)
    np.testing.assert_array_equal(mesh.vertices, mesh2.vertices)
    np.testing.assert_array_equal(mesh.faces, mesh2.faces)
    assert lat.trim_report.protrusion_after == lat2.trim_report.protrusion_after


def test_the_child_is_started_only_for_trimmed_step_fills():
    from lattice_cad.lattice import _start_cut

    def started(part, **kw):
        args = dict(method="voxel", fill="clip", skin=None, trim=True)
        args.update(kw)
        pending = _start_cut(part, 0.5, **args)
        if pending is None:
            return False
        pending.worker.close()
        return True

    assert started(str(PLATE))
    assert started(PLATE, method="tet", fill="auto")
    assert started(str(PLATE), fill="conform")
    assert not started(str(PLATE), fill="inside")  # struts inside: usually no cut at all
    assert not started(str(PLATE), fill="auto")
    assert not started(str(PLATE), skin=1.0)  # the skin's child offsets it
    assert not started(str(PLATE), trim=False)
    assert not started(str(DATA / "meshes" / "fandisk.obj"))  # a mesh is cut as it is
    assert not started(_load(PLATE))  # an object, not a file: cut here
