"""hemiraster's mid level (``mid`` knob): a decimated mesh between the coarse far field and the fine mesh.

A refined coarse blocker is replaced by the mid triangles it stands for, and only the mid triangles
near the receiver (relative to their own deviation from the fine surface) by their fine triangles.
These tests check the structures (bounds and deviations that enclose what each level stands for,
groups that partition the level below) and the behaviour: closed shells stay closed across the
coarse/mid/fine seams, the k-ring stays exact, refining everything is the exact far field, and the
contact and fold cases of ``test_hemiraster_contact`` keep their bounds with the mid level on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from helpers import level_bounds
from test_hemiraster_contact import UNOCCLUDED_T0, ball_under_cap, differences, folded_sheet, grid_sheet, hemiraster, merge
from warpshade.geometry import TriMesh
from warpshade.visibility.hemiraster import hierarchy, tables
from warpshade.visibility.hemiraster.oracle import rasterize_np, tangent_frame_np


def crumpled_sheet(n=24, seed=0):
    """An n×n sheet with random folds up to 0.15 m deep over 1 m: every coarse triangle deviates."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    z = np.zeros_like(x)
    for _ in range(6):
        k = rng.normal(size=2) * 9
        z += 0.05 * np.sin(k[0] * x + k[1] * y + rng.uniform(0, 6))
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return TriMesh(np.stack([x, y, z], -1).reshape(-1, 3), np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))


def test_mid_level_is_built_only_between_coarse_and_fine():
    mesh = crumpled_sheet()  # 1058 triangles
    assert hemiraster(mesh, order=2, coarse=64, mid=300).stats()["mid_triangles"] > 0
    for knobs in ({"mid": 0}, {"coarse": 64, "mid": 64}, {"coarse": 64, "mid": 5000}, {"coarse": 0, "mid": 300},
                  {"coarse": 64, "mid": 300, "refine": 0.0}):
        assert hemiraster(mesh, order=2, **knobs).stats()["mid_triangles"] == 0, knobs


