"""Warp kernels for exit radiance (orchestration and NumPy reference in :mod:`warpshade.radiance`)."""

from __future__ import annotations

import warp as wp


@wp.kernel
def shade_vertices(
    transfer: wp.array2d[float],
    light: wp.array[wp.vec3],
    local_light: wp.array2d[wp.vec3],
    albedo: wp.array[wp.vec3],
    clamp: int,
    radiance: wp.array[wp.vec3],
):
    """``radiance[v] = albedo[v]/π ⊙ Σ_i T[v,i] (L_i + L_local[v,i])`` (docs/conventions.md §2), clamped
    at 0 per channel when ``clamp`` is non-zero (truncated SH ring slightly negative behind lights).

    ``local_light`` has 0 rows when no light is local; ``albedo`` has 1 row (shared) or V rows.
    """
    v = wp.tid()
    n = transfer.shape[1]
    acc = wp.vec3(0.0, 0.0, 0.0)
    has_local = local_light.shape[0] > 0
    for i in range(n):
        li = light[i]
        if has_local:
            li = li + local_light[v, i]
        acc = acc + transfer[v, i] * li
    a = albedo[0]
    if albedo.shape[0] > 1:
        a = albedo[v]
    r = wp.cw_mul(a, acc) * (1.0 / wp.pi)
    if clamp != 0:
        r = wp.vec3(wp.max(r[0], 0.0), wp.max(r[1], 0.0), wp.max(r[2], 0.0))
    radiance[v] = r
