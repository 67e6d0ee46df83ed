"""Warp kernels for lights evaluated per receiver (orchestration in :mod:`warpshade.lighting.lights`)."""

from __future__ import annotations

import warp as wp

from ..sh.kernels import sh_accumulate


@wp.kernel
def integrate_rect_light(
    points: wp.array[wp.vec3],
    center: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    emit_normal: wp.vec3,
    two_sided: int,
    nodes: wp.array[wp.vec2],
    weights: wp.array[float],
    order: int,
    k: wp.array[float],
    out: wp.array2d[float],
):
    """``out[p, i] = ∫_rect y_i(ω_q) cos θ_q / |q − p|² dA`` by the tensor Gauss–Legendre rule
    ``nodes`` (in [-1, 1]², q = center + s u + t v) and ``weights`` (area elements, summing to the area).

    ``out`` must be zeroed; shape (P, order*order).
    """
    p = wp.tid()
    x = points[p]
    for j in range(nodes.shape[0]):
        st = nodes[j]
        d = center + st[0] * u + st[1] * v - x
        r2 = wp.dot(d, d)
        if r2 > 0.0:
            cos_e = -wp.dot(d, emit_normal) / wp.sqrt(r2)
            if two_sided != 0:
                cos_e = wp.abs(cos_e)
            if cos_e > 0.0:
                # solid angle of the sample: dA cos θ / r² (receiver-side cosine lives in the transfer)
                sh_accumulate(d, weights[j] * cos_e / r2, order, k, out, p)
