"""Intersection count of a cloth frame: triangle pairs that pass through each other.

A cloth-cloth pair is two cloth triangles without a shared vertex whose closed triangles share a
point (touching counts); a cloth-collider pair is a cloth triangle and a mesh collider's triangle
that do, plus cloth triangles lying wholly inside a closed mesh collider (generalised winding
number > 1/2 at the centroid, no crossing); against an analytic shape a cloth triangle counts when its
distance to the solid is <= 0 (exact for every kind: planes, spheres, capsules, boxes, cylinders
and cones).

The triangle-triangle test is orientation based, in float64: two non-coplanar triangles meet iff
an edge of one meets the other (segment-triangle by the signs of five orientation determinants);
coplanar ones by 2-D edge crossings and containment. Cloth-cloth candidates come from a dense
grid of the triangles' boxes (a BVH over them, ``wp.Mesh`` + ``mesh_query_aabb``, when the boxes
are too small against the coordinates for float32 cells), so a 64 x 64 cloth counts in
milliseconds.
"""

from __future__ import annotations

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

from . import collision_kernels as ck
from .kernels import boxes_overlap

# ---------------------------------------------------------------------------------------------
# Exact predicates (float64)
# ---------------------------------------------------------------------------------------------


@wp.func
def orient3d(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, d: wp.vec3d) -> float:
    """Sign of det[b - a, c - a, d - a]: +1, -1 or 0 (d above, below or on plane abc)."""
    v = wp.dot(wp.cross(b - a, c - a), d - a)
    if v > wp.float64(0.0):
        return 1.0
    if v < wp.float64(0.0):
        return -1.0
    return 0.0


@wp.func
def segment_meets_triangle(a: wp.vec3d, b: wp.vec3d, p: wp.vec3d, q: wp.vec3d, r: wp.vec3d) -> bool:
    """Closed segment a-b meets closed triangle pqr, for a segment not in the triangle's plane."""
    sa = orient3d(p, q, r, a)
    sb = orient3d(p, q, r, b)
    if sa * sb > 0.0 or (sa == 0.0 and sb == 0.0):
        return False
    # the line a-b passes through the triangle iff it sees the three edges turning the same way
    s1 = orient3d(a, b, p, q)
    s2 = orient3d(a, b, q, r)
    s3 = orient3d(a, b, r, p)
    if (s1 > 0.0 or s2 > 0.0 or s3 > 0.0) and (s1 < 0.0 or s2 < 0.0 or s3 < 0.0):
        return False
    return True


@wp.func
def orient2d(a: wp.vec2d, b: wp.vec2d, c: wp.vec2d) -> float:
    v = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    if v > wp.float64(0.0):
        return 1.0
    if v < wp.float64(0.0):
        return -1.0
    return 0.0


@wp.func
def on_segment2d(a: wp.vec2d, b: wp.vec2d, c: wp.vec2d) -> bool:
    """c (collinear with a-b) lies on the closed segment a-b."""
    return (wp.min(a[0], b[0]) <= c[0] and c[0] <= wp.max(a[0], b[0]) and wp.min(a[1], b[1]) <= c[1]
            and c[1] <= wp.max(a[1], b[1]))


@wp.func
def segments_meet2d(a: wp.vec2d, b: wp.vec2d, c: wp.vec2d, d: wp.vec2d) -> bool:
    o1 = orient2d(a, b, c)
    o2 = orient2d(a, b, d)
    o3 = orient2d(c, d, a)
    o4 = orient2d(c, d, b)
    if o1 * o2 < 0.0 and o3 * o4 < 0.0:
        return True
    if o1 == 0.0 and on_segment2d(a, b, c):
        return True
    if o2 == 0.0 and on_segment2d(a, b, d):
        return True
    if o3 == 0.0 and on_segment2d(c, d, a):
        return True
    if o4 == 0.0 and on_segment2d(c, d, b):
        return True
    return False


@wp.func
def inside2d(p: wp.vec2d, a: wp.vec2d, b: wp.vec2d, c: wp.vec2d) -> bool:
    s1 = orient2d(a, b, p)
    s2 = orient2d(b, c, p)
    s3 = orient2d(c, a, p)
    return not ((s1 > 0.0 or s2 > 0.0 or s3 > 0.0) and (s1 < 0.0 or s2 < 0.0 or s3 < 0.0))


@wp.func
def drop_axis(p: wp.vec3d, axis: int) -> wp.vec2d:
    if axis == 0:
        return wp.vec2d(p[1], p[2])
    if axis == 1:
        return wp.vec2d(p[0], p[2])
    return wp.vec2d(p[0], p[1])


@wp.func
def coplanar_triangles_meet(a0: wp.vec3d, a1: wp.vec3d, a2: wp.vec3d, b0: wp.vec3d, b1: wp.vec3d,
                            b2: wp.vec3d) -> bool:
    n = wp.cross(a1 - a0, a2 - a0)
    ax = 0
    if wp.abs(n[1]) > wp.abs(n[0]) and wp.abs(n[1]) >= wp.abs(n[2]):
        ax = 1
    elif wp.abs(n[2]) > wp.abs(n[0]) and wp.abs(n[2]) > wp.abs(n[1]):
        ax = 2
    p0 = drop_axis(a0, ax)
    p1 = drop_axis(a1, ax)
    p2 = drop_axis(a2, ax)
    q0 = drop_axis(b0, ax)
    q1 = drop_axis(b1, ax)
    q2 = drop_axis(b2, ax)
    if segments_meet2d(p0, p1, q0, q1) or segments_meet2d(p0, p1, q1, q2) or segments_meet2d(p0, p1, q2, q0):
        return True
    if segments_meet2d(p1, p2, q0, q1) or segments_meet2d(p1, p2, q1, q2) or segments_meet2d(p1, p2, q2, q0):
        return True
    if segments_meet2d(p2, p0, q0, q1) or segments_meet2d(p2, p0, q1, q2) or segments_meet2d(p2, p0, q2, q0):
        return True
    return inside2d(p0, q0, q1, q2) or inside2d(q0, p0, p1, p2)


