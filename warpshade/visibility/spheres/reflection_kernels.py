"""Warp kernels of one-bounce diffuse reflections from sphere sets (thesis §4.3, ch. 5).

``trace_sphere_samples`` (once, rest pose) finds each sphere's surface sample points (eqs. 4.12–4.13
with the three hit rules of §4.3.1); ``resample_surface`` re-reads them from the deformed mesh every
frame (beyond the thesis, which handles rigid objects only); ``project_sphere_radiance`` builds the
radiance SH vectors (eqs. 4.16–4.20); ``shade_sphere_reflections`` accumulates, per receiver, the
average sphere radiance (form factor, eqs. 4.24–4.25) times the sphere visibility as a difference of
two exponentials (eq. 4.32, 4.33), eq. 4.22. Orchestration: :mod:`.reflections`.
"""

from __future__ import annotations

import warp as wp

from ...sh.kernels import SQRT_4PI, OLTableArrays, SHProductTable, zh_rotate_accumulate
from .kernels import adjust_sphere, lerp_zh_row, sh_exp_rows


@wp.kernel
def trace_sphere_samples(
    mesh: wp.uint64,
    face_owner: wp.array[wp.int32],
    centers: wp.array[wp.vec3],
    spheres: wp.array[wp.int32],
    directions: wp.array[wp.vec3],
    max_t: float,
    max_hits: int,
    hit_face: wp.array2d[wp.int32],
    hit_point: wp.array2d[wp.vec3],
):
    """Surface sample of sphere ``spheres[s]`` in direction ``directions[j]`` (thesis §4.3.1).

    Rays leave the centre; the farthest back-face hit on a triangle the sphere owns (eq. 4.10) wins;
    hits only on other spheres' triangles leave the sample invalid (face -1: the covering sphere
    provides that direction); with no hit at all, the first front-face hit of the opposite ray is used.
    """
    s, j = wp.tid()
    sid = spheres[s]
    o = centers[sid]
    d = directions[j]
    hit_face[s, j] = -1
    any_hit = int(0)
    start = o
    travelled = float(0.0)
    for _k in range(max_hits):
        q = wp.mesh_query_ray(mesh, start, d, max_t - travelled)
        if not q.result:
            break
        any_hit = 1
        travelled = travelled + q.t
        if q.sign < 0.0 and face_owner[q.face] == sid:
            hit_face[s, j] = q.face
            hit_point[s, j] = o + d * travelled
        # step past the hit; relative epsilon keeps scale invariance
        start = o + d * (travelled * (1.0 + 1.0e-5) + 1.0e-7 * max_t)
    if any_hit == 0:
        q = wp.mesh_query_ray(mesh, o, -d, max_t)
        if q.result and q.sign > 0.0:
            hit_face[s, j] = q.face
            hit_point[s, j] = o - d * q.t


@wp.kernel
def resample_surface(
    sample_face: wp.array2d[wp.int32],
    sample_bary: wp.array2d[wp.vec3],
    faces: wp.array2d[wp.int32],
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    albedo: wp.array[wp.vec3],
    sample_points: wp.array2d[wp.vec3],
    sample_normals: wp.array2d[wp.vec3],
    sample_albedo: wp.array2d[wp.vec3],
):
    """Re-read a surface sample from the current (deformed) mesh by its rest-pose triangle and barycentrics.

    Invalid samples (face -1) get a zero normal, as in the thesis, and zero albedo (black). ``albedo``
    is per vertex (the surface colour environment of §4.3.1, sampled where the sample sits).
    """
    s, j = wp.tid()
    f = sample_face[s, j]
    if f < 0:
        sample_points[s, j] = wp.vec3(0.0)
        sample_normals[s, j] = wp.vec3(0.0)
        sample_albedo[s, j] = wp.vec3(0.0)
        return
    b = sample_bary[s, j]
    i0 = faces[f, 0]
    i1 = faces[f, 1]
    i2 = faces[f, 2]
    sample_points[s, j] = b[0] * points[i0] + b[1] * points[i1] + b[2] * points[i2]
    sample_albedo[s, j] = b[0] * albedo[i0] + b[1] * albedo[i1] + b[2] * albedo[i2]
    n = b[0] * normals[i0] + b[1] * normals[i1] + b[2] * normals[i2]
    ln = wp.length(n)
    if ln > 0.0:
        n = n / ln
    sample_normals[s, j] = n


@wp.kernel
def project_sphere_radiance(
    transfer: wp.array2d[float],
    sample_face: wp.array2d[wp.int32],
    light: wp.array2d[float],
    sample_albedo: wp.array2d[wp.vec3],
    voronoi_sh: wp.array2d[float],
    n2: int,
    radiance: wp.array3d[float],
):
    """Radiance SH vector of sphere ``s``, colour ``c`` (eqs. 4.16–4.20), in the sphere's rest frame.

    ``M_j = (1/π) Σ_i L_i,c T_j,i`` is the white-albedo shadowed exit radiance at sample ``j`` (rows of
    ``transfer``: sample ``s * m + j``); projecting the Voronoi-cell-constant function by the
    precomputed cell sums ``voronoi_sh[j]`` (eq. 4.19), with the albedo sampled at the same point,
    gives ``r = Σ_j albedo_j,c M_j Y_j``: the product with the colour environment of eq. 4.20 taken
    on the same Voronoi cells (no SH-product truncation); invalid directions are black.
    """
    s, c = wp.tid()
    m = sample_face.shape[1]
    for i in range(n2):
        radiance[s, c, i] = 0.0
    for j in range(m):
        if sample_face[s, j] < 0:
            continue
        row = s * m + j
        e = float(0.0)
        for i in range(n2):
            e = e + light[i, c] * transfer[row, i]
        e = e * sample_albedo[s, j][c] / wp.pi
        for i in range(n2):
            radiance[s, c, i] = radiance[s, c, i] + e * voronoi_sh[j, i]


