"""Ray helpers shared by the visibility methods: tangent frames, cosine-weighted directions, and rays traced
from a mesh vertex past its own surface (the reference transfer, hemiraster, disks, sphere-set reflections)."""

from __future__ import annotations

import math

import numpy as np
import warp as wp

FRAME_AXIS = wp.constant(wp.vec3(0.4472136, 0.5477226, 0.7071068))
"""``(√2, √3, √5) / √10``: the direction the tangent frames of :func:`orthonormal_basis` turn about, at least
2.8° from every axis, face and body diagonal, 2:1 lattice direction and icosphere vertex or face normal (subdivisions
0-3), so that no normal a mesh is likely to have lies near it."""


@wp.func
def orthonormal_basis(n: wp.vec3) -> wp.mat33:
    """Columns (t, b, n): a right-handed frame around unit ``n`` that turns continuously with ``n``.

    ``t`` is ``FRAME_AXIS × n`` normalised: continuous everywhere but at ``n = ±FRAME_AXIS``, so a normal that
    moves by float rounding (a mesh scaled, or shifted by an ulp) moves its frame, its ray pattern and its
    raster by as little; a frame with a jump at a common normal (Duff et al. 2017 flips at ``n_z = 0``,
    every horizontal normal) there re-draws every sample direction of a vertex. Within 0.006° of the axis
    the frame turns about the x axis instead (a jump, only there)."""
    t = wp.cross(FRAME_AXIS, n)
    lt = wp.length(t)
    if lt < 1.0e-4:
        t = wp.cross(wp.vec3(1.0, 0.0, 0.0), n)
        lt = wp.length(t)
    t = t / lt
    return wp.matrix_from_cols(t, wp.cross(n, t), n)


@wp.func
def concentric_disk(u: float, v: float) -> wp.vec2:
    """Shirley–Chiu concentric map of [0,1)^2 onto the unit disk (area preserving, low distortion)."""
    a = 2.0 * u - 1.0
    b = 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return wp.vec2(0.0, 0.0)
    r = float(0.0)
    phi = float(0.0)
    if a * a > b * b:
        r = a
        phi = (wp.pi / 4.0) * (b / a)
    else:
        r = b
        phi = (wp.pi / 2.0) - (wp.pi / 4.0) * (a / b)
    return wp.vec2(r * wp.cos(phi), r * wp.sin(phi))


@wp.func
def cosine_direction(frame: wp.mat33, u: float, v: float) -> wp.vec3:
    """Cosine-weighted hemisphere direction about ``frame``'s third column for (u, v) in [0,1)^2
    (concentric disk lifted to the hemisphere, pdf ``cos/pi``)."""
    d2 = concentric_disk(u, v)
    z = wp.sqrt(wp.max(0.0, 1.0 - wp.dot(d2, d2)))
    return frame * wp.vec3(d2[0], d2[1], z)


@wp.struct
class SurfaceHit:
    """The surface that blocks a ray (:func:`trace_surface_ray`): ``face`` (-1: none), distance ``t`` along the
    ray, barycentrics ``u, v`` and ``sign`` (> 0: the ray meets the triangle's front, as ``MeshQueryRay.sign``)."""

    face: int
    t: float
    u: float
    v: float
    sign: float


@wp.func
def has_vertex(mesh: wp.uint64, face: int, vertex: int) -> bool:
    """Whether triangle ``face`` of ``mesh`` has corner ``vertex``."""
    return (wp.mesh_get_index(mesh, face * 3) == vertex or wp.mesh_get_index(mesh, face * 3 + 1) == vertex
            or wp.mesh_get_index(mesh, face * 3 + 2) == vertex)