@wp.func
def triangles_meet(a0: wp.vec3d, a1: wp.vec3d, a2: wp.vec3d, b0: wp.vec3d, b1: wp.vec3d, b2: wp.vec3d) -> bool:
    """Closed triangles a and b share a point (exact up to float64 rounding of the determinants)."""
    s0 = orient3d(b0, b1, b2, a0)
    s1 = orient3d(b0, b1, b2, a1)
    s2 = orient3d(b0, b1, b2, a2)
    if (s0 > 0.0 and s1 > 0.0 and s2 > 0.0) or (s0 < 0.0 and s1 < 0.0 and s2 < 0.0):
        return False
    if s0 == 0.0 and s1 == 0.0 and s2 == 0.0:
        return coplanar_triangles_meet(a0, a1, a2, b0, b1, b2)
    t0 = orient3d(a0, a1, a2, b0)
    t1 = orient3d(a0, a1, a2, b1)
    t2 = orient3d(a0, a1, a2, b2)
    if (t0 > 0.0 and t1 > 0.0 and t2 > 0.0) or (t0 < 0.0 and t1 < 0.0 and t2 < 0.0):
        return False
    # not coplanar: they meet iff an edge of one meets the other
    if segment_meets_triangle(a0, a1, b0, b1, b2) or segment_meets_triangle(a1, a2, b0, b1, b2):
        return True
    if segment_meets_triangle(a2, a0, b0, b1, b2) or segment_meets_triangle(b0, b1, a0, a1, a2):
        return True
    return segment_meets_triangle(b1, b2, a0, a1, a2) or segment_meets_triangle(b2, b0, a0, a1, a2)


@wp.func
def plane_separates(a0: wp.vec3, a1: wp.vec3, a2: wp.vec3, b0: wp.vec3, b1: wp.vec3, b2: wp.vec3) -> bool:
    """The plane of triangle a has triangle b strictly on one side, by a margin far above float32
    rounding (1e-5 of the points' spread; the float32 error of these dot products is ~1e-6 of
    it): a cheap certain rejection before the float64 test."""
    n = wp.cross(a1 - a0, a2 - a0)
    ln = wp.length(n)
    if ln == 0.0:
        return False
    n = n / ln
    d0 = wp.dot(b0 - a0, n)
    d1 = wp.dot(b1 - a0, n)
    d2 = wp.dot(b2 - a0, n)
    spread = wp.length(b0 - a0) + wp.length(a1 - a0) + wp.length(a2 - a0) + wp.length(b1 - b0) + wp.length(b2 - b0)
    eps = 1.0e-5 * spread
    return (d0 > eps and d1 > eps and d2 > eps) or (d0 < -eps and d1 < -eps and d2 < -eps)


@wp.func
def v3d(p: wp.vec3) -> wp.vec3d:
    return wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------


@wp.func
def mark_triangle(mark: wp.array[int], tris: wp.array[wp.vec3i], t: int):
    """mark[v] = 1 for the three vertices of cloth triangle t (no-op for an empty mark)."""
    if mark.shape[0] > 0:
        mark[tris[t][0]] = 1
        mark[tris[t][1]] = 1
        mark[tris[t][2]] = 1


@wp.func
def count_pair(x0: wp.array[wp.vec3], tris: wp.array[wp.vec3i], t: int, u: int, count: wp.array[int],
               pairs: wp.array[wp.vec2i], mark: wp.array[int]):
    """Count intersecting cloth pair (t, u) in count[0] and keep it; mark both triangles, unless
    x0 (positions at the start of the step; empty: no such test) is given and the pair met there
    too: such an inherited pair is counted in count[1] as well and not marked (sending its
    vertices back to x0 cannot remove it)."""
    k = wp.atomic_add(count, 0, 1)
    if k < pairs.shape[0]:
        pairs[k] = wp.vec2i(t, u)
    if x0.shape[0] > 0:
        if triangles_meet(v3d(x0[tris[t][0]]), v3d(x0[tris[t][1]]), v3d(x0[tris[t][2]]), v3d(x0[tris[u][0]]),
                          v3d(x0[tris[u][1]]), v3d(x0[tris[u][2]])):
            wp.atomic_add(count, 1, 1)
            return
    mark_triangle(mark, tris, t)
    mark_triangle(mark, tris, u)


@wp.func
def test_self_pair(x: wp.array[wp.vec3], tris: wp.array[wp.vec3i], x0: wp.array[wp.vec3], t: int, u: int,
                   count: wp.array[int], pairs: wp.array[wp.vec2i], mark: wp.array[int]):
    """The narrow phase of both cloth-cloth counts: triangles t and u (sharing no vertex) are counted by
    :func:`count_pair` when they meet (a separating plane of either rejects them first)."""
    a = tris[t][0]
    b = tris[t][1]
    c = tris[t][2]
    d = tris[u][0]
    e = tris[u][1]
    f = tris[u][2]
    if a == d or a == e or a == f or b == d or b == e or b == f or c == d or c == e or c == f:
        return
    pa = x[a]
    pb = x[b]
    pc = x[c]
    pd = x[d]
    pe = x[e]
    pf = x[f]
    if plane_separates(pa, pb, pc, pd, pe, pf) or plane_separates(pd, pe, pf, pa, pb, pc):
        return
    if triangles_meet(v3d(pa), v3d(pb), v3d(pc), v3d(pd), v3d(pe), v3d(pf)):
        count_pair(x0, tris, wp.min(t, u), wp.max(t, u), count, pairs, mark)


