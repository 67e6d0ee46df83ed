"""Real spherical-harmonic basis: the single place where warpshade's SH convention is defined.

Convention (docs/conventions.md §1, thesis appendix A, Green 2003, Sloan's generated code):

* real, orthonormal SH on the unit sphere;
* order ``n`` means bands ``l = 0..n-1`` and ``n*n`` coefficients, index ``i = l*(l+1) + m``;
* with ``Y_l^m`` the complex SH including the Condon–Shortley phase,
  ``y_lm = sqrt(2) Re Y_l^m`` (m > 0), ``y_l0 = Y_l^0``, ``y_lm = sqrt(2) Im Y_l^|m|`` (m < 0);
  so ``y_1 = -0.488603 y``, ``y_2 = 0.488603 z``, ``y_3 = -0.488603 x``.

Every other module refers here instead of restating the convention.

Evaluation works in Cartesian form: ``P_l^m(z) = sin^m(theta) Q_l^m(z)`` and
``sin^m(theta) e^{i m phi} = (x + i y)^m``, so nothing divides by ``sin(theta)`` and the poles are
as accurate as anywhere else (thesis eqs. A.1–A.3 applied to ``Q``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

MAX_ORDER = 8
"""Highest SH order the Warp kernels are built for (bands 0..7, 64 coefficients)."""


def n_coeffs(order: int) -> int:
    """Number of coefficients of an order-``order`` SH vector (``order**2``)."""
    return order * order


def sh_index(l: int, m: int) -> int:
    """Flat index of band ``l``, degree ``m`` (``l*(l+1) + m``)."""
    return l * (l + 1) + m


def check_order(order: int, max_order: int = MAX_ORDER) -> int:
    """Validate an SH order; returns it as int.

    Raises:
        ValueError: if ``order`` is not in ``1..max_order``.
    """
    if int(order) != order or not 1 <= order <= max_order:
        raise ValueError(f"SH order must be an integer in 1..{max_order}, got {order!r}")
    return int(order)


@lru_cache(maxsize=None)
def normalization(order: int) -> np.ndarray:
    """Normalisation constants ``K_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)``, times ``sqrt(2)`` for m != 0.

    Returns:
        Array of shape (order*order,), dtype float64, indexed like the SH vector (``|m|`` used).
    """
    k = np.zeros(order * order)
    for l in range(order):
        for m in range(-l, l + 1):
            am = abs(m)
            v = math.sqrt((2 * l + 1) / (4.0 * math.pi) * math.factorial(l - am) / math.factorial(l + am))
            k[sh_index(l, m)] = v * (math.sqrt(2.0) if m != 0 else 1.0)
    return k


def _normalize_dirs(dirs: np.ndarray) -> np.ndarray:
    d = np.asarray(dirs, dtype=np.float64)
    if d.shape[-1] != 3:
        raise ValueError(f"directions must have a last axis of length 3, got shape {d.shape}")
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    # A zero-length direction has no meaning; +z keeps the result finite and deterministic.
    safe = n > 0.0
    d = np.where(safe, d / np.where(safe, n, 1.0), np.array([0.0, 0.0, 1.0]))
    return d


def sh_eval(dirs, order: int) -> np.ndarray:
    """Evaluate the real SH basis (convention above) at directions, in float64.

    The NumPy oracle of the Warp recurrence (:class:`warpshade.sh.kernels.LegendreState`, the same
    eqs. A.1-A.3 in float32): tests compare the kernels against it, so it is kept as a separate,
    independent implementation rather than shared with them.

    Args:
        dirs: Directions, shape (..., 3), any length (normalised here; zero length reads as +z).
        order: SH order, 1..any (float64 recurrences stay accurate well past order 8).

    Returns:
        Basis values, shape (..., order*order), dtype float64.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"SH order must be a positive integer, got {order!r}")
    d = _normalize_dirs(dirs)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.zeros(d.shape[:-1] + (order * order,))
    k = normalization(order)
    # C_m + i S_m = (x + i y)^m
    c = np.ones_like(x)
    s = np.zeros_like(x)
    pmm = np.ones_like(z)  # Q_m^m = (-1)^m (2m-1)!!   (eq. A.2 without the sin^m factor)
    for m in range(order):
        if m > 0:
            c, s = c * x - s * y, c * y + s * x
            pmm = pmm * (-(2 * m - 1))
        q_prev2 = None
        q_prev = pmm
        for l in range(m, order):
            if l == m:
                q = pmm
            elif l == m + 1:
                q = z * (2 * m + 1) * pmm  # eq. A.3
            else:
                q = ((2 * l - 1) * z * q_prev - (l + m - 1) * q_prev2) / (l - m)  # eq. A.1
            if l > m:
                q_prev2, q_prev = q_prev, q
            if m == 0:
                out[..., sh_index(l, 0)] = k[sh_index(l, 0)] * q
            else:
                out[..., sh_index(l, m)] = k[sh_index(l, m)] * q * c
                out[..., sh_index(l, -m)] = k[sh_index(l, -m)] * q * s
    return out
