"""``Lattice.fill`` with a skin starts OpenCascade's offsets as soon as the part is loaded
(the child offsets while this process builds the lattice graph and stitches it), and a fill
that fails ends that child instead of leaving it running."""

from __future__ import annotations

import warnings

import pytest

import lattice_cad.lattice as lattice_mod
from lattice_cad.core.errors import LatticeWarning
from lattice_cad.lattice import Lattice
from tests.conftest import DATA

PART = DATA / "step" / "kcl_bracket.step"


def test_offsets_start_before_the_lattice_graph(monkeypatch):
    events: list[str] = []
    started = lattice_mod._start_offsets
    graph = lattice_mod._fill_graph

    def start(*a, **k):
        pending = started(*a, **k)
        events.append("offsets" if pending is not None else "no offsets")
        return pending

    def fill_graph(*a, **k):
        events.append("graph")
        return graph(*a, **k)

    monkeypatch.setattr(lattice_mod, "_start_offsets", start)
    monkeypatch.setattr(lattice_mod, "_fill_graph", fill_graph)
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
