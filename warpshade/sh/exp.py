"""SH exponential and logarithm (thesis §3.1.4, eqs. 3.25–3.34; Ren et al. 2006).

Notation: ``1 = (sqrt(4 pi), 0, ..., 0)`` is the SH vector of the constant function 1 (the identity
of the SH product), ``f = (f_0/sqrt(4 pi)) 1 + f^`` splits off the DC term (eq. 3.26) and
``m = ||f^||``. All products are truncated to the input order (:mod:`warpshade.sh.products`).

Exponentials (all with DC isolation, eq. 3.27: ``exp*(f) = exp(f_0/sqrt(4 pi)) exp*(f^)``):

* ``"exact"`` — the limit of the product series of eq. 3.25, ``exp*(f^) = e^{M_f^} 1``, evaluated by
  eigen-decomposition of the symmetric product matrix ``M_f^`` (``M_f^^k 1`` is the k-fold product).
  It is the target the optimal-linear tables are fitted to and the reference of the benchmark.
  O(n^6) per vector: a reference, not a runtime method.
* ``"series"`` — the plain Taylor series with SH products (eq. 3.25), summed until the next term is
  below ``tol`` relative to the sum; it needs O(m) products. When ``M_f^`` has large negative
  eigenvalues and only small positive ones (mostly-blocked visibility), terms grow like
  ``(m |lambda_min|)^k / k!`` while the sum stays small and float64 cancels catastrophically
  (measured: relative errors up to 1e40 at ``m = 100``, order 8, DC -3, rescaled blocker shapes).
* ``"ol"`` — optimal linear (eqs. 3.28–3.30): ``exp(f_0/sqrt(4 pi)) (a(m) 1 + b(m) f^)`` with
  ``a, b`` tabulated by ``m`` (:func:`ol_table`). O(n^2). Accurate for small ``m`` only.
* ``"hybrid"`` — scaling and squaring (eqs. 3.31–3.32): OL on ``f^ / 2^p`` with ``p`` the smallest
  integer making ``m / 2^p <= threshold``, then ``p`` SH squarings. Every squaring renormalises
  the vector and carries its scale as a logarithm, so intermediate values never overflow or
  underflow (float32 included); the DC factor is applied once, at the end, in the same exponent.
  Truncated products are not associative, so repeated squaring converges to a band-limited
  exponential slightly different from ``exp*`` (the deviation grows with ``m``); against the true
  visibility of blocker sets both are equally accurate (benchmarks/sh_exp.py). The default threshold
  0.25 matches ``exp*``'s accuracy there; the thesis-like 1.0 is 2–4x less accurate, 2 squarings cheaper.

Logarithm (eq. 3.34): ``log(g) = R^T q'(D) R (g - 1)``, ``q'(x) = log(x)/(x - 1)``, from the
eigen-decomposition ``M_g = R^T D R``; eigenvalues below ``eps`` are raised to ``eps``.

Optimal-linear tables: for each order, ``a(m)`` and ``b(m)`` are the least-squares fit of eq. 3.29
over a training set of DC-free vectors of magnitude ``m``: the sums of SH logs of 1–16 sphere
blockers (random angular radii in [0.02, 1.2] rad, random directions in a hemisphere), each
rescaled to magnitude ``m`` (Ren et al. tabulate by magnitude because ``a, b`` depend mostly on it).
Because ``M_{m u} = m M_u``, one eigen-decomposition per training shape gives ``exp*(m u)`` at
every ``m`` exactly, so the fit is cheap and is done lazily (cached) with a fixed seed.
Stored as ``log a`` and ``c = b / a`` (both O(1)-conditioned up to large ``m``, where ``a`` and
``b`` themselves overflow float32).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from threadpoolctl import threadpool_limits

from .products import order_of, gaunt_tensor, product_matrix, sh_product
from .zonal import sphere_visibility_zh, zh_rotate

SQRT_4PI = math.sqrt(4.0 * math.pi)

DEFAULT_LOG_EPS = 1e-3
"""Default eigenvalue clip of :func:`sh_log` (absolute; visibility functions live in [0, 1])."""

DEFAULT_HYBRID_THRESHOLD = 0.25
"""Default ``m`` below which :func:`sh_exp` ``"hybrid"`` uses optimal-linear directly (benchmarks/sh_exp.py)."""

METHODS = ("hybrid", "ol", "series", "exact")


def _eigh(m: np.ndarray):
    """``np.linalg.eigh`` on one BLAS thread (many small matrices: a multi-threaded OpenBLAS only adds
    contention; docs/benchmarks/history.md)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return np.linalg.eigh(m)


