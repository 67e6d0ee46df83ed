"""SH exponential and logarithm (thesis eqs. 3.25-3.34): NumPy methods, OL tables, Warp float32 versions."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl

from warpshade.sh.basis import sh_eval
from warpshade.sh.exp import (SQRT_4PI, fit_ol_table, hybrid_exp_parts, ol_table, sh_exp, sh_log,
                              training_vectors, unit_vector, zh_log)
from warpshade.sh.kernels import sh_exp_warp
from warpshade.sh.products import product_matrix
from warpshade.sh.zonal import sh_to_zh, sphere_visibility_zh, zh_rotate, zh_to_sh

RADII = np.array([1e-3, 3e-3, 1e-2, 0.03, 0.1, 0.3, 0.5, 0.8, 1.0, 1.2, np.pi / 2])


def blocker_sets(order, count, max_blockers, rng):
    """Sums of sphere-blocker logs (thesis eq. 3.63) and the blockers, blockers above the +z plane."""
    sets = []
    for _ in range(count):
        k = int(rng.integers(1, max_blockers + 1))
        r = rng.uniform(0.05, 1.0, k)
        d = rng.normal(size=(k, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d[:, 2] = np.abs(d[:, 2])
        sets.append((zh_rotate(zh_log(sphere_visibility_zh(r, order)), d).sum(0), r, d))
    return sets


def true_visibility(order, r, d, nt=200, nphi=400):
    """Projection of the product of blocker indicators (the physical visibility) by dense quadrature."""
    x, w = np.polynomial.legendre.leggauss(nt)
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    st = np.sqrt(1 - x**2)
    dirs = np.stack([np.outer(st, np.cos(phi)), np.outer(st, np.sin(phi)), np.outer(x, np.ones(nphi))], -1).reshape(-1, 3)
    wq = np.repeat(w * 2 * np.pi / nphi, nphi)
    vis = np.all(dirs @ d.T < np.cos(r)[None, :], axis=1)
    return (wq * vis) @ sh_eval(dirs, order)


# ---------------------------------------------------------------- exponential, float64


@pytest.mark.parametrize("order", [2, 4, 8])
def test_exact_is_matrix_exponential_of_product_matrix(order, rng):
    # exp*(f) = sum_k M_f^k 1 / k! = expm(M_f) 1 (eq. 3.25 with f^k = M_f^{k-1} f); SciPy's Pade expm is an
    # independent evaluation, so agreement to 1e-12 checks DC isolation and the eigen path.
    f = rng.normal(size=order * order) * 0.7
    want = sl.expm(product_matrix(f)) @ unit_vector(order)
    np.testing.assert_allclose(sh_exp(f, "exact"), want, rtol=1e-12, atol=1e-12 * np.linalg.norm(want))


@pytest.mark.parametrize("method", ["exact", "series", "ol", "hybrid"])
def test_order_one_and_zero_are_exact(method):
    f = np.array([[-3.0], [0.0], [25.0]])
    np.testing.assert_allclose(sh_exp(f, method), SQRT_4PI * np.exp(f / SQRT_4PI), rtol=1e-14)
    np.testing.assert_allclose(sh_exp(np.zeros(25), method), unit_vector(5), atol=1e-14)


def test_series_matches_exact_for_moderate_magnitudes():
    # Float64 series terms peak near m^k/k!; at m <= 5 cancellation costs < 1e-14 (measured 2e-14).
    u = training_vectors(8, 16, seed=3)
    for m in [0.5, 2.0, 5.0]:
        f = m * u
        f[:, 0] = -1.0
        ex = sh_exp(f, "exact")
        err = np.linalg.norm(sh_exp(f, "series") - ex, axis=1) / np.linalg.norm(ex, axis=1)
        assert err.max() < 1e-12, (m, err.max())


def test_ol_table_small_magnitude_expansion():
    # exp*(h) . 1 = 4pi + |h|^2/2 + (1/6) int h~^3 + ...  so a(m) = 1 + m^2/(8 pi) + r with
    # |r| <= m^3 max|u~| / (24 pi) and max|u~| <= sqrt(n^2 / 4pi) for unit u (Cauchy-Schwarz).
    for order in [3, 8]:
        t = ol_table(order)
        bound = math.sqrt(order * order / (4 * math.pi)) / (24 * math.pi)
        assert t.a(0.0) == pytest.approx(1.0, abs=1e-15) and t.b(0.0) == pytest.approx(1.0, abs=1e-15)
        for m in [1 / 16, 1 / 8, 1 / 4]:
            r = t.a(m) - (1 + m * m / (8 * math.pi))
            assert abs(r) <= 1.01 * bound * m**3, (order, m, r)


@pytest.mark.parametrize("m", [0.5, 3.0, 20.0])
def test_ol_table_is_the_least_squares_fit(m):
    # eq. 3.29: a, b minimise sum_s |exp*(f^_s) - a 1 - b f^_s|^2 over the training set at magnitude m.
    order = 5
    table = fit_ol_table(order, max_magnitude=32.0, count=64, seed=11)
    u = training_vectors(order, 64, seed=11)
    ex = sh_exp(m * u, "exact")
    one = unit_vector(order)

    def cost(a, b):
        return np.sum((ex - a * one - b * m * u) ** 2)

    a, b = table.a(m), table.b(m)
    c0 = cost(a, b)
    for da, db in [(1e-3, 0), (-1e-3, 0), (0, 1e-3), (0, -1e-3)]:
        assert cost(a * (1 + da), b * (1 + db)) > c0, (m, da, db)


def test_hybrid_equals_ol_below_threshold_and_scales_above():
    u = training_vectors(6, 8, seed=4)
    f = 0.2 * u
    f[:, 0] = 0.3
    np.testing.assert_allclose(sh_exp(f, "hybrid", threshold=0.25), sh_exp(f, "ol"), rtol=1e-14)
    # One scaling step by hand (eq. 3.32 with p = 1): (OL(f/2))^2, DC handled by eq. 3.27.
    from warpshade.sh.products import sh_square

    g = 0.4 * u[0]
    want = sh_square(sh_exp(g / 2, "ol"))
    np.testing.assert_allclose(sh_exp(g, "hybrid", threshold=0.25), want, rtol=1e-12, atol=1e-14)


def test_blocker_sums_against_true_visibility(rng):
    # The physical target: the visibility of the blocker set. Errors are |.|/sqrt(4pi) (fraction of the
    # unoccluded vector). Measured on these 24 sets (order 5, 1-40 blockers, |f^| 0.3..60): exact exp*
    # median 0.11 max 0.17, hybrid(0.25) median 0.11 max 0.18, OL median 0.38 max 35 (OL drifts with
    # |f^|). Most of the error is the order-5 truncation of log/exp itself, shared by all methods.
    order = 5
    sets = blocker_sets(order, 24, 40, rng)
    f = np.array([s[0] for s in sets])
    truth = np.array([true_visibility(order, s[1], s[2]) for s in sets])
    err = {m: np.linalg.norm(sh_exp(f, m) - truth, axis=1) / SQRT_4PI for m in ["exact", "hybrid", "ol"]}
    mags = np.linalg.norm(f[:, 1:], axis=1)
    info = f"|f^|={np.round(mags, 1)} " + " ".join(f"{k}={np.round(v, 3)}" for k, v in err.items())
    assert np.median(err["hybrid"]) < 0.15 and err["hybrid"].max() < 0.25, info
    assert np.median(err["hybrid"]) < 1.2 * np.median(err["exact"]), info
    big = mags > 10
    assert big.sum() >= 5 and np.median(err["ol"][big]) > 2 * np.median(err["hybrid"][big]), info


@pytest.mark.parametrize("order", [3, 8])
def test_hybrid_bounded_where_ol_drifts(order):
    # Shapes of blocker-log sums rescaled to |f^| up to 100, DC chosen so exp* is O(1). Hybrid's deviation
    # from exp* is the non-associativity of truncated squaring (it tends to a different band-limited
    # exponential, as close to the truth, see the test above). Measured max relative deviation 0.1 at
    # m <= 10 and 2.7 at m = 100 (order 3); OL's deviation is > 10x larger from m = 50 on.
    u = training_vectors(order, 12, seed=5)
    lam_max = np.linalg.eigvalsh(product_matrix(u)).max(axis=1)
    for m, bound in [(0.0, 1e-12), (1.0, 0.05), (10.0, 0.3), (50.0, 2.0), (100.0, 4.0)]:
        f = m * u
        f[:, 0] = -SQRT_4PI * m * lam_max
        ex = sh_exp(f, "exact")
        hy = sh_exp(f, "hybrid")
        assert np.all(np.isfinite(hy)), (order, m)
        err = np.linalg.norm(hy - ex, axis=1) / np.linalg.norm(ex, axis=1)
        assert err.max() < bound, (order, m, err)
        if m >= 50:
            ol = np.linalg.norm(sh_exp(f, "ol") - ex, axis=1) / np.linalg.norm(ex, axis=1)
            assert np.median(ol) > 10 * np.median(err), (order, m, np.median(ol), np.median(err))


def test_hybrid_parts_finite_at_huge_magnitudes():
    # |f^| = 1e6: e^{m lambda} is far outside float64, yet the carried log-scale stays finite and the
    # unit part has norm 1; sh_exp with the DC that cancels the log-scale returns that unit vector.
    order = 8
    u = training_vectors(order, 4, seed=6)
    f = 1e6 * u
    log_scale, unit = hybrid_exp_parts(f)
    assert np.all(np.isfinite(log_scale)) and np.all(np.abs(log_scale) < 1e8), log_scale
    np.testing.assert_allclose(np.linalg.norm(unit, axis=1), 1.0, rtol=1e-12)
    f[:, 0] = -SQRT_4PI * log_scale
    np.testing.assert_allclose(sh_exp(f, "hybrid"), unit, atol=1e-9)


# ---------------------------------------------------------------- logarithm


def test_log_of_constants_and_zonal_consistency():
    for c in [0.5, 1.0, 3.0]:
        np.testing.assert_allclose(sh_log(c * unit_vector(4)), math.log(c) * unit_vector(4), atol=1e-13)
    g = sphere_visibility_zh(RADII, 6)
    np.testing.assert_allclose(zh_log(g), sh_to_zh(sh_log(zh_to_sh(g))), atol=1e-10)
    with pytest.raises(ValueError, match="eps"):
        sh_log(unit_vector(2), eps=0.0)


@pytest.mark.parametrize("order", [3, 5, 8])
def test_exp_log_round_trip_for_sphere_blockers(order):
    # Analytic blocker visibility (1 - cap) for radii 1e-3..pi/2. The closed form (eq. 3.34) inverts exp*
    # exactly only if truncated products were associative; measured |exp*(log g) - g|/sqrt(4pi):
    # < 2e-8 for radii <= 0.1 at every order, <= 0.06 up to pi/2. Refinement (damped Newton) brings the
    # radii <= 0.3 to rounding (< 1e-12 measured 4e-16) and never increases a residual.
    g = zh_to_sh(sphere_visibility_zh(RADII, order))
    small = RADII <= 0.1
    err0 = np.linalg.norm(sh_exp(sh_log(g), "exact") - g, axis=1) / SQRT_4PI
    assert err0[small].max() < 1e-7 and err0.max() < 0.08, (order, err0)
    err1 = np.linalg.norm(sh_exp(sh_log(g, refine=8), "exact") - g, axis=1) / SQRT_4PI
    assert np.all(err1 <= err0 * (1 + 1e-9) + 1e-15), (order, err0, err1)
    assert err1[RADII <= 0.3].max() < 1e-12, (order, err1)
    # Refining against the hybrid exponential makes the runtime path invert the log for small blockers.
    errh = np.linalg.norm(sh_exp(sh_log(g, refine=8, exp_method="hybrid"), "hybrid") - g, axis=1) / SQRT_4PI
    assert errh[RADII <= 0.1].max() < 1e-9, (order, errh)


def test_log_exp_round_trip_small_vectors(rng):
    # For small f, M_{exp* f} = expm(M_f) + O(|f|^2 * truncation), so log(exp* f) = f to O(|f|^3).
    f = 0.05 * rng.normal(size=(5, 25))
    np.testing.assert_allclose(sh_log(sh_exp(f, "exact")), f, atol=1e-4)


# ---------------------------------------------------------------- Warp float32


@pytest.mark.parametrize("order", range(1, 9))
def test_warp_exp_matches_numpy_float32(order):
    u = training_vectors(order, 12, seed=9)
    for m in [0.0, 0.2, 3.0, 30.0, 100.0]:
        f = m * u
        f[:, 0] = -2.0
        for method in ["ol", "hybrid"]:
            want = sh_exp(f, method)
            got = sh_exp_warp(f, method).astype(np.float64)
            # float32 rounding (6e-8) through up to p = 9 squarings, each a ~200-term sum: measured
            # < 1.6e-4 of the result's norm (at m = 100); 5e-4 leaves margin.
            err = np.linalg.norm(got - want, axis=1) / np.linalg.norm(want, axis=1)
            assert err.max() < 5e-4, (order, m, method, err.max())


@pytest.mark.parametrize("magnitude", [1e3, 1e6])
def test_warp_hybrid_huge_magnitudes_float32(magnitude):
    # float32 cannot hold e^{m lambda} for m >= 1e3 (limit e^88); the Warp version carries the scale as a
    # logarithm, so with the DC that cancels it the result is the float64 unit vector.
    order = 8
    u = training_vectors(order, 6, seed=2)
    f = magnitude * u
    log_scale, unit = hybrid_exp_parts(f)
    f[:, 0] = -SQRT_4PI * log_scale
    got = sh_exp_warp(f, "hybrid").astype(np.float64)
    assert np.all(np.isfinite(got))
    # The direction goes through p = 12 (1e3) or 22 (1e6) float32 squarings: measured 1.7e-5 and 1.1e-3.
    nrm = np.linalg.norm(got, axis=1)
    assert np.abs(got / nrm[:, None] - unit).max() < (1e-4 if magnitude < 1e4 else 5e-3), got
    # The scale is exp(DC + log-scale) with both ~m in float32: their ulp (6e-8 m) times the ~2p
    # operations bounds |log |got|| by ~1e-6 m: measured 0.36 at m = 1e6 and 8e-4 at 1e3.
    assert np.abs(np.log(nrm)).max() < 2e-6 * magnitude + 1e-3, nrm


def test_warp_hybrid_non_finite_input_gives_nan():
    f = np.zeros((3, 16))
    f[0, 3] = np.inf
    f[1, 0] = np.nan
    f[2, 5] = 1e20  # squared norm overflows float32
    got = sh_exp_warp(f, "hybrid")
    assert np.isnan(got).all(), got
    with pytest.raises(ValueError, match="NaN or inf"):
        sh_exp(f[:2], "hybrid")
