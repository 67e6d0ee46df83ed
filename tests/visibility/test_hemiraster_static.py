"""hemiraster's ``keep_static``: the part of unmoved receivers' masks that unmoved blockers give is stored
and only the rest rasterized while they stay put; every mask, transfer and count must equal the full
rasterization's bit for bit (a mask is an OR of per-triangle images, so the split is exact)."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import swaying_frames
from warpshade.geometry import TriMesh
from warpshade.visibility import get_method


def ground_and_sheet(n=9, m=10):
    """A wavy n×n ground around z = 0 (its hills shadow its valleys) and a wavy m×m sheet 0.15 m above it,
    merged (members share no vertex)."""
    x, y = np.meshgrid(np.linspace(-0.6, 0.6, n), np.linspace(-0.6, 0.6, n), indexing="ij")
    ground = np.stack([x, y, 0.06 * np.sin(9 * x) * np.cos(8 * y)], -1).reshape(-1, 3)
    u, w = np.meshgrid(np.linspace(-0.4, 0.4, m), np.linspace(-0.4, 0.4, m), indexing="ij")
    sheet = np.stack([u, w, 0.15 + 0.05 * np.sin(6 * u) * np.cos(5 * w)], -1).reshape(-1, 3)

    def grid(k, base):
        idx = np.arange(k * k).reshape(k, k) + base
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])

    faces = np.concatenate([grid(n, 0), grid(m, n * n)])
    return TriMesh(np.concatenate([ground, sheet]), faces), n * n


def frames(mesh, ng, count):
    """The ground stays, the sheet sways and sinks a little every frame."""
    return swaying_frames(mesh, ng, count, up=2, across=1)


def same_state(a, b):
    np.testing.assert_array_equal(a.transfer.numpy(), b.transfer.numpy())
    np.testing.assert_array_equal(a._mask.numpy(), b._mask.numpy())
    np.testing.assert_array_equal(a._counts.numpy(), b._counts.numpy())
    np.testing.assert_array_equal(a._refined.numpy(), b._refined.numpy())


@pytest.mark.parametrize("knobs", [{"coarse": 64}, {"coarse": 64, "ring": 0}, {"coarse": 0},
                                   {"coarse": 64, "refine": 0.0, "ring": 2}, {"coarse": 64, "interpolate": 0.05},
                                   {"coarse": 64, "mode": "glossy"}])
def test_stored_part_gives_the_same_masks(knobs):
    mesh, ng = ground_and_sheet()
    full = get_method("hemiraster")(mesh, order=3, keep_static=False, **knobs)
    kept = get_method("hemiraster")(mesh, order=3, **knobs)
    for f, pts in enumerate(frames(mesh, ng, 5)):
        full.update(pts)
        kept.update(pts)
        same_state(full, kept)
        st = kept.stats()
        # stored on the second frame (the first that finds the ground where the last one left it), then reused;
        # with interpolation for the receivers computed every frame
        stored = ng if kept._interp is None else int((kept._interp[0].numpy() < ng).sum())
        assert st["static_receivers"] == (0 if f == 0 else stored), (f, st["static_receivers"])
        assert st["static_stores"] == (0 if f == 0 else 1)
    assert full.stats()["static_stores"] == 0
    # the stored part holds what the ground does to itself
    assert kept._static.counts.numpy()[:ng].sum() > 0


def test_unmoved_receivers_start_from_the_stored_part():
    mesh, ng = ground_and_sheet()
    h = get_method("hemiraster")(mesh, order=3, coarse=64)
    seq = frames(mesh, ng, 3)
    h.update(seq[0])
    h.update(seq[1])  # stored here
    blocked = h._static.mask.numpy()
    blocked[:] = np.uint64(2**64 - 1)
    h._static.mask.assign(blocked)  # as if every stored pixel were blocked
    h.update(seq[2])
    mask = h._mask.numpy()
    assert (mask[:ng] == np.uint64(2**64 - 1)).all()  # the stored part was ORed in
    assert not (mask[ng:] == np.uint64(2**64 - 1)).all()  # the moving sheet's receivers were not stored


def test_a_moved_unmoved_vertex_drops_the_stored_part():
    mesh, ng = ground_and_sheet()
    full = get_method("hemiraster")(mesh, order=3, coarse=64, keep_static=False)
    kept = get_method("hemiraster")(mesh, order=3, coarse=64)
    seq = frames(mesh, ng, 6)
    for f in (3, 4, 5):  # from frame 3 on one ground vertex under the sheet is raised
        seq[f][ng // 2, 2] = 0.01
    for f, pts in enumerate(seq):
        full.update(pts)
        kept.update(pts)
        same_state(full, kept)
        if f == 3:  # it moved: the part is dropped and this frame rasterized whole
            assert kept.stats()["static_receivers"] == 0
    # frame 4 stored the part again (every ground vertex as frame 3 left it)
    assert kept.stats()["static_stores"] == 2 and kept.stats()["static_receivers"] == ng


def test_a_repeated_pose_stores_nothing():
    mesh, ng = ground_and_sheet()
    h = get_method("hemiraster")(mesh, order=3, coarse=64)
    for _ in range(3):
        h.update(mesh.points)
    assert h.stats()["static_stores"] == 0


def test_compute_rows_stores_the_rows_it_computes():
    mesh, ng = ground_and_sheet()
    rows = np.arange(0, mesh.num_vertices, 3)
    full = get_method("hemiraster")(mesh, order=3, coarse=64, keep_static=False)
    kept = get_method("hemiraster")(mesh, order=3, coarse=64)
    for pts in frames(mesh, ng, 4):
        for h in (full, kept):
            h.set_points(pts)
            h.compute_rows(rows)
        np.testing.assert_array_equal(full.transfer.numpy()[rows], kept.transfer.numpy()[rows])
        np.testing.assert_array_equal(full._mask.numpy()[rows], kept._mask.numpy()[rows])
    assert kept.stats()["static_receivers"] == int((rows < ng).sum())


def test_compute_rows_stores_for_the_receivers_later_frames_compute():
    # temporal reuse computes another set of rows every frame: with ``later`` (every receiver here) the part
    # is stored once for every unmoved receiver, not only for the rows of the frame that stored it
    mesh, ng = ground_and_sheet()
    nv = mesh.num_vertices
    full = get_method("hemiraster")(mesh, order=3, coarse=64, keep_static=False)
    kept = get_method("hemiraster")(mesh, order=3, coarse=64)
    for k, pts in enumerate(frames(mesh, ng, 5)):
        rows = np.arange(k % 3, nv, 3)  # another third of the receivers each frame
        for h in (full, kept):
            h.set_points(pts)
            h.compute_rows(rows, later=np.arange(nv))
        np.testing.assert_array_equal(full.transfer.numpy()[rows], kept.transfer.numpy()[rows])
        np.testing.assert_array_equal(full._mask.numpy()[rows], kept._mask.numpy()[rows])
    assert kept.stats()["static_stores"] == 1 and kept.stats()["static_receivers"] == ng