@wp.kernel
def shade_sphere_reflections(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    spheres: wp.array[wp.int32],
    centers: wp.array[wp.vec3],
    radii: wp.array[float],
    rotations: wp.array[wp.mat33],
    radiance: wp.array3d[float],
    log_table: wp.array2d[float],
    ff_table: wp.array2d[float],
    theta_step: float,
    ones: wp.array2d[float],
    cos_zh: wp.array2d[float],
    kz: wp.array[float],
    ol: OLTableArrays,
    products: SHProductTable,
    mode: int,
    tau: float,
    order: int,
    key: wp.array2d[float],
    logsum: wp.array2d[float],
    zbuf: wp.array2d[float],
    e_prev: wp.array2d[float],
    e_new: wp.array2d[float],
    ybuf: wp.array2d[float],
    alt: wp.array2d[float],
    tmp: wp.array2d[float],
    tmp2: wp.array2d[float],
    irradiance: wp.array[wp.vec3],
):
    """Reflected irradiance at receiver ``v`` from every reflecting sphere (eqs. 4.22, 4.25, 4.32, 4.33).

    Spheres (after the tangent-plane rules of §4.2) are taken nearest first; with ``P`` the running sum
    of the closer spheres' log blocker vectors, a sphere's visibility is ``exp(P) - exp(P + G_i)``
    (eq. 4.32), dotted with the clamped cosine (eq. 4.33), times the form-factor average of its
    radiance vector (eq. 4.25; direction taken into the sphere's rest frame, Fig. 4.17).
    """
    v = wp.tid()
    p = points[v]
    n = normals[v]
    n2 = order * order
    ns = spheres.shape[0]
    # keys: distance of the adjusted centre, or -1 when the rules removed the sphere
    for q in range(ns):
        sid = spheres[q]
        a = adjust_sphere(p, n, centers[sid], radii[sid])
        key[v, q] = -1.0
        if a[3] > 0.0:
            key[v, q] = wp.length(wp.vec3(a[0], a[1], a[2]) - p)
    for i in range(n2):
        logsum[v, i] = 0.0
        e_prev[v, i] = 0.0
        ybuf[v, i] = 0.0
    e_prev[v, 0] = SQRT_4PI
    zh_rotate_accumulate(n, cos_zh, 0, 1.0, order, kz, ybuf, v)
    total = wp.vec3(0.0)
    for _step in range(ns):
        # nearest remaining sphere (selection: ns is a few dozen)
        best = int(-1)
        bd = float(0.0)
        for q in range(ns):
            kq = key[v, q]
            if kq >= 0.0 and (best < 0 or kq < bd):
                best = q
                bd = kq
        if best < 0:
            break
        key[v, best] = -1.0
        sid = spheres[best]
        a = adjust_sphere(p, n, centers[sid], radii[sid])
        cvec = wp.vec3(a[0], a[1], a[2])
        d = cvec - p
        theta = wp.asin(wp.min(a[3] / wp.max(bd, 1.0e-30), 1.0))
        lerp_zh_row(log_table, theta, theta_step, ones, 0, order, zbuf, v)
        zh_rotate_accumulate(d, zbuf, v, 1.0, order, kz, logsum, v)
        sh_exp_rows(logsum, v, mode, tau, n2, ol, products, e_new, alt, tmp, tmp2)
        vis = float(0.0)
        for i in range(n2):
            vis = vis + (e_prev[v, i] - e_new[v, i]) * ybuf[v, i]
            e_prev[v, i] = e_new[v, i]
        if vis <= 0.0:
            continue
        # form factor lobe toward the receiver, in the sphere's rest frame
        u = wp.transpose(rotations[sid]) * (p - centers[sid])
        lerp_zh_row(ff_table, theta, theta_step, ones, 0, order, zbuf, v)
        for i in range(n2):
            tmp[v, i] = 0.0
        zh_rotate_accumulate(u, zbuf, v, 1.0, order, kz, tmp, v)
        col = wp.vec3(0.0)
        for c in range(3):
            acc = float(0.0)
            for i in range(n2):
                acc = acc + radiance[best, c, i] * tmp[v, i]
            col[c] = acc
        total = total + vis * col
    # SH ringing of a sharply coloured radiance vector can dip below 0; irradiance cannot
    irradiance[v] = wp.vec3(wp.max(total[0], 0.0), wp.max(total[1], 0.0), wp.max(total[2], 0.0))
