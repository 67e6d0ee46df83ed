"""Precomputed 1D tables of the sphere-set method (thesis §4.2 "Precomputation", §4.3.3, eq. 4.24).

Everything a sphere contributes is circularly symmetric about the direction of its centre, so it is a
zonal-harmonic (ZH) vector ``g_l`` (the ``m = 0`` coefficients of an SH vector aligned with +z) that
depends on one number, the sphere's angular radius θ. The run-time kernels interpolate these tables
and rotate the result with ``f_lm = sqrt(4π/(2l+1)) g_l y_lm(w)`` (CONTRACTS.md §1).

Zonal algebra is exact in 1D: a product of two zonal functions is zonal, and the SH product matrix of a
zonal vector is block-diagonal in ``m``, so the ``m = 0`` block (``order × order``) carries the whole
SH logarithm / exponential of a zonal vector (thesis eqs. 3.25, 3.34). Integrals use Gauss–Legendre
quadrature in ``z = cos(angle)``, exact for the polynomial degrees involved.

SH convention: :mod:`warpshade.sh.basis`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre

# Angular-radius grid: dense near 0 would waste entries (g is linear in the cap's solid angle there),
# so the table is uniform in θ over [0, π/2] (a sphere that does not contain the receiver subtends at
# most π/2). 512 entries: linear interpolation error of the log vectors measured < 1e-4 (tests).
TABLE_SIZE = 512
THETA_MAX = 0.5 * math.pi


@lru_cache(maxsize=None)
def _gl_nodes(n: int):
    return legendre.leggauss(n)


def zonal_basis(z: np.ndarray, order: int) -> np.ndarray:
    """``Y_l0(z) = sqrt((2l+1)/4π) P_l(z)``, shape (len(z), order)."""
    z = np.asarray(z, dtype=np.float64)
    out = np.empty((len(z), order))
    for l in range(order):
        c = np.zeros(l + 1)
        c[l] = 1.0
        out[:, l] = math.sqrt((2 * l + 1) / (4 * math.pi)) * legendre.legval(z, c)
    return out


def zh_project(fn, order: int, nodes: int = 256) -> np.ndarray:
    """ZH coefficients ``g_l = 2π ∫ f(z) Y_l0(z) dz`` of a function of ``z = cos(angle from +z)``.

    Args:
        fn: Vectorised function of ``z`` in [-1, 1].
        order: SH order.
        nodes: Gauss–Legendre nodes (the integrand may have a kink; callers split at it, see
            :func:`zh_project_pieces`).
    """
    return zh_project_pieces(fn, order, [-1.0, 1.0], nodes)


def zh_project_pieces(fn, order: int, breaks, nodes: int = 64) -> np.ndarray:
    """Like :func:`zh_project` with the ``z`` range split at ``breaks`` (where ``fn`` has kinks/jumps)."""
    x, w = _gl_nodes(nodes)
    g = np.zeros(order)
    for a, b in zip(breaks[:-1], breaks[1:]):
        if b <= a:
            continue
        z = 0.5 * (b - a) * x + 0.5 * (b + a)
        g += 2 * math.pi * 0.5 * (b - a) * (w * fn(z)) @ zonal_basis(z, order)
    return g


def cap_blocker_zh(theta: float, order: int) -> np.ndarray:
    """ZH vector of the blocker function of a sphere of angular radius ``theta`` centred on +z.

    ``B(ω) = 0`` inside the cap ``z > cos θ``, 1 outside (thesis eq. 4.3). Analytic:
    ``∫_{-1}^{c} P_l = (P_{l+1}(c) - P_{l-1}(c)) / (2l+1)``.
    """
    c = math.cos(theta)
    p = [1.0, c]
    for l in range(1, order + 1):
        p.append(((2 * l + 1) * c * p[l] - l * p[l - 1]) / (l + 1))
    g = np.zeros(order)
    g[0] = 2 * math.pi * math.sqrt(1 / (4 * math.pi)) * (c + 1.0)
    for l in range(1, order):
        g[l] = 2 * math.pi * math.sqrt((2 * l + 1) / (4 * math.pi)) * (p[l + 1] - p[l - 1]) / (2 * l + 1)
    return g


@lru_cache(maxsize=None)
def zonal_gaunt(order: int) -> np.ndarray:
    """``Γ_{l l1 l2} = ∫ Y_l0 Y_l1,0 Y_l2,0 dω``, shape (order, order, order) (thesis eq. 3.20, m = 0 block)."""
    x, w = _gl_nodes(3 * order + 2)
    y = zonal_basis(x, order)
    return 2 * math.pi * np.einsum("q,qa,qb,qc->abc", w, y, y, y)


def zonal_product_matrix(g: np.ndarray) -> np.ndarray:
    """SH product matrix ``(M_g)_{l l2} = Σ_l1 g_l1 Γ_{l l1 l2}`` of a ZH vector (thesis eq. 3.22), (order, order)."""
    return np.einsum("b,abc->ac", g, zonal_gaunt(len(g)))


def zonal_one(order: int) -> np.ndarray:
    """The unit vector ``1 = (sqrt(4π), 0, ...)`` (thesis eq. 3.25)."""
    e = np.zeros(order)
    e[0] = math.sqrt(4 * math.pi)
    return e


LOG_EIG_FLOOR = 0.02
"""Eigenvalue clip of the SH logarithm (thesis eq. 3.34, "clipped to a small ε"). 0.02 keeps the log of
a hemisphere-sized blocker finite; exp(log(B)) reproduces B to < 1e-3 (tests)."""


def zonal_log(g: np.ndarray, floor: float = LOG_EIG_FLOOR) -> np.ndarray:
    """SH logarithm of a ZH vector, Ren et al.'s ``R^T q'(D) R (g - 1)`` (thesis eq. 3.34).

    With ``M_g = R^T D R`` this equals ``R^T log(D) R 1``; eigenvalues are clipped to ``floor``.
    """
    d, r = np.linalg.eigh(zonal_product_matrix(g))
    return r @ (np.log(np.maximum(d, floor)) * (r.T @ zonal_one(len(g))))


def zonal_exp_series(f: np.ndarray) -> np.ndarray:
    """Accurate SH exponential ``exp_*(f) = Σ M_f^k 1 / k!`` of a ZH vector (thesis eq. 3.25), via expm."""
    # M_f is symmetric (Γ is), so expm(M_f) = R exp(D) R^T exactly.
    d, r = np.linalg.eigh(zonal_product_matrix(f))
    return r @ (np.exp(d) * (r.T @ zonal_one(len(f))))


def clamped_cosine_zh(order: int) -> np.ndarray:
    """ZH vector ``A_l`` of ``max(0, z)`` (CONTRACTS.md §2)."""
    return zh_project_pieces(lambda z: np.maximum(z, 0.0), order, [-1.0, 0.0, 1.0])


def form_factor(theta: float, alpha: np.ndarray) -> np.ndarray:
    """Thesis eq. 4.24: cosine weight of a sphere point at angle ``alpha`` from the direction to the receiver.

    ``theta`` is the sphere's angular radius at the receiver.
    """
    st = math.sin(theta)
    a = np.asarray(alpha, dtype=np.float64)
    beta = np.arctan2(1.0 - st * np.cos(a), st * np.sin(a))
    return np.maximum(0.0, np.sin(beta - a))


def form_factor_zh(theta: float, order: int) -> np.ndarray:
    """ZH vector of eq. 4.24, normalised to ``∫ f dω = 1`` so ``r · R(f)`` is a weighted average of ``r``."""
    theta = min(max(theta, 1e-6), THETA_MAX - 1e-3)  # at π/2 f degenerates to a point
    # f vanishes for α beyond the horizon, cos α < sin θ (the tangent circle seen from the receiver).
    zc = math.sin(theta)
    fn = lambda z: form_factor(theta, np.arccos(np.clip(z, -1, 1)))  # noqa: E731
    g = zh_project_pieces(fn, order, [zc, 1.0], nodes=128)
    return g / (g[0] * math.sqrt(4 * math.pi))


@dataclass(frozen=True)
class ExpTable:
    """Optimal-linear SH exponential coefficients ``a(m), b(m)`` by ``m = ||f̂||`` (thesis eq. 3.30).

    ``exp_*(f) ≈ exp(f_0/sqrt(4π)) (a 1 + b f̂)``. Built from representative blocker logs (scaled log
    caps of many angular radii, DC removed) whose exact exponential is known from :func:`zonal_exp_series`;
    ``a, b`` are the least-squares projections of eq. 3.29 averaged over the representatives.
    """

    m_max: float
    a: np.ndarray
    b: np.ndarray

    @property
    def size(self) -> int:
        return len(self.a)

    def lookup(self, m):
        t = np.clip(np.asarray(m, dtype=np.float64) / self.m_max * (self.size - 1), 0, self.size - 1)
        return np.interp(t, np.arange(self.size), self.a), np.interp(t, np.arange(self.size), self.b)


@lru_cache(maxsize=None)
def exp_table(order: int, m_max: float = 64.0, size: int = 1024) -> ExpTable:
    """Build :class:`ExpTable` for ``order`` (magnitudes 0..``m_max``; beyond it the last entry is used)."""
    shapes = []
    for theta in np.linspace(0.05, THETA_MAX, 12):
        f = zonal_log(cap_blocker_zh(theta, order))
        f[0] = 0.0
        n = np.linalg.norm(f)
        if n > 0:
            shapes.append(f / n)
    e = zonal_one(order)
    ms = np.linspace(0.0, m_max, size)
    aa = np.zeros((len(shapes), size))
    bb = np.zeros((len(shapes), size))
    for k, s in enumerate(shapes):
        # exp_*(m s) = R exp(m D) R^T 1 for the eigen-decomposition of M_s (M is linear in s)
        d, r = np.linalg.eigh(zonal_product_matrix(s))
        ex = (r * np.exp(np.outer(ms, d))[:, None, :]) @ (r.T @ e)  # (size, order)
        aa[k] = ex @ e / (e @ e)
        bb[k] = np.where(ms > 0, ex @ s / np.maximum(ms, 1e-30), 1.0)
    return ExpTable(m_max=float(m_max), a=aa.mean(axis=0), b=bb.mean(axis=0))


@dataclass(frozen=True)
class SphereTables:
    """The 1D tables of one SH order, sampled uniformly in angular radius θ ∈ [0, π/2].

    Attributes:
        order: SH order.
        log_blocker: ZH log of the blocker function of a sphere of angular radius θ, shape (TABLE_SIZE, order).
        form_factor: Normalised form-factor ZH vectors (eq. 4.24), shape (TABLE_SIZE, order).
        band_scale: ``sqrt(4π/(2l+1))`` per SH coefficient (ZH rotation), shape (order*order,).
        cosine: Clamped-cosine ZH ``A_l`` times ``sqrt(4π/(2l+1))`` per coefficient, shape (order*order,).
        exp: Optimal-linear exponential coefficients.
    """

    order: int
    log_blocker: np.ndarray
    form_factor: np.ndarray
    band_scale: np.ndarray
    cosine: np.ndarray
    exp: ExpTable

    @property
    def theta_step(self) -> float:
        return THETA_MAX / (TABLE_SIZE - 1)


def per_coeff(zh: np.ndarray) -> np.ndarray:
    """Expand a per-band array (order,) to per coefficient (order*order,) (band l repeated 2l+1 times)."""
    return np.concatenate([[zh[l]] * (2 * l + 1) for l in range(len(zh))])


EXP_BLEND = 0.25
"""Octaves of ``||f̂||`` over which results of ``p`` and ``p+1`` squarings are blended (see kernels)."""


def _exp_scaled(f, mode, p, m, table, product):
    s = 0.5 ** p
    dc = math.exp(f[0] * s / math.sqrt(4 * math.pi))
    fh = f.copy()
    fh[0] = 0.0
    if mode == "series":
        out = s * fh
        out[0] = math.sqrt(4 * math.pi)
        term = s * fh
        for k in range(2, 9):
            term = product(term, fh) * s / k
            out = out + term
        out = out * dc
    else:
        a, b = table.lookup(m * s)
        out = dc * b * s * fh
        out[0] = dc * a * math.sqrt(4 * math.pi)
    for _ in range(p):
        out = product(out, out)
    return out


def sh_exp_generic(f: np.ndarray, mode: str, tau: float, table: ExpTable, product) -> np.ndarray:
    """SH exponential, the same algorithm as the kernel ``sh_exp_rows`` (see there), for any product.

    Args:
        f: SH (or ZH) vector.
        mode: ``"ol"``, ``"hyb"`` or ``"series"``.
        tau: Hybrid: largest ``||f̂||`` given to the optimal-linear step.
        table: Optimal-linear coefficients.
        product: ``product(a, b)``: SH product (full) or zonal product.
    """
    f = np.asarray(f, dtype=np.float64)
    m = float(np.linalg.norm(f[1:]))
    lim = 0.25 if mode == "series" else tau
    p, w = 0, 0.0
    if mode != "ol" and m > 0:
        q = math.log2(m / lim)
        p = min(max(math.ceil(q), 0), 16)
        w = min(max((q - (p - EXP_BLEND)) / EXP_BLEND, 0.0), 1.0)
    out = _exp_scaled(f, mode, p, m, table, product)
    if w > 0:
        out = (1 - w) * out + w * _exp_scaled(f, mode, p + 1, m, table, product)
    return out


LOG_FIT_POINTS = 96
LOG_FIT_REG = 1e-2


@lru_cache(maxsize=None)
def log_blocker_table(order: int, mode: str = "hyb", tau: float = 1.0) -> np.ndarray:
    """Log blocker ZH vectors by angular radius, shape (TABLE_SIZE, order), matched to an exponential.

    Ren et al.'s eigen-log (eq. 3.34) inverts the Taylor exponential; the run-time exponentials
    (optimal linear, hybrid squaring) are different maps, and for a large sphere the mismatch reaches
    0.4 (hybrid) to 0.9 (optimal linear) in a ZH coefficient of a single blocker. So each entry is
    refined by damped least squares, ``min ||exp_mode(f) - B_θ||² + λ²||f - log_Ren(B_θ)||²`` with
    λ = 1e-2, on LOG_FIT_POINTS radii and interpolated to the table (single-sphere errors measured in
    tests: <= 0.08 hybrid, <= 0.17 optimal linear at θ -> π/2, ~0 below θ = 0.6).
    """
    from scipy.optimize import least_squares

    table = exp_table(order)
    prod = lambda a, b: zonal_product_matrix(a) @ b  # noqa: E731
    fit_t = np.linspace(0.0, THETA_MAX, LOG_FIT_POINTS)
    fits = []
    for t in fit_t:
        blocker = cap_blocker_zh(t, order)
        f0 = zonal_log(blocker)
        res = least_squares(lambda f: np.concatenate([sh_exp_generic(f, mode, tau, table, prod) - blocker,
                                                      LOG_FIT_REG * (f - f0)]), f0, max_nfev=200)
        fits.append(res.x)
    fits = np.array(fits)
    thetas = np.linspace(0.0, THETA_MAX, TABLE_SIZE)
    return np.stack([np.interp(thetas, fit_t, fits[:, l]) for l in range(order)], axis=1)


@lru_cache(maxsize=None)
def sphere_tables(order: int, mode: str = "hyb", tau: float = 1.0) -> SphereTables:
    """Build (once per process, order and exponential) every table the sphere kernels need."""
    thetas = np.linspace(0.0, THETA_MAX, TABLE_SIZE)
    ffs = np.array([form_factor_zh(t, order) for t in thetas])
    scale = per_coeff(np.array([math.sqrt(4 * math.pi / (2 * l + 1)) for l in range(order)]))
    return SphereTables(order=order, log_blocker=log_blocker_table(order, mode, tau), form_factor=ffs,
                        band_scale=scale, cosine=scale * per_coeff(clamped_cosine_zh(order)), exp=exp_table(order))


@lru_cache(maxsize=None)
def gaunt_sparse(order: int, tol: float = 1e-10):
    """Nonzero SH triple products ``Γ_ijk`` (eq. 3.20) of one order as ``(i, j, k, value)`` arrays.

    Product quadrature (Gauss–Legendre in z × uniform in φ) exact for the degree ``3(order-1)`` integrand.
    """
    from ...sh.basis import sh_eval

    z, wz = _gl_nodes(2 * order)
    nphi = 3 * order + 1
    phi = 2 * math.pi * np.arange(nphi) / nphi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1 - zz ** 2)
    dirs = np.stack([s * np.cos(pp), s * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    w = (np.repeat(wz, nphi) * (2 * math.pi / nphi))
    y = sh_eval(dirs, order)
    g = np.einsum("q,qi,qj,qk->ijk", w, y, y, y)
    i, j, k = np.nonzero(np.abs(g) > tol)
    return i.astype(np.int32), j.astype(np.int32), k.astype(np.int32), g[i, j, k].astype(np.float32)