@wp.kernel
def count_self_pairs(
    mesh: wp.uint64,
    x: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    x0: wp.array[wp.vec3],
    count: wp.array[int],
    pairs: wp.array[wp.vec2i],
    mark: wp.array[int],
):
    """Cloth-cloth intersecting pairs (t, u), t < u, no shared vertex; the first pairs are kept,
    and the vertices of both triangles marked (except inherited pairs, see :func:`count_pair`)."""
    t = wp.tid()
    pa = x[tris[t][0]]
    pb = x[tris[t][1]]
    pc = x[tris[t][2]]
    lo = wp.min(wp.min(pa, pb), pc)
    hi = wp.max(wp.max(pa, pb), pc)
    query = wp.mesh_query_aabb(mesh, lo, hi)
    u = int(0)
    while wp.mesh_query_aabb_next(query, u):
        if u <= t:
            continue
        test_self_pair(x, tris, x0, t, u, count, pairs, mark)


@wp.kernel
def triangle_boxes(x: wp.array[wp.vec3], tris: wp.array[wp.vec3i], lower: wp.array[wp.vec3], upper: wp.array[wp.vec3]):
    t = wp.tid()
    pa = x[tris[t][0]]
    pb = x[tris[t][1]]
    pc = x[tris[t][2]]
    lower[t] = wp.min(wp.min(pa, pb), pc)
    upper[t] = wp.max(wp.max(pa, pb), pc)


@wp.func
def before(lo_t: wp.vec3, t: int, lo_u: wp.vec3, u: int) -> bool:
    """Triangle t comes before u in the order (lower box corner's x, index)."""
    return lo_t[0] < lo_u[0] or (lo_t[0] == lo_u[0] and t < u)


@wp.func
def grid_cell(p: wp.vec3, origin: wp.vec3, inv: wp.vec3, dims: wp.vec3i) -> wp.vec3i:
    """Cell of point p in the dense grid of ``dims`` cells 1 / ``inv[k]`` wide along axis k from
    ``origin``, clamped to the grid (monotone along each axis)."""
    q = wp.cw_mul(p - origin, inv)
    return wp.vec3i(wp.clamp(int(wp.floor(q[0])), 0, dims[0] - 1), wp.clamp(int(wp.floor(q[1])), 0, dims[1] - 1),
                    wp.clamp(int(wp.floor(q[2])), 0, dims[2] - 1))


@wp.kernel
def bin_boxes(lower: wp.array[wp.vec3], origin: wp.vec3, inv: wp.vec3, dims: wp.vec3i, cell: wp.array[int],
              rank: wp.array[int], cell_size: wp.array[int]):
    """Grid cell of each triangle's lower box corner (x fastest), its rank among the cell's
    triangles and the cells' sizes."""
    t = wp.tid()
    c = grid_cell(lower[t], origin, inv, dims)
    k = (c[2] * dims[1] + c[1]) * dims[0] + c[0]
    cell[t] = k
    rank[t] = wp.atomic_add(cell_size, k, 1)


@wp.struct
class GridSlot:
    """A triangle in the grid's counting-sorted order: its box, vertices and index."""
    lo: wp.vec3
    hi: wp.vec3
    tri: wp.vec3i
    id: int


@wp.kernel
def sort_boxes(cell: wp.array[int], rank: wp.array[int], first: wp.array[int], lower: wp.array[wp.vec3],
               upper: wp.array[wp.vec3], tris: wp.array[wp.vec3i], slots: wp.array[GridSlot]):
    """Counting sort of the triangles by cell (``first[k]`` the first slot of cell k), their
    boxes and vertices stored in the slot so that a walk along a row of cells reads them in order."""
    t = wp.tid()
    g = GridSlot()
    g.lo = lower[t]
    g.hi = upper[t]
    g.tri = tris[t]
    g.id = t
    slots[first[cell[t]] + rank[t]] = g


@wp.func
def share_vertex(a: wp.vec3i, b: wp.vec3i) -> bool:
    """Triangles with vertices a and b share a vertex."""
    return (a[0] == b[0] or a[0] == b[1] or a[0] == b[2] or a[1] == b[0] or a[1] == b[1] or a[1] == b[2]
            or a[2] == b[0] or a[2] == b[1] or a[2] == b[2])


