"""The intersection count against brute-force NumPy oracles written here: the grid broad
phase of the cloth-cloth count (pair for pair against every pair by separating axes, and against
the BVH search), and the exact cloth-triangle-versus-cylinder/cone test (against dense sampling of
a signed distance with a Lipschitz bound)."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter
from warpshade.sim.intersections import count_self_pairs

# -- oracles ------------------------------------------------------------------------------------


def sat_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest separation of triangle pairs a, b (shape (P, 3, 3)) over the 17 candidate axes of
    two triangles (both normals, the 9 edge-edge cross products, the 6 in-plane edge normals),
    each axis normalised: > 0 proves the closed triangles disjoint, <= 0 that they meet (separating
    axis theorem for convex sets, complete for this axis set)."""
    ea = np.roll(a, -1, axis=1) - a
    eb = np.roll(b, -1, axis=1) - b
    na = np.cross(ea[:, 0], ea[:, 1])
    nb = np.cross(eb[:, 0], eb[:, 1])
    axes = [na, nb]
    axes += [np.cross(ea[:, i], eb[:, j]) for i in range(3) for j in range(3)]
    axes += [np.cross(na, ea[:, i]) for i in range(3)] + [np.cross(nb, eb[:, i]) for i in range(3)]
    best = np.full(len(a), -np.inf)
    for ax in axes:
        ln = np.linalg.norm(ax, axis=1)
        ok = ln > 1e-12 * (1 + np.abs(a).max())
        ax = ax / np.where(ok, ln, 1.0)[:, None]
        pa = np.einsum("pki,pi->pk", a, ax)
        pb = np.einsum("pki,pi->pk", b, ax)
        gap = np.maximum(pb.min(1) - pa.max(1), pa.min(1) - pb.max(1))
        best = np.where(ok, np.maximum(best, gap), best)
    return best


def all_pairs(points: np.ndarray, faces: np.ndarray):
    """(set of meeting non-adjacent pairs (t, u), t < u; number of pairs within 1e-9 m of touching)."""
    t, u = np.triu_indices(len(faces), 1)
    shared = (faces[t][:, :, None] == faces[u][:, None, :]).any(axis=(1, 2))
    t, u = t[~shared], u[~shared]
    gap = sat_gap(points[faces[t]], points[faces[u]])
    return {(int(i), int(j)) for i, j in zip(t[gap <= 0], u[gap <= 0])}, int((np.abs(gap) < 1e-9).sum())


def _pair_set(pairs: np.ndarray) -> set:
    return {(int(min(p)), int(max(p))) for p in pairs}


def _grid_and_bvh(points: np.ndarray, faces: np.ndarray):
    c = IntersectionCounter(faces, keep=20000)
    n_grid, p_grid = c.self_pairs(points)  # the hash grid (cells ~1 m, coordinates < 40 m)
    x = c._points(points)
    n_bvh, p_bvh = c._run(count_self_pairs, [c._mesh_id(), x, c.tris], None)
    assert n_grid == len(p_grid) and n_bvh == len(p_bvh)
    return _pair_set(p_grid), _pair_set(p_bvh)


@pytest.mark.parametrize("seed", range(6))
def test_grid_broad_phase_matches_all_pairs_on_triangle_soups(seed):
    """150 separate triangles of sizes 0.02-0.4 m in a cube (hundreds of crossings, boxes of very
    different widths, so a pair found from the wrong cell or twice would show): the grid count,
    the BVH count and the all-pairs separating-axis oracle give the same pairs."""
    rng = np.random.default_rng(seed)
    n = 150
    centre = rng.uniform(-0.5, 0.5, size=(n, 1, 3)) + (seed - 3) * 10.0  # away from the origin too
    size = rng.uniform(0.02, 0.4, size=(n, 1, 1))
    points = (centre + size * rng.uniform(-1, 1, size=(n, 3, 3))).reshape(-1, 3)
    faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    ref, near = all_pairs(points, faces)
    assert near == 0 and len(ref) > 50, (near, len(ref))
    grid, bvh = _grid_and_bvh(points, faces)
    assert grid == ref, (sorted(grid - ref)[:5], sorted(ref - grid)[:5])
    assert bvh == ref


