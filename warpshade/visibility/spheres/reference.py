"""Small, obviously-correct NumPy reference of the sphere kernels (one receiver at a time, float64).

Tests compare the Warp kernels against these functions, and these against analytic cases.
"""

from __future__ import annotations

import math

import numpy as np

from ...sh.basis import sh_eval
from .tables import gaunt_sparse, per_coeff, sh_exp_generic, sphere_tables

SQRT_4PI = math.sqrt(4 * math.pi)


def adjust_sphere_np(p, n, c, r):
    """Tangent-plane rules of §4.2 with the continuity factor α (same as kernel ``adjust_sphere``).

    Returns:
        ``(centre (3,), radius)``; radius 0 means removed.
    """
    p, n, c = (np.asarray(x, dtype=np.float64) for x in (p, n, c))
    h = float(np.dot(c - p, n))
    if h >= r:
        return c, float(r)
    if h <= -r:
        return np.zeros(3), 0.0
    q1 = c - h * n
    d = math.sqrt(max(r * r - h * h, 0.0))
    alpha = 1.0
    if d > 1e-6 * r:
        alpha = min(max((np.linalg.norm(p - q1) - d) / d, 0.0), 1.0)
    if h > 0:
        alpha = alpha + (1 - alpha) * h / r
    rho = alpha * 0.5 * (r + h)
    return q1 + n * rho, rho


def gaunt_dense(order: int) -> np.ndarray:
    """Dense ``Γ_ijk``, shape (N*N, N*N, N*N)."""
    i, j, k, v = gaunt_sparse(order)
    g = np.zeros((order * order,) * 3)
    g[i, j, k] = v
    return g


def sh_product_np(a, b, order):
    """SH product (eq. 3.19)."""
    return np.einsum("ijk,j,k->i", gaunt_dense(order), a, b)


def zh_rotate_np(g, d, order):
    """Rotate ZH vector ``g`` (order,) to axis ``d`` (eq. 3.17); returns (order*order,)."""
    scale = per_coeff(np.array([math.sqrt(4 * math.pi / (2 * l + 1)) for l in range(order)]))
    return scale * per_coeff(np.asarray(g)) * sh_eval(np.asarray(d, dtype=np.float64), order)


def log_blocker_np(theta, order, mode="hyb", tau=1.0):
    """Tabulated log blocker ZH vector at angular radius ``theta`` (linear interpolation, as the kernel)."""
    t = sphere_tables(order, mode, tau)
    x = np.clip(theta / t.theta_step, 0, len(t.log_blocker) - 1)
    i0 = min(int(x), len(t.log_blocker) - 2)
    f = x - i0
    return t.log_blocker[i0] * (1 - f) + t.log_blocker[i0 + 1] * f


def sh_exp_np(f, order, mode="hyb", tau=1.0):
    """SH exponential as in kernel ``sh_exp_rows`` (modes ``ol``, ``hyb``, ``series``), full SH products."""
    return sh_exp_generic(f, mode, tau, sphere_tables(order, mode, tau).exp, lambda a, b: sh_product_np(a, b, order))


def cosine_np(n, order):
    """Clamped cosine about ``n``: the unoccluded transfer (CONTRACTS.md §2)."""
    return sphere_tables(order, "ol").cosine * sh_eval(np.asarray(n, dtype=np.float64), order)


def shade_np(p, n, centers, radii, order, mode="hyb", tau=1.0, ratios=None):
    """Visibility and transfer of one receiver under blocker spheres (kernel ``shade_sphere_shadows``).

    Args:
        p, n: Receiver position and unit normal, (3,).
        centers, radii: Blocker spheres, (S, 3) and (S,).
        ratios: Optional per-sphere band ratios (S, order) (eq. 4.9).

    Returns:
        ``(visibility (N*N,), transfer (N*N,), log_sum (N*N,))``.
    """
    logsum = np.zeros(order * order)
    for s, (c, r) in enumerate(zip(np.atleast_2d(centers), np.atleast_1d(radii))):
        cc, rho = adjust_sphere_np(p, n, c, r)
        if rho <= 0:
            continue
        d = cc - np.asarray(p, dtype=np.float64)
        dist = np.linalg.norm(d)
        if dist <= 0:
            continue
        g = log_blocker_np(math.asin(min(rho / dist, 1.0)), order, mode, tau)
        if ratios is not None:
            g = g * ratios[s]
        logsum += zh_rotate_np(g, d, order)
    vis = sh_exp_np(logsum, order, mode, tau)
    bound = 1.1 * SQRT_4PI  # kernel guard_visibility
    if not (0 <= vis[0] <= bound and vis @ vis <= bound * bound):
        vis = np.zeros_like(vis)
        vis[0] = SQRT_4PI * math.exp(min(logsum[0] / SQRT_4PI, 0.0))
    tr = sh_product_np(vis, cosine_np(n, order), order)
    if tr[0] < 0:
        tr = np.zeros_like(tr)
    return vis, tr, logsum
