"""Warp kernels for lights evaluated per receiver (orchestration in :mod:`warpshade.lighting.lights`)."""

from __future__ import annotations

import warp as wp

from ..sh.kernels import sh_accumulate
from ..geometry.kernels import clip_polygon, mat63


@wp.func
def rect_tiles(x: wp.vec3, center: wp.vec3, u: wp.vec3, v: wp.vec3, half_max: float, max_tiles: int):
    """Tiles per axis for a receiver at ``x``: ``ceil(half_max / distance to the rectangle)``,
    clamped to ``1..max_tiles``, so each tile's half-size stays below the receiver distance (where
    the per-tile Gauss–Legendre rule is accurate)."""
    rel = x - center
    s = wp.clamp(wp.dot(rel, u) / wp.dot(u, u), -1.0, 1.0)
    t = wp.clamp(wp.dot(rel, v) / wp.dot(v, v), -1.0, 1.0)
    dist = wp.length(center + s * u + t * v - x)
    if dist * float(max_tiles) <= half_max:
        return max_tiles
    return wp.clamp(int(wp.ceil(half_max / dist)), 1, max_tiles)


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
    half_max: float,
    max_tiles: int,
    order: int,
    k: wp.array[float],
    out: wp.array2d[float],
):
    """``out[p, i] = ∫_rect y_i(ω_q) cos θ_q / |q − p|² dA`` by the tensor Gauss–Legendre rule
    ``nodes`` (in [-1, 1]², q = center + s u + t v) and ``weights`` (area elements, summing to the
    area), applied on each of ``T × T`` tiles (:func:`rect_tiles`).

    ``out`` must be zeroed; shape (P, order*order).
    """
    p = wp.tid()
    x = points[p]
    tiles = rect_tiles(x, center, u, v, half_max, max_tiles)
    inv = 1.0 / float(tiles)
    for a in range(tiles):
        for b in range(tiles):
            sc = -1.0 + float(2 * a + 1) * inv
            tc = -1.0 + float(2 * b + 1) * inv
            for j in range(nodes.shape[0]):
                st = nodes[j]
                d = center + (sc + st[0] * inv) * u + (tc + st[1] * inv) * v - x
                r2 = wp.dot(d, d)
                if r2 > 0.0:
                    cos_e = -wp.dot(d, emit_normal) / wp.sqrt(r2)
                    if two_sided != 0:
                        cos_e = wp.abs(cos_e)
                    if cos_e > 0.0:
                        # solid angle of the sample: dA cos θ / r² (the receiver cosine is in the transfer)
                        sh_accumulate(d, weights[j] * inv * inv * cos_e / r2, order, k, out, p)


@wp.func
def rect_projected_solid_angle(x: wp.vec3, n: wp.vec3, center: wp.vec3, u: wp.vec3, v: wp.vec3) -> float:
    """Projected solid angle ``∫ max(0, n·ω) dω`` of the rectangle ``center ± u ± v`` seen from ``x``.

    Lambert's formula for a polygon, ``Φ = ½ |Σ_e θ_e (n · ĝ_e)|`` (``θ_e``: angle subtended by edge
    e, ``ĝ_e``: unit normal of the plane through ``x`` and the edge), on the part of the rectangle
    above the receiver's tangent plane (clipped, so the formula's clamped cosine holds). The edge
    angle is ``atan2(|a × b|, a · b)``, accurate for short edges where ``acos`` is not.
    """
    poly = mat63()
    poly[0] = center - u - v
    poly[1] = center + u - v
    poly[2] = center + u + v
    poly[3] = center - u + v
    clipped, m = clip_polygon(poly, 4, n, 0.0, x)
    total = float(0.0)
    for i in range(m):
        a = clipped[i] - x
        b = clipped[(i + 1) % m] - x
        g = wp.cross(a, b)
        lg = wp.length(g)
        if lg > 0.0:
            total += wp.atan2(lg, wp.dot(a, b)) * wp.dot(n, g) / lg
    return 0.5 * wp.abs(total)


@wp.kernel
def integrate_rect_irradiance(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    center: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    emit_normal: wp.vec3,
    two_sided: int,
    out: wp.array[float],
):
    """``out[p]`` = projected solid angle of the emitting rectangle from ``points[p]`` with unit normal
    ``normals[p]`` (:func:`rect_projected_solid_angle`); irradiance is this times the radiance.

    A one-sided light (``two_sided = 0``) gives 0 to receivers behind its emitting side
    (``(x − c)·emit_normal <= 0``). Shape (P,).
    """
    p = wp.tid()
    x = points[p]
    out[p] = 0.0
    if two_sided == 0 and wp.dot(x - center, emit_normal) <= 0.0:
        return
    out[p] = rect_projected_solid_angle(x, normals[p], center, u, v)