@pytest.mark.parametrize("seed", range(3))
def test_grid_broad_phase_with_cells_wider_than_the_boxes(seed):
    """Eight clusters of small triangles (0.02-0.06 m) at the corners of a 30 m cube: a grid of
    cells one box wide would have about 10^8 cells, so the cells grow to keep within
    ``IntersectionCounter.MAX_CELLS`` (to over 0.6 m, five times the widest box) and a walk covers
    one or two cells holding many boxes; the grid count still finds exactly the pairs of all pairs."""
    rng = np.random.default_rng(seed)
    n = 200
    corner = rng.integers(0, 2, size=(n, 1, 3)) * 30.0
    centre = corner + rng.uniform(-0.05, 0.05, size=(n, 1, 3))
    size = rng.uniform(0.02, 0.06, size=(n, 1, 1))
    points = (centre + size * rng.uniform(-1, 1, size=(n, 3, 3))).reshape(-1, 3)
    faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    ref, near = all_pairs(points, faces)
    assert near == 0 and len(ref) > 50, (near, len(ref))
    c = IntersectionCounter(faces, keep=20000)
    n_grid, p_grid = c.self_pairs(points)
    assert c._cell_width > 3 * 0.12  # the cells grew past three times the widest box (<= 0.12 m)
    assert n_grid == len(p_grid) and _pair_set(p_grid) == ref


@pytest.mark.parametrize("seed", range(3))
def test_grid_broad_phase_matches_all_pairs_on_a_crumpled_cloth(seed):
    """A 14 x 14 cloth folded over itself and shaken (neighbours sharing a vertex are excluded by
    both): the same pairs from the grid, the BVH and all pairs."""
    b = ClothBuilder()
    b.add_grid(14, 14, 1.0, 1.0, origin=(-0.5, 0.0, -0.5))
    m = b.finalize()
    rng = np.random.default_rng(seed)
    x = m.rest_points_np.astype(np.float64)
    # fold the x > 0 half back over the other half at 0.03 m, then shake every vertex by 0.05 m
    r = 0.015
    fold = x[:, 0] > 0
    ang = np.clip(x[fold, 0] / r, 0, np.pi)
    x[fold, 0] = np.where(x[fold, 0] / r < np.pi, r * np.sin(ang), -(x[fold, 0] - np.pi * r))
    x[fold, 1] = r * (1 - np.cos(ang))
    x += rng.normal(0, 0.05, size=x.shape) * [1, 0.3, 1]
    ref, near = all_pairs(x, m.faces)
    assert near == 0 and len(ref) > 20, (near, len(ref))
    grid, bvh = _grid_and_bvh(x, m.faces)
    assert grid == ref, (sorted(grid - ref)[:5], sorted(ref - grid)[:5])
    assert bvh == ref


# -- cylinders and cones --------------------------------------------------------------------------


def _meridian(x, p0, p1):
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    h = (x - p0) @ u
    return np.linalg.norm((x - p0) - h[..., None] * u, axis=-1), h


def sd_cylinder(x, p0, p1, radius):
    """Exact signed distance: the 2-D box sdf (Quilez) of the meridian section."""
    r, h = _meridian(x, p0, p1)
    half = np.linalg.norm(p1 - p0) / 2
    q = np.stack([r - radius, np.abs(h - half) - half], -1)
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(axis=-1), 0)


def sd_cone(x, base, apex, radius):
    """Exact signed distance to the meridian triangle (-R, 0), (R, 0), (0, L)."""
    r, h = _meridian(x, base, apex)
    length = np.linalg.norm(apex - base)
    q = np.stack([r, h], -1)
    tri = np.array([[-radius, 0.0], [radius, 0.0], [0.0, length]])
    dist = np.inf
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        t = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        dist = np.minimum(dist, np.linalg.norm(q - (a + t[..., None] * (b - a)), axis=-1))
    inside = (h >= 0) & (r / radius + h / length <= 1)
    return np.where(inside, -dist, dist)


SAMPLES = 80
"""Subdivisions of the sampling grid along a triangle edge: every point of the triangle is within
longest edge / SAMPLES of a sample."""


