"""Warp functions of plane geometry shared by lights and visibility: convex polygon clipping."""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

MAX_POLY = 10  # a triangle clipped by six planes has at most 9 vertices
mat63 = wp.types.matrix(shape=(MAX_POLY, 3), dtype=float)


@wp.func
def clip_polygon(poly: mat63, n: int, plane: wp.vec3, offset: float, origin: wp.vec3):
    """Sutherland–Hodgman: keep the part of polygon ``poly[:n]`` where ``dot(X - origin, plane) >= offset``.

    Returns the clipped polygon and its vertex count (0 when nothing remains).
    """
    out = mat63()
    m = int(0)
    for i in range(n):
        a = poly[i]
        b = poly[(i + 1) % n]
        da = wp.dot(a - origin, plane) - offset
        db = wp.dot(b - origin, plane) - offset
        if da >= 0.0:
            out[m] = a
            m += 1
        if (da >= 0.0) != (db >= 0.0):
            # da and db have opposite signs here, so the denominator is never zero
            out[m] = a + (b - a) * (da / (da - db))
            m += 1
    return out, m
