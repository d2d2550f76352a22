"""Shared fixtures and independent mesh checks for the test suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lattice_cad import LatticeGraph

#: The repository root, and the shared test data beside it (``../shared/data``).
ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def pytest_configure(config: pytest.Config) -> None:
    # real parts are part of the suite: a missing ../shared is a failure, never a skip
    if not DATA.is_dir():
        raise pytest.UsageError(f"the shared test data is missing: expected {DATA}")


@pytest.fixture
def refined_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[float, bool]]:
    """The ``(deflection, checked)`` of every ``conformal.Part.refined`` call the test makes,
    in order (the tessellations the cutting part asks for)."""
    from conformal.part import Part

    calls: list[tuple[float, bool]] = []
    real = Part.refined

    def refined(self, deflection, **kw):
        calls.append((deflection, kw.get("checked", True)))
        return real(self, deflection, **kw)

    monkeypatch.setattr(Part, "refined", refined)
    return calls


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: every random test is reproducible."""
    return np.random.default_rng(20261121)


def star_graph(dirs, lengths=1.0, radii=0.05) -> LatticeGraph:
    """A node at the origin with one strut along each direction.

    dirs : (d, 3) float64, lengths : float or (d,), radii : float, (d,) or (d, 2)
    """
    dirs = np.asarray(dirs, dtype=np.float64)
    dirs = dirs / np.linalg.norm(dirs, axis=1)[:, None]
    lengths = np.broadcast_to(np.asarray(lengths, dtype=np.float64), (len(dirs),))
    nodes = np.vstack([np.zeros(3), dirs * lengths[:, None]])
    edges = np.column_stack([np.zeros(len(dirs), dtype=np.int64), np.arange(1, len(dirs) + 1)])
    return LatticeGraph(nodes, edges, radii)


def cubic_grid(n: int, spacing: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and edges of an n x n x n cubic grid of nodes (plain numpy)."""
    i = np.arange(n)
    ijk = np.stack(np.meshgrid(i, i, i, indexing="ij"), -1).reshape(-1, 3)
    idx = lambda a: (a[:, 0] * n + a[:, 1]) * n + a[:, 2]  # noqa: E731
    edges = []
    for axis in range(3):
        step = np.zeros(3, dtype=np.int64)
        step[axis] = 1
        a = ijk[ijk[:, axis] < n - 1]
        edges.append(np.column_stack([idx(a), idx(a + step)]))
    return ijk * spacing, np.vstack(edges)


def independent_check(mesh, *, self_intersections: bool = True) -> dict:
    """Validity of a mesh judged by trimesh, manifold3d and pymeshlab (not our own code);
    pymeshlab's self-intersecting faces are confirmed by an exact test
    (``exact_intersect.confirmed_faces``)."""
    import manifold3d
    import trimesh

    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    tm = trimesh.Trimesh(vertices=v, faces=f, process=False)
    man = manifold3d.Manifold(
        manifold3d.Mesh(vert_properties=v.astype(np.float32), tri_verts=f.astype(np.uint32))
    )
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    out = {
        "watertight": bool(tm.is_watertight),
        "winding_consistent": bool(tm.is_winding_consistent),
        "outward": bool(tm.volume > 0),
        "manifold3d": man.status() == manifold3d.Error.NoError,
        "min_area": float(0.5 * np.linalg.norm(cross, axis=1).min()),
    }
    if self_intersections:
        import pymeshlab

        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
        ms.compute_selection_by_self_intersections_per_face()
        flagged = np.flatnonzero(ms.current_mesh().face_selection_array())
        out["pymeshlab_flagged"] = len(flagged)
        # pymeshlab flags some coplanar faces that share a vertex without overlapping: each
        # flagged face counts when an exact test (rational arithmetic) confirms it
        from exact_intersect import confirmed_faces

        # (a bcc cut along a rocket fin can's faces, s37: 277 flagged, none confirmed, 9 s)
        out["self_intersecting_faces"] = len(confirmed_faces(v, f, flagged[:1000]))
        if len(flagged) > 1000:  # too many to confirm one by one: trust the flag
            out["self_intersecting_faces"] = len(flagged)
    return out


def assert_valid(mesh, *, self_intersections: bool = True) -> None:
    """Assert the guarantees of fast_stitch with independent checkers, and with ours beside them."""
    import fast_stitch

    ours = fast_stitch.check(mesh, self_intersections=self_intersections)
    assert ours.valid, str(ours)
    rep = independent_check(mesh, self_intersections=self_intersections)
    assert rep["watertight"], rep
    assert rep["winding_consistent"], rep
    assert rep["outward"], rep
    assert rep["manifold3d"], rep
    assert rep["min_area"] > 0.0, rep
    if self_intersections:
        assert rep["self_intersecting_faces"] == 0, rep


def gunzipped(name: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``tests/NAME`` (a gzipped regression file, ``NAME`` ending in ``.gz``) unpacked into
    a new temporary directory; its path, without the ``.gz``."""
    import gzip
    import shutil

    out = tmp_path_factory.mktemp(name.split(".")[0]) / name[: -len(".gz")]
    with gzip.open(Path(__file__).parent / name, "rb") as fin, open(out, "wb") as fout:
        shutil.copyfileobj(fin, fout)
    return out
