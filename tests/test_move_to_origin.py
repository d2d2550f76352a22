"""Parts far from the origin (plant or site coordinates): ``--move-to-origin``.

Found in session 33 on a float32 STL of an L-bracket exported 20 km from the origin: every
fill was refused with "move the lattice by (...) (centre it on the origin)", which no option
of the command line could do. A float32 STL resolves 0.002 mm at 20,000 mm, too coarse for
struts of 0.1-0.3 mm (``config.PRECISION_RATIO_F32``), so the file cannot be written where
the part is; moved to the origin it can.
"""

from __future__ import annotations

import numpy as np
import pytest

from lattice_cad.cli import main

#: where the parts lie (mm), and the box's size
FAR = np.array([20000.0, -12000.0, 3500.0])
SIZE = (30.0, 20.0, 6.0)
ARGS = ["--cell", "bcc", "--cell-size", "3", "--radius", "0.25"]


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def far_stl(tmp_path_factory):
    """A float32 STL of a rotated box 20 km from the origin, as CAD tools export it."""
    import trimesh

    tm = trimesh.creation.box(extents=SIZE)
    tm.apply_transform(trimesh.transformations.rotation_matrix(np.radians(23), [0, 0, 1]))
    tm.apply_translation(FAR)
    p = tmp_path_factory.mktemp("far") / "far_box.stl"
    tm.export(p)  # binary STL: float32
    return p


def _independent(path):
    """trimesh and manifold3d read the file as one closed solid."""
    import manifold3d
    import trimesh

    tm = trimesh.load(path, force="mesh")
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    man = manifold3d.Manifold(
        manifold3d.Mesh(
            np.asarray(tm.vertices, dtype=np.float32), np.asarray(tm.faces, dtype=np.uint32)
        )
    )
    assert man.status() == manifold3d.Error.NoError
    return tm


def test_far_stl_is_refused_with_the_option_to_use(capsys, far_stl, tmp_path):
    out = tmp_path / "out.stl"
    code, _, err = run(capsys, "fill", far_stl, "-o", out, *ARGS)
    assert code == 1 and not out.exists()
    # the move named, and the option that makes it (the library says its keyword)
    assert "move the lattice by (-20000, 12000, -3500)" in err
    assert "a fill does that with --move-to-origin" in err


def test_far_stl_is_filled_at_the_origin(capsys, far_stl, tmp_path):
    import trimesh

    out = tmp_path / "out.stl"
    code, text, err = run(capsys, "fill", far_stl, "-o", out, *ARGS, "--move-to-origin")
    assert code == 0, err
    assert "part moved by (-20000, 12000, -3500) to centre it on the origin" in text
    code, text, err = run(capsys, "check", out)
    assert code == 0 and "valid" in text, text + err
    tm = _independent(out)
    # the lattice fills the moved part: centred on the origin, inside its box
    part = trimesh.load(far_stl, force="mesh")
    lo, hi = part.bounds - part.bounds.mean(axis=0)
    assert np.all(tm.bounds[0] >= lo - 1e-3) and np.all(tm.bounds[1] <= hi + 1e-3)
    assert np.all(np.abs(tm.bounds.mean(axis=0)) < 1.0)
    assert tm.volume > 0.05 * part.volume


def test_far_brep_skin_keeps_the_occt_offset():
    """A B-rep is moved before it is tessellated, so OCCT's offset (started while the part
    loads) is of the moved solid: the skin is OpenCascade's, exact to its tolerance."""
    import cadquery as cq

    from lattice_cad import Lattice

    shape = cq.Workplane("XY").box(*SIZE).val().translate(cq.Vector(*FAR))
    lat = Lattice.fill(shape, "octet", 3.0, 0.25, skin=0.6, move_to_origin=True)
    np.testing.assert_array_equal(lat.part.moved_by, -FAR)
    np.testing.assert_allclose(lat.part.bounds, [np.negative(SIZE) / 2, np.array(SIZE) / 2])
    mesh = lat.mesh()
    assert lat.skin_report is not None and lat.skin_report.method == "occt"
    assert lat.skin_report.accurate and lat.skin_report.bodies == 1
    assert np.all(np.abs(mesh.vertices).max(axis=0) <= np.array(SIZE) / 2 + 1e-6)
    # without the move the same skin cannot be written in single precision
    from lattice_cad.core.errors import InvalidGraphError

    far = Lattice.fill(shape, "octet", 3.0, 0.25, skin=0.6)
    with pytest.raises(InvalidGraphError, match="move_to_origin=True"):
        far.mesh()


def test_move_to_origin_needs_a_file_or_shape(far_stl, capsys, tmp_path):
    from conformal import load_part
    from lattice_cad import Lattice

    part = load_part(far_stl)
    np.testing.assert_array_equal(part.moved_by, 0.0)
    with pytest.raises(ValueError, match="move_to_origin applies when loading a part"):
        Lattice.fill(part, "bcc", 3.0, 0.25, move_to_origin=True)
    moved = load_part(far_stl, move_to_origin=True)
    np.testing.assert_allclose(moved.vertices - moved.moved_by, part.vertices, atol=0)
    assert np.all(np.abs(moved.bounds.sum(axis=0)) < 1e-3)
    graph = tmp_path / "g.json"
    Lattice.fill(moved, "bcc", 3.0, 0.25).graph.save(graph)
    code, _, err = run(capsys, "validate", graph, "--move-to-origin", "--report", tmp_path / "r.md")
    assert code == 1 and "apply to part files, not to a graph" in err


def test_validate_moves_the_part_and_says_so(capsys, tmp_path):
    """``validate PART --move-to-origin`` compares the lattice of the moved part and prints
    the move, as ``fill`` does (one helper in the CLI; untested until session 34)."""
    import trimesh

    tm = trimesh.creation.box(extents=(6.0, 6.0, 3.0))
    tm.apply_translation(FAR)
    part = tmp_path / "far_small.stl"
    tm.export(part)
    report = tmp_path / "report"
    code, text, err = run(capsys, "validate", part, *ARGS, "--move-to-origin", "--report", report)
    assert code == 0, err
    assert "part moved by (-20000, 12000, -3500) to centre it on the origin" in text
    # the comparison ran on the lattice of the moved part (the exact solid's volume is the
    # mesh's within its error), and wrote its report
    assert "exact volume" in text and "reference complete" in text
    assert (report / "report.md").exists()
