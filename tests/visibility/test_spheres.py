"""Sphere-set soft shadows: tables, kernels vs NumPy reference, analytic caps, tangent-plane rules,
extremes, cluster borders, fitting/refit, between-object API, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from conftest import warp_asset
from warpshade.cli import main as cli_main
from warpshade.geometry import TriMesh
from warpshade.usd import load_mesh
from warpshade.visibility import get_method
from warpshade.visibility.spheres import SpheresTransfer, build_sphere_tree, refit_np
from warpshade.visibility.spheres.fitting import tree_from_spheres
from warpshade.sh.products import sh_product
from warpshade.sh.zonal import sphere_visibility_zh as cap_blocker_zh
from warpshade.sh.zonal import zh_rotate
from warpshade.sh import unoccluded_transfer
from warpshade.visibility.spheres.oracle import adjust_sphere_np, shade_np

SQRT_4PI = math.sqrt(4 * math.pi)


def point_receiver(normal=(0.0, 0.0, 1.0), at=(0.0, 0.0, 0.0)):
    """A tiny triangle whose vertex 0 sits at ``at`` with normal ``normal`` (given explicitly)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    p = np.asarray(at, float)
    return TriMesh([p, p + 1e-4 * t, p + 1e-4 * b], [[0, 1, 2]], normals=np.tile(n, (3, 1)))


def spheres_on(recv, centers, radii, **kw):
    kw.setdefault("order", 5)
    m = SpheresTransfer(recv, self_shadow=False, blockers=[tree_from_spheres(centers, radii)], **kw)
    m.update(recv.points, recv.normals)
    return m


def grid(n, size):
    x = np.linspace(-size, size, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], 1)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
    return TriMesh(pts, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))


# -- kernels vs reference ------------------------------------------------------------------------
@pytest.mark.parametrize("mode, order", [("ol", 5), ("hyb", 5), ("series", 5), ("ol", 4), ("hyb", 4)])
def test_kernel_matches_numpy_reference(mode, order, rng):
    # ol/hyb run the fixed-order register kernel (fixed_kernels.py), series the runtime-order one
    # spheres all around, several straddling the tangent plane (exercises every adjustment rule)
    c = rng.normal(size=(12, 3)) * 1.5
    r = rng.uniform(0.2, 0.9, 12)
    for normal in ([0, 0, 1], [0.3, -0.5, 0.8]):
        recv = point_receiver(normal)
        m = spheres_on(recv, c, r, exp=mode, order=order)
        vis, tr, _ = shade_np(recv.points[0], recv.normals[0], c, r, order, mode, m.tau)
        # float32 kernel vs float64 reference; products of O(1) vectors: 1e-5 absolute is float32 noise
        np.testing.assert_allclose(m.visibility.numpy()[0], vis, atol=2e-5, err_msg=f"{mode} n={normal}")
        np.testing.assert_allclose(m.transfer.numpy()[0], tr, atol=2e-5, err_msg=f"{mode} n={normal}")


# Single-sphere error bounds measured over θ in [0, 1.56] (order 5, 40 radii): max 0.067 (ol), 0.077
# (hyb), 0.076 (series), all near θ -> π/2 where the cap's product matrix is indefinite and no log
# reproduces it; below θ = 0.6 every mode reproduces the cap to <= 2e-3.
SINGLE_TOL = {"ol": 0.085, "hyb": 0.095, "series": 0.095}


@pytest.mark.parametrize("mode", ["ol", "hyb", "series"])
def test_single_sphere_matches_analytic_cap(mode):
    recv = point_receiver()
    w = np.array([0.02, 0.01, 1.0])
    w /= np.linalg.norm(w)
    for theta in (1e-4, 0.1, 0.3, 0.6, 1.0, 1.3, 1.5, 1.56):
        dist = 2.0
        m = spheres_on(recv, [w * dist], [dist * math.sin(theta)], exp=mode)
        cap = zh_rotate(cap_blocker_zh(theta, 5), w)
        err = np.abs(m.visibility.numpy()[0] - cap).max()
        tol = 3e-3 if theta <= 0.6 else SINGLE_TOL[mode]
        assert err < tol, (mode, theta, err)


