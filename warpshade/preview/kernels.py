"""Warp kernels of the preview ray caster (one primary ray per pixel, no shading: colours are baked)."""

from __future__ import annotations

import warp as wp


@wp.kernel
def cast_primary_rays(
    mesh: wp.uint64,
    faces: wp.array2d[wp.int32],
    colors: wp.array[wp.vec3],
    back_colors: wp.array[wp.vec3],
    eye: wp.vec3,
    forward: wp.vec3,
    right: wp.vec3,
    up: wp.vec3,
    tan_half_fov: float,
    width: int,
    height: int,
    world_up: wp.vec3,
    ground_height: float,
    ground_color: wp.vec3,
    sky_color: wp.vec3,
    max_t: float,
    image: wp.array2d[wp.vec3],
):
    """Per pixel: the hit triangle's barycentric blend of per-vertex ``colors`` (``back_colors`` where the ray
    meets the triangle's back), else the ground
    plane (``dot(p, world_up) = ground_height``, a faint checker so motion reads), else the sky.

    ``image`` has shape (height, width), row 0 at the top, linear RGB.
    """
    y, x = wp.tid()
    aspect = float(width) / float(height)
    sx = (2.0 * (float(x) + 0.5) / float(width) - 1.0) * tan_half_fov * aspect
    sy = (1.0 - 2.0 * (float(y) + 0.5) / float(height)) * tan_half_fov
    d = wp.normalize(forward + sx * right + sy * up)
    q = wp.mesh_query_ray(mesh, eye, d, max_t)
    if q.result:
        i = faces[q.face, 0]
        j = faces[q.face, 1]
        k = faces[q.face, 2]
        w = 1.0 - q.u - q.v
        if q.sign >= 0.0:
            image[y, x] = colors[i] * q.u + colors[j] * q.v + colors[k] * w
        else:
            image[y, x] = back_colors[i] * q.u + back_colors[j] * q.v + back_colors[k] * w
        return
    dn = wp.dot(d, world_up)
    if dn < -1.0e-6:
        t = (ground_height - wp.dot(eye, world_up)) / dn
        if t > 0.0:
            p = eye + d * t
            c = wp.floor(p[0] * 2.0) + wp.floor(p[1] * 2.0) + wp.floor(p[2] * 2.0)
            checker = 0.92 + 0.08 * (c - 2.0 * wp.floor(c * 0.5))
            image[y, x] = ground_color * checker
            return
    image[y, x] = sky_color
