"""Warp kernels: cloth vertices against kinematic colliders (analytic shapes and triangle meshes).

Each collider is given at the start and at the end of a step; a substep sees the linear
interpolation of the two, so fast colliders sweep through the substeps instead of teleporting.
Contacts push the vertex out to ``thickness`` from the surface along the surface normal, then
apply position-based Coulomb friction (Macklin et al. 2014, eq. 24-25) on the displacement of the
vertex relative to the collider's surface point over the substep.
"""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

from .kernels import closest_on_triangle, closest_segments, push_candidate, stored_side

SHAPE_PLANE = wp.constant(0)
SHAPE_SPHERE = wp.constant(1)
SHAPE_CAPSULE = wp.constant(2)
SHAPE_BOX = wp.constant(3)
SHAPE_CYLINDER = wp.constant(4)
SHAPE_CONE = wp.constant(5)

FLAT_EDGE_COS = wp.constant(0.9999)
"""Mesh-collider edges whose two faces' normals have a cosine above this (bent by less than
0.8 degrees) are flat: the inner edges of a tessellated box face, which the vertex projection
already holds (pushing along them would lift cloth hanging beside the face's border)."""


@wp.func
def segment_parameter(p: wp.vec3, a: wp.vec3, b: wp.vec3) -> float:
    """Parameter in [0, 1] of the point of segment a-b closest to p (0 for a degenerate segment)."""
    ab = b - a
    l2 = wp.length_sq(ab)
    if l2 == 0.0:
        return 0.0
    return wp.clamp(wp.dot(p - a, ab) / l2, 0.0, 1.0)


@wp.func
def axial_frame(p: wp.vec3, a: wp.vec3, b: wp.vec3) -> wp.vec4:
    """The meridian half-plane of p around the axis a -> b: vec4(ex, ey, ez, h), e the unit radial
    direction of p (any perpendicular on the axis) and h its height above a along the axis."""
    u = wp.normalize(b - a)
    h = wp.dot(p - a, u)
    rv = (p - a) - u * h
    lr = wp.length(rv)
    e = wp.vec3(0.0)
    if lr > 0.0:
        e = rv / lr
    else:
        # on the axis: any direction perpendicular to u
        t = wp.vec3(1.0, 0.0, 0.0)
        if wp.abs(u[0]) > 0.9:
            t = wp.vec3(0.0, 1.0, 0.0)
        e = wp.normalize(wp.cross(u, t))
    return wp.vec4(e[0], e[1], e[2], h)


@wp.func
def segment2_closest(q: wp.vec2, s0: wp.vec2, s1: wp.vec2) -> wp.vec2:
    """Point of the 2-D segment s0-s1 closest to q."""
    d = s1 - s0
    if wp.dot(d, d) == 0.0:
        return s0
    t = wp.clamp(wp.dot(q - s0, d) / wp.dot(d, d), 0.0, 1.0)
    return s0 + d * t


@wp.func
def meridian_distance(q: wp.vec2, c0: wp.vec2, c1: wp.vec2, c2: wp.vec2, c3: wp.vec2, n01: wp.vec2,
                      n12: wp.vec2, n23: wp.vec2, inside: bool) -> wp.vec3:
    """Signed distance of q = (r, h) to the surface part c0-c1-c2-c3 of a solid of revolution's
    half-section (the axis closes it) and the 2-D outward normal: vec3(nr, nh, d). The normal is
    the edge normal in an edge's interior and the direction from the nearest corner outside it
    (a sharp rim's normal fan)."""
    best = float(1.0e30)
    cp = wp.vec2(0.0)
    en = wp.vec2(0.0)
    p01 = segment2_closest(q, c0, c1)
    d01 = wp.length(q - p01)
    if d01 < best:
        best = d01
        cp = p01
        en = n01
    p12 = segment2_closest(q, c1, c2)
    d12 = wp.length(q - p12)
    if d12 < best:
        best = d12
        cp = p12
        en = n12
    p23 = segment2_closest(q, c2, c3)
    d23 = wp.length(q - p23)
    if d23 < best:
        best = d23
        cp = p23
        en = n23
    if inside:
        return wp.vec3(en[0], en[1], -best)
    n = en
    if best > 1.0e-9:
        n = (q - cp) / best
    return wp.vec3(n[0], n[1], best)


@wp.func
def shape_distance(kind: int, p: wp.vec3, a: wp.vec3, b: wp.vec3, rot: wp.quat, size: wp.vec3) -> wp.vec4:
    """Signed distance [m] of p to a shape and the outward unit normal: vec4(nx, ny, nz, d).

    plane: a point on it, b its normal; sphere: a centre, size[0] radius; capsule: segment a-b,
    size[0] radius; box: a centre, rot orientation, size half extents; cylinder: a and b the
    centres of its two caps, size[0] radius; cone: a the centre of its base, b its apex, size[0]
    the base radius. Cylinders and cones are exact solids of revolution with flat caps: the
    distance in the meridian half-plane to the caps and the side, sharp rims included.
    """
    if kind == SHAPE_PLANE:
        n = wp.normalize(b)
        return wp.vec4(n[0], n[1], n[2], wp.dot(p - a, n))
    if kind == SHAPE_SPHERE:
        d = p - a
        ld = wp.length(d)
        n = wp.vec3(0.0, 1.0, 0.0)
        if ld > 0.0:
            n = d / ld
        return wp.vec4(n[0], n[1], n[2], ld - size[0])
    if kind == SHAPE_CAPSULE:
        d = p - wp.lerp(a, b, segment_parameter(p, a, b))
        ld = wp.length(d)
        n = wp.vec3(0.0, 1.0, 0.0)
        if ld > 0.0:
            n = d / ld
        return wp.vec4(n[0], n[1], n[2], ld - size[0])
    if kind == SHAPE_CYLINDER or kind == SHAPE_CONE:
        fr = axial_frame(p, a, b)
        e = wp.vec3(fr[0], fr[1], fr[2])
        h = fr[3]
        length = wp.length(b - a)
        u = (b - a) / length
        r = wp.length((p - a) - u * h)
        rad = size[0]
        q2 = wp.vec2(r, h)
        md = wp.vec3(0.0)
        if kind == SHAPE_CYLINDER:
            inside = r <= rad and h >= 0.0 and h <= length
            md = meridian_distance(q2, wp.vec2(0.0, 0.0), wp.vec2(rad, 0.0), wp.vec2(rad, length),
                                   wp.vec2(0.0, length), wp.vec2(0.0, -1.0), wp.vec2(1.0, 0.0),
                                   wp.vec2(0.0, 1.0), inside)
        else:
            inside = h >= 0.0 and r * length + h * rad <= rad * length
            sl = wp.normalize(wp.vec2(length, rad))
            # the apex segment c2-c3 is degenerate (both the apex): the side ends there
            md = meridian_distance(q2, wp.vec2(0.0, 0.0), wp.vec2(rad, 0.0), wp.vec2(0.0, length),
                                   wp.vec2(0.0, length), wp.vec2(0.0, -1.0), sl, sl, inside)
        n = e * md[0] + u * md[1]
        return wp.vec4(n[0], n[1], n[2], md[2])
    # box: distance in the box frame (Quilez' exact box SDF), normal from the closest feature
    lp = wp.quat_rotate_inv(rot, p - a)
    q = wp.vec3(wp.abs(lp[0]) - size[0], wp.abs(lp[1]) - size[1], wp.abs(lp[2]) - size[2])
    outside = wp.max(q, wp.vec3(0.0))
    lo = wp.length(outside)
    ln = wp.vec3(0.0)
    bd = float(0.0)
    if lo > 0.0:
        ln = wp.vec3(wp.sign(lp[0]) * outside[0], wp.sign(lp[1]) * outside[1], wp.sign(lp[2]) * outside[2]) / lo
        bd = lo
    else:
        # inside: leave through the nearest face
        if q[0] >= q[1] and q[0] >= q[2]:
            ln = wp.vec3(wp.sign(lp[0]), 0.0, 0.0)
            bd = q[0]
        elif q[1] >= q[2]:
            ln = wp.vec3(0.0, wp.sign(lp[1]), 0.0)
            bd = q[1]
        else:
            ln = wp.vec3(0.0, 0.0, wp.sign(lp[2]))
            bd = q[2]
    n = wp.quat_rotate(rot, ln)
    return wp.vec4(n[0], n[1], n[2], bd)


@wp.func
def shape_point_motion(kind: int, p: wp.vec3, a0: wp.vec3, a1: wp.vec3, b0: wp.vec3, b1: wp.vec3,
                       r0: wp.quat, r1: wp.quat) -> wp.vec3:
    """Displacement over the substep of the surface point attached to p (pose 0 -> pose 1)."""
    if kind == SHAPE_CAPSULE or kind == SHAPE_CYLINDER or kind == SHAPE_CONE:
        t = segment_parameter(p, a1, b1)
        return wp.lerp(a1, b1, t) - wp.lerp(a0, b0, t)
    if kind == SHAPE_BOX:
        local = wp.quat_rotate_inv(r1, p - a1)
        return p - (a0 + wp.quat_rotate(r0, local))
    return a1 - a0


