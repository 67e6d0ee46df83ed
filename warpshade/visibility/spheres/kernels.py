"""Warp kernels of the sphere-set shadows (orchestration in :mod:`.method`, NumPy reference in :mod:`.reference`).

Per frame: ``refit_spheres``/``bound_parents`` move the spheres with the mesh, ``fit_clusters`` bounds
the receiver clusters, ``compute_cut_ratios`` evaluates eq. 4.9 at cluster centres (SH vectors in rows
of 2D scratch arrays, one compiled kernel for every order). The per-receiver work (tangent-plane
adjustment ``adjust_sphere`` of §4.2, table lookup of the log blocker ZH vector, ZH rotation (eq.
3.17), log accumulation (eq. 4.7), SH exponential (eqs. 3.30 / 3.32) and the product with the clamped
cosine, docs/conventions.md §2) is the kernel ``shade`` of :mod:`.fixed_kernels`, compiled per order with
the SH vectors in registers; the one-bounce reflections are in :mod:`.reflection_kernels`. SH
products, the optimal-linear/hybrid exponentials and ZH rotation are the SH core's
(:mod:`warpshade.sh.kernels`); SH convention: :mod:`warpshade.sh.basis`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...sh.kernels import SHProductTable, sh_product_rows, zh_rotate_accumulate

EXP_OL = 0
EXP_HYBRID = 1
EXP_SERIES = 2


# --------------------------------------------------------------------------------------------------
# geometry
@wp.kernel
def classify_inside(mesh: wp.uint64, query: wp.array[wp.vec3], max_dist: float, inside: wp.array[wp.int32]):
    """``inside[i] = 1`` if the generalised winding number of ``query[i]`` exceeds 0.5 (closed mesh)."""
    i = wp.tid()
    q = wp.mesh_query_point_sign_winding_number(mesh, query[i], max_dist, 2.0, 0.5)
    inside[i] = 0
    if q.result and q.sign < 0.0:
        inside[i] = 1


def winding_inside(points: np.ndarray, faces: np.ndarray, query: np.ndarray, device: str = "cpu") -> np.ndarray:
    """Boolean mask (len(query),) of query points inside the closed mesh."""
    pts = wp.array(np.asarray(points, dtype=np.float32), dtype=wp.vec3, device=device)
    idx = wp.array(np.asarray(faces, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device)
    mesh = wp.Mesh(points=pts, indices=idx, support_winding_number=True)
    q = wp.array(np.asarray(query, dtype=np.float32), dtype=wp.vec3, device=device)
    out = wp.zeros(len(query), dtype=wp.int32, device=device)
    diag = float(np.linalg.norm(np.ptp(np.asarray(points), axis=0))) + 1.0
    wp.launch(classify_inside, dim=len(query), inputs=[mesh.id, q, 4.0 * diag], outputs=[out], device=device)
    return out.numpy().astype(bool)


@wp.func
def max_abs_entry(m: wp.mat33) -> float:
    """Largest ``|m_ij|``: the scale to normalise a matrix by before ``wp.svd3``, whose float32 thresholds
    are absolute (a mesh scaled by 1e-4 gives entries ~1e-10 and a garbage decomposition)."""
    h = float(0.0)
    for i in range(3):
        for j in range(3):
            h = wp.max(h, wp.abs(m[i, j]))
    return h


@wp.func
def indexed_mean(start: wp.array[wp.int32], index: wp.array[wp.int32], points: wp.array[wp.vec3], k: int) -> wp.vec3:
    """Mean of ``points[index[start[k]:start[k+1]]]`` (CSR group ``k``; origin when empty)."""
    a = start[k]
    b = start[k + 1]
    m = wp.vec3(0.0)
    for i in range(a, b):
        m = m + points[index[i]]
    return m / float(wp.max(b - a, 1))


@wp.func
def indexed_reach(start: wp.array[wp.int32], index: wp.array[wp.int32], points: wp.array[wp.vec3], k: int,
                  c: wp.vec3) -> float:
    """Largest distance from ``c`` of ``points[index[start[k]:start[k+1]]]`` (CSR group ``k``; 0 when empty)."""
    r = float(0.0)
    for i in range(start[k], start[k + 1]):
        r = wp.max(r, wp.length(points[index[i]] - c))
    return r


@wp.kernel
def refit_spheres(
    vert_start: wp.array[wp.int32],
    vert_index: wp.array[wp.int32],
    rest_points: wp.array[wp.vec3],
    points: wp.array[wp.vec3],
    rest_centroid: wp.array[wp.vec3],
    rest_offset: wp.array[wp.vec3],
    rest_radius: wp.array[float],
    rest_spread: wp.array[float],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
    rotations: wp.array[wp.mat33],
):
    """Move sphere ``s`` rigidly with its vertices (Kabsch) and change its radius with their spread.

    The thesis refits nothing (rigid objects only); this keeps each sphere on the part of the mesh it
    was fitted to without re-running the fit. ``radius >= spread`` keeps the vertices bounded.
    """
    s = wp.tid()
    a = vert_start[s]
    b = vert_start[s + 1]
    m = indexed_mean(vert_start, vert_index, points, s)
    h = wp.mat33(0.0)
    m0 = rest_centroid[s]
    for k in range(a, b):
        v = vert_index[k]
        h = h + wp.outer(rest_points[v] - m0, points[v] - m)
    # The rotation does not depend on the scale of h, but wp.svd3 has absolute float32 thresholds: a
    # mesh scaled by 1e-4 gives entries ~1e-10 and a garbage rotation. Normalise to max |h_ij| = 1.
    hmax = max_abs_entry(h)
    if hmax > 0.0:
        h = h / hmax
    u = wp.mat33()
    sig = wp.vec3()
    vv = wp.mat33()
    wp.svd3(h, u, sig, vv)
    rot = vv * wp.transpose(u)
    if wp.determinant(rot) < 0.0:  # reflection from a degenerate (planar) vertex set: flip the weakest axis
        vv = wp.matrix_from_cols(wp.vec3(vv[0, 0], vv[1, 0], vv[2, 0]), wp.vec3(vv[0, 1], vv[1, 1], vv[2, 1]),
                                 -wp.vec3(vv[0, 2], vv[1, 2], vv[2, 2]))
        rot = vv * wp.transpose(u)
    c = m + rot * rest_offset[s]
    spread = indexed_reach(vert_start, vert_index, points, s, c)
    centers[s] = c
    radii[s] = wp.max(rest_radius[s] + spread - rest_spread[s], spread)
    rotations[s] = rot


@wp.kernel
def refit_spheres_bones(
    sphere_joint: wp.array2d[wp.int32],
    sphere_weight: wp.array2d[float],
    sphere_spread: wp.array2d[float],
    rest_center: wp.array[wp.vec3],
    rest_radius: wp.array[float],
    transforms: wp.array[wp.mat44],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
    rotations: wp.array[wp.mat33],
):
    """Move sphere ``s`` with the skinning bones: its rest centre ``c0`` skinned like a vertex with the
    mean weights ``ŵ`` of its vertices (column-vector matrices as :func:`warpshade.sim.kernels.skin_points`),
    rotation the polar part of the blended transform, and a radius that still bounds its vertices.

    Bound: a vertex ``x = Σ_k w_k M_k r`` (``Σ w_k = 1``, rigid ``M_k``) of a sphere with rest radius
    ``r_0 >= |r - c0|`` and skinned centre ``c = Σ_k ŵ_k M_k c0`` has
    ``x - c = Σ_k w_k R_k (r - c0) + Σ_k (w_k - ŵ_k)(M_k c0 - c)`` (the ``ŵ`` also sum to 1), so
    ``|x - c| <= σ r_0 + Σ_k δ_k |M_k c0 - c|`` with ``δ_k = max_v |w_vk - ŵ_k|`` over the sphere's vertices
    (``sphere_spread``) and ``σ`` the largest singular value of the transforms (1 when rigid). It grows
    only where the sphere's vertices bend between joints. ``sphere_joint``/``sphere_weight``/``sphere_spread``
    (S, K): every joint influencing the sphere's vertices (unused slots weight 0, spread 0). Cost
    O(S K) per frame instead of the point refit's O(V) with an SVD per sphere.
    """
    s = wp.tid()
    m = wp.mat33(0.0)
    t = wp.vec3(0.0)
    for k in range(sphere_joint.shape[1]):
        w = sphere_weight[s, k]
        if w != 0.0:
            x = transforms[sphere_joint[s, k]]
            m = m + w * wp.mat33(x[0, 0], x[0, 1], x[0, 2], x[1, 0], x[1, 1], x[1, 2], x[2, 0], x[2, 1], x[2, 2])
            t = t + w * wp.vec3(x[0, 3], x[1, 3], x[2, 3])
    c0 = rest_center[s]
    c = m * c0 + t
    centers[s] = c
    # polar decomposition by SVD (normalised, as refit_spheres: wp.svd3 has absolute thresholds)
    hmax = max_abs_entry(m)
    u = wp.mat33()
    sig = wp.vec3()
    vv = wp.mat33()
    rot = wp.identity(n=3, dtype=float)
    smax = float(0.0)
    if hmax > 0.0:
        wp.svd3(m / hmax, u, sig, vv)
        rot = u * wp.transpose(vv)
        if wp.determinant(rot) < 0.0:
            u = wp.matrix_from_cols(wp.vec3(u[0, 0], u[1, 0], u[2, 0]), wp.vec3(u[0, 1], u[1, 1], u[2, 1]),
                                    -wp.vec3(u[0, 2], u[1, 2], u[2, 2]))
            rot = u * wp.transpose(vv)
        smax = wp.max(wp.max(sig[0], sig[1]), sig[2]) * hmax
    r = rest_radius[s] * wp.max(smax, 1.0)
    for k in range(sphere_joint.shape[1]):
        dk = sphere_spread[s, k]
        if dk != 0.0:
            x = transforms[sphere_joint[s, k]]
            mk = wp.vec3(x[0, 0] * c0[0] + x[0, 1] * c0[1] + x[0, 2] * c0[2] + x[0, 3],
                         x[1, 0] * c0[0] + x[1, 1] * c0[1] + x[1, 2] * c0[2] + x[1, 3],
                         x[2, 0] * c0[0] + x[2, 1] * c0[1] + x[2, 2] * c0[2] + x[2, 3])
            r = r + dk * wp.length(mk - c)
    radii[s] = r
    rotations[s] = rot


@wp.kernel
def bound_parents(
    child_start: wp.array[wp.int32],
    child_index: wp.array[wp.int32],
    spheres: wp.array[wp.int32],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
):
    """Grow each parent in ``spheres`` until it bounds its children (launched level by level, bottom up)."""
    t = wp.tid()
    s = spheres[t]
    c = centers[s]
    r = radii[s]
    for k in range(child_start[s], child_start[s + 1]):
        j = child_index[k]
        r = wp.max(r, wp.length(centers[j] - c) + radii[j])
    radii[s] = r


@wp.kernel
def fit_clusters(
    member_start: wp.array[wp.int32],
    member_index: wp.array[wp.int32],
    points: wp.array[wp.vec3],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
):
    """Bounding sphere (centroid, farthest member) of each receiver cluster."""
    k = wp.tid()
    m = indexed_mean(member_start, member_index, points, k)
    centers[k] = m
    radii[k] = indexed_reach(member_start, member_index, points, k, m)


# --------------------------------------------------------------------------------------------------
# SH helpers on rows of 2D arrays
@wp.func
def adjust_sphere(p: wp.vec3, n: wp.vec3, c: wp.vec3, r: float) -> wp.vec4:
    """Tangent-plane rules of §4.2 (Ren et al. 2006) with the continuity factor α; returns (centre, radius).

    Radius 0 means the sphere is removed. A sphere straddling ``T_p`` becomes the sphere tangent to ``T_p``
    at the foot ``q1`` of its centre, keeping its highest point (radius ``(r+h)/2``), scaled by α about
    ``q1``. α = 0 while ``p`` is inside the sphere and rises to 1 at twice the cut circle's radius ``d``
    (the thesis' ``α = min(1, (|p-q1| - d)/d)``). For a centre in front of ``T_p`` (h > 0) the thesis
    applies no α; we blend ``α + (1-α) h/r`` so the two straddling rules meet continuously at h = 0.
    """
    h = wp.dot(c - p, n)
    if h >= r:
        return wp.vec4(c[0], c[1], c[2], r)
    if h <= -r:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    q1 = c - h * n
    d = wp.sqrt(wp.max(r * r - h * h, 0.0))
    alpha = float(1.0)
    if d > 1.0e-6 * r:
        alpha = wp.clamp((wp.length(p - q1) - d) / d, 0.0, 1.0)
    if h > 0.0:
        alpha = alpha + (1.0 - alpha) * (h / r)
    rho = alpha * 0.5 * (r + h)
    cc = q1 + n * rho
    return wp.vec4(cc[0], cc[1], cc[2], rho)


@wp.func
def lerp_zh_row(
    table: wp.array2d[float],
    theta: float,
    step: float,
    weight: wp.array2d[float],
    wrow: int,
    order: int,
    out: wp.array2d[float],
    row: int,
):
    """``out[row, l] = w_l g_l(θ)``: table row interpolated by angular radius, times a ratio row (eq. 4.9)."""
    t = wp.clamp(theta / step, 0.0, float(table.shape[0] - 1))
    i0 = wp.min(int(t), table.shape[0] - 2)
    f = t - float(i0)
    for l in range(order):
        out[row, l] = (table[i0, l] * (1.0 - f) + table[i0 + 1, l] * f) * weight[wrow, l]


EXP_BLEND = 0.125
"""Width (in octaves of ``||f̂||``) over which the exponentials with ``p`` and ``p+1`` squarings are
blended, so the result is continuous where the squaring count changes (the SH core's hybrid jumps
there by up to 0.1 in a coefficient: visible flicker as receivers move)."""

VIS_NORM_SLACK = 1.1
"""A visibility in [0, 1] has ``||V|| <= sqrt(4π)`` and ``0 <= V_0 <= sqrt(4π)``; 10 % slack admits SH
ringing of legitimate results. Beyond it the exponential has diverged: when many blockers overlap in
one direction the log sum is a deep narrow well whose order-N SH truncation rings positive elsewhere,
and exp of that ringing explodes (1000 overlapping spheres: V_0 ~ 200). No exponential recovers from
it; the kernels then use the geometric-mean visibility ``exp(f_0/sqrt(4π))`` (DC only), bounded by the
true mean visibility (Jensen) and tending to 0 as blockers accumulate."""


@wp.kernel
def multiply_transfer(
    transfer_in: wp.array2d[float],
    visibility: wp.array2d[float],
    products: SHProductTable,
    order: int,
    transfer: wp.array2d[float],
):
    """``transfer = transfer_in * visibility`` (SH product): another method's self-shadowed transfer
    times the sphere visibility of other objects (visibilities multiply, §4.2 eq. 4.5)."""
    v = wp.tid()
    sh_product_rows(transfer_in, v, visibility, v, order * order, products, transfer, v)
    if transfer[v, 0] < 0.0:
        for i in range(order * order):
            transfer[v, i] = 0.0


@wp.kernel
def compute_cut_ratios(
    cut_cluster: wp.array[wp.int32],
    cut_sphere: wp.array[wp.int32],
    cluster_centers: wp.array[wp.vec3],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
    leaf_start: wp.array[wp.int32],
    leaf_index: wp.array[wp.int32],
    log_table: wp.array2d[float],
    theta_step: float,
    ones: wp.array2d[float],
    order: int,
    kz: wp.array[float],
    zbuf: wp.array2d[float],
    fb: wp.array2d[float],
    fd: wp.array2d[float],
    ratio: wp.array2d[float],
):
    """Ratio vector of eq. 4.9 for cut entry ``e``: per band, the least-squares scale of the parent's log
    vector ``F_b`` onto the sum ``F_d`` of its leaves' log vectors, both at the cluster centre.

    Leaves, and parents whose (or whose leaves') sphere contains the centre, get ratio 1.
    """
    e = wp.tid()
    s = cut_sphere[e]
    x = cluster_centers[cut_cluster[e]]
    for l in range(order):
        ratio[e, l] = 1.0
    a = leaf_start[s]
    b = leaf_start[s + 1]
    if b - a == 1 and leaf_index[a] == s:
        return
    d = centers[s] - x
    dist = wp.length(d)
    if dist <= radii[s]:
        return
    for i in range(order * order):
        fd[e, i] = 0.0
        fb[e, i] = 0.0
    for q in range(a, b):
        j = leaf_index[q]
        dj = centers[j] - x
        lj = wp.length(dj)
        if lj <= radii[j]:
            return
        lerp_zh_row(log_table, wp.asin(radii[j] / lj), theta_step, ones, 0, order, zbuf, e)
        zh_rotate_accumulate(dj, zbuf, e, 1.0, order, kz, fd, e)
    lerp_zh_row(log_table, wp.asin(radii[s] / dist), theta_step, ones, 0, order, zbuf, e)
    zh_rotate_accumulate(d, zbuf, e, 1.0, order, kz, fb, e)
    for l in range(order):
        num = float(0.0)
        den = float(0.0)
        for i in range(l * l, (l + 1) * (l + 1)):
            num = num + fb[e, i] * fd[e, i]
            den = den + fb[e, i] * fb[e, i]
        if den > 1.0e-12:
            ratio[e, l] = wp.clamp(num / den, -4.0, 4.0)
