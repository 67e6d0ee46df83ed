"""Zonal harmonics: clamped-cosine / Phong / cap coefficients and ZH rotation (thesis eq. 3.17), NumPy and Warp."""

from __future__ import annotations


import numpy as np
import pytest
import scipy.integrate as si
import scipy.special as ss
import warp as wp

from warpshade.sh import sh_eval
from warpshade.sh.kernels import zh_lerp_rotate_accumulate, zh_normalization_array, zh_rotate_accumulate
from warpshade.sh.zonal import (cap_zh, clamped_cosine_zh, phong_zh, sphere_visibility_zh, zh_rotate,
                                zh_to_sh)


def legendre_moment(f, lo, hi, order, nodes=64):
    """g_l = 2 pi sqrt((2l+1)/4pi) int_lo^hi f(z) P_l(z) dz by Gauss-Legendre (exact for polynomials)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    z = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
    w = 0.5 * (hi - lo) * w
    l = np.arange(order)
    p = np.stack([ss.eval_legendre(li, z) for li in l])
    return 2 * np.pi * np.sqrt((2 * l + 1) / (4 * np.pi)) * (p * f(z) * w).sum(1)


def test_clamped_cosine_contract_values():
    # docs/conventions.md §2 spells these out.
    want = [np.sqrt(np.pi) / 2, np.sqrt(np.pi / 3), np.sqrt(5 * np.pi) / 8, 0.0, -np.sqrt(np.pi) / 16]
    np.testing.assert_allclose(clamped_cosine_zh(5), want, rtol=1e-13, atol=1e-15)


def test_clamped_cosine_high_order_by_quadrature():
    # z * P_l(z) is a polynomial of degree <= 40: 64-node Gauss-Legendre on [0, 1] is exact.
    order = 40
    np.testing.assert_allclose(clamped_cosine_zh(order), legendre_moment(lambda z: z, 0.0, 1.0, order),
                               atol=1e-13)


@pytest.mark.parametrize("s", [0.0, 0.5, 2.0, 7.3, 20.0, 100.0])
def test_phong_by_quad(s):
    order = 9
    got = phong_zh(s, order, normalize=False)
    for l in range(order):
        val, _ = si.quad(lambda z: z**s * ss.eval_legendre(l, z), 0.0, 1.0, epsabs=1e-14, epsrel=1e-12, limit=200)
        want = 2 * np.pi * np.sqrt((2 * l + 1) / (4 * np.pi)) * val
        assert abs(got[l] - want) < 1e-10, (s, l, got[l], want)


def test_phong_normalised_and_limits():
    np.testing.assert_allclose(phong_zh(1.0, 8, normalize=False), clamped_cosine_zh(8), rtol=1e-14)
    for s in [0.0, 3.0, 50.0]:
        assert abs(phong_zh(s, 4)[0] - 1 / np.sqrt(4 * np.pi)) < 1e-14
    # s -> infinity: the normalised lobe tends to a delta at +z, g_l -> sqrt((2l+1)/4pi); the first
    # correction is -l(l+1)/(2s) relative (expanding P_l near 1); the next is O((l(l+1)/2s)^2) ~ 1e-7
    # at l = 7, s = 1e5, so 5e-7 relative still checks the first-order term (3e-4) tightly.
    l = np.arange(8)
    big = phong_zh(1e5, 8)
    assert np.isfinite(big).all()
    np.testing.assert_allclose(big, np.sqrt((2 * l + 1) / (4 * np.pi)) * (1 - l * (l + 1) / 2e5), rtol=5e-7)


@pytest.mark.parametrize("angle", [0.3, 1.0, np.pi / 2, 2.5, np.pi])
def test_cap_by_quadrature(angle):
    order = 12
    np.testing.assert_allclose(cap_zh(angle, order), legendre_moment(np.ones_like, np.cos(angle), 1.0, order),
                               atol=1e-13)


@pytest.mark.parametrize("angle", [1e-3, 1e-5, 1e-7])
def test_cap_tiny_radius_relative_accuracy(angle):
    # int_x^1 P_l = t - l(l+1) t^2/4 + O(t^3), t = 1 - cos a; the dropped term is ~t^2 ~ 2.5e-13 relative
    # at a = 1e-3, so 1e-10 relative is a demanding check that naive P_{l-1}-P_{l+1} (1e-16/t ~ 2e-10
    # at 1e-3 and 100 % wrong at 1e-7) fails.
    order = 8
    t = 2 * np.sin(angle / 2) ** 2
    l = np.arange(order)
    want = 2 * np.pi * np.sqrt((2 * l + 1) / (4 * np.pi)) * (t - l * (l + 1) * t**2 / 4)
    np.testing.assert_allclose(cap_zh(angle, order), want, rtol=1e-10)


def test_sphere_visibility_is_one_minus_cap():
    a = np.array([0.0, 0.1, np.pi])
    v = sphere_visibility_zh(a, 4)
    np.testing.assert_allclose(v[0], [np.sqrt(4 * np.pi), 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(v[2], 0.0, atol=1e-14)
    with pytest.raises(ValueError, match="angular radius"):
        cap_zh(-0.1, 3)


def zh_function(g, z):
    """sum_l g_l y_l0 at cos(angle) = z, evaluated with the basis along a meridian."""
    order = len(g)
    d = np.stack([np.sqrt(np.clip(1 - z**2, 0, None)), np.zeros_like(z), z], -1)
    y = sh_eval(d, order)
    return sum(g[l] * y[:, l * (l + 1)] for l in range(order))


@pytest.mark.parametrize("order", [1, 3, 5, 8])
def test_zh_rotate_is_the_rotated_lobe(order, rng):
    g = rng.normal(size=order)
    w = rng.normal(size=3)
    w /= np.linalg.norm(w)
    f = zh_rotate(g, w)
    dirs = rng.normal(size=(300, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    np.testing.assert_allclose(sh_eval(dirs, order) @ f, zh_function(g, dirs @ w), atol=1e-12,
                               err_msg=f"g={g} w={w}")
    np.testing.assert_allclose(zh_rotate(g, [0, 0, 2.0]), zh_to_sh(g), atol=1e-14)


def test_zh_rotate_batched(rng):
    g = rng.normal(size=(4, 5))
    w = rng.normal(size=(4, 3))
    out = zh_rotate(g, w)
    assert out.shape == (4, 25)
    np.testing.assert_allclose(out[2], zh_rotate(g[2], w[2]), atol=0)


@wp.kernel
def _rotate_rows(d: wp.array[wp.vec3], zh: wp.array2d[float], t: float, weight: float, order: int,
                 kz: wp.array[float], out: wp.array2d[float]):
    i = wp.tid()
    zh_rotate_accumulate(d[i], zh, i, weight, order, kz, out, i)
    zh_lerp_rotate_accumulate(d[i], zh, i, 0, t, weight, order, kz, out, i)


@pytest.mark.parametrize("order", range(1, 9))
def test_warp_zh_rotate_float32(order, rng):
    n = 64
    d = rng.normal(size=(n, 3))
    d[:4] = [[0, 0, 1], [0, 0, -3], [0, 1e-9, 1], [0, 0, 0]]
    zh = rng.normal(size=(n, order))
    t, weight = 0.3, 0.7
    out = wp.zeros((n, order * order), dtype=float)
    wp.launch(_rotate_rows, dim=n, inputs=[wp.array(d.astype(np.float32), dtype=wp.vec3),
                                            wp.array(zh.astype(np.float32), dtype=float), t, weight, order,
                                            zh_normalization_array(order)], outputs=[out])
    lerp = (1 - t) * zh + t * zh[0]
    want = weight * (zh_rotate(zh, d) + zh_rotate(lerp, d))
    want[3] = 0.0  # a zero axis contributes nothing in the kernel
    # float32 basis error (<2e-5, test_sh_basis) times coefficients of size ~3 and the factor
    # sqrt(4pi) ~ 3.5: 3e-4 absolute leaves margin while catching any wrong index or sign.
    np.testing.assert_allclose(out.numpy(), want, atol=3e-4, err_msg=f"order {order}")


@pytest.mark.parametrize("order", [1, 4, 8])
def test_warp_zh_rotate_vector_types(order, rng):
    from warpshade.sh.kernels import zh_vector_funcs

    fn = zh_vector_funcs(order)

    d = rng.normal(size=(20, 6, 3))
    d[0, 0] = 0.0  # a zero axis contributes nothing
    d[1, 0] = [0, 0, -2.0]
    zh = rng.normal(size=(6, order))
    out = wp.zeros(20, dtype=fn.vec_sh)
    wp.launch(fn.accumulate_lobes, dim=20, inputs=[wp.array(d.astype(np.float32), dtype=wp.vec3),
                                         wp.array(zh.astype(np.float32), dtype=fn.vec_zh), fn.zh_constants()],
              outputs=[out])
    lobes = zh_rotate(zh[None], d)
    lobes[0, 0] = 0.0
    # Six lobes of float32 error <= 3e-4 each (see test_warp_zh_rotate_float32).
    np.testing.assert_allclose(out.numpy().reshape(20, -1), lobes.sum(1), atol=1e-3)
