"""Lights as SH: environment maps and their files, sky, directional/point/sphere/rect lights, motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpshade.lighting import (ConstantEnvironment, DirectionalLight, EnvironmentMap, ImageError, PointLight,
                                RectLight, Sky, SphereLight, default_environment, lights_sh,
                                read_image, spin, sun_direction, up_frame, write_image)
from warpshade.sh import rotation_from_axis_angle, sh_eval
from warpshade.sh.projection import latlong_directions, project_latlong_reference, sphere_quadrature

SQRT_4PI = math.sqrt(4 * math.pi)
K1 = math.sqrt(3 / (4 * math.pi))  # 0.488603, docs/conventions.md §1


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.linalg.det(q)


def first_band(v):
    """∫ (v·ω)-style band-1 coefficients of a vector moment v = ∫ ω f dω (docs/conventions.md §1 signs)."""
    return K1 * np.array([-v[1], v[2], -v[0]])


# --- files ---------------------------------------------------------------------------------------

def _exr_write(path, img, half=False):
    import OpenEXR

    data = img.astype(np.float16 if half else np.float32)
    channels = {c: np.ascontiguousarray(data[:, :, i]) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.PIZ_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(str(path))


@pytest.mark.parametrize("half", [False, True])
def test_exr_written_by_openexr_reads_back(tmp_path, rng, half):
    img = (rng.random((8, 16, 3)) * 50).astype(np.float32)
    img[0, 0] = [1e4, 0.0, 3e-3]  # HDR range and zero
    path = tmp_path / "env.exr"
    _exr_write(path, img, half)
    back = read_image(path)
    assert back.shape == (8, 16, 3) and back.dtype == np.float32
    expected = img.astype(np.float16).astype(np.float32) if half else img
    np.testing.assert_array_equal(back, expected)


def test_hdr_written_by_opencv_reads_back(tmp_path, rng):
    import cv2

    img = (rng.random((8, 16, 3)) * 50).astype(np.float32)
    img[1, 2] = [2e4, 1.0, 0.5]
    path = tmp_path / "env.hdr"
    assert cv2.imwrite(str(path), img[:, :, ::-1].copy())  # OpenCV wants BGR
    back = read_image(path)
    assert back.shape == (8, 16, 3) and back.dtype == np.float32
    # RGBE: 8-bit mantissas sharing the largest channel's exponent -> error <= max(rgb) / 128.
    tol = img.max(axis=2, keepdims=True) / 128
    assert (np.abs(back - img) <= tol).all(), np.abs(back - img).max()
    # Channel order: red stays red.
    assert back[1, 2, 0] > 100 * back[1, 2, 2]


@pytest.mark.parametrize("ext", [".exr", ".hdr"])
def test_write_image_round_trip_and_environment_from_file(tmp_path, rng, ext):
    img = (rng.random((4, 8, 3)) + 0.5).astype(np.float32)
    path = tmp_path / f"env{ext}"
    write_image(path, img)
    env = EnvironmentMap.from_file(path, intensity=2.0)
    # .exr float32 is exact; .hdr (RGBE) errs by at most max(rgb)/128 per pixel.
    tol = 0.0 if ext == ".exr" else img.max(axis=2, keepdims=True) / 128
    assert (np.abs(env.image - img) <= tol).all(), np.abs(env.image - img).max()
    assert env.path == str(path)


def test_missing_file_is_named(tmp_path):
    path = tmp_path / "nope" / "sky.exr"
    with pytest.raises(FileNotFoundError, match="sky.exr"):
        EnvironmentMap.from_file(path)


@pytest.mark.parametrize("name,content", [("bad.exr", b"not an exr"), ("bad.hdr", b"P6 garbage"),
                                          ("truncated.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n\x02")])
def test_unreadable_file_is_named(tmp_path, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ImageError, match=name):
        read_image(path)


def test_unsupported_extension_and_nan_pixels(tmp_path):
    png = tmp_path / "env.png"
    png.write_bytes(b"\x89PNG")
    with pytest.raises(ImageError, match="env.png"):
        read_image(png)
    img = np.ones((2, 4, 3), np.float32)
    img[1, 3, 1] = np.nan
    path = tmp_path / "nan.exr"
    _exr_write(path, img)
    with pytest.raises(ImageError, match="nan.exr.*row 1, column 3"):
        read_image(path)


# --- environment maps ---------------------------------------------------------------------------

def test_constant_environment_and_constant_map_agree():
    c = ConstantEnvironment(radiance=[1.0, 2.0, 3.0]).sh(4)
    m = EnvironmentMap(image=np.broadcast_to(np.float32([1, 2, 3]), (3, 6, 3)), up="Z").sh(4)
    np.testing.assert_allclose(c[0], np.array([1, 2, 3]) * SQRT_4PI, rtol=1e-14)
    np.testing.assert_allclose(m, c, atol=1e-12)


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_environment_map_rotation_matches_bruteforce(up, rng):
    # Cached map-frame projection + SH rotation vs per-texel quadrature evaluated in world space.
    img = rng.random((6, 12, 3)).astype(np.float32)
    r = random_rotation(rng)
    env = EnvironmentMap(image=img, up=up, intensity=[1.0, 0.5, 2.0]).rotated(r)
    expected = project_latlong_reference(img, 5, frame=r @ up_frame(up)) * [1.0, 0.5, 2.0]
    np.testing.assert_allclose(env.sh(5), expected, atol=1e-9)
    # Radiance lookup: the texel centre directions map back to their own texels.
    dirs = latlong_directions(6, 12).reshape(-1, 3) @ (r @ up_frame(up)).T
    np.testing.assert_allclose(env.radiance(dirs), img.reshape(-1, 3) * [1.0, 0.5, 2.0], rtol=1e-6)
    np.testing.assert_allclose(env.mean_radiance() * SQRT_4PI, env.sh(1)[0], rtol=1e-12)


def test_environment_rejects_bad_images():
    with pytest.raises(ImageError, match="shape"):
        EnvironmentMap(image=np.zeros((4, 8)), name="dome")
    with pytest.raises(ImageError, match="dome"):
        EnvironmentMap(image=np.full((4, 8, 3), np.inf), name="dome")
    with pytest.raises(ValueError, match="up axis"):
        EnvironmentMap(image=np.zeros((4, 8, 3)), up="X")


# --- sky ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("elevation,turbidity", [(0.0, 1.7), (5.0, 3.0), (45.0, 3.0), (90.0, 10.0)])
def test_sky_positive_finite_sun_brighter(elevation, turbidity):
    sky = Sky(sun_elevation=elevation, turbidity=turbidity, sun_azimuth=70.0)
    dirs, _ = sphere_quadrature(40, 80)
    rad = sky.radiance(dirs)
    assert np.isfinite(rad).all() and (rad >= 0).all() and (rad.sum(axis=1) > 0).all()
    sun_dir = sky.sun_direction
    in_sun = dirs @ sun_dir >= math.cos(math.radians(0.53 / 2))
    # In luminance: at the horizon the sun is red (air mass ~38) and its blue falls below the sky's.
    luma = np.array([0.2126, 0.7152, 0.0722])
    assert sky.sun_radiance @ luma > 10 * (rad[~in_sun] @ luma).max(), (sky.sun_radiance, rad[~in_sun].max(axis=0))
    assert np.isfinite(sky.sh(8)).all()
    np.testing.assert_allclose(sun_dir, sun_direction(elevation, 70.0, "Y"), atol=1e-12)
    assert abs(sun_dir[1] - math.sin(math.radians(elevation))) < 1e-12


def test_sky_is_blue_overhead_and_brighter_towards_sun():
    sky = Sky(sun_elevation=30.0, sun_azimuth=0.0)
    zen = sky.radiance([[0, 1, 0]])[0]
    assert zen[2] > zen[0], zen  # Rayleigh-blue zenith
    toward = sky.radiance([sun_direction(35.0, 0.0)])[0].sum()
    away = sky.radiance([sun_direction(35.0, 180.0)])[0].sum()
    assert toward > 2 * away


def test_sky_normalization_gives_unit_upward_luminance():
    # normalize=True: a white, unoccluded, upward Lambertian surface has exit luminance `intensity`.
    # Exit radiance from SH, (1/π) Σ L_i T_i with the unoccluded T of docs/conventions.md §2. Without the
    # sun the sky is smooth and order 8 is accurate (measured < 0.1%); with it, the sun's truncated
    # delta adds ringing (measured 0.9% at 40°, up to 1.7% at other elevations): tolerance 2.5%.
    from warpshade.sh.zonal import clamped_cosine_zh, zh_rotate

    t = zh_rotate(clamped_cosine_zh(8), np.array([0.0, 1.0, 0.0]))
    luma = np.array([0.2126, 0.7152, 0.0722])
    for sun, tol in [(False, 0.002), (True, 0.05)]:
        sky = Sky(sun_elevation=40.0, intensity=2.0, sun=sun)
        rgb = t @ sky.sh(8) / math.pi
        assert abs(rgb @ luma - 2.0) < tol, (sun, rgb)


def test_sky_up_z_equals_rotated_y_sky():
    # Projected directly around world +Z vs. the Y-up sky rotated by the SH rotation matrices.
    z_sky = Sky(up="Z", sun_elevation=20.0, sun_azimuth=40.0).sh(6)
    y_rot = Sky(up="Y", sun_elevation=20.0, sun_azimuth=40.0).rotated(up_frame("Z")).sh(6)
    np.testing.assert_allclose(z_sky, y_rot, rtol=1e-6, atol=1e-6 * np.abs(z_sky).max())


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_sky_image_projects_like_the_sky(up):
    # The rendered lat-long vs the analytic SH, bands 0-2, relative to DC. Sky alone: measured
    # 1e-4 at 64x128 (tolerance 5e-4), which checks layout, up frame and rotation. With the sun,
    # splatted energy-preservingly into one texel: DC measured 1e-5 (tolerance 1e-4); bands 1-2 move
    # with the texel quantisation of the sun's position, measured 1.7% at 128x256 (tolerance 3%).
    from warpshade.sh.projection import project_latlong

    for sun, h, tol_dc, tol in [(False, 64, 5e-4, 5e-4), (True, 128, 1e-4, 0.03)]:
        sky = Sky(up=up, sun_elevation=35.0, sun_azimuth=-60.0, sun=sun)
        img = sky.to_image(h)
        assert img.shape == (h, 2 * h, 3) and np.isfinite(img).all() and (img >= 0).all()
        c = project_latlong(img, 3, frame=up_frame(up))
        ref = sky.sh(3)
        np.testing.assert_allclose(c[0], ref[0], rtol=tol_dc, err_msg=f"sun={sun}")
        np.testing.assert_allclose(c, ref, atol=tol * ref[0].max(), err_msg=f"sun={sun}")


def test_sky_rejects_out_of_range():
    with pytest.raises(ValueError, match="sun_elevation"):
        Sky(sun_elevation=-5.0)
    with pytest.raises(ValueError, match="turbidity"):
        Sky(turbidity=1.0)
    assert isinstance(default_environment(), Sky)


# --- directional, point, sphere, rect -----------------------------------------------------------

def test_directional_delta_light_band_one(rng):
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    c = DirectionalLight(direction=d * 3.0, irradiance=[2.0, 1.0, 0.5]).sh(3)
    expected = np.concatenate([[1 / SQRT_4PI], first_band(d)])
    np.testing.assert_allclose(c[:4], np.outer(expected, [2.0, 1.0, 0.5]), rtol=1e-12)


def test_directional_disc_from_radiance():
    # An unnormalized UsdLux DistantLight: radiance L over a disc of angular diameter 10°.
    light = DirectionalLight.from_radiance([0, 0, 1], radiance=5.0, angle=10.0)
    half = math.radians(5.0)
    np.testing.assert_allclose(light.irradiance, 5.0 * math.pi * math.sin(half) ** 2)
    omega = 2 * math.pi * (1 - math.cos(half))
    np.testing.assert_allclose(light.sh(2)[0], 5.0 * omega / SQRT_4PI, rtol=1e-12)
    # ∫_cap ω dω = π sin²(half) ẑ
    np.testing.assert_allclose(light.sh(2)[1:4, 0], 5.0 * first_band([0, 0, math.pi * math.sin(half) ** 2]), atol=1e-12)


def test_spin_and_at_time():
    light = DirectionalLight(direction=[1, 0, 0], motion=spin([0, 1, 0], 90.0))
    at1 = light.at_time(1.0)
    np.testing.assert_allclose(at1.direction, [0, 0, -1], atol=1e-12)  # right-handed about +Y
    assert at1.motion is None and light.at_time(0.0).direction @ [1, 0, 0] > 0.999999
    np.testing.assert_allclose(at1.sh(4), DirectionalLight(direction=[0, 0, -1]).sh(4), atol=1e-12)
    with pytest.raises(ValueError, match="rotation"):
        light.rotated(np.diag([1.0, 1.0, -1.0]))


def test_point_light_inverse_square(rng):
    pts = rng.normal(size=(5, 3))
    light = PointLight(position=[0.5, 2.0, -1.0], intensity=[4.0, 2.0, 1.0])
    s = light.sh_at(pts, 3)
    d = light.position - pts
    r2 = (d * d).sum(axis=1)
    expected = sh_eval(d, 3)[:, :, None] * np.array([4.0, 2.0, 1.0]) / r2[:, None, None]
    np.testing.assert_allclose(s, expected, rtol=1e-12)
    with pytest.raises(ValueError, match="receiver"):
        light.sh(3)


def _sphere_bruteforce(center, radius, p, order, n=40):
    """∫ y(ω) [ray p+tω hits the sphere] dω by a product rule about the light direction whose
    Gauss–Legendre pieces in t = cos θ break at the silhouette, so the indicator is constant on each."""
    w = center - p
    r = np.linalg.norm(w)
    t_edge = math.sqrt(1 - (radius / r) ** 2) if r > radius else -1.0
    x, gw = np.polynomial.legendre.leggauss(n)
    pieces = [(-1.0, t_edge), (t_edge, 1.0)] if t_edge > -1.0 else [(-1.0, 1.0)]
    t = np.concatenate([0.5 * (b - a) * x + 0.5 * (a + b) for a, b in pieces])
    wt = np.concatenate([0.5 * (b - a) * gw for a, b in pieces])
    n_phi = 2 * order + 1
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    s = np.sqrt(1 - t * t)
    local = np.stack([np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)), np.repeat(t[:, None], n_phi, 1)], -1)
    u = np.cross([1.0, 0.0, 0.0] if abs(w[0]) < 0.9 * r else [0.0, 1.0, 0.0], w)
    u /= np.linalg.norm(u)
    frame = np.stack([u, np.cross(w / r, u), w / r], axis=1)
    dirs = local.reshape(-1, 3) @ frame.T
    wts = np.repeat(wt * 2 * np.pi / n_phi, n_phi)
    along = dirs @ w
    miss2 = (w @ w) - along**2
    hit = (along > 0) & (miss2 <= radius**2) | (w @ w <= radius**2)
    return (sh_eval(dirs, order) * (wts * hit)[:, None]).sum(axis=0)


@pytest.mark.parametrize("p", [[0.0, 0.0, 0.0], [3.0, -1.0, 2.0], [1.05, 0.0, 0.2], [1.2, 0.3, 0.1]])
def test_sphere_light_matches_bruteforce_cap(p):
    # Analytic cap ZH + ZH rotation vs. ray-sphere hit tests integrated by a product rule that is
    # exact for these orders on each piece (the indicator is decided by the ray test, not by the
    # cap formula). Agreement to rounding, so the tolerance is 1e-10 of the DC term.
    center, radius = np.array([1.0, 0.5, 0.0]), 0.6
    light = SphereLight(position=center, radius=radius, radiance=[1.0, 2.0, 3.0])
    got = light.sh(6, point=np.array(p))
    ref = _sphere_bruteforce(center, radius, np.array(p), 6)
    np.testing.assert_allclose(got[:, 0], ref, atol=1e-10 * abs(ref[0]), err_msg=f"receiver {p}")
    np.testing.assert_allclose(got[:, 2], 3 * got[:, 0], rtol=1e-12)


def test_sphere_light_inside_and_far_field():
    light = SphereLight(position=[0, 0, 0], radius=1.0, radiance=2.0)
    inside = light.sh(4, point=[0.2, 0.1, 0.0])
    np.testing.assert_allclose(inside[0], 2.0 * SQRT_4PI, rtol=1e-12)
    assert np.abs(inside[1:]).max() < 1e-12
    # Far away a sphere is a point of equal power: relative difference O((a/r)²) = 1e-4 at r = 100 a
    # (measured 5e-5).
    far = np.array([[0.0, 100.0, 0.0]])
    np.testing.assert_allclose(light.sh_at(far, 3), light.as_point().sh_at(far, 3), rtol=2e-4)


def _triangle_solid_angle(a, b, c):
    """Van Oosterom & Strackee (1983)."""
    la, lb, lc = np.linalg.norm(a), np.linalg.norm(b), np.linalg.norm(c)
    num = abs(np.dot(a, np.cross(b, c)))
    den = la * lb * lc + np.dot(a, b) * lc + np.dot(a, c) * lb + np.dot(b, c) * la
    return 2 * math.atan2(num, den)


def _polygon_moments(corners, p):
    """Exact ∫_poly dω and ∫_poly ω dω (Arvo 1995: ½ Σ θ_e n̂_e) of a planar polygon seen from p."""
    v = [c - p for c in corners]
    omega = _triangle_solid_angle(v[0], v[1], v[2]) + _triangle_solid_angle(v[0], v[2], v[3])
    m = np.zeros(3)
    for i in range(4):
        a, b = v[i], v[(i + 1) % 4]
        n = np.cross(a, b)
        theta = math.atan2(np.linalg.norm(n), np.dot(a, b))
        m += 0.5 * theta * n / np.linalg.norm(n)
    to_plane = v[0]
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    if np.dot(m, normal) * np.dot(to_plane, normal) < 0:  # orientation: the moment points at the polygon
        m = -m
    return omega, m


@pytest.mark.parametrize("dist,tol", [(4.0, 1e-6), (1.0, 1e-6), (0.5, 1e-5), (0.1, 1e-5), (0.05, 1e-5),
                                      (0.01, 2e-2)])
def test_rect_light_bands_zero_and_one_exact(dist, tol):
    # Tiled 8x8 Gauss–Legendre over the rectangle (Warp kernel, float32) vs. the exact solid angle
    # and vector moment. Measured relative errors (half-sizes 0.5 x 0.4, receiver `dist` below the
    # plane, off-centre): 1e-7 (float32) at 4 and 1, 1.8e-6 at 0.5, < 1e-6 at 0.1 and 0.05 (5 and 10
    # tiles), 6.6e-3 at 0.01 where the 16-tile cap binds.
    light = RectLight(center=[0, 0, 0], u=[0.5, 0, 0], v=[0, 0.4, 0], radiance=[1.0, 1.0, 2.0])
    assert np.allclose(light.emit_normal, [0, 0, -1])
    p = np.array([0.3, -0.2, -dist])
    s = light.sh(3, point=p)
    omega, m = _polygon_moments(light.corners(), p)
    ref = np.concatenate([[omega / SQRT_4PI], first_band(m)])
    np.testing.assert_allclose(s[:4, 0], ref, atol=tol * abs(ref).max(), err_msg=f"receiver {p}")
    np.testing.assert_allclose(s[:, 2], 2 * s[:, 0], rtol=1e-12)
    # One-sided (UsdLux emits along local -Z): nothing behind; two-sided mirrors it.
    assert np.abs(light.sh(3, point=p * [1, 1, -1])).max() == 0.0
    two = RectLight(center=[0, 0, 0], u=[0.5, 0, 0], v=[0, 0.4, 0], radiance=1.0, two_sided=True)
    np.testing.assert_allclose(two.sh(1, point=p * [1, 1, -1])[0, 0], omega / SQRT_4PI, atol=tol * omega)


@pytest.mark.parametrize("two_sided", [False, True])
def test_rect_light_kernel_matches_numpy(rng, two_sided):
    light = RectLight(center=[0.1, 1.0, 0.0], u=[0.4, 0.1, 0.0], v=[0.0, 0.1, 0.3], radiance=[1.0, 2.0, 0.5],
                      two_sided=two_sided, samples=5)
    pts = np.concatenate([rng.normal(size=(50, 3)), [[0.1, 1.02, 0.05], [0.3, 1.0, 0.0]]])  # incl. near/on it
    got = light.sh_at(pts, 6)
    ref = light.sh_at_reference(pts, 6)
    # float32 kernel vs float64: measured 8e-6 relative to the largest coefficient (dominated by
    # the receiver lying on the light, where 1/r² weights are large): tolerance 5e-5.
    np.testing.assert_allclose(got, ref, atol=5e-5 * np.abs(ref).max())


def test_rect_light_rotation_and_validation(rng):
    light = RectLight(center=[0, 1, 0], u=[0.2, 0, 0], v=[0, 0, 0.3], radiance=1.0)
    r = rotation_from_axis_angle([1, 1, 0], 0.7)
    p = np.array([[0.1, -1.0, 0.4]])
    # Rotating light and receiver together rotates the SH; bands 0-1 rotate as a scalar and a vector.
    np.testing.assert_allclose(light.rotated(r).sh_at(p @ r.T, 2)[0], _rotate_band01(light.sh_at(p, 2)[0], r),
                               atol=1e-12)
    with pytest.raises(ValueError, match="area"):
        RectLight(u=[1, 0, 0], v=[2, 0, 0], name="flat")


def _rotate_band01(c, r):
    """Rotate order-2 RGB SH by r directly: DC unchanged, band 1 is a vector (y, z, x) with signs."""
    out = c.copy()
    vec = np.stack([-c[3], -c[1], c[2]])  # (x, y, z) moments up to K1
    rv = r @ vec
    out[1], out[2], out[3] = -rv[1], rv[2], -rv[0]
    return out


def test_lights_sh_sums_and_requires_points():
    a = DirectionalLight(direction=[0, 1, 0], irradiance=1.0)
    b = ConstantEnvironment(radiance=0.5)
    distant, local = lights_sh([a, b], 3)
    np.testing.assert_allclose(distant, a.sh(3) + b.sh(3))
    assert local is None
    sphere = SphereLight(position=[0, 2, 0], radius=0.5, radiance=1.0, name="bulb")
    with pytest.raises(ValueError, match="bulb"):
        lights_sh([a, sphere], 3)
    pts = np.zeros((2, 3))
    distant, local = lights_sh([a, sphere], 3, points=pts)
    np.testing.assert_allclose(local, sphere.sh_at(pts, 3))


def test_cli_light_exports_sky_and_reads_it_back(tmp_path, capsys):
    from warpshade.cli import main

    img, npy = tmp_path / "sky.exr", tmp_path / "sky.npy"
    assert main(["light", "--order", "3", "--image", str(img), "--height", "64", "--save", str(npy)]) == 0
    sky_sh = np.load(npy)
    assert sky_sh.shape == (9, 3)
    assert main(["light", str(img), "--order", "3", "--save", str(tmp_path / "env.npy")]) == 0
    # Same DC from the analytic projection and from the written 64x128 image (the sun is splatted
    # with its energy; the sky is sampled at texel centres): measured 2e-5 relative (2.6e-4 at 32x64).
    np.testing.assert_allclose(np.load(tmp_path / "env.npy")[0], sky_sh[0], rtol=1e-4)
    assert main(["light", str(tmp_path / "missing.hdr")]) != 0
    assert "missing.hdr" in capsys.readouterr().err


def test_lights_pickle_with_motion(tmp_path):
    # Lights travel to parallel workers: every kind, with a spin motion, survives pickling.
    import pickle

    img = np.ones((2, 4, 3), np.float32)
    lights = [Sky(motion=spin([0, 1, 0], 10.0)), EnvironmentMap(image=img, motion=spin([0, 0, 1], 5.0)),
              ConstantEnvironment(radiance=1.0), DirectionalLight(direction=[0, 1, 0], motion=spin([1, 0, 0], 3.0)),
              PointLight(position=[0, 1, 0]), SphereLight(position=[0, 1, 0], radius=0.1),
              RectLight(center=[0, 1, 0], motion=spin([0, 1, 0], 1.0))]
    for light in lights:
        back = pickle.loads(pickle.dumps(light))
        p = np.array([[0.0, 0.0, 0.5]])
        np.testing.assert_allclose(back.at_time(2.0).sh_at(p, 3), light.at_time(2.0).sh_at(p, 3), atol=1e-12)


def test_exr_rgba_and_luminance_only(tmp_path):
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    rgba = np.arange(2 * 4 * 4, dtype=np.float32).reshape(2, 4, 4)
    with OpenEXR.File(header, {c: np.ascontiguousarray(rgba[:, :, i]) for i, c in enumerate("RGBA")}) as f:
        f.write(str(tmp_path / "rgba.exr"))
    np.testing.assert_array_equal(read_image(tmp_path / "rgba.exr"), rgba[:, :, :3])
    y = np.linspace(0, 5, 8, dtype=np.float32).reshape(2, 4)
    with OpenEXR.File(header, {"Y": y}) as f:
        f.write(str(tmp_path / "grey.exr"))
    np.testing.assert_array_equal(read_image(tmp_path / "grey.exr"), np.stack([y, y, y], -1))
    with OpenEXR.File(header, {"Z": y}) as f:
        f.write(str(tmp_path / "depth.exr"))
    with pytest.raises(ImageError, match="depth.exr.*channels"):
        read_image(tmp_path / "depth.exr")