@wp.kernel
def count_self_pairs_grid(
    first: wp.array[int],
    slots: wp.array[GridSlot],
    origin: wp.vec3,
    inv: wp.vec3,
    dims: wp.vec3i,
    width_y: float,
    width_z: float,
    slack: float,
    x: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    x0: wp.array[wp.vec3],
    count: wp.array[int],
    pairs: wp.array[wp.vec2i],
    mark: wp.array[int],
):
    """:func:`count_self_pairs` with a dense grid of the triangles' lower box corners as the
    broad phase (cells 1 / ``inv[k]`` wide along axis k; counting-sorted by
    :func:`sort_boxes`, ``first[k]`` the first slot of cell k); ``width_y`` and ``width_z`` are at
    least every box's extent along y and z. A pair is tested from the triangle t that comes first
    in (lower x, index): the other's lower corner then lies in [lo.x, hi.x] x [lo.y - width_y,
    hi.y] x [lo.z - width_z, hi.z] of t's box, and t walks the cells covering that range widened
    by ``slack`` (the float32 rounding of the bounds), one contiguous run of slots per row of
    cells along x, so every box-overlapping pair is tested exactly once. Most slots of a cloth's walk
    hold triangles sharing a vertex with t (its neighbours), so that test comes first."""
    me = slots[wp.tid()]
    t = me.id
    lo = me.lo
    hi = me.hi
    vt = me.tri
    c0 = grid_cell(wp.vec3(lo[0] - slack, lo[1] - width_y - slack, lo[2] - width_z - slack), origin, inv, dims)
    c1 = grid_cell(hi + wp.vec3(slack), origin, inv, dims)
    for cz in range(c0[2], c1[2] + 1):
        for cy in range(c0[1], c1[1] + 1):
            row = (cz * dims[1] + cy) * dims[0]
            for r in range(first[row + c0[0]], first[row + c1[0] + 1]):
                other = slots[r]
                if share_vertex(vt, other.tri):
                    continue
                if not before(lo, t, other.lo, other.id):
                    continue
                if not boxes_overlap(lo, hi, other.lo, other.hi):
                    continue
                test_self_pair(x, tris, x0, t, other.id, count, pairs, mark)


@wp.func
def mesh_inside(mesh: wp.uint64, pa: wp.vec3, pb: wp.vec3, pc: wp.vec3) -> bool:
    """The centroid of triangle abc is inside the closed mesh (winding number > 1/2)."""
    q = wp.mesh_query_point_sign_winding_number(mesh, (pa + pb + pc) / 3.0, 1.0e6, 2.0, 0.5)
    return q.result and q.sign < 0.0


@wp.func
def mesh_meets(mesh: wp.uint64, mesh_points: wp.array[wp.vec3], mesh_tris: wp.array[int], closed: int, pa: wp.vec3,
               pb: wp.vec3, pc: wp.vec3) -> bool:
    """Triangle abc crosses a triangle of the collider mesh, or lies inside it (closed mesh)."""
    query = wp.mesh_query_aabb(mesh, wp.min(wp.min(pa, pb), pc), wp.max(wp.max(pa, pb), pc))
    u = int(0)
    while wp.mesh_query_aabb_next(query, u):
        if triangles_meet(v3d(pa), v3d(pb), v3d(pc), v3d(mesh_points[mesh_tris[3 * u]]),
                          v3d(mesh_points[mesh_tris[3 * u + 1]]), v3d(mesh_points[mesh_tris[3 * u + 2]])):
            return True
    if closed != 0:
        return mesh_inside(mesh, pa, pb, pc)
    return False


@wp.kernel
def count_mesh_pairs(
    mesh: wp.uint64,
    mesh_points: wp.array[wp.vec3],
    mesh_tris: wp.array[int],
    closed: int,
    x: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    x0: wp.array[wp.vec3],
    count: wp.array[int],
    pairs: wp.array[wp.vec2i],
    mark: wp.array[int],
):
    """Cloth triangle t against a collider mesh: crossing triangle pairs (t, collider triangle),
    or, for a closed mesh, (t, -1) once for a cloth triangle wholly inside it; t's vertices are
    marked, unless t at x0 (if given) meets the mesh too (inherited: its pairs also counted in
    count[1])."""
    t = wp.tid()
    pa = x[tris[t][0]]
    pb = x[tris[t][1]]
    pc = x[tris[t][2]]
    lo = wp.min(wp.min(pa, pb), pc)
    hi = wp.max(wp.max(pa, pb), pc)
    query = wp.mesh_query_aabb(mesh, lo, hi)
    u = int(0)
    crossed = int(0)
    while wp.mesh_query_aabb_next(query, u):
        q0 = mesh_points[mesh_tris[3 * u]]
        q1 = mesh_points[mesh_tris[3 * u + 1]]
        q2 = mesh_points[mesh_tris[3 * u + 2]]
        if triangles_meet(v3d(pa), v3d(pb), v3d(pc), v3d(q0), v3d(q1), v3d(q2)):
            crossed += 1
            k = wp.atomic_add(count, 0, 1)
            if k < pairs.shape[0]:
                pairs[k] = wp.vec2i(t, u)
    hit = int(0)
    if crossed > 0:
        hit = crossed
    elif closed != 0:
        if mesh_inside(mesh, pa, pb, pc):
            hit = 1
            k = wp.atomic_add(count, 0, 1)
            if k < pairs.shape[0]:
                pairs[k] = wp.vec2i(t, -1)
    if hit > 0:
        if x0.shape[0] > 0:
            if mesh_meets(mesh, mesh_points, mesh_tris, closed, x0[tris[t][0]], x0[tris[t][1]], x0[tris[t][2]]):
                wp.atomic_add(count, 1, hit)
                return
        mark_triangle(mark, tris, t)


