"""Zonal harmonics (ZH): lobes symmetric about +z, their coefficients and their rotation.

A ZH vector ``g`` of order ``n`` has ``n`` entries ``g_l``, the coefficients of ``y_l0``
(basis and convention: :mod:`warpshade.sh.basis`). Rotating the lobe from +z to a unit axis ``w``
gives the SH vector (thesis eq. 3.17, docs/conventions.md §1)::

    f_lm = sqrt(4 pi / (2l + 1)) * g_l * y_lm(w)

All functions here are float64 NumPy; the Warp counterpart of :func:`zh_rotate` is
:func:`warpshade.sh.kernels.zh_rotate_accumulate`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln

from .basis import sh_eval


def _check_positive_order(order) -> int:
    if int(order) != order or order < 1:
        raise ValueError(f"ZH order must be a positive integer, got {order!r}")
    return int(order)


def zh_band_factors(order: int) -> np.ndarray:
    """``sqrt(4 pi / (2l + 1))`` for ``l = 0..order-1``, shape (order,), dtype float64 (eq. 3.17)."""
    order = _check_positive_order(order)
    l = np.arange(order)
    return np.sqrt(4.0 * np.pi / (2 * l + 1))


def zh_expand_index(order: int) -> np.ndarray:
    """Band ``l`` of every SH index ``i < order*order``, shape (order*order,), dtype int64."""
    order = _check_positive_order(order)
    return np.repeat(np.arange(order), 2 * np.arange(order) + 1)


def zh_rotate(zh, axis) -> np.ndarray:
    """Rotate zonal lobes from +z to ``axis`` (thesis eq. 3.17).

    Args:
        zh: ZH coefficients, shape (..., order), any float dtype.
        axis: Lobe axes, shape (..., 3) broadcastable against ``zh``'s leading shape; normalised
            here (a zero axis reads as +z, like :func:`~warpshade.sh.basis.sh_eval`).

    Returns:
        SH coefficients in world space, shape (..., order*order), dtype float64.
    """
    g = np.asarray(zh, dtype=np.float64)
    if g.ndim < 1 or g.shape[-1] < 1:
        raise ValueError(f"zh must have shape (..., order) with order >= 1, got {g.shape}")
    order = g.shape[-1]
    y = sh_eval(axis, order)
    band = zh_expand_index(order)
    return (g * zh_band_factors(order))[..., band] * y


def zh_to_sh(zh) -> np.ndarray:
    """Embed ZH coefficients (..., order) into SH vectors (..., order*order) along +z (no rotation)."""
    g = np.asarray(zh, dtype=np.float64)
    order = g.shape[-1]
    out = np.zeros(g.shape[:-1] + (order * order,))
    l = np.arange(order)
    out[..., l * (l + 1)] = g
    return out


def sh_to_zh(f) -> np.ndarray:
    """The zonal (m = 0) coefficients of SH vectors (..., order*order) -> (..., order)."""
    f = np.asarray(f, dtype=np.float64)
    order = math.isqrt(f.shape[-1])
    if order * order != f.shape[-1]:
        raise ValueError(f"SH vectors must have a square length, got {f.shape[-1]}")
    l = np.arange(order)
    return f[..., l * (l + 1)]


def _power_cosine_moments(s: float, order: int) -> np.ndarray:
    """``int_0^1 z^s P_l(z) dz`` for l < order, s > -1 (closed form through Gamma functions).

    ``int_0^1 x^s P_l(x) dx = sqrt(pi) Gamma(s+1) / (2^(s+1) Gamma(1+(s-l)/2) Gamma((s+l+3)/2))``
    (Gradshteyn & Ryzhik 7.126.2). Log-Gamma keeps it finite for exponents in the thousands;
    ``1/Gamma`` at non-positive integers is exactly zero (integer ``s`` below ``l`` of equal parity).
    """
    out = np.zeros(order)
    for l in range(order):
        x = 1.0 + 0.5 * (s - l)
        base = 0.5 * math.log(math.pi) + gammaln(s + 1.0) - (s + 1.0) * math.log(2.0) - gammaln(0.5 * (s + l + 3))
        if x > 0:
            out[l] = math.exp(base - gammaln(x))
        else:
            if float(x).is_integer():
                continue
            # Reflection: 1/Gamma(x) = sin(pi x) Gamma(1-x) / pi.
            out[l] = math.exp(base + gammaln(1.0 - x)) * math.sin(math.pi * x) / math.pi
    return out


def clamped_cosine_zh(order: int) -> np.ndarray:
    """ZH coefficients of ``max(0, cos theta)`` (docs/conventions.md §2 ``A_l``), any order.

    ``A_0 = sqrt(pi)/2, A_1 = sqrt(pi/3), A_2 = sqrt(5 pi)/8, A_3 = 0, A_4 = -sqrt(pi)/16, ...``

    Returns:
        Shape (order,), dtype float64.
    """
    return phong_zh(1.0, order, normalize=False)


def unoccluded_transfer(normals, order: int) -> np.ndarray:
    """Transfer of an unshadowed vertex (docs/conventions.md §2): the clamped-cosine lobe
    (:func:`clamped_cosine_zh`) rotated to the normal, ``sqrt(4π/(2l+1)) A_l y_lm(n)``.

    Args:
        normals: Vertex normals, shape (..., 3) (normalised here).
        order: SH order N.

    Returns:
        Shape (..., N*N), dtype float64.
    """
    return zh_rotate(clamped_cosine_zh(order), normals)


def phong_zh(exponent: float, order: int, normalize: bool = True) -> np.ndarray:
    """ZH coefficients of the Phong lobe ``c * max(0, cos theta)^s`` about +z.

    Args:
        exponent: ``s >= 0`` (any real; ``s = 1`` is the clamped cosine, ``s = 0`` the hemisphere).
        order: number of bands.
        normalize: if True ``c = (s + 1) / (2 pi)`` so the lobe integrates to 1 over the sphere
            (then ``g_0 = 1/sqrt(4 pi)``); if False ``c = 1``.

    Returns:
        Shape (order,), dtype float64: ``g_l = 2 pi sqrt((2l+1)/(4 pi)) c int_0^1 z^s P_l(z) dz``.
    """
    order = _check_positive_order(order)
    s = float(exponent)
    if not math.isfinite(s) or s < 0:
        raise ValueError(f"Phong exponent must be finite and >= 0, got {exponent!r}")
    l = np.arange(order)
    g = 2.0 * np.pi * np.sqrt((2 * l + 1) / (4.0 * np.pi)) * _power_cosine_moments(s, order)
    if normalize:
        g *= (s + 1.0) / (2.0 * np.pi)
    return g


def cap_zh(angle, order: int) -> np.ndarray:
    """ZH coefficients of the indicator of a spherical cap of angular radius ``angle`` about +z.

    ``g_l = 2 pi sqrt((2l+1)/(4 pi)) int_{cos a}^1 P_l(z) dz``. The integral is
    ``(P_{l-1} - P_{l+1})(cos a) / (2l+1)``; it is evaluated through ``Q_l = 1 - P_l(cos a)``, whose
    three-term recurrence is driven by ``t = 1 - cos a = 2 sin^2(a/2)`` and has no cancellation, so
    caps of radius 1e-6 rad are as accurate (relative) as large ones.

    Args:
        angle: Angular radius [rad], shape (...,), in [0, pi].
        order: number of bands.

    Returns:
        Shape (..., order), dtype float64.
    """
    order = _check_positive_order(order)
    a = np.asarray(angle, dtype=np.float64)
    if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > np.pi):
        raise ValueError(f"cap angular radius must lie in [0, pi], got {angle!r}")
    t = 2.0 * np.sin(0.5 * a) ** 2
    x = 1.0 - t
    q = [np.zeros_like(a), t]  # Q_0, Q_1
    for l in range(1, order):
        # P_{l+1} = ((2l+1) x P_l - l P_{l-1}) / (l+1) rewritten for Q = 1 - P.
        q.append(((2 * l + 1) * t + (2 * l + 1) * x * q[l] - l * q[l - 1]) / (l + 1))
    out = np.empty(a.shape + (order,))
    out[..., 0] = 2.0 * np.pi * t / np.sqrt(4.0 * np.pi)
    for l in range(1, order):
        integral = (q[l + 1] - q[l - 1]) / (2 * l + 1)
        out[..., l] = 2.0 * np.pi * np.sqrt((2 * l + 1) / (4.0 * np.pi)) * integral
    return out


def sphere_visibility_zh(angle, order: int) -> np.ndarray:
    """ZH coefficients of a spherical blocker's visibility: 0 inside the cap of radius ``angle``, 1 outside.

    This is ``1 - cap`` (thesis §4.2, the blocker function ``B_theta`` before rotation).

    Args:
        angle: Angular radius of the blocker as seen from the receiver [rad], shape (...,), in [0, pi].
        order: number of bands.

    Returns:
        Shape (..., order), dtype float64.
    """
    out = -cap_zh(angle, order)
    out[..., 0] += np.sqrt(4.0 * np.pi)
    return out
