"""Small, obviously-correct NumPy reference of the sphere kernels (one receiver at a time, float64).

Tests compare the Warp kernels against these functions, and these against analytic cases. The SH
algebra is the SH core's (:mod:`warpshade.sh`).
"""

from __future__ import annotations

import math

import numpy as np

from ...sh.products import sh_product
from ...sh.zonal import clamped_cosine_zh, zh_rotate
from .tables import sh_exp_np, sphere_tables

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


def log_blocker_np(theta, order, mode="hyb", tau=0.5):
    """Tabulated log blocker ZH vector at angular radius ``theta`` (linear interpolation, as the kernel)."""
    t = sphere_tables(order, mode, tau)
    x = np.clip(theta / t.theta_step, 0, len(t.log_blocker) - 1)
    i0 = min(int(x), len(t.log_blocker) - 2)
    f = x - i0
    return t.log_blocker[i0] * (1 - f) + t.log_blocker[i0 + 1] * f


def cosine_np(n, order):
    """Clamped cosine about ``n``: the unoccluded transfer (CONTRACTS.md §2)."""
    return zh_rotate(clamped_cosine_zh(order), np.asarray(n, dtype=np.float64))


def shade_np(p, n, centers, radii, order, mode="hyb", tau=0.5, ratios=None):
    """Visibility and transfer of one receiver under blocker spheres (kernel ``shade`` of :mod:`.fixed_kernels`).

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
        logsum += zh_rotate(g, d)
    vis = sh_exp_np(logsum, order, mode, tau)
    bound = 1.1 * SQRT_4PI  # kernels.VIS_NORM_SLACK
    if not (0 <= vis[0] <= bound and vis @ vis <= bound * bound):
        vis = np.zeros_like(vis)
        vis[0] = SQRT_4PI * math.exp(min(logsum[0] / SQRT_4PI, 0.0))
    tr = sh_product(vis, cosine_np(n, order), order)
    if tr[0] < 0:
        tr = np.zeros_like(tr)
    return vis, tr, logsum
