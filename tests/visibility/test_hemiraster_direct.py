"""hemiraster's ``direct_far`` knob: coarse far-field triangles whose image spans at most 2 x 2 pixel
centres are rasterized in the per-blocker pass (:func:`warpshade.visibility.hemiraster.kernels.far_field_bits`)
from their LUT-quantised edge planes instead of through the queue.

The property checked: the masks are the plane LUT's images of the blockers, computed independently by
the NumPy oracle (:func:`~warpshade.visibility.hemiraster.oracle.rasterize_np` with the LUT, triangle
by triangle), except for bits a sliver's LUT image holds beyond the box of its corners; and the
triangles so handled are no longer queued.
"""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.geometry import TriMesh
from warpshade.visibility import get_method
from warpshade.visibility.hemiraster import tables
from warpshade.visibility.hemiraster.oracle import rasterize_np, tangent_frame_np

MASK, LUT = 32, 48


def grid(n, size, z, x0=0.0):
    """An n×n grid of size ``size`` at height ``z`` from (x0, x0), normals +z."""
    x, y = np.meshgrid(np.linspace(x0, x0 + size, n), np.linspace(x0, x0 + size, n), indexing="ij")
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return np.stack([x, y, np.full_like(x, z)], -1).reshape(-1, 3), np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def floor_under_canopy():
    """A flat 1 m receiver patch (6×6 vertices) under a wavy 5 m canopy of 1058 triangles 6 m up: seen
    from the patch, the canopy's triangles are sub-pixel to a few pixels wide (32² mask), so both
    paths of ``direct_far`` are taken; the patch's own triangles lie in its tangent plane (no image)."""
    rp, rf = grid(6, 1.0, 0.0)
    op, of = grid(24, 5.0, 6.0, x0=-2.0)
    op[:, 2] += 0.3 * np.sin(3 * op[:, 0]) * np.cos(2 * op[:, 1])
    return TriMesh(rp, rf), TriMesh(op, of)


def masks(direct_far):
    recv, canopy = floor_under_canopy()
    # refine 1e-6: nothing but the patch's own coplanar k-ring is refined, so every canopy blocker is
    # rasterized as a coarse triangle (the canopy is decimated a little: coarse < the patch's triangles)
    h = get_method("hemiraster")(recv, order=3, mask=MASK, lut=LUT, coarse=recv.num_faces - 2, min_image=0.0,
                                 refine=1e-6, fan=False, occluders=[canopy], direct_far=direct_far)
    h.update()
    return h, tables.unpack_bits(h._mask.numpy(), MASK * MASK)


@pytest.fixture(scope="module")
def oracle_masks():
    """Per receiver the OR of the LUT images of every blocker (the coarse scene at this pose), by the oracle."""
    h, _ = masks(False)
    pts, faces = h._bpoints.numpy().astype(np.float64), h._bfaces.numpy()
    recv = h.mesh
    lut = tables.build_lut(MASK, LUT)[0]
    want = np.zeros((recv.num_vertices, MASK * MASK), bool)
    for v in range(recv.num_vertices):
        frame = tangent_frame_np(recv.normals[v].astype(np.float64))
        want[v] = rasterize_np((pts[faces] - recv.points[v]) @ frame, MASK, lut, LUT)
    return want


def test_direct_far_masks_are_the_lut_images_but_for_sliver_tips(oracle_masks):
    want = oracle_masks
    off_h, off = masks(False)
    on_h, on = masks(True)
    assert want.sum() > 4000  # the canopy covers a good part of every mask (5235 bits measured)
    # the queue's masks are the oracle's (the harness is right) but for pixel centres on a blocker's edge, where the
    # kernel (float32) and the oracle (float64) round apart: 1 of 36864 bits measured since the occluders keep their
    # outline (the canopy's decimation changed; 0 before), a pixel 1.7e-4 rad from the edge two canopy triangles share
    ties = off != want
    assert ties.sum() <= 4
    assert not (on & ~want & ~ties).any()  # no bit outside a LUT image
    # bits of LUT images reaching past a sliver's box are lost: measured 17 of 5235 here (0.3 %)
    assert (want & ~on).sum() <= 0.01 * want.sum()
    # nearly every canopy triangle is small enough: 1015 queued per receiver without, 9.7 with (measured)
    assert on_h.stats()["triangles_per_vertex"] < 0.05 * off_h.stats()["triangles_per_vertex"]


def test_direct_far_needs_the_refinement_and_no_pvs():
    recv, _ = floor_under_canopy()
    with pytest.raises(ValueError, match="direct_far needs refine"):
        get_method("hemiraster")(recv, order=3, refine=0.0, coarse=recv.num_faces - 2, direct_far=True)
    with pytest.raises(ValueError, match="direct_far needs no PVS"):
        get_method("hemiraster")(recv, order=3, coarse=recv.num_faces - 2, direct_far=True,
                                 pvs_frames=recv.points[None].astype(np.float32))


def test_direct_far_on_a_self_shadowing_sheet_sets_only_queue_bits():
    """The receiver mesh as its own far field (a wavy 24 x 24 sheet, 300 coarse triangles, the default
    refinement and k-ring): the blockers the direct path takes (listed from the bit rows, their planes
    quantised in the second pass) set no bit the queue would not, and lose few (sliver tips)."""
    p, f = grid(24, 1.0, 0.0)
    p[:, 2] = 0.12 * np.sin(9 * p[:, 0]) * np.cos(7 * p[:, 1]) + 0.05 * np.sin(23 * p[:, 1])
    sheet = TriMesh(p, f)
    got = {}
    for direct_far in (False, True):
        h = get_method("hemiraster")(sheet, order=3, mask=MASK, lut=LUT, coarse=300, min_image=0.0, direct_far=direct_far)
        h.update()
        got[direct_far] = (h.stats()["triangles_per_vertex"], tables.unpack_bits(h._mask.numpy(), MASK * MASK))
    (off_tris, off), (on_tris, on) = got[False], got[True]
    assert off.sum() > 50000  # the sheet shades itself (84 952 bits measured)
    assert not (on & ~off).any()
    assert (off & ~on).sum() <= 0.001 * off.sum()  # 30 lost measured (0.035 %)
    assert on_tris < 0.95 * off_tris  # 206 -> 187 triangles queued per receiver measured
