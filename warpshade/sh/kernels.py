"""Warp ``@wp.func``s and kernels of the SH core (convention: :mod:`warpshade.sh.basis`), float32.

* basis: :func:`sh_accumulate`;
* zonal rotation (thesis eq. 3.17): :func:`zh_rotate_accumulate`, :func:`zh_lerp_rotate_accumulate`
  (array rows, runtime order) and :func:`zh_vector_funcs` (fixed-order vector types in registers);
* products (eq. 3.19): :class:`SHProductTable` / :func:`product_table_arrays`, :func:`sh_product_rows`,
  kernel :func:`multiply_sh`;
* exponential (eqs. 3.30, 3.32): :class:`OLTableArrays` / :func:`ol_table_arrays`, :func:`sh_exp_ol`,
  :func:`sh_exp_hybrid`, kernels :func:`exponentiate_sh_ol`, :func:`exponentiate_sh_hybrid`, and the
  host helper :func:`sh_exp_warp`.

Order is a runtime argument (1..:data:`~warpshade.sh.basis.MAX_ORDER`) for the row-based functions;
constants and tables come in as arrays so one compiled function serves all orders. Each NumPy
reference lives beside its float64 API (:mod:`.zonal`, :mod:`.products`, :mod:`.exp`).
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

import numpy as np
import warp as wp

from .basis import normalization

# The kernels here are forward-only; skipping adjoint generation roughly halves their compile time.
wp.set_module_options({"enable_backward": False})


def normalization_array(order: int, device: str = "cpu") -> wp.array:
    """Normalisation constants for :func:`sh_accumulate`, shape (order*order,), dtype float32."""
    return wp.array(normalization(order).astype(np.float32), dtype=float, device=device)


@wp.struct
class LegendreState:
    """Running values of the Cartesian SH recurrences (thesis eqs. A.1-A.3 without the ``sin^m`` factor;
    the NumPy oracle is :func:`warpshade.sh.basis.sh_eval`) at one unit direction ``(x, y, z)``.

    :func:`legendre_start` sets it up, :func:`legendre_band` enters band ``m`` and
    :func:`legendre_degree` steps to degree ``l >= m`` of that band; then ``q * c`` (``m > 0``),
    ``q * s`` (``-m``) or ``q`` (``m = 0``) times ``K_lm`` is the basis function ``y_l^{+-m}``.
    The one Warp copy of the recurrence: every Warp basis evaluation walks ``m`` in ``0..order-1``
    and, inside, ``l`` in ``m..order-1`` through these functions.
    """

    x: float
    y: float
    z: float
    c: float
    """``C_m = Re (x + i y)^m``."""
    s: float
    """``S_m = Im (x + i y)^m``."""
    pmm: float
    """``Q_m^m = (-1)^m (2m-1)!!``."""
    q: float
    """``Q_l^m(z)`` of the current degree (0 before the band's first step)."""
    q_prev: float
    """``Q_{l-1}^m(z)`` (0 before the band's second step)."""


@wp.func
def legendre_state(x: float, y: float, z: float, c: float, s: float, pmm: float, q: float,
                   q_prev: float) -> LegendreState:
    """A :class:`LegendreState` with these fields (a fresh value: assigning a struct local aliases it)."""
    r = LegendreState()
    r.x = x
    r.y = y
    r.z = z
    r.c = c
    r.s = s
    r.pmm = pmm
    r.q = q
    r.q_prev = q_prev
    return r


@wp.func
def legendre_start(n: wp.vec3) -> LegendreState:
    """Recurrence state at the unit direction ``n``, before band 0."""
    return legendre_state(n[0], n[1], n[2], 1.0, 0.0, 1.0, 0.0, 0.0)


@wp.func
def legendre_band(st: LegendreState, m: int) -> LegendreState:
    """Enter band ``m`` (called for ``m = 0, 1, ...`` in turn): ``C_m``, ``S_m``, ``Q_m^m`` from band ``m-1``."""
    c = st.c
    s = st.s
    pmm = st.pmm
    if m > 0:
        c = st.c * st.x - st.s * st.y
        s = st.c * st.y + st.s * st.x
        pmm = st.pmm * (-float(2 * m - 1))
    return legendre_state(st.x, st.y, st.z, c, s, pmm, 0.0, 0.0)


@wp.func
def legendre_degree(st: LegendreState, l: int, m: int) -> LegendreState:
    """Step to degree ``l`` of band ``m`` (called for ``l = m, m+1, ...`` in turn): ``q = Q_l^m(z)``."""
    q = st.pmm
    if l == m + 1:
        q = st.z * float(2 * m + 1) * st.pmm
    elif l > m + 1:
        q = (float(2 * l - 1) * st.z * st.q - float(l + m - 1) * st.q_prev) / float(l - m)
    return legendre_state(st.x, st.y, st.z, st.c, st.s, st.pmm, q, st.q)


@wp.func
def sh_accumulate_banded(
    d: wp.vec3,
    zh: wp.array2d[float],
    zh_row_a: int,
    zh_row_b: int,
    t: float,
    use_bands: int,
    weight: float,
    order: int,
    k: wp.array[float],
    out: wp.array2d[float],
    row: int,
):
    """Add ``w_l * k[i] * Q_l^m(d) * (cos | sin)(m phi)`` to ``out[row, i]`` for all ``i < order*order``.

    ``w_l = weight`` when ``use_bands == 0`` (``zh`` is then not read), else
    ``weight * lerp(zh[zh_row_a, l], zh[zh_row_b, l], t)``. Cartesian recurrences (:class:`LegendreState`),
    so the poles are exact.
    ``d`` is normalised here; a zero vector contributes nothing.
    """
    len_d = wp.length(d)
    if len_d == 0.0:
        return
    r = legendre_start(d / len_d)
    for m in range(order):
        r = legendre_band(r, m)
        for l in range(m, order):
            r = legendre_degree(r, l, m)
            g = weight
            if use_bands != 0:
                g = weight * ((1.0 - t) * zh[zh_row_a, l] + t * zh[zh_row_b, l])
            base = l * (l + 1)
            if m == 0:
                out[row, base] = out[row, base] + g * k[base] * r.q
            else:
                out[row, base + m] = out[row, base + m] + g * k[base + m] * r.q * r.c
                out[row, base - m] = out[row, base - m] + g * k[base - m] * r.q * r.s


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
    sh_accumulate_banded(d, out, 0, 0, 0.0, 0, weight, order, k, out, row)


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
    ``d`` is normalised here; a zero axis contributes nothing (exact at the poles).
    """
    sh_accumulate_banded(d, zh, zh_row_a, zh_row_b, t, 1, weight, order, kz, out, row)


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
    sh_accumulate_banded(d, zh, zh_row, zh_row, 0.0, 1, weight, order, kz, out, row)


@functools.lru_cache(maxsize=None)
def zh_vector_funcs(order: int) -> SimpleNamespace:
    """Fixed-order vector types and a register-resident ZH rotation for ``order`` (built once, cached).

    Returns a namespace with:

    * ``vec_sh``: ``wp.types.vector(length=order*order, dtype=float32)`` — an SH vector;
    * ``vec_zh``: ``wp.types.vector(length=order, dtype=float32)`` — a ZH vector;
    * ``zh_rotate``: ``@wp.func (d: vec3, g: vec_zh, kz: vec_sh) -> vec_sh``, thesis eq. 3.17, with
      ``kz = zh_constants()`` (:func:`zh_normalization_array` as a ``vec_sh``); zero ``d`` gives zero;
    * ``zh_constants()``: that ``kz`` value to pass into kernels;
    * ``accumulate_lobes``: kernel ``(d (V, B) vec3, zh (B,) vec_zh, kz) -> out (V,) vec_sh`` summing
      lobe ``b`` rotated to ``d[v, b]`` for every vertex ``v`` (an example of use, and the benchmark).

    Rotated lobes accumulate in a ``vec_sh`` local (registers) instead of an array row as in
    :func:`zh_rotate_accumulate`, at the price of one compiled function per order (``benchmarks/sh_exp.py``
    compares them).
    """
    from .basis import check_order

    order = check_order(order)
    n_sh = order * order

    class vec_sh(wp.types.vector(length=n_sh, dtype=wp.float32)):
        pass

    class vec_zh(wp.types.vector(length=order, dtype=wp.float32)):
        pass

    bands = wp.constant(order)

    def zh_rotate(d: wp.vec3, g: vec_zh, kz: vec_sh) -> vec_sh:
        out = vec_sh()
        len_d = wp.length(d)
        if len_d == 0.0:
            return out
        r = legendre_start(d / len_d)
        for m in range(bands):
            r = legendre_band(r, m)
            for l in range(m, bands):
                r = legendre_degree(r, l, m)
                base = l * (l + 1)
                if m == 0:
                    out[base] = g[l] * kz[base] * r.q
                else:
                    out[base + m] = g[l] * kz[base + m] * r.q * r.c
                    out[base - m] = g[l] * kz[base - m] * r.q * r.s
        return out

    # This module uses postponed annotations; Warp needs the real (closure-local) types.
    zh_rotate.__annotations__ = {"d": wp.vec3, "g": vec_zh, "kz": vec_sh, "return": vec_sh}
    zh_rotate.__name__ = f"zh_rotate_order{order}"
    func = wp.func(zh_rotate)

    def zh_constants():
        return vec_sh(*zh_normalization_array(order).numpy().tolist())

    def accumulate_lobes(d: wp.array2d[wp.vec3], zh: wp.array[vec_zh], kz: vec_sh, out: wp.array[vec_sh]):
        v = wp.tid()
        acc = vec_sh()
        for b in range(d.shape[1]):
            acc = acc + func(d[v, b], zh[b], kz)
        out[v] = acc

    accumulate_lobes.__annotations__ = {"d": wp.array2d(dtype=wp.vec3), "zh": wp.array(dtype=vec_zh), "kz": vec_sh,
                                        "out": wp.array(dtype=vec_sh)}
    accumulate_lobes.__name__ = f"accumulate_lobes_order{order}"
    kernel = wp.kernel(accumulate_lobes, enable_backward=False)
    return SimpleNamespace(order=order, vec_sh=vec_sh, vec_zh=vec_zh, zh_rotate=func, zh_constants=zh_constants,
                           accumulate_lobes=kernel)


UNROLL_MAX_ORDER = 6
"""Highest order whose vector products are unrolled. Cold compile of the sphere-set kernels (both
products, several call sites) on a loaded 2-core machine: 21 s for orders 4 and 5 together, 37 s at
order 6, 125 s at order 8; above this order the products loop over the table instead."""


@functools.lru_cache(maxsize=None)
def sh_product_vector_funcs(order: int) -> SimpleNamespace:
    """Truncated SH product and square on the ``vec_sh`` of :func:`zh_vector_funcs` (built once, cached).

    Returns a namespace with ``vec_sh`` and two ``@wp.func``s:

    * ``product(a: vec_sh, b: vec_sh, table: SHProductTable) -> vec_sh``: ``a * b`` (thesis eq. 3.19);
    * ``square(a: vec_sh, table: SHProductTable) -> vec_sh``: ``a * a`` with one multiply per symmetric
      entry (``c_i = sum 2 v a_j a_k`` over :func:`~warpshade.sh.products.symmetric_product_table`,
      whose diagonal entries hold ``Gamma_ijj / 2``).

    ``table`` is :func:`product_table_arrays` of the same order. Up to :data:`UNROLL_MAX_ORDER` the
    Gaunt coefficients are written into generated source as float32 literals and ``table`` is not
    read, so the compiler keeps the operands in registers (the sphere-set kernels use them; docs/methods/sh-core.md). The
    generated source is registered with ``linecache`` so Warp can parse it. Above that order the
    functions loop over ``table`` (compile time).
    """
    import linecache

    from .products import symmetric_product_table

    zf = zh_vector_funcs(order)
    vec_sh = zf.vec_sh
    if order > UNROLL_MAX_ORDER:

        def product(a: vec_sh, b: vec_sh, table: SHProductTable) -> vec_sh:
            out = vec_sh()
            for e in range(table.v.shape[0]):
                i = table.i[e]
                j = table.j[e]
                k = table.k[e]
                out[i] = out[i] + table.v[e] * (a[j] * b[k] + a[k] * b[j])
            return out

        def square(a: vec_sh, table: SHProductTable) -> vec_sh:
            out = vec_sh()
            for e in range(table.v.shape[0]):
                i = table.i[e]
                out[i] = out[i] + 2.0 * table.v[e] * (a[table.j[e]] * a[table.k[e]])
            return out

        # This module uses postponed annotations; Warp needs the real (closure-local) types.
        product.__annotations__ = {"a": vec_sh, "b": vec_sh, "table": SHProductTable, "return": vec_sh}
        square.__annotations__ = {"a": vec_sh, "table": SHProductTable, "return": vec_sh}
        product.__name__, square.__name__ = f"sh_product_order{order}", f"sh_square_order{order}"
        return SimpleNamespace(order=order, vec_sh=vec_sh, product=wp.func(product), square=wp.func(square))

    t = symmetric_product_table(order)
    n = order * order
    prod_terms = [[] for _ in range(n)]
    sq_terms = [[] for _ in range(n)]
    for i, j, k, v in zip(t.i, t.j, t.k, t.value):
        prod_terms[i].append(f"{float(np.float32(v))!r} * (a[{j}] * b[{k}] + a[{k}] * b[{j}])")
        sq_terms[i].append(f"{float(np.float32(2.0 * v))!r} * a[{j}] * a[{k}]")

    def body(terms):
        return ",\n        ".join(" + ".join(x) if x else "0.0" for x in terms)

    src = (f"def sh_product_order{order}(a: vec_sh, b: vec_sh, table: SHProductTable) -> vec_sh:\n"
           f"    return vec_sh(\n        {body(prod_terms)})\n\n\n"
           f"def sh_square_order{order}(a: vec_sh, table: SHProductTable) -> vec_sh:\n"
           f"    return vec_sh(\n        {body(sq_terms)})\n")
    filename = f"<warpshade-sh-product-order{order}>"
    linecache.cache[filename] = (len(src), None, src.splitlines(keepends=True), filename)
    scope = {"vec_sh": vec_sh, "SHProductTable": SHProductTable}
    exec(compile(src, filename, "exec"), scope)  # noqa: S102 - source generated above from the Gaunt table
    return SimpleNamespace(order=order, vec_sh=vec_sh, product=wp.func(scope[f"sh_product_order{order}"]),
                           square=wp.func(scope[f"sh_square_order{order}"]))


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


SQRT_4PI = 3.5449077018110318
"""``sqrt(4 pi)``: the DC coefficient of the constant function 1."""


@wp.struct
class OLTableArrays:
    """Optimal-linear table on the device (:class:`~warpshade.sh.exp.OLTable`), nodes at ``m = t / inv_step``."""

    log_a: wp.array[float]
    """``log a(m)`` per node, shape (K,), dtype float32."""
    c: wp.array[float]
    """``b(m) / a(m)`` per node, shape (K,), dtype float32."""
    inv_step: float
    """Nodes per unit magnitude."""


def ol_table_arrays(order: int, device: str = "cpu", table=None) -> OLTableArrays:
    """Upload the optimal-linear table for ``order`` (default :func:`~warpshade.sh.exp.ol_table`)."""
    from .exp import ol_table

    t = ol_table(order) if table is None else table
    s = OLTableArrays()
    s.log_a = wp.array(t.log_a.astype(np.float32), dtype=float, device=device)
    s.c = wp.array(t.c.astype(np.float32), dtype=float, device=device)
    s.inv_step = float(1.0 / t.step)
    return s


@wp.func
def ol_lookup(table: OLTableArrays, m: float) -> wp.vec2:
    """``(log a(m), c(m))`` linearly interpolated, clamped to the table's range."""
    count = table.log_a.shape[0]
    x = wp.clamp(m * table.inv_step, 0.0, float(count - 1))
    i = wp.min(int(x), count - 2)
    if i < 0:
        return wp.vec2(table.log_a[0], table.c[0])
    t = x - float(i)
    return wp.vec2((1.0 - t) * table.log_a[i] + t * table.log_a[i + 1], (1.0 - t) * table.c[i] + t * table.c[i + 1])


@wp.func
def sh_dc_free_norm(f: wp.array2d[float], row: int, n: int) -> float:
    """``||f^||``: the norm of ``f[row, 1:n]`` (DC isolated, thesis eq. 3.26)."""
    s = float(0.0)
    for i in range(1, n):
        s = s + f[row, i] * f[row, i]
    return wp.sqrt(s)


@wp.func
def sh_exp_ol(
    f: wp.array2d[float],
    f_row: int,
    n: int,
    table: OLTableArrays,
    out: wp.array2d[float],
    out_row: int,
):
    """Optimal-linear SH exponential (thesis eq. 3.30): ``out = e^{f_0/sqrt(4pi)} (a 1 + b f^)``.

    ``log a`` and the DC term share one exponent, so huge ``a`` with a very negative DC stays
    finite. ``out`` may be the same row as ``f``.
    """
    f0 = f[f_row, 0]
    ac = ol_lookup(table, sh_dc_free_norm(f, f_row, n))
    s = wp.exp(f0 / SQRT_4PI + ac[0])
    out[out_row, 0] = s * SQRT_4PI
    for i in range(1, n):
        out[out_row, i] = s * ac[1] * f[f_row, i]


@wp.func
def sh_scale_row_to_unit(v: wp.array2d[float], row: int, n: int) -> float:
    """Divide ``v[row, :n]`` by its norm and return the log of that norm (-inf-safe: -1e30 for 0)."""
    s = float(0.0)
    for i in range(n):
        s = s + v[row, i] * v[row, i]
    nrm = wp.sqrt(s)
    if nrm == 0.0:
        return -1.0e30
    inv = 1.0 / nrm
    for i in range(n):
        v[row, i] = v[row, i] * inv
    return wp.log(nrm)


@wp.func
def sh_exp_hybrid(
    f: wp.array2d[float],
    f_row: int,
    n: int,
    threshold: float,
    table: OLTableArrays,
    products: SHProductTable,
    tmp: wp.array2d[float],
    tmp_row: int,
    out: wp.array2d[float],
    out_row: int,
):
    """Hybrid SH exponential (thesis eq. 3.32): OL on ``f^/2^p`` then ``p`` squarings, ``||f^||/2^p <= threshold``.

    Every squaring renormalises to unit length and doubles a log-scale, and the DC factor joins that
    exponent at the end, so float32 stays finite for any input whose exponential is representable.
    ``tmp`` is scratch (a row distinct from ``out``); ``out`` may be the same row as ``f``.
    """
    f0 = f[f_row, 0]
    m = sh_dc_free_norm(f, f_row, n)
    if not wp.isfinite(m) or not wp.isfinite(f0):
        # NaN/inf input (or |f| beyond 1e19, whose squared norm overflows float32): say so, don't guess.
        for i in range(n):
            out[out_row, i] = wp.nan
        return
    p = int(0)
    if m > threshold:
        p = int(wp.ceil(wp.log2(m / threshold)))
    scale = wp.pow(2.0, -float(p))
    ac = ol_lookup(table, m * scale)
    tmp[tmp_row, 0] = SQRT_4PI
    for i in range(1, n):
        tmp[tmp_row, i] = ac[1] * scale * f[f_row, i]
    log_s = ac[0] + sh_scale_row_to_unit(tmp, tmp_row, n)
    for k in range(p):
        # Ping-pong between tmp and out; the squared vector's log-norm doubles the carried scale.
        if k % 2 == 0:
            sh_product_rows(tmp, tmp_row, tmp, tmp_row, n, products, out, out_row)
            log_s = 2.0 * log_s + sh_scale_row_to_unit(out, out_row, n)
        else:
            sh_product_rows(out, out_row, out, out_row, n, products, tmp, tmp_row)
            log_s = 2.0 * log_s + sh_scale_row_to_unit(tmp, tmp_row, n)
    s = wp.exp(wp.max(log_s + f0 / SQRT_4PI, -1.0e30))
    if p % 2 == 1:
        for i in range(n):
            out[out_row, i] = s * out[out_row, i]
    else:
        for i in range(n):
            out[out_row, i] = s * tmp[tmp_row, i]


@wp.kernel
def exponentiate_sh_ol(
    f: wp.array2d[float],
    n: int,
    table: OLTableArrays,
    out: wp.array2d[float],
):
    """Row-wise optimal-linear SH exponential, shapes (V, n), float32."""
    v = wp.tid()
    sh_exp_ol(f, v, n, table, out, v)


@wp.kernel
def exponentiate_sh_hybrid(
    f: wp.array2d[float],
    n: int,
    threshold: float,
    table: OLTableArrays,
    products: SHProductTable,
    tmp: wp.array2d[float],
    out: wp.array2d[float],
):
    """Row-wise hybrid SH exponential, shapes (V, n), float32; ``tmp`` is (V, n) scratch."""
    v = wp.tid()
    sh_exp_hybrid(f, v, n, threshold, table, products, tmp, v, out, v)


def sh_exp_warp(f, method: str = "hybrid", threshold: float | None = None, device: str = "cpu") -> np.ndarray:
    """Run the Warp float32 exponential on a batch of SH vectors (testing and benchmarking helper).

    Args:
        f: SH vectors, shape (V, n*n).
        method: ``"hybrid"`` or ``"ol"``.
        threshold: hybrid threshold (default :data:`~warpshade.sh.exp.DEFAULT_HYBRID_THRESHOLD`).
        device: Warp device.

    Returns:
        Shape (V, n*n), dtype float32.
    """
    from .exp import DEFAULT_HYBRID_THRESHOLD
    from .products import order_of

    f = np.asarray(f, dtype=np.float32)
    if f.ndim != 2:
        raise ValueError(f"sh_exp_warp: f must have shape (V, n*n), got {f.shape}")
    order = order_of(f.shape[1], "f")
    fa = wp.array(f, dtype=float, device=device)
    out = wp.zeros_like(fa)
    table = ol_table_arrays(order, device)
    if method == "ol":
        wp.launch(exponentiate_sh_ol, dim=f.shape[0], inputs=[fa, order * order, table], outputs=[out], device=device)
    elif method == "hybrid":
        thr = DEFAULT_HYBRID_THRESHOLD if threshold is None else float(threshold)
        tmp = wp.zeros_like(fa)
        wp.launch(exponentiate_sh_hybrid, dim=f.shape[0],
                  inputs=[fa, order * order, thr, table, product_table_arrays(order, device)],
                  outputs=[tmp, out], device=device)
    else:
        raise ValueError(f"sh_exp_warp: method must be 'hybrid' or 'ol', got {method!r}")
    return out.numpy()
