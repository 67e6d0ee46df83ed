"""The SH basis against SciPy (docs/conventions.md §1) and by quadrature, in float64 and in the Warp kernel."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special as ss
import warp as wp

from warpshade.sh import sh_eval, sh_index
from warpshade.sh.kernels import normalization_array, sh_accumulate


def scipy_real_sh(l, m, dirs):
    """docs/conventions.md §1 conversion from SciPy's complex SH (Condon–Shortley phase included)."""
    theta = np.arctan2(np.hypot(dirs[:, 0], dirs[:, 1]), dirs[:, 2])  # accurate near the poles
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    y = ss.sph_harm_y(l, abs(m), theta, phi)
    if m > 0:
        return np.sqrt(2) * y.real
    if m < 0:
        return np.sqrt(2) * y.imag
    return y.real


def random_dirs(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_first_band_signs():
    # The values docs/conventions.md §1 spells out.
    x, y, z = 0.3, -0.5, np.sqrt(1 - 0.34)
    v = sh_eval(np.array([x, y, z]), 2)
    c = 0.4886025119029199
    np.testing.assert_allclose(v, [0.28209479177387814, -c * y, c * z, -c * x], rtol=1e-12)


@pytest.mark.parametrize("order", range(1, 9))
def test_matches_scipy(order, rng):
    dirs = np.concatenate([random_dirs(rng, 200), [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1e-9, -1]]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ours = sh_eval(dirs, order)
    for l in range(order):
        for m in range(-l, l + 1):
            np.testing.assert_allclose(ours[:, sh_index(l, m)], scipy_real_sh(l, m, dirs), atol=1e-12,
                                       err_msg=f"l={l} m={m}")


def test_unnormalised_and_zero_input():
    d = np.array([[0, 0, 5.0], [1e-30, 0, 0], [0, 0, 0]])
    v = sh_eval(d, 4)
    np.testing.assert_allclose(v[0], sh_eval([0, 0, 1.0], 4), atol=1e-15)
    np.testing.assert_allclose(v[1], sh_eval([1.0, 0, 0], 4), atol=1e-15)
    assert np.isfinite(v).all()


def _warp_eval(dirs, order):
    @wp.kernel
    def eval_dirs(d: wp.array[wp.vec3], order: int, k: wp.array[float], out: wp.array2d[float]):
        i = wp.tid()
        sh_accumulate(d[i], 1.0, order, k, out, i)

    d = wp.array(dirs.astype(np.float32), dtype=wp.vec3)
    out = wp.zeros((len(dirs), order * order), dtype=float)
    wp.launch(eval_dirs, dim=len(dirs), inputs=[d, order, normalization_array(order)], outputs=[out])
    return out.numpy()


@pytest.mark.parametrize("order", range(1, 9))
def test_warp_float32_matches_float64(order, rng):
    dirs = np.concatenate([random_dirs(rng, 500), [[0, 0, 1], [0, 0, -1], [0, 0, 3]]])
    ref = sh_eval(dirs, order)
    got = _warp_eval(dirs, order)
    # float32 rounding of inputs (~6e-8 relative) amplified by the band-7 recurrence (<~1e2 ULP
    # measured); 2e-5 absolute on values of magnitude <= 1.5 leaves a 10x margin.
    np.testing.assert_allclose(got, ref, atol=2e-5, err_msg=f"order {order}")


@pytest.mark.parametrize("order", range(1, 9))
def test_orthonormal_by_quadrature_float32(order):
    # Gauss–Legendre in cos(theta) x uniform in phi integrates band-limited products exactly.
    nt, nphi = 2 * order + 2, 4 * order + 4
    x, w = np.polynomial.legendre.leggauss(nt)
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    ct, ph = np.meshgrid(x, phi, indexing="ij")
    st = np.sqrt(1 - ct**2)
    dirs = np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1).reshape(-1, 3)
    weights = (w[:, None] * np.full(nphi, 2 * np.pi / nphi)[None, :]).reshape(-1)
    y = _warp_eval(dirs, order).astype(np.float64)
    gram = (y * weights[:, None]).T @ y
    np.testing.assert_allclose(gram, np.eye(order * order), atol=5e-5)
