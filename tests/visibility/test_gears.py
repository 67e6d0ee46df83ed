"""GEARS area-light visibility: analytic cases, NumPy and ray-traced agreement, the grid, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from conftest import warp_asset
from helpers import post_on_floor

from warpshade.cli import main as cli_main
from warpshade.geometry import TriMesh
from warpshade.usd import load_mesh
from warpshade.visibility.gears import LightRect, get_area_method
from warpshade.visibility.gears.oracle import blocked_samples_np, masks_to_bool

Gears = get_area_method("gears")
Rays = get_area_method("reference")


def light_above(mesh: TriMesh, height=1.5, size=0.3, tilt=0.0) -> LightRect:
    return LightRect.over_points(mesh.points, size=size, height=height, tilt=tilt)


def plane_scene(blocker_x0=0.0):
    """Upward receiver triangle at the origin and a big blocker quad at z = 1 covering x >= blocker_x0."""
    pts = [[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0],
           [blocker_x0, -5, 1], [5, -5, 1], [5, 5, 1], [blocker_x0, 5, 1]]
    return TriMesh(np.array(pts, float), [[0, 1, 2], [3, 4, 5], [3, 5, 6]])


def test_unoccluded_rectangle_is_fully_visible():
    m = TriMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    light = LightRect((0.3, 0.3, 2.0), (0.5, 0, 0), (0, 0.7, 0))
    for cls in (Gears, Rays):
        vis = cls(m, light, k=8).update().numpy()
        assert np.array_equal(vis, np.ones(3, np.float32)), (cls.name, vis)


@pytest.mark.parametrize("k", [4, 7, 16, 32])
def test_half_covered_light(k):
    # The blocker edge x = 0 splits the light centred above the receiver in half. Cell-centre samples
    # never lie on the edge for even k (exactly 0.5); for odd k the middle column sits on it, so the
    # answer is within half a column, 1/(2k), of 0.5.
    m = plane_scene(0.0)
    light = LightRect((0.0, 0.0, 2.0), (0.5, 0, 0), (0, 0.5, 0))
    vis = Gears(m, light, k=k, grid=8).update().numpy()[0]
    assert abs(vis - 0.5) <= 1.0 / (2 * k) + 1e-6, vis
    if k % 2 == 0:
        assert vis == 0.5
    # the ray-traced reference with the same samples agrees exactly
    assert Rays(m, light, k=k, jitter=False).update().numpy()[0] == vis


def test_fully_blocked_and_facing_away():
    # icosphere: a vertex whose tangent plane has the whole light below it is blocked by the sphere
    # itself (geometric visibility 0, docs/conventions.md §4); one with the whole light above sees all of it.
    # The faces around a vertex deviate from its tangent plane by about half an edge angle (~4° at
    # subdivision 3), so "whole light above/below" is required with a 10° margin.
    ico = trimesh.creation.icosphere(3)
    m = TriMesh(ico.vertices, ico.faces)
    light = LightRect((0, 0, 3.0), (0.4, 0, 0), (0, 0.4, 0))
    vis = Gears(m, light, k=8).update().numpy()
    corners = light.point([-1, 1, -1, 1], [-1, -1, 1, 1])
    to_corner = corners[:, None, :] - m.points[None]
    side = np.einsum("vc,jvc->vj", m.normals, to_corner / np.linalg.norm(to_corner, axis=-1, keepdims=True))
    margin = np.sin(np.radians(10))
    above, below = (side > margin).all(1), (side < -margin).all(1)
    assert above.sum() > 10 and below.sum() > 10
    assert np.all(vis[above] == 1.0) and np.all(vis[below] == 0.0)


def random_scene(seed, n_tris=12):
    rng = np.random.default_rng(seed)
    ground = [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]]
    gx, gy = np.meshgrid(np.linspace(-1.5, 1.5, 4), np.linspace(-1.5, 1.5, 4))
    recv = np.stack([gx.ravel(), gy.ravel(), np.zeros(16)], 1)
    centres = rng.uniform([-1.5, -1.5, 0.3], [1.5, 1.5, 1.7], (n_tris, 1, 3))
    tris = (centres + rng.normal(0, 0.4, (n_tris, 3, 3))).reshape(-1, 3)
    pts = np.concatenate([ground, recv, tris])
    faces = [[0, 1, 2], [0, 2, 3]] + [[20 + 3 * i, 21 + 3 * i, 22 + 3 * i] for i in range(n_tris)]
    # receivers 4..19 are isolated vertices (no triangle): give them +z normals explicitly
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    return TriMesh(pts, np.array(faces), normals=normals)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_masks_match_numpy_segment_tests(seed):
    m = random_scene(seed)
    light = LightRect((0.2, -0.1, 2.2), (0.8, 0.1, 0), (-0.05, 0.4, 0.0))
    k = 8
    g = Gears(m, light, k=k, grid=4)
    g.update()
    got = masks_to_bool(g.masks.numpy(), k)
    want = blocked_samples_np(m.points, m.normals, m.faces, light, k, g._offset_abs())
    # Ground and grid receivers (0..19): exact up to samples within float32 rounding of a triangle
    # edge (measured: none differ). The blocker triangles' own vertices (20..) are excluded: their
    # +z normals are not their triangles' normals, so their own triangle passes through the offset
    # receiver, where the near clip (h >= 1e-6) legitimately differs from the segment test.
    diff = got[:20] != want[:20]
    assert diff.mean() <= 1e-3, (seed, np.argwhere(diff)[:5])
    assert want[:20].any() and not want[:20].all()


@pytest.mark.parametrize("asset,height,size,tilt", [
    ("bear.usd", 1.5, 0.3, 0.0),     # light above
    ("bear.usd", 0.5, 0.8, 0.3),     # light plane through the mesh: receivers on both sides
    ("bear.usd", 1.2, 0.05, 1.2),    # small, strongly tilted light
])
def test_grid_never_misses_a_blocker(asset, height, size, tilt):
    m = load_mesh(warp_asset(asset))
    light = light_above(m, height, size, tilt)
    brute = Gears(m, light, k=16, grid=0)
    brute.update()
    for grid in (8, 64):
        g = Gears(m, light, k=16, grid=grid)
        g.update()
        assert np.array_equal(g.masks.numpy(), brute.masks.numpy()), (asset, grid)
        # the grid must also cull: far fewer triangles than brute force
        assert g.stats()["triangles_tested_per_vertex"] < brute.stats()["triangles_tested_per_vertex"]


@pytest.mark.parametrize("asset,k,height,size,tilt", [
    ("bunny.usd", 16, 1.4, 0.3, 0.4),    # the benchmark light
    ("bunny.usd", 32, 0.5, 0.5, 1.2),    # light plane through the mesh, steep: receivers on both sides
    ("bear.usd", 7, 1.2, 0.05, 1.2),     # small light, odd k
    ("bear.usd", 4, 3.0, 1.0, 0.0),      # big far light, coarse mask
])
def test_cull_drops_no_triangle_that_sets_a_bit(asset, k, height, size, tilt):
    # cull_batch drops triangles before the exact clipping and scan conversion; with it off every
    # candidate is scan-converted. A dropped triangle that sets a bit would change a mask.
    m = load_mesh(warp_asset(asset))
    light = light_above(m, height, size, tilt)
    for grid in (0, 16):
        on, off = Gears(m, light, k=k, grid=grid), Gears(m, light, k=k, grid=grid)
        off._cull = 0
        on.update()
        off.update()
        assert np.array_equal(on.masks.numpy(), off.masks.numpy()), (asset, grid)
        # the cull must cull
        assert on.stats()["triangles_scanned_per_vertex"] < 0.5 * off.stats()["triangles_scanned_per_vertex"]
    # the same on the random scenes of the segment test, and with the light inside the bunny
    for seed in (0, 1, 2):
        rs = random_scene(seed)
        rl = LightRect((0.2, -0.1, 2.2), (0.8, 0.1, 0), (-0.05, 0.4, 0.0))
        on, off = Gears(rs, rl, k=k, grid=4), Gears(rs, rl, k=k, grid=4)
        off._cull = 0
        assert np.array_equal(on.update().numpy(), off.update().numpy())
        assert np.array_equal(on.masks.numpy(), off.masks.numpy())


def test_cull_keeps_grazing_and_inside_light_masks():
    m = load_mesh(warp_asset("bunny.usd"))
    for light in (LightRect((0.0, 0.3, 0.0), (0.05, 0, 0), (0, 0, 0.05)),   # inside the bunny
                  light_above(m, 0.6, 0.4, 1.5)):                          # nearly edge-on to many receivers
        on, off = Gears(m, light, k=16), Gears(m, light, k=16)
        off._cull = 0
        on.update()
        off.update()
        assert np.array_equal(on.masks.numpy(), off.masks.numpy())


def test_bitmask_agrees_with_ray_tracing_on_bunny():
    m = load_mesh(warp_asset("bunny.usd"))
    light = light_above(m, 1.4, 0.4, 0.4)
    g = Gears(m, light, k=16)
    g.update()
    r = Rays(m, light, k=16, jitter=False)
    r.update()
    bits_g, bits_r = masks_to_bool(g.masks.numpy(), 16), masks_to_bool(r.masks.numpy(), 16)
    # Same samples, different algorithms: they differ for rays grazing a triangle edge (float32) and for rays
    # the rays' own-surface rule (rays.trace_surface_ray: no origin offset) blocks at the vertex while GEARS's
    # receiver, offset along its normal, passes them. Measured: 356 of 1.56 M samples (2.3e-4) at 327
    # vertices, 352 blocked by the rays only (cos to the normal: median -0.06, 274 below 0.05); visibility
    # max 0.0117, form factor max 1.33e-3 (with the offset origin the rays used before: 2 samples).
    assert (bits_g != bits_r).mean() < 4e-4
    np.testing.assert_allclose(g.visibility.numpy(), r.visibility.numpy(), atol=5 / 256)
    np.testing.assert_allclose(g.form_factor.numpy(), r.form_factor.numpy(), atol=2e-3)
    # Jittered (stratified) rays estimate the same fractions; the mean difference is a quantization
    # effect of order 1/k per penumbra vertex, averaged (measured 0.0023).
    rj = Rays(m, light, k=16, jitter=True)
    rj.update()
    assert np.abs(rj.visibility.numpy() - g.visibility.numpy()).mean() < 0.02


def test_light_inside_a_closed_mesh_is_invisible():
    # A small light inside the bunny: every segment to it crosses the surface, so rays give 0
    # everywhere. Vertices near the light's plane see it edge-on and are blocked only by their
    # own triangles within 5e-5 of the way (a regression: float32 projection once lost those and
    # reported 1). Measured after the homogeneous clip: mean 1.8e-5, worst 2 samples of 256.
    m = load_mesh(warp_asset("bunny.usd"))
    light = LightRect((0.0, 0.3, 0.0), (0.05, 0, 0), (0, 0, 0.05))
    vis = Gears(m, light, k=16).update().numpy()
    assert vis.mean() < 1e-4 and vis.max() <= 2 / 256, (vis.mean(), np.argsort(-vis)[:5])


def test_form_factor_of_unoccluded_square_light():
    # Receiver under the centre of a parallel square of half-side a at height h: the point-to-square
    # form factor is (2/π) [a/sqrt(h²+a²) atan(a/sqrt(h²+a²))]·2 (two-axis closed form, Howell C-11).
    a, h = 0.5, 1.0
    m = TriMesh([[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]], [[0, 1, 2]])
    light = LightRect((0, 0, h), (a, 0, 0), (0, a, 0))
    g = Gears(m, light, k=32)
    g.update()
    x = a / np.hypot(h, a)
    exact = 2.0 / np.pi * 2 * x * np.arctan(x)
    # midpoint rule on 32x32 cells: relative error ~ (cell/h)²/24 ≈ 1e-4
    assert abs(g.form_factor.numpy()[0] - exact) < 1e-3 * exact
    assert g.radiance(emitted=2.0, albedo=0.5)[0] == pytest.approx(g.form_factor.numpy()[0])


def test_degenerate_triangles_change_nothing():
    m = load_mesh(warp_asset("bear.usd"))
    light = light_above(m, 1.3, 0.3, 0.2)
    f = m.faces
    extra = np.array([[f[0, 0], f[0, 0], f[0, 1]], [f[5, 0], f[5, 1], f[5, 1]], [f[9, 2], f[9, 2], f[9, 2]]])
    m2 = TriMesh(m.points, np.concatenate([f, extra]))
    a = Gears(m, light, k=16).update().numpy()
    b = Gears(m2, light, k=16).update().numpy()
    assert np.isfinite(b).all() and np.array_equal(a, b)


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_scale_invariance(scale):
    m = load_mesh(warp_asset("bear.usd"))
    light = light_above(m, 1.3, 0.3, 0.2)
    base = Gears(m, light, k=16).update().numpy()
    ms = TriMesh(m.points * scale, m.faces)
    ls = LightRect(tuple(np.array(light.center) * scale), tuple(np.array(light.u) * scale),
                   tuple(np.array(light.v) * scale))
    got = Gears(ms, ls, k=16).update().numpy()
    # float32 rounding could move samples lying on triangle edges (measured: none move)
    np.testing.assert_allclose(got, base, atol=2 / 256)
    assert np.abs(got - base).mean() < 1e-4


def test_updates_follow_moving_points():
    m = plane_scene(0.0)
    light = LightRect((0.0, 0.0, 2.0), (0.5, 0, 0), (0, 0.5, 0))
    g = Gears(m, light, k=8)
    assert g.update().numpy()[0] == 0.5
    moved = m.points.copy()
    moved[3:, 0] += 10.0  # slide the blocker away
    assert g.update(moved).numpy()[0] == 1.0


def test_accepts_the_lighting_rect_light():
    from warpshade.lighting import RectLight

    m = plane_scene(0.0)
    g = Gears(m, RectLight(center=[0.0, 0.0, 2.0], u=[0.5, 0, 0], v=[0, 0.5, 0], radiance=3.0), k=8)
    assert g.update().numpy()[0] == 0.5 and isinstance(g.light, LightRect)


def test_bad_inputs_are_clear_errors():
    m = plane_scene()
    with pytest.raises(ValueError, match="orthogonal"):
        LightRect((0, 0, 1), (1, 0, 0), (1, 1, 0))
    with pytest.raises(ValueError, match="9 comma"):
        LightRect.parse("1,2,3")
    with pytest.raises(ValueError, match="k"):
        Gears(m, LightRect((0, 0, 1), (1, 0, 0), (0, 1, 0)), k=33)


def test_cli_contract(tmp_path):
    out, stats = tmp_path / "v.npz", tmp_path / "s.json"
    rc = cli_main(["visibility", warp_asset("bear.usd"), "--rect-light", "0,7,0,1.5,0,0,0,0,1.5", "--method", "gears",
                   "--k", "8", "--repeat", "1", "--save", str(out), "--json", str(stats)])
    assert rc == 0
    z = np.load(out)
    assert sorted(z.files) == ["normals", "points", "visibility"]
    assert z["visibility"].shape == (1986,) and z["visibility"].dtype == np.float32
    assert z["points"].shape == (1986, 3) and z["points"].dtype == np.float32
    assert 0.0 <= z["visibility"].min() and z["visibility"].max() == 1.0
    s = json.loads(stats.read_text())
    assert s["method"] == "gears" and s["order"] is None and s["vertices"] == 1986 and s["triangles"] == 3968
    assert s["seconds"] > 0 and s["knobs"]["k"] == 8 and s["knobs"]["grid"] == 16
    rc = cli_main(["visibility", warp_asset("bear.usd"), "--rect-light", "0,7,0,1.5,0,0,0,0,1.5", "--method",
                   "reference", "--k", "8", "--repeat", "1", "--save", str(tmp_path / "r.npz")])
    assert rc == 0
    r = np.load(tmp_path / "r.npz")["visibility"]
    assert np.abs(r - z["visibility"]).mean() < 0.02


def test_cli_bad_light_is_an_error(tmp_path, capsys):
    rc = cli_main(["visibility", warp_asset("bear.usd"), "--rect-light", "0,7,0,1,0,0", "--method", "gears",
                   "--save", str(tmp_path / "v.npz")])
    assert rc == 1 and "--rect-light" in capsys.readouterr().err


@pytest.mark.parametrize("shift", [0.0, 1e4])
def test_rays_from_a_post_standing_on_a_floor_see_the_light(shift):
    """A post standing on a floor (:func:`helpers.post_on_floor`, base ring in the floor's plane) under a light
    beside it, everything moved by ``shift``: the ray-traced base ring sees the light as GEARS does at the
    origin, vertex by vertex. Measured: max 0.012 (3 of 256 cells) at 0 and at 1e4. Before (origin pushed
    along the horizontal normal, still on the floor; world coordinates) every base vertex was blocked (0 vs
    0.45) and at 1e4 every vertex, the floor's too."""
    mesh, base = post_on_floor()
    far, _ = post_on_floor(shift=shift)
    light = LightRect((1.5, 0.25, 3.0), (0.5, 0, 0), (0, 0.5, 0))
    light_far = LightRect(np.array(light.center) + shift, light.u, light.v)
    want = Gears(mesh, light, k=16).update().numpy()
    got = Rays(far, light_far, k=16).update().numpy()
    np.testing.assert_allclose(got[base], want[base], atol=0.025)
    np.testing.assert_allclose(got[base + len(base)], want[base + len(base)], atol=0.025)


@pytest.mark.parametrize("shift", [1e3, 1e4])
def test_gears_far_from_the_origin_matches_the_origin(shift):
    """GEARS on the post standing on a floor moved by ``shift`` (and its light with it) agrees with GEARS at the
    origin, every vertex: it works about ``rays.local_origin`` of the points. Measured: max 1/256 (one cell of
    16 vertices, the float32 rounding of the shifted input, ulp 1e-3 at 1e4), mean 2e-4, at 1e3 and 1e4; bound
    two cells and mean 1e-3. Before (world coordinates) at 1e4: max 1.0, mean 0.10 (133 vertices off)."""
    mesh, _ = post_on_floor()
    far, _ = post_on_floor(shift=shift)
    light = LightRect((1.5, 0.25, 3.0), (0.5, 0, 0), (0, 0.5, 0))
    light_far = LightRect(np.array(light.center) + shift, light.u, light.v)
    want = Gears(mesh, light, k=16)
    got = Gears(far, light_far, k=16)
    v0, v1 = want.update().numpy(), got.update().numpy()
    d = np.abs(v1 - v0)
    assert d.max() <= 2.0 / 256 and d.mean() <= 1e-3, (d.max(), d.mean())
    w0, w1 = want.weighted_visibility().numpy(), got.weighted_visibility().numpy()
    assert np.abs(w1 - w0).max() <= 2.0 / 256, np.abs(w1 - w0).max()
