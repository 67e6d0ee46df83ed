"""Warp kernels of one-bounce diffuse reflections from sphere sets (thesis §4.3, ch. 5).

``trace_sphere_samples`` (once, rest pose) finds each sphere's surface sample points (eqs. 4.12–4.13
with the three hit rules of §4.3.1); ``resample_surface`` re-reads them from the deformed mesh every
frame (beyond the thesis, which handles rigid objects only); ``project_sphere_radiance`` builds the
radiance SH vectors (eqs. 4.16–4.20); the per-receiver sum of eq. 4.22 (average sphere radiance by
form factor, eqs. 4.24–4.25, times the sphere visibility as a difference of two exponentials, eqs.
4.32, 4.33) is the kernel ``reflect`` of :mod:`.fixed_kernels`. Orchestration: :mod:`.reflections`.
"""

from __future__ import annotations

import warp as wp

from ..rays import cosine_direction, near_faces, orthonormal_basis, trace_surface_ray


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
    given: int,
    radiance: wp.array3d[float],
):
    """Radiance SH vector of sphere ``s``, colour ``c`` (eqs. 4.16–4.20), in the sphere's rest frame.

    ``M_j = (1/π) Σ_i L_i,c T_j,i`` is the white-albedo shadowed exit radiance at sample ``j`` (rows of
    ``transfer``: sample ``s * m + j``); projecting the Voronoi-cell-constant function by the
    precomputed cell sums ``voronoi_sh[j]`` (eq. 4.19), with the albedo sampled at the same point,
    gives ``r = Σ_j albedo_j,c M_j Y_j``: the product with the colour environment of eq. 4.20 taken
    on the same Voronoi cells (no SH-product truncation); invalid directions are black. With ``given``
    the resampled ``sample_albedo`` already is the sample's exit radiance (albedo included).
    """
    s, c = wp.tid()
    m = sample_face.shape[1]
    for i in range(n2):
        radiance[s, c, i] = 0.0
    for j in range(m):
        if sample_face[s, j] < 0:
            continue
        e = sample_albedo[s, j][c]
        if given == 0:
            row = s * m + j
            t = float(0.0)
            for i in range(n2):
                t = t + light[i, c] * transfer[row, i]
            e = e * t / wp.pi
        for i in range(n2):
            radiance[s, c, i] = radiance[s, c, i] + e * voronoi_sh[j, i]


@wp.kernel
def trace_bounce(
    mesh: wp.uint64,
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    vertex_ids: wp.array[int],
    strata: int,
    offset: float,
    max_t: float,
    seed: int,
    irradiance: wp.array[wp.vec3],
):
    """Ray-traced reflected irradiance ``E_R(p) = ∫ L_o(hit(p, ω)) max(0, n·ω) dω`` at receiver ``v``
    (``vertex_ids[v]``: the mesh vertex at the receiver, whose own triangles do not block it, or -1).

    ``mesh`` carries the exit radiance of every vertex in its velocities (interpolated at the hit by
    ``mesh_eval_velocity``); back-face hits (the inside of a closed object) reflect nothing. Stratified
    cosine-weighted directions as the reference transfer: estimator ``(π/N) Σ L_o``.
    """
    v = wp.tid()
    n = normals[v]
    frame = orthonormal_basis(n)
    near = near_faces(mesh, vertex_ids[v], points[v], n, offset)
    rng = wp.rand_init(seed, v)
    acc = wp.vec3(0.0)
    for sx in range(strata):
        for sy in range(strata):
            u = (float(sx) + wp.randf(rng)) / float(strata)
            w = (float(sy) + wp.randf(rng)) / float(strata)
            # the same rays as the reference transfer (trace_surface_ray: no origin pushed through a surface
            # the receiver rests on)
            q = trace_surface_ray(mesh, vertex_ids[v], points[v], n, cosine_direction(frame, u, w), offset, max_t,
                                  near)
            if q.face >= 0 and q.sign > 0.0:
                acc = acc + wp.mesh_eval_velocity(mesh, q.face, q.u, q.v)
    irradiance[v] = acc * (wp.pi / float(strata * strata))
