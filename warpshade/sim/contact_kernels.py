"""Warp kernels of cloth self-contact beyond vertex-triangle: edge-edge contacts, and the
intersection guard that ends every step free of intersections (orchestrated by
:mod:`warpshade.sim.solver_xpbd`).

The guard is the safe fallback of continuous collision detection (Bridson, Fedkiw & Anderson
2002, section 7.4, "rigid impact zones", in its simplest form): after a step, every vertex of a
triangle that intersects another (exact test, :mod:`warpshade.sim.intersections`) goes back to
where it was at the start of the step, which was intersection-free; the marked region grows by
one ring of neighbours per round until the count is 0.
"""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

from .kernels import boxes_overlap, closest_segments, dihedral_angle, push_candidate, stored_side

# ---------------------------------------------------------------------------------------------
# Geometry
# ---------------------------------------------------------------------------------------------


@wp.func
def pair_closure(v: wp.array[wp.vec3], i: int, a: int, b: int, c: int, horizon: float) -> float:
    """Upper bound of the relative motion of vertex i and triangle (or edge, c = -1) abc over horizon."""
    vi = v[i]
    m = wp.max(wp.length(vi - v[a]), wp.length(vi - v[b]))
    if c >= 0:
        m = wp.max(m, wp.length(vi - v[c]))
    return m * horizon


@wp.func
def edge_orientation(a: wp.vec3, b: wp.vec3, c: wp.vec3, d: wp.vec3) -> float:
    """Sign of det[b - a, d - c, c - a] scaled: which side of edge ab edge cd passes (0 if parallel)."""
    n = wp.cross(b - a, d - c)
    ln = wp.length(n)
    if ln < 1.0e-12:
        return 0.0
    s = wp.dot(n, c - a)
    if s > 0.0:
        return 1.0
    if s < 0.0:
        return -1.0
    return 0.0


@wp.func
def triple(u: wp.vec3, v: wp.vec3, w: wp.vec3) -> float:
    """The triple product det[u, v, w]."""
    return wp.dot(wp.cross(u, v), w)


@wp.func
def coplanarity(a0: wp.vec3, b0: wp.vec3, c0: wp.vec3, d0: wp.vec3, a1: wp.vec3, b1: wp.vec3, c1: wp.vec3,
                d1: wp.vec3, t: float) -> float:
    """det[b - a, d - c, c - a] of the four points moved linearly a fraction t from 0 to 1."""
    a = a0 + (a1 - a0) * t
    b = b0 + (b1 - b0) * t
    c = c0 + (c1 - c0) * t
    d = d0 + (d1 - d0) * t
    return triple(b - a, d - c, c - a)


@wp.func
def crossing_root(a0: wp.vec3, b0: wp.vec3, c0: wp.vec3, d0: wp.vec3, a1: wp.vec3, b1: wp.vec3, c1: wp.vec3,
                  d1: wp.vec3, lo: float, hi: float, tol: float) -> bool:
    """Whether the coplanarity changes sign on [lo, hi] (where it is monotone) with the segments
    within tol of each other at the root (found by bisection)."""
    flo = coplanarity(a0, b0, c0, d0, a1, b1, c1, d1, lo)
    fhi = coplanarity(a0, b0, c0, d0, a1, b1, c1, d1, hi)
    if (flo > 0.0 and fhi > 0.0) or (flo < 0.0 and fhi < 0.0):
        return False
    for _ in range(32):
        mid = 0.5 * (lo + hi)
        fm = coplanarity(a0, b0, c0, d0, a1, b1, c1, d1, mid)
        if (fm > 0.0 and flo > 0.0) or (fm < 0.0 and flo < 0.0):
            lo = mid
            flo = fm
        else:
            hi = mid
    t = 0.5 * (lo + hi)
    a = a0 + (a1 - a0) * t
    b = b0 + (b1 - b0) * t
    c = c0 + (c1 - c0) * t
    d = d0 + (d1 - d0) * t
    st = closest_segments(a, b, c, d)
    return wp.length((a + (b - a) * st[0]) - (c + (d - c) * st[1])) <= tol


