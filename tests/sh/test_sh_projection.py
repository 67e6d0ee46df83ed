"""SH projection: exact texel solid angles, constant maps, band-limited functions, map orientation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpshade.sh import sh_eval
from warpshade.sh.projection import (latlong_directions, latlong_row_solid_angles, project_function,
                                     project_latlong, project_latlong_reference, quadrature_size, sphere_quadrature)

SQRT_4PI = math.sqrt(4 * math.pi)
Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +90° about X, map +Y -> world +Z


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.linalg.det(q)


@pytest.mark.parametrize("h,w", [(1, 2), (3, 5), (7, 13), (512, 1024)])
def test_texel_solid_angles_sum_to_4pi(h, w):
    # ΔΦ (cos θ0 − cos θ1) telescopes: exact to rounding for any resolution.
    omega = latlong_row_solid_angles(h, w)
    assert abs(w * omega.sum() - 4 * math.pi) < 1e-12, (h, w, w * omega.sum())
    assert (omega > 0).all()


@pytest.mark.parametrize("h,w", [(1, 2), (2, 4), (3, 7), (16, 32)])
@pytest.mark.parametrize("order", [1, 3, 8])
@pytest.mark.parametrize("frame", [None, "zup"])
def test_constant_map_projects_to_dc_only(h, w, order, frame):
    # Exact per-texel integration: even a 2x1 map gives DC = value * sqrt(4π) and nothing else
    # (centre sampling would put P_l(cos θ_c) mass into every even band). Tolerance: rounding.
    value = np.array([0.5, 2.0, 7.0])
    img = np.broadcast_to(value, (h, w, 3))
    c = project_latlong(img, order, frame=Z_UP if frame else None)
    np.testing.assert_allclose(c[0], value * SQRT_4PI, rtol=1e-13, err_msg=f"{h}x{w} order {order}")
    assert np.abs(c[1:]).max(initial=0.0) < 1e-12, (h, w, order, np.abs(c[1:]).max())


def test_latlong_directions_follow_openexr_convention():
    # OpenEXR (and UsdLux DomeLight): top row latitude +π/2 (+Y), left edge longitude +π (-Z),
    # longitude 0 -> +Z, longitude +π/2 -> +X.
    h, w = 64, 128
    d = latlong_directions(h, w)
    assert d[0, 0, 1] > 0.999 and d[-1, 0, 1] < -0.999
    mid = h // 2  # row just below the equator: lon only matters
    np.testing.assert_allclose(d[mid, w // 2], [0, 0, 1], atol=0.03)  # image centre looks along +Z
    np.testing.assert_allclose(d[mid, w // 4], [1, 0, 0], atol=0.03)  # longitude +π/2
    np.testing.assert_allclose(d[mid, 3 * w // 4], [-1, 0, 0], atol=0.03)
    np.testing.assert_allclose(d[mid, 0], [0, 0, -1], atol=0.03)


@pytest.mark.parametrize("order", [2, 5, 8])
def test_project_function_exact_for_band_limited(order, rng):
    band = 4
    coeffs = rng.normal(size=(band + 1) ** 2)

    def f(d):
        return sh_eval(d, band + 1) @ coeffs

    c = project_function(f, order, band=band)
    expected = np.zeros(order * order)
    n = min(order, band + 1) ** 2
    expected[:n] = coeffs[:n]
    np.testing.assert_allclose(c, expected, atol=1e-12, err_msg=f"coeffs={coeffs}")
    # The rule is tight: one Gauss–Legendre node fewer is visibly wrong (the test can fail).
    nt, nphi = quadrature_size(order, band)
    c_short = project_function(f, order, n_theta=nt - 1, n_phi=nphi)
    assert np.abs(c_short - expected).max() > 1e-6


def test_project_function_rgb_and_pole(rng):
    coeffs = rng.normal(size=(16, 3))

    def f(d):
        return sh_eval(d, 4) @ coeffs

    for pole, split in [((0, 0, 1), False), ((1, 2, 3), True)]:
        c = project_function(f, 4, band=3, pole=pole, split=split)
        np.testing.assert_allclose(c, coeffs, atol=1e-12)


@pytest.mark.parametrize("split", [False, True])
def test_sphere_quadrature_weights(split):
    d, w = sphere_quadrature(5, 9, pole=(0.3, -1, 0.2), split=split)
    assert abs(w.sum() - 4 * math.pi) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-14)


@pytest.mark.parametrize("h", [3, 6, 16])
def test_latlong_matches_bruteforce_reference(h, rng):
    # The separable projection (polar-frame integrals + SH rotation) against per-texel 8x8 quadrature
    # evaluated directly in world space. Measured agreement: 3e-11 (h=3), 1e-15 (h >= 6).
    img = rng.random((h, 2 * h, 3))
    frame = random_rotation(rng)
    a = project_latlong(img, 6, frame=frame)
    b = project_latlong_reference(img, 6, frame=frame)
    np.testing.assert_allclose(a, b, atol=1e-9, err_msg=f"frame={frame}")


def test_latlong_of_sampled_linear_function():
    # A map sampled from f(ω) = a·ω (band 1): the projection recovers f's coefficients up to the
    # texel-averaging error: centre value vs texel mean is a relative O(Δ²/24) ≈ 1.3e-5 at 256x512
    # (measured 1.25e-5 relative, 3.1e-5 absolute); tolerance 1e-4 absolute. Checks that the texel
    # layout of latlong_directions and of the projection agree, in world space, with a Z-up frame.
    a = np.array([0.3, -1.2, 0.7])
    d = latlong_directions(256, 512) @ Z_UP.T
    c = project_latlong(d @ a, 3, frame=Z_UP)
    k = math.sqrt(4 * math.pi / 3)  # ∫ (a·ω) y_1m dω: y_1 = -0.4886 y, y_2 = 0.4886 z, y_3 = -0.4886 x
    expected = np.zeros(9)
    expected[1:4] = k * np.array([-a[1], a[2], -a[0]])
    np.testing.assert_allclose(c, expected, atol=1e-4)


def test_bad_image_shape():
    with pytest.raises(ValueError, match="lat-long image"):
        project_latlong(np.zeros((0, 4, 3)), 3)
