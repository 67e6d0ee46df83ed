"""Small, obviously-correct NumPy oracle of the sphere kernels (one receiver at a time, float64).

Tests compare the Warp kernels against these functions, and these against analytic cases. The SH
algebra is the SH core's (:mod:`warpshade.sh`).
"""

from __future__ import annotations

import math

import numpy as np

from ...sh.products import sh_product
from ...sh.zonal import unoccluded_transfer, zh_rotate
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
    return _lerp_table_np(t.log_blocker, theta, t.theta_step)


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
    tr = sh_product(vis, unoccluded_transfer(n, order), order)
    if tr[0] < 0:
        tr = np.zeros_like(tr)
    return vis, tr, logsum


def _lerp_table_np(table, theta, step):
    x = np.clip(theta / step, 0, len(table) - 1)
    i0 = min(int(x), len(table) - 2)
    f = x - i0
    return table[i0] * (1 - f) + table[i0 + 1] * f


def reflect_np(p, n, centers, radii, rotations, radiance, objects, order, mode="ol", tau=0.5, ratios=None,
               exclude_intersecting=False, own=-1):
    """Reflected irradiance of one receiver from reflecting spheres (kernel ``reflect`` of :mod:`.fixed_kernels`).

    Spheres after the tangent-plane rules, nearest first (ties: lower index first); sphere ``i``'s
    visibility ``exp(P_i) - exp(P_i + G_i)`` (eq. 4.32), ``P_i`` the log sum of the closer spheres (with
    ``exclude_intersecting``: without closer spheres of the same object that intersect sphere ``i``),
    dotted with the clamped cosine (eq. 4.33), times the form-factor average of its radiance vector in its
    rest frame (eq. 4.25, Fig. 4.17), times its ratio (eq. 4.35). Spheres of object ``own`` are skipped.

    Args:
        p, n: Receiver position and unit normal, (3,).
        centers, radii, rotations: Spheres (S, 3), (S,), (S, 3, 3) (rest-to-current rotation).
        radiance: Radiance SH vectors, (S, 3, N*N).
        objects: Object of each sphere, (S,).
        ratios: Optional per-sphere scalar ratio (S,).

    Returns:
        Reflected irradiance, (3,), clamped at 0.
    """
    p, n = np.asarray(p, np.float64), np.asarray(n, np.float64)
    centers, radii = np.asarray(centers, np.float64), np.asarray(radii, np.float64)
    t = sphere_tables(order, mode, tau)
    entries = []
    for s in range(len(radii)):
        if objects[s] == own:
            continue
        cc, rho = adjust_sphere_np(p, n, centers[s], radii[s])
        if rho > 0:
            entries.append((float(np.linalg.norm(cc - p)), s, cc, rho))
    entries.sort(key=lambda e: e[0])  # stable: equal distances keep index order, as the kernel's selection

    def log_vec(cc, rho):
        d = cc - p
        theta = math.asin(min(rho / max(np.linalg.norm(d), 1e-30), 1.0))
        return zh_rotate(log_blocker_np(theta, order, mode, tau), d), theta

    cosine = unoccluded_transfer(n, order)
    logsum = np.zeros(order * order)
    total = np.zeros(3)
    done = []
    for _dist, s, cc, rho in entries:
        g, theta = log_vec(cc, rho)
        pp = logsum.copy()
        if exclude_intersecting:
            for j, ccj, rhoj in done:
                if objects[j] == objects[s] and np.linalg.norm(centers[j] - centers[s]) < radii[j] + radii[s]:
                    pp -= log_vec(ccj, rhoj)[0]
        vis = float((sh_exp_np(pp, order, mode, tau) - sh_exp_np(pp + g, order, mode, tau)) @ cosine)
        logsum += g
        done.append((s, cc, rho))
        if vis <= 0:
            continue
        u = np.asarray(rotations[s], np.float64).T @ (p - centers[s])
        ff = zh_rotate(_lerp_table_np(t.form_factor, theta, t.theta_step), u)
        w = 1.0 if ratios is None else float(ratios[s])
        total += vis * w * (np.asarray(radiance[s], np.float64) @ ff)
    return np.maximum(total, 0.0)
