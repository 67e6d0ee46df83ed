"""Precomputed 1D tables of the sphere-set method (thesis §4.2 "Precomputation", §4.3.3, eq. 4.24).

Everything a sphere contributes is circularly symmetric about the direction of its centre, so it is a
zonal-harmonic (ZH) vector ``g_l`` that depends on one number, the sphere's angular radius θ. The
run-time kernels interpolate these tables and rotate the result with ``f_lm = sqrt(4π/(2l+1)) g_l
y_lm(w)`` (docs/conventions.md §1). The SH algebra (caps, logarithm, exponential tables, products) is the
SH core's (:mod:`warpshade.sh`); this module only tabulates it by angular radius.

SH convention: :mod:`warpshade.sh.basis`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre

from ... import _cache
from ...sh import exp as _exp_module
from ...sh import zonal as _zonal_module
from ...sh.exp import ol_table, sh_exp, zh_log
from ...sh.products import sh_product
from ...sh.zonal import clamped_cosine_zh, sh_to_zh, sphere_visibility_zh, zh_band_factors, zh_expand_index, zh_to_sh

# Uniform in θ over [0, π/2] (a sphere that does not contain the receiver subtends at most π/2).
# 512 entries: linear interpolation error of the log vectors < 1e-4.
TABLE_SIZE = 512
THETA_MAX = 0.5 * math.pi

LOG_EPS = 0.02
"""Eigenvalue clip of the blocker logarithm (thesis eq. 3.34). Measured over θ ∈ [0, π/2] at orders 4–6:
max |exp(log B) - B| is 0.072 at 0.02 against 0.10 at 1e-3 and 0.12 at 1e-5 (ringing makes ``M_B``
of a large cap indefinite, and a small clip turns those directions into huge logs)."""

LOG_FIT_POINTS = 64
LOG_FIT_REG = 1e-2

CACHE_KIND = "spheres_log"
"""Kind of the fitted log tables' entries in warpshade's disk cache (:mod:`warpshade._cache`)."""

EXP_BLEND = 0.125
"""Octaves of ``||f̂||`` over which results with ``p`` and ``p+1`` squarings are blended (kernels.EXP_BLEND)."""


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


def zh_project_pieces(fn, order: int, breaks, nodes: int = 64) -> np.ndarray:
    """ZH coefficients ``g_l = 2π ∫ f(z) Y_l0(z) dz`` of a function of ``z = cos(angle from +z)``.

    The ``z`` range is split at ``breaks`` (where ``fn`` has kinks or jumps) and each piece integrated
    by Gauss–Legendre quadrature.
    """
    x, w = _gl_nodes(nodes)
    g = np.zeros(order)
    for a, b in zip(breaks[:-1], breaks[1:]):
        if b <= a:
            continue
        z = 0.5 * (b - a) * x + 0.5 * (b + a)
        g += 2 * math.pi * 0.5 * (b - a) * (w * fn(z)) @ zonal_basis(z, order)
    return g


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
class SphereTables:
    """The 1D tables of one SH order and exponential, sampled uniformly in angular radius θ ∈ [0, π/2].

    Attributes:
        order: SH order.
        log_blocker: ZH log of the blocker function of a sphere of angular radius θ, shape (TABLE_SIZE, order).
        form_factor: Normalised form-factor ZH vectors (eq. 4.24), shape (TABLE_SIZE, order).
        band_scale: ``sqrt(4π/(2l+1))`` per SH coefficient (ZH rotation), shape (order*order,).
        cosine: Clamped-cosine ZH ``A_l`` times ``sqrt(4π/(2l+1))`` per coefficient, shape (order*order,).
    """

    order: int
    log_blocker: np.ndarray
    form_factor: np.ndarray
    band_scale: np.ndarray
    cosine: np.ndarray

    @property
    def theta_step(self) -> float:
        return THETA_MAX / (TABLE_SIZE - 1)


def per_coeff(zh: np.ndarray) -> np.ndarray:
    """Expand a per-band array (order,) to per coefficient (order*order,) (band l repeated 2l+1 times)."""
    zh = np.asarray(zh)
    return zh[zh_expand_index(len(zh))]


def _series_scaled(f, p, order):
    s = 0.5 ** p
    fh = f.copy()
    fh[0] = 0.0
    out = s * fh
    out[0] = math.sqrt(4 * math.pi)
    term = s * fh
    for k in range(2, 9):
        term = sh_product(term, fh, order) * s / k
        out = out + term
    out = out * math.exp(f[0] * s / math.sqrt(4 * math.pi))
    for _ in range(p):
        out = sh_product(out, out, order)
    return out


def sh_exp_np(f, order, mode="hyb", tau=0.5):
    """Host twin of ``exp_blended`` in :mod:`.fixed_kernels` (modes ``ol``, ``hyb``, ``series``; see there), float64."""
    f = np.asarray(f, dtype=np.float64)
    if mode == "ol":
        return sh_exp(f, "ol")
    m = float(np.linalg.norm(f[1:]))
    lim = 0.25 if mode == "series" else tau
    p, w = 0, 0.0
    if m > 0:
        q = math.log2(m / lim)
        p = min(max(math.ceil(q), 0), 30)
        w = min(max((q - (p - EXP_BLEND)) / EXP_BLEND, 0.0), 1.0)
    if mode == "hyb":
        out = sh_exp(f, "hybrid", threshold=lim)
        if w > 0:
            out = (1 - w) * out + w * sh_exp(f, "hybrid", threshold=0.5 * lim)
        return out
    out = _series_scaled(f, p, order)
    if w > 0:
        out = (1 - w) * out + w * _series_scaled(f, p + 1, order)
    return out


def log_table_key(order: int, mode: str, tau: float) -> str:
    """The disk-cache key of :func:`log_blocker_table`: everything the fit reads (the SH core's optimal-linear
    table, this module's constants), the sources of the code that computes it (this module, the SH core's
    exponentials and zonal functions) and the NumPy and SciPy versions."""
    ol = ol_table(order)
    return _cache.Key(order, mode, float(tau), ol.log_a, ol.c, TABLE_SIZE, LOG_EPS, LOG_FIT_POINTS, LOG_FIT_REG,
                      EXP_BLEND, *(_cache.source_digest(f) for f in (__file__, _exp_module.__file__, _zonal_module.__file__)),
                      *_cache.versions("numpy", "scipy")).hexdigest()


@lru_cache(maxsize=None)
def log_blocker_table(order: int, mode: str = "hyb", tau: float = 0.5) -> np.ndarray:
    """Log blocker ZH vectors by angular radius, shape (TABLE_SIZE, order), matched to exponential ``mode``.

    Ren et al.'s eigen-log (eq. 3.34, :func:`warpshade.sh.exp.zh_log`) inverts the exact exponential;
    the run-time exponentials are different maps (optimal linear; squarings of truncated products),
    and for a hemisphere-sized sphere exp(log B) misses B by up to 0.4 (hybrid) and 0.9 (optimal
    linear) in a coefficient. Each entry is therefore refined by damped least squares against the
    host twin of the run-time exponential, ``min ||exp_mode(f) - B_θ||² + λ²||f - log(B_θ)||²``
    (λ = 1e-2, :data:`LOG_FIT_POINTS` radii, linear interpolation between them). Cached on disk
    (:func:`warpshade._cache.root`: ``$WARPSHADE_CACHE``, else the user cache directory) because the fit
    takes seconds; the entry's key is :func:`log_table_key`.
    """
    from scipy.optimize import least_squares

    key = log_table_key(order, mode, tau)
    hit = _cache.load(CACHE_KIND, key, check=lambda a: _cache.has_layout(a, {"table": ((TABLE_SIZE, order), np.float64)}))
    if hit is not None:
        return hit["table"]
    fit_t = np.linspace(0.0, THETA_MAX, LOG_FIT_POINTS)
    blockers = sphere_visibility_zh(fit_t, order)
    anchors = zh_log(blockers, eps=LOG_EPS)
    fits = []
    for b, f0 in zip(blockers, anchors):
        res = least_squares(lambda f: np.concatenate([sh_to_zh(sh_exp_np(zh_to_sh(f), order, mode, tau)) - b,
                                                      LOG_FIT_REG * (f - f0)]), f0, max_nfev=100)
        fits.append(res.x)
    fits = np.array(fits)
    thetas = np.linspace(0.0, THETA_MAX, TABLE_SIZE)
    table = np.stack([np.interp(thetas, fit_t, fits[:, l]) for l in range(order)], axis=1)
    _cache.save(CACHE_KIND, key, {"table": table})  # an unwritable root only costs the fit again next time
    return table


@lru_cache(maxsize=None)
def sphere_tables(order: int, mode: str = "hyb", tau: float = 0.5) -> SphereTables:
    """Build (once per process, order and exponential) every table the sphere kernels need."""
    thetas = np.linspace(0.0, THETA_MAX, TABLE_SIZE)
    ffs = np.array([form_factor_zh(t, order) for t in thetas])
    scale = per_coeff(zh_band_factors(order))
    return SphereTables(order=order, log_blocker=log_blocker_table(order, mode, tau), form_factor=ffs,
                        band_scale=scale, cosine=scale * per_coeff(clamped_cosine_zh(order)))


def ol_arrays(order: int):
    """The SH core's optimal-linear table (``log a``, ``c = b/a``, step) for ``order``."""
    t = ol_table(order)
    return t.log_a, t.c, t.step