@wp.func
def cross_triangle(mesh: wp.uint64, face: int, start: wp.vec3, d: wp.vec3, length: float, front_only: bool) -> wp.vec4:
    """Where the segment ``start + t d`` (0 <= t <= length) crosses triangle ``face`` (Möller–Trumbore, edges
    inclusive): ``(t, u, v, side)`` with side +1 when it meets the front, -1 the back; t = -1 when it does
    not cross (or, with ``front_only``, meets the back)."""
    a = wp.mesh_get_point(mesh, face * 3)
    e1 = wp.mesh_get_point(mesh, face * 3 + 1) - a
    e2 = wp.mesh_get_point(mesh, face * 3 + 2) - a
    pv = wp.cross(d, e2)
    det = wp.dot(e1, pv)  # = -d · (e1 × e2): > 0 when the ray meets the front
    tiny = 1.0e-7 * wp.length(e1) * wp.length(e2)
    if det <= tiny and (front_only or det >= -tiny):
        return wp.vec4(-1.0, 0.0, 0.0, 0.0)
    s = start - a
    u = wp.dot(s, pv) / det
    q = wp.cross(s, e1)
    v = wp.dot(d, q) / det
    t = wp.dot(e2, q) / det
    tol = 1.0e-6  # barycentric slack: a point on a shared edge belongs to both triangles
    if u < -tol or v < -tol or u + v > 1.0 + tol or t < 0.0 or t > length:
        return wp.vec4(-1.0, 0.0, 0.0, 0.0)
    return wp.vec4(t, u, v, wp.where(det > 0.0, 1.0, -1.0))


@wp.func
def under_corner(mesh: wp.uint64, f: int, p: wp.vec3, n: wp.vec3, d: wp.vec3) -> wp.vec4:
    """Whether triangle ``f``, one of the receiver's own with a corner at ``p``, blocks the ray from ``p`` along
    ``d`` as seen from ``p`` lifted along its unit normal ``n``: ``d`` lies in the cone spanned by the two
    edges at that corner and ``-n`` (edges inclusive). Then the triangle blocks it at the start,
    ``(0, u, v, +1)`` with ``(u, v)`` the corner's barycentrics as :func:`cross_triangle` gives them; else t = -1.

    This is the limit, as the lift goes to zero, of testing ``f`` from ``p + lift n``: the rays from there to
    the points of ``f`` near its corner fill that cone (``-n`` reaches the corner itself). It depends on
    directions only, so it does not change when the mesh is scaled or rounded (a finite lift made rays
    nearly in ``f``'s plane flip with the rounding of ``p``, which is a sizeable fraction of the lift). Where
    the surface folds up around the vertex (valleys, creases) the cone rises above the horizon; where it folds
    down (ridges, the outside of a fold) it stays below."""
    a = wp.mesh_get_point(mesh, f * 3)
    b = wp.mesh_get_point(mesh, f * 3 + 1)
    c = wp.mesh_get_point(mesh, f * 3 + 2)
    # the corner at p (the nearest one), with the other two in the triangle's cyclic order
    e1 = b - a
    e2 = c - a
    cu = float(0.0)
    cv = float(0.0)
    da = wp.length_sq(a - p)
    db = wp.length_sq(b - p)
    dc = wp.length_sq(c - p)
    if db < da and db <= dc:
        e1 = c - b
        e2 = a - b
        cu = 1.0
    elif dc < da and dc < db:
        e1 = a - c
        e2 = b - c
        cv = 1.0
    # d = x e1 + y e2 + z (-n) with x, y, z >= 0 (Cramer's rule; det = 0: a flat cone, no solid angle)
    m = -n
    det = wp.dot(e1, wp.cross(e2, m))
    x = wp.dot(d, wp.cross(e2, m)) * det
    y = wp.dot(d, wp.cross(m, e1)) * det
    z = wp.dot(d, wp.cross(e1, e2)) * det
    if det != 0.0 and x >= 0.0 and y >= 0.0 and z >= 0.0:
        return wp.vec4(0.0, cu, cv, 1.0)
    return wp.vec4(-1.0, 0.0, 0.0, 0.0)


@wp.func
def continues_surface(mesh: wp.uint64, f: int, p: wp.vec3, n: wp.vec3) -> bool:
    """Whether triangle ``f`` has a corner exactly at ``p`` and faces within 120° of normal ``n``: the receiver's
    own surface through a duplicated vertex (a seam, split normals), not a surface it rests on."""
    a = wp.mesh_get_point(mesh, f * 3)
    b = wp.mesh_get_point(mesh, f * 3 + 1)
    c = wp.mesh_get_point(mesh, f * 3 + 2)
    if wp.length_sq(a - p) > 0.0 and wp.length_sq(b - p) > 0.0 and wp.length_sq(c - p) > 0.0:
        return False
    nf = wp.cross(b - a, c - a)
    return wp.dot(nf, n) > -0.5 * wp.length(nf)


