"""``Lattice.fill`` with a skin starts OpenCascade's offsets as soon as the part's solids
are read (the child offsets while this process tessellates the part, builds the lattice
graph and stitches it), and a fill that fails ends that child instead of leaving it
running."""

from __future__ import annotations

import warnings

import pytest

import lattice_cad.lattice as lattice_mod
from lattice_cad.core.errors import LatticeWarning
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

PART = DATA / "step" / "kcl_bracket.step"


def _spy(monkeypatch, events: list[str], owner, name: str, label) -> None:
    """Replace ``owner.name`` by a wrapper that appends ``label`` (or ``label(result)``) to
    ``events`` when it is called."""
    real = getattr(owner, name)

    def spy(*a, **k):
        if not callable(label):
            events.append(label)
        out = real(*a, **k)
        if callable(label):
            events.append(label(out))
        return out

    monkeypatch.setattr(owner, name, spy)


def test_offsets_start_before_the_lattice_graph(monkeypatch):
    events: list[str] = []
    _spy(monkeypatch, events, lattice_mod, "_start_offsets",
         lambda pending: "offsets" if pending is not None else "no offsets")  # fmt: skip
    _spy(monkeypatch, events, lattice_mod, "_fill_graph", "graph")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(PART, "bcc", 12.0, 1.0, skin=2.0)
    assert events == ["offsets", "graph"]
    pending = lat._pending_offsets
    assert pending is not None and pending.worker.submitted
    pending.worker.close()


def test_a_failing_fill_ends_the_offset_child(monkeypatch):
    seen = []
    started = lattice_mod._start_offsets

    def start(*a, **k):
        pending = started(*a, **k)
        seen.append(pending)
        return pending

    def fill_graph(*a, **k):
        raise RuntimeError("the lattice graph failed")

    monkeypatch.setattr(lattice_mod, "_start_offsets", start)
    monkeypatch.setattr(lattice_mod, "_fill_graph", fill_graph)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        with pytest.raises(RuntimeError, match="lattice graph failed"):
            Lattice.fill(PART, "bcc", 12.0, 1.0, skin=2.0)
    assert len(seen) == 1 and seen[0] is not None
    worker = seen[0].worker
    assert worker._pool is None and not worker.running  # closed: the child was killed


def test_offsets_start_from_the_solids_before_the_part_is_tessellated(monkeypatch):
    """The child gets the solids as soon as they are read (``load_part(on_solids=)``), not
    after their tessellation and its checks (the GE bracket: 1.2 s earlier)."""
    from conformal import part as part_mod
    from conformal import skin as skin_mod

    events: list[str] = []
    _spy(monkeypatch, events, part_mod, "_closed_tessellation", "tessellate")
    _spy(monkeypatch, events, skin_mod, "start_solid_offsets", "offsets")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(PART, "bcc", 12.0, 1.0, skin=2.0)
    assert events[:2] == ["offsets", "tessellate"]
    pending = lat._pending_offsets
    assert pending.part is lat.part and pending.solids is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        mesh = lat.mesh()
    assert lat.skin_report.method == "occt" and lat.skin_report.bodies == 1
    assert len(mesh.faces)


def test_early_offsets_of_other_solids_are_not_adopted():
    from conformal.part import load_part
    from conformal.skin import PendingOffsets

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # 3 solids united
        part = load_part(PART)
        other = load_part(PART)  # the same file read again: other solid objects
    pending = PendingOffsets(None, None, 2.0, False, solids=list(other.shape))
    assert not pending.adopt(part)
    assert pending.part is None
    assert pending.adopt(other) and pending.part is other and pending.solids is None
