"""lattice_cad.render (software rasteriser, pictures) and the shaded ``preview``.

Every picture test renders headless (no display, no GPU) and checks the image by
its pixels: not blank, the object filling a sensible part of the frame, the
colours of a colour-by where they must be.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
from PIL import Image

from conformal.cells import tile
from lattice_cad import LatticeGraph
from lattice_cad.render import (
    ColorBar,
    Layer,
    Marker,
    Panel,
    Section,
    _kernels,
    camera_for,
    picture,
    shade,
    strut_angles,
    tubes,
)
from lattice_cad.render.geometry import _icosphere
from lattice_cad.render.raster import BACKGROUND
from tests.conftest import DATA, ROOT

BG = np.array(BACKGROUND)


def _pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float64) / 255.0


def _object_mask(img: np.ndarray) -> np.ndarray:
    return np.abs(img - BG).max(axis=-1) > 0.03


def _assert_framed(mask: np.ndarray, *, min_fill: float = 0.05, min_span: float = 0.6) -> None:
    """Not blank, and the object spans most of the frame in at least one direction."""
    h, w = mask.shape
    assert min_fill < mask.mean() < 0.97, mask.mean()
    ys, xs = np.nonzero(mask)
    span = max((xs.max() - xs.min() + 1) / w, (ys.max() - ys.min() + 1) / h)
    assert span > min_span, span


# --------------------------------------------------------------------- kernel
def test_rasteriser_covers_exactly_the_pixel_centres_inside():
    rng = np.random.default_rng(7)
    w, h = 64, 48
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    for _ in range(100):
        p = rng.uniform([-10, -10], [74, 58], (3, 2)).astype(np.float32)
        depth = np.full((h, w), np.inf, np.float32)
        nbuf = np.zeros((h, w, 3), np.float32)
        sbuf = np.zeros((h, w), np.float32)
        ids = np.zeros((h, w), np.int16)
        _kernels.rasterise(
            p[:, 0].copy(), p[:, 1].copy(), np.zeros(3, np.float32), np.array([[0, 1, 2]]),
            np.zeros((3, 3), np.float32), np.zeros(3, np.float32), np.zeros(3, np.float32),
            1, False, depth, nbuf, sbuf, ids, 3, 1.0,
        )  # fmt: skip

        def edge(a, b):
            return (b[0] - a[0]) * (yy - a[1]) - (b[1] - a[1]) * (xx - a[0])

        e = np.stack([edge(p[1], p[2]), edge(p[2], p[0]), edge(p[0], p[1])])
        inside = (e >= 0).all(0) | (e <= 0).all(0)
        # pixel centres on an edge may go either way
        on_edge = (np.abs(e) < 1e-3).any(0)
        assert np.array_equal(inside[~on_edge], (ids != 0)[~on_edge])


def test_sphere_covers_its_disc_and_fills_the_frame():
    v, f = _icosphere(4)
    layer = Layer(v * 10.0, f, closed=True)
    cam = camera_for([layer], view="top", size=(400, 400), margin=0.1)
    img, stats = shade([layer], cam)
    mask = np.abs(img - BG).max(axis=-1) > 0.02
    # the disc of radius 10 mm, scaled to pixels (the icosphere is a little smaller)
    disc = np.pi * (10.0 * cam.scale) ** 2
    assert mask.sum() == pytest.approx(disc, rel=0.03)
    assert mask.sum() / mask.size == pytest.approx(np.pi / 4 * 0.8**2, rel=0.03)
    assert stats["triangles"] == len(f)
    # lit: the upper-left (key light) half is brighter than the lower-right
    lum = img.mean(-1)
    c = 200
    assert lum[c - 60, c - 60] > lum[c + 60, c + 60] + 0.1


def test_section_removes_the_camera_side_and_shows_the_inside():
    v, f = _icosphere(3)
    layer = Layer(v * 10.0, f, closed=True)
    cam = camera_for([layer], view="iso", size=(300, 300))
    whole, _ = shade([layer], cam)
    cut, _ = shade([layer], cam, section=Section(2, 0.0))
    rows_whole = np.nonzero((np.abs(whole - BG).max(-1) > 0.02).any(1))[0]
    rows_cut = np.nonzero((np.abs(cut - BG).max(-1) > 0.02).any(1))[0]
    assert rows_cut[0] > rows_whole[0] + 20  # the top cap is gone
    assert rows_cut[-1] == pytest.approx(rows_whole[-1], abs=1)  # the bottom stays
    # through the cut, the inside of the bottom half: darker than the lit top cap was
    x, y, _ = cam.project(np.zeros((1, 3)))[0].astype(int)
    assert cut[y, x].mean() < whole[y, x].mean() - 0.1
    # a section away from the sphere removes nothing / everything
    same, _ = shade([layer], cam, section=Section(2, 20.0))
    assert np.allclose(same, whole)
    gone, _ = shade([layer], cam, section=Section(2, -20.0))
    assert np.allclose(gone, BG, atol=0.01)


# ------------------------------------------------------------------- geometry
def test_strut_angles_closed_form():
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1]], float)
    edges = np.array([[0, 1], [0, 2], [0, 3], [0, 4], [2, 0]])
    ang = strut_angles(nodes, edges)
    expect = [0.0, 90.0, 45.0, np.degrees(np.arctan(1 / np.sqrt(2))), 90.0]
    assert ang == pytest.approx(expect)


def test_tubes_are_outward_and_sized():
    nodes = np.array([[0.0, 0, 0], [10, 0, 0]])
    v, f, n, sc = tubes(nodes, np.array([[0, 1]]), np.array([[1.0, 0.5]]), sides=16, balls=False,
                        end_values=np.array([[1.0, 2.0]]))  # fmt: skip
    assert len(f) == 32 and sc is not None and set(sc) == {1.0, 2.0}
    # face normals point away from the axis, like the vertex normals
    c = v[f].mean(axis=1)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    radial = c - np.c_[c[:, 0], np.zeros(len(c)), np.zeros(len(c))]
    assert (np.einsum("ij,ij->i", fn, radial) > 0).all()
    assert (np.einsum("ij,ij->i", n, v - np.c_[v[:, 0], 0 * v[:, :2]]) > 0).all()
    r = np.linalg.norm(v[:, 1:], axis=1)
    assert r[:16] == pytest.approx(1.0) and r[16:] == pytest.approx(0.5)
    # balls: a closed, outward icosphere of the largest radius at each node
    v, f, _, _ = tubes(nodes, np.array([[0, 1]]), np.array([[1.0, 0.5]]), sides=6)
    ball = f[12:] - f[12:].min()
    bv = v[f[12:].min() : f[12:].max() + 1]
    vol = np.einsum("ij,ij->i", bv[ball[:, 0]], np.cross(bv[ball[:, 1]], bv[ball[:, 2]])).sum() / 6
    assert vol == pytest.approx(4 / 3 * np.pi, rel=0.1)


# ------------------------------------------------------------------- pictures
@pytest.fixture(scope="module")
def graded():
    """A small BCC block whose radii grow with x (0.2 .. 0.6 mm)."""
    i = np.stack(np.meshgrid(np.arange(4), np.arange(3), np.arange(2), indexing="ij"), -1)
    g = tile("bcc", i.reshape(-1, 3), cell_size=5.0, radius=0.4)
    x = g.nodes[g.edges].mean(axis=1)[:, 0]
    r = 0.2 + 0.4 * (x - x.min()) / np.ptp(x)
    return LatticeGraph(g.nodes, g.edges, np.c_[r, r])


def test_picture_colour_bar_maps_the_scalars(graded):
    from matplotlib import colormaps

    v, f, n, sc = tubes(graded.nodes, graded.edges, graded.radii, end_values=graded.radii)
    png, info = picture(
        [Layer(v, f, n, sc, closed=True)],
        panels=[Panel("top")],
        size=(500, 420),
        colorbar=ColorBar("strut radius (mm)", (0.2, 0.6)),
    )
    img = _pixels(png)
    assert len(png) < 300_000
    panel_h = info["cameras"][0].size[1]
    body = img[8 : 8 + panel_h]
    _assert_framed(_object_mask(body))
    lut = colormaps["viridis"](np.linspace(0, 1, 5))[:, :3]
    # thin struts on the left are dark purple, thick ones on the right yellow
    # (hue, not brightness: compare with the ends of the map after normalising)
    cols = _object_mask(body).any(axis=0).nonzero()[0]
    left = body[:, cols[0] : cols[0] + 40][_object_mask(body[:, cols[0] : cols[0] + 40])]
    right = body[:, cols[-1] - 40 : cols[-1]][_object_mask(body[:, cols[-1] - 40 : cols[-1]])]

    def hue_dist(px, c):
        a = px / np.maximum(px.sum(-1, keepdims=True), 1e-9)
        return np.abs(a - c / c.sum()).sum(-1).mean()

    assert hue_dist(left, lut[0]) < hue_dist(left, lut[-1])
    assert hue_dist(right, lut[-1]) < hue_dist(right, lut[0])
    # the colour bar itself is smooth (the palette keeps its colours)
    bar = img[-84, img.shape[1] // 4 + 5 : 3 * img.shape[1] // 4 - 5]
    assert len(np.unique(bar.round(3), axis=0)) > 40


def test_markers_land_on_their_points(graded):
    v, f, n, _ = tubes(graded.nodes, graded.edges, graded.radii)
    target = graded.nodes[0]
    png, info = picture(
        [Layer(v, f, n, closed=True)], size=(400, 330), markers=[Marker(tuple(target), "1")]
    )
    img = _pixels(png)
    cam = info["cameras"][0]
    x, y, _ = cam.project(target[None])[0]
    red = (img[..., 0] > 0.7) & (img[..., 1] < 0.35) & (img[..., 2] < 0.35)
    ys, xs = np.nonzero(red)
    top = 8  # the panel starts 8 px below the top without a title
    assert len(xs) > 20
    d = np.hypot(xs - x, ys - top - y)
    assert np.median(d) < 15


# -------------------------------------------------------------------- preview
@pytest.fixture(scope="module")
def bracket_lattice():
    from lattice_cad.core.errors import LatticeWarning
    from lattice_cad.lattice import Lattice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LatticeWarning)  # struts thinned at the walls
        return Lattice.fill(ROOT / "examples" / "bracket.step", "bcc", 6.0, 0.5, fill="clip")


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"color_by": "overhang"},
        {"section": "z=6"},
        {"views": ["iso", "top"], "section": "x"},
    ],
    ids=["ghost", "overhang", "section", "views"],
)
def test_preview_pictures_are_framed(bracket_lattice, options):
    from lattice_cad import preview

    png = preview.render_png(bracket_lattice, size=(640, 480), **options)
    assert len(png) < 300_000
    img = _pixels(png)
    n_panels = len(options.get("views", ["iso"])) + ("section" in options)
    top, bottom = 8, 26 + (78 if options.get("color_by") == "overhang" else 0)
    width = 640 // n_panels
    for k in range(n_panels):
        _assert_framed(_object_mask(img[top : 480 - bottom, k * width : (k + 1) * width]))
    if options.get("color_by") == "overhang":
        # BCC struts stand at 35.3 degrees to the plate: all below 45, warm colours
        body = img[top : 480 - bottom][_object_mask(img[top : 480 - bottom])]
        assert (body[:, 0] > body[:, 2]).mean() > 0.6


def test_preview_mesh_is_simplified_for_display_only(tmp_path):
    import fast_stitch
    from lattice_cad import preview

    g = tile("bcc", np.argwhere(np.ones((3, 3, 2))), cell_size=4.0, radius=0.4)
    m = fast_stitch.stitch(g, 6)
    faces = m.faces.copy()
    png = preview.render_png(m, size=(400, 300), max_triangles=len(m.faces) // 4)
    assert np.array_equal(m.faces, faces)  # the mesh itself is untouched
    _assert_framed(_object_mask(_pixels(png)[8:270]))
    with pytest.raises(ValueError, match="needs a lattice graph"):
        preview.render_png(m, color_by="overhang")
    with pytest.raises(ValueError, match="section must be x, y or z"):
        preview.render_png(g, section="w=3")
    with pytest.raises(ValueError, match="style must be"):
        preview.render_png(g, style="photo")  # type: ignore[arg-type]
    # the wireframe style is still there
    assert preview.render_png(g, style="wireframe", size=(300, 200))[:4] == b"\x89PNG"


def test_preview_of_a_real_mesh_file(tmp_path):
    from lattice_cad import preview

    p = preview.save_png(DATA / "meshes" / "spot_triangulated.obj", tmp_path / "s.png",
                         size=(400, 300))  # fmt: skip
    _assert_framed(_object_mask(_pixels(p.read_bytes())[8:270]))


def test_report_render_marks_the_worst_nodes():
    from types import SimpleNamespace

    from reference_boolean.pictures import HIGHLIGHT
    from reference_boolean.report import lattice_render

    g = tile("bcc", np.argwhere(np.ones((2, 2, 1))), cell_size=5.0, radius=0.4)
    dev = np.linspace(0.0, 0.01, g.num_nodes)
    worst = [(int(i), float(dev[i])) for i in np.argsort(-dev)[:5]]
    rep = SimpleNamespace(
        graph=g,
        node_deviation=dev,
        worst_nodes=lambda k: worst[:k],
        reference=SimpleNamespace(failed={}),
        label="test",
        comparisons={},  # no surface comparison: places ranked by node deviation alone
        hub_zone=None,  # zone balls of 3 r
    )
    img = _pixels(lattice_render(rep, size=(500, 400)))
    rgb = np.array([int(HIGHLIGHT[i : i + 2], 16) for i in (1, 3, 5)]) / 255.0
    ringed = np.abs(img - rgb).max(axis=-1) < 0.12
    assert ringed.sum() > 50  # the numbered rings, in the highlight green
    _assert_framed(_object_mask(img[40:300]))
