"""Warp ``@wp.func``s for the real SH basis of :mod:`warpshade.sh.basis` (convention stated there).

Order is a runtime argument (1..:data:`~warpshade.sh.basis.MAX_ORDER`); the normalisation constants
come in as an array made by :func:`normalization_array` so one compiled function serves all orders.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .basis import normalization


def normalization_array(order: int, device: str = "cpu") -> wp.array:
    """Normalisation constants for :func:`sh_accumulate`, shape (order*order,), dtype float32."""
    return wp.array(normalization(order).astype(np.float32), dtype=float, device=device)


@wp.func
def sh_accumulate(
    d: wp.vec3,
    weight: float,
    order: int,
    k: wp.array[float],
    out: wp.array2d[float],
    row: int,
):
    """Add ``weight * y_i(d)`` to ``out[row, i]`` for all ``i < order*order``.

    Cartesian recurrences (thesis eqs. A.1–A.3 without the ``sin^m`` factor), so the poles are exact.
    ``d`` is normalised here; a zero vector contributes nothing.
    """
    len_d = wp.length(d)
    if len_d == 0.0:
        return
    n = d / len_d
    x = n[0]
    y = n[1]
    z = n[2]
    c = float(1.0)
    s = float(0.0)
    pmm = float(1.0)
    for m in range(order):
        if m > 0:
            c_new = c * x - s * y
            s = c * y + s * x
            c = c_new
            pmm = pmm * (-float(2 * m - 1))
        q2 = float(0.0)
        q1 = float(0.0)
        for l in range(m, order):
            q = pmm
            if l == m + 1:
                q = z * float(2 * m + 1) * pmm
            elif l > m + 1:
                q = (float(2 * l - 1) * z * q1 - float(l + m - 1) * q2) / float(l - m)
            q2 = q1
            q1 = q
            base = l * (l + 1)
            if m == 0:
                out[row, base] = out[row, base] + weight * k[base] * q
            else:
                out[row, base + m] = out[row, base + m] + weight * k[base + m] * q * c
                out[row, base - m] = out[row, base - m] + weight * k[base - m] * q * s