def sampled_min(sd, tri):
    """Minimum of sd over the barycentric sample grid of each triangle (T, 3, 3), and the bound on
    how much lower the true minimum can be (sd is 1-Lipschitz)."""
    i, j = np.meshgrid(np.arange(SAMPLES + 1), np.arange(SAMPLES + 1), indexing="ij")
    keep = i + j <= SAMPLES
    w1, w2 = i[keep] / SAMPLES, j[keep] / SAMPLES
    pts = tri[:, None, 0] + w1[None, :, None] * (tri[:, None, 1] - tri[:, None, 0]) + w2[None, :, None] * (
        tri[:, None, 2] - tri[:, None, 0])
    edges = np.linalg.norm(np.roll(tri, -1, axis=1) - tri, axis=2).max(1)
    return sd(pts).min(1), edges / SAMPLES


@pytest.mark.parametrize("shape", ["cylinder", "cone"])
def test_cylinder_and_cone_count_is_exact(shape):
    """400 random triangles (0.05-0.5 m) around a tilted cylinder or cone of radius 0.15 m, length
    0.4 m: a triangle is counted iff its sampled signed distance says it meets the solid, wherever
    the sampling decides (min <= 0: meets; min > the Lipschitz bound: misses; the few in between
    are left out). Many of the hits have every corner outside (an edge or the face cuts a rim or
    the apex), which corner and sparse-interior sampling miss."""
    rng = np.random.default_rng(7)
    p0, p1 = np.array([0.05, 0.1, -0.02]), np.array([0.2, 0.45, 0.1])
    radius = 0.15
    col = ColliderSet()
    if shape == "cylinder":
        col.add_cylinder(p0, p1, radius)
        sd = lambda x: sd_cylinder(x, p0, p1, radius)  # noqa: E731
    else:
        col.add_cone(p0, p1, radius)
        sd = lambda x: sd_cone(x, p0, p1, radius)  # noqa: E731
    n = 400
    centre = (p0 + p1) / 2 + rng.uniform(-0.35, 0.35, size=(n, 1, 3))
    tri = centre + rng.uniform(0.05, 0.5, size=(n, 1, 1)) * rng.uniform(-1, 1, size=(n, 3, 3))
    smin, bound = sampled_min(sd, tri)
    hit, miss = smin <= 0, smin > bound
    decided = hit | miss
    corners_out = sd(tri).min(1) > 0
    assert decided.mean() > 0.9 and hit.sum() > 30 and (hit & corners_out).sum() > 15, (
        decided.mean(), hit.sum(), (hit & corners_out).sum())
    faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    c = IntersectionCounter(faces, keep=n)
    total, pairs = c.collider_pairs(tri.reshape(-1, 3), col)
    got = np.zeros(n, bool)
    got[pairs[:, 0]] = True
    assert total == got.sum()
    bad = np.flatnonzero(decided & (got != hit))
    assert len(bad) == 0, f"{len(bad)} triangles disagree, e.g. {tri[bad[0]].tolist()} (oracle says {hit[bad[0]]})"


# -- pairs inherited from the start of a step ---------------------------------------------------


def _crossing_sheets(dy):
    """A horizontal 6 x 6 sheet at y = 0 and a vertical one whose lower edge is at y = dy (crossing
    the first when dy < 0), in one mesh."""
    b = ClothBuilder()
    b.add_grid(6, 6, 1.0, 1.0, origin=(-0.5, 0.0, -0.5))
    b.add_grid(6, 6, 1.0, 1.0, origin=(-0.43, dy, -0.31), u_axis=(1, 0, 0), v_axis=(0, 1, 0.1))
    m = b.finalize()
    return m, m.rest_points_np.astype(np.float32)


