"""A B-rep face that folds over itself finer than the part's own tessellation (s35).

A 5-spoke wheel hub made outside shared/data (CadQuery, R4 fillets where the spokes meet
the rim; ``regression_wheel_corner.step`` is its corner at one spoke, cut out of it) is one
solid that BRepCheck accepts, but the fillets' corner patches fold over themselves by about
0.05 mm. Its tessellation at load (chord 0.085 mm) does not cross itself; the skin's fine
cutting tessellation (0.005 mm) does, in 259 pairs of triangles. The skin built on it could
not be written in float32, and the retries on the same tessellation were refused as a
surface that crosses itself: the whole wheel's skin failed after 88 s in the new-parts
benchmark of s34. The last retry is now built on the finest tessellation between the two
that does not cross itself, and a warning says how far it stands off the exact surface.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import pytest

from conformal import load_part
from conformal.skin import outer_chord
from conformal.trim import cutting_part, protrusion, unfolded_tessellation
from lattice_cad import Lattice
from lattice_cad.core.errors import LatticeWarning

CORNER = Path(__file__).parent / "regression_wheel_corner.step"  # made by CadQuery (s35)


def test_the_finest_tessellation_that_does_not_fold_is_found():
    part = load_part(CORNER)
    assert part.self_crossings[0] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        fine = cutting_part(part, 0.6, chord=outer_chord(0.76))
    assert fine.self_crossings[0] >= 100  # the fold shows at the skin's chord error
    unfolded = unfolded_tessellation(part, fine)
    assert unfolded is not part
    assert unfolded.self_crossings[0] == 0
    assert fine.deflection < unfolded.deflection < part.deflection
    # the finest that holds: half its chord error (the last one tried) folds
    finer = part.refined(unfolded.deflection / 2)
    assert finer is fine or finer.self_crossings[0] > 0
    assert unfolded.chord_error is not None and unfolded.chord_error < part.chord_bound


def test_no_finer_tessellation_than_the_part_s_own_is_taken_when_none_holds():
    """A tessellation that folds however coarse: the part itself comes back."""
    part = load_part(CORNER)
    assert unfolded_tessellation(part, part) is part
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        fine = cutting_part(part, 0.6, chord=outer_chord(0.76))
    part.__dict__["self_crossings"] = (-1, part.self_crossings[1])  # nothing is allowed
    assert unfolded_tessellation(part, fine) is part


@pytest.mark.slow
def test_a_skin_on_a_fillet_that_folds_finer_than_the_load_tessellation_is_written(tmp_path):
    from tests.conftest import assert_valid

    part = load_part(CORNER)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)
        lat = Lattice.fill(part, cell="octet", cell_size=8.0, radius=0.6, skin=0.76)
    with pytest.warns(LatticeWarning) as caught:
        mesh = lat.mesh()
    said = [
        str(w.message) for w in caught if "cutting tessellation crosses itself" in str(w.message)
    ]
    assert len(said) == 1, [str(w.message) for w in caught]
    off = float(re.search(r"stands up to ([\d.]+) mm .* off the exact one", said[0]).group(1))
    assert lat.skin_retry == "coarse"
    assert lat.skin_report.bodies == 1, lat.skin_report.summary()
    assert_valid(mesh)
    # the outer wall stands off the exact surface by about what the warning says: measured
    # against the fine tessellation (within 0.005 mm of it), where it does not fold
    assert off < part.chord_bound
    out = protrusion(lat._cutting_part, mesh.vertices)
    assert out <= off + 0.01, (out, off)
    path = tmp_path / "corner.stl"
    lat.save(path)
    from lattice_cad.cli import main

    assert main(["check", str(path)]) == 0