@wp.func
def own_surface(mesh: wp.uint64, f: int, vertex: int, p: wp.vec3, n: wp.vec3) -> bool:
    """Whether triangle ``f`` is part of the receiver's own surface at ``p``: one of ``vertex``'s triangles, or
    one through a duplicate of it (:func:`continues_surface`)."""
    return (vertex >= 0 and has_vertex(mesh, f, vertex)) or continues_surface(mesh, f, p, n)


NEAR_FACES = 16
"""Triangles near a vertex kept per vertex (:class:`NearFaces`: its own triangles and any other within the
near-field distance); with more, every ray queries the BVH for them itself."""


class vec_near(wp.types.vector(length=NEAR_FACES, dtype=wp.int32)):
    pass


@wp.struct
class NearFaces:
    """Triangles whose bounds come within ``eps`` of a receiver point, the only ones :func:`trace_surface_ray`
    tests in the near field: ``f`` for another surface's, ``-1 - f`` for the receiver's own (:func:`own_surface`).
    ``count`` > ``NEAR_FACES``: too many to keep. ``tilt``: sine of the largest angle between the receiver's
    normal and its own triangles' (1 past 90°): a ray with ``d · n >= tilt`` points to the front of every one
    of them, so none can block it."""

    faces: vec_near
    count: int
    tilt: float


@wp.func
def near_faces(mesh: wp.uint64, vertex: int, p: wp.vec3, n: wp.vec3, eps: float) -> NearFaces:
    """The :class:`NearFaces` of receiver point ``p`` with unit normal ``n`` (``vertex``: its index in ``mesh``,
    or -1), gathered once for all its rays."""
    out = NearFaces()
    out.count = 0
    out.tilt = 0.0
    e = wp.vec3(eps, eps, eps)
    query = wp.mesh_query_aabb(mesh, p - e, p + e)
    f = int(0)
    faces = vec_near()
    while wp.mesh_query_aabb_next(query, f):
        own = own_surface(mesh, f, vertex, p, n)
        if own:
            a = wp.mesh_get_point(mesh, f * 3)
            nf = wp.cross(wp.mesh_get_point(mesh, f * 3 + 1) - a, wp.mesh_get_point(mesh, f * 3 + 2) - a)
            lf = wp.length(nf)
            if lf > 0.0:
                c = wp.dot(nf, n) / lf
                out.tilt = wp.max(out.tilt, wp.where(c > 0.0, wp.sqrt(wp.max(0.0, 1.0 - c * c)), 1.0))
        if out.count < NEAR_FACES:
            faces[out.count] = wp.where(own, -1 - f, f)
        out.count += 1
    out.faces = faces
    return out


@wp.func
def near_crossing(mesh: wp.uint64, f: int, own: bool, p: wp.vec3, n: wp.vec3, d: wp.vec3, eps: float,
                  max_t: float) -> wp.vec4:
    """Where triangle ``f`` blocks the ray by the near-field rules of :func:`trace_surface_ray`: ``(t, u, v, side)``
    as :func:`cross_triangle`, t = -1 when it does not."""
    if own:
        return under_corner(mesh, f, p, n, d)
    return cross_triangle(mesh, f, p - d * eps, d, 2.0 * eps, True)


OWN_GRAZES = 4
"""Far hits on the receiver's own surface a ray passes (:func:`trace_surface_ray`) before it counts as open."""


@wp.func
def skip_own(near: NearFaces, n: wp.vec3, d: wp.vec3) -> bool:
    """Whether no triangle of the receiver's own surface can block ``d`` (it points to the front of all)."""
    return wp.dot(d, n) >= near.tilt


