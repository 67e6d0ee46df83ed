"""SH triple products (thesis §3.1.3): the Gaunt tensor, truncated products and product matrices.

``Gamma_ijk = int_S y_i y_j y_k ds`` (eq. 3.20), basis and convention of :mod:`warpshade.sh.basis`.

How the tensor is computed: by quadrature that is exact for the integrand. ``y_i y_j y_k`` is a
polynomial of degree ``L = l_i + l_j + l_k`` on the sphere; Gauss–Legendre in ``cos theta`` with
``floor(L/2) + 1`` nodes and ``L + 1`` uniform nodes in ``phi`` integrate it exactly, so the only
error is float64 rounding (~1e-16, checked against the closed-form Wigner-3j values in the tests).
Using :func:`~warpshade.sh.basis.sh_eval` itself makes the tensor follow the basis convention by
construction. Entries below 1e-13 in magnitude (rounding noise where the selection rules give
exact zeros) are dropped; what remains is exactly the set allowed by the selection rules.

Products (eq. 3.19) are truncated to the requested output order: ``(f * g)_i = sum_jk Gamma_ijk f_j g_k``
for ``i < order_out**2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .basis import sh_eval
from .projection import sphere_quadrature

_DROP = 1e-13


def order_of(n: int, what: str) -> int:
    """SH order ``N`` of ``n = N*N`` coefficients.

    Raises:
        ValueError: ``n`` is not a positive square (the message names ``what``).
    """
    order = math.isqrt(n)
    if order * order != n or order < 1:
        raise ValueError(f"{what} must have a square number of SH coefficients on its last axis, got {n}")
    return order


@dataclass(frozen=True, eq=False)
class GauntTensor:
    """Sparse SH triple-product tensor ``Gamma_ijk`` (eq. 3.20) for ``i < n_out, j < n_f, k < n_g``.

    Attributes:
        order_out: order of the product (truncation), ``n_out = order_out**2``.
        order_f: order of the first factor.
        order_g: order of the second factor.
        i: output indices, shape (nnz,), dtype int32, sorted (then by j, k).
        j: first-factor indices, shape (nnz,), dtype int32.
        k: second-factor indices, shape (nnz,), dtype int32.
        value: ``Gamma_ijk``, shape (nnz,), dtype float64.
    """

    order_out: int
    order_f: int
    order_g: int
    i: np.ndarray
    j: np.ndarray
    k: np.ndarray
    value: np.ndarray

    @property
    def nnz(self) -> int:
        """Number of stored non-zeros."""
        return int(self.value.size)

    def dense(self) -> np.ndarray:
        """Dense tensor, shape (order_out**2, order_f**2, order_g**2), dtype float64."""
        out = np.zeros((self.order_out**2, self.order_f**2, self.order_g**2))
        out[self.i, self.j, self.k] = self.value
        return out

    @property
    def matrix(self) -> sp.csr_matrix:
        """``Gamma`` as a sparse matrix of shape (order_out**2, order_f**2 * order_g**2), row i, column j*n_g + k."""
        return _csr(self)


@lru_cache(maxsize=None)
def _csr(t: GauntTensor) -> sp.csr_matrix:
    ng = t.order_g**2
    return sp.csr_matrix((t.value, (t.i, t.j.astype(np.int64) * ng + t.k)),
                         shape=(t.order_out**2, t.order_f**2 * ng))


@lru_cache(maxsize=None)
def gaunt_tensor(order: int, order_f: int | None = None, order_g: int | None = None) -> GauntTensor:
    """The sparse Gaunt tensor for products of an order-``order_f`` and an order-``order_g`` vector truncated to ``order``.

    Computed once per argument triple by exact quadrature (module docstring) and cached.

    Args:
        order: output order (bands kept in the product).
        order_f: order of the first factor (default ``order``).
        order_g: order of the second factor (default ``order_f``).
    """
    order_f = order if order_f is None else order_f
    order_g = order_f if order_g is None else order_g
    for name, o in (("order", order), ("order_f", order_f), ("order_g", order_g)):
        if int(o) != o or o < 1:
            raise ValueError(f"gaunt_tensor: {name} must be a positive integer, got {o!r}")
    degree = (order - 1) + (order_f - 1) + (order_g - 1)
    dirs, w = sphere_quadrature(degree // 2 + 1, degree + 1)
    yo = sh_eval(dirs, order) * w[:, None]
    yf = sh_eval(dirs, order_f)
    yg = sh_eval(dirs, order_g)
    rows_i, rows_j, rows_k, vals = [], [], [], []
    for i in range(order * order):
        block = np.einsum("q,qj,qk->jk", yo[:, i], yf, yg)
        j, k = np.nonzero(np.abs(block) > _DROP)
        rows_i.append(np.full(j.size, i))
        rows_j.append(j)
        rows_k.append(k)
        vals.append(block[j, k])
    return GauntTensor(order, order_f, order_g, np.concatenate(rows_i).astype(np.int32),
                       np.concatenate(rows_j).astype(np.int32), np.concatenate(rows_k).astype(np.int32),
                       np.concatenate(vals))


def sh_product(f, g, order: int | None = None) -> np.ndarray:
    """Truncated SH product ``f * g`` (thesis eq. 3.19): projection of ``f~ g~`` onto the first ``order`` bands.

    Args:
        f: SH vectors, shape (..., nf), nf a square.
        g: SH vectors, shape (..., ng), broadcastable against ``f``'s leading shape.
        order: output order (default: the larger input order).

    Returns:
        Shape (..., order**2), dtype float64.
    """
    f = np.asarray(f, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    of = order_of(f.shape[-1], "f")
    og = order_of(g.shape[-1], "g")
    order = max(of, og) if order is None else order
    t = gaunt_tensor(order, of, og)
    lead = np.broadcast_shapes(f.shape[:-1], g.shape[:-1])
    f = np.broadcast_to(f, lead + f.shape[-1:]).reshape(-1, f.shape[-1])
    g = np.broadcast_to(g, lead + g.shape[-1:]).reshape(-1, g.shape[-1])
    outer = (f[:, :, None] * g[:, None, :]).reshape(f.shape[0], -1)
    out = (t.matrix @ outer.T).T
    return np.asarray(out).reshape(lead + (order * order,))


def product_matrix(f, order: int | None = None) -> np.ndarray:
    """SH product matrix ``M_f`` with ``M_f g = f * g`` (thesis eqs. 3.21–3.22), symmetric.

    Args:
        f: SH vectors, shape (..., nf), nf a square.
        order: order of ``g`` and of the product (default: ``f``'s order).

    Returns:
        ``(M_f)_ij = sum_k f_k Gamma_ijk``, shape (..., order**2, order**2), dtype float64.
    """
    f = np.asarray(f, dtype=np.float64)
    of = order_of(f.shape[-1], "f")
    order = of if order is None else order
    t = gaunt_tensor(order, order, of)
    n = order * order
    flat = f.reshape(-1, f.shape[-1])
    # Column (i*n + j) of the (n*n, nf) matrix holds Gamma_ijk over k.
    m = sp.csr_matrix((t.value, (t.i.astype(np.int64) * n + t.j, t.k)), shape=(n * n, of * of))
    out = np.asarray((m @ flat.T).T)
    return out.reshape(f.shape[:-1] + (n, n))


def sh_square(f, order: int | None = None) -> np.ndarray:
    """``f * f`` truncated to ``order`` (default ``f``'s order), shape (..., order**2)."""
    return sh_product(f, f, order)


@dataclass(frozen=True, eq=False)
class SymmetricProductTable:
    """Gaunt entries with ``j <= k`` for branch-free products ``c_i += v (a_j b_k + a_k b_j)``.

    Diagonal entries (``j == k``) store ``Gamma_ijj / 2`` so the same update counts them once.
    Entries are sorted by ``i``. This is what the Warp product functions read
    (:func:`warpshade.sh.kernels.product_table_arrays`).

    Attributes:
        order: order of both factors and of the product.
        i, j, k: indices, shape (nnz,), dtype int32.
        value: weights, shape (nnz,), dtype float64.
    """

    order: int
    i: np.ndarray
    j: np.ndarray
    k: np.ndarray
    value: np.ndarray


@lru_cache(maxsize=None)
def symmetric_product_table(order: int) -> SymmetricProductTable:
    """The ``j <= k`` half of :func:`gaunt_tensor` ``(order, order, order)`` (cached)."""
    t = gaunt_tensor(order, order, order)
    keep = t.j <= t.k
    v = np.where(t.j[keep] == t.k[keep], 0.5, 1.0) * t.value[keep]
    return SymmetricProductTable(order, t.i[keep], t.j[keep], t.k[keep], v)
