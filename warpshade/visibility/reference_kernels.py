"""Kernels of the ray-traced reference transfer (see :mod:`warpshade.visibility.reference`)."""

from __future__ import annotations

import warp as wp

from ..sh.kernels import sh_accumulate


@wp.func
def orthonormal_basis(n: wp.vec3) -> wp.mat33:
    """Columns (t, b, n): a right-handed frame around unit ``n`` (Duff et al. 2017, no branch on |n_z|)."""
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    bb = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return wp.matrix_from_cols(t, bb, n)


@wp.func
def concentric_disk(u: float, v: float) -> wp.vec2:
    """Shirley–Chiu concentric map of [0,1)^2 onto the unit disk (area preserving, low distortion)."""
    a = 2.0 * u - 1.0
    b = 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return wp.vec2(0.0, 0.0)
    r = float(0.0)
    phi = float(0.0)
    if a * a > b * b:
        r = a
        phi = (wp.pi / 4.0) * (b / a)
    else:
        r = b
        phi = (wp.pi / 2.0) - (wp.pi / 4.0) * (a / b)
    return wp.vec2(r * wp.cos(phi), r * wp.sin(phi))


@wp.func
def cosine_direction(frame: wp.mat33, u: float, v: float) -> wp.vec3:
    """Cosine-weighted hemisphere direction about ``frame``'s third column for (u, v) in [0,1)^2
    (concentric disk lifted to the hemisphere, pdf ``cos/pi``)."""
    d2 = concentric_disk(u, v)
    z = wp.sqrt(wp.max(0.0, 1.0 - wp.dot(d2, d2)))
    return frame * wp.vec3(d2[0], d2[1], z)


@wp.kernel
def trace_transfer(
    mesh: wp.uint64,
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    strata: int,
    offset: float,
    max_t: float,
    seed: int,
    order: int,
    k: wp.array[float],
    transfer: wp.array2d[float],
):
    """Monte-Carlo diffuse transfer (CONTRACTS.md §2) by stratified cosine-weighted rays.

    With pdf ``cos/pi`` the estimator of ``∫ y_i V cos dω`` is ``(pi/N) Σ y_i(ω_k) V(ω_k)``.
    """
    v = wp.tid()
    n = normals[v]
    frame = orthonormal_basis(n)
    origin = points[v] + n * offset
    rng = wp.rand_init(seed, v)
    weight = wp.pi / float(strata * strata)
    for i in range(order * order):
        transfer[v, i] = 0.0
    for sx in range(strata):
        for sy in range(strata):
            u = (float(sx) + wp.randf(rng)) / float(strata)
            w = (float(sy) + wp.randf(rng)) / float(strata)
            d = cosine_direction(frame, u, w)
            q = wp.mesh_query_ray(mesh, origin, d, max_t)
            if not q.result:
                sh_accumulate(d, weight, order, k, transfer, v)
