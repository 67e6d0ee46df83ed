"""Buried vertices (no light from any direction: under or inside a solid) take their non-buried neighbours'
transfer over the mesh edges (:func:`warpshade.pipeline.shading.fill_buried`), so the floor triangles
straddling a solid's footprint do not fade to black outside it. A box standing on a ground grid, both in one
shading group; the unfilled run is the same pipeline with nothing counted as buried."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.geometry import TriMesh
from warpshade.geometry.mesh import fill_from_neighbours, mesh_edges
from warpshade.geometry.shapes import box_shape
from warpshade.pipeline import Pipeline
from warpshade.pipeline import shading
from warpshade.scene import LightSpec, Scene, SceneObject

N = 21  # ground: N×N vertices on [-1.5, 1.5]² at y = 0 (spacing 0.15)
HALF = 0.4  # the box's footprint is [-HALF, HALF]² (0.8 × 0.5 × 0.8, standing on y = 0)
T0 = np.sqrt(np.pi) / 2  # unoccluded DC of the transfer, any normal


def ground_mesh() -> TriMesh:
    x = np.linspace(-1.5, 1.5, N)
    X, Z = np.meshgrid(x, x, indexing="ij")
    i = np.arange(N * N).reshape(N, N)
    faces = np.concatenate([np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:]], -1).reshape(-1, 3),
                            np.stack([i[:-1, :-1], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 3)])
    return TriMesh(np.stack([X.ravel(), np.zeros(N * N), Z.ravel()], 1), faces, name="ground")


def box_mesh() -> TriMesh:
    pts, faces = box_shape((2 * HALF, 0.5, 2 * HALF), (4, 3, 4))
    return TriMesh(pts + (0.0, 0.25, 0.0), faces, name="box")


def transfer(fill: bool, monkeypatch) -> dict:
    """Per object: (exit radiance (V, 3), transfer (V, N*N)) of frame 0, with or without the fill."""
    if not fill:
        monkeypatch.setattr(shading, "BURIED", -np.inf)  # nothing counts as buried
    sc = Scene(objects=[SceneObject("ground", ground_mesh(), method="hemiraster"),
                        SceneObject("box", box_mesh(), method="hemiraster")],
               frames=1, lights=[LightSpec("dome", "sky")])
    pipe = Pipeline(sc, order=3, write_transfer=True)
    assert [g.names for g in pipe.groups] == [["ground", "box"]]
    out = pipe.shader.build()(0, {})
    monkeypatch.undo()
    return {k: (out[k][2], out[k][3]) for k in ("ground", "box")}


@pytest.fixture(scope="module")
def runs():
    mp = pytest.MonkeyPatch()
    return transfer(False, mp), transfer(True, mp)


def test_floor_under_the_box_is_buried_and_filled_from_the_ring_outside(runs):
    before, after = runs
    g = ground_mesh()
    x, z = g.points[:, 0], g.points[:, 2]
    under = (np.abs(x) < HALF) & (np.abs(z) < HALF)  # 5 × 5 vertices, at least 0.1 inside the outline
    t_before, t_after = before["ground"][1], after["ground"][1]
    assert under.sum() == 25
    buried = t_before[:, 0] <= shading.BURIED * T0
    # hemiraster's mask is fully blocked under the box up to a pixel leaking through a seam of the box's
    # triangles (one of the 32² mask's ~804 disk pixels: 1.2e-3 of T0), black before the fill; the
    # threshold picks exactly these vertices
    assert np.abs(t_before[under]).max() < 2e-3 and np.array_equal(buried, under)
    lit = before["ground"][0].max()  # the open floor's colour
    assert np.all(before["ground"][0][under] < 2e-3 * lit)
    # the rest of the floor (and its colour) is bit-identical
    assert np.array_equal(t_after[~under], t_before[~under])
    assert np.array_equal(after["ground"][0][~under], before["ground"][0][~under])
    # the outer ring of the footprint (|x| or |z| = 0.3) takes the mean of its non-buried grid neighbours
    # (faces of ground_mesh: the 4-neighbours and one diagonal), computed here from the grid's layout
    nb = {tuple(sorted(e)) for f in g.faces for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    for v in np.flatnonzero(under):
        outside = [b if a == v else a for a, b in nb if v in (a, b) and not under[b if a == v else a]]
        if outside:
            np.testing.assert_allclose(t_after[v], t_before[outside].mean(axis=0), rtol=1e-6, atol=1e-7)
    # every buried vertex now has a transfer between its ring's extremes: none is black
    assert np.all(t_after[under, 0] >= t_before[~under, 0].min())
    assert np.all(after["ground"][0][under] > 0.1 * lit)


def test_box_vertices_that_receive_light_are_unchanged(runs):
    before, after = runs
    t_before, t_after = before["box"][1], after["box"][1]
    kept = t_before[:, 0] > shading.BURIED * T0
    assert kept.sum() > 0.8 * len(kept)
    assert np.array_equal(t_after[kept], t_before[kept])
    assert np.array_equal(after["box"][0][kept], before["box"][0][kept])


def test_fill_from_neighbours_by_hand():
    # path 0-1-2-3 with holes 1, 2 and a separate part 4-5 made only of holes
    values = np.array([[1.0], [9.0], [9.0], [5.0], [7.0], [8.0]], dtype=np.float32)
    holes = np.array([False, True, True, False, True, True])
    out = fill_from_neighbours(values, mesh_edges(np.array([[0, 1, 1], [1, 2, 2], [2, 3, 3], [4, 5, 5]])), holes)
    # round 1: 1 <- 0 (1.0), 2 <- 3 (5.0); nothing reaches 4, 5
    np.testing.assert_array_equal(out[:, 0], [1.0, 1.0, 5.0, 5.0, 7.0, 8.0])
    # a hole two edges in takes the mean of the round before: 0 - 1 - 2, 3 - 1
    out = fill_from_neighbours(np.array([[2.0], [0.0], [0.0], [4.0]]),
                               mesh_edges(np.array([[0, 1, 1], [1, 2, 2], [3, 1, 1]])),
                               np.array([False, True, True, False]))
    np.testing.assert_array_equal(out[:, 0], [2.0, 3.0, 3.0, 4.0])


def _fill_by_loop(values, edges, holes):
    """fill_from_neighbours' rounds written out edge by edge: each round's sums in float64, added in the
    order of ``edges`` (first ends, then second ends), from the values at the start of the round."""
    out = np.array(values, copy=True)
    flat = out.reshape(len(out), -1)
    filled = ~holes
    if filled.all() or not filled.any():
        return out
    pairs = [(int(i), int(j)) for i, j in edges] + [(int(j), int(i)) for i, j in edges]  # j's value flows to i
    while True:
        total, count = {}, {}
        for i, j in pairs:
            if filled[j] and not filled[i]:
                total[i] = total.get(i, np.zeros(flat.shape[1])) + flat[j].astype(np.float64)
                count[i] = count.get(i, 0) + 1
        if not total:
            return out
        for i in total:
            flat[i] = (total[i] / count[i]).astype(flat.dtype)
            filled[i] = True


@pytest.mark.parametrize("columns", [0, 1, 16])
def test_fill_from_neighbours_adds_like_a_loop_over_the_edges(columns):
    # bit for bit against the loop (float64 sums in edge order, then float32), values spread over 30 decades;
    # the pipeline's output hashes rely on this function not changing a bit
    pts, faces = box_shape((1.0, 0.6, 0.4), (7, 5, 4))
    edges = mesh_edges(faces)
    rng = np.random.default_rng(columns)
    edges = edges[rng.permutation(len(edges))]
    shape = (len(pts),) if columns == 0 else (len(pts), columns)
    values = (rng.standard_normal(shape) * 10.0 ** rng.uniform(-15, 15, shape)).astype(np.float32)
    for share in (0.1, 0.5, 0.9):
        holes = rng.random(len(pts)) < share
        out = fill_from_neighbours(values, edges, holes)
        assert out.dtype == values.dtype and out.shape == values.shape
        assert out.tobytes() == _fill_by_loop(values, edges, holes).tobytes()


def test_back_of_a_sheet_lying_on_the_floor_is_filled_from_its_rim(monkeypatch):
    """A two-sided 1.2 m sheet (9 × 9 vertices, x in [1.0, 2.2]) 2 cm above the ground (x up to 1.5): its back
    faces the floor. Its far end (x = 1.0) sees sky only within atan(0.02 / 0.5) of the horizon towards the
    ground's edge, under 0.16 % of the unoccluded light (sin² of it): buried; the part beyond the ground's
    edge sees the sky below. The back rows that receive light are unchanged, the buried ones are no longer
    black."""
    from warpshade.pipeline.shading import back_key

    n = 9
    x = np.linspace(-0.6, 0.6, n)
    X, Z = np.meshgrid(x, x, indexing="ij")
    i = np.arange(n * n).reshape(n, n)
    faces = np.concatenate([np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:]], -1).reshape(-1, 3),
                            np.stack([i[:-1, :-1], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 3)])
    sheet = TriMesh(np.stack([X.ravel() + 1.6, np.full(n * n, 0.02), Z.ravel()], 1), faces, name="sheet")

    def back(fill):
        if not fill:
            monkeypatch.setattr(shading, "BURIED", -np.inf)
        sc = Scene(objects=[SceneObject("ground", ground_mesh(), method="hemiraster"),
                            SceneObject("sheet", sheet, method="hemiraster", two_sided=True)],
                   frames=1, lights=[LightSpec("dome", "sky")])
        out = Pipeline(sc, order=3, write_transfer=True).shader.build()(0, {})
        monkeypatch.undo()
        return out[back_key("sheet")][2], out[back_key("sheet")][3]

    (c0, t0), (c1, t1) = back(False), back(True)
    buried = t0[:, 0] <= shading.BURIED * T0
    px = sheet.points[:, 0]
    assert buried[px < 1.01].all() and not buried[px > 1.7].any()
    assert np.array_equal(t1[~buried], t0[~buried]) and np.array_equal(c1[~buried], c0[~buried])
    assert np.all(t1[buried, 0] >= t0[~buried, 0].min())  # means of the rim's values, none black


def test_the_early_stop_leaves_the_output_as_it_was(runs, monkeypatch):
    """The pipeline lets hemiraster stop rasterizing at receivers it will fill anyway
    (``stop_when_dark``): the output is the same bit for bit as without the stop, which did stop somewhere."""
    from warpshade.visibility.hemiraster.method import HemirasterTransfer

    calls = []
    stop_when_dark = HemirasterTransfer.stop_when_dark
    monkeypatch.setattr(HemirasterTransfer, "stop_when_dark",
                        lambda self, dc, near_first=False: calls.append(stop_when_dark(self, dc, near_first)) or calls[-1])
    sc = Scene(objects=[SceneObject("ground", ground_mesh(), method="hemiraster"),
                        SceneObject("box", box_mesh(), method="hemiraster")],
               frames=1, lights=[LightSpec("dome", "sky")])
    pipe = Pipeline(sc, order=3, write_transfer=True)
    out = pipe.shader.build()(0, {})
    monkeypatch.undo()
    assert calls and all(c >= 1 for c in calls)  # the stop was on
    monkeypatch.setattr(HemirasterTransfer, "stop_when_dark", lambda self, dc, near_first=False: -1)
    plain = Pipeline(sc, order=3, write_transfer=True).shader.build()(0, {})
    for k in ("ground", "box"):
        for a, b in zip(out[k], plain[k]):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