@wp.func
def segments_cross(a0: wp.vec3, b0: wp.vec3, c0: wp.vec3, d0: wp.vec3, a1: wp.vec3, b1: wp.vec3, c1: wp.vec3,
                   d1: wp.vec3, tol: float) -> bool:
    """Whether segments ab and cd pass through each other (come within tol of each other at a
    moment their four points are coplanar) while every point moves linearly from its position 0
    to its position 1: continuous collision detection, the coplanarity det[b - a, d - c, c - a]
    being a cubic in time, cut at its turning points into monotone pieces."""
    u0 = b0 - a0
    du = (b1 - a1) - u0
    v0 = d0 - c0
    dv = (d1 - c1) - v0
    w0 = c0 - a0
    dw = (c1 - a1) - w0
    k1 = triple(du, v0, w0) + triple(u0, dv, w0) + triple(u0, v0, dw)
    k2 = triple(du, dv, w0) + triple(du, v0, dw) + triple(u0, dv, dw)
    k3 = triple(du, dv, dw)
    # turning points: roots of 3 k3 t^2 + 2 k2 t + k1 inside (0, 1), in order
    r0 = float(1.0)
    r1 = float(1.0)
    qa = 3.0 * k3
    qb = 2.0 * k2
    if qa != 0.0:
        disc = qb * qb - 4.0 * qa * k1
        if disc > 0.0:
            sq = wp.sqrt(disc)
            ta = (-qb - sq) / (2.0 * qa)
            tb = (-qb + sq) / (2.0 * qa)
            r0 = wp.clamp(wp.min(ta, tb), 0.0, 1.0)
            r1 = wp.clamp(wp.max(ta, tb), 0.0, 1.0)
    elif qb != 0.0:
        r0 = wp.clamp(-k1 / qb, 0.0, 1.0)
    if crossing_root(a0, b0, c0, d0, a1, b1, c1, d1, 0.0, r0, tol):
        return True
    if r1 > r0 and crossing_root(a0, b0, c0, d0, a1, b1, c1, d1, r0, r1, tol):
        return True
    return r1 < 1.0 and crossing_root(a0, b0, c0, d0, a1, b1, c1, d1, r1, 1.0, tol)


@wp.func
def crosses_ring(x0: wp.array[wp.vec3], x1: wp.array[wp.vec3], ring_offsets: wp.array[int], ring: wp.array[int],
                 v: int, p: int, q: int, tol: float) -> bool:
    """Whether edge pq passed through an edge of vertex v's one ring (other than itself) moving
    linearly from x0 to x1 (:func:`segments_cross`)."""
    for r in range(ring_offsets[v], ring_offsets[v + 1]):
        o = ring[r]
        if o == p or o == q:
            continue
        if segments_cross(x0[v], x0[o], x0[p], x0[q], x1[v], x1[o], x1[p], x1[q], tol):
            return True
    return False


@wp.func
def followed_side(side: float, x0: wp.array[wp.vec3], x1: wp.array[wp.vec3], ring_offsets: wp.array[int],
                  ring: wp.array[int], i0: int, i1: int, j0: int, j1: int, tol: float) -> float:
    """Edge pair (i0 i1, j0 j1)'s side after its points moved linearly from x0 to x1. When the
    orientation sign was `side` at x0 and is the other at x1, the pair takes the new sign unless
    the edges passed through each other on the way or one edge passed through an edge of the one
    ring of an end of the other (:func:`segments_cross` within tol: the cloth beside that end,
    which a flip beside an end goes past); else it keeps `side`. Turning past parallel, or the
    lines passing through each other beside an end of either edge clear of the cloth there, flips
    the sign without a crossing; a side kept across such a flip pulls the edges back through
    whatever lies between them. A pair already on the other side at x0 (a crossing in progress)
    keeps its side."""
    if side == 0.0:
        return side
    now = edge_orientation(x1[i0], x1[i1], x1[j0], x1[j1])
    if now == 0.0 or now == side:
        return side
    if edge_orientation(x0[i0], x0[i1], x0[j0], x0[j1]) != side:
        return side
    if segments_cross(x0[i0], x0[i1], x0[j0], x0[j1], x1[i0], x1[i1], x1[j0], x1[j1], tol):
        return side
    if crosses_ring(x0, x1, ring_offsets, ring, i0, j0, j1, tol) or crosses_ring(x0, x1, ring_offsets, ring, i1, j0, j1, tol):
        return side
    if crosses_ring(x0, x1, ring_offsets, ring, j0, i0, i1, tol) or crosses_ring(x0, x1, ring_offsets, ring, j1, i0, i1, tol):
        return side
    return now