def unit_vector(order: int) -> np.ndarray:
    """The SH vector of the constant function 1, ``(sqrt(4 pi), 0, ...)``, shape (order**2,)."""
    one = np.zeros(order * order)
    one[0] = SQRT_4PI
    return one


def _split_dc(f: np.ndarray):
    f0 = f[..., 0].copy()
    fh = f.copy()
    fh[..., 0] = 0.0
    return f0, fh


def _q_prime(x: np.ndarray) -> np.ndarray:
    """``log(x)/(x - 1)`` with its limit 1 at x = 1 (log1p keeps it accurate near 1)."""
    d = x - 1.0
    small = np.abs(d) < 1e-6
    safe = np.where(small, 1.0, d)
    return np.where(small, 1.0 - d / 2.0 + d * d / 3.0, np.log1p(safe) / safe)


def sh_log(g, eps: float = DEFAULT_LOG_EPS, refine: int = 0, exp_method: str = "exact",
           threshold: float | None = None) -> np.ndarray:
    """SH logarithm (thesis eq. 3.34) by eigen-decomposition of the product matrix ``M_g``.

    Args:
        g: SH vectors, shape (..., n*n), e.g. blocker visibilities.
        eps: eigenvalues of ``M_g`` below ``eps`` are raised to ``eps`` before the log (> 0).
        refine: extra damped Newton steps that make ``sh_exp(log g, exp_method)`` match ``g``
            (0 = the thesis' closed form only). Each step solves ``M_E d = g - E`` (``E`` the current
            exponential, eigenvalues clipped at ``eps``; exact if products were associative) and
            halves the step until the residual decreases, so the residual never grows. Vectors whose
            ``M_g`` has eigenvalues far below 0 (caps wider than ~1.4 rad) are not reachable by the
            exponential; there the steps stop early and the closed form's residual is kept or improved.
        exp_method: the :func:`sh_exp` method the refinement inverts (``"exact"`` or ``"hybrid"``).
        threshold: hybrid threshold for ``exp_method="hybrid"``.

    Returns:
        ``log(g)``, shape (..., n*n), dtype float64, with ``exp*(log g) ~= g``.
    """
    if not eps > 0:
        raise ValueError(f"sh_log: eps must be > 0, got {eps!r}")
    g = np.asarray(g, dtype=np.float64)
    order = order_of(g.shape[-1], "g")
    lam, vec = _eigh(product_matrix(g))
    lam = np.maximum(lam, eps)
    r = g - unit_vector(order)
    coef = np.einsum("...ki,...k->...i", vec, r) * _q_prime(lam)
    f = np.einsum("...ik,...k->...i", vec, coef)
    if refine > 0:
        f = _refine_log(g.reshape(-1, order * order), f.reshape(-1, order * order), eps, refine, exp_method,
                        DEFAULT_HYBRID_THRESHOLD if threshold is None else threshold).reshape(g.shape)
    return f


def _refine_log(g, f, eps, steps, exp_method, threshold):
    def residual(x):
        ok = np.all(np.isfinite(x), axis=-1) & (np.abs(x).max(axis=-1) < 1e6)
        e = np.full_like(x, np.inf)
        if ok.any():
            with np.errstate(over="ignore", invalid="ignore"):
                e[ok] = sh_exp(x[ok], exp_method, threshold=threshold)
        err = np.linalg.norm(e - g, axis=-1)
        return e, np.where(np.isfinite(err), err, np.inf)

    e, err = residual(f)
    for _ in range(steps):
        lam, vec = _eigh(product_matrix(np.where(np.isfinite(e), e, 0.0)))
        step = np.einsum("...ik,...k->...i", vec, np.einsum("...ki,...k->...i", vec, g - e) / np.maximum(lam, eps))
        improved = np.zeros(len(f), dtype=bool)
        t = 1.0
        for _ in range(6):
            trial = f + t * step
            e_t, err_t = residual(trial)
            take = (err_t < err) & ~improved
            f[take], e[take], err[take] = trial[take], e_t[take], err_t[take]
            improved |= take
            if improved.all():
                break
            t *= 0.5
        if not improved.any():
            break
    return f


