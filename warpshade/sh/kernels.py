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


def zh_normalization_array(order: int, device: str = "cpu") -> wp.array:
    """``K_lm * sqrt(4 pi / (2l+1))`` per SH index for :func:`zh_rotate_accumulate`, shape (order*order,), float32.

    Folding the eq. 3.17 band factor into the basis constants makes ZH rotation cost the same as
    one basis evaluation.
    """
    from .zonal import zh_band_factors, zh_expand_index

    k = normalization(order) * zh_band_factors(order)[zh_expand_index(order)]
    return wp.array(k.astype(np.float32), dtype=float, device=device)


@wp.func
def zh_lerp_rotate_accumulate(
    d: wp.vec3,
    zh: wp.array2d[float],
    zh_row_a: int,
    zh_row_b: int,
    t: float,
    weight: float,
    order: int,
    kz: wp.array[float],
    out: wp.array2d[float],
    row: int,
):
    """Add ``weight * zh_rotate(lerp(zh[a], zh[b], t), d)`` to ``out[row, :order*order]`` (thesis eq. 3.17).

    Interpolating two rows of a ZH table (e.g. a table by blocker angular radius) inside the
    rotation costs no more than rotating one row. ``kz`` comes from :func:`zh_normalization_array`.
    ``d`` is normalised here; a zero axis contributes nothing. Same recurrences as
    :func:`sh_accumulate` (exact at the poles).
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
            g = weight * ((1.0 - t) * zh[zh_row_a, l] + t * zh[zh_row_b, l])
            base = l * (l + 1)
            if m == 0:
                out[row, base] = out[row, base] + g * kz[base] * q
            else:
                out[row, base + m] = out[row, base + m] + g * kz[base + m] * q * c
                out[row, base - m] = out[row, base - m] + g * kz[base - m] * q * s


@wp.func
def zh_rotate_accumulate(
    d: wp.vec3,
    zh: wp.array2d[float],
    zh_row: int,
    weight: float,
    order: int,
    kz: wp.array[float],
    out: wp.array2d[float],
    row: int,
):
    """Add ``weight * zh_rotate(zh[zh_row], d)`` to ``out[row, :order*order]`` (thesis eq. 3.17).

    ``zh`` has shape (rows, >= order); ``kz`` comes from :func:`zh_normalization_array`.
    """
    zh_lerp_rotate_accumulate(d, zh, zh_row, zh_row, 0.0, weight, order, kz, out, row)


@wp.struct
class SHProductTable:
    """Sparse symmetric Gaunt table on the device (:class:`~warpshade.sh.products.SymmetricProductTable`).

    ``c_i += v (a_j b_k + a_k b_j)`` over all entries computes the truncated product ``a * b``
    (thesis eq. 3.19); diagonal entries hold ``Gamma_ijj / 2``. Sorted by ``i``.
    """

    i: wp.array[wp.int32]
    """Output index per entry, shape (nnz,), dtype int32."""
    j: wp.array[wp.int32]
    """First factor index (j <= k), shape (nnz,), dtype int32."""
    k: wp.array[wp.int32]
    """Second factor index, shape (nnz,), dtype int32."""
    v: wp.array[float]
    """Weight, shape (nnz,), dtype float32."""


def product_table_arrays(order: int, device: str = "cpu") -> SHProductTable:
    """Upload :func:`~warpshade.sh.products.symmetric_product_table` for ``order`` to ``device``."""
    from .products import symmetric_product_table

    t = symmetric_product_table(order)
    s = SHProductTable()
    s.i = wp.array(t.i, dtype=wp.int32, device=device)
    s.j = wp.array(t.j, dtype=wp.int32, device=device)
    s.k = wp.array(t.k, dtype=wp.int32, device=device)
    s.v = wp.array(t.value.astype(np.float32), dtype=float, device=device)
    return s


@wp.func
def sh_product_rows(
    a: wp.array2d[float],
    a_row: int,
    b: wp.array2d[float],
    b_row: int,
    n: int,
    table: SHProductTable,
    out: wp.array2d[float],
    out_row: int,
):
    """``out[out_row, :n] = a[a_row] * b[b_row]``, the truncated SH product (thesis eq. 3.19).

    ``n`` is ``order*order`` of the table. ``out`` must not alias either input row. Entries are
    sorted by output index, so each output is summed in a register and written once.
    """
    for i in range(n):
        out[out_row, i] = 0.0
    nnz = table.v.shape[0]
    if nnz == 0:
        return
    cur = table.i[0]
    acc = float(0.0)
    for e in range(nnz):
        i = table.i[e]
        if i != cur:
            out[out_row, cur] = acc
            acc = 0.0
            cur = i
        j = table.j[e]
        k = table.k[e]
        acc = acc + table.v[e] * (a[a_row, j] * b[b_row, k] + a[a_row, k] * b[b_row, j])
    out[out_row, cur] = acc


@wp.kernel
def multiply_sh(
    a: wp.array2d[float],
    b: wp.array2d[float],
    n: int,
    table: SHProductTable,
    out: wp.array2d[float],
):
    """Row-wise truncated SH products ``out[v] = a[v] * b[v]``, shapes (V, n), float32."""
    v = wp.tid()
    sh_product_rows(a, v, b, v, n, table, out, v)
