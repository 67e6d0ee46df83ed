"""Kernels of the ray-traced reference transfer (see :mod:`warpshade.visibility.reference.method`)."""

from __future__ import annotations

import warp as wp

from ...sh.kernels import sh_accumulate
from ..rays import (
    cosine_direction,
    near_faces,
    orthonormal_basis,
    ray_eps,
    trace_surface_ray,
)


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
    first: int,
    transfer: wp.array2d[float],
):
    """Monte-Carlo diffuse transfer (docs/conventions.md §2) by stratified cosine-weighted rays, of
    vertices ``first + tid`` (a launch covers one block of vertices).

    With pdf ``cos/pi`` the estimator of ``∫ y_i V cos dω`` is ``(pi/N) Σ y_i(ω_k) V(ω_k)``.
    """
    v = wp.tid() + first
    n = normals[v]
    frame = orthonormal_basis(n)
    rng = wp.rand_init(seed, v)
    weight = wp.pi / float(strata * strata)
    eps = ray_eps(offset, points[v])
    near = near_faces(mesh, v, points[v], n, eps)
    for i in range(order * order):
        transfer[v, i] = 0.0
    for sx in range(strata):
        for sy in range(strata):
            u = (float(sx) + wp.randf(rng)) / float(strata)
            w = (float(sy) + wp.randf(rng)) / float(strata)
            d = cosine_direction(frame, u, w)
            if trace_surface_ray(mesh, v, points[v], n, d, eps, max_t, near).face < 0:
                sh_accumulate(d, weight, order, k, transfer, v)