# ---------------------------------------------------------------------------------------------
# Edge-edge self-contact
# ---------------------------------------------------------------------------------------------


@wp.kernel
def compute_edge_bounds(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    edges: wp.array[wp.vec2i],
    horizon: float,
    pad: wp.array[float],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
):
    """Box around an edge now and after `horizon` seconds of its current velocity, each end
    padded by its own pad."""
    e = wp.tid()
    ij = edges[e]
    p0 = x[ij[0]]
    p1 = x[ij[1]]
    q0 = p0 + v[ij[0]] * horizon
    q1 = p1 + v[ij[1]] * horizon
    r0 = wp.vec3(pad[ij[0]])
    r1 = wp.vec3(pad[ij[1]])
    lower[e] = wp.min(wp.min(p0, q0) - r0, wp.min(p1, q1) - r1)
    upper[e] = wp.max(wp.max(p0, q0) + r0, wp.max(p1, q1) + r1)


@wp.kernel
def mark_crease_edges(
    x: wp.array[wp.vec3],
    hinges: wp.array[wp.vec4i],
    hinge_edge: wp.array[int],
    min_angle: float,
    active: wp.array[int],
):
    """active[edge] = 1 for the shared edge of every hinge bent by more than min_angle [rad]
    (a fold's crease: with the border, where edge-edge contact can happen without a vertex
    meeting a triangle first)."""
    h = wp.tid()
    ids = hinges[h]
    theta = dihedral_angle(x[ids[0]], x[ids[1]], x[ids[2]], x[ids[3]])
    if wp.abs(theta) > min_angle:
        active[hinge_edge[h]] = 1