@wp.func
def trace_surface_ray(mesh: wp.uint64, vertex: int, p: wp.vec3, n: wp.vec3, d: wp.vec3, eps: float, max_t: float,
                      near: NearFaces) -> SurfaceHit:
    """The surface that blocks a ray leaving the surface point ``p`` (unit normal ``n``) along unit ``d``
    within ``max_t``.

    ``p`` lies on the mesh (``vertex``: its index in ``mesh``, or -1 when it is no vertex of it) and maybe
    exactly on another surface too (an object resting on a ground). Pushing the ray origin ``eps`` off along
    the normal, the usual cure for self-intersection, moves it through such a surface whenever the normal
    leans into it (the rim of a box standing on the ground: its rays then start under the ground and see
    the wrong half of the sky). So the receiver's own surface at ``p`` (``vertex``'s triangles, and triangles
    through a duplicate of it facing the side of ``n``, :func:`own_surface`) blocks exactly the rays that start
    under it (:func:`under_corner`: it folds up around the vertex, valleys, creases) and is passed further
    on (a ray from a triangle's corner meets its plane nowhere else; a far hit on it is rounding); another
    surface within ``eps`` of ``p`` blocks if the ray enters its front there (the ground under a vertex, for
    rays going down; a ray leaving a surface through its back started on it and is let go); and from
    ``p + eps d`` on, the first hit blocks whichever side it meets (open meshes such as cloth block from
    both). ``eps`` is a length, a small fraction of the scene's size; ``near`` comes from
    :func:`near_faces` with the same ``mesh``, ``vertex``, ``p``, ``n`` and ``eps``.
    """
    best = wp.vec4(-1.0, 0.0, 0.0, 0.0)
    face = int(-1)
    if near.count <= NEAR_FACES:
        for k in range(near.count):
            f = near.faces[k]
            own = f < 0
            if own:
                f = -1 - f
            if not (own and skip_own(near, n, d)):
                c = near_crossing(mesh, f, own, p, n, d, eps, max_t)
                if c[0] >= 0.0 and (face < 0 or c[0] < best[0]):
                    best = c
                    face = f
    else:
        e = wp.vec3(eps, eps, eps)
        query = wp.mesh_query_aabb(mesh, p - e, p + e)
        f = int(0)
        while wp.mesh_query_aabb_next(query, f):
            c = near_crossing(mesh, f, own_surface(mesh, f, vertex, p, n), p, n, d, eps, max_t)
            if c[0] >= 0.0 and (face < 0 or c[0] < best[0]):
                best = c
                face = f
    hit = SurfaceHit()
    hit.face = face
    if face >= 0:
        hit.t = best[0]
        hit.u = best[1]
        hit.v = best[2]
        hit.sign = best[3]
        return hit
    # A ray from a corner of a triangle meets its plane only at the start (:func:`under_corner`), so a far hit
    # on the receiver's own surface is a ray grazing that triangle's plane, decided by rounding: pass it.
    start = eps
    for _ in range(OWN_GRAZES):
        q = wp.mesh_query_ray(mesh, p + d * start, d, max_t)
        if not q.result:
            return hit
        if not own_surface(mesh, q.face, vertex, p, n):
            hit.face = q.face
            hit.t = q.t + start
            hit.u = q.u
            hit.v = q.v
            hit.sign = q.sign
            return hit
        start = start + q.t + eps
    return hit


EPS_REL = 128.0 * 2.0 ** -24
"""The near-field distance of :func:`trace_surface_ray` is at least this fraction of the receiver point's largest
coordinate (:func:`ray_eps`): 64-128 float32 spacings of it."""


def local_origin(points: np.ndarray) -> np.ndarray:
    """Where to put the origin of the coordinates rays are traced in: the centre of ``points``' bounding box,
    rounded per axis to a multiple of the power of two at or above the box's diagonal (float64, shape (3,)).

    Float32 coordinates resolve a scene to a fraction of their magnitude (an ulp, 6e-5 at 1000 units), not of
    the scene's size: relative to this origin, a scene far from the world origin keeps the resolution it has
    at the origin (the shift is exact or adds rounding far below the scene's own). A box within half a
    diagonal of the world origin gets 0 on that axis and is traced in the coordinates it was given."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not len(pts):
        return np.zeros(3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    step = 2.0 ** math.ceil(math.log2(float(np.linalg.norm(hi - lo)) or 1.0))
    return np.round(0.5 * (lo + hi) / step) * step


@wp.func
def ray_eps(eps: float, p: wp.vec3) -> float:
    """The near-field distance of rays from point ``p`` (in the coordinates rays are traced in): ``eps``, but at
    least :data:`EPS_REL` of ``p``'s largest coordinate, above the float32 rounding of the surfaces there (below
    it a ray from ``p + eps d`` starts at ``p`` or behind it, on the surface it leaves, which blocks it)."""
    return wp.max(eps, float(EPS_REL) * wp.max(wp.abs(p[0]), wp.max(wp.abs(p[1]), wp.abs(p[2]))))