@lru_cache(maxsize=None)
def _zonal_gaunt(order: int) -> np.ndarray:
    z = np.arange(order) * (np.arange(order) + 1)
    return gaunt_tensor(order).dense()[np.ix_(z, z, z)]


def zh_log(zh, eps: float = DEFAULT_LOG_EPS, refine: int = 0, exp_method: str = "exact",
           threshold: float | None = None) -> np.ndarray:
    """SH logarithm of zonal vectors, staying in the zonal subspace.

    ``M_g`` of a zonal ``g`` commutes with rotations about z, so it maps zonal vectors to zonal
    vectors and its zonal block (order x order) is all eq. 3.34 needs; the result equals
    ``sh_to_zh(sh_log(zh_to_sh(g)))`` at a fraction of the cost.

    Args:
        zh: ZH coefficients, shape (..., order).
        eps: eigenvalue clip as in :func:`sh_log`.
        refine, exp_method, threshold: as in :func:`sh_log` (the refinement runs on full SH vectors).

    Returns:
        ZH coefficients of the logarithm, shape (..., order), dtype float64.
    """
    if refine > 0:
        from .zonal import sh_to_zh, zh_to_sh

        return sh_to_zh(sh_log(zh_to_sh(zh), eps, refine, exp_method, threshold))
    if not eps > 0:
        raise ValueError(f"zh_log: eps must be > 0, got {eps!r}")
    g = np.asarray(zh, dtype=np.float64)
    order = g.shape[-1]
    m = np.einsum("ijk,...k->...ij", _zonal_gaunt(order), g)
    lam, vec = _eigh(m)
    lam = np.maximum(lam, eps)
    r = g.copy()
    r[..., 0] -= SQRT_4PI
    coef = np.einsum("...ki,...k->...i", vec, r) * _q_prime(lam)
    return np.einsum("...ik,...k->...i", vec, coef)


@dataclass(frozen=True, eq=False)
class OLTable:
    """Optimal-linear coefficients ``a(m), b(m)`` (thesis eqs. 3.29–3.30) for one SH order.

    Attributes:
        order: SH order the table was fitted for.
        step: magnitude spacing of the nodes; node ``t`` is at ``m = t * step``.
        log_a: ``log a(m)`` at the nodes, shape (K,), dtype float64.
        c: ``b(m) / a(m)`` at the nodes, shape (K,), dtype float64.
    """

    order: int
    step: float
    log_a: np.ndarray
    c: np.ndarray

    @property
    def magnitudes(self) -> np.ndarray:
        """Node magnitudes ``m``, shape (K,)."""
        return np.arange(self.log_a.size) * self.step

    @property
    def max_magnitude(self) -> float:
        """Largest tabulated magnitude; beyond it the last node is used (OL is inaccurate there anyway)."""
        return (self.log_a.size - 1) * self.step

    def lookup(self, m):
        """Linearly interpolated ``(log a, c)`` at magnitudes ``m`` (clamped to the table)."""
        x = np.clip(np.asarray(m, dtype=np.float64) / self.step, 0.0, self.log_a.size - 1)
        i = np.minimum(np.floor(x).astype(np.int64), self.log_a.size - 2)
        t = x - i
        return ((1 - t) * self.log_a[i] + t * self.log_a[i + 1], (1 - t) * self.c[i] + t * self.c[i + 1])

    def a(self, m):
        """``a(m)`` (eq. 3.30)."""
        return np.exp(self.lookup(m)[0])

    def b(self, m):
        """``b(m)`` (eq. 3.30)."""
        la, c = self.lookup(m)
        return np.exp(la) * c