def test_pairs_that_met_at_the_start_are_inherited_and_not_marked():
    """The same crossing at the start: every pair is inherited and nothing is marked; from a start
    where the sheets were apart: none is inherited and every crossing triangle is marked."""
    import warp as wp

    m, crossed = _crossing_sheets(-0.37)
    _, apart = _crossing_sheets(0.2)
    c = IntersectionCounter(m.faces)
    ref, _ = all_pairs(crossed.astype(np.float64), m.faces)
    for start, inherited in ((crossed, len(ref)), (apart, 0)):
        mark = wp.zeros(len(crossed), dtype=wp.int32)
        n = c.self_pairs(crossed, mark, wp.array(start, dtype=wp.vec3))[0]
        assert n == len(ref) > 4 and c.inherited == inherited
        corners = np.unique(m.faces[np.array(sorted(ref))].reshape(-1))
        expect = np.zeros(len(crossed), np.int32)
        if not inherited:
            expect[corners] = 1
        np.testing.assert_array_equal(mark.numpy(), expect)


def test_guard_leaves_an_inherited_intersection_alone():
    """Cloth that starts crossed (a state the guard did not make): the guard spends no rounds on
    it (no unresolved step, nothing sent back), and the free sheet falls as without the guard."""
    from warpshade.sim import XPBDSolver

    m, crossed = _crossing_sheets(-0.37)
    runs = {}
    for guard in (True, False):
        s = XPBDSolver(m, guard=guard, substeps=2)
        st = m.state()
        for _ in range(3):
            s.step(st, st, 1.0 / 60.0)
        runs[guard] = (st.points.numpy(), s.stats())
    (x_on, stats), (x_off, _) = runs[True], runs[False]
    assert stats["guard_steps"] == 0 and stats["guard_unresolved"] == 0, stats
    np.testing.assert_allclose(x_on, x_off, atol=1e-6)  # same float32 steps: the guard did nothing
    assert x_on[:, 1].mean() < crossed[:, 1].mean() - 0.01  # it fell


def test_box_edge_does_not_cut_between_cloth_vertices():
    """A coarse sheet (0.25 m spacing) falling on the ridge of a box turned 45 degrees, guard off:
    the edge contacts push the cloth's edges off the box's edge, so no cloth triangle meets the box
    in 30 frames (with vertex contacts alone the ridge cut through 24 triangles)."""
    from warpshade.sim import ColliderSet, XPBDSolver

    b = ClothBuilder()
    b.add_grid(5, 5, 1.0, 1.0, origin=(-0.5, 0.02, -0.5))
    m = b.finalize()
    col = ColliderSet()
    half = 0.2
    col.add_box((0.125, -half * np.sqrt(2), 0.0), (half, half, 0.8), (0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)))
    s = XPBDSolver(m, col, guard=False)
    st = m.state()
    c = IntersectionCounter(m.faces)
    worst = 0
    for _ in range(30):
        s.step(st, st, 1.0 / 60.0)
        worst = max(worst, c.collider_pairs(st.points, col)[0])
    assert worst == 0
    assert st.points.numpy()[:, 1].min() < -0.1  # it fell onto and past the ridge


def test_the_bvh_is_built_only_for_the_bvh_count_and_follows_the_points():
    """The hash-grid count never reads the counter's cloth BVH, so it is not built (nor refitted)
    for it; the BVH count, asked after the points moved, refits it first and finds the moved
    cloth's pairs (a stale BVH would miss the pairs that only the new points make)."""
    b = ClothBuilder()
    b.add_grid(14, 14, 1.0, 1.0, origin=(-0.5, 0.0, -0.5))
    m = b.finalize()
    flat = m.rest_points_np.astype(np.float64)
    c = IntersectionCounter(m.faces, keep=20000)
    assert c.self_pairs(flat)[0] == 0 and c.collider_pairs(flat, ColliderSet())[0] == 0
    assert c._mesh is None
    x = c._points(flat)
    assert c._run(count_self_pairs, [c._mesh_id(), x, c.tris], None)[0] == 0  # built at the flat cloth
    rng = np.random.default_rng(7)
    crumpled = flat + rng.normal(0, 0.05, size=flat.shape)
    ref, _ = all_pairs(crumpled, m.faces)
    n_grid, p_grid = c.self_pairs(crumpled)
    n_bvh, p_bvh = c._run(count_self_pairs, [c._mesh_id(), c._x, c.tris], None)
    assert len(ref) > 20 and _pair_set(p_grid) == ref and _pair_set(p_bvh) == ref, (len(ref), n_grid, n_bvh)