@wp.func
def apply_friction(dx: wp.vec3, n: wp.vec3, depth: float, mu: float) -> wp.vec3:
    """Tangential correction for a relative displacement dx after a push of `depth` (eq. 24-25)."""
    dt_ = dx - n * wp.dot(dx, n)
    lt = wp.length(dt_)
    if lt <= mu * depth:
        return -dt_
    return -dt_ * (mu * depth / lt)


@wp.kernel
def pose_shapes(
    a_start: wp.array[wp.vec3],
    a_end: wp.array[wp.vec3],
    b_start: wp.array[wp.vec3],
    b_end: wp.array[wp.vec3],
    rot_start: wp.array[wp.quat],
    rot_end: wp.array[wp.quat],
    alpha0: float,
    alpha1: float,
    a0: wp.array[wp.vec3],
    a1: wp.array[wp.vec3],
    b0: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    r0: wp.array[wp.quat],
    r1: wp.array[wp.quat],
):
    """Shape poses at the start (alpha0) and end (alpha1) of a substep, once per substep."""
    s = wp.tid()
    a0[s] = wp.lerp(a_start[s], a_end[s], alpha0)
    a1[s] = wp.lerp(a_start[s], a_end[s], alpha1)
    b0[s] = wp.lerp(b_start[s], b_end[s], alpha0)
    b1[s] = wp.lerp(b_start[s], b_end[s], alpha1)
    r0[s] = wp.normalize(wp.quat_slerp(rot_start[s], rot_end[s], alpha0))
    r1[s] = wp.normalize(wp.quat_slerp(rot_start[s], rot_end[s], alpha1))