@wp.kernel
def find_edge_contacts(
    bvh: wp.uint64,
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    horizon: float,
    ahead: float,
    edges: wp.array2d[int],
    active: wp.array[int],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    ahead_lower: wp.array[wp.vec3],
    ahead_upper: wp.array[wp.vec3],
    thickness: float,
    prev_edge: wp.array2d[int],
    prev_side: wp.array2d[float],
    prev_count: wp.array[int],
    contact_edge: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    contact_dist: wp.array2d[float],
    overflow: wp.array[int],
    near: wp.array[int],
):
    """Edge-edge candidates (e, f) of the active edges e (borders and creases, against every
    edge f; a pair of two active edges is kept once, f > e) whose swept boxes overlap and that
    may come within 1.5 thicknesses (as :func:`warpshade.sim.kernels.find_self_contacts`); edges
    sharing a vertex are skipped. The side (orientation sign of the edge pair) is stored,
    kept from the previous detection while the pair is in contact. ``lower``/``upper`` are the
    edges' boxes swept over ``horizon``; ``bvh`` holds ``ahead_lower``/``ahead_upper``, swept over
    ``ahead`` >= ``horizon``, and near[0] is set to 1 when some pair, moved on with its velocities
    to the next detection, would be a candidate of it (the look-ahead of
    :func:`warpshade.sim.kernels.find_self_contacts`)."""
    e = wp.tid()
    later = ahead - horizon
    if active[e] == 0:
        contact_count[e] = 0
        return
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    count = int(0)
    query = wp.bvh_query_aabb(bvh, ahead_lower[e], ahead_upper[e])
    f = int(0)
    while wp.bvh_query_next(query, f):
        if f <= e and active[f] != 0:
            continue  # the pair is found from f
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        if i0 == j0 or i0 == j1 or i1 == j0 or i1 == j1:
            continue
        now = boxes_overlap(lower[e], upper[e], lower[f], upper[f])
        look = later > 0.0 and near[0] == 0
        if not now and not look:
            continue
        a = x[i0]
        b = x[i1]
        c = x[j0]
        d = x[j1]
        st = closest_segments(a, b, c, d)
        dist = wp.length((a + (b - a) * st[0]) - (c + (d - c) * st[1]))
        close = wp.max(pair_closure(v, i0, j0, j1, -1, horizon), pair_closure(v, i1, j0, j1, -1, horizon))
        if look:
            reach = 1.5 * (thickness + wp.max(pair_closure(v, i0, j0, j1, -1, later),
                                              pair_closure(v, i1, j0, j1, -1, later)))
            # (the pair's distance changes by at most `close` until the next detection)
            if dist - close <= reach:
                ta = a + v[i0] * horizon
                tb = b + v[i1] * horizon
                tc = c + v[j0] * horizon
                td = d + v[j1] * horizon
                sn = closest_segments(ta, tb, tc, td)
                if wp.length((ta + (tb - ta) * sn[0]) - (tc + (td - tc) * sn[1])) <= reach:
                    near[0] = 1
        if not now or dist > 1.5 * (thickness + close):
            continue
        side = edge_orientation(a, b, c, d)
        if dist < thickness:
            side = stored_side(prev_edge, prev_side, prev_count, e, f, side)
        count = push_candidate(contact_edge, contact_side, contact_dist, e, count, f, side, dist, overflow)
    contact_count[e] = count