@pytest.mark.parametrize("nb", [2, 5, 10, 20, 50])
def test_exp_of_log_sum_vs_sh_products(nb):
    rng = np.random.default_rng(nb)
    w = rng.normal(size=(nb, 3))
    w[:, 2] = np.abs(w[:, 2]) + 0.3
    w /= np.linalg.norm(w, axis=1)[:, None]
    th = np.minimum(rng.uniform(0.05, 0.25, nb), 0.95 * np.arcsin(w[:, 2]))
    dist = rng.uniform(2, 5, nb)
    prod = np.zeros(25)
    prod[0] = SQRT_4PI
    for i in range(nb):
        prod = sh_product(prod, zh_rotate(cap_blocker_zh(th[i], 5), w[i]), 5)
    # relative L2 distance to the product of projected caps; measured (3 seeds, 50 blockers): series
    # 0.0055, hybrid (tau 0.5) 0.032, optimal linear 0.092; it grows about linearly with blockers.
    tol = {"series": 0.0002 * nb + 0.001, "hyb": 0.001 * nb + 0.003, "ol": 0.0022 * nb + 0.003}
    for mode, t in tol.items():
        m = spheres_on(point_receiver(), w * dist[:, None], dist * np.sin(th), exp=mode)
        err = np.linalg.norm(m.visibility.numpy()[0] - prod) / SQRT_4PI
        assert err < t, (mode, nb, err)


# -- tangent-plane rules -------------------------------------------------------------------------
def test_receiver_inside_tangent_outside_no_self_shadow_no_jump():
    r, h = 1.0, -0.4  # sphere centre below the tangent plane z = 0; cut circle radius d = sqrt(r^2 - h^2)
    d = math.sqrt(r * r - h * h)
    unocc = unoccluded_transfer([0, 0, 1], 5)
    xs = np.concatenate([np.linspace(0, d, 30), d + np.array([0.0, 1e-6, 1e-4, 1e-3]), np.linspace(d, 3 * d, 60)])
    xs.sort()
    ts = []
    for x in xs:
        recv = point_receiver(at=(x, 0, 0))
        m = spheres_on(recv, [[0, 0, h]], [r])
        ts.append(m.transfer.numpy()[0])
        if x <= d:  # inside or on the sphere: the sphere is removed -> exactly unoccluded
            np.testing.assert_allclose(ts[-1], unocc, atol=1e-5, err_msg=f"x={x}")
    ts = np.array(ts)
    # just outside: alpha ~ (x-d)/d, the blocker is tiny -> unoccluded within 1e-3
    k = np.searchsorted(xs, d + 1e-4)
    assert np.abs(ts[k] - unocc).max() < 1e-3
    # no discontinuity: the change between neighbours is bounded by a Lipschitz constant times the step
    steps = np.linalg.norm(np.diff(ts, axis=0), axis=1) / np.maximum(np.diff(xs), 1e-12)
    assert steps.max() < 5.0, steps.max()


def test_straddling_rules_continuous_in_sphere_height():
    # centre height h crosses 0 (rule "centre behind" -> "centre in front") and r (-> unadjusted)
    p, n = np.zeros(3), np.array([0, 0, 1.0])
    for x in (0.3, 1.5):  # receiver inside, and outside, the cut circle
        prev = None
        for h in np.linspace(-1.2, 1.2, 481):
            c, rho = adjust_sphere_np(p, n, np.array([x, 0, h]), 1.0)
            cur = np.append(c * rho, rho)  # the centre matters only in proportion to the size
            if prev is not None:
                assert np.abs(cur - prev).max() < 0.05, (x, h, cur, prev)
            prev = cur
            assert rho == 0 or np.dot(c - p, n) >= rho - 1e-12  # never behind or through p's plane


