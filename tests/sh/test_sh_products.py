"""Gaunt tensor (thesis eq. 3.20), truncated SH products (eq. 3.19) and product matrices (eqs. 3.21-3.22)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warpshade.sh import sh_eval, sh_index
from warpshade.sh.kernels import SHProductTable, multiply_sh, product_table_arrays
from warpshade.sh.products import gaunt_tensor, product_matrix, sh_product, sh_square, symmetric_product_table


def wigner3j_000(l1, l2, l3):
    """Closed form of (l1 l2 l3; 0 0 0) (Edmonds 3.7.17): independent of the code under test."""
    s = l1 + l2 + l3
    if s % 2 or l3 < abs(l1 - l2) or l3 > l1 + l2:
        return 0.0
    g = s // 2
    f = math.factorial
    return (-1) ** g * math.sqrt(f(s - 2 * l1) * f(s - 2 * l2) * f(s - 2 * l3) / f(s + 1)) * f(g) / (
        f(g - l1) * f(g - l2) * f(g - l3))


def band(i):
    return math.isqrt(i)


def random_dirs(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_zonal_entries_match_wigner_3j():
    order = 8
    dense = gaunt_tensor(order).dense()
    for l1 in range(order):
        for l2 in range(order):
            for l3 in range(order):
                want = math.sqrt((2 * l1 + 1) * (2 * l2 + 1) * (2 * l3 + 1) / (4 * math.pi)) * wigner3j_000(l1, l2, l3) ** 2
                got = dense[sh_index(l1, 0), sh_index(l2, 0), sh_index(l3, 0)]
                assert abs(got - want) < 1e-14, (l1, l2, l3, got, want)


def test_selection_rules_symmetry_and_dc():
    t = gaunt_tensor(6)
    li, lj, lk = (np.array([band(x) for x in idx]) for idx in (t.i, t.j, t.k))
    # Non-zeros only where the triangle inequality and even parity allow them.
    assert np.all((li + lj + lk) % 2 == 0) and np.all(li <= lj + lk) and np.all(lj <= li + lk) and np.all(lk <= li + lj)
    dense = t.dense()
    for perm in [(0, 2, 1), (1, 0, 2), (2, 1, 0)]:
        np.testing.assert_allclose(dense, dense.transpose(perm), atol=1e-15)
    # Gamma_0jk = delta_jk / sqrt(4 pi)
    np.testing.assert_allclose(dense[0], np.eye(36) / math.sqrt(4 * math.pi), atol=1e-15)
    # Sparse: far fewer than n^6 entries (12868 of 262144 at order 8).
    assert gaunt_tensor(8).nnz < 0.06 * 64**3


@pytest.mark.parametrize("of,og", [(1, 3), (2, 3), (3, 3), (4, 5), (2, 7)])
def test_exact_when_product_is_band_limited(of, og, rng):
    # f~ g~ has bands < of + og - 1, so truncating there is exact: compare pointwise, no quadrature.
    f = rng.normal(size=(3, of * of))
    g = rng.normal(size=(3, og * og))
    order = of + og - 1
    fg = sh_product(f, g, order)
    d = random_dirs(rng, 200)
    np.testing.assert_allclose(sh_eval(d, order) @ fg.T, (sh_eval(d, of) @ f.T) * (sh_eval(d, og) @ g.T),
                               atol=1e-11, err_msg=f"f={f} g={g}")


@pytest.mark.parametrize("order", [2, 5, 8])
def test_truncated_product_is_projection_of_pointwise_product(order, rng):
    # Direct projection of f~ g~ by a Lebedev-free product rule: 2-D Gauss-Legendre x uniform phi with
    # enough nodes for degree 3(order-1) is exact, so only rounding separates the two.
    f = rng.normal(size=order * order)
    g = rng.normal(size=order * order)
    deg = 3 * (order - 1)
    x, w = np.polynomial.legendre.leggauss(deg // 2 + 3)
    nphi = deg + 3
    phi = 2 * np.pi * np.arange(nphi) / nphi
    st = np.sqrt(1 - x**2)
    d = np.stack([np.outer(st, np.cos(phi)), np.outer(st, np.sin(phi)), np.outer(x, np.ones(nphi))], -1).reshape(-1, 3)
    wq = np.repeat(w * 2 * np.pi / nphi, nphi)
    y = sh_eval(d, order)
    want = y.T @ (wq * (y @ f) * (y @ g))
    np.testing.assert_allclose(sh_product(f, g), want, atol=1e-12)
    np.testing.assert_allclose(sh_square(f), sh_product(f, f), atol=1e-15)


def test_product_matrix(rng):
    order = 6
    f = rng.normal(size=(2, order * order))
    g = rng.normal(size=order * order)
    m = product_matrix(f)
    assert m.shape == (2, 36, 36)
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2), atol=1e-15)
    np.testing.assert_allclose(m @ g, sh_product(f, g), atol=1e-12)
    one = np.zeros(36)
    one[0] = math.sqrt(4 * math.pi)  # the constant function 1
    np.testing.assert_allclose(product_matrix(one), np.eye(36), atol=1e-14)
    # A lower-order f acting on a higher-order g.
    f3 = f[0, :9]
    np.testing.assert_allclose(product_matrix(f3, order) @ g, sh_product(f3, g, order), atol=1e-12)


def test_bad_length():
    with pytest.raises(ValueError, match="square"):
        sh_product(np.ones(5), np.ones(4))


def _warp_products(a, b, order):
    out = wp.zeros(a.shape, dtype=float)
    wp.launch(multiply_sh, dim=a.shape[0], inputs=[wp.array(a.astype(np.float32), dtype=float),
                                                    wp.array(b.astype(np.float32), dtype=float), order * order,
                                                    product_table_arrays(order)], outputs=[out])
    return out.numpy().astype(np.float64)


@pytest.mark.parametrize("order", range(1, 9))
def test_warp_products_float32(order, rng):
    n = order * order
    a = rng.normal(size=(50, n))
    b = rng.normal(size=(50, n))
    a[1] *= 1e15  # huge magnitudes: float32 products stay relative
    b[2] *= 1e-15
    want = sh_product(a, b)
    got = _warp_products(a, b, order)
    scale = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1) / math.sqrt(4 * math.pi)
    # Each output sums <= ~200 float32 terms bounded by |Gamma| |a||b|: measured error < 1e-6 of
    # |a||b|/sqrt(4pi); 1e-5 relative to that scale keeps a 10x margin.
    err = np.abs(got - want).max(axis=1) / scale
    assert err.max() < 1e-5, (order, err.max(), int(err.argmax()))
    sym = symmetric_product_table(order)
    assert sym.value.size <= gaunt_tensor(order).nnz


def _vector_product_kernel(order):
    from warpshade.sh.kernels import sh_product_vector_funcs

    f = sh_product_vector_funcs(order)
    V = f.vec_sh

    def products(a: wp.array(dtype=V), b: wp.array(dtype=V), table: SHProductTable, ab: wp.array(dtype=V),
                 aa: wp.array(dtype=V)):
        i = wp.tid()
        ab[i] = f.product(a[i], b[i], table)
        aa[i] = f.square(a[i], table)

    products.__annotations__ = {"a": wp.array(dtype=V), "b": wp.array(dtype=V), "table": SHProductTable,
                                "ab": wp.array(dtype=V), "aa": wp.array(dtype=V)}
    products.__name__ = f"vector_products_order{order}"
    return V, wp.kernel(products, enable_backward=False)


@pytest.mark.parametrize("order", [1, 2, 4, 5, 7])
def test_vector_products_float32(order, rng):
    # The vector product and square (unrolled up to UNROLL_MAX_ORDER = 6, table loop at 7) against the
    # float64 NumPy product; tolerance as in test_warp_products_float32 (same float32 sums, only the
    # order of the terms differs).
    n = order * order
    a = rng.normal(size=(50, n))
    b = rng.normal(size=(50, n))
    a[1] *= 1e15
    b[2] *= 1e-15
    V, kernel = _vector_product_kernel(order)
    ab, aa = wp.zeros(50, dtype=V), wp.zeros(50, dtype=V)
    wp.launch(kernel, dim=50, inputs=[wp.array(a.astype(np.float32), dtype=V), wp.array(b.astype(np.float32), dtype=V),
                                      product_table_arrays(order)], outputs=[ab, aa])
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    err_ab = np.abs(ab.numpy().reshape(50, n) - sh_product(a, b)).max(axis=1) / (na * nb / math.sqrt(4 * math.pi))
    err_aa = np.abs(aa.numpy().reshape(50, n) - sh_square(a)).max(axis=1) / (na * na / math.sqrt(4 * math.pi))
    assert err_ab.max() < 1e-5, (order, err_ab.max(), int(err_ab.argmax()))
    assert err_aa.max() < 1e-5, (order, err_aa.max(), int(err_aa.argmax()))