@wp.kernel
def solve_edge_contacts(
    x: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    edges: wp.array2d[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    contact_edge: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    thickness: float,
    friction: float,
    side_tol: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Edge-edge separation: the closest points of two edges (both strictly inside their edges)
    are kept `thickness` apart along the edges' common normal, on the stored side (with side_tol
    >= 0, followed from the substep's start, :func:`followed_side` within side_tol; the stored
    side itself is then updated at the substep's end, :func:`update_edge_sides`), with
    position-based Coulomb friction on their relative tangential motion over the substep."""
    e = wp.tid()
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    for k in range(contact_count[e]):
        f = contact_edge[e, k]
        s0 = contact_side[e, k]
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        a = x[i0]
        b = x[i1]
        c = x[j0]
        d = x[j1]
        st = closest_segments(a, b, c, d)
        s = st[0]
        t = st[1]
        if s <= 0.0 or s >= 1.0 or t <= 0.0 or t >= 1.0:
            continue  # an endpoint is closest: vertex-triangle contacts hold it
        nn = wp.cross(b - a, d - c)
        ln = wp.length(nn)
        if ln < 1.0e-9 * wp.length(b - a) * wp.length(d - c):
            continue
        n = nn / ln
        side = s0
        if side == 0.0:
            side = edge_orientation(a, b, c, d)
            if side == 0.0:
                continue
            contact_side[e, k] = side
        elif side_tol >= 0.0:
            side = followed_side(side, x_prev, x, ring_offsets, ring, i0, i1, j0, j1, side_tol)
        # side > 0: edge cd lies on the +n side of edge ab
        p = a + (b - a) * s
        q = c + (d - c) * t
        gap = side * wp.dot(q - p, n)
        if gap >= thickness or gap < -4.0 * thickness:
            continue
        wa = inv_mass[i0] * (1.0 - s)
        wb = inv_mass[i1] * s
        wc = inv_mass[j0] * (1.0 - t)
        wd = inv_mass[j1] * t
        denom = wa * (1.0 - s) + wb * s + wc * (1.0 - t) + wd * t
        if denom == 0.0:
            continue
        depth = thickness - gap
        lam = depth / denom
        g = n * (side * lam)
        # friction: relative tangential displacement of the two closest points over the substep
        pp = x_prev[i0] * (1.0 - s) + x_prev[i1] * s
        qp = x_prev[j0] * (1.0 - t) + x_prev[j1] * t
        rel = (q - qp) - (p - pp)
        rt = rel - n * wp.dot(rel, n)
        lt = wp.length(rt)
        ft = wp.vec3(0.0)
        if lt > 0.0:
            ft = rt * (wp.min(1.0, friction * depth / lt) / denom)
        wp.atomic_add(delta, i0, (-g + ft) * wa)
        wp.atomic_add(delta, i1, (-g + ft) * wb)
        wp.atomic_add(delta, j0, (g - ft) * wc)
        wp.atomic_add(delta, j1, (g - ft) * wd)
        wp.atomic_add(delta_count, i0, 1.0)
        wp.atomic_add(delta_count, i1, 1.0)
        wp.atomic_add(delta_count, j0, 1.0)
        wp.atomic_add(delta_count, j1, 1.0)


@wp.kernel
def update_edge_sides(
    x_from: wp.array[wp.vec3],
    x_to: wp.array[wp.vec3],
    edges: wp.array2d[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    contact_edge: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    tol: float,
):
    """The edge pairs' stored sides followed along a motion from x_from to x_to
    (:func:`followed_side`)."""
    e = wp.tid()
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    for k in range(contact_count[e]):
        side = contact_side[e, k]
        if side == 0.0:
            continue
        f = contact_edge[e, k]
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        contact_side[e, k] = followed_side(side, x_from, x_to, ring_offsets, ring, i0, i1, j0, j1, tol)


# ---------------------------------------------------------------------------------------------
# Intersection guard
# ---------------------------------------------------------------------------------------------


@wp.kernel
def grow_mark(
    edges: wp.array2d[int],
    mark_in: wp.array[int],
    mark_out: wp.array[int],
):
    """mark_out (a copy of mark_in) also gets both ends of every edge with a marked end: the
    marked region grows by one ring of neighbours."""
    e = wp.tid()
    i = edges[e, 0]
    j = edges[e, 1]
    if mark_in[i] != 0 or mark_in[j] != 0:
        mark_out[i] = 1
        mark_out[j] = 1


@wp.kernel
def revert_marked(
    mark: wp.array[int],
    inv_mass: wp.array[float],
    x_start: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    reverted: wp.array[int],
):
    """Free marked vertices go back to their start-of-step positions."""
    i = wp.tid()
    if mark[i] != 0 and inv_mass[i] > 0.0:
        x[i] = x_start[i]
        reverted[i] = 1


@wp.kernel
def held_inv_mass(reverted: wp.array[int], inv_mass: wp.array[float], out: wp.array[float]):
    """inv_mass with the vertices the guard sent back made kinematic (0)."""
    i = wp.tid()
    out[i] = wp.where(reverted[i] != 0, 0.0, inv_mass[i])


@wp.kernel
def moved_velocities(
    x_unguarded: wp.array[wp.vec3],
    x_start: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    dt: float,
    v: wp.array[wp.vec3],
):
    """A vertex the guard moved leaves with its mean velocity over the step."""
    i = wp.tid()
    d = x[i] - x_unguarded[i]
    if d[0] != 0.0 or d[1] != 0.0 or d[2] != 0.0:
        v[i] = (x[i] - x_start[i]) / dt


@wp.kernel
def update_streaks(reverted: wp.array[int], streak: wp.array[int]):
    """Consecutive steps in which each vertex was sent back (0 after a step it was not)."""
    i = wp.tid()
    if reverted[i] != 0:
        streak[i] = streak[i] + 1
    else:
        streak[i] = 0


@wp.kernel
def reverted_velocities(
    reverted: wp.array[int],
    x_start: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
    dt: float,
    v: wp.array[wp.vec3],
):
    """A reverted vertex leaves with its mean velocity over the step (0 unless a collider pushed
    it): the revert is an inelastic impact."""
    i = wp.tid()
    if reverted[i] != 0:
        v[i] = (x[i] - x_start[i]) / dt
