"""Per-receiver kernels of the sphere-set shadows and reflections, compiled per SH order.

Orchestration in :mod:`.method` and :mod:`.reflections`; NumPy reference :mod:`.reference` (shadows).
:func:`shade_kernel_fixed` builds, once per order, the kernels ``shade`` (shadows: tangent-plane rules,
log table lookup, ratio vectors, log accumulation, SH exponential, divergence guard, product with the
clamped cosine) and ``reflect`` (one-bounce reflections). Every SH vector is a fixed-length Warp vector
(``vec_sh`` of the SH core's :func:`~warpshade.sh.kernels.zh_vector_funcs`) held in registers, and
products are the SH core's :func:`~warpshade.sh.kernels.sh_product_vector_funcs` (unrolled up to order
6; squarings use the Gaunt table's symmetry). How they compare with the runtime-order kernels
they replaced: docs/benchmarks/history.md ("spheres").

This module deliberately does not use postponed annotations: Warp reads the (closure-local) vector
types from the annotations of the generated functions.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ...sh.kernels import SQRT_4PI, OLTableArrays, SHProductTable, ol_lookup, sh_product_vector_funcs, zh_vector_funcs
from .kernels import EXP_BLEND, EXP_HYBRID, EXP_OL, VIS_NORM_SLACK, adjust_sphere

wp.set_module_options({"enable_backward": False})


@functools.lru_cache(maxsize=None)
def shade_kernel_fixed(order: int) -> SimpleNamespace:
    """Kernels ``shade`` and ``reflect`` (and their vector types) for one SH order; built and cached on first use.

    Returns a namespace with ``vec_sh``, ``vec_zh``, ``kz`` (ZH-rotation constants as a ``vec_sh``),
    ``shade`` and ``reflect`` (arguments and shapes in their docstrings).
    """
    zf = zh_vector_funcs(order)
    vec_sh, vec_zh, zh_rotate = zf.vec_sh, zf.vec_zh, zf.zh_rotate
    pf = sh_product_vector_funcs(order)
    product, square = pf.product, pf.square
    n2 = wp.constant(order * order)
    nb = wp.constant(order)
    sqrt_4pi = wp.constant(SQRT_4PI)
    blend = wp.constant(EXP_BLEND)
    slack = wp.constant(VIS_NORM_SLACK)
    hybrid = wp.constant(EXP_HYBRID)
    exp_ol_mode = wp.constant(EXP_OL)

    def dc_free_norm(f: vec_sh) -> float:
        s = float(0.0)
        for i in range(1, n2):
            s = s + f[i] * f[i]
        return wp.sqrt(s)

    def exp_ol(f: vec_sh, ol: OLTableArrays) -> vec_sh:
        # Optimal linear (eq. 3.30), as the SH core's sh_exp_ol: e^{f0/sqrt(4π)} (a 1 + b f̂).
        ac = ol_lookup(ol, dc_free_norm(f))
        s = wp.exp(f[0] / sqrt_4pi + ac[0])
        out = f * (s * ac[1])
        out[0] = s * sqrt_4pi
        return out

    def exp_hybrid(f: vec_sh, m: float, threshold: float, ol: OLTableArrays, products: SHProductTable) -> vec_sh:
        # The SH core's sh_exp_hybrid (eq. 3.32) on a register vector: OL on f̂/2^p, p renormalised squarings.
        f0 = f[0]
        out = vec_sh()
        if not wp.isfinite(m) or not wp.isfinite(f0):
            for i in range(n2):
                out[i] = wp.nan
            return out
        p = int(0)
        if m > threshold:
            p = int(wp.ceil(wp.log2(m / threshold)))
        scale = wp.pow(2.0, -float(p))
        ac = ol_lookup(ol, m * scale)
        t = f * (ac[1] * scale)
        t[0] = sqrt_4pi
        nrm = wp.length(t)
        t = t / nrm
        log_s = ac[0] + wp.log(nrm)
        for _k in range(p):
            t = square(t, products)
            nrm = wp.length(t)
            if nrm == 0.0:
                log_s = 2.0 * log_s - 1.0e30
            else:
                t = t / nrm
                log_s = 2.0 * log_s + wp.log(nrm)
        return t * wp.exp(wp.max(log_s + f0 / sqrt_4pi, -1.0e30))

    def lerp_table(table: wp.array(dtype=vec_zh), theta: float, step: float) -> vec_zh:
        # Log / form-factor ZH table row at angular radius θ, linearly interpolated (kernels.lerp_zh_row).
        last = table.shape[0] - 1
        x = wp.clamp(theta / step, 0.0, float(last))
        i0 = wp.min(int(x), last - 1)
        f = x - float(i0)
        return table[i0] * (1.0 - f) + table[i0 + 1] * f

    def angular_radius(rho: float, dist: float) -> float:
        # Angular radius [rad] of a sphere of radius rho whose centre is dist (> 0) away.
        return wp.asin(wp.min(rho / dist, 1.0))

    def sphere_lobe(d: wp.vec3, theta: float, ratio: vec_zh, table: wp.array(dtype=vec_zh), step: float,
                    kz: vec_sh) -> vec_sh:
        # The per-sphere lobe of shade and reflect: the ZH row of `table` (log blocker or form factor) at
        # angular radius theta, times the per-band `ratio` (eq. 4.9; ones for none), rotated toward d.
        g = lerp_table(table, theta, step)
        for l in range(nb):
            g[l] = g[l] * ratio[l]
        return zh_rotate(d, g, kz)

    def exp_series(f: vec_sh, p: int, products: SHProductTable) -> vec_sh:
        # (exp_*(2^-p f))^(2^p): 8 Taylor terms of SH products (eq. 3.25) at the small scale, p squarings
        # (eq. 3.32); the DC is isolated (eq. 3.27) and restored as a factor.
        # (Fresh vectors, not `fh = f; fh[0] = 0`: a component store may alias the assigned-from local.)
        s = wp.pow(0.5, float(p))
        fh = vec_sh()
        for i in range(1, n2):
            fh[i] = f[i]
        term = fh * s
        one = vec_sh()
        one[0] = sqrt_4pi
        out = term + one
        for kk in range(2, 9):
            term = product(term, fh, products) * (s / float(kk))
            out = out + term
        out = out * wp.exp(f[0] * s / sqrt_4pi)
        for _q in range(p):
            out = square(out, products)
        return out

    def exp_blended(f: vec_sh, mode: int, tau: float, ol: OLTableArrays, products: SHProductTable) -> vec_sh:
        """SH exponential (thesis §3.1.4): EXP_OL the SH core's optimal linear (eq. 3.30); EXP_HYBRID the
        core's hybrid (OL on f̂/2^p with ||f̂||/2^p <= tau, p squarings, eq. 3.32); EXP_SERIES 8 Taylor terms
        after scaling to ||f̂|| <= 1/4, then squarings (accurate, slow). For the two squaring modes the
        results with p and p+1 squarings are blended within EXP_BLEND octaves below each change of p,
        linearly in log2 ||f̂|| (continuity: the core's hybrid jumps by up to 0.1 there)."""
        if mode == exp_ol_mode:
            return exp_ol(f, ol)
        m = dc_free_norm(f)
        lim = tau
        if mode != hybrid:
            lim = 0.25
        p = int(0)
        w = float(0.0)
        if m > 0.0:
            q = wp.log2(m / lim)
            p = wp.clamp(int(wp.ceil(q)), 0, 30)
            w = wp.clamp((q - (float(p) - blend)) / blend, 0.0, 1.0)
        out = vec_sh()
        if mode == hybrid:
            out = exp_hybrid(f, m, lim, ol, products)
            if w > 0.0:
                # threshold/2 makes the core's hybrid take exactly one more squaring
                out = out * (1.0 - w) + exp_hybrid(f, m, 0.5 * lim, ol, products) * w
        else:
            out = exp_series(f, p, products)
            if w > 0.0:
                out = out * (1.0 - w) + exp_series(f, p + 1, products) * w
        return out

    def shade(
        points: wp.array(dtype=wp.vec3),
        normals: wp.array(dtype=wp.vec3),
        cluster: wp.array(dtype=wp.int32),
        centers: wp.array(dtype=wp.vec3),
        radii: wp.array(dtype=float),
        cut_start: wp.array(dtype=wp.int32),
        cut_sphere: wp.array(dtype=wp.int32),
        cut_ratio: wp.array2d(dtype=float),
        log_table: wp.array(dtype=vec_zh),
        theta_step: float,
        cos_zh: vec_zh,
        kz: vec_sh,
        ol: OLTableArrays,
        products: SHProductTable,
        mode: int,
        tau: float,
        used: wp.array(dtype=wp.int32),
        fallback: wp.array(dtype=wp.int32),
        visibility: wp.array2d(dtype=float),
        transfer: wp.array2d(dtype=float),
    ):
        """Sphere-set visibility (eq. 4.7) and diffuse transfer ``V * cos`` (docs/conventions.md §2) of receiver ``v``.

        Receivers ``points``/``normals`` (R,) vec3 in cluster ``cluster[v]``, whose cut entries are
        ``cut_start[c]..cut_start[c+1]-1`` (sphere ``cut_sphere[e]``, ratio row ``cut_ratio[e]`` of eq. 4.9,
        shape (E, order)); ``log_table`` (T,) vec_zh by angular radius in steps of ``theta_step`` [rad].
        Outputs: ``used``/``fallback`` (R,) int32 (``fallback = 1``: diverged exponential replaced by the
        geometric mean, see kernels.VIS_NORM_SLACK), ``visibility``/``transfer`` (R, N*N) float32.
        ``transfer_0`` (irradiance under a uniform sky) is physically >= 0; SH ringing of a nearly
        closed visibility can push it below, in which case the row is set to 0.
        """
        v = wp.tid()
        p = points[v]
        n = normals[v]
        c = cluster[v]
        # Log accumulation (eq. 4.7) of the cluster's cut (eq. 4.8) with ratio vectors (eq. 4.9).
        logsum = vec_sh()
        count = int(0)
        for e in range(cut_start[c], cut_start[c + 1]):
            s = cut_sphere[e]
            a = adjust_sphere(p, n, centers[s], radii[s])
            rho = a[3]
            if rho <= 0.0:
                continue
            d = wp.vec3(a[0], a[1], a[2]) - p
            dist = wp.length(d)
            if dist <= 0.0:
                continue
            ratio = vec_zh()
            for l in range(nb):
                ratio[l] = cut_ratio[e, l]
            logsum = logsum + sphere_lobe(d, angular_radius(rho, dist), ratio, log_table, theta_step, kz)
            count = count + 1
        used[v] = count
        # SH exponential (thesis §3.1.4), blended between p and p+1 squarings (exp_blended).
        vis = exp_blended(logsum, mode, tau, ol, products)
        # Divergence guard: geometric-mean visibility when the exponential exploded (kernels.VIS_NORM_SLACK).
        bound = slack * sqrt_4pi
        fb = int(0)
        if not (vis[0] >= 0.0 and vis[0] <= bound and wp.dot(vis, vis) <= bound * bound):
            vis = vec_sh()
            vis[0] = sqrt_4pi * wp.exp(wp.min(logsum[0] / sqrt_4pi, 0.0))
            fb = 1
        fallback[v] = fb
        # Transfer = V * clamped cosine (docs/conventions.md §2); negative irradiance (ringing) -> 0.
        t = product(vis, zh_rotate(n, cos_zh, kz), products)
        if t[0] < 0.0:
            t = vec_sh()
        for i in range(n2):
            visibility[v, i] = vis[i]
            transfer[v, i] = t[i]

    def reflect(
        points: wp.array(dtype=wp.vec3),
        normals: wp.array(dtype=wp.vec3),
        cluster: wp.array(dtype=wp.int32),
        receiver_object: wp.array(dtype=wp.int32),
        cut_start: wp.array(dtype=wp.int32),
        cut_row: wp.array(dtype=wp.int32),
        cut_ratio: wp.array(dtype=float),
        row_sphere: wp.array(dtype=wp.int32),
        row_object: wp.array(dtype=wp.int32),
        centers: wp.array(dtype=wp.vec3),
        radii: wp.array(dtype=float),
        rotations: wp.array(dtype=wp.mat33),
        radiance: wp.array3d(dtype=float),
        log_table: wp.array(dtype=vec_zh),
        ff_table: wp.array(dtype=vec_zh),
        theta_step: float,
        cos_zh: vec_zh,
        kz: vec_sh,
        ol: OLTableArrays,
        products: SHProductTable,
        mode: int,
        tau: float,
        exclude_intersecting: int,
        record: int,
        key: wp.array2d(dtype=float),
        slot: wp.array2d(dtype=wp.int32),
        irradiance: wp.array(dtype=wp.vec3),
        contribution: wp.array(dtype=float),
    ):
        """Reflected irradiance at receiver ``v`` from the reflecting spheres of its cluster's cut (eqs. 4.22,
        4.25, 4.32, 4.33, 4.35).

        Cut entries ``e`` of cluster ``cluster[v]`` are ``cut_start[c]..cut_start[c+1]-1``: radiance row
        ``cut_row[e]`` (sphere ``row_sphere[row]`` of object ``row_object[row]``) with the ratio
        ``cut_ratio[e]`` of eq. 4.34 (corrected, see :mod:`.reflections`). Spheres of the receiver's own
        object (``receiver_object[v]``, -1: none) are skipped. Spheres (after the tangent-plane rules of
        §4.2) are taken nearest first; with ``P`` the sum of the closer spheres' log blocker vectors, a
        sphere's visibility is ``exp(P) - exp(P + G_i)`` (eq. 4.32), dotted with the clamped cosine (eq.
        4.33), times the form-factor average of its radiance vector (eq. 4.25; direction taken into the
        sphere's rest frame, Fig. 4.17). With ``exclude_intersecting`` the thesis' rule below eq. 4.33:
        closer spheres of the same object that intersect sphere ``i`` are left out of its ``P`` (their
        occlusion is already in sphere ``i``'s black samples, §4.3.1). ``radiance`` (rows, 3, N*N) per
        colour in each sphere's rest frame; ``key``/``slot`` (R, >= max cut size) scratch; output ``irradiance``
        (R,) vec3; with ``record`` also ``contribution[e]`` = ``Ṽ L̃`` summed over colours, without the
        ratio (one receiver per cluster: the ratio pass at cluster centres).
        """
        v = wp.tid()
        p = points[v]
        n = normals[v]
        c = cluster[v]
        own = receiver_object[v]
        e0 = cut_start[c]
        ns = cut_start[c + 1] - e0
        # spheres kept by the tangent-plane rules (and not of the receiver's own object), sorted by the
        # distance of their adjusted centres: insertion sort into (key, slot); the cut lists come sorted by
        # distance from the cluster centre, so few shifts (the thesis' presorted lists, ch. 5.2)
        cnt = int(0)
        for q in range(ns):
            row = cut_row[e0 + q]
            if record != 0:
                contribution[e0 + q] = 0.0
            if own >= 0 and row_object[row] == own:
                continue
            sid = row_sphere[row]
            a = adjust_sphere(p, n, centers[sid], radii[sid])
            if a[3] > 0.0:
                k = wp.length(wp.vec3(a[0], a[1], a[2]) - p)
                j = cnt
                while j > 0 and key[v, j - 1] > k:
                    key[v, j] = key[v, j - 1]
                    slot[v, j] = slot[v, j - 1]
                    j = j - 1
                key[v, j] = k
                slot[v, j] = q
                cnt = cnt + 1
        logsum = vec_sh()
        e_full = vec_sh()  # exp(logsum), valid while full_ok
        e_full[0] = sqrt_4pi
        full_ok = int(1)
        cosine = zh_rotate(n, cos_zh, kz)
        ones = vec_zh(1.0)
        total = wp.vec3(0.0)
        for step in range(cnt):  # nearest first
            best = slot[v, step]
            bd = key[v, step]
            row = cut_row[e0 + best]
            sid = row_sphere[row]
            a = adjust_sphere(p, n, centers[sid], radii[sid])
            d = wp.vec3(a[0], a[1], a[2]) - p
            theta = angular_radius(a[3], wp.max(bd, 1.0e-30))
            g = sphere_lobe(d, theta, ones, log_table, theta_step, kz)
            excl = vec_sh()
            nex = int(0)
            if exclude_intersecting != 0:
                obj = row_object[row]
                for jj in range(step):  # the closer spheres
                    row2 = cut_row[e0 + slot[v, jj]]
                    sid2 = row_sphere[row2]
                    if row_object[row2] == obj and wp.length(centers[sid2] - centers[sid]) < radii[sid] + radii[sid2]:
                        a2 = adjust_sphere(p, n, centers[sid2], radii[sid2])
                        d2 = wp.vec3(a2[0], a2[1], a2[2]) - p
                        th2 = angular_radius(a2[3], wp.max(wp.length(d2), 1.0e-30))
                        excl = excl + sphere_lobe(d2, th2, ones, log_table, theta_step, kz)
                        nex = nex + 1
            # sphere visibility as a difference of two exponentials (eq. 4.32)
            e_a = vec_sh()
            e_b = vec_sh()
            if nex == 0:
                if full_ok == 0:
                    e_full = exp_blended(logsum, mode, tau, ol, products)
                e_a = e_full
                logsum = logsum + g
                e_b = exp_blended(logsum, mode, tau, ol, products)
                e_full = e_b
                full_ok = 1
            else:
                pp = logsum - excl
                e_a = exp_blended(pp, mode, tau, ol, products)
                e_b = exp_blended(pp + g, mode, tau, ol, products)
                logsum = logsum + g
                full_ok = 0
            vis = wp.dot(e_a - e_b, cosine)  # eq. 4.33
            if vis <= 0.0:
                continue
            # form-factor lobe toward the receiver, in the sphere's rest frame (Fig. 4.17)
            u = wp.transpose(rotations[sid]) * (p - centers[sid])
            ff = sphere_lobe(u, theta, ones, ff_table, theta_step, kz)
            col = wp.vec3(0.0)
            for cc in range(3):
                acc = float(0.0)
                for i in range(n2):
                    acc = acc + radiance[row, cc, i] * ff[i]
                col[cc] = acc
            if record != 0:
                contribution[e0 + best] = vis * (col[0] + col[1] + col[2])
            total = total + (vis * cut_ratio[e0 + best]) * col  # eq. 4.35
        # SH ringing of a sharply coloured radiance vector can dip below 0; irradiance cannot
        irradiance[v] = wp.vec3(wp.max(total[0], 0.0), wp.max(total[1], 0.0), wp.max(total[2], 0.0))

    for fn in (dc_free_norm, exp_ol, exp_hybrid, exp_series, lerp_table, angular_radius, sphere_lobe, exp_blended, shade,
               reflect):
        fn.__name__ = f"{fn.__name__}_order{order}"
        fn.__qualname__ = fn.__name__
    dc_free_norm = wp.func(dc_free_norm)
    exp_ol, exp_hybrid, exp_series = wp.func(exp_ol), wp.func(exp_hybrid), wp.func(exp_series)
    lerp_table, exp_blended = wp.func(lerp_table), wp.func(exp_blended)
    angular_radius, sphere_lobe = wp.func(angular_radius), wp.func(sphere_lobe)
    return SimpleNamespace(order=order, vec_sh=vec_sh, vec_zh=vec_zh, kz=zf.zh_constants(),
                           shade=wp.kernel(shade, enable_backward=False),
                           reflect=wp.kernel(reflect, enable_backward=False))