@wp.kernel
def collide_shapes(
    kind: wp.array[int],
    a0: wp.array[wp.vec3],
    a1: wp.array[wp.vec3],
    b0: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    r0: wp.array[wp.quat],
    r1: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    friction: wp.array[float],
    thickness: float,
    passes: int,
    inv_mass: wp.array[float],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Push each free vertex out of every analytic shape posed (a1, b1, r1) at the substep's end;
    (a0, b0, r0), the pose at its start, gives the surface motion for friction. ``passes`` passes
    over the shapes, the same as as many launches of one pass (a vertex depends on itself only);
    after a pass that pushed the vertex nowhere, the rest would repeat it and are not run."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p = x[i]
    for _pass in range(passes):
        pushed = bool(False)
        for s in range(kind.shape[0]):
            k = kind[s]
            sd = shape_distance(k, p, a1[s], b1[s], r1[s], size[s])
            depth = thickness - sd[3]
            if depth > 0.0:
                pushed = True
                n = wp.vec3(sd[0], sd[1], sd[2])
                p = p + n * depth
                motion = shape_point_motion(k, p, a0[s], a1[s], b0[s], b1[s], r0[s], r1[s])
                p = p + apply_friction((p - x_prev[i]) - motion, n, depth, friction[s])
        if not pushed:
            break
    x[i] = p


@wp.kernel
def interpolate_points(
    start: wp.array[wp.vec3],
    end: wp.array[wp.vec3],
    alpha: float,
    out: wp.array[wp.vec3],
):
    """out = lerp(start, end, alpha)."""
    i = wp.tid()
    out[i] = wp.lerp(start[i], end[i], alpha)


@wp.func
def open_mesh_side(
    mesh: wp.uint64,
    points_ref: wp.array[wp.vec3],
    tris: wp.array[int],
    moved: int,
    p: wp.vec3,
    max_distance: float,
) -> float:
    """The side (+1 along the face normals, -1 against) of an open mesh that point p was on when
    the mesh was posed as ``points_ref``, found against the mesh's current pose (``mesh``): the
    side of p's nearest face; when the mesh has moved since (``moved``), p is first carried along
    by the surface's move at its nearest point, so a surface that moved past p since does not put
    it on the far side. +1 when no face is within ``max_distance``."""
    side = float(1.0)
    q0 = wp.mesh_query_point_no_sign(mesh, p, max_distance)
    if q0.result:
        c0 = wp.mesh_eval_position(mesh, q0.face, q0.u, q0.v)
        if moved != 0:
            w0 = 1.0 - q0.u - q0.v
            r0 = (points_ref[tris[3 * q0.face]] * q0.u + points_ref[tris[3 * q0.face + 1]] * q0.v
                  + points_ref[tris[3 * q0.face + 2]] * w0)
            pc = p + (c0 - r0)
            q1 = wp.mesh_query_point_no_sign(mesh, pc, max_distance)
            if q1.result:
                c1 = wp.mesh_eval_position(mesh, q1.face, q1.u, q1.v)
                if wp.dot(pc - c1, wp.mesh_eval_face_normal(mesh, q1.face)) < 0.0:
                    side = -1.0
        elif wp.dot(p - c0, wp.mesh_eval_face_normal(mesh, q0.face)) < 0.0:
            side = -1.0
    return side


@wp.kernel
def collide_mesh(
    mesh: wp.uint64,
    points_prev: wp.array[wp.vec3],
    tris: wp.array[int],
    closed: int,
    max_distance: float,
    thickness: float,
    friction: float,
    inv_mass: wp.array[float],
    x_prev: wp.array[wp.vec3],
    points_ref: wp.array[wp.vec3],
    moved: int,
    x: wp.array[wp.vec3],
):
    """Push each free vertex out of a triangle mesh.

    A closed mesh (or a union of overlapping closed parts) is a solid: inside/outside comes from
    the generalised winding number (Barill et al. 2018), which stays right for unions of
    overlapping closed parts such as a character built from limbs, where the normal-based sign is
    wrong near the overlaps. An open mesh (a ground sheet, a wall) has no inside: it is a
    two-sided shell, and each vertex is kept `thickness` away on the side of the closest face it
    was on at the start of the substep (x_prev). The winding number of an open sheet is only
    +-1/2 on its two sides, so the solid test would let a vertex through. `points_prev` is the
    mesh at the previous substep, to move the contact point with the surface for friction.
    `points_ref` is the open mesh as posed when the vertices were at x_prev and `moved` says
    whether it differs from the current pose (:func:`open_mesh_side`: a surface that moved past
    x_prev since would otherwise put the vertex on its far side, and push it through).
    """
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p = x[i]
    face = int(0)
    u = float(0.0)
    v = float(0.0)
    cp = wp.vec3(0.0)
    n = wp.vec3(0.0)
    sd = float(0.0)
    if closed != 0:
        q = wp.mesh_query_point_sign_winding_number(mesh, p, max_distance, 2.0, 0.5)
        if not q.result:
            return
        face = q.face
        u = q.u
        v = q.v
        cp = wp.mesh_eval_position(mesh, face, u, v)
        d = p - cp
        ld = wp.length(d)
        if ld > 1.0e-9:
            n = d * (q.sign / ld)
        else:
            n = wp.normalize(wp.mesh_eval_face_normal(mesh, face))
        sd = q.sign * ld
    else:
        q = wp.mesh_query_point_no_sign(mesh, p, max_distance)
        if not q.result:
            return
        face = q.face
        u = q.u
        v = q.v
        # the side: where the vertex was at the start of the substep, against its closest face then
        side = open_mesh_side(mesh, points_ref, tris, moved, x_prev[i], max_distance + wp.length(p - x_prev[i]))
        n = wp.mesh_eval_face_normal(mesh, face) * side
        cp = wp.mesh_eval_position(mesh, face, u, v)
        sd = wp.length(p - cp)
        if wp.dot(p - cp, n) < 0.0:
            sd = -sd
    depth = thickness - sd
    if depth <= 0.0:
        return
    p = cp + n * thickness
    w = 1.0 - u - v
    cp0 = points_prev[tris[3 * face]] * u + points_prev[tris[3 * face + 1]] * v + points_prev[tris[3 * face + 2]] * w
    x[i] = p + apply_friction((p - x_prev[i]) - (cp - cp0), n, depth, friction)


@wp.kernel
def collide_mesh_edges(
    mesh: wp.uint64,
    mesh_points: wp.array[wp.vec3],
    mesh_tris: wp.array[int],
    tri_edges: wp.array2d[int],
    edge_verts: wp.array2d[int],
    edge_faces: wp.array2d[int],
    x: wp.array[wp.vec3],
    edges: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth edges against a mesh collider's sharp edges: a cloth edge whose inner point dips into
    the thickness layer around a collider edge (below both adjacent faces' offset planes, within 4
    thicknesses of the edge and closest to an inner point of it) is pushed out along the face it
    is least deep under. Flat edges (faces within FLAT_EDGE_COS) are left to the vertex projection. This is what
    keeps a sharp box edge from cutting through a cloth edge whose two vertices are outside."""
    k = wp.tid()
    i0 = edges[k, 0]
    i1 = edges[k, 1]
    w0 = inv_mass[i0]
    w1 = inv_mass[i1]
    if w0 + w1 == 0.0:
        return
    a = x[i0]
    b = x[i1]
    lo = wp.min(a, b) - wp.vec3(thickness)
    hi = wp.max(a, b) + wp.vec3(thickness)
    query = wp.mesh_query_aabb(mesh, lo, hi)
    f = int(0)
    while wp.mesh_query_aabb_next(query, f):
        for c in range(3):
            e = tri_edges[f, c]
            if edge_faces[e, 0] != f:
                continue  # each collider edge once, from its first face
            m0 = mesh_points[edge_verts[e, 0]]
            m1 = mesh_points[edge_verts[e, 1]]
            st = closest_segments(a, b, m0, m1)
            s = st[0]
            if s <= 0.0 or s >= 1.0:
                continue  # a cloth vertex is closest: the vertex projection holds it
            if st[1] <= 0.0 or st[1] >= 1.0:
                continue  # beyond the collider edge's ends, below its faces' planes is not inside
            p = a + (b - a) * s
            q = m0 + (m1 - m0) * st[1]
            if wp.length(p - q) > 4.0 * thickness:
                continue
            fa = edge_faces[e, 0]
            na = wp.normalize(wp.cross(mesh_points[mesh_tris[3 * fa + 1]] - mesh_points[mesh_tris[3 * fa]],
                                       mesh_points[mesh_tris[3 * fa + 2]] - mesh_points[mesh_tris[3 * fa]]))
            n = na
            da = wp.dot(p - q, na)
            d = da
            fb = edge_faces[e, 1]
            if fb >= 0:
                nb = wp.normalize(wp.cross(mesh_points[mesh_tris[3 * fb + 1]] - mesh_points[mesh_tris[3 * fb]],
                                           mesh_points[mesh_tris[3 * fb + 2]] - mesh_points[mesh_tris[3 * fb]]))
                if wp.dot(na, nb) > FLAT_EDGE_COS:
                    continue  # a flat edge (inside a face of a box): the vertex projection holds it
                db = wp.dot(p - q, nb)
                if db >= thickness:
                    continue
                if db > da:
                    n = nb
                    d = db
            if da >= thickness:
                continue
            denom = (1.0 - s) * (1.0 - s) * w0 + s * s * w1
            if denom == 0.0:
                continue
            g = n * ((thickness - d) / denom)
            wp.atomic_add(delta, i0, g * ((1.0 - s) * w0))
            wp.atomic_add(delta, i1, g * (s * w1))
            wp.atomic_add(delta_count, i0, 1.0)
            wp.atomic_add(delta_count, i1, 1.0)


SHARP_EDGE_COS = wp.constant(0.766)
"""Closed-mesh edges whose two faces' normals have a cosine below this (turned by more than 40
degrees: a box's edges, 90) are pushed out of cloth triangles by :func:`collide_mesh_edge_faces`;
the gentler edges of a tessellated ball (a 1280-triangle sphere's: about 10 degrees) are left to the
vertex and edge passes."""


@wp.kernel
def mesh_sharp_edges(
    mesh_points: wp.array[wp.vec3],
    mesh_tris: wp.array[int],
    tri_edges: wp.array2d[int],
    edge_verts: wp.array2d[int],
    edge_faces: wp.array2d[int],
    edge_normals: wp.array2d[wp.vec3],
    tri_sharp: wp.array2d[int],
):
    """The sharp convex edges of a closed mesh collider as posed (``mesh_points``), the table
    :func:`collide_mesh_edge_faces` reads. One thread per collider triangle ``f``; for each of its
    sides ``ce``, ``tri_sharp[f, ce]`` is the side's edge ``e`` when ``f`` is the edge's first face
    and the edge is sharp (its faces turned by more than :data:`SHARP_EDGE_COS`) and convex, else -1
    (so that each collider edge is met once, from its first face; a border edge has no solid). For
    a sharp convex edge, ``edge_normals[e]`` holds its first and second faces' unit normals."""
    f = wp.tid()
    for ce in range(3):
        tri_sharp[f, ce] = -1
        e = tri_edges[f, ce]
        fb = edge_faces[e, 1]
        if edge_faces[e, 0] != f or fb < 0:
            continue
        m0 = mesh_points[edge_verts[e, 0]]
        pa0 = mesh_points[mesh_tris[3 * f]]
        na = wp.normalize(wp.cross(mesh_points[mesh_tris[3 * f + 1]] - pa0, mesh_points[mesh_tris[3 * f + 2]] - pa0))
        pb0 = mesh_points[mesh_tris[3 * fb]]
        pb1 = mesh_points[mesh_tris[3 * fb + 1]]
        pb2 = mesh_points[mesh_tris[3 * fb + 2]]
        nb = wp.normalize(wp.cross(pb1 - pb0, pb2 - pb0))
        if wp.dot(na, nb) > SHARP_EDGE_COS:
            continue  # flat or gently bent: the vertex and edge passes hold it
        if wp.dot((pb0 + pb1 + pb2) / 3.0 - m0, na) >= 0.0:
            continue  # concave: a fold inward pokes through nothing
        tri_sharp[f, ce] = e
        edge_normals[e, 0] = na
        edge_normals[e, 1] = nb


@wp.kernel
def collide_mesh_edge_faces(
    mesh: wp.uint64,
    mesh_points: wp.array[wp.vec3],
    tri_sharp: wp.array2d[int],
    edge_verts: wp.array2d[int],
    edge_normals: wp.array2d[wp.vec3],
    x: wp.array[wp.vec3],
    tris: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth triangles against a closed mesh collider's sharp convex edges (faces turned by more
    than :data:`SHARP_EDGE_COS`, listed with their faces' normals by :func:`mesh_sharp_edges` for
    the collider as posed in ``mesh_points``): a cloth triangle laid across a box's edge, its vertices held
    outside by the vertex pass, has edges that cut through the solid as chords across the edge.
    :func:`collide_mesh_edges` pushes such a cloth edge along the face it is least deep under,
    which for a chord crossing the edge at about 45 degrees leaves it cutting the solid after
    several passes; this pass lifts the whole triangle along its normal instead. The part of the
    collider edge under the triangle (the segment clipped to the triangle's prism) is measured
    against the triangle's plane, whose normal is turned towards the edge's outward direction (the
    sum of its faces' normals); where its highest point is in front of the plane (through the
    triangle, by less than 4 thicknesses, the reach of :func:`collide_mesh_edges`, and than the
    triangle's longest edge: deeper pushes sent ``usd_scenes/cloth_table`` on another course) and the
    triangle's point behind it lies inside the edge's wedge (the normal on the outer side of both
    faces; else that point is outside the solid, beyond a face, and nothing pokes through), the
    triangle is moved along the normal until the edge is ``thickness`` behind it, the move split
    between its three vertices by the barycentric weights of the point's projection
    (:func:`push_triangle_point`). Edges within ``thickness`` behind the plane are left alone (the
    vertex and edge passes keep the layer; pushed here too, cloth folded over a table's corner was
    driven into its own layers). Corrections accumulated for averaging."""
    k = wp.tid()
    i0 = tris[k, 0]
    i1 = tris[k, 1]
    i2 = tris[k, 2]
    w0 = inv_mass[i0]
    w1 = inv_mass[i1]
    w2 = inv_mass[i2]
    if w0 + w1 + w2 == 0.0:
        return
    a = x[i0]
    b = x[i1]
    c = x[i2]
    nn = wp.cross(b - a, c - a)
    ln = wp.length(nn)
    if ln == 0.0:
        return
    nt = nn / ln
    lmax = wp.max(wp.max(wp.length(b - a), wp.length(c - b)), wp.length(a - c))
    lo = wp.min(wp.min(a, b), c) - wp.vec3(thickness)
    hi = wp.max(wp.max(a, b), c) + wp.vec3(thickness)
    query = wp.mesh_query_aabb(mesh, lo, hi)
    f = int(0)
    while wp.mesh_query_aabb_next(query, f):
        for ce in range(3):
            e = tri_sharp[f, ce]
            if e < 0:
                continue  # not a sharp convex edge, or met from its other face
            m0 = mesh_points[edge_verts[e, 0]]
            m1 = mesh_points[edge_verts[e, 1]]
            na = edge_normals[e, 0]
            nb = edge_normals[e, 1]
            out = na + nb
            cs = wp.dot(nt, out)
            if wp.abs(cs) < 1.0e-3 * wp.length(out):
                continue  # the triangle's plane holds the edge's outward direction: no side
            n = nt
            if cs < 0.0:
                n = -nt
            # clip the edge to the triangle's prism: each side's inner half-plane, linear in t
            t0 = float(0.0)
            t1 = float(1.0)
            for j in range(3):
                p = a
                q = b
                if j == 1:
                    p = b
                    q = c
                elif j == 2:
                    p = c
                    q = a
                side = wp.cross(nt, q - p)  # points into the triangle
                g0 = wp.dot(m0 - p, side)
                g1 = wp.dot(m1 - p, side)
                if g0 < 0.0 and g1 < 0.0:
                    t0 = 2.0
                elif g0 < 0.0:
                    t0 = wp.max(t0, g0 / (g0 - g1))
                elif g1 < 0.0:
                    t1 = wp.min(t1, g0 / (g0 - g1))
            if t0 > t1:
                continue
            # the highest point of the clipped part above the plane, on the solid's side (h > 0: through)
            h0 = wp.dot(wp.lerp(m0, m1, t0) - a, n)
            h1 = wp.dot(wp.lerp(m0, m1, t1) - a, n)
            tp = t0
            h = h0
            if h1 > h0:
                tp = t1
                h = h1
            if h <= 0.0 or h > wp.min(lmax, 4.0 * thickness):
                continue
            if wp.dot(n, na) <= 0.0 or wp.dot(n, nb) <= 0.0:
                continue  # the triangle's point behind the edge lies beyond a face: outside the solid
            bary = plane_barycentric(wp.lerp(m0, m1, tp), a, b, c, nt)
            bary = wp.vec3(wp.max(bary[0], 0.0), wp.max(bary[1], 0.0), wp.max(bary[2], 0.0))
            bary = bary / (bary[0] + bary[1] + bary[2])
            push_triangle_point(i0, i1, i2, w0, w1, w2, bary, n, h + thickness, delta, delta_count)


@wp.func
def shape_bounds(kind: int, a: wp.vec3, b: wp.vec3, size: wp.vec3) -> wp.vec4:
    """Bounding sphere of a box, cylinder or cone: vec4(centre, radius)."""
    mid = (a + b) * 0.5
    reach = wp.sqrt(0.25 * wp.length_sq(b - a) + size[0] * size[0])
    if kind == SHAPE_BOX:
        mid = a
        reach = wp.length(size)
    return wp.vec4(mid[0], mid[1], mid[2], reach)


@wp.func
def deepest_on_segment(kind: int, pa: wp.vec3, pb: wp.vec3, t0: float, t1: float, rounds: int, a: wp.vec3,
                       b: wp.vec3, rot: wp.quat, size: wp.vec3) -> float:
    """The parameter t in [t0, t1] of the point ``lerp(pa, pb, t)`` deepest in a shape (lowest
    :func:`shape_distance`), by ``rounds`` rounds of golden-section search: the signed distance of a
    convex solid is convex along a line, so the search finds the minimum."""
    lo = t0
    hi = t1
    g = 0.6180339887
    c = hi - g * (hi - lo)
    d = lo + g * (hi - lo)
    fc = shape_distance(kind, wp.lerp(pa, pb, c), a, b, rot, size)[3]
    fd = shape_distance(kind, wp.lerp(pa, pb, d), a, b, rot, size)[3]
    for it in range(rounds):
        if fc < fd:
            hi = d
            d = c
            fd = fc
            c = hi - g * (hi - lo)
            fc = shape_distance(kind, wp.lerp(pa, pb, c), a, b, rot, size)[3]
        else:
            lo = c
            c = d
            fc = fd
            d = lo + g * (hi - lo)
            fd = shape_distance(kind, wp.lerp(pa, pb, d), a, b, rot, size)[3]
    return 0.5 * (lo + hi)


@wp.kernel
def collide_shape_edges(
    kind: wp.array[int],
    a1: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    r1: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    edges: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth edges against the sharp edges of boxes and rims of cylinders and cones (and a cone's
    apex): the point of
    the edge deepest in the solid is found by golden-section search (the signed distance of a
    convex solid is convex along a line, so the search finds the edge's minimum), and an edge
    whose inner point is closer than ``thickness`` is pushed out along the normal there, split
    between its two vertices as in :func:`collide_mesh_edges`."""
    k = wp.tid()
    i0 = edges[k, 0]
    i1 = edges[k, 1]
    w0 = inv_mass[i0]
    w1 = inv_mass[i1]
    if w0 + w1 == 0.0:
        return
    pa = x[i0]
    pb = x[i1]
    for s in range(kind.shape[0]):
        kd = kind[s]
        if kd != SHAPE_CYLINDER and kd != SHAPE_CONE and kd != SHAPE_BOX:
            continue
        # bounding sphere of the solid against the edge
        bs = shape_bounds(kd, a1[s], b1[s], size[s])
        mid = wp.vec3(bs[0], bs[1], bs[2])
        t = segment_parameter(mid, pa, pb)
        if wp.length(wp.lerp(pa, pb, t) - mid) > bs[3] + thickness:
            continue
        u = deepest_on_segment(kd, pa, pb, 0.0, 1.0, 24, a1[s], b1[s], r1[s], size[s])
        if u <= 1.0e-3 or u >= 1.0 - 1.0e-3:
            continue  # a cloth vertex is deepest: the vertex projection holds it
        sd = shape_distance(kd, wp.lerp(pa, pb, u), a1[s], b1[s], r1[s], size[s])
        if sd[3] >= thickness:
            continue
        denom = (1.0 - u) * (1.0 - u) * w0 + u * u * w1
        if denom == 0.0:
            continue
        push = wp.vec3(sd[0], sd[1], sd[2]) * ((thickness - sd[3]) / denom)
        wp.atomic_add(delta, i0, push * ((1.0 - u) * w0))
        wp.atomic_add(delta, i1, push * (u * w1))
        wp.atomic_add(delta_count, i0, 1.0)
        wp.atomic_add(delta_count, i1, 1.0)


@wp.kernel
def limit_round_motion(
    kind: wp.array[int],
    a1: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    size: wp.array[wp.vec3],
    fraction: float,
    thickness: float,
    inv_mass: wp.array[float],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Shorten a free vertex's move over the substep (x_prev -> x) to ``fraction`` of a sphere's or
    capsule's radius when the move passes within ``thickness`` of that solid (posed a1, b1): the
    vertex projection pushes a vertex out on the side it is nearest, so one yanked past the core
    in one substep would leave on the far side. Moves that stay clear of the round solids are
    left alone."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p0 = x_prev[i]
    p = x[i]
    for s in range(kind.shape[0]):
        kd = kind[s]
        if kd != SHAPE_SPHERE and kd != SHAPE_CAPSULE:
            continue
        cap = fraction * size[s][0]
        d = p - p0
        ld = wp.length(d)
        if ld <= cap:
            continue
        b = b1[s]
        if kd == SHAPE_SPHERE:
            b = a1[s]
        st = closest_segments(p0, p, a1[s], b)
        gap = wp.length(wp.lerp(p0, p, st[0]) - wp.lerp(a1[s], b, st[1])) - size[s][0]
        if gap < thickness:
            p = p0 + d * (cap / ld)
    x[i] = p


@wp.func
def shape_line_value(kind: int, p0: wp.vec3, dr: wp.vec3, t: float, a: wp.vec3, b: wp.vec3, rot: wp.quat,
                     size: wp.vec3) -> float:
    """Signed distance of the point ``p0 + dr t`` to a shape (:func:`shape_distance`)."""
    return shape_distance(kind, p0 + dr * t, a, b, rot, size)[3]


@wp.func
def shape_chord(kind: int, p0: wp.vec3, dr: wp.vec3, a: wp.vec3, b: wp.vec3, rot: wp.quat, size: wp.vec3) -> wp.vec2:
    """Where the ray ``p0 + dr t`` (t >= 0, dr a unit vector, p0 outside) enters a box, cylinder
    or cone and the length of the chord it cuts through it: vec2(t_in, chord), or vec2(-1, 0)
    when it misses the solid. The solid is convex, so its signed distance is convex along the
    ray: its minimum, on the part of the ray inside the solid's bounding sphere, is found by
    golden-section search, the entry and exit by bisection on either side (to about 1e-6 of the
    sphere's diameter)."""
    bs = shape_bounds(kind, a, b, size)
    mid = wp.vec3(bs[0], bs[1], bs[2])
    reach = bs[3]
    tc = wp.dot(mid - p0, dr)
    off2 = wp.length_sq(p0 + dr * tc - mid)
    if off2 >= reach * reach:
        return wp.vec2(-1.0, 0.0)
    half = wp.sqrt(reach * reach - off2)
    lo = wp.max(tc - half, 0.0)
    hi = tc + half
    if hi <= lo:
        return wp.vec2(-1.0, 0.0)
    # the deepest point along the ray, by golden-section search as in deepest_on_segment but on the
    # points p0 + dr t (not lerp(p0, p0 + dr, t): the hammock tests' outcomes depend on the last bits)
    g = 0.6180339887
    l = lo
    h = hi
    c = h - g * (h - l)
    d = l + g * (h - l)
    fc = shape_line_value(kind, p0, dr, c, a, b, rot, size)
    fd = shape_line_value(kind, p0, dr, d, a, b, rot, size)
    for it in range(32):
        if fc < fd:
            h = d
            d = c
            fd = fc
            c = h - g * (h - l)
            fc = shape_line_value(kind, p0, dr, c, a, b, rot, size)
        else:
            l = c
            c = d
            fc = fd
            d = l + g * (h - l)
            fd = shape_line_value(kind, p0, dr, d, a, b, rot, size)
    tm = 0.5 * (l + h)
    if shape_line_value(kind, p0, dr, tm, a, b, rot, size) >= 0.0:
        return wp.vec2(-1.0, 0.0)  # clear of the solid
    # entry in [lo, tm] (outside at lo), exit in [tm, hi] (outside at hi, on the bounding sphere)
    el = lo
    eh = tm
    xl = tm
    xh = hi
    for it in range(24):
        em = 0.5 * (el + eh)
        if shape_line_value(kind, p0, dr, em, a, b, rot, size) < 0.0:
            eh = em
        else:
            el = em
        xm = 0.5 * (xl + xh)
        if shape_line_value(kind, p0, dr, xm, a, b, rot, size) < 0.0:
            xl = xm
        else:
            xh = xm
    return wp.vec2(el, xh - el)


@wp.kernel
def limit_shape_motion(
    kind: wp.array[int],
    a1: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    r1: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    fraction: float,
    thickness: float,
    inv_mass: wp.array[float],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Shorten a free vertex's move over the substep (x_prev -> x) that enters a box, cylinder or
    cone (posed a1, b1, r1) to ``fraction`` of the chord its line cuts through the solid
    (:func:`shape_chord`): the analytic counterpart of :func:`limit_mesh_motion`, with its
    exceptions (moves shorter than ``thickness``, moves that stay clear of the solid and moves
    that start inside it are left alone)."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p0 = x_prev[i]
    p = x[i]
    for s in range(kind.shape[0]):
        kd = kind[s]
        if kd != SHAPE_BOX and kd != SHAPE_CYLINDER and kd != SHAPE_CONE:
            continue
        d = p - p0
        ld = wp.length(d)
        if ld <= thickness:
            continue
        bs = shape_bounds(kd, a1[s], b1[s], size[s])
        mid = wp.vec3(bs[0], bs[1], bs[2])
        if wp.length(wp.lerp(p0, p, segment_parameter(mid, p0, p)) - mid) > bs[3]:
            continue  # the move stays outside the solid's bounding sphere
        if shape_distance(kd, p0, a1[s], b1[s], r1[s], size[s])[3] <= 0.0:
            continue  # starts inside
        dr = d / ld
        ch = shape_chord(kd, p0, dr, a1[s], b1[s], r1[s], size[s])
        if ch[0] < 0.0 or ch[0] > ld:
            continue  # clear of the solid, or stopping short of it
        cap = fraction * ch[1]
        if ld > cap:
            p = p0 + dr * cap
    x[i] = p


MESH_RAY_SKIP = wp.constant(1.0e-5)
"""[m] How far past a ray's entry into a mesh collider the ray that finds where it leaves starts."""


@wp.kernel
def limit_mesh_motion(
    mesh: wp.uint64,
    fraction: float,
    thickness: float,
    inv_mass: wp.array[float],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Shorten a free vertex's move over the substep (x_prev -> x) that enters a closed mesh
    collider (posed as ``mesh``'s points) to ``fraction`` of the chord its line cuts through the
    solid (from where it enters to where it next meets the surface): the vertex projection
    (:func:`collide_mesh`) pushes a vertex out at the surface nearest to it, so one yanked past the
    middle of the solid in one substep (or through it) would leave on the far side, and one
    driven in by more than a little of the solid's depth every substep would work its way round
    it. Moves shorter than ``thickness`` (they cannot enter the solid from outside the contact
    distance), moves that stay clear of the solid and moves that start inside it are left
    alone."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p0 = x_prev[i]
    d = x[i] - p0
    ld = wp.length(d)
    if ld <= thickness:
        return
    dr = d / ld
    hit = wp.mesh_query_ray(mesh, p0, dr, ld)
    if not hit.result or wp.dot(hit.normal, dr) >= 0.0:
        return  # clear of the solid, or leaving it (started inside)
    # the chord: from the entry point to where the line next meets the surface (leaving the
    # solid), looked for from just past the entry so as not to find the entry face again
    out = wp.mesh_query_ray(mesh, p0 + dr * (hit.t + MESH_RAY_SKIP), dr, 1.0e6)
    chord = float(1.0e6)
    if out.result:
        chord = out.t + MESH_RAY_SKIP
    cap = fraction * chord
    if ld > cap:
        x[i] = p0 + dr * cap


ROUND_CORE_ROUNDS = wp.constant(4)
"""Alternating projections (triangle <-> capsule axis) that find a triangle's point closest to a capsule's axis."""


@wp.func
def round_closest(kind: int, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, a: wp.vec3, b: wp.vec3) -> wp.mat33:
    """The point of triangle p0 p1 p2 closest to the core of a sphere (its centre a) or capsule
    (its axis a-b; alternating projections, :data:`ROUND_CORE_ROUNDS`): rows (its barycentric
    coordinates, the point, the core point closest to it)."""
    c = a
    bary = closest_on_triangle(c, p0, p1, p2)
    if kind == SHAPE_CAPSULE:
        for _r in range(ROUND_CORE_ROUNDS):
            q = p0 * bary[0] + p1 * bary[1] + p2 * bary[2]
            c = wp.lerp(a, b, segment_parameter(q, a, b))
            bary = closest_on_triangle(c, p0, p1, p2)
    q = p0 * bary[0] + p1 * bary[1] + p2 * bary[2]
    return wp.mat33(bary[0], bary[1], bary[2], q[0], q[1], q[2], c[0], c[1], c[2])


@wp.func
def push_triangle_point(
    i0: int,
    i1: int,
    i2: int,
    w0: float,
    w1: float,
    w2: float,
    bary: wp.vec3,
    n: wp.vec3,
    t: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Add to the per-vertex correction sums the moves of a triangle's vertices i0, i1, i2
    (inverse masses w0, w1, w2) that carry its point at barycentric coordinates ``bary`` by
    ``n * t``, split by the barycentric weights and inverse masses (as :func:`solve_corner_contacts`
    does); nothing when every weighted vertex is kinematic."""
    denom = bary[0] * bary[0] * w0 + bary[1] * bary[1] * w1 + bary[2] * bary[2] * w2
    if denom == 0.0:
        return
    push = n * (t / denom)
    wp.atomic_add(delta, i0, push * (bary[0] * w0))
    wp.atomic_add(delta, i1, push * (bary[1] * w1))
    wp.atomic_add(delta, i2, push * (bary[2] * w2))
    wp.atomic_add(delta_count, i0, 1.0)
    wp.atomic_add(delta_count, i1, 1.0)
    wp.atomic_add(delta_count, i2, 1.0)


@wp.kernel
def collide_round_faces(
    kind: wp.array[int],
    a0: wp.array[wp.vec3],
    b0: wp.array[wp.vec3],
    a1: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    size: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    tris: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth triangles that cut into a sphere or capsule (pose a1, b1) while their vertices are
    held outside (an edge drawn across a ball, or the ball's dome poking through a stretched
    triangle's inside): the triangle's point closest to the core is moved out to ``thickness``
    from the surface on the side the triangle was on earlier (x_prev against the pose a0, b0),
    not along the normal where it is now (a triangle pulled past the core goes back the way it
    came instead of through), the push split between the three vertices by their barycentric
    weights (as :func:`solve_corner_contacts` does). A triangle outside the solid, or deepest at
    a vertex (the vertex projection holds it), is left alone."""
    k = wp.tid()
    i0 = tris[k, 0]
    i1 = tris[k, 1]
    i2 = tris[k, 2]
    w0 = inv_mass[i0]
    w1 = inv_mass[i1]
    w2 = inv_mass[i2]
    if w0 + w1 + w2 == 0.0:
        return
    for s in range(kind.shape[0]):
        kd = kind[s]
        if kd != SHAPE_SPHERE and kd != SHAPE_CAPSULE:
            continue
        rad = size[s][0]
        cl = round_closest(kd, x[i0], x[i1], x[i2], a1[s], b1[s])
        bary = cl[0]
        d = cl[1] - cl[2]
        ld = wp.length(d)
        if ld >= rad or wp.max(bary) >= 1.0 - 1.0e-3:
            continue
        cl0 = round_closest(kd, x_prev[i0], x_prev[i1], x_prev[i2], a0[s], b0[s])
        d0 = cl0[1] - cl0[2]
        n = wp.vec3(0.0, 1.0, 0.0)
        if wp.length(d0) > 0.0:
            n = wp.normalize(d0)
        elif ld > 0.0:
            n = d / ld
        # move the point along n until it is rad + thickness from the core point
        dn = wp.dot(d, n)
        reach = rad + thickness
        t = -dn + wp.sqrt(wp.max(dn * dn - ld * ld + reach * reach, 0.0))
        push_triangle_point(i0, i1, i2, w0, w1, w2, bary, n, t, delta, delta_count)


@wp.kernel
def collide_mesh_faces(
    mesh: wp.uint64,
    points_ref: wp.array[wp.vec3],
    mesh_tris: wp.array[int],
    closed: int,
    moved: int,
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    tris: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    max_distance: float,
    samples: int,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth triangles that cut into a closed mesh collider (posed as ``mesh``'s points) while their
    vertices are held outside (a stretched triangle drawn over a round part, the mesh's dome poking
    through its inside): the triangle is sampled on a barycentric grid of ``samples`` steps a side
    (its vertices left out: the vertex projection holds them), each sample tested against the solid
    (generalised winding number, as :func:`collide_mesh`), and the deepest sample inside (the
    farthest from its nearest surface point) moved out of the solid back the way it came: to
    ``thickness`` outside the point where the straight path from it to the same point of the
    triangle at ``x_prev`` leaves the solid (a triangle dragged past the solid's middle goes back,
    not through), or to ``thickness`` from its nearest surface point when that path stays inside
    (the mesh moved onto the point). The push is split between the three vertices by their
    barycentric weights (as :func:`collide_round_faces` does). A triangle with no sample inside is
    left alone.

    An open mesh (``closed`` 0) has no inside: a sample is across it when it is on the other side
    of its nearest face from the side the same point of the triangle at ``x_prev`` was on with the
    mesh posed as ``points_ref`` (:func:`open_mesh_side`, ``moved`` as there), and the deepest such
    sample moves back along that face's normal to ``thickness`` on its own side."""
    k = wp.tid()
    ids = wp.vec3i(tris[k, 0], tris[k, 1], tris[k, 2])
    w = wp.vec3(inv_mass[ids[0]], inv_mass[ids[1]], inv_mass[ids[2]])
    if w[0] + w[1] + w[2] == 0.0:
        return
    p0 = x[ids[0]]
    p1 = x[ids[1]]
    p2 = x[ids[2]]
    c = (p0 + p1 + p2) / 3.0
    r = wp.max(wp.max(wp.length(p0 - c), wp.length(p1 - c)), wp.length(p2 - c))
    if not wp.mesh_query_point_no_sign(mesh, c, r + thickness).result:
        return  # no part of the mesh near the triangle
    best = float(0.0)
    bary = wp.vec3(0.0)
    n = wp.vec3(0.0)
    inv = 1.0 / float(samples)
    for a in range(samples + 1):
        for b in range(samples + 1 - a):
            if (a == samples) or (b == samples) or (a + b == 0):
                continue  # a vertex
            u = float(a) * inv
            v = float(b) * inv
            q = p0 * (1.0 - u - v) + p1 * u + p2 * v
            if closed == 0:
                h0 = wp.mesh_query_point_no_sign(mesh, q, max_distance)
                if not h0.result:
                    continue
                c0 = wp.mesh_eval_position(mesh, h0.face, h0.u, h0.v)
                fn = wp.normalize(wp.mesh_eval_face_normal(mesh, h0.face))
                qs = x_prev[ids[0]] * (1.0 - u - v) + x_prev[ids[1]] * u + x_prev[ids[2]] * v
                side = open_mesh_side(mesh, points_ref, mesh_tris, moved, qs, max_distance + wp.length(q - qs))
                depth = thickness - wp.dot(q - c0, fn) * side
                if depth > thickness and depth > best:
                    best = depth
                    bary = wp.vec3(1.0 - u - v, u, v)
                    n = fn * side
                continue
            h = wp.mesh_query_point_sign_winding_number(mesh, q, max_distance, 2.0, 0.5)
            if not h.result or h.sign >= 0.0:
                continue
            cp = wp.mesh_eval_position(mesh, h.face, h.u, h.v)
            dd = cp - q
            ld = wp.length(dd)
            if ld + thickness > best:
                best = ld + thickness
                bary = wp.vec3(1.0 - u - v, u, v)
                if ld > 1.0e-9:
                    n = dd / ld
                else:
                    n = wp.normalize(wp.mesh_eval_face_normal(mesh, h.face))
    if best == 0.0:
        return
    if closed == 0:
        push_triangle_point(ids[0], ids[1], ids[2], w[0], w[1], w[2], bary, n * best, 1.0, delta, delta_count)
        return
    # back the way the point came: from where it is to where it was (x_prev), out of the solid
    # where that path first leaves it (a triangle dragged past the solid's middle goes back, not
    # through); the nearest surface when the path stays inside (the mesh moved onto the point)
    q = p0 * bary[0] + p1 * bary[1] + p2 * bary[2]
    back = x_prev[ids[0]] * bary[0] + x_prev[ids[1]] * bary[1] + x_prev[ids[2]] * bary[2] - q
    lb = wp.length(back)
    move = n * best
    if lb > 0.0:
        out = wp.mesh_query_ray(mesh, q, back / lb, lb)
        if out.result:
            move = back * (out.t / lb) + out.normal * thickness
    push_triangle_point(ids[0], ids[1], ids[2], w[0], w[1], w[2], bary, move, 1.0, delta, delta_count)


CLEAR_MARGIN = wp.constant(0.25)
"""Fraction of the thickness by which a cloth triangle must lie beyond a solid's tangent plane for
:func:`collide_shape_faces` to skip it unsampled (far above rounding, so what is skipped is what the
samples would have found clear)."""

FACE_REFINE_STEPS = wp.constant(24)
"""Steps of the pattern search (six directions in barycentric coordinates, the step halved when none
goes deeper) that refines :func:`collide_shape_faces`' lowest sample."""


@wp.func
def shape_carry(kind: int, p: wp.vec3, a0: wp.vec3, b0: wp.vec3, r0: wp.quat, a1: wp.vec3, b1: wp.vec3,
                r1: wp.quat) -> wp.vec3:
    """Point p, given against a shape posed a0, b0, r0, carried with the shape to its pose a1, b1,
    r1: a box's rigid motion; for the axial shapes, the motion of p's point on the axis (the
    inverse of :func:`shape_point_motion`)."""
    if kind == SHAPE_BOX:
        return a1 + wp.quat_rotate(r1, wp.quat_rotate_inv(r0, p - a0))
    t = segment_parameter(p, a0, b0)
    return p + wp.lerp(a1, b1, t) - wp.lerp(a0, b0, t)


@wp.kernel
def collide_shape_faces(
    kind: wp.array[int],
    a0: wp.array[wp.vec3],
    b0: wp.array[wp.vec3],
    r0: wp.array[wp.quat],
    a1: wp.array[wp.vec3],
    b1: wp.array[wp.vec3],
    r1: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    tris: wp.array2d[int],
    inv_mass: wp.array[float],
    thickness: float,
    samples: int,
    kinds: int,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Cloth triangles that cut into a box, cylinder or cone (pose a1, b1, r1; only the shapes whose
    kind k has bit ``1 << k`` set in ``kinds``) while their vertices
    are held outside (a stretched triangle drawn over a rim, a cloth edge cut through as a chord):
    the analytic counterpart of the closed-mesh branch of :func:`collide_mesh_faces`. The triangle
    is sampled on a barycentric grid of ``samples`` steps a side (its vertices left out), the
    deepest point in the solid (:func:`shape_distance`; the lowest sample refined by a pattern
    search of :data:`FACE_REFINE_STEPS` steps, so that a rim or edge poking through the triangle
    between the samples is found) is moved out back the way it came: to
    ``thickness`` outside the point where the straight path from it to the same point of the
    triangle at ``x_prev`` leaves the solid (found by bisection: the solid is convex, the path
    leaves it once), or to ``thickness`` outside its nearest surface point when that path stays
    inside. That point at ``x_prev`` is taken where it was against the solid posed a0, b0, r0 (the
    step's start: :func:`shape_carry`), so a solid driven up into the triangle sends it back up,
    the side it came from. The push is split between the three vertices by their barycentric
    weights. A triangle with no sample inside is left alone, and one that lies wholly beyond the
    tangent plane at the surface point nearest its centroid, by :data:`CLEAR_MARGIN` of the
    thickness, is not sampled (the solid is convex: every point of such a triangle is at least that
    far out, so no sample would be inside)."""
    k = wp.tid()
    ids = wp.vec3i(tris[k, 0], tris[k, 1], tris[k, 2])
    w = wp.vec3(inv_mass[ids[0]], inv_mass[ids[1]], inv_mass[ids[2]])
    if w[0] + w[1] + w[2] == 0.0:
        return
    p0 = x[ids[0]]
    p1 = x[ids[1]]
    p2 = x[ids[2]]
    c = (p0 + p1 + p2) / 3.0
    r = wp.max(wp.max(wp.length(p0 - c), wp.length(p1 - c)), wp.length(p2 - c))
    inv = 1.0 / float(samples)
    for s in range(kind.shape[0]):
        kd = kind[s]
        if kd != SHAPE_BOX and kd != SHAPE_CYLINDER and kd != SHAPE_CONE:
            continue
        if (kinds >> kd) & 1 == 0:
            continue
        bs = shape_bounds(kd, a1[s], b1[s], size[s])
        if wp.length(c - wp.vec3(bs[0], bs[1], bs[2])) > r + bs[3]:
            continue  # no part of the solid near the triangle
        # the plane through the surface point nearest the centroid, across the normal there, bounds
        # the (convex) solid: a triangle wholly beyond it is clear
        sc = shape_distance(kd, c, a1[s], b1[s], r1[s], size[s])
        nc = wp.vec3(sc[0], sc[1], sc[2])
        if wp.min(wp.min(wp.dot(p0 - c, nc), wp.dot(p1 - c, nc)), wp.dot(p2 - c, nc)) + sc[3] >= CLEAR_MARGIN * thickness:
            continue
        # the lowest sample, then a pattern search from it (the signed distance is convex over the
        # triangle): a rim or edge poking through the triangle by less than the grid's spacing
        bu = float(0.0)
        bv = float(0.0)
        low = float(1.0e30)
        for ia in range(samples + 1):
            for ib in range(samples + 1 - ia):
                if (ia == samples) or (ib == samples) or (ia + ib == 0):
                    continue  # a vertex
                u = float(ia) * inv
                v = float(ib) * inv
                sdv = shape_distance(kd, p0 * (1.0 - u - v) + p1 * u + p2 * v, a1[s], b1[s], r1[s], size[s])[3]
                if sdv < low:
                    low = sdv
                    bu = u
                    bv = v
        if low >= thickness:
            continue  # clear of the solid
        step = inv
        for it in range(FACE_REFINE_STEPS):
            moved = bool(False)
            for dirn in range(6):
                du = step
                dv = float(0.0)
                if dirn == 1:
                    du = -step
                elif dirn == 2:
                    du = 0.0
                    dv = step
                elif dirn == 3:
                    du = 0.0
                    dv = -step
                elif dirn == 4:
                    dv = -step
                elif dirn == 5:
                    du = -step
                    dv = step
                u = bu + du
                v = bv + dv
                if u < 0.0 or v < 0.0 or u + v > 1.0:
                    continue
                sdv = shape_distance(kd, p0 * (1.0 - u - v) + p1 * u + p2 * v, a1[s], b1[s], r1[s], size[s])[3]
                if sdv < low:
                    low = sdv
                    bu = u
                    bv = v
                    moved = True
            if not moved:
                step = step * 0.5
        if low >= 0.0:
            continue  # outside the solid
        bary = wp.vec3(1.0 - bu - bv, bu, bv)
        if wp.max(bary) >= 1.0 - 1.0e-3:
            continue  # deepest at a vertex: the vertex projection holds it
        sd = shape_distance(kd, p0 * bary[0] + p1 * bary[1] + p2 * bary[2], a1[s], b1[s], r1[s], size[s])
        best = thickness - sd[3]
        n = wp.vec3(sd[0], sd[1], sd[2])
        q = p0 * bary[0] + p1 * bary[1] + p2 * bary[2]
        qb = shape_carry(kd, x_prev[ids[0]] * bary[0] + x_prev[ids[1]] * bary[1] + x_prev[ids[2]] * bary[2],
                         a0[s], b0[s], r0[s], a1[s], b1[s], r1[s])
        move = n * best
        sb = shape_distance(kd, qb, a1[s], b1[s], r1[s], size[s])
        if sb[3] > 0.0:
            lo = float(0.0)  # inside
            hi = float(1.0)  # outside
            for it in range(24):
                m = 0.5 * (lo + hi)
                if shape_distance(kd, wp.lerp(q, qb, m), a1[s], b1[s], r1[s], size[s])[3] < 0.0:
                    lo = m
                else:
                    hi = m
            e = wp.lerp(q, qb, hi)
            se = shape_distance(kd, e, a1[s], b1[s], r1[s], size[s])
            move = e - q + wp.vec3(se[0], se[1], se[2]) * thickness
        push_triangle_point(ids[0], ids[1], ids[2], w[0], w[1], w[2], bary, move, 1.0, delta, delta_count)


CORNER_INSIDE_TOL = wp.constant(0.01)
"""A corner's projection counts as inside a cloth triangle down to this barycentric coordinate: a
corner right under the edge between two triangles would otherwise fall between them through
round-off (as in the vertex-triangle self-contacts)."""


@wp.kernel
def shape_corners(
    kind: wp.array[int],
    a: wp.array[wp.vec3],
    b: wp.array[wp.vec3],
    rot: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    corner_shape: wp.array[int],
    corner_local: wp.array[int],
    corners: wp.array[wp.vec3],
    inward: wp.array[wp.vec3],
):
    """The corners of the analytic solids as posed (a, b, rot): the eight of a box (corner_local
    0..7, bit k flipping axis k) and the apex of a cone, with the unit direction from each into
    its solid (to the box's centre, down the cone's axis)."""
    c = wp.tid()
    s = corner_shape[c]
    if kind[s] == SHAPE_CONE:
        corners[c] = b[s]
        inward[c] = wp.normalize(a[s] - b[s])
        return
    he = size[s]
    k = corner_local[c]
    local = wp.vec3(he[0], he[1], he[2])
    if k & 1:
        local = wp.vec3(-local[0], local[1], local[2])
    if k & 2:
        local = wp.vec3(local[0], -local[1], local[2])
    if k & 4:
        local = wp.vec3(local[0], local[1], -local[2])
    p = a[s] + wp.quat_rotate(rot[s], local)
    corners[c] = p
    inward[c] = wp.normalize(a[s] - p)


@wp.kernel
def mesh_corners(
    points: wp.array[wp.vec3],
    corner_vertex: wp.array[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    offset: int,
    corners: wp.array[wp.vec3],
    inward: wp.array[wp.vec3],
):
    """The sharp convex vertices of a mesh collider as posed (points), written from slot `offset`
    on, with the unit direction from each towards the centroid of its neighbours (into the solid
    at a convex vertex, whatever the faces' winding)."""
    c = wp.tid()
    p = points[corner_vertex[c]]
    m = wp.vec3(0.0)
    for r in range(ring_offsets[c], ring_offsets[c + 1]):
        m = m + points[ring[r]]
    m = m / float(ring_offsets[c + 1] - ring_offsets[c])
    corners[offset + c] = p
    inward[offset + c] = wp.normalize(m - p)


@wp.func
def plane_barycentric(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3, n: wp.vec3) -> wp.vec3:
    """Barycentric coordinates of the projection of p onto the plane of triangle abc (unit normal n)."""
    ln = wp.length(wp.cross(b - a, c - a))
    pp = p - n * wp.dot(p - a, n)
    w = wp.dot(wp.cross(b - a, pp - a), n) / ln
    v = wp.dot(wp.cross(pp - a, c - a), n) / ln
    return wp.vec3(1.0 - v - w, v, w)


@wp.func
def unit_normal(x: wp.array[wp.vec3], tris: wp.array2d[int], t: int) -> wp.vec3:
    """Unit normal of cloth triangle t (zero when degenerate)."""
    a = x[tris[t, 0]]
    nn = wp.cross(x[tris[t, 1]] - a, x[tris[t, 2]] - a)
    ln = wp.length(nn)
    if ln == 0.0:
        return wp.vec3(0.0)
    return nn / ln


@wp.func
def pseudo_normal(x: wp.array[wp.vec3], tris: wp.array2d[int], vt_offsets: wp.array[int], vt_tris: wp.array[int],
                  t: int, bc: wp.vec3) -> wp.vec3:
    """The cloth's outward direction at the point of triangle t with barycentric coordinates bc
    (Baerentzen and Aanaes 2005): the triangle's normal inside it, the sum of the two triangles'
    normals on an edge, the angle-weighted sum of the triangles' normals at a vertex (a point's
    side of it is the side of the surface there, also beside a fold's ridge, where the side of
    one triangle's plane is not). Assumes the triangles around are wound alike."""
    if bc[0] > 0.0 and bc[1] > 0.0 and bc[2] > 0.0:
        return unit_normal(x, tris, t)
    if bc[0] > 0.0 or bc[1] > 0.0 or bc[2] > 0.0:
        # an edge: which two vertices
        e = 0
        if bc[1] <= 0.0:
            e = 1
        elif bc[2] <= 0.0:
            e = 2
        if (bc[0] > 0.0 and bc[1] > 0.0) or (bc[0] > 0.0 and bc[2] > 0.0) or (bc[1] > 0.0 and bc[2] > 0.0):
            i = tris[t, (e + 1) % 3]
            j = tris[t, (e + 2) % 3]
            n = unit_normal(x, tris, t)
            for r in range(vt_offsets[i], vt_offsets[i + 1]):
                u = vt_tris[r]
                if u != t and (tris[u, 0] == j or tris[u, 1] == j or tris[u, 2] == j):
                    n = n + unit_normal(x, tris, u)
            return n
    # a vertex
    vi = 0
    if bc[1] > 0.0:
        vi = 1
    elif bc[2] > 0.0:
        vi = 2
    i = tris[t, vi]
    n = wp.vec3(0.0)
    for r in range(vt_offsets[i], vt_offsets[i + 1]):
        u = vt_tris[r]
        k = 0
        if tris[u, 1] == i:
            k = 1
        elif tris[u, 2] == i:
            k = 2
        p = x[i]
        e1 = x[tris[u, (k + 1) % 3]] - p
        e2 = x[tris[u, (k + 2) % 3]] - p
        l1 = wp.length(e1)
        l2 = wp.length(e2)
        if l1 > 0.0 and l2 > 0.0:
            angle = wp.acos(wp.clamp(wp.dot(e1, e2) / (l1 * l2), -1.0, 1.0))
            n = n + unit_normal(x, tris, u) * angle
    return n


@wp.kernel
def find_corner_contacts(
    corner_start: wp.array[wp.vec3],
    corner_end: wp.array[wp.vec3],
    inward: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array2d[int],
    vt_offsets: wp.array[int],
    vt_tris: wp.array[int],
    horizon: float,
    thickness: float,
    prev_ids: wp.array2d[int],
    prev_sides: wp.array2d[float],
    prev_count: wp.array[int],
    ids: wp.array2d[int],
    sides: wp.array2d[float],
    count: wp.array[int],
    dists: wp.array2d[float],
    overflow: wp.array[int],
):
    """The cloth triangles collider corner k (a box corner, a cone's apex, a sharp mesh vertex)
    may meet within the next `horizon` seconds: closer than 2 thicknesses plus twice the distance
    the triangle's fastest vertex travels in that time at its velocity v plus the corner's own
    travel (corner_start -> corner_end) plus the triangle's longest edge (the stretch sweeps of
    cloth hanging on a corner move it far more within a step than its velocity says: the
    triangles of the corner's neighbourhood); the nearest are kept when there are more than a row
    holds. Each is stored with the side of the cloth the corner is on, in the triangle's winding:
    the side of the surface at the triangle's point closest to the corner (:func:`pseudo_normal`;
    beside a triangle, the side of its plane can be the wrong one). A corner under the inside of
    the triangle keeps the side it had at the previous detection (a change of side there is the
    corner poking through, which the solve must undo), and a corner new to the triangle and
    inside its contact layer there gets the solid's side (its inward direction), the only one the
    cloth may be on. vt_offsets, vt_tris: the triangles of each cloth vertex."""
    k = wp.tid()
    p = corner_start[k]
    motion = wp.length(corner_end[k] - p)
    cnt = int(0)
    for t in range(tris.shape[0]):
        a = x[tris[t, 0]]
        b = x[tris[t, 1]]
        c = x[tris[t, 2]]
        vmax = wp.max(wp.max(wp.length(v[tris[t, 0]]), wp.length(v[tris[t, 1]])), wp.length(v[tris[t, 2]]))
        lmax = wp.max(wp.max(wp.length(b - a), wp.length(c - b)), wp.length(a - c))
        reach = 2.0 * thickness + 2.0 * vmax * horizon + motion + lmax
        # (a bounding-box test first: it rejects most triangles)
        lo = wp.min(wp.min(a, b), c) - wp.vec3(reach)
        hi = wp.max(wp.max(a, b), c) + wp.vec3(reach)
        if p[0] < lo[0] or p[1] < lo[1] or p[2] < lo[2] or p[0] > hi[0] or p[1] > hi[1] or p[2] > hi[2]:
            continue
        bc = closest_on_triangle(p, a, b, c)
        q = a * bc[0] + b * bc[1] + c * bc[2]
        dist = wp.length(p - q)
        if dist > reach:
            continue
        n = unit_normal(x, tris, t)
        if wp.length_sq(n) == 0.0:
            continue
        side = float(1.0)
        if wp.dot(p - q, pseudo_normal(x, tris, vt_offsets, vt_tris, t, bc)) < 0.0:
            side = -1.0
        d = wp.dot(p - a, n)
        pb = plane_barycentric(p, a, b, c, n)
        inside = pb[0] >= -CORNER_INSIDE_TOL and pb[1] >= -CORNER_INSIDE_TOL and pb[2] >= -CORNER_INSIDE_TOL
        known = stored_side(prev_ids, prev_sides, prev_count, k, t, 0.0)
        if inside and known != 0.0 and wp.abs(d) < lmax:
            side = known
        elif inside and known == 0.0 and wp.abs(d) < thickness:
            side = 1.0
            if wp.dot(inward[k], n) < 0.0:
                side = -1.0
        cnt = push_candidate(ids, sides, dists, k, cnt, t, side, dist, overflow)
    count[k] = cnt


@wp.func
def push_corner_contact(x: wp.array[wp.vec3], x_prev: wp.array[wp.vec3], inv_mass: wp.array[float], i0: int,
                        i1: int, i2: int, bc: wp.vec3, g: wp.vec3, depth: float, slip: wp.vec3, mu: float,
                        delta: wp.array[wp.vec3], delta_count: wp.array[float]):
    """Move the cloth point with barycentric coordinates bc on triangle (i0, i1, i2) by `depth`
    along the unit direction g, with position-based Coulomb friction (Macklin et al. 2014, eq.
    24-25) on its tangential motion over the substep relative to the corner (`slip`: the corner's
    motion; x_prev empty: no friction); vertices with a zero weight are left alone."""
    w0 = inv_mass[i0] * wp.where(bc[0] > 0.0, 1.0, 0.0)
    w1 = inv_mass[i1] * wp.where(bc[1] > 0.0, 1.0, 0.0)
    w2 = inv_mass[i2] * wp.where(bc[2] > 0.0, 1.0, 0.0)
    denom = bc[0] * bc[0] * w0 + bc[1] * bc[1] * w1 + bc[2] * bc[2] * w2
    if denom == 0.0:
        return
    corr = g * depth
    if mu > 0.0 and x_prev.shape[0] > 0:
        rel = (x[i0] - x_prev[i0]) * bc[0] + (x[i1] - x_prev[i1]) * bc[1] + (x[i2] - x_prev[i2]) * bc[2] - slip
        corr = corr + apply_friction(rel, g, depth, mu)
    corr = corr / denom
    if w0 > 0.0:
        wp.atomic_add(delta, i0, corr * (bc[0] * w0))
        wp.atomic_add(delta_count, i0, 1.0)
    if w1 > 0.0:
        wp.atomic_add(delta, i1, corr * (bc[1] * w1))
        wp.atomic_add(delta_count, i1, 1.0)
    if w2 > 0.0:
        wp.atomic_add(delta, i2, corr * (bc[2] * w2))
        wp.atomic_add(delta_count, i2, 1.0)


@wp.kernel
def solve_corner_contacts(
    corners: wp.array[wp.vec3],
    corners_prev: wp.array[wp.vec3],
    corner_friction: wp.array[float],
    x: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    tris: wp.array2d[int],
    inv_mass: wp.array[float],
    ids: wp.array2d[int],
    sides: wp.array2d[float],
    count: wp.array[int],
    thickness: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Collider corner k against the cloth near it (the triangles found for it), the corner kept
    ``thickness`` away on its stored side of the cloth (only the cloth moves: the corner is
    kinematic), with the collider's friction against the cloth's motion relative to the corner
    over the substep (corners_prev: the corner at the substep's start; x_prev: the cloth then, or
    empty for no friction); corrections accumulated for averaging.

    * Every triangle the corner lies under (its projection inside, or through it) is pushed along
      its normal.
    * The cloth's point q closest to the corner, when on an edge or a vertex (where the cloth folds
      over the corner, the corner can lie beyond every triangle's inside: above the ridge or the
      peak of a tent over a cone's apex once through it), is pushed along the side direction g
      there (the mean of the normals of the triangles meeting at q, each turned by its stored side
      to point away from the corner): only that edge's or vertex's cloth vertices move.

    A corner poking through the inside of a triangle, or through an edge or a vertex where the
    cloth folds over it, touches no cloth vertex and cuts no cloth edge against a collider edge,
    so neither the vertex nor the edge pass sees it. The stored sides tell through from in front:
    a corner through the cloth is pushed back, down to the longest edge of the triangle (deeper,
    the pair is taken for a stale one)."""
    k = wp.tid()
    cnt = count[k]
    if cnt == 0:
        return
    p = corners[k]
    slip = p - corners_prev[k]
    mu = corner_friction[k]
    best = float(1.0e30)
    bt = int(-1)
    bq = wp.vec3(0.0)
    bbc = wp.vec3(0.0)
    for j in range(cnt):
        t = ids[k, j]
        i0 = tris[t, 0]
        i1 = tris[t, 1]
        i2 = tris[t, 2]
        a = x[i0]
        b = x[i1]
        c = x[i2]
        bc = closest_on_triangle(p, a, b, c)
        q = a * bc[0] + b * bc[1] + c * bc[2]
        dist = wp.length(p - q)
        if dist < best:
            best = dist
            bt = t
            bq = q
            bbc = bc
        n = unit_normal(x, tris, t)
        if wp.length_sq(n) == 0.0:
            continue
        s = sides[k, j]
        d = s * wp.dot(p - a, n)  # > 0: the corner is on its side
        lmax = wp.max(wp.max(wp.length(b - a), wp.length(c - b)), wp.length(a - c))
        if d >= thickness or d < -lmax:
            continue
        pb = plane_barycentric(p, a, b, c, n)
        if pb[0] < -CORNER_INSIDE_TOL or pb[1] < -CORNER_INSIDE_TOL or pb[2] < -CORNER_INSIDE_TOL:
            continue
        pb = wp.vec3(wp.max(pb[0], 0.0), wp.max(pb[1], 0.0), wp.max(pb[2], 0.0))
        pb = pb / (pb[0] + pb[1] + pb[2])
        push_corner_contact(x, x_prev, inv_mass, i0, i1, i2, pb, n * (-s), thickness - d, slip, mu, delta,
                            delta_count)
    if bbc[0] > 0.0 and bbc[1] > 0.0 and bbc[2] > 0.0:
        return  # the closest point is inside a triangle: held above
    # the side direction at q: the triangles through q (on an edge or a vertex)
    eps = 1.0e-6 + 1.0e-5 * best
    g = wp.vec3(0.0)
    for j in range(cnt):
        t = ids[k, j]
        a = x[tris[t, 0]]
        b = x[tris[t, 1]]
        c = x[tris[t, 2]]
        bc = closest_on_triangle(bq, a, b, c)
        if wp.length(bq - (a * bc[0] + b * bc[1] + c * bc[2])) > eps:
            continue
        g = g - unit_normal(x, tris, t) * sides[k, j]
    lg = wp.length(g)
    if lg < 1.0e-3:
        return  # no side (layers back to back at q)
    g = g / lg
    a = x[tris[bt, 0]]
    b = x[tris[bt, 1]]
    c = x[tris[bt, 2]]
    lmax = wp.max(wp.max(wp.length(b - a), wp.length(c - b)), wp.length(a - c))
    d = wp.dot(bq - p, g)  # > 0: the cloth is on its side
    if d >= thickness or d < -lmax:
        return
    push_corner_contact(x, x_prev, inv_mass, tris[bt, 0], tris[bt, 1], tris[bt, 2], bbc, g, thickness - d, slip, mu,
                        delta, delta_count)