def training_vectors(order: int, count: int = 256, seed: int = 0, eps: float = DEFAULT_LOG_EPS) -> np.ndarray:
    """DC-free unit SH vectors shaped like sums of sphere-blocker logs (the OL training set).

    Args:
        order: SH order.
        count: number of vectors.
        seed: RNG seed.
        eps: :func:`sh_log` clip used for the blocker logs.

    Returns:
        Shape (count, order**2), dtype float64, ``v[:, 0] == 0`` and ``||v|| == 1``.
    """
    rng = np.random.default_rng(seed)
    blockers = rng.integers(1, 17, size=count)
    total = int(blockers.sum())
    radii = rng.uniform(0.02, 1.2, size=total)
    d = rng.normal(size=(total, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2])  # blockers above the receiver's tangent plane (normal +z)
    logs = zh_rotate(zh_log(sphere_visibility_zh(radii, order), eps), d)
    owner = np.repeat(np.arange(count), blockers)
    f = np.zeros((count, order * order))
    np.add.at(f, owner, logs)
    f[:, 0] = 0.0
    nrm = np.linalg.norm(f, axis=1, keepdims=True)
    return f / np.where(nrm > 0, nrm, 1.0)


def fit_ol_table(order: int, max_magnitude: float = 128.0, step: float = 1.0 / 16.0, count: int = 256,
                 seed: int = 0) -> OLTable:
    """Least-squares fit of ``a(m), b(m)`` (eq. 3.29) over :func:`training_vectors` (module docstring).

    For unit training shapes ``u_s`` and ``e_s(m) = exp*(m u_s)``, the least-squares ``a, b`` minimising
    ``sum_s ||e_s - a 1 - b m u_s||^2`` are (``1`` is orthogonal to every ``u_s``)
    ``a = mean_s e_s . 1 / 4 pi`` and ``b = mean_s e_s . u_s / m``.
    """
    order = int(order)
    if order == 1:
        # No non-DC coefficients: exp*(f) = exp(f_0/sqrt(4 pi)) 1 exactly.
        k = int(round(max_magnitude / step)) + 1
        return OLTable(1, step, np.zeros(k), np.ones(k))
    u = training_vectors(order, count, seed)
    lam, vec = _eigh(product_matrix(u))
    w1 = SQRT_4PI * vec[:, 0, :]  # R 1 per shape, (S, n)
    wu = np.einsum("ski,sk->si", vec, u)  # R u_s
    m = np.arange(int(round(max_magnitude / step)) + 1) * step
    a = np.empty_like(m)
    b = np.empty_like(m)
    for s in range(0, m.size, 64):  # chunks keep the (K, S, n) exponent array small
        mc = m[s:s + 64]
        ml = mc[:, None, None] * lam[None]
        a[s:s + 64] = np.mean(np.sum(w1**2 * np.exp(ml), axis=-1), axis=1) / (4.0 * np.pi)
        # sum_k w1 wu = 1 . u = 0, so b = sum w1 wu (e^{m lam} - 1) / m; expm1 keeps small m exact.
        b[s:s + 64] = np.mean(np.sum(w1 * wu * np.expm1(ml), axis=-1), axis=1) / np.where(mc > 0, mc, 1.0)
    b[0] = 1.0  # limit m -> 0: b -> u^T M_u 1 / ... = u . u = 1
    return OLTable(order, step, np.log(a), b / a)


@lru_cache(maxsize=None)
def ol_table(order: int) -> OLTable:
    """The cached default optimal-linear table for ``order`` (:func:`fit_ol_table` defaults)."""
    return fit_ol_table(order)


def _exp_exact(f0, fh):
    lam, vec = _eigh(product_matrix(fh))
    # Combine the DC factor with e^{lambda} in one exponent: no overflow before the final product.
    return np.einsum("...ik,...k->...i", vec, SQRT_4PI * vec[..., 0, :] * np.exp(lam + (f0 / SQRT_4PI)[..., None]))


def _exp_series(f0, fh, tol, max_terms):
    order = order_of(fh.shape[-1], "f")
    m = product_matrix(fh)
    term = np.broadcast_to(unit_vector(order), fh.shape).copy()
    total = term.copy()
    for k in range(1, max_terms + 1):
        term = np.einsum("...ij,...j->...i", m, term) / k
        total += term
        if np.all(np.linalg.norm(term, axis=-1) <= tol * np.linalg.norm(total, axis=-1)):
            break
    return total * np.exp(f0 / SQRT_4PI)[..., None]


def _ol_parts(fh, table: OLTable):
    """``(log a, u)`` with ``a 1 + b f^ = exp(log a) (1 + c f^)`` un-normalised in u."""
    mag = np.linalg.norm(fh, axis=-1)
    la, c = table.lookup(mag)
    u = fh * c[..., None]
    u[..., 0] = SQRT_4PI
    return la, u


