"""hemiraster's early stop for buried receivers (``stop_when_dark``): a receiver stops rasterizing once its
transfer's DC is certainly at most the given value. Blockers only block more pixels, so a stopped receiver's
full transfer is that dark too, and every receiver whose full transfer is brighter must come out bit for bit
as without the stop (the stop also queues the refined blockers' fine triangles before the far field: the
same triangles, so the same masks and counts)."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import swaying_frames
from warpshade.geometry import TriMesh
from warpshade.geometry.shapes import box_shape
from warpshade.visibility import get_method

T0 = np.sqrt(np.pi) / 2  # unoccluded DC of the transfer, any normal
DARK = 5e-3 * T0  # the pipeline's buried threshold (warpshade.pipeline.shading.buried_dc)


def ground_box_sheet(n=13, m=8):
    """A ground grid at y = 0, a closed box standing on it (the ground under it is buried) and a wavy sheet
    above, merged (members share no vertex); returns the mesh and the sheet's first vertex."""
    x, z = np.meshgrid(np.linspace(-0.6, 0.6, n), np.linspace(-0.6, 0.6, n), indexing="ij")
    ground = np.stack([x, np.zeros_like(x), z], -1).reshape(-1, 3)
    bp, bf = box_shape((0.5, 0.25, 0.5), (4, 2, 4))
    bp = bp + (0.0, 0.125, 0.0)
    u, w = np.meshgrid(np.linspace(-0.4, 0.4, m), np.linspace(-0.4, 0.4, m), indexing="ij")
    sheet = np.stack([u, 0.45 + 0.05 * np.sin(6 * u) * np.cos(5 * w), w], -1).reshape(-1, 3)

    def grid(k, base):  # upward-facing triangles (normal +y)
        idx = np.arange(k * k).reshape(k, k) + base
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        return np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)])

    nb = len(bp)
    faces = np.concatenate([grid(n, 0), bf + n * n, grid(m, n * n + nb)])
    return TriMesh(np.concatenate([ground, bp, sheet]), faces), n * n + nb


def frames(mesh, first_sheet, count):
    """Ground and box stay, the sheet sways (so unmoved receivers keep a stored part from the second frame)."""
    return swaying_frames(mesh, first_sheet, count, up=1, across=2)


@pytest.mark.parametrize("near_first", [False, True])
@pytest.mark.parametrize("knobs", [{"coarse": 64}, {"coarse": 64, "ring": 0}, {"coarse": 0},
                                   {"coarse": 64, "refine": 0.0, "ring": 2}, {"coarse": 64, "keep_static": False}])
def test_stopped_receivers_are_dark_and_the_others_exact(knobs, near_first):
    mesh, first_sheet = ground_box_sheet()
    full = get_method("hemiraster")(mesh, order=3, **knobs)
    stop = get_method("hemiraster")(mesh, order=3, **knobs)
    assert stop.stop_when_dark(DARK, near_first=near_first) >= 1  # a few pixels of the 32² mask (~1.1e-3 of T0 each) fit under DARK
    fewer = 0
    for pts in frames(mesh, first_sheet, 4):
        full.update(pts)
        stop.update(pts)
        tf, ts = full.transfer.numpy(), stop.transfer.numpy()
        mf, ms = full._mask.numpy(), stop._mask.numpy()
        cf, cs = full._counts.numpy(), stop._counts.numpy()
        dark = tf[:, 0] <= DARK
        assert dark.sum() >= 9  # the ground under the box (3 × 3 vertices at least inside its footprint)
        bright = ~dark
        np.testing.assert_array_equal(ts[bright], tf[bright])
        np.testing.assert_array_equal(ms[bright], mf[bright])
        np.testing.assert_array_equal(cs[bright], cf[bright])
        np.testing.assert_array_equal(stop._refined.numpy()[bright], full._refined.numpy()[bright])
        # the dark ones: a subset of the full mask's pixels, and still dark
        assert not (ms[dark] & ~mf[dark]).any()
        assert (ts[dark, 0] <= DARK).all()
        assert (cs <= cf).all()
        fewer += int((cs < cf).sum())
    if knobs.get("refine") != 0.0:  # it stopped (with near_first at the ground under the box)
        assert fewer >= (9 if near_first else 1), fewer
    # (without refinement the box's coarse triangles come in one last batch: nothing left to skip)


@pytest.mark.parametrize("knobs", [{"coarse": 64, "interpolate": 0.05}, {"coarse": 64, "mode": "glossy"}])
def test_no_stop_where_rows_are_read_or_the_dc_is_not_the_diffuse_one(knobs):
    mesh, first_sheet = ground_box_sheet()
    full = get_method("hemiraster")(mesh, order=3, **knobs)
    stop = get_method("hemiraster")(mesh, order=3, **knobs)
    assert stop.stop_when_dark(DARK, near_first=True) == -1
    for pts in frames(mesh, first_sheet, 2):
        full.update(pts)
        stop.update(pts)
        np.testing.assert_array_equal(stop.transfer.numpy(), full.transfer.numpy())
        np.testing.assert_array_equal(stop._counts.numpy(), full._counts.numpy())
