"""SH rotation matrices for any order (thesis §3.1.2, eqs. 3.13–3.15), basis of :mod:`warpshade.sh.basis`.

Semantics: for a 3x3 rotation ``R`` the matrix ``M = rotation_matrix(R, order)`` maps the coefficients
of ``f`` to those of the rotated function ``f'(s) = f(R^T s)`` (a lobe pointing along ``d`` ends up
pointing along ``R d``), so ``zh_rotate(g, R @ e_z) == M @ zh_to_sh(g)``. ``M`` is block diagonal
(band ``l`` is a (2l+1)x(2l+1) orthogonal block) and ``M(R1 R2) = M(R1) M(R2)``.

Method: the Ivanic–Ruedenberg recurrences (J. Phys. Chem. 1996, 100, 6342; erratum 1998, 102,
9099), which build band ``l`` from band ``l-1`` and band 1 with only products and square roots of
small integers; they are stable (the matrix stays orthogonal to 6e-15 at order 24, measured). They are
written for real SH without the Condon–Shortley phase; warpshade's basis differs by
``(-1)^m`` on ``m != 0`` (docs/conventions.md §1), so each block is conjugated by that diagonal sign
matrix, which is its own inverse.
"""

from __future__ import annotations

import math

import numpy as np


def check_rotation(r, what: str | None = None) -> np.ndarray:
    """``r`` as a float64 (3, 3) proper rotation (finite, orthonormal to 1e-6, det +1).

    Raises:
        ValueError: naming the shape, the orthonormality error or the determinant, after ``what: `` when given.
    """
    prefix = f"{what}: " if what else ""
    r = np.asarray(r, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"{prefix}rotation must be a finite 3x3 matrix, got shape {r.shape}")
    err = np.abs(r @ r.T - np.eye(3)).max()
    if err > 1e-6 or np.linalg.det(r) < 0:
        raise ValueError(f"{prefix}rotation must be orthonormal with det +1 (|R R^T - I| = {err:.2e}, "
                         f"det = {np.linalg.det(r):.3f})")
    return r


def _band_blocks(r: np.ndarray, order: int) -> list[np.ndarray]:
    """Ivanic–Ruedenberg blocks (no Condon–Shortley phase), ``blocks[l][m + l, n + l]``."""
    blocks = [np.ones((1, 1))]
    if order == 1:
        return blocks
    # Band 1 in the order (m = -1, 0, 1) ~ (y, z, x).
    perm = [1, 2, 0]
    r1 = r[np.ix_(perm, perm)]
    blocks.append(r1)

    def rr(i, j):  # R^1 indexed by m in {-1, 0, 1}
        return r1[i + 1, j + 1]

    for l in range(2, order):
        prev = blocks[l - 1]

        def mp(a, b):  # M^{l-1}[a][b], |a|, |b| <= l - 1
            return prev[a + l - 1, b + l - 1]

        def p(i, a, b):
            if b == l:
                return rr(i, 1) * mp(a, l - 1) - rr(i, -1) * mp(a, -l + 1)
            if b == -l:
                return rr(i, 1) * mp(a, -l + 1) + rr(i, -1) * mp(a, l - 1)
            return rr(i, 0) * mp(a, b)

        cur = np.zeros((2 * l + 1, 2 * l + 1))
        for m in range(-l, l + 1):
            am = abs(m)
            d = 1.0 if m == 0 else 0.0
            for n in range(-l, l + 1):
                den = (l + n) * (l - n) if abs(n) < l else (2 * l) * (2 * l - 1)
                u = math.sqrt((l + m) * (l - m) / den)
                v = 0.5 * math.sqrt((1 + d) * (l + am - 1) * (l + am) / den) * (1 - 2 * d)
                w = -0.5 * math.sqrt((l - am - 1) * (l - am) / den) * (1 - d)
                val = 0.0
                if u != 0.0:
                    val += u * p(0, m, n)
                if v != 0.0:
                    if m == 0:
                        vv = p(1, 1, n) + p(-1, -1, n)
                    elif m > 0:
                        d1 = 1.0 if m == 1 else 0.0
                        vv = p(1, m - 1, n) * math.sqrt(1 + d1) - p(-1, -m + 1, n) * (1 - d1)
                    else:
                        d1 = 1.0 if m == -1 else 0.0
                        vv = p(1, m + 1, n) * (1 - d1) + p(-1, -m - 1, n) * math.sqrt(1 + d1)
                    val += v * vv
                if w != 0.0:
                    if m > 0:
                        ww = p(1, m + 1, n) + p(-1, -m - 1, n)
                    else:
                        ww = p(1, m - 1, n) - p(-1, -m + 1, n)
                    val += w * ww
                cur[m + l, n + l] = val
        blocks.append(cur)
    return blocks


def rotation_blocks(r, order: int) -> list[np.ndarray]:
    """Per-band rotation blocks in warpshade's convention: ``blocks[l]`` has shape (2l+1, 2l+1), float64."""
    if int(order) != order or order < 1:
        raise ValueError(f"SH order must be a positive integer, got {order!r}")
    r = check_rotation(r)
    out = []
    for l, b in enumerate(_band_blocks(r, int(order))):
        s = np.where(np.arange(-l, l + 1) % 2 == 0, 1.0, -1.0)  # (-1)^m: Condon–Shortley phase
        out.append(s[:, None] * b * s[None, :])
    return out


def rotation_matrix(r, order: int) -> np.ndarray:
    """The (order², order²) block-diagonal SH rotation matrix of the 3x3 rotation ``r`` (module docstring).

    Args:
        r: rotation matrix, shape (3, 3), orthonormal with det +1 (checked to 1e-6).
        order: SH order, any positive integer.

    Returns:
        Shape (order*order, order*order), dtype float64, orthogonal.

    Raises:
        ValueError: if ``r`` is not a rotation.
    """
    n = int(order) ** 2
    out = np.zeros((n, n))
    for l, b in enumerate(rotation_blocks(r, order)):
        out[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2] = b
    return out


def rotate(coeffs, r, axis: int = -1) -> np.ndarray:
    """Rotate SH vectors by the 3x3 rotation ``r`` (``f'(s) = f(r^T s)``), band by band.

    Args:
        coeffs: SH coefficients with the SH index on ``axis``, e.g. (..., n²) or RGB lighting (n², 3)
            with ``axis=0``.
        r: rotation matrix, shape (3, 3).
        axis: the axis holding the n² coefficients.

    Returns:
        Same shape as ``coeffs``, dtype float64.
    """
    c = np.moveaxis(np.asarray(coeffs, dtype=np.float64), axis, -1)
    order = math.isqrt(c.shape[-1])
    if order * order != c.shape[-1] or order < 1:
        raise ValueError(f"rotate: axis {axis} must hold a square number of SH coefficients, got {c.shape[-1]}")
    out = np.empty_like(c)
    for l, b in enumerate(rotation_blocks(r, order)):
        sl = slice(l * l, (l + 1) ** 2)
        out[..., sl] = c[..., sl] @ b.T
    return np.moveaxis(out, -1, axis)


def rotation_from_axis_angle(axis, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix for a unit ``axis`` (normalised here) and ``angle`` [rad], shape (3, 3)."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if not n > 0:
        raise ValueError("rotation axis must be non-zero")
    x, y, z = a / n
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)