def _hybrid_parts(f0, fh, table: OLTable, threshold: float):
    order = order_of(fh.shape[-1], "f")
    lead = fh.shape[:-1]
    fh = fh.reshape(-1, order * order)
    f0 = np.asarray(f0).reshape(-1)
    mag = np.linalg.norm(fh, axis=-1)
    p = np.where(mag > threshold, np.ceil(np.log2(np.maximum(mag, 1e-300) / threshold)), 0).astype(np.int64)
    la, u = _ol_parts(fh * np.ldexp(1.0, -p)[:, None], table)
    nrm = np.linalg.norm(u, axis=-1)
    log_scale = la + np.log(nrm)
    u = u / nrm[:, None]
    for k in range(int(p.max(initial=0))):
        act = p > k
        sq = sh_product(u[act], u[act], order)
        nrm = np.linalg.norm(sq, axis=-1)
        zero = nrm == 0.0
        u[act] = sq / np.where(zero, 1.0, nrm)[:, None]
        with np.errstate(divide="ignore"):
            log_scale[act] = 2.0 * log_scale[act] + np.log(nrm)
    return (log_scale + f0 / SQRT_4PI).reshape(lead), u.reshape(lead + (order * order,))


def hybrid_exp_parts(f, table: OLTable | None = None, threshold: float = DEFAULT_HYBRID_THRESHOLD):
    """The hybrid exponential as ``exp(log_scale) * unit``, for results beyond the float range.

    Args:
        f: SH vectors, shape (..., n*n).
        table: optimal-linear table (default :func:`ol_table` of the input order).
        threshold: as in :func:`sh_exp`.

    Returns:
        ``(log_scale, unit)``: shapes (...,) and (..., n*n), float64; ``unit`` has norm 1 (or 0).
    """
    f = np.asarray(f, dtype=np.float64)
    order = order_of(f.shape[-1], "f")
    table = ol_table(order) if table is None else table
    f0, fh = _split_dc(f)
    return _hybrid_parts(f0, fh, table, threshold)


def _exp_hybrid(f0, fh, table: OLTable, threshold: float):
    log_scale, u = _hybrid_parts(f0, fh, table, threshold)
    return u * np.exp(log_scale)[..., None]


def sh_exp(f, method: str = "hybrid", *, table: OLTable | None = None,
           threshold: float = DEFAULT_HYBRID_THRESHOLD, tol: float = 1e-15, max_terms: int = 500) -> np.ndarray:
    """SH exponential ``exp*(f)`` (thesis eqs. 3.25–3.32), float64; methods in the module docstring.

    Args:
        f: SH vectors, shape (..., n*n) (e.g. a sum of blocker logs).
        method: ``"hybrid"`` (default), ``"ol"``, ``"series"`` or ``"exact"``.
        table: optimal-linear table (default :func:`ol_table` of the input order).
        threshold: ``"hybrid"``: largest ``||f^||`` handed to OL unscaled (> 0).
        tol: ``"series"``: stop when the last term's norm is below ``tol`` times the sum's.
        max_terms: ``"series"``: hard cap on the number of terms.

    Returns:
        Shape (..., n*n), dtype float64.
    """
    f = np.asarray(f, dtype=np.float64)
    order = order_of(f.shape[-1], "f")
    if method not in METHODS:
        raise ValueError(f"sh_exp: method must be one of {METHODS}, got {method!r}")
    if not np.all(np.isfinite(f)):
        raise ValueError("sh_exp: f contains NaN or inf")
    f0, fh = _split_dc(f)
    if method == "exact":
        return _exp_exact(f0, fh)
    if method == "series":
        return _exp_series(f0, fh, tol, max_terms)
    table = ol_table(order) if table is None else table
    if table.order != order:
        raise ValueError(f"sh_exp: OL table is for order {table.order}, f has order {order}")
    if method == "ol":
        la, u = _ol_parts(fh, table)
        return u * np.exp(la + f0 / SQRT_4PI)[..., None]
    if not threshold > 0:
        raise ValueError(f"sh_exp: threshold must be > 0, got {threshold!r}")
    return _exp_hybrid(f0, fh, table, threshold)