def test_mid_groups_partition_each_level():
    mesh = folded_sheet(8, 20)
    parts = [(mesh.points, mesh.faces.astype(np.int64))]
    far = hierarchy.far_field(parts, [40], [120])
    mid = far["mid"]
    nm, nc = len(mid["faces"]), len(far["faces"])
    # every fine triangle has one primary mid triangle, every mid triangle one primary coarse one
    assert mid["owner"].shape == (mesh.num_faces,) and mid["owner"].min() >= 0 and mid["owner"].max() < nm
    assert mid["coarse_owner"].shape == (nm,) and mid["coarse_owner"].max() < nc
    for pairs, primary in ((mid["extra"], mid["owner"]), (mid["coarse_extra"], mid["coarse_owner"])):
        assert (pairs[:, 1] != primary[pairs[:, 0]]).all()  # extras are never primaries
        assert len(np.unique(pairs, axis=0)) == len(pairs)
    # the mid vertices are bound to the fine surface: at rest the binding reproduces them
    a, b, c = (mesh.points[mesh.faces[mid["bind_face"], k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    w = mid["bind_bary"].astype(np.float64)
    q = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c + mid["bind_offset"][:, None] * n
    np.testing.assert_allclose(q, mid["points"], atol=1e-5)


def test_mid_bounds_and_deviation_enclose_what_each_level_stands_for():
    mesh = crumpled_sheet()
    h = hemiraster(mesh, order=2, coarse=48, mid=240)
    rng = np.random.default_rng(2)
    pts = mesh.points + rng.normal(scale=0.002, size=mesh.points.shape)
    h.update(pts)
    p64 = pts.astype(np.float32).astype(np.float64)
    mp = h._mids.points.numpy().astype(np.float64)
    mf = h._mids.faces.numpy()
    start, mid, tris = (x.numpy() for x in (h._sub.start, h._sub.mid, h._sub.tris))
    lo, hi, dev = h._mid_box[0].numpy(), h._mid_box[1].numpy(), h._mid_dev.numpy()
    offs = np.abs(h._mid_bind[2].numpy())
    outline = h._mid_outline.numpy()
    assert outline.max() > 0  # the sheet's boundary
    assert h.num_mid == len(mf) and len(mf) > 48
    # the box holds the mid triangle and every fine triangle it stands for (primaries and extras)
    want_lo, want_hi, want_dev = level_bounds(mp, mf, p64, mesh.faces, start, mid, tris, offs, outline)
    np.testing.assert_allclose(lo, want_lo, atol=1e-6)
    np.testing.assert_allclose(hi, want_hi, atol=1e-6)
    np.testing.assert_allclose(dev, want_dev, rtol=1e-4, atol=1e-7)
    for m in range(len(mf)):
        # the deviation bounds every primary fine vertex's distance from the mid triangle's plane
        a, b, c = mp[mf[m]]
        nrm = np.cross(b - a, c - a)
        prim = p64[mesh.faces[tris[start[m]:mid[m]]]].reshape(-1, 3)
        assert (np.abs((prim - a) @ nrm) / np.linalg.norm(nrm) <= dev[m] * (1 + 1e-4) + 1e-7).all(), f"mid {m}"
    # a coarse blocker's box holds the boxes of the mid triangles it stands for (and so their fine triangles)
    clo, chi = h._blocker_box[0].numpy(), h._blocker_box[1].numpy()
    gs, gt = h._group_start.numpy(), h._group_tris.numpy()
    for t in range(h.num_blockers):
        ms = gt[gs[t]:gs[t + 1]]
        if len(ms):
            assert (clo[t] <= lo[ms].min(axis=0) + 1e-6).all() and (chi[t] >= hi[ms].max(axis=0) - 1e-6).all(), t
    # and the mid triangles deviate less than the coarse ones: that is what the level is for
    assert np.median(dev) < 0.5 * np.median(h._blocker_dev.numpy())


def test_outline_deviation_covers_the_corners_decimation_rounds_off():
    # decimation rounds off a sheet's corners; along the surface nothing else covers them, so the
    # mid triangles there deviate by at least how far the fine boundary lies from them
    mesh = folded_sheet()
    far = hierarchy.far_field([(mesh.points, mesh.faces.astype(np.int64))], [128], [400])
    mid = far["mid"]
    corner = np.array([0.0, 0.5, 0.02])  # a corner of the upper leg
    at_corner = (np.linalg.norm(mesh.points - corner, axis=1) < 1e-9)[mesh.faces].any(axis=1)
    owners = np.unique(mid["owner"][at_corner])
    tri = mid["points"][mid["faces"][owners]]
    near, _ = hierarchy.closest_points_on_triangles(corner, tri[:, 0], tri[:, 1], tri[:, 2])
    gone = np.linalg.norm(near - corner, axis=1)
    assert gone.min() > 0.005  # measured 0.0116: the corner is cut off
    np.testing.assert_array_less(gone - 1e-6, mid["outline"][owners])
    assert (mid["outline"] == 0).sum() > len(mid["faces"]) // 2  # zero away from the boundary


def test_border_keeps_the_outline_in_both_decimations():
    # a crumpled sheet's boundary vertices: decimation drops most (it rounds the outline off);
    # with border every one stays a vertex of the coarse and of the mid mesh, at its fine position
    mesh = crumpled_sheet()
    f = mesh.faces.astype(np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    outline = mesh.points[np.unique(uniq[counts == 1])].astype(np.float64)  # the 92 boundary vertices

    def kept(points):
        d = np.linalg.norm(outline[:, None] - np.asarray(points)[None], axis=2).min(axis=1)
        return int((d < 1e-5).sum())  # decimation snaps to a grid of 2^-20 diagonals (1.4e-6 here)

    plain = hierarchy.far_field([(mesh.points, f)], [128], [400])
    kept_far = hierarchy.far_field([(mesh.points, f)], [128], [400], border=True)
    assert kept(plain["points"]) < len(outline) // 2
    assert kept(kept_far["points"]) == len(outline) and kept(kept_far["mid"]["points"]) == len(outline)
    h = hemiraster(mesh, order=1, coarse=128, border=True)
    assert h.knobs()["border"] and hemiraster(mesh, order=1, coarse=128).knobs()["border"] is False


def test_refining_everything_with_the_mid_level_is_the_exact_far_field():
    # every coarse blocker refined, every mid triangle expanded: the primaries partition the fine
    # mesh at both levels, so the masks equal coarse=0's bit for bit
    mesh = merge(grid_sheet(14, 0.0), grid_sheet(14, 0.03, flip=True))
    bent = mesh.points.copy()
    bent[:, 2] += 0.1 * np.sin(3 * bent[:, 0])
    exact = hemiraster(mesh, order=3, coarse=0)
    h = hemiraster(mesh, order=3, coarse=48, mid=200, refine=1e9)
    assert h.stats()["mid_triangles"] > 0
    for pts in (mesh.points, bent):
        np.testing.assert_allclose(h.update(pts).numpy(), exact.update(pts).numpy(), atol=1e-6)
        np.testing.assert_array_equal(h._mask.numpy(), exact._mask.numpy())
        assert h.stats()["mid_per_vertex"] == 0


def shell_with_receivers(subdivisions=4, count=40, seed=1):
    """A closed unit icosphere and ``count`` tiny receiver triangles inside it, 0.5-10 cm from its wall."""
    shell = trimesh.creation.icosphere(subdivisions, radius=1.0)
    rng = np.random.default_rng(seed)
    recv, faces = [], []
    for i in range(count):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        t1 = np.cross(d, [0.3, 0.5, 0.8])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(d, t1)
        c = d * rng.uniform(0.9, 0.995)
        recv += [c, c + 0.002 * t1, c + 0.002 * t2]
        faces.append([3 * i, 3 * i + 1, 3 * i + 2])
    n = len(recv)
    return TriMesh(np.concatenate([np.array(recv), shell.vertices]), np.concatenate([np.array(faces), shell.faces + n])), n


def test_closed_shell_stays_closed_across_coarse_mid_and_fine_seams():
    # receivers inside a closed shell near its wall: coarse triangles near them are refined to mid
    # triangles, the nearest mid triangles to fine ones, the rest stay coarse, so every kind of seam
    # is in view. Every direction must stay blocked up to LUT pinholes at quantised vertices (at
    # most three 32² pixels, as in test_hemiraster's closed shell; measured max 0.17 % of T_0)
    mesh, n = shell_with_receivers()
    h = hemiraster(mesh, order=3, coarse=256, mid=1280)
    t = h.update().numpy()[:n]
    st = h.stats()
    assert st["mid_per_vertex"] > 10 and st["refined_per_vertex"] > 10  # both seams are there
    assert np.abs(t).max() < 0.0036 * UNOCCLUDED_T0, np.abs(t).max() / UNOCCLUDED_T0


def ring_images_missing(h, mesh, receivers):
    """Per receiver: LUT bits of its k-ring's fine triangles (NumPy, the kernels' quantisation) that
    are not in its mask."""
    table, _, _ = tables.build_lut(h.mask_res, h.lut_res)
    start, tris, _ = hierarchy.ring_triangles(mesh.faces.astype(np.int64), mesh.num_vertices, h.ring)
    words = h._mask.numpy()
    pts = h.points.numpy().astype(np.float64)
    nrm = h.normals.numpy().astype(np.float64)
    out = []
    for v in receivers:
        frame = tangent_frame_np(nrm[v])
        local = (pts[mesh.faces[tris[start[v]:start[v + 1]]]] - pts[v]) @ frame
        want = rasterize_np(local, h.mask_res, table, h.lut_res)
        have = tables.unpack_bits(words[v], h.mask_res * h.mask_res)
        out.append(int((want & ~have).sum()))
    return np.array(out)


def test_k_ring_mid_triangles_are_forced_and_their_images_kept():
    # the k-ring is always rasterized from fine triangles: per receiver, the mid triangles standing
    # for its k-ring (and for its own triangles) are listed and always replaced by their fine ones
    mesh = crumpled_sheet()
    h = hemiraster(mesh, order=2, coarse=48, mid=240, refine=1e-6)
    faces = mesh.faces.astype(np.int64)
    rs, rt, _ = hierarchy.ring_triangles(faces, mesh.num_vertices, 1)
    vf = hierarchy.vertex_faces(faces, mesh.num_vertices)
    start, items = h._mids.ring_start.numpy(), h._mids.ring_tris.numpy()
    # the method's mid triangles are renumbered: map each fine triangle's primary through the sub-groups
    sub_start, sub_mid, sub_tris = h._sub.start.numpy(), h._sub.mid.numpy(), h._sub.tris.numpy()
    primary = np.empty(mesh.num_faces, np.int64)
    for m in range(h.num_mid):
        primary[sub_tris[sub_start[m]:sub_mid[m]]] = m
    for v in range(mesh.num_vertices):
        want = np.unique(primary[np.concatenate([rt[rs[v]:rs[v + 1]], vf[v]])])
        np.testing.assert_array_equal(np.sort(items[start[v]:start[v + 1]]), want, err_msg=f"receiver {v}")
    # with a vanishing refinement radius only the forced ones are refined: every k-ring triangle's
    # image is in the mask (float32 kernel vs float64 NumPy planes can differ by a few rim pixels)
    h.update()
    assert h.stats()["mid_per_vertex"] > 0 and h.stats()["refined_per_vertex"] > 0
    missing = ring_images_missing(h, mesh, np.arange(0, mesh.num_vertices, 10))
    assert missing.max() <= 3, (missing.max(), (missing > 0).sum())


# ------------------------------------------------------ the contact cases of test_hemiraster_contact
@pytest.mark.parametrize("case", ["stacked", "folded"])
def test_surfaces_in_contact_match_the_exact_far_field_with_the_mid_level(case):
    if case == "stacked":
        mesh = merge(grid_sheet(20, 0.0), grid_sheet(20, 0.01, flip=True))
        bound_mean, bound_max = 0.002, 0.02  # test_hemiraster_contact's bounds
    else:
        mesh = folded_sheet()
        bound_mean, bound_max = 0.01, 0.08
    exact = hemiraster(mesh, order=3, coarse=0).update().numpy()
    h = hemiraster(mesh, order=3, coarse=128, mid=400)
    d = differences(h.update().numpy(), exact)
    st = h.stats()
    assert st["mid_triangles"] > 0 and st["mid_per_vertex"] > 0
    assert d.mean() < bound_mean and d.max() < bound_max, (case, d.mean(), d.max())


def test_ball_under_a_draped_cap_sees_no_sky_with_the_mid_level():
    mesh, under = ball_under_cap()
    h = hemiraster(mesh, order=3, coarse=256, mid=800)
    t = h.update().numpy()[under]
    assert h.stats()["mid_per_vertex"] > 0
    assert np.abs(t).max() < 0.0036 * UNOCCLUDED_T0, np.abs(t).max()


def test_character_frame_matches_the_exact_far_field_with_the_mid_level():
    from warpshade.bench.meshes import character

    bm = character()
    exact = hemiraster(bm.rest, order=3, coarse=0).update(bm.frame).numpy()
    h = hemiraster(bm.rest, order=3, coarse=256, mid=1024)
    d = differences(h.update(bm.frame).numpy(), exact)
    assert h.stats()["mid_per_vertex"] > 0
    # test_hemiraster_contact's bounds (mid level off: measured mean 0.0088, p99 0.046)
    assert d.mean() < 0.02 and np.percentile(d, 99) < 0.1, (d.mean(), np.percentile(d, 99))


def test_redecimate_rebuilds_the_mid_level_too():
    from warpshade.bench.meshes import wrinkled_cloth

    bm = wrinkled_cloth(24)
    h = hemiraster(bm.rest, order=2, coarse=64, mid=256, redecimate=0.1)
    t = h.update(bm.frame).numpy()
    fresh = hemiraster(TriMesh(bm.frame, bm.rest.faces), order=2, coarse=64, mid=256)
    assert h.stats()["rebuilds"] == 1 and h.stats()["mid_triangles"] == fresh.stats()["mid_triangles"]
    np.testing.assert_allclose(t, fresh.update(bm.frame).numpy(), atol=1e-5)


def test_mid_level_stats_and_knob():
    mesh = crumpled_sheet()
    h = hemiraster(mesh, order=2, coarse=64, mid=300)
    h.update()
    st = h.stats()
    assert st["mid_triangles"] == h.num_mid > 0 and st["mid_per_vertex"] > 0
    assert h.knobs()["mid"] == 300
    with pytest.raises(ValueError, match="mid"):
        hemiraster(mesh, order=2, mid=-1)
    assert math.isfinite(st["refined_per_vertex"])


def test_group_bits_are_the_groups_lists():
    start = np.array([0, 3, 3, 7])
    mid = np.array([2, 3, 5])
    tris = np.array([0, 65, 3, 1, 2, 70, 129])
    cover, primary = hierarchy.group_bits(start, mid, tris, 130)
    for t in range(3):
        for bits, items in ((cover, tris[start[t]:start[t + 1]]), (primary, tris[start[t]:mid[t]])):
            got = [w * 64 + k for w in range(bits.shape[1]) for k in range(64) if (int(bits[t, w]) >> k) & 1]
            assert got == sorted(items.tolist()), (t, got)


@pytest.mark.parametrize("ring", [0, 1, "bear"])
def test_mid_set_queues_what_the_per_group_walk_queues(ring):
    """The far-field pass collects the refined coarse blockers' mid triangles as a bit set
    (kernels.rasterize_mid_set), and the fine triangles of the mid triangles replaced near the receiver
    as a second bit set (``sub.use_set``); recording a PVS walks each refined blocker's group instead
    (kernels.rasterize_mid_group, kernels.rasterize_mid_fine). Both must rasterize the same triangles:
    same masks and counts."""
    import warp as wp

    from warpshade.bench.meshes import wrinkled_cloth

    from warpshade.bench.meshes import warp_mesh

    if ring == "bear":
        # closed: refined coarse blockers below the horizon whose replaced mid triangles' primaries are
        # extras of visited ones (the fine set's removal step); the walk and the set differ in counts
        # without it
        mesh = warp_mesh("bear").rest
        h, pts = hemiraster(mesh, order=2, mid=2048), mesh.points
    else:
        bm = wrinkled_cloth(24)
        h, pts = hemiraster(TriMesh(bm.frame, bm.rest.faces), order=2, coarse=64, mid=256, ring=ring), bm.frame
    assert h._groups.use_set == 1 and h._sub.use_set == 1
    h.update(pts)
    mask, counts, mids = h._mask.numpy().copy(), h._counts.numpy().copy(), h._mids.counts.numpy().copy()
    refined = h._refined.numpy().copy()
    assert mids.mean() > 10 and h.stats()["refined_per_vertex"] > 1
    h._hits = wp.zeros((h.mesh.num_vertices, (h.num_blockers + 31) // 32), dtype=wp.uint32, device=h.device)
    h._launch(record=1, use_pvs=0)
    assert np.array_equal(h._mask.numpy(), mask)
    assert np.array_equal(h._counts.numpy(), counts) and np.array_equal(h._mids.counts.numpy(), mids)
    assert np.array_equal(h._refined.numpy(), refined)


@pytest.mark.parametrize("closed", [False, True])
def test_fine_set_queues_what_the_per_group_walk_queues(closed, monkeypatch):
    """Without the mid level the far-field pass collects the refined coarse blockers' fine triangles as
    a bit set (kernels.rasterize_fine_set); recording a PVS, or a mesh too large for the bit rows
    (method.SET_BYTES), walks each refined blocker's group instead (kernels.rasterize_group). All must
    rasterize the same triangles: same masks and counts (the rasterized-once table makes the walk's
    counts those of distinct triangles)."""
    import warp as wp

    from warpshade.bench.meshes import warp_mesh, wrinkled_cloth
    from warpshade.visibility.hemiraster import method

    if closed:
        mesh = warp_mesh("bear").rest  # closed: back-face culling; seam extras around every refined group
        pts = mesh.points
    else:
        bm = wrinkled_cloth(24)
        mesh, pts = TriMesh(bm.frame, bm.rest.faces), bm.frame
    h = hemiraster(mesh, order=2, coarse=64 if not closed else 256)
    assert h._groups.use_set == 1
    h.update(pts)
    mask, counts, refined = h._mask.numpy().copy(), h._counts.numpy().copy(), h._refined.numpy().copy()
    assert refined.mean() > 10
    h._hits = wp.zeros((h.mesh.num_vertices, (h.num_blockers + 31) // 32), dtype=wp.uint32, device=h.device)
    h._launch(record=1, use_pvs=0)
    assert np.array_equal(h._mask.numpy(), mask)
    assert np.array_equal(h._counts.numpy(), counts) and np.array_equal(h._refined.numpy(), refined)
    monkeypatch.setattr(method, "SET_BYTES", 0)
    walk = hemiraster(mesh, order=2, coarse=64 if not closed else 256)
    assert walk._groups.use_set == 0
    walk.update(pts)
    assert np.array_equal(walk._mask.numpy(), mask)
    assert np.array_equal(walk._counts.numpy(), counts) and np.array_equal(walk._refined.numpy(), refined)


@pytest.mark.parametrize("mesh_name", ["bear", "wrinkled"])
def test_far_field_bits_give_the_per_cluster_culls(mesh_name):
    """kernels.far_field_bits computes every coarse blocker's per-frame culls (skip_early, bounds_below)
    and refinement bits per receiver in one native pass; per cluster in Warp (``precull`` 0) they must
    be the same bits: same masks and counts (closed bear: back faces culled; wrinkled sheet: the fan)."""
    from warpshade.bench.meshes import warp_mesh, wrinkled_cloth

    if mesh_name == "bear":
        mesh = warp_mesh("bear").rest
        pts = mesh.points
    else:
        bm = wrinkled_cloth(24)
        mesh, pts = TriMesh(bm.frame, bm.rest.faces), bm.frame
    h = hemiraster(mesh, order=2, coarse=200)
    assert h._blockers.precull == 1
    a = h.update(pts).numpy().copy()
    mask, counts, refined = h._mask.numpy().copy(), h._counts.numpy().copy(), h._refined.numpy().copy()
    assert counts.mean() > 20
    h._blockers.precull = 0
    b = h.update(pts).numpy()
    assert np.array_equal(h._mask.numpy(), mask) and np.array_equal(a, b)
    assert np.array_equal(h._counts.numpy(), counts) and np.array_equal(h._refined.numpy(), refined)


@pytest.mark.parametrize("refine", [2.0, 0.05])
def test_refined_bits_are_the_per_blocker_refinement_test(refine):
    """kernels.mark_refined skips the clusters that do not come near the receiver; its bits must equal
    kernels.refine_here of every blocker (float32, the same operations) or the receiver's k-ring bits
    (a small ``refine`` leaves few near clusters; the k-ring's blockers hold the receiver in their boxes,
    so they pass the distance test too unless their deviation is 0)."""
    from warpshade.bench.meshes import wrinkled_cloth

    bm = wrinkled_cloth(24)
    h = hemiraster(TriMesh(bm.frame, bm.rest.faces), order=2, coarse=64, refine=refine)
    lo, hi = (b.numpy() for b in h._blocker_box)
    for v in (0, 123, 311, 575):
        h.compute_rows([v])
        got = h._blockers.refined.numpy()[0]
        got = np.array([(int(got[t >> 6]) >> (t & 63)) & 1 for t in range(h.num_blockers)], bool)
        p = h.points.numpy()[v]
        d = np.maximum(np.maximum(lo - p, p - hi), np.float32(0))
        r = np.float32(h.refine) * h._blocker_dev.numpy()
        near = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]) < r * r
        excl = h._excl.numpy()[v]
        ring = np.array([(int(excl[s >> 5]) >> (s & 31)) & 1 for s in h._bsource.numpy()], bool)
        assert np.array_equal(got, near | ring), v
        assert got.any() and got.sum() < h.num_blockers


def test_faces_with_vertices_of_their_own_block_like_the_welded_surface():
    """A box table and a floor slab whose faces have vertices of their own along the rims (as the
    USD reader tessellates a Cube), a ball on the table and a sheet hanging above it: the far field
    is decimated from the surface, so the ball sees what it sees with the rims welded. Decimated
    apart, the faces' seams let the sky through: the ball's mean T_0 came out 0.434 instead of
    0.325 (welded). Tolerance: 1 % of an unoccluded T_0 (0.886); measured 0.00003 apart."""
    from warpshade.geometry.mesh import weld_indices
    from warpshade.geometry.shapes import box_shape

    cube = box_shape([1.0, 1.0, 1.0], [22, 22, 22])
    table, floor = (cube[0] * [1.2, 0.8, 0.8], cube[1]), (cube[0] * [6.0, 0.1, 6.0], cube[1])  # scaled Cubes
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.15)
    sheet, sheet_faces = grid_sheet(30, 0.0, size=1.0)
    sheet = sheet[:, [0, 2, 1]] * [1.6, 0.0, 1.2] + [-0.8, 1.4, -0.6]  # flat, horizontal, 1.4 m up
    parts = [(np.asarray(ball.vertices) + [0.2, 0.95, 0], ball.faces), (table[0] + [0, 0.4, 0], table[1]),
             (sheet, sheet_faces), (floor[0] + [0, -0.05, 0], floor[1])]
    split = merge(*parts)
    w = weld_indices(split.points)
    keep, inverse = np.unique(w, return_inverse=True)
    welded = TriMesh(split.points[keep], inverse[split.faces.reshape(-1)].reshape(-1, 3))
    rows = slice(0, len(ball.vertices))  # the ball's vertices come first, welded or not
    assert np.array_equal(welded.points[rows], split.points[rows])
    t_split = hemiraster(split, order=4).update().numpy()[rows, 0]
    t_welded = hemiraster(welded, order=4).update().numpy()[rows, 0]
    assert t_welded.mean() < 0.9 * UNOCCLUDED_T0  # the sheet shades the ball
    assert abs(t_split.mean() - t_welded.mean()) < 0.01 * UNOCCLUDED_T0, (t_split.mean(), t_welded.mean())


def _k_ring_by_search(faces, num_vertices, v, k):
    """The k-ring of ``v`` by breadth-first search over the triangles' edges (plain Python sets), and the
    triangles touching it that do not have ``v`` as a corner: an independent statement of what
    :func:`hierarchy.ring_triangles` lists."""
    nbrs = [set() for _ in range(num_vertices)]
    for f in faces.tolist():
        for a in f:
            nbrs[a].update(f)
    ring, frontier = {v}, {v}
    for _ in range(k):
        frontier = {u for w in frontier for u in nbrs[w]} - ring
        ring |= frontier
    tris = sorted(t for t, f in enumerate(faces.tolist()) if set(f) & ring and v not in f)
    return ring, tris


def ring_test_meshes():
    """Closed and open meshes, one with a degenerate triangle (a corner listed twice) and an isolated vertex."""
    sheet = crumpled_sheet(n=7)
    odd = np.array([[0, 1, 2], [2, 1, 3], [3, 1, 1], [3, 4, 2], [4, 5, 2], [5, 0, 2]], np.int64)  # vertex 6 unused
    return [(trimesh.creation.icosphere(2).faces.astype(np.int64), 162), (sheet.faces.astype(np.int64), sheet.num_vertices),
            (odd, 7)]


@pytest.mark.parametrize("k", [1, 2, 3])
def test_ring_triangles_match_a_breadth_first_search(k):
    for faces, nv in ring_test_meshes():
        start, tris, rings = hierarchy.ring_triangles(faces, nv, k)
        assert start.dtype == np.int32 and tris.dtype == np.int32 and start.shape == (nv + 1,) and len(rings) == nv
        for v in range(nv):
            ring, want = _k_ring_by_search(faces, nv, v, k)
            assert tris[start[v]:start[v + 1]].tolist() == want, (nv, v)
            assert sorted(rings[v].tolist()) == sorted(ring), (nv, v)


def test_ring_groups_hold_the_owners_of_the_ring_and_incident_triangles():
    rng = np.random.default_rng(3)
    for faces, nv in ring_test_meshes():
        start, tris, _ = hierarchy.ring_triangles(faces, nv, 2)
        for num_coarse in (5, 40):  # one word and two words of bits
            owner = rng.integers(0, num_coarse, len(faces))
            bits = hierarchy.ring_groups(start, tris, faces, owner, num_coarse)
            assert bits.dtype == np.uint32 and bits.shape == (nv, (num_coarse + 31) // 32)
            for v in range(nv):
                listed = [int(t) for t in tris[start[v]:start[v + 1]]] + [t for t, f in enumerate(faces.tolist()) if v in f]
                want = np.zeros(bits.shape[1] * 32, bool)
                want[owner[listed]] = True
                have = (bits[v][:, None] >> np.arange(32, dtype=np.uint32)) & 1
                np.testing.assert_array_equal(have.reshape(-1).astype(bool), want, err_msg=f"receiver {v}")