# -- extremes ------------------------------------------------------------------------------------
def test_enclosed_receiver_is_dark_not_negative():
    # 800 spheres of angular radius 0.2 on a shell around p: each covers 1 % of the sphere, so random
    # placement leaves ~e^-8 of it open
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(800, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    for mode in ("ol", "hyb", "series"):
        m = spheres_on(point_receiver(), 3 * dirs, np.full(800, 0.6), exp=mode)
        t = m.transfer.numpy()[0]
        v = m.visibility.numpy()[0]
        assert np.isfinite(t).all() and np.isfinite(v).all()
        assert t[0] >= 0 and v[0] >= 0
        assert t[0] < 0.05 * unoccluded_transfer([0, 0, 1], 5)[0], (mode, t[0])


@pytest.mark.parametrize("mode", ["ol", "hyb", "series"])
def test_thousand_overlapping_blockers(mode):
    rng = np.random.default_rng(4)
    unocc = unoccluded_transfer([0, 0, 1], 5)[0]
    # a cloud over the whole upper hemisphere: transfer goes to 0
    c = rng.normal(size=(1000, 3)) * [2.0, 2.0, 0.8] + [0, 0, 1.5]
    m = spheres_on(point_receiver(), c, rng.uniform(0.2, 0.5, 1000), exp=mode)
    t, v = m.transfer.numpy()[0], m.visibility.numpy()[0]
    assert np.isfinite(t).all() and np.isfinite(v).all() and t[0] >= 0 and v[0] >= 0
    assert t[0] < 0.05 * unocc, t[0]
    # a dense clump in a 30-degree cone: the log sum is a deep narrow well whose SH truncation rings, so
    # no exponential can represent it; the guard keeps the result finite, non-negative and bounded
    c = rng.normal(size=(1000, 3)) * 0.3 + [0, 0, 2.0]
    m = spheres_on(point_receiver(), c, rng.uniform(0.2, 0.5, 1000), exp=mode)
    t, v = m.transfer.numpy()[0], m.visibility.numpy()[0]
    assert np.isfinite(t).all() and np.isfinite(v).all() and t[0] >= 0 and v[0] >= 0
    assert t[0] <= 1.1 * unocc and v @ v <= 1.1 ** 2 * 4 * math.pi * (1 + 1e-5)


def test_extreme_angular_radii():
    unocc = unoccluded_transfer([0, 0, 1], 5)
    tiny = spheres_on(point_receiver(), [[0, 0, 1.0]], [1e-4])  # θ = 1e-4 rad
    np.testing.assert_allclose(tiny.transfer.numpy()[0], unocc, atol=1e-5)  # float32 sums of ~1 terms
    # a sphere touching p from above subtends π/2: it covers the whole upper hemisphere
    for mode in ("ol", "hyb", "series"):
        big = spheres_on(point_receiver(), [[0, 0, 1.0]], [1.0], exp=mode)
        t = big.transfer.numpy()[0]
        assert np.isfinite(t).all() and 0 <= t[0] < 0.1 * unocc[0], (mode, t[0])


# -- against ray tracing -------------------------------------------------------------------------
def test_plane_under_sphere_matches_ray_traced_reference():
    plane = grid(21, 3.0)
    ball = trimesh.creation.icosphere(3, radius=0.8)
    ball_mesh = TriMesh(ball.vertices + [0, 0, 1.2], ball.faces)
    ref = get_method("reference")(plane, order=4, rays=1024, occluders=[ball_mesh]).update().numpy()
    m = SpheresTransfer(plane, order=4, self_shadow=False, blockers=[ball_mesh], spheres=8, levels=2)
    t = m.update().numpy()
    err = np.linalg.norm(t - ref, axis=1).mean() / np.linalg.norm(ref, axis=1).mean()
    unocc = np.array([unoccluded_transfer(n, 4) for n in plane.normals])
    err_unocc = np.linalg.norm(unocc - ref, axis=1).mean() / np.linalg.norm(ref, axis=1).mean()
    # measured: spheres 0.05 vs unoccluded 0.19 (sphere-set fit of a sphere + SH product truncation)
    assert err < 0.08 and err < 0.4 * err_unocc, (err, err_unocc)


# -- clusters ------------------------------------------------------------------------------------
def test_continuity_across_cluster_borders():
    bear = load_mesh(warp_asset("bear.usd"))
    p = bear.points[:, [0, 2, 1]].copy()
    p[:, 1] *= -1
    p[:, 2] += 3.0
    bear = TriMesh(p, bear.faces[:, [0, 2, 1]])
    g = grid(60, 8.0)
    edges = np.concatenate([g.faces[:, [0, 1]], g.faces[:, [1, 2]], g.faces[:, [2, 0]]])
    for thr in (0.35, 0.7):  # 0.7: 12.6 of 16 cut spheres per cluster, i.e. coarse levels in use
        m = SpheresTransfer(g, order=4, spheres=16, levels=3, threshold=thr, self_shadow=False, blockers=[bear],
                            clusters=16)
        t = m.update().numpy()
        lab = m.cluster.numpy()
        border = lab[edges[:, 0]] != lab[edges[:, 1]]
        jump = np.linalg.norm(t[edges[:, 0]] - t[edges[:, 1]], axis=1) / np.linalg.norm(t, axis=1).mean()
        # measured: border/inner mean 1.11 (0.35) and 1.20 (0.7); max border jump below max inner jump
        assert jump[border].mean() < 1.4 * jump[~border].mean(), (thr, jump[border].mean(), jump[~border].mean())
        assert jump[border].max() < 1.2 * jump[~border].max(), (thr, jump[border].max(), jump[~border].max())


# -- fitting and refit ---------------------------------------------------------------------------
def test_fit_bounds_vertices_and_hierarchy():
    bear = load_mesh(warp_asset("bear.usd"))
    tree = build_sphere_tree(bear.points, bear.faces, spheres=12, levels=3, seed=1)
    assert tree.closed and tree.num_leaves <= 12 and tree.num_levels >= 2
    leaf = np.flatnonzero(tree.level == 0)
    for s in leaf:
        v = tree.vertices_of(s)
        assert (np.linalg.norm(bear.points[v] - tree.centers[s], axis=1) <= tree.radii[s] * (1 + 1e-9)).all()
    # every vertex belongs to exactly one leaf
    owned = np.concatenate([tree.vertices_of(s) for s in leaf])
    assert np.array_equal(np.sort(owned), np.arange(bear.num_vertices))
    for s in np.flatnonzero(tree.level > 0):
        ch = tree.children(s)
        assert (np.linalg.norm(tree.centers[ch] - tree.centers[s], axis=1) + tree.radii[ch]
                <= tree.radii[s] * (1 + 1e-6)).all()
    # outside volume (eq. 4.1) falls with more spheres; measured on the bear (grid estimate): 1 sphere 290,
    # 12 spheres 178 (ratio 0.61; before the scale-invariant fit 341 and 179, when 1 sphere fitted worse)
    one = build_sphere_tree(bear.points, bear.faces, spheres=1, levels=1, seed=1)
    assert tree.outside_volume < 0.7 * one.outside_volume, (tree.outside_volume, one.outside_volume)


def test_refit_follows_deformation_and_matches_numpy():
    bear = load_mesh(warp_asset("bear.usd"))
    m = SpheresTransfer(bear, order=3, spheres=10, levels=2, clusters=4)
    tree = m.scene.trees[0]
    rng = np.random.default_rng(7)
    # rigid motion + smooth non-rigid stretch
    a = rng.normal(size=3)
    a *= 0.7 / np.linalg.norm(a)
    rot = trimesh.transformations.rotation_matrix(np.linalg.norm(a), a)[:3, :3]
    pts = bear.points @ rot.T + [1.0, -2.0, 0.5]
    pts[:, 1] *= 1.0 + 0.05 * np.sin(pts[:, 0])
    m.update(pts)
    cen, rad, _ = refit_np(tree, bear.points, pts)
    np.testing.assert_allclose(m.scene.centers.numpy(), cen, atol=2e-4 * np.ptp(pts))
    np.testing.assert_allclose(m.scene.radii.numpy(), rad, atol=2e-4 * np.ptp(pts))
    for s in np.flatnonzero(tree.level == 0):
        v = tree.vertices_of(s)
        assert (np.linalg.norm(pts[v] - cen[s], axis=1) <= rad[s] * (1 + 1e-9)).all()
    # rest pose reproduces the fit
    c0, r0, _ = refit_np(tree, bear.points, bear.points)
    np.testing.assert_allclose(c0, tree.centers, atol=1e-9)
    np.testing.assert_allclose(r0[tree.level == 0], tree.radii[tree.level == 0], atol=1e-9)


def test_translation_invariance():
    plane = grid(11, 2.0)
    c, r = np.array([[0.3, 0.2, 1.0], [-0.5, 0.1, 0.7]]), np.array([0.4, 0.3])
    a = SpheresTransfer(plane, order=4, self_shadow=False, blockers=[tree_from_spheres(c, r)]).update().numpy()
    shift = np.array([5.0, -3.0, 2.0])
    tree, rest = tree_from_spheres(c, r)
    b = SpheresTransfer(TriMesh(plane.points + shift, plane.faces), order=4, self_shadow=False,
                        blockers=[(tree, rest)])
    b.update(blocker_points=[rest + shift])
    np.testing.assert_allclose(b.transfer.numpy(), a, atol=1e-5)


# -- between objects -----------------------------------------------------------------------------
def test_shadow_api_multiplies_visibilities():
    plane = grid(11, 2.0)
    tree, rest = tree_from_spheres([[0.0, 0.0, 1.0]], [0.5])
    m = SpheresTransfer(plane, order=4, self_shadow=False, blockers=[(tree, rest)])
    direct = m.update().numpy()
    unocc = np.array([unoccluded_transfer(n, 4) for n in plane.normals])
    import warp as wp

    combined = m.shadow(wp.array(unocc.astype(np.float32), dtype=float)).numpy()
    # unoccluded transfer times sphere visibility == sphere transfer (the SH product is symmetric)
    np.testing.assert_allclose(combined, direct, atol=1e-5)
    # moving the blocker away through update(blocker_points=...) removes the shadow
    m.update(blocker_points=[rest + [100.0, 0, 0]])
    np.testing.assert_allclose(m.transfer.numpy(), unocc, atol=2e-3)


def test_bad_knobs_are_errors():
    recv = point_receiver()
    with pytest.raises(ValueError, match="exp"):
        SpheresTransfer(recv, exp="taylor", self_shadow=False)
    with pytest.raises(ValueError, match="threshold"):
        SpheresTransfer(recv, threshold=0.0, self_shadow=False)
    m = SpheresTransfer(recv, self_shadow=False, blockers=[tree_from_spheres([[0, 0, 1.0]], [0.1])])
    with pytest.raises(ValueError, match="blocker point"):
        m.update(blocker_points=[])


def test_cli_spheres(tmp_path):
    out, stats = tmp_path / "t.npz", tmp_path / "s.json"
    rc = cli_main(["transfer", warp_asset("bear.usd"), "--method", "spheres", "--order", "4", "--spheres", "12",
                   "--levels", "2", "--threshold", "0.4", "--exp", "ol", "--repeat", "1", "--save", str(out),
                   "--json", str(stats)])
    assert rc == 0
    z = np.load(out)
    assert z["transfer"].shape == (1986, 16) and z["transfer"].dtype == np.float32
    assert np.isfinite(z["transfer"]).all()
    s = json.loads(stats.read_text())
    assert s["method"] == "spheres" and s["knobs"]["spheres"] == 12 and s["knobs"]["exp"] == "ol"
    assert s["knobs"]["levels"] == 2 and s["knobs"]["threshold"] == 0.4


# -- reflections ---------------------------------------------------------------------------------
def _ball_scene(dist, exp="hyb"):
    from warpshade.visibility.spheres.reflections import SphereReflections

    ball = trimesh.creation.icosphere(3, radius=1.0)
    bm = TriMesh(ball.vertices + [0, 0, dist], ball.faces)
    recv = point_receiver()
    m = SpheresTransfer(recv, order=5, self_shadow=False, blockers=[bm], spheres=1, levels=1)
    m.update(recv.points, recv.normals)
    return m, SphereReflections(m, [bm], exp=exp), bm


WHITE_SKY = np.zeros((25, 3))
WHITE_SKY[0] = SQRT_4PI  # radiance 1 from every direction


@pytest.mark.parametrize("exp", ["hyb", "ol", "series"])
@pytest.mark.parametrize("dist", [1.5, 3.0, 6.0])
def test_reflection_from_lit_ball_matches_analytic(dist, exp):
    # every exponential with its own fitted log table (with the shadows' hybrid table OL was +20 % at 1.5)
    # A convex ball under a white sky has exit radiance albedo * 1 everywhere; seen from a point facing
    # it along the normal it subtends θ = asin(1/dist), so the reflected irradiance is π sin²θ.
    m, refl, _ = _ball_scene(dist, exp=exp)
    e = refl.update(WHITE_SKY, [[1.0, 1.0, 1.0]]).numpy()[0]
    expect = math.pi / dist ** 2
    # measured: hyb/ol/series 1.3/1.1/1.4 % at dist 1.5, 1.2/0.9/0.8 % at 3, 1.5/1.5/1.5 % at 6 (SH
    # truncation of cap and form factor)
    np.testing.assert_allclose(e, expect, rtol=0.04)
    assert refl.valid_fraction == 1.0


def test_reflections_vanish_without_albedo_and_are_linear():
    m, refl, _ = _ball_scene(2.0)
    zero = refl.update(WHITE_SKY, [[0.0, 0.0, 0.0]]).numpy().copy()
    assert np.array_equal(zero, np.zeros_like(zero))
    one = refl.update(WHITE_SKY, [[0.2, 0.5, 1.0]]).numpy().copy()
    two = refl.update(WHITE_SKY, [[0.4, 1.0, 2.0]]).numpy().copy()
    assert one[0, 2] > 0
    np.testing.assert_allclose(two, 2 * one, rtol=1e-5)
    np.testing.assert_allclose(one[0, 0] / one[0, 2], 0.2, rtol=1e-5)


def test_reflection_samples_follow_deformation():
    m, refl, bm = _ball_scene(3.0)
    e0 = refl.update(WHITE_SKY, [[1.0, 1.0, 1.0]]).numpy()[0, 0]
    # squash the ball towards the receiver (non-rigid): samples are re-read from the deformed surface
    pts = bm.points.copy()
    pts[:, 2] = 3.0 + 0.5 * (pts[:, 2] - 3.0)
    recv = m.mesh
    m.update(recv.points, recv.normals, blocker_points=[pts])
    e1 = refl.update(WHITE_SKY, [[1.0, 1.0, 1.0]]).numpy()[0, 0]
    face, bary = refl._face.numpy(), refl._bary.numpy()
    ok = face >= 0
    expect = np.einsum("nk,nkd->nd", bary[ok], pts[bm.faces[face[ok]]])
    np.testing.assert_allclose(refl._spts.numpy()[ok], expect, atol=1e-5)
    # the squashed ball's bottom is farther away (z = 2.5 instead of 2): less reflected light
    assert e1 < e0


def test_reflection_per_vertex_albedo():
    # per-vertex albedo equal to a constant reproduces the constant case; black on the half facing the
    # receiver (z < dist) removes almost all of the bounce, black on the far half almost none of it
    m, refl, bm = _ball_scene(3.0)
    const = refl.update(WHITE_SKY, [[0.5, 0.5, 0.5]]).numpy().copy()
    per_vertex = refl.update(WHITE_SKY, [np.full((bm.num_vertices, 3), 0.5)]).numpy().copy()
    np.testing.assert_allclose(per_vertex, const, rtol=1e-6)
    lower = np.repeat((bm.points[:, 2] < 3.0)[:, None], 3, axis=1)
    near = np.where(lower, 0.0, 0.5)  # black on the half facing the receiver
    far = np.where(lower, 0.5, 0.0)
    e_near_black = refl.update(WHITE_SKY, [near]).numpy()[0, 0]
    e_far_black = refl.update(WHITE_SKY, [far]).numpy()[0, 0]
    # measured 0 (-0.011 before the clamp at 0: SH ringing) and 1.011 of the constant case
    assert 0 <= e_near_black < 0.05 * const[0, 0] and 0.95 * const[0, 0] < e_far_black < 1.05 * const[0, 0], \
        (e_near_black, e_far_black)
    with pytest.raises(ValueError, match="albedo"):
        refl.update(WHITE_SKY, [np.ones((5, 3))])


def test_log_tables_from_the_disk_cache(cache_root):
    """The fitted log tables (seconds of least squares) are stored in warpshade's disk cache: a second process
    (here: the in-process cache cleared) reads back the fitted array bit for bit, a damaged entry is refitted
    with one warning, and another exponential is another entry."""
    from warpshade import _cache
    from warpshade.visibility.spheres import tables

    def fresh(order=3, mode="hyb"):
        tables.log_blocker_table.cache_clear()
        return tables.log_blocker_table(order, mode)

    def counts():
        return {w: _cache.stats[tables.CACHE_KIND, w] for w in ("hit", "miss", "write", "bad")}

    first = fresh()
    assert counts() == {"hit": 0, "miss": 1, "write": 1, "bad": 0}
    (entry,) = (cache_root / tables.CACHE_KIND).iterdir()
    again = fresh()
    assert counts()["hit"] == 1 and again.tobytes() == first.tobytes()
    entry.write_bytes(entry.read_bytes()[:100])  # truncated, as by a full disk
    with pytest.warns(RuntimeWarning, match="rebuilding"):
        refit = fresh()
    assert counts()["bad"] == 1 and counts()["write"] == 2 and refit.tobytes() == first.tobytes()
    fresh(3, "ol")
    assert counts()["write"] == 3 and len(list((cache_root / tables.CACHE_KIND).iterdir())) == 2
    tables.log_blocker_table.cache_clear()
