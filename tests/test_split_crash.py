"""OCCT's split of dense faces runs in a child process: it can die of a segmentation fault.

Found in session 33 on a trefoil knot made outside shared/data (three swept thirds of a
tube fused into one solid of three B-spline faces): ``ShapeUpgrade_FaceDivideArea`` died
on its second face, and with it every fill of the part (bcc, tet, conform, clip: "killed
by SIGSEGV"; the skin's OCCT offset child then ran on for minutes). The face, as binary
BREP: ``regression_knot_face.brep.gz``. Its surface has a spike (``|S_v|`` of 206 mm
against 1-4 elsewhere, near the end of its v range), a defect of that sweep, which
BRepCheck does not see.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from lattice_cad.core.errors import ExternalCrash
from lattice_cad.core.isolate import run_isolated
from lattice_cad.occ_impl import chord
from lattice_cad.occ_impl import shapes as occ

FACE = Path(__file__).with_name("regression_knot_face.brep.gz")


@pytest.fixture(scope="module")
def face():
    return occ.from_bytes(gzip.decompress(FACE.read_bytes()))


def test_the_face_kills_occts_split(face):
    """Why the split is isolated: in the process it would end the caller (OCP 7.8.1)."""
    area = occ.face_area(chord._faces(face)[0])
    with pytest.raises(ExternalCrash, match="crashed"):
        run_isolated(
            chord._divided_faces,
            occ.to_bytes(face),
            1,
            [(0, area / 20)],
            timeout=120,
            what="the knot's face split",
        )


@pytest.mark.parametrize("deflection", [0.1172, 0.0293])  # the load's, the refined one's
def test_split_dense_faces_survives_it(face, deflection, monkeypatch):
    """The split is asked for (the face is dense at these chords), its child dies, and the
    face is meshed whole (None), here, in a process that lives on."""
    import lattice_cad.core.isolate as isolate

    crashed = []

    def watched(fn, *args, **kwargs):
        try:
            return run_isolated(fn, *args, **kwargs)
        except ExternalCrash:
            crashed.append(fn.__name__)
            raise

    monkeypatch.setattr(isolate, "run_isolated", watched)
    assert chord.split_dense_faces(face, deflection, 0.3) is None
    assert crashed == ["_divided_faces"]
    # the face still meshes as it is: the caller's way on
    chord._mesh(face, deflection, 0.3, True)
    assert chord._triangle_counts(chord._faces(face))[0] > 1000