@wp.func
def point_triangle_closest(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> wp.vec3d:
    """Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    zero = wp.float64(0.0)
    if d1 <= zero and d2 <= zero:
        return a
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    if d3 >= zero and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= zero and d1 >= zero and d3 <= zero:
        return a + ab * (d1 / (d1 - d3))
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    if d6 >= zero and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= zero and d2 >= zero and d6 <= zero:
        return a + ac * (d2 / (d2 - d6))
    va = d3 * d6 - d5 * d4
    if va <= zero and (d4 - d3) >= zero and (d5 - d6) >= zero:
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    denom = wp.float64(1.0) / (va + vb + vc)
    return a + ab * (vb * denom) + ac * (vc * denom)


@wp.func
def segment_segment_distance(p1: wp.vec3d, q1: wp.vec3d, p2: wp.vec3d, q2: wp.vec3d) -> wp.float64:
    """Distance between closed segments p1-q1 and p2-q2 (Ericson 5.1.9)."""
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = wp.dot(d1, d1)
    e = wp.dot(d2, d2)
    f = wp.dot(d2, r)
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    s = zero
    t = zero
    if a <= wp.float64(1.0e-30) and e <= wp.float64(1.0e-30):
        return wp.length(p1 - p2)
    if a <= wp.float64(1.0e-30):
        t = wp.clamp(f / e, zero, one)
    else:
        c = wp.dot(d1, r)
        if e <= wp.float64(1.0e-30):
            s = wp.clamp(-c / a, zero, one)
        else:
            b = wp.dot(d1, d2)
            den = a * e - b * b
            if den != zero:
                s = wp.clamp((b * f - c * e) / den, zero, one)
            t = (b * s + f) / e
            if t < zero:
                t = zero
                s = wp.clamp(-c / a, zero, one)
            elif t > one:
                t = one
                s = wp.clamp((b - c) / a, zero, one)
    return wp.length((p1 + d1 * s) - (p2 + d2 * t))


@wp.func
def segment_triangle_distance(s0: wp.vec3d, s1: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> wp.float64:
    if segment_meets_triangle(s0, s1, a, b, c):
        return wp.float64(0.0)
    d = wp.length(s0 - point_triangle_closest(s0, a, b, c))
    d = wp.min(d, wp.length(s1 - point_triangle_closest(s1, a, b, c)))
    d = wp.min(d, segment_segment_distance(s0, s1, a, b))
    d = wp.min(d, segment_segment_distance(s0, s1, b, c))
    return wp.min(d, segment_segment_distance(s0, s1, c, a))


@wp.func
def quadratic_min_on(qa: wp.float64, qb: wp.float64, qc: wp.float64, t0: wp.float64, t1: wp.float64) -> wp.float64:
    """Minimum of qa t^2 + qb t + qc over t0 <= t <= t1: the ends, and the vertex when the
    parabola opens upwards and its vertex lies between them."""
    m = wp.min(qa * t0 * t0 + qb * t0 + qc, qa * t1 * t1 + qb * t1 + qc)
    if qa > wp.float64(0.0):
        tv = -qb / (wp.float64(2.0) * qa)
        if tv > t0 and tv < t1:
            m = wp.min(m, qa * tv * tv + qb * tv + qc)
    return m


@wp.func
def segment_meets_revolved(cone: bool, p: wp.vec3d, q: wp.vec3d, a: wp.vec3d, u: wp.vec3d, length: wp.float64,
                           rad: wp.float64) -> bool:
    """Closed segment p-q meets the solid cylinder (cone: the solid cone with its apex at the far
    end) of axis a + u h, 0 <= h <= length, radius rad (cone: at h = 0). Along the segment the
    height h(t) is linear, so 0 <= h <= length is an interval of t; on it the solid is
    |w(t)|^2 - k(t)^2 <= 0 with w the offset from the axis and k the radius at h(t) (constant, or
    linear and >= 0 for the cone): a quadratic in t whose minimum over the interval decides."""
    zero = wp.float64(0.0)
    d = q - p
    h0 = wp.dot(p - a, u)
    dh = wp.dot(d, u)
    t0 = zero
    t1 = wp.float64(1.0)
    if dh == zero:
        if h0 < zero or h0 > length:
            return False
    else:
        ta = -h0 / dh
        tb = (length - h0) / dh
        t0 = wp.max(t0, wp.min(ta, tb))
        t1 = wp.min(t1, wp.max(ta, tb))
        if t0 > t1:
            return False
    w0 = (p - a) - u * h0
    dw = d - u * dh
    k0 = rad
    dk = zero
    if cone:
        k0 = rad * (wp.float64(1.0) - h0 / length)
        dk = -rad * dh / length
    qa = wp.dot(dw, dw) - dk * dk
    qb = wp.float64(2.0) * (wp.dot(w0, dw) - k0 * dk)
    qc = wp.dot(w0, w0) - k0 * k0
    return quadratic_min_on(qa, qb, qc, t0, t1) <= zero


@wp.func
def in_triangle(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, n: wp.vec3d) -> bool:
    """p (in the plane of abc, normal n) lies in the closed triangle: the three edge signs agree."""
    zero = wp.float64(0.0)
    return (wp.dot(wp.cross(b - a, p - a), n) >= zero and wp.dot(wp.cross(c - b, p - b), n) >= zero
            and wp.dot(wp.cross(a - c, p - c), n) >= zero)


@wp.func
def circle_meets_triangle(cen: wp.vec3d, u: wp.vec3d, rad: wp.float64, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> bool:
    """The circle of radius rad about cen in the plane normal to unit u crosses the closed triangle
    abc: the (up to two) points where it crosses the triangle's plane, c + rad (cos s e1 + sin s e2)
    with A cos s + B sin s = -D, lie in the triangle. A circle in the triangle's plane gives False
    (the callers cover that case by the axis test)."""
    n = wp.cross(b - a, c - a)
    e1 = wp.cross(u, wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0)))
    if wp.length(e1) < wp.float64(0.5):
        e1 = wp.cross(u, wp.vec3d(wp.float64(0.0), wp.float64(1.0), wp.float64(0.0)))
    e1 = wp.normalize(e1)
    e2 = wp.cross(u, e1)
    ca = rad * wp.dot(n, e1)
    cb = rad * wp.dot(n, e2)
    cd = wp.dot(n, cen - a)
    m = wp.sqrt(ca * ca + cb * cb)
    if m == wp.float64(0.0) or wp.abs(cd) > m:
        return False
    phi = wp.atan2(cb, ca)
    delta = wp.acos(wp.clamp(-cd / m, wp.float64(-1.0), wp.float64(1.0)))
    s = phi + delta
    p0 = cen + (e1 * wp.cos(s) + e2 * wp.sin(s)) * rad
    s = phi - delta
    p1 = cen + (e1 * wp.cos(s) + e2 * wp.sin(s)) * rad
    return in_triangle(p0, a, b, c, n) or in_triangle(p1, a, b, c, n)


@wp.func
def triangle_meets_revolved(cone: bool, a0: wp.vec3d, b0: wp.vec3d, rad: wp.float64, pa: wp.vec3d, pb: wp.vec3d,
                            pc: wp.vec3d) -> bool:
    """Closed triangle meets the solid cylinder with cap centres a0, b0 (cone: base centre a0,
    apex b0) of radius rad. Exact: if no edge of the triangle meets the solid, the solid's section
    by the triangle's plane lies inside the triangle; that section either holds a point of the axis
    segment (the plane separates the two caps, or the base from the apex) or meets a cap disc, whose
    chord ends on the rim circle inside the triangle. So: an edge meets the solid, the axis segment
    meets the triangle, or a rim circle crosses it."""
    length = wp.length(b0 - a0)
    u = (b0 - a0) / length
    if segment_meets_revolved(cone, pa, pb, a0, u, length, rad) or segment_meets_revolved(cone, pb, pc, a0, u,
                                                                                          length, rad):
        return True
    if segment_meets_revolved(cone, pc, pa, a0, u, length, rad):
        return True
    if segment_meets_triangle(a0, b0, pa, pb, pc):
        return True
    if circle_meets_triangle(a0, u, rad, pa, pb, pc):
        return True
    if not cone:
        return circle_meets_triangle(b0, u, rad, pa, pb, pc)
    return False


@wp.func
def triangle_box_overlap(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, h: wp.vec3d) -> bool:
    """Closed triangle meets the closed box |x_k| <= h_k (separating axes: 3 box faces, the
    triangle's normal, 9 edge cross products; Akenine-Moller 2001)."""
    # box face normals
    for k in range(3):
        lo = wp.min(wp.min(a[k], b[k]), c[k])
        hi = wp.max(wp.max(a[k], b[k]), c[k])
        if lo > h[k] or hi < -h[k]:
            return False
    n = wp.cross(b - a, c - a)
    rn = h[0] * wp.abs(n[0]) + h[1] * wp.abs(n[1]) + h[2] * wp.abs(n[2])
    if wp.abs(wp.dot(n, a)) > rn:
        return False
    for i in range(3):
        e = b - a
        if i == 1:
            e = c - b
        elif i == 2:
            e = a - c
        for k in range(3):
            ax = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
            # axis = e x unit_k
            if k == 0:
                ax = wp.vec3d(wp.float64(0.0), e[2], -e[1])
            elif k == 1:
                ax = wp.vec3d(-e[2], wp.float64(0.0), e[0])
            else:
                ax = wp.vec3d(e[1], -e[0], wp.float64(0.0))
            pa = wp.dot(ax, a)
            pb = wp.dot(ax, b)
            pc = wp.dot(ax, c)
            r = h[0] * wp.abs(ax[0]) + h[1] * wp.abs(ax[1]) + h[2] * wp.abs(ax[2])
            if wp.min(wp.min(pa, pb), pc) > r or wp.max(wp.max(pa, pb), pc) < -r:
                return False
    return True


@wp.func
def shape_meets(k: int, a: wp.vec3, b: wp.vec3, rot: wp.quat, size: wp.vec3, pa: wp.vec3, pb: wp.vec3,
                pc: wp.vec3) -> bool:
    """Closed cloth triangle abc meets analytic solid k (exact for every kind)."""
    if k == ck.SHAPE_PLANE:
        n = wp.normalize(b)
        return wp.min(wp.min(wp.dot(pa - a, n), wp.dot(pb - a, n)), wp.dot(pc - a, n)) <= 0.0
    if k == ck.SHAPE_SPHERE:
        cen = v3d(a)
        cp = point_triangle_closest(cen, v3d(pa), v3d(pb), v3d(pc))
        return wp.length(cp - cen) <= wp.float64(size[0])
    if k == ck.SHAPE_CAPSULE:
        return segment_triangle_distance(v3d(a), v3d(b), v3d(pa), v3d(pb), v3d(pc)) <= wp.float64(size[0])
    if k == ck.SHAPE_BOX:
        la = v3d(wp.quat_rotate_inv(rot, pa - a))
        lb = v3d(wp.quat_rotate_inv(rot, pb - a))
        lc = v3d(wp.quat_rotate_inv(rot, pc - a))
        return triangle_box_overlap(la, lb, lc, v3d(size))
    return triangle_meets_revolved(k == ck.SHAPE_CONE, v3d(a), v3d(b), wp.float64(size[0]), v3d(pa), v3d(pb),
                                   v3d(pc))


@wp.kernel
def count_shape_triangles(
    kind: wp.array[int],
    a: wp.array[wp.vec3],
    b: wp.array[wp.vec3],
    rot: wp.array[wp.quat],
    size: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    x0: wp.array[wp.vec3],
    count: wp.array[int],
    pairs: wp.array[wp.vec2i],
    mark: wp.array[int],
):
    """Cloth triangles meeting an analytic solid: pairs (cloth triangle, shape index); t's
    vertices are marked, unless t at x0 (if given) meets that solid too (inherited: also counted
    in count[1])."""
    t = wp.tid()
    pa = x[tris[t][0]]
    pb = x[tris[t][1]]
    pc = x[tris[t][2]]
    for s in range(kind.shape[0]):
        if shape_meets(kind[s], a[s], b[s], rot[s], size[s], pa, pb, pc):
            q = wp.atomic_add(count, 0, 1)
            if q < pairs.shape[0]:
                pairs[q] = wp.vec2i(t, s)
            inherited = bool(False)
            if x0.shape[0] > 0:
                inherited = shape_meets(kind[s], a[s], b[s], rot[s], size[s], x0[tris[t][0]], x0[tris[t][1]],
                                        x0[tris[t][2]])
            if inherited:
                wp.atomic_add(count, 1, 1)
            else:
                mark_triangle(mark, tris, t)


# ---------------------------------------------------------------------------------------------
# Host entry points
# ---------------------------------------------------------------------------------------------


class IntersectionCounter:
    """Counts intersecting triangle pairs of one cloth topology frame after frame (keeps its BVH).

    Args:
        faces: Cloth triangles, shape (F, 3), int.
        device: Warp device.
        keep: How many pairs to return (the count is always complete).
    """

    def __init__(self, faces: np.ndarray, device="cpu", keep: int = 64):
        self.device = wp.get_device(device)
        f = np.asarray(faces, dtype=np.int32)
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"count_intersections: faces must have shape (F, 3), got {f.shape}")
        self.faces = f
        self.tris = wp.array(f, dtype=wp.vec3i, device=self.device)
        self._indices = wp.array(f.reshape(-1), dtype=wp.int32, device=self.device)
        self._x = None
        self._mesh = None
        self._mesh_stale = True
        self._count = wp.zeros(2, dtype=wp.int32, device=self.device)
        self._no_points = wp.zeros(0, dtype=wp.vec3, device=self.device)
        self.inherited = 0
        """Of the last count's pairs, how many also met at ``start`` (0 without ``start``)."""
        self._pairs = wp.zeros(max(keep, 1), dtype=wp.vec2i, device=self.device)
        self._no_mark = wp.zeros(0, dtype=wp.int32, device=self.device)
        self._lower = wp.zeros(len(f), dtype=wp.vec3, device=self.device)
        self._upper = wp.zeros(len(f), dtype=wp.vec3, device=self.device)
        nf = max(len(f), 1)
        self._cell = wp.zeros(nf, dtype=wp.int32, device=self.device)
        self._rank = wp.zeros(nf, dtype=wp.int32, device=self.device)
        self._slots = wp.zeros(nf, dtype=GridSlot, device=self.device)
        self._cell_size = self._first = self._cell_width = None

    X_CELL = 0.5
    """Width of the cloth-cloth count's grid cells along x (the axis a walk reads as contiguous runs
    of slots) against their width along y and z: narrower cells along x add no runs to a walk, only
    table room, and leave fewer boxes that lie before the walking triangle's in its runs."""

    MAX_CELLS = 1 << 17
    """Most cells of the cloth-cloth count's grid (cells grow beyond the widest box past it);
    every count clears and scans them."""

    def _points(self, points) -> wp.array:
        if isinstance(points, wp.array):
            pts = points
        else:
            p = np.asarray(points, dtype=np.float32)
            if p.ndim != 2 or p.shape[1] != 3 or (len(self.faces) and self.faces.max() >= len(p)):
                raise ValueError(f"count_intersections: points must have shape (V, 3) covering the faces, got {p.shape}")
            if not np.isfinite(p).all():
                raise ValueError(f"count_intersections: vertex {int(np.flatnonzero(~np.isfinite(p).all(1))[0])} "
                                 "is not finite")
            pts = wp.array(p, dtype=wp.vec3, device=self.device)
        if self._x is None or self._x.shape != pts.shape:
            self._x = wp.empty(pts.shape[0], dtype=wp.vec3, device=self.device)
            self._mesh = None
        wp.copy(self._x, pts)
        self._mesh_stale = True
        return self._x

    def _mesh_id(self) -> int:
        """The BVH of the cloth's triangles at the points last given, built or refitted only when
        a count uses it (the grid count and the collider counts do not)."""
        if self._mesh is None:
            self._mesh = wp.Mesh(points=self._x, indices=self._indices)
        elif self._mesh_stale:
            self._mesh.refit()
        self._mesh_stale = False
        return self._mesh.id

    def _run(self, kernel, inputs, mark, start=None) -> tuple[int, np.ndarray]:
        self._count.zero_()
        wp.launch(kernel, dim=len(self.faces), inputs=[*inputs, self._no_points if start is None else start],
                  outputs=[self._count, self._pairs, self._no_mark if mark is None else mark], device=self.device)
        n, self.inherited = (int(v) for v in self._count.numpy())
        return n, self._pairs.numpy()[:min(n, self._pairs.shape[0])].copy()

    def self_pairs(self, points, mark=None, start=None) -> tuple[int, np.ndarray]:
        """(count, first pairs (K, 2) of triangle indices) of cloth-cloth intersections.

        Args:
            points: Cloth vertex positions [m], shape (V, 3) (array or ``wp.array`` of vec3).
            mark: Optional, shape (V,), dtype int32: set to 1 at every vertex of an intersecting triangle.
            start: Optional ``wp.array`` of vec3, shape (V,): the positions at the start of the
                step. A pair that met there too is inherited: counted (and in :attr:`inherited`)
                but not marked.
        """
        x = self._points(points)
        self.inherited = 0
        if not len(self.faces):
            return 0, self._pairs.numpy()[:0].copy()
        wp.launch(triangle_boxes, dim=len(self.faces), inputs=[x, self.tris], outputs=[self._lower, self._upper],
                  device=self.device)
        # (3, F): numpy reduces the rows of an (F, 3) array along axis 0 some 20 times slower
        lo, hi = np.ascontiguousarray(self._lower.numpy().T), np.ascontiguousarray(self._upper.numpy().T)
        extent = (hi - lo).max(axis=1)
        width = float(extent.max())
        size = float(np.abs(lo).max() + np.abs(hi).max())
        if not (np.isfinite(size) and width * 1.0e5 > size):
            # cells too small against the coordinates for float32 cell arithmetic: the BVH
            return self._run(count_self_pairs, [self._mesh_id(), x, self.tris], mark, start)
        # cells as wide as the widest box along y and z (a walk then covers 2-3 of them along
        # each) and X_CELL of that along x, wider when the grid would have more than MAX_CELLS;
        # the walk's slack (2 % of a cell and the float32 rounding of the bounds, a few ulp of the
        # largest coordinate) so no overlapping box is missed
        origin = lo.min(axis=1).astype(np.float64)
        span = lo.max(axis=1) - origin
        cell = width
        shape = np.array([self.X_CELL, 1.0, 1.0])
        while np.prod(np.floor(span / (cell * shape)) + 1) > self.MAX_CELLS:
            cell *= 1.25
        dims = (np.floor(span / (cell * shape)) + 1).astype(int)
        cells = int(np.prod(dims))
        self._cell_width = cell
        if self._first is None or self._first.shape[0] < cells + 1:
            room = min(max(cells + 1, 2 * (0 if self._first is None else self._first.shape[0])), self.MAX_CELLS + 1)
            self._cell_size = wp.zeros(room, dtype=wp.int32, device=self.device)
            self._first = wp.zeros(room, dtype=wp.int32, device=self.device)
        nf, d = len(self.faces), self.device
        o, inv, dm = wp.vec3(*origin), wp.vec3(*(1.0 / (cell * shape))), wp.vec3i(*dims.tolist())
        sizes, first = self._cell_size[:cells + 1], self._first[:cells + 1]
        sizes.zero_()
        wp.launch(bin_boxes, dim=nf, inputs=[self._lower, o, inv, dm], outputs=[self._cell, self._rank, sizes],
                  device=d)
        wp.utils.array_scan(sizes, first, inclusive=False)
        wp.launch(sort_boxes, dim=nf, inputs=[self._cell, self._rank, first, self._lower, self._upper, self.tris],
                  outputs=[self._slots], device=d)
        return self._run(count_self_pairs_grid, [first, self._slots, o, inv, dm,
                                                 float(extent[1]), float(extent[2]), 0.02 * cell + 1.0e-6 * size, x,
                                                 self.tris], mark, start)

    def collider_pairs(self, points, colliders, mark=None, start=None) -> tuple[int, np.ndarray]:
        """(count, first pairs) against a :class:`~warpshade.sim.ColliderSet` as posed at the end
        of the last step: (cloth triangle, shape index) for analytic shapes, then (cloth triangle,
        collider triangle or -1 for wholly inside) per mesh collider; ``mark`` and ``start`` as
        in :meth:`self_pairs` (a cloth triangle at ``start`` against the collider as posed now)."""
        x = self._points(points)
        total, inherited, kept = 0, 0, []
        ar = colliders.end_pose_arrays()
        if ar is not None:
            n, p = self._run(count_shape_triangles, [ar["kind"], ar["a_end"], ar["b_end"], ar["rot_end"], ar["size"],
                                                     x, self.tris], mark, start)
            total += n
            inherited += self.inherited
            kept.append(p)
        for m in colliders.meshes:
            n, p = self._run(count_mesh_pairs, [m.mesh.id, m.mesh.points, m.indices, int(m.closed), x, self.tris], mark,
                             start)
            total += n
            inherited += self.inherited
            kept.append(p)
        self.inherited = inherited
        return total, (np.concatenate(kept) if kept else np.zeros((0, 2), np.int32))


def count_intersections(points, faces, colliders=None, device="cpu") -> dict:
    """Intersecting triangle pairs of one cloth frame.

    Args:
        points: Cloth vertex positions [m], shape (V, 3) (array or ``wp.array`` of vec3).
        faces: Cloth triangles, shape (F, 3).
        colliders: A :class:`~warpshade.sim.ColliderSet` (as posed at the end of its last step), or None.
        device: Warp device.

    Returns:
        ``{"self": n, "collider": m, "total": n + m, "self_pairs": (K, 2), "collider_pairs": (K, 2)}``.
    """
    c = IntersectionCounter(faces, device)
    n, p = c.self_pairs(points)
    out = {"self": n, "self_pairs": p, "collider": 0, "collider_pairs": np.zeros((0, 2), np.int32)}
    if colliders is not None:
        out["collider"], out["collider_pairs"] = c.collider_pairs(points, colliders)
    out["total"] = out["self"] + out["collider"]
    return out
